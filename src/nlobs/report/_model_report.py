"""``nlobs report``: the self-contained HTML report of one model — observability verdicts, every observer kind
(applies / why not), the runs side by side with plots, and the parameter estimates."""

from __future__ import annotations

import html
import platform
from dataclasses import replace
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from .._version import __version__
from ..advise import Advice
from ..advise._advice import WHAT_TO_TRY
from ..references import bibliography
from ._html import equations, img, page, table

__all__ = ["model_report", "write_model_report", "parameter_estimates", "kind_rows"]

#: How many of the best-ranked candidates get their own states-vs-estimates plot.
TOP = 3


def _esc(text: Any) -> str:
    return html.escape(str(text))


def parameter_estimates(adv: Advice) -> list[dict[str, Any]]:
    """One row per (candidate, estimated parameter): final estimate, ±2σ where the observer carries a covariance
    (:meth:`nlobs.Run.parameters`), and the true value of the simulation (None on a recording)."""
    if adv.scores is None or not adv.system.estimated_params:
        return []
    rows = []
    for s in adv.scores:
        for k, v in s.parameters.items():
            est, std, true = v.get("estimate"), v.get("std"), v.get("true")
            rows.append({"observer": s.kind, "parameter": k, "estimate": est, "pm2sigma": None if std is None else 2 * std,
                         "true": true, "error": None if true is None or est is None else est - true})
    return rows


def _tables_of(system: Any) -> list[Any]:
    """The lookup tables the model's equations call (each once, in the order met)."""
    from ..model._tables import table_calls

    seen: dict[str, Any] = {}
    for c in table_calls([*system.f, *system.h]):
        seen.setdefault(c.table.name, (c.table, tuple(str(a) for a in c.args)))
    return list(seen.values())


def _table_section(tb: Any, args: Sequence[str], adv: Advice) -> str:
    """A table's breakpoints and its interpolation (1-D: the curve; 2-D: filled contours), and how it is used."""
    fig = Figure(figsize=(6.4, 3.2), layout="constrained")
    ax = fig.subplots()
    units = dict(adv.text.units) if adv.text is not None else {}

    def label(i: int) -> str:
        name = args[i] if i < len(args) else ("first", "second")[i] + " argument"
        return f"{name} [{units[name]}]" if name in units else name

    if tb.dims == 1:
        x = np.asarray(tb.x, dtype=float)
        lo, hi = x[0], x[-1]
        pad = 0.05 * (hi - lo)
        xs = np.linspace(lo - pad, hi + pad, 600)
        ax.plot(xs, tb(xs), color="C0", lw=1.3, label=f"{tb.method} interpolation ({tb.outside} outside)")
        ax.plot(x, tb.values, "o", ms=2.5, color="k", label=f"{x.size} breakpoints")
        ax.axvspan(lo - pad, lo, color="0.9", lw=0)
        ax.axvspan(hi, hi + pad, color="0.9", lw=0)
        ax.set_xlabel(label(0))
        ax.legend(fontsize="small")
    else:
        x, z = np.asarray(tb.x, dtype=float), np.asarray(tb.z, dtype=float)
        X, Z = np.meshgrid(np.linspace(x[0], x[-1], 120), np.linspace(z[0], z[-1], 120), indexing="ij")
        V = tb(X.ravel(), Z.ravel()).reshape(X.shape)
        cs = ax.contourf(X, Z, V, levels=20, cmap="viridis")
        fig.colorbar(cs, ax=ax)
        ax.plot(*np.meshgrid(x, z, indexing="ij"), "k.", ms=1.5)
        ax.set_xlabel(label(0))
        ax.set_ylabel(label(1))
    ax.set_title(f"{tb.name}", fontsize="medium")
    ax.grid(alpha=0.3)
    where = ", ".join(f"[{a:g}, {b:g}]" for a, b in tb.ranges)
    note = (f"<p class='note'>{_esc(tb.name)}: {tb.dims}-D, {tb.values.size} values on {_esc(where)}, {_esc(tb.method)} "
            f"(CasADi interpolant: exact derivatives in the filters and the C code), {_esc(tb.outside)} outside the "
            "breakpoints (shaded); the analysis treats it as a generic smooth function.</p>")
    return img(fig, f"lookup table {tb.name}") + note


