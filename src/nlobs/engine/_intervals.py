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
n_k = max(ceil(dt_k · ρ_measured / c), 2 n_k): a stiff covariance equation or a fast transient
cannot silently inflate the state between samples. When twice the sub-steps do not shrink h·ρ (by at
least a quarter), the interval holds a kink or a jump of the flow (abs, sign, min, max: the difference
quotient grows as 1/h there), not a fast mode: it is finished with those sub-steps and its rate is not
passed on to the next interval. An interval needing more than `max_substeps`
sub-steps is refused (with its index and the count needed), and a state that becomes non-finite
stops the run (with the interval).

The C path is a generated loop over the intervals with the sub-step loop inside (nothing is
unrolled: a gap of 10⁸ steps costs 10⁸ calls, not a graph of that size); the VM path runs chunks of
sub-steps with :meth:`casadi.Function.mapaccum` under the same rule, predicting each interval's
count and re-running from the first interval whose prediction proves wrong.
"""

from __future__ import annotations

import ctypes
import time
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..errors import EngineError
from ._deferred import raise_deferred
from ._codegen import COSTS, Backend, _build, _generate, _renamed, built_path, choose_backend, signature_of

__all__ = ["IntervalRunner", "IntervalResult", "MAX_SUBSTEPS"]

#: The most RK4 sub-steps one interval may take before it is refused.
MAX_SUBSTEPS = 10**8

_C_DRIVER = r"""
/* nlobs interval driver: per interval k, n_k sub-steps of SUB then JUMP (see nlobs.engine._intervals).
   Returns 0; k + 1 when the state became non-finite in interval k; -(k + 1) when interval k needs more than
   max_sub sub-steps (their number is written to need[0]). nsub[k], rate[k] are filled for every finished interval. */
