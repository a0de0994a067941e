"""`simulate` on a file without observers says how to get some; `--observer KIND` designs a kind with the
advisor's automatic tuning (issue 20 §6)."""

from __future__ import annotations

import json

import pytest

from nlobs.cli import main

MODEL = """
name = "pend"
states = ["x1", "x2"]
inputs = ["u"]
outputs = ["y"]
[dynamics]
x1 = "x2"
x2 = "-9.81*sin(x1) - 0.5*x2 + u"
[output]
y = "x1"
[simulation]
t_final = 5.0
dt = 1e-3
x0 = [1.0, 0.0]
inputs = { u = "sin(t)" }
noise = { y = 0.01 }
seed = 1
"""


@pytest.fixture
def model(tmp_path):
    p = tmp_path / "pend.toml"
    p.write_text(MODEL, encoding="utf-8")
    return str(p)


def test_no_observers_names_the_two_ways_to_get_some(model, capsys):
    assert main(["simulate", model]) == 0
    out = capsys.readouterr().out
    assert f"no observers: {model} configures none. `nlobs design {model} --toml` proposes them" in out
    assert "--observer ekf` runs one kind with its automatic tuning" in out


def test_a_kind_name_is_designed_with_the_automatic_tuning_and_runs(model, capsys):
    assert main(["simulate", model, "--observer", "ekf", "--observer", "ukf", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert [v["method"] for v in d["observers"].values()] == ["ekf", "ukf"]
    # the pendulum is observable from its angle: both converge from the advisor's x̂(0) (an error of 0.36 at the start)
    assert all(v["final_error"] < 0.02 and v["convergence_time"] is not None for v in d["observers"].values())


def test_a_kind_that_cannot_be_tuned_or_an_unknown_name_is_one_clear_line(model, capsys):
    assert main(["simulate", model, "--observer", "lipschitz"]) == 1
    err = capsys.readouterr().err
    assert "--observer lipschitz: no observer of that name is configured, and the kind 'lipschitz' cannot be tuned" in err
    assert main(["simulate", model, "--observer", "foo"]) == 1
    assert "no observer 'foo'; configured: (none); or name an observer kind" in capsys.readouterr().err
