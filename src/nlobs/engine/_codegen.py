"""Run CasADi functions either on CasADi's virtual machine or as generated, compiled C.

The C path writes the function with :meth:`casadi.Function.generate`, compiles it with the
system C compiler (``$CC``, else ``gcc``/``cc``) and loads it with :func:`casadi.external`.
The shared object is cached on disk, keyed by a hash of the C source, the compiler and its
flags, so a model is compiled once per machine. Without a compiler the VM is used, with a
warning when C was asked for explicitly.
"""

from __future__ import annotations

import atexit
import ctypes
import functools
import hashlib
import json
import os
import platform
import shutil
import subprocess
import tempfile
import threading
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

import casadi as ca
import numpy as np

from ..errors import ConvergenceWarning, EngineError
from ._budget import Watchdog, expired, remaining
from ._split import split_large, units

__all__ = ["Backend", "COSTS", "choose_backend", "code_size", "signature_of", "built_path", "CompiledBatch", "CompiledLoop", "cache_dir", "find_compiler", "compile_c", "resolve_backend"]

Backend = Literal["auto", "vm", "c"]

# -fno-semantic-interposition lets gcc inline the generated step into the driver loop of the shared object
# (without it every step is an interposable call through the PLT: measured 1.6x the instructions on P1);
# -fno-math-errno lets sqrt & co. compile to single instructions (same results, errno is never read)
CFLAGS = ("-O3", "-march=native", "-shared", "-fPIC", "-fno-semantic-interposition", "-fno-math-errno")

#: Generated code longer than this many lines is compiled with -O1 instead of -O3. gcc's -O2/-O3 passes are superlinear
#: in the size of one straight-line function (on a 24-state EKF's update, 74,000 lines: -O3 62 s, of which partial
#: redundancy elimination 49 % and hard-register assignment 35 %; -O1 3.3 s), while the code runs only 1.2-1.6x slower
#: at -O1 (a 13-state EKF and SR-UKF on 30,000 grid steps). Below it -O3 compiles in seconds anyway.
BIG_CODE = 20_000


#: Added for code above :data:`BIG_CODE` when the compiler is gcc: register allocation is most of -O1's time on
#: CasADi's straight-line code, and priority colouring in one region does it faster (a 35,000-line unit of the
#: 24-state square-root UKF's update: 3.2 s -> 2.6 s; its whole build 19.9 s -> 17.3 s, running as fast: 337 and
#: 342 µs a call).
BIG_CODE_GCC = ("-fira-algorithm=priority", "-fira-region=one", "-fno-ira-hoist-pressure")

#: Added for the translation units of a split function (:func:`nlobs.engine._split.units`) when the compiler is gcc:
#: LRA's hard-register assignment weighs at most 50 reload pseudos (gcc's default 500). Its time grows with the
#: pseudos live at once in one basic block, and a part of a square-root filter's update is one block of thousands of
#: products with no branch in it: a 28,000-line unit of the 24-state square-root UKF took 32 s, 28 s of them in that
#: pass, and 5 s with this. On units with branches it changes nothing measurable (the 24-state IEKF's: 2.0-3.9 s
#: either way). Not for one-file code: with it, `nlobs simulate ins24 --observer ekf` (its update one function of
#: 74,015 operations) took 6.0-6.7 s warm instead of 4.3-4.6 s.
SPLIT_UNIT_GCC = ("--param=lra-max-considered-reload-pseudos=50",)


def cflags(lines: int) -> tuple[str, ...]:
    """The compiler flags for generated code of `lines` lines (see :data:`BIG_CODE`)."""
    flags = tuple("-O1" if f == "-O3" and lines > BIG_CODE else f for f in CFLAGS)
    return flags + BIG_CODE_GCC if lines > BIG_CODE and _is_gcc(find_compiler()) else flags


@functools.lru_cache(maxsize=8)
def _is_gcc(cc: str | None) -> bool:
    """Whether the compiler `cc` is gcc (its ``--version`` says so)."""
    if cc is None:
        return False
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=30).stdout
    except (OSError, subprocess.SubprocessError):
        return False
    return "Free Software Foundation" in out and "clang" not in out.lower()


def cache_dir() -> Path:
    """Where compiled models live: ``$NLOBS_CACHE_DIR``, else ``~/.cache/nlobs``."""
    env = os.environ.get("NLOBS_CACHE_DIR")
    base = Path(env) if env else Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "nlobs"
    return base


