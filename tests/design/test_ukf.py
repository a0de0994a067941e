"""Continuous-discrete UKF (Särkkä 2007): exact on linear models, comparable to the EKF on Van der Pol."""

import numpy as np
import pytest

import nlobs
from nlobs.design import design_ekf, design_ukf
from nlobs.design.kalman._ukf import unscented_weights
from nlobs.errors import PreconditionError

LTI = nlobs.System.lti([[0.0, 1.0], [-2.0, -0.5]], None, [[1.0, 0.0]])
VDP = nlobs.System(states=["x1", "x2"], f=["x2", "(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"])


def test_weights_sum_to_one_and_reproduce_the_covariance():
    for alpha, beta, kappa in ((1.0, 0.0, 0.0), (0.5, 2.0, 1.0)):
        wm, wc, c = unscented_weights(3, alpha, beta, kappa)
        assert wm.sum() == pytest.approx(1.0)
        # Σ Wc_i (X_i - m)(X_i - m)ᵀ = P for the points m ± sqrt(c) L e_i (the centre adds nothing)
        assert 2 * c * wc[1] == pytest.approx(1.0)


def test_linear_model_matches_the_kalman_filter():
    # Two routes agree: on a linear model the unscented transform is exact, so the UKF equals the
    # continuous-discrete (E)KF to round-off, with noise, sampling and an irregular start.
    u = design_ukf(LTI, Q=0.1 * np.eye(2), R=[[0.01]], P0=np.diag([2.0, 0.5]))
    e = design_ekf(LTI, Q=0.1 * np.eye(2), R=[[0.01]], P0=np.diag([2.0, 0.5]), mode="continuous-discrete")
    run = nlobs.simulate(LTI, {"u": u, "e": e}, t_final=5.0, dt=1e-3, x0=[1.0, 0.0], noise=nlobs.Noise.gaussian(0.1),
                         sampling=nlobs.Sampling(0.05), seed=0, engine="vm")
    np.testing.assert_allclose(run.observers["u"].z, run.observers["e"].z, atol=1e-10)


def test_van_der_pol_converges_like_the_ekf():
    u = design_ukf(VDP, Q=0.01 * np.eye(2), R=[[0.01]])
    e = design_ekf(VDP, Q=0.01 * np.eye(2), R=[[0.01]], mode="continuous-discrete")
    run = nlobs.simulate(VDP, {"u": u, "e": e}, t_final=20.0, dt=1e-3, x0=[2.0, 0.0], noise=nlobs.Noise.gaussian(0.1),
                         sampling=nlobs.Sampling(0.01), seed=0, engine="vm")
    mu, me = run.metrics("u").rms_error, run.metrics("e").rms_error
    assert mu < 0.05 and 0.5 < mu / me < 2.0
    P = run.observers["u"].z[:, 2:].reshape(-1, 2, 2, order="F")
    assert np.linalg.eigvalsh(P).min() > 0


def test_missing_outputs_do_not_move_the_estimate():
    u = nlobs.Observer(design_ukf(VDP, Q=0.01 * np.eye(2), R=[[0.01]]))
    z = u.initial_state([0.5, -0.5])
    np.testing.assert_array_equal(u.update(0.0, z, None, [3.0], mask=[0.0])[:2], z[:2])
    assert not np.allclose(u.update(0.0, z, None, [3.0], mask=[1.0])[:2], z[:2])


def test_bad_spread_is_refused():
    with pytest.raises(PreconditionError, match="n \\+ λ"):
        design_ukf(VDP, Q=np.eye(2), R=[[1.0]], alpha=1.0, kappa=-2.0)
