"""The Riccati observers of 002 against an independent integration, on the paths the paper examples do not take.

002_613af42269ea26a7.txt, "'Non uniformly observable' systems - LTV", Result [Kalman]:
    x̂' = A x̂ + B u - K (C x̂ - y),  M' = A M + M Aᵀ - M Cᵀ W⁻¹ C M + V + δ M,  K = M Cᵀ W⁻¹,
    δ > 2‖A(t)‖ or V > 0;
"LTV-like with I/O NL" (state-affine): the same with A(u, y), B(u, y);
"LTV-like with structured NL" (high gain):
    x̂' = A0(u, y) x̂ + φ(x̂, u) - diag(λ, ..., λⁿ) K0 (C0 x̂ - y),  M' = λ[M Aᵀ + A M - M Cᵀ W⁻¹ C M + δ M].
Every reference trajectory below integrates these equations (plant and observer together) with scipy's
DOP853 at rtol 1e-12, written out here from the slides, not from nlobs. nlobs integrates with fixed-step
RK4 (dt = 1e-3): its global error is O(dt⁴), measured below 1e-9 on these runs, so the tolerances are 1e-8.
"""

import numpy as np
import pytest
import scipy.linalg
from scipy.integrate import solve_ivp

import nlobs
from nlobs.design import design_augmented, design_high_gain_kalman, design_kalman_bucy, design_kalman_like
from nlobs.errors import FormError, PreconditionError, ShapeError
from nlobs.model import StateAffine

T_FINAL, DT, EVERY = 2.0, 1e-3, 50


def reference(rhs, z0):
    """The joint plant/observer ODE integrated by scipy, at the samples the test compares."""
    t = np.arange(0.0, T_FINAL + DT / 2, DT)[::EVERY]
    sol = solve_ivp(rhs, (0.0, T_FINAL), z0, t_eval=t, rtol=1e-12, atol=1e-13, method="DOP853")
    assert sol.success
    return sol.y.T


def sym(M):
    return (M + M.T) / 2


def test_kalman_bucy_with_output_matrix_depending_on_the_input():
    # LTV plant with A(t) and C(u) (y = C(u, t)x is allowed), a non-identity P0 and x̂0, Q > 0, R > 0.
    # No output is a single state, so the state-affine reading has no measured state to substitute.
    sys = nlobs.System(states=["x1", "x2"], f=["x2", "-(1 + 0.5*sin(t))*x1 - 0.3*x2 + u"], inputs=["u"],
                       outputs=["y"], h=["(1 + 0.5*u**2)*x1 + 0.2*x2"])
    Q, R, P0 = np.diag([0.2, 0.1]), 0.2, np.array([[2.0, 0.3], [0.3, 1.0]])
    x0, xh0 = np.array([1.0, 0.0]), np.array([0.5, -0.4])
    d = design_kalman_bucy(sys, Q=Q, R=[[R]], P0=P0, xhat0=xh0)
    run = nlobs.simulate(sys, d, t_final=T_FINAL, dt=DT, x0=x0, inputs={"u": "cos(t)"}, engine="vm")

    def rhs(t, z):
        x, xh, P = z[:2], z[2:4], z[4:].reshape(2, 2)
        u = np.cos(t)
        A = np.array([[0.0, 1.0], [-(1 + 0.5 * np.sin(t)), -0.3]])
        C = np.array([[1 + 0.5 * u**2, 0.2]])
        b = np.array([0.0, u])
        K = P @ C.T / R
        return np.concatenate([A @ x + b, A @ xh + b - K @ (C @ xh - C @ x),
                               sym(A @ P + P @ A.T + Q - K @ C @ P).ravel()])

    ref = reference(rhs, np.concatenate([x0, xh0, P0.ravel()]))
    tr = run.observers["kalman_bucy"]
    np.testing.assert_allclose(tr.xhat[::EVERY], ref[:, 2:4], rtol=0, atol=1e-8)
    np.testing.assert_allclose(tr.z[::EVERY, 2:].reshape(-1, 2, 2, order="F"), ref[:, 4:].reshape(-1, 2, 2), rtol=0, atol=1e-8)
    # without forgetting, M is the error covariance: the design exposes it (noise intensities Q, R)
    assert d.covariance is not None
    np.testing.assert_allclose(np.array(d.covariance(tr.z[-1])), ref[-1, 4:].reshape(2, 2), atol=1e-8)
    assert d.certificate.method.startswith("Kalman-Bucy") and "Besançon (2010)" in d.certificate.reference


