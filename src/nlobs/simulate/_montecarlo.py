"""Monte Carlo over initial states, noise seeds and parameter draws: compiled batches, optionally on Dask.

Trajectory j uses exactly the per-step inputs ``simulate(..., seed=seeds[j])`` would use, so
any trajectory can be re-run alone (:meth:`MonteCarloResult.trajectory`). The work is split
into chunks of trajectories; each chunk is one call of a compiled C loop (or of the CasADi VM).
The chunks run on threads, one per core by default: the compiled loop and CasADi's virtual machine
both release Python's lock while they run, so the chunks run side by side.
With a Dask scheduler the chunks run on its workers with the same code. Every trajectory's inputs
depend on its seed alone, so the same seeds give the same numbers however the runs are chunked,
threaded or distributed.

On the JAX engine with ``draws="device"`` the noise is drawn inside the runs by JAX's generator
(:class:`nlobs.engine._jax.DeviceNoise`): the same distributions and the same rule (a run's noise
depends on its seed alone), other numbers, so those runs are not re-run by :func:`simulate`.
"""

from __future__ import annotations

import contextvars
import functools
import threading
import warnings
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor, wait
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .._display import Column, SummaryTable, short_repr
from .._progress import as_progress
from ..design import check_positive
from ..engine import Backend, batch_backend, evaluate_many, run_batch, saved_steps, usable_cores
from ..engine._simd import LANES
from ..errors import FiniteEscapeError, ModelError, ShapeError, SolverError
from ..model import System
from ._metrics import convergence_band, convergence_time, state_convergence
from ._options import Noise, ProcessNoise, Sampling, channel_generators
from ._results import Run
from ._run import Prepared, prepare, simulate
from ._schedule import run_seeds

__all__ = ["montecarlo", "MonteCarloResult", "ObserverStats"]


@dataclass(frozen=True, eq=False)
class ObserverStats:
    """Per-trajectory metrics of one observer (arrays of length M; NaN where undefined).

    Only the estimates are stored; every metric is computed on first access (vectorised over the
    runs where the definition allows), so a Monte Carlo run whose caller reads only the final
    states does no per-run work for metrics.

    Attributes
    ----------
    xhat : numpy.ndarray of shape (M, n_save, n)
    error_norm : numpy.ndarray of shape (M, n_save)
    convergence_time : numpy.ndarray of shape (M,)
        NaN when the error did not settle below the tolerance within the run (or failed).
    rms_error : numpy.ndarray of shape (M,)
        RMS of the error norm over the last 20 % of the saved times.
    final_error, peak_error : numpy.ndarray of shape (M,)
    """

    name: str
    xhat: np.ndarray
    t: np.ndarray = field(repr=False)
    x: np.ndarray = field(repr=False)
    initial_errors: Callable[[], np.ndarray] = field(repr=False)  #: x̂(0⁻) − x(0) of each run (M, n), computed on demand
    tol: float | None = None  #: an absolute convergence tolerance replacing the rule (see ``Run.metrics``)
    #: (M,) runs in which this observer failed while the plant and the other observers completed (None: none)
    failed: np.ndarray | None = field(default=None, repr=False)
    noisy: bool = False  #: the runs had noise (see :func:`nlobs.simulate._metrics.state_convergence`)

    @functools.cached_property
    def error_norm(self) -> np.ndarray:
        return np.linalg.norm(self.xhat - self.x, axis=2)

    @functools.cached_property
    def convergence_time(self) -> np.ndarray:
        t, e = self.t, self.error_norm
        out = np.full(e.shape[0], np.nan)
        for j, (row, e0) in enumerate(zip(e, self.initial_errors())):
            if not np.all(np.isfinite(row)):
                continue
            if self.tol is not None:  # the tolerance on ‖x̂ − x‖, as in Run.metrics
                tc = convergence_time(t, row, convergence_band(t, row, e0=float(np.linalg.norm(e0)), tol=self.tol).tol)
            else:  # each state in its own units, as in Run.metrics (PER_STATE_RULE)
                tc = state_convergence(t, self.xhat[j] - self.x[j], e0, noisy=self.noisy).time
            out[j] = np.nan if tc is None else tc
        return out

    @functools.cached_property
    def rms_error(self) -> np.ndarray:
        t = self.t
        tail = t >= t[-1] - 0.2 * (t[-1] - t[0])
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # "mean of empty slice": a failed run's NaN row gives NaN
            return np.sqrt(np.nanmean(self.error_norm[:, tail] ** 2, axis=1))

    @functools.cached_property
    def final_error(self) -> np.ndarray:
        return self.error_norm[:, -1]

    @functools.cached_property
    def peak_error(self) -> np.ndarray:
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return np.nanmax(self.error_norm, axis=1)

    def __repr__(self) -> str:
        return short_repr(self, {"name": self.name, "xhat": self.xhat})


