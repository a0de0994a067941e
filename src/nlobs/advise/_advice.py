"""What :func:`nlobs.advise` returns: one row per observer kind, the verdicts behind them, and a ranking."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._display import MISSING
from ..analysis import ObservabilityReport
from ..design import Check, ObserverDesign
from ..model import System
from ..simulate import Run
from ._present import ModelText

__all__ = ["Candidate", "Score", "Advice", "STATUSES", "jsonable", "WHAT_TO_TRY"]

#: What to try when no candidate converged (in the text, the report and ``--json``).
WHAT_TO_TRY = ("tune the noise covariances on the run's measurements (`nlobs tune MODEL DATA --observer ekf`, then paste "
               "its [observers.NAME] table into the file), make the run longer ([simulation] t_final) so that the "
               "constants have time to settle, excite them more (richer [simulation] inputs), or add sensors that see them "
               "(`nlobs sensors MODEL`)")

#: Candidate statuses: the design was made and its checks hold (`applies`); a precondition fails with its numbers
#: (`fails`); the kind needs structure only the user can give (`needs input`); the kind exists but nlobs has no
#: automatic tuning for it (`not tuned`).
STATUSES = ("applies", "fails", "needs input", "not tuned")


def jsonable(value: Any) -> Any:
    """Options and values as JSON/TOML-ready data (arrays -> lists, numpy scalars -> floats, non-finite -> None)."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if np.isfinite(v) else None
    if isinstance(value, complex):
        return [value.real, value.imag]
    if value is None or isinstance(value, str):
        return value
    return str(value)


@dataclass(frozen=True, eq=False)
class Candidate:
    """One observer kind tried on the model.

    Attributes
    ----------
    kind : str
        The kind, as in model files (``[observers.NAME] kind = "..."``).
    status : {"applies", "fails", "needs input", "not tuned"}
    why : str
        Why it applies (the tuning and what the certificate guarantees) or why not (the failed
        precondition with its numbers, or what the user must supply).
    options : mapping
        The tuning options the design was made with (paste them into ``[observers.NAME]``), or, for
        ``needs input``, the options the user must supply.
    reference : str
        The work the kind implements, by authors and year.
    design : ObserverDesign or None
        The design, when it applies.
    runnable : bool
        Whether ``--run`` simulates it (MHE on many samples is left out, with the reason in `why`).
    """

    kind: str
    status: str
    why: str
    options: Mapping[str, Any] = field(default_factory=dict)
    reference: str = ""
    design: ObserverDesign | None = None
    runnable: bool = True
    seconds: float = 0.0

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"Candidate: `status` must be one of {', '.join(STATUSES)}, got {self.status!r}")

    @property
    def applies(self) -> bool:
        return self.status == "applies"

    @property
    def checks(self) -> tuple[Check, ...]:
        return self.design.certificate.checks if self.design is not None else ()

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"kind": self.kind, "applies": self.applies, "status": self.status, "why": self.why,
                               "options": jsonable(self.options), "reference": self.reference}
        if self.design is not None:
            out["certificate"] = {"method": self.design.certificate.method,
                                  "checks": [{"condition": c.condition, "status": c.status, "detail": c.detail}
                                             for c in self.design.certificate.checks]}
        if self.applies and not self.runnable:
            out["run"] = False
        return out

    def __str__(self) -> str:
        return f"{self.kind}: {self.status} - {self.why}"


@dataclass(frozen=True)
class Score:
    """One candidate measured on the comparison run (metrics from :meth:`nlobs.Run.metrics`)."""

    kind: str
    status: str                 # "ok", "diverged", "failed"
    rms_error: float | None = None
    convergence_time: float | None = None
    final_error: float | None = None
    detail: str = ""
    parameters: Mapping[str, Any] = field(default_factory=dict)
    #: RMS over the last 20 % of the error with each state divided by its scale on the run (its range): what the
    #: ranking uses, so that the state with the largest units does not decide it alone (None on a recording)
    normalised_rms: float | None = None
    #: False when the run ends worse than it started (the per-state normalised error over the last 20 % above the
    #: initial one) or a constant state or unknown parameter did not settle; True when neither; None when it cannot be
    #: judged (a recording: no true state). A score that is not True-or-None is never named best
    converged: bool | None = None
    #: the model file's ``[observers.NAME]`` this score is of ("" for the advisor's candidates)
    own: str = ""

    @property
    def eligible(self) -> bool:
        """Whether it may be named best: it ran, and did not end worse than it started or leave a constant unsettled."""
        return self.status == "ok" and self.converged is not False

    def to_dict(self) -> dict[str, Any]:
        return jsonable({"kind": self.kind, "status": self.status, "rms_error": self.rms_error,
                         "normalised_rms": self.normalised_rms, "converged": self.converged,
                         **({"observer": self.own, "from_file": True} if self.own else {}),
                         "convergence_time": self.convergence_time, "final_error": self.final_error, "detail": self.detail,
                         **({"parameters": dict(self.parameters)} if self.parameters else {})})


