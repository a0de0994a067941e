"""Observers of discrete-time models against independent NumPy implementations (filterpy's conventions):
predict with u[k-1] from the filtered estimate, then correct with y[k]; the estimate at t[k] is x[k|k]."""

from __future__ import annotations

import numpy as np
import pytest

import nlobs
from nlobs.errors import DataError, PreconditionError

# a damped pendulum discretised by hand (its own map, not an integrator): x1[k+1] = x1 + T x2,
# x2[k+1] = x2 + T(-sin x1 - 0.3 x2 + u); y = [x1, x1 x2]
T = 0.05
PEND = nlobs.System(states=["x1", "x2"], f=[f"x1 + {T}*x2", f"x2 + {T}*(-sin(x1) - 0.3*x2 + u)"], inputs=["u"],
                    outputs=["y1", "y2"], h=["x1", "x1*x2"], time="discrete", sample_time=T, name="dpend")


def f(x, u):
    return np.array([x[0] + T * x[1], x[1] + T * (-np.sin(x[0]) - 0.3 * x[1] + u)])


def F(x, u):
    return np.array([[1.0, T], [-T * np.cos(x[0]), 1 - 0.3 * T]])


def h(x):
    return np.array([x[0], x[0] * x[1]])


def H(x):
    return np.array([[1.0, 0.0], [x[1], x[0]]])


def _data(N=200, seed=3):
    rng = np.random.default_rng(seed)
    u = 0.5 * np.sin(0.1 * np.arange(N))
    x = np.zeros((N, 2))
    x[0] = [1.0, 0.0]
    for k in range(N - 1):
        x[k + 1] = f(x[k], u[k]) + 0.01 * rng.standard_normal(2)
    y = np.array([h(v) for v in x]) + 0.05 * rng.standard_normal((N, 2))
    return np.arange(N) * T, u, x, y


Q, R, P0, X0 = np.diag([1e-4, 1e-4]), np.diag([0.0025, 0.0025]), np.diag([0.5, 0.5]), np.array([0.5, 0.3])


def _numpy_ekf_pass(u, y):
    """The EKF by hand: per step the prediction (x⁻, P⁻), the innovation ν and its covariance S, the filtered (x, P)."""
    x, P, out = X0.copy(), P0.copy(), {"xp": [], "nu": [], "S": [], "xf": [], "Pf": []}
    for k in range(len(y)):
        if k:
            Fk = F(x, u[k - 1])
            x, P = f(x, u[k - 1]), Fk @ P @ Fk.T + Q
        Hk = H(x)
        S = Hk @ P @ Hk.T + R
        nu = y[k] - h(x)
        K = P @ Hk.T @ np.linalg.inv(S)
        out["xp"].append(x)
        out["nu"].append(nu)
        out["S"].append(S)
        x = x + K @ nu
        IKH = np.eye(2) - K @ Hk
        P = IKH @ P @ IKH.T + K @ R @ K.T
        out["xf"].append(x)
        out["Pf"].append(P)
    return {k: np.array(v) for k, v in out.items()}


def numpy_ekf(u, y):
    return _numpy_ekf_pass(u, y)["xf"]


def numpy_ekf_innovations(u, y):
    """y[k] − h(x[k|k−1]) of the same EKF (x[0|−1] = X0)."""
    return _numpy_ekf_pass(u, y)["nu"]


def _sigma(alpha, beta, kappa, n=2):
    """filterpy's MerweScaledSigmaPoints: the weights and a function of (x, P) giving the 2n + 1 points."""
    lam = alpha ** 2 * (n + kappa) - n
    Wm = np.full(2 * n + 1, 0.5 / (n + lam))
    Wc = Wm.copy()
    Wm[0], Wc[0] = lam / (n + lam), lam / (n + lam) + 1 - alpha ** 2 + beta

    def points(x, P):
        U = np.linalg.cholesky((n + lam) * P)
        return np.array([x] + [x + U[:, i] for i in range(n)] + [x - U[:, i] for i in range(n)])

    return Wm, Wc, points


