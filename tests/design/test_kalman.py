"""Kalman-Bucy (LTV), Kalman-like (state-affine, forgetting) and LTV-based high-gain Kalman observers (002)."""

import numpy as np
import pytest
import scipy.linalg

import nlobs
from nlobs.design import design_high_gain_kalman, design_kalman_bucy, design_kalman_like
from nlobs.errors import FormError, PreconditionError

A_LTI = np.array([[0.0, 1.0], [-2.0, -0.5]])
C_LTI = np.array([[1.0, 0.0]])
PEND_B = nlobs.System(states=["x1", "x2", "b"], f=["x2", "-a1*sin(x1) - a2*x2 + b*u", "0"], inputs=["u"],
                      outputs=["y"], h=["x1"], params={"a1": 9.81, "a2": 0.5})


def covariances(run, name, n):
    z = run.observers[name].z
    return z[:, n:].reshape(-1, n, n, order="F")


def test_kalman_bucy_reaches_the_lqe_riccati_solution():
    # On an LTI model the Riccati ODE converges to the filter ARE solution (scipy, independent).
    sys = nlobs.System.lti(A_LTI, None, C_LTI)
    d = design_kalman_bucy(sys, Q=0.1 * np.eye(2), R=[[0.01]])
    run = nlobs.simulate(sys, d, t_final=20.0, dt=1e-3, x0=[1.0, 0.0], engine="vm")
    P_are = scipy.linalg.solve_continuous_are(A_LTI.T, C_LTI.T, 0.1 * np.eye(2), 0.01 * np.eye(1))
    np.testing.assert_allclose(covariances(run, "kalman_bucy", 2)[-1], P_are, atol=1e-10)
    assert run.error_norm()[-1] < 1e-8


def test_state_affine_is_read_from_a_system():
    d = design_kalman_like(PEND_B, Q=0.01 * np.eye(3))
    assert d.certificate.values["A(u, y, t)"] == "[[0, 1, 0], [0, -1/2, u], [0, 0, 0]]"
    bad = nlobs.System(states=["x1", "x2"], f=["x2**2", "0"], outputs=["y"], h=["x1"])
    with pytest.raises(FormError, match=r"x1' = x2\*\*2 is not affine"):
        design_kalman_like(bad, Q=np.eye(2))


def test_forgetting_gives_exponential_decay_of_e_Minv_e():
    # Noise-free, V_e = eᵀM⁻¹e obeys dV_e/dt <= -δ V_e (derived in design_kalman_like's docstring):
    # V_e(t) e^{δt} must not increase. u = sin t makes A(u) time-varying.
    d = design_kalman_like(PEND_B, delta=3.0, region={"u": (-1.0, 1.0)})
    assert d.certificate.values["sup_norm_A"] < 1.5
    run = nlobs.simulate(PEND_B, d, t_final=6.0, dt=1e-3, x0=[0.5, 0.0, 2.0], inputs={"u": "sin(t)"},
                         xhat0=[0.0, 0.0, 0.0], engine="vm")
    e = run.error()
    M = covariances(run, "kalman_like", 3)
    Ve = np.einsum("ti,tij,tj->t", e, np.linalg.inv(M), e)
    g = Ve * np.exp(3.0 * run.t)
    assert np.all(np.diff(g) <= 1e-6 * g[:-1])
    assert run.error_norm()[-1] < 1e-4 * run.error_norm()[0]


def test_forgetting_and_noise_preconditions():
    with pytest.raises(PreconditionError, match=r"δ = 1 is not above 2 sup‖A‖"):
        design_kalman_like(PEND_B, delta=1.0, region={"u": (-1.0, 1.0)})
    with pytest.raises(PreconditionError, match="region"):
        design_kalman_like(PEND_B, delta=5.0)
    with pytest.raises(PreconditionError, match="neither forgetting nor noise"):
        design_kalman_like(PEND_B)
    with pytest.raises(PreconditionError, match="positive definite"):
        design_kalman_bucy(PEND_B, Q=np.diag([1.0, 1.0, 0.0]), R=[[1.0]])
    with pytest.raises(PreconditionError, match="positive definite"):
        design_kalman_like(PEND_B, Q=np.eye(3), R=[[0.0]])


