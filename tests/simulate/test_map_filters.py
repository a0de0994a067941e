"""The square-root UKF and EKF, the iterated EKF and the particle filter on discrete-time maps (issue 38, item 1), against
independent NumPy implementations written here: the same semantics as the map EKF and UKF (predict with u[k−1] from
x̂[k−1|k−1], correct with y[k], Q per step, the first sample corrects the prior), outputs missing at some steps; the
smoothers; the particle filter against the exact Kalman filter of a linear-Gaussian map within its Monte Carlo error,
and against a NumPy bootstrap filter on a nonlinear map."""

from __future__ import annotations

import numpy as np
import pytest

import nlobs
from nlobs.errors import PreconditionError
from nlobs.observer import particle_runner

T = 0.1
# a pendulum map (Euler by hand), its angle seen through a range to a station one unit above the pivot, and its rate
MAP = nlobs.System(states=["p", "v"], f=[f"p + {T}*v", f"v + {T}*(-2*sin(p) - 0.4*v + u)"], inputs=["u"],
                   outputs=["r", "w"], h=["sqrt(1 + (p - 0.5)**2)", "v"], time="discrete", sample_time=T, name="range_map")
Q, R, P0, X0 = np.diag([1e-3, 4e-3]), np.diag([1e-3, 0.01]), np.diag([0.3, 0.5]), np.array([1.3, 0.4])


def f(x, u):
    return np.array([x[0] + T * x[1], x[1] + T * (-2 * np.sin(x[0]) - 0.4 * x[1] + u)])


def F(x):
    return np.array([[1.0, T], [-2 * T * np.cos(x[0]), 1 - 0.4 * T]])


def h(x):
    return np.array([np.sqrt(1 + (x[0] - 0.5) ** 2), x[1]])


def H(x):
    return np.array([[(x[0] - 0.5) / np.sqrt(1 + (x[0] - 0.5) ** 2), 0.0], [0.0, 1.0]])


