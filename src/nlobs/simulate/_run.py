"""simulate(): a plant and any number of observers on the same measured signals.

The plant and every observer are integrated together as one ODE with fixed-step RK4,
compiled through CasADi (see :mod:`nlobs.engine`). Two measurement modes:

- continuous (no ``sampling``): observers see y(t) = h(x(t), u(t), t) + n_k at every RK4
  stage, with the noise sample n_k held over step k; continuous-discrete observers update at
  every step;
- sampled (``sampling=Sampling(period)``): y_k = h(x(t_k)) + n_k is taken every `period`
  seconds and held (zero-order hold); continuous-discrete observers update at the samples.
"""

from __future__ import annotations

import functools

import numbers
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import casadi as ca
import numpy as np

from .._progress import as_progress
from ..design import ObserverDesign
from ..design.kalman._pf import ParticleDesign
from ..engine import Backend, StepRunner, compile_system, evaluate_many, rk4_step, rows
from ..errors import EngineError, FiniteEscapeError, ModelError, ShapeError
from ..model import ModelFile, ObserverConfig, System, input_signals
from ..observer import AbstractObserver, Observer, ParticleObserver, as_observer
from ..observer._signals import delays_of
from ._file import file_arguments, observers_of
from ._options import Adaptive, Noise, ProcessNoise, Sampling
from ._options import xhat0_for as _xhat0_for
from ._isolate import culprits, each_observer, isolate, merged, observer_fault
from ._results import ObserverTrace, Run
from ._schedule import SampleSchedule
from ._tables import table_range_notes

__all__ = ["simulate", "Simulation", "prepare", "Prepared", "named_observers", "check_compatible", "stage_inputs",
           "augmented_plant"]


def named_observers(observers: Any) -> dict[str, AbstractObserver]:
    """Observers by name, from a mapping, a sequence, or a single observer/design/model-file
    configuration (a ModelFile stands for all its configured observers)."""
    observers = observers_of(observers)
    if observers is None:
        return {}
    if isinstance(observers, Mapping):
        return {str(k): as_observer(v, str(k)) for k, v in observers.items()}
    if isinstance(observers, (ObserverDesign, ParticleDesign, AbstractObserver, ObserverConfig)):
        observers = [observers]
    out: dict[str, AbstractObserver] = {}
    for obj in observers:
        obs = as_observer(obj)
        base = obs.name if isinstance(obs, Observer) else obs.design.method
        name, i = base, 2
        while name in out:
            name, i = f"{base}_{i}", i + 1
        out[name] = obs
    return out


def check_compatible(plant: System, name: str, obs: AbstractObserver) -> None:
    """An observer must consume the plant's inputs and outputs and estimate its states."""
    s = obs.system
    if s.time != plant.time:
        raise ModelError(f"observer {name!r} was designed for a {s.time}-time model, but the plant {plant.name!r} is "
                         f"{plant.time}-time; design it on the plant's model")
    for what, mine, theirs in (("inputs", s.inputs, plant.inputs), ("outputs", s.outputs, plant.outputs),
                               ("states", s.states, plant.states)):
        if tuple(mine) != tuple(theirs):
            raise ModelError(f"observer {name!r} was designed for {what} {list(mine)}, but the plant {plant.name!r} has "
                             f"{list(theirs)}; design it on a model with the same {what}")