def find_compiler() -> str | None:
    """The C compiler to use, or None when there is none (``NLOBS_CC=none`` forces None)."""
    return _find_compiler(os.environ.get("NLOBS_CC"), os.environ.get("CC"), os.environ.get("PATH", ""))


@functools.lru_cache(maxsize=16)
def _find_compiler(forced: str | None, cc: str | None, path: str) -> str | None:
    if forced is not None:
        return None if forced in ("", "none") else shutil.which(forced, path=path)
    for cand in (cc, "gcc", "cc", "clang"):
        if cand and shutil.which(cand, path=path):
            return shutil.which(cand, path=path)
    return None


def _forced(backend: Backend) -> Literal["vm", "c"] | None:
    """The backend an explicit choice (or ``$NLOBS_ENGINE``, or the lack of a compiler) fixes; None for "auto"."""
    if backend == "auto":
        backend = os.environ.get("NLOBS_ENGINE", "auto")  # type: ignore[assignment]
    if backend not in ("auto", "vm", "c"):
        raise ValueError(f"the engine backend must be 'auto', 'vm' or 'c', got {backend!r}")
    if backend == "vm":
        return "vm"
    if find_compiler() is None:
        if backend == "c":
            warnings.warn("no C compiler found (set $CC); running on the CasADi virtual machine instead",
                          ConvergenceWarning, stacklevel=4)
        return "vm"
    return "c" if backend == "c" else None


def resolve_backend(backend: Backend, *, work: int, threshold: int = 200_000) -> Literal["vm", "c"]:
    """Choose the backend by size alone: ``"auto"`` compiles when `work` (steps x states) exceeds
    `threshold` and a compiler exists. ``$NLOBS_ENGINE`` (vm/c/auto) overrides ``"auto"``. The
    runners use :func:`choose_backend` (by measured cost) instead."""
    forced = _forced(backend)
    if forced is not None:
        return forced
    return "c" if work >= threshold else "vm"


class _Costs:
    """Measured costs on this machine, kept in ``cache_dir()/costs.json``: seconds per compile
    (a + b·instructions of the compiled function) and seconds per VM instruction executed.
    Every compile and every timed VM run updates them (exponential averages)."""

    DEFAULT = {"compile_a": 0.35, "compile_b": 2e-4, "compile_b1": 5e-5, "vm_per_instr": 6e-9}

    def __init__(self) -> None:
        self._data: dict[str, float] | None = None
        self.spent: dict[str, float] = {}  # VM seconds spent per function signature in this process
        self._dirty = False

    @property
    def data(self) -> dict[str, float]:
        if self._data is None:
            self._data = dict(self.DEFAULT)
            try:
                saved = json.loads((cache_dir() / "costs.json").read_text())
                self._data.update({k: float(v) for k, v in saved.items() if k in self.DEFAULT and float(v) > 0})
            except (OSError, ValueError, TypeError, AttributeError):
                pass
        return self._data

    def _save(self) -> None:
        try:
            cache_dir().mkdir(parents=True, exist_ok=True)
            tmp = cache_dir() / f"costs.json.{os.getpid()}"
            tmp.write_text(json.dumps(self.data))
            os.replace(tmp, cache_dir() / "costs.json")
        except OSError:  # a read-only cache only loses the calibration
            pass

    def compile_seconds(self, n_instr: int) -> float:
        """Predicted seconds to compile a function of `n_instr` instructions (-O1 above :data:`BIG_CODE`)."""
        return self.data["compile_a"] + self.data["compile_b1" if n_instr > BIG_CODE else "compile_b"] * n_instr

    def vm_seconds(self, n_instr_executed: float) -> float:
        return self.data["vm_per_instr"] * n_instr_executed

    def record_compile(self, n_instr: int, seconds: float, *, big: bool = False) -> None:
        d = self.data  # attribute the time above the fixed part to the size, averaged (per optimisation level)
        key = "compile_b1" if big else "compile_b"
        d[key] = 0.7 * d[key] + 0.3 * max(seconds - d["compile_a"], 0.0) / max(n_instr, 1) + 1e-9
        self._save()

    def record_vm(self, n_instr_executed: float, seconds: float) -> None:
        if n_instr_executed >= 1e5:  # too short a run says little; saved with the next compile (or at exit)
            d = self.data
            d["vm_per_instr"] = 0.7 * d["vm_per_instr"] + 0.3 * seconds / n_instr_executed
            if not self._dirty:
                self._dirty = True
                atexit.register(self._save)


