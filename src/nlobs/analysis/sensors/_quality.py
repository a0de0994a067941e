r"""Quality of a set of sensors from its Fisher information :math:`F_S = \sum_{c\in S} F_c`: the Cramér–Rao bounds,
the unobservability index (Krener & Ide (2009)), the criterion that ranks sets, the best set under a budget and the
cost–quality Pareto front."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...references import cite

__all__ = ["Quality", "quality", "batch_criterion", "pareto_front", "greedy_path", "ZERO"]

#: An eigenvalue of the Jacobi-scaled information below ZERO × the largest is taken as zero: a direction of the
#: unknowns the run does not inform (double precision leaves about 1e-16 × condition of rounding in the scaled matrix).
ZERO = 1e-12
#: Subsets evaluated per batch of eigen-decompositions (memory: batch × m² doubles).
_BATCH = 2048


@dataclass(frozen=True)
class Quality:
    r"""The estimation quality a set's Fisher information allows.

    Attributes
    ----------
    crb : numpy.ndarray
        Cramér–Rao bound (standard deviation) of each unknown; inf where the run does not inform it.
    log_det : float
        The criterion: :math:`\log\det` of the targets' information (the inverse of their Cramér–Rao covariance);
        -inf when a target is not informed.
    unobservability_index : float
        :math:`1/\sqrt{\lambda_{\min}(F_S)}` (Krener & Ide (2009)): the bound's standard deviation along the worst
        direction, in the unknowns' units, or in units of their scales when :func:`quality` is given them; inf when
        :math:`F_S` is singular (a bound is infinite).
    condition : float
        :math:`\sqrt{\lambda_{\max}/\lambda_{\min}}` (the local estimation condition number, in the same units).
    """

    crb: np.ndarray
    log_det: float
    unobservability_index: float
    condition: float


def _scaled_eig(F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Batched: Jacobi scale d (1/√diag, 0 where the diagonal is 0), eigenvalues and vectors of D F D, and the mask
    of eigenvalues taken as nonzero."""
    diag = np.einsum("bii->bi", F)
    d = np.where(diag > 0, 1.0 / np.sqrt(np.where(diag > 0, diag, 1.0)), 0.0)
    Fs = F * d[:, :, None] * d[:, None, :]
    lam, V = np.linalg.eigh((Fs + np.swapaxes(Fs, 1, 2)) / 2)
    top = np.max(lam, axis=1, keepdims=True)
    live = lam > ZERO * np.maximum(top, 1e-300)
    return d, lam, V, live


