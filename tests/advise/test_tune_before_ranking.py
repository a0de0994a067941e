"""design --run tunes the Kalman family on the run's measurements before ranking (issue 42, item 2).

The data: a unicycle whose speed and turn rate are random walks of known intensity (Q_v = 0.01, Q_ω = 0.0025 per
second), drawn here in NumPy by Euler-Maruyama at 1 kHz; the model file declares only the output noise, so the
advisor's default Q must guess. Reference: the true intensities that drew the data."""

from __future__ import annotations

import numpy as np

import nlobs

MODEL = """
name = "uni"
states = ["x", "y", "theta", "v", "omega"]
outputs = ["gx", "gy", "gyro"]
[dynamics]
x = "v*cos(theta)"
y = "v*sin(theta)"
theta = "omega"
v = "0"
omega = "0"
[output]
gx = "x"
gy = "y"
gyro = "omega"
[simulation]
t_final = 60.0
dt = 0.02
x0 = [0.0, 0.0, 0.5, 2.0, 0.1]
noise = { gx = 0.5, gy = 0.5, gyro = 0.02 }
sample_period = { gx = 0.5, gy = 0.5, gyro = 0.02 }
"""
QV, QW = 0.01, 0.0025


def _recording(system):
    rng = np.random.default_rng(11)
    h, T = 1e-3, 60.0
    s = np.array([0.0, 0.0, 0.5, 2.0, 0.1])
    t_out = np.round(np.arange(0.0, T + 1e-9, 0.02), 10)
    rows, X = [], []
    k_out = 0
    for k in range(int(round(T / h)) + 1):
        t = k * h
        if k_out < t_out.size and abs(t - t_out[k_out]) < 1e-9:
            gps = abs(t / 0.5 - round(t / 0.5)) < 1e-9
            y = [s[0] + 0.5 * rng.standard_normal() if gps else np.nan,
                 s[1] + 0.5 * rng.standard_normal() if gps else np.nan, s[4] + 0.02 * rng.standard_normal()]
            rows.append(y)
            X.append(s.copy())
            k_out += 1
        f = np.array([s[3] * np.cos(s[2]), s[3] * np.sin(s[2]), s[4], 0.0, 0.0])
        s = s + h * f + np.sqrt(h) * np.array([0, 0, 0, np.sqrt(QV), np.sqrt(QW)]) * rng.standard_normal(5)
    return nlobs.Recording.from_arrays(system, t_out, np.array(rows), x=np.array(X))


def test_design_run_tunes_q_and_r_on_the_measurements_before_ranking(tmp_path):
    path = tmp_path / "uni.toml"
    path.write_text(MODEL, encoding="utf-8")
    mf = nlobs.load_model(str(path))
    rec = _recording(mf.system)
    plain = nlobs.advise(mf, recording=rec, kinds=["ekf"], run=True, tune=False, progress=False)
    tuned = nlobs.advise(mf, recording=rec, kinds=["ekf"], run=True, progress=False)
    assert any("tuned on the run's measurements" in n and "converged" in n for n in tuned.notes), tuned.notes
    Q = np.asarray(tuned.candidate("ekf").options["Q"], dtype=float)
    # the random walks' intensities, found from the data within a factor 3 (a 60 s record; their standard errors are
    # ~20-40 %); the default reads v and omega as constants (Q below 1e-4 of the truth)
    assert QV / 3 < Q[3, 3] < 3 * QV and QW / 3 < Q[4, 4] < 3 * QW, np.diag(Q)
    assert np.asarray(plain.candidate("ekf").options["Q"], dtype=float)[3, 3] < QV / 10
    rms = {k: next(s for s in a.scores if s.kind == "ekf").rms_error for k, a in (("plain", plain), ("tuned", tuned))}
    assert rms["tuned"] < 0.5 * rms["plain"], rms
