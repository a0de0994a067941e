"""KKL (004 Prop. 1), PEBO (Prop. 2), KKL+PEBO (Prop. 3, R5), windowed NLS and the Prop. 7 class.

Reference values: closed-form error laws (ξ - φ(x) = e^{Λt}(ξ0 - φ(x0)), φ(x) = ξ + θ) and
maps solved by hand; 004_f1e237c45ff4719e.txt equation numbers in each test.
"""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import (PreconditionError, ShapeError, System, WindowedNLS, design_kkl, design_kkl_pebo, design_kkl_pebo_cascade,
                   design_pebo, simulate)
from nlobs.design import GD, Gradient, excitation_report

# harmonic oscillator, y = x1. With Λ = diag(-1, -2), B = (1, 1), the rows of φ = Tx solve
# t_i (A - λ_i I) = C, i.e. t_i = C (A - λ_i I)^{-1} = (-λ_i, -1)/(λ_i² + 1): φ = ((x1 - x2)/2, (2x1 - x2)/5)
OSC = System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1"], name="oscillator")
OSC_KKL = dict(phi=["(x1 - x2)/2", "(2*x1 - x2)/5"], left_inverse=["5*xi2 - 2*xi1", "5*xi2 - 4*xi1"], B=["y", "y"],
               Lambda=[-1, -2])
# x1' = x2, x2' = -x1 + u: φ = x2 obeys φ' = -y + u (004 eq. 7)
PEB = System(states=["x1", "x2"], f=["x2", "-x1 + u"], outputs=["y"], h=["x1"], inputs=["u"], name="pebo_plant")
PEB_MAPS = dict(phi=["x2"], left_inverse=["y", "xi1"], B=["-y + u"])
# x2 has a stable mode (KKL, λ = -1), x3 none (PEBO): Λ = diag(-1, 0), φ = (x2, x3)
MIX = System(states=["x1", "x2", "x3"], f=["-x1 + x2 + x3", "-x2 + x1", "u"], outputs=["y"], h=["x1"], inputs=["u"],
             name="mixed")


def test_kkl_error_follows_the_linear_law_004_prop_1():
    d = design_kkl(OSC, **OSC_KKL)
    x0 = np.array([1.0, 0.5])
    run = simulate(OSC, {"k": d}, t_final=6.0, dt=1e-3, x0=x0)
    T = np.array([[0.5, -0.5], [0.4, -0.2]])
    e0 = -T @ x0                                  # ξ(0) = φ(x̂0) = 0
    err_xi = np.exp(np.outer(run.t, [-1.0, -2.0])) * e0
    assert np.allclose(run.error("k"), err_xi @ np.linalg.inv(T).T, atol=1e-9)


def test_kkl_pde_failure_names_the_component_and_the_state():
    bad = dict(OSC_KKL, B=["y", "2*y"])
    with pytest.raises(PreconditionError, match=r"fails for component 2 .*residual is -y|fails for component 2 .*x1"):
        design_kkl(OSC, **bad)
    with pytest.raises(PreconditionError, match="not a left inverse"):
        design_kkl(OSC, **dict(OSC_KKL, left_inverse=["xi1", "xi2"]))
    with pytest.raises(PreconditionError, match="λ = 0|zero eigenvalue"):
        design_kkl(OSC, **dict(OSC_KKL, Lambda=[-1, 0]))
    with pytest.raises(PreconditionError, match=r"λ_2 = 1 > 0"):
        design_kkl_pebo(OSC, **dict(OSC_KKL, Lambda=[-1, 1]))
    with pytest.raises(PreconditionError, match="n - p"):
        design_kkl(MIX, phi=["x2"], left_inverse=["y", "xi1", "xi1"], B=["y"], Lambda=[-1])


def test_pebo_key_relation_and_convergence_004_eqs_9_10():
    d = design_pebo(PEB, **PEB_MAPS, estimator=Gradient(5.0), alpha=2.0)
    x0 = np.array([0.3, -0.8])
    run = simulate(PEB, {"p": d}, t_final=15.0, dt=1e-3, x0=x0, inputs={"u": "sin(t)"})
    z, names = run.observers["p"].z, d.z_names
    xi = z[:, names.index("xi")]
    assert np.allclose(run.x[:, 1] - xi, x0[1], atol=1e-9)             # φ(x(t)) = ξ(t) + θ, θ = φ(x0) - ξ(0)
    assert run.error_norm("p")[-1] < 1e-6
    assert "b = [[1]]" in d.certificate.values["regressor psi"]


