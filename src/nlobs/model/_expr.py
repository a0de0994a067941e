"""Safe parsing of expression text into SymPy, through a whitelist of Python AST nodes.

A model file (or a string given to :class:`~nlobs.System`) is user text. It is parsed with
:func:`ast.parse` in ``eval`` mode and then *walked*: only numbers, declared names, the
operators ``+ - * / **`` (binary and unary) and calls of a fixed list of functions are
turned into SymPy objects. Nothing is ever evaluated by Python: no ``eval``, ``exec``,
``sympify`` or ``parse_expr`` touches the text, so a model file cannot run code.

Limits keep SymPy from doing unbounded work on hostile input: the text length, the nesting
depth, the size of exponents (also once SymPy combines nested powers, ``(x**64)**64 = x**4096``)
and the magnitude of constant sub-expressions.

``min(a, b)``, ``max(a, b)`` and ``sat(x, lo, hi) = min(max(x, lo), hi)`` are piecewise, like
``abs`` and ``sign``: numerically exact (CasADi ``fmin``/``fmax``), analysed symbolically on one
regime at a time (see :func:`nlobs.analyze`).
"""

from __future__ import annotations

from typing import Any

import ast
import math
import re
from collections.abc import Callable, Mapping

import sympy as sp
from sympy.printing.str import StrPrinter

from .._text import shorten_list

__all__ = ["FUNCTIONS", "CONSTANTS", "ExpressionError", "parse_expression", "MAX_EXPONENT"]

#: Functions a model expression may call, with their number of arguments.
FUNCTIONS: Mapping[str, tuple[Callable[..., sp.Expr], int]] = {
    "sin": (sp.sin, 1),
    "cos": (sp.cos, 1),
    "tan": (sp.tan, 1),
    "asin": (sp.asin, 1),
    "acos": (sp.acos, 1),
    "atan": (sp.atan, 1),
    "atan2": (sp.atan2, 2),
    "sinh": (sp.sinh, 1),
    "cosh": (sp.cosh, 1),
    "tanh": (sp.tanh, 1),
    "exp": (sp.exp, 1),
    "log": (sp.log, 1),
    "sqrt": (sp.sqrt, 1),
    "abs": (sp.Abs, 1),
    "sign": (sp.sign, 1),
    "min": (lambda a, b: sp.Min(a, b), 2),
    "max": (lambda a, b: sp.Max(a, b), 2),
    "sat": (lambda x, lo, hi: _sat(x, lo, hi), 3),
}

#: Named constants a model expression may use.
CONSTANTS: Mapping[str, sp.Expr] = {"pi": sp.pi}

#: Longest accepted expression text, in characters: published identifiability models reach 10⁵ (StructuralIdentifiability.jl's
#: QY model has a 13,260-character output); raise it with ``nlobs --max-expression N`` or :func:`set_max_expression`.
MAX_TEXT = 200_000
#: A top-level sum of more terms is parsed in chunks of this many (Python's parser nests one level per term).
CHUNK_TERMS = 1000
MAX_DEPTH = 200  #: deepest accepted nesting of operations
MAX_EXPONENT = 64  #: largest accepted magnitude of a constant exponent
MAX_CONSTANT = 1e300  #: largest accepted magnitude of a constant sub-expression

_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}

_NODE_WORDS = {
    ast.Attribute: "attribute access (`a.b`)",
    ast.Subscript: "indexing (`a[i]`)",
    ast.Lambda: "lambda",
    ast.ListComp: "comprehension",
    ast.SetComp: "comprehension",
    ast.DictComp: "comprehension",
    ast.GeneratorExp: "comprehension",
    ast.Compare: "comparison",
    ast.BoolOp: "`and`/`or`",
    ast.IfExp: "`if ... else`",
    ast.JoinedStr: "f-string",
    ast.NamedExpr: "assignment (`:=`)",
    ast.Starred: "`*` unpacking",
    ast.List: "list",
    ast.Tuple: "tuple",
    ast.Dict: "dict",
    ast.Set: "set",
    ast.Await: "await",
    ast.Yield: "yield",
}


class ExpressionError(ValueError):
    """Raised by :func:`parse_expression`; the caller adds the file and key."""