def _errors_figure(adv: Advice, kinds: Sequence[str]) -> Figure:
    """‖x̂ − x‖ of every candidate on a log scale; on recorded data (no true state), ‖y − h(x̂)‖."""
    from ..advise._rank import residuals

    run = adv.run
    truth = run.x is not None
    fig = Figure(figsize=(8, 3.6), layout="constrained")
    ax = fig.subplots()
    for j, k in enumerate(kinds):
        e = run.error_norm(k) if truth else np.linalg.norm(residuals(run, k, adv.system)[0], axis=1)
        ax.semilogy(run.t, np.maximum(e, 1e-16), lw=1.1, color=f"C{j % 10}", ls="-" if j < 10 else "--", label=k)
    t_unit = dict(adv.text.units).get("t") if adv.text is not None else None
    ax.set_xlabel(f"t [{t_unit}]" if t_unit else "t")
    ax.set_ylabel("‖x̂ − x‖" if truth else "‖innovation‖")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize="small", ncol=3)
    ax.set_title("estimation error of every candidate that ran (log scale)" if truth else
                 "innovations y − h(x̂⁻) of every candidate (recorded data: no true state)")
    return fig


def model_report(adv: Advice, *, source: str = "", sensors: Any = None) -> str:
    """The HTML text of the report of one :class:`~nlobs.advise.Advice` (with or without a run); with `sensors` (a
    :class:`~nlobs.analysis.SensorSelection`), its section "What to measure" after the observability verdicts."""
    rep = adv.observability
    body: list[str] = []
    cited_text: list[str] = [adv.description]
    if adv.description:
        body.append(f"<p>{_esc(adv.description)}</p>")
    # -- observability
    verdict = "observable" if rep.observable else "NOT observable"
    cls = "ok" if rep.observable and not rep.symmetries else ("warn" if rep.observable else "fail")
    body.append("<h2 id='observability'>Observability</h2>")
    body.append(f"<p>Structural verdict (generic rank {rep.rank} of {len(rep.unknowns)} unknowns): "
                f"<span class='{cls}'>{verdict}</span>. Observable: {_esc(', '.join(rep.observable_states) or 'none')}"
                + (f"; identifiable: {_esc(', '.join(rep.identifiable_params) or 'none')}" if rep.unknown_params else "") + ".</p>")
    for b in adv.blockers:
        body.append(f"<p class='fail'>{_esc(b)}</p>")
    if adv.notes:
        body.append("<ul>" + "".join(f"<li class='note'>{_esc(n)}</li>" for n in adv.notes) + "</ul>")
        cited_text += list(adv.notes)
    if adv.forms:
        text_of = adv.text.refer if adv.text is not None else str
        body.append("<h3>Observer forms</h3><ul>" + "".join(f"<li>{_esc(text_of(f))}</li>" for f in adv.forms) + "</ul>")
        cited_text += list(adv.forms)
    body.append(f"<details><summary>Observability report</summary><pre>{_esc(rep)}</pre></details>")
    cited_text.append(str(rep))
    if sensors is not None:   # -- what to measure
        from ._sensors import sensors_section

        body.append(sensors_section(sensors))
        cited_text.append(str(sensors))
    # -- candidates
    counts = {s: sum(c.status == s for c in adv.candidates) for s in ("applies", "fails", "needs input", "not tuned")}
    body.append("<h2 id='candidates'>Observer kinds</h2>")
    body.append("<p>" + ", ".join(f"{v} {k}" for k, v in counts.items() if v) + ". Each kind was tried with an automatic "
                "tuning; the options column is what to paste into <code>[observers.NAME]</code>.</p>")
    rows = kind_rows(adv)
    cited_text += [text for r in rows for text in (r["why"], r["reference"])]
    body.append(_status_table(rows))
    designs = [c for c in adv.candidates if c.design is not None]
    if designs:
        body.append("<details><summary>Design certificates</summary>"
                    + "".join(f"<pre>{_esc(c.design)}</pre>" for c in designs) + "</details>")
        cited_text += [c.design.certificate.reference for c in designs]
    # -- runs
    if adv.scores is not None:
        body.append(f"<h2 id='runs'>Comparison run</h2><p class='ref'>{_esc(adv.scenario)}</p>")
        srows = []
        rank = 0
        for s in adv.scores:
            rank += s.eligible
            srows.append({"rank": rank if s.eligible else None, "kind": s.kind + (" (yours)" if s.own else ""),
                          "normalised": s.normalised_rms,
                          "rms_error": s.rms_error, "convergence_time": s.convergence_time, "final_error": s.final_error,
                          "status": s.status + (f": {s.detail}" if s.detail else "")})
        body.append(table(srows, [("rank", "rank"), ("kind", "observer"),
                                  ("normalised", "relative RMS error (each state / its range)"),
                                  ("rms_error", "RMS error (last 20 %)"), ("convergence_time", "convergence time"),
                                  ("final_error", "final error"), ("status", "status")]))
        body.append("<p class='note'>Ranked by the RMS error over the last 20 % of the run with each state divided by its "
                    "range on the run, at least the offset the run resolves (a state that does not move: that offset or "
                    "its initial uncertainty), so that no state's units decide alone; errors within a factor 1.25 of each "
                    "other are ordered by convergence time (— : never within the run). A run that ends worse than it "
                    "started, or leaves a constant (a bias, an unknown parameter) unsettled, gets no rank and comes after "
                    "those that converged. Rows marked (yours) are the model file's own [observers.NAME]. A kind whose "
                    "auto-tuned design blew up is listed "
                    "above as not applying, with the time.</p>")
        if adv.best is None and any(s.status == "ok" for s in adv.scores):
            body.append("<p class='warn'><b>No observer converged on this run</b> (each ended worse than it started or "
                        "left a constant state or parameter unsettled), so none is recommended. Try: "
                        f"{_esc(WHAT_TO_TRY)}.</p>")
        ok = [s.kind for s in adv.scores if s.status == "ok"]
        run = adv.run
        if run is not None and adv.text is not None and adv.text.units:
            run = replace(run, info={**run.info, "units": dict(adv.text.units)})   # the file's [units] on the axes
        if run is not None and ok:
            body.append(img(_errors_figure(adv, ok), "error norms"))
            figs = []
            for k in ok[:TOP]:
                fig = run.plot(observers=[k])
                figs.append(f"<figure><figcaption>#{ok.index(k) + 1} {_esc(k)}</figcaption>{img(fig, k)}</figure>")
            body.append("<div class='runs'>" + "".join(figs) + "</div>")
        prow = parameter_estimates(adv)
        if prow:
            body.append("<h3>Parameter estimates</h3>" + table(prow, [("observer", "observer"), ("parameter", "parameter"),
                        ("estimate", "final estimate"), ("pm2sigma", "± 2σ"), ("true", "true value"), ("error", "error")]))
            body.append("<p class='note'>± 2σ from the observer's covariance, where it carries one (EKF, UKF, Kalman–Bucy); "
                        "the true value is the simulation's.</p>")
    # -- model and bibliography
    body.append("<h2 id='model'>Model</h2>" + equations(adv.system))
    if adv.text is not None:
        written = [{"row": k, "as written": v} for k, v in (*adv.text.rows, *adv.text.definitions)]
        body.append("<details><summary>As written in the model file (definitions last)</summary>"
                    + table(written, [("row", "equation / definition"), ("as written", "expression")]) + "</details>")
        if adv.text.units:
            body.append("<p class='note'>units: " + ", ".join(f"{_esc(k)} [{_esc(v)}]" for k, v in adv.text.units) + "</p>")
    tables = _tables_of(adv.system)
    if tables:
        body.append("<h3 id='tables'>Lookup tables</h3>" + "".join(_table_section(tb, args, adv) for tb, args in tables))
    if source:
        body.append(f"<p class='ref'>source: {_esc(source)}</p>")
    refs = bibliography(*cited_text)
    if refs:
        body.append("<h2 id='references'>References</h2><ol>" + "".join(f"<li>{_esc(r)}</li>" for r in refs) + "</ol>")
    nav = ("<nav><ul><li><a href='#observability'>Observability</a></li>"
           + ("<li><a href='#sensors'>What to measure</a></li>" if sensors is not None else "")
           + "<li><a href='#candidates'>Observer kinds</a></li>"
           + ("<li><a href='#runs'>Comparison run</a></li>" if adv.scores is not None else "")
           + "<li><a href='#model'>Model</a></li></ul></nav>")
    subtitle = (f"nlobs {__version__} · {_esc(adv.model)} · {len(adv.applicable)} of {len(adv.candidates)} observer kinds apply"
                + (f" · best: {_esc(adv.best.kind)}" if adv.best is not None else
                   " · no observer converged on the run: none is recommended" if adv.ranking else "")
                + f" · {adv.seconds:.1f} s · Python "
                f"{platform.python_version()}")
    return page(f"nlobs — observers for {adv.model}", subtitle, [nav, *body])


