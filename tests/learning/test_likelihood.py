"""Innovations likelihood and learning from it (issue 22, item 2).

References are independent: the prediction-error decomposition computed here by a NumPy Kalman filter on a
linear-Gaussian model (where the EKF and UKF are that filter); central finite differences of the likelihood
(here only) for the gradient; a plant simulated here by Euler-Maruyama with known parameters and noise.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import nlobs
from nlobs.cli import main
from nlobs.errors import PreconditionError
from nlobs.learning import fit_likelihood, log_likelihood
from nlobs.estimation import Recording

A = np.array([[0.0, 1.0], [-2.0, -0.5]])
B = np.array([0.0, 1.0])
C = np.array([[1.0, 0.0]])
LINEAR = nlobs.System(states=["x1", "x2"], inputs=["u"], f=["x2", "-k*x1 - 0.5*x2 + u"], outputs=["y"], h=["x1"],
                      params={"k": 2.0})
Q = np.diag([1e-3, 1e-2])
R = np.array([[0.01]])


def _numpy_loglik(t, u, y, qs: float, rs: float, k: float = 2.0, terms: bool = False):
    """Σ −½(log det 2πS + νᵀS⁻¹ν) of the Kalman filter with RK4 (one step per interval) of the mean and of
    Ṗ = AP + PAᵀ + Q; the first sample is predicted by the prior (x̂0 = (0.1, 0), P0 = I). With `terms`, the
    innovations and their covariances."""
    h = t[1] - t[0]
    A = np.array([[0.0, 1.0], [-k, -0.5]])
    nus, Ss = [], []

    def rk4(fn, x):
        k1 = fn(x)
        k2 = fn(x + h / 2 * k1)
        k3 = fn(x + h / 2 * k2)
        k4 = fn(x + h * k3)
        return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    x, P, total = np.array([0.1, 0.0]), np.eye(2), 0.0
    for k in range(t.size):
        if k:
            uk = u[k - 1]
            x = rk4(lambda v: A @ v + B * uk, x)
            P = rk4(lambda M: A @ M + M @ A.T + qs * Q, P)
        if np.isnan(y[k]):
            continue
        S = C @ P @ C.T + rs * R
        nu = y[k] - C @ x
        total += -0.5 * (np.log(np.linalg.det(2 * np.pi * S)) + nu @ np.linalg.solve(S, nu))
        nus.append(nu)
        Ss.append(S)
        K = P @ C.T @ np.linalg.inv(S)
        x, P = x + K @ nu, P - K @ S @ K.T
    return (np.array(nus), np.array(Ss)) if terms else total


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_linear_gaussian_loglik_matches_the_kalman_filter(kind):
    rng = np.random.default_rng(1)
    N = 300
    t = np.arange(N) * 0.05
    u = np.sin(t)
    y = np.sin(2 * t) + 0.1 * rng.standard_normal(N)
    y[[10, 200]] = np.nan
    rec = Recording.from_arrays(LINEAR, t, y[:, None], u[:, None])
    make = nlobs.design_ekf if kind == "ekf" else nlobs.design_ukf
    d = make(LINEAR, Q=Q, R=R, P0=np.eye(2), xhat0=[0.1, 0.0])
    ll, g = log_likelihood(d, rec, on_missing="skip")
    assert g.shape == (0,)
    assert abs(ll - _numpy_loglik(t, u, y, 1.0, 1.0)) < 1e-9 * abs(ll)
    ll2, g2 = log_likelihood(d, rec, learn_noise=True, values={"log_Q_scale": np.log(3.0), "log_R_scale": np.log(0.5)},
                             on_missing="skip")
    assert abs(ll2 - _numpy_loglik(t, u, y, 3.0, 0.5)) < 1e-9 * abs(ll2)
    assert g2.shape == (2,)


def test_fisher_information_matches_the_innovation_sensitivities():
    """𝓘 = Σ ∂νᵀS⁻¹∂ν + ½ tr(S⁻¹∂S S⁻¹∂S), with ∂ν, ∂S from central differences of the NumPy filter (here only)."""
    rng = np.random.default_rng(2)
    N = 400
    t = np.arange(N) * 0.05
    u = np.sin(t)
    y = np.sin(2 * t) + 0.1 * rng.standard_normal(N)
    rec = Recording.from_arrays(LINEAR, t, y[:, None], u[:, None])
    d = nlobs.design_ekf(LINEAR.with_params(k=1.6), Q=Q, R=R, P0=np.eye(2), xhat0=[0.1, 0.0])
    fit = fit_likelihood(d, rec, ["k"], learn_noise=True)
    th = fit.estimate
    info = np.array(fit.info["information"])

    def terms(v):
        return _numpy_loglik(t, u, y, np.exp(v[1]), np.exp(v[2]), k=v[0], terms=True)

    nu0, S0 = terms(th)
    dnu, dS = [], []
    for i in range(3):
        e = np.zeros(3)
        e[i] = 1e-6
        (np_, Sp), (nm, Sm) = terms(th + e), terms(th - e)
        dnu.append((np_ - nm) / 2e-6)
        dS.append((Sp - Sm) / 2e-6)
    ref = np.zeros((3, 3))
    for k in range(N):
        Si = np.linalg.inv(S0[k])
        for i in range(3):
            for j in range(3):
                ref[i, j] += dnu[i][k] @ Si @ dnu[j][k] + 0.5 * np.trace(Si @ dS[i][k] @ Si @ dS[j][k])
    assert np.allclose(info, ref, rtol=1e-5, atol=1e-6 * np.abs(ref).max())
    assert np.allclose(fit.std, np.sqrt(np.diag(np.linalg.inv(ref))), rtol=1e-5)


def _pendulum(seed: int, N: int = 2000, a1: float = 6.0, a2: float = 0.3, sq: float = 0.1, sr: float = 0.05):
    """th' = om, om' = −a1 sin th − a2 om + u + σ_q ẇ (10 steps per sample), y = th + σ_r v."""
    rng = np.random.default_rng(seed)
    dt, sub = 0.02, 10
    h = dt / sub
    t = np.arange(N) * dt
    u = 0.5 * np.sin(0.7 * t)
    x = np.array([1.2, 0.0])
    X = np.empty((N, 2))
    def f(v, uk):
        return np.array([v[1], -a1 * np.sin(v[0]) - a2 * v[1] + uk])

    for k in range(N):
        X[k] = x
        for _ in range(sub):  # RK4 of the drift, then the Wiener increment (Euler alone damps by about h·a1 less)
            k1 = f(x, u[k])
            k2 = f(x + h / 2 * k1, u[k])
            k3 = f(x + h / 2 * k2, u[k])
            k4 = f(x + h * k3, u[k])
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            x[1] += sq * np.sqrt(h) * rng.standard_normal()
    y = X[:, :1] + sr * rng.standard_normal((N, 1))
    system = nlobs.System(states=["th", "om"], inputs=["u"], f=["om", "-a1*sin(th) - a2*om + u"], outputs=["y"],
                          h=["th"], params={"a1": a1, "a2": a2})
    return system, Recording.from_arrays(system, t, y, u[:, None], X)


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_gradient_matches_central_differences(kind):
    system, rec = _pendulum(0, N=400)
    make = nlobs.design_ekf if kind == "ekf" else nlobs.design_ukf
    d = make(system.with_params(a1=5.0, a2=0.4), Q=np.diag([1e-6, 0.01]), R=[[0.0025]], xhat0=[1.0, 0.0])
    names = ["a1", "a2", "log_Q_scale", "log_R_scale"]
    at = {"a1": 5.0, "a2": 0.4, "log_Q_scale": 0.3, "log_R_scale": -0.2}
    ll, g = log_likelihood(d, rec, params=["a1", "a2"], learn_noise=True, values=at)
    for i, name in enumerate(names):
        eps = 1e-5
        lp, _ = log_likelihood(d, rec, params=["a1", "a2"], learn_noise=True, values={**at, name: at[name] + eps})
        lm, _ = log_likelihood(d, rec, params=["a1", "a2"], learn_noise=True, values={**at, name: at[name] - eps})
        fd = (lp - lm) / (2 * eps)
        assert abs(g[i] - fd) < 1e-5 * max(1.0, abs(fd)), (name, g[i], fd)


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_fit_started_20_percent_off_recovers_the_parameter(kind):
    system, rec = _pendulum(11)
    make = nlobs.design_ekf if kind == "ekf" else nlobs.design_ukf
    start = system.with_params(a1=6.0 * 0.8)
    d = make(start, Q=np.diag([1e-8, 0.1**2]), R=[[0.05**2]], xhat0=[1.0, 0.0])
    fit = fit_likelihood(d, rec, ["a1"], learn_noise=True)
    assert fit.success
    a1, s = fit.parameters["a1"]["estimate"], fit.parameters["a1"]["std"]
    assert abs(a1 - 6.0) < 3 * s and s < 0.05 * 6.0, (a1, s)
    assert fit.loglik > fit.loglik_initial
    for key in ("Q", "R"):  # the true noise: scalings of 1 within ±3σ (log scale)
        assert abs(fit.noise[key]["log_scale"]) < 3 * fit.noise[key]["log_std"], (key, fit.noise[key])
    assert fit.system.params["a1"] == pytest.approx(a1)


def test_refuses_observers_without_a_likelihood():
    system, rec = _pendulum(0, N=50)
    with pytest.raises(PreconditionError, match="supported: the continuous-discrete kinds ekf, ukf"):
        log_likelihood(nlobs.design_ekf(system, Q=np.eye(2), R=[[1.0]], mode="continuous"), rec)
    with pytest.raises(PreconditionError, match="supported: the continuous-discrete kinds ekf, ukf"):
        fit_likelihood(nlobs.design_high_gain(system, theta=5.0), rec, ["a1"])
    with pytest.raises(nlobs.errors.ModelError, match="'b' is not a parameter"):
        fit_likelihood(nlobs.design_ekf(system, Q=np.eye(2), R=[[1.0]]), rec, ["b"])
    t = np.r_[np.arange(50) * 0.1, 200 + np.arange(50) * 0.1]  # a gap the filter crosses in 235 sub-steps
    gap = Recording.from_arrays(LINEAR, t, np.cos(t)[:, None], np.zeros((100, 1)))
    with pytest.raises(nlobs.errors.DataError, match="from t = 4.9 to 200 .* split the recording at long gaps"):
        log_likelihood(nlobs.design_ekf(LINEAR, Q=Q, R=R), gap, params=["k"])


MODEL = '''name = "pend"
states = ["th", "om"]
inputs = ["u"]
outputs = ["y"]
[parameters]
a1 = 4.8
a2 = 0.3
[dynamics]
th = "om"
om = "-a1*sin(th) - a2*om + u"
[output]
y = "th"
[observers.filter]
kind = "ekf"
Q = [[1e-8, 0.0], [0.0, 0.01]]
R = [[0.0025]]
xhat0 = [1.0, 0.0]
[observers.hg]
kind = "high_gain"
theta = 5.0
'''


def test_cli_fit_likelihood_json(tmp_path, capsys):
    system, rec = _pendulum(5)
    model = tmp_path / "pend.toml"
    model.write_text(MODEL)
    data = tmp_path / "rec.csv"
    Recording.from_arrays(system, rec.t, rec.y, rec.u)  # the same columns as estimate reads
    np.savetxt(data, np.column_stack([rec.t, rec.u, rec.y]), delimiter=",", header="t,u,y", comments="")
    assert main(["fit", str(model), str(data), "--param", "a1", "--method", "likelihood", "--observer", "ekf",
                 "--learn-noise", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "likelihood" and set(out["parameters"]) == {"a1"}
    p = out["parameters"]["a1"]
    assert abs(p["estimate"] - 6.0) < 3 * p["std"]
    assert set(out["noise_scaling"]) == {"Q", "R"} and "Fisher information" in out["std_from"]
    api = fit_likelihood(nlobs.design_ekf(system.with_params(a1=4.8), Q=np.diag([1e-8, 0.01]), R=[[0.0025]],
                                          xhat0=[1.0, 0.0]), Recording.from_csv(data, system), ["a1"], learn_noise=True)
    assert p["estimate"] == pytest.approx(api.estimate[0], rel=1e-9)
    # the default method is still the simulation-error fit
    assert main(["fit", str(model), str(data), "--param", "a1", "--x0", "1.2,0", "--json"]) == 0
    assert "method" not in json.loads(capsys.readouterr().out)
    for argv, msg in ((["--method", "likelihood"], "needs --observer"),
                      (["--method", "likelihood", "--observer", "hg"], "kind 'high_gain'"),
                      (["--method", "likelihood", "--observer", "filter", "--fit-x0", "th"], "--fit-x0: not used"),
                      (["--observer", "filter"], "--observer is an option of --method likelihood")):
        assert main(["fit", str(model), str(data), "--param", "a1", *argv]) == 1
        err = capsys.readouterr().err
        assert msg in err and len(err.strip().splitlines()) == 1, err


def test_a_filter_that_blows_up_raises_with_its_sample_instead_of_returning_minus_infinity():
    # at k = 50 one RK4 step per 1 s sample multiplies the unmeasured x2 (and its variance) by ~2e5: the filter's state
    # overflows within a few samples; log_likelihood returned (-inf, NaN) without saying where
    m = nlobs.System(states=["x1", "x2"], f=["x2 - x1", "-k*x2"], outputs=["y"], h=["x1"], params={"k": 0.5})
    t = np.arange(200.0)
    rec = Recording.from_arrays(m, t, np.exp(-0.5 * t)[:, None] + 0.01)
    d = nlobs.design_ekf(m, Q=np.eye(2) * 1e-4, R=[[1e-4]], P0=np.eye(2), xhat0=[1.0, 0.5])
    assert np.isfinite(log_likelihood(d, rec, params=["k"], max_step=1.0)[0])
    with pytest.raises(nlobs.errors.FiniteEscapeError, match=r"non-finite at sample \d+ \(t = \d+"):
        log_likelihood(d, rec, params=["k"], values={"k": 50.0}, max_step=1.0)
