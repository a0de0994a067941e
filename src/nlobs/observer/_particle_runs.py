"""What both particle-filter engines share: a run's result (:class:`ParticleRun`), one run's checked arrays
(:class:`_Job`) and the count of draws a run takes. The C loop is in ``_particles.py``, the JAX one in
``_particles_jax.py``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..design.kalman._pf import ParticleDesign, square_roots
from ..errors import DataError, FiniteEscapeError, ShapeError
from ._signals import signals_by_keyword

__all__ = ["ParticleRun", "draws_needed"]


@dataclass(frozen=True, eq=False)
class ParticleRun:
    """What :meth:`ParticleRunner.run` returns (time on the first axis).

    Attributes
    ----------
    t : numpy.ndarray of shape (N,)
    xhat : numpy.ndarray of shape (N, n)
        Weighted particle mean after each sample's weighting.
    P : numpy.ndarray of shape (N, n, n)
        Weighted particle covariance.
    ess : numpy.ndarray of shape (N,)
        Effective sample size 1/Σw² after weighting (before resampling).
    resampled : numpy.ndarray of shape (N,), bool
    loglik : numpy.ndarray of shape (N,)
        log p̂(y_k | y_1..k-1), the particle estimate of each sample's predictive likelihood.
    particles : numpy.ndarray of shape (M, n)
        The final particles (after the last resampling, if any).
    weights : numpy.ndarray of shape (M,)
    xhat_prior : numpy.ndarray of shape (N, n)
        The weighted mean of the particles moved to each sample, before its measurement is used (the
        auxiliary filter: moved without noise).
    """

    t: np.ndarray
    xhat: np.ndarray
    P: np.ndarray
    ess: np.ndarray
    resampled: np.ndarray
    loglik: np.ndarray
    particles: np.ndarray
    weights: np.ndarray
    xhat_prior: np.ndarray
    log_weights: np.ndarray | None = None
    kept: tuple[np.ndarray, np.ndarray] | None = None   # the clouds (particles, log-weights) after the samples in `keep`

    @property
    def z(self) -> np.ndarray:
        """The trace rows of the filter (x̂, P column-major, ESS, resampled, log-likelihood), as its ``z_names``."""
        N, n = self.xhat.shape
        return np.hstack([self.xhat, self.P.transpose(0, 2, 1).reshape(N, n * n), self.ess[:, None],
                          self.resampled[:, None].astype(float), self.loglik[:, None]])


def draws_needed(design: ParticleDesign, nsub: np.ndarray, N: int, M: int) -> int:
    """How many standard normals a run over N samples takes: M·n for the initial particles and M·n per noisy
    sub-step (`nsub` per interval; a map: one per interval)."""
    return M * design.system.n_states * (1 + int(np.sum(nsub[:N - 1])))


@dataclass
class _Job:
    """One run's arrays, checked and laid out as both engines take them."""

    label: str
    t: np.ndarray
    U: np.ndarray
    y: np.ndarray
    mask: np.ndarray
    W: np.ndarray
    cst: np.ndarray
    nsub: np.ndarray
    M: int
    x0: np.ndarray
    L0: np.ndarray
    Lq: np.ndarray
    seed: int
    design: ParticleDesign

    @property
    def N(self) -> int:
        return int(self.t.size)

    @classmethod
    def of(cls, runner: Any, t: Any, args: Any, u: Any, y: Any, mask: Any, xhat0: Any, seed: Any, particles: Any,
           name: Any) -> _Job:
        u, y = signals_by_keyword("ParticleRunner.run", args, u, y)
        d = runner.design
        label = f"observer {name or d.method!r}"
        t = np.ascontiguousarray(t, dtype=float).reshape(-1)
        N = t.size
        if N < 1 or np.any(np.diff(t) <= 0):
            raise ShapeError(f"{label}: the sample times must be strictly increasing")
        y = np.ascontiguousarray(y, dtype=float).reshape(N, runner.ny)
        U = np.zeros((N, 1)) if runner.nu == 0 else np.ascontiguousarray(u, dtype=float).reshape(N, runner.nu)
        m = np.ones((N, runner.ny)) if mask is None else np.asarray(mask, dtype=float).reshape(N, runner.ny)
        y = np.ascontiguousarray(np.where(m > 0, y, 0.0))
        if not (np.all(np.isfinite(y)) and np.all(np.isfinite(U))):
            raise DataError(f"{label}: non-finite samples (give missing outputs by `mask`)")
        W, cst = _precision_factors(d.R, m > 0)
        dts = np.diff(t)
        nsub = np.ones(max(N - 1, 1)) if d.max_step is None else np.maximum(1.0, np.ceil(dts / d.max_step - 1e-9))
        M = d.particles if particles is None else int(particles)
        x0 = np.ascontiguousarray(d.xhat0 if xhat0 is None else np.asarray(xhat0, dtype=float).reshape(runner.n))
        L0, Lq = (np.ascontiguousarray(a) for a in square_roots(d))
        return cls(label, t, U, y, m, W, cst, np.ascontiguousarray(nsub), M, x0, L0, Lq,
                   int(d.seed if seed is None else seed), d)

    def vanished(self, k: int, xhat: np.ndarray) -> None:
        t, d = self.t, self.design
        last = xhat[k - 1] if k > 0 else self.x0
        raise FiniteEscapeError(self.label, float(t[k - 1] if k > 0 else t[0]), last, d.system.states, np.inf,
                                hint=f"at the sample t = {t[k]:g} every particle's likelihood vanished (the model's output is "
                                     "not finite at all of them: outside its domain): start x̂0 inside the domain, "
                                     "or use a smaller P0 or Q")


def _precision_factors(R: np.ndarray, measured: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per sample: W with WᵀW = R_sub⁻¹ on the measured outputs (zero elsewhere), and the Gaussian's log constant."""
    N, p = measured.shape
    W, cst = np.zeros((N, p, p)), np.zeros(N)
    for pattern in {tuple(r) for r in measured}:
        rows = np.all(measured == np.array(pattern), axis=1)
        sel = np.flatnonzero(pattern)
        Wk = np.zeros((p, p))
        c = 0.0
        if sel.size:
            L = np.linalg.cholesky(R[np.ix_(sel, sel)])
            Wk[np.ix_(sel, sel)] = np.linalg.inv(L)
            c = -0.5 * sel.size * np.log(2 * np.pi) - np.log(np.diag(L)).sum()
        W[rows], cst[rows] = Wk, c
    return np.ascontiguousarray(W), cst
