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
    header = out_csv.read_text().splitlines()[0]
    assert header == "t,u,y,injection.x1,injection.x2"
    back = Recording.from_csv(out_csv, mf.system)  # what estimate writes, estimate reads
    assert np.isnan(back.y[7, 0]) and np.array_equal(back.t, rec.t)


def test_demo_only_writes_the_report(tmp_path, capsys):
    assert main(["demo", "--only", "002-pendulum", "--out", str(tmp_path), "--quiet"]) == 0
    html = (tmp_path / "index.html").read_text()
    assert "robot arm" in html and "data:image/png;base64," in html
    assert "twice its steady-state error" in html and "2 % of its initial value" not in html  # the rule the numbers follow
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


# -- simulate / estimate / fit workflow ------------------------------------------------------------------


def test_simulate_output_round_trips_through_estimate(tmp_path, capsys):
    """simulate --output writes what a data logger would record: the outputs at the sample instants of a sampled run,
    and every input sample (the input sin(t) changes at every step of 1 ms: every row, the outputs empty between
    their samples; issue 44, item 3), with the true states; estimate reads it back and gets nearly the same estimates
    and metrics (nearly: the simulation's RK4 saw sin(t) inside each step, the recording holds it over the step)."""
    sim_csv = tmp_path / "sim.csv"
    assert main(["simulate", PEND, "--t-final", "4", "--output", str(sim_csv), "--json"]) == 0
    sim = json.loads(capsys.readouterr().out)
    lines = sim_csv.read_text().splitlines()
    assert lines[0] == "t,u,y,x1,x2,injection.x1,injection.x2,ekf.x1,ekf.x2" and len(lines) == 1 + 4001  # every step
    assert sum(line.split(",")[2] != "" for line in lines[1:]) == 401  # 100 Hz samples
    assert "e+" not in lines[1] and "000000000" not in lines[2]  # shortest exact floats, not %.18e
    assert main(["estimate", PEND, str(sim_csv), "--observer", "ekf", "--json"]) == 0
    est = json.loads(capsys.readouterr().out)
    data = np.genfromtxt(sim_csv, delimiter=",", names=True)
    assert np.allclose([data["ekfx1"][-1], data["ekfx2"][-1]], est["observers"]["ekf"]["final_estimate"], atol=5e-3)
    s, e = sim["observers"]["ekf"], est["observers"]["ekf"]
    assert e["final_error"] == pytest.approx(s["final_error"], abs=5e-3)
    assert e["convergence_time"] == pytest.approx(s["convergence_time"], abs=0.05) and e["convergence_time"] < 0.5
    assert list(est["observers"]["ekf"]["estimate"]) == ["x1", "x2"]
    # the floats read back to the same doubles
    from nlobs import Recording, load_model

    back = Recording.from_csv(sim_csv, load_model(PEND).system)
    assert np.array_equal(back.x[:, 0], data["x1"])