def _sat(x: sp.Expr, lo: sp.Expr, hi: sp.Expr) -> sp.Expr:
    """sat(x, lo, hi) = min(max(x, lo), hi): x clipped to [lo, hi]."""
    if lo.is_number and hi.is_number and bool(lo > hi):
        raise ExpressionError(f"sat(x, lo, hi) needs lo <= hi, got lo = {lo}, hi = {hi}")
    return sp.Min(sp.Max(x, lo), hi)


def parse_expression(text: str, symbols: Mapping[str, sp.Expr]) -> sp.Expr:
    """Parse `text` into a SymPy expression over the declared `symbols`, without evaluating it.

    Parameters
    ----------
    text : str
        The expression, in Python syntax (``"mu*(1 - x1**2)*x2 - x1 + u"``).
    symbols : mapping of str to sympy.Expr
        The names the expression may use: symbols, or expressions (a model file's
        ``[definitions]``) that replace the name.

    Returns
    -------
    sympy.Expr

    Raises
    ------
    ExpressionError
        If the text is not an expression made only of numbers, declared names,
        ``+ - * / **`` and the functions in :data:`FUNCTIONS`, or exceeds a size limit.
    """
    if not isinstance(text, str):
        raise ExpressionError(f"an expression must be a string, got {type(text).__name__}")
    if len(text) > MAX_TEXT:
        raise ExpressionError(f"the expression is {len(text)} characters long; the limit is {MAX_TEXT} (raise it with "
                              "`nlobs --max-expression N ...` or nlobs.model.set_max_expression(N))")
    if "__" in text:
        raise ExpressionError("double underscores (dunder names) are not allowed in a model expression")
    if not text.strip():
        raise ExpressionError("the expression is empty")
    text = text.strip()
    chunks = _sum_chunks(text) if len(text) > 4 * CHUNK_TERMS else [text]
    walker = _Walker(symbols)
    if len(chunks) > 1:   # a long sum: each chunk on its own (its leading sign is a unary one), then one Add
        return walker.checked(sp.Add(*(walker.expr(_parse(c), 0) for c in chunks)))
    return walker.expr(_parse(text), 0)


def _terminating(r: sp.Rational) -> bool:
    """Whether the rational has a finite decimal expansion (a denominator of 2s and 5s only)."""
    q = int(r.q)
    for d in (2, 5):
        while q % d == 0:
            q //= d
    return q == 1 and r.q != 1


def as_written(expr: Any) -> str:
    """`expr` as text for a message, with decimals where the file had them: a model file's decimals become exact
    rationals when parsed (0.1 -> 1/10), and 2943/250 is shown as 11.772, not as a fraction the user never wrote."""
    if not isinstance(expr, sp.Basic):
        return expr if isinstance(expr, str) else repr(expr)   # already text, or a plain number
    e = expr
    reps = {r: sp.Float(repr(float(r))) for r in e.atoms(sp.Rational) if _terminating(r)}
    return StrPrinter({"full_prec": False}).doprint(e.xreplace(reps))


def set_max_expression(n: int) -> int:
    """Set the longest accepted expression text (characters) and return the previous limit.

    The default limit (two hundred thousand characters) accepts the largest published models seen; every
    symbolic step after parsing runs within :func:`nlobs.model.symbolic_budget`.
    """
    global MAX_TEXT
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"set_max_expression: the limit must be a positive whole number of characters, got {n!r}")
    old, MAX_TEXT = MAX_TEXT, n
    return old


def _sum_chunks(text: str) -> list[str]:
    """`text` cut before top-level binary + and − into pieces of :data:`CHUNK_TERMS` terms ([text] when shorter)."""
    import io
    import tokenize

    starts = [0]
    for line in text.splitlines(keepends=True):
        starts.append(starts[-1] + len(line))
    cuts, depth, prev, count = [], 0, None, 0
    try:
        for tok in tokenize.generate_tokens(io.StringIO(text).readline):
            if tok.type == tokenize.OP and tok.string in "([{":
                depth += 1
            elif tok.type == tokenize.OP and tok.string in ")]}":
                depth -= 1
            elif (tok.type == tokenize.OP and tok.string in "+-" and depth == 0 and prev is not None
                  and (prev.type in (tokenize.NAME, tokenize.NUMBER) or prev.string in ")]}")):
                count += 1
                if count % CHUNK_TERMS == 0:
                    cuts.append(starts[tok.start[0] - 1] + tok.start[1])
            if tok.type not in (tokenize.NL, tokenize.NEWLINE, tokenize.COMMENT, tokenize.INDENT, tokenize.DEDENT,
                                tokenize.ENDMARKER):
                prev = tok
    except (tokenize.TokenError, IndentationError, SyntaxError):
        return [text]   # the parser reports what is wrong
    bounds = [0, *cuts, len(text)]
    return [text[a:b] for a, b in zip(bounds, bounds[1:])]