COSTS = _Costs()


def choose_backend(backend: Backend, *, ready: bool, n_instr: int, vm_instr: float, signature: str) -> Literal["vm", "c"]:
    """Choose where to run a function by measured cost.

    ``"auto"`` compiles when a compiler exists and either the compiled code is already built
    (`ready`: loaded in this process or cached on disk), or the predicted VM time of this call
    (`vm_instr` instructions executed at the measured VM speed), added to the VM time already
    spent on this function in this process, reaches the predicted compile time of a function of
    `n_instr` instructions. Like renting skis until their price is reached, this never costs
    more than twice the better choice made in hindsight; the build is then cached on disk for
    every later call and process. ``$NLOBS_ENGINE`` (vm/c/auto) overrides ``"auto"``.
    """
    forced = _forced(backend)
    if forced is not None:
        return forced
    if ready:
        return "c"
    spent = COSTS.spent.get(signature, 0.0)
    return "c" if spent + COSTS.vm_seconds(vm_instr) >= COSTS.compile_seconds(n_instr) else "vm"


def code_size(fn: ca.Function) -> int:
    """The instructions the C of `fn` is generated from: its own, plus those of every function an MX graph calls
    (an MX instruction may be a call of a large SX function). The size compile times are predicted from."""
    if fn.is_a("SXFunction"):
        return int(fn.n_instructions())
    try:
        called = fn.find_functions()
    except (AttributeError, RuntimeError):
        called = []
    return int(fn.n_instructions()) + sum(int(f.n_instructions()) for f in called if f.is_a("SXFunction"))


def signature_of(fn: ca.Function) -> str:
    """A hash of the function's full definition (CasADi serialisation)."""
    return hashlib.sha256(fn.serialize().encode()).hexdigest()


def built_path(tag: str, signature: str, template: str) -> Path | None:
    """Where the shared object for (`tag`, `signature`, `template`) is cached, or None without a compiler."""
    cc = find_compiler()
    if cc is None:
        return None
    key = hashlib.sha256("\0".join([tag, signature, template, cc, *CFLAGS, f"O1>{BIG_CODE}", platform.machine(), platform.node(),
                                     ca.__version__]).encode()).hexdigest()[:32]
    return cache_dir() / f"{tag}-{key}.so"


_DRIVER = r"""
/* nlobs driver: s_{k+1}, o_k = step(s_k, a_k, c); states to out[k*ns ...], per-step outputs to obuf[k*no ...].
   Returns 0, or k + 1 when step k failed, or -(k + 2) when the state after step k is not finite or exceeds bound,
   or -(n_steps + 2 + k) when *stop was raised (a time budget) before step k. */
long long nlobs_run(const casadi_real* s0, const casadi_real* a, const casadi_real* c,
                    casadi_real* out, casadi_real* obuf, long long n_steps, casadi_real bound, const volatile int* stop) {
  casadi_int sz_arg = 0, sz_res = 0, sz_iw = 0, sz_w = 0;
  const casadi_real* arg[NLOBS_SZ_ARG];
  casadi_real* res[NLOBS_SZ_RES];
  casadi_int iw[NLOBS_SZ_IW + 1];
  casadi_real w[NLOBS_SZ_W + 1];
  const casadi_real* s = s0;
  long long k;
  int i;
  NLOBS_STEP_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  if (sz_arg > NLOBS_SZ_ARG || sz_res > NLOBS_SZ_RES || sz_iw > NLOBS_SZ_IW || sz_w > NLOBS_SZ_W) return -1;
  for (k = 0; k < n_steps; ++k) {
    if (stop && *stop) return -(n_steps + 2 + k);
    arg[0] = s; arg[1] = a + k * NLOBS_NA; arg[2] = c;
    res[0] = out + k * NLOBS_NS;
    if (NLOBS_NO > 0) res[1] = obuf + k * NLOBS_NO;
    if (NLOBS_STEP(arg, res, iw, w, 0)) return k + 1;
    s = out + k * NLOBS_NS;
    for (i = 0; i < NLOBS_NS; ++i) if (!(s[i] <= bound && s[i] >= -bound)) return -(k + 2); /* NaN fails too */
  }
  return 0;
}
"""


