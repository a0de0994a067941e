"""Error metrics of an estimate: convergence time, RMS error, peak error.

The convergence time is a property of the observer, not of the run length: the first time
after which the error norm stays within a band, and the band is

- the absolute tolerance the user gives (``tol``), else
- the larger of 2 % of the initial error ‖x̂(0⁻) − x(0)‖ (before any measurement: the classical
  settling band, which governs noise-free runs) and twice the *steady-state error* — the
  largest error over the last 20 % of the run, when the error has stopped decreasing there
  (a noise floor or a bias). The band never exceeds 20 % of the initial error: an observer
  whose error stays above a fifth of where it started has not converged, whatever the reason.

Below the noise floor a fixed fraction of the initial error is crossed by every noise peak, so
"2 % of the initial error" alone reads as "converged at the end of the run" for any run length;
with the band above the floor's peaks, the time is where the error curve visibly settles. The
floor's largest value grows only slowly with the run length (like the extremes of the noise),
and the factor 2 leaves room for the peaks of a longer run.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["Metrics", "error_metrics", "convergence_time", "convergence_band", "steady_state_error", "CONVERGENCE_RULE"]

#: The settling band as a fraction of the initial error (classical 2 % settling time).
RELATIVE_BAND = 0.02
#: The band is this many times the steady-state error (the error's largest value over the tail).
FLOOR_FACTOR = 2.0
#: The error has stopped decreasing when its median over the window before the tail is at most
#: this many times its median over the tail.
STEADY_RATIO = 1.5
#: A band wider than this fraction of the initial error is no convergence.
MAX_BAND = 0.2

#: One sentence for results, JSON and reports.
CONVERGENCE_RULE = ("convergence time: the first time after which ‖x̂ − x‖ stays within a band — the tolerance given, "
                    "else the larger of 2 % of the initial error ‖x̂(0⁻) − x(0)‖ and twice the steady-state error "
                    "(the largest error over the last 20 % of the run, once the error has stopped decreasing there), "
                    "at most 20 % of the initial error; measured from the initial estimate, before the first update")


def convergence_time(t: np.ndarray, e: np.ndarray, tol: float) -> float | None:
    """The first time after which ``e`` stays at or below `tol` until the end; None if it never does."""
    above = np.flatnonzero(~(e <= tol))
    if above.size == 0:
        return float(t[0])
    last = above[-1]
    return None if last == e.size - 1 else float(t[last + 1])


def steady_state_error(t: np.ndarray, e: np.ndarray, *, tail: float = 0.2) -> float | None:
    """The error level the run settles to: the largest value of `e` over the last `tail` of the
    run, or None while the error is still decreasing there (its median over the window of the
    same length before the tail is more than 1.5 times its median over the tail)."""
    t = np.asarray(t, dtype=float)
    e = np.asarray(e, dtype=float)
    span = t[-1] - t[0]
    last = t >= t[-1] - tail * span
    before = (t >= t[-1] - 2 * tail * span) & ~last
    if last.sum() < 2 or before.sum() < 2 or not np.all(np.isfinite(e[last | before])):
        return None
    m_last, m_before = float(np.median(e[last])), float(np.median(e[before]))
    if not m_last > 0 or m_before > STEADY_RATIO * m_last:
        return None
    return float(np.max(e[last]))


@dataclass(frozen=True)
class Band:
    """The convergence band of one error signal and how it was set."""

    tol: float
    basis: str  # "tol" (given), "initial" (2 % of e0), "steady" (2 x steady-state error), "cap" (20 % of e0)
    initial_error: float
    steady_error: float | None


def convergence_band(t: np.ndarray, e: np.ndarray, *, e0: float | None = None, tol: float | None = None,
                     tail: float = 0.2) -> Band:
    """The band the convergence time is measured against (see the module docstring).

    `e0` is the initial error before any measurement (default: ``e[0]``); `tol` an absolute
    tolerance that replaces the rule.
    """
    e0_ = float(e[0]) if e0 is None else float(e0)
    steady = steady_state_error(t, e, tail=tail)
    if tol is not None:
        return Band(float(tol), "tol", e0_, steady)
    band, basis = RELATIVE_BAND * e0_, "initial"
    if steady is not None and FLOOR_FACTOR * steady > band:
        band, basis = FLOOR_FACTOR * steady, "steady"
        if band > MAX_BAND * e0_:
            band, basis = MAX_BAND * e0_, "cap"
    if not band > 0:  # started exactly on the true state and stays there
        band = 1e-12
    return Band(float(band), basis, e0_, steady)


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
        How long after the start of the run (the initial estimate, before the first update) the
        error enters the band `tol` for good (None: not within the run).
    rms_after_convergence : float or None
        RMS of the error norm from `convergence_time` on.
    tol : float
        The band: the tolerance given, else ``max(2 % of initial_error, 2 × steady_error)``,
        at most 20 % of `initial_error` (see :data:`CONVERGENCE_RULE`).
    tol_basis : str
        What set the band: ``"tol"`` (given), ``"initial"`` (2 % of the initial error),
        ``"steady"`` (twice the steady-state error) or ``"cap"`` (20 % of the initial error).
    initial_error : float
        ‖x̂(0⁻) − x(0)‖, the error of the initial estimate before any measurement.
    steady_error : float or None
        The largest error over the last 20 % of the run; None when the error was still
        decreasing there (no steady state within the run).
    """

    final_error: float
    rms_error: float
    peak_error: float
    convergence_time: float | None
    rms_after_convergence: float | None
    tol: float
    tol_basis: str = "tol"
    initial_error: float | None = None
    steady_error: float | None = None

    def to_dict(self) -> dict[str, float | str | None]:
        return asdict(self)


def error_metrics(t: np.ndarray, e: np.ndarray, *, tol: float | None = None, e0: float | None = None,
                  tail: float = 0.2) -> Metrics:
    """Metrics of the error norm `e` sampled at times `t` (see :class:`Metrics`).

    `e0` is the error of the initial estimate before any measurement (default ``e[0]``); `tol`
    an absolute convergence tolerance (default: the band of :data:`CONVERGENCE_RULE`).
    """
    t = np.asarray(t, dtype=float)
    e = np.asarray(e, dtype=float)
    if not 0 < tail <= 1:
        raise ValueError(f"`tail` must be in (0, 1], got {tail}")
    if tol is not None and not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"the convergence tolerance `tol` must be a positive number, got {tol!r}")
    band = convergence_band(t, e, e0=e0, tol=tol)
    start = np.searchsorted(t, t[-1] - tail * (t[-1] - t[0]), side="left")
    tc = convergence_time(t, e, band.tol)
    after = None
    if tc is not None:
        sel = e[t >= tc]
        after = float(np.sqrt(np.mean(sel**2)))
        tc = float(tc - t[0])  # a duration from the initial estimate (recordings need not start at t = 0)
    return Metrics(float(e[-1]), float(np.sqrt(np.mean(e[start:] ** 2))), float(np.max(e)), tc, after, band.tol,
                   band.basis, band.initial_error, band.steady_error)
