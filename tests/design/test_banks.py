"""Banks' observer (003): matrix measure, Lemma 2.3/2.4 and Theorem 2.6 conditions, guaranteed rate ε - K."""

import numpy as np
import pytest
import sympy as sp

import nlobs
from nlobs.design import design_banks
from nlobs.analysis import matrix_measure
from nlobs.errors import PreconditionError

# 003 example 3.1 (Kou et al.), here without perturbation: x1' = x1, x2' = x1 - 2x2 + e^{-x2}, y = x1 + x2
KOU = nlobs.System(states=["x1", "x2"], f=["x1", "x1 - 2*x2 + exp(-x2)"], outputs=["y"], h=["x1 + x2"])


def test_matrix_measure_is_the_largest_eigenvalue_of_the_symmetric_part():
    rng = np.random.default_rng(0)
    M = rng.normal(size=(5, 3, 3))
    ref = [np.linalg.eigvalsh((m + m.T) / 2).max() for m in M]
    np.testing.assert_allclose(matrix_measure(M), ref)
    # 003 example 3.1: λ([[-1, -2], [2, -1]]) = λ(-I) = -1
    assert matrix_measure(np.array([[-1.0, -2.0], [2.0, -1.0]])) == pytest.approx(-1.0)


def test_lemma_2_3_example_rate_and_monotone_error():
    # e^{-x2} is dissipative, A + PB = [[-1, -2], [2, -1]] with P = (-2, 1)ᵀ: ε = 1 (003 §2 and ex. 3.1).
    d = design_banks(KOU, L=[[-2.0], [1.0]], region={"x2": (-2.0, 40.0)})
    assert d.certificate.values["epsilon"] == pytest.approx(1.0, abs=1e-9)
    run = nlobs.simulate(KOU, d, t_final=6.0, dt=1e-3, x0=[1.0, 0.0], xhat0=[-1.0, 1.0], engine="vm")
    e, t = run.error_norm(), run.t
    # Lemma 2.3: ‖x̂ - x‖ <= e^{-εt}‖x̂(0) - x(0)‖, so e(t)e^{t} never exceeds e(0)
    assert np.all(e * np.exp(t) <= e[0] * (1 + 1e-7))


def test_theorem_2_6_with_a_nonlinear_output_reproduces_the_corrected_jacobian():
    # 003 example 3.2. The paper prints Df + P·DB as diag(-1 - 2x1², -1 - 5x2²): both entries are
    # typos (d/dx1 x1³ = 3x1², d/dx2 x2⁵ = 5x2⁴); the conclusion λ <= -1 is unaffected.
    sys = nlobs.System(states=["x1", "x2"], f=["-x1 - x1**3 + x1*x2", "-x2 - x2**5 - 4*x1*x2"], outputs=["y"], h=["x1*x2"])
    d = design_banks(sys, L=[[-1.0], [4.0]], region={"x1": (-2.0, 2.0), "x2": (-2.0, 2.0)})
    x1, x2 = sp.symbols("x1 x2", real=True)
    assert d.certificate.values["jacobian"] == str([[-3 * x1**2 - 1, 0], [0, -5 * x2**4 - 1]])
    assert d.certificate.values["epsilon"] == pytest.approx(1.0, abs=1e-9)
    assert d.certificate.values["guaranteed_rate"] == pytest.approx(1.0, abs=1e-9)


def test_perturbation_lipschitz_constant_is_estimated_and_limits_the_rate():
    sys = nlobs.System(states=["x1", "x2"], f=["x1 + 0.5*sin(x1)", "x1 - 2*x2 + exp(-x2)"], outputs=["y"], h=["x1 + x2"])
    d = design_banks(sys, L=[[-2.0], [1.0]], region={"x1": (-3.0, 3.0), "x2": (-2.0, 40.0)}, perturbation=["0.5*sin(x1)", 0])
    assert d.certificate.values["K"] == pytest.approx(0.5, abs=1e-9)
    assert d.certificate.values["guaranteed_rate"] == pytest.approx(0.5, abs=1e-9)
    with pytest.raises(PreconditionError, match=r"K = 1\.5 is not below ε = 1"):
        design_banks(sys, L=[[-2.0], [1.0]], region={"x2": (-2.0, 40.0)}, perturbation=["0.5*sin(x1)", 0],
                     perturbation_bound=1.5)


def test_bad_gain_is_refused_with_the_point():
    with pytest.raises(PreconditionError, match=r"λ\(Df1 \+ P·DB\) = .* >= 0"):
        design_banks(KOU, L=[[1.0], [1.0]], region={"x2": (-2.0, 2.0)})
    with pytest.raises(PreconditionError, match="region"):
        design_banks(KOU, L=[[-2.0], [1.0]])


def test_constant_jacobian_is_decided_exactly():
    # LTI model: Df1 + P·DB = A + PC is constant, so ε = -λ(A + PC) exactly (no region needed, evidence "exact")
    lti = nlobs.System(states=["x1", "x2"], f=["-x1 + 3*x2", "-2*x2"], outputs=["y"], h=["x1"])
    d = design_banks(lti, L=[[-1.0], [0.0]])
    M = np.array([[-2.0, 3.0], [0.0, -2.0]])                      # A + PC
    assert d.certificate.values["epsilon"] == pytest.approx(-np.linalg.eigvalsh((M + M.T) / 2).max(), abs=1e-12)
    assert d.certificate.values["epsilon"] == pytest.approx(0.5, abs=1e-12)   # -(-2 + 3/2)
    first = d.certificate.checks[0]
    assert first.holds and first.evidence == "exact (constant matrix)"


