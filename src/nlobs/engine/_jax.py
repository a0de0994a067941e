r"""The JAX engine: the same compiled step as the C engine, run as an XLA program (CPU or GPU).

Why from CasADi and not from SymPy: every run nlobs compiles (plant, noise, observers, sample-and-hold,
escape check) is one CasADi step function, the one the C engine generates its code from. Translating
that function's SX instruction list (``Function.instruction_id`` / ``instruction_input`` /
``instruction_output`` / ``instruction_constant``, CasADi's documented algorithm API) into
``jax.numpy`` operations gives a JAX function with the *same* operations in the same order, so the
two engines agree to rounding (about 1e-15 relative), and nothing of the model is written twice.
SymPy's ``lambdify(modules="jax")`` would translate the model's equations only, not the observer and
integrator built around them; the converters from CasADi to JAX on PyPI (``jaxadi``) are young and
not kept up with CasADi's releases. The translation here is one table, from CasADi's operation codes
to ``jax.numpy``, and refuses what it does not know, by name.

JAX is an optional extra (``pip install 'nlobs[jax]'``); double precision is switched on when the
engine is first used (``jax_enable_x64``), as nlobs computes in float64 everywhere.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from ..errors import EngineError

__all__ = ["jax_available", "to_jax", "run_batch_jax", "DeviceNoise"]


def _jax() -> Any:
    try:
        import jax
    except ImportError as exc:  # pragma: no cover - exercised only without the extra
        raise EngineError("engine='jax' needs JAX: pip install 'nlobs[jax]' (or jax[cuda12] for a GPU)") from exc
    jax.config.update("jax_enable_x64", True)
    _persistent_cache(jax)
    return jax


_CACHE_CHOSEN = False


def _persistent_cache(jax: Any) -> None:
    """XLA's compiled programs kept on disk beside the C engine's builds (``<cache>/jax``, see
    :func:`nlobs.engine.cache_dir`), as JAX's persistent compilation cache, unless the user chose a directory of their
    own (``jax_compilation_cache_dir``). A program JAX took at least a second to compile (its default threshold) is then
    compiled once per machine, as the C engine's are: a 12-state EKF's Monte Carlo, 11-12 s for its first call in a
    fresh process, about 5 s in the next (tracing the program is most of what remains)."""
    global _CACHE_CHOSEN
    if _CACHE_CHOSEN:
        return
    _CACHE_CHOSEN = True
    if jax.config.jax_compilation_cache_dir:   # the user's own
        return
    from ._codegen import cache_dir
    jax.config.update("jax_compilation_cache_dir", str(cache_dir() / "jax"))


def jax_available() -> bool:
    """Whether JAX can be imported (the optional ``nlobs[jax]`` extra)."""
    try:
        import jax  # noqa: F401
    except ImportError:
        return False
    return True


def _ops(jnp: Any, special: Any) -> dict[int, Callable[..., Any]]:
    f = lambda b: jnp.asarray(b, dtype=jnp.float64)  # noqa: E731  (comparisons give 0.0 / 1.0, as in CasADi)
    return {
        ca.OP_ASSIGN: lambda a: a,
        ca.OP_ADD: lambda a, b: a + b,
        ca.OP_SUB: lambda a, b: a - b,
        ca.OP_MUL: lambda a, b: a * b,
        ca.OP_DIV: lambda a, b: a / b,
        ca.OP_NEG: lambda a: -a,
        ca.OP_EXP: jnp.exp,
        ca.OP_LOG: jnp.log,
        ca.OP_POW: jnp.power,
        ca.OP_CONSTPOW: jnp.power,
        ca.OP_SQRT: jnp.sqrt,
        ca.OP_SQ: lambda a: a * a,
        ca.OP_TWICE: lambda a: 2.0 * a,
        ca.OP_SIN: jnp.sin,
        ca.OP_COS: jnp.cos,
        ca.OP_TAN: jnp.tan,
        ca.OP_ASIN: jnp.arcsin,
        ca.OP_ACOS: jnp.arccos,
        ca.OP_ATAN: jnp.arctan,
        ca.OP_LT: lambda a, b: f(a < b),
        ca.OP_LE: lambda a, b: f(a <= b),
        ca.OP_EQ: lambda a, b: f(a == b),
        ca.OP_NE: lambda a, b: f(a != b),
        ca.OP_NOT: lambda a: f(a == 0),
        ca.OP_AND: lambda a, b: f((a != 0) & (b != 0)),
        ca.OP_OR: lambda a, b: f((a != 0) | (b != 0)),
        ca.OP_FLOOR: jnp.floor,
        ca.OP_CEIL: jnp.ceil,
        ca.OP_FMOD: jnp.fmod,
        ca.OP_FABS: jnp.abs,
        ca.OP_SIGN: jnp.sign,
        ca.OP_COPYSIGN: jnp.copysign,
        ca.OP_IF_ELSE_ZERO: lambda c, x: jnp.where(c != 0, x, 0.0),
        ca.OP_ERF: special.erf,
        ca.OP_ERFINV: special.erfinv,
        ca.OP_FMIN: jnp.fmin,
        ca.OP_FMAX: jnp.fmax,
        ca.OP_INV: lambda a: 1.0 / a,
        ca.OP_SINH: jnp.sinh,
        ca.OP_COSH: jnp.cosh,
        ca.OP_TANH: jnp.tanh,
        ca.OP_ASINH: jnp.arcsinh,
        ca.OP_ACOSH: jnp.arccosh,
        ca.OP_ATANH: jnp.arctanh,
        ca.OP_ATAN2: jnp.arctan2,
        ca.OP_LOG1P: jnp.log1p,
        ca.OP_EXPM1: jnp.expm1,
        ca.OP_HYPOT: jnp.hypot,
        ca.OP_REMAINDER: lambda a, b: a - jnp.round(a / b) * b,   # IEEE remainder: nearest quotient, ties to even
    }


_NAMES = {getattr(ca, k): k for k in dir(ca) if k.startswith("OP_")}


def _sx(fn: ca.Function) -> ca.Function:
    if fn.is_a("SXFunction"):
        return fn
    try:
        return fn.expand()
    except RuntimeError as exc:
        raise EngineError(f"engine='jax': the function {fn.name()!r} cannot be expanded into scalar operations "
                          f"(it calls something only the C and VM engines run: {str(exc).splitlines()[0]}); use engine='c'") from exc


def to_jax(fn: ca.Function) -> Callable[..., tuple[Any, ...]]:
    """A JAX function computing what the CasADi function `fn` computes.

    Every input and output of `fn` must be dense; the JAX function takes and returns flat vectors of
    their entries (column-major, as CasADi stores them). Traceable: jit and vmap it.
    """
    jax = _jax()
    jnp = jax.numpy
    sx = _sx(fn)
    for i in range(sx.n_in()):
        if not sx.sparsity_in(i).is_dense():
            raise EngineError(f"engine='jax': input {sx.name_in(i)!r} of {fn.name()!r} is sparse; only dense inputs are translated")
    for i in range(sx.n_out()):
        if not sx.sparsity_out(i).is_dense():
            raise EngineError(f"engine='jax': output {sx.name_out(i)!r} of {fn.name()!r} is sparse; only dense outputs are translated")
    ops = _ops(jnp, jax.scipy.special)
    program: list[tuple[int, list[int], list[int], float]] = []
    for k in range(sx.n_instructions()):
        op = sx.instruction_id(k)
        if op not in ops and op not in (ca.OP_CONST, ca.OP_INPUT, ca.OP_OUTPUT):
            raise EngineError(f"engine='jax': the operation {_NAMES.get(op, op)} in {fn.name()!r} has no JAX translation; use engine='c'")
        program.append((op, list(sx.instruction_input(k)), list(sx.instruction_output(k)),
                        float(sx.instruction_constant(k)) if op == ca.OP_CONST else 0.0))
    sizes = [sx.nnz_out(i) for i in range(sx.n_out())]
    n_work = int(sx.sz_w())

    def run(*args: Any) -> tuple[Any, ...]:
        work: list[Any] = [None] * n_work
        outs: list[list[Any]] = [[None] * n for n in sizes]
        flat = [jnp.reshape(jnp.asarray(a, dtype=jnp.float64), (-1,)) for a in args]
        for op, ins, res, const in program:
            if op == ca.OP_INPUT:
                work[res[0]] = flat[ins[0]][ins[1]]
            elif op == ca.OP_OUTPUT:
                outs[res[0]][res[1]] = work[ins[0]]
            elif op == ca.OP_CONST:
                work[res[0]] = jnp.float64(const)
            else:
                work[res[0]] = ops[op](*(work[i] for i in ins))
        return tuple(jnp.stack([jnp.asarray(v, dtype=jnp.float64) if v is not None else jnp.float64(0.0) for v in o])
                     if o else jnp.zeros((0,)) for o in outs)

    return run


@dataclass(frozen=True)
class DeviceNoise:
    """Noise drawn on the device, step by step inside the runs, by JAX's counter-based generator: the columns
    ``[at, at + len(scales))`` of the per-step inputs are measurement noise (Gaussian with standard deviation
    `scales[j]` where `gaussian[j]`, else uniform in ±`scales[j]`; a fresh draw every `every` steps, held in between)
    and the `process` columns after them process-noise increments (standard deviation ``process[j]``, none at the
    last row `last`). Run r's draws at step k depend on its seed, the stream and k only (``fold_in``), so they do not
    depend on how the runs are chunked, nor on the horizon."""

    at: int
    scales: tuple[float, ...]
    gaussian: tuple[bool, ...]
    every: int
    process: tuple[float, ...]
    last: int


def _noisy_inputs(jax: Any, noise: DeviceNoise | None) -> Callable[[Any, Any, Any], Any]:
    """``inputs(a, key, k)``: row k of the shared inputs `a` with run `key`'s noise written into its noise columns."""
    if noise is None:
        return lambda a, key, k: a[k]
    jnp, random = jax.numpy, jax.random
    nv, nw = len(noise.scales), len(noise.process)
    s_v, gauss = jnp.asarray(noise.scales, dtype=jnp.float64), jnp.asarray(noise.gaussian)
    s_w = jnp.asarray(noise.process, dtype=jnp.float64)

    def inputs(a: Any, key: Any, k: Any) -> Any:
        row = a[k]
        if nv:
            kv = random.fold_in(random.fold_in(key, 0), k // noise.every)
            if all(noise.gaussian):   # one kind: only its draws (the generator is most of a step's cost on a CPU)
                v = random.normal(kv, (nv,), dtype=jnp.float64)
            elif not any(noise.gaussian):
                v = random.uniform(kv, (nv,), dtype=jnp.float64, minval=-1.0, maxval=1.0)
            else:
                g, u = random.split(kv)
                v = jnp.where(gauss, random.normal(g, (nv,), dtype=jnp.float64),
                              random.uniform(u, (nv,), dtype=jnp.float64, minval=-1.0, maxval=1.0))
            row = row.at[noise.at:noise.at + nv].set(s_v * v)
        if nw:
            w = s_w * random.normal(random.fold_in(random.fold_in(key, 1), k), (nw,), dtype=jnp.float64)
            row = row.at[noise.at + nv:noise.at + nv + nw].set(jnp.where(k < noise.last, w, 0.0))
        return row

    return inputs


_BATCH_CACHE: dict[tuple[Any, ...], tuple[ca.Function, Any]] = {}

#: The most scalar operations a Monte Carlo step may have on this engine (``$NLOBS_JAX_MAX_OPERATIONS`` overrides it).
#: Each becomes one XLA operation, and XLA's compile grows faster than their number, the more so the denser the
#: covariance they update (first calls on 2 CPU cores, JAX 0.10: a chain-coupled 15-state EKF, 15,345 operations,
#: 23 s and 1.5 GB; a fully coupled 8-state EKF, 12,532, 48 s; a fully coupled 10-state EKF, 22,519, over 150 s;
#: the 12-state quadrotor's EKF, 34,545, over 4 minutes and 19 GB, unfinished). The C engine compiles these in seconds.
MAX_OPERATIONS = 12_000


def _check_size(step: ca.Function) -> None:
    """EngineError when `step` has more scalar operations than :data:`MAX_OPERATIONS` (or its override)."""
    try:
        limit = int(os.environ.get("NLOBS_JAX_MAX_OPERATIONS", MAX_OPERATIONS))
    except ValueError:
        limit = MAX_OPERATIONS
    n = _sx(step).n_instructions()
    if n > limit:
        raise EngineError(f"engine='jax': the step {step.name()!r} has {n:,} scalar operations, more than the "
                          f"{limit:,} this engine compiles in reasonable time and memory (each is one XLA operation; a "
                          "12-state EKF's 34,545 took XLA more than 4 minutes and 19 GB without finishing). Use "
                          "engine='c', which compiles it in seconds; or set NLOBS_JAX_MAX_OPERATIONS to try anyway")


def _cpu_options(jax: Any) -> dict[str, Any] | None:
    """XLA options for a batch program compiled for the CPU: without XLA's newer CPU fusion emitters, which recompute
    a fused value for each use, so that a step's run time grew exponentially with its depth (2 CPU cores, JAX 0.10, 64
    runs of a 6-state chain integrated by RK4 inside one function: 0.2 ms a call for 1 step, 18 ms for 3, 0.41 s for
    4, 9.2 s for 5; 0.5 ms for 5 without them). A fully coupled 8-state EKF's 200 steps for 64 runs: 5.75 s -> 0.135
    s, compiled in 36 s instead of 64.5 s. None on other backends."""
    return {"xla_cpu_use_fusion_emitters": False} if jax.default_backend() == "cpu" else None


def _batch_program(step: ca.Function, bound: float, shared_a: bool, shared_c: bool, noise: DeviceNoise | None = None) -> Any:
    jax = _jax()
    jnp, lax = jax.numpy, jax.lax
    f = jax.jit(to_jax(step))   # traced once, called twice (the step in the loop, its outputs after it)
    inputs = _noisy_inputs(jax, noise)

    def trajectory(s0: Any, a: Any, c: Any, seed: Any, targets: Any) -> tuple[Any, Any, Any]:
        key = jax.random.key(seed)

        def advance(carry: Any, target: Any) -> tuple[Any, tuple[Any, Any]]:
            def body(state: Any) -> Any:
                s, k, alive, status = state
                nxt = f(s, inputs(a, key, k), c)[0]
                bad = ~jnp.all(jnp.abs(nxt) <= bound)   # NaN compares false: non-finite is bad
                status = jnp.where(alive & bad, k, status)
                alive = alive & ~bad
                return jnp.where(alive, nxt, s), k + 1, alive, status

            s, k, alive, status = lax.while_loop(lambda st: st[1] < target, body, carry)
            o = f(s, inputs(a, key, target), c)[1]
            nan = jnp.float64(np.nan)
            return (s, k, alive, status), (jnp.where(alive, s, nan), jnp.where(alive, o, nan))

        n_steps = targets[-1]
        init = (s0, jnp.int64(0), jnp.bool_(True), n_steps)
        (_, _, _, status), (S, O) = lax.scan(advance, init, targets)
        return S, O, status

    batched = jax.vmap(trajectory, in_axes=(0, None if shared_a else 0, None if shared_c else 0, 0, None))
    return jax.jit(batched, compiler_options=_cpu_options(jax))


def run_batch_jax(step: ca.Function, S0: np.ndarray, A: np.ndarray, C: np.ndarray, steps: np.ndarray,
                  bound: float, *, noise: DeviceNoise | None = None,
                  seeds: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`nlobs.engine.run_batch` on JAX (one XLA program: vmap over trajectories, scan over saves).

    `steps` are the saved step indices (:func:`nlobs.engine.saved_steps`); the semantics, NaN after a
    trajectory stops and `status`, are those of the C batch driver. With `noise`, each run's noise is drawn on the
    device from its entry of `seeds` (non-negative integers below 2**32) into the shared inputs `A` (N + 1, na).
    """
    jax = _jax()
    shared_a, shared_c = A.ndim == 2, C.ndim == 1
    if noise is not None and (not shared_a or seeds is None or len(seeds) != S0.shape[0]):
        raise ValueError("run_batch_jax: noise drawn on the device needs shared inputs A (N + 1, na) and one seed a run")
    key = (id(step), float(bound), shared_a, shared_c, noise)
    hit = _BATCH_CACHE.get(key)
    if hit is None or hit[0] is not step:
        _check_size(step)
        hit = _BATCH_CACHE[key] = (step, _batch_program(step, bound, shared_a, shared_c, noise))
        if len(_BATCH_CACHE) > 64:
            _BATCH_CACHE.pop(next(iter(_BATCH_CACHE)))
    program = hit[1]
    seeds = np.zeros(S0.shape[0], dtype=np.uint32) if seeds is None else np.asarray(seeds).astype(np.uint32)
    S, O, status = program(jax.numpy.asarray(S0), jax.numpy.asarray(A), jax.numpy.asarray(C), jax.numpy.asarray(seeds),
                           jax.numpy.asarray(np.asarray(steps, dtype=np.int64)))
    return np.asarray(S), np.asarray(O), np.asarray(status, dtype=np.int64)