def huge_integer(message: str) -> str | None:
    """nlobs's own words for Python's refusal of an integer literal of more than 4300 digits (whose message points to
    ``sys.set_int_max_str_digits``), else None."""
    m = re.search(r"integer string conversion: value has (\d+) digits", message)
    if not m:
        return None
    return (f"an integer of {int(m.group(1)):,} digits: a number in a model must be finite and at most 1e300 in "
            "magnitude (a double's range); check the number")


def _parse(text: str) -> ast.expr:
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as e:
        raise ExpressionError(huge_integer(str(e.msg)) or f"not a valid expression ({e.msg})") from None
    except RecursionError:
        raise ExpressionError("the expression is nested too deeply (or is too long a chain) for Python's parser; "
                              "split it into shorter expressions") from None
    except (ValueError, MemoryError, OverflowError) as e:
        raise ExpressionError(huge_integer(str(e)) or f"cannot be parsed ({type(e).__name__})") from None
    return tree.body


def _spine(node: ast.AST, ops: tuple[type, ...]) -> list[tuple[bool, ast.AST]]:
    """Flatten a left-deep chain ``a + b - c + ...`` into ``[(negated, operand), ...]``.

    Long sums and products would otherwise be walked recursively one level per term.
    """
    items: list[tuple[bool, ast.AST]] = []
    while isinstance(node, ast.BinOp) and isinstance(node.op, ops):
        items.append((isinstance(node.op, (ast.Sub, ast.Div)), node.right))
        node = node.left
    items.append((False, node))
    items.reverse()
    return items


