"""Observability of linear pairs (A, C): Kalman rank, unobservable directions, PBH test."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["observability_matrix", "LinearObservability", "kalman_rank", "pbh_test", "PBHResult"]


def observability_matrix(A: np.ndarray, C: np.ndarray) -> np.ndarray:
    r"""The observability matrix :math:`\mathcal O = [C; CA; \dots; CA^{n-1}]`.

    Parameters
    ----------
    A : array_like of shape (n, n)
    C : array_like of shape (p, n)
    """
    A = np.asarray(A, dtype=float)
    C = np.atleast_2d(np.asarray(C, dtype=float))
    blocks = [C]
    for _ in range(A.shape[0] - 1):
        blocks.append(blocks[-1] @ A)
    return np.vstack(blocks)


def _rank_tol(M: np.ndarray, s: np.ndarray) -> float:
    return float(s.max(initial=0.0) * max(M.shape) * np.finfo(float).eps * 10)


def _clean(v: np.ndarray) -> np.ndarray:
    """A unit vector with its largest entry positive and round-off zeros removed (for messages)."""
    v = v / np.linalg.norm(v)
    v = v * np.sign(v[np.argmax(np.abs(v))])
    v[np.abs(v) < 1e-12] = 0.0
    return v + 0.0


@dataclass(frozen=True, eq=False)
class LinearObservability:
    """Result of the Kalman rank test.

    Attributes
    ----------
    rank : int
        Rank of the observability matrix.
    n : int
        State dimension.
    observable : bool
        ``rank == n``.
    unobservable_directions : numpy.ndarray of shape (n - rank, n)
        An orthonormal basis of ker O, one direction per row.
    singular_values : numpy.ndarray
        Singular values of O (how close to unobservable the pair is).
    """

    rank: int
    n: int
    observable: bool
    unobservable_directions: np.ndarray
    singular_values: np.ndarray

    def __str__(self) -> str:
        if self.observable:
            return f"(A, C) is observable: rank O = {self.rank} = n; smallest singular value {self.singular_values[-1]:.3g}"
        dirs = "; ".join(np.array2string(_clean(v), precision=4, separator=", ") for v in self.unobservable_directions)
        return f"(A, C) is not observable: rank {self.rank} < {self.n}; unobservable direction(s) {dirs}"


def kalman_rank(A: np.ndarray, C: np.ndarray) -> LinearObservability:
    """Kalman rank test of (A, C), with a basis of the unobservable subspace.

    Parameters
    ----------
    A : array_like of shape (n, n)
    C : array_like of shape (p, n)

    References
    ----------
    002_613af42269ea26a7.txt, "Result [Luenberger]": an observer with arbitrary rate exists
    iff (A, C) is observable.
    """
    O = observability_matrix(A, C)
    n = np.asarray(A).shape[0]
    _, s, Vt = np.linalg.svd(O)
    rank = int(np.sum(s > _rank_tol(O, s)))
    kernel = np.array([_clean(v) for v in Vt[rank:]]).reshape(-1, n)
    return LinearObservability(rank, n, rank == n, kernel, s)


@dataclass(frozen=True, eq=False)
class PBHResult:
    """Popov-Belevitch-Hautus test: for each eigenvalue λ of A, rank [A - λI; C]."""

    eigenvalues: np.ndarray
    ranks: np.ndarray
    n: int

    @property
    def unobservable_eigenvalues(self) -> np.ndarray:
        return self.eigenvalues[self.ranks < self.n]

    @property
    def observable(self) -> bool:
        return bool(np.all(self.ranks == self.n))

    @property
    def detectable(self) -> bool:
        """Every unobservable mode is stable (Re λ < 0)."""
        return bool(np.all(self.unobservable_eigenvalues.real < 0))

    def __str__(self) -> str:
        bad = self.unobservable_eigenvalues
        if bad.size == 0:
            return "PBH: every mode is observable"
        return "PBH: unobservable mode(s) at " + ", ".join(f"{complex(l):.4g}" for l in bad) + (
            " (all stable: detectable)" if self.detectable else " (not detectable)")


def pbh_test(A: np.ndarray, C: np.ndarray) -> PBHResult:
    """PBH rank test: rank [A - λI; C] at every eigenvalue λ of A.

    Parameters
    ----------
    A : array_like of shape (n, n)
    C : array_like of shape (p, n)
    """
    A = np.asarray(A, dtype=float)
    C = np.atleast_2d(np.asarray(C, dtype=float))
    n = A.shape[0]
    lams = np.linalg.eigvals(A)
    ranks = []
    for lam in lams:
        M = np.vstack([A - lam * np.eye(n), C])
        s = np.linalg.svd(M, compute_uv=False)
        ranks.append(int(np.sum(s > _rank_tol(M, s) * 100)))
    return PBHResult(lams, np.array(ranks), n)
