"""The command line: JSON contracts, one-line errors, demo."""

from __future__ import annotations

import json
import subprocess
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from nlobs.cli import main

PEND = str(resources.files("nlobs.models").joinpath("pendulum.toml"))
VDP = str(resources.files("nlobs.models").joinpath("van_der_pol.toml"))


def test_simulate_json_contract(capsys):
    assert main(["simulate", PEND, "--json", "--t-final", "5"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"] == "pendulum" and set(out["observers"]) == {"injection", "ekf"}
    for entry in out["observers"].values():
        assert isinstance(entry["final_error"], float) and isinstance(entry["rms_error"], float)
        assert entry["convergence_time"] is None or isinstance(entry["convergence_time"], float)
    assert out["observers"]["injection"]["final_error"] < 0.05


def test_simulate_selects_observers_and_plots(tmp_path, capsys):
    png = tmp_path / "p.png"
    assert main(["simulate", VDP, "--observer", "ekf", "--t-final", "5", "--seed", "3", "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "ekf" in text and png.stat().st_size > 10_000


def test_simulate_json_final_error_is_the_norm_at_the_end(capsys):
    main(["simulate", PEND, "--json", "--t-final", "2", "--observer", "injection"])
    out = json.loads(capsys.readouterr().out)["observers"]["injection"]
    from nlobs import load_model, simulate, Noise, Sampling
    from nlobs.design import design_from_config

    mf = load_model(PEND)
    d = design_from_config(mf.system, "output_injection", mf.observers["injection"].options)
    run = simulate(mf.system, {"injection": d}, t_final=2.0, dt=1e-3, x0=mf.simulation.x0, inputs=dict(mf.simulation.inputs),
                   noise=Noise.gaussian(0.01), sampling=Sampling(0.01), seed=1)
    assert out["final_error"] == pytest.approx(np.linalg.norm(run.error("injection")[-1]), rel=1e-12)
    tail = run.t >= 0.8 * 2.0
    assert out["rms_error"] == pytest.approx(np.sqrt(np.mean(run.error_norm("injection")[tail] ** 2)), rel=1e-9)


def test_errors_are_one_line_and_non_zero(capsys, tmp_path):
    assert main(["simulate", "/nonexistent.toml"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("nlobs: error: /nonexistent.toml") and err.count("\n") == 1
    assert main(["simulate", PEND, "--observer", "nope"]) == 1
    assert "no observer 'nope'; configured: injection, ekf" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text(Path(PEND).read_text().replace('poles = [-2.0, -3.0]', 'poles = [2.0, -3.0]'))
    assert main(["simulate", str(bad), "--observer", "injection"]) == 1
    msg = capsys.readouterr().err
    assert "observers.injection" in msg and "not in the open left half-plane" in msg
    with pytest.raises(Exception):
        main(["--debug", "simulate", "/nonexistent.toml"])


def test_estimate_from_csv(tmp_path, capsys):
    from nlobs import Recording, load_model, simulate

    mf = load_model(PEND)
    run = simulate(mf.system, t_final=4.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": "sin(t)"})
    rec = Recording.from_run(run, every=10)
    data = tmp_path / "rec.csv"
    y = rec.y.copy()
    y[7] = np.nan
    rows = np.column_stack([rec.t, y, rec.u])
    with data.open("w") as fh:
        fh.write("t,y,u\n")
        for r in rows:
            fh.write(",".join("" if np.isnan(v) else repr(float(v)) for v in r) + "\n")
    assert main(["estimate", PEND, str(data), "--observer", "injection", "--json"]) == 1
    assert "missing (NaN) at row 7" in capsys.readouterr().err
    out_csv = tmp_path / "est.csv"
    assert main(["estimate", PEND, str(data), "--observer", "injection", "--skip-missing", "--json", "--output", str(out_csv)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert np.allclose(out["observers"]["injection"]["final_estimate"], run.x[-1], atol=0.05)
    est = np.loadtxt(out_csv, delimiter=",", skiprows=1)
    assert est.shape == (rec.t.size, 3)


def test_demo_only_writes_the_report(tmp_path, capsys):
    assert main(["demo", "--only", "002-pendulum", "--out", str(tmp_path), "--quiet"]) == 0
    html = (tmp_path / "index.html").read_text()
    assert "robot arm" in html and "data:image/png;base64," in html
    assert "claims 3/3 hold" in capsys.readouterr().out
    assert main(["demo", "--only", "nope", "--out", str(tmp_path)]) == 1


def test_console_script_entry_point():
    out = subprocess.run([sys.executable, "-m", "nlobs.cli", "demo", "--list"], capture_output=True, text=True)
    assert out.returncode == 0 and "aug-toy" in out.stdout


def test_errors_under_json_are_one_json_object(capsys):
    assert main(["simulate", PEND, "--json", "--observer", "nope"]) == 1
    captured = capsys.readouterr()
    err = json.loads(captured.err)
    assert captured.out == "" and err["error"]["type"] == "KeyError"
    assert "no observer 'nope'" in err["error"]["message"]
