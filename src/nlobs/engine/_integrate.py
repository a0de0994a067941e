"""Fixed-step integration: an RK4 step builder and a runner for s_{k+1} = step(s_k, a_k, c).

The runner evaluates the step N times — in a generated C loop, or with
:meth:`casadi.Function.mapaccum` on the VM (in chunks of bounded size) — writing straight into a
preallocated NumPy array through :meth:`casadi.Function.buffer` (no intermediate DM).
"""

from __future__ import annotations

import os
import threading
import time
import warnings
from collections import OrderedDict
from collections.abc import Callable
from typing import Any, Literal

import casadi as ca
import numpy as np

from ..errors import ConvergenceWarning, EngineError
from ._codegen import (_BATCH, _DRIVER, COSTS, Backend, CompiledBatch, CompiledLoop, _forced, built_path, choose_backend,
                       code_size, signature_of)
from ._budget import check_time
from ._deferred import raise_deferred
from ._simd import _DRIVER as _SIMD_DRIVER
from ._simd import _KERNEL_VERSION, LANES, CompiledSimdBatch, simd_supported

__all__ = ["rk4_step", "rk4_step_rate", "StepRunner", "DEFAULT_CHUNK", "run_batch", "batch_backend", "saved_steps",
           "usable_cores"]

DEFAULT_CHUNK = 10_000
#: The most (state + input + output) entries times steps one VM chunk of :class:`StepRunner` covers: building CasADi's
#: mapaccum over K steps takes about 35 bytes per entry and step for a while (1.26 GB, and 4.6 s, for the 16-state
#: navigation model's sensitivities, 469 entries, over 10,000 steps; 0.13 GB for 1,000).
VM_CHUNK_ENTRIES = 1_000_000


def rk4_step(rhs: Callable[[Any, Any, int], Any], t: Any, s: Any, dt: Any, *, half: Any = None, sixth: Any = None) -> Any:
    """One classical Runge-Kutta 4 step; ``rhs(t, s, stage)`` gets the stage index 0, 1, 1, 2
    (start, midpoint twice, end) so callers can feed stage-specific inputs.

    `half` and `sixth` may carry dt/2 and dt/6 precomputed (e.g. as run-time constants), so that
    the step itself has no division.
    """
    return rk4_step_rate(rhs, t, s, dt, half=half, sixth=sixth)[0]


def rk4_step_rate(rhs: Callable[[Any, Any, int], Any], t: Any, s: Any, dt: Any, *, half: Any = None,
                  sixth: Any = None, rate: bool = False) -> tuple[Any, Any]:
    """One RK4 step and, with ``rate=True``, an estimate of the flow's fastest local rate (1/time).

    The rate is ``‖k3 − k2‖ / ‖Y3 − Y2‖`` for the two stages evaluated at the same time
    t + dt/2 (Y2 = s + dt/2·k1, Y3 = s + dt/2·k2, so Y3 − Y2 = dt/2·(k2 − k1)): a difference
    quotient of the vector field along the direction the stages differ in, i.e. ‖J v‖/‖v‖ for
    the Jacobian J. When the step is too long for a fast (stiff) mode, that mode dominates the
    stage differences and the quotient approaches its rate (the stiffness detector of Hairer &
    Wanner, Solving ODEs II, sec. IV.2, applied to the two equal-time stages of RK4). Classical
    RK4 is stable for dt·|λ| up to about 2.8 on the real and imaginary axes. The quotient is 0
    when the stages agree to 1e-10 relative (no information; e.g. a flow that depends on t only).
    The rate returned is the larger of that quotient and the same quotient of the last two stages,
    ``‖f(t + dt/2, Y4) − k3‖ / ‖Y4 − Y3‖`` (Y4 = s + dt·k3): a fast mode that only the last stage
    enters (a state the step's end carries past a steep kink) leaves k3 − k2 small but not this one.
    f(t + dt/2, Y4) is k4 itself when the flow does not depend on t (no extra evaluation); else one
    more evaluation, at the time (and stage index 1) of k3.
    """
    if half is None:
        half = dt / 2
    if sixth is None:
        sixth = dt / 6
    k1 = rhs(t, s, 0)
    y2 = s + half * k1
    k2 = rhs(t + half, y2, 1)
    y3 = s + half * k2
    k3 = rhs(t + half, y3, 1)
    y4 = s + dt * k3
    k4 = rhs(t + dt, y4, 2)
    s_next = s + sixth * (k1 + 2 * k2 + 2 * k3 + k4)
    if not rate:
        return s_next, None
    # a fast mode the last stage enters alone (a weir the step's end overflows: Y4 past a steep kink that Y2, Y3 stay
    # below) leaves k3 - k2 small; the quotient of the last two stages, ‖f(Y4) − f(Y3)‖ / ‖Y4 − Y3‖, sees it. Taken at
    # the same time as Y3 (k4 itself when the flow does not depend on t: no extra evaluation), so that a flow's own
    # change in time is not read as a rate.
    X = ca.MX if isinstance(s, ca.MX) else ca.SX
    tau = X.sym("tau")
    probe = rhs(tau, s, 2)
    timed = isinstance(probe, (ca.SX, ca.MX)) and ca.depends_on(probe, tau)
    k4_same = rhs(t + half, y4, 1) if timed else k4
    return s_next, ca.fmax(_quotient(k3 - k2, y3 - y2, s), _quotient(k4_same - k3, y4 - y3, s))