def test_covariance_stays_symmetric_positive_definite_over_a_million_steps():
    # SPEC M9: 10⁶ RK4 steps of an LTV Kalman-like observer with forgetting and measurement noise,
    # on the compiled engine; M must stay finite, exactly symmetric, and positive definite.
    sys = nlobs.System(states=["x1", "x2"], f=["x2", "-(1 + 0.5*sin(t))*x1 - 0.1*x2 + u"], inputs=["u"],
                       outputs=["y"], h=["x1"])
    d = design_kalman_like(sys, delta=4.0, Q=1e-4 * np.eye(2), R=[[1e-3]])
    run = nlobs.simulate(sys, d, t_final=1000.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": "cos(0.3*t)"},
                         noise=nlobs.Noise.gaussian(0.01), seed=3, engine="c")
    M = covariances(run, "kalman_like", 2)
    assert M.shape[0] == 1_000_001
    assert np.all(np.isfinite(M))
    assert np.array_equal(M[:, 0, 1], M[:, 1, 0])
    assert np.linalg.eigvalsh(M).min() > 0
    assert run.metrics(tail=0.5).rms_error < 0.1


def test_high_gain_kalman_converges_and_faster_with_larger_lambda():
    sys = nlobs.System(states=["x1", "x2"], f=["(1.5 + sin(u))*x2", "-sin(x1) - 0.2*x2"], inputs=["u"],
                       outputs=["y"], h=["x1"])
    times = {}
    for lam in (2.0, 6.0):
        d = design_high_gain_kalman(sys, lam=lam, delta=5.5, region={"u": (-2.0, 2.0)})
        run = nlobs.simulate(sys, d, t_final=8.0, dt=5e-4, x0=[1.0, 1.0], inputs={"u": "2*sin(t)"},
                             xhat0=[0.0, 0.0], engine="vm")
        assert run.error_norm()[-1] < 1e-6
        times[lam] = run.metrics(tol=1e-3).convergence_time
    assert times[6.0] < 0.6 * times[2.0]
    with pytest.raises(PreconditionError, match="not above"):
        design_high_gain_kalman(sys, lam=2.0, delta=4.0, region={"u": (-2.0, 2.0)})
    broken = nlobs.System(states=["x1", "x2"], f=["x2**2", "x1"], outputs=["y"], h=["x1"])
    with pytest.raises(FormError, match="not linear in x2"):
        design_high_gain_kalman(broken, lam=2.0, delta=1.0)


def test_high_gain_kalman_riccati_and_gain_follow_002():
    # 002 "LTV-like with structured NL": x̂' = A0 x̂ + φ(x̂, u) - diag(λ, λ²) K (C x̂ - y), K = M Cᵀ W⁻¹,
    # M' = λ[M A0ᵀ + A0 M - M Cᵀ W⁻¹ C M + δ M]. For x1' = 1.5 x2, x2' = -x1 - 0.2 x2 + u (A0 = [[0, 1.5], [0, 0]],
    # φ linear) the error obeys e' = (A0 + Dφ - diag(λ, λ²) K C) e: M and e are integrated here independently.
    from scipy.integrate import solve_ivp

    sys = nlobs.System(states=["x1", "x2"], f=["1.5*x2", "-x1 - 0.2*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"])
    lam, delta, W = 3.0, 4.0, 0.5
    d = design_high_gain_kalman(sys, lam=lam, delta=delta, R=[[W]], P0=np.diag([1.0, 2.0]))
    run = nlobs.simulate(sys, d, t_final=3.0, dt=1e-4, x0=[1.0, -1.0], inputs={"u": "sin(t)"}, xhat0=[0.0, 0.0], engine="vm")
    A0 = np.array([[0.0, 1.5], [0.0, 0.0]])
    Dphi = np.array([[0.0, 0.0], [-1.0, -0.2]])
    C = np.array([[1.0, 0.0]])
    Lam = np.diag([lam, lam**2])

    def rhs(t, z):
        M, e = z[:4].reshape(2, 2), z[4:]
        K = M @ C.T / W
        dM = lam * (M @ A0.T + A0 @ M - K @ C @ M + delta * M)
        return np.concatenate([dM.ravel(), (A0 + Dphi - Lam @ K @ C) @ e])

    t = run.t[::100]
    sol = solve_ivp(rhs, (0.0, 3.0), np.concatenate([np.diag([1.0, 2.0]).ravel(), [-1.0, 1.0]]), t_eval=t, rtol=1e-12,
                    atol=1e-14, method="DOP853")
    M = covariances(run, "high_gain_kalman", 2)[::100]
    assert np.max(np.abs(M - sol.y[:4].T.reshape(-1, 2, 2))) < 1e-8 * np.abs(sol.y[:4]).max()
    assert np.max(np.abs(run.error()[::100] - sol.y[4:].T)) < 1e-8
