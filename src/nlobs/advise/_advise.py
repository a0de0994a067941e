"""``advise``: from a model to the observers that fit it, with the reasons, and optionally a ranking."""

from __future__ import annotations

import contextvars
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis import ltv_gramian, uco_test
from ..design import KINDS
from ..errors import ModelError
from ..model import ModelFile, System, load_model
from ..references import cite
from ..estimation import Recording
from ._advice import Advice, Candidate, Score
from ..design._constructions import evaluate
from ._context import Context, build_context, file_true_parameters, file_unknown_params
from ._early import EarlyBuild
from ._kinds import try_kind
from ._present import model_text
from ._rank import compare, demoted, own_observers, screen, unscreened
from ._tune_family import tune_candidates

__all__ = ["advise"]


#: Seconds after which the progress names the kind being tried on a line of its own (in logs as on a terminal).
SLOW_KIND = 3.0

#: Seconds each candidate gets in ``--run`` by default (compiling its C included): a candidate that takes longer is
#: reported as "did not finish", never the reason a whole run is lost.
BUDGET = 120.0


def _progress_writer(progress: bool | Callable[[str], None] | None) -> Callable[[str], None] | None:
    """True: one line redrawn in place on a terminal; elsewhere (logs, CI) only the phases, one line each."""
    if progress is None or progress is False:
        return None
    if progress is True:
        tty = sys.stderr.isatty()

        def write(msg: str) -> None:
            if tty:
                sys.stderr.write(f"\r\033[K{msg}")
            elif "] " not in msg:
                sys.stderr.write(f"{msg}\n")
            sys.stderr.flush()
        return write
    return progress


