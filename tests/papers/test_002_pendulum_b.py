"""Acceptance, M8 #5 (second half): 002_613af42269ea26a7.txt robot arm with unknown b, Kalman-like observer,
converging under a persistently exciting input and not under u = 0."""

import numpy as np

from nlobs import design_kalman_like, simulate
from nlobs.examples import pendulum_unknown_b as ex
from nlobs.examples._classical_util import a_matrix, gramian_min_eig

V = np.diag([1e-4, 1e-3, 1e-3])


def test_exciting_input_identifies_b():
    s = ex.pendulum_unknown_b()
    d = design_kalman_like(s, Q=V, R=[[1e-3]])
    run = simulate(s, d, t_final=30.0, dt=1e-3, x0=[1.0, 0.0, 1.0], inputs={"u": "sin(t) + 0.5*sin(2.3*t)"})
    assert abs(run.observers["kalman_like"].xhat[-1, 2] - 1.0) < 1e-5
    assert run.error_norm()[-1] < 1e-4 * run.error_norm()[0]


def test_zero_input_leaves_b_unobserved():
    s = ex.pendulum_unknown_b()
    d = design_kalman_like(s, Q=V, R=[[1e-3]])
    run = simulate(s, d, t_final=30.0, dt=1e-3, x0=[1.0, 0.0, 1.0], xhat0=[0.0, 0.0, 0.3], inputs={"u": 0})
    e = run.error()
    assert e[-1, 2] == e[0, 2] == -0.7
    assert np.linalg.norm(e[-1, :2]) < 1e-6
    # independent evidence: the Gramian of (A_e(0), C_e) is singular, with kernel along b
    lam = gramian_min_eig(a_matrix(s), np.array([[1.0, 0, 0]]), run.t[::10], run.u[::10], run.y_true[::10], window=5.0)
    assert lam < 1e-12


def test_example_claims_hold():
    result = ex.run()
    assert all(c.holds is True for c in result.claims), [str(c) for c in result.claims if c.holds is not True]
