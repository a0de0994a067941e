"""Tuning Q, R (and P0) from a recording (issue 42, item 1).

References are independent of the code under test: the exact Kalman likelihood of a linear-Gaussian model computed
here in NumPy (the discretisation of the continuous-time model by Van Loan's matrix exponential, not RK4) and
maximised here by SciPy over the same log-variances; the RMS error of a filter computed here from nlobs.estimate's
estimates and the true states drawn here.
"""

from __future__ import annotations

import json
import math
import tomllib

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import minimize

import nlobs
from nlobs.cli import main
from nlobs.learning import tune
from nlobs.estimation import Recording

A_MAP = np.array([[1.0, 0.1], [-0.2, 0.9]])
MAP = nlobs.System(states=["x1", "x2"], f=["x1 + 0.1*x2", "-0.2*x1 + 0.9*x2"], outputs=["y"], h=["x1"],
                   time="discrete", sample_time=0.1)
A_CT = np.array([[0.0, 1.0], [-1.0, -0.4]])
LTI = nlobs.System(states=["x1", "x2"], f=["x2", "-x1 - 0.4*x2"], outputs=["y1", "y2"], h=["x1", "x1 + x2"])


def _kalman_loglik(F, Qd, H, r, y, x0, P0):
    """Σ log p(y_k | y_0..k-1) of the Kalman filter x_{k+1} = F x_k + w (cov Qd), y = Hx + v (diagonal cov r) for two
    states, in plain floats, the outputs of a sample processed one at a time (sequential updates: the same joint
    likelihood as a joint update with diagonal R); the first sample is updated from the prior (x0, P0); NaN outputs
    are left out."""
    f11, f12, f21, f22 = (float(v) for v in np.ravel(F))
    q11, q12, q22 = float(Qd[0, 0]), float(Qd[0, 1]), float(Qd[1, 1])
    x1, x2 = (float(v) for v in x0)
    a, b, c = float(P0[0, 0]), float(P0[0, 1]), float(P0[1, 1])
    rows = [[(float(H[j, 0]), float(H[j, 1]), float(r[j]), float(v)) for j, v in enumerate(yk) if v == v] for yk in y]
    total, log2pi = 0.0, math.log(2 * math.pi)
    for k, row in enumerate(rows):
        if k:
            x1, x2 = f11 * x1 + f12 * x2, f21 * x1 + f22 * x2
            m11, m12, m21, m22 = f11 * a + f12 * b, f11 * b + f12 * c, f21 * a + f22 * b, f21 * b + f22 * c
            a, b, c = m11 * f11 + m12 * f12 + q11, m11 * f21 + m12 * f22 + q12, m21 * f21 + m22 * f22 + q22
        for h1, h2, rj, v in row:
            p1, p2 = a * h1 + b * h2, b * h1 + c * h2
            s = h1 * p1 + h2 * p2 + rj
            nu = v - (h1 * x1 + h2 * x2)
            total -= 0.5 * (log2pi + math.log(s) + nu * nu / s)
            k1, k2 = p1 / s, p2 / s
            x1, x2 = x1 + k1 * nu, x2 + k2 * nu
            a, b, c = a - k1 * p1, b - k1 * p2, c - k2 * p2
    return total


def _van_loan(A, Qc, dt):
    """F = e^{A dt} and Qd = ∫ e^{As} Qc e^{Aᵀs} ds over one interval (Van Loan 1978)."""
    n = A.shape[0]
    M = np.block([[-A, Qc], [np.zeros((n, n)), A.T]]) * dt
    E = expm(M)
    F = E[n:, n:].T
    return F, F @ E[:n, n:]


def _numpy_maximum(loglik, theta0):
    """SciPy's BFGS (gradient by its own finite differences) on −log p, from `theta0` (the true values)."""
    res = minimize(lambda th: -loglik(th), theta0, method="BFGS", options={"gtol": 1e-6})
    return res.x, -res.fun


def _map_recording(seed=0, N=2000, q=(1e-3, 4e-3), r=0.01):
    rng = np.random.default_rng(seed)
    x, y, X = np.zeros(2), [], []
    for _ in range(N):
        X.append(x.copy())
        y.append(x[0] + np.sqrt(r) * rng.standard_normal())
        x = A_MAP @ x + np.sqrt(q) * rng.standard_normal(2)
    return Recording.from_arrays(MAP, np.arange(N) * 0.1, np.array(y)[:, None]), np.array(X)


