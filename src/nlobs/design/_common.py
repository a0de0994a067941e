"""Helpers shared by the designs of the classical catalogue (issue 3).

- translating a model's SymPy expressions into the CasADi symbols of a design;
- reading the measured states (outputs that are a single state) of a model;
- gain vectors from desired poles for integrator-like chains;
- the supremum of a scalar function of the state over a box (grid, then local polish).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ..engine import to_casadi
from ..errors import ModelError, PreconditionError, ShapeError
from ..model import TIME, System
from ._base import Symbols

__all__ = ["require_system", "leaves_of", "to_sx", "measured_states", "chain_gain", "box_of", "sup_over_box", "saturate", "saturation_bounds", "batch", "symmetric_part"]


def require_system(system: Any, caller: str) -> System:
    """`system` if it is an nlobs.System, else a TypeError naming the design (never an AttributeError later)."""
    if not isinstance(system, System):
        raise TypeError(f"{caller}: expected an nlobs.System as the model, got {type(system).__name__}"
                        + (" (a model file's name? load it with nlobs.load_model(path).system)" if isinstance(system, str) else ""))
    return system


def leaves_of(system: System, s: Symbols, x: Any = None) -> dict[sp.Symbol, Any]:
    """SymPy symbols of the model -> CasADi symbols of the design (t, u, y and, if given, x)."""
    leaves: dict[sp.Symbol, Any] = {TIME: s.t}
    leaves.update({sym: s.u[i] for i, sym in enumerate(system.u)})
    leaves.update({sym: s.y[i] for i, sym in enumerate(system.y)})
    if x is not None:
        leaves.update({sym: x[i] for i, sym in enumerate(system.x)})
    return leaves


def to_sx(exprs: Sequence[sp.Expr], leaves: Mapping[sp.Symbol, Any]) -> ca.SX:
    """CasADi column of the expressions (an empty column for none)."""
    return to_casadi(list(exprs), leaves) if len(exprs) else ca.SX(0, 1)


def measured_states(system: System, caller: str) -> list[int]:
    """For each output, the index of the state it measures (``y_k = x_j``), or a PreconditionError."""
    _, h = system.substituted()
    out = []
    for k, name in enumerate(system.outputs):
        hk = sp.expand(h[k])
        hit = [j for j, xs in enumerate(system.x) if hk == xs]
        if not hit:
            raise PreconditionError(f"{caller}: output {name} = {h[k]} is not a single state; this design needs each output "
                                    "to measure one state (y_k = x_j). Rewrite the model in these coordinates.")
        out.append(hit[0])
    return out


def chain_gain(couplings: Sequence[float], poles: Sequence[complex]) -> np.ndarray:
    r"""K0 with eig(A_c - K0 e1ᵀ) = `poles` for the chain matrix A_c (superdiagonal `couplings`).

    With :math:`T = \mathrm{diag}(1, a_1, a_1a_2, \dots)`, :math:`T A_c T^{-1} = A_0` (ones on the
    superdiagonal), whose companion structure gives
    :math:`\det(sI - A_0 + kC_0) = s^n + k_1 s^{n-1} + \dots + k_n`; so
    :math:`K_0 = T^{-1}k` with k the coefficients of :math:`\prod (s - p_i)`.
    """
    k = np.real(np.poly(np.asarray(poles, dtype=complex)))[1:]
    scale = np.concatenate([[1.0], np.cumprod(np.asarray(couplings, dtype=float))])
    return k / scale


def box_of(system: System, region: Mapping[str, Sequence[float]] | None, names: Sequence[str], caller: str,
           what: str = "region") -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds for `names` from a mapping ``{name: (lo, hi)}`` (every name required)."""
    from ..analysis.forms._conditions import region_pairs  # here, not at the top: a Monte Carlo worker loads no analysis
    if region is None:
        raise PreconditionError(f"{caller}: `{what}` is required here: give a box {{name: (lo, hi)}} for {', '.join(names)}")
    region_pairs(region, names, what, caller)   # every name once, no other
    lo, hi = [], []
    for k in names:
        try:
            a, b = (float(v) for v in region[k])
        except (TypeError, ValueError):
            raise ShapeError(f"{caller}: `{what}[{k!r}]` must be a pair (lo, hi) of numbers, got {region[k]!r}") from None
        if not (np.isfinite(a) and np.isfinite(b) and a <= b):
            raise ShapeError(f"{caller}: `{what}[{k!r}]` = ({a}, {b}) must be finite with lo <= hi")
        lo.append(a)
        hi.append(b)
    return np.array(lo), np.array(hi)


