"""Plots of a Run: states against estimates, error norms on a log scale."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Protocol

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

__all__ = ["plot_run", "style_axes", "log_axis", "LINESTYLES"]

#: One dash pattern per observer (cycled), so that estimates lying on top of each other stay
#: distinguishable: the patterns interleave instead of hiding one another.
LINESTYLES = ((0, (5, 3)), (0, (1, 2)), (0, (8, 3, 1, 3)), (0, (3, 1, 1, 1, 1, 1)), (0, (2, 4)))
#: Font sizes in points (readable at the size the figure is shown: 1 inch = 96 CSS pixels).
#: Samples drawn per line at most (every k-th sample of longer runs).
MAX_POINTS = 2500
FONT = {"tick": 9.0, "label": 10.0, "legend": 9.0, "title": 11.0}


class RunLike(Protocol):
    """What :func:`plot_run` reads of a run; :class:`~nlobs.simulate.Run` has it. A protocol, so that this module does
    not import ``_results.py``, which calls it (``Run.plot``)."""

    @property
    def t(self) -> np.ndarray: ...
    @property
    def state_names(self) -> tuple[str, ...]: ...
    @property
    def observers(self) -> Mapping[str, Any]: ...  # name -> ObserverTrace (xhat, filtered, smoothed)
    @property
    def x(self) -> np.ndarray | None: ...
    @property
    def info(self) -> Mapping[str, Any]: ...
    def error_norm(self, name: str | None = None) -> np.ndarray: ...


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _decade(value: float, _pos: Any = None) -> str:
    """10⁻³ as plain text (no mathtext to typeset: drawing stays fast)."""
    if value <= 0:
        return ""
    k = int(round(np.log10(value)))
    return "1" if k == 0 else "10" + str(k).translate(_SUPERSCRIPT)


def log_axis(ax: Any) -> None:
    """A log-scaled y axis with decade ticks labelled 10ⁿ in plain text."""
    ax.set_yscale("log")
    ax.yaxis.set_major_locator(LogLocator(base=10, numticks=6))
    ax.yaxis.set_major_formatter(FuncFormatter(_decade))
    ax.yaxis.set_minor_formatter(NullFormatter())


def _layout(fig: Figure, rows: int, legend: bool, title: bool) -> None:
    """Margins in inches (constrained layout costs as much as drawing the figure); the left one wide enough for the
    longest tick label (a bias that moves in its fourth decimal is labelled −0.03075) and the y label beside it."""
    w, h = fig.get_size_inches()
    top = 0.12 + (0.32 if legend else 0) + (0.3 if title else 0)
    chars = 5
    for ax in fig.axes:
        if ax.get_yscale() == "linear":
            labels = ax.yaxis.get_major_formatter().format_ticks(ax.get_yticks())
            chars = max([chars, *(len(t) for t in labels)])
    left = min(0.8 + 0.075 * (chars - 5), 0.45 * w)
    fig.subplots_adjust(left=left / w, right=1 - 0.15 / w, bottom=0.5 / h, top=1 - top / h, hspace=0.12 * rows / max(rows, 1))
    fig.align_ylabels(fig.axes)


def style_axes(ax: Any) -> None:
    """Readable ticks and labels and a light grid (major ticks only) on one matplotlib Axes."""
    ax.tick_params(labelsize=FONT["tick"])
    ax.xaxis.label.set_size(FONT["label"])
    ax.yaxis.label.set_size(FONT["label"])
    ax.grid(alpha=0.3, which="major")


def _label(name: str, units: Mapping[str, str]) -> str:
    unit = units.get(name)
    return f"{name} [{unit}]" if unit else name


def plot_run(run: RunLike, path: str | None = None, *, observers: Sequence[str] | None = None, width: float = 6.4,
             title: str | None = None) -> Figure:
    """One panel per state (true state in black, one line per observer; for a smoothed run the
    smoothed estimate and, dotted, the filtered one) and, when the truth is known, a last panel with
    ‖x̂ - x‖ on a log scale. Uses no GUI backend.

    Parameters
    ----------
    run : Run
    path : str, optional
        Save the figure there (the format follows the extension).
    observers : sequence of str, optional
        Observers to draw (default: all).
    width : float
        Figure width in inches (the height follows the number of panels).
    title : str, optional
        A title above the panels.

    Returns
    -------
    matplotlib.figure.Figure
    """
    names = list(run.observers) if observers is None else list(observers)
    k = max(1, -(-run.t.size // MAX_POINTS))  # draw at most MAX_POINTS samples per line (a figure is ~500 px wide)
    t = run.t[::k]
    units: Mapping[str, str] = dict(run.info.get("units") or {})
    n = len(run.state_names)
    rows = n + (1 if run.x is not None and names else 0)
    fig = Figure(figsize=(width, 1.55 * rows + 0.9 + (0.3 if title else 0)))
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    for i, state in enumerate(run.state_names):
        ax = axes[i]
        if run.x is not None and i < run.x.shape[1]:  # recorded truth may lack the estimated parameters
            ax.plot(t, run.x[::k, i], color="k", lw=2.2, alpha=0.35, label="true", zorder=1)
        for j, name in enumerate(names):
            tr = run.observers[name]
            if tr.filtered is not None:  # a smoothed run: the filter's estimate too, thin
                ax.plot(t, tr.filtered[::k, i], color=f"C{j % 10}", lw=0.8, alpha=0.6, ls=":", label=f"{name} (filtered)",
                        zorder=2 + j)
            ax.plot(t, tr.xhat[::k, i], color=f"C{j % 10}", lw=1.3, ls=LINESTYLES[j % len(LINESTYLES)],
                    label=f"{name} (smoothed)" if tr.smoothed else name, zorder=2 + j)
        ax.set_ylabel(_label(state, units))
        style_axes(ax)
    if rows > n:
        ax = axes[-1]
        for j, name in enumerate(names):
            filtered = run.observers[name].filtered
            if filtered is not None:
                ef = np.linalg.norm(filtered[::k, :run.x.shape[1]] - run.x[::k], axis=1)
                ax.plot(t, np.maximum(ef, 1e-16), color=f"C{j % 10}", lw=0.8, alpha=0.6, ls=":")
            e = run.error_norm(name)[::k]
            ax.plot(t, np.maximum(e, 1e-16), color=f"C{j % 10}", lw=1.3, ls=LINESTYLES[j % len(LINESTYLES)], label=name)
        ax.set_ylabel("‖x̂ − x‖")
        log_axis(ax)
        style_axes(ax)
    handles, labels = axes[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 1 - (0.3 if title else 0.02) / fig.get_size_inches()[1]),
                   ncol=min(3, len(labels)), fontsize=FONT["legend"], frameon=False, handlelength=3.0)
    axes[-1].set_xlabel(_label("t", units))
    if title:
        fig.suptitle(title, fontsize=FONT["title"], y=1 - 0.08 / fig.get_size_inches()[1], va="top")
    _layout(fig, rows, bool(handles), bool(title))
    if path is not None:
        fig.savefig(path, dpi=150)
    return fig


def plot_outputs(t: np.ndarray, y: np.ndarray, fitted: np.ndarray, names: Sequence[str], path: str | None = None, *,
                 std: np.ndarray | None = None, label: str = "fitted", width: float = 6.4,
                 title: str | None = None) -> Figure:
    """Recorded outputs (dots) against a model's (a line), one panel per output; with `std`, the band ± 2 std around
    the model's (a filter's one-step predictions ŷ⁻ ± 2σ). NaN samples are left out. Saved to `path` if given."""
    k = max(1, -(-t.size // MAX_POINTS))
    p = len(names)
    fig = Figure(figsize=(width, 1.9 * p + 0.9 + (0.3 if title else 0)))
    axes = fig.subplots(p, 1, sharex=True, squeeze=False)[:, 0]
    for j, name in enumerate(names):
        ax = axes[j]
        if std is not None:
            lo, hi = fitted[::k, j] - 2 * std[::k, j], fitted[::k, j] + 2 * std[::k, j]
            ax.fill_between(t[::k], lo, hi, color="C0", alpha=0.2, lw=0, label=f"{label} ± 2σ")
        ax.plot(t[::k], y[::k, j], ".", color="k", ms=2.0, alpha=0.6, label="recorded", zorder=1)
        ax.plot(t[::k], fitted[::k, j], color="C0", lw=1.2, label=label, zorder=2)
        ax.set_ylabel(name)
        style_axes(ax)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 1 - (0.3 if title else 0.02) / fig.get_size_inches()[1]),
               ncol=len(labels), fontsize=FONT["legend"], frameon=False)
    axes[-1].set_xlabel("t")
    if title:
        fig.suptitle(title, fontsize=FONT["title"], y=1 - 0.08 / fig.get_size_inches()[1], va="top")
    _layout(fig, p, True, bool(title))
    if path is not None:
        fig.savefig(path, dpi=150)
    return fig