def test_on_a_map_the_tuned_variances_are_the_maximum_of_the_exact_kalman_likelihood():
    rec, _ = _map_recording()
    d = nlobs.design_ekf(MAP, Q=np.eye(2) * 1e-2, R=[[0.1]], P0=np.eye(2), xhat0=[0.0, 0.0])
    res = tune(d, rec)
    assert res.converged and res.objective == "likelihood"
    y, H = rec.y, np.array([[1.0, 0.0]])

    def ll(th):
        return _kalman_loglik(A_MAP, np.diag(np.exp(th[:2])), H, np.exp(th[2:]), y, np.zeros(2), np.eye(2))

    th_ref, ll_ref = _numpy_maximum(ll, np.log([1e-3, 4e-3, 0.01]))
    assert np.all(np.isfinite(res.std)) and np.all(res.std > 0)
    assert np.all(np.abs(res.log_variance - th_ref) < res.std), (res.log_variance, th_ref, res.std)
    assert abs(res.loglik - ll_ref) < 1e-6 * abs(ll_ref)
    assert abs(ll(res.log_variance) - res.loglik) < 1e-8 * abs(ll_ref)   # the same function at the same point
    assert res.nis_ok
    np.testing.assert_allclose(res.Q, np.diag(np.exp(res.log_variance[:2])))


def test_continuous_discrete_multirate_tuning_is_the_maximum_of_the_exact_kalman_likelihood():
    """A continuous-time LTI with process-noise intensity Qc, y1 every sample, y2 every 4th (a multi-rate recording)."""
    rng = np.random.default_rng(3)
    N, dt = 1500, 0.05
    Qc, Rt = np.diag([2e-3, 2e-2]), np.diag([4e-3, 1e-2])
    F, Qd = _van_loan(A_CT, Qc, dt)
    Lq = np.linalg.cholesky(Qd)
    H = np.array([[1.0, 0.0], [1.0, 1.0]])
    x, Y = np.array([0.5, 0.0]), []
    for _ in range(N):
        Y.append(H @ x + np.sqrt(np.diag(Rt)) * rng.standard_normal(2))
        x = F @ x + Lq @ rng.standard_normal(2)
    Y = np.array(Y)
    Y[np.arange(N) % 4 != 0, 1] = np.nan
    rec = Recording.from_arrays(LTI, np.arange(N) * dt, Y)
    d = nlobs.design_ekf(LTI, Q=np.diag([1e-2, 1e-2]), R=np.diag([1e-2, 1e-2]), P0=np.eye(2), xhat0=[0.0, 0.0])
    res = tune(d, rec)
    assert res.converged

    def ll(th):
        F_, Qd_ = _van_loan(A_CT, np.diag(np.exp(th[:2])), dt)
        return _kalman_loglik(F_, Qd_, H, np.exp(th[2:]), Y, np.zeros(2), np.eye(2))

    th_ref, ll_ref = _numpy_maximum(ll, np.log([2e-3, 2e-2, 4e-3, 1e-2]))
    assert np.all(np.abs(res.log_variance - th_ref) < res.std), (res.log_variance, th_ref, res.std)
    assert abs(res.loglik - ll_ref) < 1e-6 * abs(ll_ref)
    assert res.nis_ok and res.nis["dof"] == N + N // 4


def test_fix_r_keeps_the_declared_r_and_the_nis_check_catches_a_wrong_one():
    rec, _ = _map_recording(seed=1)
    good = tune(nlobs.design_ekf(MAP, Q=np.eye(2) * 1e-2, R=[[0.01]], P0=np.eye(2), xhat0=[0.0, 0.0]), rec, fix_r=True)
    assert good.names == ("Q[x1]", "Q[x2]") and np.array_equal(good.R, [[0.01]])
    assert good.nis_ok
    # R declared 100 times too large: no Q makes the innovations as large as the filter expects
    bad = tune(nlobs.design_ekf(MAP, Q=np.eye(2) * 1e-2, R=[[1.0]], P0=np.eye(2), xhat0=[0.0, 0.0]), rec, fix_r=True)
    assert not bad.nis_ok and bad.nis["mean"] < bad.nis["band"][0]
    assert "OUTSIDE" in bad.summary()


