"""observer/_rate.FlowRate: the first interval's rate, the spectral radius of ∂F/∂z. Above 64 internal states it is
estimated by power iteration on Jacobian-vector products (no n x n Jacobian is built); the reference here is the
eigenvalues of the matrix A - LC itself (a Luenberger observer: ∂F/∂z = A - LC exactly)."""

from __future__ import annotations

import numpy as np
import pytest

import nlobs
from nlobs.design import design_luenberger
from nlobs.engine._intervals import EXACT_RATE_MAX
from nlobs.observer._rate import FlowRate


def _chain(n: int, fast: float):
    """x1' = -fast*x1 + x2, x_i' = -x_i + x_{i+1}, ..., y = x1: A - LC with L = (l, 0, ..., 0) has the eigenvalues of
    a bidiagonal matrix with a one-entry change in its first column (computed below by NumPy)."""
    f = [f"-{fast}*x1 + x2"] + [f"-x{i} + x{i + 1}" for i in range(2, n)] + [f"-x{n}"]
    sys_ = nlobs.System(states=[f"x{i}" for i in range(1, n + 1)], f=f, outputs=["y"], h=["x1"], name=f"chain{n}")
    L = np.zeros((n, 1))
    L[0, 0] = 2.0
    A = np.diag([-fast] + [-1.0] * (n - 1)) + np.diag(np.ones(n - 1), 1)
    C = np.zeros((1, n))
    C[0, 0] = 1.0
    return sys_, L, float(np.max(np.abs(np.linalg.eigvals(A - L @ C))))


@pytest.mark.parametrize("n", [12, 80])
def test_the_rate_is_the_spectral_radius_of_the_observer_matrix(n):
    sys_, L, want = _chain(n, fast=40.0)
    d = design_luenberger(sys_, L=L, xhat0=np.zeros(n))
    rate = FlowRate(d)
    assert (n > EXACT_RATE_MAX) == (n == 80)
    got = rate(0.0, np.linspace(-1, 1, n), np.zeros(0), np.array([0.3]))
    # exact eigenvalues up to 64 states; the power iteration's geometric mean over its last 24 steps above (a
    # dominant eigenvalue 42 against 1: converged to round-off)
    assert got == pytest.approx(want, rel=1e-9 if n <= EXACT_RATE_MAX else 1e-6)
    assert rate(0.0, np.linspace(-1, 1, n), np.zeros(0), np.array([0.3])) == got   # the last point kept


def test_a_point_that_is_not_finite_has_rate_0():
    sys_, L, _ = _chain(80, fast=40.0)
    z = np.zeros(80)
    z[3] = np.nan
    assert FlowRate(design_luenberger(sys_, L=L, xhat0=np.zeros(80)))(0.0, z, np.zeros(0), np.array([0.0])) == 0.0


def test_one_rate_per_design_shared_by_the_prepared_and_the_online_observers():
    from nlobs.observer._compiled import compiled_observer
    from nlobs.observer._rate import flow_rate

    sys_, L, want = _chain(12, fast=40.0)
    d = design_luenberger(sys_, L=L, xhat0=np.zeros(12))
    assert compiled_observer(d).rate is flow_rate(d) is flow_rate(d)
    assert nlobs.Observer(d).rate(0.0, np.zeros(12), np.zeros(0), np.array([0.0])) == pytest.approx(want, rel=1e-9)
