"""Plots of a Run: states against estimates, error norms on a log scale."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

if TYPE_CHECKING:
    from ._results import Run

__all__ = ["plot_run"]


def plot_run(run: Run, path: str | None = None, *, observers: Sequence[str] | None = None) -> Figure:
    """One panel per state (true state in black, one line per observer) and, when the truth is
    known, a last panel with ‖x̂ - x‖ on a log scale. Uses no GUI backend."""
    names = list(run.observers) if observers is None else list(observers)
    n = len(run.state_names)
    rows = n + (1 if run.x is not None and names else 0)
    fig = Figure(figsize=(8, 1.9 * rows + 0.6), layout="constrained")
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    colors = [f"C{i}" for i in range(10)]
    for i, state in enumerate(run.state_names):
        ax = axes[i]
        if run.x is not None and i < run.x.shape[1]:  # recorded truth may lack the estimated parameters
            ax.plot(run.t, run.x[:, i], color="k", lw=1.6, label="true")
        for j, name in enumerate(names):
            ax.plot(run.t, run.observers[name].xhat[:, i], color=colors[j % 10], lw=1.1, ls="--", label=name)
        ax.set_ylabel(state)
        ax.grid(alpha=0.3)
    if rows > n:
        ax = axes[-1]
        for j, name in enumerate(names):
            e = run.error_norm(name)
            ax.semilogy(run.t, np.maximum(e, 1e-16), color=colors[j % 10], lw=1.1, label=name)
        ax.set_ylabel("‖x̂ − x‖")
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(loc="best", fontsize="small", ncol=min(4, len(names) + 1))
    axes[-1].set_xlabel("t")
    fig.suptitle(run.model)
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig


