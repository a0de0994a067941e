"""Observers on recorded data: arrays or a CSV of t, u, y (and, optionally, the true states)."""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import casadi as ca
import numpy as np

from ..design import check_positive
from ..engine import Backend, StepRunner, compile_system, evaluate_many, rk4_step, rows
from ..errors import DataError, FiniteEscapeError, ModelError, ShapeError
from ..model import System
from ..observer import AbstractObserver
from ._results import ObserverTrace, Run
from ._run import _xhat0_for, named_observers

__all__ = ["Recording", "estimate"]


@dataclass(frozen=True, eq=False)
class Recording:
    """Recorded signals on sample times ``t`` (time on the first axis).

    NaN in `y` marks a missing sample (allowed only with ``on_missing="skip"`` in
    :func:`estimate`); NaN or inf anywhere else is rejected with its row and column.
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
            raise ShapeError(f"a recording needs at least 2 samples, got {N}")

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
    def from_csv(cls, path: str | Path, system: System, *, columns: Mapping[str, str] | None = None,
                 require_outputs: bool = True) -> Recording:
        """Read a CSV whose header names ``t``, the model's outputs and inputs, and optionally its states.

        Empty cells and ``nan`` mark missing output samples. Other columns are ignored. The file
        must be UTF-8 (a byte-order mark is accepted).

        Parameters
        ----------
        path : str or Path
        system : System
        columns : mapping of CSV column name to model name, optional
            For files whose header does not use the model's names, e.g.
            ``{"time": "t", "level_2": "y2"}``.
        require_outputs : bool
            With False, output columns may be absent (they read as missing): a recorded input
            to drive a simulation.
        """
        p = Path(path)
        try:
            with p.open(newline="", encoding="utf-8-sig") as fh:
                rows = list(csv.reader(fh))
        except OSError as e:
            raise DataError(f"cannot read the recording {p}: {e.strerror}") from None
        except UnicodeDecodeError as e:
            raise DataError(f"{p}: not a UTF-8 text file (byte {e.object[e.start]:#04x} at offset {e.start} cannot be decoded); "
                            "save the CSV as UTF-8 (e.g. from a spreadsheet: CSV UTF-8)") from None
        except csv.Error as e:
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

    def check_finite(self, on_missing: str) -> np.ndarray:
        """The mask of measured outputs (1 = measured), after rejecting what may not be missing."""
        for name, arr, names in (("u", self.u, self.input_names), ("x", self.x, self.state_names)):
            if arr is None:
                continue
            bad = np.argwhere(~np.isfinite(arr))
            if bad.size:
                r, c = bad[0]
                raise DataError(f"recording ({self.source}): input/state {names[c]!r} is {arr[r, c]} at row {r} (t = {self.t[r]:g}); "
                                "inputs and states must be finite")
        inf = np.argwhere(np.isinf(self.y))
        if inf.size:
            r, c = inf[0]
            raise DataError(f"recording ({self.source}): output {self.output_names[c]!r} is {self.y[r, c]} at row {r} (t = {self.t[r]:g})")
        nan = np.argwhere(np.isnan(self.y))
        if nan.size and on_missing == "error":
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
) -> Run:
    """Run observers on recorded data.

    Between samples each observer integrates its flow with the last sample of u and y held
    (zero-order hold), in RK4 steps no longer than `max_step` (default: one step per sample
    interval); at each sample the continuous-discrete observers apply their update.
    Irregular sample times are allowed.

    Parameters
    ----------
    observers : observer, design, or a mapping/sequence of them
    recording : Recording
    xhat0 : mapping of name to vector, or one vector, optional
        Initial estimates (default: each design's).
    max_step : float, optional
        Largest RK4 step between samples.
    on_missing : {"error", "skip"}
        With ``"skip"``, NaN output samples are left out of the update (the prediction carries
        on; a continuous observer sees its own predicted output for the missing component).
    hold : {"zoh", "linear"}
        How the measurement and the input are held between samples: zero-order hold (causal,
        as in a real loop) or linear interpolation to the next sample (offline only; more
        accurate when the signals change fast between samples).
    engine : {"auto", "vm", "c"}
        Numeric backend (see :func:`nlobs.simulate`).

    Returns
    -------
    Run
        With the recording's true states when it has them (then errors and metrics work), and
        each observer's innovations y_k − h(x̂_k⁻) (:meth:`Run.innovations`, :meth:`Run.whiteness`):
        what recorded data without states can tell about an observer.

    Raises
    ------
    DataError
        For NaN/inf in the data (with the row and column) unless skipped, or non-increasing time.
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
        s = o.system
        if tuple(s.outputs) != recording.output_names or tuple(s.inputs) != recording.input_names:
            raise ModelError(f"estimate: observer {name!r} expects outputs {list(s.outputs)} and inputs {list(s.inputs)}; "
                             f"the recording has {list(recording.output_names)} and {list(recording.input_names)}")
    mask = recording.check_finite(on_missing)
    y0 = np.where(mask > 0, recording.y, 0.0)
    t, u = recording.t, recording.u
    dts = np.diff(t)
    n_sub = 1 if max_step is None else max(1, int(np.ceil(dts.max() / max_step - 1e-9)))
    step, fill = _estimation_step(obs, n_sub, linear=hold == "linear")
    A = np.hstack([t[:-1, None], dts[:, None], u[:-1], y0[:-1], mask[:-1], u[1:], y0[1:], mask[1:]])
    z0, priors = [], {}
    for name, o in obs.items():
        z = o.initial_state(_xhat0_for(xhat0, name, o.system.n_states))
        priors[name] = o.estimate(t[0], z, u[0], y0[0])
        z0.append(z)
    prior_z0 = np.concatenate(z0)
    s0 = np.concatenate([o.update(t[0], z, u[0], y0[0], mask[0]) if o.sampled else z for z, o in zip(z0, obs.values())])
    bad0 = np.flatnonzero(~np.isfinite(s0))
    if bad0.size:
        _raise_non_finite(obs, recording, 0, int(bad0[0]), prior_z0, s0, first=True)
    states, before, done = StepRunner(step, backend=engine).run(s0, A, np.zeros(1))
    if done < len(A):
        bad = int(np.flatnonzero(~np.isfinite(states[done]))[0])
        _raise_non_finite(obs, recording, done + 1, bad, states[done - 1] if done else s0, states[done])
    S = np.vstack([s0, states])
    Z_prior = np.vstack([prior_z0, before])  # z at each sample before its update
    traces = {}
    off = 0
    for name, o in obs.items():
        sl = slice(off, off + o.n_z)
        z = S[:, sl]
        off += o.n_z
        y_used = evaluate_many(fill[name], t[:, None], z, u, y0, mask) if (mask < 1).any() else y0
        xhat = evaluate_many(o.design.output, t[:, None], z, u, y_used)
        bad = np.argwhere(~np.isfinite(xhat))
        if bad.size:  # the internal state is finite, but the estimate read from it is not
            r, c = (int(v) for v in bad[0])
            raise FiniteEscapeError(f"observer {name!r}", float(t[r]), z[r], o.design.z_names, np.inf,
                                    message=f"observer {name!r} on the recording {recording.source}: its estimate of "
                                            f"{o.system.states[c]} is {xhat[r, c]} at t = {t[r]:.6g} (row {r}) although its "
                                            "internal state is finite; check the observer's output map x̂ = H(t, z, u, y)")
        traces[name] = ObserverTrace(name, o.design.method, o.design.z_names, z, xhat, priors[name],
                                     innovation=_innovations(o, t, Z_prior[:, sl], u, y_used, mask, recording.y))
    system = next(iter(obs.values())).system
    return Run(f"{system.name} (recorded: {recording.source})", t, system.states, recording.input_names, recording.output_names,
               u, recording.y, traces, x=recording.x, info={"max_step": max_step, "substeps": n_sub, "on_missing": on_missing, "hold": hold})


def _innovations(o: AbstractObserver, t: np.ndarray, z_prior: np.ndarray, u: np.ndarray, y_used: np.ndarray, mask: np.ndarray,
                 y: np.ndarray) -> np.ndarray:
    """y_k − h(t_k, x̂_k⁻, u_k): each sample against the output predicted before it was used (NaN where missing).

    x̂_k⁻ = H(t_k, z_k⁻, u_k, y_{k−1}): the internal state before the update at t_k, read with the measurement the
    flow held until then (an estimate that depends on y would otherwise see y_k itself)."""
    _, h = compile_system(o.system).bind()
    y_held = np.vstack([y_used[:1], y_used[:-1]])
    xhat_prior = evaluate_many(o.design.output, t[:, None], z_prior, u, y_held)
    yhat = evaluate_many(h, t[:, None], xhat_prior, u)
    return np.where(mask > 0, y - yhat, np.nan)


def _raise_non_finite(obs: Mapping[str, AbstractObserver], rec: Recording, row: int, col: int, last: np.ndarray, bad: np.ndarray,
                      *, first: bool = False) -> None:
    """Stop with the observer, the sample and the data that made its state non-finite."""
    off = 0
    for name, o in obs.items():
        if off <= col < off + o.n_z:
            break
        off += o.n_z
    names = o.design.z_names
    z_bad = names[col - off]
    t = rec.t

    def data(k: int) -> str:
        return ", ".join(f"{n} = {v:.6g}" for n, v in zip(rec.output_names + rec.input_names, np.r_[rec.y[k], rec.u[k]]))

    if first:
        what = f"at its first sample (t = {t[0]:.6g}, row 0; {data(0)})"
    else:
        what = (f"in the step from the sample at t = {t[row - 1]:.6g} (row {row - 1}; {data(row - 1)}) to the sample at "
                f"t = {t[row]:.6g} (row {row}; {data(row)}), a step of {t[row] - t[row - 1]:.6g} s")
    last_ = ", ".join(f"{n}={v:.6g}" for n, v in zip(names, last[off:off + o.n_z]))
    raise FiniteEscapeError(f"observer {name!r}", float(t[max(row - 1, 0)]), last[off:off + o.n_z], names, np.inf,
                            message=(f"observer {name!r} on the recording {rec.source}: its state {z_bad} became "
                                     f"{bad[col]} {what}; last finite state: {last_}. Check that sample (units, outliers, a gap in time) "
                                     "or pass a smaller max_step (command line: --max-step)"))


def _estimation_step(obs: Mapping[str, AbstractObserver], n_sub: int, *, linear: bool) -> tuple[ca.Function, dict[str, ca.Function]]:
    first = next(iter(obs.values())).system
    nu, ny = first.n_inputs, first.n_outputs
    ns = sum(o.n_z for o in obs.values())
    X = ca.MX if any(o.design.needs_mx for o in obs.values()) else ca.SX  # MHE's update embeds an NLP: MX graph
    s = X.sym("s", ns)
    a = X.sym("a", 2 + 2 * (nu + 2 * ny))
    t, dt = a[0], a[1]
    u0, y0, m0 = rows(a, 2, 2 + nu), rows(a, 2 + nu, 2 + nu + ny), rows(a, 2 + nu + ny, 2 + nu + 2 * ny)
    o1 = 2 + nu + 2 * ny
    u1, y1, m1 = rows(a, o1, o1 + nu), rows(a, o1 + nu, o1 + nu + ny), rows(a, o1 + nu + ny, o1 + nu + 2 * ny)
    parts, priors, fills = [], [], {}
    off = 0
    for name, o in obs.items():
        d = o.design
        z = rows(s, off, off + o.n_z)
        off += o.n_z
        _, h = compile_system(o.system).bind()
        zz, tt, uu, yy, mm = ca.SX.sym("z", o.n_z), ca.SX.sym("t"), ca.SX.sym("u", nu), ca.SX.sym("y", ny), ca.SX.sym("m", ny)
        yhat = h(tt, d.output(tt, zz, uu, yy), uu)
        fill = ca.Function(f"{d.method}_fill", [tt, zz, uu, yy, mm], [mm * yy + (1 - mm) * yhat])
        fills[name] = fill
        y_use = fill(t, z, u0, y0, m0)
        # first-order hold (y where both ends were measured, and u), else the held (or predicted) value
        slope = (m0 * m1) * (y1 - y_use) / dt if linear else ca.DM.zeros(ny)
        u_slope = (u1 - u0) / dt if linear else ca.DM.zeros(nu)

        def rhs(t_: ca.SX, z_: ca.SX, _k: int, d=d, y_use=y_use, slope=slope, u_slope=u_slope) -> ca.SX:
            return d.flow(t_, z_, u0 + (t_ - t) * u_slope, y_use + (t_ - t) * slope)

        h_ = dt / n_sub
        for i in range(n_sub):
            z = rk4_step(rhs, t + i * h_, z, h_)
        priors.append(z)
        if d.update is not None:
            z = d.update(t + dt, z, u1, y1, m1)
        parts.append(z)
    # second output: the state at the next sample before its update (for the innovations)
    return ca.Function("estimation_step", [s, a, X.sym("c", 1)], [ca.vertcat(*parts), ca.vertcat(*priors)]), fills
