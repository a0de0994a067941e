"""Integrate between irregular sample times: RK4 sub-steps whose number is chosen per interval, at run time.

A recording is a sequence of intervals [t_k, t_k + dt_k]. Over each, a state s is integrated by
``sub(s, a_k, (t, h)) -> (s', rate)`` — one RK4 step of length h from t that also returns the
flow's local rate (see :func:`nlobs.engine.rk4_step_rate`) — and at its end an event
``jump(s, a_k) -> (s', o)`` is applied (a sample-time update; `o` is a per-sample output).
The number of sub-steps of interval k is

    n_k = max(nmin_k, ceil(dt_k · ρ / c)),

with nmin_k from the user's largest step, ρ the fastest rate measured in the previous interval
(the first interval uses a given `rate0`, e.g. the spectral radius of the flow's Jacobian at the
initial state) and c the target product h·ρ (default 1: well inside RK4's stability limit 2.8,
and about 1 % amplitude error per step on the fastest mode). When the rate measured during the
interval shows that a step was longer than `reject`/ρ, the interval is redone from its start with
n_k = max(min(ceil(dt_k · ρ_measured / c), REDO_GROWTH n_k), 2 n_k): a stiff covariance equation or a fast transient
cannot silently inflate the state between samples. When twice the sub-steps do not shrink h·ρ (by at
least a quarter), the interval holds a kink or a jump of the flow (abs, sign, min, max: the difference
quotient grows as 1/h there), not a fast mode: it is finished with those sub-steps and its rate is not
passed on to the next interval. An interval needing more than `max_substeps`
sub-steps is refused (with its index and the count needed). A state that becomes non-finite, or a kink whose
step-doubling check fails, first has its interval redone with REDO_GROWTH times the sub-steps and the rate rule on
(at most BLOWUP_REDOS times: a stiff region past a kink, or a rate the previous interval could not see), and then
stops the run (with the interval).

The C path is a generated loop over the intervals with the sub-step loop inside (nothing is
unrolled: a gap of 10⁸ steps costs 10⁸ calls, not a graph of that size); the VM path runs chunks of
sub-steps with :meth:`casadi.Function.mapaccum` under the same rule, predicting each interval's
count and re-running from the first interval whose prediction proves wrong.
"""

from __future__ import annotations

import ctypes
import math
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..errors import ConvergenceWarning, EngineError
from ._budget import Watchdog, check_time
from ._deferred import raise_deferred
from ._codegen import (COSTS, Backend, _build, _forced, _generate, _renamed, built_path, choose_backend, code_size,
                       signature_of)

__all__ = ["IntervalRunner", "IntervalResult", "Schedule", "MAX_SUBSTEPS", "EXACT_RATE_MAX", "fastest_rate", "power_rate",
           "BLOWUP_REDOS"]

#: The most RK4 sub-steps one interval may take before it is refused.
MAX_SUBSTEPS = 10**8

#: An interval accepted as a kink is checked by step doubling: the end state with 2n sub-steps against n, each entry
#: within KINK_ATOL + KINK_RTOL·|x| (the check is for divergence, a state that moves with the step by a good part of
#: itself, not for RK4's accuracy); at most KINK_DOUBLINGS doublings (a true kink costs at most 2 + 4 + 8 = 14 times
#: its sub-steps more), after which the interval is accepted if the change still shrinks by KINK_SHRINK per doubling (a kink's
#: error shrinks with h) and refused otherwise. The C driver's #defines below carry the same values.
KINK_DOUBLINGS, KINK_RTOL, KINK_ATOL, KINK_SHRINK = 3, 1e-2, 1e-8, 0.7

#: A redone interval takes at most REDO_GROWTH times its sub-steps more per redo: the rate measured on a step far too
#: long is that of states far off the solution (a tank level at -1400 m), often decades above the one the solution
#: meets (637,527 sub-steps in one 4 s interval of the Cascaded Tanks with a steep weir, 524 with the cap); for a true
#: fast mode the cap costs at most 1/63 more. It also keeps a rate that rises as the steps shrink (a fast mode a long
#: step hardly excited) from being taken for a kink unless it rose 48-fold.
REDO_GROWTH = 64

#: An interval whose state becomes non-finite (in its sub-steps or at the event after them) before any stage measured a
#: rate above the rejection threshold — the first interval's rate comes from the start estimate, and a UKF's sigma points
#: may already sit on a stiff weir it does not see; an interval finished as a kink may run into a stiff region past it —
#: is redone with REDO_GROWTH times its sub-steps and the rate rule on, at most BLOWUP_REDOS times (a true finite escape
#: or a bad sample costs at most 64 + 4096 times that interval's sub-steps more before it is reported).
BLOWUP_REDOS = 2