@dataclass(frozen=True, eq=False)
class MonteCarloResult:
    """The result of :func:`montecarlo` (trajectories on the first axis, saved times on the second)."""

    model: str
    t: np.ndarray
    x: np.ndarray
    seeds: np.ndarray
    status: np.ndarray
    observers: Mapping[str, ObserverStats]
    failures: Sequence[tuple[int, str]]
    n_steps: int
    info: Mapping[str, Any] = field(default_factory=dict)
    _spec: Any = None
    _inputs: Any = None

    @property
    def runs(self) -> int:
        return int(self.seeds.size)

    @property
    def failed(self) -> np.ndarray:
        """Indices of trajectories that blew up (the plant, or every observer)."""
        return np.flatnonzero(self.status < self.n_steps)

    def _ok(self, name: str) -> np.ndarray:
        """(M,) runs that completed for observer `name` (its trajectory completed and it did not fail in it)."""
        ok = self.status == self.n_steps
        failed = self.observers[name].failed
        return ok if failed is None else ok & ~failed

    def stats(self, name: str) -> dict[str, Any]:
        """Median and 90th percentile of convergence time and RMS error, and failure counts."""
        o = self.observers[name]
        ok = self._ok(name)
        conv = o.convergence_time[ok]
        rms = o.rms_error[ok]
        settled = conv[np.isfinite(conv)]
        return {
            "runs": self.runs,
            "failed": int((~ok).sum()),
            "not_converged": int(np.isnan(conv).sum()),
            "convergence_time_median": float(np.median(settled)) if settled.size else None,
            "convergence_time_p90": float(np.percentile(conv, 90)) if conv.size and np.isfinite(np.percentile(conv, 90)) else None,
            "rms_error_median": float(np.median(rms)) if rms.size else None,
            "rms_error_p90": float(np.percentile(rms, 90)) if rms.size else None,
        }

    def summary(self) -> SummaryTable:
        """Per observer: runs, failures, unsettled runs, median and 90th percentile of the
        convergence time and of the RMS error; ``print()`` it, show it in a notebook, or ``.to_pandas()`` it."""
        cols = [Column("observer", "observer", str, numeric=False), Column("runs", "runs"), Column("failed", "failed"),
                Column("not_converged", "unsettled"), Column("convergence_time_median", "conv. median"),
                Column("convergence_time_p90", "conv. p90"), Column("rms_error_median", "RMS median"),
                Column("rms_error_p90", "RMS p90")]
        rows = [{"observer": name, **self.stats(name)} for name in self.observers]
        notes = [f"  run {j}: {reason}" for j, reason in self.failures[:10]]
        if len(self.failures) > 10:
            notes.append(f"  ... and {len(self.failures) - 10} more failed runs")
        return SummaryTable(f"{self.model}: Monte Carlo, {self.runs} runs, t in [0, {self.t[-1]:g}]", cols, rows, notes)

    def __repr__(self) -> str:
        return short_repr(self, {"model": self.model, "runs": self.runs, "failed": len(self.failed),
                                 "t": (float(self.t[0]), float(self.t[-1])), "observers": tuple(self.observers)})

    def _repr_html_(self) -> str:
        return self.summary()._repr_html_()

    def to_pandas(self) -> Any:
        """One row per (run, observer): seed, status and the metrics."""
        import pandas as pd

        rows = []
        for name, o in self.observers.items():
            for j in range(self.runs):
                rows.append({"run": j, "observer": name, "seed": int(self.seeds[j]), "failed": not bool(self._ok(name)[j]),
                             "convergence_time": o.convergence_time[j], "rms_error": o.rms_error[j],
                             "final_error": o.final_error[j], "peak_error": o.peak_error[j]})
        return pd.DataFrame(rows)

    def trajectory(self, j: int) -> Run:
        """Re-run trajectory `j` alone with :func:`simulate` (full resolution, every signal)."""
        if self._spec is None:
            raise ValueError("this result does not keep its set-up; re-run montecarlo")
        if getattr(self._spec, "draws", "host") == "device":
            raise ValueError("montecarlo ran with draws='device': its noise was drawn by JAX on the device, and "
                             f"simulate(seed={int(self.seeds[j])}) would draw other numbers. Run montecarlo with "
                             "draws='host' (the default) to replay its runs")
        return self._spec.rerun(j, self._inputs)

    def plot(self, path: str | None = None) -> Any:
        """Error bands: the median and the 10-90 % band of ‖x̂ − x‖ over the runs, per observer."""
        from matplotlib.figure import Figure

        fig = Figure(figsize=(8, 3.6), layout="constrained")
        ax = fig.subplots()
        for i, (name, o) in enumerate(self.observers.items()):
            e = np.maximum(o.error_norm[self._ok(name)], 1e-16)
            if e.size == 0:
                continue
            lo, med, hi = np.percentile(e, [10, 50, 90], axis=0)
            ax.fill_between(self.t, lo, hi, color=f"C{i}", alpha=0.25, lw=0)
            ax.semilogy(self.t, med, color=f"C{i}", lw=1.4, label=f"{name} (median, 10–90 %)")
        ax.set_xlabel("t")
        ax.set_ylabel("‖x̂ − x‖")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize="small")
        ax.set_title(f"{self.model}: {self.runs} runs" + (f", {len(self.failed)} failed" if len(self.failed) else ""))
        if path is not None:
            fig.savefig(path, dpi=110)
        return fig


