"""The robust Kalman family: square-root UKF and EKF, iterated EKF (issue 22, item 3).

Reference values come from the existing covariance-form filters (design_ukf, design_ekf: independent code,
P integrated by its Riccati/Särkkä ODE and updated in covariance form), on cases where both are the same
filter in exact arithmetic.
"""

import numpy as np
import pytest

import nlobs
from nlobs.design import design_ekf, design_ukf
from nlobs.design.kalman._iekf import design_iekf
from nlobs.design.kalman._srekf import design_srekf
from nlobs.design.kalman._srukf import design_srukf
from nlobs.errors import FiniteEscapeError, PreconditionError

LTI = nlobs.System.lti([[0.0, 1.0], [-2.0, -0.5]], None, [[1.0, 0.0]])
VDP = nlobs.System(states=["x1", "x2"], f=["x2", "(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"])
# a strongly nonlinear measurement: ranges of a point from two stations at (0, 0) and (2, 0)
RANGE = nlobs.System(states=["px", "py"], f=["0", "0"], outputs=["r1", "r2"],
                     h=["sqrt(px**2 + py**2)", "sqrt((px - 2)**2 + py**2)"])
P0 = np.diag([0.2, 0.1])


def _pair(system, a, b, **kw):
    return nlobs.simulate(system, {"a": a, "b": b}, dt=1e-3, x0=[1.0, 0.0], noise=nlobs.Noise.gaussian(0.1),
                          sampling=nlobs.Sampling(0.05), seed=0, **kw)


# -- square-root UKF -------------------------------------------------------------------------------
def test_srukf_measurement_update_is_the_ukf_update_to_round_off():
    # nonlinear dynamics, a sample where the prior is the same for both: the QR update must give the
    # UKF's m + K(y - ŷ) and P - K S Kᵀ (which the UKF computes in covariance form)
    su, u = nlobs.Observer(design_srukf(VDP, Q=0.01 * np.eye(2), R=[[0.01]], P0=P0)), \
        nlobs.Observer(design_ukf(VDP, Q=0.01 * np.eye(2), R=[[0.01]], P0=P0))
    a = su.update(0.0, su.initial_state([0.5, -0.3]), None, [1.3])
    b = u.update(0.0, u.initial_state([0.5, -0.3]), None, [1.3])
    np.testing.assert_allclose(su.estimate(0.0, a), b[:2], rtol=0, atol=1e-14)
    np.testing.assert_allclose(np.array(su.design.covariance(a)), np.array(u.design.covariance(b)), rtol=0, atol=1e-14)
    assert not np.allclose(b[:2], [0.5, -0.3])  # the update moved the estimate


def test_srukf_equals_the_ukf_on_a_linear_model():
    # linear f, Q = 0: propagating the sigma points through the flow is the UKF's moment ODE exactly
    run = _pair(LTI, design_srukf(LTI, Q=np.zeros((2, 2)), R=[[0.01]], P0=P0),
                design_ukf(LTI, Q=np.zeros((2, 2)), R=[[0.01]], P0=P0), t_final=5.0)
    np.testing.assert_allclose(run.observers["a"].xhat, run.observers["b"].xhat, rtol=0, atol=1e-11)


def test_srukf_survives_a_tiny_R_where_the_ukf_fails():
    # R = 1e-10 on the measured position: after the first update P is nearly singular, and the UKF's
    # Cholesky factorisation of the RK4 stage covariance fails (non-finite); the square-root form never factorises
    kw = dict(Q=np.diag([0.0, 1e-2]), R=[[1e-10]])
    sim = dict(t_final=50.0, dt=1e-2, x0=[1.0, 0.0], noise=nlobs.Noise.gaussian(1e-5), sampling=nlobs.Sampling(0.01),
               seed=0, xhat0=[0.5, 0.5])
    with pytest.raises(FiniteEscapeError, match="observer 'o'"):
        nlobs.simulate(VDP, {"o": design_ukf(VDP, **kw)}, **sim)
    d = design_srukf(VDP, **kw)
    run = nlobs.simulate(VDP, {"o": d}, **sim)
    z = run.observers["o"].z
    assert z.shape[0] == 5001 and np.all(np.isfinite(z))
    err = np.abs(run.observers["o"].xhat - run.x)[100:]
    assert err[:, 0].max() < 1e-4 and err[:, 1].max() < 0.05
    P = np.array(d.covariance(z[-1]))
    assert np.linalg.eigvalsh(P).min() > 0 and P[0, 0] < 1e-9


