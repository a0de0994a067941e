"""`nlobs demo`: run every paper example, write an HTML report and print a summary table."""

from __future__ import annotations

import html
import platform
import sys
import time
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from .. import __version__
from ..analysis import analyze
from ..examples import EXAMPLES, ExampleResult
from ..simulate import CONVERGENCE_RULE
from ._html import fmt, img, page, table

__all__ = ["run_demo", "DemoOutcome"]

COLUMNS = [("run", "run"), ("observer", "observer"), ("convergence_time", "convergence time"),
           ("rms_error", "RMS error (last 20 %)"), ("final_error", "final error")]


@dataclass(frozen=True)
class DemoOutcome:
    results: Sequence[ExampleResult]
    failed: Sequence[tuple[str, str]]  # (key, error text) of examples that crashed
    report: Path
    seconds: float

    @property
    def exit_code(self) -> int:
        return 1 if self.failed else 0


def run_demo(out_dir: str | Path = "nlobs-report", *, only: Sequence[str] | None = None, progress: bool = True,
             stream: TextIO | None = None) -> DemoOutcome:
    """Run the registered paper examples (all, or `only` these keys), write ``out_dir/index.html``,
    print a summary to `stream`, and return what happened."""
    stream = stream or sys.stdout
    examples = sorted(EXAMPLES.values(), key=lambda e: e.order)
    if only:
        unknown = [k for k in only if k not in EXAMPLES]
        if unknown:
            raise KeyError(f"no example {unknown[0]!r}; available: {', '.join(e.key for e in examples)}")
        examples = [e for e in examples if e.key in only]
    t0 = time.perf_counter()
    results, failed, timings = [], [], {}
    for i, ex in enumerate(examples):
        if progress:
            print(f"[{i + 1}/{len(examples)}] {ex.title} ...", file=sys.stderr, flush=True)
        t1 = time.perf_counter()
        try:
            results.append(ex.run())
        except Exception as e:  # noqa: BLE001 - one broken example must not hide the others
            failed.append((ex.key, f"{type(e).__name__}: {e}\n{traceback.format_exc()}"))
        timings[ex.key] = time.perf_counter() - t1
    seconds = time.perf_counter() - t0
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    report = out / "index.html"
    report.write_text(_html(results, failed, timings, seconds), encoding="utf-8")
    _print_summary(results, failed, stream, report, seconds)
    return DemoOutcome(results, failed, report, seconds)


def _print_summary(results: Sequence[ExampleResult], failed: Sequence[tuple[str, str]], stream: TextIO, report: Path,
                   seconds: float) -> None:
    w = stream.write
    head = f"{'example':<14} {'run':<14} {'observer':<28} {'conv. time':>10} {'RMS error':>10} {'final err':>10}"
    w(head + "\n" + "-" * len(head) + "\n")
    for r in results:
        for row in r.table:
            w(f"{r.key:<14} {str(row['run'])[:14]:<14} {str(row['observer'])[:28]:<28} {fmt(row['convergence_time']):>10} "
              f"{fmt(row['rms_error']):>10} {fmt(row['final_error']):>10}\n")
    w(f"conv. time: the time after which the error stays within its band, max(2 % of the initial error, 2 × the "
      f"steady-state error), at most 20 % of the initial error (— : not within the run); see the report\n\n")
    for r in results:
        n_ok = sum(c.holds for c in r.claims)
        w(f"{r.key:<14} claims {n_ok}/{len(r.claims)} hold" + ("" if r.ok else "  <-- see the report") + "\n")
        for c in r.claims:
            if not c.holds:
                w(f"    FAILS: {c.text} ({c.detail})\n")
    for key, err in failed:
        w(f"{key:<14} CRASHED: {err.splitlines()[0]}\n")
    w(f"\nreport: {report.resolve()}  ({seconds:.1f} s)\n")


def _convergence_note(r: ExampleResult) -> str:
    """What the convergence-time column of an example means (its own rule, or the rule of nlobs.simulate)."""
    if r.convergence_rule:
        return r.convergence_rule
    return f"{CONVERGENCE_RULE[0].upper() + CONVERGENCE_RULE[1:]} (— : not within the run). RMS over the last 20 % of the run."


