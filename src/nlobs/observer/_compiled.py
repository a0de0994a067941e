"""An observer prepared once to run on sampled measurements many times.

Between two samples t_k < t_{k+1} the observer integrates its flow ż = F(t, z, u, y) with the
input and the measurement held (zero-order hold, or linear interpolation to the next sample),
in RK4 sub-steps whose number is chosen per interval at run time (see :mod:`nlobs.engine`'s
interval runner): at least ``ceil(dt_k / max_step)``, and enough that h·ρ ≤ 1 for the fastest
rate ρ of the flow, measured as the run goes (the first interval uses the spectral radius of
∂F/∂z at the initial state, estimated for large observers: :mod:`nlobs.observer._rate`). At each sample the continuous-discrete observers apply their
update. The functions are built once per design; the C code for them is compiled once per
machine and cached on disk.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import casadi as ca
import numpy as np

from ..design import ObserverDesign
from ..engine import Backend, compile_system, rows
from ..engine._batch import PointEvaluator, evaluate_one, forget_point
from ..engine._integrate import rk4_step_rate
from ..engine._intervals import MAX_SUBSTEPS, IntervalRunner, Rows
from .._progress import as_progress
from ..errors import DataError, FiniteEscapeError, ShapeError
from ._rate import flow_rate, forget_rate
from ._signals import signals_by_keyword

__all__ = ["CompiledObserver", "ObserverTrajectory", "compiled_observer", "initial_state_of", "forget"]

Hold = Literal["zoh", "linear"]


@dataclass(frozen=True, eq=False)
class ObserverTrajectory:
    """What :meth:`CompiledObserver.run` returns (time on the first axis).

    Attributes
    ----------
    t : numpy.ndarray of shape (N,)
    z : numpy.ndarray of shape (N, n_z)
        The internal state at each sample, after the sample-time update.
    xhat : numpy.ndarray of shape (N, n)
        The estimate at each sample.
    y_used : numpy.ndarray of shape (N, p)
        The measurement the observer held after each sample (a missing component replaced by the
        predicted output).
    xhat_prior : numpy.ndarray of shape (n,)
        The estimate at t[0] before the first measurement.
    yhat_prior : numpy.ndarray of shape (N, p)
        The output predicted for each sample before it is used: h(t_k, x̂_k⁻, u_k), with x̂_k⁻
        read from the internal state before the update at t_k and the measurement held until
        then (y_k − ŷ_k⁻ are the innovations).
    substeps : numpy.ndarray of shape (N - 1,)
        RK4 sub-steps taken in each interval.
    rate : numpy.ndarray of shape (N - 1,)
        The fastest rate of the flow measured in each interval (1/time unit).
    engine : str
        Where it ran: ``"c"`` or ``"vm"``.
    """

    t: np.ndarray
    z: np.ndarray
    xhat: np.ndarray
    y_used: np.ndarray
    xhat_prior: np.ndarray
    yhat_prior: np.ndarray
    substeps: np.ndarray
    rate: np.ndarray
    engine: str

    def info(self) -> dict[str, Any]:
        """How the run was integrated, for a result's ``info``."""
        n = self.substeps
        fastest = float(np.fmax.reduce(self.rate)) if n.size else 0.0  # one pass; fmax skips NaN
        if not np.isfinite(fastest):   # every rate NaN, or one infinite: the largest finite-or-not as nanmax gives it
            fastest = float(np.nanmax(self.rate)) if n.size and np.isfinite(self.rate).any() else 0.0
        return {"substeps": int(n.sum()), "max_substeps": int(n.max()) if n.size else 0,
                "fastest_rate": fastest, "engine": self.engine}