def test_kalman_like_on_a_state_affine_model_with_forgetting_and_singular_noise():
    # StateAffine with parameters: A(u) and b(y) (the measured output enters b), C = (1, 0).
    # V is positive semidefinite but singular, so the design rests on forgetting δ > 2 sup‖A‖ (002).
    sa = StateAffine(A=[["0", "1"], ["-a", "-c*u"]], b=["0", "g*sin(y)"], C=[[1], [0]], states=["x1", "x2"],
                     inputs=["u"], outputs=["y"], params={"a": 2.0, "c": 0.5, "g": 0.7})
    plant = sa.to_system()
    V, W, M0, delta = np.diag([0.1, 0.0]), 0.3, np.array([[1.0, 0.2], [0.2, 0.5]]), 5.0
    x0, xh0 = np.array([0.8, -0.5]), np.array([0.0, 0.3])
    d = design_kalman_like(sa, Q=V, R=[[W]], delta=delta, P0=M0, region={"u": (-1.0, 1.0)}, xhat0=xh0)
    # sup over u in [-1, 1] of ‖[[0, 1], [-2, -0.5u]]‖₂, by brute force on a grid that contains the ends
    grid = max(np.linalg.norm(np.array([[0.0, 1.0], [-2.0, -0.5 * u]]), 2) for u in np.linspace(-1.0, 1.0, 401))
    assert d.certificate.values["sup_norm_A"] == pytest.approx(grid, rel=1e-9)
    run = nlobs.simulate(plant, d, t_final=T_FINAL, dt=DT, x0=x0, inputs={"u": "sin(2*t)"}, engine="vm")

    def rhs(t, z):
        x, xh, M = z[:2], z[2:4], z[4:].reshape(2, 2)
        u = np.sin(2 * t)
        A = np.array([[0.0, 1.0], [-2.0, -0.5 * u]])
        C = np.array([[1.0, 0.0]])
        y = x[0]
        b = np.array([0.0, 0.7 * np.sin(y)])
        K = M @ C.T / W
        return np.concatenate([A @ x + b, A @ xh + b - K @ (C @ xh - y),
                               sym(A @ M + M @ A.T - K @ C @ M + V + delta * M).ravel()])

    ref = reference(rhs, np.concatenate([x0, xh0, M0.ravel()]))
    tr = run.observers["kalman_like"]
    np.testing.assert_allclose(tr.xhat[::EVERY], ref[:, 2:4], rtol=0, atol=1e-8)
    M = tr.z[::EVERY, 2:].reshape(-1, 2, 2, order="F")
    np.testing.assert_allclose(M, ref[:, 4:].reshape(-1, 2, 2), rtol=1e-9, atol=1e-8)
    # with forgetting M is not the error covariance: none is claimed
    assert d.covariance is None
    assert d.certificate.method.startswith("Kalman-like") and "Besançon (2010)" in d.certificate.reference
    assert any(c.status == "assumed" and "regularly persistent" in c.condition for c in d.certificate.checks)


