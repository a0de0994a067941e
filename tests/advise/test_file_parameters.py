"""nlobs.advise on model files with unknown parameters (``k = {value, unknown = true}``, ``[simulation]
true_parameters``) and with observer tables that supply what nlobs cannot tune.

Models are written here for these tests; reference values are independent: the true parameter is the file's
``true_parameters``, identifiability is decided by hand (b multiplies u, and u = 0 in the run).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import nlobs
from nlobs.advise import advise
from nlobs.cli import main

LAG = """
name = "lag"
states = ["x"]
inputs = ["u"]
outputs = ["y"]
[parameters]
a = 1.0
b = { value = 2.0, unknown = true }
[dynamics]
x = "-a*x + b*u"
[output]
y = "x"
[simulation]
t_final = 15.0
dt = 1e-3
x0 = [1.0]
inputs = { u = "U" }
noise = { y = 0.005 }
sample_period = 0.01
true_parameters = { b = 1.0 }
seed = 1
"""


def _lag(u: str) -> nlobs.ModelFile:
    return nlobs.loads_model(LAG.replace('"U"', f'"{u}"'), path="lag.toml")


def test_unknown_parameter_from_the_file_is_estimated_jointly_with_its_std():
    adv = advise(_lag("1 + sin(t)"), kinds=["ekf", "luenberger"], run=True)
    assert adv.system.estimated_params == ("b",) and adv.system.states == ("x", "b")
    assert adv.candidate("ekf").applies
    assert not adv.candidate("luenberger").applies                        # b·u makes the augmented model nonlinear
    (score,) = [s for s in adv.scores if s.kind == "ekf"]
    b = score.parameters["b"]
    assert b["true"] == 1.0                                               # the file's true_parameters, not the guess 2
    assert b["std"] is not None and b["std"] > 0
    assert abs(b["estimate"] - 1.0) < 0.05 and abs(b["estimate"] - 1.0) < 4 * b["std"]
    d = adv.to_dict()
    got = next(s for s in d["scores"] if s["kind"] == "ekf")["parameters"]["b"]
    assert set(got) == {"estimate", "std", "true"} and got["std"] == pytest.approx(b["std"])


def test_a_parameter_the_simulation_input_does_not_excite_is_refused_before_the_run():
    adv = advise(_lag("0"), kinds=["ekf"], run=True)
    assert adv.candidate("ekf").applies                                   # identifiable for generic inputs ...
    assert adv.scores == () and adv.run is None                           # ... but nothing was estimated on u = 0
    assert "b is not identifiable" in adv.run_refused and "richer [simulation] input" in adv.run_refused
    assert "Nothing was run" in str(adv)
    assert advise(_lag("0"), kinds=["ekf"]).run_refused == ""             # only a run is refused


def test_cli_design_json_reports_parameters_and_the_refusal(capsys):
    import pathlib
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        p = pathlib.Path(d) / "lag.toml"
        p.write_text(LAG.replace('"U"', '"0"'))
        assert main(["design", str(p), "--run", "--json", "--kind", "ekf"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["estimated_params"] == ["b"] and out["ranking"] == [] and "not identifiable" in out["run_refused"]


CUSTOM = """
name = "decay"
states = ["x"]
outputs = ["y"]
[dynamics]
x = "-x"
[output]
y = "x"
[simulation]
t_final = 5.0
dt = 1e-3
x0 = [1.0]
sample_period = 0.01
seed = 1
[observers.mine]
kind = "custom"
states = ["z"]
flow = ["-z + 4*(y - z)"]
estimate = ["z"]
"""


def test_a_kind_that_needs_input_uses_what_the_file_supplies():
    adv = advise(nlobs.loads_model(CUSTOM, path="decay.toml"), kinds=["custom"], run=True)
    c = adv.candidate("custom")
    assert c.applies and "[observers.mine]" in c.why
    e = adv.run.error_norm("custom")
    assert e[-1] < 1e-2 * e[0]                                            # z' = -z + 4(y - z): error decays at rate 5
    bad = nlobs.loads_model(CUSTOM.replace('flow = ["-z + 4*(y - z)"]', 'flow = ["-z", "0"]'), path="decay.toml")
    c = advise(bad, kinds=["custom"]).candidate("custom")
    assert c.status == "fails" and "[observers.mine] does not design" in c.why
    auto = advise(nlobs.loads_model(CUSTOM.split("[observers.mine]")[0], path="d.toml"), kinds=["custom"])
    assert auto.candidate("custom").status == "needs input" and "flow" in auto.candidate("custom").why


def test_a_file_with_unidentifiable_parameters_runs_nothing_and_says_why():
    text = LAG.replace("a = 1.0", 'a = { value = 1.0, unknown = true }').replace('x = "-a*x + b*u"', 'x = "-a*b*x + u"')
    adv = advise(nlobs.loads_model(text.replace('"U"', '"sin(t)"'), path="ab.toml"), kinds=["ekf"], run=True)
    assert any("not identifiable" in b for b in adv.blockers) and adv.scores == ()
    assert "no estimation was attempted" in str(adv)
    assert np.all([c.design is None for c in adv.candidates])
