"""Luenberger, output-injection and augmented designs: gains, evidence, refusals."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from nlobs import PreconditionError, ShapeError, System, design_luenberger, design_output_injection
from nlobs.analysis import kalman_rank, pbh_test
from nlobs.design import observer_gain

DOUBLE_INTEGRATOR = System.lti([[0, 1], [0, 0]], [[0], [1]], [[1, 0]], states=["p", "v"], inputs=["a"], outputs=["y"])


def test_kalman_rank_and_pbh_on_textbook_pairs():
    r = kalman_rank([[0, 1], [0, 0]], [[1, 0]])
    assert r.observable and r.rank == 2
    r = kalman_rank([[0, 1], [0, 0]], [[0, 1]])  # velocity only: position unobservable
    assert not r.observable and r.rank == 1 and np.allclose(np.abs(r.unobservable_directions), [[1, 0]])
    p = pbh_test([[-1, 0], [0, 2]], [[0, 1]])
    assert not p.observable and p.detectable and np.allclose(p.unobservable_eigenvalues, [-1])
    assert not pbh_test([[1, 0], [0, 2]], [[0, 1]]).detectable


def test_pole_placement_places_the_poles():
    d = design_luenberger(DOUBLE_INTEGRATOR, poles=[-2, -3])
    L = d.certificate.values["L"]
    A, C = np.array([[0, 1], [0, 0]]), np.array([[1, 0]])
    # independent: for the double integrator, char poly of A - LC is s^2 + l1 s + l2 = (s+2)(s+3)
    assert np.allclose(L.ravel(), [5, 6])
    assert np.allclose(np.sort(np.linalg.eigvals(A - L @ C).real), [-3, -2])
    assert d.certificate.values["decay_rate"] == pytest.approx(2.0)


def test_lqe_gain_solves_the_filter_riccati_equation():
    A, C = np.array([[0, 1], [-1, -0.2]]), np.array([[1, 0]])
    sys = System.lti(A, None, C)
    Q, R = np.diag([0.1, 1.0]), np.array([[0.05]])
    d = design_luenberger(sys, Q=Q, R=R)
    L, P = d.certificate.values["L"], d.certificate.values["P"]
    residual = A @ P + P @ A.T - P @ C.T @ np.linalg.inv(R) @ C @ P + Q
    assert np.max(np.abs(residual)) < 1e-10
    assert np.all(np.linalg.eigvalsh(P) > 0) and np.allclose(L, P @ C.T / 0.05)


def test_luenberger_runs_the_textbook_error_dynamics():
    d = design_luenberger(DOUBLE_INTEGRATOR, poles=[-2, -3])
    e = np.array([1.0, -1.0])
    z = np.zeros(2)
    flow = np.array(d.flow(0.0, z, [0.3], [1.0])).ravel()
    # xhat' = A xhat + B u - L(C xhat - y) at xhat = 0, y = 1, u = 0.3
    assert np.allclose(flow, [5.0, 6.0 + 0.3])
    del e


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(poles=[-1, -2], L=[[1], [1]]), "exactly one of"),
        (dict(), "exactly one of"),
        (dict(poles=[-1]), "must list 2 poles"),
        (dict(poles=[-1, 0.5]), "0.5.* not in the open left half-plane"),
        (dict(poles=[-1 + 1j, -2]), "conjugate pairs"),
        (dict(L=[[-1], [0]]), "does not make A - LC Hurwitz"),
        (dict(L=[[1, 2]]), "incompatible dimensions of `L`: expected \\(2, 1\\)"),
        (dict(Q=np.eye(2)), "`Q` was given without `R`"),
        (dict(Q=-np.eye(2), R=[[1]]), "positive semidefinite"),
        (dict(Q=np.eye(2), R=[[0]]), "positive definite"),
        (dict(Q=[[1, 2], [0, 1]], R=[[1]]), "symmetric"),
    ],
)
def test_luenberger_refusals(kwargs, match):
    with pytest.raises((PreconditionError, ShapeError), match=match):
        design_luenberger(DOUBLE_INTEGRATOR, **kwargs)


def test_unobservable_pair_names_rank_and_direction():
    sys = System.lti([[0, 0, 1], [0, 0, 0], [0, 0, 0]], [[0], [1], [0]], [[1, 0, 0]])  # 001 (21) with c = 0
    with pytest.raises(PreconditionError, match=r"not observable: rank 2 < 3; unobservable direction\(s\) \[0\., 1\., 0\.\]"):
        design_luenberger(sys, poles=[-1, -2, -3])


def test_undetectable_pair_refused_for_lqe():
    sys = System.lti([[1, 0], [0, -1]], None, [[0, 1]])
    with pytest.raises(PreconditionError, match="not detectable"):
        design_luenberger(sys, Q=np.eye(2), R=[[1]])


def test_nonlinear_model_refused_by_luenberger():
    s = System(states=["x"], f=["-x**3"], outputs=["y"], h=["x"])
    with pytest.raises(PreconditionError, match="not LTI.*design_output_injection or design_ekf"):
        design_luenberger(s, poles=[-1])


def test_output_injection_gain_and_refusal():
    pend = System(states=["x1", "x2"], f=["x2", "-9.81*sin(x1) - 0.5*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"])
    d = design_output_injection(pend, poles=[-2, -3])
    A = d.certificate.values["A"]
    K = d.certificate.values["K"]
    assert np.allclose(np.sort(np.linalg.eigvals(A - K @ np.array([[1, 0]])).real), [-3, -2])
    vdp = System(states=["x1", "x2"], f=["x2", "(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"])
    with pytest.raises(PreconditionError, match="not in output-injection form"):
        design_output_injection(vdp, poles=[-2, -3])


def test_observer_gain_values_are_independent_of_scipy_place_for_siso():
    # Ackermann's formula as the independent route for a SISO pair
    A = np.array([[0, 1, 0], [0, 0, 1], [-1, -2, -3]], float)
    C = np.array([[1, 0, 0]])
    poles = [-1, -2, -4]
    L, _, _ = observer_gain(A, C, poles=poles, caller="test")
    O = np.vstack([C, C @ A, C @ A @ A])
    coeffs = np.poly(poles)
    phi = sum(c * np.linalg.matrix_power(A, 3 - i) for i, c in enumerate(coeffs))
    L_ack = phi @ np.linalg.inv(O) @ np.array([[0], [0], [1]])
    assert np.allclose(L, L_ack)


def test_place_refusal_explains_multiplicity():
    A, C = np.zeros((2, 2)), np.array([[1.0, 0], [0, 1.0]])
    L, _, _ = observer_gain(A, C, poles=[-1, -1], caller="t")  # repeated pole with 2 outputs is fine
    assert np.allclose(np.linalg.eigvals(A - L @ C), [-1, -1])
    with pytest.raises(PreconditionError, match="repeated at most 1 time"):
        observer_gain(np.array([[0, 1], [0, 0.0]]), np.array([[1.0, 0]]), poles=[-1, -1], caller="t")


def test_lqe_scipy_residual_independent_check():
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    C = np.array([[1.0, 0.0]])
    L, _, v = observer_gain(A, C, Q=np.eye(2), R=np.eye(1), caller="t")
    # closed form for the double integrator with Q = I, R = 1: P = [[sqrt(3), 1], [1, sqrt(3)]]
    assert np.allclose(v["P"], [[np.sqrt(3), 1], [1, np.sqrt(3)]])
    assert np.allclose(L.ravel(), [np.sqrt(3), 1])
    assert np.allclose(scipy.linalg.solve_continuous_are(A.T, C.T, np.eye(2), np.eye(1)), v["P"])


def test_check_has_three_states_and_never_prints_an_assumption_as_ok():
    from nlobs.design import Check

    ok, assumed, bad = Check("a", True, "1 < 2"), Check.assumed("b", "depends on the data"), Check("c", False)
    assert (ok.status, assumed.status, bad.status) == ("holds", "assumed", "fails")
    assert ok.holds and not assumed.holds and not bad.holds and bad.fails and not assumed.fails
    assert str(ok).startswith("[ok]") and str(assumed).startswith("[assumed]") and str(bad).startswith("[FAILED]")
    with pytest.raises(ValueError, match="status"):
        Check("d", "maybe")


def test_poles_that_are_not_numbers_name_the_argument():
    import nlobs

    s = nlobs.System(states=["p", "v"], f=["v", "-p"], outputs=["y"], h=["p"])
    with pytest.raises(nlobs.ShapeError, match=r"design_luenberger: `poles` must be 2 numbers"):
        nlobs.design_luenberger(s, poles=["a", "b"])