class _Walker:
    def __init__(self, symbols: Mapping[str, sp.Expr]):
        self.symbols = symbols

    def expr(self, node: ast.AST, depth: int) -> sp.Expr:
        if depth > MAX_DEPTH:
            raise ExpressionError(f"the expression is nested more than {MAX_DEPTH} levels deep")
        if isinstance(node, ast.Constant):
            return self.constant(node.value)
        if isinstance(node, ast.Name):
            return self.name(node.id)
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.USub):
                return -self.expr(node.operand, depth + 1)
            if isinstance(node.op, ast.UAdd):
                return self.expr(node.operand, depth + 1)
            raise ExpressionError(f"the operator `{type(node.op).__name__}` is not allowed; use + - * / **")
        if isinstance(node, ast.BinOp):
            if isinstance(node.op, (ast.Add, ast.Sub)):
                terms = []
                for neg, operand in _spine(node, (ast.Add, ast.Sub)):
                    value = self.expr(operand, depth + 1)
                    terms.append(-value if neg else value)
                return self.checked(sp.Add(*terms))
            if isinstance(node.op, (ast.Mult, ast.Div)):
                out = []
                for neg, operand in _spine(node, (ast.Mult, ast.Div)):
                    value = self.expr(operand, depth + 1)
                    if neg:
                        if value.is_zero:
                            raise ExpressionError("division by zero")
                        value = sp.Pow(value, -1)
                    out.append(value)
                return self.checked(sp.Mul(*out))
            if isinstance(node.op, ast.Pow):
                return self.power(self.expr(node.left, depth + 1), self.expr(node.right, depth + 1))
            raise ExpressionError(
                f"the operator `{type(node.op).__name__}` is not allowed; use + - * / **"
            )
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        word = _NODE_WORDS.get(type(node), f"`{type(node).__name__}`")
        raise ExpressionError(f"{word} is not allowed in a model expression")

    def constant(self, value: object) -> sp.Expr:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            kind = "a string" if isinstance(value, str) else type(value).__name__
            raise ExpressionError(f"{kind} is not allowed here; only numbers, names and + - * / **")
        if isinstance(value, float) and not math.isfinite(value):
            raise ExpressionError("the number is out of range")
        if abs(value) > MAX_CONSTANT:
            raise ExpressionError(f"the number exceeds {MAX_CONSTANT:g} in magnitude")
        if isinstance(value, int):
            return sp.Integer(value)
        # decimal literals become exact rationals (0.1 -> 1/10) so symbolic work stays exact
        return sp.Rational(repr(value))

    def name(self, name: str) -> sp.Expr:
        if name in self.symbols:
            if isinstance(self.symbols[name], type):
                raise ExpressionError(f"`{name}` is a table; call it, as in `{name}(x)`")
            return self.symbols[name]
        if name in CONSTANTS:
            return CONSTANTS[name]
        if name in FUNCTIONS:
            raise ExpressionError(f"`{name}` is a function; call it, as in `{name}(x)`")
        shown = name if len(name) <= 40 else name[:40] + "…"
        raise ExpressionError(f"unknown name `{shown}`; the names declared here are: {shorten_list(sorted(self.symbols))}")

    def call(self, node: ast.Call, depth: int) -> sp.Expr:
        if not isinstance(node.func, ast.Name):
            raise ExpressionError("only the functions " + ", ".join(FUNCTIONS) + " may be called")
        fname = node.func.id
        table = self.symbols.get(fname)
        if isinstance(table, type) and issubclass(table, sp.Function):   # a lookup table of the model
            nargs = next(iter(table.nargs))
            if node.keywords or any(isinstance(a, ast.Starred) for a in node.args) or len(node.args) != nargs:
                raise ExpressionError(f"the table `{fname}` takes {nargs} positional argument(s), got {len(node.args)}")
            return self.checked(table(*[self.expr(a, depth + 1) for a in node.args]))
        if fname not in FUNCTIONS:
            raise ExpressionError(
                f"`{fname[:40]}` is not an allowed function; allowed: {', '.join(FUNCTIONS)}"
            )
        if node.keywords or any(isinstance(a, ast.Starred) for a in node.args):
            raise ExpressionError(f"`{fname}` takes positional arguments only")
        fn, nargs = FUNCTIONS[fname]
        if len(node.args) != nargs:
            raise ExpressionError(f"`{fname}` takes {nargs} argument(s), got {len(node.args)}")
        args = [self.expr(a, depth + 1) for a in node.args]
        return self.checked(fn(*args))

    def power(self, base: sp.Expr, exponent: sp.Expr) -> sp.Expr:
        if exponent.is_number:
            e = complex(exponent.evalf(30))
            if e.imag != 0 or not math.isfinite(e.real):
                raise ExpressionError("the exponent is not a finite real number")
            if abs(e.real) > MAX_EXPONENT:
                raise ExpressionError(
                    f"the constant exponent {e.real:g} exceeds {MAX_EXPONENT} in magnitude"
                )
            if base.is_number:
                b = complex(base.evalf(30))
                if b == 0 and e.real < 0:
                    raise ExpressionError("zero raised to a negative power")
                if b != 0 and e.real * math.log10(abs(b)) > math.log10(MAX_CONSTANT):
                    raise ExpressionError(f"the constant power exceeds {MAX_CONSTANT:g}")
        return self.checked(sp.Pow(base, exponent))

    @staticmethod
    def checked(value: sp.Expr) -> sp.Expr:
        """Reject constant sub-expressions that are infinite, complex or too large, and powers whose
        exponent SymPy combined above the limit (``(x**64)**64 = x**4096``, ``x**64*x**64 = x**128``)."""
        for node in (value, *value.args):
            if node.is_Pow and node.args[1].is_number:
                e = complex(node.args[1].evalf(30))
                if not math.isfinite(e.real) or abs(e.real) > MAX_EXPONENT:
                    raise ExpressionError(f"a power of exponent {e.real:g} (after combining nested powers and products) "
                                          f"exceeds {MAX_EXPONENT} in magnitude")
        if value.has(sp.zoo, sp.oo, -sp.oo, sp.nan):
            raise ExpressionError("the expression is undefined (division by zero or infinity)")
        if value.is_number:
            v = complex(value.evalf(30))
            if not (math.isfinite(v.real) and math.isfinite(v.imag)) or abs(v) > MAX_CONSTANT:
                raise ExpressionError(f"a constant part exceeds {MAX_CONSTANT:g} in magnitude")
            if abs(v.imag) > 1e-12 * max(1.0, abs(v.real)):
                raise ExpressionError("a constant part is not a real number")
        return value
