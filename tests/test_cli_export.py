"""``nlobs export MODEL --observer NAME --c DIR``: the files, the summary, the errors; the C runs like estimate."""

from __future__ import annotations

import shutil
import subprocess
from importlib import resources

import numpy as np
import pytest

import nlobs
from nlobs.cli import main
from nlobs.design import design_from_config

PEND = str(resources.files("nlobs.models").joinpath("pendulum.toml"))
CC = shutil.which("gcc") or shutil.which("cc")


def test_export_writes_the_three_files_and_says_how_to_build(tmp_path, capsys):
    out = tmp_path / "c"
    assert main(["export", PEND, "--observer", "ekf", "--c", str(out), "--max-step", "0.002"]) == 0
    text = capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["main.c", "pendulum_ekf.c", "pendulum_ekf.h"]
    assert "RK4 steps <= 0.002" in text and "cc -std=c99 -O2 -o pendulum_ekf pendulum_ekf.c main.c -lm" in text
    header = (out / "pendulum_ekf.h").read_text()
    assert "#define PENDULUM_EKF_NZ 6" in header and "#define PENDULUM_EKF_MAX_STEP 0.002" in header


def test_export_errors_are_one_line(tmp_path, capsys):
    assert main(["export", PEND, "--observer", "nope", "--c", str(tmp_path)]) == 1
    assert "no observer 'nope'; configured: injection, ekf" in capsys.readouterr().err
    assert main(["export", PEND, "--observer", "ekf", "--c", str(tmp_path), "--name", "bad-name"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "`name` must be a C identifier" in err
    assert main(["export", PEND, "--observer", "ekf", "--c", str(tmp_path), "--max-step", "0"]) == 1
    assert "`max_step` must be a positive number" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())  # nothing half-written


@pytest.mark.skipif(CC is None, reason="no C compiler (gcc/cc) on PATH: the exported C cannot be compiled here")
def test_exported_program_runs_on_a_csv_like_estimate(tmp_path, capsys):
    assert main(["export", PEND, "--observer", "injection", "--c", str(tmp_path), "--name", "inj"]) == 0
    capsys.readouterr()
    exe = tmp_path / "inj"
    subprocess.run([CC, "-std=c99", "-O2", "-o", str(exe), str(tmp_path / "inj.c"), str(tmp_path / "main.c"), "-lm"],
                   check=True, capture_output=True)
    mf = nlobs.load_model(PEND)
    run = nlobs.simulate(mf.system, t_final=2.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": "sin(t)"})
    rec = nlobs.Recording.from_run(run, every=10)
    rows = zip(rec.t.tolist(), rec.u[:, 0].tolist(), rec.y[:, 0].tolist())
    csv = "t,u,y\n" + "".join(f"{t!r},{u!r},{y!r}\n" for t, u, y in rows)
    lines = subprocess.run([str(exe)], input=csv, capture_output=True, text=True, check=True).stdout.splitlines()
    assert lines[0] == "t,xhat_x1,xhat_x2"
    got = np.loadtxt(lines[1:], delimiter=",")
    cfg = mf.observers["injection"]
    ref = nlobs.estimate(design_from_config(mf.system, cfg.kind, cfg.options), rec, engine="vm")
    assert np.abs(got[:, 1:] - next(iter(ref.observers.values())).xhat).max() <= 1e-10
