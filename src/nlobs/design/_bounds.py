"""State bounds (e.g. tank levels >= 0) shared by the EKF, the UKF and MHE.

One option, one format: ``bounds={"x1": (0, None)}`` maps a state name to ``(lo, hi)``, with
``None`` (or an infinite number) for a side without a bound. The policy, the same for every
design that takes the option:

- the model is evaluated on the box: :math:`f(\\Pi(x))` and :math:`h(\\Pi(x))` where
  :math:`\\Pi` clips each bounded state to ``[lo, hi]`` (so a square root of a level never sees a
  negative argument, whatever an integration stage or a sigma point does); Jacobians are those of
  the model at :math:`\\Pi(x)`;
- filters (EKF, UKF) project the estimate onto the box after each measurement update (the
  estimate projection of Simon (2010) with the identity weight, which for a box is clipping);
  the covariance is left as the update made it;
- MHE constrains every state of its window to the box (hard bounds in its NLP).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from ..engine import compile_system
from ..errors import PreconditionError, ShapeError
from ..model import System
from ..references import cite
from ._base import Check

__all__ = ["Box", "parse_bounds", "clip", "clip_const", "check_start", "bounds_check", "POLICY"]

POLICY = (f"the model is evaluated at the estimate clipped to the bounds; the estimate is projected onto the "
          f"bounds after each update ({cite('simon2010', 'estimate projection')})")


@dataclass(frozen=True, eq=False)
class Box:
    """Lower and upper bounds per state (``-inf``/``inf`` where a state is unbounded)."""

    names: tuple[str, ...]
    lo: np.ndarray
    hi: np.ndarray

    @property
    def bounded(self) -> np.ndarray:
        return np.isfinite(self.lo) | np.isfinite(self.hi)

    def describe(self) -> str:
        return ", ".join(f"{nm} in [{lo:g}, {hi:g}]" for nm, lo, hi, b in zip(self.names, self.lo, self.hi, self.bounded) if b)

    def contains(self, x: np.ndarray) -> bool:
        return bool(np.all(x >= self.lo) and np.all(x <= self.hi))


def _side(v: Any, which: str, name: str, caller: str) -> float:
    if v is None:
        return -np.inf if which == "lower" else np.inf
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise ShapeError(f"{caller}: the {which} bound of `{name}` must be a number or None, got {v!r}") from None
    if np.isnan(f):
        raise ShapeError(f"{caller}: the {which} bound of `{name}` is NaN; use None for 'no bound'")
    return f


def parse_bounds(system: System, bounds: Mapping[str, Any] | None, caller: str) -> Box | None:
    """Check `bounds` ({state: (lo, hi)}) against the model; None when no state is bounded.

    Raises
    ------
    ShapeError, PreconditionError
        For a name that is not a state, a pair that is not two numbers/None, or lo > hi.
    """
    if bounds is None:
        return None
    if not isinstance(bounds, Mapping):
        raise ShapeError(f"{caller}: `bounds` must map state names to (lo, hi) pairs, e.g. {{'{system.states[0]}': (0, None)}}; "
                         f"got {type(bounds).__name__}")
    n = system.n_states
    lo, hi = np.full(n, -np.inf), np.full(n, np.inf)
    for name, pair in bounds.items():
        if name not in system.states:
            raise ShapeError(f"{caller}: `bounds` names {name!r}, which is not a state of {system.name!r} "
                             f"(states: {', '.join(system.states)})")
        if isinstance(pair, (str, bytes)) or not hasattr(pair, "__len__") or len(pair) != 2:
            raise ShapeError(f"{caller}: the bounds of `{name}` must be a pair (lo, hi) with None for no bound, got {pair!r}")
        i = system.states.index(name)
        lo[i], hi[i] = _side(pair[0], "lower", name, caller), _side(pair[1], "upper", name, caller)
        if lo[i] > hi[i]:
            raise PreconditionError(f"{caller}: the bounds of `{name}` are empty: lower {lo[i]:g} > upper {hi[i]:g}")
    box = Box(tuple(system.states), lo, hi)
    return box if box.bounded.any() else None


def clip(x: Any, lo: Any, hi: Any) -> Any:
    """x clipped to [lo, hi] element-wise, with derivative 1 on the closed box (0 outside).

    Written with ``if_else`` rather than ``fmin``/``fmax`` (whose derivative at a tie is 1/2), so a
    state sitting exactly on its bound keeps its full sensitivity.
    """
    return ca.if_else(x < lo, lo, ca.if_else(x > hi, hi, x))


def clip_const(x: Any, box: Box | None) -> Any:
    """x clipped to a box known at design time (only the bounded entries; the identity without a box)."""
    if box is None:
        return x
    parts = []
    for i in range(box.lo.size):
        xi = x[i]
        if np.isfinite(box.lo[i]):
            xi = ca.if_else(xi < box.lo[i], box.lo[i], xi)
        if np.isfinite(box.hi[i]):
            xi = ca.if_else(xi > box.hi[i], box.hi[i], xi)
        parts.append(xi)
    return ca.vertcat(*parts)


def check_start(system: System, box: Box | None, xhat0: np.ndarray, caller: str) -> list[str]:
    """Checks of a box at design time: `xhat0` inside it, and the model's Jacobians finite on each bound
    (a square root has an infinite slope at 0: a bound there would stall a filter or an NLP).

    Returns the evidence, one line per bound; raises PreconditionError with what to change.
    """
    if box is None:
        return []
    if not box.contains(xhat0):
        bad = [f"{nm} = {v:g} not in [{lo:g}, {hi:g}]" for nm, v, lo, hi in zip(box.names, xhat0, box.lo, box.hi) if not lo <= v <= hi]
        raise PreconditionError(f"{caller}: the initial estimate is outside the bounds: {'; '.join(bad)}; "
                                "start inside the bounds (pass `xhat0`)")
    comp = compile_system(system)
    fx, hx = comp.f_x, comp.h_x
    u0, p = np.zeros(system.n_inputs), system.param_values
    lines = []
    for i in np.flatnonzero(box.bounded):
        for side in (box.lo[i], box.hi[i]):
            if not np.isfinite(side):
                continue
            x = xhat0.copy()
            x[i] = side
            F, H = np.asarray(fx(0.0, x, u0, p), dtype=float), np.asarray(hx(0.0, x, u0, p), dtype=float)
            if not (np.all(np.isfinite(F)) and np.all(np.isfinite(H))):
                raise PreconditionError(
                    f"{caller}: the model's Jacobian is not finite at the bound {box.names[i]} = {side:g} (at the initial estimate "
                    f"otherwise): e.g. sqrt({box.names[i]}) has an infinite slope at 0. Move the bound slightly inside "
                    f"(e.g. {box.names[i]} >= {side + 1e-6 * max(1.0, abs(side)):g}) or write the model so that it is "
                    "differentiable there")
            lines.append(f"{box.names[i]} = {side:g}")
    return lines


def bounds_check(box: Box | None, lines: list[str]) -> Check | None:
    """The certificate line for the checks of :func:`check_start` (None without bounds)."""
    if box is None:
        return None
    return Check("initial estimate inside the bounds; model Jacobians finite on each bound", True,
                 f"{box.describe()}; finite f_x, h_x at {', '.join(lines)} (other states at the initial estimate)",
                 "floating point")