def batch_criterion(F: np.ndarray, targets: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    r"""The Cramér–Rao bounds (B, m) and the criterion (B,) of a batch of information matrices (B, m, m).

    An unknown is bounded when its axis has no component along the uninformed directions (relative 1e-6); its bound
    is then :math:`\sqrt{(F^+)_{ii}}`. The criterion is :math:`-\log\det` of the targets' covariance block (the
    log det of F itself when every unknown is a target), -inf when a target is unbounded.
    """
    d, lam, V, live = _scaled_eig(F)
    inv = np.where(live, 1.0 / np.where(live, lam, 1.0), 0.0)
    cov_s = np.einsum("bik,bk,bjk->bij", V, inv, V)
    dead = np.einsum("bik,bk->bi", V ** 2, (~live).astype(float))
    bounded = (dead < 1e-12) & (d > 0)
    var = np.einsum("bii->bi", cov_s) * d ** 2
    crb = np.where(bounded, np.sqrt(np.maximum(var, 0.0)), np.inf)
    T = list(targets)
    cov_t = cov_s[:, T][:, :, T] * d[:, T, None] * d[:, None, T]
    sign, logdet = np.linalg.slogdet(cov_t) if T else (np.ones(F.shape[0]), np.zeros(F.shape[0]))
    ok = np.all(bounded[:, T], axis=1) & (sign > 0)
    return crb, np.where(ok, -logdet, -np.inf)


def quality(F: np.ndarray, targets: Sequence[int], scales: Sequence[float] | None = None) -> Quality:
    """The :class:`Quality` of one information matrix.

    Parameters
    ----------
    F : numpy.ndarray of shape (m, m)
        The set's Fisher information.
    targets : sequence of int
        The unknowns the criterion is of.
    scales : sequence of float, optional
        Each unknown's scale (its prior σ₀: ``[simulation] initial_std``, else its size on the run). The
        unobservability index and the condition number are then those of the information in those units
        (S F S, S = diag(scales)): with mixed units (a quaternion and a position) the plain eigenvalues of F span
        more decades than double precision holds, and F looked singular where every bound is finite.

    The index is computed as √λ_max of the Cramér–Rao covariance (in the same units), which the Jacobi-scaled
    eigen-decomposition of F gives accurately; it is infinite exactly when a bound is (an uninformed direction).
    """
    crb, crit = batch_criterion(F[None], targets)
    d, lam, V, live = _scaled_eig(F[None])
    d, lam, V = d[0], lam[0], V[0]
    if not (live[0].all() and np.all(d > 0)):
        return Quality(crb[0], float(crit[0]), math.inf, math.inf)
    s = np.ones(F.shape[0]) if scales is None else np.asarray(scales, dtype=float).reshape(F.shape[0])
    cov = (V / lam) @ V.T * np.outer(d / s, d / s)      # the Cramér–Rao covariance in units of the scales
    Fs = F * np.outer(s, s)
    big = float(np.linalg.eigvalsh((cov + cov.T) / 2)[-1])
    top = float(np.linalg.eigvalsh((Fs + Fs.T) / 2)[-1])
    return Quality(crb[0], float(crit[0]), math.sqrt(big), math.sqrt(max(big * top, 1.0)))


def all_subsets(information: np.ndarray, costs: np.ndarray, targets: Sequence[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every nonempty subset of the candidates (as bit masks), its cost and its criterion."""
    nc = information.shape[0]
    masks = np.arange(1, 1 << nc, dtype=np.int64)
    bits = ((masks[:, None] >> np.arange(nc)) & 1).astype(float)
    flat = information.reshape(nc, -1)
    m = information.shape[1]
    crit = np.empty(masks.size)
    for i in range(0, masks.size, _BATCH):
        Fb = (bits[i:i + _BATCH] @ flat).reshape(-1, m, m)
        crit[i:i + _BATCH] = batch_criterion(Fb, targets)[1]
    return masks, bits @ costs, crit


def pareto_front(masks: np.ndarray, costs: np.ndarray, crit: np.ndarray) -> list[int]:
    """Indices of the sets on the cost–quality Pareto front: no other set costs no more and scores higher (among the
    sets with a finite criterion; ties in cost go to the higher score, then the fewer sensors)."""
    size = np.array([bin(int(b)).count("1") for b in masks])
    ok = np.flatnonzero(np.isfinite(crit))
    order = ok[np.lexsort((size[ok], -crit[ok], costs[ok]))]
    front, best = [], -np.inf
    for i in order:
        if not front or crit[i] > best + 1e-9 * max(1.0, abs(best)):
            front.append(int(i))
            best = crit[i]
    return front


def greedy_path(information: np.ndarray, costs: np.ndarray, prior: np.ndarray, budget: float,
                per_cost: bool) -> list[list[int]]:
    r"""The greedy sequence of sets maximising :math:`f(S) = \log\det(\Lambda_0 + F_S)` (:math:`\Lambda_0` = `prior`,
    the prior information, positive definite): each step adds the candidate of largest gain (per unit cost when
    `per_cost`) that keeps the cost within `budget`. f is monotone submodular, so with equal costs the set of k
    sensors is within (1 − 1/e) of the best k (Nemhauser, Wolsey & Fisher (1978); Summers, Cortesi & Lygeros (2016)).
    """
    nc = information.shape[0]
    chosen: list[int] = []
    path: list[list[int]] = []
    cur = prior.copy()
    spent = 0.0
    base = np.linalg.slogdet(cur)[1]
    while len(chosen) < nc:
        best, best_score, best_val = -1, -np.inf, base
        for c in range(nc):
            if c in chosen or spent + costs[c] > budget * (1 + 1e-12):
                continue
            val = np.linalg.slogdet(cur + information[c])[1]
            gain = val - base
            score = gain / costs[c] if per_cost and costs[c] > 0 else (np.inf if per_cost and gain > 0 else gain)
            if score > best_score:
                best, best_score, best_val = c, score, val
        if best < 0:
            break
        chosen.append(best)
        spent += costs[best]
        cur = cur + information[best]
        base = best_val
        path.append(list(chosen))
    return path


GREEDY_GUARANTEE = (f"with equal costs the greedy set of k sensors reaches at least (1 − 1/e) of the best log det(Λ₀ + F) "
                    f"gain of any k sensors ({cite('nemhauser1978')}; log det is submodular: {cite('summers2016')}); with "
                    f"costs, the better of the cost-benefit and the plain greedy sets reaches at least ½(1 − 1/e) "
                    f"({cite('leskovec2007')})")
