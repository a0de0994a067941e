"""The papers' examples (SPEC M8): each is a function returning an :class:`ExampleResult`.

An example builds its models, checks the paper's claims with numbers, runs the observers
(noise-free and with noise) and returns everything the demo report and the terminal
summary need. The acceptance tests call the same functions.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..model import System
from ..simulate import Run

__all__ = ["Claim", "claim_from_global", "ExampleResult", "Example", "EXAMPLES", "ALIASES", "PRACTICE", "register", "practice",
           "find_example", "rows_from_run"]


@dataclass(frozen=True)
class Claim:
    """A claim of the paper (or of nlobs about the paper's example), checked with numbers.

    `holds` is True or False when the claim was checked, None when it could not be (e.g. the global
    check without a Gröbner engine); `detail` then says why and what to install or change. A claim
    that was not checked is never shown as holding, nor as failing.

    `paper` marks a claim the paper makes that nlobs checks without standing behind it: where it does
    not hold, that is a finding about the paper, shown as "not true" with `why` (what the numbers show
    instead, and where the example's notes explain it), not a failure of nlobs. A claim of nlobs that
    does not hold FAILS.
    """

    text: str
    holds: bool | None
    detail: str = ""
    paper: bool = False
    why: str = ""

    def __post_init__(self) -> None:
        if self.holds is not None:  # NumPy booleans from comparisons become bool
            object.__setattr__(self, "holds", bool(self.holds))

    @property
    def not_true(self) -> bool:
        """Whether this is a claim of the paper, checked, that does not hold (a finding, not a failure)."""
        return self.paper and self.holds is False

    @property
    def word(self) -> str:
        """How the claim is shown: "ok", "not true" (a claim of the paper that the check contradicts), "FAILS"
        or "not checked"."""
        if self.holds is None:
            return "not checked"
        return "ok" if self.holds else ("not true" if self.paper else "FAILS")

    def __str__(self) -> str:
        return (f"[{self.word}] {self.text}" + (f" ({self.detail})" if self.detail else "")
                + (f"; why: {self.why}" if self.not_true and self.why else ""))


def claim_from_global(text: str, result: Any, holds: bool) -> Claim:
    """A claim decided by a global check (:func:`nlobs.analysis.global_identifiability`): not checked
    when the check could not run for want of an engine (its reason as the detail), else `holds`."""
    from ..analysis.structural._global import NO_ENGINE

    if result.refused == NO_ENGINE:
        return Claim(text, None, result.refused)
    return Claim(text, holds, "; ".join(result.describe("observable")) if result.ok else (result.refused or ""))


@dataclass(frozen=True, eq=False)
class ExampleResult:
    """What one paper example produced.

    Attributes
    ----------
    key, title : str
    reference : str
        The work and the place in it, cited by author and year through
        :func:`nlobs.references.cite`, e.g. ``"Viegas, Batista, Oliveira & Silvestre (2015), §IV-C, eqs. (20)-(22)"``.
    summary : str
        One paragraph: what is shown and what was found.
    model : str
        The model(s), as text.
    evidence : sequence of str
        Observability verdicts and design certificates, as text blocks.
    runs : mapping of label to Run
        Simulations to plot (states vs estimates, error norms).
    table : sequence of dict
        Rows with keys ``run``, ``observer``, ``convergence_time``, ``rms_error``, ``final_error``
        (and optional extras).
    claims : sequence of Claim
    figures : mapping of caption to matplotlib Figure
        Extra figures beyond the runs (Gramian eigenvalues, excitation, ...).
    notes : sequence of str
        Choices made where the paper is silent, and deviations found.
    systems : mapping of label to System
        The example's models; the demo reports the observability verdict of each
        (:func:`nlobs.analysis.analyze`).
    convergence_rule : str
        What the table's ``convergence_time`` and errors mean when the example measures them its own
        way (default "": the rule of :meth:`nlobs.Run.metrics`, :data:`nlobs.simulate.PER_STATE_RULE`,
        and RMS over the last 20 % of the run).
    """

    key: str
    title: str
    reference: str
    summary: str
    model: str
    evidence: Sequence[str] = ()
    runs: Mapping[str, Run] = field(default_factory=dict)
    table: Sequence[Mapping[str, Any]] = ()
    claims: Sequence[Claim] = ()
    figures: Mapping[str, Any] = field(default_factory=dict)
    notes: Sequence[str] = ()
    systems: Mapping[str, System] = field(default_factory=dict)
    convergence_rule: str = ""

    @property
    def ok(self) -> bool:
        """Whether no claim fails (a claim that could not be checked, and a claim of the paper found not true,
        are counted apart, see :attr:`tally`)."""
        return all(c.holds is not False or c.paper for c in self.claims)

    @property
    def tally(self) -> str:
        """E.g. "claims 5/6 hold, 1 not checked", or "claims 8/10 hold, 2 of the paper's checked and not true"."""
        n_ok = sum(c.holds is True for c in self.claims)
        n_none = sum(c.holds is None for c in self.claims)
        n_not = sum(c.not_true for c in self.claims)
        return (f"claims {n_ok}/{len(self.claims)} hold"
                + (f", {n_not} of the paper's checked and not true" if n_not else "")
                + (f", {n_none} not checked" if n_none else ""))

    def __repr__(self) -> str:
        return f"ExampleResult({self.key!r}, {self.tally}, runs={list(self.runs)}, figures={list(self.figures)})"

    def _repr_html_(self) -> str | None:
        """The example as the demo report shows it (claims, table, plots, model, evidence, notes), once
        :mod:`nlobs.report` is loaded (it registers the renderer: the report renders examples, never the reverse);
        None before that (a notebook then shows the repr)."""
        return None if HTML_RENDERER is None else HTML_RENDERER(self)


#: How an ExampleResult shows itself in a notebook: set by :mod:`nlobs.report` when it is imported.
HTML_RENDERER: Callable[["ExampleResult"], str] | None = None


def register_html_renderer(render: Callable[["ExampleResult"], str]) -> None:
    """Let `render` show an ExampleResult as HTML in a notebook (called once, by :mod:`nlobs.report`)."""
    global HTML_RENDERER
    HTML_RENDERER = render


@dataclass(frozen=True)
class Example:
    """A registered example: its key (``nlobs demo --only KEY``), title, place in the demo and function."""

    key: str
    title: str
    order: int
    run: Callable[[], ExampleResult]
    aliases: tuple[str, ...] = ()


#: Every registered example by key, in the order the demo shows them.
EXAMPLES: dict[str, Example] = {}
#: Former keys that still select an example (``nlobs demo --only 002-pendulum``).
ALIASES: dict[str, str] = {}


def register(key: str, title: str, order: int, *, aliases: Sequence[str] = ()) -> Callable[[Callable[[], ExampleResult]], Callable[[], ExampleResult]]:
    """Decorator: register a paper example for the demo under `key` (and its former keys `aliases`)."""

    def deco(fn: Callable[[], ExampleResult]) -> Callable[[], ExampleResult]:
        EXAMPLES[key] = Example(key, title, order, fn, tuple(aliases))
        ALIASES.update({a: key for a in aliases})
        return fn

    return deco


#: Practitioners' models, by key, in the order of the docs' gallery: a battery with an OCV table, a discrete-time
#: building, a multi-rate vehicle. They show features the papers do not (tables, maps, clocks and latencies) and are not
#: part of ``nlobs demo``, which reproduces the papers.
PRACTICE: dict[str, Example] = {}


def practice(key: str, title: str, order: int) -> Callable[[Callable[[], ExampleResult]], Callable[[], ExampleResult]]:
    """Decorator: register a practitioner's model under `key` in :data:`PRACTICE` (the gallery's second part)."""

    def deco(fn: Callable[[], ExampleResult]) -> Callable[[], ExampleResult]:
        PRACTICE[key] = Example(key, title, order, fn)
        return fn

    return deco


def find_example(key: str) -> Example:
    """The example registered under `key` or a former key of it.

    Raises
    ------
    KeyError
        Naming the available keys.
    """
    key = ALIASES.get(key, key)
    if key not in EXAMPLES:
        raise KeyError(f"no example {key!r}; available: {', '.join(e.key for e in sorted(EXAMPLES.values(), key=lambda e: e.order))}")
    return EXAMPLES[key]


def rows_from_run(label: str, run: Run, *, tol: float | None = None, **extra: Any) -> list[dict[str, Any]]:
    """Summary-table rows (one per observer) from a run with known true state.

    The convergence time is :meth:`nlobs.Run.metrics`'s: the time after which the error stays
    within its band (`tol`, else each state's in its own units: :data:`nlobs.simulate.PER_STATE_RULE`).
    """
    rows = []
    for name in run.observers:
        m = run.metrics(name, tol=tol)
        rows.append({"run": label, "observer": name, "convergence_time": m.convergence_time,
                     "rms_error": m.rms_error, "final_error": m.final_error, **extra})
    return rows
