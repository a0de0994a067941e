"""One failing observer does not discard a run.

Plant and observers run as one compiled step (their cost is one loop). When an observer fails in
it — its state blows up, or the optimisation inside it (an MHE window) cannot be solved — the run
is redone with each observer on its own, on the same measurements (the noise depends only on the
seed): those that run keep their results, and each failing one gets an :class:`ObserverFailure`
(what happened, when, and the one or two quantities that blew up) in :attr:`Run.failures`. When
every observer fails the first error is raised, as is a plant that blows up (not the observers'
failure).
"""

from __future__ import annotations

import contextvars
import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from typing import Any, TypeVar

import numpy as np

from .._memory import release_free_memory
from ..engine import Backend
from ..engine._budget import per_observer, time_budget
from ..errors import DataError, EngineError, FiniteEscapeError, ModelError, SolverError, TimeBudgetError
from ..observer import AbstractObserver, ParticleObserver
from ._delays import Events, Plan, run_delayed
from ._results import ObserverFailure, ObserverTrace, Run

__all__ = ["culprits", "isolate", "merged", "observer_fault", "failure_of", "each_observer", "WORKERS"]

T = TypeVar("T")

#: Threads that run independent observers side by side: their C compiles (gcc processes) and compiled runs (which
#: release Python's lock) use the cores; so does CasADi's virtual machine, which releases the lock while it evaluates
#: (checked with CasADi 3.8.2: another thread runs Python throughout a one-second evaluation).
WORKERS = max(1, min(2, os.cpu_count() or 1))

#: Places a FiniteEscapeError can name that are not an observer.
_NOT_OBSERVERS = ("plant", "the plant's output", "measurement hold")


def observer_fault(e: BaseException) -> bool:
    """Whether `e` is an observer's failure (not the plant's, not a wrong argument)."""
    if isinstance(e, (SolverError, TimeBudgetError)):
        return True
    return isinstance(e, FiniteEscapeError) and e.where not in _NOT_OBSERVERS


def culprits(names: Sequence[str], nxt: np.ndarray, bound: float, k: int = 2) -> list[tuple[str, float]]:
    """The (at most `k`) entries of the state after the failing step that left |x| <= bound or are not finite:
    non-finite ones first, then the largest."""
    nxt = np.asarray(nxt, dtype=float)
    bad = np.flatnonzero(~(np.abs(nxt) <= bound))
    order = sorted(bad, key=lambda i: (bool(np.isfinite(nxt[i])), -abs(nxt[i]) if np.isfinite(nxt[i]) else 0.0))
    return [(str(names[i]), float(nxt[i])) for i in order[:k]]


def failure_of(name: str, method: str, e: BaseException, partial: Run | None = None) -> ObserverFailure:
    """The row of a failed observer: a one-line reason, the time, and the full message."""
    if isinstance(e, SolverError):
        t = e.window[1]
        reason = f"its optimisation failed on the data up to t = {t:.6g} ({e.status})"
    elif isinstance(e, FiniteEscapeError):
        t, reason = e.t, e.reason
    elif isinstance(e, TimeBudgetError):
        t, reason = None, f"did not finish within {e.seconds:g} s (it was {e.what})"
    else:   # a refusal that concerns this observer only (e.g. a delay it cannot handle)
        t, reason = None, str(e).split(";")[0]
    trace = None
    if partial is not None and name in partial.observers:
        trace = partial.observers[name]
    return ObserverFailure(name, method, t, reason, str(e), type(e).__name__, trace)


def isolate(run_with: Callable[[tuple[str, ...] | None], Run], names: Sequence[str], methods: Mapping[str, str]) -> Run:
    """``run_with(None)`` (all observers together); when an observer fails there, each observer alone
    (``run_with((name,))``). When every observer fails, the first one's error is raised (there is nothing else
    to show)."""
    try:
        return run_with(None)
    except (FiniteEscapeError, SolverError) as e:
        if not observer_fault(e) or not names:
            raise
    runs: dict[str, Run | BaseException] = {}
    for name in names:
        try:
            runs[name] = run_with((name,))
        except (FiniteEscapeError, SolverError) as e:
            runs[name] = e
    return merged(names, runs, methods)