_BATCH = r"""
/* nlobs batch driver: many trajectories of s_{k+1}, o_k = step(s_k, a_k, c), one after another.
   Saves state and per-step output at k = 0, stride, 2 stride, ... (< n_steps) and at k = n_steps.
   status[j] = n_steps when trajectory j finished, else the step after which its state left `bound`. */
long long nlobs_batch(const casadi_real* S0, const casadi_real* A, long long a_stride, const casadi_real* C,
                      long long c_stride, casadi_real* Sout, casadi_real* Oout, long long n_save, long long n_traj,
                      long long n_steps, long long stride, casadi_real bound, long long* status) {
  casadi_int sz_arg = 0, sz_res = 0, sz_iw = 0, sz_w = 0;
  const casadi_real* arg[NLOBS_SZ_ARG];
  casadi_real* res[NLOBS_SZ_RES];
  casadi_int iw[NLOBS_SZ_IW + 1];
  casadi_real w[NLOBS_SZ_W + 1];
  casadi_real buf_a[NLOBS_NS + 1], buf_b[NLOBS_NS + 1], o[NLOBS_NO + 1];
  casadi_real *cur, *nxt, *tmp;
  long long j, k, isave, next_save;
  int i, bad;
  NLOBS_STEP_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  if (sz_arg > NLOBS_SZ_ARG || sz_res > NLOBS_SZ_RES || sz_iw > NLOBS_SZ_IW || sz_w > NLOBS_SZ_W) return -1;
  for (j = 0; j < n_traj; ++j) {
    const casadi_real* a = A + j * a_stride;
    const casadi_real* c = C + j * c_stride;
    casadi_real* so = Sout + j * n_save * NLOBS_NS;
    casadi_real* oo = Oout + j * n_save * NLOBS_NO;
    cur = buf_a; nxt = buf_b;
    for (i = 0; i < NLOBS_NS; ++i) cur[i] = S0[j * NLOBS_NS + i];
    isave = 0;
    next_save = 0;
    status[j] = n_steps;
    arg[2] = c; res[1] = o;
    for (k = 0; k <= n_steps; ++k) {
      arg[0] = cur; arg[1] = a + k * NLOBS_NA; res[0] = nxt;
      if (NLOBS_STEP(arg, res, iw, w, 0)) return j + 1;
      if (k == next_save) {
        for (i = 0; i < NLOBS_NS; ++i) so[isave * NLOBS_NS + i] = cur[i];
        for (i = 0; i < NLOBS_NO; ++i) oo[isave * NLOBS_NO + i] = o[i];
        ++isave;
        next_save = next_save + stride < n_steps ? next_save + stride : n_steps;
      }
      if (k == n_steps) break;
      bad = 0;
      for (i = 0; i < NLOBS_NS; ++i) bad |= !(nxt[i] <= bound && nxt[i] >= -bound);
      if (bad) { status[j] = k; break; }
      tmp = cur; cur = nxt; nxt = tmp;
    }
  }
  return 0;
}
"""


_ERFINV = r"""
#include <math.h>
/* inverse error function: Giles' single-precision approximation refined by two Newton steps on erf */
static double nlobs_erfinv(double x) {
  double w, p, y;
  int i;
  if (!(x > -1 && x < 1)) return x == 1 ? INFINITY : (x == -1 ? -INFINITY : NAN);
  w = -log((1 - x) * (1 + x));
  if (w < 5) {
    w -= 2.5;
    p = 2.81022636e-08; p = 3.43273939e-07 + p * w; p = -3.5233877e-06 + p * w; p = -4.39150654e-06 + p * w;
    p = 0.00021858087 + p * w; p = -0.00125372503 + p * w; p = -0.00417768164 + p * w; p = 0.246640727 + p * w;
    p = 1.50140941 + p * w;
  } else {
    w = sqrt(w) - 3;
    p = -0.000200214257; p = 0.000100950558 + p * w; p = 0.00134934322 + p * w; p = -0.00367342844 + p * w;
    p = 0.00573950773 + p * w; p = -0.0076224613 + p * w; p = 0.00943887047 + p * w; p = 1.00167406 + p * w;
    p = 2.83297682 + p * w;
  }
  y = p * x;
  for (i = 0; i < 2; ++i) y -= (erf(y) - x) / (1.1283791670955126 * exp(-y * y));
  return y;
}
"""


