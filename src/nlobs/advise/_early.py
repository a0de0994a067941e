"""The comparison run's code built early: on a large model, ``design --run`` spends most of its time compiling each
candidate's C code, and before that the main thread designs the candidates one after another (SymPy and CasADi work
on one core). :class:`EarlyBuild` starts each runnable candidate's build as soon as it is designed, on one thread
beside the designs: a short run of the candidate alone on the scenario, on the compiled engine, which builds exactly
what the comparison run loads (the compiled code is keyed by the functions, not by the horizon). The comparison then
finds it in the cache, or waits for a build still under way (``engine._codegen._build`` builds each object once).

Used only where the comparison run is compile-bound and its designs are final: a scenario (not a recording), a C
compiler, and a model the advisor does not tune before ranking (``_tune_family.tunes_here``: a tuned design is a
new one, with other code)."""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

from ..engine import find_compiler
from ._advice import Candidate
from ._context import Context
from ._rank import _without_diverging
from ._tune_family import tunes_here

#: Samples of the scenario the early run covers (enough for every sensor's first sample and a delayed one's arrival).
EARLY_SAMPLES = 20


class EarlyBuild:
    """Build the comparison run's code of each candidate given to :meth:`add`, one at a time on a thread of its own.

    Parameters
    ----------
    ctx : Context
        The advisor's context (its scenario is run).
    engine : str
        The comparison run's engine ("vm": nothing is built).
    budget : float or None
        Seconds each early run may take.
    tune : bool
        Whether ``design --run`` tunes the Kalman family (where it does, nothing is built early).
    """

    def __init__(self, ctx: Context, engine: str, budget: float | None, tune: bool) -> None:
        sc = ctx.scenario
        self.active = (sc is not None and ctx.recording is None and engine != "vm" and find_compiler() is not None
                       and not (tune and tunes_here(ctx)))
        self.ctx, self.engine, self.budget = ctx, ("c" if engine == "auto" else engine), budget
        self.futures: list[Future[Any]] = []
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="nlobs-early-build") if self.active else None
        if sc is not None:
            period = sc.sample_period or sc.dt
            self.t_end = min(sc.t_final, max(sc.dt, EARLY_SAMPLES * period))

    def add(self, candidate: Candidate) -> None:
        """Start building `candidate`'s code if it is part of the comparison run (applies, runnable, not an NLP
        estimator: those run on the virtual machine's solver calls)."""
        d = candidate.design
        if (self._pool is None or not (candidate.applies and candidate.runnable) or d is None
                or getattr(d, "needs_mx", False)):
            return
        self.futures.append(self._pool.submit(self._one, candidate.kind, d))

    def _one(self, kind: str, design: Any) -> None:
        try:   # its result is not used: a failure shows again (and is reported) in the comparison run
            _without_diverging(self.ctx, {kind: design}, self.t_end, self.engine, None, self.budget)
        except Exception:  # noqa: BLE001,S110 - only the build matters here
            pass

    def stop(self) -> None:
        """Cancel the builds not started; the one under way finishes (the comparison waits for it where it needs
        the same code)."""
        if self._pool is not None:
            for f in self.futures:
                f.cancel()
            self._pool.shutdown(wait=False)