def test_sup_norm_of_A_constant_and_over_a_box():
    # constant A: the spectral norm itself (largest singular value, scipy), not another matrix norm
    A = np.array([[0.0, 1.0], [-2.0, -0.5]])
    d = design_kalman_like(nlobs.System.lti(A, None, [[1.0, 0.0]]), delta=5.0)
    assert d.certificate.values["sup_norm_A"] == pytest.approx(scipy.linalg.svdvals(A)[0], rel=1e-14)
    # A(u, t) depending on two quantities: ‖[[0, 1 + u], [t, 0]]‖₂ = max(|1 + u|, |t|) = 1.5 on the box
    two = nlobs.System(states=["x1", "x2"], f=["(1 + u)*x2", "t*x1"], inputs=["u"], outputs=["y"], h=["x1 + x2"])
    d2 = design_kalman_like(two, delta=3.5, region={"u": (0.0, 0.5), "t": (0.0, 1.0)})
    assert d2.certificate.values["sup_norm_A"] == pytest.approx(1.5, rel=1e-9)
    # where the supremum is attained is reported (to 4 digits): ‖A(u)‖ grows with |u| on PEND_B-like A
    sys = nlobs.System(states=["x1", "x2", "x3"], f=["x2", "-0.5*x2 + x3*u", "0"], inputs=["u"], outputs=["y"], h=["x1"])
    d3 = design_kalman_like(sys, delta=3.0, region={"u": (0.0, 0.123456)})
    detail = next(c.detail for c in d3.certificate.checks if c.condition.startswith("δ > 2 sup‖A‖"))
    assert "attained at {'u': 0.1235}" in detail


def test_high_gain_kalman_three_states_with_output_dependent_couplings():
    # 002 "LTV-like with structured NL", n = 3: a12(y) = 2 + cos(y), a23(u) = 1 + 0.5 sin(u), triangular
    # φ = (0, -x1, -sin(x1) - 0.3 x3). sup‖A0‖ = max sup|a12|, sup|a23| = 3 (a superdiagonal matrix).
    sys = nlobs.System(states=["x1", "x2", "x3"],
                       f=["(2 + cos(x1))*x2", "(1 + 0.5*sin(u))*x3 - x1", "-sin(x1) - 0.3*x3"],
                       inputs=["u"], outputs=["y"], h=["x1"])
    lam, delta, W = 2.0, 6.5, 0.5
    M0, x0, xh0 = np.diag([1.0, 2.0, 0.5]), np.array([0.5, -0.3, 0.2]), np.array([0.1, 0.2, -0.1])
    d = design_high_gain_kalman(sys, lam=lam, delta=delta, R=[[W]], P0=M0, xhat0=xh0,
                                region={"u": (-1.0, 1.0), "y": (-3.0, 3.0)})
    assert d.certificate.values["sup_norm_A"] == pytest.approx(3.0, rel=1e-9)
    assert d.certificate.values["lambda"] == lam
    assert d.certificate.values["phi"] == ["0", "-x1", "-3*x3/10 - sin(x1)"]
    assert "λ = 2" in d.certificate.method and "Besançon (2010)" in d.certificate.reference
    assert any(c.holds and c.condition.startswith("structure: x_i' = a_i(u, y) x_(i+1)") for c in d.certificate.checks)
    assert d.covariance is None
    run = nlobs.simulate(sys, d, t_final=T_FINAL, dt=DT, x0=x0, inputs={"u": "sin(3*t)"}, engine="vm")
    C, Lam = np.array([[1.0, 0.0, 0.0]]), np.diag([lam, lam**2, lam**3])

    def A0(u, y):
        return np.array([[0.0, 2 + np.cos(y), 0.0], [0.0, 0.0, 1 + 0.5 * np.sin(u)], [0.0, 0.0, 0.0]])

    def rhs(t, z):
        x, xh, M = z[:3], z[3:6], z[6:].reshape(3, 3)
        u, y = np.sin(3 * t), z[0]
        f = A0(u, x[0]) @ x + np.array([0.0, -x[0], -np.sin(x[0]) - 0.3 * x[2]])
        phi = np.array([0.0, -xh[0], -np.sin(xh[0]) - 0.3 * xh[2]])
        A = A0(u, y)
        K = M @ C.T / W
        return np.concatenate([f, A @ xh + phi - Lam @ K @ (C @ xh - y),
                               sym(lam * (M @ A.T + A @ M - K @ C @ M + delta * M)).ravel()])

    ref = reference(rhs, np.concatenate([x0, xh0, M0.ravel()]))
    tr = run.observers["high_gain_kalman"]
    np.testing.assert_allclose(run.x[::EVERY], ref[:, :3], rtol=0, atol=1e-8)
    np.testing.assert_allclose(tr.xhat[::EVERY], ref[:, 3:6], rtol=0, atol=1e-8)
    # M grows to ~2e3 (forgetting λδ = 13 against the correction): compared relative to its size
    np.testing.assert_allclose(tr.z[::EVERY, 3:].reshape(-1, 3, 3, order="F"), ref[:, 6:].reshape(-1, 3, 3), rtol=0,
                               atol=1e-9 * np.abs(ref[:, 6:]).max())


