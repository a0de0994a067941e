"""The likelihood at a fine integration step (issue 44 item 4): re-evaluating a filter with a --max-step that needs
more than the 64 RK4 sub-steps the recursion unrolls per row must not refuse, and must give the log-likelihood of an
independent reference: a continuous-discrete EKF written here in NumPy, its mean and Riccati equation integrated by
SciPy's solve_ivp (DOP853, rtol 1e-11) between the samples, and the prediction-error decomposition
Σ −½(log det 2πS + ν²/S) (Schweppe (1965); Harvey (1989), sec. 3.4)."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

import nlobs
from nlobs.learning import log_likelihood

PEND = nlobs.System(states=["th", "w"], inputs=["u"], outputs=["y"], f=["w", "-g*sin(th) - 0.3*w + u"], h=["th"],
                    params={"g": 4.0}, name="pendulum")
Q, R, P0, X0 = np.diag([1e-3, 1e-2]), np.array([[4e-3]]), np.diag([0.1, 0.1]), np.array([0.8, 0.0])


def _reference(t, u, y, g):
    def flow(_t, z, uk):
        x, P = z[:2], z[2:].reshape(2, 2)
        F = np.array([[0.0, 1.0], [-g * np.cos(x[0]), -0.3]])
        dx = [x[1], -g * np.sin(x[0]) - 0.3 * x[1] + uk]
        return np.concatenate([dx, (F @ P + P @ F.T + Q).ravel()])

    x, P, total = X0.copy(), P0.copy(), 0.0
    H = np.array([[1.0, 0.0]])
    for k in range(t.size):
        if k:
            sol = solve_ivp(flow, (t[k - 1], t[k]), np.concatenate([x, P.ravel()]), args=(u[k - 1],), method="DOP853",
                            rtol=1e-11, atol=1e-13)
            x, P = sol.y[:2, -1], sol.y[2:, -1].reshape(2, 2)
            P = (P + P.T) / 2
        S = H @ P @ H.T + R
        nu = y[k] - x[:1]
        total += -0.5 * (np.log(np.linalg.det(2 * np.pi * S)) + nu @ np.linalg.solve(S, nu))
        K = P @ H.T @ np.linalg.inv(S)
        IKH = np.eye(2) - K @ H
        x, P = x + K @ nu, IKH @ P @ IKH.T + K @ R @ K.T
    return total


def test_a_max_step_needing_more_than_64_substeps_gives_the_reference_likelihood():
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 24.0, 2.0)      # 2 s between samples; max_step 0.01 s: 200 sub-steps per interval
    u = 0.5 * np.sin(0.4 * t)
    x, th = np.array([1.0, 0.5]), [1.0]       # the plant (u held over each interval), read with noise
    for k in range(1, t.size):
        x = solve_ivp(lambda _t, v, uk=u[k - 1]: [v[1], -4.0 * np.sin(v[0]) - 0.3 * v[1] + uk], (t[k - 1], t[k]), x,
                      rtol=1e-10, atol=1e-12).y[:, -1]
        th.append(x[0])
    y = np.array(th) + 0.06 * rng.standard_normal(t.size)
    rec = nlobs.Recording.from_arrays(PEND, t, y[:, None], u[:, None])
    d = nlobs.design_ekf(PEND, Q=Q, R=R, xhat0=X0, P0=P0)
    ref = _reference(t, u, y, 4.0)
    ll, g = log_likelihood(d, rec, params=["g"], max_step=0.01)
    assert abs(ll - ref) < 1e-6 * max(1.0, abs(ref)), (ll, ref)
    # at the default step (the filter's own rule: a few sub-steps) it differs by RK4's error: the fine step matters
    ll_coarse, _ = log_likelihood(d, rec, params=["g"])
    assert abs(ll_coarse - ref) > 10 * abs(ll - ref), (ll_coarse, ll, ref)
    # its gradient in g agrees with central differences of the reference
    e = 1e-4
    fd = (_reference(t, u, y, 4.0 + e) - _reference(t, u, y, 4.0 - e)) / (2 * e)
    assert abs(g[0] - fd) < 1e-4 * max(1.0, abs(fd)), (g, fd)