def sup_over_box(fn: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray) -> tuple[float, np.ndarray]:
    """The supremum of a scalar function over the box [lo, hi], estimated from below by
    :func:`nlobs.analysis.box_sup` (samples with the corners and the centre, then L-BFGS-B).

    `fn` maps an (N, d) array of points to N values. A non-finite value inside the box is a
    :class:`~nlobs.errors.PreconditionError` (the design's region is too large).

    Returns
    -------
    value : float
    argmax : numpy.ndarray of shape (d,)
    """
    from ..analysis.forms._conditions import box_sup  # here, not at the top: a Monte Carlo worker loads no analysis
    try:
        return box_sup(fn, np.column_stack([lo, hi]))
    except ModelError as e:
        raise PreconditionError(str(e)) from e


def saturate(x: ca.SX, bounds: np.ndarray) -> ca.SX:
    """Componentwise clipping to [-bound, bound] (an infinite bound leaves the entry free)."""
    out = []
    for i in range(x.numel()):
        b = float(bounds[i])
        out.append(x[i] if not np.isfinite(b) else ca.fmin(ca.fmax(x[i], -b), b))
    return ca.vertcat(*out) if out else x


def saturation_bounds(saturation: Mapping[str, float] | Sequence[float] | None, names: Sequence[str],
                      caller: str) -> np.ndarray | None:
    """Bounds M (one per name, inf = none) from a mapping by name or a sequence; None without saturation."""
    if saturation is None:
        return None
    if isinstance(saturation, Mapping):
        unknown = [k for k in saturation if k not in names]
        if unknown:
            raise ShapeError(f"{caller}: `saturation` names {unknown[0]!r}, which is not one of {', '.join(names)}")
        b = np.array([float(saturation.get(n, np.inf)) for n in names])
    else:
        b = np.asarray(saturation, dtype=float).reshape(-1)
        if b.size != len(names):
            raise ShapeError(f"{caller}: `saturation` needs {len(names)} bounds ({', '.join(names)}), got {b.size}")
    if np.any(np.isnan(b)) or np.any(b <= 0):
        raise PreconditionError(f"{caller}: saturation bounds must be positive (inf for none), got {b}")
    return b


def batch(fn: ca.Function, points: np.ndarray) -> np.ndarray:
    """Evaluate a one-input CasADi function of a vector at many points: (N, d) -> (N, rows, cols)."""
    P = np.atleast_2d(np.asarray(points, dtype=float))
    N = P.shape[0]
    out = np.asarray(fn.map(N)(ca.DM(P.T)), dtype=float)
    r, c = fn.size1_out(0), fn.size2_out(0)
    return out.reshape(r, N, c).transpose(1, 0, 2)  # map() concatenates the N results horizontally


def symmetric_part(M: ca.SX) -> ca.SX:
    """(M + Mᵀ)/2: what a covariance update keeps, so that round-off never makes P asymmetric.

    Tried and dropped: M's lower triangle mirrored (the 24-state EKF's covariance rate 6,889 -> 3,233 operations, the
    whole advisor run on it 5 % fewer) made gcc's register allocation of the EKF's Joseph update take 42 s instead of
    9 s (each lower entry then lives until its mirror is written), and on a stiff reactor one sensor set's RTS
    smoother diverged that runs with the mean."""
    return (M + M.T) / 2
