"""The sensor-selection section of a report and its figure: the Cramér–Rao bound of every unknown, per set
(``nlobs sensors --plot``, ``nlobs report`` on a model with ``[sensors]``)."""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from ..analysis.sensors._text import fmt_bound, set_label
from ..references import cite
from ._html import FIGURE_WIDTH, img, table

__all__ = ["sensors_figure", "sensors_section", "plotted_sets"]

#: Most sets drawn in one figure.
MAX_SETS = 8


def plotted_sets(sel: Any, max_sets: int = MAX_SETS) -> list[Any]:
    """The sets a figure draws: the best one, the minimal ones, then the Pareto front and the whole pool, at most
    `max_sets`."""
    order = [s for s in sel.sets if "best" in s.roles]
    order += [s for s in sel.sets if "minimal" in s.roles]
    order += [s for s in sel.sets if "pareto" in s.roles]
    order += [s for s in sel.sets if "pool" in s.roles]
    out: list[Any] = []
    for s in order:
        if s not in out and s.crb is not None:
            out.append(s)
    return out[:max_sets]


def sensors_figure(sel: Any, *, max_sets: int = MAX_SETS, sets: Sequence[Any] | None = None,
                   errors: Mapping[tuple[str, ...], Mapping[str, float]] | None = None) -> Figure:
    """Grouped bars (log scale): the Cramér–Rao bound σ of each unknown's initial value, one bar per set; an unknown
    the set leaves uninformed is a hatched bar to the top marked ∞. `errors` (``nlobs sensors --run``): per set, the
    RMS error of a smoothed filter's x̂(0), a black dot on its bar."""
    chosen = list(sets) if sets is not None else plotted_sets(sel, max_sets)
    if not chosen:
        raise ValueError("no set has bounds to plot: the model has no [simulation] run (x0)")
    names = list(sel.unknowns)
    fig = Figure(figsize=(min(FIGURE_WIDTH, 2.2 + 0.9 * len(names) * max(1.0, len(chosen) / 3)), 4.2),
                 layout="constrained")
    ax = fig.subplots()
    finite = [v for s in chosen for v in s.crb.values() if math.isfinite(v) and v > 0]
    lo = min(finite) if finite else 1e-3
    hi = max(finite) if finite else 1.0
    top = hi * 30
    width = 0.8 / len(chosen)
    x = np.arange(len(names))
    dots = False
    for j, s in enumerate(chosen):
        vals = np.array([s.crb[n] for n in names], dtype=float)
        inf = ~np.isfinite(vals)
        pos = x - 0.4 + width * (j + 0.5)
        label = set_label(s.sensors) + f" (cost {s.cost:g})" + (" ★" if "best" in s.roles else "")
        ax.bar(pos[~inf], vals[~inf], width * 0.92, color=f"C{j % 10}", label=label)
        if inf.any():
            ax.bar(pos[inf], np.full(inf.sum(), top), width * 0.92, color="none", edgecolor=f"C{j % 10}", hatch="//")
            for p in pos[inf]:
                ax.text(p, top, "∞", ha="center", va="bottom", fontsize=9, color=f"C{j % 10}")
        err = (errors or {}).get(tuple(s.sensors))
        if err:  # only the finite, positive errors are dots (a log axis draws no other); the legend names drawn ones only
            ev = np.array([err.get(n, np.nan) for n in names], dtype=float)
            shown = np.isfinite(ev) & (ev > 0)
            if shown.any():
                ax.plot(pos[shown], ev[shown], "o", color="k", ms=4,
                        label="RMS error of a smoothed EKF's x̂(0)" if not dots else None)
                dots = True
    ax.set_yscale("log")
    ax.set_ylim(lo / 3, top * 3)
    ax.set_xticks(x, names)
    ax.set_ylabel("Cramér–Rao bound σ of the initial value")
    ax.grid(axis="y", alpha=0.3, which="both")
    ax.legend(fontsize="small", ncol=2 if len(chosen) > 4 else 1)
    run = sel.run or {}
    ax.set_title(f"{sel.model}: bounds per set on the [simulation] run ({run.get('samples', '?')} samples)",
                 fontsize="medium")
    return fig


def sensors_section(sel: Any) -> str:
    """The HTML section: the minimal sets, the bounds of every listed set (with the figure), the Pareto front, the
    best set under the budget, and how each was found."""
    esc = html.escape
    body = ["<h2 id='sensors'>What to measure</h2>"]
    body.append(f"<p>{len(sel.pool)} candidate sensors; targets {esc(', '.join(sel.targets))}. Searched: "
                f"{esc(sel.search.method)}; exact generic rank ({esc(cite('sedoglavic2002'))}).</p>")
    if sel.graph.sinks and len(sel.graph.components) > 1:
        body.append("<p class='note'>Sink components of the influence graph: "
                    + esc("; ".join(set_label(c) for c in sel.graph.sinks)) + f": a set that observes every state has a "
                    f"sensor that sees each ({esc(cite('liu2013'))}).</p>")
    if not sel.search.pool_observes:
        body.append("<p class='fail'>No set of these candidates makes the targets locally observable.</p>")
    else:
        what = "Minimal sets" if sel.search.complete else "Minimum-size sets"
        body.append(f"<p>{what}: " + esc(", ".join(set_label(m) for m in sel.minimal_sets)) + "</p>")
    if sel.run is not None:
        rows = [{"set": set_label(s.sensors), "cost": s.cost, "observable": "yes" if s.observable else "no",
                 "log_det": fmt_bound(s.log_det), **{f"crb_{u}": fmt_bound(s.crb[u]) for u in sel.unknowns},
                 "index": fmt_bound(s.unobservability_index), "roles": ", ".join(s.roles)} for s in sel.sets]
        cols = [("set", "set"), ("cost", "cost"), ("observable", "observable"), ("log_det", "log det F"),
                *[(f"crb_{u}", f"σ {u}(0)") for u in sel.unknowns], ("index", "unobservability index"),
                ("roles", "listed as")]
        body.append(table(rows, cols))
        body.append(img(sensors_figure(sel), "Cramér–Rao bounds per set"))
        body.append(f"<p class='note'>Bounds on {esc(sel.run['method'])}.</p>")
        body.append(f"<p class='note'>Criterion: {esc(sel.criterion)}. Ranking: {esc(sel.ranking)}.</p>")
        if sel.best is not None:
            body.append(f"<p>Best{'' if sel.budget is None else f' within the budget {sel.budget:g}'}: "
                        f"<b>{esc(set_label(sel.best.sensors))}</b> (cost {sel.best.cost:g}).</p>")
    for n in sel.notes:
        body.append(f"<p class='note'>{esc(n)}</p>")
    return "".join(body)
