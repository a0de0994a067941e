"""Fixed-interval smoothing (issue 22, item 1): estimate(..., smooth=True) and ``nlobs estimate --smooth``.

References are independent: a NumPy Kalman filter and RTS smoother written here (Rauch, Tung & Striebel 1965)
on a linear-Gaussian model, where RK4 of x' = Ax + Bu over a step h is the matrix polynomial
I + hA + (hA)²/2 + (hA)³/6 + (hA)⁴/24 and the smoother is exact; and the true states of a pendulum
integrated by SciPy at tight tolerance.
"""

from __future__ import annotations

import csv
import json

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import nlobs
from nlobs.cli import main
from nlobs.errors import PreconditionError
from nlobs.estimation import Recording

A = np.array([[0.0, 1.0], [-2.0, -0.5]])
B = np.array([0.0, 1.0])
C = np.array([[1.0, 0.0]])
Q = np.diag([1e-3, 1e-2])
R = np.array([[0.01]])
P0 = np.eye(2)
X0 = np.array([0.1, 0.0])
LINEAR = nlobs.System(states=["x1", "x2"], inputs=["u"], f=["x2", "-2*x1 - 0.5*x2 + u"], outputs=["y"], h=["x1"])


def _linear_recording(N: int = 200, dt: float = 0.05) -> Recording:
    rng = np.random.default_rng(0)
    t = np.arange(N) * dt
    y = (np.sin(2 * t) + 0.1 * rng.standard_normal(N))[:, None]
    y[[40, 41, 120]] = np.nan  # missing samples: no update there
    return Recording.from_arrays(LINEAR, t, y, np.sin(t)[:, None])


