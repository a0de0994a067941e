"""Per-output sample periods (issue 21 §3): a slow position sensor beside a fast velocity sensor."""

from __future__ import annotations

import json

import numpy as np
import pytest

import nlobs
from nlobs import System
from nlobs.cli import main
from nlobs.simulate import Noise, Sampling

# a cart: position p from a GPS, velocity v + bias b from a wheel encoder
CART = System(states=["p", "v", "b"], inputs=["a"], outputs=["gps", "wheel"], f=["v", "a - 0.1*v", "0"],
              h=["p", "v + b"], name="cart")
CLOCKS = Sampling({"gps": 1.0, "wheel": 0.01})


def _ekf():
    return nlobs.design_ekf(CART, R=np.diag([1.0, 0.01]), Q=np.diag([1e-4, 1e-3, 1e-6]), xhat0=[5.0, 0.0, 0.0])


def _run(sampling=CLOCKS, t_final=30.0):
    return nlobs.simulate(CART, {"ekf": _ekf()}, t_final=t_final, dt=0.01, x0=[0.0, 1.0, 0.3], inputs={"a": 0.2},
                          noise=Noise.per_output({"gps": 1.0, "wheel": 0.1}), sampling=sampling, seed=2)


def test_each_output_keeps_its_own_clock():
    run = _run()
    k = np.arange(run.t.size)
    gps, meas = run.y[:, 0], run.info["measured"]
    np.testing.assert_array_equal(meas[:, 0], k % 100 == 0)   # the GPS at whole seconds only
    assert meas[:, 1].all()                                    # the wheel at every step
    for j in range(1, 30):                                     # held between its samples
        np.testing.assert_array_equal(gps[100 * (j - 1):100 * j], gps[100 * (j - 1)])
    # the position's variance grows between GPS samples and drops at each: the EKF updates p only then
    P = run.observers["ekf"].std[:, 0] ** 2
    for j in range(5, 30):
        assert P[100 * j - 1] > P[100 * j - 50] > P[100 * (j - 1)]
        assert P[100 * j] < P[100 * j - 1]


def test_the_csv_round_trip_gives_the_same_estimates_through_the_recording_runner(tmp_path):
    # two code paths: the joint compiled step with per-output flags, and the interval runner of estimate() reading
    # NaN cells as "not measured" (accepted without on_missing='skip': each output is on a clock). The input is
    # constant, so the recording's hold is exact and the two agree to round-off.
    run = _run()
    path = tmp_path / "cart.csv"
    run.to_csv(path, every=CLOCKS.every(0.01))
    rec = nlobs.Recording.from_csv(path, CART)
    assert np.isnan(rec.y[:, 0]).sum() == 3001 - 31 and not np.isnan(rec.y[:, 1]).any()
    est = nlobs.estimate({"ekf": _ekf()}, rec)
    np.testing.assert_allclose(est.observers["ekf"].xhat, run.observers["ekf"].xhat, rtol=0, atol=1e-9)


def test_fewer_gps_samples_cost_accuracy_but_the_filter_still_converges():
    slow, fast = _run(t_final=60.0), _run(Sampling(0.01), t_final=60.0)
    m_slow, m_fast = slow.metrics("ekf"), fast.metrics("ekf")
    assert m_slow.final_error < 0.3 and m_fast.rms_error < m_slow.rms_error


def test_irregular_missing_values_still_need_skip():
    run = _run(Sampling(0.01), t_final=2.0)
    y = run.y.copy()
    y[[17, 18, 60], 0] = np.nan                       # dropouts, not a clock
    rec = nlobs.Recording.from_arrays(CART, run.t, y, run.u)
    with pytest.raises(nlobs.DataError, match="output 'gps' is missing"):
        nlobs.estimate({"ekf": _ekf()}, rec)
    nlobs.estimate({"ekf": _ekf()}, rec, on_missing="skip")


MODEL = """
name = "cart"
states = ["p", "v", "b"]
inputs = ["a"]
outputs = ["gps", "wheel"]
[dynamics]
p = "v"
v = "a - 0.1*v"
b = "0"
[output]
gps = "p"
wheel = "v + b"
[simulation]
t_final = 20.0
dt = 0.01
x0 = [0.0, 1.0, 0.3]
inputs = { a = "0.2" }
noise = { gps = 1.0, wheel = 0.1 }
sample_period = { gps = 1.0, wheel = 0.01 }
seed = 2
[observers.ekf]
kind = "ekf"
xhat0 = [5.0, 0.0, 0.0]
R = [[1.0, 0.0], [0.0, 0.01]]
Q = [[1e-4, 0.0, 0.0], [0.0, 1e-3, 0.0], [0.0, 0.0, 1e-6]]
"""