def test_apply_and_toml_give_the_tuned_design():
    rec, _ = _map_recording(seed=2, N=600)
    d = nlobs.design_ukf(MAP, Q=np.eye(2) * 1e-2, R=[[0.1]], P0=2 * np.eye(2), xhat0=[0.0, 0.0], alpha=0.5, beta=2.0)
    res = tune(d, rec, tune_p0=True)
    assert res.likelihood_kind == "ukf" and res.P0 is not None and len(res.names) == 5
    tuned = res.apply()
    assert tuned.method == "ukf" and tuned.certificate.values["alpha"] == 0.5
    np.testing.assert_array_equal(tuned.certificate.values["Q"], res.Q)
    np.testing.assert_array_equal(tuned.certificate.values["P0"], res.P0)
    table = tomllib.loads(res.toml("mine"))["observers"]["mine"]
    assert table["kind"] == "ukf" and np.allclose(table["R"], res.R, rtol=1e-15)
    sr = res.apply(nlobs.design_srukf(MAP, Q=np.eye(2), R=[[1.0]], P0=np.eye(2), xhat0=[0.0, 0.0]))
    assert sr.method == "srukf" and np.array_equal(sr.certificate.values["R"], res.R)
    kept = tune(d, rec, starts=1).apply()     # P0 not tuned: the design's own
    np.testing.assert_array_equal(kept.certificate.values["P0"], 2 * np.eye(2))
    pf = tune(nlobs.design_pf(MAP, Q=np.eye(2) * 1e-2, R=[[0.1]], P0=np.eye(2), xhat0=[0.0, 0.0], particles=200), rec)
    assert pf.likelihood_kind == "ekf" and any("particle filter" in n for n in pf.notes)
    tuned_pf = pf.apply()
    assert tuned_pf.method == "pf" and tuned_pf.particles == 200 and np.array_equal(tuned_pf.Q, pf.Q)


def test_truth_mode_reduces_the_rms_error_of_the_filter():
    rec, X = _map_recording(seed=4, N=800)
    d = nlobs.design_ekf(MAP, Q=np.eye(2) * 1.0, R=[[1e-4]], P0=np.eye(2), xhat0=[0.0, 0.0])
    res = tune(d, rec, truth=X)
    assert res.objective == "truth" and np.all(np.isnan(res.std))

    def rms(design):   # the filtered estimates of nlobs.estimate against the states drawn here, in units of √P0_ii
        est = nlobs.estimate(design, rec).observers
        xhat = next(iter(est.values())).xhat
        return float(np.sqrt(np.mean((xhat - X) ** 2)))

    assert abs(rms(d) - res.rms_start) < 1e-9 and abs(rms(res.apply()) - res.rms) < 1e-9
    true_noise = nlobs.design_ekf(MAP, Q=np.diag([1e-3, 4e-3]), R=[[0.01]], P0=np.eye(2), xhat0=[0.0, 0.0])
    assert res.rms < 0.9 * res.rms_start and res.rms <= rms(true_noise) * (1 + 1e-6)


def test_a_delayed_output_enters_the_likelihood_when_it_was_taken():
    """y2 arrives 3 samples late (stamped at arrival): the tuning equals the one on the samples at their times."""
    rng = np.random.default_rng(5)
    N, dt = 400, 0.05
    F, Qd = _van_loan(A_CT, np.diag([2e-3, 2e-2]), dt)
    H = np.array([[1.0, 0.0], [1.0, 1.0]])
    x, Y = np.array([0.5, 0.0]), []
    for _ in range(N):
        Y.append(H @ x + 0.05 * rng.standard_normal(2))
        x = F @ x + np.linalg.cholesky(Qd) @ rng.standard_normal(2)
    Y = np.array(Y)
    t = np.arange(N) * dt
    at_arrival = Y.copy()
    at_arrival[3:, 1], at_arrival[:3, 1] = Y[:-3, 1], np.nan
    d = nlobs.design_ekf(LTI, Q=np.diag([1e-2, 1e-2]), R=np.diag([1e-2, 1e-2]), P0=np.eye(2), xhat0=[0.0, 0.0])
    late = tune(d, Recording.from_arrays(LTI, t, at_arrival), delay={"y2": 3 * dt}, starts=1)
    cut = Y.copy()
    cut[N - 3:, 1] = np.nan     # the last three have not arrived by the end of the recording
    ref = tune(d, Recording.from_arrays(LTI, t, cut), on_missing="skip", starts=1)
    assert abs(late.loglik - ref.loglik) < 1e-9 * abs(ref.loglik)
    np.testing.assert_allclose(late.log_variance, ref.log_variance, atol=1e-6)
    assert any("taken" in n for n in late.notes)