def _numpy_ukf_pass(u, y, alpha=0.5, beta=2.0, kappa=0.0):
    """The UKF by hand (its update reuses the propagated points): the innovation ν and its covariance S per step, and
    the filtered (x, P)."""
    Wm, Wc, points = _sigma(alpha, beta, kappa)
    x, P, out = X0.copy(), P0.copy(), {"nu": [], "S": [], "xf": [], "Pf": []}
    for k in range(len(y)):
        sig = points(x, P)
        if k:
            sig = np.array([f(s, u[k - 1]) for s in sig])
            x = Wm @ sig
            P = sum(w * np.outer(s - x, s - x) for w, s in zip(Wc, sig)) + Q
        ys = np.array([h(s) for s in sig])
        yh = Wm @ ys
        S = sum(w * np.outer(v - yh, v - yh) for w, v in zip(Wc, ys)) + R
        Pxy = sum(w * np.outer(s - x, v - yh) for w, s, v in zip(Wc, sig, ys))
        K = Pxy @ np.linalg.inv(S)
        out["nu"].append(y[k] - yh)
        out["S"].append(S)
        x = x + K @ (y[k] - yh)
        P = P - K @ S @ K.T
        out["xf"].append(x)
        out["Pf"].append(P)
    return {k_: np.array(v) for k_, v in out.items()}


def numpy_ukf(u, y, alpha=0.5, beta=2.0, kappa=0.0):
    return _numpy_ukf_pass(u, y, alpha, beta, kappa)["xf"]


def _recording(t, u, y):
    return nlobs.Recording.from_arrays(PEND, t, y=y, u=u[:, None])


def test_discrete_ekf_matches_an_independent_ekf():
    t, u, x, y = _data()
    d = nlobs.design_ekf(PEND, Q=Q, R=R, P0=P0, xhat0=X0)
    run = nlobs.estimate(d, _recording(t, u, y))
    np.testing.assert_allclose(run.observers["ekf"].xhat, numpy_ekf(u, y), rtol=0, atol=1e-10)
    assert np.sqrt(np.mean((run.observers["ekf"].xhat[50:] - x[50:]) ** 2)) < 0.05


def test_discrete_innovations_are_against_the_one_step_prediction():
    t, u, x, y = _data()
    run = nlobs.estimate(nlobs.design_ekf(PEND, Q=Q, R=R, P0=P0, xhat0=X0), _recording(t, u, y))
    np.testing.assert_allclose(run.innovations("ekf"), numpy_ekf_innovations(u, y), rtol=0, atol=1e-10)
    assert set(run.whiteness("ekf")) == {"y1", "y2"}     # the recorded-data summary works on maps


def test_discrete_ukf_matches_an_independent_ukf():
    t, u, x, y = _data()
    d = nlobs.design_ukf(PEND, Q=Q, R=R, P0=P0, xhat0=X0, alpha=0.5, beta=2.0)
    run = nlobs.estimate(d, _recording(t, u, y))
    np.testing.assert_allclose(run.observers["ukf"].xhat, numpy_ukf(u, y), rtol=0, atol=1e-10)


def test_a_missing_output_is_left_out_of_the_update():
    t, u, x, y = _data(40)
    y_missing = y.copy()
    y_missing[10:20, 1] = np.nan
    d = nlobs.design_ekf(PEND, Q=Q, R=R, P0=P0, xhat0=X0)
    run = nlobs.estimate(d, _recording(t, u, y_missing), on_missing="skip")
    # reference: the same EKF with only y1 at those rows
    xr, P, out = X0.copy(), P0.copy(), []
    for k in range(len(y)):
        if k:
            Fk = F(xr, u[k - 1])
            xr, P = f(xr, u[k - 1]), Fk @ P @ Fk.T + Q
        rows = [0] if 10 <= k < 20 else [0, 1]
        Hk, Rk = H(xr)[rows], R[np.ix_(rows, rows)]
        K = P @ Hk.T @ np.linalg.inv(Hk @ P @ Hk.T + Rk)
        xr = xr + K @ (y[k, rows] - h(xr)[rows])
        IKH = np.eye(2) - K @ Hk
        P = IKH @ P @ IKH.T + K @ Rk @ K.T
        out.append(xr)
    np.testing.assert_allclose(run.observers["ekf"].xhat, np.array(out), atol=1e-10)


def test_a_recording_off_the_model_grid_is_refused():
    t, u, x, y = _data(20)
    t2 = t.copy()
    t2[5:] += 0.01
    with pytest.raises(DataError, match=r"one step apart.*row 5"):
        nlobs.estimate(nlobs.design_ekf(PEND, Q=Q, R=R), _recording(t2, u, y))


