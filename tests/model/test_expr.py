"""The safe expression parser: what it accepts, and what it refuses (with the reason)."""

from __future__ import annotations

import pytest
import sympy as sp

from nlobs.model import parse_expression, symbol
from nlobs.model._expr import ExpressionError
from nlobs import System
from nlobs.errors import FormError
from nlobs.model import LTI

X, Y = symbol("x"), symbol("y")
SYMS = {"x": X, "y": Y}


@pytest.mark.parametrize(
    "text, expected",
    [
        ("x + 2*y", X + 2 * Y),
        ("-x**2 / 4", -(X**2) / 4),
        ("x - y - 1 + 2", X - Y + 1),
        ("sin(x)*exp(-y) + sqrt(x)", sp.sin(X) * sp.exp(-Y) + sp.sqrt(X)),
        ("atan2(y, x)", sp.atan2(Y, X)),
        ("abs(x) + sign(y)", sp.Abs(X) + sp.sign(Y)),
        ("0.1*x", sp.Rational(1, 10) * X),
        ("1e-3", sp.Rational(1, 1000)),
        ("pi*x", sp.pi * X),
        ("x**0.5", X ** sp.Rational(1, 2)),
        ("+x", X),
        ("2**10", sp.Integer(1024)),
    ],
)
def test_accepted(text, expected):
    assert sp.simplify(parse_expression(text, SYMS) - expected) == 0


def test_long_flat_sums_are_not_a_recursion_problem():
    text = "+".join(["x"] * 1000)  # our walker is iterative along chains; Python's own parser sets the limit
    assert parse_expression(text, SYMS) == 1000 * X


@pytest.mark.parametrize(
    "text, reason",
    [
        ("__import__('os').system('echo hacked')", "dunder"),
        ("x.real", "attribute access"),
        ("(lambda: 1)()", "only the functions"),
        ("lambda q: q", "lambda"),
        ("[x for x in y]", "comprehension"),
        ("x if y else 1", "if ... else"),
        ("x < y", "comparison"),
        ("x and y", "`and`/`or`"),
        ("'text'", "a string is not allowed"),
        ("x[0]", "indexing"),
        ("open('f')", "`open` is not an allowed function"),
        ("eval('1')", "`eval` is not an allowed function"),
        ("sin", "is a function; call it"),
        ("sin(x, y)", "takes 1 argument"),
        ("sin(x=1)", "positional arguments only"),
        ("z + 1", "unknown name `z`; the names declared here are: x, y"),
        ("x**1000", "exceeds 64"),
        ("2**10**10", "exceeds 64"),
        ("10**60 * 10**60 * 10**60 * 10**60 * 10**60 * 10**60", "exceeds 1e\\+300"),
        ("x / 0", "division by zero"),
        ("1e999", "out of range"),
        ("x // 2", "`FloorDiv` is not allowed"),
        ("x % 2", "`Mod` is not allowed"),
        ("~x", "`Invert` is not allowed"),
        ("x := 1", "not a valid expression"),
        ("x; y", "not a valid expression"),
        ("", "empty"),
        ("(" * 300 + "x" + ")" * 300, "nested|not a valid expression"),
        ("log(-1)", "not a real number"),
        ("True", "bool is not allowed"),
        ("1j", "complex is not allowed"),
        ("x" * 200_001, "characters long"),
    ],
)
def test_refused_with_reason(text, reason):
    with pytest.raises(ExpressionError, match=reason):
        parse_expression(text, SYMS)


def test_non_string_refused():
    with pytest.raises(ExpressionError, match="must be a string"):
        parse_expression(3, SYMS)  # type: ignore[arg-type]


def test_messages_show_numbers_as_the_file_wrote_them():
    from nlobs.model._expr import as_written
    from nlobs.model._system import symbol

    t, x = symbol("t"), symbol("x")
    assert as_written(parse_expression("1.2*9.81 + 0.5*sin(t)", {"t": t})) == "0.5*sin(t) + 11.772"
    assert as_written(parse_expression("9.81*x", {"x": x})) == "9.81*x"
    assert as_written(parse_expression("x/3", {"x": x})) == "x/3"          # not a decimal in any file: kept exact
    assert as_written("0.5*sin(t)") == "0.5*sin(t)" and as_written(2) == "2"
    quad = System(states=["vx", "th"], inputs=["T"], f=["-T*sin(th)/m", "0"], outputs=["y"], h=["th"],
                  params={"m": 1.2})
    with pytest.raises(FormError, match=r"f\[vx\] = -T\*sin\(th\)/m is not linear .*a derivative is -T\*cos\(th\)/m"):
        LTI.from_system(quad)