def _generate(*fns: ca.Function) -> str:
    """C for the functions `fns`; CasADi writes erfinv as a call to a C function libm does not have, so one is supplied."""
    with tempfile.TemporaryDirectory(prefix="nlobs-gen-") as tmp:
        gen = ca.CodeGenerator("gen.c", {"with_header": False, "main": False})
        for fn in fns:
            gen.add(fn)
        gen.generate(tmp + os.sep)
        code = (Path(tmp) / "gen.c").read_text()
    return _ERFINV + "#define erfinv nlobs_erfinv\n" + code if "erfinv(" in code else code


#: One lock per shared object being built in this process: a second thread that needs the same code (the advisor's
#: early build of a candidate and its run) waits for the first build instead of compiling it again beside it.
_BUILDING: dict[Path, threading.Lock] = {}
_BUILDING_LOCK = threading.Lock()


def _build(code: str | Callable[[], str], tag: str, so: Path | None = None, n_instr: int = 0) -> Path:
    """Compile `code` (or `code()`, generated only when needed) to a shared object in the cache, once per
    machine, and return its path: `so` when given (keyed by the function's signature), else keyed by the code.
    Builds of the same object in this process run one at a time (the later ones then find it built)."""
    cc = find_compiler()
    if cc is None:
        raise EngineError("no C compiler found: install gcc or set $CC, or use the 'vm' backend")
    if so is None:
        code = code() if callable(code) else code
        key = hashlib.sha256("\0".join([code, cc, *cflags(code.count("\n")), platform.machine(), platform.node(),
                                         ca.__version__]).encode()).hexdigest()[:32]
        so = cache_dir() / f"{tag}-{key}.so"
    if so.exists():
        return so
    with _BUILDING_LOCK:
        lock = _BUILDING.setdefault(so, threading.Lock())
    left = remaining()
    if not lock.acquire(timeout=-1 if left is None else max(left, 0.0)):
        raise expired(f"waiting for another thread's build of its C code ({tag})")
    try:
        return _build_locked(code, tag, so, cc, n_instr)
    finally:
        lock.release()


def _build_locked(code: str | Callable[[], str], tag: str, so: Path, cc: str, n_instr: int) -> Path:
    """:func:`_build` holding the lock of `so`."""
    if not so.exists():
        code = code() if callable(code) else code
        out_dir = so.parent
        out_dir.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix="nlobs-cc-", dir=out_dir) as tmp:
            flags = cflags(code.count("\n"))
            tmp_so = Path(tmp) / "gen.so"
            t0 = time.perf_counter()
            left = remaining()
            if left is not None and left <= 0:
                raise expired(f"compiling its C code ({tag})")
            pieces = units(code)
            if pieces is None:
                (Path(tmp) / "gen.c").write_text(code)
                _run_compilers(cc, [[cc, *flags, str(Path(tmp) / "gen.c"), "-o", str(tmp_so), "-lm"]], tag, left)
            else:   # a function split into parts: the units compiled apart (two at a time), then linked
                objs = []
                for i, src in enumerate(pieces):
                    (Path(tmp) / f"u{i}.c").write_text(src)
                    objs.append(str(Path(tmp) / f"u{i}.o"))
                unit_flags = [f for f in flags if f != "-shared"] + (list(SPLIT_UNIT_GCC) if _is_gcc(cc) else [])
                _run_compilers(cc, [[cc, *unit_flags, "-c", str(Path(tmp) / f"u{i}.c"), "-o", o] for i, o in enumerate(objs)],
                               tag, left)
                _run_compilers(cc, [[cc, *flags, *objs, "-o", str(tmp_so), "-lm"]], tag, remaining())
            if n_instr:
                COSTS.record_compile(n_instr, time.perf_counter() - t0, big=code.count("\n") > BIG_CODE)
            os.replace(tmp_so, so)  # atomic: concurrent builders never see a half-written file
    return so


#: gcc processes one build runs at once (the units of a split function).
UNIT_WORKERS = max(1, min(2, os.cpu_count() or 1))


