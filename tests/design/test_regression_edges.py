"""Regression models and DREM at their edges: documented defaults and the flow of the estimator against a hand
computation. Written against the mutants the mutation run (benchmarks/mutation.py) found alive in
design/pebo/_regression.py. DREM: extension by the Kreisselmeier filter and mixing with the adjugate,
000_6cd8bea7ca1db43b.txt eqs. (17c)-(19) (the estimator θ̂ᵢ' = γᵢΔ(Y_m,i − Δθ̂ᵢ)).
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from nlobs import PreconditionError, ShapeError, System
from nlobs.model import symbol
from nlobs.design import DREM, GD, Gradient, LeastSquares, LinearRegression, design_drem, design_gd, design_gradient, design_least_squares

T = sp.Symbol("t")


def test_linear_regression_defaults_from_the_signals():
    # documented defaults: ψ = the signals, parameters theta1.., one output Y, no offset
    reg = LinearRegression(signals=["a", "b"])
    a, b = symbol("a"), symbol("b")
    assert reg.theta == ("theta1", "theta2") and reg.outputs == ("Y",) and reg.signals == ("a", "b")
    assert reg.psi == sp.Matrix([[a], [b]]) and reg.offset == sp.Matrix([[0]])
    th1, th2 = symbol("theta1"), symbol("theta2")
    assert sp.expand(reg.to_system().h[0] - (a * th1 + b * th2)) == 0


def test_linear_regression_defaults_of_a_matrix_regressor():
    # ψ 2x2 (two rows of Y): signals psi1..psi4 by default, outputs Y1, Y2; Y = ψᵀθ + d
    reg = LinearRegression([["psi1", "t"], ["0", "psi2"]], offset=["0", "cos(t)"])
    assert reg.signals == ("psi1", "psi2", "psi3", "psi4") and reg.theta == ("theta1", "theta2")
    assert reg.outputs == ("Y1", "Y2")
    p1, p2, th1, th2 = (symbol(k) for k in ("psi1", "psi2", "theta1", "theta2"))
    h = reg.to_system().h
    free_t = [s for s in h[1].free_symbols if s.name == "t"]
    assert sp.expand(h[0] - p1 * th1) == 0
    assert len(free_t) == 1 and sp.expand(h[1] - (free_t[0] * th1 + p2 * th2 + sp.cos(free_t[0]))) == 0


def test_linear_regression_refusals():
    with pytest.raises(ShapeError, match=r"^LinearRegression: give `psi` or `signals`"):
        LinearRegression()
    with pytest.raises(ShapeError, match=r"^LinearRegression: ψ is 2x1: give 2 parameter name\(s\) and 1 output name\(s\)"):
        LinearRegression(["psi1", "psi2"], theta=["a"])
    with pytest.raises(ShapeError, match=r"^LinearRegression: ψ is 2x1: give 2 parameter name\(s\) and 1 output name\(s\)"):
        LinearRegression(["psi1", "psi2"], outputs=["Y1", "Y2"])
    with pytest.raises(ValueError, match=r"^psi\[0, 0\]: 'zz': unknown name `zz`"):
        LinearRegression([["zz"]], signals=["a"])
    with pytest.raises(ValueError, match=r"^offset\[0, 0\]: 'zz': unknown name `zz`"):
        LinearRegression(["a"], signals=["a"], offset=["zz"])


def _z(d, values):
    return np.array([values[k] for k in d.z_names], dtype=float)


def test_drem_kreisselmeier_flow_matches_the_equations():
    # default extension: Kreisselmeier filter with a = 1, Ψe' = -aΨe + ψψᵀ, Ye' = -aYe + ψY; mixing Δ = det Ψe,
    # Ym = adj(Ψe) Ye, θ̂ᵢ' = γᵢ Δ (Ym,i − Δ θ̂ᵢ) (000 eqs. 17c-19), with one gain per parameter
    reg = LinearRegression(signals=["a", "b"])
    d = design_drem(reg, gamma=[2.0, 3.0])
    assert d.z_names == ("drem_Psi[0,0]", "drem_Psi[1,0]", "drem_Psi[0,1]", "drem_Psi[1,1]", "drem_Y[0]", "drem_Y[1]",
                         "theta_hat[0]", "theta_hat[1]")
    Pe = np.array([[2.0, 0.5], [0.3, 1.5]])
    Ye = np.array([0.7, -0.4])
    th = np.array([0.2, -0.1])
    z = np.concatenate([Pe.ravel(order="F"), Ye, th])
    psi = np.array([1.1, -0.6])
    Y = 0.9
    f = np.asarray(d.flow(0.0, z, psi, [Y])).ravel()
    delta = 2.0 * 1.5 - 0.5 * 0.3
    adj = np.array([[1.5, -0.5], [-0.3, 2.0]])
    Ym = adj @ Ye
    expect = np.concatenate([(-Pe + np.outer(psi, psi)).ravel(order="F"), -Ye + psi * Y,
                             np.array([2.0, 3.0]) * delta * (Ym - delta * th)])
    assert np.max(np.abs(f - expect)) < 1e-14
    assert d.certificate.values["internal states"] == 8


def test_drem_lti_filters_name_their_states():
    # extension by H(p) = λ/(p + λ) (one extra row per pole for a scalar regression with 2 parameters)
    reg = LinearRegression(signals=["a", "b"])
    d = design_drem(reg, lambdas=[3.0], xhat0=[0.5, -0.25])
    assert d.z_names[:3] == ("drem_Y1", "drem_psi1[0,0]", "drem_psi1[0,1]")
    assert d.z_names[-2:] == ("theta_hat[0]", "theta_hat[1]")


def test_gradient_and_gd_defaults_are_unit_gains():
    reg = LinearRegression(signals=["a"])
    g = design_gradient(reg)
    f = np.asarray(g.flow(0.0, np.array([0.3]), [2.0], [1.0])).ravel()
    # θ̂' = γψ(Y − ψθ̂) with γ = 1 (Yi, Ortega & Zhang eq. (34)): 2·(1 − 0.6) = 0.8
    assert f[0] == pytest.approx(0.8, abs=1e-15)
    gd = design_gd(reg)
    assert gd.certificate.values["gd.gamma_g"] == 1.0 and gd.certificate.values["gd.gamma"] == 1.0


def test_known_offset_is_subtracted_from_the_output():
    # Y = ψᵀθ + d: the estimators run on Y − d. Gradient (Yi, Ortega & Zhang eq. (34)) with d = cos t, γ = 1:
    # θ̂' = ψ(Y − d − ψθ̂) = 2·(1 − cos 0 − 0.6) = −1.2 at t = 0
    reg = LinearRegression(["a"], signals=["a"], offset=["cos(t)"])
    f = np.asarray(design_gradient(reg).flow(0.0, np.array([0.3]), [2.0], [1.0])).ravel()
    assert f[0] == pytest.approx(-1.2, abs=1e-15)


@pytest.mark.parametrize("fn, method, cls, ref", [
    (design_gradient, "gradient", "Gradient", "eqs. (34)"),
    (design_least_squares, "least_squares", "LeastSquares", "Ioannou & Sun (1996)"),
    (design_drem, "drem", "DREM", "Aranovskiy"),
    (design_gd, "gd", "GD", "(16)-(17)"),
])
def test_each_estimator_design_names_what_was_built(fn, method, cls, ref):
    d = fn(LinearRegression(signals=["a"]), xhat0=[0.5])
    assert d.method == method and d.certificate.method == f"{cls} parameter estimator"
    assert ref in d.certificate.reference and d.xhat0.tolist() == [0.5]
    assert [c.condition for c in d.certificate.checks] == ["model is a linear regression Y = ψ(s, t)ᵀθ + d with θ constant"]
    assert d.certificate.checks[0].holds


def test_default_gains_are_one():
    # the documented defaults: γ = 1 (gradient, DREM), P0 = 1 (least squares)
    reg = LinearRegression(signals=["a"])
    assert design_drem(reg).certificate.values["drem.gamma"] == 1.0
    assert design_least_squares(reg).certificate.values["least_squares.P0"] == 1.0


@pytest.mark.parametrize("make, message", [
    (lambda: Gradient(-1.0), r"^Gradient: `gamma` must be positive"),
    (lambda: LeastSquares(-1.0), r"^LeastSquares: `P0` must be positive"),
    (lambda: LeastSquares(1.0, np.inf), r"^LeastSquares: `forgetting` must be a number >= 0, got inf"),
    (lambda: LeastSquares(1.0, 0.0, -1.0), r"^LeastSquares: `p_max` must be a positive number"),
    (lambda: DREM(-1.0), r"^DREM: `gamma` must be positive"),
    (lambda: DREM(kreisselmeier=0.0), r"^DREM: `kreisselmeier` must be a positive number"),
    (lambda: DREM(lambdas=[0.0]), r"^DREM: every filter pole in `lambdas` must be positive"),
    (lambda: design_gradient(System(states=["th"], f=["th"], outputs=["y"], h=["th"])),
     r"^design_gradient: 'system' is not a regression model: th' = th"),
    (lambda: design_least_squares(System(states=["th"], f=["th"], outputs=["y"], h=["th"])), r"^design_least_squares: "),
    (lambda: design_drem(System(states=["th"], f=["th"], outputs=["y"], h=["th"])), r"^design_drem: "),
    (lambda: design_gradient(LinearRegression(signals=["a", "b"]), gamma=np.array([[1.0, 0], [0, -1]])),
     r"^Gradient: `gamma` must be positive definite; its smallest eigenvalue is -1"),
    (lambda: design_gradient(LinearRegression(signals=["a", "b"]), gamma=[[1.0, 0], [0, -1]]),
     r"^Gradient: `gamma` must be positive definite; its smallest eigenvalue is -1"),
])
def test_refusals_name_the_estimator_and_the_argument(make, message):
    with pytest.raises(PreconditionError, match=message):
        make()


def test_matrix_gain_given_as_an_array_or_a_list():
    # Γ = diag(2, 3): θ̂' = Γψ(Y − ψᵀθ̂); ψ = (1, 2), θ̂ = 0, Y = 1 → (2·1·1, 3·2·1) = (2, 6)
    reg = LinearRegression(signals=["a", "b"])
    for gain in (np.diag([2.0, 3.0]), [[2.0, 0.0], [0.0, 3.0]]):
        f = np.asarray(design_gradient(reg, gamma=gain).flow(0.0, np.zeros(2), [1.0, 2.0], [1.0])).ravel()
        assert f.tolist() == [2.0, 6.0]


def test_excitation_report_against_a_hand_computed_run():
    # ψ = a; a = 0, 0, 2, 2 at t = 0..3: ∫ψψᵀ by the trapezoid rule = 0, 0, 2, 6 (the IE level of 000 eq. (15))
    from nlobs.design import excitation_report

    d = design_gradient(LinearRegression(signals=["a"]))
    rep = excitation_report(d, [0, 1, 2, 3], [[0], [0], [0], [0]], [0, 0, 2, 2], [1, 1, 1, 1], window=2, tol=2.0)
    assert rep.ie_level.tolist() == [0.0, 0.0, 2.0, 6.0]
    assert rep.ie_time == 3.0                    # the first level strictly above tol = 2
    assert rep.pe_level == 2.0                   # windows [0, 2] and [1, 3]: min(2 - 0, 6 - 0) (Yi, Ortega & Zhang eq. 42)
    assert rep.delta is None and rep.delta_time is None
    assert str(rep) == "IE level λmin∫ψψᵀ = 6 at t = 3; IE reached at t_d = 3; PE level over windows of 2: 2"
    rep0 = excitation_report(d, [0, 1, 2, 3], [[0], [0], [0], [0]])   # no inputs given: ψ = 0, never excited
    assert rep0.ie_level.tolist() == [0.0] * 4 and rep0.ie_time is None
    assert str(rep0) == "IE level λmin∫ψψᵀ = 0 at t = 3; IE reached never"
    with pytest.raises(PreconditionError, match=r"^excitation_report: `window`"):
        excitation_report(d, [0, 1, 2, 3], [[0]] * 4, [0, 0, 2, 2], window=-1.0)
    with pytest.raises(PreconditionError, match=r"^excitation_report: `window` = 5 is longer than the run \(3\)"):
        excitation_report(d, [0, 1, 2, 3], [[0]] * 4, [0, 0, 2, 2], window=5.0)


def test_excitation_report_of_drem_reports_delta():
    # DREM with the Kreisselmeier extension and one parameter: Δ = det Ψe = Ψe, the first internal state
    from nlobs.design import excitation_report

    d = design_drem(LinearRegression(signals=["a"]))
    z = [[0, 0, 0], [5e-7, 0, 0], [0.5, 0, 0], [3, 0, 0]]
    rep = excitation_report(d, [0, 1, 2, 3], z, [0, 0, 2, 2], [1, 1, 1, 1])
    assert rep.delta.tolist() == [0.0, 5e-7, 0.5, 3.0] and rep.delta_time == 2.0   # |Δ| > 1e-6 from t = 2
    assert str(rep) == "IE level λmin∫ψψᵀ = 6 at t = 3; IE reached at t_d = 2; |Δ| > 1e-06 from t = 2, final Δ = 3"
    rep0 = excitation_report(d, [0, 1, 2, 3], [[0, 0, 0]] * 4, [0, 0, 2, 2])
    assert str(rep0).endswith("|Δ| > 1e-06 never, final Δ = 0")


@pytest.mark.parametrize("fn", [design_gradient, design_least_squares, design_drem, design_gd])
def test_the_estimate_starts_at_xhat0(fn):
    d = fn(LinearRegression(signals=["a", "b"]), xhat0=[0.5, -0.25])
    z0 = np.asarray(d.initial(xhat0=[0.5, -0.25])["z0"]).ravel()
    got = [z0[d.z_names.index(k)] for k in ("theta_hat[0]", "theta_hat[1]")]
    assert got == [0.5, -0.25]
    assert d.certificate.values["excitation monitor"].estimator == d.method


@pytest.mark.parametrize("make, message", [
    (lambda: Gradient(0.0), r"^Gradient: `gamma` must be positive"),                 # a zero gain never adapts
    (lambda: DREM([1.0, -1.0]), r"^DREM: `gamma` must be positive"),
    (lambda: GD(-1.0, 1.0), r"^GD: `gamma_g` must be a positive number"),
    (lambda: GD(1.0, -1.0), r"^GD: `gamma` must be a positive number"),
    (lambda: design_least_squares(LinearRegression(signals=["a"]), P0=[[2.0]], p_max=2.0),
     r"^LeastSquares: `p_max` = 2 must exceed ‖P0‖_F = 2"),
    (lambda: design_least_squares(LinearRegression(signals=["a"]), P0=[[-2.0]]), r"^LeastSquares: `P0` must be positive definite"),
])
def test_more_refusals_name_the_estimator_and_the_argument(make, message):
    with pytest.raises(PreconditionError, match=message):
        make()


def test_empty_matrices_keep_their_shape():
    from nlobs.design.pebo._regression import sx_matrix

    assert sx_matrix(sp.zeros(2, 0), []).shape == (2, 0)
    assert sx_matrix(sp.zeros(0, 3), []).shape == (0, 3)
