"""Observers on recorded data: arrays or a CSV of t, u, y (and, optionally, the true states)."""

from __future__ import annotations

import csv
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..design import check_positive
from ..engine import Backend
from ..errors import (DataError, EngineError, FiniteEscapeError, ModelError, ShapeError, SolverError,
                      TimeBudgetError)
from ..model import ModelFile, System
from ..observer import AbstractObserver, ParticleObserver, compiled_observer
from ..simulate._isolate import each_observer, failure_of
from ..simulate._options import xhat0_for as _xhat0_for
from ..simulate._results import ObserverTrace, Run
from ..simulate._run import named_observers

__all__ = ["Recording", "estimate"]


@dataclass(frozen=True, eq=False)
class Recording:
    """Recorded signals on sample times ``t`` (time on the first axis).

    NaN in `y` marks a sample not taken: per-output clocks (each output measured at regular times of its own,
    a multi-rate recording) are accepted as they are; other missing samples only with ``on_missing="skip"`` in
    :func:`estimate`. NaN or inf anywhere else is rejected with its row and column.
    """

    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    x: np.ndarray | None = None
    state_names: tuple[str, ...] = ()
    source: str = "arrays"

    @classmethod
    def from_arrays(cls, system: System, t: Any, y: Any, u: Any = None, x: Any = None, *, source: str = "arrays") -> Recording:
        """Check and wrap arrays: t (N,), y (N, p), u (N, m), optional true states x (N, n)."""
        t_ = np.asarray(t, dtype=float).reshape(-1)
        N = t_.size
        if N < 2:
            raise ShapeError(f"recording ({source}): a recording needs at least 2 samples (rows of data), got {N}; "
                             "record more samples or check the file's rows")

        def mat(v: Any, k: int, name: str) -> np.ndarray:
            a = np.zeros((N, 0)) if v is None and k == 0 else np.asarray(v, dtype=float)
            if a.ndim == 1 and k == 1:
                a = a.reshape(-1, 1)
            if a.shape != (N, k):
                raise ShapeError(f"recording: `{name}` must have shape ({N}, {k}) for the model {system.name!r}, found {a.shape}")
            return a

        if u is None and system.n_inputs:
            raise ShapeError(f"recording: the model {system.name!r} has inputs {list(system.inputs)}; pass `u`")
        rec = cls(t_, mat(u, system.n_inputs, "u"), mat(y, system.n_outputs, "y"), system.inputs, system.outputs,
                  None if x is None else mat(x, system.n_states, "x"), system.states if x is not None else (), source)
        rec._check_time()
        return rec

    @classmethod
    def from_csv(cls, path: str | Path, system: System | ModelFile, *, columns: Mapping[str, str] | None = None,
                 require_outputs: bool = True) -> Recording:
        """Read a CSV whose header names ``t``, the model's outputs and inputs, and optionally its states.

        Empty cells and ``nan`` mark missing output samples. Other columns are ignored. The file
        must be UTF-8 (a byte-order mark is accepted). A model file stands for its system.

        Parameters
        ----------
        path : str or Path
        system : System or ModelFile
        columns : mapping of CSV column name to model name, optional
            For files whose header does not use the model's names, e.g.
            ``{"time": "t", "level_2": "y2"}``.
        require_outputs : bool
            With False, output columns may be absent (they read as missing): a recorded input
            to drive a simulation.
        """
        system = system.system if isinstance(system, ModelFile) else system
        p = Path(path)
        try:
            with p.open(newline="", encoding="utf-8-sig") as fh:
                reader = csv.reader(fh)
                rows = list(reader)
        except OSError as e:
            raise DataError(f"cannot read the recording {p}: {e.strerror}") from None
        except UnicodeDecodeError as e:
            raise DataError(f"{p}: not a UTF-8 text file (byte {e.object[e.start]:#04x} at offset {e.start} cannot be decoded); "
                            "save the CSV as UTF-8 (e.g. from a spreadsheet: CSV UTF-8)") from None
        except csv.Error as e:
            if "field limit" in str(e):   # the csv module's field_size_limit (131072 characters by default)
                raise DataError(f"{p}, line {reader.line_num}: a field is longer than {csv.field_size_limit()} characters, which "
                                "a CSV of numbers never needs; check the delimiter (',') and the line endings of the file") from None
            raise DataError(f"{p}: not a readable CSV file ({e})") from None
        if not rows:
            raise DataError(f"{p}: the file is empty; expected a header naming t, {', '.join(system.outputs)}")
        header = [h.strip() for h in rows[0]]
        header = _rename_columns(p, header, columns, system)
        seen: dict[str, int] = {}
        for j, h in enumerate(header):
            if h in seen and h != "":
                raise DataError(f"{p}: column {h!r} appears twice in the header"
                                + (" after the column mapping" if columns else "")
                                + f" (columns {seen[h] + 1} and {j + 1}); rename or remove one")
            seen[h] = j
        need = ["t", *system.outputs, *system.inputs]
        missing = [h for h in need if h not in header and (require_outputs or h not in system.outputs)]
        if missing:
            raise DataError(f"{p}: the header lacks column(s) {', '.join(missing)}; it must name t, the outputs "
                            f"({', '.join(system.outputs)}) and the inputs ({', '.join(system.inputs) or 'none'}); found "
                            f"{_shown(header)}"
                            + ("" if columns else "; map other names with `columns` (command line: --column CSV=MODEL)"))
        data = np.full((len(rows) - 1, len(header)), np.nan)
        used = {h: j for h, j in seen.items() if h in need or h in system.states}
        for i, row in enumerate(rows[1:]):
            if len(row) != len(header):
                raise DataError(f"{p}, line {i + 2}: {len(row)} field(s), the header has {len(header)}")
            for h, j in used.items():
                cell = row[j].strip()
                if cell == "":
                    continue
                try:
                    data[i, j] = float(cell)
                except ValueError:
                    raise DataError(f"{p}, line {i + 2}, column {h!r}: {_shown(cell)} is not a number") from None
        col = {h: data[:, j] for h, j in used.items()}
        for o in system.outputs:
            col.setdefault(o, np.full(data.shape[0], np.nan))
        has_x = all(s in header for s in system.states)
        return cls.from_arrays(
            system, col["t"], np.column_stack([col[o] for o in system.outputs]),
            np.column_stack([col[u] for u in system.inputs]) if system.inputs else None,
            np.column_stack([col[s] for s in system.states]) if has_x else None, source=str(p))

    @classmethod
    def from_run(cls, run: Run, *, every: int = 1) -> Recording:
        """The measured signals of a simulation (every `every`-th sample), with its true states."""
        sl = slice(None, None, every)
        return cls(run.t[sl].copy(), run.u[sl].copy(), run.y[sl].copy(), run.input_names, run.output_names,
                   None if run.x is None else run.x[sl].copy(), run.state_names if run.x is not None else (), f"run of {run.model}")

    def _check_time(self) -> None:
        bad = np.flatnonzero(~np.isfinite(self.t))
        if bad.size:
            raise DataError(f"recording ({self.source}): t is {self.t[bad[0]]} at row {bad[0]}; times must be finite")
        with np.errstate(over="ignore"):
            span = self.t[-1] - self.t[0]
        if not np.isfinite(span):
            raise DataError(f"recording ({self.source}): the times span from {self.t[0]:g} to {self.t[-1]:g}, which overflows; "
                            "check the time column (units, a stray value in the first or last row)")
        back = np.flatnonzero(np.diff(self.t) <= 0)
        if back.size:
            k = back[0]
            raise DataError(f"recording ({self.source}): time does not increase at row {k + 1} "
                            f"(t = {self.t[k]:g} then {self.t[k + 1]:g}); sort the samples or remove duplicates")

    def clocked(self) -> bool:
        """Whether the missing outputs (NaN) are per-output clocks: each output is measured at regular times of its
        own (a multi-rate recording: a GPS at 1 s beside a wheel encoder at 10 ms; a 200 Hz input beside a 50 Hz
        sensor, its rows between the sensor's samples carrying the input only). Such NaN cells mean "not measured at
        this row" and need no ``on_missing='skip'``; a dropped sample breaks its output's clock, and so does a clock that
        stops before the end of the recording."""
        finite = np.isfinite(self.y)
        if not finite.any():
            return False
        for j in np.flatnonzero(~finite.all(axis=0)):
            times = self.t[finite[:, j]]
            if times.size < 2:
                return False
            d = np.diff(times)
            if np.max(np.abs(d - d[0])) > 1e-6 * d[0]:
                return False
            # the clock runs to the end of the recording: a sensor that stops has missing samples (one that starts late
            # is a delayed sensor, whose first sample arrives after its latency)
            if times[-1] < self.t[-1] - d[0] * (1 + 1e-6):
                return False
        return True

    def check_columns(self, system: Any, where: str) -> None:
        """ModelError unless the recording has `system`'s outputs and inputs, in its order (`where` opens the message)."""
        if tuple(system.outputs) != tuple(self.output_names) or tuple(system.inputs) != tuple(self.input_names):
            raise ModelError(f"{where} expects outputs {list(system.outputs)} and inputs {list(system.inputs)}; "
                             f"the recording has {list(self.output_names)} and {list(self.input_names)}")

    def check_finite(self, on_missing: str) -> np.ndarray:
        """The mask of measured outputs (1 = measured), after rejecting what may not be missing."""
        for name, arr, names in (("u", self.u, self.input_names), ("x", self.x, self.state_names)):
            if arr is None or np.isfinite(arr).all():
                continue
            bad = np.argwhere(~np.isfinite(arr))
            if bad.size:
                r, c = bad[0]
                raise DataError(f"recording ({self.source}): input/state {names[c]!r} is {arr[r, c]} at row {r} (t = {self.t[r]:g}); "
                                "inputs and states must be finite")
        finite = np.isfinite(self.y)
        if finite.all():
            return finite.astype(float)
        inf = np.argwhere(np.isinf(self.y))
        if inf.size:
            r, c = inf[0]
            raise DataError(f"recording ({self.source}): output {self.output_names[c]!r} is {self.y[r, c]} at row {r} (t = {self.t[r]:g})")
        nan = np.argwhere(np.isnan(self.y))
        if nan.size and on_missing == "error" and not self.clocked():
            r, c = nan[0]
            raise DataError(f"recording ({self.source}): output {self.output_names[c]!r} is missing (NaN) at row {r} (t = {self.t[r]:g}), "
                            f"{len(nan)} missing value(s) in all; to leave them out of the observer's update pass "
                            "on_missing='skip' (command line: --skip-missing)")
        return np.isfinite(self.y).astype(float)


