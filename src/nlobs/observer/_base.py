"""The runnable observer contract.

An observer is the dynamical system of its design (Yi, Ortega & Zhang (2019), eq. 2, Wang, Ortega & Bobtsov (2021), eq. 6):

.. math::

    \\dot z = F(t, z, u, y), \\qquad \\hat x = H(t, z, u, y),

plus, for continuous-discrete observers, the update :math:`z^+ = J(t, z^-, u, y, m)` at
each sample. Between samples the measurement and the input are held (zero-order hold).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, Literal

import casadi as ca
import numpy as np

from ..design import ObserverDesign, check_positive
from ..engine import compile_system, raise_deferred, rk4_step
from ..engine._batch import evaluate_one
from ..errors import DataError, FiniteEscapeError, ShapeError
from ._compiled import CompiledObserver, compiled_observer, initial_state_of
from ._rate import flow_rate
from ._signals import signals_by_keyword, time_first

__all__ = ["AbstractObserver", "Observer", "OnlineObserver"]


def _vec(value: Any, n: int, name: str) -> np.ndarray:
    v = np.asarray(value if value is not None else np.zeros(n), dtype=float).reshape(-1)
    if v.size != n:
        raise ShapeError(f"`{name}` must have {n} entries, got {v.size}")
    return v


class AbstractObserver(ABC):
    """What every runnable observer offers; see the module docstring for the equations."""

    @property
    @abstractmethod
    def design(self) -> ObserverDesign:
        """The design this observer runs (equations and certificate)."""

    @abstractmethod
    def rhs(self, t: float, z: Any, u: Any, y: Any) -> np.ndarray:
        """dz/dt."""

    @abstractmethod
    def estimate(self, t: float, z: Any, u: Any, y: Any) -> np.ndarray:
        """x̂ from the internal state."""

    @abstractmethod
    def update(self, t: float, z: Any, u: Any, y: Any, mask: Any = None) -> np.ndarray:
        """z⁺ at a sample instant (identity for continuous observers)."""

    @abstractmethod
    def step(self, t: float, z: Any, dt: float, u: Any, y: Any, *, substeps: int = 1) -> np.ndarray:
        """Integrate the flow from t to t + dt with u and y held (RK4, `substeps` steps)."""

    @property
    def system(self):  # noqa: ANN201 - System, re-exported from the design
        return self.design.system

    @property
    def sampled(self) -> bool:
        return self.design.sampled

    @property
    def n_z(self) -> int:
        return self.design.n_z

    def initial_state(self, xhat0: Any = None) -> np.ndarray:
        """The internal state that starts from the estimate `xhat0` (default: the design's); the last one is kept
        (a run from the design's estimate asks for the same one every time: a tenth of a short estimate's time)."""
        x0 = self.design.xhat0 if xhat0 is None else _vec(xhat0, self.system.n_states, "xhat0")
        return initial_state_of(self.design, x0)

    def start(self, xhat0: Any = None, *, max_step: float | None = None) -> OnlineObserver:
        """An online estimator fed one sample at a time (see :class:`OnlineObserver`)."""
        return OnlineObserver(self, xhat0, max_step=max_step)

    def rate(self, t: float, z: Any, u: Any, y: Any) -> float:
        """The flow's fastest local rate at (t, z): the spectral radius of ∂F/∂z (1/time; estimated above 64 internal
        states, see :mod:`nlobs.observer._rate`), 0 where it is not finite."""
        n = self.n_z
        return flow_rate(self.design)(float(t), _vec(z, n, "z"), _vec(u, self.system.n_inputs, "u"), _vec(y, self.system.n_outputs, "y"))


class Observer(AbstractObserver):
    """An observer whose equations are CasADi functions (every design in nlobs).

    Parameters
    ----------
    design : ObserverDesign
    name : str, optional
        A label for results (default: the design's method).
    """

    def __init__(self, design: ObserverDesign, name: str | None = None):
        if not isinstance(design, ObserverDesign):
            raise TypeError(f"Observer needs an ObserverDesign (from a design_* function), got {type(design).__name__}")
        self._design = design
        self.name = name or design.method
        self._step_fns: dict[int, ca.Function] = {}

    @property
    def design(self) -> ObserverDesign:
        return self._design

    def _io(self, t: float, z: Any, u: Any, y: Any) -> list[np.ndarray]:
        s = self.system
        return [np.array([float(t)]), _vec(z, self.n_z, "z"), _vec(u, s.n_inputs, "u"), _vec(y, s.n_outputs, "y")]

    def rhs(self, t: float, z: Any, u: Any = None, y: Any = None) -> np.ndarray:
        return np.asarray(self._design.flow(*self._io(t, z, u, y)), dtype=float).reshape(-1)

    def estimate(self, t: float, z: Any, u: Any = None, y: Any = None) -> np.ndarray:
        return evaluate_one(self._design.output, *self._io(t, z, u, y))

    def update(self, t: float, z: Any, u: Any = None, y: Any = None, mask: Any = None) -> np.ndarray:
        if self._design.update is None:
            return _vec(z, self.n_z, "z").copy()
        m = np.ones(self.system.n_outputs) if mask is None else _vec(mask, self.system.n_outputs, "mask")
        out = np.asarray(self._design.update(*self._io(t, z, u, y), m), dtype=float).reshape(-1)
        raise_deferred()  # an update that runs Python (MHE's solver) reports its failure here, with its own error
        return out

    def step_function(self, substeps: int = 1) -> ca.Function:
        """``(z, t, dt, u, y) -> z(t + dt)``: `substeps` RK4 steps of the flow with u, y held."""
        fn = self._step_fns.get(substeps)
        if fn is None:
            d, s = self._design, self.system
            z, t, dt = ca.SX.sym("z", d.n_z), ca.SX.sym("t"), ca.SX.sym("dt")
            u, y = ca.SX.sym("u", s.n_inputs), ca.SX.sym("y", s.n_outputs)
            h = dt / substeps
            zk = z
            for i in range(substeps):
                zk = rk4_step(lambda tt, zz, _k: d.flow(tt, zz, u, y), t + i * h, zk, h)
            fn = self._step_fns[substeps] = ca.Function(f"{d.method}_step", [z, t, dt, u, y], [zk])
        return fn

    def step(self, t: float, z: Any, dt: float, u: Any = None, y: Any = None, *, substeps: int = 1) -> np.ndarray:
        """z at t + dt from z at t, with u and y held (RK4, `substeps` steps)."""
        t, z = time_first("Observer.step", t, z)
        if substeps < 1:
            raise ValueError(f"`substeps` must be at least 1, got {substeps}")
        s = self.system
        return evaluate_one(self.step_function(substeps), _vec(z, self.n_z, "z"), np.array([float(t)]),
                            np.array([float(dt)]), _vec(u, s.n_inputs, "u"), _vec(y, s.n_outputs, "y"))

    def compiled(self, *, hold: Literal["zoh", "linear"] = "zoh") -> CompiledObserver:
        """This observer prepared to run on sampled data many times (see :class:`CompiledObserver`).

        The functions are built once per design and cached (as :func:`nlobs.estimate` does); the C
        code is compiled once per machine when worth it and cached on disk.

        Examples
        --------
        >>> fast = Observer(design_ekf(model, Q=Q, R=R)).compiled()        # doctest: +SKIP
        >>> for rec in recordings:                                        # doctest: +SKIP
        ...     traj = fast.run(rec.t, u=rec.u, y=rec.y)                      # doctest: +SKIP
        """
        return compiled_observer(self._design, hold)

    def __repr__(self) -> str:
        return f"Observer({self.name!r}, method={self._design.method!r}, system={self.system.name!r})"

    def __str__(self) -> str:
        return str(self._design)


#: Most RK4 steps the online observer takes between two samples (beyond: a clear error, see ``OnlineObserver``).
MAX_ONLINE_SUBSTEPS = 10**6
_CHUNK = 64


def _stepper(obs: AbstractObserver, k: int) -> ca.Function:
    """``(z, t, dt, u, y) -> [z(t + dt); ρ]``: `k` RK4 steps of the flow with u, y held, and the fastest rate the
    stages measured (the difference-quotient stiffness detector of :func:`nlobs.engine._integrate.rk4_step_rate`, as
    the interval runner of :func:`nlobs.estimate` uses: no Jacobian, no eigenvalues)."""
    cache = obs.__dict__.setdefault("_rate_steps", {})
    fn = cache.get(k)
    if fn is None:
        from ..engine._integrate import rk4_step_rate

        d, s = obs.design, obs.system
        X = ca.MX if d.needs_mx else ca.SX
        z, t, dt = X.sym("z", d.n_z), X.sym("t"), X.sym("dt")
        u, y = X.sym("u", s.n_inputs), X.sym("y", s.n_outputs)
        h = dt / k
        zk, rmax = z, 0
        for i in range(k):
            zk, r = rk4_step_rate(lambda tt, zz, _k: d.flow(tt, zz, u, y), t + i * h, zk, h, rate=True)
            rmax = ca.fmax(rmax, r)
        fn = cache[k] = ca.Function(f"{d.method}_step_rate", [z, t, dt, u, y], [ca.densify(ca.vertcat(zk, rmax))])
    return fn


def _rk4_chunks(obs: AbstractObserver, t: float, z: np.ndarray, dt: float, u: np.ndarray, y: np.ndarray,
                n: int) -> tuple[np.ndarray, float]:
    """`n` equal RK4 steps from t to t + dt, in calls of at most 64 steps (a few compiled functions, not one per n);
    the state and the fastest rate the stages met."""
    h = dt / n
    done, rmax = 0, 0.0
    s = obs.system
    uu, yy = _vec(u, s.n_inputs, "u"), _vec(y, s.n_outputs, "y")
    while done < n:
        k = min(_CHUNK, n - done)
        if k != _CHUNK and k > 8:
            k = 8 * (k // 8)
        out = evaluate_one(_stepper(obs, k), np.asarray(z, dtype=float), np.array([t + done * h]), np.array([k * h]),
                           uu, yy)
        z, rmax = out[:-1], max(rmax, float(out[-1]))
        done += k
        if not np.all(np.isfinite(z)):
            break
    return z, rmax


def integrate(obs: AbstractObserver, t0: float, z: np.ndarray, t1: float, u: np.ndarray, y: np.ndarray, *,
              max_step: float | None = None, where: str = "the observer", rate: list[float] | None = None) -> np.ndarray:
    """The observer's flow from (t0, z) to t1 with u and y held: RK4 steps h with h·ρ <= 1 for the flow's fastest
    rate ρ (at the start the spectral radius of ∂F/∂z, or the rate carried from the previous interval; inside, the
    rate the RK4 stages measure, as the interval runner of :func:`nlobs.estimate` does: an interval whose steps were
    too long for it is integrated again with shorter ones) and h <= `max_step`. An interval that needs more than :data:`MAX_ONLINE_SUBSTEPS` steps is refused, never stepped
    over (one RK4 step across a long gap returns a number, not the estimate).

    `rate`, a one-element list, carries the rate at t0 in (when the caller knows it: the end of its previous
    interval, with the same u and y) and the rate at t1 out."""
    dt = t1 - t0
    if dt == 0:
        return np.asarray(z, dtype=float)
    n = 1 if not max_step else max(1, int(np.ceil(dt / max_step - 1e-9)))
    rho = rate[0] if rate and np.isfinite(rate[0]) else obs.rate(t0, z, u, y)
    for _ in range(6):
        n = max(n, int(np.ceil(dt * rho - 1e-9)))
        if n > MAX_ONLINE_SUBSTEPS:
            raise DataError(
                f"{where}: the gap from t = {t0:g} to t = {t1:g} ({dt:g} time units) needs more than "
                f"{MAX_ONLINE_SUBSTEPS:.0e} RK4 steps at the observer's fastest rate {rho:.3g} per time unit; the "
                "estimate across it would not be worth the time. Start the observer again at the new sample "
                "(Observer(design).start(xhat0=...)), or feed the samples in between")
        zn, met = _rk4_chunks(obs, t0, z, dt, u, y, n)
        h = dt / n
        end = met if np.all(np.isfinite(zn)) and np.isfinite(met) else np.inf
        if np.isfinite(end) and h * end <= 2.0:   # RK4 is stable up to h·|λ| ≈ 2.8 on the axes
            if rate is not None:
                rate[:] = [end]
            return zn
        rho = max(rho, end if np.isfinite(end) else 0.0, 4.0 * n / dt)
    if rate is not None:
        rate[:] = [np.nan]
    return zn


class OnlineObserver:
    """Run an observer one sample at a time, for use in a real loop.

    Each :meth:`update` integrates the observer from the previous sample time to `t` with the
    previous measurement and input held, applies the sample-time update with the new
    measurement, and returns the estimate at `t`. Components of `y` that are NaN are
    treated as missing: left out of the update, and replaced by the predicted output in the
    flow.

    Parameters
    ----------
    observer : AbstractObserver
    xhat0 : array_like, optional
        Initial estimate (default: the design's).
    max_step : float, optional
        Largest RK4 step between samples. The steps are shorter where the flow's fastest rate ρ asks for it
        (h·ρ <= 1, as :func:`nlobs.estimate` integrates), so a long gap is integrated, not stepped over; a gap that
        would take more than 10⁶ steps is refused with a DataError.
    """

    def __init__(self, observer: AbstractObserver, xhat0: Any = None, *, max_step: float | None = None):
        if not isinstance(observer, AbstractObserver):
            raise TypeError(f"OnlineObserver needs an observer (nlobs.Observer(design)), got {type(observer).__name__}")
        if max_step is not None:
            max_step = check_positive(max_step, "max_step", "OnlineObserver")
        self.observer = observer
        self.z = observer.initial_state(xhat0)
        self.t: float | None = None
        self.max_step = max_step
        self._u = np.zeros(observer.system.n_inputs)
        self._y = np.zeros(observer.system.n_outputs)
        self._predicted: float | None = None   # the time predict() brought z to, until the update there
        self._rate = [np.nan]   # the flow's rate at the end of the last interval: the next one's first step size

    @property
    def P(self) -> np.ndarray | None:
        """The covariance of the current estimate (n x n) for observers that carry one (EKF, UKF, Kalman filters);
        None for the others."""
        cov = self.observer.design.covariance
        if cov is None:
            return None
        n = self.observer.system.n_states
        return np.asarray(cov(self.z), dtype=float).reshape(n, n)

    def predict(self, t: float) -> np.ndarray:
        """Integrate to time `t` without a measurement (the last input and output held) and return the predicted
        estimate; :meth:`update` at the same `t` then applies the measurement there (filterpy's predict/update)."""
        try:
            t = float(t)
        except (TypeError, ValueError):
            raise DataError(f"OnlineObserver.predict: `t` must be a number, got {t!r}") from None
        if self.t is None:
            raise DataError("OnlineObserver.predict: no sample yet; call update(t0, u=..., y=...) with the first sample")
        if not (np.isfinite(t) and t > self.t):
            raise DataError(f"OnlineObserver.predict: `t` must be a finite time after the last one ({self.t:g}), got {t:g}")
        self.z = self._flow(t, t - self.t)
        self.t = self._predicted = t
        return self.xhat

    @property
    def xhat(self) -> np.ndarray:
        """The current estimate."""
        t = 0.0 if self.t is None else self.t
        return self.observer.estimate(t, self.z, self._u, self._y)

    def update(self, t: float, *args: Any, u: Any = None, y: Any = None) -> np.ndarray:
        """Feed the measurement `y` taken at time `t` (and the input `u` applied from `t` on): ``update(t, u=..., y=...)``."""
        u, y = signals_by_keyword("OnlineObserver.update", args, u, y)
        obs, sys_ = self.observer, self.observer.system
        y = _vec(y, sys_.n_outputs, "y")
        u = _vec(u, sys_.n_inputs, "u")
        try:
            t = float(t)
        except (TypeError, ValueError):
            raise DataError(f"OnlineObserver.update: `t` must be a number, got {t!r}") from None
        if np.any(np.isinf(y)) or not np.isfinite(t):
            raise DataError(f"OnlineObserver.update: t = {t} and y = {y} must be finite (NaN marks a missing output)")
        if not np.all(np.isfinite(u)):
            raise DataError(f"OnlineObserver.update: the input u = {u} at t = {t:g} must be finite")
        if self._predicted is not None and t == self._predicted:   # predict(t) already brought z to t
            z_pred = self.z
        elif self.t is not None:
            dt = t - self.t
            if not dt > 0:
                raise DataError(f"OnlineObserver.update: time must increase from one sample to the next; got t = {t:g} after "
                                f"t = {self.t:g}" + (" (the same time again: a second update would count the measurement twice)"
                                                     if dt == 0 else "") + "; give each sample once, in time order")
            z_pred = self._flow(t, dt)
        else:
            z_pred = self.z
        self._predicted = None
        mask = np.isfinite(y)
        if not mask.all():
            yhat = self._predicted_output(t, z_pred, u)
            y = np.where(mask, y, yhat)
        z = obs.update(t, z_pred, u, y, mask.astype(float))
        if not np.all(np.isfinite(z)):
            bad = int(np.flatnonzero(~np.isfinite(z))[0])
            label = f"observer {getattr(obs, 'name', obs.design.method)!r}"
            raise FiniteEscapeError(label, t, self.z, obs.design.z_names, np.inf,
                                    message=f"OnlineObserver.update: the observer's state {obs.design.z_names[bad]} became "
                                            f"{z[bad]} "
                                            f"at t = {t:g} (y = {y}, u = {u}); the state before this sample is kept. Check the "
                                            "sample (units, outliers, a long gap) or give a smaller max_step")
        self.z = z
        self.t, self._u, self._y = t, u, y
        return obs.estimate(self.t, self.z, u, y)

    def _flow(self, t: float, dt: float) -> np.ndarray:
        """z at `t` from the previous sample, with its u and y held (see :func:`integrate`)."""
        return integrate(self.observer, self.t, self.z, t, self._u, self._y, max_step=self.max_step,
                         where="OnlineObserver.update", rate=self._rate)

    def _predicted_output(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        xhat = self.observer.estimate(t, z, u, self._y)
        _, h = compile_system(self.observer.system).bind()
        return np.asarray(h(t, xhat, u), dtype=float).reshape(-1)
