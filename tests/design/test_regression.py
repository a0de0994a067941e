"""Regression equations and estimators: gradient, least squares, DREM, G+D, filters, excitation.

Reference values are closed-form solutions of the estimators' error equations (independent of
the code), or identities from 000_6cd8bea7ca1db43b.txt (eqs. 15, 18-19).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nlobs import PreconditionError, System, simulate
from nlobs.design import (DREM, GD, Certificate, Gradient, LeastSquares, LinearRegression, StateStack, derivative_filter,
                          design_drem, design_from_config, design_gd, design_gradient, design_least_squares,
                          excitation_report, lowpass)
from nlobs.design.pebo._regression import adjugate
from nlobs.errors import ModelError

SCALAR = LinearRegression(["psi1"], signals=["psi1"])          # Y = ψ θ
TWO = LinearRegression(["psi1", "psi2"], signals=["psi1", "psi2"])
THETA = (1.5, -0.7)


def test_linear_regression_model_and_recognition():
    s = TWO.to_system()
    assert s.states == ("theta1", "theta2") and all(e == 0 for e in s.f)
    psi, d = LinearRegression.parts_of(s)
    assert [str(e) for e in psi] == ["psi1", "psi2"] and d[0] == 0
    bad = System(states=["a"], f=["0"], outputs=["Y"], h=["a**2*p"], inputs=["p"])
    with pytest.raises(PreconditionError, match="not linear in the parameters"):
        design_gradient(bad)
    moving = System(states=["a"], f=["-a"], outputs=["Y"], h=["a*p"], inputs=["p"])
    with pytest.raises(PreconditionError, match="must be constant"):
        design_gd(moving)


def test_gradient_matches_the_closed_form_error():
    # ψ = 1: θ̃' = -γ θ̃, so θ̂(t) = θ + (θ̂0 - θ) e^{-γt}
    d = design_gradient(SCALAR, gamma=2.0)
    run = simulate(SCALAR.to_system(), {"g": d}, t_final=2.0, dt=1e-3, x0=[3.0], inputs={"psi1": 1.0}, xhat0=[0.0])
    assert np.allclose(run.observers["g"].xhat[:, 0], 3.0 - 3.0 * np.exp(-2.0 * run.t), atol=1e-9)


def test_least_squares_matches_the_closed_form_error():
    # ψ = 1, β = 0: P = P0/(1 + P0 t) and θ̃ = θ̃0/(1 + P0 t)
    d = design_least_squares(SCALAR, P0=4.0)
    run = simulate(SCALAR.to_system(), {"ls": d}, t_final=3.0, dt=1e-3, x0=[2.0], inputs={"psi1": 1.0})
    tr = run.observers["ls"]
    assert np.allclose(tr.xhat[:, 0], 2.0 - 2.0 / (1 + 4.0 * run.t), atol=1e-8)
    assert np.allclose(tr.z[:, tr.z_names.index("P")], 4.0 / (1 + 4.0 * run.t), atol=1e-8)


def test_least_squares_forgetting_and_bounded_gain():
    # ψ = 0 (no excitation): P' = βP grows as P0 e^{βt}; with p_max, P' = β(1 - P/p_max)P is logistic,
    # P = p_max / (1 + (p_max/P0 - 1) e^{-βt}), and stays below p_max
    sys = SCALAR.to_system()
    plain = design_least_squares(SCALAR, P0=1.0, forgetting=0.5)
    bounded = design_least_squares(SCALAR, P0=1.0, forgetting=0.5, p_max=3.0)
    run = simulate(sys, {"plain": plain, "bounded": bounded}, t_final=10.0, dt=1e-2, x0=[1.0], inputs={"psi1": 0.0})
    P = run.observers["plain"].z[:, 1]
    assert P[-1] == pytest.approx(np.exp(5.0), rel=1e-6)
    assert np.allclose(run.observers["bounded"].z[:, 1], 3.0 / (1 + 2.0 * np.exp(-0.5 * run.t)), rtol=1e-8)
    with pytest.raises(PreconditionError, match="p_max"):
        design_least_squares(SCALAR, P0=5.0, p_max=3.0)


@pytest.mark.parametrize("est", [DREM(10.0, lambdas=[2.0]), DREM(10.0, kreisselmeier=1.0), GD(5.0, 50.0),
                                 Gradient(5.0), LeastSquares(10.0, forgetting=0.5)])
def test_every_estimator_recovers_theta_under_pe(est):
    d = {"drem": design_drem, "gd": design_gd, "gradient": design_gradient, "least_squares": design_least_squares}[est.kind]
    kwargs = {k: v for k, v in est.__dict__.items() if v is not None}
    design = d(TWO, **kwargs)
    run = simulate(TWO.to_system(), {"e": design}, t_final=30.0, dt=1e-3, x0=THETA, inputs={"psi1": "sin(t)", "psi2": "cos(2*t)"})
    assert np.allclose(run.observers["e"].xhat[-1], THETA, atol=1e-3)
    assert design.n_z == est.n_states(2, 1)


def test_gd_mixing_identity_000_eq_19():
    # along any run, Y = adj(I - Ω)(θ̂_g - Ω θ_g0) equals Δ θ exactly (000 eqs. 18-19), θ_g0 = 0
    d = design_gd(TWO, gamma_g=3.0, gamma=1.0)
    run = simulate(TWO.to_system(), {"gd": d}, t_final=3.0, dt=1e-3, x0=THETA, inputs={"psi1": "sin(t)", "psi2": "1"})
    tr = run.observers["gd"]
    names = tr.z_names
    tg = tr.z[:, [names.index(f"theta_g[{i}]") for i in range(2)]]
    Om = tr.z[:, [names.index(f"Omega[{i},{j}]") for j in range(2) for i in range(2)]].reshape(-1, 2, 2, order="F")
    for k in range(0, run.t.size, 300):
        D = np.eye(2) - Om[k]
        adj = np.array([[D[1, 1], -D[0, 1]], [-D[1, 0], D[0, 0]]])
        assert np.allclose(adj @ tg[k], np.linalg.det(D) * np.array(THETA), atol=1e-9)


def test_gd_converges_under_interval_excitation_only():
    # ψ = (1, e^{-t}): IE (rank 2 on [0, T]) but not PE; gradient stalls, G+D converges (000 Lemma 2)
    reg = LinearRegression(["1", "exp(-t)"], signals=["unused"])
    gd = design_gd(reg, gamma_g=5.0, gamma=50.0)
    grad = design_gradient(reg, gamma=5.0)
    run = simulate(reg.to_system(), {"gd": gd, "grad": grad}, t_final=20.0, dt=1e-3, x0=THETA)
    assert run.error_norm("gd")[-1] < 1e-6
    assert run.error_norm("grad")[-1] > 1e-2
    rep = excitation_report(gd, run.t, run.observers["gd"].z, run.u, run.y, window=5.0)
    assert rep.ie_time is not None and rep.delta_time is not None and rep.pe_level < 1e-6


def test_drem_extension_rows_must_match():
    with pytest.raises(PreconditionError, match="exactly 2"):
        design_drem(TWO, lambdas=[1.0, 2.0])
    with pytest.raises(PreconditionError, match="either `lambdas`"):
        DREM(1.0, lambdas=[1.0], kreisselmeier=1.0)
    with pytest.raises(PreconditionError, match="distinct"):
        DREM(1.0, lambdas=[1.0, 1.0])
    with pytest.raises(PreconditionError, match="positive"):
        DREM(1.0, lambdas=[-1.0])


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), "x"])
def test_gains_are_checked(bad):
    with pytest.raises(PreconditionError, match="gamma"):
        GD(1.0, bad)
    with pytest.raises(PreconditionError, match="gamma"):
        design_gradient(TWO, gamma=bad)


def test_gradient_gain_matrix_must_be_positive_definite():
    with pytest.raises(PreconditionError, match="positive definite"):
        design_gradient(TWO, gamma=[[1.0, 2.0], [2.0, 1.0]])


def test_filters_004_eq_37():
    # F = α/(p+α) and W = αp/(p+α) applied to sin t, against their analytic responses from rest
    s = System(states=["a", "b"], f=["0", "0"], outputs=["y"], h=["a"])
    st = StateStack(s)
    alpha = 2.0
    F = lowpass(st, ca.sin(st.t), alpha, "F")
    W = derivative_filter(st, ca.sin(st.t), alpha, "W")
    d = st.build("filters", xhat=ca.vertcat(F, W), certificate=Certificate("filters", "004 eq. (37)"))
    run = simulate(s, {"f": d}, t_final=5.0, dt=1e-3, x0=[0.0, 0.0])
    t, out = run.t, run.observers["f"].xhat
    c = alpha / (alpha**2 + 1)
    assert np.allclose(out[:, 0], c * (alpha * np.sin(t) - np.cos(t) + np.exp(-alpha * t)), atol=1e-9)
    # W[sin] = F[cos] since sin(0) = 0: α/(α²+1)(α cos t + sin t - α e^{-αt})
    assert np.allclose(out[:, 1], c * (alpha * np.cos(t) + np.sin(t) - alpha * np.exp(-alpha * t)), atol=1e-9)
    with pytest.raises(PreconditionError, match="alpha"):
        lowpass(st, st.t, 0.0, "bad")


def test_adjugate_identity():
    rng = np.random.default_rng(3)
    for n in (1, 2, 3, 4):
        M = ca.SX.sym("M", n, n)
        fn = ca.Function("adj", [M], [adjugate(M) @ M])
        A = rng.normal(size=(n, n))
        assert np.allclose(np.array(fn(A)), np.linalg.det(A) * np.eye(n), atol=1e-10)
    S = np.array([[1.0, 2.0], [2.0, 4.0]])                     # singular: adj still defined, adj·M = 0
    M2 = ca.SX.sym("M", 2, 2)
    assert np.allclose(np.array(ca.Function("a", [M2], [adjugate(M2)])(S)), [[4, -2], [-2, 1]])


def test_excitation_report_against_closed_form():
    # ψ = (1, t): ∫_0^T ψψᵀ = [[T, T²/2], [T²/2, T³/3]]
    reg = LinearRegression(["1", "t"], signals=["unused"])
    d = design_gradient(reg, gamma=0.1)
    run = simulate(reg.to_system(), {"g": d}, t_final=4.0, dt=1e-3, x0=THETA)
    rep = excitation_report(d, run.t, run.observers["g"].z, run.u, run.y, window=1.0)
    T = 4.0
    exact = np.linalg.eigvalsh([[T, T**2 / 2], [T**2 / 2, T**3 / 3]])[0]
    assert rep.ie_level[-1] == pytest.approx(exact, rel=1e-5)
    window = min(np.linalg.eigvalsh([[1.0, t0 + 0.5], [t0 + 0.5, ((t0 + 1) ** 3 - t0**3) / 3]])[0] for t0 in np.arange(0, 3.001, 0.001))
    assert rep.pe_level == pytest.approx(window, rel=1e-3)
    assert rep.delta is None and "IE level" in str(rep)
    with pytest.raises(PreconditionError, match="longer than the run"):
        excitation_report(d, run.t, run.observers["g"].z, run.u, run.y, window=10.0)


def test_estimators_from_model_file_tables():
    s = TWO.to_system()
    d = design_from_config(s, "gd", {"gamma_g": 2.0, "gamma": 3.0})
    assert d.certificate.values["gd.gamma"] == 3.0
    with pytest.raises(ModelError, match="unknown option"):
        design_from_config(s, "gd", {"gamma_gg": 2.0})


def test_gd_error_law_000_lemma_2_proof():
    # The proof of 000 Lemma 2: with Y = Δθ (eq. 19), (16c) gives θ̃_i' = -γΔ²θ̃_i, so
    # θ̂(t) = θ + (θ̂(0) - θ) exp(-γ ∫Δ²). Ω' = -γ_g ψψᵀΩ, Ω(0) = I (eqs. 16b, 17a) and Δ = det(I - Ω) (17b-c)
    # are integrated here independently (scipy, ψ = (sin t, cos 2t) in closed form).
    from scipy.integrate import solve_ivp

    gg, g, T = 3.0, 2.0, 4.0
    d = design_gd(TWO, gamma_g=gg, gamma=g)
    run = simulate(TWO.to_system(), {"gd": d}, t_final=T, dt=1e-3, x0=THETA, inputs={"psi1": "sin(t)", "psi2": "cos(2*t)"},
                   xhat0=[0.5, 0.5])

    def rhs(s, z):
        Om = z[:4].reshape(2, 2)
        psi = np.array([np.sin(s), np.cos(2 * s)])
        return np.concatenate([(-gg * np.outer(psi, psi) @ Om).ravel(), [np.linalg.det(np.eye(2) - Om) ** 2]])

    t = run.t[::100]
    sol = solve_ivp(rhs, (0.0, T), np.concatenate([np.eye(2).ravel(), [0.0]]), t_eval=t, rtol=1e-12, atol=1e-15, method="DOP853")
    expected = np.array(THETA) + (np.array([0.5, 0.5]) - np.array(THETA)) * np.exp(-g * sol.y[4])[:, None]
    got = run.observers["gd"].xhat[::100]
    assert np.max(np.abs(got - expected)) < 1e-9
    assert np.max(np.abs(expected - np.array(THETA))) > 0.1      # the test sees the transient, not only the limit
    # and Δ itself (the mixed regressor the estimator reports) equals det(I - Ω) of the independent Ω
    rep = excitation_report(d, run.t, run.observers["gd"].z, run.u, run.y)
    Om_ref = sol.y[:4].T.reshape(-1, 2, 2)
    assert np.allclose(rep.delta[::100], np.linalg.det(np.eye(2) - Om_ref), atol=1e-10)


def test_drem_error_law():
    # DREM with the Kreisselmeier extension: Ψe' = -aΨe + ψψᵀ, Ye' = -aYe + ψY, Ψe(0) = 0, Ye(0) = 0, so Ye = Ψe θ
    # exactly, and θ̃_i' = -γΔ²θ̃_i with Δ = det Ψe: θ̂ = θ + (θ̂0 - θ) exp(-γ ∫Δ²), integrated independently here
    from scipy.integrate import solve_ivp

    a, g, T = 1.5, 20.0, 4.0
    d = design_drem(TWO, gamma=g, kreisselmeier=a)
    run = simulate(TWO.to_system(), {"drem": d}, t_final=T, dt=1e-3, x0=THETA, inputs={"psi1": "sin(t)", "psi2": "cos(2*t)"})

    def rhs(s, z):
        Pe = z[:4].reshape(2, 2)
        psi = np.array([np.sin(s), np.cos(2 * s)])
        return np.concatenate([(-a * Pe + np.outer(psi, psi)).ravel(), [np.linalg.det(Pe) ** 2]])

    t = run.t[::100]
    sol = solve_ivp(rhs, (0.0, T), np.zeros(5), t_eval=t, rtol=1e-12, atol=1e-15, method="DOP853")
    expected = np.array(THETA) * (1 - np.exp(-g * sol.y[4]))[:, None]        # θ̂(0) = 0
    assert np.max(np.abs(run.observers["drem"].xhat[::100] - expected)) < 1e-9
    assert np.max(np.abs(expected - np.array(THETA))) > 0.1


@pytest.mark.parametrize("n", [4, 7, 10])
def test_det_and_adjugate_of_a_large_matrix_by_faddeev_leverrier(n):
    # CasADi's det expands cofactors (n! terms: a 10-parameter DREM or G+D never finished building); the recursion
    # must give NumPy's det and det·inv, and stay exact at a singular matrix (the estimators start at D = 0)
    import casadi as ca

    from nlobs.design.pebo._regression import det_adj

    M = ca.SX.sym("M", n, n)
    f = ca.Function("f", [M], list(det_adj(M)))
    A = np.random.default_rng(n).standard_normal((n, n))
    d, adj = (np.array(v) for v in f(A))
    assert d.item() == pytest.approx(np.linalg.det(A), rel=1e-12)
    np.testing.assert_allclose(adj, np.linalg.det(A) * np.linalg.inv(A), rtol=0, atol=1e-10 * np.abs(adj).max())
    d0, adj0 = (np.array(v) for v in f(np.zeros((n, n))))
    assert d0.item() == 0 and np.all(adj0 == 0)
    assert f.n_nodes() < 20 * n ** 4                 # polynomial size (cofactors: n! terms)