def merged(names: Sequence[str], runs: Mapping[str, Run | BaseException], methods: Mapping[str, str], *,
           fault: Callable[[BaseException], bool] = observer_fault) -> Run:
    """One Run of observers that each ran on their own on the same measurements (a Run per name holding its observer,
    or the exception it raised): failures, per `fault`, listed with their reason; any other exception (the plant's, a
    wrong argument: everyone's) raised; when every observer failed, the first one's error."""
    traces, failures, particles = {}, {}, {}
    base: Run | None = None
    first: BaseException | None = None
    for name in names:
        r = runs[name]
        if isinstance(r, BaseException):
            if not fault(r):
                raise r
            failures[name] = failure_of(name, methods.get(name, "?"), r, getattr(r, "partial", None))
            first = first or r
            continue
        traces[name] = r.observers[name]
        particles.update(r.info.get("particles", {}))
        base = base or r
    if base is None:  # every observer failed: nothing to show but the error (of the first one)
        raise first  # type: ignore[misc]
    info = dict(base.info, **({"particles": particles} if particles else {}))
    return replace(base, observers=traces, failures=failures, info=info)


def each_observer(names: Sequence[str], work: Callable[[str], T], *, alone: Sequence[str] = ()) -> dict[str, T | BaseException]:
    """``work(name)`` for every observer, the names in `alone` (e.g. an MHE, whose solver reports errors through
    process-wide state) one after another first, the others on :data:`WORKERS` threads; each name's result, or the
    exception it raised (kept with that name: one observer's failure is not the others')."""
    out: dict[str, Any] = {}
    budget = per_observer()   # each observer's own time budget (nlobs design --run), from when it starts

    many = len(names) > 1

    def guarded(name: str) -> Any:
        try:
            if budget is None:
                return work(name)
            with time_budget(budget):
                return work(name)
        except Exception as e:   # noqa: BLE001 - returned to the caller, who decides per observer
            return e
        finally:
            if many:   # what this observer's run freed, given back before the next one allocates (nlobs._memory)
                release_free_memory()

    for name in alone:
        out[name] = guarded(name)
    rest = [n for n in names if n not in alone]
    if len(rest) > 1 and WORKERS > 1:
        with ThreadPoolExecutor(max_workers=WORKERS, thread_name_prefix="nlobs-observer") as pool:
            # each task in a copy of this context: the budgets and deadlines set here reach the worker threads
            futures = [pool.submit(contextvars.copy_context().run, guarded, n) for n in rest]
            out.update(zip(rest, (f.result() for f in futures)))
    else:
        out.update((n, guarded(n)) for n in rest)
    return {n: out[n] for n in names}


def run_all_delayed(obs: dict[str, AbstractObserver], t: np.ndarray, u: np.ndarray, y0: np.ndarray, events: Events,
                    z0s: dict[str, np.ndarray], *, the_plan: Plan | None, engine: Backend = "auto",
                    max_step: float | None = None, knot_rows: np.ndarray | None = None
                    ) -> tuple[dict[str, ObserverTrace], dict[str, ObserverFailure]]:
    """Every observer of `obs` on the late samples (:func:`nlobs.simulate._delays.run_delayed`), each on its own: the traces of those that
    ran and the failures of the others (the others keep their results). `y0` is the output the estimate at ``t[0]``
    reads; `z0s` the initial states by name. Raises the first error when none ran, and any error that is not a run's
    failure (a bug) at once."""

    def one(name: str) -> ObserverTrace:   # the trace made in the observer's thread (lean_traces frees z there)
        o = obs[name]
        Z, X = run_delayed(o, t, u, events, z0s[name], max_step=max_step, name=name, engine=engine, the_plan=the_plan,
                           knot_rows=knot_rows)
        return ObserverTrace(name, o.design.method, o.design.z_names, Z, X,
                             z0s[name] if isinstance(o, ParticleObserver) else o.estimate(t[0], z0s[name], u[0], y0),
                             covariance=getattr(o.design, "covariance", None))

    done = each_observer(list(obs), one, alone=[k for k, o in obs.items() if getattr(o.design, "needs_mx", False)])
    traces: dict[str, ObserverTrace] = {}
    failures: dict[str, ObserverFailure] = {}
    errors: list[BaseException] = []
    for name, o in obs.items():
        res = done[name]
        if isinstance(res, BaseException):   # ModelError: e.g. a kind that takes the output continuously
            if not isinstance(res, (FiniteEscapeError, SolverError, ModelError, DataError, EngineError, TimeBudgetError)):
                raise res
            failures[name] = failure_of(name, o.design.method, res)
            errors.append(res)
            continue
        traces[name] = res
    if errors and not traces:
        raise errors[0]
    return traces, failures
