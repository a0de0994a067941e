"""Error metrics of an estimate: convergence time, RMS error, peak error.

The convergence time is a property of the observer, not of the run length: the first time
after which the error norm stays within a band, and the band is

- the absolute tolerance the user gives (``tol``), else
- the larger of 2 % of the initial error ‖x̂(0⁻) − x(0)‖ (before any measurement: the classical
  settling band, which governs noise-free runs) and twice the *steady-state error* — the
  largest error over the last 20 % of the run, when the error has stopped decreasing there
  (a noise floor or a bias). The band never exceeds 20 % of the initial error: an observer
  whose error stays above a fifth of where it started has not converged, whatever the reason.

Without a tolerance given, a run with true states is judged *per state, each in its own units*
(:func:`state_convergence`): the norm of a mixed-unit error (metres beside radians beside a bias of
1e-3) is set by its largest entries, so one band for the norm is below the noise of some states and
above the whole error of others. Each state gets the band above from its own initial error (or its largest error, when
larger: a state that started right and was pulled off by the others) and its own steady-state error; when its floor is above 20 % of its initial error the cap applies unless the
floor is noise — zero-mean over the tail (``|mean| <= NOISE_MEAN × RMS``): a state that started
inside the noise of its sensor, or whose noise exceeds a fifth of its start, is inside its floor,
while a constant bias or a state the observer cannot correct (mean ≈ RMS) still has not converged.
On a run with noise, a state whose error rises as well as falls over the tail is taken to be at
its floor even when the medians of the two last windows say it is still decreasing (a parameter's
estimate wandering over a few dozen samples); noise-free, the classical 2 % band stays.
The convergence time is the latest of the states' times, and the states that set it are named.

Below the noise floor a fixed fraction of the initial error is crossed by every noise peak, so
"2 % of the initial error" alone reads as "converged at the end of the run" for any run length;
with the band above the floor's peaks, the time is where the error curve visibly settles. The
floor's largest value grows only slowly with the run length (like the extremes of the noise),
and the factor 2 leaves room for the peaks of a longer run.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

__all__ = ["Metrics", "error_metrics", "convergence_time", "convergence_band", "steady_state_error", "CONVERGENCE_RULE",
           "StateConvergence", "state_convergence", "state_metrics", "PER_STATE_RULE"]

#: The settling band as a fraction of the initial error (classical 2 % settling time).
RELATIVE_BAND = 0.02
#: The band is this many times the steady-state error (the error's largest value over the tail).
FLOOR_FACTOR = 2.0
#: The error has stopped decreasing when its median over the window before the tail is at most
#: this many times its median over the tail.
STEADY_RATIO = 1.5
#: A band wider than this fraction of the initial error is no convergence (unless, per state, the floor is noise).
MAX_BAND = 0.2
#: Per state, a steady-state error is noise when its mean over the tail is at most this fraction of its RMS there.
NOISE_MEAN = 0.5

#: One sentence for results, JSON and reports.
CONVERGENCE_RULE = ("convergence time: the first time after which ‖x̂ − x‖ stays within a band — the tolerance given, "
                    "else the larger of 2 % of the initial error ‖x̂(0⁻) − x(0)‖ and twice the steady-state error "
                    "(the largest error over the last 20 % of the run, once the error has stopped decreasing there), "
                    "at most 20 % of the initial error; measured from the initial estimate, before the first update")
PER_STATE_RULE = ("convergence time: the first time after which every state's error |x̂ᵢ − xᵢ| stays within its own band, in "
                  "its own units — the larger of 2 % of its initial error |x̂ᵢ(0⁻) − xᵢ(0)| (or of its largest error, "
                  "when larger) and twice its steady-state error (the largest over the last 20 % of the run, once it has "
                  "stopped decreasing), at most 20 % of that initial error unless the floor is noise (zero-mean over the "
                  "tail); the states that settle last set it")


def convergence_time(t: np.ndarray, e: np.ndarray, tol: float) -> float | None:
    """The first time of `t` after which the error `e` (sampled at `t`) stays at or below `tol` until the end; None if
    it never does."""
    above = np.flatnonzero(~(e <= tol))
    if above.size == 0:
        return float(t[0])
    last = above[-1]
    return None if last == e.size - 1 else float(t[last + 1])


def steady_state_error(t: np.ndarray, e: np.ndarray, *, tail: float = 0.2) -> float | None:
    """The error level the run settles to: the largest value of `e` (sampled at times `t`) over the last `tail` of the
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
    """The band the convergence time of the error `e`, sampled at times `t`, is measured against (see the module
    docstring).

    `e0` is the initial error before any measurement (default: ``e[0]``); `tol` an absolute
    tolerance that replaces the rule; `tail` the fraction of the run at its end whose error is the steady state.
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
        ``"steady"`` (twice the steady-state error), ``"cap"`` (20 % of the initial error), or
        ``"per state"`` (:func:`state_metrics`: `tol` is then the norm of the states' bands).
    initial_error : float
        ‖x̂(0⁻) − x(0)‖, the error of the initial estimate before any measurement.
    steady_error : float or None
        The largest error over the last 20 % of the run; None when the error was still
        decreasing there (no steady state within the run).
    bands : mapping of state to float, or None
        Per state (``tol_basis == "per state"``): each state's band in its own units.
    set_by : tuple of str
        Per state: the states that settle last and so set the convergence time, or that do not settle.
    band_basis : mapping of state to str, or None
        Per state: what set each band (``initial``, ``steady``, ``cap`` or ``noise``).
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
    bands: dict[str, float] | None = None
    set_by: tuple[str, ...] = ()
    band_basis: dict[str, str] | None = None

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["set_by"] = list(self.set_by)
        return out


def error_metrics(t: np.ndarray, e: np.ndarray, *, tol: float | None = None, e0: float | None = None,
                  tail: float = 0.2) -> Metrics:
    """Metrics of the error norm `e` sampled at times `t` (see :class:`Metrics`).

    `e0` is the error of the initial estimate before any measurement (default ``e[0]``); `tol`
    an absolute convergence tolerance (default: the band of :data:`CONVERGENCE_RULE`); `tail` the fraction of the run
    at its end over which the RMS error is taken.
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