def _quotient(dk: Any, dy: Any, s: Any) -> Any:
    """‖dk‖/‖dy‖ over the entries where both are finite (a stage past the model's domain, e.g. the Jacobian of
    max(x, 0)^b at x < 0, is NaN in some entries: the others still measure the rate), 0 when the stages agree to
    1e-10 relative to the state (no information)."""
    ok = (ca.fabs(dk) < np.inf) * (ca.fabs(dy) < np.inf)   # 1 where both entries are finite
    dk, dy = ca.if_else(ok, dk, 0), ca.if_else(ok, dy, 0)
    den = ca.norm_2(dy)
    return ca.if_else(den > 1e-10 * ca.norm_2(s) + 1e-300, ca.norm_2(dk) / (den + 1e-300), 0)


_VM: dict[tuple[Any, ...], ca.Function] = {}
_LOOPS: dict[str, CompiledLoop] = {}
_BATCHES: dict[str, CompiledBatch | CompiledSimdBatch] = {}
_BUILD_LOCK = threading.Lock()   # one build per step when threads ask for the same batch at once
_STEP_INFO: OrderedDict[int, tuple[ca.Function, str, bool]] = OrderedDict()   # id -> (step, signature, lane-parallel)


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system tells it, else the machine's count)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # no affinity on this platform (macOS, Windows)
        return max(1, os.cpu_count() or 1)


def _signature(fn: ca.Function) -> str:
    return signature_of(fn)


