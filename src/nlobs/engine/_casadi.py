"""A System compiled once to CasADi: f, h and their Jacobians, as SX functions of (t, x, u, p)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import casadi as ca
import sympy as sp

from ..model import TIME, System, translate
from ..model._translate import piecewise_table

__all__ = ["CASADI", "to_casadi", "rows", "CompiledSystem", "compile_system"]

#: Elementary functions for CasADi SX/MX.
CASADI: Mapping[Any, Any] = {
    sp.sin: ca.sin, sp.cos: ca.cos, sp.tan: ca.tan,
    sp.asin: ca.asin, sp.acos: ca.acos, sp.atan: ca.atan, sp.atan2: ca.atan2,
    sp.sinh: ca.sinh, sp.cosh: ca.cosh, sp.tanh: ca.tanh,
    sp.exp: ca.exp, sp.log: ca.log, sp.Abs: ca.fabs, sp.sign: ca.sign,
    **piecewise_table(ca.fmin, ca.fmax, ca.sign, lambda x: x == 0),  # min, max, sat: exact, no smoothing
    "sqrt": ca.sqrt,
    "table": lambda cls, *a: cls.casadi(*a),   # a lookup table: CasADi's interpolant, exact derivatives by AD
}


def to_casadi(exprs: Sequence[sp.Expr], leaves: Mapping[sp.Symbol, Any]) -> ca.SX:
    """Translate SymPy expressions to one CasADi column vector."""
    if not exprs:
        return ca.SX(0, 1)
    return ca.vertcat(*[ca.SX(translate(e, leaves, CASADI)) for e in exprs])


def rows(v: Any, start: int, stop: int) -> Any:
    """Rows start:stop of a CasADi column, always as a column (an empty slice of a 1x1 SX is 1x0 in CasADi)."""
    if stop <= start:
        return type(v)(0, 1) if isinstance(v, (ca.SX, ca.MX, ca.DM)) else ca.SX(0, 1)
    return v[start:stop]


@dataclass(frozen=True, eq=False)
class CompiledSystem:
    """CasADi functions of a :class:`~nlobs.System` (all with inputs ``(t, x, u, p)``).

    Attributes
    ----------
    f, h : casadi.Function
        The vector field and the output map.
    f_x, h_x : casadi.Function
        Their Jacobians with respect to x (exact, by automatic differentiation).
    t, x, u, p : casadi.SX
        The symbols the expressions below are written in.
    f_sx, h_sx : casadi.SX
        The expressions themselves, for building larger graphs.
    """

    system: System
    t: ca.SX
    x: ca.SX
    u: ca.SX
    p: ca.SX
    f_sx: ca.SX
    h_sx: ca.SX
    f: ca.Function
    h: ca.Function
    f_x: ca.Function
    h_x: ca.Function

    def bind(self, params: Sequence[float] | None = None) -> tuple[ca.Function, ca.Function]:
        """f(t, x, u) and h(t, x, u) with the parameter values fixed (default: the model's)."""
        pv = self.system.param_values if params is None else params
        f = ca.Function("f", [self.t, self.x, self.u], [ca.substitute(self.f_sx, self.p, ca.DM(pv))])
        h = ca.Function("h", [self.t, self.x, self.u], [ca.substitute(self.h_sx, self.p, ca.DM(pv))])
        return f, h


_CACHE: dict[str, CompiledSystem] = {}


def compile_system(system: System) -> CompiledSystem:
    """Compile `system` to CasADi, once per structure (cached by :attr:`System.key`)."""
    hit = _CACHE.get(system.key)
    if hit is not None:  # same structure; parameter values are inputs, so only the label differs
        return hit if hit.system == system else replace(hit, system=system)
    t = ca.SX.sym("t")
    x = ca.SX.sym("x", system.n_states)
    u = ca.SX.sym("u", system.n_inputs)
    p = ca.SX.sym("p", system.n_params)
    leaves = {TIME: t}
    leaves.update({s: x[i] for i, s in enumerate(system.x)})
    leaves.update({s: u[i] for i, s in enumerate(system.u)})
    leaves.update({s: p[i] for i, s in enumerate(system.p)})
    f_sx = to_casadi(system.f, leaves)
    h_sx = to_casadi(system.h, leaves)
    args = [t, x, u, p]
    names = ["t", "x", "u", "p"]
    compiled = CompiledSystem(
        system, t, x, u, p, f_sx, h_sx,
        ca.Function("f", args, [f_sx], names, ["dx"]),
        ca.Function("h", args, [h_sx], names, ["y"]),
        ca.Function("f_x", args, [ca.jacobian(f_sx, x)], names, ["F"]),
        ca.Function("h_x", args, [ca.jacobian(h_sx, x)], names, ["H"]),
    )
    _CACHE[system.key] = compiled
    return compiled