def _section(r: ExampleResult, seconds: float) -> str:
    parts = [f"<h2 id='{html.escape(r.key)}'>{html.escape(r.title)}</h2>",
             f"<p class='ref'>{html.escape(r.reference)} · ran in {seconds:.1f} s</p>",
             f"<p>{html.escape(r.summary)}</p>", "<h3>Claims checked</h3><ul class='claims'>"]
    for c in r.claims:
        cls, word = ("ok", "holds") if c.holds else ("fail", "FAILS")
        parts.append(f"<li><span class='{cls}'>{word}</span> — {html.escape(c.text)}"
                     + (f" <span class='note'>({html.escape(c.detail)})</span>" if c.detail else "") + "</li>")
    parts.append("</ul>")
    if r.systems:
        parts.append("<h3>Observability (nlobs.analyze)</h3><ul>")
        details = []
        for label, system in r.systems.items():
            try:
                rep = analyze(system)
                d = rep.to_dict()
                verdict = (f"observable: generic rank {d['rank']} = {d['n_states']}" if d["observable"] else
                           f"not observable: generic rank {d['rank']} < {d['n_states']}; observable states: "
                           f"{', '.join(d['observable_states']) or 'none'}")
                cls = "ok" if d["observable"] else "fail"
                if d.get("globally_observable") is False:
                    verdict += "; locally only: a symmetry makes it globally unobservable"
                    cls = "warn"
                parts.append(f"<li>{html.escape(label)}: <span class='{cls}'>{html.escape(verdict)}</span></li>")
                details.append(f"<pre>{html.escape(label)}\n{html.escape(str(rep))}</pre>")
            except Exception as e:  # noqa: BLE001 - an analysis that cannot run is reported, not fatal
                parts.append(f"<li>{html.escape(label)}: <span class='fail'>analysis failed: {html.escape(str(e))}</span></li>")
        parts.append("</ul>")
        if details:
            parts.append("<details><summary>Observability reports</summary>" + "".join(details) + "</details>")
    if r.table:
        parts.append("<h3>Convergence and accuracy</h3>" + table(r.table, COLUMNS)
                     + f"<p class='note'>{html.escape(_convergence_note(r))}</p>")
    if r.runs:
        parts.append("<div class='runs'>" + "".join(
            f"<figure><figcaption>{html.escape(label)}</figcaption>{img(run.plot(), f'{r.key} {label}')}</figure>"
            for label, run in r.runs.items()) + "</div>")
    for caption, fig in r.figures.items():
        parts.append(f"<h3>{html.escape(caption)}</h3>" + img(fig, caption))
    parts.append(f"<details><summary>Model</summary><pre>{html.escape(r.model)}</pre></details>")
    if r.evidence:
        parts.append("<details><summary>Evidence: observability verdicts and design certificates</summary>"
                     + "".join(f"<pre>{html.escape(e)}</pre>" for e in r.evidence) + "</details>")
    if r.notes:
        parts.append("<h3>Notes</h3><ul>" + "".join(f"<li class='note'>{html.escape(n)}</li>" for n in r.notes) + "</ul>")
    return "".join(parts)


def _html(results: Sequence[ExampleResult], failed: Sequence[tuple[str, str]], timings: dict[str, float], seconds: float) -> str:
    nav = "<nav><h3>Examples</h3><ul>" + "".join(
        f"<li><a href='#{html.escape(r.key)}'>{html.escape(r.title)}</a> — "
        f"<span class='{'ok' if r.ok else 'fail'}'>{sum(c.holds for c in r.claims)}/{len(r.claims)} claims</span></li>"
        for r in results) + "".join(f"<li><span class='fail'>{html.escape(k)} crashed</span></li>" for k, _ in failed) + "</ul></nav>"
    overview = [dict(row, example=r.key) for r in results for row in r.table]
    body = [nav]
    if overview:
        body.append("<details open><summary>All observers at a glance</summary>"
                    + table(overview, [("example", "example"), *COLUMNS]) + "</details>")
    body += [_section(r, timings[r.key]) for r in results]
    for key, err in failed:
        body.append(f"<h2>{html.escape(key)}</h2><p class='fail'>This example crashed:</p><pre>{html.escape(err)}</pre>")
    subtitle = (f"nlobs {__version__} · the papers' examples reproduced · {len(results)} example(s) in {seconds:.1f} s · "
                f"Python {platform.python_version()} on {html.escape(platform.machine())}")
    return page("nlobs — the papers' examples", subtitle, body)
