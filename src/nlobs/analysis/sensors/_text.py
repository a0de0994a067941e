"""The text of a :class:`SensorSelection` (what ``nlobs sensors`` prints)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from ...references import cite

__all__ = ["selection_text", "fmt_bound", "set_label"]

#: Above this many unknowns the text shows each set's largest bound instead of one column per unknown.
WIDE = 8


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
    what = ("Minimal sets (every inclusion-minimal set" if s.complete else "Minimum-size sets (" + (
        "proven minimum" if s.proven_minimum else "the minimum is not proven"))
    out.append(f"{what} that makes {', '.join(sel.targets)} locally observable; exact generic rank, "
               f"{cite('sedoglavic2002')}):")
    for m in sel.minimal_sets:
        st = sel.set_of(m)
        out.append(f"  {set_label(m)}  cost {st.cost:g}" + ("" if st.within_budget else "  (over the budget)"))
    out.append(f"  searched: {s.method}; {s.checked} ranks taken, {s.pruned} sets ruled out by the influence graph")
    if s.error_probability > 0:
        out.append(f"  A set reported deficient is wrong with probability at most {s.error_probability:.1e} (two random points; "
                   "a full rank is a proof).")
    return out


def _quality_lines(sel: Any) -> list[str]:
    run = sel.run
    out = [f"Cramér–Rao bounds (σ) of the initial values on the [simulation] run (t in [0, {run['t_final']:g}], "
           f"{run['samples']} samples{'' if run['sample_period'] is None else ' every ' + format(run['sample_period'], 'g')}; "
           f"{cite('krener2009')} for the index: the bound along the worst direction, in units of each unknown's "
           "initial_std, else its size on the run):"]
    wide = len(sel.unknowns) > WIDE
    head = ["set", "cost", "observable", "log det", *(["largest σ"] if wide else sel.unknowns), "unobs. index",
            "listed as"]
    rows = []
    for s in sel.sets:
        if wide:
            worst = max(sel.unknowns, key=lambda u: s.crb[u])
            bounds = [f"{fmt_bound(s.crb[worst])} ({worst})"]
        else:
            bounds = [fmt_bound(s.crb[u]) for u in sel.unknowns]
        rows.append([set_label(s.sensors), f"{s.cost:g}", "yes" if s.observable else "no", fmt_bound(s.log_det),
                     *bounds, fmt_bound(s.unobservability_index), ", ".join(s.roles)])
    out += _table(rows, head)
    if wide:
        out.append(f"  (the bound of each of the {len(sel.unknowns)} unknowns is in --json)")
    out.append(f"Criterion: {sel.criterion}.")
    out.append(f"Ranking: {sel.ranking}.")
    if sel.pareto:
        exact = sel.ranking.startswith("every")
        out.append("Cost–quality Pareto front" + (" (no other set costs as little and scores higher):" if exact else
                                                  " of the sets scored (not proven over every set):"))
        out += [f"  cost {sel.set_of(p).cost:<6g} log det {fmt_bound(sel.set_of(p).log_det):<8} {set_label(p)}"
                for p in sel.pareto]
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