def test_pebo_refuses_a_model_outside_its_pde_and_says_what_would_work():
    # x2' = -x2 + ...: needs λ = -1 (KKL), not λ = 0
    s = System(states=["x1", "x2"], f=["x2", "-x2 + x1"], outputs=["y"], h=["x1"])
    with pytest.raises(PreconditionError, match=r"component 1 .*depends on the state\(s\) x2.*KKL component with λ = -1"):
        design_pebo(s, phi=["x2"], left_inverse=["y", "xi1"], B=["y"])


def test_pebo_regression_must_carry_theta():
    s = System(states=["x1", "x2"], f=["-x1", "u"], outputs=["y"], h=["x1"], inputs=["u"])
    with pytest.raises(PreconditionError, match="does not appear in the regression"):
        design_pebo(s, phi=["x2"], left_inverse=["y", "xi1"], B=["u"])


def test_nonlinear_regression_needs_a_reparametrisation_or_nls():
    s = System(states=["x1", "x2"], f=["-x1 + exp(x2)", "u"], outputs=["y"], h=["x1"], inputs=["u"])
    maps = dict(phi=["x2"], left_inverse=["y", "xi1"], B=["u"])
    with pytest.raises(PreconditionError, match="not linear in θ.*WindowedNLS"):
        design_pebo(s, **maps)
    with pytest.raises(PreconditionError, match="does not invert"):
        design_pebo(s, **maps, Theta=["exp(theta1)"], theta_from_Theta=["Theta1"])
    with pytest.raises(PreconditionError, match="both"):
        design_pebo(s, **maps, Theta=["exp(theta1)"])
    # α = 3: the filter transient ε = α y(0) e^{-αt} (004 §V-A) is then below 1e-12 at t = 10
    d = design_pebo(s, **maps, Theta=["exp(theta1)"], theta_from_Theta=["log(Theta1)"], estimator=Gradient(20.0), alpha=3.0)
    n = design_pebo(s, **maps, estimator=WindowedNLS(window=1.0, samples=11, iterations=2))
    run = simulate(s, {"lin": d, "nls": n}, t_final=10.0, dt=1e-3, x0=[0.5, 0.3], inputs={"u": "0.3*sin(t)"})
    assert run.error_norm("lin")[-1] < 1e-6
    assert run.error_norm("nls")[-1] < 1e-5
    assert n.update is not None and d.update is None


def test_windowed_nls_options_are_checked():
    for kw, match in ((dict(window=0.0), "window"), (dict(window=1.0, samples=2), "samples"),
                      (dict(window=1.0, iterations=0), "iterations"), (dict(window=1.0, damping=0.0), "damping")):
        with pytest.raises(PreconditionError, match=match):
            WindowedNLS(**kw)


def test_kkl_pebo_partition_004_prop_3():
    d = design_kkl_pebo(MIX, phi=["x2", "x3"], left_inverse=["y", "xi1", "xi2"], B=["y", "u"], Lambda=[-1, 0],
                        estimator=Gradient(10.0), alpha=1.0)
    assert d.certificate.values["KKL components"] == [1] and d.certificate.values["PEBO components"] == [2]
    run = simulate(MIX, {"kp": d}, t_final=20.0, dt=1e-3, x0=[0.2, 1.0, -0.5], inputs={"u": "cos(t)"})
    xi1 = run.observers["kp"].z[:, d.z_names.index("xi[0]")]
    assert np.allclose(xi1 - run.x[:, 1], -1.0 * np.exp(-run.t), atol=1e-9)   # KKL part: ξ1 - x2 = e^{-t}(0 - 1)
    assert run.error_norm("kp")[-1] < 1e-6