LIN = nlobs.System(states=["x1", "x2"], f=["0.9*x1 + 0.2*x2", "-0.1*x1 + 0.95*x2 + u"], inputs=["u"], outputs=["y"],
                   h=["x1"], time="discrete", sample_time=0.1)


def test_discrete_luenberger_error_contracts_by_a_minus_lc_exactly():
    d = nlobs.design_luenberger(LIN, poles=[0.5, 0.4], xhat0=[0.0, 0.0])
    A, C = np.array([[0.9, 0.2], [-0.1, 0.95]]), np.array([[1.0, 0.0]])
    L = d.certificate.values["L"]
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(A - L @ C).real), [0.4, 0.5], atol=1e-12)
    run = nlobs.simulate(LIN, {"obs": d}, t_final=2.0, x0=[1.0, -1.0], inputs={"u": "sin(t)"})
    e = run.x - run.observers["obs"].xhat
    for k in range(1, 20):   # e[k] = (A − LC) e[k−1] (the estimate at k uses y[k−1])
        np.testing.assert_allclose(e[k], (A - L @ C) @ e[k - 1], atol=1e-12)
    with pytest.raises(PreconditionError, match=r"pole 1\.2.* not inside the unit circle"):
        nlobs.design_luenberger(LIN, poles=[1.2, 0.3])


def test_discrete_lti_analysis_is_the_kalman_rank():
    r = nlobs.analyze(LIN)
    assert r.observable and r.rank == 2 and "GF(" in r.method
    blind = nlobs.System(states=["x1", "x2"], f=["0.9*x1", "0.5*x2 + x1"], outputs=["y"], h=["x1"], time="discrete")
    rb = nlobs.analyze(blind)
    A, C = np.array([[0.9, 0.0], [1.0, 0.5]]), np.array([[1.0, 0.0]])
    assert rb.rank == np.linalg.matrix_rank(np.vstack([C, C @ A])) == 1
    assert rb.observable_states == ("x1",) and np.allclose(np.abs(rb.unobservable_directions), [[0.0, 1.0]])


def test_map_identifiability_and_a_symmetry():
    ricker = nlobs.System(states=["N"], f=["N*exp(r*(1 - N/K))"], outputs=["y"], h=["N"], params={"r": 1.2, "K": 10.0},
                          time="discrete")
    assert nlobs.analyze(ricker, unknown_params=["r", "K"]).identifiable_params == ("r", "K")
    # y = x1², x1[k+1] = 0.5 x1: the sign of x1 never shows, but locally observable (rank 1 = 1)
    sq = nlobs.System(states=["x1"], f=["0.5*x1"], outputs=["y"], h=["x1**2"], time="discrete")
    assert nlobs.analyze(sq).observable
    # two parameters entering only as a product are not identifiable one by one
    prod = nlobs.System(states=["x"], f=["a*b*x + u"], inputs=["u"], outputs=["y"], h=["x"], params={"a": 0.5, "b": 0.8},
                        time="discrete")
    rp = nlobs.analyze(prod, unknown_params=["a", "b"])
    assert rp.rank == 2 and rp.identifiable_params == () and rp.observable_states == ("x",)


def test_montecarlo_on_a_map_is_simulate_per_seed():
    d = nlobs.design_ekf(PEND, Q=Q, R=R, P0=P0, xhat0=X0)
    kw = dict(t_final=5.0, inputs={"u": "0.5*sin(2*t)"}, noise=nlobs.Noise.gaussian(0.05),
              process_noise=nlobs.ProcessNoise(0.01))
    mc = nlobs.montecarlo(PEND, {"ekf": d}, x0=[[1.0, 0.0], [0.5, 0.2], [-1.0, 0.5]], **kw)
    assert mc.runs == 3 and mc.failed.size == 0 and mc.info["time"] == "discrete"
    for j in range(3):
        one = nlobs.simulate(PEND, {"ekf": d}, x0=mc.x[j, 0], seed=int(mc.seeds[j]), **kw)
        np.testing.assert_array_equal(mc.observers["ekf"].xhat[j], one.observers["ekf"].xhat)
        assert mc.observers["ekf"].rms_error[j] == pytest.approx(one.metrics("ekf").rms_error, rel=1e-12)
    np.testing.assert_array_equal(mc.trajectory(1).x, nlobs.simulate(PEND, {"ekf": d}, x0=[0.5, 0.2],
                                                                      seed=int(mc.seeds[1]), **kw).x)
    assert "ekf" in str(mc.summary())