def _run_compilers(cc: str, commands: list[list[str]], tag: str, left: float | None) -> None:
    """Run the compiler `commands`, :data:`UNIT_WORKERS` at a time, within `left` seconds (None: no limit); the first
    failure (its message included) or the time running out stops the others."""
    deadline = None if left is None else time.monotonic() + left
    waiting, running = list(commands), []
    try:
        while waiting or running:
            while waiting and len(running) < UNIT_WORKERS:
                running.append(subprocess.Popen(waiting.pop(0), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
            proc = running[0]
            try:
                _, err = proc.communicate(timeout=None if deadline is None else max(deadline - time.monotonic(), 0.0))
            except subprocess.TimeoutExpired:
                raise expired(f"compiling its C code ({tag})") from None
            running.pop(0)
            if proc.returncode != 0:
                raise EngineError(f"the C compiler {cc} failed on the generated code for {tag}:\n{err[-2000:]}")
    finally:
        for proc in running:   # stopped (a failure, the time running out): killed, reaped and its pipes closed
            proc.kill()
            proc.communicate()


def compile_c(fn: ca.Function, *, sig: str | None = None, tag: str | None = None) -> ca.Function:
    """Generate C for `fn`, compile it (or reuse the cached build) and load it with ``casadi.external``.

    With `sig` (e.g. :func:`signature_of`), the build is found in the cache by it, without generating the code.

    Raises
    ------
    EngineError
        If there is no compiler or the compiler fails (its message is included).
    """
    if sig is not None:
        so = _build(lambda: _generate(fn), tag or fn.name(), built_path(tag or fn.name(), sig, ""), n_instr=code_size(fn))
    else:
        so = _build(_generate(fn), fn.name())
    try:
        return ca.external(fn.name(), str(so))
    except RuntimeError as e:
        raise EngineError(f"cannot load the compiled model {so}: {e}") from e


class CompiledLoop:
    """A step ``(s, a, c) -> (s_next[, o])`` compiled together with a C loop over the steps.

    Calling it runs ``n`` steps, writing every state into `out` (shape (n, ns)) and, when the
    step has a second output, every per-step output into `obuf` (shape (n, no)), with no
    Python work per step.
    """

    def __init__(self, step: ca.Function, sig: str | None = None):
        if step.n_in() != 3 or step.n_out() not in (1, 2):
            raise ValueError("CompiledLoop needs step(s, a, c) -> s_next or -> (s_next, o)")
        self.ns, self.na, self.nc = step.size1_in(0), step.size1_in(1), step.size1_in(2)
        self.no = step.size1_out(1) if step.n_out() == 2 else 0
        self.path, lib = _compile_driver(step, _DRIVER, "loop", self.no, sig)
        self._run = lib.nlobs_run
        dbl = ctypes.POINTER(ctypes.c_double)
        self._run.argtypes = [dbl, dbl, dbl, dbl, dbl, ctypes.c_longlong, ctypes.c_double, ctypes.c_void_p]
        self._run.restype = ctypes.c_longlong
        self._lib = lib

    def __call__(self, s0: np.ndarray, a: np.ndarray, c: np.ndarray, out: np.ndarray, obuf: np.ndarray | None = None,
                 bound: float = np.inf) -> int:
        """Run; returns the number of good steps: n, or k when the state after step k left `bound`
        or became non-finite (that state is row k of `out`). Raises :class:`nlobs.TimeBudgetError` when
        the time budget (:mod:`nlobs.engine._budget`) runs out."""
        n = out.shape[0]
        ptr = ctypes.POINTER(ctypes.c_double)
        o = obuf if obuf is not None else out
        with Watchdog() as dog:
            rc = self._run(s0.ctypes.data_as(ptr), a.ctypes.data_as(ptr), c.ctypes.data_as(ptr), out.ctypes.data_as(ptr),
                           o.ctypes.data_as(ptr), n, bound, dog.ref)
        if rc > 0:
            raise EngineError(f"the compiled step failed at step {rc - 1}")
        if rc <= -(n + 2):
            dog.raise_if_tripped("running its compiled loop")
        return n if rc == 0 else int(-rc - 2)


class CompiledBatch:
    """A step ``(s, a, c) -> (s_next, o)`` compiled with a C loop over trajectories and steps.

    See :func:`nlobs.engine.run_batch` for the arguments.
    """

    def __init__(self, step: ca.Function, sig: str | None = None):
        if step.n_in() != 3 or step.n_out() != 2:
            raise ValueError("CompiledBatch needs step(s, a, c) -> (s_next, o)")
        self.ns, self.na, self.nc, self.no = step.size1_in(0), step.size1_in(1), step.size1_in(2), step.size1_out(1)
        self.path, self._lib = _compile_driver(step, _BATCH, "batch", self.no, sig)
        self._run = bind_batch(self._lib)

    def __call__(self, S0: np.ndarray, A: np.ndarray, a_stride: int, C: np.ndarray, c_stride: int, Sout: np.ndarray,
                 Oout: np.ndarray, n_steps: int, stride: int, bound: float, status: np.ndarray) -> None:
        call_batch(self._run, S0, A, a_stride, C, c_stride, Sout, Oout, n_steps, stride, bound, status)


BATCH_ARGTYPES = [ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double), ctypes.c_longlong,
                  ctypes.POINTER(ctypes.c_double), ctypes.c_longlong, ctypes.POINTER(ctypes.c_double),
                  ctypes.POINTER(ctypes.c_double), ctypes.c_longlong, ctypes.c_longlong, ctypes.c_longlong, ctypes.c_longlong,
                  ctypes.c_double, ctypes.POINTER(ctypes.c_longlong)]


def bind_batch(lib: ctypes.CDLL) -> Any:
    """The ``nlobs_batch`` entry point of a compiled driver, with its argument types set."""
    run = lib.nlobs_batch
    run.argtypes = BATCH_ARGTYPES
    run.restype = ctypes.c_longlong
    return run


def call_batch(run: Any, S0: np.ndarray, A: np.ndarray, a_stride: int, C: np.ndarray, c_stride: int, Sout: np.ndarray,
               Oout: np.ndarray, n_steps: int, stride: int, bound: float, status: np.ndarray) -> None:
    """Call a compiled ``nlobs_batch`` driver (scalar or lane-parallel) on NumPy buffers."""
    dbl = ctypes.POINTER(ctypes.c_double)
    rc = run(S0.ctypes.data_as(dbl), A.ctypes.data_as(dbl), a_stride, C.ctypes.data_as(dbl), c_stride,
             Sout.ctypes.data_as(dbl), Oout.ctypes.data_as(dbl), Sout.shape[1], S0.shape[0], n_steps, stride, bound,
             status.ctypes.data_as(ctypes.POINTER(ctypes.c_longlong)))
    if rc != 0:
        raise EngineError(f"the compiled batch failed in trajectory {rc - 1}")


def _compile_driver(step: ca.Function, template: str, tag: str, no: int, sig: str | None = None) -> tuple[Path, ctypes.CDLL]:
    """Generate C for `step` (as ``nlobs_step``), append a driver `template` with its sizes filled in,
    compile (or reuse the cached build, found by the step's signature without generating) and load it."""
    name = "nlobs_step"

    def code() -> str:
        renamed = _renamed(step, name)
        defs = {
            "NLOBS_SZ_ARG": renamed.sz_arg(), "NLOBS_SZ_RES": renamed.sz_res(),
            "NLOBS_SZ_IW": renamed.sz_iw(), "NLOBS_SZ_W": renamed.sz_w(),
            "NLOBS_NA": step.size1_in(1), "NLOBS_NS": step.size1_in(0), "NLOBS_NO": no,
        }
        driver = template.replace("NLOBS_STEP_work", f"{name}_work").replace("NLOBS_STEP", name)
        for k, v in defs.items():
            driver = driver.replace(k, str(int(v)))
        return _generate(renamed) + driver

    so = built_path(tag, sig if sig is not None else signature_of(step), template)
    path = _build(code, tag, so, n_instr=code_size(step))
    return path, ctypes.CDLL(str(path))


def _renamed(fn: ca.Function, name: str) -> ca.Function:
    """`fn` under another name (the C symbol), evaluated symbolically so it stays SX when it was (and an MX function
    stays one call: the functions it calls are generated once, not inlined). A very large SX function becomes a chain
    of parts (:func:`nlobs.engine._split.split_large`: the compiler sees no huge function)."""
    fn = split_large(fn)
    Sym = ca.SX if fn.is_a("SXFunction") else ca.MX
    args = [Sym.sym(fn.name_in(i), fn.sparsity_in(i)) for i in range(fn.n_in())]
    return ca.Function(name, args, fn.call(args))
