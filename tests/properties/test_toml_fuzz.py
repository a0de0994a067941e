"""Fuzzing the model-file parser (hypothesis): it never executes code and never fails with
anything but our own errors."""

from __future__ import annotations

import ast
import builtins
import contextlib
import string
from unittest import mock

import pytest
import sympy
from hypothesis import given, settings
from hypothesis import strategies as st

from nlobs import ModelFileError, loads_model
from nlobs.model import parse_expression, symbol
from nlobs.model._expr import ExpressionError

SYMS = {"x": symbol("x"), "y": symbol("y"), "k": symbol("k")}
ATOMS = ["x", "y", "k", "1", "2.5", "0", "pi", "t", "__import__", "os", "eval", "exec", "open", "sin", "exp", "sqrt",
         "lambda", "import", "'s'", "x.y", "[", "]", "(", ")", "{", "}", ":", ",", ";", "=", "==", "*", "**", "+", "-",
         "/", "//", "%", "@", "~", "<", "if", "else", "for", "in", "not", "and", ".", "1e400", "9" * 30, "\\", "\n",
         "min", "max", "sat", "abs", "sign", "64", "**64", "I", "E", "N", "S", "d1", "\ufeff", "\x1b", "*/"]


@contextlib.contextmanager
def no_eval():
    """Make every way of running text raise while the parser works: if it used one, the test fails."""

    def forbidden(*args, **kwargs):
        raise AssertionError("the model parser tried to evaluate text")

    real_compile = builtins.compile

    def parse_only(source, filename, mode, flags=0, *args, **kwargs):
        # ast.parse is compile(..., PyCF_ONLY_AST): it builds a syntax tree and cannot run anything.
        if not flags & ast.PyCF_ONLY_AST:
            raise AssertionError("the model parser tried to compile text to code")
        return real_compile(source, filename, mode, flags, *args, **kwargs)

    with contextlib.ExitStack() as stack:
        for name in ("eval", "exec"):
            stack.enter_context(mock.patch.object(builtins, name, forbidden))
        stack.enter_context(mock.patch.object(builtins, "compile", parse_only))
        stack.enter_context(mock.patch.object(sympy, "sympify", forbidden))
        stack.enter_context(mock.patch.object(sympy.parsing.sympy_parser, "parse_expr", forbidden))
        yield


def _check_expression(text: str) -> None:
    try:
        with no_eval():
            out = parse_expression(text, SYMS)
    except ExpressionError:
        return
    assert isinstance(out, sympy.Expr)
    assert out.free_symbols <= set(SYMS.values())


@settings(max_examples=1500, deadline=None)
@given(st.lists(st.sampled_from(ATOMS), min_size=1, max_size=25).map(" ".join))
def test_token_soup_never_executes_and_only_raises_our_error(text):
    _check_expression(text)


@settings(max_examples=1500, deadline=None)
@given(st.text(alphabet=string.printable, max_size=60))
def test_random_text_never_executes_and_only_raises_our_error(text):
    _check_expression(text)


@settings(max_examples=400, deadline=None)
@given(st.lists(st.sampled_from(ATOMS), min_size=1, max_size=12).map(" ".join),
       st.sampled_from(["dynamics", "output", "parameters", "simulation", "observers.o", "definitions", "units"]))
def test_whole_files_never_execute(text, table):
    doc = 'states = ["x"]\noutputs = ["y"]\n[dynamics]\nx = "-x"\n[output]\ny = "x"\n'
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
    doc += f'[{table}]\nz = "{escaped}"\n'.replace("[dynamics]\nz", "[extra]\nz").replace("[output]\nz", "[extra2]\nz")
    try:
        with no_eval():
            loads_model(doc, path="fuzz.toml")
    except ModelFileError:
        pass


DEFS_DOC = ('states = ["x", "I"]\ninputs = ["u"]\noutputs = ["y"]\n[parameters]\nk = {{ value = 0.5, unknown = true }}\n'
            '[definitions]\nd1 = "{d1}"\nd2 = "{d2}"\n[dynamics]\nx = "{fx}"\nI = "0"\n[output]\ny = "{hy}"\n'
            '[simulation]\ninputs = {{ u = "{u}" }}\n[observers.o]\nkind = "custom"\nstates = ["z"]\nflow = ["{obs}"]\n')


def _esc(text: str) -> str:
    return text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n").replace("\x1b", "\\u001b").replace(
        "\ufeff", "\\ufeff")


@settings(max_examples=300, deadline=None)
@given(*[st.lists(st.sampled_from(ATOMS), min_size=1, max_size=10).map(" ".join) for _ in range(6)])
def test_files_with_definitions_never_execute_and_only_raise_our_errors(d1, d2, fx, hy, u, obs):
    """The new syntax (definitions used everywhere, unknown parameters, min/max/sat, SymPy's names) through the
    same guard: nothing evaluated, and either a ModelFileError or a valid model."""
    doc = DEFS_DOC.format(d1=_esc(d1), d2=_esc(d2), fx=_esc(fx), hy=_esc(hy), u=_esc(u), obs=_esc(obs))
    try:
        with no_eval():
            mf = loads_model(doc)
    except ModelFileError:
        return
    assert mf.unknown_params == ("k",) and mf.observer_system.states == ("x", "I", "k")
    assert all(isinstance(e, sympy.Expr) for e in (*mf.system.f, *mf.system.h))


def test_malicious_file_does_not_run(tmp_path):
    canary = tmp_path / "pwned"
    text = ('states = ["x"]\noutputs = ["y"]\n[dynamics]\n'
            f'x = "__import__(\'os\').system(\'touch {canary}\')"\n[output]\ny = "x"\n')
    with pytest.raises(ModelFileError), no_eval():
        loads_model(text)
    assert not canary.exists()