def stage_inputs(plant: System, inputs: Any, params: Mapping[str, float], t: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Inputs at the RK4 stages of each step: shape (N, 3·nu), blocks [u(t_k), u(t_k + dt/2), u(t_k + dt)].

    Held (piecewise-constant) signals use their left limit at t_k + dt, so a switch exactly
    on the grid takes effect in the next step; a switch within 1e-9 dt of a grid time counts as on it (a
    recorded input's 0.175 and the grid's 35 × 0.005 = 0.17500000000000002 are the same instant).
    """
    signals = input_signals(plant, inputs, params, grid=t)
    N, nu = t.size, plant.n_inputs
    out = np.empty((N, 3 * nu))
    # the end of step k is the next grid time: t_k + dt can exceed t_{k+1} by an ulp (0.059 + 0.001 > 0.06), and a
    # held signal switching at t_{k+1} would then leak its new value into the last stage of step k
    t_end = t + dt
    t_end[:-1] = np.where(np.abs(t_end[:-1] - t[1:]) <= 4 * np.spacing(np.abs(t[1:])), t[1:], t_end[:-1])
    snap = 1e-9 * np.asarray(dt, dtype=float)
    for j, sig in enumerate(signals):
        start, end = (t + snap, t_end - snap) if sig.held else (t, t_end)
        for k, times in enumerate((start, t + dt / 2, end)):
            v = sig(times)
            bad = np.flatnonzero(~np.isfinite(v))
            if bad.size:
                raise ShapeError(f"input `{plant.inputs[j]}` is {v[bad[0]]} at t = {times[bad[0]]:g}; inputs must be finite")
            out[:, k * nu + j] = v
    return out


def simulate(
    plant: System | ModelFile,
    observers: Any = None,
    *,
    t_final: float | None = None,
    dt: float | None = None,
    x0: Sequence[float] | None = None,
    inputs: Any = None,
    params: Mapping[str, float] | None = None,
    noise: Noise | None = None,
    process_noise: ProcessNoise | None = None,
    sampling: Sampling | None = None,
    seed: int | None = None,
    xhat0: Mapping[str, Sequence[float]] | Sequence[float] | None = None,
    engine: Backend = "auto",
    progress: bool | Callable[[float], None] | None = None,
    escape_bound: float = 1e12,
    integrator: Adaptive | None = None,
    delay: Mapping[str, float] | None = None,
) -> Run:
    """Simulate a plant and observers on the same measurements, with fixed-step RK4 (or CVODES).

    Parameters
    ----------
    plant : System or ModelFile
        The true system; or a model file (:func:`nlobs.load_model`): its plant with
        ``[simulation] true_parameters``, its observers (unless `observers` is given, which may
        then also be a list of their names) and its ``[simulation]`` defaults for every argument
        not given here.
    observers : mapping of name to observer/design, or a sequence, optional
        Observers (or designs, made runnable with :class:`nlobs.Observer`, or a model file's
        ``ObserverConfig`` objects, designed on the way). Observers that estimate some of the
        plant's parameters (designed on ``plant.augmented(names)``) get the augmented plant:
        its true parameter values are appended to `x0`, and the run reports the estimates.
    t_final, dt : float
        Horizon [0, t_final] and step; t_final must be a whole multiple of dt (required unless
        a model file gives them).
    x0 : sequence of float
        Initial plant state (required unless a model file gives it).
    inputs : mapping of input name to signal, optional
        Numbers, expressions of ``t`` (``"0.5*sin(t)"``), callables ``u(t)``, or
        :mod:`nlobs.model` signals. Inputs not given are zero.

    Other Parameters
    ----------------
    params : mapping, optional
        Plant parameter overrides (the observers keep the model they were designed on).
    noise : Noise, optional
        Measurement noise on each output sample.
    process_noise : ProcessNoise, optional
        Additive noise on the plant state.
    sampling : Sampling, optional
        Sampled measurements with zero-order hold; default: continuous measurements.
    seed : int, optional
        Seed for all random draws (measurement noise first, then process noise).
    xhat0 : mapping of observer name to vector, or one vector for all, optional
        Initial estimates (default: each design's).
    engine : {"auto", "vm", "c"}
        ``"c"`` generates and compiles C (cached on disk); ``"vm"`` runs on CasADi's virtual
        machine; ``"auto"`` compiles long runs when a compiler exists.
    progress : bool or callable, optional
        Show progress on stderr (True) or call ``progress(fraction)``.
    escape_bound : float
        A state larger than this in magnitude counts as a blow-up.
    integrator : Adaptive, optional
        Integrate each step adaptively with CVODES instead of one RK4 step (see
        :class:`nlobs.Adaptive`); measurements, noise and sample-time updates are unchanged.
    delay : mapping of output name to seconds, optional
        Known measurement delays: a sample of the output taken at t reaches the observers at t + delay. Needs
        sampled measurements; the continuous-discrete observers re-apply a late sample at the time it was taken
        (filter recalculation from a state history, :mod:`nlobs.simulate._delays`).

    Returns
    -------
    Run

    Raises
    ------
    FiniteEscapeError
        When the plant or an observer blows up; it carries the time and state where it
        happened and the partial result as ``partial``.
    ModelError, ShapeError
        For inconsistent arguments (wrong sizes, unknown names, incompatible observers).
    """
    if isinstance(plant, ModelFile):
        run = simulate(**file_arguments(plant, observers, t_final=t_final, dt=dt, x0=x0, inputs=inputs, params=params,
                                         noise=noise, process_noise=process_noise, sampling=sampling, seed=seed,
                                         xhat0=xhat0, engine=engine, progress=progress, escape_bound=escape_bound,
                                         integrator=integrator, delay=delay))
        return replace(run, info={**run.info, "units": dict(plant.units)})  # the file's [units] label the plots
    if isinstance(plant, System) and plant.is_discrete:   # a map: iterated, never integrated
        if integrator is not None:
            raise ModelError(f"simulate: {plant.name!r} is a discrete-time model; `integrator` does not apply")
        from ._discrete import simulate_map

        plant_ = plant.with_params(**params) if params else plant
        obs = named_observers(observers)
        plant_, tail = augmented_plant(plant_, obs)
        for name, o in obs.items():
            check_compatible(plant_, name, o)
        return simulate_map(plant_, obs, t_final=t_final, dt=dt, x0=x0, inputs=inputs, noise=noise,
                            process_noise=process_noise, sampling=sampling, seed=seed, xhat0=xhat0,
                            escape_bound=escape_bound, x0_tail=tail)
    if delay and any(float(v) > 0 for v in delay.values()):
        return _simulate_delayed(plant, observers, delay, t_final=t_final, dt=dt, x0=x0, inputs=inputs, params=params,
                                 noise=noise, process_noise=process_noise, sampling=sampling, seed=seed, xhat0=xhat0,
                                 engine=engine, progress=progress, escape_bound=escape_bound, integrator=integrator)
    sim = Simulation(plant, observers, t_final=t_final, dt=dt, inputs=inputs, params=params, noise=noise,
                     process_noise=process_noise, sampling=sampling, integrator=integrator, engine=engine, _caller="simulate")
    return _noted(sim, sim.run(x0, xhat0=xhat0, seed=seed, progress=progress, escape_bound=escape_bound))


def _noted(sim: Simulation, run: Run) -> Run:
    """The run with a note for each table its plant read outside the table's range."""
    notes = table_range_notes(sim.plant, run.t, run.x, run.u)
    return replace(run, info={**run.info, "notes": (*run.info.get("notes", ()), *notes)}) if notes else run


def _simulate_delayed(plant: System, observers: Any, delay: Mapping[str, float], *, sampling: Sampling | None,
                      x0: Any, xhat0: Any, params: Mapping[str, float] | None, **kw: Any) -> Run:
    """The plant on its own, then each observer on the samples as they arrive (see :mod:`nlobs.simulate._delays`):
    one compiled re-processing per observer, planned once for all of them; an observer that fails is reported with
    its reason and the others keep their results."""
    from ._delays import latency_notes, plan
    from ._isolate import run_all_delayed

    if not isinstance(plant, System) or plant.is_discrete:
        raise ModelError("simulate: measurement delays are handled for continuous-time models")
    if sampling is None:
        raise ModelError("simulate: measurement delays need sampled measurements (a sample is taken, then arrives later): "
                         "give sampling=Sampling(period) or [simulation] sample_period")
    obs = named_observers(observers)
    d = delays_of(delay, list(plant.outputs), "simulate")
    plant_ = plant.with_params(**params) if params else plant
    plant_, tail = augmented_plant(plant_, obs)
    x0v = list(np.asarray(x0, dtype=float).reshape(-1))
    if tail and len(x0v) == plant_.n_states - len(tail):
        x0v += list(tail)
    for name, o in obs.items():
        check_compatible(plant_, name, o)
    run_kw = {k: kw.pop(k) for k in ("seed", "progress", "escape_bound")}
    sim = Simulation(plant_, None, sampling=sampling, **kw, _caller="simulate")
    base = _noted(sim, sim.run(x0v, **run_kw))
    # the plant's run has the schedule of every sample; with the delays it says when each one arrives
    schedule = replace(sim._prep.schedule, delays=d)
    measured = schedule.measured()
    events = schedule.events(base.y)
    the_plan = plan(base.t, base.u, events, plant_.n_outputs) if obs else None
    z0s = {name: o.initial_state(_xhat0_for(xhat0, name, plant_.n_states)) for name, o in obs.items()}
    traces, failures = run_all_delayed(obs, base.t, base.u, base.y[0], events, z0s, the_plan=the_plan,
                                       engine=kw.get("engine", "auto"),
                                       knot_rows=schedule.sample_rows())   # where a pf steps (as without delays)
    notes = (*base.info.get("notes", ()), *latency_notes(events, float(base.t[-1]), list(plant_.outputs), schedule.delays))
    info = {**base.info, "delay": {k: float(v) for k, v in delay.items()}, "measured": measured, "notes": notes,
            "replayed": the_plan.replayed if the_plan is not None else 0}
    return replace(base, observers=traces, failures=failures, info=info)


class Simulation:
    """A simulation set-up prepared once and run many times (initial states, estimates, noise seeds).

    Validates the arguments, evaluates the input signals on the time grid and builds the joint
    plant + observer step once (its C code compiled when worth it and cached on disk); each
    :meth:`run` then only draws the noise of its seed and runs. ``simulate(...)`` is
    ``Simulation(...).run(...)``.

    Parameters
    ----------
    plant, observers, t_final, dt, inputs, params, noise, process_noise, sampling, integrator, engine :
        As in :func:`nlobs.simulate`.

    Examples
    --------
    >>> sim = Simulation(plant, {"ekf": ekf}, t_final=20, dt=1e-3, noise=Noise.gaussian(0.1))  # doctest: +SKIP
    >>> runs = [sim.run([2.0, 0.0], seed=s) for s in range(100)]                                # doctest: +SKIP
    """

    def __init__(self, plant: System, observers: Any = None, *, t_final: float, dt: float, inputs: Any = None,
                 params: Mapping[str, float] | None = None, noise: Noise | None = None,
                 process_noise: ProcessNoise | None = None, sampling: Sampling | None = None,
                 integrator: Adaptive | None = None, engine: Backend = "auto", _caller: str = "Simulation"):
        setup = dict(t_final=t_final, dt=dt, inputs=inputs, params=params, noise=noise, process_noise=process_noise,
                     sampling=sampling, integrator=integrator, engine=engine, _caller=_caller)
        obs = named_observers(observers) if isinstance(plant, System) else observers
        # several observers: each runs with its own copy of the plant, as its own compiled step (fixed-step RK4 gives
        # every copy the same trajectory and measurements: the noise depends only on the seed). So a step is compiled
        # per observer and cached (another combination, an isolation or the advisor reuses it), the steps compile
        # and run side by side on the cores, and one observer's failure is its own. (An adaptive integrator chooses
        # its steps for the whole state: there the plant and the observers stay one step.)
        self._parts: dict[str, Simulation] = {}
        if integrator is None and isinstance(obs, Mapping) and len(obs) > 1:
            self._parts = {name: Simulation(plant, {name: o}, **setup) for name, o in obs.items()}
            self._prep = next(iter(self._parts.values()))._prep
        else:
            self._prep = prepare(plant, obs, t_final=t_final, dt=dt, inputs=inputs, params=params, noise=noise,
                                 process_noise=process_noise, sampling=sampling, caller=_caller, integrator=integrator)
        # to run an observer on its own when another one fails (see :meth:`run`)
        self._setup = (plant, setup)
        self._alone: dict[str, Simulation] = {}
        self.engine = engine
        self._info = {"dt": dt, "sampling": None if sampling is None else sampling.period, "engine": engine,
                      "noisy": self._prep.seeded,
                      "integrator": "rk4" if integrator is None else
                      f"cvodes ({integrator.method}, rtol={integrator.rtol:g}, atol={integrator.atol:g})"}
        self._c = self._prep.constants()
        self._prep.t.setflags(write=False)  # shared by the runs' results
        self._A_clean = None if self._prep.seeded else self._prep.inputs_for(None)
        if self._A_clean is not None:
            self._A_clean.setflags(write=False)  # shared by the runs (their `u` are read-only views of it)

    @property
    def plant(self) -> System:
        return self._prep.plant

    @property
    def t(self) -> np.ndarray:
        """The time grid (a copy)."""
        return self._prep.t.copy()

    def run(self, x0: Sequence[float], *, xhat0: Mapping[str, Sequence[float]] | Sequence[float] | None = None,
            seed: int | None = None, progress: bool | Callable[[float], None] | None = None,
            escape_bound: float = 1e12) -> Run:
        """One run from the plant state `x0` (see :func:`nlobs.simulate` for the arguments and errors).

        An observer that fails (blows up, or its window problem cannot be solved) does not stop the others:
        each observer then runs on its own on the same measurements, and the failing ones are listed in
        :attr:`Run.failures` with what happened and when. A plant that blows up still raises."""
        if self._parts:
            return self._run_parts(x0, xhat0=xhat0, seed=seed, progress=progress, escape_bound=escape_bound)
        names = (*self._prep.obs, *self._prep.particle)
        methods = {k: o.design.method for k, o in {**self._prep.obs, **self._prep.particle}.items()}

        def run_with(only: tuple[str, ...] | None) -> Run:
            if only is None:
                return self._run_all(x0, xhat0=xhat0, seed=seed, progress=progress, escape_bound=escape_bound)
            return self._run_alone(only, x0, xhat0=xhat0, seed=seed, escape_bound=escape_bound)

        return isolate(run_with, names, methods)

    def _run_parts(self, x0: Sequence[float], *, xhat0: Any, seed: int | None,
                   progress: bool | Callable[[float], None] | None, escape_bound: float) -> Run:
        """Each observer with its own copy of the plant, side by side (see ``__init__``); one Run of them all."""
        names = list(self._parts)
        report = as_progress(progress, f"simulate {self.plant.name}")
        reached = dict.fromkeys(names, 0.0)

        def one(name: str) -> Run:
            part = self._parts[name]
            mine = xhat0 if not isinstance(xhat0, Mapping) else ({name: xhat0[name]} if name in xhat0 else None)

            def moved(fraction: float) -> None:
                reached[name] = fraction
                report(sum(reached.values()) / len(reached))   # type: ignore[misc]
            return part._run_all(x0, xhat0=mine, seed=seed, progress=moved if report is not None else None,
                                 escape_bound=escape_bound)

        heavy = [k for k, p in self._parts.items() if any(o.design.needs_mx for o in p._prep.obs.values())]
        done = each_observer(names, one, alone=heavy)
        methods = {name: next(iter({**p._prep.obs, **p._prep.particle}.values())).design.method
                   for name, p in self._parts.items()}
        # the plant's failure, or a wrong argument, is everyone's; a compile error of this part's step is its observer's
        # (the plant's own code is in every part: were it at fault, every part would fail)
        return merged(names, done, methods, fault=lambda e: observer_fault(e) or isinstance(e, EngineError))

    def _run_alone(self, only: tuple[str, ...], x0: Sequence[float], *, xhat0: Any, seed: int | None,
                   escape_bound: float) -> Run:
        """The plant with the observers `only`, on the measurements of the same seed."""
        prep, (plant, kw) = self._prep, self._setup
        key = ",".join(only)
        if key not in self._alone:
            obs = {k: o for k, o in {**prep.obs, **prep.particle}.items() if k in only}
            self._alone[key] = Simulation(plant, obs, **kw)
        mine = xhat0
        if isinstance(xhat0, Mapping):
            mine = {k: v for k, v in xhat0.items() if k in only} or None
        return self._alone[key]._run_all(x0, xhat0=mine, seed=seed, progress=None, escape_bound=escape_bound)

    def _run_all(self, x0: Sequence[float], *, xhat0: Any, seed: int | None,
                 progress: bool | Callable[[float], None] | None, escape_bound: float) -> Run:
        prep = self._prep
        plant, obs, layout, N, t = prep.plant, prep.obs, prep.layout, prep.n_steps, prep.t
        s0 = prep.initial_state(x0, xhat0)
        A = self._A_clean if self._A_clean is not None else prep.inputs_for(seed)
        c = self._c
        report = as_progress(progress, f"simulate {plant.name}")
        info = dict(self._info, seed=seed)
        if prep.kind.multirate:   # which outputs were sampled at each time (the others are held, NaN in a CSV)
            info["measured"] = prep.schedule.measured()
        runner = layout.runner(self.engine)
        # one step beyond t_final: its per-step outputs are the measurements and estimates at t_final (row N of O), and
        # its state (row N + 1 of S) is dropped; one RK4 step instead of a separate evaluation of the outputs
        S = np.empty((N + 2, layout.size))
        O = np.empty((N + 1, layout.no))
        S[0] = s0
        _, _, done = runner.run(s0, A, c, out=S[1:], obuf=O, bound=escape_bound,
                                on_chunk=None if report is None else (lambda states, k: report(min(k / N, 1.0))))
        if done < N:  # the state after step `done` (row done + 1) left the bound: report the last good one, row done
            r = done
            col = int(np.flatnonzero(~(np.abs(S[r + 1]) <= escape_bound))[0])
            where, sl, names = layout.owner(col)
            O[r] = runner.outputs(S[r:r + 1], A[r:r + 1], c)[0]
            err = _plant_output_failure(plant, S, A, c, layout, runner, r) if where != "plant" else None
            if err is None and where != "plant":
                err = _indefinite_failure(where, S[:r + 2, sl], names, t, escape_bound)
            if err is None:
                err = FiniteEscapeError(where, float(t[r]), S[r, sl], names, escape_bound,
                                        culprits=culprits(names, S[r + 1, sl], escape_bound))
            err.partial = _assemble(plant, obs, layout, S[:r + 1], O[:r + 1], t[:r + 1], A[:r + 1], info)
            raise err
        S = S[:N + 1]
        run = _assemble(plant, obs, layout, S, O, t, A, info)
        return _with_particles(run, prep, xhat0) if prep.particle else run


def _indefinite_failure(where: str, Z: np.ndarray, names: Sequence[str], t: np.ndarray,
                        bound: float) -> FiniteEscapeError | None:
    """When a filter's variance (an internal state named P_i_i) went negative before its state left the bound (rows
    Z[0..r+1], the last one the first out of bound), the filter had diverged there: its state at that step is no
    "last finite state" to show. The error then names the first step with a negative variance and shows the state
    before it (RK4 at a fixed step unstable for a stiff covariance equation: every variance positive, then negative)."""
    import re

    diag = [j for j, nm in enumerate(names) if re.fullmatch(r"P_(\d+)_\1", str(nm))]
    if not diag:
        return None
    neg = np.flatnonzero((Z[:-1, diag] < 0).any(axis=1))
    if not neg.size or neg[0] == 0:
        return None
    k = int(neg[0])
    j = diag[int(np.flatnonzero(Z[k, diag] < 0)[0])]
    dt = float(t[1] - t[0]) if t.size > 1 else float("nan")
    err = FiniteEscapeError(where, float(t[k - 1]), Z[k - 1], names, bound, culprits=[(names[j], float(Z[k, j]))])
    went = (f"{where} diverged after t = {t[k - 1]:.6g}: its covariance lost its positive definiteness in the next step "
            f"({names[j]} = {Z[k, j]:.3g} < 0), and its state left |x| <= {bound:g} at t = {t[Z.shape[0] - 1]:.6g}")
    shown = str(err).split("last finite state: ", 1)[1].split(". Check", 1)[0]
    return FiniteEscapeError(where, float(t[k - 1]), Z[k - 1], names, bound, culprits=[(names[j], float(Z[k, j]))],
                             message=f"{went}; last state with a positive covariance: {shown}. A fixed RK4 step of "
                                     f"dt = {dt:g} may be too long for a stiff flow (h·rate above 2.8: unstable): "
                                     "reduce `dt`, or check the observer's tuning and its initial estimate.")


def _plant_output_failure(plant: System, S: np.ndarray, A: np.ndarray, c: np.ndarray, layout: _Layout, runner: _Runner,
                          r: int) -> FiniteEscapeError | None:
    """When an observer's state became non-finite in step r, but what it was fed — the plant's output at
    the start or the end of the step — was already non-finite, the error belongs to the plant's output map."""
    n = layout.n
    for row in (r, r + 1):
        if row >= A.shape[0] or not np.all(np.isfinite(S[row, :n])):
            continue
        probe = S[row:row + 1].copy()
        probe[:, n:] = np.where(np.isfinite(probe[:, n:]), probe[:, n:], 0.0)  # the outputs do not depend on the observers
        y = runner.outputs(probe, A[row:row + 1], c)[0, layout.y_true]
        bad = np.flatnonzero(~np.isfinite(y))
        if bad.size:
            j = int(bad[0])
            x = ", ".join(f"{s}={v:.6g}" for s, v in zip(plant.states, S[row, :n]))
            expr = str(plant.h[j]) if len(str(plant.h[j])) <= 80 else str(plant.h[j])[:68] + " ..."
            return FiniteEscapeError(
                "the plant's output", float(A[row, 0]), S[row, :n], plant.states, np.inf,
                message=(f"the plant's output {plant.outputs[j]} = {expr} is {y[j]} at t = {A[row, 0]:.6g} (plant state "
                         f"{x}): the output map is not defined there (e.g. sqrt or log of a negative number, division by zero), "
                         "and the observers cannot use it. Check the output equations, the initial state or the inputs"))
    return None


@dataclass(frozen=True, eq=False)
class Prepared:
    """A validated run set-up: plant, observers, the compiled joint step, the time grid and the
    per-step inputs that do not depend on the noise seed. Shared by simulate and montecarlo."""

    plant: System
    obs: Mapping[str, AbstractObserver]
    kind: _Kind
    layout: _Layout
    n_steps: int
    dt: float
    t: np.ndarray
    base: np.ndarray  # per-step inputs before noise: [t, u stages], shape (N + 1, 1 + 3 nu)
    #: what is sampled when and the noise, on the grid `t` (its seed set per run: :meth:`inputs_for`)
    schedule: SampleSchedule
    caller: str
    x0_tail: tuple[float, ...] = ()  # true values of the estimated parameters, appended to a model-state x0
    #: particle filters: run on the sampled measurements after the plant (not in the joint step)
    particle: Mapping[str, ParticleObserver] = field(default_factory=dict)

    def initial_state(self, x0: Sequence[float], xhat0: Any) -> np.ndarray:
        n, ny = self.plant.n_states, self.plant.n_outputs
        x0v = np.asarray(x0, dtype=float).reshape(-1)
        if self.x0_tail and x0v.size == n - len(self.x0_tail):
            x0v = np.concatenate([x0v, self.x0_tail])
        if x0v.size != n or not np.all(np.isfinite(x0v)):
            raise ShapeError(f"{self.caller}: `x0` must be {n} finite numbers (one per state: {', '.join(self.plant.states)}), "
                             f"got {list(x0v)}")
        z0s = [o.initial_state(_xhat0_for(xhat0, name, n)) for name, o in self.obs.items()]
        return np.concatenate([x0v, *z0s, np.zeros(ny if self.kind.sampled else 0)])

    def constants(self, params: Sequence[float] | None = None) -> np.ndarray:
        """The run-time constants of the compiled step: dt, dt/2, dt/6 (no division per step) and the
        plant parameters (none when they are folded into the step as constants)."""
        head = [self.dt, self.dt / 2, self.dt / 6]
        if self.kind.folded is not None:
            return np.array(head)
        return np.concatenate([head, self.plant.param_values if params is None else np.asarray(params, dtype=float)])

    def inputs_for(self, seed: int | None) -> np.ndarray:
        """The per-step inputs with the noise of `seed`, as the schedule draws it (a generator per output and per state:
        the noise of a step does not depend on the horizon), and its sample flags."""
        sched = self.schedule.with_seed(seed)
        columns = [self.base]
        V, W = sched.measurement_noise(), sched.process_increments()
        if V is not None:
            columns.append(V)
        if W is not None:
            columns.append(np.vstack([W, np.zeros((1, self.plant.n_states))]))
        if self.kind.sampled:
            columns.append(sched.flags())
        return columns[0] if len(columns) == 1 else np.hstack(columns)

    @property
    def noise(self) -> Noise | None:
        return self.schedule.noise

    @property
    def process_noise(self) -> ProcessNoise | None:
        return self.schedule.process_noise

    @property
    def seeded(self) -> bool:
        """Whether the per-step inputs depend on the seed (noise of any kind)."""
        return self.noise is not None or self.process_noise is not None


#: Most RK4 steps one run stores (t_final / dt); beyond it the trajectories alone need tens of GB.
MAX_STEPS = 1e8


def prepare(plant: System, observers: Any, *, t_final: float, dt: float, inputs: Any, params: Mapping[str, float] | None,
            noise: Noise | None, process_noise: ProcessNoise | None, sampling: Sampling | None, caller: str,
            integrator: Adaptive | None = None, fold_params: bool = False) -> Prepared:
    """Validate the arguments shared by simulate and montecarlo and build the compiled joint step.

    With `fold_params` the plant's parameter values are compiled into the step as constants
    (for runs that do not vary them); otherwise they are run-time inputs.
    """
    if not isinstance(plant, System):
        raise TypeError(f"{caller}: `plant` must be an nlobs.System, got {type(plant).__name__}")
    if plant.is_discrete:
        raise ModelError(f"{caller}: {plant.name!r} is a discrete-time model; this runner integrates ODEs (nlobs.simulate "
                         "iterates maps)")
    for label, v in (("t_final", t_final), ("dt", dt)):  # Python and NumPy numbers (np.float32 too), not bool
        if not (isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_)) and np.isfinite(v) and v > 0):
            raise ShapeError(f"{caller}: `{label}` must be a positive number, got {v!r}")
    # a single-precision number (np.float32(0.1)) is only that precise: compare the grid at its precision
    rel = max([1e-9] + [4 * float(np.finfo(v.dtype).eps) for v in (t_final, dt) if isinstance(v, np.floating)])
    t_final, dt = float(t_final), float(dt)
    if t_final / dt > MAX_STEPS:
        raise ShapeError(f"{caller}: t_final / dt = {t_final:g} / {dt:g} = {t_final / dt:.3g} steps, more than {MAX_STEPS:.0e} "
                         "(every step is stored): choose a larger dt or a shorter t_final")
    N = int(round(t_final / dt))
    if N < 1 or abs(N * dt - t_final) > rel * max(1.0, t_final):
        raise ShapeError(f"{caller}: t_final = {t_final:g} must be a whole multiple of dt = {dt:g}")
    plant = plant.with_params(**params) if params else plant
    obs = named_observers(observers)
    plant, x0_tail = augmented_plant(plant, obs)
    if obs and plant.n_outputs == 0:
        raise ModelError(f"{caller}: the plant {plant.name!r} has no outputs; an observer needs a measurement")
    for name, o in obs.items():
        check_compatible(plant, name, o)
    particle = {k: o for k, o in obs.items() if isinstance(o, ParticleObserver)}
    obs = {k: o for k, o in obs.items() if k not in particle}
    if integrator is not None and not isinstance(integrator, Adaptive):
        raise TypeError(f"{caller}: `integrator` must be an nlobs.Adaptive (or None for fixed-step RK4), got {integrator!r}")
    t = _grid(N, dt)
    schedule = SampleSchedule.on_grid(t, dt, plant.outputs, plant.states, sampling=sampling, noise=noise,
                                      process_noise=process_noise, caller=caller)
    multirate = schedule.multirate
    kind = _Kind(sampled=sampling is not None, noisy=noise is not None, process=process_noise is not None, adaptive=integrator,
                 folded=tuple(float(v) for v in plant.param_values) if fold_params else None, multirate=multirate)
    _, layout = _joint_step(plant, obs, kind)
    base = t[:, None]
    if plant.n_inputs:
        base = np.hstack([base, stage_inputs(plant, inputs, plant.params, t, np.full(N + 1, dt))])
    elif inputs:
        input_signals(plant, inputs)  # reports unknown input names
    return Prepared(plant, obs, kind, layout, N, float(dt), t, base, schedule, caller, x0_tail, particle)