@dataclass(frozen=True, eq=False)
class Advice:
    """The answer to "how do I observe this model?": verdicts, one candidate per kind, and (with a run) a ranking.

    Attributes
    ----------
    model : str
    system : System
        What the observers estimate (unknown parameters appended as constant states).
    observability : ObservabilityReport
    candidates : tuple of Candidate
    notes : tuple of str
        The tuning rules used, and warnings (singular input, local-only observability, ...).
    blockers : tuple of str
        Why no full-state observer can apply (an unobservable state, an unidentifiable parameter).
    forms : tuple of str
        Form recognition (output injection, state-affine, triangular, Lipschitz), one line each.
    extra : mapping
        JSON-ready evidence: ``"uco"`` along the run for state-affine models, ``"detectability"``, ...
    scores : tuple of Score or None
        With a run: every runnable candidate, best first.
    run : Run or None
        The comparison run (all candidates that did not diverge): their estimates and standard deviations, without the
        observers' internal states (:func:`nlobs.simulate` with a candidate's design gives those).
    scenario : str
        What the run was (horizon, step, sampling, noise, x̂(0)), or the recording.
    seconds : float
    description : str
        The model file's description (it cites the model's source).
    run_refused : str
        Why ``run=True`` ran nothing although designs apply (the simulation's inputs do not identify an unknown
        parameter: refused before any estimation); empty otherwise.
    text : ModelText or None
        The model as written (the file's strings), shown once at the top of the text; the long substituted
        equations that messages quote are replaced there by references to it.
    choice : (str, str) or None
        The kind a rule marks as the choice for this model, with the reason (the particle filter for an output
        symmetric in a state: a multimodal posterior), when that kind applies.
    """

    model: str
    system: System
    observability: ObservabilityReport
    candidates: tuple[Candidate, ...]
    notes: tuple[str, ...] = ()
    blockers: tuple[str, ...] = ()
    forms: tuple[str, ...] = ()
    extra: Mapping[str, Any] = field(default_factory=dict)
    scores: tuple[Score, ...] | None = None
    run: Run | None = None
    scenario: str = ""
    seconds: float = 0.0
    description: str = ""  #: the model file's description (it cites the model's source)
    run_refused: str = ""  #: why the comparison run was not made although asked for (an input that identifies nothing)
    text: ModelText | None = None  #: the model as written, for the text (equations shown once, then referred to)
    choice: tuple[str, str] | None = None  #: (kind, why) when a rule marks one applicable kind as the choice

    @property
    def applicable(self) -> tuple[Candidate, ...]:
        return tuple(c for c in self.candidates if c.applies)

    @property
    def ranking(self) -> tuple[str, ...] | None:
        """Kinds best first (only candidates that ran without diverging), or None without a run."""
        if self.scores is None:
            return None
        return tuple(s.kind for s in self.scores if s.status == "ok")

    @property
    def best(self) -> Score | None:
        """The best-ranked run that converged (it did not end worse than it started and left no constant unsettled),
        or None: without a run, or when none converged (then :attr:`ranking` still orders them, and nothing is
        recommended)."""
        return next((s for s in self.scores or () if s.eligible), None)

    def candidate(self, kind: str) -> Candidate:
        for c in self.candidates:
            if c.kind == kind:
                return c
        raise KeyError(f"no candidate {kind!r}; kinds: {', '.join(c.kind for c in self.candidates)}")

    def to_dict(self) -> dict[str, Any]:
        """The ``nlobs design --json`` object: model, observability, candidates (and ranking with a run)."""
        obs = self.observability.to_dict()
        obs.update(jsonable(dict(self.extra)))
        obs["blockers"] = list(self.blockers)
        obs["forms"] = list(self.forms)
        out: dict[str, Any] = {"model": self.model, "description": self.description, "states": list(self.system.states),
                               "estimated_params": list(self.system.estimated_params), "observability": jsonable(obs),
                               "candidates": [c.to_dict() for c in self.candidates], "notes": list(self.notes)}
        if self.choice is not None:
            out["choice"] = {"kind": self.choice[0], "why": self.choice[1]}
        if self.scores is not None:
            out["ranking"] = list(self.ranking or ())
            b = self.best
            out["best"] = None if b is None else b.kind
            if b is None and any(s.status == "ok" for s in self.scores):
                out["none_converged"] = ("no observer converged on the run (each ended worse than it started or left a "
                                         "constant unsettled): none is recommended; " + WHAT_TO_TRY)
            out["scores"] = [s.to_dict() for s in self.scores]
            out["scenario"] = self.scenario
            if self.run_refused:
                out["run_refused"] = self.run_refused
        return out

    def __str__(self) -> str:
        rep = self.observability
        lines = [f"Observer design for {self.model!r} ({self.system.n_states} states"
                 + (f", of which {len(self.system.estimated_params)} unknown parameter(s): "
                    f"{', '.join(self.system.estimated_params)}" if self.system.estimated_params else "") + ")"
                 + (f": {self.description}" if self.description else "")]
        verdict = "observable" if rep.observable else "NOT observable"
        lines.append(f"  observability: {verdict} (generic rank {rep.rank} of {len(rep.unknowns)}; "
                     f"observable: {', '.join(rep.observable_states) or 'none'}"
                     + (f"; identifiable: {', '.join(rep.identifiable_params) or 'none'}" if rep.unknown_params else "") + ")")
        for b in self.blockers:
            lines.append(f"  BLOCKED: {b}")
        for f in self.forms:
            lines.append(f"  form: {f}")
        for n in self.notes:
            lines.append(f"  note: {n}")
        if self.choice is not None:
            lines.append(f"  choice: {self.choice[0]}")
        groups = [("applies", "Applies"), ("fails", "Does not apply"), ("needs input", "Needs input"), ("not tuned", "Not tuned")]
        blocked = "; ".join(self.blockers)
        for status, title in groups:
            rows = [c for c in self.candidates if c.status == status]
            if not rows:
                continue
            lines.append(f"{title} ({len(rows)}):")
            same = [c.kind for c in rows if blocked and c.why == blocked]
            if same:
                lines.append(f"  blocked (see above): {', '.join(same)}")
            for c in rows:
                if not (blocked and c.why == blocked):
                    lines.append(f"  {c.kind:<24} {c.why}")
        if self.scores is not None and not self.scores:
            lines.append(f"Nothing was run: {self.run_refused}" if self.run_refused else
                         "Nothing was run: blocked (see BLOCKED above), no estimation was attempted." if self.blockers else
                         "Nothing to run: no observer kind applies.")
        elif self.scores is not None:
            normalised = any(s.normalised_rms is not None for s in self.scores)
            lines.append(f"Ranking on {self.scenario} (error RMS over the last 20 %"
                         + (", each state relative to its range on the run (rel.)" if normalised else "")
                         + ", then convergence time):")
            for i, s in enumerate(self.scores):
                if s.status == "ok":
                    conv = ("did not converge within the run" if s.convergence_time is None and s.final_error is not None
                            and any(o.status == "ok" and o.convergence_time is not None for o in self.scores)
                            else f"converged at {MISSING if s.convergence_time is None else f'{s.convergence_time:.3g}'}")
                    rel = f"rel. {s.normalised_rms:.3g}  " if s.normalised_rms is not None else ""
                    mark = f"{i + 1:>2}." if s.eligible else " x."
                    lines.append(f"  {mark} {s.kind:<24} {rel}RMS {s.rms_error:.3g}  {conv}  "
                                 f"final {s.final_error:.3g}" + (f"  {s.detail}" if s.detail else ""))
                    for k, v in s.parameters.items():  # unknown parameters: the estimate at the final time
                        est = f"{v['estimate']:.6g}" + ("" if v.get("std") is None else f" ± {2 * v['std']:.3g} (2σ)")
                        lines.append(f"      {k} = {est}" + ("" if v.get("true") is None else f", true {v['true']:.6g}"))
                else:
                    lines.append(f"   -  {s.kind:<24} {s.status}: {s.detail}")
            b = self.best
            if b is not None:
                lines.append(f"  best: {b.kind}" + (f" (your [observers.{b.own}])" if b.own else ""))
            elif any(s.status == "ok" for s in self.scores):
                lines.append("  NO BEST: no observer converged on the run (each ended worse than it started or left a "
                             "constant unsettled), so none is recommended; try: " + WHAT_TO_TRY)
            elif not any(s.status == "ok" and s.convergence_time is not None for s in self.scores):
                lines.append("  none converged within the run (into its convergence band): see the report's plots")
            lines.append(f"  converged at: the time after which the error stays within its band ({MISSING}: not within the run)")
        lines.append(f"(advice in {self.seconds:.1f} s wall time, after start-up)")
        if self.text is not None:   # the model once as written; long equations in the messages refer to it
            lines = lines[:1] + self.text.lines() + [self.text.refer(line) for line in lines[1:]]
        return "\n".join(lines)