@dataclass(frozen=True)
class StateConvergence:
    """Per-state convergence of one run (see the module docstring).

    Attributes
    ----------
    time : float or None
        The latest of the states' times (None: some state does not settle within the run).
    times : numpy.ndarray
        Each state's time (NaN: not within the run).
    bands : numpy.ndarray
        Each state's band, in its own units.
    basis : tuple of str
        What set each band: ``initial``, ``steady``, ``cap`` or ``noise`` (a noise floor above the cap).
    set_by : tuple of int
        The states that settle last (or do not settle).
    """

    time: float | None
    times: np.ndarray
    bands: np.ndarray
    basis: tuple[str, ...]
    set_by: tuple[int, ...]


def state_convergence(t: np.ndarray, E: np.ndarray, e0: np.ndarray, *, tail: float = 0.2,
                      noisy: bool = False) -> StateConvergence:
    """Convergence judged per state: `E` (N, n) the signed errors x̂ − x, `e0` (n,) the initial errors before any
    measurement (states beyond its length: their first error), see :data:`PER_STATE_RULE`. `noisy`: the run had noise,
    so a state's error that rises again over the tail is at its floor even when the medians of the two windows before
    the end say it is still decreasing (a slowly wandering estimate of a parameter, over a few dozen samples)."""
    t = np.asarray(t, dtype=float)
    E = np.asarray(E, dtype=float).reshape(t.size, -1)
    e0 = np.abs(np.asarray(e0, dtype=float).reshape(-1))
    n = E.shape[1]
    if e0.size < n:
        e0 = np.concatenate([e0, np.abs(E[0, e0.size:])])
    last = t >= t[-1] - tail * (t[-1] - t[0])
    times, bands, basis = np.full(n, np.nan), np.zeros(n), []
    for i in range(n):
        a = np.abs(E[:, i])
        # the state's largest deviation: its initial error, or a later one when it started right and was disturbed
        ref = max(float(e0[i]), float(np.max(a)) if np.all(np.isfinite(a)) else np.inf)
        band = convergence_band(t, a, e0=ref, tail=tail)
        if noisy and band.steady_error is None and band.basis == "initial":
            up = np.diff(a[last])
            if up.size and np.any(up > 0) and np.all(np.isfinite(a[last])):  # the tail rises as well as falls: its floor
                steady = float(np.max(a[last]))
                band = Band(band.tol, band.basis, band.initial_error, steady)
                if FLOOR_FACTOR * steady > band.tol:
                    band = Band(FLOOR_FACTOR * steady, "steady", band.initial_error, steady)
                    if band.tol > MAX_BAND * ref:
                        band = Band(MAX_BAND * ref, "cap", band.initial_error, steady)
        tol, why = band.tol, band.basis
        if why == "cap" and band.steady_error is not None:
            tail_e = E[last, i]
            rms = float(np.sqrt(np.mean(tail_e ** 2)))
            if rms > 0 and abs(float(np.mean(tail_e))) <= NOISE_MEAN * rms:
                tol, why = FLOOR_FACTOR * band.steady_error, "noise"
        tc = convergence_time(t, a, tol)
        times[i] = np.nan if tc is None else tc
        bands[i] = tol
        basis.append(why)
    if np.isnan(times).any():
        return StateConvergence(None, times, bands, tuple(basis), tuple(int(i) for i in np.flatnonzero(np.isnan(times))))
    latest = float(np.max(times)) if n else float(t[0])
    return StateConvergence(latest, times, bands, tuple(basis), tuple(int(i) for i in np.flatnonzero(times == latest)))


def state_metrics(t: np.ndarray, E: np.ndarray, e0: np.ndarray, names: tuple[str, ...] | list[str], *,
                  tail: float = 0.2, noisy: bool = False) -> Metrics:
    """:class:`Metrics` of the signed errors `E` (N, n) with the convergence judged per state (:func:`state_convergence`):
    the errors on the norm, ``tol`` the norm of the states' bands (‖x̂ − x‖ stays within it from the convergence time on,
    as every state stays within its own), ``bands`` each state's band and ``set_by`` the states that set the time."""
    t = np.asarray(t, dtype=float)
    E = np.asarray(E, dtype=float).reshape(t.size, -1)
    if not 0 < tail <= 1:
        raise ValueError(f"`tail` must be in (0, 1], got {tail}")
    e = np.linalg.norm(E, axis=1)
    sc = state_convergence(t, E, e0, tail=tail, noisy=noisy)
    start = np.searchsorted(t, t[-1] - tail * (t[-1] - t[0]), side="left")
    tc, after = sc.time, None
    if tc is not None:
        after = float(np.sqrt(np.mean(e[t >= tc] ** 2)))
        tc = float(tc - t[0])
    steady = steady_state_error(t, e, tail=tail)
    return Metrics(float(e[-1]), float(np.sqrt(np.mean(e[start:] ** 2))), float(np.max(e)), tc, after,
                   float(np.linalg.norm(sc.bands)), "per state", float(np.linalg.norm(np.asarray(e0, dtype=float))), steady,
                   {names[i]: float(b) for i, b in enumerate(sc.bands)}, tuple(names[i] for i in sc.set_by),
                   {names[i]: b for i, b in enumerate(sc.basis)})
