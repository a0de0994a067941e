"""The text of a :class:`SensorSelection` (what ``nlobs sensors`` prints)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from ...references import cite

__all__ = ["selection_text", "fmt_bound", "set_label"]


def fmt_bound(v: float | None) -> str:
    """A bound for a table: 4 significant digits, ∞ when the run does not inform it."""
    if v is None:
        return "—"
    if not math.isfinite(v):
        return "∞" if v > 0 else "−∞"
    return f"{v:.4g}"


def set_label(sensors: Sequence[str]) -> str:
    """``{A, B}``."""
    return "{" + ", ".join(sensors) + "}"


def _table(rows: list[list[str]], head: list[str]) -> list[str]:
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]
    out = ["  " + "  ".join(h.ljust(w) for h, w in zip(head, widths)).rstrip()]
    out += ["  " + "  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
    return out


def _pool_lines(sel: Any) -> list[str]:
    names = sel.graph.unknowns
    rows = []
    for c, mask in zip(sel.pool, sel.graph.seen):
        seen = [n for i, n in enumerate(names) if mask >> i & 1]
        rows.append([c.name, c.text if len(c.text) <= 30 else c.text[:29] + "…", fmt_bound(c.noise), f"{c.cost:g}",
                     ", ".join(seen) if len(seen) < len(names) else "all", c.noise_source])
    return _table(rows, ["sensor", "measures", "noise σ", "cost", "can see (influence graph)", "noise from"])


def _structural_lines(sel: Any) -> list[str]:
    s = sel.search
    out = []
    if len(sel.graph.components) > 1 or len(sel.graph.sinks[0]) < len(sel.graph.unknowns):
        sinks = "; ".join(set_label(c) for c in sel.graph.sinks)
        out.append(f"Sink components of the influence graph: {sinks} — a set that observes every state has a sensor that "
                   f"sees each ({cite('liu2013')}).")
    if not s.pool_observes:
        out.append(f"No set of these candidates makes {', '.join(sel.targets)} locally observable: the whole pool does not "
                   f"(exact generic rank; {cite('sedoglavic2002')}). Add candidates.")
        return out
    what = "every inclusion-minimal set" if s.complete else ("the minimum-size sets" if s.proven_minimum else "a set found greedily")
    out.append(f"Sets that make {', '.join(sel.targets)} locally observable — {what} ({s.method}; {s.checked} rank checks, "
               f"{s.pruned} sets ruled out by the graph):")
    for m in sel.minimal_sets:
        st = sel.set_of(m)
        out.append(f"  {set_label(m)}  cost {st.cost:g}" + ("" if st.within_budget else "  (over the budget)"))
    if s.error_probability > 0:
        out.append(f"  A set reported deficient is wrong with probability at most {s.error_probability:.1e} (two random points; "
                   "a full rank is a proof).")
    return out


def _quality_lines(sel: Any) -> list[str]:
    run = sel.run
    out = [f"Cramér–Rao bounds (σ) of the initial values on the [simulation] run (t in [0, {run['t_final']:g}], "
           f"{run['samples']} samples{'' if run['sample_period'] is None else ' every ' + format(run['sample_period'], 'g')}; "
           f"{cite('krener2009')} for the index):"]
    head = ["set", "cost", "observable", "log det", *sel.unknowns, "unobs. index", "listed as"]
    rows = []
    for s in sel.sets:
        rows.append([set_label(s.sensors), f"{s.cost:g}", "yes" if s.observable else "no", fmt_bound(s.log_det),
                     *[fmt_bound(s.crb[u]) for u in sel.unknowns], fmt_bound(s.unobservability_index), ", ".join(s.roles)])
    out += _table(rows, head)
    out.append(f"Criterion: {sel.criterion}.")
    out.append(f"Ranking: {sel.ranking}.")
    if sel.pareto:
        out.append("Cost–quality Pareto front: " + "  →  ".join(
            f"{set_label(p)} (cost {sel.set_of(p).cost:g}, log det {fmt_bound(sel.set_of(p).log_det)})" for p in sel.pareto))
    if sel.best is not None:
        within = "" if sel.budget is None else f" within the budget {sel.budget:g}"
        out.append(f"Best{within}: {set_label(sel.best.sensors)} (cost {sel.best.cost:g}, log det {fmt_bound(sel.best.log_det)}).")
    elif sel.budget is not None:
        out.append(f"No set within the budget {sel.budget:g} makes the targets' bounds finite on the run.")
    return out


def selection_text(sel: Any) -> str:
    """The report: pool, structural verdicts, bounds per set, criterion, Pareto front, best set, notes."""
    out = [f"{sel.model}: sensor selection among {len(sel.pool)} candidates; targets: {', '.join(sel.targets)}"]
    out += _pool_lines(sel)
    out += _structural_lines(sel)
    if sel.run is not None:
        out += _quality_lines(sel)
    for n in sel.notes:
        out.append(f"  note: {n}")
    out.append(f"  ({sel.seconds:.2f} s)")
    return "\n".join(out)