def test_kalman_bucy_on_an_augmented_ltv_system():
    # 001 (state augmentation): the double integrator with w = (x1, x2, x1²) mimics
    # w' = A(y) w + b(u), A = [[0, 1, 0], [0, 0, 0], [0, 2y, 0]] since (x1²)' = 2 x1 x2 = 2 y w2; C = (1, 0, 0),
    # x = (w1, w2). The Kalman-Bucy filter runs on w (ŵ(0) = T(x̂0)) and the estimate is T⁺(ŵ).
    sys = nlobs.System(states=["x1", "x2"], f=["x2", "u"], inputs=["u"], outputs=["y"], h=["x1"])
    Q, R, P0 = np.diag([0.1, 0.2, 0.3]), 0.1, np.diag([1.0, 0.5, 2.0])
    d = design_augmented(sys, T=["x1", "x2", "x1**2"], A=[[0, 1, 0], [0, 0, 0], [0, "2*y", 0]], C=[[1, 0, 0]],
                         b=[0, "u", 0], left_inverse=["w1", "w2"], Q=Q, R=[[R]], P0=P0, xhat0=[0.4, -0.2])
    assert d.z_names[:3] == ("what_1", "what_2", "what_3")
    assert d.covariance is None
    x0 = np.array([1.0, 0.5])
    run = nlobs.simulate(sys, d, t_final=T_FINAL, dt=DT, x0=x0, inputs={"u": "cos(t)"}, engine="vm")
    C = np.array([[1.0, 0.0, 0.0]])

    def rhs(t, z):
        x, w, P = z[:2], z[2:5], z[5:].reshape(3, 3)
        u, y = np.cos(t), z[0]
        A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 0.0], [0.0, 2 * y, 0.0]])
        K = P @ C.T / R
        return np.concatenate([[x[1], u], A @ w + np.array([0.0, u, 0.0]) - K @ (C @ w - y),
                               sym(A @ P + P @ A.T + Q - K @ C @ P).ravel()])

    ref = reference(rhs, np.concatenate([x0, [0.4, -0.2, 0.16], P0.ravel()]))
    tr = run.observers["augmented"]
    np.testing.assert_allclose(tr.z[::EVERY, :3], ref[:, 2:5], rtol=0, atol=1e-8)
    np.testing.assert_allclose(tr.xhat[::EVERY], ref[:, 2:4], rtol=0, atol=1e-8)


PEND_B = nlobs.System(states=["x1", "x2", "b"], f=["x2", "-a1*sin(x1) - a2*x2 + b*u", "0"], inputs=["u"],
                      outputs=["y"], h=["x1"], params={"a1": 9.81, "a2": 0.5})
DOUBLE = nlobs.System.lti([[0.0, 1.0], [0.0, 0.0]], None, [[1.0, 0.0]])  # ‖A‖₂ = 1 exactly