def test_estimate_without_states_reports_innovations_and_takes_initial_conditions(tmp_path, capsys):
    sim_csv = tmp_path / "sim.csv"
    assert main(["simulate", PEND, "--t-final", "6", "--output", str(sim_csv), "--json"]) == 0
    capsys.readouterr()
    data = np.genfromtxt(sim_csv, delimiter=",", names=True)
    rec = tmp_path / "rec.csv"
    with rec.open("w") as fh:
        fh.write("time,level,force\n")
        for t, y, u in zip(data["t"], data["y"], data["u"]):
            fh.write(f"{float(t)!r},{float(y)!r},{float(u)!r}\n")
    args = ["estimate", PEND, str(rec), "--observer", "ekf", "--column", "time=t,level=y", "--column", "force=u"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "innovations" in text and "Ljung-Box" in text and "(no true state)" not in text
    assert main(args + ["--json", "--xhat0", "x1=1", "--P0", "1e-4,1"]) == 0
    out = json.loads(capsys.readouterr().out)["observers"]["ekf"]
    w = out["innovations"]["y"]
    assert isinstance(w["white"], bool) and 0 <= w["p_value"] <= 1 and w["rms"] == pytest.approx(0.01, rel=0.3)
    assert set(out["estimate"]) == {"x1", "x2"}
    # --xhat0 and --P0 reach the filter
    from nlobs import Recording, estimate, load_model
    from nlobs.cli._common import designs_of

    mf = load_model(PEND)
    d = designs_of(mf, ["ekf"], overrides={"P0": np.diag([1e-4, 1.0])})["ekf"]
    ref = estimate(d, Recording.from_csv(rec, mf.system, columns={"time": "t", "level": "y", "force": "u"}), xhat0=[1.0, 0.0])
    assert out["estimate"]["x2"] == pytest.approx(ref.observers["ekf"].xhat[-1, 1], abs=1e-12)
    assert main(["estimate", PEND, str(rec), "--observer", "injection", "--column", "time=t,level=y,force=u", "--P0", "1"]) == 1
    assert "observer 'injection' (kind 'output_injection') has no option P0; kinds that take it: " in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["simulate", PEND, "--t-final", "0"], "--t-final: expected a positive number"),
    (["simulate", PEND, "--dt", "0"], "--dt: expected a positive number"),
    (["simulate", PEND, "--tol", "-1"], "--tol: expected a positive number"),
    (["estimate", PEND, "x.csv", "--observer", "ekf", "--max-step", "0"], "--max-step: expected a positive number"),
])
def test_zero_and_negative_options_are_refused_not_replaced(argv, message, capsys):
    """`--t-final 0` / `--dt 0` were silently replaced by the file's values; `--tol -1` was accepted."""
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2 and message in capsys.readouterr().err


def test_simulate_from_a_recorded_input_with_x0_and_parameters(tmp_path, capsys):
    """Validation of a model on a recording: the recorded input drives the plant from x0, with chosen parameter values,
    and the simulated outputs are compared with the recorded ones."""
    from nlobs import Recording, load_model, simulate
    from nlobs.model import Sampled

    mf = load_model(PEND)
    t = np.round(np.arange(0, 5.0001, 0.05), 10)
    u = np.cos(1.3 * t)
    truth = simulate(mf.system.with_params(a2=0.8), t_final=5.0, dt=1e-3, x0=[0.5, 0.0], inputs={"u": Sampled(t, u)})
    y = truth.y[::50, 0]
    rec = tmp_path / "rec.csv"
    with rec.open("w") as fh:
        fh.write("t,u,y\n")
        for row in zip(t, u, y):
            fh.write(",".join(repr(float(v)) for v in row) + "\n")
    argv = ["simulate", PEND, "--input", str(rec), "--x0", "x1=0.5,x2=0", "--param", "a2=0.8", "--observer", "ekf",
            "--dt", "0.001", "--json"]
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["t_final"] == 5.0 and out["validation"]["y"]["rmse"] < 1e-12 and out["validation"]["y"]["fit_percent"] > 99.99
    assert main(argv[:-1] + ["--param", "a1=9"]) == 0  # a wrong gravity shows in the fit
    assert "simulated vs recorded outputs" in capsys.readouterr().out
    assert main(["simulate", PEND, "--param", "zz=1"]) == 1
    assert "--param: 'zz' is not one of a1, a2, b" in capsys.readouterr().err