def test_srukf_refuses_negative_weights():
    with pytest.raises(PreconditionError, match="non-negative weights"):
        design_srukf(VDP, Q=np.eye(2), R=[[1.0]], alpha=0.5, beta=2.0)


# two outputs of the same coordinate (a GPS height and a barometer both see pz): the predicted outputs are correlated,
# so the factor Sy of S = Sy Syᵀ is not diagonal, and K = Pxy (Sy Syᵀ)⁻¹ needs Sy⁻ᵀ Sy⁻¹, not Sy⁻¹ Sy⁻¹
TWIN = nlobs.System(states=["z", "w", "v"], f=["w", "-z", "-v"], outputs=["gps", "baro", "both"],
                    h=["z", "z + 0.1*sin(w)", "z + v"], name="twin")
P3 = np.array([[0.5, 0.1, 0.05], [0.1, 0.3, 0.0], [0.05, 0.0, 0.2]])


@pytest.mark.parametrize("square_root, reference", [(design_srukf, design_ukf), (design_srekf, design_ekf)],
                         ids=["srukf", "srekf"])
def test_square_root_update_with_correlated_outputs_is_the_covariance_update(square_root, reference):
    kw = dict(Q=np.zeros((3, 3)), R=np.diag([0.04, 0.01, 0.02]), P0=P3)
    a, b = nlobs.Observer(square_root(TWIN, **kw)), nlobs.Observer(reference(TWIN, **kw))
    x0, y = [0.3, -0.2, 0.1], [0.9, 0.7, 0.2]
    za, zb = a.update(0.0, a.initial_state(x0), None, y), b.update(0.0, b.initial_state(x0), None, y)
    np.testing.assert_allclose(a.estimate(0.0, za), b.estimate(0.0, zb), rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.array(a.design.covariance(za)), np.array(b.design.covariance(zb)), rtol=0, atol=1e-13)


# -- square-root EKF -------------------------------------------------------------------------------
@pytest.mark.parametrize("system", [LTI, VDP], ids=["linear", "van der Pol"])
def test_srekf_equals_the_ekf_without_process_noise(system):
    # Q = 0: G = ΦS carries P = ΦPΦᵀ exactly, and the QR Joseph update is the EKF's Joseph update
    run = _pair(system, design_srekf(system, Q=np.zeros((2, 2)), R=[[0.01]], P0=P0),
                design_ekf(system, Q=np.zeros((2, 2)), R=[[0.01]], P0=P0), t_final=3.0)
    np.testing.assert_allclose(run.observers["a"].xhat, run.observers["b"].xhat, rtol=0, atol=1e-11)


def _covariance_gaps(square_root, reference):
    """Relative gap between the last covariances of a square-root filter and its covariance-form reference
    (same tuning, Q ≠ 0) on the linear model, sampled every 0.1 and every 0.05."""
    gaps = []
    for ts in (0.1, 0.05):
        a = square_root(LTI, Q=0.1 * np.eye(2), R=[[0.01]], P0=P0)
        run = nlobs.simulate(LTI, {"a": a, "b": reference(LTI, Q=0.1 * np.eye(2), R=[[0.01]], P0=P0)},
                             t_final=3.0, dt=1e-3, x0=[1.0, 0.0], noise=nlobs.Noise.gaussian(0.1),
                             sampling=nlobs.Sampling(ts), seed=0)
        Pa = np.array([np.array(a.covariance(z)) for z in run.observers["a"].z[-5:]])
        Pb = run.observers["b"].z[-5:, 2:].reshape(-1, 2, 2, order="F")
        gaps.append(np.abs(Pa - Pb).max() / np.abs(Pb).max())
    return gaps