@dataclass(frozen=True, eq=False)
class _Spec:
    """Everything a chunk needs (picklable: runs on Dask workers)."""

    prep: Prepared
    x0: np.ndarray            # (M, n)
    xhat0: Mapping[str, np.ndarray]  # name -> (M, n)
    params: np.ndarray        # (M, n_params)
    seeds: np.ndarray         # (M,)
    stride: int
    bound: float
    engine: str
    draws: str = "host"       # "device": the noise drawn by JAX on the device (engine "jax")

    def run_chunk(self, j0: int, j1: int, buffers: _Buffers | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Runs j0 .. j1 - 1: final arrays (states, outputs, status) of :func:`nlobs.engine.run_batch`; `buffers`
        lends the chunk its noise inputs' array (reused from an earlier chunk of the same call)."""
        prep, layout = self.prep, self.prep.layout
        S0 = np.empty((j1 - j0, layout.size))
        S0[:, :prep.plant.n_states] = self.x0[j0:j1]
        for name, o in prep.obs.items():
            S0[:, layout.slices[name]] = evaluate_many(o.design.initial, self.xhat0[name][j0:j1])
        if prep.kind.sampled:
            S0[:, layout.held] = 0.0
        C = np.tile(prep.constants(), (j1 - j0, 1)) if prep.kind.folded is not None else \
            np.column_stack([np.tile(prep.constants()[:3], (j1 - j0, 1)), self.params[j0:j1]])
        if not prep.seeded:
            return run_batch(layout.step, S0, prep.inputs_for(None), C, prep.n_steps, stride=self.stride, bound=self.bound,
                             backend=self.engine)
        if self.draws == "device":
            from ..engine._jax import run_batch_jax

            A, noise = device_noise(prep)
            return run_batch_jax(layout.step, S0, A, C, saved_steps(prep.n_steps, self.stride), self.bound, noise=noise,
                                 seeds=self.seeds[j0:j1])
        flat = (buffers or _Buffers()).take((j1 - j0) * (prep.n_steps + 1) * prep.layout.step.size1_in(1))
        try:
            A = seeded_inputs(prep, self.seeds[j0:j1], flat)
            return run_batch(layout.step, S0, A, C, prep.n_steps, stride=self.stride, bound=self.bound, backend=self.engine)
        finally:
            if buffers is not None:
                buffers.give(flat)

    def rerun(self, j: int, inputs: Any) -> Run:
        prep = self.prep
        plant = prep.plant.with_params(**dict(zip(prep.plant.param_names, self.params[j])))
        # the schedule's own sampling: every output on its clock, as in the batch (one clock per output too)
        return simulate(plant, prep.obs, t_final=prep.n_steps * prep.dt, dt=prep.dt, x0=self.x0[j],
                        inputs=inputs, noise=prep.noise, process_noise=prep.process_noise, sampling=prep.schedule.sampling,
                        seed=int(self.seeds[j]), xhat0={k: v[j] for k, v in self.xhat0.items()}, escape_bound=self.bound)


class _Buffers:
    """Flat float arrays lent to the chunks of one call and given back after each: a fresh array of tens of MB pays a
    page fault per 4 kB on its first write (on the noisy P2 run that cost more than drawing the noise), a reused one
    does not. Thread-safe; freed with the call."""

    def __init__(self) -> None:
        self._free: list[np.ndarray] = []
        self._lock = threading.Lock()

    def take(self, size: int) -> np.ndarray:
        """An array of at least `size` floats (contents undefined)."""
        with self._lock:
            for i, b in enumerate(self._free):
                if b.size >= size:
                    return self._free.pop(i)
        return np.empty(size)

    def give(self, flat: np.ndarray) -> None:
        """Return an array from :meth:`take`."""
        with self._lock:
            self._free.append(flat)


def seeded_inputs(prep: Prepared, seeds: np.ndarray, flat: np.ndarray | None = None) -> np.ndarray:
    """The per-step inputs of runs with the given seeds, shape (len(seeds), N + 1, na): row r equals
    ``prep.inputs_for(seeds[r])`` bit for bit (the same generators, draws and products), written in place into one
    array for the chunk (no per-run arrays to stack; into `flat`, a float array of at least that size, when given),
    with the seed-free columns (time and inputs, sample flags) broadcast once and the noise scales computed once."""
    N, plant = prep.n_steps, prep.plant
    flags = prep.schedule.flags() if prep.kind.sampled else None
    nb = prep.base.shape[1]
    nv = plant.n_outputs if prep.noise is not None else 0
    nw = plant.n_states if prep.process_noise is not None else 0
    shape = (len(seeds), N + 1, nb + nv + nw + (flags.shape[1] if flags is not None else 0))
    A = np.empty(shape) if flat is None else flat[:int(np.prod(shape))].reshape(shape)
    A[:, :, :nb] = prep.base
    if flags is not None:
        A[:, :, nb + nv + nw:] = flags
    V, W = slice(nb, nb + nv), slice(nb + nv, nb + nv + nw)
    A[:, N, W] = 0.0  # process noise: an increment per step, none after the last
    scratch = np.empty(N + 1)
    if nv:
        s_v, kinds = prep.noise.scales(plant.outputs), prep.noise.kind_of(plant.outputs)  # type: ignore[union-attr]
    if nw:
        s_w = prep.process_noise.scales(plant.states) * np.sqrt(prep.dt)  # type: ignore[union-attr]
    for r, seed in enumerate(seeds):
        if nv:
            prep.noise.fill(channel_generators(int(seed), "measurement", nv), A[r, :, V], s_v, kinds, prep.dt,  # type: ignore[union-attr]
                            scratch)
        if nw:
            ProcessNoise.fill(channel_generators(int(seed), "process", nw), A[r, :N, W], s_w, scratch)
    return A


def device_noise(prep: Prepared) -> tuple[np.ndarray, Any]:
    """The per-step inputs every run shares (N + 1, na), noise columns 0, and the noise JAX draws into them on the
    device (:class:`nlobs.engine._jax.DeviceNoise`): the same columns, scales, kinds and hold as :func:`seeded_inputs`,
    drawn by JAX's generator instead of NumPy's."""
    from ..engine._jax import DeviceNoise

    N, plant = prep.n_steps, prep.plant
    A = seeded_inputs(prep, np.zeros(1, dtype=np.int64))[0]
    nb = prep.base.shape[1]
    nv = plant.n_outputs if prep.noise is not None else 0
    nw = plant.n_states if prep.process_noise is not None else 0
    A[:, nb:nb + nv + nw] = 0.0
    scales: tuple[float, ...] = ()
    gaussian: tuple[bool, ...] = ()
    every = 1
    if nv:
        noise = prep.noise
        scales = tuple(float(v) for v in noise.scales(plant.outputs))  # type: ignore[union-attr]
        gaussian = tuple(k == "gaussian" for k in noise.kind_of(plant.outputs))  # type: ignore[union-attr]
        every = Sampling(noise.hold).every(prep.dt) if noise.hold is not None else 1  # type: ignore[union-attr]
    process = tuple(float(v) for v in prep.process_noise.scales(plant.states) * np.sqrt(prep.dt)) if nw else ()  # type: ignore[union-attr]
    return np.ascontiguousarray(A), DeviceNoise(nb, scales, gaussian, int(every), process, N)


def _per_run(value: Any, M: int, n: int, name: str) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    if a.ndim == 1:
        a = np.broadcast_to(a, (M, a.size))
    if a.shape != (M, n) or not np.all(np.isfinite(a)):
        raise ShapeError(f"montecarlo: `{name}` must be {n} finite numbers or an array of shape ({M}, {n}), got shape {np.shape(value)}")
    return np.ascontiguousarray(a)


def montecarlo(
    plant: System,
    observers: Any,
    *,
    t_final: float,
    dt: float | None = None,
    x0: Sequence[float] | np.ndarray,
    runs: int | None = None,
    xhat0: Mapping[str, Any] | Sequence[float] | np.ndarray | None = None,
    params: Mapping[str, Sequence[float] | float] | None = None,
    inputs: Any = None,
    noise: Noise | None = None,
    process_noise: ProcessNoise | None = None,
    sampling: Sampling | None = None,
    seed: int = 0,
    save_every: int | None = None,
    tol: float | None = None,
    engine: Backend = "auto",
    scheduler: Any = None,
    workers: int | None = None,
    chunk: int | None = None,
    progress: bool | Callable[[float], None] | None = None,
    escape_bound: float = 1e12,
    draws: str = "host",
) -> MonteCarloResult:
    """Run a plant and observers over many initial states, noise seeds and parameter draws.

    Parameters
    ----------
    plant : System
    observers : mapping of name to observer/design, or a sequence
    t_final, dt : float
        As in :func:`nlobs.simulate` (`dt` is required for a continuous-time plant; a discrete-time one steps by
        its sample_time, each run iterating the map as :func:`nlobs.simulate` does).
    x0 : array_like of shape (n,) or (M, n)
        Initial plant states, the same for every run or one per run.
    runs : int, optional
        The number of runs M when no argument is per-run (then only the noise differs).
    xhat0 : array_like of shape (n,) or (M, n), or a mapping of observer name to one of those
        Initial estimates (default: each design's).
    params : mapping of parameter name to a number or M draws, optional
        Plant parameters per run (the observers keep their design model).
    inputs, noise, process_noise, sampling :
        As in :func:`nlobs.simulate`.

    Other Parameters
    ----------------
    seed : int
        Base seed; run j uses ``seeds[j]`` (see the result), exactly as ``simulate(seed=seeds[j])``.
    save_every : int, optional
        Keep every k-th step (default: about a thousand saved times); the final time is always kept.
    tol : float, optional
        Absolute convergence tolerance on ‖x̂ − x‖ (default: each run judged per state in its own units
        as in :meth:`Run.metrics`: each state's band the larger of 2 % of its initial error and twice
        its steady-state error, at most 20 % of its initial error unless that floor is zero-mean noise;
        see :data:`nlobs.simulate._metrics.PER_STATE_RULE`).
    engine : {"auto", "vm", "c", "jax"}
        Where the batches run; ``"auto"`` decides once for the whole Monte Carlo run (every chunk runs there).
        ``"jax"`` (the optional ``nlobs[jax]`` extra): the same compiled step as one XLA program over every run
        (vmap over runs, scan over steps), on a GPU when JAX has one; equal to the C engine to rounding. Noise is
        drawn on the host, as the C engine draws it (the same seeds give the same numbers), and sent to the device
        with the runs, in chunks of at most 512 MB of it, unless ``draws="device"`` (below). A step with more scalar
        operations than :data:`nlobs.engine._jax.MAX_OPERATIONS` is refused, since XLA then takes minutes and GB to
        compile it; a 12-state EKF has 34,545.
    scheduler : str or dask.distributed.Client, optional
        Run the chunks on a Dask cluster (its address, or a client); needs ``nlobs[dask]``.
    workers : int, optional
        Threads that run the chunks on this machine (default: one per usable core; 1 runs them one after another).
        The compiled batches and CasADi's virtual machine release Python's lock, so the threads use the cores (with
        an MHE, whose solver reports through process-wide state, the chunks run one after another; so do the runs of
        a discrete-time plant, each one :func:`nlobs.simulate`'s map iteration). The numbers do not depend on it.
        Not with `scheduler` (the cluster's workers run the chunks there).
    chunk : int, optional
        Runs per compiled call (and per Dask task). Default: about four chunks per thread (or per thread of the
        cluster's workers), in whole blocks of the SIMD width, and small enough that a chunk's noise inputs
        stay near 64 MB.
    progress : bool or callable, optional
    escape_bound : float
        A run whose state leaves this bound is stopped and reported as failed (the others go on).
    draws : {"host", "device"}
        Where the noise is drawn. ``"host"``: by NumPy, run j's exactly as ``simulate(seed=seeds[j])`` draws it, on
        every engine. ``"device"`` (``engine="jax"`` only): by JAX's generator, step by step inside the runs on the
        device, from each run's seed: no noise array is made or sent (on a GPU, drawing on the host costs more than
        the runs). The noise has the same distribution, scales, hold and seeds-to-runs rule, but other numbers than
        ``simulate``'s: :meth:`MonteCarloResult.trajectory` is then refused, and a run that blows up is reported
        whole, its observers not isolated by a re-run.

    Returns
    -------
    MonteCarloResult
    """
    _check_draws(draws, engine, plant)
    if tol is not None:
        tol = check_positive(tol, "tol", "montecarlo")
    for name, value in (("workers", workers), ("chunk", chunk)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1):
            raise ShapeError(f"montecarlo: `{name}` must be a positive whole number, got {value!r}")
    if workers is not None and scheduler is not None:
        raise ShapeError("montecarlo: give `workers` (threads on this machine) or `scheduler` (a Dask cluster), not both: "
                         "on a cluster its workers run the chunks")
    if isinstance(plant, System) and plant.is_discrete:
        return _montecarlo_map(plant, observers, t_final=t_final, dt=dt, x0=x0, runs=runs, xhat0=xhat0, params=params,
                               inputs=inputs, noise=noise, process_noise=process_noise, sampling=sampling, seed=seed,
                               tol=tol, progress=progress, escape_bound=escape_bound)
    if dt is None:
        raise ShapeError("montecarlo: give `dt`, the integration step of a continuous-time plant")
    # parameters nobody varies are compiled in as constants (one build per model and values)
    prep = prepare(plant, observers, t_final=t_final, dt=dt, inputs=inputs, params=None, noise=noise,
                   process_noise=process_noise, sampling=sampling, caller="montecarlo", fold_params=not params)
    if prep.particle:
        raise ModelError(f"montecarlo: particle filters ({', '.join(prep.particle)}) are not run in Monte Carlo batches; "
                         "run nlobs.simulate once per seed for them")
    plant, n = prep.plant, prep.plant.n_states
    M = _count_runs(x0, xhat0, params, runs)
    if prep.x0_tail and np.shape(x0)[-1:] == (n - len(prep.x0_tail),):  # estimated parameters: true values appended
        x0 = np.asarray(x0, dtype=float)
        x0 = np.concatenate([x0, np.broadcast_to(np.asarray(prep.x0_tail), x0.shape[:-1] + (len(prep.x0_tail),))], axis=-1)
    X0 = _per_run(x0, M, n, "x0")
    XH = {}
    for name, o in prep.obs.items():
        given = xhat0.get(name) if isinstance(xhat0, Mapping) else xhat0
        XH[name] = _per_run(o.design.xhat0 if given is None else given, M, n, f"xhat0[{name}]")
    unknown = [k for k in (params or {}) if k not in plant.params]
    if unknown:
        raise ShapeError(f"montecarlo: `params` names {unknown[0]!r}, which is not a parameter of {plant.name!r}")
    P = np.column_stack([np.broadcast_to(np.asarray((params or {}).get(k, v), dtype=float), (M,)) for k, v in plant.params.items()]) \
        if plant.n_params else np.zeros((M, 0))
    seeds = run_seeds(seed, M)
    N = prep.n_steps
    stride = max(1, N // 1000) if save_every is None else int(save_every)
    if stride < 1:
        raise ShapeError(f"montecarlo: `save_every` must be a positive number of steps, got {save_every}")
    spec = _Spec(prep, X0, XH, P, seeds, stride, escape_bound, engine, draws if prep.seeded else "host")
    report = as_progress(progress, f"montecarlo {plant.name}")
    # bytes of one run's noise inputs (none drawn on the host with draws="device")
    per_run = (N + 1) * prep.layout.step.size1_in(1) * 8 if prep.seeded and spec.draws == "host" else 0
    if scheduler is None:
        parts, size, info = _on_this_machine(spec, M, N, engine, workers, chunk, per_run, report)
    else:
        parts, size, info = _on_dask(scheduler, spec, M, chunk, per_run, report)
    S = np.concatenate([p[0] for p in parts])
    O = np.concatenate([p[1] for p in parts])
    status = np.concatenate([p[2] for p in parts])
    return _result(spec, S, O, status, tol, inputs, info={"dt": dt, "save_every": stride, "engine": engine,
                                                          "dask": scheduler is not None, "chunk": size, "draws": spec.draws,
                                                          **info})



def _check_draws(draws: str, engine: str, plant: Any) -> None:
    """ShapeError unless `draws` is "host", or "device" on the JAX engine with a continuous-time plant."""
    if draws not in ("host", "device"):
        raise ShapeError(f"montecarlo: `draws` must be 'host' or 'device', got {draws!r}")
    if draws == "device" and engine != "jax":
        raise ShapeError(f"montecarlo: draws='device' draws the noise with JAX on the device: it needs engine='jax' "
                         f"(got engine={engine!r})")
    if draws == "device" and isinstance(plant, System) and plant.is_discrete:
        raise ShapeError(f"montecarlo: draws='device' runs continuous-time plants on JAX; {plant.name!r} is a "
                         "discrete-time map, whose runs are drawn and iterated on the host: leave `draws` out")


def _count_runs(x0: Any, xhat0: Any, params: Any, runs: int | None) -> int:
    """The number of runs the per-run arguments agree on."""
    sizes = [np.shape(x0)[0]] if np.ndim(x0) == 2 else []
    if isinstance(xhat0, Mapping):
        sizes += [np.shape(v)[0] for v in xhat0.values() if np.ndim(v) == 2]
    elif xhat0 is not None and np.ndim(xhat0) == 2:
        sizes.append(np.shape(xhat0)[0])
    sizes += [np.size(v) for v in (params or {}).values() if np.ndim(v) == 1]
    if runs is not None:
        sizes.append(int(runs))
    if not sizes:
        raise ShapeError("montecarlo: nothing varies between runs: give `runs`, or x0/xhat0/params with one row per run")
    M = sizes[0]
    if any(s != M for s in sizes):
        raise ShapeError(f"montecarlo: the per-run arguments disagree on the number of runs: {sorted(set(sizes))}")
    return M


def _on_this_machine(spec: _Spec, M: int, N: int, engine: str, workers: int | None, chunk: int | None, per_run: int,
                     report: Any) -> tuple[list[Any], int, dict[str, Any]]:
    """The chunks on this machine's threads (JAX: one XLA program over every run, the device parallelises)."""
    prep = spec.prep
    if engine == "jax":
        # one program over every run, unless the runs' noise inputs (drawn here, sent to the device) would pass
        # JAX_CHUNK_BYTES: then equal chunks under it, one after another (one more trace for a shorter last chunk)
        parts = max(1, -(-M * per_run // JAX_CHUNK_BYTES))
        size = int(chunk) if chunk is not None else -(-M // parts)
        return _on_threads(spec, [(j, min(j + size, M)) for j in range(0, M, size)], 1, report), size, {"workers": 1}
    # where the whole batch runs, decided (and compiled) once: every chunk, on every thread, runs there
    where = batch_backend(prep.layout.step, M, N, engine)
    # compiled loops and CasADi's virtual machine (3.8) both release Python's lock while they run; a step with an
    # optimisation inside (MHE) reports solver errors through process-wide state, so its chunks take turns
    alone = any(getattr(o.design, "needs_mx", False) for o in prep.obs.values())
    threads = 1 if alone else (usable_cores() if workers is None else int(workers))
    size = int(chunk) if chunk is not None else _chunk_size(M, threads, per_run)
    bounds = [(j, min(j + size, M)) for j in range(0, M, size)]
    threads = min(threads, len(bounds))
    return _on_threads(replace(spec, engine=where), bounds, threads, report), size, {"workers": threads}

#: About this many bytes of noise inputs per chunk (the per-step inputs of its runs, made before the chunk runs).
CHUNK_BYTES = 64 * 2**20
#: At most this many bytes of noise inputs per chunk on the JAX engine (drawn on the host as the C engine draws them,
#: then copied to the device): 16,000 runs of 10,000 steps with one noisy output are 1.3 GB of them, 160,000 runs 13 GB.
JAX_CHUNK_BYTES = 512 * 2**20


def _chunk_size(M: int, slots: int, per_run: int) -> int:
    """Runs per chunk: about four chunks per thread that runs them (the last ones even out uneven threads), in whole
    blocks of the SIMD width, at most 1,024, and few enough that a chunk's noise inputs (`per_run` bytes a run) stay
    near :data:`CHUNK_BYTES`."""
    size = min(-(-M // (4 * max(slots, 1))), 1024, max(1, CHUNK_BYTES // max(per_run, 1)))
    return max(LANES, -(-size // LANES) * LANES)


def _on_threads(spec: _Spec, bounds: Sequence[tuple[int, int]], threads: int, report: Any) -> list[Any]:
    """The chunks, in order, run on `threads` threads (1: one after another in this thread)."""
    buffers = _Buffers()
    if threads <= 1:
        parts = []
        for i, (j0, j1) in enumerate(bounds):
            parts.append(spec.run_chunk(j0, j1, buffers))
            if report is not None:
                report((i + 1) / len(bounds))
        return parts
    with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="nlobs-montecarlo") as pool:
        # each chunk in a copy of this context: time budgets and deadlines set by the caller reach the threads
        futures = [pool.submit(contextvars.copy_context().run, spec.run_chunk, j0, j1, buffers) for j0, j1 in bounds]
        pending, done = set(futures), 0
        while pending:
            finished, pending = wait(pending, return_when=FIRST_EXCEPTION)
            for fut in finished:
                if fut.exception() is not None:  # the first failure stops the chunks not yet started
                    for other in pending:
                        other.cancel()
                    raise fut.exception()  # type: ignore[misc]
            done += len(finished)
            if report is not None:
                report(done / len(futures))
        return [f.result() for f in futures]


@dataclass(frozen=True, eq=False)
class _MapSpec:
    """How to re-run trajectory j of a discrete-time Monte Carlo run (:meth:`MonteCarloResult.trajectory`)."""

    plant: System
    obs: Mapping[str, Any]
    kw: Mapping[str, Any]
    X0: np.ndarray
    XH: Mapping[str, np.ndarray]
    P: np.ndarray
    seeds: np.ndarray

    def rerun(self, j: int, inputs: Any) -> Run:
        from ._discrete import simulate_map

        plant = self.plant.with_params(**dict(zip(self.plant.param_names, self.P[j]))) if self.plant.n_params else self.plant
        return simulate_map(plant, self.obs, x0=self.X0[j], xhat0={k: v[j] for k, v in self.XH.items()}, inputs=inputs,
                            seed=int(self.seeds[j]), caller="montecarlo", **self.kw)


def _montecarlo_map(plant: System, observers: Any, *, x0: Any, runs: int | None, xhat0: Any, params: Any, inputs: Any,
                    seed: int, tol: float | None, progress: Any, **kw: Any) -> MonteCarloResult:
    """Monte Carlo runs of a discrete-time plant and its observers: each run is :func:`nlobs.simulate`'s map
    iteration (one compiled mapaccum for the plant, the compiled observer loop), with the seeds, initial states and
    parameter draws of the continuous-time runner; a run that leaves the bound counts as failed."""
    from ._run import augmented_plant, named_observers

    obs = named_observers(observers)
    plant_, tail = augmented_plant(plant, obs)
    n = plant_.n_states
    sizes = [np.shape(x0)[0]] if np.ndim(x0) == 2 else []
    sizes += [np.size(v) for v in (params or {}).values() if np.ndim(v) == 1]
    if runs is not None:
        sizes.append(int(runs))
    if not sizes or any(s != sizes[0] for s in sizes):
        raise ShapeError("montecarlo: give `runs`, or x0/params with one row per run (the same number of rows)")
    M = sizes[0]
    x0 = np.asarray(x0, dtype=float)
    if tail and x0.shape[-1] == n - len(tail):
        x0 = np.concatenate([x0, np.broadcast_to(np.asarray(tail), x0.shape[:-1] + (len(tail),))], axis=-1)
    X0 = _per_run(x0, M, n, "x0")
    XH = {}
    for name, o in obs.items():
        given = xhat0.get(name) if isinstance(xhat0, Mapping) else xhat0
        XH[name] = _per_run(o.design.xhat0 if given is None else given, M, n, f"xhat0[{name}]")
    unknown = [k for k in (params or {}) if k not in plant_.params]
    if unknown:
        raise ShapeError(f"montecarlo: `params` names {unknown[0]!r}, which is not a parameter of {plant_.name!r}")
    P = np.column_stack([np.broadcast_to(np.asarray((params or {}).get(k, v), dtype=float), (M,))
                         for k, v in plant_.params.items()]) if plant_.n_params else np.zeros((M, 0))
    seeds = run_seeds(seed, M)
    spec = _MapSpec(plant_, obs, kw, X0, XH, P, seeds)
    report = as_progress(progress, f"montecarlo {plant_.name}")
    runs_, failures = [], []
    for j in range(M):
        try:
            runs_.append(spec.rerun(j, inputs))
        except FiniteEscapeError as err:
            runs_.append(None)
            failures.append((j, str(err).split(". Check")[0]))
        if report is not None:
            report((j + 1) / M)
    ok = next((r for r in runs_ if r is not None), None)
    if ok is None:
        raise ModelError(f"montecarlo: every run of {plant_.name!r} failed; the first: {failures[0][1]}")
    t, N = ok.t, ok.t.size - 1
    status = np.array([N if r is not None else 0 for r in runs_])
    x = np.stack([r.x if r is not None else np.full_like(ok.x, np.nan) for r in runs_])
    stats = {}
    for name in obs:
        xh = np.stack([r.observers[name].xhat if r is not None else np.full_like(ok.x, np.nan) for r in runs_])
        priors = np.stack([r.observers[name].xhat_prior if r is not None else np.full(n, np.nan) for r in runs_])
        stats[name] = ObserverStats(name, xh, t, x, lambda p=priors: np.linalg.norm(p - X0, axis=1), tol)
    return MonteCarloResult(plant_.name, t, x, seeds, status, stats, failures, N,
                            {"time": "discrete", "sample_time": plant_.sample_time, "save_every": 1}, spec, inputs)


def _on_dask(scheduler: Any, spec: _Spec, M: int, chunk: int | None, per_run: int, report: Any) -> tuple[list[Any], int, dict]:
    """The chunks run as tasks on a Dask cluster: the chunk size from the cluster's threads (unless given), the spec
    sent to every worker once per call under a key of this call's own (an identical call, even a concurrent one,
    never shares it: a shared key released by one call while the next sends it again left the scheduler waiting for
    good), and the results in order."""
    try:
        from dask.distributed import Client, as_completed
    except ImportError as e:
        raise ImportError("montecarlo on a cluster needs dask.distributed: pip install 'nlobs[dask]'") from e
    own = not isinstance(scheduler, Client)
    client = Client(scheduler) if own else scheduler
    try:
        slots = sum(client.nthreads().values()) or 1
        size = int(chunk) if chunk is not None else _chunk_size(M, slots, per_run)
        bounds = [(j, min(j + size, M)) for j in range(0, M, size)]
        spec_future = client.scatter(spec, broadcast=True, hash=False)
        futures = [client.submit(_chunk_task, spec_future, j0, j1, pure=False) for j0, j1 in bounds]
        index = {f.key: i for i, f in enumerate(futures)}
        parts: list[Any] = [None] * len(futures)
        try:
            for done, fut in enumerate(as_completed(futures), 1):
                parts[index[fut.key]] = fut.result()
                if report is not None:
                    report(done / len(futures))
        finally:
            client.cancel(futures)
            spec_future.release()
        return parts, size, {"dask_threads": slots}
    finally:
        if own:
            client.close()


def _chunk_task(spec: _Spec, j0: int, j1: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return spec.run_chunk(j0, j1)


def _result(spec: _Spec, S: np.ndarray, O: np.ndarray, status: np.ndarray, tol: float | None, inputs: Any,
            info: dict[str, Any]) -> MonteCarloResult:
    prep, layout = spec.prep, spec.prep.layout
    n, N = prep.plant.n_states, prep.n_steps
    steps = saved_steps(N, spec.stride)
    t = steps * prep.dt
    x = S[:, :, :n]
    xhats = {}
    for name in prep.obs:
        zsl, xsl = layout.out[name]
        xhats[name] = O[:, :, xsl] if xsl is not None else (O[:, :, zsl] if zsl is not None else S[:, :, layout.slices[name]])[:, :, :n]
    observer_failed = {name: np.zeros(status.size, dtype=bool) for name in prep.obs}
    failures = _isolate_failed_runs(spec, status, x, xhats, observer_failed, steps, inputs)
    stats = {}
    for name, o in prep.obs.items():

        def initial_errors(o: Any = o, name: str = name) -> np.ndarray:
            prior = evaluate_many(o.design.output, np.zeros((spec.x0.shape[0], 1)), evaluate_many(o.design.initial, spec.xhat0[name]),
                                  np.zeros(prep.plant.n_inputs), np.zeros(prep.plant.n_outputs))
            return prior - spec.x0

        stats[name] = ObserverStats(name, xhats[name], t, x, initial_errors, tol, observer_failed[name], prep.seeded)
    return MonteCarloResult(prep.plant.name, t, x, spec.seeds, status, stats, failures, N, info, spec, inputs)


#: Trajectories that stopped are re-run alone (to keep the observers that did not fail, and to tell why) up to this many.
RERUN_LIMIT = 200


def _isolate_failed_runs(spec: _Spec, status: np.ndarray, x: np.ndarray, xhats: dict[str, np.ndarray],
                         observer_failed: dict[str, np.ndarray], steps: np.ndarray, inputs: Any) -> list[tuple[int, str]]:
    """A trajectory stops (in the batch) when any of its subsystems blows up. Re-run alone, with each observer
    isolated (:meth:`Simulation.run`), it keeps the plant and the observers that did not fail: their signals are
    written back into `x` and `xhats`, `status` marks the trajectory complete, and only the failing observers are
    counted as failed in it. A plant blow-up (or one of every observer) stays a failed trajectory."""
    N, failures = spec.prep.n_steps, []
    for k, j in enumerate(np.flatnonzero(status < N)):
        j = int(j)
        if spec.draws == "device":   # simulate would draw other noise: the run is reported whole
            failures.append((j, f"left |x| <= {spec.bound:g} after t = {status[j] * spec.prep.dt:.6g} (not re-run: its "
                                "noise was drawn on the device, draws='device')"))
            continue
        if k >= RERUN_LIMIT:
            failures.append((j, f"left |x| <= {spec.bound:g} after t = {status[j] * spec.prep.dt:.6g} (not re-run: more than "
                                f"{RERUN_LIMIT} runs stopped)"))
            continue
        try:
            r = spec.rerun(j, inputs)
        except (FiniteEscapeError, SolverError) as err:
            failures.append((j, str(err).split(". Check")[0]))
            continue
        x[j] = r.x[steps, :x.shape[2]]
        for name, xh in xhats.items():
            if name in r.failures:
                observer_failed[name][j] = True
                xh[j] = np.nan
                failures.append((j, f"observer {name!r} {r.failures[name].reason}"))
            else:
                xh[j] = r.observers[name].xhat[steps, :xh.shape[2]]
        status[j] = N
    return failures
