"""High-gain observers: triangular form (002, GHK) and output derivatives (004 Table I, Khalil-Esfandiari)."""

import casadi as ca
import numpy as np
import pytest

import nlobs
from nlobs.design import design_high_gain, design_high_gain_derivatives
from nlobs.errors import FormError, PreconditionError


def decay_rate(t, e, t1, t2):
    """Least-squares slope of -log e on [t1, t2]."""
    sel = (t >= t1) & (t <= t2)
    return -np.polyfit(t[sel], np.log(e[sel]), 1)[0]


def flow_jacobian_eigs(design, n_u):
    """Eigenvalues of d(flow)/dz: for a linear plant these are the error-dynamics eigenvalues."""
    z = ca.SX.sym("z", design.n_z)
    J = ca.jacobian(design.flow(0.0, z, ca.DM.zeros(n_u), ca.DM.zeros(design.system.n_outputs)), z)
    return np.sort_complex(np.linalg.eigvals(np.array(ca.Function("J", [z], [J])(np.zeros(design.n_z)))))


def test_linear_chain_rate_is_theta_times_the_poles():
    # 002 "Result [High Gain Observer]": the scaled error has linear part θ(A0 - K0C0), so with
    # poles (-1, -2) and θ = 5 the error decays at 5 (the slowest eigenvalue -5).
    sys = nlobs.System(states=["x1", "x2"], f=["x2", "u"], inputs=["u"], outputs=["y"], h=["x1"])
    d = design_high_gain(sys, theta=5.0, poles=[-1.0, -2.0])
    np.testing.assert_allclose(flow_jacobian_eigs(d, 1), [-10.0, -5.0], rtol=1e-12)
    run = nlobs.simulate(sys, d, t_final=4.0, dt=1e-3, x0=[1.0, -1.0], inputs={"u": "sin(t)"}, engine="vm")
    assert decay_rate(run.t, run.error_norm(), 1.0, 3.0) == pytest.approx(5.0, rel=0.02)
    assert d.certificate.values["nominal_rate"] == pytest.approx(5.0)


def test_default_gains_are_binomial_as_in_004_table_I():
    # 004 Table I uses α1 = 2, α2 = 1: the binomial gains, double root at -1.
    sys = nlobs.System(states=["x1", "x2", "x3"], f=["x2", "x3", "0"], outputs=["y"], h=["x1"])
    d = design_high_gain(sys, theta=2.0)
    np.testing.assert_allclose(d.certificate.values["K0"][0], [3.0, 3.0, 1.0])


def test_nonconstant_coupling_and_scaled_gain():
    # coupling 2 on the superdiagonal: K0 = T⁻¹k with T = diag(1, 2) so that eig = poles.
    sys = nlobs.System(states=["x1", "x2"], f=["2*x2", "0"], outputs=["y"], h=["x1"])
    d = design_high_gain(sys, theta=3.0, poles=[-1.0, -4.0])
    np.testing.assert_allclose(flow_jacobian_eigs(d, 0), [-12.0, -3.0], rtol=1e-12)


def test_two_chains_like_the_cuk_converter():
    # two outputs, chains (y1, x1) and (y2, x2); y2' couples to x2 with -3 and to y1 (level 1).
    sys = nlobs.System(states=["y1s", "x1", "y2s", "x2"], f=["x1 + y2s", "0", "-3*x2 + y1s", "y2s"],
                       outputs=["y1", "y2"], h=["y1s", "y2s"])
    d = design_high_gain(sys, theta=10.0, poles=[[-1.0, -2.0], [-3.0, -4.0]])
    # plant linear, but B(x̂) uses x̂ (not y): eigenvalues of the error system are those of
    # A(plant) - L C with L = Δ K0; compute them independently with numpy.
    A = np.array([[0, 1, 1, 0], [0, 0, 0, 0], [1, 0, 0, -3], [0, 0, 1, 0]], float)
    K = d.certificate.values["K0"]
    L = np.zeros((4, 2))
    L[0, 0], L[1, 0] = 10 * K[0][0], 100 * K[0][1]
    L[2, 1], L[3, 1] = 10 * K[1][0], 100 * K[1][1]
    C = np.array([[1, 0, 0, 0], [0, 0, 1, 0]], float)
    np.testing.assert_allclose(flow_jacobian_eigs(d, 0), np.sort_complex(np.linalg.eigvals(A - L @ C)), atol=1e-9)
    # chain gains place eig(A_c - K0C0) exactly (the chain part of the certificate)
    np.testing.assert_allclose(np.sort(d.certificate.values["eigenvalues"][1].real), [-4.0, -3.0])


