"""``nlobs export`` with measurement delays: the model file's delay (or --delay) writes the fusion filter, and the
example program run on the CSV that ``nlobs simulate --output`` writes (stamped at arrival) equals ``nlobs estimate``.

Both sides get --max-step 0.002 (rows 10 ms apart or more, the cart EKF's rates below 1/s): ``estimate``'s rule
h·ρ <= 1 adds no RK4 step, so both take ceil(gap / max_step) steps per gap between knots.
"""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from nlobs.cli import main

CC = shutil.which("gcc") or shutil.which("cc")

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
t_final = 10.0
dt = 0.01
x0 = [0.0, 1.0, 0.3]
inputs = { a = "sin(0.5*t)" }
noise = { gps = 0.5, wheel = 0.1 }
sample_period = { gps = 0.25, wheel = 0.1 }
delay = { gps = 0.15, wheel = 0.05 }
seed = 3
[observers.ekf]
kind = "ekf"
xhat0 = [5.0, 0.0, 0.0]
R = [[0.25, 0.0], [0.0, 0.01]]
Q = [[1e-4, 0.0, 0.0], [0.0, 1e-3, 0.0], [0.0, 0.0, 1e-6]]
"""


def _columns(path, names):
    data = np.genfromtxt(path, delimiter=",", names=True)
    return np.column_stack([data[n] for n in names])


@pytest.mark.skipif(CC is None, reason="no C compiler (gcc/cc) on PATH: the exported C cannot be compiled here")
def test_export_with_the_files_delay_runs_on_the_simulated_csv_like_estimate(tmp_path, capsys):
    model = tmp_path / "cart.toml"
    model.write_text(MODEL, encoding="utf-8")
    data, est, out = tmp_path / "x.csv", tmp_path / "est.csv", tmp_path / "c"
    assert main(["simulate", str(model), "--output", str(data)]) == 0
    assert main(["export", str(model), "--observer", "ekf", "--c", str(out), "--max-step", "0.002"]) == 0
    text = capsys.readouterr().out
    assert "delays gps 0.15 s, wheel 0.05 s" in text and "rows at least 0.01 s apart" in text   # the file's delay and dt
    header = (out / "cart_ekf.h").read_text()
    assert "#define CART_EKF_MAX_DELAY 0.15" in header and "#define CART_EKF_MIN_INTERVAL 0.01" in header
    exe = tmp_path / "cart_ekf"
    subprocess.run([CC, "-std=c99", "-O2", "-o", str(exe), str(out / "cart_ekf.c"), str(out / "main.c"), "-lm"],
                   check=True, capture_output=True)
    with open(data) as f:   # the simulated CSV as it is: header, t, a, gps, wheel, then states and estimates (ignored)
        proc = subprocess.run([str(exe)], stdin=f, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    got = np.loadtxt(proc.stdout.splitlines()[1:], delimiter=",")
    assert main(["estimate", str(model), str(data), "--observer", "ekf", "--skip-missing", "--max-step", "0.002",
                 "--output", str(est)]) == 0
    ref = _columns(est, ["t", "ekfp", "ekfv", "ekfb"])
    rows = _columns(data, ["t", "gps", "wheel"])
    assert got.shape == ref.shape and np.isnan(rows[:, 1:]).any()          # rows where only one output arrived
    np.testing.assert_array_equal(got[:, 0], ref[:, 0])
    assert np.abs(got[:, 1:] - ref[:, 1:]).max() <= 1e-12
    # the delays made a difference: the same export without them (the rows taken as current) is another filter
    assert main(["export", str(model), "--observer", "ekf", "--c", str(tmp_path / "plain"), "--max-step", "0.002",
                 "--no-delay"]) == 0
    assert "fusion" not in capsys.readouterr().out and "fusion" not in (tmp_path / "plain" / "cart_ekf.h").read_text()
    subprocess.run([CC, "-std=c99", "-O2", "-o", str(tmp_path / "plain_ekf"), str(tmp_path / "plain" / "cart_ekf.c"),
                    str(tmp_path / "plain" / "main.c"), "-lm"], check=True, capture_output=True)
    with open(data) as f:
        plain = subprocess.run([str(tmp_path / "plain_ekf")], stdin=f, capture_output=True, text=True, check=True)
    assert np.abs(np.loadtxt(plain.stdout.splitlines()[1:], delimiter=",")[:, 1:] - got[:, 1:]).max() > 1e-2


def test_delay_options_and_their_errors(tmp_path, capsys):
    model = tmp_path / "cart.toml"
    model.write_text(MODEL, encoding="utf-8")
    out = str(tmp_path / "c")
    assert main(["export", str(model), "--observer", "ekf", "--c", out, "--delay", "gps=0.3", "--min-interval", "0.05"]) == 0
    text = capsys.readouterr().out
    assert "delays gps 0.3 s;" in text and "rows at least 0.05 s apart" in text   # --delay replaces the file's
    assert main(["export", str(model), "--observer", "ekf", "--c", out, "--delay", "gps=0.3,wheel=0.1", "--history",
                 "40"]) == 0
    assert "history of 40 knots" in capsys.readouterr().out
    for argv, message in (
        (["--delay", "z=0.1"], "--delay: 'z' is not one of gps, wheel"),
        (["--delay", "gps=-1"], "--delay gps: a delay must be >= 0 seconds"),
        (["--delay", "gps=0.1", "--no-delay"], "--delay and --no-delay: give one of them"),
        (["--no-delay", "--min-interval", "0.01"], "--min-interval and --history size the delay history"),
    ):
        assert main(["export", str(model), "--observer", "ekf", "--c", out, *argv]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err, (argv, err)
    model.write_text(MODEL.replace("dt = 0.01\n", ""), encoding="utf-8")
    assert main(["export", str(model), "--observer", "ekf", "--c", str(tmp_path / "d")]) == 1
    assert "give --min-interval SECONDS" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()
