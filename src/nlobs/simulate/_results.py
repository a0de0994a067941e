"""The result of a simulation or of an estimation on recorded data."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._display import MISSING, Column, SummaryTable, fmt_number, short_repr
from ._metrics import Metrics, error_metrics

__all__ = ["ObserverTrace", "Run"]


@dataclass(frozen=True, eq=False)
class ObserverTrace:
    """One observer's signals in a :class:`Run` (time on the first axis).

    Attributes
    ----------
    name, method : str
    z_names : tuple of str
    z : numpy.ndarray of shape (N, n_z)
        Internal state at each time (after the sample-time update, for sampled observers).
    xhat : numpy.ndarray of shape (N, n)
        The estimate.
    """

    name: str
    method: str
    z_names: tuple[str, ...]
    z: np.ndarray
    xhat: np.ndarray
    xhat_prior: np.ndarray | None = None  #: the initial estimate before any measurement (sets the default tolerance)

    def __repr__(self) -> str:
        return short_repr(self, {"name": self.name, "method": self.method, "z": self.z, "xhat": self.xhat})


@dataclass(frozen=True, eq=False)
class Run:
    """Time, true states (when known), inputs, measurements and every observer's estimate.

    All arrays have time on the first axis; signals are labelled by the model's own names.
    """

    model: str
    t: np.ndarray
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    u: np.ndarray
    y: np.ndarray
    observers: Mapping[str, ObserverTrace]
    x: np.ndarray | None = None
    y_true: np.ndarray | None = None
    info: Mapping[str, Any] = field(default_factory=dict)

    # -- errors and metrics -------------------------------------------------------------
    def _trace(self, name: str | None) -> ObserverTrace:
        if name is None:
            if len(self.observers) != 1:
                raise KeyError(f"this run has {len(self.observers)} observers; name one of: {', '.join(self.observers)}")
            return next(iter(self.observers.values()))
        if name not in self.observers:
            raise KeyError(f"no observer named {name!r} in this run; observers: {', '.join(self.observers) or '(none)'}")
        return self.observers[name]

    def error(self, name: str | None = None) -> np.ndarray:
        """x̂ - x, shape (N, n). Needs the true state."""
        if self.x is None:
            raise ValueError("this run has no true state (recorded data without states): errors cannot be computed")
        return self._trace(name).xhat - self.x

    def error_norm(self, name: str | None = None) -> np.ndarray:
        """‖x̂(t) - x(t)‖₂ at each time."""
        return np.linalg.norm(self.error(name), axis=1)

    def metrics(self, name: str | None = None, *, tol: float | None = None, tail: float = 0.2) -> Metrics:
        """Convergence time, RMS and peak errors of one observer (see :class:`Metrics`).

        The default tolerance is 2 % of the initial error before any measurement,
        ‖x̂(0⁻) − x(0)‖ (a settling criterion that filters updating at t = 0 cannot game).
        """
        trace = self._trace(name)
        if tol is None and trace.xhat_prior is not None and self.x is not None:
            e0 = float(np.linalg.norm(trace.xhat_prior - self.x[0]))
            tol = 0.02 * e0 if e0 > 0 else None
        return error_metrics(self.t, self.error_norm(name), tol=tol, tail=tail)

    def noise_gain(self, name: str | None = None, *, tail: float = 0.2) -> float:
        """RMS estimation error over the last `tail` of the run divided by the RMS of the
        measurement noise y − y_true over the same window (SPEC M5). Needs a noisy simulation."""
        if self.y_true is None or self.x is None:
            raise ValueError("noise_gain needs a simulated run (true states and noise-free outputs)")
        sel = self.t >= self.t[-1] - tail * (self.t[-1] - self.t[0])
        noise = self.y[sel] - self.y_true[sel]
        noise_rms = float(np.sqrt(np.mean(np.sum(noise**2, axis=1))))
        if noise_rms == 0:
            raise ValueError("noise_gain: this run has no measurement noise")
        return float(np.sqrt(np.mean(self.error_norm(name)[sel] ** 2)) / noise_rms)

    def summary(self, *, tol: float | None = None) -> SummaryTable:
        """Every observer's metrics as a table: ``print()`` it, show it in a notebook, or
        ``.to_pandas()`` it. Without a true state (recorded data) the table gives the final estimates.

        Parameters
        ----------
        tol : float, optional
            Convergence tolerance (default: 2 % of each observer's initial error).
        """
        title = f"{self.model}: t in [{self.t[0]:g}, {self.t[-1]:g}], {len(self.t)} samples"
        name = Column("observer", "observer", str, numeric=False)
        if self.x is None:
            cols = [name] + [Column(s, s, lambda v: fmt_number(v, 6)) for s in self.state_names]
            rows = [{"observer": n, **dict(zip(self.state_names, tr.xhat[-1].tolist()))} for n, tr in self.observers.items()]
            return SummaryTable(title + " (no true state: final estimates)", cols, rows)
        cols = [name, Column("final_error", "final err"), Column("rms_error", "RMS (last 20%)"),
                Column("peak_error", "peak err"), Column("convergence_time", "conv. time")]
        rows = [{"observer": n, **self.metrics(n, tol=tol).to_dict()} for n in self.observers]
        return SummaryTable(title, cols, rows, ("conv. time: first time after which the error stays within the tolerance; "
                                                f"{MISSING}: not within the run",))

    def __repr__(self) -> str:
        return short_repr(self, {"model": self.model, "t": (float(self.t[0]), float(self.t[-1])), "samples": int(self.t.size),
                                 "states": self.state_names, "observers": tuple(self.observers),
                                 "true_state": self.x is not None})

    def _repr_html_(self) -> str:
        return self.summary()._repr_html_()

    # -- export -------------------------------------------------------------------------
    def to_numpy(self) -> dict[str, np.ndarray]:
        """Every signal as a NumPy array, keyed ``t``, ``x``, ``u``, ``y``, ``y_true``, ``xhat[NAME]``, ``z[NAME]``."""
        out = {"t": self.t, "u": self.u, "y": self.y}
        if self.x is not None:
            out["x"] = self.x
        if self.y_true is not None:
            out["y_true"] = self.y_true
        for name, tr in self.observers.items():
            out[f"xhat[{name}]"] = tr.xhat
            out[f"z[{name}]"] = tr.z
        return out

    def to_pandas(self) -> Any:
        """A DataFrame indexed by time: ``x1 ...`` (true states), inputs, measured outputs,
        ``<output>_true``, then ``<observer>.<state>`` estimates and ``<observer>.error``."""
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("to_pandas needs pandas: pip install 'nlobs[pandas]'") from e
        cols: dict[str, np.ndarray] = {}
        if self.x is not None:
            cols.update({n: self.x[:, i] for i, n in enumerate(self.state_names)})
        cols.update({n: self.u[:, i] for i, n in enumerate(self.input_names)})
        cols.update({n: self.y[:, i] for i, n in enumerate(self.output_names)})
        if self.y_true is not None:
            cols.update({f"{n}_true": self.y_true[:, i] for i, n in enumerate(self.output_names)})
        for name, tr in self.observers.items():
            cols.update({f"{name}.{n}": tr.xhat[:, i] for i, n in enumerate(self.state_names)})
            if self.x is not None:
                cols[f"{name}.error"] = self.error_norm(name)
        return pd.DataFrame(cols, index=pd.Index(self.t, name="t"))

    def summary_dict(self, *, tol: float | None = None) -> dict[str, Any]:
        """``{"model": str, "observers": {NAME: {"final_error", "rms_error", "convergence_time", ...}}}``."""
        obs: dict[str, Any] = {}
        for name, tr in self.observers.items():
            entry: dict[str, Any] = {"method": tr.method, "final_estimate": tr.xhat[-1].tolist()}
            if self.x is not None:
                entry.update(self.metrics(name, tol=tol).to_dict())
                if self.y_true is not None and not np.array_equal(self.y, self.y_true):
                    entry["noise_gain"] = self.noise_gain(name)
            obs[name] = entry
        return {"model": self.model, "t_final": float(self.t[-1]), "samples": int(self.t.size), "observers": obs}

    def plot(self, path: str | None = None, *, observers: Sequence[str] | None = None, width: float = 6.4,
             title: str | None = None) -> Any:
        """States vs estimates, and the error norms on a log scale; saved to `path` if given.

        Parameters
        ----------
        path : str, optional
            File to save the figure to (png, pdf, svg, ...).
        observers : sequence of str, optional
            Observers to draw (default: all).
        width : float
            Figure width in inches.
        title : str, optional
            A title above the panels.

        Returns
        -------
        matplotlib.figure.Figure
        """
        from ._plot import plot_run

        return plot_run(self, path, observers=observers, width=width, title=title)