_C_DRIVER = r"""
#define REDO_GROWTH 64
#define BLOWUP_REDOS 2
#define KINK_DOUBLINGS 3
#define KINK_RTOL 1e-2
#define KINK_ATOL 1e-8
#define KINK_SHRINK 0.7
/* nlobs interval driver: per interval k, n_k sub-steps of SUB then JUMP (see nlobs.engine._intervals).
   Returns 0; k + 1 when the state became non-finite in interval k; -(k + 1) when interval k needs more than
   max_sub sub-steps (their number is written to need[0]). nsub[k], rate[k] are filled for every finished interval.
   With a schedule (ops != NULL, three entries per interval: load, store, emit), interval k starts from slot
   ops[3k] (its state and carried rate) when that is >= 0, else from the end of interval k - 1; its end state and
   the rate it passes on are written to slot ops[3k+1] when >= 0, and to row ops[3k+2] of out/obuf when >= 0.
   Without one, interval k's end is row k. carry[k] (when carry != NULL) is the rate interval k passes on.
   When *stop is raised (a time budget), returns -(k + 1) with need[0] = -1. When an interval accepted as a kink
   fails its step-doubling check (and its redos), returns k + 1 with need[0] = -2 and need[1] = the relative change.
   With A == NULL, interval k's row is assembled from the sample times tg (n_int + 1) and the sample rows B
   ((n_int + 1) x NW): (tg[k], tg[k+1] - tg[k], B[k], B[k+1]), the layout of the table A. */
long long nlobs_intervals(const double* s0, const double* A, const double* nmin, double rate0, double target,
                          double reject, double max_sub, double* out, double* obuf, double* nsub, double* rate,
                          long long n_int, double* need, const long long* ops, double* slots, double* carry,
                          const volatile int* stop, const double* tg, const double* B) {
  const double* arg[NLOBS_SZ_ARG];
  double* res[NLOBS_SZ_RES];
  casadi_int iw[NLOBS_SZ_IW + 1];
  double w[NLOBS_SZ_W + 1];
  double start[NS], cur[NS], nxt[NS], th[2], r, o[NO + 1], end[NS], oend[NO + 1], arow[NA];
  double rho = rate0, t, dt, n, m, h, rmax, hr, prev_hr, kink_e;
  double *dst, *odst, *slot;
  long long k, i, ni;
  int j, bad, stiff, check, idle, redos;
  for (j = 0; j < NS; ++j) start[j] = s0[j];
  for (k = 0; k < n_int; ++k) {
    const double* a = A ? A + k * NA : arow;
    if (!A) {
      arow[0] = tg[k]; arow[1] = tg[k + 1] - tg[k];
      for (j = 0; j < NW; ++j) { arow[2 + j] = B[k * NW + j]; arow[2 + NW + j] = B[(k + 1) * NW + j]; }
    }
    if (stop && *stop) { need[0] = -1; return -(k + 1); }
    if (ops && ops[3 * k] >= 0) {
      slot = slots + ops[3 * k] * (NS + 1);
      for (j = 0; j < NS; ++j) start[j] = slot[j];
      rho = slot[NS];
    }
    t = a[0]; dt = a[1];
    n = nmin[k];
    m = ceil(dt * rho / target);
    if (m > n) n = m;
    prev_hr = INFINITY; check = 1; redos = 0; kink_e = -1;
    if (!(dt > 0)) {                            /* a zero-length interval (an update only): no flow, the rate kept */
      for (j = 0; j < NS; ++j) cur[j] = start[j];
      nsub[k] = 0; rate[k] = nan("");
    } else again: for (;;) {
      if (n > max_sub && kink_e >= 0) { nsub[k] = n; need[0] = -2; need[1] = kink_e; return k + 1; }
      if (n > max_sub) { need[0] = n; return -(k + 1); }
      ni = (long long)n; h = dt / n; rmax = 0; bad = 0; stiff = 0;
      for (j = 0; j < NS; ++j) cur[j] = start[j];
      arg[1] = a; arg[2] = th; res[1] = &r;
      for (i = 0; i < ni; ++i) {
        if ((i & 65535) == 65535 && stop && *stop) { need[0] = -1; return -(k + 1); }
        th[0] = t + i * h; th[1] = h;
        arg[0] = cur; res[0] = nxt;
        SUB(arg, res, iw, w, 0);
        if (r > rmax) rmax = r;                 /* a NaN rate compares false: ignored */
        for (j = 0; j < NS; ++j) bad |= !(fabs(nxt[j]) < INFINITY);
        for (j = 0; j < NS; ++j) cur[j] = nxt[j];
        if (check && h * rmax > reject) { stiff = 1; break; }
        if (bad) break;
      }
      if (stiff) {
        hr = h * rmax;
        /* more sub-steps did not shrink h*rate: a kink or jump of the flow (abs, sign, min, max), not a fast
           mode, whose difference quotient grows as 1/h; finish the interval with these sub-steps */
        if (hr > 0.75 * prev_hr) { check = 0; continue; }
        prev_hr = hr; m = ceil(dt * rmax / target); if (m > REDO_GROWTH * n) m = REDO_GROWTH * n;
        n = m > 2 * n ? m : 2 * n; continue;
      }
      if (bad && redos < BLOWUP_REDOS && REDO_GROWTH * n <= max_sub) {  /* (dt > 0 here) */
        /* non-finite before any rate was seen, or past a kink into a stiff region (a weir): too few sub-steps, or a
           true escape (redone at most BLOWUP_REDOS times, the rate rule on again) */
        ++redos; n *= REDO_GROWTH; prev_hr = INFINITY; check = 1; continue;
      }
      nsub[k] = n; rate[k] = rmax;
      if (bad && kink_e >= 0) { need[0] = -2; need[1] = kink_e; }  /* a diverging 'kink' redone to no avail */
      if (bad) return k + 1;
      if (!check) {  /* accepted as a kink: check its end state (after the jump, as the VM path compares) by step
                        doubling; a diverging interval fails it */
        double e = INFINITY, e_prev = INFINITY, sc, jc[NS], jf[NS], ob[NO + 1], n_kink = n;
        int d, idle0 = IDLEN > 0;
        for (j = 0; j < IDLEN; ++j) idle0 &= a[IDLEAT + j] == 0;
        arg[0] = cur; arg[1] = a; res[0] = jc; res[1] = ob;
        if (idle0) JUMP0(arg, res, iw, w, 0); else JUMP(arg, res, iw, w, 0);
        for (d = 0; d < KINK_DOUBLINGS; ++d) {
          n *= 2; ni = (long long)n; h = dt / n;
          if (n > max_sub) { need[0] = n; return -(k + 1); }
          for (j = 0; j < NS; ++j) nxt[j] = start[j];
          for (i = 0; i < ni; ++i) {
            if ((i & 65535) == 65535 && stop && *stop) { need[0] = -1; return -(k + 1); }
            th[0] = t + i * h; th[1] = h;
            arg[0] = nxt; arg[1] = a; arg[2] = th; res[0] = end; res[1] = &r;
            SUB(arg, res, iw, w, 0);
            for (j = 0; j < NS; ++j) nxt[j] = end[j];
          }
          arg[0] = nxt; arg[1] = a; res[0] = jf; res[1] = ob;
          if (idle0) JUMP0(arg, res, iw, w, 0); else JUMP(arg, res, iw, w, 0);
          e_prev = e; e = 0;
          for (j = 0; j < NS; ++j) {
            sc = KINK_ATOL + KINK_RTOL * fmax(fmax(fabs(jf[j]), fabs(jc[j])), fabs(start[j]));
            sc = fabs(jf[j] - jc[j]) / sc;
            e = sc > e || sc != sc ? sc : e;
          }
          for (j = 0; j < NS; ++j) { cur[j] = nxt[j]; jc[j] = jf[j]; }
          nsub[k] = n;
          if (e <= 1) break;
        }
        /* refused: the end state still moves with the step, and no longer shrinks as a kink's error does */
        if (!(e <= 1) && !(e <= KINK_SHRINK * e_prev)) {
          if (redos < BLOWUP_REDOS && REDO_GROWTH * n_kink <= max_sub) {
            /* a kink into a stiff region (a weir) whose first count was unstable there: REDO_GROWTH times its first
               sub-steps, the rate rule on again, before it is called diverging */
            ++redos; n = REDO_GROWTH * n_kink; prev_hr = INFINITY; check = 1; kink_e = e; continue;
          }
          need[0] = -2; need[1] = e; return k + 1;
        }
      }
      if (check) rho = rmax;  /* a kink's rate (about 2/h) says nothing about the next interval */
      break;
    }
    if (ops) {
      dst = ops[3 * k + 2] >= 0 ? out + ops[3 * k + 2] * NS : end;
      odst = ops[3 * k + 2] >= 0 && NO > 0 ? obuf + ops[3 * k + 2] * NO : oend;
    } else {
      dst = out + k * NS;
      odst = NO > 0 ? obuf + k * NO : o;
    }
    arg[0] = cur; arg[1] = a; res[0] = dst; res[1] = odst;
    idle = IDLEN > 0;                           /* nothing sampled at the end: the jump with those entries 0 */
    for (j = 0; j < IDLEN; ++j) idle &= a[IDLEAT + j] == 0;
    if (idle) JUMP0(arg, res, iw, w, 0); else JUMP(arg, res, iw, w, 0);
    bad = 0;
    for (j = 0; j < NS; ++j) bad |= !(fabs(dst[j]) < INFINITY);
    for (j = 0; j < NO; ++j) bad |= !(fabs(odst[j]) < INFINITY);
    if (bad && dt > 0 && redos < BLOWUP_REDOS && REDO_GROWTH * n <= max_sub) {
      /* finite sub-steps, but so far off (an unstable step past a kink) that the event overflows: redone alike */
      ++redos; n *= REDO_GROWTH; prev_hr = INFINITY; check = 1; goto again;
    }
    if (bad && kink_e >= 0) { need[0] = -2; need[1] = kink_e; }
    if (bad) return k + 1;
    for (j = 0; j < NS; ++j) start[j] = dst[j];
    if (carry) carry[k] = rho;
    if (ops && ops[3 * k + 1] >= 0) {
      slot = slots + ops[3 * k + 1] * (NS + 1);
      for (j = 0; j < NS; ++j) slot[j] = dst[j];
      slot[NS] = rho;
    }
  }
  return 0;
}
"""