def test_input_in_the_jacobian_ranges_over_the_region():
    # Df1 + P·DB = [[-2, u], [0, -3]] (y = x1, P = (-1, 0)): λ = (-5 + sqrt(1 + u²))/2, largest at |u| = 1:
    # ε = (5 - √2)/2 over u in [-1, 1] (closed form); the evidence says the sup was sampled
    s = nlobs.System(states=["x1", "x2"], f=["-x1 + u*x2", "-3*x2"], inputs=["u"], outputs=["y"], h=["x1"])
    d = design_banks(s, L=[[-1.0], [0.0]], region={"u": (-1.0, 1.0)})
    assert d.certificate.values["epsilon"] == pytest.approx((5 - np.sqrt(2)) / 2, abs=1e-9)
    assert "sampled" in d.certificate.checks[0].evidence
    d2 = design_banks(s, L=[[-1.0], [0.0]], region={"u": (-3.0, 3.0)})
    assert d2.certificate.values["epsilon"] == pytest.approx((5 - np.sqrt(10)) / 2, abs=1e-9)


def test_perturbation_is_taken_out_of_the_jacobian_and_measured_in_the_2_norm():
    # Theorem 2.6 splits f = f1 + f2: the certificate's Jacobian is Df1 + P·DB (f2 removed), and K = sup‖Df2‖₂
    # (the spectral norm: for Df2 = [[0, 0.3], [0.4, 0]] it is 0.4, the Frobenius norm would be 0.5)
    sys = nlobs.System(states=["x1", "x2"], f=["-2*x1 + 0.3*x2", "0.4*x1 - 2*x2"], outputs=["y"], h=["x1"])
    d = design_banks(sys, L=[[0.0], [0.0]], perturbation=["0.3*x2", "0.4*x1"])
    assert d.certificate.values["jacobian"] == "[[-2, 0], [0, -2]]"
    assert d.certificate.values["K"] == pytest.approx(0.4, abs=1e-12) and d.certificate.values["epsilon"] == pytest.approx(2.0)
    nl = nlobs.System(states=["x1", "x2"], f=["-2*x1 + 0.3*sin(x2)", "0.4*sin(x1) - 2*x2"], outputs=["y"], h=["x1"])
    d2 = design_banks(nl, L=[[0.0], [0.0]], perturbation=["0.3*sin(x2)", "0.4*sin(x1)"], region={"x1": (-1, 1), "x2": (-1, 1)})
    assert d2.certificate.values["K"] == pytest.approx(0.4, abs=1e-9)          # at x = 0
    assert "sampled" in d2.certificate.checks[1].evidence


def test_theorem_2_6_boundaries_are_strict():
    # ε must be > 0 and K < ε strictly (003 Theorem 2.6); the refusal names the worst point
    zero = nlobs.System(states=["x1", "x2"], f=["0*x1", "-x2"], outputs=["y"], h=["x2"])
    with pytest.raises(PreconditionError, match=r"λ\(Df1 \+ P·DB\) = 0 >= 0"):
        design_banks(zero, L=[[0.0], [0.0]])
    with pytest.raises(PreconditionError, match=r"K = 1 is not below ε = 1"):
        design_banks(KOU, L=[[-2.0], [1.0]], region={"x2": (-2.0, 40.0)}, perturbation=["0", "0"], perturbation_bound=1.0)
    with pytest.raises(PreconditionError, match=r"at \{'x2': "):
        design_banks(KOU, L=[[1.0], [1.0]], region={"x2": (-2.0, 2.0)})
    for bad in (-0.1, float("inf"), float("nan")):
        with pytest.raises(PreconditionError, match="perturbation_bound"):
            design_banks(KOU, L=[[-2.0], [1.0]], region={"x2": (-2.0, 40.0)}, perturbation=["0", "0"], perturbation_bound=bad)
    d = design_banks(KOU, L=[[-2.0], [1.0]], region={"x2": (-2.0, 40.0)}, perturbation=["0", "0"], perturbation_bound=0.5)
    assert d.certificate.values["guaranteed_rate"] == pytest.approx(0.5, abs=1e-9)


def test_certificate_lists_what_is_assumed():
    d = design_banks(KOU, L=[[-2.0], [1.0]], region={"x2": (-2.0, 40.0)}, perturbation=["0", "0"], perturbation_bound=0.5)
    cert = d.certificate
    assert cert.method == "Banks exponential observer" and "Banks (1980)" in cert.reference
    assumed = [c.condition for c in cert.checks if c.status == "assumed"]
    assert any("stay in the convex region" in a for a in assumed) and any("K = 0.5 given" in a for a in assumed)
    lti = nlobs.System(states=["x1", "x2"], f=["-x1 + 3*x2", "-2*x2"], outputs=["y"], h=["x1"])
    assert not any(c.status == "assumed" for c in design_banks(lti, L=[[-1.0], [0.0]]).certificate.checks)


def test_a_single_string_perturbation_says_a_list_is_needed():
    import nlobs

    pend = nlobs.System(states=["x1", "x2"], f=["x2", "-sin(x1) - x2"], outputs=["y"], h=["x1"])
    with pytest.raises(nlobs.ShapeError, match=r"`perturbation` must be a list of 2 expressions, one per state \(x1, x2\)"):
        nlobs.design_banks(pend, L=[[-1], [0]], perturbation="x1")
