r"""Excitation of regressors and inputs: IE (Wang, Ortega & Bobtsov (2021), eq. 15), PE, identifiability of a linear
regression (Wang, Ortega & Bobtsov (2021), Prop. 2), regular persistence and local regularity for state-affine systems (Besançon (2010)).

For a regressor ψ(t) ∈ R^q of a linear regression Y = ψᵀθ:

* interval excitation (IE, Wang, Ortega & Bobtsov (2021), eq. 15): :math:`\int_0^{t_d}\psi\psi^\top ds \ge C_d I` for some t_d;
* persistent excitation (PE): :math:`\int_t^{t+T}\psi\psi^\top ds \ge \alpha I` for all t;
* identifiability: rank :math:`[\psi(t_1) | \dots | \psi(t_q)] = q` for some times (Wang, Ortega & Bobtsov (2021) S2,
  equivalent to IE and, for GPEBO's regressor, to observability: Wang, Ortega & Bobtsov (2021), Prop. 2).

The integrals use the trapezoidal rule on the given samples.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import DataError, ShapeError
from ...model import StateAffine
from ._gramian import UCOResult, _integrate, _matrix_path, check_timepts, state_affine_ltv, uco_test
from .._reports import fmt_directions
from ...references import cite

__all__ = ["ExcitationResult", "interval_excitation", "persistent_excitation", "IdentifiabilityResult",
           "identifiability_rank", "regular_persistence", "LocalRegularity", "local_regularity"]

#: Eigenvalues of an excitation integral below RTOL·λ_max count as zero (trapezoid round-off is ~1e-13).
RTOL = 1e-9


def _regressor(timepts: Any, psi: Any, caller: str) -> tuple[np.ndarray, np.ndarray]:
    t = check_timepts(timepts, caller)
    P = np.asarray(psi, dtype=float)
    if P.ndim == 1:
        P = P[:, None]
    if P.ndim != 2 or P.shape[0] != t.size:
        raise ShapeError(f"{caller}: `psi` must have one row per grid time, shape ({t.size}, q); found {P.shape}")
    if not np.all(np.isfinite(P)):
        k = int(np.flatnonzero(~np.isfinite(P).all(axis=1))[0])
        raise DataError(f"{caller}: `psi` is not finite at t = {t[k]:g} (row {k}); drop or fill the sample")
    return t, P


def _cumulative(t: np.ndarray, P: np.ndarray) -> np.ndarray:
    """G(t_k) = ∫_{t_0}^{t_k} ψψᵀ (trapezoid), shape (N, q, q)."""
    outer = np.einsum("ki,kj->kij", P, P)
    G = np.zeros_like(outer)
    G[1:] = np.cumsum((outer[1:] + outer[:-1]) / 2 * np.diff(t)[:, None, None], axis=0)
    return G


def _lam_min(G: np.ndarray) -> np.ndarray:
    return np.array([np.linalg.eigvalsh((g + g.T) / 2)[0] for g in G])


@dataclass(frozen=True, eq=False)
class ExcitationResult:
    """Verdict and evidence of an IE or PE test.

    Attributes
    ----------
    kind : {"IE", "PE"}
    times : numpy.ndarray
        IE: the grid (λ_min of ∫_0^t ψψᵀ at each time); PE: the window starts.
    lambda_min : numpy.ndarray
        Smallest eigenvalue of the excitation integral at each of `times`.
    level : float
        The C_d (IE) or α (PE) achieved: IE the final λ_min, PE the smallest over the windows.
    threshold : float
    excited : bool
    t_excited : float or None
        IE: the first time the threshold is reached (a t_d of Wang, Ortega & Bobtsov (2021), eq. 15).
    window : float or None
    """

    kind: str
    times: np.ndarray
    lambda_min: np.ndarray
    level: float
    threshold: float
    excited: bool
    t_excited: float | None
    window: float | None

    def __str__(self) -> str:
        if self.kind == "IE":
            if self.excited:
                return (f"interval exciting ({cite('000')} eq. 15): λ_min ∫_0^t ψψᵀ reaches {self.threshold:.3g} at t_d = "
                        f"{self.t_excited:g}; C_d = {self.level:.3g} at the end")
            return (f"NOT interval exciting on [{self.times[0]:g}, {self.times[-1]:g}]: λ_min ∫ψψᵀ = {self.level:.3g} "
                    f"< {self.threshold:.3g}; the regression is not identifiable from these data")
        verdict = "persistently exciting" if self.excited else "NOT persistently exciting"
        return (f"{verdict} with T = {self.window:g}: min over t of λ_min ∫_t^(t+T) ψψᵀ = {self.level:.3g} "
                f"(threshold {self.threshold:.3g}; smallest at t = {self.times[np.argmin(self.lambda_min)]:g})")


def interval_excitation(timepts: Any, psi: Any, *, C_d: float | None = None, rtol: float = RTOL) -> ExcitationResult:
    r"""Interval excitation of a regressor (Wang, Ortega & Bobtsov (2021), eq. 15): :math:`\int_0^{t_d}\psi\psi^\top ds \ge C_d I`.

    Parameters
    ----------
    timepts : array_like of shape (N,)
    psi : array_like of shape (N, q)
        ψ(t_k) in rows (time on the first axis).
    C_d : float, optional
        The level to reach; default ``rtol`` times the largest eigenvalue of the full integral
        (i.e. "full rank", which by Wang, Ortega & Bobtsov (2021), Prop. 2 is identifiability).

    Returns
    -------
    ExcitationResult
        ``t_excited`` is the first grid time with λ_min ≥ C_d (a valid t_d).

    Raises
    ------
    ShapeError, DataError
        If psi does not have one finite row per grid time, or the grid is not increasing.

    References
    ----------
    Wang, Ortega & Bobtsov (2021), eq. (15) and Lemma 2 (G+D converges iff ψ is IE).
    """
    t, P = _regressor(timepts, psi, "interval_excitation")
    if C_d is not None and not (np.isfinite(C_d) and C_d > 0):
        raise DataError(f"interval_excitation: `C_d` must be positive and finite, got {C_d}")
    G = _cumulative(t, P)
    lam = _lam_min(G)
    top = float(np.linalg.eigvalsh(G[-1])[-1])
    thr = float(C_d) if C_d is not None else rtol * top
    hit = np.flatnonzero(lam >= thr) if top > 0 else np.array([], dtype=int)
    ok = bool(hit.size)
    return ExcitationResult("IE", t, lam, float(lam[-1]), thr, ok, float(t[hit[0]]) if ok else None, None)


def persistent_excitation(timepts: Any, psi: Any, window: float, *, alpha: float | None = None,
                          ratio: float = 1e-3) -> ExcitationResult:
    r"""Persistent excitation: :math:`\int_t^{t+T}\psi\psi^\top ds \ge \alpha I` for every window on the grid.

    Parameters
    ----------
    timepts : array_like of shape (N,)
    psi : array_like of shape (N, q)
    window : float
        T.
    alpha : float, optional
        The α to check; default ``ratio`` times the largest window value (so a decaying regressor,
        which is IE but not PE, is reported as not PE).

    Returns
    -------
    ExcitationResult

    References
    ----------
    Wang, Ortega & Bobtsov (2021), §1 (PE vs IE: IE is "strictly weaker"); the PE integral is the UCO
    Gramian (eq. 4) of A = 0, C = ψᵀ.
    """
    t, P = _regressor(timepts, psi, "persistent_excitation")
    if not np.isfinite(window) or window <= 0:
        raise DataError(f"persistent_excitation: `window` must be positive and finite, got {window}")
    ends = np.searchsorted(t, t + window - 1e-12 * max(1.0, abs(t[-1])))
    starts = np.flatnonzero(ends < t.size)
    if starts.size == 0:
        raise DataError(f"persistent_excitation: the window T = {window:g} is longer than the data "
                        f"[{t[0]:g}, {t[-1]:g}]; shorten the window")
    G = _cumulative(t, P)
    W = G[ends[starts]] - G[starts]
    lam = _lam_min(W)
    thr = float(alpha) if alpha is not None else ratio * float(max(np.linalg.eigvalsh(w)[-1] for w in W))
    return ExcitationResult("PE", t[starts], lam, float(lam.min()), thr, bool(np.all(lam >= thr) and thr > 0), None,
                            float(window))


@dataclass(frozen=True, eq=False)
class IdentifiabilityResult:
    """Rank of [ψ(t_1) | … | ψ(t_N)] (Wang, Ortega & Bobtsov (2021) S2) with q time instants that achieve it."""

    rank: int
    q: int
    identifiable: bool
    times: np.ndarray
    singular_values: np.ndarray
    unidentifiable_directions: np.ndarray

    def __str__(self) -> str:
        if self.identifiable:
            ts = ", ".join(f"{v:g}" for v in self.times)
            return f"identifiable: rank [ψ(t1) … ψ(tq)] = {self.q} at t = {ts} ({cite('000')} S2)"
        dirs = fmt_directions(self.unidentifiable_directions)
        return (f"NOT identifiable: rank [ψ(t1) … ψ(tN)] = {self.rank} < {self.q} over all samples; θ is unknown along "
                f"{dirs}")


def identifiability_rank(timepts: Any, psi: Any, *, rtol: float = RTOL) -> IdentifiabilityResult:
    r"""Identifiability of a linear regression Y = ψᵀθ: rank of :math:`[\psi(t_1)|\dots|\psi(t_N)]`.

    The times returned are chosen by QR with column pivoting (the best-conditioned q samples).
    A singular value below ``rtol`` times the largest counts as zero.

    Parameters
    ----------
    timepts : array_like of shape (N,)
    psi : array_like of shape (N, q)
        ψ(t_k) in rows.
    rtol : float

    Returns
    -------
    IdentifiabilityResult

    References
    ----------
    Wang, Ortega & Bobtsov (2021) S2 and Proposition 2 (identifiability ⇔ observability of (2)).
    """
    import scipy.linalg

    t, P = _regressor(timepts, psi, "identifiability_rank")
    q = P.shape[1]
    _, s, Vt = np.linalg.svd(P, full_matrices=True)
    rank = int(np.sum(s > rtol * s.max(initial=0.0))) if s.size and s.max() > 0 else 0
    _, _, piv = scipy.linalg.qr(P.T, pivoting=True, mode="economic")
    chosen = np.sort(t[piv[:rank]])
    return IdentifiabilityResult(rank, q, rank == q, chosen, s, Vt[rank:].copy())


def regular_persistence(model: StateAffine, timepts: Any, window: float, *, u: Any = None, y: Any = None,
                        alpha: float | None = None, stride: int = 1) -> UCOResult:
    r"""Is the input regularly persistent for a state-affine model (Besançon (2010))?

    u is regularly persistent when :math:`\int_{t-T}^t \Phi_u^\top C^\top C \Phi_u\,d\tau \ge \alpha I`
    for all t ≥ t0: the UCO test of the LTV system obtained by freezing A(u, y) along the
    measured u(t), y(t).

    Parameters
    ----------
    model : StateAffine
    timepts : array_like
        A uniform grid.
    window : float
        T.
    u, y : array_like of shape (N, m) / (N, p), optional
        The measured input and output on the grid.
    alpha : float, optional
        The α to check (default: 1e-3 of the largest window value).
    stride : int
        Test every `stride`-th window start.

    Returns
    -------
    UCOResult

    References
    ----------
    Besançon (2010) "Regularly persistent inputs (RP)" and "Kalman-like observer".
    """
    A, C = state_affine_ltv(model, timepts, u=u, y=y)
    return uco_test(A, C, timepts, window, delta=alpha, stride=stride)


@dataclass(frozen=True, eq=False)
class LocalRegularity:
    r"""Local regularity measure α(t, T) of Besançon (2010) for a set of short windows T."""

    windows: np.ndarray
    starts: np.ndarray
    alpha: np.ndarray  # (n_windows, n_starts)
    alpha_min: float
    threshold: float
    regular: bool

    def __str__(self) -> str:
        verdict = "locally regular" if self.regular else "NOT locally regular"
        return (f"{verdict}: α(t, T) = T·λ_min(Λ_T⁻¹ W(t, t+T) Λ_T⁻¹), Λ_T = diag(T, …, T^n), ranges over "
                f"[{self.alpha_min:.3g}, {self.alpha.max():.3g}] for T in [{self.windows.min():g}, {self.windows.max():g}] "
                f"(threshold {self.threshold:.3g}; {cite('002')} 'Locally regular inputs')")


def local_regularity(model: StateAffine, timepts: Any, windows: Any, *, u: Any = None, y: Any = None,
                     alpha: float | None = None, stride: int = 1, ratio: float = 1e-3) -> LocalRegularity:
    r"""Locally regular inputs for a state-affine model (Besançon (2010)).

    u is locally regular if for every T ≤ T0 and t,

    .. math::

        \int_{t-T}^{t}\Phi_u^\top C^\top C\Phi_u\,d\tau \;\ge\; \frac{\alpha}{T}\,
        \operatorname{diag}(T, T^2, \dots, T^n)^2 .

    (The slide's formula is garbled in the text; re-derived: for the chain x' = A_0 x, y = x1 the
    Gramian entries scale as :math:`T^{i+j-1}`, which is exactly :math:`\frac1T T^i T^j`.) Returns
    :math:`\alpha(t, T) = T\,\lambda_{\min}(\Lambda_T^{-1}W\Lambda_T^{-1})` on a uniform grid.

    Parameters
    ----------
    model : StateAffine
    timepts : array_like
        A uniform grid.
    windows : array_like
        The short window lengths T (all ≤ T0).
    u, y : array_like, optional
        The measured input and output on the grid.
    alpha : float, optional
        The α to check; default ``ratio`` times the largest α(t, T).
    stride : int
        Test every `stride`-th window start.
    ratio : float

    Returns
    -------
    LocalRegularity

    References
    ----------
    Besançon (2010) "Locally regular inputs (LR)".
    """
    A, C = state_affine_ltv(model, timepts, u=u, y=y)
    t = check_timepts(timepts, "local_regularity", uniform=True)
    dt = float(t[1] - t[0])
    Ts = np.atleast_1d(np.asarray(windows, dtype=float))
    if Ts.size == 0 or not np.all(np.isfinite(Ts)) or np.any(Ts <= 0):
        raise DataError("local_regularity: `windows` must be positive, finite window lengths")
    n = A.shape[1]
    Av, Am = _matrix_path(A, t, n, n, "A", "local_regularity")
    Cv, Cm = _matrix_path(C, t, None, n, "C", "local_regularity")
    Lmax = int(round(Ts.max() / dt))
    if Lmax >= t.size:
        raise DataError(f"local_regularity: the window {Ts.max():g} is longer than the grid")
    starts = np.arange(0, t.size - Lmax, stride)
    path = _integrate(Av, Am, Cv, Cm, np.diff(t), starts, Lmax)
    out = np.empty((Ts.size, starts.size))
    for i, T in enumerate(Ts):
        L = max(1, int(round(T / dt)))
        Tl = L * dt
        Li = np.diag(1.0 / Tl ** np.arange(1, n + 1))
        out[i] = [Tl * np.linalg.eigvalsh(Li @ ((w + w.T) / 2) @ Li)[0] for w in path[L]]
    thr = float(alpha) if alpha is not None else ratio * float(out.max())
    return LocalRegularity(Ts, t[starts], out, float(out.min()), thr, bool(np.all(out >= thr) and thr > 0))
