"""``nlobs sensors`` (issue 37): the JSON contract, the budget, the plot, and one-line errors."""

from __future__ import annotations

import json

import pytest

from nlobs.cli import main

MODEL = """
name = "cascade6"
states = ["A", "B", "C", "D", "E", "F"]
outputs = ["y"]
[parameters]
k = { value = 0.7, unknown = true }
[dynamics]
A = "1 - A - A*B"
B = "A - 2*B"
C = "B - k*C"
D = "C*E - D"
E = "D - E**2"
F = "C - F"
[output]
y = "F"
[simulation]
t_final = 8.0
dt = 0.01
x0 = [0.2, 0.1, 0.5, 0.3, 0.8, 0.0]
sample_period = 0.1
[sensors.sA]
expr = "A"
noise = 0.01
[sensors.sD]
expr = "D"
noise = 0.01
cost = 2
[sensors.sE]
expr = "E"
noise = 0.05
[sensors.sF]
expr = "F"
noise = 0.01
[sensors.sCE]
expr = "C*E"
noise = 0.01
"""


@pytest.fixture
def model(tmp_path):
    p = tmp_path / "cascade6.toml"
    p.write_text(MODEL, encoding="utf-8")
    return p


def test_json_contract(model, capsys):
    assert main(["sensors", str(model), "--json", "--budget", "3"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert sorted(map(sorted, out["minimal_sets"])) == [["sCE", "sF"], ["sD", "sF"], ["sE", "sF"]]
    for entry in out["sets"]:
        assert {"sensors", "observable", "crb", "cost"} <= set(entry)
        assert set(entry["crb"]) == {"A", "B", "C", "D", "E", "F", "k"}
    assert out["best"]["cost"] <= 3 and out["budget"] == 3
    assert out["search"]["complete"] and out["run"]["samples"] == 81


def test_text_target_and_plot(model, tmp_path, capsys):
    png = tmp_path / "bounds.png"
    assert main(["sensors", str(model), "--target", "F,k", "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "targets: F, k" in text and "{sF}" in text and "Cramér–Rao" in text
    assert png.stat().st_size > 10_000


def test_structural_only(model, capsys):
    assert main(["sensors", str(model), "--no-bounds", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["run"] is None and all(s["crb"] is None for s in out["sets"])


@pytest.mark.parametrize("change, key", [
    (lambda t: t.replace('expr = "C*E"', 'expr = "C*G"'), "sensors.sCE.expr"),
    (lambda t: t.replace("noise = 0.05", "noise = 0"), "sensors.sE.noise"),
    (lambda t: t + '[sensors.sA]\nexpr = "B"\nnoise = 1\n', "sensors.sA"),
    (lambda t: t[: t.index("[sensors.sA]")] + "[sensors]\n", "sensors"),
])
def test_bad_tables_are_one_line_errors(tmp_path, capsys, change, key):
    p = tmp_path / "bad.toml"
    p.write_text(change(MODEL), encoding="utf-8")
    assert main(["sensors", str(p)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("nlobs: error:") and f"key `{key}`" in err


def test_bad_target_and_budget(model, capsys):
    assert main(["sensors", str(model), "--target", "Q"]) == 1
    assert "'Q' is not a state or an unknown parameter" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["sensors", str(model), "--budget", "-1"])


def test_run_adds_the_filter_errors(model, tmp_path, capsys):
    png = tmp_path / "run.png"
    assert main(["sensors", str(model), "--run", "--draws", "2", "--json", "--plot", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    first = out["filter"]["sets"][0]
    assert first["sensors"] == out["best"]["sensors"] and set(first["rms_error"]) == {"A", "B", "C", "D", "E", "F", "k"}
    assert all(v > 0 for v in first["rms_error"].values()) and out["filter"]["seeds"] == 2
    assert png.stat().st_size > 10_000
