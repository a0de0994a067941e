"""GPEBO and the 2G+D observer (000_6cd8bea7ca1db43b.txt Lemma 1, eqs. 8-13, Proposition 1)."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import PreconditionError, StateAffine, System, design_gpebo_2gd, design_gpebo, simulate
from nlobs.design import DREM, Gradient, LeastSquares

OSC = StateAffine([[0, 1], [-1, 0]], [0, "u"], [[1], [0]], inputs=["u"], name="oscillator")   # uniformly stable, UCO


def test_lemma_1_relation_holds_along_a_run():
    # x = ξ + Φ_A θ with θ = x(0) - ξ(0) (000 eqs. 8, 13), whatever the estimator does
    sa = StateAffine([[0, "u"], [0, "-0.3"]], [0, "sin(t)"], [[1], [0]], inputs=["u"])
    d = design_gpebo_2gd(sa, gamma_g=1.0, gamma=1.0)
    x0, xh0 = np.array([0.7, -1.2]), np.array([0.2, 0.4])
    run = simulate(sa.to_system(), {"o": d}, t_final=5.0, dt=1e-3, x0=x0, inputs={"u": "cos(t)"}, xhat0=xh0)
    z, names = run.observers["o"].z, d.z_names
    xi = z[:, [names.index(f"xi[{i}]") for i in range(2)]]
    Phi = z[:, [names.index(f"Phi[{i},{j}]") for j in range(2) for i in range(2)]].reshape(-1, 2, 2, order="F")
    theta = x0 - xh0
    assert np.allclose(xi + Phi @ theta, run.x, atol=1e-9)
    # and the regression: Y = y - Cᵀξ = ψᵀθ with ψ = Φᵀ C
    assert np.allclose(run.y[:, 0] - xi[:, 0], Phi[:, 0, :] @ theta, atol=1e-9)


@pytest.mark.parametrize("n", [1, 2, 3])
def test_2gd_order_is_3_plus_2n_times_n(n):
    A = np.diag(-np.arange(1.0, n + 1))
    d = design_gpebo_2gd(StateAffine(A, [0] * n, np.eye(n)[:, :1]))
    assert d.n_z == (3 + 2 * n) * n
    check = [c for c in d.certificate.checks if "(3 + 2n)n" in c.condition][0]
    assert check.holds


# gains below the rotation rate of ψ (1 rad/s): with γ ≫ ω the gradient error stays orthogonal to ψ and decays
# only like ω²/γ
@pytest.mark.parametrize("est", [Gradient(1.0), LeastSquares(1.0, forgetting=1.0), DREM(50.0), None])
def test_gpebo_with_every_estimator_converges_on_an_oscillator(est):
    d = design_gpebo(OSC, estimator=est)
    run = simulate(OSC.to_system(), {"o": d}, t_final=30.0, dt=1e-3, x0=[1.0, -0.5], inputs={"u": "sin(0.5*t)"})
    assert run.error_norm("o")[-1] < 1e-3


def test_unstable_homogeneous_part_is_refused_and_injection_fixes_it():
    sa = StateAffine([[0, 1], [2, 0]], [0, 0], [[1], [0]])         # eigenvalues ±√2: assumption (5) fails
    with pytest.raises(PreconditionError, match=r"assumption 5.*1\.414.*output injection `L`"):
        design_gpebo_2gd(sa)
    d = design_gpebo_2gd(sa, gamma_g=5.0, gamma=50.0, L=[[3], [4]])     # A - LCᵀ = [[-3, 1], [-2, 0]]: eigenvalues -1, -2
    assert any("A - LCᵀ" in c.condition and c.holds for c in d.certificate.checks)
    run = simulate(sa.to_system(), {"o": d}, t_final=10.0, dt=1e-3, x0=[1.0, 1.0])
    assert run.error_norm("o")[-1] < 1e-6
    with pytest.raises(PreconditionError, match="Jordan block"):
        design_gpebo_2gd(StateAffine([[0, 1], [0, 0]], [0, 0], [[1], [0]]))   # double integrator: Φ grows like t


def test_state_affine_recognised_from_a_system_and_refused_otherwise():
    s = System(states=["x1", "x2"], f=["u*x2", "-x2 + u"], outputs=["y"], h=["x1"], inputs=["u"])
    d = design_gpebo_2gd(s)
    assert d.system.states == ("x1", "x2")
    bad = System(states=["x1", "x2"], f=["x2**2", "0"], outputs=["y"], h=["x1"])
    with pytest.raises(PreconditionError, match=r"not state-affine.*x2"):
        design_gpebo_2gd(bad)


def test_a_depending_on_the_output_uses_the_measurement():
    # Van der Pol-like A(y) = [[0, 1], [-1, 1 - y²]]: the certificate says (5) is not decidable symbolically
    sa = StateAffine([[0, 1], [-1, "-(y**2)"]], [0, 0], [[1], [0]], outputs=["y"])
    d = design_gpebo_2gd(sa)
    assert "not decidable" in d.certificate.values["assumption (5)"]
    flow = np.asarray(d.flow(0.0, np.arange(d.n_z, dtype=float) * 0.1, [], [2.0])).ravel()
    # ξ' = A(y)ξ with ξ = (0, 0.1) and y = 2: (0.1, -4·0.1)
    assert np.allclose(flow[:2], [0.1, -0.4])


def test_refusal_names_the_unstable_eigenvalue_and_the_matrix():
    # assumption (5) of 000: the message names the eigenvalue with the largest real part (3, not -1) and which
    # matrix has it (A without injection, A - LCᵀ with one), with the matching next step
    sa = StateAffine([[-1, 0], [0, 3]], [0, 0], [[1], [1]])
    with pytest.raises(PreconditionError, match=r"A has the eigenvalue 3\+0j .*choose an output injection `L`"):
        design_gpebo_2gd(sa)
    with pytest.raises(PreconditionError, match=r"A - LCᵀ has the eigenvalue 3\+0j .*choose another `L`"):
        design_gpebo_2gd(sa, L=[[0.5], [0.0]])      # A - LCᵀ = [[-1.5, -0.5], [0, 3]]: 3 stays


def test_2gd_documented_defaults_and_initial_estimate():
    # design_gpebo_2gd's defaults are γ_g = γ = 1 (its signature and docstring); x̂(0) is the xhat0 given (ξ(0) = x̂0, θ̂(0) = 0)
    d = design_gpebo_2gd(OSC, xhat0=[0.25, -0.75])
    assert d.certificate.values["gd.gamma_g"] == 1.0 and d.certificate.values["gd.gamma"] == 1.0
    run = simulate(OSC.to_system(), {"o": d}, t_final=0.01, dt=1e-3, x0=[1.0, -0.5], inputs={"u": "0"})
    assert np.array_equal(run.observers["o"].xhat[0], [0.25, -0.75])


ROT = [[0, 1], [-1, 0]]


@pytest.mark.parametrize("A, ok", [
    (np.block([[np.array(ROT), np.zeros((2, 2))], [np.zeros((2, 2)), np.array(ROT)]]), True),   # ±i twice, semisimple
    (np.block([[np.array(ROT), np.eye(2)], [np.zeros((2, 2)), np.array(ROT)]]), False),          # ±i with Jordan blocks
    (np.block([[np.array(ROT), np.zeros((2, 1))], [np.zeros((1, 3))]]), True),                   # ±i and 0, semisimple
    (np.diag([-1e6, 1e-7]), True),     # 1e-7 is round-off next to 1e6 (tolerance 1e-9·max|A|): on the axis, simple
    (np.diag([-1.0, 1e-7]), False),    # next to 1, 1e-7 is a real unstable eigenvalue
])
def test_uniform_stability_of_000_assumption_5_on_the_imaginary_axis(A, ok):
    # assumption (5): Φ_A bounded iff every eigenvalue has Re < 0, or Re = 0 and is semisimple (no Jordan block)
    n = A.shape[0]
    sa = StateAffine(A.tolist(), [0] * n, np.eye(n)[:, :1].tolist())
    if ok:
        d = design_gpebo_2gd(sa)
        assert any("assumption 5" in c.condition and c.holds for c in d.certificate.checks)
    else:
        with pytest.raises(PreconditionError, match=r"^design_gpebo: the homogeneous part is not uniformly stable"):
            design_gpebo_2gd(sa)


def test_injection_gain_may_use_parameters_and_is_checked():
    # L in the model's parameters is the same observer as L in numbers; a wrong shape names `L`
    sa = StateAffine([[0, 1], [2, 0]], [0, 0], [[1], [0]], params={"l1": 3.0, "l2": 4.0})
    d_sym = design_gpebo_2gd(sa, gamma_g=5.0, gamma=50.0, L=[["l1"], ["l2"]])
    d_num = design_gpebo_2gd(sa, gamma_g=5.0, gamma=50.0, L=[[3], [4]])
    z = np.linspace(0.1, 1.4, d_num.n_z)
    assert np.allclose(np.asarray(d_sym.flow(0.3, z, [], [0.7])), np.asarray(d_num.flow(0.3, z, [], [0.7])), atol=0, rtol=0)
    with pytest.raises(ValueError, match="`L`"):
        design_gpebo_2gd(sa, L=[[1, 2]])


def test_gpebo_default_estimator_is_gd_with_unit_gains():
    d = design_gpebo(OSC)
    assert d.certificate.values["gd.gamma_g"] == 1.0 and d.certificate.values["gd.gamma"] == 1.0


def test_method_certificate_and_reference_name_what_was_built():
    gd = design_gpebo_2gd(OSC)
    assert gd.method == "gpebo_2gd" and gd.certificate.method == "2G+D observer"
    assert "Wang, Ortega & Bobtsov" in gd.certificate.reference and "(16)-(17)" in gd.certificate.reference
    g = design_gpebo(OSC, estimator=Gradient(1.0))
    assert g.method == "gpebo" and g.certificate.method == "GPEBO observer with Gradient estimator"
    assert "gradient estimator" in g.certificate.reference
    sa = StateAffine([[0, 1], [2, 0]], [0, 0], [[1], [0]])
    assert design_gpebo_2gd(sa, L=[[3], [4]]).certificate.method == "2G+D observer and output injection"
    with pytest.raises(PreconditionError, match=r"^design_gpebo: .*not state-affine"):
        design_gpebo(System(states=["x1", "x2"], f=["x2**2", "0"], outputs=["y"], h=["x1"]))


def test_assumption_5_tolerance_is_relative_to_the_size_of_a():
    # the round-off tolerance of assumption (5) is 1e-9·max(1, max|A|): next to 1, an eigenvalue 1.5e-9 is a
    # real (slow) instability of Φ_A and is refused; at 0.5e-9 it is round-off on the axis
    with pytest.raises(PreconditionError, match="eigenvalue 1.5e-09"):
        design_gpebo_2gd(StateAffine(np.diag([-1.0, 1.5e-9]).tolist(), [0, 0], [[1], [1]]))
    design_gpebo_2gd(StateAffine(np.diag([-1.0, 0.5e-9]).tolist(), [0, 0], [[1], [1]]))


def test_time_varying_injection_gain_and_estimator_errors_name_the_design():
    # L(t) = (e^{-t}, 0): A - L(t)Cᵀ depends on t, so assumption (5) is not decidable symbolically
    # (000 assumption 5 concerns the transition matrix of a time-varying A); the certificate says so
    d = design_gpebo(OSC, L=[["exp(-t)"], ["0"]])
    assert d.certificate.values["assumption (5)"].startswith("not decidable symbolically")
    assert not any("assumption 5" in c.condition for c in d.certificate.checks)
    z = np.linspace(0.1, 1.4, d.n_z)
    f0, f1 = (np.asarray(d.flow(t, z, [0.0], [0.7])).ravel() for t in (0.0, 1.0))
    # ξ' = Aξ + b + L(t)(y - Cᵀξ): the first component changes by (e^0 - e^-1)(y - ξ1) between t = 0 and 1
    assert f0[0] - f1[0] == pytest.approx((1 - np.exp(-1)) * (0.7 - z[0]), abs=1e-14)
    with pytest.raises(PreconditionError, match=r"^design_gpebo: `estimator` must be an estimator"):
        design_gpebo(OSC, estimator="bogus")
