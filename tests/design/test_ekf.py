"""EKF: cross-checked against an independent Kalman filter and the Riccati equation; masks; long-run SPD."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from nlobs import Noise, Observer, PreconditionError, Recording, Sampling, System, design_ekf, estimate, simulate

A = np.array([[0.0, 1.0], [-2.0, -0.4]])
C = np.array([[1.0, 0.0]])
OSC = System.lti(A, [[0], [1]], C, inputs=["u"], outputs=["y"])


def _independent_cd_kalman(rec: Recording, Q, R, P0, x0, Ts):
    """Continuous-discrete Kalman filter with exact discretisation (expm, Van Loan), written from the textbook."""
    n = 2
    M = np.block([[-A, Q], [np.zeros((n, n)), A.T]]) * Ts
    E = scipy.linalg.expm(M)
    Phi = E[n:, n:].T
    Qd = Phi @ E[:n, n:]
    Bd = scipy.linalg.solve(A, (Phi - np.eye(n)) @ np.array([0.0, 1.0]))
    x, P, out = np.array(x0, float), np.array(P0, float), []
    for k in range(rec.t.size):
        if k:
            x = Phi @ x + Bd * rec.u[k - 1, 0]
            P = Phi @ P @ Phi.T + Qd
        S = C @ P @ C.T + R
        K = P @ C.T @ np.linalg.inv(S)
        x = x + (K @ (rec.y[k] - C @ x)).ravel()
        IKH = np.eye(n) - K @ C
        P = IKH @ P @ IKH.T + K @ R @ K.T
        out.append(x.copy())
    return np.array(out), P


def test_continuous_discrete_ekf_on_an_lti_plant_is_the_kalman_filter():
    Q, R, P0 = np.diag([0.01, 0.05]), np.array([[1e-3]]), np.eye(2)
    run = simulate(OSC, t_final=5.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": "sin(3*t)"}, noise=Noise.gaussian(0.03),
                   sampling=Sampling(0.01), seed=3)
    rec = Recording.from_run(run, every=10)
    ekf = design_ekf(OSC, Q=Q, R=R, P0=P0, xhat0=[0.0, 0.0])
    ours = estimate(ekf, rec, max_step=1e-3)
    ref, P_ref = _independent_cd_kalman(rec, Q, R, P0, [0.0, 0.0], 0.01)
    assert np.max(np.abs(ours.observers["ekf"].xhat - ref)) < 1e-9
    P_end = ours.observers["ekf"].z[-1, 2:].reshape(2, 2, order="F")
    assert np.allclose(P_end, P_ref, atol=1e-10)


def test_continuous_ekf_covariance_converges_to_the_filter_riccati_solution():
    Q, R = np.diag([0.1, 0.2]), np.array([[0.05]])
    ekf = design_ekf(OSC, Q=Q, R=R, P0=np.eye(2) * 3, mode="continuous")
    run = simulate(OSC, {"ekf": ekf}, t_final=20.0, dt=1e-3, x0=[1.0, 0.0])
    P_end = run.observers["ekf"].z[-1, 2:].reshape(2, 2, order="F")
    P_are = scipy.linalg.solve_continuous_are(A.T, C.T, Q, R)
    assert np.allclose(P_end, P_are, rtol=1e-6, atol=1e-9)
    assert run.metrics("ekf").final_error < 1e-6


def test_masked_update_leaves_unmeasured_outputs_out():
    two = System.lti(A, None, [[1.0, 0.0], [0.0, 1.0]], outputs=["p", "v"])
    R = np.diag([1e-2, 1e-3])
    d = design_ekf(two, Q=np.eye(2), R=R)
    obs = Observer(d)
    z = np.concatenate([[0.5, -0.3], np.array([[2.0, 0.3], [0.3, 1.0]]).ravel(order="F")])
    y = np.array([1.0, 7.0])
    assert np.allclose(obs.update(0.0, z, None, y, [0.0, 0.0]), z)  # nothing measured: no change
    # only p measured: identical to a filter whose only output is p
    one = design_ekf(System.lti(A, None, [[1.0, 0.0]], outputs=["p"]), Q=np.eye(2), R=R[:1, :1])
    expected = Observer(one).update(0.0, z, None, y[:1])
    assert np.allclose(obs.update(0.0, z, None, y, [1.0, 0.0]), expected, atol=1e-14)


def test_ekf_refusals():
    with pytest.raises(PreconditionError, match="`R` must be positive definite"):
        design_ekf(OSC, Q=np.eye(2), R=[[0.0]])
    with pytest.raises(PreconditionError, match="`mode` must be"):
        design_ekf(OSC, Q=np.eye(2), R=[[1.0]], mode="discrete")  # type: ignore[arg-type]
    with pytest.raises(Exception, match="incompatible dimensions of `Q`"):
        design_ekf(OSC, Q=np.eye(3), R=[[1.0]])


def test_covariances_stay_symmetric_positive_definite_over_a_million_steps():
    """SPEC M9: long runs (10^6 steps) keep covariances symmetric positive definite and finite."""
    vdp = System(states=["x1", "x2"], f=["x2", "(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"])
    cd = design_ekf(vdp, Q=np.diag([1e-6, 1e-6]), R=[[1e-4]], P0=np.eye(2))
    ct = design_ekf(vdp, Q=np.diag([1e-6, 1e-6]), R=[[1e-2]], P0=np.eye(2), mode="continuous")
    run = simulate(vdp, {"cd": cd, "ct": ct}, t_final=1000.0, dt=1e-3, x0=[2.0, 0.0], noise=Noise.gaussian(0.01), seed=0,
                   engine="c")
    assert run.t.size == 1_000_001
    for name in ("cd", "ct"):
        P = run.observers[name].z[::997, 2:].reshape(-1, 2, 2, order="F")
        assert np.all(np.isfinite(P))
        assert np.array_equal(P, P.transpose(0, 2, 1))  # exactly symmetric, bit for bit
        assert np.all(np.linalg.eigvalsh(P)[:, 0] > 0)
        assert run.metrics(name).rms_error < 0.05