@functools.lru_cache(maxsize=8)
def _cached_grid(N: int, dt: float) -> np.ndarray:
    t = np.arange(N + 1) * dt
    t.setflags(write=False)
    return t


def _grid(N: int, dt: float) -> np.ndarray:
    """The time grid k·dt, k = 0..N: read-only, and shared by runs on the same grid when it is small
    (up to 10⁶ steps, 8 MB) — a run's `t` is never written to (see :class:`Simulation`)."""
    if N > 10**6:
        return np.arange(N + 1) * dt
    return _cached_grid(N, dt)


def augmented_plant(plant: System, obs: Mapping[str, AbstractObserver]) -> tuple[System, tuple[float, ...]]:
    """The plant to simulate with observers that estimate some of its parameters (designed on
    ``plant.augmented(names)``): the plant augmented the same way, and the true values of those
    parameters (appended to an x0 of the model's states)."""
    est = next((o.system.estimated_params for o in obs.values() if o.system.estimated_params), ())
    if not est or plant.estimated_params or any(k not in plant.params for k in est):
        return plant, ()  # nothing to do, or check_compatible reports the mismatch
    return plant.augmented(est), tuple(plant.params[k] for k in est)


def _with_particles(run: Run, prep: Prepared, xhat0: Any) -> Run:
    """`run` with the traces of the particle filters, run on the measurements at the sample instants
    (every step without `sampling`); between samples their estimate is held."""
    measured = prep.schedule.measured()
    flags = measured.any(axis=1)
    held = np.cumsum(flags) - 1
    mask = measured[flags].astype(float)
    traces, info = dict(run.observers), dict(run.info)
    for name, o in prep.particle.items():
        pr, _ = o.trace_on(run.t[flags], run.y[flags], run.u[flags], mask=mask,
                           xhat0=_xhat0_for(xhat0, name, prep.plant.n_states), name=name)
        traces[name] = ObserverTrace(name, o.design.method, o.design.z_names, pr.z[held], pr.xhat[held], pr.xhat_prior[0],
                                     covariance=o.design.covariance)
        info.setdefault("particles", {})[name] = {"particles": o.design.particles, "samples": int(flags.sum()),
                                                  "min_ess": float(pr.ess.min()), "resampled": int(pr.resampled.sum())}
    return replace(run, observers=traces, info=info)