@dataclass(frozen=True, eq=False)
class IntervalResult:
    """What :meth:`IntervalRunner.run` returns.

    Attributes
    ----------
    states : numpy.ndarray of shape (N, ns)
        The state after the event at the end of each interval (rows after a failure are NaN).
    outputs : numpy.ndarray of shape (N, no)
        The event's per-sample output.
    substeps : numpy.ndarray of shape (N,)
        RK4 sub-steps taken in each interval (0 where not reached).
    rate : numpy.ndarray of shape (N,)
        The fastest rate measured in each interval (1/time; NaN where not reached).
    failed : int or None
        The interval where the state became non-finite, or None.
    refused : tuple of (int, float) or None
        (interval, sub-steps needed) when an interval would need more than `max_substeps`.
    carry : numpy.ndarray of shape (N,) or None
        The rate each interval passes on to the next (its measured rate, or the one it received when it held a
        kink); NaN where not reached.
    unconverged : float or None
        With `failed`: the interval was taken for a kink, but its end state still changed by this much (relative, see
        :data:`KINK_RTOL`) when its sub-steps were doubled, and again after its redos (:data:`BLOWUP_REDOS`): a
        diverging interval, not a kink.
    lead : numpy.ndarray of shape (N + 1, ns) or None
        The start state stacked above `states` in one array (`states` is a view of its rows 1..N), where the runner
        wrote them so (the compiled path without a schedule); None otherwise.
    olead : numpy.ndarray of shape (N + 1, no) or None
        Likewise for `outputs`: its row 0 is left unset for the caller (e.g. the output at the start); None otherwise.

    With a :class:`Schedule`, `states` and `outputs` have one row per emitted row of the schedule, and the other
    arrays one entry per interval of the schedule.
    """

    states: np.ndarray
    outputs: np.ndarray
    substeps: np.ndarray
    rate: np.ndarray
    failed: int | None = None
    refused: tuple[int, float] | None = None
    backend: str = "vm"
    carry: np.ndarray | None = None
    unconverged: float | None = None
    lead: np.ndarray | None = None
    olead: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Rows:
    """The intervals as the samples that bound them: times `t` (N + 1,) and one row of `B` (N + 1, w) per sample;
    interval k reads (t_k, t_{k+1} - t_k, B_k, B_{k+1}), the row the table of :meth:`IntervalRunner.run` has. The
    compiled driver assembles each interval's row as it goes (building the (N, 2 + 2w) table costs a short run more
    than a tenth of its time); :meth:`table` builds it for the virtual machine."""

    t: np.ndarray
    B: np.ndarray

    @property
    def n(self) -> int:
        """The number of intervals."""
        return self.t.size - 1

    def table(self) -> np.ndarray:
        """The (N, 2 + 2w) table: one row per interval."""
        N, w = self.n, self.B.shape[1]
        A = np.empty((N, 2 + 2 * w))
        A[:, 0] = self.t[:-1]
        np.subtract(self.t[1:], self.t[:-1], out=A[:, 1])
        A[:, 2:2 + w] = self.B[:-1]
        A[:, 2 + w:] = self.B[1:]
        return A


@dataclass(frozen=True, eq=False)
class Schedule:
    """Intervals run as a register machine over saved states: what re-processing from a state history needs.

    Interval k starts from slot ``load[k]`` (a saved state with the rate it carried) when that is >= 0, else from
    the end of interval k - 1 (the first interval: from ``s0``). Its end state is saved in slot ``store[k]`` when
    >= 0, and reported as row ``emit[k]`` of the result when >= 0. ``prior`` (optional) is a slot that receives
    ``s0`` and ``rate0`` before the first interval, so that a later interval can start from it again.

    Attributes
    ----------
    load, store, emit : numpy.ndarray of int64, shape (N,)
    n_slots : int
    n_emit : int
        Rows of the result; every one must be emitted by some interval.
    prior : int or None
    """

    load: np.ndarray
    store: np.ndarray
    emit: np.ndarray
    n_slots: int
    n_emit: int
    prior: int | None = None

    def ops(self) -> np.ndarray:
        """The (N, 3) int64 table the C driver reads: load, store, emit."""
        return np.ascontiguousarray(np.column_stack([self.load, self.store, self.emit]).astype(np.int64))