def test_kalman_refusals_name_the_design_the_argument_and_the_condition():
    like = "^design_kalman_like: "
    with pytest.raises(PreconditionError, match=like + "`Q` must be symmetric"):
        design_kalman_like(PEND_B, Q=[[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    with pytest.raises(PreconditionError, match=like + "`Q` must be positive semidefinite"):
        design_kalman_like(PEND_B, Q=np.diag([1.0, -0.1, 1.0]))
    with pytest.raises(PreconditionError, match=like + "`P0` must be positive definite"):
        design_kalman_like(PEND_B, Q=np.eye(3), P0=np.diag([1.0, 0.0, 1.0]))
    with pytest.raises(PreconditionError, match=like + "`R` must be positive definite"):
        design_kalman_like(PEND_B, Q=np.eye(3), R=[[-1.0]])
    for bad in (-1.0, np.inf, np.nan):
        with pytest.raises(PreconditionError, match=like + "the forgetting factor `delta` must be a non-negative"):
            design_kalman_like(PEND_B, Q=np.eye(3), delta=bad)
    # δ = 2‖A‖ exactly is not above: 002 needs δ > 2‖A(t)‖
    with pytest.raises(PreconditionError, match=like + r"the forgetting factor δ = 2 is not above 2 sup‖A‖ = 2"):
        design_kalman_like(DOUBLE, delta=2.0)
    assert design_kalman_like(DOUBLE, delta=2.0 + 1e-9).certificate.values["sup_norm_A"] == 1.0
    with pytest.raises(PreconditionError, match=like + "A depends on u"):
        design_kalman_like(PEND_B, delta=5.0)
    with pytest.raises(ShapeError, match=like + "`region` has no bounds for u"):
        design_kalman_like(PEND_B, delta=5.0, region={"t": (0.0, 1.0)})
    with pytest.raises(FormError, match=like + ".* is not state-affine"):
        design_kalman_like(nlobs.System(states=["x1", "x2"], f=["x2**2", "0"], outputs=["y"], h=["x1"]), Q=np.eye(2))
    # y = C(u, t)x: an affine (not linear) output is refused
    with pytest.raises(FormError, match=like + r"output y = x1 \+ 1 is not linear in the state"):
        design_kalman_like(nlobs.System(states=["x1", "x2"], f=["x2", "0"], outputs=["y"], h=["x1 + 1"]), Q=np.eye(2))
    # with V > 0 any δ >= 0 is allowed; M is not the covariance once δ > 0 (δ = 1 included)
    assert design_kalman_like(PEND_B, Q=np.eye(3), delta=1.0).covariance is None
    assert design_kalman_like(PEND_B, Q=np.eye(3)).covariance is not None

    bucy = "^design_kalman_bucy: "
    with pytest.raises(PreconditionError, match=bucy + "`Q` must be symmetric"):
        design_kalman_bucy(PEND_B, Q=[[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], R=[[1.0]])
    with pytest.raises(PreconditionError, match=bucy + "`Q` must be positive definite"):
        design_kalman_bucy(PEND_B, Q=np.diag([1.0, 1.0, 0.0]), R=[[1.0]])
    # the arguments are named as the user gave them (R, P0), not as the Riccati core calls them (W, M0)
    with pytest.raises(PreconditionError, match=bucy + "`R` must be positive definite"):
        design_kalman_bucy(PEND_B, Q=np.eye(3), R=[[0.0]])
    with pytest.raises(PreconditionError, match=bucy + "`P0` must be positive definite"):
        design_kalman_bucy(PEND_B, Q=np.eye(3), R=[[1.0]], P0=np.diag([1.0, -1.0, 1.0]))
    with pytest.raises(FormError, match=bucy + ".* is not state-affine"):
        design_kalman_bucy(nlobs.System(states=["x1", "x2"], f=["x2**2", "0"], outputs=["y"], h=["x1"]), Q=np.eye(2), R=1.0)

    hgk = "^design_high_gain_kalman: "
    chain = nlobs.System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1"])
    assert design_high_gain_kalman(chain, lam=1.0, delta=2.5).certificate.values["lambda"] == 1.0  # λ = 1 is allowed
    with pytest.raises(PreconditionError, match=hgk + "λ = 0.99 must be at least 1"):
        design_high_gain_kalman(chain, lam=0.99, delta=2.5)
    with pytest.raises(PreconditionError, match=hgk + "the gain parameter must be positive"):
        design_high_gain_kalman(chain, lam=-1.0, delta=2.5)
    with pytest.raises(PreconditionError, match=hgk + "the forgetting factor δ = 2 is not above"):
        design_high_gain_kalman(chain, lam=2.0, delta=2.0)
    with pytest.raises(PreconditionError, match=hgk + r"output y = x1 \+ x2 is not a single state"):
        design_high_gain_kalman(nlobs.System(states=["x1", "x2"], f=["x2", "x1"], outputs=["y"], h=["x1 + x2"]), lam=2.0, delta=3.0)
    with pytest.raises(TypeError, match=hgk + "the model must be an nlobs.System"):
        design_high_gain_kalman("pendulum", lam=2.0, delta=1.0)
