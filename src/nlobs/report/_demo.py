"""`nlobs demo`: run every paper example, write an HTML report and print a summary table."""

from __future__ import annotations

import html
import platform
import sys
import textwrap
import time
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from .._version import __version__
from .._display import Column, SummaryTable
from ..analysis import analyze
from ..examples import EXAMPLES, Claim, ExampleResult, find_example
from ..examples._base import register_html_renderer
from ..references import REFERENCES, cited_keys
from ..simulate import PER_STATE_RULE
from ._html import HALF_WIDTH, bibliography, details, equations, figure, page, plain, pre, prose, section, table

__all__ = ["run_demo", "DemoOutcome", "example_section", "summary_table"]

COLUMNS = [("run", "run"), ("observer", "observer"), ("convergence_time", "convergence time"),
           ("rms_error", "RMS error (last 20 %)"), ("final_error", "final error")]

@dataclass(frozen=True)
class DemoOutcome:
    """What ``nlobs demo`` did: the examples' results, the ones that crashed, the report, the wall time."""

    results: Sequence[ExampleResult]
    failed: Sequence[tuple[str, str]]  # (key, error text) of examples that crashed
    report: Path
    seconds: float

    @property
    def exit_code(self) -> int:
        return 1 if self.failed else 0


def run_demo(out_dir: str | Path = "nlobs-report", *, only: Sequence[str] | None = None, progress: bool = True,
             stream: TextIO | None = None) -> DemoOutcome:
    """Run the registered paper examples, write ``out_dir/index.html`` and print a summary.

    Parameters
    ----------
    out_dir : str or Path
        Folder of the report (created if needed).
    only : sequence of str, optional
        Keys of the examples to run (default: all); see ``nlobs demo --list``.
    progress : bool
        Print one line per example on stderr.
    stream : text stream, optional
        Where the summary goes (default: stdout).

    Returns
    -------
    DemoOutcome
    """
    t0 = time.perf_counter()
    stream = stream or sys.stdout
    examples = sorted(EXAMPLES.values(), key=lambda e: e.order)
    if only:
        chosen = {find_example(k).key for k in only}
        examples = [e for e in examples if e.key in chosen]
    results, failed, timings = [], [], {}
    for i, ex in enumerate(examples):
        if progress:
            print(f"[{i + 1}/{len(examples)}] {ex.key}: {plain(ex.title)} ...", file=sys.stderr, flush=True)
        t1 = time.perf_counter()
        try:
            results.append(ex.run())
        except Exception as e:  # noqa: BLE001 - one broken example must not hide the others
            failed.append((ex.key, f"{type(e).__name__}: {e}\n{traceback.format_exc()}"))
        timings[ex.key] = time.perf_counter() - t1
    t_examples = time.perf_counter() - t0
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    report = out / "index.html"
    report.write_text(_html(results, failed, timings, t_examples), encoding="utf-8")
    seconds = time.perf_counter() - t0
    _print_summary(results, failed, stream, report, seconds, t_examples)
    return DemoOutcome(results, failed, report, seconds)


def summary_table(results: Sequence[ExampleResult]) -> SummaryTable:
    """Every observer of every example, one row each: what ``nlobs demo`` prints."""
    cols = [Column("example", "example", str, numeric=False), Column("run", "run", str, numeric=False),
            Column("observer", "observer", str, numeric=False), Column("convergence_time", "conv. time"),
            Column("rms_error", "RMS error"), Column("final_error", "final err")]
    rows = [dict(row, example=r.key, run=plain(str(row["run"])), observer=plain(str(row["observer"])))
            for r in results for row in r.table]
    return SummaryTable("All observers", cols, rows,
                        tuple(textwrap.wrap(f"{PER_STATE_RULE} (—: not within the run). RMS error: over the "
                                            "last 20 % of the run; final err: at the final time", width=88)))