def test_mhe_on_a_linear_map_is_the_kalman_filter():
    # unconstrained MHE on a linear map with the Kalman filter's arrival cost is the Kalman filter (Rao, Rawlings &
    # Mayne (2003)): the window adds nothing a KF does not already hold, whatever the horizon
    lin = nlobs.System(states=["x1", "x2"], inputs=["u"], outputs=["y"], f=["x1 + 0.1*x2", "-0.1*x1 + 0.98*x2 + 0.1*u"],
                       h=["x1"], time="discrete", sample_time=0.1, name="dlin")
    Qd, Rd, P0d = np.diag([1e-3, 1e-2]), np.array([[0.04]]), np.eye(2)
    run = nlobs.simulate(lin, None, t_final=6.0, x0=[1.0, 0.0], inputs={"u": "sin(t)"}, noise=nlobs.Noise.gaussian(0.2),
                         process_noise=nlobs.ProcessNoise([0.03, 0.1]), seed=2)
    kf = nlobs.design_ekf(lin, Q=Qd, R=Rd, P0=P0d, xhat0=[0.0, 0.0])
    mhe = nlobs.design_mhe(lin, horizon=5, Q=Qd, R=Rd, P0=P0d, xhat0=[0.0, 0.0])
    r = nlobs.estimate({"kf": kf, "mhe": mhe}, nlobs.Recording.from_run(run))
    np.testing.assert_allclose(r.observers["mhe"].xhat, r.observers["kf"].xhat, rtol=0, atol=1e-9)


def test_mhe_on_a_nonlinear_map_converges():
    t, u, x, y = _data(N=120)
    mhe = nlobs.design_mhe(PEND, horizon=8, Q=Q, R=R, P0=P0, xhat0=X0)
    run = nlobs.estimate(mhe, _recording(t, u, y))
    assert np.sqrt(np.mean((run.observers["mhe"].xhat[60:] - x[60:]) ** 2)) < 0.05


def numpy_eks(u, y):
    """The extended RTS smoother (Simon (2006) §9.4.2) after numpy_ekf: x_s[k] = x[k] + G (x_s[k+1] − f(x[k]))."""
    run = _numpy_ekf_pass(u, y)
    xf, Pf = run["xf"], run["Pf"]
    xs = [xf[-1]]
    for k in range(len(y) - 2, -1, -1):
        Fk = F(xf[k], u[k])
        Pp = Fk @ Pf[k] @ Fk.T + Q
        G = Pf[k] @ Fk.T @ np.linalg.inv(Pp)
        xs.insert(0, xf[k] + G @ (xs[0] - f(xf[k], u[k])))
    return np.array(xs)


def test_the_map_smoother_is_the_extended_rts_smoother():
    t, u, x, y = _data()
    d = nlobs.design_ekf(PEND, Q=Q, R=R, P0=P0, xhat0=X0)
    run = nlobs.estimate(d, _recording(t, u, y), smooth=True)
    tr = run.observers["ekf"]
    np.testing.assert_allclose(tr.xhat, numpy_eks(u, y), rtol=0, atol=1e-10)
    np.testing.assert_allclose(tr.filtered, numpy_ekf(u, y), rtol=0, atol=1e-10)
    err = lambda e: np.sqrt(np.mean((e[20:-20] - x[20:-20]) ** 2))  # noqa: E731
    assert err(tr.xhat) < err(tr.filtered)                            # the samples after help
    ukf = nlobs.estimate(nlobs.design_ukf(PEND, Q=Q, R=R, P0=P0, xhat0=X0), _recording(t, u, y), smooth=True)
    assert err(ukf.observers["ukf"].xhat) < err(ukf.observers["ukf"].filtered)
    lue = nlobs.design_luenberger(nlobs.System(states=["x"], outputs=["y"], f=["0.5*x"], h=["x"], time="discrete",
                                               sample_time=0.1), poles=[0.2])
    with pytest.raises(PreconditionError, match="smoothers of a discrete-time model exist for its ") as err:
        nlobs.estimate(lue, nlobs.Recording.from_arrays(lue.system, [0.0, 0.1], [[1.0], [0.5]]), smooth=True)
    listed = str(err.value).split("exist for its ")[1].split(", ")
    assert sorted(listed) == ["ekf", "iekf", "srekf", "srukf", "ukf"]