def test_refuses_what_it_cannot_tune():
    rec, _ = _map_recording(N=50)
    with pytest.raises(nlobs.PreconditionError, match="no noise covariances"):
        tune(_luenberger(), rec)
    with pytest.raises(TypeError, match="observer design"):
        tune("ekf", rec)


def _luenberger():
    return nlobs.design_luenberger(nlobs.System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1"]),
                                   poles=[-1, -2])


MODEL = """
name = "osc"
states = ["x1", "x2"]
outputs = ["y"]
[dynamics]
x1 = "x2"
x2 = "-x1 - 0.4*x2"
[output]
y = "x1"
[simulation]
t_final = 40.0
dt = 0.05
x0 = [1.0, 0.0]
noise = { y = 0.05 }
process_noise = { x2 = 0.1 }
sample_period = 0.05
seed = 3
[observers.ekf]
kind = "ekf"
Q = [[0.1, 0.0], [0.0, 0.1]]
R = [[0.1]]
xhat0 = [0.0, 0.0]
"""


def test_cli_tune_json_and_toml_round_trip(tmp_path, capsys):
    model = tmp_path / "osc.toml"
    model.write_text(MODEL)
    data = tmp_path / "rec.csv"
    assert main(["simulate", str(model), "--output", str(data)]) == 0
    capsys.readouterr()
    assert main(["tune", str(model), str(data), "--observer", "ekf", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["converged"] and np.array(out["Q"]).shape == (2, 2) and np.array(out["R"]).shape == (1, 1)
    assert out["nis"]["ok"] and len(out["nis"]["band"]) == 2 and np.isfinite(out["loglik"])
    assert main(["tune", str(model), str(data), "--observer", "ekf", "--toml"]) == 0
    table = capsys.readouterr().out
    model.write_text(MODEL + "\n" + table)
    mf = nlobs.load_model(model)
    assert "ekf_tuned" in mf.observers
    np.testing.assert_allclose(np.asarray(mf.observers["ekf_tuned"].options["Q"], dtype=float), out["Q"], rtol=1e-12)
    assert main(["estimate", str(model), str(data), "--observer", "ekf_tuned", "--json"]) == 0
    capsys.readouterr()
    assert main(["tune", str(model), str(data), "--observer", "ekf"]) == 0
    text = capsys.readouterr().out
    assert "converged" in text and "NIS" in text and "Q[x2]" in text
    # nlobs.tune on paths, a file without observers: the advisor's EKF is the start
    bare = tmp_path / "bare.toml"
    bare.write_text(MODEL.split("[observers.ekf]")[0])
    res = nlobs.tune(str(bare), str(data), observer="ekf")
    assert res.kind == "ekf" and res.converged and res.nis_ok
    # the recording's own true states as the reference trajectory (simulate --output writes them)
    assert main(["tune", str(model), str(data), "--observer", "ekf", "--truth", str(data), "--json"]) in (0, 1)
    out = json.loads(capsys.readouterr().out)
    assert out["objective"] == "truth" and out["rms"] < out["rms_start"]


def test_a_variance_the_data_cannot_see_is_reported_undetermined():
    """x2 never reaches the output: log p does not depend on Q[x2] at all, so no value of it is an estimate."""
    hidden = nlobs.System(states=["x1", "x2"], f=["0.9*x1", "0.5*x2"], outputs=["y"], h=["x1"], time="discrete",
                          sample_time=0.1)
    rng = np.random.default_rng(7)
    x, y = 0.0, []
    for _ in range(1000):
        y.append(x + 0.1 * rng.standard_normal())
        x = 0.9 * x + 0.05 * rng.standard_normal()
    rec = Recording.from_arrays(hidden, np.arange(1000) * 0.1, np.array(y)[:, None])
    res = tune(nlobs.design_ekf(hidden, Q=np.eye(2) * 1e-2, R=[[0.1]], P0=np.eye(2), xhat0=[0.0, 0.0]), rec)
    assert res.converged and res.info["undetermined"] == ["Q[x2]"]
    assert res.std[1] == np.inf and np.all(np.isfinite(res.std[[0, 2]]))
    assert "undetermined by the data" in res.summary() and "Q[x2]" in res.message