def _print_summary(results: Sequence[ExampleResult], failed: Sequence[tuple[str, str]], stream: TextIO, report: Path,
                   seconds: float, t_examples: float) -> None:
    w = stream.write
    w(str(summary_table(results)) + "\n\n")
    width = max([len(r.key) for r in results] + [len(k) for k, _ in failed] + [7])
    for r in results:
        w(f"{r.key:<{width}} {r.tally}" + ("" if r.ok else "  <-- see the report") + "\n")
        for c in r.claims:
            if c.holds is not True:
                text = (f'NOT TRUE, checked: the paper\'s claim "{plain(c.text)}"' if c.not_true else
                        f"{c.word.upper()}: {plain(_claim_text(c))}") + (f" ({plain(c.detail)})" if c.detail else "")
                if c.not_true and c.why:
                    text += f". Why: {plain(c.why)}"
                w(textwrap.fill(text, width=88, initial_indent="    ", subsequent_indent="      ") + "\n")
    for key, err in failed:
        w(f"{key:<{width}} CRASHED: {err.splitlines()[0]}\n")
    w(f"\nreport: {report.resolve()}\n"
      f"wall time {seconds:.1f} s (examples {t_examples:.1f} s, report {seconds - t_examples:.1f} s)\n")


def _convergence_note(r: ExampleResult) -> str:
    """What the convergence-time column of an example means (its own rule, or the rule of nlobs.simulate)."""
    if r.convergence_rule:
        return r.convergence_rule
    return f"{PER_STATE_RULE[0].upper() + PER_STATE_RULE[1:]} (— : not within the run). RMS over the last 20 % of the run."


def _observability(r: ExampleResult) -> list[str]:
    items, reports = [], []
    for label, system in r.systems.items():
        try:
            rep = analyze(system)
        except Exception as e:  # noqa: BLE001 - an analysis that cannot run is reported, not fatal
            items.append(f"<li>{prose(label)}: <span class='fail'>analysis failed: {html.escape(str(e))}</span></li>")
            continue
        d = rep.to_dict()
        verdict = (f"observable: generic rank {d['rank']} = {d['n_states']}" if d["observable"] else
                   f"not observable: generic rank {d['rank']} < {d['n_states']}; observable states: "
                   f"{', '.join(d['observable_states']) or 'none'}")
        cls = "ok" if d["observable"] else "fail"
        if d.get("globally_observable") is False:
            verdict += "; locally only: a symmetry makes it globally unobservable"
            cls = "warn"
        items.append(f"<li>{prose(label)}: <span class='{cls}'>{html.escape(verdict)}</span></li>")
        reports.append(pre(f"{plain(label)}\n{rep}"))
    if not items:
        return []
    out = ["<h3>Observability (nlobs.analyze)</h3><ul>" + "".join(items) + "</ul>"]
    if reports:
        out.append(details("Observability reports", "".join(reports)))
    return out


def _tally_class(r: ExampleResult) -> str:
    """The colour of an example's tally: a claim fails (red), a claim of the paper is not true (amber), else green."""
    return "fail" if not r.ok else "warn" if any(c.not_true for c in r.claims) else "ok"


def _claim_text(c: Claim) -> str:
    """A claim as shown: a claim of the paper says so."""
    return f"paper: {c.text}" if c.paper else c.text


def _reference_links(text: str, references: str = "") -> str:
    """The reference line, each cited work linked to its entry (anchor ``ref-KEY``) on the page `references`
    ("": this page's bibliography)."""
    out = prose(text)
    for k in cited_keys(text):
        label = html.escape(REFERENCES[k].label)
        out = out.replace(label, f"<a href='{html.escape(references)}#ref-{k}'>{label}</a>", 1)
    return out


