r"""``--run``: every applicable design on the same measurements, ranked.

The candidates run in one simulation, each with its own copy of the plant (its own compiled step, cached
per observer; the copies see the same measurements). A candidate that blows up is reported as diverged,
with the time; one that fails otherwise (its NLP, a gap) as failed; the others keep their results.

Ranking: by the error after convergence — the RMS over the last 20 % of the run of x̂ − x with each
state divided by its scale on the run (its range; so that a position in metres does not outweigh an
angle in radians) — and, among errors within a factor 1.25 of each other (a tie at the
precision such a run has), by the convergence time. On a recording there is no true state; the
candidates are then ranked by the RMS of their innovations y_k − h(x̂_k⁻) over the last 20 % (what
:func:`nlobs.estimate` records; y − h(x̂) for an observer without them).

A constant (a state the run leaves where it starts, such as a sensor bias, or an unknown parameter) whose error over
the last 20 % is still above 20 % of its initial error is named in its score's detail: "not converged within the run".

Honesty: such a candidate, and one whose run ends worse than it started (the per-state normalised error over the last
20 % above its value at t = 0), is ranked after every candidate that converged, whatever its error, and is never named
best (:attr:`Score.eligible`); when none converged, the ranking says so and what to try (:data:`WHAT_TO_TRY`). The
scales the errors are divided by are the context's: a state that does not move on the run is divided by the offset
the run resolves (or its initial uncertainty), never by its (zero) range. The model file's own ``[observers.NAME]``
run beside the candidates (:func:`own_observers`), so a user's tuning is held against the advisor's.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ..engine import compile_system
from ..engine._budget import observer_budget, time_budget
from ..errors import DataError, EngineError, FiniteEscapeError, SolverError, TimeBudgetError
from ..model import System
from ..estimation import estimate
from ..simulate import Run, simulate
from ..simulate._isolate import failure_of
from ..simulate._results import lean_traces
from ._advice import WHAT_TO_TRY, Candidate, Score
from ._context import Context

__all__ = ["compare", "screen", "demoted", "unscreened", "rank", "best", "residuals", "own_observers", "TIE", "WHAT_TO_TRY", "OWN"]

#: Errors within this factor count as a tie, broken by the convergence time.
TIE = 1.25

#: Seconds each candidate's screening (the start of the run, on the VM) may take: one that takes longer is not
#: demoted (the screening checks for a blow-up at the start; it did not see one), and says so.
SCREEN_BUDGET = 20.0
#: The same for an estimator that solves an NLP per sample (MHE), whose windows on the VM can take a second each.
SCREEN_BUDGET_NLP = 5.0
#: The largest NLP estimator a screening builds, in window samples times states: building one is not interrupted by
#: the budget, and a moving-horizon estimator of the 24-state INS (28 samples, 672) took 0.9 GB and 8 s to build before
#: its budget could stop it (the screening's verdict: none). Larger ones are not screened, and the output says so.
SCREEN_NLP_SIZE = 500


def _score(run: Run, name: str, ctx: Context) -> Score:
    """The metrics of one candidate (the one place that reads :meth:`Run.metrics`, so its definition may change)."""
    tr = run.observers[name]
    if not np.all(np.isfinite(tr.xhat)):
        bad = int(np.flatnonzero(~np.isfinite(tr.xhat).all(axis=1))[0])
        return Score(name, "diverged", detail=f"non-finite estimate at t = {run.t[bad]:.4g}")
    params = _parameters(run, name, ctx)
    if run.x is not None:
        m = run.metrics(name)
        err = run.error(name)
        tail = run.t >= run.t[-1] - 0.2 * (run.t[-1] - run.t[0])
        scale = ctx.scale[:err.shape[1]]
        scaled = err[tail] / scale
        nrms = float(np.sqrt(np.mean(scaled ** 2)))
        e0 = _initial_error(run, name, err)
        start = float(np.sqrt(np.mean((e0 / scale) ** 2)))
        worse = (f"ends worse than it started: rel. error {nrms:.3g} over the last 20 % against {start:.3g} at t = 0"
                 if start > 0 and nrms > start else "")
        unsettled = _unsettled(err, tail, ctx, e0)
        return Score(name, "ok", m.rms_error, m.convergence_time, m.final_error, parameters=params, normalised_rms=nrms,
                     detail="; ".join(t for t in (worse, unsettled) if t), converged=not (worse or unsettled))
    resid, what = residuals(run, name, ctx.system)
    tail = run.t >= run.t[-1] - 0.2 * (run.t[-1] - run.t[0])
    ok = np.all(np.isfinite(resid), axis=1) & tail
    rms = float(np.sqrt(np.mean(np.sum(resid[ok] ** 2, axis=1)))) if ok.any() else float("nan")
    return Score(name, "ok", rms, None, float(np.linalg.norm(resid[-1])), detail=f"{what} (no true state)", parameters=params)


#: A constant state (a bias) or an unknown parameter whose error over the last 20 % of the run is above this fraction
#: of its initial error is reported as not converged within the run (the cap of the convergence band, nlobs.simulate).
UNSETTLED = 0.2


#: ... unless it is within this many times its Cramér–Rao bound from the run's samples
#: (:func:`nlobs.advise._context.cramer_rao`) and that is at most half its initial error: an offset only a few times
#: the bound cannot fall to 20 % of itself, and a filter that ends where no unbiased estimator could do much better has
#: settled it as far as the run allows (an offset below that, the run cannot show converge at all: named).
CRAMER_RAO = 3.0


def _initial_error(run: Run, name: str, err: np.ndarray) -> np.ndarray:
    """x̂(0) − x(0) before any measurement (the trace's first row may follow the first update)."""
    prior = getattr(run.observers[name], "xhat_prior", None)
    if prior is not None and np.size(prior) == err.shape[1]:
        return np.asarray(prior, dtype=float) - run.x[0, :err.shape[1]]
    return err[0]


def _unsettled(err: np.ndarray, tail: np.ndarray, ctx: Context, e_start: np.ndarray) -> str:
    """The constants (states that do not move on the run, unknown parameters) whose estimate did not settle: the RMS of
    their error over the last 20 % of the run above UNSETTLED of their initial error, and above CRAMER_RAO times the
    Cramér–Rao bound of the run. '' when all settled.

    A run started from an offset of these states exists to show them converge; the error norm of all states together
    (the convergence time) is dominated by the moving ones and cannot say it. A state with declared process noise is
    left out: in the plant it wanders (a random walk), and a filter tracks it rather than settles it."""
    n_plant = ctx.model.n_states
    idx = sorted(set(getattr(ctx, "constant", ())) | set(range(n_plant, err.shape[1])))
    sc = ctx.scenario
    if sc is not None and sc.process_std is not None:   # a declared random walk: tracked, not settled
        idx = [i for i in idx if i >= sc.process_std.size or not sc.process_std[i] > 0]
    out = []
    bound = getattr(ctx, "cramer_rao", None)
    for i in idx:
        e0 = abs(float(e_start[i]))
        late = float(np.sqrt(np.mean(err[tail, i] ** 2)))
        floor = CRAMER_RAO * float(bound[i]) if bound is not None and i < len(bound) and np.isfinite(bound[i]) else np.inf
        floor = floor if floor <= 0.5 * e0 else 0.0     # only where the run can show the error at least halve
        if e0 > 0 and late > max(UNSETTLED * e0, floor):
            out.append(f"{ctx.system.states[i]} ({late / e0:.0%})")
    if not out:
        return ""
    return ("not converged within the run: " + ", ".join(out) + " of the initial error left over the last 20 % (the run "
            "does not show " + ("it" if len(out) == 1 else "them") + " converge)")


def _parameters(run: Run, name: str, ctx: Context) -> dict[str, dict[str, float | None]]:
    """Each unknown parameter's final estimate, its standard deviation where the observer carries a covariance
    (:meth:`nlobs.Run.parameters`), and the value the simulation used (None on a recording)."""
    if not ctx.system.estimated_params:
        return {}
    if run.estimated_params:
        out = run.parameters(name)
    else:  # a run that does not label them (defensive: read the trailing states)
        tr = run.observers[name]
        out = {k: {"estimate": float(tr.xhat[-1, ctx.system.states.index(k)]), "std": None, "true": None}
               for k in ctx.system.estimated_params}
    if ctx.recording is None:
        for k, v in out.items():
            v["true"] = ctx.truth.get(k, v.get("true"))
    return out


def residuals(run: Run, name: str, system: System) -> tuple[np.ndarray, str]:
    """The output error along a run, shape (N, p), and what it is: the innovations y_k − h(x̂_k⁻) that
    :func:`nlobs.estimate` records (each sample against the prediction made before it was used), else y − h(x̂)."""
    import casadi as ca

    tr = run.observers[name]
    if getattr(tr, "innovation", None) is not None:
        return run.innovations(name), "innovation RMS"
    comp = compile_system(system)
    N = run.t.size
    h = comp.h.map(N)(ca.DM(run.t).T, ca.DM(tr.xhat.T), ca.DM(run.u.T) if system.n_inputs else ca.DM(0, N),
                      ca.repmat(ca.DM(system.param_values), 1, N))
    return run.y - np.asarray(h, dtype=float).T, "output residual RMS"


def _key(s: Score) -> float:
    """The error a score is ranked by: per-state normalised when there is a true state, else the residual RMS."""
    return s.normalised_rms if s.normalised_rms is not None else s.rms_error


def _shown(v: float) -> float:
    """`v` to the 6 significant figures a ranking shows: candidates equal there (filters that compute the same
    estimate in another order) are ordered by name, the same on every run, not by rounding or by which finished first."""
    return float(f"{v:.6g}")


def _ordered(scores: Sequence[Score]) -> list[Score]:
    """Finite errors (per-state normalised, :attr:`Score.normalised_rms`) grouped within a factor :data:`TIE`, each
    group by convergence time, then by error and name as shown (:func:`_shown`)."""
    ok = sorted(scores, key=_key)
    out: list[Score] = []
    i = 0
    while i < len(ok):
        j = i
        while j + 1 < len(ok) and _key(ok[j + 1]) <= TIE * _key(ok[i]):
            j += 1
        group = ok[i:j + 1]
        out += sorted(group, key=lambda s: (s.convergence_time is None, _shown(s.convergence_time or 0.0), _shown(_key(s)),
                                            s.kind))
        i = j + 1
    return out


def rank(scores: Sequence[Score]) -> list[Score]:
    """Best first: the runs that may be named best (:attr:`Score.eligible`: they did not end worse than they started
    and left no constant unsettled), by their error (:func:`_ordered`); then the other runs that finished, in the same
    order, however small their error; then the failures."""
    ok = [s for s in scores if s.status == "ok"]
    return (_ordered([s for s in ok if s.eligible]) + _ordered([s for s in ok if not s.eligible])
            + [s for s in scores if s.status != "ok"])


def best(scores: Sequence[Score] | None) -> Score | None:
    """The first score that may be named best (:attr:`Score.eligible`), or None when none converged."""
    return next((s for s in scores or () if s.eligible), None)


#: How the model file's own observers are named in the run and the ranking: ``file:NAME``.
OWN = "file:{}"


def own_observers(ctx: Context, configs: Mapping[str, Any], candidates: Sequence[Candidate]) -> tuple[dict[str, Any], list[str]]:
    """The model file's ``[observers.NAME]`` designed on the advisor's system, to run beside the candidates: by label
    (:data:`OWN`), with the sentences for those that do not design. A table already run as a candidate (a kind nlobs
    cannot tune, designed from the file) is not repeated. Without its own ``xhat0`` an observer starts where the
    candidates start (the same x̂(0), so that the tunings are compared from the same error)."""
    from ..design import KINDS, design_from_config, options_of
    from ..design._tune import clean_message
    from ..errors import NlobsError

    used = {c.why.split("]")[0].split("[observers.")[-1] for c in candidates if "designed from the file's [observers." in c.why}
    designs: dict[str, Any] = {}
    notes: list[str] = []
    for name, cfg in configs.items():
        if name in used:
            continue
        if cfg.kind not in KINDS:
            notes.append(f"your [observers.{name}] (kind {cfg.kind!r}) is not run: not an observer kind nlobs knows")
            continue
        opts = dict(cfg.options)
        xh = opts.get("xhat0")
        if isinstance(xh, (list, tuple)) and ctx.unknown and len(xh) == ctx.model.n_states:   # the guesses go at the end
            opts["xhat0"] = [*xh, *(float(ctx.model.params[k]) for k in ctx.unknown)]
        elif "xhat0" not in opts and "xhat0" in options_of(KINDS[cfg.kind].design):
            opts["xhat0"] = [float(v) for v in ctx.xhat0]
        try:
            designs[OWN.format(name)] = design_from_config(ctx.system, cfg.kind, opts)
        except (NlobsError, ValueError, TypeError, ArithmeticError) as e:
            notes.append(f"your [observers.{name}] is not run beside the candidates: it does not design on "
                         f"{ctx.system.name!r} with the states {', '.join(ctx.system.states)} ({clean_message(e)})")
    return designs, notes


def compare(ctx: Context, candidates: Sequence[Candidate], *, progress: bool | Callable[[float], None] | None = None,
            engine: str = "auto", budget: float | None = None,
            own: Mapping[str, Any] | None = None) -> tuple[list[Score], Run | None]:
    """Run every runnable applicable candidate (and the file's own observers `own`, by label) on the context's
    scenario; return the ranked scores and the run.

    Each candidate runs with its own copy of the plant (its compiled step cached per observer; an NLP estimator on
    its own, the others side by side) and gets `budget` seconds of its own: one that does not finish in time is
    reported as failed ("did not finish within N s"), the others keep their results."""
    designs = {c.kind: c.design for c in candidates if c.applies and c.runnable and c.design is not None}
    designs.update(own or {})
    run, done = _run_group(ctx, designs, engine, progress, budget) if designs else (None, [])
    done = [replace(s, own=s.kind[len(OWN.format("")):]) if own and s.kind in own else s for s in done]
    return rank(done), run


def screen(ctx: Context, candidates: Sequence[Candidate], budget: float | None = None) -> list[Score]:
    """The applicable candidates (those left out of ``--run`` too: a moving-horizon estimator on many samples) that
    blow up on the first part of the scenario (2 % of it, at least 20 samples; an NLP estimator its first 40 samples),
    run on the virtual machine: what "applies" promises without ``--run`` (the design runs on the file's
    [simulation], at least where a tuning mistake shows: an unstable first step, sigma points outside the model's
    domain). Returns one "diverged" score per candidate that blew up."""
    sc = ctx.scenario
    if sc is None or ctx.recording is not None:
        return []
    designs = {c.kind: c.design for c in candidates if c.applies and c.design is not None}
    failed: list[Score] = []
    for k, d in list(designs.items()):
        window = int(d.certificate.values.get("horizon (intervals)", 0)) if d.needs_mx else 0
        size = window * ctx.system.n_states
        if size > SCREEN_NLP_SIZE:
            failed.append(Score(k, "unscreened", detail=f"its start was not screened: its window of "
                                f"{window} samples of {ctx.system.n_states} states ({size} "
                                f"unknowns) is more than a screening builds ({SCREEN_NLP_SIZE})"))
            del designs[k]
    heavy = {k: d for k, d in designs.items() if d.needs_mx}
    light = {k: d for k, d in designs.items() if k not in heavy}
    period = sc.sample_period or sc.dt
    t_pre = min(sc.t_final, max(0.02 * sc.t_final, 20 * period))
    t_pre = max(sc.dt, round(t_pre / period) * period)
    # an estimator that solves an NLP per sample (MHE) on its first windows only: 40 samples, on the virtual machine
    # (a screen that compiled its NLP would wait minutes for the compiler before the first window)
    t_heavy = min(t_pre, max(sc.dt, 40 * period))
    for group, t_end, limit in ((light, t_pre, SCREEN_BUDGET), *(({k: d}, t_heavy, SCREEN_BUDGET_NLP)
                                                                 for k, d in heavy.items())):
        if not group:
            continue
        short = min(budget, limit) if budget is not None else limit   # a check of the start, not a run
        for s in _without_diverging(ctx, group, t_end, "vm", None, short)[2]:
            if s.status == "failed" and s.detail.startswith("did not finish"):   # no verdict: said, not demoted
                s = replace(s, status="unscreened", detail=f"its start was not screened: it {s.detail.split(' (')[0]} "
                                                              "on CasADi's virtual machine (no compiler is run for a "
                                                              "screening)")
            failed.append(s)
    return failed


def unscreened(candidates: Sequence[Candidate], scores: Sequence[Score]) -> list[Candidate]:
    """The candidates with the reason their start could not be screened (an "unscreened" score) added to `why`."""
    left = {s.kind: s.detail for s in scores if s.status == "unscreened"}
    return [replace(c, why=f"{c.why}; {left[c.kind]}") if c.kind in left and c.applies else c for c in candidates]


def demoted(candidates: Sequence[Candidate], scores: Sequence[Score], where: str) -> list[Candidate]:
    """The candidates with each one whose run blew up (a "diverged" score) moved to "fails", with the measured reason:
    "applies" means the auto-tuned design runs."""
    bad = {s.kind: s for s in scores if s.status == "diverged"}
    return [replace(c, status="fails", why=f"the auto-tuned design blew up on {where}: {bad[c.kind].detail} "
                                         f"(tuning tried: {c.why})") if c.kind in bad and c.applies else c
            for c in candidates]


def _run_group(ctx: Context, designs: dict[str, Any], engine: str, progress: Any,
               budget: float | None = None) -> tuple[Run | None, list[Score]]:
    """One simulation of `designs` (each observer runs with its own copy of the plant, compiled and cached on its own,
    side by side: :class:`nlobs.simulate.Simulation`); a design that fails is reported with its reason, the others
    keep their results."""
    run, designs, failed = _without_diverging(ctx, designs, None, engine, progress, budget)
    return run, ([_score(run, k, ctx) for k in designs] if run is not None else []) + failed


def _without_diverging(ctx: Context, designs: dict[str, Any], t_final: float | None, engine: str,
                       progress: Any, budget: float | None = None) -> tuple[Run | None, dict[str, Any], list[Score]]:
    """Run `designs` together on the scenario (up to `t_final`; None: all of it) or the recording, each within
    `budget` seconds, dropping each one that blows up or fails (reported with the time and reason); returns the run,
    the designs in it, the dropped."""
    sc, rec = ctx.scenario, ctx.recording
    failed: list[Score] = []
    while designs:
        try:
            # several observers: each gets its own budget (side by side); one alone: the whole run's budget
            # the candidates' estimates and standard deviations, not their internal states (memory: a large model's
            # square-root filters carry hundreds of numbers per sample)
            with observer_budget(budget), time_budget(budget if len(designs) == 1 else None), lean_traces():
                if rec is not None:
                    run = estimate(designs, rec, engine=engine)
                else:
                    run = simulate(ctx.system, designs, t_final=sc.t_final if t_final is None else t_final, dt=sc.dt,
                                   x0=sc.x0, inputs=sc.inputs, noise=sc.noise, process_noise=sc.process_noise,
                                   sampling=sc.sampling, seed=sc.seed, engine=engine, progress=progress, delay=sc.delay)
            # observers that failed while the others ran (see Run.failures): dropped with their measured reason
            failed += [Score(name, "diverged" if f.error == "FiniteEscapeError" else "failed", detail=f.reason)
                       for name, f in run.failures.items()]
            return run, {k: v for k, v in designs.items() if k not in run.failures}, failed
        except FiniteEscapeError as e:
            name = _culprit(e, designs)
            if name is None:
                raise
            failed.append(Score(name, "diverged", detail=f"blew up after t = {e.t:.4g}"))
            designs = {k: v for k, v in designs.items() if k != name}
        except (TimeBudgetError, SolverError, EngineError, DataError) as e:   # the one observer of the run failed
            if len(designs) != 1:
                raise
            name, d = next(iter(designs.items()))
            failed.append(Score(name, "failed", detail=failure_of(name, d.method, e).reason))
            return None, {}, failed
    return None, designs, failed


def _culprit(e: FiniteEscapeError, designs: Mapping[str, Any]) -> str | None:
    for name in designs:
        if e.where == f"observer {name!r}":
            return name
    return None
