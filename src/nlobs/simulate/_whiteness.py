"""Whiteness of innovations: the Ljung–Box portmanteau test.

An observer that extracts all the information in the data leaves innovations (one-step output
prediction errors) that are white: uncorrelated in time. The Ljung–Box statistic

.. math::

    Q = n(n + 2) \\sum_{k=1}^{h} \\frac{\\hat\\rho_k^2}{n - k}

of the sample autocorrelations :math:`\\hat\\rho_k` is approximately χ² with h degrees of freedom
for white noise (Ljung & Box (1978)).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..references import cite

__all__ = ["Whiteness", "ljung_box"]


@dataclass(frozen=True)
class Whiteness:
    """The Ljung–Box test of one residual sequence.

    Attributes
    ----------
    n : int
        Samples used (missing ones excluded).
    mean, rms : float
        Mean and root-mean-square of the residuals.
    lags : int
        h, the number of autocorrelations in the statistic.
    q : float or None
        The statistic Q (None: too few samples, or a constant sequence).
    p_value : float or None
        P(χ²_h ≥ Q): small values mean correlated residuals.
    white : bool or None
        Whether whiteness is not rejected at the level `alpha`.
    alpha : float
    """

    n: int
    mean: float
    rms: float
    lags: int
    q: float | None
    p_value: float | None
    white: bool | None
    alpha: float

    def to_dict(self) -> dict[str, float | int | bool | None]:
        return asdict(self)

    def __str__(self) -> str:
        if self.q is None:
            return f"n = {self.n}: too few samples (or a constant sequence) for a whiteness test"
        verdict = "white" if self.white else "not white"
        return (f"{verdict} at the {100 * self.alpha:g} % level: Ljung–Box Q = {self.q:.4g} over {self.lags} lags, "
                f"p = {self.p_value:.3g} ({cite('ljungbox1978')})")


def ljung_box(r: np.ndarray, *, lags: int | None = None, alpha: float = 0.05) -> Whiteness:
    """Ljung–Box test of the sequence `r` (time on the only axis; NaN marks a missing sample).

    Parameters
    ----------
    r : array_like of shape (N,)
    lags : int, optional
        h (default ``min(10, n // 5)``). Lags count samples, so the test assumes regular sampling.
    alpha : float
        The level of the verdict ``white``.

    Missing samples are left out of the sums: they count as zero deviations from the mean, and
    n is the number of samples present.
    """
    r = np.asarray(r, dtype=float).reshape(-1)
    if not 0 < alpha < 1:
        raise ValueError(f"ljung_box: `alpha` must be in (0, 1), got {alpha!r}")
    ok = np.isfinite(r)
    n = int(ok.sum())
    mean = float(np.mean(r[ok])) if n else float("nan")
    rms = float(np.sqrt(np.mean(r[ok] ** 2))) if n else float("nan")
    h = min(10, n // 5) if lags is None else int(lags)
    if lags is not None and not 1 <= h < n:
        raise ValueError(f"ljung_box: `lags` must be between 1 and n - 1 = {n - 1}, got {lags!r}")
    d = np.where(ok, r - mean, 0.0)
    denom = float(np.dot(d, d))
    if h < 1 or n < 10 or denom <= 0:
        return Whiteness(n, mean, rms, max(h, 0), None, None, None, alpha)
    rho = np.array([np.dot(d[k:], d[:-k]) / denom for k in range(1, h + 1)])
    q = float(n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, h + 1))))
    from scipy import stats  # here: importing scipy.stats costs every command a second

    p = float(stats.chi2.sf(q, h))
    return Whiteness(n, mean, rms, h, q, p, p >= alpha, alpha)