def kind_rows(adv: Advice) -> list[dict[str, Any]]:
    """The rows of the report's table of observer kinds: one per kind that applies, or that fails (or needs input) for a
    reason of its own, in the registry's order; then one row per reason shared by several kinds (every continuous-time
    kind on a map, an unobservable state that blocks every full-state observer), naming them."""
    refer = adv.text.refer if adv.text is not None else (lambda text: text)
    shared: dict[tuple[str, str], list[str]] = {}
    for c in adv.candidates:
        if c.status != "applies":
            shared.setdefault((c.status, c.why), []).append(c.kind)
    rows, grouped = [], []
    for c in adv.candidates:
        kinds = shared.get((c.status, c.why), [c.kind])
        if len(kinds) == 1:
            rows.append({"kind": c.kind, "status": c.status, "why": refer(c.why), "reference": c.reference})
        elif kinds[0] == c.kind:
            grouped.append({"kind": f"{len(kinds)} kinds: {', '.join(kinds)}", "status": c.status, "why": refer(c.why),
                            "reference": ""})
    return rows + grouped


def _status_table(rows: Sequence[dict[str, Any]]) -> str:
    css = {"applies": "ok", "fails": "fail", "needs input": "warn", "not tuned": "warn"}
    head = "<tr><th>kind</th><th>status</th><th>why</th><th>reference</th></tr>"
    body = "".join(f"<tr><td class=l>{_esc(r['kind'])}</td><td class=l><span class='{css.get(r['status'], '')}'>"
                   f"{_esc(r['status'])}</span></td><td class=l>{_esc(r['why'])}</td><td class=l>{_esc(r['reference'])}</td></tr>"
                   for r in rows)
    return f"<table><thead>{head}</thead><tbody>{body}</tbody></table>"


def write_model_report(adv: Advice, out_dir: str | Path = "nlobs-report", *, source: str = "", sensors: Any = None) -> Path:
    """Write ``out_dir/index.html`` (self-contained: plots embedded) and return its path; `sensors` as for
    :func:`model_report`."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "index.html"
    path.write_text(model_report(adv, source=source, sensors=sensors), encoding="utf-8")
    return path

