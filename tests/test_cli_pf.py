"""The particle filter from a model file through the command line: simulate, then estimate on the written samples."""

from __future__ import annotations

import json

import numpy as np

from nlobs.cli import main

MODEL = """
name = "bimodal"
states = ["x1", "x2"]
outputs = ["y"]
[dynamics]
x1 = "x2"
x2 = "-x1 + 0.6"
[output]
y = "x1**2"
[simulation]
t_final = 5.0
dt = 0.01
x0 = [1.5, 0.0]
noise = { y = 0.05 }
sample_period = 0.05
seed = 1
[observers.pf]
kind = "pf"
xhat0 = [-1.0, 0.0]
Q = [[0.01, 0.0], [0.0, 0.01]]
R = [[0.0025]]
P0 = [[4.0, 0.0], [0.0, 4.0]]
particles = 3000
seed = 4
"""


def test_pf_from_a_model_file_simulate_then_estimate(tmp_path, capsys):
    path = tmp_path / "bimodal.toml"
    path.write_text(MODEL)
    csv = tmp_path / "sim.csv"
    assert main(["simulate", str(path), "--output", str(csv), "--json"]) == 0
    sim = json.loads(capsys.readouterr().out)
    # the sign of x1 is found from the dynamics within the 5 s (started on the mirror side, x̂1(0) = -1)
    assert sim["observers"]["pf"]["final_error"] < 0.1
    assert main(["estimate", str(path), str(csv), "--observer", "pf", "--json"]) == 0
    est = json.loads(capsys.readouterr().out)
    data = np.genfromtxt(csv, delimiter=",", names=True)
    # the same samples and the same seed: the same particles, so the same estimates to the last bit
    np.testing.assert_array_equal([data["pfx1"][-1], data["pfx2"][-1]], est["observers"]["pf"]["final_estimate"])


def test_simulate_reports_the_effective_sample_size(tmp_path):
    import nlobs

    path = tmp_path / "bimodal.toml"
    path.write_text(MODEL)
    mf = nlobs.load_model(path)
    run = nlobs.simulate(mf.system, {"pf": mf.observers["pf"]}, t_final=1.0, dt=0.01, x0=[1.5, 0.0],
                         noise=nlobs.Noise.gaussian(0.05), sampling=nlobs.Sampling(0.05), seed=1)
    info = run.info["particles"]["pf"]
    trace = run.observers["pf"]
    ess = trace.z[:, trace.z_names.index("ess")]
    assert info["samples"] == 21 and 1 <= info["min_ess"] <= 3000 and info["min_ess"] == ess.min()
    assert np.all(np.isfinite(trace.std))  # ±σ from the particle covariance