def test_lipschitz_bound_rate_is_met():
    sys = nlobs.System(states=["x1", "x2"], f=["x2", "-sin(x1) - 0.1*x2"], outputs=["y"], h=["x1"])
    # |B2(x̂) - B2(x)| <= |e1| + 0.1|e2| <= sqrt(1.01)|e|
    gamma = float(np.sqrt(1.01))
    probe = design_high_gain(sys, theta=1e3, lipschitz=gamma)
    theta = 2 * probe.certificate.values["theta_min"]
    d = design_high_gain(sys, theta=theta, lipschitz=gamma)
    g = d.certificate.values["guaranteed_rate"]
    assert g > 0
    run = nlobs.simulate(sys, d, t_final=2.0, dt=2e-4, x0=[1.0, 0.5], xhat0=[0.0, 0.0], engine="vm")
    e = run.error_norm()
    t_end = run.t[np.argmax(e < 1e-9)] if (e < 1e-9).any() else 2.0
    assert decay_rate(run.t, e, 0.3 * t_end, 0.8 * t_end) >= g
    with pytest.raises(PreconditionError, match=r"theta\*"):
        design_high_gain(sys, theta=0.5 * d.certificate.values["theta_min"], lipschitz=gamma)


def test_structure_violation_names_the_entry():
    sys = nlobs.System(states=["x1", "x2", "x3"], f=["x2 + x3", "x3", "-x1"], outputs=["y"], h=["x1"])
    with pytest.raises(FormError, match=r"x1' = x2 \+ x3 depends on x3"):
        design_high_gain(sys, theta=5.0)
    nonlinear = nlobs.System(states=["x1", "x2"], f=["x2**3", "0"], outputs=["y"], h=["x1"])
    with pytest.raises(FormError, match="not linear in x2"):
        design_high_gain(nonlinear, theta=5.0)


def test_input_dependent_coupling_needs_K0():
    sys = nlobs.System(states=["x1", "x2"], f=["(2 - cos(u))*x2", "0"], inputs=["u"], outputs=["y"], h=["x1"])
    with pytest.raises(PreconditionError, match="not constant"):
        design_high_gain(sys, theta=5.0)
    d = design_high_gain(sys, theta=5.0, L0=[2.0, 1.0])
    assumed = [c for c in d.certificate.checks if c.status == "assumed"]
    assert assumed and not any(c.holds for c in assumed) and all(str(c).startswith("[assumed]") for c in assumed)


def test_bad_tuning_is_refused():
    sys = nlobs.System(states=["x1", "x2"], f=["x2", "0"], outputs=["y"], h=["x1"])
    with pytest.raises(PreconditionError, match="exactly one"):
        design_high_gain(sys, theta=2.0, r=0.5)
    with pytest.raises(PreconditionError, match="Hurwitz"):
        design_high_gain(sys, theta=2.0, L0=[-1.0, 1.0])
    with pytest.raises(PreconditionError, match="left half-plane"):
        design_high_gain(sys, theta=2.0, poles=[1.0, -1.0])