def _uco(ctx: Context) -> tuple[dict[str, Any] | None, str]:
    """Observability on the run vs uniform complete observability, for a state-affine model (Wang, Ortega &
    Bobtsov (2021) eqs. 3-4): the Gramian of the model frozen along the nominal run."""
    from ..design.kalman._riccati import state_affine_parts
    from ..errors import FormError

    if ctx.nominal is None:
        return None, ""
    try:
        parts = state_affine_parts(ctx.system, "advise")
    except (FormError, TypeError):
        return None, ""
    run = ctx.nominal
    k = np.unique(np.linspace(0, run.t.size - 1, min(run.t.size, 2001)).astype(int))
    pts = {"t": run.t[k], "x": run.x[k], "u": run.u[k], "y": run.y[k]}
    n, p = ctx.n, ctx.p
    A = evaluate(list(parts.A.T), ctx.system, pts).reshape(-1, n, n).transpose(0, 2, 1)
    C = evaluate(list(parts.C.T), ctx.system, pts).reshape(-1, n, p).transpose(0, 2, 1)
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(C))):
        return None, ""
    t = pts["t"]
    try:
        gram = ltv_gramian(A, C, t)
        window = float(min(t[-1] / 4.0, 10.0 * 2 * np.pi / ctx.omega_p))
        stride = max(1, (t.size - 1) // 100)
        uco = uco_test(A, C, t, window, stride=stride)
    except (ValueError, ModelError):
        return None, ""
    lam = float(gram.eigenvalues[0])
    top = float(np.max(np.abs(gram.eigenvalues)))
    if not np.all(np.isfinite(gram.eigenvalues)) or lam < -1e-8 * top or top > 1e12 or uco.delta.min() < -1e-8 * abs(uco.delta).max():
        return ({"observable_on_run": None, "gramian_max_eig": top},
                f"along the run the frozen model's transition matrix grows to ~{top:.1e} (A(u, y, t) is not stable along the "
                "run): its Gramian cannot decide observability or uniformity here, and GPEBO-type observers (Φ_A) need an "
                f"output injection ({cite('000', 'assumption 5')})")
    tr = np.trace(gram.W_path, axis1=1, axis2=2) if gram.W_path is not None and len(gram.W_path) == t.size else None
    peak = float(np.max(np.diff(tr) / np.diff(t))) if tr is not None else None
    info = {"observable_on_run": bool(gram.observable), "gramian_min_eig": lam, "gramian_trace": float(np.trace(gram.W)),
            "regressor_peak": peak,
            "horizon": float(t[-1] - t[0]), "uco_window": uco.window,
            "uco_uniform": bool(uco.uniform), "uco_min_delta": float(uco.delta.min()), "uco_worst_start": uco.worst_start}
    if gram.observable and not uco.uniform:
        text = (f"along the run the model is observable on [0, {t[-1]:g}] (λmin W = {lam:.3g}) but NOT uniformly completely "
                f"observable: λmin W(t, t + {uco.window:g}) falls to {uco.delta.min():.3g} (at t = {uco.worst_start:g}). "
                f"Observers whose convergence rests on uniform observability (Kalman-like, EKF) may stall; the 2G+D observer "
                f"needs only observability on an interval ({cite('000', 'Proposition 1')})")
    elif gram.observable:
        text = (f"along the run: observable and uniformly so on windows of {uco.window:g} (min λmin W(t, t + T) = "
                f"{uco.delta.min():.3g})")
    else:
        text = f"along the run the frozen model is NOT observable (λmin W(0, {t[-1]:g}) = {lam:.3g}): the input does not excite it"
    return info, text


def _try_with_progress(ctx: Any, kind: str, position: str, say: Any) -> Candidate:
    """:func:`try_kind`, saying which kind is tried; one that takes long is named again on its own line (for logs)."""
    slow = None
    if say:
        say(f"advise {ctx.model.name}: [{position.replace(' of ', '/')}] {kind} ...")
        slow = threading.Timer(SLOW_KIND, say, (f"advise {ctx.model.name}: still trying {kind} ({position}, "
                                                f"more than {SLOW_KIND:g} s) ...",))
        slow.daemon = True
        slow.start()
    try:
        return try_kind(ctx, kind)
    finally:
        if slow is not None:
            slow.cancel()


def _reconcile_choice(ctx: Context, candidates: Sequence[Candidate], failed: Sequence[Score], where: str,
                      ranked: Sequence[Score] | None = None) -> None:
    """A note that names a kind as the choice, checked against what was run.

    A kind that blew up or failed (`failed`: the screening's or the run's scores) is never recommended: its note says
    what happened, and the choice goes to the best-ranked kind that ran and converged (`ranked`, best first; without a
    run, to none: the screening ranks nothing). A kind that ran to the end but did not converge within it, where
    another did, is treated the same way; one that converged but ranked below others keeps the choice, and its note
    says where it ranked."""
    if not ctx.choice_notes:
        return
    bad = {s.kind: s for s in failed if s.status != "ok"}
    ok = [s for s in (ranked or ()) if s.status == "ok" and not s.own]
    converged = [s for s in ok if s.convergence_time is not None and s.eligible]
    best = (converged or [s for s in ok if s.eligible] or [None])[0]
    for kind, note in list(ctx.choice_notes.items()):
        cand = next((c for c in candidates if c.kind == kind), None)
        mine = next((s for s in ok if s.kind == kind), None)
        if kind in bad:
            s = bad[kind]
            problem = f"{'blew up' if s.status == 'diverged' else 'failed'} on {where} ({s.detail})"
        elif cand is not None and not cand.applies:
            problem = f"does not apply ({cand.why})"
        elif mine is not None and not mine.eligible:
            problem = f"ran on {where} but did not converge ({mine.detail})"
        elif mine is not None and mine.convergence_time is None and converged:
            problem = f"ran on {where} but did not converge within it"
        else:
            problem = ""
        if not problem:
            if mine is not None and best is not None and best.kind != kind:
                place = [s.kind for s in ok].index(kind) + 1
                text = (f"{note} (on {where} it ranked {place} of {len(ok)}: rel. error "
                        f"{mine.normalised_rms or mine.rms_error:.3g}, against {best.normalised_rms or best.rms_error:.3g} "
                        f"for {best.kind})")
                ctx.notes[ctx.notes.index(note)] = text
                ctx.choice_notes[kind] = text
            continue
        other = best if best is not None and best.kind != kind else None
        text = (f"{note}; but {kind} {problem}: it is not recommended"
                + (f"; the best-ranked kind that ran is {other.kind}" if other is not None else
                   "; `nlobs design --run` ranks the kinds that apply" if ranked is None else ""))
        if note in ctx.notes:
            ctx.notes[ctx.notes.index(note)] = text
        else:
            ctx.notes.append(text)
        ctx.choice_notes[kind] = text
        if ctx.choice is not None and ctx.choice[0] == kind:
            ctx.choice = ((other.kind, f"ranked first on {where}; the rule's choice, {kind}, {problem}") if other is not None
                          else None)


def advise(model: System | ModelFile | str | Path, *, unknown_params: Sequence[str] | None = None, simulation: Any = None,
           recording: Recording | None = None, true_parameters: Mapping[str, float] | None = None,
           kinds: Sequence[str] | None = None, run: bool = False, xhat0: Sequence[float] | None = None,
           progress: bool | Callable[[str], None] | None = None, engine: str = "auto", seed: int = 0,
           budget: float | None = BUDGET, tune: bool = True) -> Advice:
    r"""Which observers fit this model, why the others do not, and (with `run`) which works best.

    Runs the structural observability analysis (:func:`nlobs.analyze`) and the form recognition, then tries
    every registered observer kind (:data:`nlobs.design.KINDS`) with an automatic tuning from the model's
    time scales, the region its simulation visits and the declared noise (rules in
    :mod:`nlobs.advise._context`). Each kind gets a :class:`Candidate`: it applies (the design and its
    certificate), fails (the precondition with its numbers), or needs input only the user can give.

    A state that is not observable blocks every full-state observer: the reason names it and says whether it
    is detectable. An unknown parameter that is not identifiable blocks them too, before anything is estimated.

    Parameters
    ----------
    model : System, ModelFile, or a path / bundled model name
    unknown_params : sequence of str, optional
        Parameters to estimate with the states (default: those the model file marks ``unknown = true``).
        The observers then run on ``model.augmented(unknown_params)``.
    simulation : SimulationConfig, optional
        The run to tune for and compare on (default: the model file's ``[simulation]``).
    recording : Recording, optional
        Recorded data to compare on instead of a simulation (the tuning still uses ``[simulation]``).
    true_parameters : mapping, optional
        Values of the unknown parameters in the simulation (default: the file's ``true_parameters``, else the
        parameter values).
    kinds : sequence of str, optional
        Only these kinds (default: all registered).
    run : bool
        Simulate every applicable design on the same measurements and rank them.
    xhat0 : sequence of float, optional
        Initial estimate shared by every candidate (default: see the tuning rules).
    progress : bool or callable, optional
        Report progress on stderr (True) or to ``progress(message)``.

    Other Parameters
    ----------------
    engine : {"auto", "vm", "c"}
        Numeric backend of the comparison run.
    seed : int
        Seed of the structural analysis, and of the comparison run's noise where the model file's [simulation] sets
        no ``seed`` (so that the same call ranks the same way every time).
    budget : float or None
        Seconds each candidate may take in the run and the screening, compiling included (None: no limit).
    tune : bool
        With `run`: tune Q and R of the Kalman-family candidates on the run's measurements before ranking them
        (:func:`nlobs.advise._tune.tune_candidates`; the innovations likelihood), and say so.

    Returns
    -------
    Advice

    Raises
    ------
    ModelError
        For unknown kinds or parameters, or `run` without a ``[simulation]`` x0 or a recording.

    Examples
    --------
    >>> import nlobs
    >>> adv = nlobs.advise("dc_motor")
    >>> adv.candidate("luenberger").applies, adv.candidate("high_gain").applies
    (True, True)
    """
    t0 = time.perf_counter()
    mf = None
    if isinstance(model, (str, Path)):
        model = load_model(model)
    if isinstance(model, ModelFile):
        mf = model
        system = mf.system
        if unknown_params is None:
            unknown_params = file_unknown_params(mf)
        if true_parameters is None:
            true_parameters = file_true_parameters(mf.simulation)
    elif isinstance(model, System):
        system = model
    else:
        raise ModelError(f"advise: `model` must be a System, a ModelFile, or a model file path/name; got {type(model).__name__}")
    chosen = list(kinds) if kinds else list(KINDS)
    unknown_kinds = [k for k in chosen if k not in KINDS]
    if unknown_kinds:
        raise ModelError(f"advise: unknown observer kind {unknown_kinds[0]!r}; kinds: {', '.join(KINDS)}")
    say = _progress_writer(progress)
    if say:
        say(f"advise {system.name}: observability analysis and time scales ...")
    t_ctx = time.perf_counter()
    ctx = build_context(system, model_file=mf, unknown_params=unknown_params or (), simulation=simulation, recording=recording,
                        true_parameters=true_parameters, xhat0=xhat0, seed=seed)
    if mf is not None:
        for name, cfg in mf.observers.items():  # what the user supplied for kinds nlobs cannot tune (KKL's φ, custom ...)
            ctx.configs.setdefault(cfg.kind, (name, cfg.options))
    if run and ctx.recording is None and ctx.scenario is None:
        raise ModelError(f"advise: nothing to run on: {system.name!r} has no [simulation] x0 and no recording was given; "
                         "add [simulation] x0 = [...] (with t_final, inputs, noise) or pass a recording (--data)")
    # the observer forms are forms of ODEs (ẋ = Ax + B(u, y), ...): not shown for a map, whose kinds are ekf, ukf, luenberger
    forms = () if system.is_discrete else tuple(str(c) for c in ctx.forms.checks)
    extra: dict[str, Any] = {}
    if ctx.detectability:
        extra["detectability"] = ctx.detectability
    if not ctx.blockers:
        info, text = _uco(ctx)
        if info is not None:
            extra["uco"] = info
            ctx.uco = info
            ctx.notes.append(text)
    candidates: list[Candidate] = []
    if say:
        say(f"advise {system.name}: trying {len(chosen)} observer kinds ({time.perf_counter() - t_ctx:.1f} s so far) ...")
    early = EarlyBuild(ctx, engine, budget, tune) if run and not ctx.run_blockers else None
    try:
        for i, kind in enumerate(chosen):
            candidates.append(_try_with_progress(ctx, kind, f"{i + 1} of {len(chosen)}", say))
            if early is not None:   # its comparison run's code built beside the next designs (large models)
                early.add(candidates[-1])
    finally:
        if early is not None:
            early.stop()
    if not run and not ctx.blockers and not ctx.run_blockers:
        if say:
            say(f"advise {system.name}: screening the applicable designs on the start of the simulation run ...")
        screened = screen(ctx, candidates, budget)
        candidates = unscreened(demoted(candidates, screened, "the start of the [simulation] run"), screened)
        _reconcile_choice(ctx, candidates, [s for s in screened if s.status != "unscreened"],
                          "the start of the [simulation] run")
    scores = runres = None
    scenario = ""
    refused = ""
    if run and ctx.run_blockers:
        refused = "; ".join(ctx.run_blockers)
        scores, runres = [], None
    elif run:
        candidates, scores, runres = _run_and_rank(ctx, candidates, mf, chosen, engine, budget, say, tune)
    if run:
        scenario = (f"the recording ({ctx.recording.t.size} samples)" if ctx.recording is not None else
                    ctx.scenario.describe() + ", x̂(0) = (" + ", ".join(f"{v:.3g}" for v in ctx.xhat0) + ")")
    if say and progress is True and sys.stderr.isatty():
        sys.stderr.write("\r\033[K")
    text = model_text(ctx.system, mf.path if mf is not None else None, plant_states=system.states,
                      units=mf.units if mf is not None else getattr(system, "units", None))
    return Advice(system.name, ctx.system, ctx.report, tuple(candidates), tuple(ctx.notes), tuple(ctx.blockers), forms,
                  extra, None if scores is None else tuple(scores), runres, scenario, time.perf_counter() - t0,
                  mf.description if mf is not None else "", refused, text,
                  ctx.choice if ctx.choice is not None and any(c.kind == ctx.choice[0] and c.applies for c in candidates) else None)


def _run_and_rank(ctx: Context, candidates: list[Candidate], mf: ModelFile | None, chosen: Sequence[str], engine: str,
                  budget: float | None, say: Any, tune: bool) -> tuple[list[Candidate], list[Score], Any]:
    """``--run``: the Kalman family tuned on the run's measurements (with `tune`), every runnable candidate and the
    file's own observers run on the same measurements, ranked; the candidates demoted where they failed."""
    system = ctx.system
    if tune:
        candidates, note = tune_candidates(ctx, candidates, say)
        if note:
            ctx.notes.append(note)
    if say:
        n_run = sum(c.applies and c.runnable for c in candidates)
        say(f"advise {system.name}: running {n_run} design(s) ...")
    # the file's own observers of the kinds tried (all of them without --kind), beside the candidates
    mine = {k: v for k, v in mf.observers.items() if v.kind in chosen} if mf is not None else {}
    own, own_notes = own_observers(ctx, mine, candidates)
    ctx.notes.extend(own_notes)
    if own:
        ctx.notes.append("your own observer(s) " + ", ".join(f"[observers.{k.split(':', 1)[1]}]" for k in own)
                         + " run beside the candidates (as " + ", ".join(own) + ") and are ranked with them")
    # the candidates left out of the run (an NLP estimator on many samples; a particle filter) screened on the run's
    # start beside it, on a thread of their own: the comparison leaves a core idle at its start and its end
    left_out = [c for c in candidates if c.applies and not c.runnable]
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="nlobs-screen") as pool:
        pending = pool.submit(contextvars.copy_context().run, screen, ctx, left_out, budget)
        scores, runres = compare(ctx, candidates, engine=engine, budget=budget, own=own)
        screened = pending.result()
    where = "the comparison run" if ctx.recording is not None else "the [simulation] run"
    candidates = demoted(candidates, scores, where)
    candidates = unscreened(demoted(candidates, screened, "the start of the [simulation] run"), screened)
    _reconcile_choice(ctx, candidates, [*scores, *(s for s in screened if s.status != "unscreened")], where, scores)
    scores = [s for s in scores if s.status != "diverged"]
    if scores and ctx.recording is None and ctx.scenario.process_std is None:
        ctx.notes.append("the comparison run has no process noise and the model is exact: estimators that lean on the "
                         "model (an open-loop copy of a stable model, a tiny Q) look better here than on a real system; "
                         "add [simulation] process_noise to compare them under model error")
    return candidates, scores, runres
