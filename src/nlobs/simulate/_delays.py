r"""Known measurement delays: a sample of output j taken at :math:`t_s` reaches the observer at :math:`t_s + d_j`.

Method: filter recalculation from a state history (exact). The observer keeps its state after each sample it has
used, the samples sorted by the time they were *taken*. When a sample arrives that was taken before the last one
used (a late GPS fix behind the IMU's samples), it goes back to its state just before that time, applies the
samples again in the order they were taken (now with the late one), and runs forward to the present. The estimate
reported at time t is therefore exactly the one the same observer gives without delays on the samples that have
*arrived* by t: a delay costs only the information that is not there yet, never a sample applied at the wrong
time. The price is re-running the last d of the run at each late arrival: for a 5 Hz GPS 150 ms late, 75 % of the
time is integrated twice.

The whole re-processing is planned before anything runs, because which samples have arrived when does not depend on
the estimates: :func:`plan` turns the samples and their arrival times into a list of intervals ("knot" to knot, a
knot being a row time or the time a sample was taken), each starting from the end of the previous one or from a
saved state, saving its end and, when it reaches a row, reporting that row's estimate (an
:class:`nlobs.engine._intervals.Schedule`). The observer's compiled interval driver then runs the list in one call
(C), or stretch by stretch on CasADi's virtual machine: no Python per grid interval. A saved state carries the rate
the step-size rule passes on, so a replay integrates with the same sub-steps as the first pass did.

This holds for every continuous-discrete observer (a flow between samples and an update at each: EKF, UKF, the
square-root filters, ...): the update uses the sample at the time it was taken, with the state predicted to that
time. The particle filter does the same from saved particle clouds (:func:`run_particles_delayed`). Observers that
take the output continuously have no sample to re-apply and are refused.

Used by :func:`nlobs.simulate` (``delay={output: seconds}``, with sampled measurements) and :func:`nlobs.estimate`
(a recording stamped at arrival: a delayed output's row holds what was measured `d` earlier).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..engine import Backend
from ..engine._intervals import Schedule
from ..errors import ModelError
from ..observer import AbstractObserver
from ..observer._signals import delays_of

__all__ = ["delays_of", "Events", "Plan", "plan", "run_delayed", "latency_notes"]


@dataclass
class Events:
    """Samples as (time taken, time arrived, output index, value), one entry per measured output."""

    taken: np.ndarray
    arrived: np.ndarray
    output: np.ndarray
    value: np.ndarray

    @classmethod
    def from_rows(cls, t: np.ndarray, y: np.ndarray, measured: np.ndarray, delays: np.ndarray, *,
                  stamped_at_arrival: bool) -> Events:
        """One event per measured cell: rows stamped when the sample was taken (a simulation) or when it arrived (a
        recording: taken = stamp − delay)."""
        rows, cols = np.nonzero(measured)
        stamp, d = t[rows], delays[cols]
        taken, arrived = (stamp - d, stamp) if stamped_at_arrival else (stamp, stamp + d)
        return cls(taken, arrived, cols, y[rows, cols])


#: Times closer than TOL·max(1, |t|) are the same time: 64 units in the last place, far above the rounding of t − d
#: and far below any sample interval, also for Unix time stamps (1.7e9 s: 24 µs).
TOL = 64 * float(np.finfo(float).eps)


def _tol(v: np.ndarray | float) -> np.ndarray | float:
    """Times closer than this to `v` are the same time (see :data:`TOL`)."""
    return TOL * np.maximum(1.0, np.abs(v))


def _merged(v: np.ndarray) -> np.ndarray:
    """The distinct times of `v`, sorted, those within the tolerance of the one before merged into it."""
    v = np.sort(v)
    if v.size < 2:
        return v
    return v[np.r_[True, np.diff(v) > _tol(v[1:])]]


@dataclass(frozen=True, eq=False)
class Plan:
    """The re-processing of a run with delays, as intervals for the compiled driver (see :func:`plan`).

    Attributes
    ----------
    table : numpy.ndarray of shape (n_ops, na)
        One row per interval: (start, length, u held, 0, 0 (no linear hold), u at the end, the samples taken at the
        end, their mask: those arrived by the pass's time), as :func:`nlobs.observer._compiled.interval_table`.
    schedule : Schedule
        Where each interval starts from, saves to and reports (row of `t`).
    knot_time, pass_row : numpy.ndarray of shape (n_ops,)
        The time each interval ends at and the row of `t` whose arrivals it accounts for (for messages).
    m0 : numpy.ndarray of shape (ny,)
        The mask of the samples applied at the first time (taken and arrived then).
    y0 : numpy.ndarray of shape (ny,)
    replayed : int
        Intervals integrated again because a late sample arrived.
    """

    table: np.ndarray
    schedule: Schedule
    knot_time: np.ndarray
    pass_row: np.ndarray
    m0: np.ndarray
    y0: np.ndarray
    replayed: int


def plan(t: np.ndarray, u: np.ndarray, events: Events, ny: int) -> Plan:
    """Plan the exact re-processing of `events` on the rows `t` (inputs `u` held from each row to the next).

    Knots are the row times and the times samples were taken; knot q is *active* from the time its first sample
    arrives (a row: always), and pass k (for row k) accounts for every sample arrived by t_k. Pass k starts at the
    last knot before the earliest sample that arrived in (t_{k-1}, t_k] (or continues from the end of pass k - 1 when
    no such sample was taken before t_{k-1}) and runs over the active knots up to row k, applying at each knot the
    samples taken there that have arrived by t_k. Row 0 is the update at t_0 from the prior state (saved in its own
    slot, for a late sample taken at t_0)."""
    t = np.asarray(t, dtype=float)
    N = t.size
    keep = (events.taken >= t[0] - _tol(t[0])) & (events.arrived <= t[-1] + _tol(t[-1]))
    tk, ar = events.taken[keep], events.arrived[keep]
    out, val = events.output[keep].astype(np.int64), events.value[keep]
    # samples taken on a row are at that row (t - d computed in floating point)
    r = np.clip(np.searchsorted(t, tk + _tol(tk), side="right") - 1, 0, N - 1)
    on_row = np.abs(t[r] - tk) <= _tol(tk)
    tk = np.where(on_row, t[r], tk)
    # knots: the rows and the taken times between them, in time order (a row first where they are equal)
    extra = _merged(tk[~on_row])
    if extra.size:   # a taken time within the tolerance of another one is that time (t − d rounded either way)
        near = np.clip(np.searchsorted(extra, tk, side="left"), 0, extra.size - 1)
        below = np.clip(near - 1, 0, extra.size - 1)
        pick = np.where(np.abs(extra[below] - tk) < np.abs(extra[near] - tk), below, near)
        tk = np.where(on_row, tk, extra[pick])
    T = np.concatenate([t, extra])
    is_row = np.concatenate([np.ones(N, bool), np.zeros(extra.size, bool)])
    order = np.lexsort((~is_row, T))
    inv = np.argsort(order)                                  # the sorted position of each unsorted knot
    T, is_row = T[order], is_row[order]
    Q = T.size
    row_knot = inv[:N]                                       # knot of row k
    knot_row = np.clip(np.searchsorted(t, T + _tol(T), side="right") - 1, 0, N - 1)   # the row whose hold holds knot q
    q_of = inv[np.where(on_row, r, N + np.searchsorted(extra, tk))]
    # the samples at each knot: value and arrival per output (the later arrival wins where one output has two)
    arr = np.full((Q, ny), np.inf)
    yv = np.zeros((Q, ny))
    o2 = np.lexsort((ar, q_of))
    arr[q_of[o2], out[o2]] = ar[o2]
    yv[q_of[o2], out[o2]] = val[o2]
    act = np.where(is_row, -np.inf, np.min(arr, axis=1))     # a knot between rows exists once a sample taken there arrived
    # the pass (row) each arrival is accounted for in: the first row at or after it
    k_of = np.clip(np.searchsorted(t, ar - _tol(ar), side="left"), 0, N - 1)
    qmin = np.full(N, Q, dtype=np.int64)
    np.minimum.at(qmin, k_of, q_of)
    prev_end = np.r_[-1, row_knot[:-1]]                      # where pass k continues from (pass 0: the prior)
    start = prev_end.copy()
    late = qmin <= prev_end
    late[0] = False
    # a late pass starts at the last knot before its earliest new sample that existed in the previous pass
    rows_late = np.flatnonzero(late)
    s = qmin[rows_late] - 1
    cut = t[rows_late - 1] + _tol(t[rows_late - 1])
    while s.size and np.any(bad := (s >= 0) & (act[np.maximum(s, 0)] > cut)):
        s[bad] -= 1
    start[rows_late] = s
    # the intervals: pass k covers the knots in (start_k, row_knot_k] that exist at t_k
    lengths = row_knot - start
    lengths[0] = 1                                           # row 0: the update at t_0, from the prior
    total = int(lengths.sum())
    pass_of = np.repeat(np.arange(N), lengths)
    first = np.cumsum(lengths) - lengths
    q = np.repeat(start + 1, lengths) + (np.arange(total) - np.repeat(first, lengths))
    q[0] = 0
    alive = act[q] <= t[pass_of] + _tol(t[pass_of])          # rows always; every pass keeps at least its row
    q, pass_of = q[alive], pass_of[alive]
    n_ops = q.size
    is_first = np.r_[True, pass_of[1:] != pass_of[:-1]]
    cutoff = t[pass_of] + _tol(t[pass_of])
    # where each interval starts: the previous knot of its pass, or the knot the pass starts from
    prev_q = np.r_[0, q[:-1]]
    prev_q[is_first] = np.maximum(start[pass_of[is_first]], 0)
    prev_q[0] = 0                                            # the update at t_0: a zero-length interval
    t_start = T[prev_q]
    mask = (arr[q] <= cutoff[:, None]).astype(float)
    u = np.asarray(u, dtype=float).reshape(N, -1)
    table = np.hstack([t_start[:, None], (T[q] - t_start)[:, None], u[knot_row[prev_q]], np.zeros((n_ops, 2 * ny)),
                       u[knot_row[q]], np.where(mask > 0, yv[q], 0.0), mask])
    # the ring of saved states: a pass goes back at most `back` knots behind the last one stored
    back = int(np.max(prev_end[late] - start[late])) if late.any() else 0
    R = back + 2
    prior = R
    load = np.full(n_ops, -1, dtype=np.int64)
    rewind = is_first & late[pass_of]
    load[rewind] = np.where(start[pass_of[rewind]] >= 0, start[pass_of[rewind]] % R, prior)
    load[0] = prior
    store = (q % R).astype(np.int64)
    emit = np.full(n_ops, -1, dtype=np.int64)
    last = np.r_[np.flatnonzero(pass_of[1:] != pass_of[:-1]), n_ops - 1]
    emit[last] = pass_of[last]
    sched = Schedule(load, store, emit, R + 1, N, prior)
    return Plan(table, sched, T[q], pass_of, mask[0].copy(), np.where(mask[0] > 0, yv[0], 0.0), int(n_ops - N))


def latency_notes(events: Events, t_end: float, outputs: Sequence[str], delays: np.ndarray) -> list[str]:
    """A note per delayed output of which no sample arrives within the run (a latency in the wrong unit, say)."""
    notes = []
    for j, name in enumerate(outputs):
        if delays[j] <= 0:
            continue
        mine = events.output == j
        if mine.any() and not np.any(events.arrived[mine] <= t_end + _tol(t_end)):
            notes.append(f"no sample of {name} arrives within the run: its delay, {delays[j]:g} s, is longer than the "
                         f"time from its first sample to the end ({t_end - float(events.taken[mine].min()):g} s), so the "
                         f"observers never see {name}. Check the delay's unit (seconds)")
    return notes


def run_delayed(obs: AbstractObserver, t: np.ndarray, u: np.ndarray, events: Events, z0: np.ndarray, *,
                max_step: float | None = None, name: str = "observer", engine: Backend = "auto",
                the_plan: Plan | None = None, knot_rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The observer's state and estimate at each time of `t`, from the samples that have arrived by then (see the
    module docstring). `u` is held (zero-order) between the times of `t`; returns ``(Z, X)``.

    Raises
    ------
    FiniteEscapeError
        When the observer's state becomes non-finite (with the time and the pass it happened in).
    DataError
        When an interval would need more than 10⁸ RK4 steps.
    """
    from ..observer import ParticleObserver
    from ..observer._compiled import compiled_observer

    if isinstance(obs, ParticleObserver):   # re-processed from saved particle clouds
        if getattr(obs.design, "engine", "c") != "c":
            raise ModelError(f"observer {name!r}: a particle filter on late samples runs on the C engine (it re-runs from "
                             "saved clouds with the draws of the first pass); design it with engine='c'")
        return run_particles_delayed(obs, t, u, events, np.asarray(z0, dtype=float).reshape(-1), knot_rows=knot_rows,
                                     name=name)
    if not obs.sampled:
        raise ModelError(f"observer {name!r} ({obs.design.method}) takes the output continuously; measurement delays are "
                         "handled by the continuous-discrete observers (a flow between samples and an update at each: "
                         "ekf, ukf, srekf, srukf, iekf, ...)")
    p = the_plan if the_plan is not None else plan(t, u, events, obs.system.n_outputs)
    co = compiled_observer(obs.design)
    return co.replay(p, np.asarray(z0, dtype=float).reshape(-1), t=np.asarray(t, dtype=float), u=np.asarray(u, dtype=float),
                     max_step=max_step, engine=engine, name=name)



def run_particles_delayed(obs: Any, t: np.ndarray, u: np.ndarray, events: Events, xhat0: np.ndarray, *,
                          knot_rows: np.ndarray | None = None, name: str = "pf") -> tuple[np.ndarray, np.ndarray]:
    r"""A particle filter on samples that arrive late: at each time of `t`, exactly the filter that sees, on time, the
    samples arrived by then (the same particle filter, the same random numbers), re-processed from saved clouds.

    The filter runs on *knots*: the rows `knot_rows` of `t` (all rows by default) and the times samples were taken
    between them; inputs are held from the last row. Sample k's random numbers come from a stream seeded by (seed, k)
    (:class:`nlobs.observer.ParticleRunner`), so a re-run from the cloud saved after knot k draws what the first pass
    drew. First the filter runs once on every sample that arrives within the run, saving its cloud where a re-run will
    start. Then, at each time a sample arrives or a knot is reached (a *pass*): when a sample taken at an earlier knot
    has just arrived, the pass starts again from the saved cloud after the last knot before the first one whose samples
    are not all in (or from the prior); otherwise it goes on from the last pass's cloud. Between passes the estimate is
    held, as the particle filter's estimate is held between samples without delays.

    Returns the filter's trace rows and estimates at the times of `t`: ``(Z, X)``.
    """
    from ..observer._particles import particle_runner

    d = obs.design
    runner = particle_runner(d, "c")
    t = np.asarray(t, dtype=float)
    N, ny, n = t.size, d.system.n_outputs, d.system.n_states
    u = np.asarray(u, dtype=float).reshape(N, -1)
    rows = np.arange(N) if knot_rows is None else np.union1d(np.asarray(knot_rows, dtype=np.int64), [0])
    keep = (events.taken >= t[0] - _tol(t[0])) & (events.arrived <= t[-1] + _tol(t[-1]))
    tk, ar, out, val = events.taken[keep], events.arrived[keep], events.output[keep].astype(np.int64), events.value[keep]
    # knots: the rows, and the taken times between them (within the tolerance of a row: that row)
    r = np.clip(np.searchsorted(t[rows], tk + _tol(tk), side="right") - 1, 0, rows.size - 1)
    on = np.abs(t[rows][r] - tk) <= _tol(tk)
    T = np.union1d(t[rows], _merged(tk[~on]))
    T = _merged(T)
    K = T.size
    q_of = np.clip(np.searchsorted(T, tk + _tol(tk), side="right") - 1, 0, K - 1)
    arr, Y = np.full((K, ny), np.inf), np.zeros((K, ny))
    o2 = np.lexsort((ar, q_of))
    arr[q_of[o2], out[o2]] = ar[o2]
    Y[q_of[o2], out[o2]] = val[o2]
    U = u[np.clip(np.searchsorted(t, T + _tol(T), side="right") - 1, 0, N - 1)]
    # passes: the knot times and the arrival times, each with the knots reached and the samples arrived by then
    P = _merged(np.concatenate([T, ar[(ar >= t[0]) & (ar <= t[-1] + _tol(t[-1]))]]))
    reach = np.clip(np.searchsorted(T, P + _tol(P), side="right") - 1, 0, K - 1)
    full = np.isfinite(arr)
    # per pass: the first knot a sample arrived for since the last pass, and the first knot still waiting for one
    tol_p = _tol(P)
    j_of = np.clip(np.searchsorted(P, ar - _tol(ar), side="left"), 0, P.size - 1)   # the pass each arrival counts in
    new_first = np.full(P.size, K, dtype=np.int64)
    np.minimum.at(new_first, j_of, q_of)
    by_arrival = np.argsort(ar)
    tail_min = np.minimum.accumulate(q_of[by_arrival][::-1])[::-1]          # min knot over arrivals from here on
    after = np.searchsorted(ar[by_arrival], P + tol_p, side="right")         # first arrival after each pass
    pending = np.r_[tail_min, K][after]
    starts = np.full(P.size, -1, dtype=np.int64)   # -1: go on from the last pass; else the knot to start from (0: prior)
    starts[0] = 0
    late = np.r_[False, new_first[1:] <= reach[:-1]]                        # a sample taken at a knot already passed
    starts[late] = np.minimum(new_first[late], pending[late])
    saves = sorted({s - 1 for s in starts if s > 0})
    flags = np.zeros(K)
    flags[saves] = 1
    fm = full.astype(float)
    first = runner.run(T, u=U, y=Y, mask=fm, xhat0=xhat0, name=name, keep=flags)
    saved = {k: (first.kept[0][i], first.kept[1][i]) for i, k in enumerate(saves)}
    Zp = np.empty((P.size, len(d.z_names)))
    cloud: tuple[np.ndarray, np.ndarray] | None = None
    for j, (p, s) in enumerate(zip(P, starts)):
        q = int(reach[j])
        if s == -1 and j and q == reach[j - 1]:
            Zp[j] = Zp[j - 1]   # nothing new: hold
            continue
        if s == 0:
            a, resume = 0, None
        elif s > 0:
            a, resume = s - 1, saved[s - 1]
        else:
            a, resume = int(reach[j - 1]), cloud
        sl = slice(a, q + 1)
        m = (arr[sl] <= p + _tol(p)).astype(float)
        run = runner.run(T[sl], u=U[sl], y=Y[sl], mask=m, xhat0=xhat0, name=name, k0=a,
                         resume=resume) if q > a or resume is None else None
        if run is None:   # resuming at the knot itself: the cloud and its row are the last pass's
            Zp[j] = Zp[j - 1]
            continue
        cloud = (run.particles, run.log_weights)
        Zp[j] = run.z[-1]
    row_pass = np.clip(np.searchsorted(P, t + _tol(t), side="right") - 1, 0, P.size - 1)
    Z = Zp[row_pass]
    return Z, Z[:, :n].copy()