class StepRunner:
    """Run ``s_{k+1}, o_k = step(s_k, a_k, c)`` for many steps.

    Parameters
    ----------
    step : casadi.Function
        ``(s[ns], a[na], c[nc]) -> s_next[ns]`` or ``-> (s_next[ns], o[no])``; `a` changes every
        step, `c` is constant; `o` (optional) is a per-step output computed from the state
        *before* the step (measurements, estimates).
    step_c : casadi.Function, optional
        The same step built for C (e.g. an MX graph calling the functions it would otherwise inline): what
        the compiled loop is generated from. Default: `step`.
    backend : {"auto", "vm", "c"}
        Where to run; ``"auto"`` chooses by measured cost (see :func:`nlobs.engine.choose_backend`).
    chunk : int
        Steps per call when progress is reported (and per VM map); without progress the
        compiled C loop runs the whole horizon in one call.
    """

    def __init__(self, step: ca.Function, *, backend: Backend = "auto", chunk: int = DEFAULT_CHUNK,
                 step_c: ca.Function | None = None):
        if step.n_in() != 3 or step.n_out() not in (1, 2):
            raise ValueError("StepRunner needs step(s, a, c) -> s_next or -> (s_next, o)")
        self.step = step
        self.step_c = step_c
        self.ns = step.size1_in(0)
        self.na = step.size1_in(1)
        self.nc = step.size1_in(2)
        self.no = step.size1_out(1) if step.n_out() == 2 else 0
        self.backend = backend
        self.chunk = int(chunk)
        self._sig = _signature(step) + ("/c:" + _signature(step_c)[:16] if step_c is not None else "")

    def _vm_chunk(self, K: int) -> ca.Function:
        key = (self._sig, K)
        fn = _VM.get(key)
        if fn is None:
            acc = self.step.mapaccum("acc", K)
            s0 = ca.MX.sym("s0", self.ns)
            A = ca.MX.sym("a", self.na, K)
            c = ca.MX.sym("c", self.nc)
            res = acc(s0, A, ca.repmat(c, 1, K))
            fn = ca.Function(f"nlobs_run_{K}", [s0, A, c], list(res) if isinstance(res, (list, tuple)) else [res])
            _VM[key] = fn
        return fn

    def _loop(self) -> CompiledLoop:
        loop = _LOOPS.get(self._sig)
        if loop is None:
            loop = _LOOPS[self._sig] = CompiledLoop(self.step_c if self.step_c is not None else self.step, self._sig)
        return loop

    def backend_for(self, n_steps: int) -> str:
        """Where `n_steps` steps run (see :func:`nlobs.engine.choose_backend`)."""
        if self.backend == "vm":
            return "vm"
        ready = self._sig in _LOOPS or (lambda p: p is not None and p.exists())(built_path("loop", self._sig, _DRIVER))
        return choose_backend(self.backend, ready=ready, n_instr=code_size(self.step_c if self.step_c is not None else self.step),
                              vm_instr=float(n_steps) * self.step.n_instructions(), signature=self._sig)

    def run(self, s0: np.ndarray, a: np.ndarray, c: np.ndarray, *,
            on_chunk: Callable[[np.ndarray, int], None] | None = None,
            out: np.ndarray | None = None, obuf: np.ndarray | None = None,
            bound: float = np.inf) -> tuple[np.ndarray, np.ndarray, int]:
        """States after each step, shape (N, ns), per-step outputs, shape (N, no), for per-step
        inputs `a` of shape (N, na), and the number of good steps.

        The run stops at the first step k whose resulting state is non-finite or exceeds `bound`
        in magnitude; it then returns k (that state is row k of the states), else N.
        `out` and `obuf` may be given (C-contiguous, of those shapes) to write into existing
        arrays. `on_chunk(states_so_far, k_end)` is called after each chunk, for progress.
        """
        a = np.ascontiguousarray(a, dtype=float)
        N = a.shape[0]
        out = np.empty((N, self.ns)) if out is None else out
        obuf = np.empty((N, self.no)) if obuf is None else obuf
        for name, arr, cols in (("out", out, self.ns), ("obuf", obuf, self.no)):
            if arr.shape != (N, cols) or not arr.flags.c_contiguous:
                raise ValueError(f"`{name}` must be a C-contiguous array of shape {(N, cols)}")
        if N == 0:
            return out, obuf
        c = np.ascontiguousarray(np.asarray(c, dtype=float).reshape(self.nc))
        state = np.ascontiguousarray(np.asarray(s0, dtype=float).reshape(self.ns)).copy()
        # an MX step (e.g. embedding an NLP solver) cannot be generated as C: always the VM
        backend = self.backend_for(N) if self.step.is_a("SXFunction") else "vm"
        K = min(self.chunk, N) if (backend != "c" or on_chunk is not None) else N
        if backend != "c":
            K = min(K, max(256, VM_CHUNK_ENTRIES // (self.ns + self.na + self.no)))
        k = 0
        while k < N:
            n = min(K, N - k)
            block, oblock = out[k:k + n], obuf[k:k + n]
            if backend == "c":
                try:
                    loop = self._loop()
                except EngineError as e:   # the compiler refused: "auto" runs on the VM instead, "c" fails
                    if _forced(self.backend) == "c":
                        raise
                    warnings.warn(f"{e}; running on CasADi's virtual machine instead", ConvergenceWarning, stacklevel=3)
                    self.backend = backend = "vm"
                    continue
                done = loop(state, a[k:k + n], c, block, oblock if self.no else None, bound)
            else:
                check_time("running on CasADi's virtual machine")
                t_vm = time.perf_counter()
                buf, ev = self._vm_chunk(n).buffer()
                buf.set_arg(0, memoryview(state))
                buf.set_arg(1, memoryview(a[k:k + n]))
                buf.set_arg(2, memoryview(c))
                buf.set_res(0, memoryview(block))
                if self.no:
                    buf.set_res(1, memoryview(oblock))
                ev()
                raise_deferred()  # an error recorded by a Python callback in the step (e.g. MHE's solver)
                spent = time.perf_counter() - t_vm
                COSTS.spent[self._sig] = COSTS.spent.get(self._sig, 0.0) + spent
                COSTS.record_vm(float(n) * self.step.n_instructions(), spent)
                bad = (~(np.abs(block) <= bound)).any(axis=1)  # NaN counts as bad
                done = int(np.argmax(bad)) if bad.any() else n
            if done < n:
                return out, obuf, k + done
            state = block[-1].copy()
            k += n
            if on_chunk is not None:
                on_chunk(out[:k], k)
        return out, obuf, N


def batch_backend(step: ca.Function, n_traj: int, n_steps: int, backend: Backend = "auto") -> Literal["vm", "c"]:
    """Where :func:`run_batch` runs `n_traj` trajectories of `n_steps` steps of `step`: ``"auto"`` chosen by cost for
    all of them at once (see :func:`nlobs.engine.choose_backend`), and for ``"c"`` the compiled batch built (once per
    step and process, whichever thread asks first). A caller that splits a batch into chunks asks once for the whole
    batch and passes the answer to every chunk, so that every chunk runs where the whole would (and the same numbers
    come out however the batch is split, or run on threads)."""
    return "c" if _compiled_batch(step, n_traj, n_steps, backend) is not None else "vm"


def _compiled_batch(step: ca.Function, n_traj: int, n_steps: int, backend: Backend) -> CompiledBatch | CompiledSimdBatch | None:
    """The compiled batch of `step` (lane-parallel, SIMD across trajectories, when every operation allows it) where the
    batch runs compiled (:func:`batch_backend`), else None."""
    if backend == "vm":
        return None
    ns = step.size1_in(0)
    known = _STEP_INFO.get(id(step))
    if known is None or known[0] is not step:
        # its hash and whether it runs lane-parallel: read once per step (a Python pass over its instructions, under
        # Python's lock: asked again by every chunk of a Monte Carlo run, on every thread)
        known = (step, _signature(step), step.is_a("SXFunction") and simd_supported(step))
        _STEP_INFO[id(step)] = known   # the step kept: its id is not reused while it is here
        if len(_STEP_INFO) > 256:
            _STEP_INFO.popitem(last=False)
    _, sig, simd = known
    ready = sig in _BATCHES or (lambda p: p is not None and p.exists())(
        built_path("simd", sig + f"/{LANES}", _SIMD_DRIVER + _KERNEL_VERSION) if simd else built_path("batch", sig, _BATCH))
    work = float(n_traj) * n_steps * ns
    if choose_backend(backend, ready=ready, n_instr=step.n_instructions(), vm_instr=work / max(ns, 1) * step.n_instructions(),
                      signature=sig) != "c":
        return None
    batch = _BATCHES.get(sig)
    if batch is None:
        with _BUILD_LOCK:
            batch = _BATCHES.get(sig)
            if batch is None:
                batch = _BATCHES[sig] = CompiledSimdBatch(step, sig=sig) if simd else CompiledBatch(step, sig)
    return batch


def saved_steps(n_steps: int, stride: int) -> np.ndarray:
    """The step indices a batch run saves: 0, stride, 2·stride, ... (< n_steps), and n_steps."""
    return np.r_[np.arange(0, n_steps, stride), n_steps]


def run_batch(step: ca.Function, S0: np.ndarray, A: np.ndarray, C: np.ndarray, n_steps: int, *, stride: int = 1,
              bound: float = np.inf, backend: Backend = "auto") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run many trajectories of ``s_{k+1}, o_k = step(s_k, a_k, c)``, saving every `stride` steps.

    Parameters
    ----------
    step : casadi.Function
        ``(s[ns], a[na], c[nc]) -> (s_next[ns], o[no])``.
    S0 : numpy.ndarray of shape (B, ns)
        Initial states.
    A : numpy.ndarray of shape (n_steps + 1, na) or (B, n_steps + 1, na)
        Per-step inputs, shared by every trajectory or one set per trajectory.
    C : numpy.ndarray of shape (nc,) or (B, nc)
        Constants, shared or per trajectory.
    n_steps : int
    stride : int
        Save at steps 0, stride, 2·stride, ... and at n_steps (see :func:`saved_steps`).
    bound : float
        A state leaving [-bound, bound] (or non-finite) stops its trajectory; the rest continue.
    backend : {"auto", "vm", "c", "jax"}
        ``"jax"``: the same step translated to JAX (optional extra; CPU or GPU), see ``engine/_jax.py``.

    Returns
    -------
    S : numpy.ndarray of shape (B, n_save, ns)
        Saved states (NaN after a trajectory stopped).
    O : numpy.ndarray of shape (B, n_save, no)
        Saved per-step outputs (computed from the state before the step).
    status : numpy.ndarray of shape (B,)
        n_steps for trajectories that finished, else the step after which the state left the bound.
    """
    S0 = np.ascontiguousarray(S0, dtype=float)
    B, ns = S0.shape
    no = step.size1_out(1)
    A = np.ascontiguousarray(A, dtype=float)
    C = np.ascontiguousarray(C, dtype=float)
    shared_a, shared_c = A.ndim == 2, C.ndim == 1
    steps = saved_steps(n_steps, stride)
    if backend == "jax":   # one XLA program over all trajectories (CPU or GPU): see engine/_jax.py
        from ._jax import run_batch_jax

        return run_batch_jax(step, S0, A, C, steps, bound)
    S = np.full((B, steps.size, ns), np.nan)
    O = np.full((B, steps.size, no), np.nan)
    status = np.full(B, n_steps, dtype=np.int64)
    batch = _compiled_batch(step, B, n_steps, backend)
    if batch is not None:
        batch(S0, A, 0 if shared_a else A.shape[1] * A.shape[2], C, 0 if shared_c else C.shape[1], S, O, n_steps, stride,
              bound, status)
        return S, O, status
    runner = StepRunner(step, backend="vm")
    ins = step.mx_in()
    outputs = ca.Function("o", ins, [step(*ins)[1]])
    for j in range(B):
        a = A if shared_a else A[j]
        c = C if shared_c else C[j]
        states, outs, done = runner.run(S0[j], a[:n_steps], c, bound=bound)
        if done == n_steps:
            full = np.vstack([S0[j], states])
            last = np.asarray(outputs(full[-1], a[n_steps], c), dtype=float).reshape(1, -1)
            o_full = np.vstack([outs, last])
        else:  # the state after step `done` left the bound: keep the good states 0 .. done
            status[j] = done
            full = np.vstack([S0[j], states[:done]])
            o_full = outs[:done + 1]
        keep = steps[steps < full.shape[0]]
        S[j, :keep.size] = full[keep]
        O[j, :keep.size] = o_full[keep]
    return S, O, status
