r"""Discrete-time models: the plant iterates its map, the observers update at every step.

x[k+1] = f(x[k], u[k], t[k]) + w[k] (w[k] the process noise of the step), y[k] = h(x[k], u[k], t[k]) + v[k],
t[k] = k·sample_time. The plant is one CasADi ``mapaccum`` (a loop in compiled code, not in Python); each observer
then runs over the measurements on its own (:func:`~nlobs.simulate._isolate.each_observer`: one observer's failure is
its own), a Gaussian filter as its compiled update loop z[k] = U(t[k], z[k−1], u[k], y[k], m[k]) from its prior state
at k = 0, a particle filter as its compiled particle loop. :func:`observers_on` is also what runs them on
a recording, one row per step (:mod:`nlobs.estimation`, a layer above, adds the fixed-interval smoothers).
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping, Sequence
from typing import Any

import casadi as ca
import numpy as np

from ..design import ObserverDesign
from ..engine import compile_system
from ..errors import DataError, FiniteEscapeError, ModelError, ShapeError
from ..model import System, input_signals
from ..engine import Backend
from ..observer import AbstractObserver, ParticleObserver, compiled_observer
from ._isolate import each_observer, failure_of, observer_fault
from ._options import Noise, ProcessNoise, Sampling
from ._options import xhat0_for as _xhat0_for
from ._results import ObserverTrace, Run
from ._schedule import SampleSchedule

__all__ = ["simulate_map", "observers_on", "map_trace", "run_map_observer", "check_map_grid", "MAX_MAP_STEPS"]

#: The most steps a discrete-time simulation stores.
MAX_MAP_STEPS = 10_000_000


def _steps(plant: System, t_final: Any, dt: Any, caller: str) -> int:
    Ts = plant.sample_time
    if not (isinstance(t_final, numbers.Real) and not isinstance(t_final, bool) and np.isfinite(t_final) and t_final > 0):
        raise ShapeError(f"{caller}: `t_final` must be a positive number of seconds, got {t_final!r}")
    if dt is not None and abs(float(dt) - Ts) > 1e-12 * Ts:
        raise ShapeError(f"{caller}: {plant.name!r} is a discrete-time model stepping by its sample_time = {Ts:g} s; "
                         f"`dt` = {dt!r} does not apply (leave it out)")
    N = int(round(float(t_final) / Ts))
    if N < 1 or abs(N * Ts - float(t_final)) > 1e-9 * max(1.0, float(t_final)):
        raise ShapeError(f"{caller}: t_final = {t_final:g} must be a whole number of steps of sample_time = {Ts:g} s "
                         f"(e.g. {max(1, N) * Ts:g})")
    if N > MAX_MAP_STEPS:
        raise ShapeError(f"{caller}: {N:.3g} steps, more than {MAX_MAP_STEPS:.0e} (every step is stored)")
    return N


def _signals(plant: System, inputs: Any, t: np.ndarray) -> np.ndarray:
    U = np.zeros((t.size, plant.n_inputs))
    for j, sig in enumerate(input_signals(plant, inputs, plant.params, grid=t)):
        v = np.asarray(sig(t), dtype=float)
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise ShapeError(f"input `{plant.inputs[j]}` is {v[bad[0]]} at t = {t[bad[0]]:g}; inputs must be finite")
        U[:, j] = v
    return U


def _first_escape(values: np.ndarray, bound: float) -> int | None:
    """The first row with an entry that is not finite or beyond `bound`, or None."""
    bad = ~np.all(np.isfinite(values) & (np.abs(values) <= bound), axis=1)
    return int(np.argmax(bad)) if bad.any() else None


def run_map_observer(design: ObserverDesign, t: np.ndarray, u: np.ndarray, y: np.ndarray, mask: np.ndarray, z0: np.ndarray,
                     *, name: str, engine: Backend = "auto") -> tuple[np.ndarray, np.ndarray]:
    """An observer of a discrete-time model over samples: its state after each update (N, n_z) and its estimates
    (N, n). The compiled observer loop of every sampled observer runs it (its flow between samples is zero, so one
    trivial step per interval; C when worth it, cached on disk). Raises FiniteEscapeError at the first update whose
    state is not finite."""
    traj = compiled_observer(design).run(t, u=u, y=y, mask=mask, z0=z0, engine=engine, name=name)
    return traj.z, traj.xhat


def check_map_grid(system: System, t: np.ndarray, where: str) -> None:
    """Samples of a discrete-time model are on its grid: equally spaced by its sample_time."""
    if t.size > 1:
        d = np.diff(t)
        off = np.flatnonzero(np.abs(d - system.sample_time) > 1e-6 * system.sample_time)
        if off.size:
            k = int(off[0])
            raise DataError(f"{where}: {system.name!r} is a discrete-time model with sample_time = {system.sample_time:g} s; "
                            f"the samples must be one step apart, but t = {t[k]:.6g} is followed by {t[k + 1]:.6g} "
                            f"(row {k + 1}). Give one row per step (NaN marks an output not measured)")


def simulate_map(plant: System, obs: Mapping[str, AbstractObserver], *, t_final: Any, dt: Any = None,
                 x0: Sequence[float] | None, inputs: Any = None, noise: Noise | None = None,
                 process_noise: ProcessNoise | None = None, sampling: Sampling | None = None, seed: int | None = None,
                 xhat0: Any = None, escape_bound: float = 1e12, x0_tail: Sequence[float] = (),
                 caller: str = "simulate") -> Run:
    """A discrete-time plant and its observers (see the module's docstring); called by :func:`nlobs.simulate`.

    `process_noise` is the standard deviation of w[k] per step (not an intensity), `noise` that of v[k].
    """
    if sampling is not None:
        raise ShapeError(f"{caller}: {plant.name!r} is a discrete-time model, measured at every step; `sampling` does "
                         "not apply")
    for name, o in obs.items():
        if not o.system.is_discrete:
            raise ModelError(f"{caller}: observer {name!r} is a continuous-time design; {plant.name!r} is a discrete-time "
                             "model (design it on the discrete model: the kinds of `nlobs kinds` that run on maps)")
    N = _steps(plant, t_final, dt, caller)
    Ts = plant.sample_time
    t = np.arange(N + 1) * Ts
    if x0 is None:
        raise ModelError(f"{caller}: give x0 ({plant.n_states} numbers: {', '.join(plant.states)})")
    x = np.asarray([*np.asarray(x0, dtype=float).reshape(-1), *x0_tail], dtype=float)
    if x.size != plant.n_states or not np.all(np.isfinite(x)):
        raise ShapeError(f"{caller}: `x0` must be {plant.n_states - len(x0_tail)} finite numbers "
                         f"({', '.join(plant.states[:plant.n_states - len(x0_tail)])})")
    U = _signals(plant, inputs, t)
    # every output at every step; a generator per output and per state: the noise of a step does not depend on N
    schedule = SampleSchedule.on_map(t, Ts, plant.outputs, plant.states, noise=noise, process_noise=process_noise,
                                     seed=seed)
    V = schedule.measurement_noise()
    V = np.zeros((N + 1, plant.n_outputs)) if V is None else V
    W = schedule.process_increments()
    W = np.zeros((N, plant.n_states)) if W is None else W
    f, h = compile_system(plant).bind()
    sx, st, su, sw = ca.SX.sym("x", plant.n_states), ca.SX.sym("t"), ca.SX.sym("u", plant.n_inputs), ca.SX.sym("w", plant.n_states)
    F = ca.Function("plant_map", [sx, st, su, sw], [f(st, sx, su) + sw])
    X = np.vstack([x, np.asarray(F.mapaccum(N)(x, t[None, :-1], U[:-1].T, W.T), dtype=float).T])
    info = {"dt": Ts, "sampling": Ts, "time": "discrete", "sample_time": Ts, "engine": "vm", "seed": seed,
            "noisy": noise is not None or process_noise is not None}
    k = _first_escape(X, escape_bound)
    if k is not None:
        err = FiniteEscapeError("plant", float(t[k - 1]), X[k - 1], plant.states, escape_bound,
                                message=f"the plant {plant.name!r} left the bound {escape_bound:g} at step {k} (t = {t[k]:g}): "
                                        f"x[{k}] = {X[k].tolist()} from x[{k - 1}] = {X[k - 1].tolist()}")
        err.partial = Run(plant.name, t[:k], plant.states, plant.inputs, plant.outputs, U[:k], np.zeros((k, plant.n_outputs)),
                          {}, x=X[:k], info=info, estimated_params=plant.estimated_params)
        raise err
    Y_true = np.asarray(h.map(N + 1)(t[None, :], X.T, U.T), dtype=float).T.reshape(N + 1, plant.n_outputs)
    Y = Y_true + V
    traces, failures, extra = observers_on(obs, t, U, Y, schedule.measured().astype(float), xhat0, innovations=False)
    if extra:
        info["particles"] = extra
    return Run(plant.name, t, plant.states, plant.inputs, plant.outputs, U, Y, traces, x=X, y_true=Y_true,
               info={**info, "units": dict(getattr(plant, "units", None) or {})}, estimated_params=plant.estimated_params,
               failures=failures)


def map_trace(name: str, o: AbstractObserver, t: np.ndarray, U: np.ndarray, Y: np.ndarray, mask: np.ndarray, z0: np.ndarray,
              *, innovations: bool = True) -> tuple[ObserverTrace, dict[str, Any]]:
    """One observer of a map over its samples (Y with 0 where `mask` is 0): its trace (with the innovations
    y[k] − ŷ[k|k−1] when `innovations`) and, for a particle filter, its ESS and resampling counts."""
    if isinstance(o, ParticleObserver):   # its compiled particle loop over the samples
        pr, yp = o.trace_on(t, Y, U, mask=mask, xhat0=z0, name=name)
        inn = np.where(mask > 0, Y - yp, np.nan) if innovations else None
        trace = ObserverTrace(name, o.design.method, o.design.z_names, pr.z, pr.xhat, pr.xhat_prior[0],
                              covariance=o.design.covariance, innovation=inn)
        return trace, {"particles": o.design.particles, "samples": int(t.size), "min_ess": float(pr.ess.min()),
                       "resampled": int(pr.resampled.sum())}
    Z, Xh = run_map_observer(o.design, t, U, Y, mask, z0, name=name)
    prior = o.estimate(t[0], z0, U[0], Y[0])
    inn = _map_innovations(o.system, t, U, Y, mask, Xh, prior) if innovations else None
    return ObserverTrace(name, o.design.method, o.design.z_names, Z, Xh, prior, covariance=o.design.covariance,
                         innovation=inn), {}


def observers_on(obs: Mapping[str, AbstractObserver], t: np.ndarray, U: np.ndarray, Y: np.ndarray, mask: np.ndarray,
                 xhat0: Any, *, innovations: bool) -> tuple[dict[str, ObserverTrace], dict[str, Any], dict[str, Any]]:
    """Every observer on its own (:func:`each_observer`): the traces, the failures (an observer's blow-up or solver
    failure is its own; anything else is raised; when all fail, the first error) and the particle filters' counts.
    Particle filters and NLP estimators run one after another (their compiled loop and solver keep process-wide
    state), the others side by side."""
    z0s = {name: o.initial_state(_xhat0_for(xhat0, name, o.system.n_states)) for name, o in obs.items()}
    alone = [k for k, o in obs.items() if isinstance(o, ParticleObserver) or o.design.needs_mx]
    done = each_observer(list(obs), lambda name: map_trace(name, obs[name], t, U, Y, mask, z0s[name],
                                                           innovations=innovations), alone=alone)
    traces, failures, extra = {}, {}, {}
    for name, o in obs.items():
        res = done[name]
        if isinstance(res, BaseException):   # one observer's failure: the others keep their results
            if not observer_fault(res):
                raise res
            failures[name] = failure_of(name, o.design.method, res)
            continue
        traces[name], more = res
        if more:
            extra[name] = more
    if failures and not traces:
        raise done[next(iter(failures))]   # type: ignore[misc]
    return traces, failures, extra


def _map_innovations(system: System, t: np.ndarray, u: np.ndarray, y: np.ndarray, mask: np.ndarray, X: np.ndarray,
                     prior: np.ndarray) -> np.ndarray:
    """y[k] − h(x̂[k|k−1]) of a map's filter: the prediction f(x̂[k−1|k−1], u[k−1]) from its previous estimate (the
    prior x̂0 at k = 0); NaN where an output was not measured."""
    f, h = compile_system(system).bind()
    N = t.size
    pred = np.empty_like(X)
    pred[0] = prior
    if N > 1:
        pred[1:] = np.asarray(f.map(N - 1)(t[None, :-1], X[:-1].T, u[:-1].T), dtype=float).T
    yp = np.asarray(h.map(N)(t[None, :], pred.T, u.T), dtype=float).T.reshape(N, -1)
    return np.where(mask > 0, y - yp, np.nan)
