"""Observability of linear pairs (A, C): Kalman rank, unobservable directions, PBH test, Kalman decomposition."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import ShapeError
from .._reports import clean_direction as _clean
from .._reports import fmt_directions

__all__ = ["observability_matrix", "LinearObservability", "kalman_rank", "pbh_test", "PBHResult",
           "KalmanDecomposition", "kalman_decomposition", "check_pair"]


def check_pair(A: Any, C: Any, caller: str) -> tuple[np.ndarray, np.ndarray]:
    """Validate a pair (A, C): A square and finite, C with n columns (a 1-D C is one output row)."""
    try:
        A_ = np.array(A, dtype=float)
        C_ = np.array(C, dtype=float)
    except (TypeError, ValueError) as e:
        raise ShapeError(f"{caller}: `A` and `C` must be numeric matrices: {e}") from None
    if A_.ndim != 2 or A_.shape[0] != A_.shape[1]:
        raise ShapeError(f"{caller}: `A` must be a square matrix, found shape {A_.shape}")
    n = A_.shape[0]
    C_ = np.atleast_2d(C_)
    if C_.ndim != 2 or C_.shape[1] != n:
        raise ShapeError(f"{caller}: incompatible dimensions of `C`: expected (p, {n}) for {n} states, found {C_.shape}")
    for name, M in (("A", A_), ("C", C_)):
        if not np.all(np.isfinite(M)):
            raise ShapeError(f"{caller}: `{name}` has non-finite entries")
    return A_, C_


def observability_matrix(A: np.ndarray, C: np.ndarray) -> np.ndarray:
    r"""The observability matrix :math:`\mathcal O = [C; CA; \dots; CA^{n-1}]`.

    Parameters
    ----------
    A : array_like of shape (n, n)
    C : array_like of shape (p, n)
    """
    A, C = check_pair(A, C, "observability_matrix")
    blocks = [C]
    for _ in range(A.shape[0] - 1):
        blocks.append(blocks[-1] @ A)
    return np.vstack(blocks)


def _rank_tol(M: np.ndarray, s: np.ndarray) -> float:
    return float(s.max(initial=0.0) * max(M.shape) * np.finfo(float).eps * 10)


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
        dirs = fmt_directions(self.unobservable_directions)
        return f"(A, C) is not observable: rank {self.rank} < {self.n}; unobservable direction(s) {dirs}"


def kalman_rank(A: np.ndarray, C: np.ndarray) -> LinearObservability:
    """Kalman rank test of (A, C), with a basis of the unobservable subspace.

    Parameters
    ----------
    A : array_like of shape (n, n)
    C : array_like of shape (p, n)

    References
    ----------
    Besançon (2010), "Result [Luenberger]": an observer with arbitrary rate exists
    iff (A, C) is observable.
    """
    A, C = check_pair(A, C, "kalman_rank")
    O = observability_matrix(A, C)
    n = A.shape[0]
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
    A, C = check_pair(A, C, "pbh_test")
    n = A.shape[0]
    lams = np.linalg.eigvals(A)
    ranks = []
    for lam in lams:
        M = np.vstack([A - lam * np.eye(n), C])
        s = np.linalg.svd(M, compute_uv=False)
        ranks.append(int(np.sum(s > _rank_tol(M, s) * 100)))
    return PBHResult(lams, np.array(ranks), n)


@dataclass(frozen=True, eq=False)
class KalmanDecomposition:
    r"""Observable/unobservable (Kalman) decomposition of (A, C).

    With the orthogonal :math:`T = [T_o\;T_{\bar o}]`, :math:`T_{\bar o}` a basis of ker O and
    :math:`z = T^\top x`,

    .. math::

        T^\top A T = \begin{pmatrix} A_o & 0 \\ A_{21} & A_{\bar o} \end{pmatrix}, \qquad
        C T = \begin{pmatrix} C_o & 0 \end{pmatrix},

    and :math:`(A_o, C_o)` is observable: only :math:`z_o = T_o^\top x` reaches the output.

    Attributes
    ----------
    T : numpy.ndarray of shape (n, n)
        Orthogonal; its first `n_observable` columns span the observable subspace (ker O)^⊥.
    A_bar, C_bar : numpy.ndarray
        :math:`T^\top A T` and :math:`C T` (the upper-right block of A_bar and the right block of C_bar are zero up to round-off).
    n_observable : int
    A_o, C_o, A_unobs : numpy.ndarray
        The observable pair and the unobservable block.
    unobservable_eigenvalues : numpy.ndarray
        Eigenvalues of :math:`A_{\bar o}`: the modes the output never sees (detectable iff all are stable).
    """

    T: np.ndarray
    A_bar: np.ndarray
    C_bar: np.ndarray
    n_observable: int

    @property
    def A_o(self) -> np.ndarray:
        k = self.n_observable
        return self.A_bar[:k, :k]

    @property
    def C_o(self) -> np.ndarray:
        return self.C_bar[:, : self.n_observable]

    @property
    def A_unobs(self) -> np.ndarray:
        k = self.n_observable
        return self.A_bar[k:, k:]

    @property
    def unobservable_eigenvalues(self) -> np.ndarray:
        return np.linalg.eigvals(self.A_unobs) if self.A_unobs.size else np.zeros(0)

    @property
    def detectable(self) -> bool:
        return bool(np.all(self.unobservable_eigenvalues.real < 0))

    def __str__(self) -> str:
        n = self.T.shape[0]
        if self.n_observable == n:
            return f"Kalman decomposition: (A, C) is observable; all {n} states are in the observable part"
        eig = ", ".join(f"{complex(v):.4g}" for v in self.unobservable_eigenvalues)
        return (f"Kalman decomposition: observable part of dimension {self.n_observable} of {n}; unobservable modes {eig} "
                f"({'all stable: detectable' if self.detectable else 'not detectable'})")


def kalman_decomposition(A: Any, C: Any) -> KalmanDecomposition:
    """Split the state into an observable and an unobservable part (orthogonal change of coordinates).

    Raises
    ------
    ShapeError
        If A is not square or C does not have n columns.

    References
    ----------
    Besançon (2010), "Summary": a system that fails the rank condition can be written as
    ζ1' = f1(ζ1, ζ2, u), ζ2' = f2(ζ2, u), y = h2(ζ2) with the ζ2 part observable; this is the linear case.
    """
    A, C = check_pair(A, C, "kalman_decomposition")
    res = kalman_rank(A, C)
    _, _, Vt = np.linalg.svd(observability_matrix(A, C))
    T = Vt.T  # first `rank` columns: row space of O; the rest: ker O
    A_bar = T.T @ A @ T
    C_bar = C @ T
    k = res.rank
    A_bar[:k, k:] = np.where(np.abs(A_bar[:k, k:]) < 1e-10 * max(1.0, np.abs(A).max()), 0.0, A_bar[:k, k:])
    C_bar[:, k:] = np.where(np.abs(C_bar[:, k:]) < 1e-10 * max(1.0, np.abs(C).max()), 0.0, C_bar[:, k:])
    return KalmanDecomposition(T, A_bar, C_bar, k)
