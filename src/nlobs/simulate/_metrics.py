"""Error metrics of an estimate: convergence time, RMS error, peak error."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["Metrics", "error_metrics", "convergence_time"]


def convergence_time(t: np.ndarray, e: np.ndarray, tol: float) -> float | None:
    """The first time after which ``e`` stays at or below `tol` until the end; None if it never does."""
    above = np.flatnonzero(~(e <= tol))
    if above.size == 0:
        return float(t[0])
    last = above[-1]
    return None if last == e.size - 1 else float(t[last + 1])


@dataclass(frozen=True)
class Metrics:
    """Summary of an estimation error norm ‖x̂(t) - x(t)‖.

    Attributes
    ----------
    final_error : float
        Error norm at the final time.
    rms_error : float
        RMS of the error norm over the last `tail` fraction of the run (default 20 %).
    peak_error : float
        Largest error norm over the run.
    convergence_time : float or None
        First time after which the error stays below `tol` (None: never).
    rms_after_convergence : float or None
        RMS of the error norm from `convergence_time` on.
    tol : float
        The tolerance used (default: 2 % of the initial error, a settling-time criterion).
    """

    final_error: float
    rms_error: float
    peak_error: float
    convergence_time: float | None
    rms_after_convergence: float | None
    tol: float

    def to_dict(self) -> dict[str, float | None]:
        return asdict(self)


def error_metrics(t: np.ndarray, e: np.ndarray, *, tol: float | None = None, tail: float = 0.2) -> Metrics:
    """Metrics of the error norm `e` sampled at times `t` (see :class:`Metrics`)."""
    t = np.asarray(t, dtype=float)
    e = np.asarray(e, dtype=float)
    if not 0 < tail <= 1:
        raise ValueError(f"`tail` must be in (0, 1], got {tail}")
    if tol is None:
        tol = 0.02 * float(e[0]) if e[0] > 0 else 1e-12
    start = np.searchsorted(t, t[-1] - tail * (t[-1] - t[0]), side="left")
    tc = convergence_time(t, e, tol)
    after = None
    if tc is not None:
        sel = e[t >= tc]
        after = float(np.sqrt(np.mean(sel**2)))
    return Metrics(float(e[-1]), float(np.sqrt(np.mean(e[start:] ** 2))), float(np.max(e)), tc, after, float(tol))
