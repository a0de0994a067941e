"""Translate a SymPy expression tree into another algebra (NumPy arrays, CasADi SX, ...).

One walker serves every numeric backend; a backend is a table of the elementary functions.
Only the node types a :class:`~nlobs.System` may contain are handled.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import reduce
from typing import Any

import numpy as np
import sympy as sp

from ..errors import ModelError
from ._tables import TableCall

__all__ = ["translate", "NUMPY", "piecewise_table"]


def piecewise_table(fmin: Callable[[Any, Any], Any], fmax: Callable[[Any, Any], Any],
                    sign: Callable[[Any], Any], is_zero: Callable[[Any], Any]) -> dict[Any, Callable[..., Any]]:
    """Entries for min, max (any number of arguments, as SymPy flattens them) and the Heaviside step
    H(x) with H(0) = h0 (SymPy writes it in derivatives of min, max and sat), from a backend's
    binary min/max, sign and zero test."""
    return {
        sp.Min: lambda *a: reduce(fmin, a),
        sp.Max: lambda *a: reduce(fmax, a),
        sp.Heaviside: lambda x, h0=0.5: (1 + sign(x)) / 2 + (h0 - 0.5) * is_zero(x),
    }


#: Elementary functions for NumPy arrays.
NUMPY: Mapping[Any, Callable[..., Any]] = {
    sp.sin: np.sin, sp.cos: np.cos, sp.tan: np.tan,
    sp.asin: np.arcsin, sp.acos: np.arccos, sp.atan: np.arctan, sp.atan2: np.arctan2,
    sp.sinh: np.sinh, sp.cosh: np.cosh, sp.tanh: np.tanh,
    sp.exp: np.exp, sp.log: np.log, sp.Abs: np.abs, sp.sign: np.sign,
    **piecewise_table(np.minimum, np.maximum, np.sign, lambda x: np.asarray(x) == 0),
    "sqrt": np.sqrt,
    "table": lambda cls, *a: cls.numeric(*a),
}


def translate(expr: sp.Expr, leaves: Mapping[sp.Symbol, Any], table: Mapping[Any, Callable[..., Any]]) -> Any:
    """Rebuild `expr` with the symbols replaced by `leaves` and functions taken from `table`.

    Shared sub-expressions are translated once.

    Raises
    ------
    ModelError
        If the expression contains a symbol not in `leaves` or an unsupported node.
    """
    memo: dict[sp.Basic, Any] = {}

    def walk(e: sp.Basic) -> Any:
        if e in memo:
            return memo[e]
        if e.is_Symbol:
            if e not in leaves:
                raise ModelError(f"cannot evaluate: the symbol `{e}` has no value here")
            out = leaves[e]
        elif e.is_Number or e in (sp.pi, sp.E):
            out = float(e)
        elif e.is_Add:
            args = [walk(a) for a in e.args]
            out = args[0]
            for a in args[1:]:
                out = out + a
        elif e.is_Mul:
            args = [walk(a) for a in e.args]
            out = args[0]
            for a in args[1:]:
                out = out * a
        elif e.is_Pow:
            base, ex = e.args
            if ex == sp.S.Half:
                out = table["sqrt"](walk(base))
            elif ex == -sp.S.Half:
                out = 1.0 / table["sqrt"](walk(base))
            elif ex.is_Integer:
                out = walk(base) ** int(ex)
            else:
                out = walk(base) ** walk(ex)
        elif isinstance(e, TableCall) and "table" in table:   # a lookup table (or a derivative of one)
            out = table["table"](e.func, *[walk(a) for a in e.args])
        elif e.func in table:
            args = [walk(a) for a in e.args]
            if e.func is sp.Heaviside and len(args) == 2:
                args[1] = float(e.args[1])  # H(0): a number, not a symbol of the backend
            out = table[e.func](*args)
        else:
            raise ModelError(f"cannot evaluate `{e}`: `{e.func}` is not supported numerically")
        memo[e] = out
        return out

    return walk(sp.Float(expr) if isinstance(expr, (int, float)) else expr)