def _data(N=150, seed=4):
    rng = np.random.default_rng(seed)
    u = 0.8 * np.sin(0.3 * np.arange(N))
    x = np.zeros((N, 2))
    x[0] = [1.0, 0.0]
    for k in range(N - 1):
        x[k + 1] = f(x[k], u[k]) + rng.multivariate_normal(np.zeros(2), Q)
    y = np.array([h(v) for v in x]) + rng.multivariate_normal(np.zeros(2), R, N)
    measured = np.ones((N, 2), dtype=bool)
    measured[40:60, 1] = False          # the rate sensor drops out for 20 steps
    measured[N // 2 + 15, 0] = False
    return np.arange(N) * T, u, x, y, measured


def _rows(k, measured):
    return np.flatnonzero(measured[k])


def numpy_ekf(u, y, measured, iterations=1, tol=0.0):
    """The map EKF (iterations = 1) or iterated EKF by hand: Gauss-Newton on the update from x⁻, stopping once a step
    is below `tol`, the Joseph form with the last K, H; the filtered (x, P) and the predictions (x⁻, P⁻)."""
    x, P = X0.copy(), P0.copy()
    xs, Ps = [], []
    for k in range(len(y)):
        if k:
            Fk = F(x)
            x, P = f(x, u[k - 1]), Fk @ P @ Fk.T + Q
        rows = _rows(k, measured)
        Rk = R[np.ix_(rows, rows)]
        xi, K, Hk = x.copy(), np.zeros((2, rows.size)), np.zeros((rows.size, 2))
        for _ in range(iterations):
            Hi = H(xi)[rows]
            Ki = P @ Hi.T @ np.linalg.inv(Hi @ P @ Hi.T + Rk)
            x_next = x + Ki @ (y[k, rows] - h(xi)[rows] - Hi @ (x - xi))
            step = np.max(np.abs(x_next - xi))
            K, Hk, xi = Ki, Hi, x_next
            if step < tol:
                break
        IKH = np.eye(2) - K @ Hk
        x, P = xi, IKH @ P @ IKH.T + K @ Rk @ K.T
        xs.append(x)
        Ps.append(P)
    return np.array(xs), np.array(Ps)


def _merwe(alpha, beta, kappa, n=2):
    lam = alpha ** 2 * (n + kappa) - n
    Wm = np.full(2 * n + 1, 0.5 / (n + lam))
    Wc = Wm.copy()
    Wm[0], Wc[0] = lam / (n + lam), lam / (n + lam) + 1 - alpha ** 2 + beta
    return lam, Wm, Wc


def numpy_ukf(u, y, measured, alpha=1.0, beta=0.0, kappa=0.0):
    """The map UKF by hand with filterpy's MerweScaledSigmaPoints, the update reusing the propagated points."""
    n = 2
    lam, Wm, Wc = _merwe(alpha, beta, kappa)
    x, P = X0.copy(), P0.copy()
    xs, Ps = [], []
    for k in range(len(y)):
        U = np.linalg.cholesky((n + lam) * P)
        sig = np.array([x] + [x + U[:, i] for i in range(n)] + [x - U[:, i] for i in range(n)])
        if k:
            sig = np.array([f(s, u[k - 1]) for s in sig])
            x = Wm @ sig
            P = sum(w * np.outer(s - x, s - x) for w, s in zip(Wc, sig)) + Q
        rows = _rows(k, measured)
        ys = np.array([h(s)[rows] for s in sig])
        yh = Wm @ ys
        S = sum(w * np.outer(v - yh, v - yh) for w, v in zip(Wc, ys)) + R[np.ix_(rows, rows)]
        K = sum(w * np.outer(s - x, v - yh) for w, s, v in zip(Wc, sig, ys)) @ np.linalg.inv(S)
        x, P = x + K @ (y[k, rows] - yh), P - K @ S @ K.T
        xs.append(x)
        Ps.append(P)
    return np.array(xs), np.array(Ps)


def _run(kind, measured=None, smooth=False, **kw):
    t, u, x, y, m = _data()
    m = m if measured is None else measured
    d = nlobs.design.KINDS[kind].design(MAP, Q=Q, R=R, P0=P0, xhat0=X0, **kw)
    rec = nlobs.Recording.from_arrays(MAP, t, y=np.where(m, y, np.nan), u=u[:, None])
    run = nlobs.estimate(d, rec, on_missing="skip", smooth=smooth)
    tr = run.observers[kind]
    P = np.array([np.array(d.covariance(z)) for z in tr.z])
    return tr, P, (t, u, x, y, m)


def test_map_srekf_is_the_map_ekf_in_square_root_form():
    tr, P, (t, u, x, y, m) = _run("srekf")
    xr, Pr = numpy_ekf(u, y, m)
    np.testing.assert_allclose(tr.xhat, xr, rtol=0, atol=1e-11)
    np.testing.assert_allclose(P, Pr, rtol=0, atol=1e-12)
    S = tr.z[-1, 2:6].reshape(2, 2, order="F")
    assert S[0, 1] == 0 and np.all(np.diag(S) > 0)        # a lower triangular factor is carried, not P
    assert np.sqrt(np.mean((tr.xhat[30:] - x[30:]) ** 2)) < 0.1      # it tracks (the rate measured with σ = 0.1)


@pytest.mark.parametrize("alpha, beta, kappa", [(1.0, 0.0, 0.0), (0.9, 2.0, 1.0)])
def test_map_srukf_is_the_map_ukf_in_square_root_form(alpha, beta, kappa):
    tr, P, (t, u, x, y, m) = _run("srukf", alpha=alpha, beta=beta, kappa=kappa)
    xr, Pr = numpy_ukf(u, y, m, alpha, beta, kappa)
    np.testing.assert_allclose(tr.xhat, xr, rtol=0, atol=1e-11)
    np.testing.assert_allclose(P, Pr, rtol=0, atol=1e-12)


def test_map_srukf_refuses_a_negative_covariance_weight():
    with pytest.raises(PreconditionError, match=r"W0 = -0\.033.*non-negative weights: take β ≥ -0\.36695"):
        nlobs.design_srukf(MAP, Q=Q, R=R, alpha=0.9, beta=-0.4, kappa=1.0)
    with pytest.raises(PreconditionError, match="`bounds` are not available for a discrete-time model"):
        nlobs.design_srukf(MAP, Q=Q, R=R, bounds={"p": (0, None)})


def test_map_iekf_is_gauss_newton_on_the_update():
    tr, P, (t, u, x, y, m) = _run("iekf", iterations=6, tol=1e-9)
    xr, Pr = numpy_ekf(u, y, m, iterations=6, tol=1e-9)
    np.testing.assert_allclose(tr.xhat, xr, rtol=0, atol=1e-10)
    np.testing.assert_allclose(P, Pr, rtol=0, atol=1e-12)
    xe, _ = numpy_ekf(u, y, m)
    assert np.abs(tr.xhat - xe).max() > 1e-3              # the iterations change the estimate here
    one, _, _ = _run("iekf", iterations=1)
    np.testing.assert_allclose(one.xhat, xe, rtol=0, atol=1e-11)   # one iteration is the EKF
    with pytest.raises(PreconditionError, match="`iterations` must be an integer ≥ 1"):
        nlobs.design_iekf(MAP, Q=Q, R=R, iterations=0)


def numpy_rts(xf, Pf, u, unscented=None):
    """The extended RTS smoother (unscented = (α, β, κ): Särkkä's) over the filtered (x, P) of a map filter."""
    xs, Ps = [xf[-1]], [Pf[-1]]
    for k in range(len(xf) - 2, -1, -1):
        if unscented is None:
            Fk = F(xf[k])
            xp, Pp, C = f(xf[k], u[k]), Fk @ Pf[k] @ Fk.T + Q, Pf[k] @ Fk.T
        else:
            lam, Wm, Wc = _merwe(*unscented)
            U = np.linalg.cholesky((2 + lam) * Pf[k])
            sig = np.array([xf[k]] + [xf[k] + U[:, i] for i in range(2)] + [xf[k] - U[:, i] for i in range(2)])
            fs = np.array([f(s, u[k]) for s in sig])
            xp = Wm @ fs
            Pp = sum(w * np.outer(v - xp, v - xp) for w, v in zip(Wc, fs)) + Q
            C = sum(w * np.outer(s - xf[k], v - xp) for w, s, v in zip(Wc, sig, fs))
        G = C @ np.linalg.inv(Pp)
        xs.insert(0, xf[k] + G @ (xs[0] - xp))
        Ps.insert(0, Pf[k] + G @ (Ps[0] - Pp) @ G.T)
    return np.array(xs), np.array(Ps)


@pytest.mark.parametrize("kind, reference", [
    ("srekf", lambda u, y, m: numpy_rts(*numpy_ekf(u, y, m), u)),
    ("iekf", lambda u, y, m: numpy_rts(*numpy_ekf(u, y, m, iterations=5, tol=1e-10), u)),
    ("srukf", lambda u, y, m: numpy_rts(*numpy_ukf(u, y, m), u, unscented=(1.0, 0.0, 0.0))),
])
def test_the_smoothers_of_the_map_filters(kind, reference):
    tr, _, (t, u, x, y, m) = _run(kind, smooth=True)
    xs, Ps = reference(u, y, m)
    np.testing.assert_allclose(tr.xhat, xs, rtol=0, atol=1e-9)
    np.testing.assert_allclose(tr.smoothed_covariance, Ps, rtol=0, atol=1e-10)
    err = lambda e: np.sqrt(np.mean((e[10:-10] - x[10:-10]) ** 2))  # noqa: E731
    assert err(tr.xhat) < err(tr.filtered)


# -- the particle filter on maps ---------------------------------------------------------------------------------
A, B, C = np.array([[0.95, 0.1], [-0.1, 0.9]]), np.array([0.0, 0.1]), np.array([[1.0, 0.0]])
LIN = nlobs.System(states=["x1", "x2"], f=["0.95*x1 + 0.1*x2", "-0.1*x1 + 0.9*x2 + 0.1*u"], inputs=["u"], outputs=["y"],
                   h=["x1"], time="discrete", sample_time=0.5, name="lin_map")
QL, RL, P0L, X0L = np.diag([0.02, 0.05]), np.array([[0.04]]), np.diag([0.5, 0.3]), np.array([0.3, -0.2])
TL = np.arange(120) * 0.5


@pytest.fixture(scope="module")
def linear_gaussian():
    rng = np.random.default_rng(7)
    u = np.sin(0.2 * TL)
    x = np.array([1.0, 0.0])
    ys = []
    for k in range(TL.size):
        ys.append(C @ x + 0.2 * rng.standard_normal(1))
        x = A @ x + B * u[k] + rng.multivariate_normal(np.zeros(2), QL)
    y = np.array(ys)
    # the exact Kalman filter of the map (predict with u[k-1], correct with y[k], the prior corrected first)
    xk, P, xs, Ps, ll = X0L.copy(), P0L.copy(), [], [], 0.0
    for k in range(TL.size):
        if k:
            xk, P = A @ xk + B * u[k - 1], A @ P @ A.T + QL
        S = C @ P @ C.T + RL
        e = y[k] - C @ xk
        ll += float(-0.5 * (np.log(2 * np.pi * S[0, 0]) + e @ np.linalg.solve(S, e)))
        K = P @ C.T @ np.linalg.inv(S)
        xk, P = xk + K @ e, (np.eye(2) - K @ C) @ P
        xs.append(xk)
        Ps.append(P)
    return u, y, np.array(xs), np.array(Ps), ll


@pytest.mark.parametrize("scheme", ["bootstrap", "auxiliary"])
def test_map_pf_is_the_kalman_filter_within_its_monte_carlo_error(linear_gaussian, scheme):
    u, y, xk, Pk, llk = linear_gaussian
    d = nlobs.design_pf(LIN, Q=QL, R=RL, P0=P0L, xhat0=X0L, particles=2000, scheme=scheme)
    assert "discrete time" in d.certificate.method and "per step" in str(d.certificate)
    runner = particle_runner(d)
    runs = [runner.run(TL, u=u[:, None], y=y, seed=s) for s in range(1, 17)]
    xs = np.array([r.xhat for r in runs])
    # the mean of 16 seeded runs sits on the KF within the spread of the runs (a squared t statistic, mean ≈ 1.15)
    sd = xs.std(axis=0, ddof=1)
    z2 = (xs.mean(axis=0) - xk) ** 2 / (sd ** 2 / len(runs))
    assert z2.mean() < 2.5, z2.mean()
    assert np.abs(xs - xk).mean() < 0.02
    sdk = np.sqrt(np.diagonal(Pk, axis1=1, axis2=2))
    rel = np.abs(runs[0].P - Pk) / (sdk[:, :, None] * sdk[:, None, :])
    assert rel.mean() < 0.1, rel.mean()                  # the particle covariance is the posterior's
    lls = np.array([r.loglik.sum() for r in runs])
    assert abs(lls.mean() - llk) < 4 * lls.std(ddof=1) / np.sqrt(len(runs)) + 0.05, (lls.mean(), llk)


def numpy_bootstrap(u, y, M, rng):
    """A bootstrap particle filter on MAP by hand (multinomial resampling at every step): the weighted means."""
    Lq, Rinv = np.linalg.cholesky(Q), np.linalg.inv(R)
    X = X0 + rng.standard_normal((M, 2)) @ np.linalg.cholesky(P0).T
    out = []
    for k in range(len(y)):
        if k:
            X = np.stack([X[:, 0] + T * X[:, 1], X[:, 1] + T * (-2 * np.sin(X[:, 0]) - 0.4 * X[:, 1] + u[k - 1])], axis=1)
            X = X + rng.standard_normal((M, 2)) @ Lq.T
        e = y[k] - np.stack([np.sqrt(1 + (X[:, 0] - 0.5) ** 2), X[:, 1]], axis=1)
        lw = -0.5 * np.einsum("mi,ij,mj->m", e, Rinv, e)
        w = np.exp(lw - lw.max())
        w /= w.sum()
        out.append(w @ X)
        X = X[rng.choice(M, M, p=w)]
    return np.array(out)


def test_map_pf_agrees_with_a_numpy_bootstrap_filter_on_a_nonlinear_map():
    t, u, x, y, _ = _data()
    ref = numpy_bootstrap(u, y, 100_000, np.random.default_rng(0))   # its Monte Carlo error is ~ 1/√50 of the runs'
    d = nlobs.design_pf(MAP, Q=Q, R=R, P0=P0, xhat0=X0, particles=2000)
    runner = particle_runner(d)
    xs = np.array([runner.run(t, u=u[:, None], y=y, seed=s).xhat for s in range(1, 13)])
    sd = xs.std(axis=0, ddof=1)
    z2 = (xs.mean(axis=0) - ref) ** 2 / (sd ** 2 / len(xs) + 1e-12)
    assert z2.mean() < 2.5, z2.mean()
    assert np.sqrt(np.mean((xs.mean(axis=0)[30:] - x[30:]) ** 2)) < 0.1


def test_map_pf_options_and_runs():
    with pytest.raises(PreconditionError, match="`max_step` does not apply to a discrete-time model"):
        nlobs.design_pf(MAP, Q=Q, R=R, max_step=0.01)
    d = nlobs.design_pf(MAP, Q=Q, R=R, P0=P0, xhat0=X0, particles=300)
    t, u, x, y, m = _data(40)
    rec = nlobs.Recording.from_arrays(MAP, t, y=np.where(m, y, np.nan), u=u[:, None])
    a, b = nlobs.estimate(d, rec, on_missing="skip"), nlobs.estimate(d, rec, on_missing="skip")
    np.testing.assert_array_equal(a.observers["pf"].xhat, b.observers["pf"].xhat)   # seeded
    assert a.info["particles"]["pf"]["particles"] == 300 and a.observers["pf"].innovation.shape == (40, 2)
    with pytest.raises(PreconditionError, match=r"kind 'pf'.*particle filter's smoother"):
        nlobs.estimate(d, rec, on_missing="skip", smooth=True)


def test_a_map_pf_that_loses_every_particle_fails_alone():
    # particles where the output is not defined (√ of a negative level): every likelihood vanishes at the first sample
    tank = nlobs.System(states=["x"], f=["0.9*x + 0.1"], outputs=["y"], h=["sqrt(x)"], time="discrete", sample_time=1.0,
                        name="tank")
    pf = nlobs.design_pf(tank, Q=[[1e-6]], R=[[1e-4]], P0=[[1e-6]], xhat0=[-5.0], particles=50)
    ekf = nlobs.design_ekf(tank, Q=[[1e-6]], R=[[1e-4]], P0=[[0.1]], xhat0=[0.8])
    run = nlobs.simulate(tank, {"pf": pf, "ekf": ekf}, t_final=5.0, x0=[1.0])
    assert set(run.observers) == {"ekf"} and set(run.failures) == {"pf"}
    assert "likelihood vanished" in run.failures["pf"].message
