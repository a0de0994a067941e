"""Moving-horizon estimation (002_613af42269ea26a7.txt, "About methods", approach I), multiple shooting,
process noise, EKF-style arrival cost, compiled SQP with IPOPT fallback.

Most tests run the solver on CasADi's virtual machine (NLOBS_CC=none) to keep the suite fast; one test
checks that the compiled C path gives the same estimates.
"""

import numpy as np
import pytest

import nlobs
from nlobs.design import design_ekf, design_mhe
from nlobs.engine import find_compiler
from nlobs.errors import PreconditionError, ShapeError, SolverError

VDP = nlobs.System(states=["x1", "x2"], f=["x2", "(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], name="vdp")
OSC = nlobs.System(states=["x1", "x2"], f=["x2", "-x1 - 0.5*x2"], outputs=["y"], h=["x1"], name="osc")


@pytest.fixture(autouse=True)
def _virtual_machine(monkeypatch, request):
    if "compiled" not in request.node.name:
        monkeypatch.setenv("NLOBS_CC", "none")


def _noisy_vdp(t_final=12.0, dt=0.1, sigma=0.1, seed=0):
    run = nlobs.simulate(VDP, None, t_final=t_final, dt=dt / 10, x0=[2.0, 0.0])
    rng = np.random.default_rng(seed)
    t, x = run.t[::10], run.x[::10]
    y = run.y[::10] + sigma * rng.standard_normal((t.size, 1))
    return nlobs.Recording.from_arrays(VDP, t, y, x=x)


def test_noise_free_window_recovers_the_state():
    # Without noise the true trajectory fits the window exactly; with the fixed (smoothed) prior the arrival term
    # vanishes once the prior is exact, so the error collapses to the solver tolerance. 10 RK4 substeps per 0.1 s
    # sample integrate the window model exactly like the plant (dt = 0.01).
    d = design_mhe(VDP, horizon=10, R=[[1e-2]], P0=10 * np.eye(2), substeps=10, arrival="fixed")
    run = nlobs.simulate(VDP, d, t_final=6.0, dt=1e-2, x0=[2.0, 0.0], xhat0=[0.0, 1.0], sampling=nlobs.Sampling(0.1))
    e = run.error_norm()
    assert e[0] > 1.0 and e[-1] < 1e-8
    # with the EKF arrival and Q = 0 the prior keeps a Kalman-like (slowly shrinking) share: small, not zero
    d2 = design_mhe(VDP, horizon=10, R=[[1e-2]], P0=10 * np.eye(2), substeps=10)
    e2 = nlobs.simulate(VDP, d2, t_final=6.0, dt=1e-2, x0=[2.0, 0.0], xhat0=[0.0, 1.0], sampling=nlobs.Sampling(0.1)).error_norm()
    assert e2[-1] < 1e-3 and e2[-1] < e2[300] < e2[0]


def _rk4_matrix(A, h, steps):
    M = h * A
    step = np.eye(A.shape[0]) + M + M @ M / 2 + M @ M @ M / 6 + M @ M @ M @ M / 24
    return np.linalg.matrix_power(step, steps)


def test_linear_gaussian_mhe_is_the_kalman_filter():
    # For a linear model with Gaussian weights, MHE whose arrival cost is the Kalman prior is the full-information
    # estimator: its newest state equals the discrete Kalman filter's filtered estimate x(k|k), and its arrival
    # covariance the filter's prior covariance at the window start (Rao, Rawlings & Mayne 2003). Reference: a
    # NumPy Kalman filter on the same discretisation (RK4 map Φ, process noise covariance QΔ per interval).
    A = np.array([[0.0, 1.0], [-1.0, -0.5]])
    dt, N, sub = 0.1, 5, 2
    Q, R, P0 = np.diag([0.02, 0.05]), np.array([[0.01]]), np.diag([2.0, 1.0])
    rng = np.random.default_rng(3)
    K = 40
    t = np.arange(K) * dt
    x = np.zeros((K, 2))
    x[0] = [1.0, -0.5]
    Phi = _rk4_matrix(A, dt / sub, sub)
    for k in range(K - 1):
        x[k + 1] = Phi @ x[k] + rng.multivariate_normal(np.zeros(2), Q * dt)
    y = x[:, :1] + 0.1 * rng.standard_normal((K, 1))
    xh0 = np.array([0.0, 0.0])
    # Kalman filter
    H = np.array([[1.0, 0.0]])
    xp, Pp = xh0.copy(), P0.copy()
    kf, priors = [], []
    for k in range(K):
        priors.append(Pp.copy())
        S = H @ Pp @ H.T + R
        G = Pp @ H.T @ np.linalg.inv(S)
        xf = xp + G @ (y[k] - H @ xp)
        Pf = (np.eye(2) - G @ H) @ Pp
        kf.append(xf)
        xp, Pp = Phi @ xf, Phi @ Pf @ Phi.T + Q * dt
    d = design_mhe(OSC, horizon=N, Q=Q, R=R, P0=P0, xhat0=xh0, substeps=sub, tol=1e-10)
    run = nlobs.estimate(d, nlobs.Recording.from_arrays(OSC, t, y))
    np.testing.assert_allclose(run.observers["mhe"].xhat, np.array(kf), atol=1e-7)
    z = run.observers["mhe"].z[-1]
    P_mhe = z[[d.z_names.index(f"P_{i}_{j}") for j in range(2) for i in range(2)]].reshape(2, 2, order="F")
    np.testing.assert_allclose(P_mhe, priors[K - 1 - N], rtol=1e-7)


def test_sqp_and_ipopt_find_the_same_estimates():
    rec = _noisy_vdp()
    kw = dict(horizon=10, R=[[0.01]], Q=0.01 * np.eye(2), P0=np.eye(2), xhat0=[1.5, 0.5], tol=1e-10)
    a = nlobs.estimate(design_mhe(VDP, **kw), rec).observers["mhe"]
    b = nlobs.estimate(design_mhe(VDP, solver="ipopt", **kw), rec).observers["mhe"]
    np.testing.assert_allclose(a.xhat, b.xhat, atol=1e-6)
    assert a.z[-1, -1] == 0  # no IPOPT fallback was needed
    assert np.sqrt(np.mean((a.xhat[30:] - rec.x[30:]) ** 2)) < 0.1


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler on this machine: the compiled path cannot run")
def test_compiled_path_gives_the_virtual_machine_estimates(monkeypatch):
    # the structure of the conformance suite's MHE case (same model, horizon, noise rank), so one compile serves both
    plant = nlobs.System(states=["x1", "x2"], f=["x2", "-x1 - 0.5*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"], name="osc")
    run = nlobs.simulate(plant, None, t_final=4.0, dt=0.1, x0=[1.0, 0.0], inputs={"u": "sin(t)"}, noise=nlobs.Noise.gaussian(0.05),
                         sampling=nlobs.Sampling(0.1), seed=2)
    rec = nlobs.Recording.from_run(run)
    kw = dict(horizon=5, R=[[2.5e-3]], P0=np.eye(2), xhat0=[0.0, 0.0])
    fast = design_mhe(plant, **kw)
    assert fast.certificate.values["compiled"].startswith("generated C")
    a = nlobs.estimate(fast, rec).observers["mhe"].xhat
    monkeypatch.setenv("NLOBS_CC", "none")
    vm = design_mhe(plant, **kw)
    assert vm.certificate.values["compiled"].startswith("no C compiler")
    np.testing.assert_allclose(a, nlobs.estimate(vm, rec).observers["mhe"].xhat, atol=1e-10)


def test_simulated_recorded_and_online_runs_agree():
    d = design_mhe(VDP, horizon=8, R=[[0.01]], Q=0.01 * np.eye(2))
    run = nlobs.simulate(VDP, d, t_final=3.0, dt=1e-2, x0=[2.0, 0.0], noise=nlobs.Noise.gaussian(0.05),
                         sampling=nlobs.Sampling(0.05), seed=1)
    rec = nlobs.Recording.from_run(run, every=5)
    again = nlobs.estimate(d, rec, max_step=1e-2)
    np.testing.assert_allclose(again.observers["mhe"].xhat, run.observers["mhe"].xhat[::5], atol=1e-7)
    online = nlobs.Observer(d).start()
    xs = np.array([online.update(t, y=y) for t, y in zip(rec.t, rec.y)])
    np.testing.assert_allclose(xs, again.observers["mhe"].xhat, atol=1e-9)


def test_missing_samples_are_left_out():
    d = design_mhe(VDP, horizon=8, R=[[0.01]])
    o = nlobs.Observer(d)
    z = o.initial_state([0.5, 0.0])
    z1 = o.update(0.0, z, None, [5.0], mask=[0.0])
    z2 = o.update(0.0, z, None, [7.0], mask=[0.0])
    np.testing.assert_array_equal(z1[:2], z2[:2])  # the unmeasured value has no influence
    assert not np.allclose(o.update(0.0, z, None, [5.0], mask=[1.0])[:2], z1[:2])


def test_solver_failure_names_the_window_and_the_status():
    # one iteration from far away cannot converge, neither for the SQP nor for the IPOPT fallback
    d = design_mhe(VDP, horizon=6, R=[[1e-4]], Q=0.01 * np.eye(2), P0=100 * np.eye(2), xhat0=[8.0, -8.0], max_iter=1)
    rec = _noisy_vdp(t_final=3.0)
    # the window is still filling (its first slots repeat t = 0): it is told by the samples it has, not as "t in [0, 0.1]"
    with pytest.raises(SolverError, match=r"the window at t = 0\.1 \(the first 2 samples of the run; the window fills up "
                                          r"to 7 samples\).*SQP: not converged.*IPOPT: Maximum_Iterations") as err:
        nlobs.estimate(d, rec)
    assert err.value.window[0] == 0.0 and "IPOPT" in err.value.status
    online = nlobs.Observer(d).start()  # the same failure, raised by the online estimator with its own type
    with pytest.raises(SolverError, match=f"the window at t = {err.value.window[1]:g} \\(the first 2 samples"):
        for t, y in zip(rec.t, rec.y):
            online.update(t, y=y)


def test_bounds_keep_every_window_state_inside():
    # the oscillator's x1 swings to -0.44; with x1 >= -0.2 every node of every window and every estimate stays above
    rec = nlobs.Recording.from_run(nlobs.simulate(OSC, None, t_final=8.0, dt=0.1, x0=[1.0, 0.0]))
    kw = dict(horizon=6, R=[[1e-2]], Q=0.01 * np.eye(2), xhat0=[1.0, 0.0])
    free = nlobs.estimate(design_mhe(OSC, **kw), rec).observers["mhe"]
    boxed = nlobs.estimate(design_mhe(OSC, bounds={"x1": (-0.2, None)}, **kw), rec).observers["mhe"]
    assert free.xhat[:, 0].min() < -0.4
    assert boxed.xhat[:, 0].min() >= -0.2 - 1e-12
    d = design_mhe(OSC, bounds={"x1": (-0.2, None)}, **kw)
    nodes = boxed.z[:, [d.z_names.index(f"X_x1_{i}") for i in range(7)]]
    assert nodes.min() >= -0.2 - 1e-9


def test_certificate_states_what_was_checked():
    d = design_mhe(VDP, horizon=5, R=[[0.01]], Q=0.01 * np.eye(2), bounds={"x2": (None, 5.0)})
    text = str(d.certificate)
    assert "[assumed] the model is observable over the window" in text
    assert "[ok] initial estimate inside the bounds" in text and "x2 in [-inf, 5]" in text
    assert "Rao, Rawlings & Mayne (2003)" in d.certificate.reference


def test_preconditions():
    with pytest.raises(PreconditionError, match="horizon"):
        design_mhe(VDP, horizon=0)
    with pytest.raises(PreconditionError, match="positive definite"):
        design_mhe(VDP, R=[[0.0]])
    with pytest.raises(PreconditionError, match="semidefinite"):
        design_mhe(VDP, Q=-np.eye(2))
    with pytest.raises(PreconditionError, match="`arrival` must be 'ekf' or 'fixed'"):
        design_mhe(VDP, arrival="smoothed")
    with pytest.raises(PreconditionError, match="`solver` must be 'sqp' or 'ipopt'"):
        design_mhe(VDP, solver="snopt")
    with pytest.raises(ShapeError, match="'x3', which is not a state"):
        design_mhe(VDP, bounds={"x3": (0, 1)})
    with pytest.raises(PreconditionError, match="bounds of `x1` are empty"):
        design_mhe(VDP, bounds={"x1": (1, 0)})
    with pytest.raises(PreconditionError, match="initial estimate is outside the bounds: x1 = -1"):
        design_mhe(VDP, bounds={"x1": (0, None)}, xhat0=[-1.0, 0.0])
    tank = nlobs.System(states=["h"], f=["1 - sqrt(h)"], outputs=["y"], h=["h"])
    with pytest.raises(PreconditionError, match=r"Jacobian is not finite at the bound h = 0.*h >= 1e-06"):
        design_mhe(tank, bounds={"h": (0, None)}, xhat0=[1.0])
    assert design_mhe(VDP).needs_mx and not design_ekf(VDP, Q=np.eye(2), R=[[1.0]]).needs_mx