#: Sub-steps of at most this many SX instructions are compiled inlined: there the four calls of the flow cost more than
#: they save. Van der Pol's EKF (282 instructions) runs its 2,000 intervals in 0.14 ms inlined, 0.20 ms with the calls
#: (P3 of benchmarks/bench_core.py); cart-pole's EKF (1,330) and UKF (2,931) and the quadrotor's EKF (10,729) run as
#: fast either way, and the inlined quadrotor EKF takes 9 s to compile instead of 7.5 s.
SUB_INLINE_MAX = 1_000


class CompiledObserver:
    """An observer design prepared to run on sampled data: build once, run many times.

    Made by :meth:`nlobs.Observer.compiled` (and used, through the same cache, by
    :func:`nlobs.estimate`). Holding one avoids even the cache look-up.

    Parameters
    ----------
    design : ObserverDesign
    hold : {"zoh", "linear"}
        How u and y are held between samples: zero-order hold, or linear interpolation to the
        next sample (offline only).
    """

    def __init__(self, design: ObserverDesign, hold: Hold = "zoh"):
        if hold not in ("zoh", "linear"):
            raise ValueError(f"`hold` must be 'zoh' or 'linear', got {hold!r}")
        self.design, self.hold = design, hold
        s = design.system
        self.nu, self.ny, self.nz, self.n = s.n_inputs, s.n_outputs, design.n_z, s.n_states
        self.na = 2 + 2 * (self.nu + 2 * self.ny)
        self.selects_state = design.selects_state(self.n)
        self._build()
        self._runners: dict[str, IntervalRunner] = {}

    # -- construction ---------------------------------------------------------------------------
    def _build(self) -> None:
        d, nu, ny, nz = self.design, self.nu, self.ny, self.nz
        X = ca.MX if d.needs_mx else ca.SX  # MHE's update embeds an NLP: an MX graph, run on the VM
        _, h = compile_system(d.system).bind()
        zz, tt, uu, yy, mm = ca.SX.sym("z", nz), ca.SX.sym("t"), ca.SX.sym("u", nu), ca.SX.sym("y", ny), ca.SX.sym("m", ny)
        yhat = h(tt, d.output(tt, zz, uu, yy), uu)
        fill = ca.Function(f"{d.method}_fill", [tt, zz, uu, yy, mm], [mm * yy + (1 - mm) * yhat])

        self.sub = self._substep(X)
        # for C, above SUB_INLINE_MAX instructions: the same sub-step over MX, calling the flow as a function at the four
        # stages instead of inlining it four times (the same operations, a quarter of the code: a UKF's sub-step
        # compiles in a fraction); below it the SX sub-step itself, where the calls cost more than they save
        self.sub_c = self._substep(ca.MX) if X is ca.SX and self.sub.n_instructions() > SUB_INLINE_MAX else None

        S, a = X.sym("S", nz + ny), X.sym("a", self.na)
        z, yh = rows(S, 0, nz), rows(S, nz, nz + ny)
        t, dt = a[0], a[1]
        o1 = 2 + nu + 2 * ny
        u1, y1, m1 = rows(a, o1, o1 + nu), rows(a, o1 + nu, o1 + nu + ny), rows(a, o1 + nu + ny, o1 + nu + 2 * ny)
        z_plus = d.update(t + dt, z, u1, y1, m1) if d.update is not None else z
        yh_plus = fill(t + dt, z_plus, u1, y1, m1)
        y_prior = h(t + dt, d.output(t + dt, z, u1, yh), u1)  # the output predicted before the sample is used
        o = y_prior if self.selects_state else ca.vertcat(d.output(t + dt, z_plus, u1, yh_plus), y_prior)
        self.jump = ca.Function(f"{d.method}_sample", [S, a], [ca.vertcat(z_plus, yh_plus), o])

        # the start: the prior, the first update, the held measurement, x̂ after it, the predicted output
        z0, t0, u0_, y0_, m0_ = X.sym("z0", nz), X.sym("t0"), X.sym("u0", nu), X.sym("y0", ny), X.sym("m0", ny)
        prior = d.output(t0, z0, u0_, y0_)
        zs = d.update(t0, z0, u0_, y0_, m0_) if d.update is not None else z0
        ys = fill(t0, zs, u0_, y0_, m0_)
        self.start = ca.Function(f"{d.method}_start", [z0, t0, u0_, y0_, m0_],
                                 [ca.densify(v) for v in (prior, zs, ys, d.output(t0, zs, u0_, ys), h(t0, prior, u0_))])
        self.rate = flow_rate(d)   # the first interval's rate at the start (no n x n Jacobian for large observers)

    def _substep(self, X: Any) -> ca.Function:
        """``(S, a, th) -> (S_next, rate)``: one RK4 step of the flow (:func:`nlobs.engine.rk4_step_rate`) over symbols
        of type `X`; u and the held y from the interval's row `a` (held, or interpolated with ``hold="linear"``)."""
        d, nu, ny, nz = self.design, self.nu, self.ny, self.nz
        S, a, th = X.sym("S", nz + ny), X.sym("a", self.na), X.sym("th", 2)
        z, yh = rows(S, 0, nz), rows(S, nz, nz + ny)
        t, dt = a[0], a[1]
        o1 = 2 + nu + 2 * ny
        u0, m0 = rows(a, 2, 2 + nu), rows(a, 2 + nu + ny, 2 + nu + 2 * ny)
        u1, y1, m1 = rows(a, o1, o1 + nu), rows(a, o1 + nu, o1 + nu + ny), rows(a, o1 + nu + ny, o1 + nu + 2 * ny)
        if self.hold == "linear":  # first-order hold of u, and of y where both ends were measured
            slope, u_slope = (m0 * m1) * (y1 - yh) / dt, (u1 - u0) / dt
        else:
            slope, u_slope = X.zeros(ny), X.zeros(nu)

        def rhs(t_: Any, z_: Any, _k: int) -> Any:
            return d.flow(t_, z_, u0 + (t_ - t) * u_slope, yh + (t_ - t) * slope)

        z_next, rate = rk4_step_rate(rhs, th[0], z, th[1], rate=True)
        return ca.Function(f"{d.method}_substep", [S, a, th], [ca.vertcat(z_next, yh), rate])

    def _start(self, z0: np.ndarray, t0: float, u0: np.ndarray, y0: np.ndarray, m0: np.ndarray) -> list[np.ndarray]:
        """`start` evaluated into NumPy buffers (no DM conversion: a tenth of a short run's set-up time):
        the prior, the first update, the held measurement, x̂ after it, the predicted output."""
        if self.design.needs_mx:  # an NLP inside (MHE): the plain call, whose Python callbacks report their errors
            return [np.asarray(v, dtype=float).reshape(-1, order="F") for v in self.start(z0, t0, u0, y0, m0)]
        ev = self.__dict__.get("_start_eval")
        if ev is None:   # its buffer set up once
            ev = self._start_eval = PointEvaluator(self.start)
        return ev(z0, t0, u0, y0, m0)

    def _runner(self, engine: Backend) -> IntervalRunner:
        r = self._runners.get(engine)
        if r is None:
            o1 = 2 + self.nu + 2 * self.ny   # the mask of the outputs sampled at the interval's end: all 0, no update
            r = self._runners[engine] = IntervalRunner(self.sub, self.jump, backend=engine,
                                                       idle=slice(o1 + self.nu + self.ny, o1 + self.nu + 2 * self.ny),
                                                       sub_c=self.sub_c)
        return r

    # -- running --------------------------------------------------------------------------------
    def run(self, t: Any, *args: Any, u: Any = None, y: Any = None, mask: Any = None, z0: Any = None, xhat0: Any = None,
            max_step: float | None = None, engine: Backend = "auto", name: str | None = None,
            progress: bool | Callable[[float], None] | None = None) -> ObserverTrajectory:
        """Run the observer on samples: times `t` (N,), inputs `u` (N, m), outputs `y` (N, p): ``run(t, u=..., y=...)``.

        Parameters
        ----------
        t, u, y : array_like
            Strictly increasing sample times and the signals at them (no NaN: give `mask`).
        mask : array_like of shape (N, p), optional
            1 where an output was measured, 0 where missing (its value in `y` is then ignored).
        z0 : array_like of shape (n_z,), optional
            The internal state at t[0] before the first update (default: from `xhat0`).
        xhat0 : array_like of shape (n,), optional
            The initial estimate (default: the design's).
        max_step : float, optional
            Largest RK4 step between samples; the steps are shorter where the flow's rate asks for it.
        engine : {"auto", "vm", "c"}
        name : str, optional
            The observer's name in error messages.
        progress : bool or callable, optional
            Show progress on stderr (True) or call ``progress(fraction)`` with the fraction of the
            time span covered (reported as it goes on the virtual machine: a long gap takes seconds there).

        Raises
        ------
        FiniteEscapeError
            When the estimate becomes non-finite (with the interval and the last finite state).
        DataError
            When an interval (a gap in the recording) would need more than 10⁸ RK4 steps.
        """
        u, y = signals_by_keyword("CompiledObserver.run", args, u, y)
        label = f"observer {name or self.design.method!r}"
        t = np.ascontiguousarray(t, dtype=float).reshape(-1)
        N = t.size
        y = np.asarray(y, dtype=float).reshape(N, self.ny)
        u = np.zeros((N, 0)) if u is None and self.nu == 0 else np.asarray(u, dtype=float).reshape(N, self.nu)
        m = np.ones((N, self.ny)) if mask is None else np.asarray(mask, dtype=float).reshape(N, self.ny)
        if mask is not None:
            y = np.where(m > 0, y, 0.0)
        if max_step is not None and not (np.isfinite(max_step) and max_step > 0):
            raise ShapeError(f"{label}: `max_step` must be a positive number, got {max_step!r}")
        if z0 is None:
            x0 = self.design.xhat0 if xhat0 is None else np.asarray(xhat0, dtype=float).reshape(self.n)
            z0 = initial_state_of(self.design, x0)
        prior, zs, ys, xs, yp0 = self._start(np.asarray(z0, dtype=float), t[0], u[0], y[0], m[0])
        if not np.isfinite(zs).all():
            err = FiniteEscapeError(label, float(t[0]), np.asarray(z0, dtype=float).reshape(-1), self.design.z_names, np.inf,
                                    hint=f"at its first sample (t = {t[0]:g})")
            err.interval, err.substeps = -1, 0
            raise err
        rate0 = self.rate(t[0], zs, u[0], ys)
        samples = Rows(t, np.concatenate((u, y, m), axis=1))   # the intervals' table, assembled by the driver
        nmin = np.ones(N - 1) if max_step is None else np.maximum(1.0, np.ceil(np.diff(t) / max_step - 1e-9))
        runner = self._runner(engine)
        report = as_progress(progress, f"estimate {name or self.design.method}")
        s0 = np.concatenate([zs, ys])
        res = runner.run(s0, samples, nmin, rate0=rate0, on_progress=report)
        S = res.lead if res.lead is not None else np.vstack([s0, res.states])
        if res.refused is not None:
            k, need = res.refused
            dts = np.diff(t)
            rate = res.rate[k - 1] if k > 0 and np.isfinite(res.rate[k - 1]) else rate0
            raise DataError(
                f"{label}: the interval from t = {t[k]:g} to {t[k + 1]:g} (length {dts[k]:g}) would need {need:.3g} RK4 steps "
                f"(more than {MAX_SUBSTEPS:.0e}): the observer's fastest rate there is {rate:.3g} per time unit"
                + (f" and max_step = {max_step:g}" if max_step is not None else "")
                + ". Split the recording at this gap and estimate each part, or check the model's time scale")
        if res.failed is not None:
            k = res.failed
            err = FiniteEscapeError(label, float(t[k]), S[k, :self.nz], self.design.z_names, np.inf,
                                    hint=f"between the samples at t = {t[k]:g} and t = {t[k + 1]:g} "
                                         f"({int(res.substeps[k])} RK4 steps)" + _unconverged(res))
            err.interval, err.substeps = k, int(res.substeps[k])  # the step from sample k to sample k + 1
            raise err
        z = S[:, :self.nz]
        no = res.outputs.shape[1]
        # the outputs with the start's above them (written into the free row 0 the compiled driver leaves)
        O = res.olead if res.olead is not None else np.vstack([np.empty((1, no)), res.outputs])
        O[0, no - self.ny:] = yp0.reshape(-1)
        if not self.selects_state:
            O[0, :self.n] = xs.reshape(-1)
        yhat_prior = O[:, no - self.ny:]
        xhat = z[:, :self.n] if self.selects_state else O[:, :self.n]
        return ObserverTrajectory(t, z, _contiguous(xhat), S[:, self.nz:], prior.reshape(-1), yhat_prior,
                                  res.substeps, res.rate, res.backend)


    def replay(self, plan: Any, z0: np.ndarray, *, t: np.ndarray, u: np.ndarray, max_step: float | None = None,
               engine: Backend = "auto", name: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Run a re-processing plan for measurement delays (:func:`nlobs.simulate._delays.plan`): the internal
        state and the estimate at each row of `t`, each from the samples arrived by then. One call of the compiled
        interval driver (or the VM stretch by stretch); `z0` is the prior state at t[0].

        Raises
        ------
        FiniteEscapeError
            When the state becomes non-finite (with the time, and the row whose arrivals were being processed).
        DataError
            When an interval would need more than 10⁸ RK4 steps.
        """
        label = f"observer {name or self.design.method!r}"
        if max_step is not None and not (np.isfinite(max_step) and max_step > 0):
            raise ShapeError(f"{label}: `max_step` must be a positive number, got {max_step!r}")
        z0 = np.asarray(z0, dtype=float).reshape(-1)
        _, zs, ys, _, _ = self._start(z0, float(t[0]), u[0], plan.y0, plan.m0)
        if not np.all(np.isfinite(zs)):
            err = FiniteEscapeError(label, float(t[0]), z0, self.design.z_names, np.inf,
                                    hint=f"at its first sample (t = {t[0]:g})")
            err.interval, err.substeps = -1, 0
            raise err
        rate0 = self.rate(t[0], zs, u[0], ys)
        A = plan.table
        nmin = np.ones(A.shape[0]) if max_step is None else np.maximum(1.0, np.ceil(A[:, 1] / max_step - 1e-9))
        res = self._runner(engine).run(np.concatenate([z0, np.zeros(self.ny)]), A, nmin, rate0=rate0,
                                       schedule=plan.schedule)
        if res.refused is not None:
            k, need = res.refused
            raise DataError(
                f"{label}: the interval from t = {A[k, 0]:g} to {A[k, 0] + A[k, 1]:g} (length {A[k, 1]:g}) would need "
                f"{need:.3g} RK4 steps (more than {MAX_SUBSTEPS:.0e}); check the model's time scale"
                + (f" and max_step = {max_step:g}" if max_step is not None else ""))
        if res.failed is not None:
            k = res.failed
            row = int(plan.pass_row[k])
            late = " (re-processing the samples that arrived by then)" if plan.knot_time[k] < t[row] else ""
            before = res.states[row - 1, :self.nz] if row > 0 and np.isfinite(res.states[row - 1]).all() else z0
            err = FiniteEscapeError(label, float(A[k, 0]), before, self.design.z_names, np.inf,
                                    hint=f"between t = {A[k, 0]:g} and t = {A[k, 0] + A[k, 1]:g}, at the row t = {t[row]:g}"
                                         + late + _unconverged(res))
            err.interval, err.substeps = row, int(res.substeps[k])
            raise err
        z = res.states[:, :self.nz]
        xhat = z[:, :self.n] if self.selects_state else res.outputs[:, :self.n]
        return z, _contiguous(xhat)


def _contiguous(a: np.ndarray) -> np.ndarray:
    """`a` (N, k) as a C-contiguous array; a few columns of a wider array copied one at a time, which NumPy 2 does
    in a third of the time it takes to copy them together: 3 µs against 9 µs for 2 of 7 columns of 2001 rows."""
    if a.flags.c_contiguous or a.ndim != 2 or a.shape[1] > 4 or a.shape[0] > 20_000:
        return np.ascontiguousarray(a)
    out = np.empty(a.shape)
    for j in range(a.shape[1]):
        out[:, j] = a[:, j]
    return out


def _unconverged(res: Any) -> str:
    """What an interval refused by the kink check (engine/_intervals.py) adds to the message."""
    if res.unconverged is None:
        return ""
    return (f": the flow there changes faster than any step resolves, and doubling the RK4 steps still moved the end "
            f"state by {res.unconverged:.3g} times the tolerance (a state diverging, not a kink of abs, sign, min or "
            "max): the state before this interval is the last one to trust. Check the model or its parameters there, "
            "or the filter's tuning (a smaller Q, a larger R)")


def interval_table(t: np.ndarray, u: np.ndarray, y: np.ndarray, m: np.ndarray) -> np.ndarray:
    """One row per interval k: (t_k, dt_k, u_k, y_k, m_k, u_{k+1}, y_{k+1}, m_{k+1}), as the sub-step and sample
    functions read it (y: zero where m is 0); the layout of :class:`nlobs.engine._intervals.Rows`."""
    return Rows(t, np.concatenate((u, y, m), axis=1)).table()


_CACHE: OrderedDict[tuple[int, str], CompiledObserver] = OrderedDict()

#: The last initial state of each design's `initial` function (id -> (function, x̂0 bytes, z0)): an estimate or run
#: from the design's estimate asks for the same one every time (Observer wrappers are made per call).
_INITIAL: OrderedDict[int, tuple[Any, bytes, np.ndarray]] = OrderedDict()


def initial_state_of(design: ObserverDesign, x0: Any) -> np.ndarray:
    """The internal state of `design` that starts from the estimate `x0` (a new array); the last one per design is
    kept (a run from the design's estimate asks for the same one every time: a tenth of a short estimate's time)."""
    fn, key = design.initial, np.asarray(x0, dtype=float).tobytes()
    last = _INITIAL.get(id(fn))
    if last is not None and last[0] is fn and last[1] == key:
        return last[2].copy()
    z0 = evaluate_one(fn, x0)
    _INITIAL[id(fn)] = (fn, key, z0.copy())   # fn kept: its id is not reused while it is here
    if len(_INITIAL) > 64:
        _INITIAL.popitem(last=False)
    return z0


def forget(design: ObserverDesign) -> None:
    """Drop what is kept for `design` (its prepared observers, its last initial state): for a caller that designs
    filters it will not run again (``nlobs sensors --run``, one per set of sensors)."""
    for key in [k for k, c in _CACHE.items() if c.design is design]:
        del _CACHE[key]
    _INITIAL.pop(id(design.initial), None)
    forget_rate(design)
    for fn in (design.initial, design.output, design.flow, design.update):
        if fn is not None:
            forget_point(fn)


def compiled_observer(design: ObserverDesign, hold: Hold = "zoh") -> CompiledObserver:
    """The prepared observer for `design` (built on first use, then cached for the process)."""
    key = (id(design), hold)
    hit = _CACHE.get(key)
    if hit is not None and hit.design is design:  # the cache keeps the design alive, so its id is not reused
        _CACHE.move_to_end(key)
        return hit
    compiled = _CACHE[key] = CompiledObserver(design, hold)
    if len(_CACHE) > 64:
        _CACHE.popitem(last=False)
    return compiled