def test_fit_command(tmp_path, capsys):
    from nlobs import load_model, simulate
    from nlobs.model import Sampled

    mf = load_model(PEND)
    t = np.round(np.arange(0, 8.0001, 0.02), 10)
    u = np.sign(np.sin(1.1 * t))
    truth = simulate(mf.system.with_params(a2=0.8), t_final=8.0, dt=1e-3, x0=[0.5, 0.0], inputs={"u": Sampled(t, u)})
    rec = tmp_path / "rec.csv"
    with rec.open("w") as fh:
        fh.write("t,u,y\n")
        for row in zip(t, u, truth.y[::20, 0]):
            fh.write(",".join(repr(float(v)) for v in row) + "\n")
    out_csv = tmp_path / "fit.csv"
    assert main(["fit", PEND, str(rec), "--param", "a2", "--x0", "0.5,0", "--max-step", "0.005", "--bound", "a2=0:",
                 "--output", str(out_csv), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["parameters"]["a2"]["estimate"] == pytest.approx(0.8, rel=1e-6) and out["success"]
    assert out_csv.read_text().splitlines()[0] == "t,y,y.fit"
    assert main(["fit", PEND, str(rec), "--param", "a2", "--x0", "0.5,0", "--bound", "a2=x"]) == 1
    assert "--bound: expected NAME=LO:HI" in capsys.readouterr().err


def test_help_texts_explain_engine_and_hold_and_cite_no_paper_numbers(capsys):
    import re

    for cmd in ("simulate", "estimate", "fit"):
        with pytest.raises(SystemExit):
            main([cmd, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert not re.search(r"\b00[0-4]\b", text)
        if cmd != "fit":
            assert "(default: auto)" in text and "virtual machine" in text and "compiles" in text
        if cmd != "simulate":
            assert "(default: zoh)" in text and "interpolates" in text


def test_vector_and_matrix_options():
    from nlobs.cli._common import parse_columns, parse_matrix, parse_vector

    names = ("x1", "x2")
    assert parse_vector("1, -2", names, "--x0").tolist() == [1.0, -2.0]
    assert parse_vector("x2=3", names, "--xhat0", [0.5, 0.0]).tolist() == [0.5, 3.0]
    for text, message in (("1", "1 value\\(s\\) for 2 state"), ("x1=1", "no value for x2"), ("x1=1,2", "mix of named"),
                          ("x3=1,x1=0,x2=0", "'x3' is not one of x1, x2"), ("1,nan", "not a finite number"),
                          ("x1=1,x1=2,x2=0", "'x1' is given twice"), ("a,b", "'a' is not a number")):
        with pytest.raises(ValueError, match=message):
            parse_vector(text, names, "--x0")
    assert np.array_equal(parse_matrix("2", 2, "--P0"), 2 * np.eye(2))
    assert np.array_equal(parse_matrix("1,4", 2, "--P0"), np.diag([1.0, 4.0]))
    assert np.array_equal(parse_matrix("[[1, 0.5], [0.5, 2]]", 2, "--P0"), [[1, 0.5], [0.5, 2]])
    for text, message in (("1,2,3", "got 3 numbers"), ("[[1]]", "expected 2×2"), ("[[1, 2], [3", "not a JSON list")):
        with pytest.raises(ValueError, match=message):
            parse_matrix(text, 2, "--P0")
    assert parse_columns(["time=t,level=y", "force=u"]) == {"time": "t", "level": "y", "force": "u"}
    with pytest.raises(ValueError, match="expected CSV_NAME=MODEL_NAME"):
        parse_columns(["time"])


def test_a_closed_pipe_ends_the_command_quietly(monkeypatch, capsys):
    # `nlobs analyze M | head`: the reader goes away; the command stops with status 0 and no error line
    # (before: "nlobs: error: [Errno 32] Broken pipe" and status 1)
    import nlobs.cli as cli_mod
    from nlobs.cli import _kinds

    called = []

    def run(args):
        called.append(True)
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(_kinds, "run", run)
    monkeypatch.setattr(cli_mod, "_closed_pipe", lambda: 0)   # keep pytest's own stdout open
    assert cli_mod.main(["kinds"]) == 0 and called
    assert "Broken pipe" not in capsys.readouterr().err


@pytest.mark.parametrize("option, value", [("--t-final", "0"), ("--dt", "0"), ("--tol", "-1")])
def test_a_bad_number_is_one_line_naming_the_option(option, value, capsys):
    import nlobs.cli as cli_mod

    with pytest.raises(SystemExit) as e:
        cli_mod.main(["simulate", "pendulum", option, value])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and option in err and "positive" in err and "usage:" not in err


def test_starting_the_command_line_does_not_import_scipy_stats():
    # scipy.stats took a second of every command's 2.7 s start (only the whiteness test of the residuals uses it, and
    # imports it when called)
    code = "import sys, nlobs.cli; print('scipy.stats' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_estimate_plot_draws_the_estimates(tmp_path, capsys):
    """nlobs estimate --plot FILE: the filtered and smoothed estimates as a picture (a PNG with one panel per state)."""
    sim_csv, png = tmp_path / "sim.csv", tmp_path / "est.png"
    assert main(["simulate", PEND, "--t-final", "2", "--output", str(sim_csv), "--json"]) == 0
    capsys.readouterr()
    assert main(["estimate", PEND, str(sim_csv), "--observer", "ekf", "--smooth", "--plot", str(png)]) == 0
    assert f"plot: {png}" in capsys.readouterr().out
    import matplotlib.image as mpimg

    img = mpimg.imread(png)
    assert img.shape[0] > 300 and img.shape[1] > 300 and img.std() > 0.05   # a drawn figure, not a blank page


def test_estimate_plot_labels_the_axes_with_the_files_units(tmp_path, capsys, monkeypatch):
    # simulate --plot wrote 'X [g/L]' and 't [h]'; estimate --plot on the same file wrote 'X' and 't'
    model = tmp_path / "decay.toml"
    model.write_text('name = "decay"\nstates = ["x"]\noutputs = ["y"]\n[dynamics]\nx = "-0.5*x"\n[output]\ny = "x"\n'
                     '[units]\nx = "g/L"\nt = "h"\n[simulation]\nt_final = 2.0\ndt = 0.01\nx0 = [1.0]\nnoise = { y = 0.01 }\n'
                     'seed = 1\n[observers.ekf]\nkind = "ekf"\nQ = [[1e-4]]\nR = [[1e-4]]\nxhat0 = [0.5]\n')
    sim_csv, png = tmp_path / "sim.csv", tmp_path / "est.png"
    assert main(["simulate", str(model), "--output", str(sim_csv), "--json"]) == 0
    import matplotlib.figure

    labels = []
    real = matplotlib.figure.Figure.savefig
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig",
                        lambda self, *a, **k: (labels.extend(ax.get_ylabel() for ax in self.axes),
                                               labels.extend(ax.get_xlabel() for ax in self.axes), real(self, *a, **k))[-1])
    assert main(["estimate", str(model), str(sim_csv), "--observer", "ekf", "--plot", str(png)]) == 0
    assert "x [g/L]" in labels and "t [h]" in labels, labels


def test_estimate_on_a_simulated_csv_reads_the_parameters_truth(tmp_path, capsys):
    # simulate --output writes the unknown parameter's true value as a column; estimate read only the plant's states, so
    # its summary and plot lost the parameter's truth that simulate had shown
    model = tmp_path / "decay.toml"
    model.write_text('name = "decay"\nstates = ["x"]\ninputs = ["u"]\noutputs = ["y"]\n[parameters]\n'
                     'k = { value = 0.4, unknown = true }\n[dynamics]\nx = "-k*x + u"\n[output]\ny = "x"\n'
                     '[simulation]\nt_final = 5.0\ndt = 0.01\nx0 = [1.0]\ninputs = { u = "sin(2*t)" }\n'
                     'noise = { y = 0.01 }\nseed = 1\ntrue_parameters = { k = 0.5 }\n'
                     '[observers.ekf]\nkind = "ekf"\nQ = [[1e-4, 0], [0, 1e-6]]\nR = [[1e-4]]\nP0 = [[1, 0], [0, 0.1]]\n')
    sim_csv = tmp_path / "sim.csv"
    assert main(["simulate", str(model), "--observer", "ekf", "--output", str(sim_csv), "--json"]) == 0
    sim = json.loads(capsys.readouterr().out)
    assert main(["estimate", str(model), str(sim_csv), "--observer", "ekf", "--json"]) == 0
    est = json.loads(capsys.readouterr().out)
    p_sim = sim["observers"]["ekf"]["parameters"]["k"]
    p_est = est["observers"]["ekf"]["parameters"]["k"]
    assert p_est["true"] == 0.5 == p_sim["true"]
    assert abs(p_est["estimate"] - p_sim["estimate"]) < 0.01   # the recording holds the input between its rows


def test_a_huge_number_on_the_command_line_is_named_not_printed_whole(capsys):
    """--param and --x0 refuse a 4,301-digit number (no finite float) with its start and length, not all its digits."""
    big = "9" * 4301
    for argv in (["simulate", PEND, "--param", f"a1={big}"], ["simulate", PEND, "--x0", f"{big},0"]):
        assert main(argv) == 1
        err = capsys.readouterr().err
        assert "is not a finite number" in err and "(4301 characters)" in err and len(err) < 400, err[:500]
