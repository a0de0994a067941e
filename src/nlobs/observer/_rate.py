"""The fastest local rate of an observer's flow ż = F(t, z, u, y): what sets the first RK4 sub-steps of a run
(:mod:`nlobs.observer._compiled`) and of each online step (:meth:`nlobs.Observer.rate`).

Up to :data:`~nlobs.engine._intervals.EXACT_RATE_MAX` internal states it is the spectral radius of ∂F/∂z, from the
Jacobian's eigenvalues. Above it no Jacobian is formed: the power iteration of
:func:`~nlobs.engine._intervals.power_rate` runs on Jacobian-vector products ∂F/∂z·v (forward mode, about three
flows' worth of operations). The symbolic n x n Jacobian of a 24-state UKF's flow (600 internal states) took 2.4 s
and 560 MB to build, for one number.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import casadi as ca
import numpy as np

from ..design import ObserverDesign
from ..engine._batch import PointEvaluator
from ..engine._intervals import EXACT_RATE_MAX, fastest_rate, power_rate

__all__ = ["FlowRate", "flow_rate", "forget_rate"]


class FlowRate:
    """``rate(t, z, u, y)``: the fastest local rate of `design`'s flow at a point (1/time; 0 where not finite).

    The functions are built on first use; the last point's rate is kept (a run from the design's initial estimate
    asks for the same one every time).

    Parameters
    ----------
    design : ObserverDesign
    """

    def __init__(self, design: ObserverDesign) -> None:
        self.design = design
        self.n = design.n_z
        self._eval: PointEvaluator | None = None
        self._last: tuple[bytes, float] | None = None

    def _build(self) -> PointEvaluator:
        d, s = self.design, self.design.system
        X = ca.MX if d.needs_mx else ca.SX
        z, t, u, y = X.sym("z", self.n), X.sym("t"), X.sym("u", s.n_inputs), X.sym("y", s.n_outputs)
        F = d.flow(t, z, u, y)
        if self.n <= EXACT_RATE_MAX:
            fn = ca.Function("flow_jacobian", [t, z, u, y], [ca.densify(ca.jacobian(F, z))])
        else:
            v = X.sym("v", self.n)
            fn = ca.Function("flow_jvp", [t, z, u, y, v], [ca.densify(ca.jtimes(F, z, v))])
        return PointEvaluator(fn)

    def __call__(self, t: float, z: Any, u: Any, y: Any) -> float:
        """The rate at (t, z) with the input `u` and the held measurement `y` (flat vectors)."""
        args = [np.array([float(t)]), *(np.asarray(a, dtype=float).reshape(-1) for a in (z, u, y))]
        key = b"".join(a.tobytes() for a in args)
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        if self._eval is None:
            self._eval = self._build()
        ev = self._eval
        if self.n <= EXACT_RATE_MAX:
            rate = fastest_rate(ev(*args)[0].reshape(self.n, self.n, order="F"))
        elif not all(np.isfinite(a).all() for a in args):
            rate = 0.0
        else:
            rate = power_rate(lambda vec: ev(*args, vec)[0], self.n)
        self._last = (key, rate)
        return rate


_RATES: OrderedDict[int, FlowRate] = OrderedDict()


def flow_rate(design: ObserverDesign) -> FlowRate:
    """The :class:`FlowRate` of `design`, one per design in the process (the prepared observer and the online
    observers made per call share its functions)."""
    hit = _RATES.get(id(design))
    if hit is not None and hit.design is design:   # the entry keeps the design alive: its id is not reused
        _RATES.move_to_end(id(design))
        return hit
    rate = _RATES[id(design)] = FlowRate(design)
    if len(_RATES) > 64:
        _RATES.popitem(last=False)
    return rate


def forget_rate(design: ObserverDesign) -> None:
    """Drop the :class:`FlowRate` kept for `design` (see :func:`nlobs.observer._compiled.forget`)."""
    hit = _RATES.get(id(design))
    if hit is not None and hit.design is design:
        del _RATES[id(design)]