def _numpy_rts(rec: Recording, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Kalman filter (continuous-discrete: RK4 of mean and Ṗ = AP + PAᵀ + Q in m steps per interval) and RTS."""
    t, u, y = rec.t, rec.u[:, 0], rec.y[:, 0]
    N, dt = t.size, t[1] - t[0]
    h = dt / m
    Ah = A * h
    step = np.eye(2) + Ah + Ah @ Ah / 2 + Ah @ Ah @ Ah / 6 + Ah @ Ah @ Ah @ Ah / 24
    Phi = np.linalg.matrix_power(step, m)

    def rk4(fn, x):
        k1 = fn(x)
        k2 = fn(x + h / 2 * k1)
        k3 = fn(x + h / 2 * k2)
        k4 = fn(x + h * k3)
        return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    x, P = X0.copy(), P0.copy()
    xf, Pf, xp, Pp = [], [], [], []
    for k in range(N):
        if k:
            uk = u[k - 1]
            for _ in range(m):
                x = rk4(lambda v: A @ v + B * uk, x)
                P = rk4(lambda M: A @ M + M @ A.T + Q, P)
        xp.append(x)
        Pp.append(P)
        if np.isfinite(y[k]):
            S = C @ P @ C.T + R
            K = P @ C.T @ np.linalg.inv(S)
            x = x + K @ (y[k] - C @ x)
            P = P - K @ S @ K.T
        xf.append(x)
        Pf.append(P)
    xs, Ps = [None] * N, [None] * N
    xs[-1], Ps[-1] = xf[-1], Pf[-1]
    for k in range(N - 2, -1, -1):
        G = Pf[k] @ Phi.T @ np.linalg.inv(Pp[k + 1])
        xs[k] = xf[k] + G @ (xs[k + 1] - xp[k + 1])
        Ps[k] = Pf[k] + G @ (Ps[k + 1] - Pp[k + 1]) @ G.T
    return np.array(xf), np.array(xs), np.array(Ps)


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
@pytest.mark.parametrize("substeps", [1, 3])
@pytest.mark.parametrize("engine", ["c", "vm"])
def test_linear_gaussian_smoother_matches_numpy_rts(kind, substeps, engine):
    """For a linear model the EKF and UKF are the Kalman filter and RTS/URTS the exact smoother: same numbers as an
    independent NumPy RTS to 1e-10 (estimates and smoothed covariances), with one and with three RK4 sub-steps."""
    if engine == "c" and nlobs.engine.find_compiler() is None:
        pytest.skip("no C compiler")
    rec = _linear_recording()
    make = nlobs.design_ekf if kind == "ekf" else nlobs.design_ukf
    d = make(LINEAR, Q=Q, R=R, P0=P0, xhat0=X0)
    dt = rec.t[1] - rec.t[0]
    run = nlobs.estimate(d, rec, smooth=True, on_missing="skip", max_step=dt / substeps * (1 + 1e-12), engine=engine)
    tr = run.observers[kind]
    assert run.info["integration"][kind]["max_substeps"] == substeps  # the reference integrates with as many
    assert run.info["integration"][kind]["substeps"] == substeps * (rec.t.size - 1)
    xf, xs, Ps = _numpy_rts(rec, substeps)
    assert tr.smoothed and run.info["smoothed"]
    assert np.max(np.abs(tr.filtered - xf)) < 1e-10
    assert np.max(np.abs(tr.xhat - xs)) < 1e-10
    assert np.max(np.abs(tr.smoothed_covariance - Ps)) < 1e-10
    assert np.allclose(tr.std, np.sqrt(np.diagonal(Ps, axis1=1, axis2=2)), rtol=1e-9, atol=0)
    assert np.max(np.abs(tr.xhat - xf)) > 1e-2  # smoothing changed the estimates (the test can see a no-op)


def test_ekf_transition_jacobian_is_that_of_the_rk4_map():
    """The EKF smoother's A_k is the Jacobian of the RK4 map the filter integrates (nonlinear model, 4 sub-steps):
    compared with CasADi's Jacobian of that map written out here."""
    from nlobs.observer._compiled import compiled_observer, interval_table
    from nlobs.estimation._smooth import _Replay

    vdp = nlobs.System(states=["x1", "x2"], f=["x2", "1.5*(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"])
    d = nlobs.design_ekf(vdp, Q=np.eye(2) * 1e-3, R=[[0.01]], xhat0=[1.0, 0.5])
    t = np.arange(30) * 0.1
    y = np.cos(t)[:, None]
    m = np.ones_like(y)
    u = np.zeros((30, 0))
    traj = compiled_observer(d).run(t, u=u, y=y, max_step=0.025 * (1 + 1e-12), engine="vm")
    assert set(traj.substeps) == {4}
    res = _Replay(d, "zoh").run(traj.z[0], traj.y_used[0], interval_table(t, u, y, m), traj.substeps, "vm")
    x = ca.SX.sym("x", 2)

    def f(v):
        return ca.vertcat(v[1], 1.5 * (1 - v[0] ** 2) * v[1] - v[0])

    xe, h = x, 0.025
    for _ in range(4):
        k1 = f(xe)
        k2 = f(xe + h / 2 * k1)
        k3 = f(xe + h / 2 * k2)
        k4 = f(xe + h * k3)
        xe = xe + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    J = ca.Function("J", [x], [ca.jacobian(xe, x), xe])
    for k in (0, 7, 28):
        Jk, xk = (np.asarray(v) for v in J(traj.z[k, :2]))
        assert np.allclose(res.outputs[k, -4:].reshape(2, 2, order="F"), Jk, rtol=0, atol=1e-12)
        assert np.allclose(res.outputs[k, :2], xk.ravel(), rtol=0, atol=1e-12)  # the prediction is the filter's RK4 map


def _pendulum():
    """A pendulum not among the package's examples (a1 = 6, a2 = 0.3, x(0) = (1.2, 0)), angle measured with noise."""
    a1, a2 = 6.0, 0.3
    system = nlobs.System(states=["th", "om"], inputs=["u"], f=["om", "-a1*sin(th) - a2*om + u"], outputs=["y"],
                          h=["th"], params={"a1": a1, "a2": a2})
    rng = np.random.default_rng(7)
    dt, N = 0.02, 1000
    t = np.arange(N) * dt
    sol = solve_ivp(lambda tt, x: [x[1], -a1 * np.sin(x[0]) - a2 * x[1] + 0.5 * np.sin(0.7 * tt)], (0, t[-1]), [1.2, 0.0],
                    t_eval=t, rtol=1e-10, atol=1e-12)
    x = sol.y.T
    y = x[:, :1] + 0.05 * rng.standard_normal((N, 1))
    return system, Recording.from_arrays(system, t, y, 0.5 * np.sin(0.7 * t)[:, None], x)


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_smoothing_halves_the_error_of_the_unmeasured_state(kind):
    system, rec = _pendulum()
    make = nlobs.design_ekf if kind == "ekf" else nlobs.design_ukf
    d = make(system, Q=np.diag([1e-6, 1e-4]), R=[[0.05**2]], P0=np.eye(2), xhat0=[0.0, 0.0])
    tr = nlobs.estimate(d, rec, smooth=True).observers[kind]
    late = rec.t > 1.0
    rms_f = np.sqrt(np.mean((tr.filtered[late, 1] - rec.x[late, 1]) ** 2))
    rms_s = np.sqrt(np.mean((tr.xhat[late, 1] - rec.x[late, 1]) ** 2))
    assert rms_s < 0.6 * rms_f, (rms_s, rms_f)
    # the smoothed covariance is below the filtered one at every sample (more data) and its std covers the error
    Pf = np.array([np.diag(np.asarray(d.covariance(z)))[1] for z in tr.z[::50]])
    assert np.all(tr.std[::50, 1] ** 2 <= Pf * (1 + 1e-9))
    assert np.mean(np.abs(tr.xhat[late, 1] - rec.x[late, 1]) < 3 * tr.std[late, 1]) > 0.95


def test_smoother_refuses_unsupported_observers():
    system, rec = _pendulum()
    ct = nlobs.design_ekf(system, Q=np.eye(2) * 1e-4, R=[[0.01]], mode="continuous")
    with pytest.raises(PreconditionError, match="continuous-discrete kinds ekf, ukf"):
        nlobs.estimate(ct, rec, smooth=True)
    hg = nlobs.design_high_gain(system, theta=5.0)
    with pytest.raises(PreconditionError, match="kind 'high_gain'; smoothers exist for the continuous-discrete kinds ekf, ukf"):
        nlobs.estimate(hg, rec, smooth=True)
    bounded = nlobs.design_ekf(system, Q=np.eye(2) * 1e-4, R=[[0.01]], bounds={"th": (-4, 4)})
    with pytest.raises(PreconditionError, match="state bounds"):
        nlobs.estimate(bounded, rec, smooth=True)


def test_cli_estimate_smooth_writes_the_smoothed_estimates(tmp_path, capsys):
    system, rec = _pendulum()
    model = tmp_path / "pend.toml"
    model.write_text('name = "pend"\nstates = ["th", "om"]\ninputs = ["u"]\noutputs = ["y"]\n'
                     '[parameters]\na1 = 6.0\na2 = 0.3\n[dynamics]\nth = "om"\nom = "-a1*sin(th) - a2*om + u"\n'
                     '[output]\ny = "th"\n[observers.ekf]\nkind = "ekf"\nQ = [[1e-6, 0.0], [0.0, 1e-4]]\n'
                     'R = [[0.0025]]\nxhat0 = [0.0, 0.0]\n[observers.hg]\nkind = "high_gain"\ntheta = 5.0\n')
    data = tmp_path / "rec.csv"
    with open(data, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "u", "y"])
        for row in np.column_stack([rec.t, rec.u, rec.y]):
            w.writerow([repr(float(v)) for v in row])
    out = tmp_path / "est.csv"
    assert main(["estimate", str(model), str(data), "--observer", "ekf", "--smooth", "--output", str(out)]) == 0
    assert "smoothed" in capsys.readouterr().out
    back = np.genfromtxt(out, delimiter=",", names=True)
    assert back.dtype.names == ("t", "u", "y", "ekfth", "ekfom")  # today's columns
    d = nlobs.design_ekf(system, Q=np.diag([1e-6, 1e-4]), R=[[0.0025]], xhat0=[0.0, 0.0])
    ref = nlobs.estimate(d, Recording.from_csv(data, system), smooth=True).observers["ekf"].xhat
    assert np.max(np.abs(np.column_stack([back["ekfth"], back["ekfom"]]) - ref)) < 1e-12
    assert main(["estimate", str(model), str(data), "--observer", "ekf", "--smooth", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["observers"]["ekf"]["smoothed"] is True
    assert main(["estimate", str(model), str(data), "--observer", "ekf", "--json"]) == 0
    assert "smoothed" not in json.loads(capsys.readouterr().out)["observers"]["ekf"]
    assert main(["estimate", str(model), str(data), "--observer", "hg", "--smooth"]) == 1
    err = capsys.readouterr().err
    assert "ekf, ukf" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("hold", ["zoh", "linear"])
def test_the_smoother_predicts_as_the_filter_did(hold):
    """The replayed prediction (same RK4 sub-steps, same hold of u and y) reproduces the filter's states to rounding."""
    system, rec = _pendulum()
    for make in (nlobs.design_ekf, nlobs.design_ukf):
        d = make(system, Q=np.diag([1e-6, 1e-4]), R=[[0.05**2]], xhat0=[0.0, 0.0])
        run = nlobs.estimate(d, rec, smooth=True, hold=hold, max_step=0.01)
        info = run.info["integration"][d.method]
        assert info["max_substeps"] == 2 and info["replay_difference"] < 1e-12
        assert np.array_equal(run.observers[d.method].filtered, nlobs.estimate(d, rec, hold=hold, max_step=0.01).observers[d.method].xhat)


def test_plot_of_a_smoothed_run_shows_the_filtered_estimate_too():
    system, rec = _pendulum()
    d = nlobs.design_ekf(system, Q=np.diag([1e-6, 1e-4]), R=[[0.05**2]], xhat0=[0.0, 0.0])
    run = nlobs.estimate(d, rec, smooth=True)
    fig = run.plot()
    labels = [ln.get_label() for ln in fig.axes[1].get_lines()]
    assert labels == ["true", "ekf (filtered)", "ekf (smoothed)"]
    ys = [ln.get_ydata() for ln in fig.axes[1].get_lines()]
    assert np.allclose(ys[1], run.observers["ekf"].filtered[:, 1]) and np.allclose(ys[2], run.observers["ekf"].xhat[:, 1])
    assert len(fig.axes[2].get_lines()) == 2  # error norms: filtered (dotted) and smoothed


STIFF = nlobs.System(states=["a", "b", "c"], f=["-30*a + b", "-40*b + c", "-50*c"], outputs=["y"], h=["a + b + c"])


def _stiff_recording(N: int = 100, dt: float = 0.1) -> Recording:
    rng = np.random.default_rng(1)
    t = np.arange(N) * dt
    return Recording.from_arrays(STIFF, t, 0.01 * rng.standard_normal((N, 1)))


def test_a_diverged_backward_pass_is_refused_not_returned():
    """Issue 44, item 1: with Q = 0 on a contracting flow the RTS gain is Φ⁻¹ (growth e^{3..5} per sample here), so the
    backward pass amplifies rounding beyond any bound. A smoothed variance never exceeds the filtered one (Rauch,
    Tung & Striebel 1965), so the result is refused with where it failed instead of returned as numbers."""
    d = nlobs.design_ekf(STIFF, Q=np.zeros((3, 3)), R=[[1e-4]], P0=np.eye(3), xhat0=[1.0, 1.0, 1.0])
    with pytest.raises(nlobs.errors.FiniteEscapeError, match=r"smoother diverged going backwards: at t = .* \(row \d+\)"):
        nlobs.estimate({"ekf": d}, _stiff_recording(), smooth=True)


def test_with_a_small_process_noise_the_same_smoother_stays_below_the_filter():
    d = nlobs.design_ekf(STIFF, Q=np.eye(3) * 1e-10, R=[[1e-4]], P0=np.eye(3), xhat0=[1.0, 1.0, 1.0])
    tr = nlobs.estimate({"ekf": d}, _stiff_recording(), smooth=True).observers["ekf"]
    Ps, zf = tr.smoothed_covariance, tr.z[:, 3:].reshape(-1, 3, 3)
    vs, vf = np.einsum("kii->ki", Ps), np.einsum("kii->ki", zf)
    assert np.isfinite(tr.xhat).all() and np.all(vs <= vf * (1 + 1e-6) + 1e-15)