def numpy_urts(u, y, alpha=0.5, beta=2.0, kappa=0.0):
    """numpy_ukf's filter, then the unscented RTS smoother of Särkkä (2008) with the same sigma points."""
    Wm, Wc, points = _sigma(alpha, beta, kappa)
    run = _numpy_ukf_pass(u, y, alpha, beta, kappa)
    xf, Pf = run["xf"], run["Pf"]
    xs = [xf[-1]]
    for k in range(len(y) - 2, -1, -1):
        sig = points(xf[k], Pf[k])
        fs = np.array([f(s, u[k]) for s in sig])
        xp = Wm @ fs
        Pp = sum(w * np.outer(v - xp, v - xp) for w, v in zip(Wc, fs)) + Q
        C = sum(w * np.outer(s - xf[k], v - xp) for w, s, v in zip(Wc, sig, fs))
        xs.insert(0, xf[k] + C @ np.linalg.inv(Pp) @ (xs[0] - xp))
    return np.array(xs)


def test_the_unscented_map_smoother_is_sarkkas():
    t, u, x, y = _data()
    run = nlobs.estimate(nlobs.design_ukf(PEND, Q=Q, R=R, P0=P0, xhat0=X0, alpha=0.5, beta=2.0), _recording(t, u, y),
                         smooth=True)
    np.testing.assert_allclose(run.observers["ukf"].xhat, numpy_urts(u, y), rtol=0, atol=1e-9)


def numpy_ekf_loglik(u, y):
    """Σ −½(log det(2π S_k) + ν_kᵀ S_k⁻¹ ν_k) of numpy_ekf (Schweppe's prediction-error decomposition)."""
    run = _numpy_ekf_pass(u, y)
    return sum(-0.5 * (np.log(np.linalg.det(2 * np.pi * S)) + nu @ np.linalg.solve(S, nu)) for nu, S in zip(run["nu"], run["S"]))


def test_the_likelihood_of_a_map_and_learning_its_parameter():
    t, u, x, y = _data()
    ll, grad = nlobs.log_likelihood(nlobs.design_ekf(PEND, Q=Q, R=R, P0=P0, xhat0=X0), _recording(t, u, y))
    assert ll == pytest.approx(numpy_ekf_loglik(u, y), rel=1e-11)
    # the damping of the pendulum map, learnt from 400 steps of its data (true 0.3)
    damped = nlobs.System(states=["x1", "x2"], f=[f"x1 + {T}*x2", f"x2 + {T}*(-sin(x1) - c*x2 + u)"], inputs=["u"],
                          outputs=["y1", "y2"], h=["x1", "x1*x2"], params={"c": 0.6}, time="discrete", sample_time=T)
    t, u, x, y = _data(N=400, seed=5)
    fit = nlobs.fit_likelihood(nlobs.design_ekf(damped, Q=Q, R=R, P0=P0, xhat0=X0),
                               nlobs.Recording.from_arrays(damped, t, y=y, u=u[:, None]), ["c"])
    c = fit.parameters["c"]
    assert abs(c["estimate"] - 0.3) < 3 * c["std"] and c["std"] < 0.1
    t, u, x, y = _data()
    uk = nlobs.log_likelihood(nlobs.design_ukf(PEND, Q=Q, R=R, P0=P0, xhat0=X0, alpha=0.5, beta=2.0), _recording(t, u, y))
    assert uk[0] == pytest.approx(numpy_ukf_loglik(u, y), rel=1e-11)


def numpy_ukf_loglik(u, y, alpha=0.5, beta=2.0, kappa=0.0):
    """The same sum for numpy_ukf (its update reuses the propagated sigma points)."""
    run = _numpy_ukf_pass(u, y, alpha, beta, kappa)
    return sum(-0.5 * (np.log(np.linalg.det(2 * np.pi * S)) + nu @ np.linalg.solve(S, nu)) for nu, S in zip(run["nu"], run["S"]))