@dataclass(frozen=True)
class _Kind:
    """Which per-step inputs a run has (the compiled step is specialised to them)."""

    sampled: bool
    noisy: bool
    process: bool
    multirate: bool = False   # one sample clock per output (flags per output in the per-step inputs)
    adaptive: Adaptive | None = None
    folded: tuple[float, ...] | None = None  # plant parameter values compiled in as constants


class _Layout:
    """Where each subsystem lives in the joint state, the per-step inputs and the per-step outputs."""

    def __init__(self, plant: System, obs: Mapping[str, AbstractObserver], kind: _Kind):
        n, nu, ny = plant.n_states, plant.n_inputs, plant.n_outputs
        self.n = n
        self.slices: dict[str, slice] = {}
        self.names: dict[str, Sequence[str]] = {"plant": plant.states}
        off = n
        for name, o in obs.items():
            self.slices[name] = slice(off, off + o.n_z)
            self.names[name] = o.design.z_names
            off += o.n_z
        self.held = slice(off, off + (ny if kind.sampled else 0))
        self.size = self.held.stop
        # per-step inputs a = [t, u(t), u(t + dt/2), u(t + dt), noise, w, flag], only those present
        k = 1
        self.u = slice(k, k + 3 * nu); k += 3 * nu  # noqa: E702
        self.noise = slice(k, k + (ny if kind.noisy else 0)); k = self.noise.stop  # noqa: E702
        self.w = slice(k, k + (n if kind.process else 0)); k = self.w.stop  # noqa: E702
        nflag = (ny if kind.multirate else 1) if kind.sampled else 0
        self.flag = k if kind.sampled else None
        self.flags = slice(k, k + nflag)
        self.na = k + nflag
        # per-step outputs o = [y_true, y_measured, (z after the sample update, xhat) per observer];
        # the ones that are plain copies of the state are not written (None: read them from the state)
        self.y_true = slice(0, ny)
        k = ny
        self.y_meas: slice | None = None
        if kind.noisy or kind.sampled:
            self.y_meas, k = slice(k, k + ny), k + ny
        self.out: dict[str, tuple[slice | None, slice | None]] = {}
        for name, o in obs.items():
            zsl = xsl = None
            if o.design.update is not None:
                zsl, k = slice(k, k + o.n_z), k + o.n_z
            if not o.design.selects_state(n):
                xsl, k = slice(k, k + n), k + n
            self.out[name] = (zsl, xsl)
        self.no = k
        self.step: ca.Function | None = None
        self.step_c: ca.Function | None = None   # the step as C is generated from (see _build_step)
        self.step_outputs: ca.Function | None = None
        self.designs: tuple[ObserverDesign, ...] = ()  # keeps the cached designs (and their ids) alive
        self._runners: dict[str, StepRunner] = {}

    def runner(self, engine: Backend) -> _Runner:
        if engine not in self._runners:
            self._runners[engine] = StepRunner(self.step, backend=engine, step_c=self.step_c)
        return _Runner(self._runners[engine], self)

    def owner(self, col: int) -> tuple[str, slice, Sequence[str]]:
        if col < self.n:
            return "plant", slice(0, self.n), self.names["plant"]
        for name, sl in self.slices.items():
            if sl.start <= col < sl.stop:
                return f"observer {name!r}", sl, self.names[name]
        return "measurement hold", self.held, [f"y{i}" for i in range(self.held.stop - self.held.start)]


