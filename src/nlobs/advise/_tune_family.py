"""``design --run``'s noise tuning: the Kalman-family candidates' Q and R fitted on the comparison run's measurements
(or the recording) by :func:`nlobs.learning.tune` before they are ranked."""

from __future__ import annotations

from typing import Any

from ..estimation import Recording
from ..learning._tune_noise import tune as _tune

__all__ = ["family", "scenario_recording", "tune_candidates"]


def family() -> tuple[str, ...]:
    """The kinds ``design --run`` tunes from the run's measurements before ranking: those that declare a likelihood in
    the registry (``@kind(likelihood=...)``): the Kalman family, the pf, and MHE, whose cost weighs by the same Q and R
    (those covariances in its maximum-a-posteriori reading)."""
    from ..design import KINDS

    return tuple(k for k, v in KINDS.items() if v.likelihood)
#: Seconds the noise tuning of ``design --run`` may take (compiling included) before the ranking goes on without it.
TUNE_BUDGET = 90.0
#: ``design --run`` tunes models up to this many filter states (the EKF's state and covariance: n + n(n+1)/2) and this
#: many of them times recording rows: beyond, compiling the likelihood's adjoint and the fit take minutes (a 16-state
#: INS: about 200 s to compile once, 30-100 s to fit 30 s of data), which ``nlobs tune`` spends once, not every run.
TUNE_MAX_STATES, TUNE_MAX_WORK = 12, 2.5e6


def scenario_recording(ctx: Any) -> Recording:
    """The measurements of the comparison run (the scenario's plant, inputs, noise and seed; samples stamped when they
    were taken), as a recording: what ``design --run`` tunes the Kalman family on."""
    import numpy as np

    from ..simulate import simulate
    from ..simulate._schedule import SampleSchedule

    sc = ctx.scenario
    run = simulate(ctx.system, None, t_final=sc.t_final, dt=sc.dt, x0=sc.x0, inputs=sc.inputs, noise=sc.noise,
                   process_noise=sc.process_noise, sampling=sc.sampling, seed=sc.seed)
    measured = run.info.get("measured")
    if measured is None:   # one clock for every output (or none): the schedule the run was built on says which rows are samples
        measured = SampleSchedule.on_grid(run.t, sc.dt, run.output_names, run.state_names, sampling=sc.sampling).measured()
    return Recording.from_arrays(ctx.system, run.t, np.where(measured, run.y, np.nan), run.u,
                                 source="the comparison run's measurements")


def _rows(ctx: Any) -> int:
    """Rows of the comparison run: the recording's, or the scenario's steps."""
    return ctx.recording.t.size if ctx.recording is not None else int(round(ctx.scenario.t_final / ctx.scenario.dt)) + 1


def tunes_here(ctx: Any) -> bool:
    """Whether ``design --run`` tunes the Kalman family on this model and run: at most :data:`TUNE_MAX_STATES`
    states and :data:`TUNE_MAX_WORK` state-rows (above, compiling and fitting the likelihood takes minutes)."""
    n = ctx.system.n_states
    return n <= TUNE_MAX_STATES and _rows(ctx) * (n + n * (n + 1) // 2) <= TUNE_MAX_WORK


def tune_candidates(ctx: Any, candidates: list[Any], say: Any = None) -> tuple[list[Any], str | None]:
    """The Kalman-family candidates with Q and R tuned on the comparison run's measurements (or the recording), and a
    note saying what was done. One tuning, of the EKF's innovations likelihood (the UKF's when there is no EKF), is
    shared by the family within :data:`TUNE_BUDGET`: tuning each kind on its own likelihood would cost each its own
    fit for differences that are second order on a model the EKF fits. The result is used only when it converged and
    its NIS lies in its chi-square band; otherwise the candidates keep the default tuning, and the note says why."""
    from dataclasses import replace

    from ..engine._budget import time_budget
    from ..errors import DataError, EngineError, FiniteEscapeError, NlobsError, SolverError, TimeBudgetError

    kinds = family()
    members = [c for c in candidates if c.kind in kinds and c.applies and c.design is not None]
    base = next((c for c in members if c.kind == "ekf"), next((c for c in members if c.kind == "ukf"), None))
    if base is None:
        return candidates, None
    n = ctx.system.n_states
    rows = _rows(ctx)
    if not tunes_here(ctx):
        return candidates, (f"Q and R were not tuned on the run's measurements here ({n} states, {rows} rows: compiling and "
                            "fitting the likelihood takes minutes); `nlobs tune MODEL DATA --observer ekf` tunes them once "
                            "(`nlobs simulate MODEL --output DATA` writes the run's measurements)")
    if say:
        say(f"advise {ctx.system.name}: tuning Q and R of the Kalman family on the run's measurements ({base.kind}) ...")
    try:
        rec = ctx.recording if ctx.recording is not None else scenario_recording(ctx)
        # the declared output noise is the run's own (and a recording's best knowledge of its sensors): R stays, Q is
        # tuned; without declared noise both are (R and Q trade off on short records: fixing R removes that ridge)
        declared = ctx.scenario is not None and ctx.scenario.noise_std is not None
        with time_budget(TUNE_BUDGET):
            res = _tune(base.design, rec, observer=base.kind, starts=3, max_iter=200, on_missing="skip", fix_r=declared)
    except (TimeBudgetError, FiniteEscapeError, SolverError, EngineError, DataError, NlobsError) as e:
        return candidates, (f"Q and R were not tuned on the run's measurements ({type(e).__name__}: "
                            f"{str(e).splitlines()[0][:160]}); the candidates keep the default tuning")
    if not (res.converged and res.nis_ok):
        why = "did not converge" if not res.converged else f"its NIS {res.nis['mean']:.3g} is outside its band"
        return candidates, (f"tuning Q and R on the run's measurements {why} ({res.seconds:.0f} s); the candidates keep "
                            "the default tuning (nlobs tune MODEL DATA tunes one filter with more starts)")
    out = []
    for c in candidates:
        if c in members:
            try:
                if c.kind == "mhe":
                    from ..design import KINDS

                    d = KINDS["mhe"].design(c.design.system, **{**c.options, "Q": res.Q, "R": res.R})
                else:
                    d = res.apply(c.design)
            except (NlobsError, TypeError, ValueError):
                out.append(c)
                continue
            opts = {**c.options, "Q": res.Q, "R": res.R}   # what `design --toml` prints
            out.append(replace(c, design=d, options=opts,
                               why=c.why + f"; then tuned on the run's measurements ({base.kind} likelihood)"))
        else:
            out.append(c)
    tuned = ", ".join(c.kind for c in members)
    what = "Q (R kept: the declared output noise)" if declared else "Q and R"
    return out, (f"{what} of {tuned} tuned on the run's measurements by the {base.kind}'s innovations likelihood "
                 f"(Schweppe (1965)): converged, NIS {res.nis['mean']:.3g} in its band, {res.seconds:.0f} s; "
                 "`design --run --toml` prints the tuned values")
