"""Lipschitz (Thau) observer, 002 'LTI + Lipschitz NL': P(A - KC) + (A - KC)ᵀP = -Q, eigmin(Q)/(2 eigmax(P)) > γ."""

import numpy as np
import pytest
import scipy.linalg

import nlobs
from nlobs.design import design_lipschitz
from nlobs.design.lipschitz._lipschitz import region_lipschitz, thau_margin
from nlobs.errors import PreconditionError

DAMPED = nlobs.System(states=["x1", "x2"], f=["x2", "-x1 - x2 + 0.3*sin(x2)"], outputs=["y"], h=["x1"])
A_LIN = [[0.0, 1.0], [-1.0, -1.0]]  # φ = (0, 0.3 sin x2), γ = 0.3


def test_certificate_satisfies_the_thau_inequality_independently():
    d = design_lipschitz(DAMPED, lipschitz=0.3, A=A_LIN)
    v = d.certificate.values
    A, C, K, P = np.array(A_LIN), v["C"], v["K"], v["P"]
    Q = -(P @ (A - K @ C) + (A - K @ C).T @ P)
    np.testing.assert_allclose(Q, np.eye(2), atol=1e-9)
    margin = np.linalg.eigvalsh(Q).min() / (2 * np.linalg.eigvalsh(P).max())
    assert margin == pytest.approx(v["margin"], rel=1e-9)
    assert margin > 0.3
    assert v["guaranteed_rate"] == pytest.approx(margin - 0.3)


def test_q_identity_is_the_best_q_for_a_given_gain():
    # thau_margin's claim: for fixed K no Q beats Q = I (random positive definite Q, scipy Lyapunov).
    A, C, K = np.array(A_LIN), np.array([[1.0, 0.0]]), np.array([[1.0], [0.5]])
    best, _ = thau_margin(A, C, K)
    rng = np.random.default_rng(1)
    Acl = A - K @ C
    for _ in range(200):
        M = rng.normal(size=(2, 2))
        Q = M @ M.T + 1e-3 * np.eye(2)
        P = scipy.linalg.solve_continuous_lyapunov(Acl.T, -Q)
        assert np.linalg.eigvalsh(Q).min() / (2 * np.linalg.eigvalsh(P).max()) <= best * (1 + 1e-9)


def test_measured_rate_is_at_least_the_guaranteed_one():
    d = design_lipschitz(DAMPED, lipschitz=0.3, A=A_LIN)
    run = nlobs.simulate(DAMPED, d, t_final=8.0, dt=1e-3, x0=[1.0, 2.0], xhat0=[-1.0, -1.0], engine="vm")
    e, t = run.error_norm(), run.t
    g = d.certificate.values["guaranteed_rate"]
    # the bound itself: ‖e(t)‖ <= sqrt(κ(P)) e^{-(μ-γ)t} ‖e(0)‖ at every sample
    assert np.all(e <= d.certificate.values["overshoot"] * np.exp(-g * t) * e[0] * (1 + 1e-6))
    sel = (t > 1.0) & (t < 7.0)
    assert -np.polyfit(t[sel], np.log(e[sel]), 1)[0] >= g


def test_gamma_too_large_is_refused_with_the_achieved_margin():
    with pytest.raises(PreconditionError, match=r"best margin found .* is [0-9.]+ <= γ = 5"):
        design_lipschitz(DAMPED, lipschitz=5.0, A=A_LIN)


def test_gamma_estimated_over_a_region():
    # φ = (0, 0.3 sin x2): sup |∂φ/∂x| = 0.3 at x2 = 0 (the centre of the box is on the grid)
    gam, where = region_lipschitz(DAMPED, [0, nlobs.model.parse_expression("3*sin(x2)/10", {"x2": DAMPED.x[1]})],
                                    {"x1": (-2, 2), "x2": (-1, 1)})
    assert gam == pytest.approx(0.3, rel=1e-9)
    d = design_lipschitz(DAMPED, A=A_LIN, region={"x1": (-2, 2), "x2": (-1, 1)})
    assert d.certificate.values["gamma"] == pytest.approx(0.3, rel=1e-9)


def test_preconditions():
    with pytest.raises(PreconditionError, match="`lipschitz`"):
        design_lipschitz(DAMPED, A=A_LIN)
    unobs = nlobs.System(states=["x1", "x2"], f=["-x1", "-x2 + 0.1*sin(x2)"], outputs=["y"], h=["x1"])
    with pytest.raises(PreconditionError, match="not observable"):
        design_lipschitz(unobs, lipschitz=0.1)
    nonlin_out = nlobs.System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1**2"])
    with pytest.raises(PreconditionError, match="y = Cx"):
        design_lipschitz(nonlin_out, lipschitz=0.1)
    with pytest.raises(PreconditionError, match="Hurwitz"):
        design_lipschitz(DAMPED, lipschitz=0.1, A=A_LIN, L=[[-5.0], [0.0]])