def test_r5_similar_lambda():
    # φ' = (x2 + x3, x3): d/dt φ'_1 = -φ'_1 + φ'_2 + y + u, d/dt φ'_2 = u, so Λ = [[-1, 1], [0, 0]], which is
    # P⁻¹ diag(-1, 0) P (004 R5)
    d = design_kkl_pebo(MIX, phi=["x2 + x3", "x3"], left_inverse=["y", "xi1 - xi2", "xi2"], B=["y + u", "u"],
                        Lambda=[[-1, 1], [0, 0]], estimator=GD(5.0, 50.0), alpha=1.0)
    assert "P" in d.certificate.values and d.certificate.values["KKL components"] and d.certificate.values["PEBO components"]
    run = simulate(MIX, {"r5": d}, t_final=20.0, dt=1e-3, x0=[0.2, 1.0, -0.5], inputs={"u": "cos(t)"})
    assert run.error_norm("r5")[-1] < 1e-6
    with pytest.raises(PreconditionError, match="not diagonalisable"):
        design_kkl_pebo(MIX, phi=["x2 + x3", "x3"], left_inverse=["y", "xi1 - xi2", "xi2"], B=["y + u", "u"],
                        Lambda=[[0, 1], [0, 0]])


def test_maps_are_validated():
    with pytest.raises(ShapeError, match="phi"):
        design_kkl(OSC, phi="x1", left_inverse=["xi1"], B=["y"], Lambda=[-1])
    with pytest.raises(ShapeError, match="left_inverse"):
        design_kkl(OSC, **dict(OSC_KKL, left_inverse=["xi1"]))
    from nlobs.errors import ModelError
    with pytest.raises(ModelError, match="unknown symbol|not declared|x3"):
        design_kkl(OSC, **dict(OSC_KKL, phi=["x3", "x1"]))


# the class of 004 Proposition 7 (40)-(41): x1 = y, x2 = a (A2 = -2), x3 = b (A3 = -1), x4 = c, b(u) = 1 + cos(u)/2
CASC = System(states=["y1s", "a", "b", "c"], f=["-y1s + a + b + (1 + 0.5*cos(u))*c", "-2*a + sin(y1s)", "-b + a*y1s + u", "-y1s"],
              outputs=["y"], h=["y1s"], inputs=["u"], name="cascade")


def test_prop_7_observer_converges_and_reports_pe():
    d = design_kkl_pebo_cascade(CASC, x2=["a"], x3=["b"], x4=["c"], k="y1s", alpha=2.0, estimator=Gradient(20.0))
    run = simulate(CASC, {"c": d}, t_final=20.0, dt=1e-3, x0=[0.3, 1.0, -1.0, 0.5], inputs={"u": "sin(t)"})
    err = np.abs(run.error("c"))
    assert np.allclose(err[:, 1], np.exp(-2 * run.t) * 1.0, atol=1e-9)      # (43): x̃2' = A2 x̃2 exactly
    assert err[-1].max() < 1e-5
    rep = excitation_report(d, run.t, run.observers["c"].z, run.u, run.y, window=2 * np.pi)
    assert rep.pe_level > 0.1                                                # b = 1 + cos(u)/2 ≥ 1/2: PE (42)


def test_prop_7_structure_is_checked():
    kw = dict(x2=["a"], x3=["b"], x4=["c"], k="y1s")
    unstable = System(states=CASC.states, f=["-y1s + a + b + c", "2*a + sin(y1s)", "-b + u", "-y1s"], outputs=["y"],
                      h=["y1s"], inputs=["u"])
    with pytest.raises(PreconditionError, match="A2 is not Hurwitz"):
        design_kkl_pebo_cascade(unstable, **kw)
    nonaff = System(states=CASC.states, f=["-y1s + a + b + c**3", "-2*a", "-b", "-y1s"], outputs=["y"], h=["y1s"], inputs=["u"])
    with pytest.raises(PreconditionError, match="not affine in x4"):
        design_kkl_pebo_cascade(nonaff, **kw)
    wrong = System(states=CASC.states, f=["-y1s + a + b + c", "-2*a + b", "-b", "-y1s"], outputs=["y"], h=["y1s"], inputs=["u"])
    with pytest.raises(PreconditionError, match="f2 may depend only on x1 and u.*b"):
        design_kkl_pebo_cascade(wrong, **kw)
    with pytest.raises(PreconditionError, match="y = x1"):
        design_kkl_pebo_cascade(CASC, x2=["a"], x3=[], x4=["c"], k="y1s")