def example_section(r: ExampleResult, seconds: float | None = None, *, level: int = 2, plots: bool = True,
                    references: str = "") -> str:
    """One example as an HTML section: claims, observability, the table, the plots, the model, the evidence, notes.

    Parameters
    ----------
    r : ExampleResult
    seconds : float, optional
        How long it ran (shown under the title).
    level : int
        Heading level of the title (2: ``<h2>``).
    plots : bool
        Include the run plots and the example's figures.
    references : str
        The page whose anchors ``ref-KEY`` list the cited works (the documentation's references page, as a
        relative link); "" (default): the page the section is on, as the demo report, which ends with its
        bibliography.
    """
    h = level + 1
    sub = _reference_links(r.reference, references) + (f" · ran in {seconds:.1f} s" if seconds is not None else "")
    parts = [f"<p>{prose(r.summary)}</p>", f"<h{h}>Claims checked</h{h}><ul class='claims'>"]
    for c in r.claims:
        cls, word = {True: ("ok", "holds"), False: ("fail", "FAILS"), None: ("unchecked", "not checked")}[c.holds]
        if c.not_true:
            cls, word = "warn", "not true"
        parts.append(f"<li><span class='{cls}'>{word}</span> — {prose(_claim_text(c))}"
                     + (f" <span class='note'>({prose(c.detail)})</span>" if c.detail else "")
                     + (f"<br><span class='note'>Why: {prose(c.why)}</span>" if c.not_true and c.why else "") + "</li>")
    parts.append("</ul>")
    parts += _observability(r)
    if r.table:
        parts.append(f"<h{h}>Convergence and accuracy</h{h}>" + table(r.table, COLUMNS + _extra_columns(r))
                     + f"<p class='note'>{html.escape(_convergence_note(r))}</p>")
    if r.runs and plots:
        parts.append("<div class='figs'>" + "".join(figure(run.plot(width=HALF_WIDTH), label, alt=f"{r.key} {plain(label)}")
                                                  for label, run in r.runs.items()) + "</div>")
    for caption, fig in r.figures.items() if plots else ():
        parts.append(figure(fig, caption))
    if r.systems:
        parts.append(f"<h{h}>Model</h{h}>" + "".join(f"<p>{prose(label)}</p>{equations(s)}" for label, s in r.systems.items()))
    else:
        parts.append(details("Model", pre(r.model)))
    if r.evidence:
        parts.append(details("Evidence: observability verdicts and design certificates", "".join(pre(e) for e in r.evidence)))
    if r.notes:
        parts.append(f"<h{h}>Notes</h{h}><ul>" + "".join(f"<li class='note'>{prose(n)}</li>" for n in r.notes) + "</ul>")
    return section(r.title, parts, id=r.key, level=level, subtitle=sub)


_EXTRA_HEADERS = {"guaranteed_rate": "guaranteed rate ε − K", "gramian_min_eig": "λmin Gramian", "b_hat": "b̂(T)",
                  "gamma_hat": "γ̂(T)", "omega2_hat": "ω̂²(T)", "rms_noise_free": "RMS noise-free",
                  "noise_induced_rms": "RMS due to noise", "order": "order"}


def _extra_columns(r: ExampleResult) -> list[tuple[str, str]]:
    keys = []
    for row in r.table:
        keys += [k for k in row if k not in keys and k not in {c for c, _ in COLUMNS}]
    return [(k, _EXTRA_HEADERS.get(k, k.replace("_", " "))) for k in keys]


def _html(results: Sequence[ExampleResult], failed: Sequence[tuple[str, str]], timings: dict[str, float], seconds: float) -> str:
    nav = "<nav><h3>Examples</h3><ol>" + "".join(
        f"<li><a href='#{html.escape(r.key)}'>{prose(r.title)}</a> — "
        f"<span class='{_tally_class(r)}'>{r.tally}</span></li>"
        for r in results) + "".join(f"<li><span class='fail'>{html.escape(k)} crashed</span></li>" for k, _ in failed) + "</ol></nav>"
    overview = [dict(row, example=r.key) for r in results for row in r.table]
    body = [nav]
    if overview:
        body.append(details("All observers at a glance", table(overview, [("example", "example"), *COLUMNS]), open=True))
    body += [example_section(r, timings[r.key]) for r in results]
    for key, err in failed:
        body.append(section(key, "<p class='fail'>This example crashed:</p>" + pre(err), id=key))
    body.append(bibliography(*(f"{r.title}\n{r.reference}\n{r.summary}\n" + "\n".join(r.notes)
                               + "\n".join(c.text + c.detail for c in r.claims) + "\n".join(r.evidence) for r in results)))
    subtitle = (f"nlobs {__version__} · the papers' examples reproduced · {len(results)} example(s), computed in "
                f"{seconds:.1f} s · Python {platform.python_version()} on {html.escape(platform.machine())}")
    return page("nlobs — the papers' examples", subtitle, body)


register_html_renderer(example_section)   # notebooks show an ExampleResult as its report section