@dataclass(frozen=True)
class _Runner:
    engine: StepRunner
    layout: _Layout

    def run(self, s0: np.ndarray, A: np.ndarray, c: np.ndarray, **kw: Any) -> tuple[np.ndarray, np.ndarray]:
        return self.engine.run(s0, A, c, **kw)

    def outputs(self, S: np.ndarray, A: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Per-step outputs at given states (no step taken): for the final time and partial results."""
        return evaluate_many(self.layout.step_outputs, S, A, c)


_STEPS: OrderedDict[tuple[Any, ...], _Layout] = OrderedDict()


def _joint_step(plant: System, obs: Mapping[str, AbstractObserver], kind: _Kind) -> tuple[ca.Function, _Layout]:
    """The compiled joint step for this plant structure, these observer designs and this kind of run (cached)."""
    key = (plant.key, tuple((name, id(o.design)) for name, o in obs.items()), kind)
    hit = _STEPS.get(key)
    if hit is not None and all(hit_d is o.design for hit_d, o in zip(hit.designs, obs.values())):
        _STEPS.move_to_end(key)
        return hit.step, hit
    layout = _build_step(plant, obs, kind)
    layout.designs = tuple(o.design for o in obs.values())
    _STEPS[key] = layout
    if len(_STEPS) > 64:
        _STEPS.popitem(last=False)
    return layout.step, layout


#: Joint steps of at most this many SX instructions are compiled with their functions inlined: there a call costs more
#: than it saves (Van der Pol with an observer, 134 instructions: 3.8x the hand-written C loop with calls, 1.2x inlined).
#: Above it, C is generated from an MX step that calls f, h and each observer's flow at the RK4 stages (a 16-state INS
#: EKF, 36,530 instructions: 5 s less to compile, 1.5x slower to run).
INLINE_MAX = 15_000


def _build_step(plant: System, obs: Mapping[str, AbstractObserver], kind: _Kind, sym: Any = None,
                inline_flow: bool = False) -> _Layout:
    comp = compile_system(plant)
    n, ny = plant.n_states, plant.n_outputs
    layout = _Layout(plant, obs, kind)
    # designs whose functions are not SX (MHE embeds an NLP solver) need an MX graph (run on the VM)
    X = ca.MX if kind.adaptive is not None or any(o.design.needs_mx for o in obs.values()) else ca.SX
    if sym is None and X is ca.SX:
        layout = _build_step(plant, obs, kind, ca.SX, inline_flow=True)
        if layout.step.n_instructions() > INLINE_MAX:
            # the same step over MX, calling f, h and each observer's flow at the RK4 stages and its update (only at a
            # sample) instead of inlining them: the same operations in a fraction of the code to compile
            layout.step_c = _build_step(plant, obs, kind, ca.MX).step
        elif kind.sampled and any(o.design.update is not None for o in obs.values()):
            # the flow inlined as one call, each update called only at a sample (SX would compute it at every step)
            layout.step_c = _build_step(plant, obs, kind, ca.MX, inline_flow=True).step
        return layout
    X = sym or X
    s = X.sym("s", layout.size)
    a = X.sym("a", layout.na)
    c = X.sym("c", 3 + (0 if kind.folded is not None else plant.n_params))
    dt, half, sixth = c[0], c[1], c[2]
    p = ca.DM(kind.folded) if kind.folded is not None else rows(c, 3, 3 + plant.n_params)
    t = a[0]
    nu = plant.n_inputs
    U = [rows(a, layout.u.start + k * nu, layout.u.start + (k + 1) * nu) for k in range(3)]
    noise = rows(a, layout.noise.start, layout.noise.stop) if kind.noisy else ca.DM.zeros(ny)
    x = rows(s, 0, n)
    y_true = comp.h(t, x, U[0], p)
    y_now = y_true + noise
    mask = ca.DM.ones(ny)
    if kind.multirate:   # each output on its own clock: held between its samples; an update uses the ones sampled now
        F = rows(a, layout.flags.start, layout.flags.stop)
        held = rows(s, layout.held.start, layout.held.stop)
        y_s = ca.vertcat(*[ca.if_else(F[i], y_now[i], held[i]) for i in range(ny)])
        flag, mask = ca.mmax(F), F
    elif kind.sampled:
        flag = a[layout.flag]
        y_s = ca.if_else(flag, y_now, rows(s, layout.held.start, layout.held.stop))
    else:
        flag, y_s = 1, y_now
    zs, outs = {}, [y_true] + ([y_s] if layout.y_meas is not None else [])
    for name, o in obs.items():
        sl = layout.slices[name]
        z = rows(s, sl.start, sl.stop)
        d = o.design
        if d.update is not None:
            jumped = d.update(t, z, U[0], y_s, mask)
            z = ca.if_else(flag, jumped, z, X is ca.MX) if kind.sampled else jumped  # MX: solve only when sampled
            outs.append(z)
        zs[name] = z
        if layout.out[name][1] is not None:
            outs.append(d.output(t, z, U[0], y_s))

    joint = ca.vertcat(x, *zs.values())
    y_flow = y_s if kind.sampled else noise   # what the observers' flows see: the held sample, or h + noise
    if kind.adaptive is None and inline_flow:
        S_next = _flow_function(plant, obs, kind)(t, joint, *U, y_flow, dt, half, sixth, p if kind.folded is None else X(0, 1))
    elif kind.adaptive is None:
        S_next = rk4_step(_joint_rhs(plant, obs, kind, U, p, y_flow), t, joint, dt, half=half, sixth=sixth)
    else:
        S_next = _adaptive_flow(plant, obs, layout, kind)(joint, a, c, y_s if kind.sampled else ca.DM.zeros(ny))
    x_next = rows(S_next, 0, n) + (rows(a, layout.w.start, layout.w.stop) if kind.process else 0)
    s_next = ca.vertcat(x_next, rows(S_next, n, joint.shape[0]), y_s if kind.sampled else X(0, 1))
    o = ca.vertcat(*outs)
    layout.step = ca.Function("joint_step", [s, a, c], [s_next, o])
    layout.step_outputs = ca.Function("joint_outputs", [s, a, c], [o])
    return layout


def _joint_rhs(plant: System, obs: Mapping[str, AbstractObserver], kind: _Kind, U: Sequence[Any], p: Any,
               y_flow: Any) -> Callable[[Any, Any, int], Any]:
    """``rhs(t, S, stage)`` of the joint state S = (x, z per observer) for :func:`rk4_step`: the plant's f and each
    observer's flow, fed the held sample (sampled runs) or h + noise (`y_flow` is then the noise)."""
    comp = compile_system(plant)
    n = plant.n_states

    def rhs(tt: Any, S: Any, k: int) -> Any:
        xx, u = rows(S, 0, n), U[k]
        y = y_flow if kind.sampled else comp.h(tt, xx, u, p) + y_flow
        parts = [comp.f(tt, xx, u, p)]
        off_ = n
        for o in obs.values():
            parts.append(o.design.flow(tt, rows(S, off_, off_ + o.n_z), u, y))
            off_ += o.n_z
        return ca.vertcat(*parts)
    return rhs


def _flow_function(plant: System, obs: Mapping[str, AbstractObserver], kind: _Kind) -> ca.Function:
    """``(t, S, u0, u_half, u1, y, dt, dt/2, dt/6, p) -> S(t + dt)``: one RK4 step of the joint flow with every function
    inlined (SX). Called on SX it inlines; called on MX it is one call."""
    nu, ny = plant.n_inputs, plant.n_outputs
    S = ca.SX.sym("S", plant.n_states + sum(o.n_z for o in obs.values()))
    t, y, dt, half, sixth = ca.SX.sym("t"), ca.SX.sym("y", ny), ca.SX.sym("dt"), ca.SX.sym("half"), ca.SX.sym("sixth")
    U = [ca.SX.sym(f"u{k}", nu) for k in range(3)]
    p = ca.SX.sym("p", plant.n_params if kind.folded is None else 0)
    pv = ca.DM(kind.folded) if kind.folded is not None else p
    S_next = rk4_step(_joint_rhs(plant, obs, kind, U, pv, y), t, S, dt, half=half, sixth=sixth)
    return ca.Function("joint_flow", [t, S, *U, y, dt, half, sixth, p], [S_next])


def _adaptive_flow(plant: System, obs: Mapping[str, AbstractObserver], layout: _Layout, kind: _Kind) -> ca.Function:
    """``(S, a, c, y_held) -> S(t + dt)``: the joint flow over one step, by CVODES in τ = (t - t_k)/dt ∈ [0, 1]."""
    comp = compile_system(plant)
    n, nu, ny = plant.n_states, plant.n_inputs, plant.n_outputs
    S = ca.SX.sym("S", layout.n + sum(o.n_z for o in obs.values()))
    nc = 3 + (0 if kind.folded is not None else plant.n_params)
    a, c, yh, tau = ca.SX.sym("a", layout.na), ca.SX.sym("c", nc), ca.SX.sym("yh", ny), ca.SX.sym("tau")
    dt = c[0]
    p = ca.DM(kind.folded) if kind.folded is not None else rows(c, 3, 3 + plant.n_params)
    t = a[0] + tau * dt
    stages = [rows(a, layout.u.start + k * nu, layout.u.start + (k + 1) * nu) for k in range(3)]
    # quadratic through u(t_k), u(t_k + dt/2), u(t_k + dt): exact for held and linear inputs
    u = (2 * (tau - 0.5) * (tau - 1)) * stages[0] - (4 * tau * (tau - 1)) * stages[1] + (2 * tau * (tau - 0.5)) * stages[2]
    noise = rows(a, layout.noise.start, layout.noise.stop) if kind.noisy else ca.DM.zeros(ny)
    xx = rows(S, 0, n)
    y = yh if kind.sampled else comp.h(t, xx, u, p) + noise
    parts, off = [comp.f(t, xx, u, p)], n
    for o in obs.values():
        parts.append(o.design.flow(t, rows(S, off, off + o.n_z), u, y))
        off += o.n_z
    opts = {"abstol": kind.adaptive.atol, "reltol": kind.adaptive.rtol, "linear_multistep_method": kind.adaptive.method}
    F = ca.integrator("joint_flow", "cvodes", {"x": S, "t": tau, "p": ca.vertcat(a, c, yh), "ode": dt * ca.vertcat(*parts)},
                      0.0, 1.0, opts)
    Sm, am, cm, ym = ca.MX.sym("S", S.shape[0]), ca.MX.sym("a", layout.na), ca.MX.sym("c", c.shape[0]), ca.MX.sym("y", ny)
    return ca.Function("adaptive_step", [Sm, am, cm, ym], [F(x0=Sm, p=ca.vertcat(am, cm, ym))["xf"]])


def _assemble(plant: System, obs: Mapping[str, AbstractObserver], layout: _Layout, S: np.ndarray, O: np.ndarray,
              t: np.ndarray, A: np.ndarray, info: dict[str, Any]) -> Run:
    nu, n = plant.n_inputs, layout.n
    u = A[:, layout.u.start:layout.u.start + nu] if nu else np.zeros((t.size, 0))
    y_true = O[:, layout.y_true]
    y = O[:, layout.y_meas] if layout.y_meas is not None else y_true
    traces = {}
    for name, o in obs.items():
        zsl, xsl = layout.out[name]
        z = O[:, zsl] if zsl is not None else S[:, layout.slices[name]]
        xhat = O[:, xsl] if xsl is not None else z[:, :n]
        prior = o.estimate(t[0], S[0, layout.slices[name]], u[0], y[0])
        traces[name] = ObserverTrace(name, o.design.method, o.design.z_names, z, xhat, prior,
                                     covariance=getattr(o.design, "covariance", None))
    return Run(plant.name, t, plant.states, plant.inputs, plant.outputs, u, y, traces, x=S[:, :n], y_true=y_true,
               info={**info, "units": dict(getattr(plant, "units", None) or {})}, estimated_params=plant.estimated_params)