def test_the_model_file_and_the_command_line(tmp_path, capsys):
    model = tmp_path / "cart.toml"
    model.write_text(MODEL, encoding="utf-8")
    out = tmp_path / "run.csv"
    assert main(["simulate", str(model), "--json", "--output", str(out)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["observers"]["ekf"]["final_error"] < 1.2   # 3 × the filter's final σ of p (0.39 m; GPS σ 1 m at 1 Hz)
    assert main(["estimate", str(model), str(out), "--observer", "ekf", "--json"]) == 0   # GPS NaN cells: no --skip-missing
    e = json.loads(capsys.readouterr().out)
    assert e["observers"]["ekf"]["final_estimate"] == pytest.approx(d["observers"]["ekf"]["final_estimate"], abs=1e-9)
    for bad, msg in (('{ gps = 1.0 }', "no period for wheel"), ('{ gps = 1.0, wheel = 0.01, z = 1 }', "`z` is not an output")):
        model.write_text(MODEL.replace("{ gps = 1.0, wheel = 0.01 }", bad), encoding="utf-8")
        assert main(["simulate", str(model)]) == 1
        assert msg in capsys.readouterr().err


IMU = """
name = "imu1d"
states = ["p", "v"]
inputs = ["a"]
outputs = ["gps"]
[dynamics]
p = "v"
v = "a"
[output]
gps = "p"
[simulation]
t_final = 2.0
dt = 0.005
x0 = [0.0, 1.0]
sample_period = 0.02
noise = { gps = 0.1 }
seed = 3
[observers.ekf]
kind = "ekf"
Q = [[1e-4, 0], [0, 1e-2]]
R = [[0.01]]
xhat0 = [0.5, 0.0]
"""


def test_simulate_output_keeps_every_input_sample_and_estimate_replays_the_run(tmp_path, capsys):
    """Issue 44, item 3: a 200 Hz input beside a 50 Hz sensor. The recording written by simulate --output has every
    input sample (the input CSV's 401 rows, read back exactly), the sensor in its own 101 rows only, and estimate on it
    drives the EKF with the run's inputs: its estimates equal the run's at every row (to rounding)."""
    model, inp, out, est = (tmp_path / n for n in ("imu.toml", "imu_in.csv", "run.csv", "est.csv"))
    model.write_text(IMU, encoding="utf-8")
    t = np.round(np.arange(401) * 0.005, 12)
    a = np.sin(7 * t) + np.cos(3 * t)
    inp.write_text("t,a\n" + "".join(f"{float(ti)!r},{float(ai)!r}\n" for ti, ai in zip(t, a)), encoding="utf-8")
    assert main(["simulate", str(model), "--input", str(inp), "--output", str(out), "--json"]) == 0
    rec = np.genfromtxt(out, delimiter=",", names=True)
    assert rec.size == 401 and np.array_equal(rec["a"], a) and np.allclose(rec["t"], t, rtol=0, atol=1e-12)
    assert np.isfinite(rec["gps"]).sum() == 101 and np.all(np.isfinite(rec["gps"][::4]))
    capsys.readouterr()
    assert main(["estimate", str(model), str(out), "--observer", "ekf", "--output", str(est), "--json"]) == 0
    back = np.genfromtxt(est, delimiter=",", names=True)
    for s in ("p", "v"):
        assert np.max(np.abs(back[f"ekf{s}"] - rec[f"ekf{s}"])) < 1e-9


def test_run_to_csv_writes_a_single_rate_run_at_its_own_samples(tmp_path):
    """Issue 44, item 3 (the Python side): `Run.to_csv(path)` without `every` on a run sampled every 0.02 s on a
    0.005 s grid writes the sensor in its 101 sample rows only, not its held value in all 401 rows (which estimate
    read back as 401 measurements, four copies of each), and every input sample; estimate on the file replays the
    run's EKF."""
    mf = nlobs.loads_model(IMU.replace("dt = 0.005", 'dt = 0.005\ninputs = { a = "sin(7*t) + cos(3*t)" }'),
                           path="imu.toml")
    run = nlobs.simulate(mf)
    path = tmp_path / "run.csv"
    run.to_csv(path)
    rec = np.genfromtxt(path, delimiter=",", names=True)
    assert rec.size == 401 and np.isfinite(rec["gps"]).sum() == 101 and np.all(np.isfinite(rec["gps"][::4]))
    back = nlobs.estimate(mf, nlobs.Recording.from_csv(path, mf.system), hold="linear")
    # the file's inputs are the expression's samples, linearly interpolated for the RK4 midpoints the run evaluated:
    # 2e-5 off (the held outputs as 401 measurements: 0.53)
    assert np.max(np.abs(back.observers["ekf"].xhat[::4] - run.observers["ekf"].xhat[::4])) < 1e-4
