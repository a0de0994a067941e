"""Square-root building blocks for the square-root Kalman filters (symbolic, CasADi SX).

- :func:`tria`: a lower-triangular L with L Lᵀ = A Aᵀ, by Householder reflections (the R factor of the QR
  decomposition of Aᵀ, transposed; Arasaratnam & Haykin (2009) call it Tria). P = L Lᵀ is never formed.
- :func:`lower_solve`: L⁻¹ B by forward substitution; :func:`lower_t_solve`: L⁻ᵀ B by back substitution (a gain
  K = C (L Lᵀ)⁻¹ is (L⁻ᵀ (L⁻¹ Cᵀ))ᵀ: one of each).
- :func:`phi`: Φ(A), the lower triangle of A with half its diagonal (Särkkä (2007), eq. of the square-root
  continuous-time UKF): with Ṡ = S Φ(S⁻¹ M S⁻ᵀ), d(SSᵀ)/dt = M for symmetric M.
- :func:`sqrt_psd`: a numerical square root of a positive semidefinite matrix (Cholesky when definite).
- :func:`covariance_checks`: the common checks of Q, R, P0.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from .._base import Check
from .._checks import check_matrix

__all__ = ["tria", "lower_solve", "lower_t_solve", "phi", "sqrt_psd", "covariance_inputs", "unpack_lower", "pack_lower"]


def tria(A: ca.SX) -> ca.SX:
    """Lower-triangular L (n x n, non-negative diagonal) with L Lᵀ = A Aᵀ for A of shape (n, k), k >= n.

    Householder reflections of the columns of A zero row i right of the diagonal, for i = 0..n-1 (the QR
    decomposition of Aᵀ, Golub & Van Loan (2013), Algorithm 5.2.1, transposed); each reflection is orthogonal, so
    A Aᵀ is unchanged, and a column of L whose diagonal came out negative is negated. A row already zero right of
    its diagonal is left alone, and so are structural zeros. One square root per row: Givens rotations took one per
    entry, and on a 24 x 73 block (the square-root UKF's time update for 24 states) 135,554 operations that compiled
    in 19 s and ran in 85 µs, against 96,792 operations, 10 s and 25 µs here (78,524 operations since the signs
    and β are arithmetic, see :func:`_sign`).

    Each reflection is applied to the rows below as two matrix products (CasADi's SX arithmetic drops a product with
    a zero and a sum with zero as it builds them, so the structural zeros cost nothing): as many operations as a
    loop over the entries (94,364 on a 24 x 73 block with half its entries zero, with the signs as ``if_else``),
    built 30x faster.
    """
    n, k = A.shape
    if k < n:
        A = ca.horzcat(A, ca.SX.zeros(n, n - k))
        k = n
    M = ca.densify(ca.SX(A))
    for i in range(n):
        row = M[i, i:]
        nonzero = [j for j in range(k - i) if not ca.is_equal(row[j], 0)]
        if not nonzero or nonzero == [0]:   # nothing right of the diagonal: no reflection (its sign is fixed below)
            continue
        a = row[0]
        sig = ca.dot(row, row)
        alpha = -_sign(a) * ca.sqrt(sig)   # the new diagonal; its sign avoids cancellation in v_i
        v = ca.SX(row.T)
        v[0] = a - alpha
        vtv = sig - a * a + v[0] * v[0]                       # ‖v‖² = 2‖x‖² + 2|a|‖x‖: 0 only when the row is 0
        nz = vtv > 0                                          # 2/‖v‖², and 0 for a zero row (then v = 0 too)
        beta = (2 * nz) / (vtv + (1 - nz))
        if i + 1 < n:   # (I - β v vᵀ) applied from the right to the rows below
            below = M[i + 1:, i:]
            M[i + 1:, i:] = below - ca.mtimes(beta * ca.mtimes(below, v), v.T)
        M[i, i:] = ca.horzcat(alpha, ca.SX.zeros(1, k - i - 1))
    L = ca.SX.zeros(n, n)
    for j in range(n):   # a column whose diagonal came out negative is negated
        L[j:, j] = _sign(M[j, j]) * M[j:, j]
    return L


def _sign(x: ca.SX) -> ca.SX:
    """1 where x >= 0, else -1, as arithmetic on the comparison (0 or 1). Not ``if_else``: CasADi carries an
    ``if_else`` factor into every product it enters, so a reflection's β = if_else(‖v‖² > 0, …) became one
    conditional per entry of the rows it updates (18,266 of a 24 x 73 block's 96,792 operations, each a branch in
    the generated C)."""
    return 2 * (x >= 0) - 1


def lower_solve(L: ca.SX, B: ca.SX) -> ca.SX:
    """L⁻¹ B for a lower-triangular L, by forward substitution (no symbolic factorisation)."""
    n = L.shape[0]
    X = ca.SX.zeros(n, B.shape[1])
    for c in range(B.shape[1]):
        xs: list[ca.SX] = []
        for i in range(n):
            acc = B[i, c]
            for j in range(i):
                if not ca.is_equal(L[i, j], 0):
                    acc = acc - L[i, j] * xs[j]
            xs.append(acc / L[i, i])
        for i in range(n):
            X[i, c] = xs[i]
    return X


def lower_t_solve(L: ca.SX, B: ca.SX) -> ca.SX:
    """L⁻ᵀ B for a lower-triangular L (Lᵀ is upper triangular), by back substitution."""
    n = L.shape[0]
    X = ca.SX.zeros(n, B.shape[1])
    for c in range(B.shape[1]):
        xs: list[Any] = [None] * n
        for i in reversed(range(n)):
            acc = B[i, c]
            for j in range(i + 1, n):
                if not ca.is_equal(L[j, i], 0):
                    acc = acc - L[j, i] * xs[j]
            xs[i] = acc / L[i, i]
        for i in range(n):
            X[i, c] = xs[i]
    return X


def phi(A: ca.SX) -> ca.SX:
    """Φ(A): the strictly lower triangle of A plus half its diagonal."""
    n = A.shape[0]
    out = ca.SX.zeros(n, n)
    for i in range(n):
        out[i, i] = A[i, i] / 2
        for j in range(i):
            out[i, j] = A[i, j]
    return out


def sqrt_psd(M: np.ndarray) -> np.ndarray:
    """A square root G with G Gᵀ = M: the lower Cholesky factor when M is definite, else from eigenvectors."""
    try:
        return np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh((M + M.T) / 2)
        return V * np.sqrt(np.clip(w, 0, None))


def pack_lower(L: Any) -> ca.SX | ca.DM:
    """The lower triangle of L, column by column (n(n+1)/2 entries)."""
    n = L.shape[0]
    return ca.vertcat(*[L[i, j] for j in range(n) for i in range(j, n)])


def unpack_lower(v: ca.SX, n: int) -> ca.SX:
    """The lower-triangular matrix whose packed lower triangle is `v` (see :func:`pack_lower`)."""
    L = ca.SX.zeros(n, n)
    k = 0
    for j in range(n):
        for i in range(j, n):
            L[i, j] = v[k]
            k += 1
    return L


def lower_names(prefix: str, n: int) -> list[str]:
    return [f"{prefix}_{i}_{j}" for j in range(n) for i in range(j, n)]


def covariance_inputs(Q: Any, R: Any, P0: Any, n: int, p: int, caller: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[Check]]:
    """Q (semidefinite), R, P0 (definite) checked, and the certificate's checks for them."""
    Qm = check_matrix(Q, n, n, "Q", caller, definite="semidefinite")
    Rm = check_matrix(R, p, p, "R", caller, definite="positive")
    P0m = np.eye(n) if P0 is None else check_matrix(P0, n, n, "P0", caller, definite="positive")
    checks = [Check("Q positive semidefinite", True, f"min eig {np.linalg.eigvalsh(Qm).min():.3g}"),
              Check("R positive definite", True, f"min eig {np.linalg.eigvalsh(Rm).min():.3g}"),
              Check("P0 positive definite", True, f"min eig {np.linalg.eigvalsh(P0m).min():.3g}")]
    return Qm, Rm, P0m, checks
