"""nlobs models / design / report from the command line: JSON contracts, TOML round trip, one-line errors."""

from __future__ import annotations

import json
import tomllib

import pytest

from nlobs.cli import main
from nlobs.design import design_from_config
from nlobs.model import load_model


def test_models_lists_the_library_and_prints_a_file(capsys):
    assert main(["models", "--json"]) == 0
    names = {m["name"] for m in json.loads(capsys.readouterr().out)["models"]}
    assert {"lorenz", "cart_pole", "sir"} <= names
    assert main(["models", "lorenz"]) == 0
    text = capsys.readouterr().out
    assert tomllib.loads(text)["name"] == "lorenz"
    assert main(["models", "nope"]) == 1
    assert "no bundled model 'nope'" in capsys.readouterr().err


def test_design_json_contract(capsys):
    assert main(["design", "dc_motor", "--json", "--kind", "luenberger", "--kind", "kkl", "--kind", "iandi"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"] == "dc_motor" and out["observability"]["observable"] is True
    assert [c["kind"] for c in out["candidates"]] == ["luenberger", "kkl", "iandi"]
    assert all({"kind", "applies", "why", "options", "reference"} <= set(c) for c in out["candidates"])
    assert out["candidates"][0]["applies"] and not out["candidates"][2]["applies"]
    assert "ranking" not in out


def test_design_run_ranks(capsys):
    assert main(["design", "dc_motor", "--run", "--json", "--kind", "luenberger", "--kind", "ekf", "--kind", "pebo",
                 "--engine", "vm"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert sorted(out["ranking"]) == ["ekf", "luenberger", "pebo"]
    assert out["scores"][0]["kind"] == out["ranking"][0] and out["scores"][0]["rms_error"] < 0.05


def test_design_toml_output_pastes_into_a_model_file(capsys):
    assert main(["design", "pendulum", "--toml", "--kind", "output_injection", "--kind", "kkl", "--kind", "ekf"]) == 0
    tables = tomllib.loads(capsys.readouterr().out)["observers"]
    system = load_model("pendulum").system
    assert set(tables) == {"output_injection", "kkl", "ekf_design"}     # the file has its own [observers.ekf]
    for name, table in tables.items():
        opts = {k: v for k, v in table.items() if k != "kind"}
        design_from_config(system, table["kind"], opts, where=name)         # the pasted table designs the same observer


def test_design_errors_are_one_line(capsys):
    assert main(["design", "dc_motor", "--kind", "no_such_kind"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("nlobs: error: advise: unknown observer kind 'no_such_kind'") and err.count("\n") == 1
    assert main(["design", "dc_motor", "--params", "zz", "--json"]) == 1
    assert json.loads(capsys.readouterr().err)["error"]["message"].startswith("advise: unknown parameter 'zz'")


def test_report_writes_a_self_contained_page(tmp_path, capsys):
    out = tmp_path / "rep"
    assert main(["report", "dc_motor", "--out", str(out), "--kind", "luenberger", "--kind", "ekf", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    html = (out / "index.html").read_text()
    assert info["report"].endswith("index.html") and set(info["ranking"]) == {"luenberger", "ekf"}
    assert "Observer kinds" in html and "data:image/png" in html and "Messner &amp; Tilbury" in html


@pytest.mark.parametrize("cmd", [["analyze", "lorenz", "--json"], ["simulate", "pendulum", "--t-final", "1", "--json"]])
def test_bundled_names_work_in_every_command(cmd, capsys):
    assert main(cmd) == 0
    assert json.loads(capsys.readouterr().out)


def test_design_ranks_on_a_recording(tmp_path, capsys):
    import numpy as np

    import nlobs

    mf = load_model("dc_motor")
    run = nlobs.simulate(mf.system, None, t_final=5.0, dt=1e-3, x0=[0.5, 0.2], inputs={"V": "1 + 0.5*sin(2*t)"},
                         noise=nlobs.Noise.gaussian(0.001), sampling=nlobs.Sampling(0.01), seed=3)
    k = np.arange(0, run.t.size, 10)
    csv = tmp_path / "rec.csv"
    np.savetxt(csv, np.column_stack([run.t[k], run.y[k, 0], run.u[k, 0]]), delimiter=",", header="t,y,V", comments="")
    assert main(["design", "dc_motor", "--data", str(csv), "--json", "--kind", "luenberger", "--kind", "ekf",
                 "--engine", "vm"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert sorted(out["ranking"]) == ["ekf", "luenberger"] and out["scenario"].startswith("the recording (501 samples")
    assert all(s["detail"] == "innovation RMS (no true state)" and s["rms_error"] < 0.01 for s in out["scores"])