long long nlobs_intervals(const double* s0, const double* A, const double* nmin, double rate0, double target,
                          double reject, double max_sub, double* out, double* obuf, double* nsub, double* rate,
                          long long n_int, double* need) {
  const double* arg[NLOBS_SZ_ARG];
  double* res[NLOBS_SZ_RES];
  casadi_int iw[NLOBS_SZ_IW + 1];
  double w[NLOBS_SZ_W + 1];
  double start[NS], cur[NS], nxt[NS], th[2], r, o[NO + 1];
  double rho = rate0, t, dt, n, m, h, rmax, hr, prev_hr;
  long long k, i, ni;
  int j, bad, stiff, check;
  for (j = 0; j < NS; ++j) start[j] = s0[j];
  for (k = 0; k < n_int; ++k) {
    const double* a = A + k * NA;
    t = a[0]; dt = a[1];
    n = nmin[k];
    m = ceil(dt * rho / target);
    if (m > n) n = m;
    prev_hr = INFINITY; check = 1;
    for (;;) {
      if (n > max_sub) { need[0] = n; return -(k + 1); }
      ni = (long long)n; h = dt / n; rmax = 0; bad = 0; stiff = 0;
      for (j = 0; j < NS; ++j) cur[j] = start[j];
      arg[1] = a; arg[2] = th; res[1] = &r;
      for (i = 0; i < ni; ++i) {
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
        prev_hr = hr; m = ceil(dt * rmax / target); n = m > 2 * n ? m : 2 * n; continue;
      }
      nsub[k] = n; rate[k] = rmax;
      if (bad) return k + 1;
      if (check) rho = rmax;  /* a kink's rate (about 2/h) says nothing about the next interval */
      break;
    }
    arg[0] = cur; arg[1] = a; res[0] = out + k * NS; res[1] = NO > 0 ? obuf + k * NO : o;
    JUMP(arg, res, iw, w, 0);
    bad = 0;
    for (j = 0; j < NS; ++j) bad |= !(fabs(out[k * NS + j]) < INFINITY);
    for (j = 0; j < NO; ++j) bad |= !(fabs(res[1][j]) < INFINITY);
    if (bad) return k + 1;
    for (j = 0; j < NS; ++j) start[j] = out[k * NS + j];
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
    """

    states: np.ndarray
    outputs: np.ndarray
    substeps: np.ndarray
    rate: np.ndarray
    failed: int | None = None
    refused: tuple[int, float] | None = None
    backend: str = "vm"


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
    """

    def __init__(self, sub: ca.Function, jump: ca.Function, *, backend: Backend = "auto"):
        self.sub, self.jump = sub, jump
        self.ns, self.na, self.no = sub.size1_in(0), sub.size1_in(1), jump.size1_out(1)
        self.backend = backend
        self.compilable = sub.is_a("SXFunction") and jump.is_a("SXFunction")
        self._sig = signature_of(sub) + signature_of(jump) if self.compilable else ""
        self._c: _CompiledIntervals | None = None
        self._ready = False
        self._vm: dict[tuple[int, bool], ca.Function] = {}
        self._progress: Callable[[float], None] | None = None  # during a VM run: called with the time reached
        self._n_instr = (sub.n_instructions() + jump.n_instructions()) if self.compilable else 0

    def backend_for(self, work: float) -> str:
        """Where a run of `work` sub-steps goes (by measured cost; MX functions always run on the VM)."""
        if not self.compilable or self.backend == "vm":
            return "vm"
        if not self._ready:  # remembered once true: the build stays in the cache
            path = built_path("intervals", self._sig, _C_DRIVER)
            self._ready = self._c is not None or (path is not None and path.exists())
        ready = self._ready
        return choose_backend(self.backend, ready=ready, n_instr=self._n_instr, vm_instr=work * self.sub.n_instructions(),
                              signature=self._sig)

    def run(self, s0: np.ndarray, A: np.ndarray, nmin: np.ndarray, *, rate0: float, target: float = 1.0,
            reject: float = 2.0, max_substeps: int = MAX_SUBSTEPS,
            on_progress: Callable[[float], None] | None = None) -> IntervalResult:
        """Integrate from `s0` over the intervals described by the rows of `A` (shape (N, na)).

        `on_progress(fraction)` is called with the fraction of the time span covered: after each VM call
        on the virtual machine (a long gap reports as it goes), once at the end for the compiled loop."""
        A = np.ascontiguousarray(A, dtype=float)
        nmin = np.ascontiguousarray(nmin, dtype=float)
        s0 = np.ascontiguousarray(s0, dtype=float).reshape(self.ns)
        N = A.shape[0]
        if not np.isfinite(rate0) or rate0 < 0:
            rate0 = 0.0
        # the work predicted from the first rate (a long gap needs many sub-steps although nmin is small there)
        backend = self.backend_for(float(np.maximum(nmin, np.ceil(A[:, 1] * rate0 / target)).sum()))
        if backend == "c":
            if self._c is None:
                self._c = _CompiledIntervals(self.sub, self.jump, self._sig)
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
            COSTS.record_vm(float(res.substeps.sum()) * self.sub.n_instructions(), spent)
        return res

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
        substeps, rate = np.zeros(N), np.full(N, np.nan)
        dt = A[:, 1]
        start, rho, k = s0.copy(), rate0, 0
        forced: float | None = None  # the count for interval k after a rejection
        stiff_k, stiff_hr, kink_k = -1, np.inf, -1  # the last stiff rejection (interval, h·rate); an interval with a kink
        budget = 4096  # sub-step rows per VM call; shrinks where the predictions fail, grows while they hold
        while k < N:
            n_k = forced if forced is not None else max(nmin[k], np.ceil(dt[k] * rho / target))
            if n_k > max_substeps:
                return IntervalResult(states, outputs, substeps, rate, refused=(k, float(n_k)))
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
            sl = slice(k, k + accepted)
            substeps[sl], rate[sl], states[sl], outputs[sl] = counts[:accepted], rmaxes[:accepted], finals[:accepted], outs[:accepted]
            reason = None
            if bad.size:
                b = accepted
                reason = "recount" if recount[b] else ("stiff" if stiff[b] else "broken")
                if reason == "broken":
                    substeps[k + b], rate[k + b] = counts[b], rmaxes[b]
                    return IntervalResult(states, outputs, substeps, rate, failed=k + b)
                rho_stiff = float(rfirst[b])  # the rate where the C loop stops the interval
            prev_rate = float(eff[accepted - 1]) if accepted else rho
            forced = None
            if accepted:
                start, rho, k = states[k + accepted - 1].copy(), prev_rate, k + accepted
            if reason == "stiff":
                hr = dt[k] / counts[accepted] * rho_stiff
                if k == stiff_k and hr > 0.75 * stiff_hr:
                    # more sub-steps did not shrink h·rate: a kink or jump of the flow (abs, sign, min, max), not a
                    # fast mode (its difference quotient grows as 1/h); finish the interval with these sub-steps
                    kink_k, forced = k, float(counts[accepted])
                else:
                    stiff_k, stiff_hr = k, hr
                    forced = max(np.ceil(dt[k] * rho_stiff / target), 2 * float(counts[accepted]))
                budget = max(64, budget // 4)
            elif reason == "recount":
                budget = max(64, budget // 4)
            else:
                budget = min(budget * 4, 1 << 16)
        return IntervalResult(states, outputs, substeps, rate)

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
            K = min(4096, total - i)
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


class _CompiledIntervals:
    """The C interval driver for one (sub, jump) pair, built once per machine (cached on disk)."""

    def __init__(self, sub: ca.Function, jump: ca.Function, sig: str):
        self.ns, self.na, self.no = sub.size1_in(0), sub.size1_in(1), jump.size1_out(1)
        rs, rj = _renamed(sub, "nlobs_sub"), _renamed(jump, "nlobs_jump")

        def code() -> str:
            defs = {"NLOBS_SZ_ARG": max(rs.sz_arg(), rj.sz_arg()), "NLOBS_SZ_RES": max(rs.sz_res(), rj.sz_res()),
                    "NLOBS_SZ_IW": max(rs.sz_iw(), rj.sz_iw()), "NLOBS_SZ_W": max(rs.sz_w(), rj.sz_w()),
                    "NS": self.ns, "NA": self.na, "NO": self.no}
            driver = _C_DRIVER.replace("SUB(", "nlobs_sub(").replace("JUMP(", "nlobs_jump(")
            for k, v in defs.items():
                driver = driver.replace(k, str(int(v)))
            return _generate(rs, rj) + "#include <math.h>\n" + driver

        path = _build(code, "intervals", built_path("intervals", sig, _C_DRIVER), n_instr=sub.n_instructions() + jump.n_instructions())
        self.path = path
        lib = ctypes.CDLL(str(path))
        self._fn = lib.nlobs_intervals
        dbl = ctypes.POINTER(ctypes.c_double)
        self._fn.argtypes = [dbl, dbl, dbl, ctypes.c_double, ctypes.c_double, ctypes.c_double, ctypes.c_double,
                             dbl, dbl, dbl, dbl, ctypes.c_longlong, dbl]
        self._fn.restype = ctypes.c_longlong
        self._lib = lib

    def __call__(self, s0: np.ndarray, A: np.ndarray, nmin: np.ndarray, rate0: float, target: float, reject: float,
                 max_substeps: int) -> IntervalResult:
        N = A.shape[0]
        states, outputs = np.full((N, self.ns), np.nan), np.full((N, max(self.no, 1)), np.nan)
        substeps, rate, need = np.zeros(N), np.full(N, np.nan), np.zeros(1)
        p = ctypes.POINTER(ctypes.c_double)
        rc = self._fn(s0.ctypes.data_as(p), A.ctypes.data_as(p), nmin.ctypes.data_as(p), rate0, target, reject,
                      float(max_substeps), states.ctypes.data_as(p), outputs.ctypes.data_as(p), substeps.ctypes.data_as(p),
                      rate.ctypes.data_as(p), N, need.ctypes.data_as(p))
        outputs = outputs[:, :self.no]
        if rc > 0:
            return IntervalResult(states, outputs, substeps, rate, failed=int(rc - 1), backend="c")
        if rc < 0:
            return IntervalResult(states, outputs, substeps, rate, refused=(int(-rc - 1), float(need[0])), backend="c")
        if not np.all(np.isfinite(states)):  # pragma: no cover - the driver checks every interval
            raise EngineError("the compiled interval driver returned non-finite states without reporting them")
        return IntervalResult(states, outputs, substeps, rate, backend="c")