class IntervalRunner:
    """Run ``sub``/``jump`` over intervals with sub-step counts chosen at run time (see the module docstring).

    Parameters
    ----------
    sub : casadi.Function
        ``(s[ns], a[na], th[2]) -> (s_next[ns], rate[1])``; ``a[0]`` is the interval's start time and
        ``a[1]`` its length; ``th = (t, h)`` is the sub-step's start and length.
    jump : casadi.Function
        ``(s[ns], a[na]) -> (s_next[ns], o[no])``, applied at the end of every interval.
    backend : {"auto", "vm", "c"}
    sub_c : casadi.Function, optional
        The same sub-step built for C (e.g. over MX, calling the flow at the stages rather than inlining it); it is
        what the compiled driver is generated from. Default: `sub`.
    idle : slice, optional
        Entries of `a` (e.g. the mask of the outputs sampled at the interval's end) that, when all zero, mean
        nothing happens at the end but what the jump does with them zero: the compiled driver then calls the
        jump with those entries fixed at 0 and simplified by CasADi (the same values; an EKF's update without a
        measurement is 1/15 of the instructions), so the intervals between samples cost the flow only.
    """

    def __init__(self, sub: ca.Function, jump: ca.Function, *, backend: Backend = "auto", idle: slice | None = None,
                 sub_c: ca.Function | None = None):
        self.sub, self.jump = sub, jump
        self.sub_c = sub_c if sub_c is not None else sub
        self.ns, self.na, self.no = sub.size1_in(0), sub.size1_in(1), jump.size1_out(1)
        self.backend = backend
        self.compilable = sub.is_a("SXFunction") and jump.is_a("SXFunction")
        self.idle = idle if idle is not None and idle.stop > idle.start else None
        self._sig = signature_of(sub) + signature_of(jump) if self.compilable else ""
        if self._sig and self.idle is not None:
            self._sig += f"/idle{self.idle.start}:{self.idle.stop}"
        if self._sig and sub_c is not None:
            self._sig += "/sub-c:" + signature_of(sub_c)[:16]
        self._c: _CompiledIntervals | None = None
        self._ready = False
        self._vm: dict[tuple[int, bool], ca.Function] = {}
        self._progress: Callable[[float], None] | None = None  # during a VM run: called with the time reached
        self._n_instr = (code_size(self.sub_c) + jump.n_instructions()) if self.compilable else 0

    def _compiled(self) -> _CompiledIntervals | None:
        """The compiled driver, built on first use; None when the compiler refused it and the backend is "auto" (the
        VM runs instead, with a warning); with "c" the refusal is raised."""
        if self._c is None:
            try:
                self._c = _CompiledIntervals(self.sub_c, self.jump, self._sig, self.idle)
            except EngineError as e:
                if _forced(self.backend) == "c":
                    raise
                warnings.warn(f"{e}; running on CasADi's virtual machine instead", ConvergenceWarning, stacklevel=4)
                self.backend = "vm"
                return None
        return self._c

    def vm_instructions(self, substeps: float, intervals: float) -> float:
        """VM instructions of a run: every sub-step evaluates the flow, every interval the jump (the VM's rows of an
        interval with few sub-steps evaluate both: an SX conditional computes both branches)."""
        return substeps * self.sub.n_instructions() + intervals * (self.jump.n_instructions() if self.compilable else 0)

    def backend_for(self, work: float, intervals: float = 0.0) -> str:
        """Where a run of `work` sub-steps over `intervals` intervals goes (by measured cost; MX functions always run
        on the VM)."""
        if not self.compilable or self.backend == "vm":
            return "vm"
        if not self._ready:  # remembered once true: the build stays in the cache
            path = built_path("intervals", self._sig, _C_DRIVER)
            self._ready = self._c is not None or (path is not None and path.exists())
        ready = self._ready
        return choose_backend(self.backend, ready=ready, n_instr=self._n_instr, vm_instr=self.vm_instructions(work, intervals),
                              signature=self._sig)

    def run(self, s0: np.ndarray, A: np.ndarray | Rows, nmin: np.ndarray, *, rate0: float, target: float = 1.0,
            reject: float = 2.0, max_substeps: int = MAX_SUBSTEPS,
            on_progress: Callable[[float], None] | None = None, schedule: Schedule | None = None) -> IntervalResult:
        """Integrate from `s0` over the intervals described by the rows of `A` (shape (N, na)).

        `on_progress(fraction)` is called with the fraction of the time span covered: after each VM call
        on the virtual machine (a long gap reports as it goes), once at the end for the compiled loop.
        With a `schedule` the intervals are run as it says (states restored from and saved to slots; see
        :class:`Schedule`): on the compiled path in one call, on the virtual machine one call per stretch
        of intervals that continue each other (never a Python step per interval). `A` may be given as
        :class:`Rows` (the samples; the compiled driver then assembles each row itself)."""
        loaded = self._c is not None and _forced(self.backend) != "vm"   # the compiled driver runs, as loaded
        if isinstance(A, Rows):   # the table is built only where it is read whole
            A = Rows(np.ascontiguousarray(A.t, dtype=float), np.ascontiguousarray(A.B, dtype=float)) \
                if loaded and schedule is None else A.table()
        if schedule is not None:
            return self._run_schedule(s0, A, nmin, rate0, target, reject, max_substeps, schedule, on_progress)
        A = A if isinstance(A, Rows) else np.ascontiguousarray(A, dtype=float)
        N = A.n if isinstance(A, Rows) else A.shape[0]
        nmin = np.ascontiguousarray(nmin, dtype=float)
        s0 = np.ascontiguousarray(s0, dtype=float).reshape(self.ns)
        rate0 = _finite_rate(rate0)
        # the work predicted from the first rate (a long gap needs many sub-steps although nmin is small there); not
        # needed once the compiled driver is loaded and no backend is forced (then it runs)
        backend = "c" if loaded else \
            self.backend_for(float(np.maximum(nmin, np.ceil(A[:, 1] * rate0 / target)).sum()), N)
        if backend == "c" and self._compiled() is not None:
            res = self._c(s0, A, nmin, rate0, target, reject, max_substeps)
            if on_progress is not None and res.failed is None and res.refused is None:
                on_progress(1.0)
            return res
        t0 = time.perf_counter()
        span = (A[0, 0], float(A[-1, 0] + A[-1, 1] - A[0, 0])) if N else (0.0, 0.0)
        reached = [0.0]  # a rejected attempt is redone from its start: the fraction reported never goes back

        def report(t: float) -> None:
            if on_progress is not None and (t - span[0]) / span[1] > reached[0]:
                reached[0] = (t - span[0]) / span[1]
                on_progress(reached[0])

        self._progress = report if on_progress is not None and span[1] > 0 else None
        try:
            res = self._run_vm(s0, A, nmin, rate0, target, reject, max_substeps)
        finally:
            self._progress = None
        if on_progress is not None and res.failed is None and res.refused is None:
            on_progress(1.0)
        if self.compilable:
            spent = time.perf_counter() - t0
            COSTS.spent[self._sig] = COSTS.spent.get(self._sig, 0.0) + spent
            COSTS.record_vm(self.vm_instructions(float(res.substeps.sum()), N), spent)
        return res

    def _run_schedule(self, s0: np.ndarray, A: np.ndarray, nmin: np.ndarray, rate0: float, target: float, reject: float,
                      max_substeps: int, sched: Schedule, on_progress: Callable[[float], None] | None) -> IntervalResult:
        """:meth:`run` with a :class:`Schedule`: the C driver in one call, or the VM stretch by stretch."""
        A = np.ascontiguousarray(A, dtype=float)
        nmin = np.ascontiguousarray(nmin, dtype=float)
        s0 = np.ascontiguousarray(s0, dtype=float).reshape(self.ns)
        rate0 = _finite_rate(rate0)
        N = A.shape[0]
        slots = np.full((sched.n_slots, self.ns + 1), np.nan)
        if sched.prior is not None:
            slots[sched.prior, :self.ns], slots[sched.prior, self.ns] = s0, rate0
        backend = self.backend_for(float(np.maximum(nmin, np.ceil(A[:, 1] * rate0 / target)).sum()), N)
        if backend == "c" and self._compiled() is not None:
            res = self._c(s0, A, nmin, rate0, target, reject, max_substeps, sched, slots)
        else:
            t0 = time.perf_counter()
            res = self._schedule_vm(s0, A, nmin, rate0, target, reject, max_substeps, sched, slots, on_progress)
            if self.compilable:
                spent = time.perf_counter() - t0
                COSTS.spent[self._sig] = COSTS.spent.get(self._sig, 0.0) + spent
                COSTS.record_vm(self.vm_instructions(float(res.substeps.sum()), N), spent)
        if on_progress is not None and res.failed is None and res.refused is None and N:
            on_progress(1.0)
        return res

    def _schedule_vm(self, s0: np.ndarray, A: np.ndarray, nmin: np.ndarray, rate0: float, target: float, reject: float,
                     max_substeps: int, sched: Schedule, slots: np.ndarray,
                     on_progress: Callable[[float], None] | None) -> IntervalResult:
        """The schedule on the VM: each stretch of intervals that continue one another is one :meth:`_run_vm`."""
        N, ns = A.shape[0], self.ns
        states, outputs = np.full((sched.n_emit, ns), np.nan), np.full((sched.n_emit, self.no), np.nan)
        substeps, rate, carry = np.zeros(N), np.full(N, np.nan), np.full(N, np.nan)
        starts = np.flatnonzero(sched.load >= 0)
        bounds = np.unique(np.r_[0, starts, N]).astype(np.int64)
        state, rho = s0, rate0
        for b0, b1 in zip(bounds[:-1], bounds[1:]):
            check_time("running on CasADi's virtual machine")
            if b1 <= b0:
                continue
            if sched.load[b0] >= 0:
                state, rho = slots[sched.load[b0], :ns], float(slots[sched.load[b0], ns])
            if not A[b0, 1] > 0:   # a zero-length interval (an update only): the jump, the rate kept
                s2, o = (np.asarray(v, dtype=float).reshape(-1) for v in self.jump(state, A[b0]))
                raise_deferred()
                if not (np.isfinite(s2).all() and np.isfinite(o).all()):
                    return IntervalResult(states, outputs, substeps, rate, failed=int(b0), carry=carry)
                carry[b0], state = rho, s2
                if sched.emit[b0] >= 0:
                    states[sched.emit[b0]], outputs[sched.emit[b0]] = s2, o
                if sched.store[b0] >= 0:
                    slots[sched.store[b0], :ns], slots[sched.store[b0], ns] = s2, rho
                b0 += 1
                if b0 == b1:
                    continue
            part = self._run_vm(np.ascontiguousarray(state), A[b0:b1], nmin[b0:b1], rho, target, reject, max_substeps)
            sl = slice(b0, b1)
            substeps[sl], rate[sl], carry[sl] = part.substeps, part.rate, part.carry
            done = (b1 - b0) if part.failed is None and part.refused is None else (part.failed if part.failed is not None
                                                                                   else part.refused[0])
            idx = np.arange(b0, b0 + done)
            em = sched.emit[idx] >= 0
            states[sched.emit[idx[em]]] = part.states[:done][em]
            outputs[sched.emit[idx[em]]] = part.outputs[:done][em]
            st = sched.store[idx] >= 0
            if st.any():   # in order: a later interval of the stretch may reuse a slot
                for i in np.flatnonzero(st):
                    slots[sched.store[idx[i]], :ns] = part.states[i]
                    slots[sched.store[idx[i]], ns] = part.carry[i]
            if part.failed is not None:
                return IntervalResult(states, outputs, substeps, rate, failed=b0 + part.failed, carry=carry)
            if part.refused is not None:
                return IntervalResult(states, outputs, substeps, rate, refused=(b0 + part.refused[0], part.refused[1]),
                                      carry=carry)
            state, rho = part.states[-1], float(part.carry[-1])
            if on_progress is not None:
                on_progress(b1 / N)
        return IntervalResult(states, outputs, substeps, rate, carry=carry)

    # -- the VM path -------------------------------------------------------------------------
    def _rows_fn(self, K: int, jumps: bool = True) -> ca.Function:
        """K sub-step rows in one call: row i = (a, t, h, flag); the jump is applied after the rows flagged 1.

        Without `jumps`, the rows are sub-steps only (the flags are ignored): the bulk of a long gap, where
        an SX conditional would otherwise evaluate the jump on every row and discard it.
        """
        fn = self._vm.get((K, jumps))
        if fn is None and not jumps:
            s, row = ca.SX.sym("s", self.ns), ca.SX.sym("row", self.na + 3)
            s1, r = self.sub(s, row[:self.na], row[self.na:self.na + 2])
            step = ca.Function("row", [s, row], [s1, ca.vertcat(r, ca.SX.zeros(self.no))])
            S0, R = ca.MX.sym("s0", self.ns), ca.MX.sym("rows", self.na + 3, K)
            fn = self._vm[(K, jumps)] = ca.Function(f"subs_{K}", [S0, R], list(step.mapaccum("subs", K)(S0, R)))
        if fn is None:
            # SX when both functions are (the fast VM); MX otherwise, where the jump (an NLP) runs only when flagged
            X = ca.SX if self.compilable else ca.MX
            s = X.sym("s", self.ns)
            row = X.sym("row", self.na + 3)
            a, th, flag = row[:self.na], row[self.na:self.na + 2], row[self.na + 2]
            s1, r = self.sub(s, a, th)
            s2, o = self.jump(s1, a)
            # one conditional for the state and the output together: with short-circuiting (MX), an output taken
            # outside the branch would evaluate the jump a second time
            both = ca.if_else(flag, ca.vertcat(s2, o), ca.vertcat(s1, X.zeros(self.no)), not self.compilable)
            step = ca.Function("row", [s, row], [both[:self.ns], ca.vertcat(r, both[self.ns:])])
            acc = step.mapaccum("rows", K)
            S0, R = ca.MX.sym("s0", self.ns), ca.MX.sym("rows", self.na + 3, K)
            out = acc(S0, R)
            fn = self._vm[(K, jumps)] = ca.Function(f"rows_{K}", [S0, R], list(out))
        return fn

    def _run_vm(self, s0: np.ndarray, A: np.ndarray, nmin: np.ndarray, rate0: float, target: float, reject: float,
                max_substeps: int) -> IntervalResult:
        N, ns, no = A.shape[0], self.ns, self.no
        states, outputs = np.full((N, ns), np.nan), np.full((N, no), np.nan)
        substeps, rate, carry = np.zeros(N), np.full(N, np.nan), np.full(N, np.nan)
        dt = A[:, 1]
        start, rho, k = s0.copy(), rate0, 0
        forced: float | None = None  # the count for interval k after a rejection
        stiff_k, stiff_hr, kink_k = -1, np.inf, -1  # the last stiff rejection (interval, h·rate); an interval with a kink
        redo_k, redos = -1, 0  # the interval redone after its state became non-finite in its sub-steps, and how often
        kink_e: dict[int, float] = {}  # an interval redone after its kink check failed: the change it measured
        budget = 4096  # sub-step rows per VM call; shrinks where the predictions fail, grows while they hold
        while k < N:
            n_k = forced if forced is not None else max(nmin[k], np.ceil(dt[k] * rho / target))
            if n_k > max_substeps and k in kink_e:
                substeps[k] = n_k
                return IntervalResult(states, outputs, substeps, rate, failed=k, carry=carry, unconverged=kink_e[k])
            if n_k > max_substeps:
                return IntervalResult(states, outputs, substeps, rate, refused=(k, float(n_k)), carry=carry)
            # predicted counts for k, k+1, ... while the rate stays at rho, as many as fit in the budget of rows
            rest = np.maximum(nmin[k + 1:], np.ceil(dt[k + 1:] * rho / target))
            fit = int(np.searchsorted(np.cumsum(rest), budget - n_k, side="right")) if n_k < budget else 0
            counts = np.concatenate([[n_k], rest[:fit]]).astype(np.int64)
            finals, rmaxes, rfirst, outs = self._eval_rows(start, A, k, counts, reject, keep=kink_k - k)
            # verify: the count each interval needed given the rate measured in the one before it
            m = counts.size
            eff = rmaxes.copy()  # the rate each interval passes on; a kink's (about 2/h) says nothing about the next
            if k <= kink_k < k + m:
                eff[kink_k - k] = rho if kink_k == k else eff[kink_k - k - 1]
            prev = np.concatenate([[rho], eff[:-1]])
            need = np.maximum(nmin[k:k + m], np.ceil(dt[k:k + m] * prev / target))
            if forced is not None:
                need[0] = forced
            recount = need != counts
            stiff = np.isfinite(rfirst)
            if k <= kink_k < k + m:
                stiff[kink_k - k] = False
            broken = ~(np.isfinite(finals).all(axis=1) & np.isfinite(outs).all(axis=1))
            bad = np.flatnonzero(recount | stiff | broken)
            accepted = int(bad[0]) if bad.size else m
            if k <= kink_k < k + accepted:   # the kink is accepted: check it by step doubling, as the C driver does
                i_k = kink_k - k
                s_start = start if i_k == 0 else finals[i_k - 1]
                e, e_prev, n_kink = np.inf, np.inf, float(counts[i_k])
                for _ in range(KINK_DOUBLINGS):
                    n2 = 2 * int(counts[i_k])
                    if n2 > max_substeps:
                        return IntervalResult(states, outputs, substeps, rate, refused=(kink_k, float(n2)), carry=carry)
                    f2, r2, _, o2 = self._eval_rows(s_start, A, kink_k, np.array([n2], dtype=np.int64), reject, keep=0)
                    e_prev, e = e, _kink_change(f2[0], finals[i_k], s_start)
                    finals[i_k], outs[i_k], counts[i_k], rmaxes[i_k] = f2[0], o2[0], n2, max(rmaxes[i_k], r2[0])
                    if e <= 1:
                        break
                if not (e <= 1) and not (e <= KINK_SHRINK * e_prev):
                    sl = slice(k, kink_k)
                    substeps[sl], rate[sl], states[sl], outputs[sl] = counts[:i_k], rmaxes[:i_k], finals[:i_k], outs[:i_k]
                    carry[sl] = eff[:i_k]
                    if redo_k != kink_k:
                        redo_k, redos = kink_k, 0
                    if redos < BLOWUP_REDOS and REDO_GROWTH * n_kink <= max_substeps:
                        # as the C driver: a kink into a stiff region whose first count was unstable there
                        redos += 1
                        kink_e[kink_k] = float(e)
                        if i_k:
                            start, rho = finals[i_k - 1].copy(), float(eff[i_k - 1])
                        k, forced, stiff_k, stiff_hr, kink_k = kink_k, REDO_GROWTH * n_kink, -1, np.inf, -1
                        budget = max(64, budget // 4)
                        continue
                    substeps[kink_k], rate[kink_k] = counts[i_k], rmaxes[i_k]
                    return IntervalResult(states, outputs, substeps, rate, failed=kink_k, carry=carry, unconverged=float(e))
                accepted = i_k + 1          # the intervals after it started from its old end: they are run again
                bad = bad[bad < accepted]
            sl = slice(k, k + accepted)
            substeps[sl], rate[sl], states[sl], outputs[sl] = counts[:accepted], rmaxes[:accepted], finals[:accepted], outs[:accepted]
            carry[sl] = eff[:accepted]
            reason = None
            if bad.size:
                b = accepted
                reason = "recount" if recount[b] else ("stiff" if stiff[b] else "broken")
                if reason == "broken":
                    if redo_k != k + b:
                        redo_k, redos = k + b, 0
                    if redos < BLOWUP_REDOS and REDO_GROWTH * counts[b] <= max_substeps and dt[k + b] > 0:
                        redos += 1   # as the C driver: too few sub-steps before any rate was seen, or a true escape
                        reason = "redo"
                    else:
                        substeps[k + b], rate[k + b] = counts[b], rmaxes[b]
                        return IntervalResult(states, outputs, substeps, rate, failed=k + b, carry=carry,
                                              unconverged=kink_e.get(k + b))
                rho_stiff = float(rfirst[b])  # the rate where the C loop stops the interval
            prev_rate = float(eff[accepted - 1]) if accepted else rho
            forced = None
            if accepted:
                start, rho, k = states[k + accepted - 1].copy(), prev_rate, k + accepted
            if reason == "redo":   # the rate rule on again (a kink into a stiff region is no kink to finish)
                forced, stiff_k, stiff_hr, kink_k = REDO_GROWTH * float(counts[accepted]), -1, np.inf, -1
                budget = max(64, budget // 4)
            elif reason == "stiff":
                hr = dt[k] / counts[accepted] * rho_stiff
                if k == stiff_k and hr > 0.75 * stiff_hr:
                    # more sub-steps did not shrink h·rate: a kink or jump of the flow (abs, sign, min, max), not a
                    # fast mode (its difference quotient grows as 1/h); finish the interval with these sub-steps
                    kink_k, forced = k, float(counts[accepted])
                else:
                    stiff_k, stiff_hr = k, hr
                    forced = max(min(np.ceil(dt[k] * rho_stiff / target), REDO_GROWTH * float(counts[accepted])),
                                 2 * float(counts[accepted]))
                budget = max(64, budget // 4)
            elif reason == "recount":
                budget = max(64, budget // 4)
            else:
                budget = min(budget * 4, 1 << 16)
        return IntervalResult(states, outputs, substeps, rate, carry=carry)

    def _eval_rows(self, start: np.ndarray, A: np.ndarray, k: int, counts: np.ndarray,
                   reject: float, keep: int = -1) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Run intervals k, k+1, ... with the given sub-step counts from `start`, in VM calls of at most 4096
        sub-step rows built on the fly (a long gap never becomes one big array): the state and the output
        after each interval's jump, the fastest rate measured in each, and the first rate with h·rate > reject
        in each (NaN where none: the rate at which the C loop abandons the interval).

        Like the C loop, the run stops after the call in which an interval exceeds the rate (except interval
        k + `keep`, a kink finished at its count) or its state becomes non-finite: that interval is redone
        anyway, and the intervals after it are left NaN (so a rejected long gap is not run to its end first)."""
        cum = np.cumsum(counts)
        total = int(cum[-1])
        finals = np.full((counts.size, self.ns), np.nan)
        outs = np.full((counts.size, self.no), np.nan)
        rmax = np.zeros(counts.size)
        rfirst = np.full(counts.size, np.nan)
        state, i = start, 0
        while i < total:
            check_time("running on CasADi's virtual machine")
            K = min(4096 if self.compilable else 256, total - i)   # an MX row (an NLP inside) holds much more
            K2 = 1 << (K - 1).bit_length()  # a power of two: few distinct VM functions
            r = np.arange(i, i + K)
            idx = np.searchsorted(cum, r, side="right")
            a = A[k + idx]
            n = counts[idx]
            h = a[:, 1] / n
            flag = (r == cum[idx] - 1).astype(float)
            block = np.column_stack([a, a[:, 0] + (r - (cum[idx] - n)) * h, h, flag])
            if K2 != K:  # pad with no-op rows (h = 0, no jump), dropped below
                pad = np.repeat(block[-1:], K2 - K, axis=0)
                pad[:, self.na + 1:] = 0.0
                block = np.vstack([block, pad])
            Sk, Ok = np.empty((K2, self.ns)), np.empty((K2, 1 + self.no))
            buf, ev = self._rows_fn(K2, jumps=bool(flag.any())).buffer()  # NumPy buffers in and out: no DM conversion
            state_in, rows_in = np.ascontiguousarray(state, dtype=float), np.ascontiguousarray(block)
            buf.set_arg(0, memoryview(state_in))
            buf.set_arg(1, memoryview(rows_in))  # row-major (K2, na + 3) is CasADi's column-major (na + 3, K2)
            buf.set_res(0, memoryview(Sk))
            buf.set_res(1, memoryview(Ok))
            ev()
            raise_deferred()  # an error recorded by a Python callback in the jump (e.g. MHE's solver)
            Sk, Ok = Sk[:K], Ok[:K]
            rates = np.where(np.isfinite(Ok[:, 0]), Ok[:, 0], 0.0)
            np.maximum.at(rmax, idx, rates)
            over = np.flatnonzero(h * rates > reject)
            if over.size:  # the first exceedance per interval, if that interval had none before
                first_of, where = np.unique(idx[over], return_index=True)
                new = np.isnan(rfirst[first_of])
                rfirst[first_of[new]] = rates[over[where[new]]]
            ends = flag > 0
            finals[idx[ends]] = Sk[ends]
            outs[idx[ends]] = Ok[ends, 1:]
            state = Sk[-1]
            i += K
            stop = np.isfinite(rfirst)
            if 0 <= keep < stop.size:
                stop[keep] = False
            if stop.any() or not np.isfinite(state).all():
                break
            if self._progress is not None and np.isfinite(Sk[ends]).all() and np.isfinite(Ok[ends]).all():
                self._progress(float(block[K - 1, self.na] + block[K - 1, self.na + 1]))  # the time reached
        return finals, rmax, rfirst, outs


def _kink_change(fine: np.ndarray, coarse: np.ndarray, start: np.ndarray) -> float:
    """The largest change of an end state between n and 2n sub-steps, each entry relative to KINK_ATOL + KINK_RTOL·|x|
    (NaN or infinite: infinite)."""
    scale = KINK_ATOL + KINK_RTOL * np.maximum(np.maximum(np.abs(fine), np.abs(coarse)), np.abs(start))
    e = np.abs(fine - coarse) / scale
    return float(np.max(e)) if np.all(np.isfinite(e)) else np.inf


def fastest_rate(J: np.ndarray) -> float:
    """The flow's fastest local rate from its Jacobian J (n x n): the spectral radius, exactly (eigenvalues) up to
    n = 64, above that estimated by :func:`power_rate`. It only sets the first interval's sub-steps — the rate measured
    by the RK4 stages takes over after it, and redoes an interval whose steps were too long — so an estimate is enough,
    and a 16-state EKF's 272 x 272 Jacobian costs 0.1 ms instead of an eigenvalue problem of 50-250 ms. 0 when J is
    empty or not finite."""
    J = np.asarray(J, dtype=float)
    n = J.shape[0] if J.ndim == 2 else 0
    if n == 0 or not np.all(np.isfinite(J)):
        return 0.0
    if n <= EXACT_RATE_MAX:
        return float(np.max(np.abs(np.linalg.eigvals(J))))
    return power_rate(lambda v: J @ v, n)


#: Up to this many states the fastest rate is the spectral radius of the Jacobian, exactly; above it the power
#: iteration of :func:`power_rate`, on Jacobian-vector products (no n x n Jacobian is formed).
EXACT_RATE_MAX = 64


def power_rate(matvec: Callable[[np.ndarray], np.ndarray], n: int) -> float:
    """The spectral radius of a linear map of R^n given by its product `matvec(v)`, estimated by 48 steps of power
    iteration from a fixed vector: the geometric mean of the growth over the last 24 (a dominant complex pair makes
    single steps oscillate). 0 when a product is 0 or not finite."""
    v = 1.0 + 0.5 * np.cos(np.arange(n) * 2.399963229728653)   # no symmetry a structured J could be blind to
    v /= np.linalg.norm(v)
    logs = np.empty(48)
    for i in range(48):
        w = np.asarray(matvec(v), dtype=float).reshape(-1)
        nw = float(np.linalg.norm(w))
        if not (nw > 0 and np.isfinite(nw)):
            return 0.0
        logs[i], v = np.log(nw), w / nw
    return float(np.exp(np.mean(logs[24:])))


def _finite_rate(rate: float) -> float:
    """A usable first rate: 0 where it is not finite or negative."""
    rate = float(rate)
    return rate if math.isfinite(rate) and rate >= 0 else 0.0


class _CompiledIntervals:
    """The C interval driver for one (sub, jump) pair, built once per machine (cached on disk)."""

    def __init__(self, sub: ca.Function, jump: ca.Function, sig: str, idle: slice | None = None):
        self.ns, self.na, self.no = sub.size1_in(0), sub.size1_in(1), jump.size1_out(1)

        def code() -> str:
            rs, rj = _renamed(sub, "nlobs_sub"), _renamed(jump, "nlobs_jump")   # (MX stays MX: its calls stay calls)
            fns = [rs, rj]
            skip = idle
            if idle is not None:   # the jump with the idle entries of `a` at 0, simplified by SX's constant folding
                s, a = ca.SX.sym("s", self.ns), ca.SX.sym("a", self.na)
                a0 = ca.vertcat(a[:idle.start], ca.SX.zeros(idle.stop - idle.start), a[idle.stop:])
                j0 = ca.Function("nlobs_jump0", [s, a], list(jump(s, a0)))
                # worth its compile only when it is much smaller (an EKF's update without a sample is 1/15 of it; a
                # square-root filter's still re-triangularises its factor, half of it)
                if j0.n_instructions() <= 0.25 * jump.n_instructions():
                    fns.append(j0)
                else:
                    skip = None
            defs = {"NLOBS_SZ_ARG": max(f.sz_arg() for f in fns), "NLOBS_SZ_RES": max(f.sz_res() for f in fns),
                    "NLOBS_SZ_IW": max(f.sz_iw() for f in fns), "NLOBS_SZ_W": max(f.sz_w() for f in fns),
                    "IDLEAT": skip.start if skip is not None else 0,
                    "IDLEN": (skip.stop - skip.start) if skip is not None else 0,
                    "NS": self.ns, "NA": self.na, "NW": (self.na - 2) // 2, "NO": self.no}
            driver = (_C_DRIVER.replace("SUB(", "nlobs_sub(").replace("JUMP0(", "nlobs_jump0(" if skip is not None else
                                                                      "nlobs_jump(").replace("JUMP(", "nlobs_jump("))
            for k, v in defs.items():
                driver = driver.replace(k, str(int(v)))
            return _generate(*fns) + "#include <math.h>\n" + driver

        path = _build(code, "intervals", built_path("intervals", sig, _C_DRIVER), n_instr=code_size(sub) + code_size(jump))
        self.path = path
        lib = ctypes.CDLL(str(path))
        self._fn = lib.nlobs_intervals
        ptr = ctypes.c_void_p  # arrays passed by address (ndarray.ctypes.data: a third of the cost of data_as)
        self._fn.argtypes = [ptr, ptr, ptr, ctypes.c_double, ctypes.c_double, ctypes.c_double, ctypes.c_double,
                             ptr, ptr, ptr, ptr, ctypes.c_longlong, ptr, ptr, ptr, ptr, ctypes.c_void_p, ptr, ptr]
        self._fn.restype = ctypes.c_longlong
        self._lib = lib

    def __call__(self, s0: np.ndarray, A: np.ndarray | Rows, nmin: np.ndarray, rate0: float, target: float,
                 reject: float, max_substeps: int, sched: Schedule | None = None,
                 slots: np.ndarray | None = None) -> IntervalResult:
        rows_in = A if isinstance(A, Rows) else None
        N = A.n if rows_in is not None else A.shape[0]
        ns, no = self.ns, max(self.no, 1)
        if sched is None:   # every row written up to a failure, the rest set below (a fifth of a short run's set-up)
            # one block for every result (one allocation, one address: ndarray.ctypes costs a microsecond a call):
            # the states and the outputs each with a row 0 above (the start state; the caller's), then the sub-steps,
            # rates, carried rates and the two entries of `need`
            buf = np.empty((N + 1) * (ns + no) + 3 * N + 2)
            base, f8 = buf.ctypes.data, buf.itemsize
            lead = buf[:(N + 1) * ns].reshape(N + 1, ns)
            lead[0] = s0
            o0 = (N + 1) * ns
            olead = buf[o0:o0 + (N + 1) * no].reshape(N + 1, no)
            v0 = o0 + (N + 1) * no
            states, outputs = lead[1:], olead[1:]
            substeps, rate, carry, need = buf[v0:v0 + N], buf[v0 + N:v0 + 2 * N], buf[v0 + 2 * N:v0 + 3 * N], \
                buf[v0 + 3 * N:]
            need[:] = 0
            at = (base + ns * f8, base + (o0 + no) * f8, base + v0 * f8, base + (v0 + N) * f8, base + (v0 + 3 * N) * f8,
                  base + (v0 + 2 * N) * f8)
        else:
            lead, olead, rows = None, None, sched.n_emit
            states, outputs = np.full((rows, ns), np.nan), np.full((rows, no), np.nan)
            substeps, rate, carry, need = np.zeros(N), np.full(N, np.nan), np.full(N, np.nan), np.zeros(2)
            at = (states.ctypes.data, outputs.ctypes.data, substeps.ctypes.data, rate.ctypes.data, need.ctypes.data,
                  carry.ctypes.data)
        ops = None if sched is None else np.ascontiguousarray(sched.ops(), dtype=np.int64)
        slots = None if sched is None else np.ascontiguousarray(slots, dtype=float)
        with Watchdog() as dog:
            rc = self._fn(s0.ctypes.data, None if rows_in is not None else A.ctypes.data, nmin.ctypes.data, rate0,
                          target, reject, float(max_substeps), at[0], at[1], at[2], at[3], N, at[4],
                          None if ops is None else ops.ctypes.data, None if slots is None else slots.ctypes.data,
                          at[5], dog.ref, None if rows_in is None else rows_in.t.ctypes.data,
                          None if rows_in is None else rows_in.B.ctypes.data)
        if rc < 0 and need[0] == -1:
            dog.raise_if_tripped("running its compiled loop")
        if rc != 0 and sched is None:   # the rows from the interval that failed on are NaN (substeps 0), as documented
            k = int(abs(rc) - 1)
            states[k:], outputs[k:], rate[k + 1:], carry[k:], substeps[k + 1:] = np.nan, np.nan, np.nan, np.nan, 0
            if rc < 0:   # refused before its sub-steps ran
                rate[k], substeps[k] = np.nan, 0
        outputs = outputs[:, :self.no]
        olead = None if olead is None else olead[:, :self.no]
        if rc > 0:
            return IntervalResult(states, outputs, substeps, rate, failed=int(rc - 1), backend="c", carry=carry,
                                  unconverged=float(need[1]) if need[0] == -2 else None, lead=lead, olead=olead)
        if rc < 0:
            return IntervalResult(states, outputs, substeps, rate, refused=(int(-rc - 1), float(need[0])), backend="c",
                                  carry=carry, lead=lead, olead=olead)
        # (the driver checks every state and output of every interval it finishes: rc == 0 means all are finite)
        return IntervalResult(states, outputs, substeps, rate, backend="c", carry=carry, lead=lead, olead=olead)