def _shown(value: Any, limit: int = 80) -> str:
    """`value` as it may appear in an error message: its repr, cut to `limit` characters."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 12] + f"... ({len(text)} characters)"


def _rename_columns(path: Path, header: list[str], columns: Mapping[str, str] | None, system: System) -> list[str]:
    """The header with CSV names replaced by model names (`columns`: CSV name -> model name)."""
    if not columns:
        return header
    targets = {"t", *system.outputs, *system.inputs, *system.states}
    for src, dst in columns.items():
        if src not in header:
            raise DataError(f"{path}: the column mapping names {src!r}, which is not in the header {_shown(header)}")
        if dst not in targets:
            raise DataError(f"{path}: the column mapping sends {src!r} to {dst!r}, which is not t, an output, an input or a "
                            f"state of {system.name!r} ({', '.join(sorted(targets))})")
    dsts = list(columns.values())
    twice = sorted({d for d in dsts if dsts.count(d) > 1})
    if twice:
        raise DataError(f"{path}: the column mapping sends two columns to {twice[0]!r}")
    return [columns.get(h, h) for h in header]


def estimate(
    observers: Any,
    recording: Recording,
    *,
    xhat0: Mapping[str, Sequence[float]] | Sequence[float] | None = None,
    max_step: float | None = None,
    on_missing: Literal["error", "skip"] = "error",
    hold: Literal["zoh", "linear"] = "zoh",
    engine: Backend = "auto",
    progress: bool | Callable[[float], None] | None = None,
    smooth: bool = False,
    delay: Mapping[str, float] | None = None,
) -> Run:
    """Run observers on recorded data (filtering, or with ``smooth=True`` fixed-interval smoothing).

    Between samples each observer integrates its flow with the last sample of u and y held
    (zero-order hold), in RK4 steps chosen per interval at run time: no longer than `max_step`,
    and short enough that h·ρ ≤ 1 for the fastest rate ρ of the observer's flow, measured as the
    run goes (the default time scale: 1/ρ, with ρ at the start the spectral radius of ∂F/∂z at the
    initial estimate). An interval whose steps turn out too long for the rate met inside it (a
    stiff covariance equation, a fast transient) is integrated again with shorter steps, so the
    state cannot inflate silently between samples; a gap needing more than 10⁸ steps is refused.
    At each sample the continuous-discrete observers apply their update. Irregular sample times
    are allowed. ``Run.info["integration"]`` reports, per observer, the RK4 steps taken, the most
    in one interval, the fastest rate met, and the engine.

    The observer's functions are built once per design (and their C code compiled once per
    machine), so repeated calls only run; :meth:`nlobs.Observer.compiled` gives the same prepared
    observer as an object.

    Parameters
    ----------
    observers : observer, design, or a mapping/sequence of them
    recording : Recording
    xhat0 : mapping of name to vector, or one vector, optional
        Initial estimates (default: each design's).
    max_step : float, optional
        Largest RK4 step between samples (default: set by the observer's own time scale, above).
    on_missing : {"error", "skip"}
        With ``"skip"``, NaN output samples are left out of the update (the prediction carries
        on; a continuous observer sees its own predicted output for the missing component).
    hold : {"zoh", "linear"}
        How the measurement and the input are held between samples: zero-order hold (causal,
        as in a real loop) or linear interpolation to the next sample (offline only; more
        accurate when the signals change fast between samples).
    engine : {"auto", "vm", "c"}
        Numeric backend (see :func:`nlobs.simulate`).
    progress : bool or callable, optional
        Show progress on stderr (True; one bar per observer) or call ``progress(fraction)`` with the
        fraction of all the observers' work done.
    smooth : bool
        Smooth the whole recording after filtering it (fixed-interval Rauch-Tung-Striebel
        smoother on the sample grid; unscented RTS for the UKF): each estimate then uses the samples
        after it as well as those before. For the continuous-discrete ``ekf`` and ``ukf`` without
        bounds; other kinds are refused. The smoother's prediction is the filter's own: the RK4 map
        it integrates between samples (same sub-steps), linearised by its exact Jacobian (EKF) or
        statistically (UKF); see :mod:`nlobs.estimation._smooth`.
    delay : mapping of output name to seconds, optional
        Known measurement delays: the recording is stamped when each sample *arrived*, and a delayed output's
        value in a row was measured `delay` seconds earlier. The continuous-discrete observers apply it at the
        time it was taken (filter recalculation from a state history, :mod:`nlobs.simulate._delays`); the
        estimate at each row uses the samples that have arrived by then.

    Returns
    -------
    Run
        With the recording's true states when it has them (then errors and metrics work), and
        each observer's innovations y_k − h(x̂_k⁻) (:meth:`Run.innovations`, :meth:`Run.whiteness`):
        what recorded data without states can tell about an observer. Smoothed: each trace's
        ``xhat`` holds the smoothed estimates, ``filtered`` the filter's, ``smoothed_covariance``
        the smoothed covariance (N, n, n) and ``std`` its standard deviations; the innovations
        are the filter's.

    Raises
    ------
    DataError
        For NaN/inf in the data (with the row and column) unless skipped, or non-increasing time;
        for a gap that would need more than 10⁸ RK4 steps (with its time and length).
    FiniteEscapeError
        When an observer's state becomes non-finite: with the observer, the two samples and
        the step where it happened (never NaN estimates in a result).
    """
    if hold not in ("zoh", "linear"):
        raise ValueError(f"estimate: `hold` must be 'zoh' or 'linear', got {hold!r}")
    if on_missing not in ("error", "skip"):
        raise ValueError(f"estimate: `on_missing` must be 'error' or 'skip', got {on_missing!r}")
    if not isinstance(recording, Recording):
        raise TypeError(f"estimate: `recording` must be an nlobs.Recording (Recording.from_csv / from_arrays), "
                        f"got {type(recording).__name__}")
    if max_step is not None:
        max_step = check_positive(max_step, "max_step", "estimate")
    obs = named_observers(observers)
    if not obs:
        raise ModelError("estimate: give at least one observer")
    for name, o in obs.items():
        recording.check_columns(o.system, f"estimate: observer {name!r}")
    if smooth and not any(o.system.is_discrete for o in obs.values()):   # maps: checked by _estimate_map
        from ._smooth import check_smoothable
        for name, o in obs.items():
            check_smoothable(o.design, name)
    mask = recording.check_finite(on_missing)
    y0 = np.where(mask > 0, recording.y, 0.0)
    t, u = recording.t, recording.u
    if any(o.system.is_discrete for o in obs.values()):
        if delay and any(float(v) > 0 for v in delay.values()):
            raise ModelError("estimate: measurement delays are handled for continuous-time models (a late sample is "
                             "applied at the time it was taken, between two steps of the flow); a discrete-time model "
                             "steps from sample to sample: shift the delayed output's column by its delay in steps instead")
        return _estimate_map(obs, recording, t, u, y0, mask, xhat0, smooth)
    if delay and any(float(v) > 0 for v in delay.values()):
        return _estimate_delayed(obs, recording, delay, mask, xhat0, max_step, smooth, engine)
    traces, integration, failures, first = {}, {}, {}, None
    names = list(obs)

    reached = dict.fromkeys(names, 0.0)   # each observer's fraction: the mean never goes back (they run side by side)

    def one(name: str) -> Any:
        def moved(f: float) -> None:
            reached[name] = f
            progress(sum(reached.values()) / len(reached))   # type: ignore[operator,misc]
        part = progress if progress is None or isinstance(progress, bool) else moved
        return _estimate_one(name, obs[name], recording, xhat0, y0, mask, hold, max_step, engine, smooth, part)

    done = each_observer(names, one, alone=[k for k, o in obs.items() if getattr(o.design, "needs_mx", False)])
    for name, o in obs.items():
        res = done[name]
        if isinstance(res, BaseException):   # the others keep their results; when all fail, the first error
            if not isinstance(res, (FiniteEscapeError, SolverError, DataError, EngineError, TimeBudgetError)):
                raise res
            failures[name] = failure_of(name, o.design.method, res)
            first = first or res
        else:
            traces[name], integration[name] = res
    if not traces:
        raise first  # type: ignore[misc]
    system = next(iter(obs.values())).system
    return Run(f"{system.name} (recorded: {recording.source})", t, system.states, recording.input_names, recording.output_names,
               u, recording.y, traces, x=recording.x,
               info={"max_step": max_step, "substeps": max(v["max_substeps"] for v in integration.values()),
                     "integration": integration, "on_missing": on_missing, "hold": hold, "smoothed": bool(smooth)},
               estimated_params=system.estimated_params, failures=failures)


def _estimate_one(name: str, o: AbstractObserver, recording: Recording, xhat0: Any, y0: np.ndarray, mask: np.ndarray,
                  hold: str, max_step: float | None, engine: Any, smooth: bool,
                  part: Callable[[float], None] | bool | None) -> tuple[ObserverTrace, dict[str, Any]]:
    """One observer on the recording: its trace and how it was integrated."""
    t, u = recording.t, recording.u
    # built once per design and cached (see Observer.compiled); the C code is cached on disk
    z0 = o.initial_state(_xhat0_for(xhat0, name, o.system.n_states))
    if isinstance(o, ParticleObserver):  # a random particle cloud, run over the samples at once
        pr, yp = o.trace_on(t, y0, u, mask=mask, xhat0=z0, name=name)
        trace = ObserverTrace(name, o.design.method, o.design.z_names, pr.z, pr.xhat, pr.xhat_prior[0],
                              innovation=np.where(mask > 0, recording.y - yp, np.nan), covariance=o.design.covariance)
        return trace, {"substeps": 0, "max_substeps": 1, "fastest_rate": 0.0, "engine": "c",
                       "particles": o.design.particles, "min_ess": float(pr.ess.min()), "resampled": int(pr.resampled.sum())}
    prepared = compiled_observer(o.design, hold)
    complete = bool(mask.all())   # every output measured at every row (y0 is then the recording's y)
    try:
        traj = prepared.run(t, u=u, y=y0, mask=None if complete else mask, z0=z0, max_step=max_step, engine=engine,
                            name=name, progress=part)
    except FiniteEscapeError as e:
        if getattr(e, "interval", None) is None:
            raise
        raise _non_finite(name, o, recording, e) from None
    except DataError as e:   # an interval too long to integrate: name the recording it comes from
        raise DataError(f"recording ({recording.source}): {e}") from None
    # (an estimate that is part of the internal state is finite: the run checked every state)
    bad = np.empty((0, 2), dtype=int) if prepared.selects_state or np.isfinite(traj.xhat).all() else \
        np.argwhere(~np.isfinite(traj.xhat))
    if bad.size:  # the internal state is finite, but the estimate read from it is not
        r, c = (int(v) for v in bad[0])
        raise FiniteEscapeError(f"observer {name!r}", float(t[r]), traj.z[r], o.design.z_names, np.inf,
                                message=f"observer {name!r} on the recording {recording.source}: its estimate of "
                                        f"{o.system.states[c]} is {traj.xhat[r, c]} at t = {t[r]:.6g} (row {r}) although its "
                                        "internal state is finite; check the observer's output map x̂ = H(t, z, u, y)")
    innovation = recording.y - traj.yhat_prior
    if not complete:
        innovation[mask == 0] = np.nan
    smoothed: dict[str, Any] = {}
    info = traj.info()
    xs = traj.xhat
    if smooth:
        from ._smooth import rts_smooth
        try:
            xs, Ps, how = rts_smooth(o.design, traj, u, y0, mask, hold=hold, engine=engine)
        except FiniteEscapeError as e:  # a diverged backward pass: never smoothed numbers in a result
            raise FiniteEscapeError(f"observer {name!r}", e.t, e.x, o.system.states, np.inf,
                                    message=f"observer {name!r} on the recording {recording.source}: {e}") from None
        smoothed = {"filtered": traj.xhat, "smoothed_covariance": Ps}
        info.update(smoother="urts" if o.design.method == "ukf" else "rts", **how)
    return ObserverTrace(name, o.design.method, o.design.z_names, traj.z, xs, traj.xhat_prior, innovation=innovation,
                         covariance=getattr(o.design, "covariance", None), **smoothed), info


def _estimate_delayed(obs: Mapping[str, Any], rec: Recording, delay: Mapping[str, float], mask: np.ndarray, xhat0: Any,
                      max_step: float | None, smooth: bool, engine: Backend = "auto") -> Run:
    """Observers on a recording stamped at arrival, with the delayed samples applied when they were taken."""
    from ..simulate._delays import TOL, plan
    from ..simulate._isolate import run_all_delayed
    from ..simulate._schedule import SampleSchedule

    if smooth:
        raise ModelError("estimate: smoothing a recording with measurement delays is not supported (the smoother "
                         "uses every sample at its row); estimate without `smooth`, or without `delay`")
    # the recording's schedule: its measured cells, stamped when they arrived, each taken its output's delay earlier
    schedule = SampleSchedule.of_recording(rec.t, mask > 0, rec.output_names, delay=delay, caller="estimate")
    events = schedule.events(rec.y)
    the_plan = plan(rec.t, rec.u, events, rec.y.shape[1])
    z0s = {name: o.initial_state(_xhat0_for(xhat0, name, o.system.n_states)) for name, o in obs.items()}
    traces, failures = run_all_delayed(obs, rec.t, rec.u, np.zeros(rec.y.shape[1]), events, z0s, the_plan=the_plan,
                                       engine=engine, max_step=max_step)
    system = next(iter(obs.values())).system
    early = int(np.sum(events.taken < rec.t[0] - TOL * max(1.0, abs(float(rec.t[0])))))
    notes = ([f"{early} delayed sample(s) taken before the recording's first time were left out"] if early else [])
    return Run(f"{system.name} (recorded: {rec.source})", rec.t, system.states, rec.input_names, rec.output_names,
               rec.u, rec.y, traces, x=rec.x, info={"delay": {k: float(v) for k, v in delay.items()}, "notes": notes,
                                                    "max_step": max_step, "replayed": the_plan.replayed},
               estimated_params=system.estimated_params, failures=failures)


def _non_finite(name: str, o: AbstractObserver, rec: Recording, err: FiniteEscapeError) -> FiniteEscapeError:
    """The observer's blow-up told with the samples and the data around it (err.interval: -1 for the first sample,
    k for the step from sample k to sample k + 1)."""
    k, t = err.interval, rec.t
    names = o.design.z_names
    last = ", ".join(f"{n}={v:.6g}" for n, v in zip(names, err.x))

    def data(i: int) -> str:
        return ", ".join(f"{n} = {v:.6g}" for n, v in zip(rec.output_names + rec.input_names, np.r_[rec.y[i], rec.u[i]]))

    if k < 0:
        what = f"at its first sample (t = {t[0]:.6g}, row 0; {data(0)})"
    else:
        what = (f"in the step from the sample at t = {t[k]:.6g} (row {k}; {data(k)}) to the sample at "
                f"t = {t[k + 1]:.6g} (row {k + 1}; {data(k + 1)}), a step of {t[k + 1] - t[k]:.6g} s"
                + (f" ({err.substeps} RK4 steps)" if getattr(err, "substeps", None) else ""))
    out = FiniteEscapeError(f"observer {name!r}", err.t, err.x, names, np.inf,
                            message=(f"observer {name!r} on the recording {rec.source}: its state became non-finite {what}; "
                                     f"last finite state: {last}. Check that sample (units, outliers, a gap in time) "
                                     "or pass a smaller max_step (command line: --max-step)"))
    out.interval = k
    return out


def _estimate_map(obs: Mapping[str, Any], recording: Recording, t: np.ndarray, u: np.ndarray, y0: np.ndarray,
                  mask: np.ndarray, xhat0: Any, smooth: bool) -> Run:
    """Observers of a discrete-time model on a recording on its grid: :func:`nlobs.estimation._map.estimate_map`."""
    from ._map import estimate_map

    return estimate_map(obs, recording, t, u, y0, mask, xhat0, smooth)