def test_saturation_bounds_the_estimate_during_peaking():
    sys = nlobs.System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1"])
    free = design_high_gain(sys, theta=50.0)
    sat = design_high_gain(sys, theta=50.0, saturation={"x2": 2.0})
    run = nlobs.simulate(sys, {"free": free, "sat": sat}, t_final=1.0, dt=1e-4, x0=[1.0, 0.0], engine="vm")
    assert np.abs(run.observers["free"].xhat[:, 1]).max() > 10.0  # peaking ~ θ
    assert np.abs(run.observers["sat"].xhat[:, 1]).max() <= 2.0 + 1e-12
    assert run.error_norm("sat")[-1] < 1e-6


PENDULUM = nlobs.System(states=["x1", "x2"], f=["x2", "-sin(x1) + u"], inputs=["u"], outputs=["y"], h=["x1"])


def test_output_derivative_observer_error_scales_with_r():
    # Khalil-Esfandiari with φ0 = 0: the unknown ÿ is a disturbance; the steady error of the
    # derivative estimate is O(r) (transfer from ÿ to e2 is r·(s·r + α1)/(r²s² + α1 r s + α2)).
    runs = {}
    for r in (0.02, 0.01):
        d = design_high_gain_derivatives(PENDULUM, r=r, psi={"x1": "D0_y", "x2": "D1_y"})
        run = nlobs.simulate(PENDULUM, d, t_final=6.0, dt=1e-4, x0=[0.5, 0.0], inputs={"u": "sin(2*t)"}, engine="vm")
        runs[r] = run.metrics(tail=0.5).rms_error
    assert 1.7 < runs[0.02] / runs[0.01] < 2.3


def test_output_derivative_eigenvalues_from_004_table_I():
    # Ćuk converter (004 eq. 50), Table I "HGO (linear dynamics)": r2 = 0.005, α = (2, 1) per
    # output, x̂ = ((C2 ξ2 - u y2)/(1 - u), -L3 ξ4 - u y1). Error eigenvalues: -1/r2 (double).
    cuk = nlobs.System(
        states=["x1", "x2", "v2", "i3"],
        f=["-(1 - u)*v2/L1 + Ein/L1", "i3/C4 - G*x2/C4", "(1 - u)*x1/C2 + u*i3/C2", "-u*v2/L3 - x2/L3"],
        inputs=["u"], outputs=["y1", "y2"], h=["v2", "i3"],
        params={"L1": 10e-3, "C2": 22e-6, "L3": 10e-3, "C4": 22.9e-6, "G": 0.0447, "Ein": 12.0})
    psi = {"x1": "(C2*D1_y1 - u*y2)/(1 - u)", "x2": "-L3*D1_y2 - u*y1", "v2": "y1", "i3": "y2"}
    d = design_high_gain_derivatives(cuk, r=0.005, alpha=[2.0, 1.0, 2.0, 1.0], psi=psi)
    for e in d.certificate.values["eigenvalues"]:
        np.testing.assert_allclose(e, [-200.0, -200.0], rtol=1e-6)
    np.testing.assert_allclose(flow_jacobian_eigs(d, 1), [-200.0] * 4, rtol=1e-4)
    wrong = dict(psi, x2="L3*D1_y2 - u*y1")
    with pytest.raises(PreconditionError, match=r"psi\[x2\]"):
        design_high_gain_derivatives(cuk, r=0.005, psi=wrong)


def test_output_derivative_saturation_and_orders():
    d = design_high_gain_derivatives(PENDULUM, r=0.01, psi={"x1": "y", "x2": "D1_y"}, saturation={"D1_y": 3.0})
    run = nlobs.simulate(PENDULUM, d, t_final=1.0, dt=1e-4, x0=[1.0, 0.0], engine="vm")
    assert np.abs(run.observers[d.method].xhat[:, 1]).max() <= 3.0 + 1e-12
    with pytest.raises(PreconditionError, match="uses derivative 1"):
        design_high_gain_derivatives(PENDULUM, r=0.01, psi={"x1": "y", "x2": "D1_y"}, orders=[1])