def test_srekf_process_noise_by_the_trapezoid_rule():
    # with Q the prediction differs from the Riccati ODE by the trapezoid rule's O(τ³) per interval:
    # halving the sampling interval must shrink the difference about 4x (global O(τ²))
    gaps = _covariance_gaps(design_srekf, design_ekf)
    assert 2.5 < gaps[0] / gaps[1] < 6.0, gaps


# -- iterated EKF ----------------------------------------------------------------------------------
def test_iekf_with_one_iteration_is_the_ekf():
    kw = dict(Q=0.01 * np.eye(2), R=[[0.01]], P0=P0)
    run = _pair(VDP, design_iekf(VDP, iterations=1, **kw), design_ekf(VDP, **kw), t_final=3.0)
    np.testing.assert_allclose(run.observers["a"].z, run.observers["b"].z, rtol=0, atol=1e-13)


def test_iekf_beats_the_ekf_on_ranges():
    # start 3.6 away with ranges accurate to 1e-2: the EKF's single linearisation overshoots, Gauss-Newton
    # iterations reach the posterior mode at the first sample
    kw = dict(Q=1e-6 * np.eye(2), R=1e-4 * np.eye(2), P0=4 * np.eye(2))
    e, i = design_ekf(RANGE, **kw), design_iekf(RANGE, iterations=10, **kw)
    err_e, err_i = [], []
    for seed in range(5):
        run = nlobs.simulate(RANGE, {"e": e, "i": i}, t_final=0.3, dt=0.1, x0=[3.0, 4.0], noise=nlobs.Noise.gaussian(1e-2),
                             sampling=nlobs.Sampling(0.1), seed=seed, xhat0=[1.0, 1.0])
        err_e.append(np.abs(run.observers["e"].xhat - run.x).max())
        err_i.append(np.abs(run.observers["i"].xhat - run.x)[1:].max())
    assert np.mean(err_i) < 0.05 and np.mean(err_e) > 10 * np.mean(err_i), (err_e, err_i)


def test_iekf_options_are_checked():
    with pytest.raises(PreconditionError, match="iterations"):
        design_iekf(VDP, Q=np.eye(2), R=[[1.0]], iterations=0)
    with pytest.raises(PreconditionError, match="tol"):
        design_iekf(VDP, Q=np.eye(2), R=[[1.0]], tol=-1.0)


def test_srukf_process_noise_is_first_order_in_the_interval():
    # Q·τ added at the end of an interval differs from the UKF's ∫ΦQΦᵀ by O(τ²) per interval: halving
    # the sampling interval at least halves the covariance gap (without the Q·τ term the gap would not shrink)
    gaps = _covariance_gaps(design_srukf, design_ukf)
    assert gaps[0] < 0.05 and gaps[0] / gaps[1] > 1.8, gaps


def test_iekf_update_is_gauss_newton():
    # an independent NumPy transcription of Bell & Cathey (1993): iterate, then the Joseph form with the last K, H
    P = np.array([[4.0, 0.5], [0.5, 3.0]])
    R = 1e-4 * np.eye(2)
    xm, y = np.array([1.0, 1.0]), np.array([5.0, np.hypot(1.0, 4.0)])

    def hH(x):
        d1, d2 = np.hypot(*x), np.hypot(x[0] - 2, x[1])
        return np.array([d1, d2]), np.array([[x[0] / d1, x[1] / d1], [(x[0] - 2) / d2, x[1] / d2]])

    xi = xm.copy()
    for _ in range(8):
        hi, H = hH(xi)
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        xi = xm + K @ (y - hi - H @ (xm - xi))
    IKH = np.eye(2) - K @ H
    P_plus = IKH @ P @ IKH.T + K @ R @ K.T
    d = design_iekf(RANGE, Q=np.zeros((2, 2)), R=R, P0=P, iterations=8, tol=0.0)
    z = nlobs.Observer(d).update(0.0, np.concatenate([xm, P.reshape(-1)]), None, y)
    np.testing.assert_allclose(z[:2], xi, rtol=0, atol=1e-12)
    np.testing.assert_allclose(z[2:].reshape(2, 2), P_plus, rtol=0, atol=1e-12)
    assert np.abs(xi - [3.0, 4.0]).max() < 1e-3  # near the true point (exact ranges, a weak prior)
