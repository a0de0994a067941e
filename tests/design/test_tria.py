"""design/kalman/_sqrt.tria: L lower triangular with a non-negative diagonal and L Lᵀ = A Aᵀ. The reference is
NumPy's Cholesky factor of A Aᵀ (unique for a full-row-rank A) and, for rank-deficient blocks, A Aᵀ itself."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nlobs.design.kalman._sqrt import tria


def _tria_numeric(A: np.ndarray, pattern: np.ndarray | None = None) -> np.ndarray:
    """tria of a symbolic block, with structural zeros where `pattern` is False, evaluated at A."""
    n, k = A.shape
    x = ca.SX.sym("A", n, k)
    S = ca.SX.zeros(n, k)   # entries never set stay structural zeros
    for i in range(n):
        for j in range(k):
            if pattern is None or pattern[i, j]:
                S[i, j] = x[i, j]
    return np.array(ca.Function("tria", [x], [tria(S)])(A))


@pytest.mark.parametrize("n,k", [(24, 73), (5, 5), (4, 9), (6, 3)])
def test_a_full_block_gives_the_cholesky_factor(n, k):
    rng = np.random.default_rng(n * 100 + k)
    A = rng.normal(size=(n, k))
    L = _tria_numeric(A)
    assert np.array_equal(L, np.tril(L)) and (np.diag(L) >= 0).all()
    np.testing.assert_allclose(L @ L.T, A @ A.T, atol=1e-12 * np.abs(A @ A.T).max())
    if k >= n:
        np.testing.assert_allclose(L, np.linalg.cholesky(A @ A.T), atol=1e-11 * np.abs(A).max())


def test_structural_zeros_a_zero_row_and_a_row_already_triangular():
    rng = np.random.default_rng(7)
    n, k = 6, 10
    pattern = rng.random((n, k)) < 0.6
    pattern[2, :] = False            # a zero row
    pattern[0, 1:] = False           # a row with only its diagonal (negative below: its column's sign flips)
    pattern[0, 0] = True
    A = np.where(pattern, rng.normal(size=(n, k)), 0.0)
    A[0, 0] = -abs(A[0, 0]) - 0.5
    L = _tria_numeric(A, pattern)
    assert np.array_equal(L, np.tril(L)) and (np.diag(L) >= 0).all()
    np.testing.assert_allclose(L @ L.T, A @ A.T, atol=1e-12 * np.abs(A @ A.T).max())
    assert np.all(L[2, :] == 0)


def test_a_row_of_numeric_zeros_in_a_full_block():
    """A row that is zero in value, not in structure: its reflection has ‖v‖² = 0, and β must come out 0, not 0/0."""
    rng = np.random.default_rng(11)
    A = rng.normal(size=(5, 8))
    A[1, :] = 0.0
    A[3, 3:] = 0.0   # a row zero right of its diagonal entry
    L = _tria_numeric(A)
    assert np.isfinite(L).all()
    assert np.array_equal(L, np.tril(L)) and (np.diag(L) >= 0).all()
    np.testing.assert_allclose(L @ L.T, A @ A.T, atol=1e-12 * np.abs(A @ A.T).max())
    assert np.all(L[1, :] == 0)


def test_no_conditional_operation_reaches_the_products():
    """The signs and β are arithmetic on comparisons: an ``if_else`` there was carried by CasADi into every product
    it entered, one conditional (a branch in the generated C) per updated entry: 18,266 of the 24 x 73 block's
    96,792 operations."""
    A = ca.SX.sym("A", 24, 73)
    f = ca.Function("tria", [A], [tria(A)])
    ops = [f.instruction_id(k) for k in range(f.n_instructions())]
    assert ops.count(ca.OP_IF_ELSE_ZERO) == 0
    assert len(ops) < 96_792 - 18_000
