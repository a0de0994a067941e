"""Model files: the documented format parses; anything else is refused naming file, key and text."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from nlobs import ModelFileError, load_model, loads_model
from nlobs.model import symbol

# The model file of the core issue, verbatim.
ISSUE_EXAMPLE = textwrap.dedent('''
    name = "van_der_pol"
    states = ["x1", "x2"]
    inputs = ["u"]            # optional
    outputs = ["y"]
    [parameters]
    mu = 1.0
    [dynamics]                # one time derivative per state
    x1 = "x2"
    x2 = "mu*(1 - x1**2)*x2 - x1 + u"
    [output]
    y = "x1"
    [simulation]              # defaults for `simulate` and the demo
    t_final = 20.0
    dt = 1e-3
    x0 = [2.0, 0.0]
    inputs = { u = "0.5*sin(t)" }     # expressions of t
    noise = { y = 0.01 }              # std of Gaussian measurement noise per output
    seed = 1
    [observers.ekf]           # named observer configurations: kind + tuning
    kind = "ekf"
    xhat0 = [0.0, 0.0]
    Q = [[0.01, 0.0], [0.0, 0.01]]
    R = [[0.0001]]
    [observers.luen]
    kind = "luenberger"       # for LTI models; or give gains directly with L = [...]
    poles = [-2.0, -3.0]
    xhat0 = [0.0, 0.0]
''')


def test_issue_example_parses():
    mf = loads_model(ISSUE_EXAMPLE, path="vdp.toml")
    s = mf.system
    assert s.name == "van_der_pol" and s.states == ("x1", "x2") and s.inputs == ("u",) and dict(s.params) == {"mu": 1.0}
    sim = mf.simulation
    assert (sim.t_final, sim.dt, sim.x0, sim.seed) == (20.0, 1e-3, (2.0, 0.0), 1)
    assert dict(sim.noise) == {"y": 0.01}
    t = symbol("t")
    assert sim.inputs["u"].equals(0.5 * __import__("sympy").sin(t))
    assert set(mf.observers) == {"ekf", "luen"}
    assert mf.observers["ekf"].kind == "ekf" and mf.observers["luen"].options["poles"] == [-2.0, -3.0]


def test_bundled_models_load(tmp_path):
    from importlib import resources

    for f in resources.files("nlobs.models").iterdir():
        if f.name.endswith(".toml"):
            mf = load_model(f)
            assert mf.system.n_states >= 1


def test_load_model_reads_a_file_and_defaults_the_name(tmp_path):
    p = tmp_path / "osc.toml"
    p.write_text('states = ["x"]\noutputs = ["y"]\n[dynamics]\nx = "-x"\n[output]\ny = "x"\n')
    mf = load_model(p)
    assert mf.system.name == "osc" and mf.path == str(p)


BASE = 'states = ["x"]\noutputs = ["y"]\n[dynamics]\nx = "-x"\n[output]\ny = "x"\n'


@pytest.mark.parametrize(
    "text, key, fragment",
    [
        (BASE.replace('"-x"', '"__import__(\'os\').system(\'touch /tmp/nlobs-pwned\')"'), "dynamics.x", "dunder"),
        (BASE.replace('"-x"', '"x.__class__"'), "dynamics.x", "dunder"),
        (BASE.replace('"-x"', '"x.real"'), "dynamics.x", "attribute access"),
        (BASE.replace('"-x"', '"(lambda: 0)()"'), "dynamics.x", "only the functions"),
        (BASE.replace('"-x"', '"[q for q in x]"'), "dynamics.x", "comprehension"),
        (BASE.replace('"-x"', '"\'hello\'"'), "dynamics.x", "a string is not allowed"),
        (BASE.replace('"-x"', '"x**100000"'), "dynamics.x", "exceeds 64"),
        (BASE.replace('"-x"', '"import os"'), "dynamics.x", "not a valid expression"),
        (BASE.replace('"-x"', 'true'), "dynamics.x", "expression string or a number"),
        (BASE.replace('"-x"', '"-z"'), "dynamics.x", "unknown name `z`"),
        ('extra = 1\n' + BASE, "extra", "unknown key"),
        (BASE.replace('states = ["x"]\n', ''), "", "`states` is required"),
        (BASE.replace('[dynamics]\nx = "-x"\n', ''), "", "table \\[dynamics\\] is required"),
        (BASE.replace('x = "-x"', 'w = "-x"'), "dynamics.w", "not a declared state"),
        (BASE + '[simulation]\nx0 = [1, 2]\n', "simulation.x0", "list of 1 numbers"),
        (BASE + '[simulation]\ndt = -1\n', "simulation.dt", "positive"),
        (BASE + '[simulation]\nt_finale = 1\n', "simulation.t_finale", "unknown key"),
        (BASE + '[simulation]\nnoise = { q = 0.1 }\n', "simulation.noise.q", "not one of y"),
        (BASE + '[simulation]\ninputs = { u = "t" }\n', "simulation.inputs.u", "not an input"),
        (BASE + '[observers.a]\nL = [1]\n', "observers.a.kind", "`kind` is required"),
        (BASE + '[parameters]\nk = "1"\n', "parameters.k", "finite number"),
        ('states = "x"\n', "states", "list of names"),
        ('states = ["x"\n', "", "not valid TOML"),
    ],
)
def test_bad_files_are_refused_naming_file_key_and_text(text, key, fragment):
    with pytest.raises(ModelFileError, match=fragment) as info:
        loads_model(text, path="m.toml")
    err = info.value
    assert str(err).startswith("m.toml")
    assert err.key == key
    if key == "dynamics.x":
        assert err.text  # the offending expression is quoted


def test_missing_file():
    with pytest.raises(ModelFileError, match="cannot read the model file"):
        load_model("/nonexistent/model.toml")


def test_parameters_usable_in_simulation_inputs():
    mf = loads_model(BASE.replace('outputs', 'inputs = ["u"]\noutputs') + '[parameters]\nw = 2.0\n[simulation]\ninputs = { u = "sin(w*t)" }\n')
    from nlobs.model import as_signal

    sig = as_signal(mf.simulation.inputs["u"], name="u", params=mf.system.params)
    assert np.allclose(sig(np.array([0.3])), np.sin(0.6))


PERIOD = """
name = "bp"
states = ["x"]
outputs = ["y", "gps"]
[dynamics]
x = "-x"
[output]
y = "x"
gps = "2*x"
[simulation]
t_final = 2.0
dt = 0.005
x0 = [1.0]
"""


@pytest.mark.parametrize("line, key", [("sample_period = 0.0123", "simulation.sample_period"),
                                       ("sample_period = { y = 0.01, gps = 0.0123 }", "simulation.sample_period.gps"),
                                       ('[sensors.pos]\nexpr = "x"\nnoise = 0.1\nperiod = 0.0123', "sensors.pos.period")])
def test_a_sample_period_off_the_integration_grid_is_refused_at_load_naming_file_and_key(tmp_path, line, key):
    """Issue 44, item 8a: the period 0.0123 is 2.46 steps of dt = 0.005; said at once by load_model, with the file and
    the key (before: "Sampling: the period 0.0123 must be a whole multiple of dt = 0.005" after the run had started)."""
    p = tmp_path / "bp.toml"
    p.write_text(PERIOD + line + "\n", encoding="utf-8")
    with pytest.raises(ModelFileError) as err:
        load_model(p)
    msg = str(err.value)
    assert str(p) in msg and f"key `{key}`" in msg and "whole multiple of dt = 0.005" in msg and "2.46 steps" in msg
    p.write_text(PERIOD + line.replace("0.0123", "0.015") + "\n", encoding="utf-8")  # 3 steps: fine
    mf = load_model(p)
    assert (mf.simulation.sample_period if key.startswith("simulation") else mf.sensors["pos"].period) is not None


def test_without_dt_the_default_step_is_checked_before_the_run_naming_file_and_key(tmp_path, capsys):
    from nlobs.cli import main

    p = tmp_path / "bp.toml"
    p.write_text(PERIOD.replace("dt = 0.005\n", "") + "sample_period = 0.0123\n", encoding="utf-8")
    assert main(["simulate", str(p)]) == 1
    err = capsys.readouterr().err
    assert str(p) in err and "key `simulation.sample_period`" in err and "dt = 0.001" in err and "not set" in err


@pytest.mark.parametrize("where", ["expression", "parameter"])
def test_a_4301_digit_integer_is_refused_in_nlobs_own_words(where):
    """Issue 44, item 8c: Python refuses integer literals of more than 4300 digits with a hint to call
    sys.set_int_max_str_digits; the model parser says it in its own words, with the key or the line."""
    big = "1" * 4301
    text = ('name = "b"\nstates = ["x"]\noutputs = ["y"]\n' +
            (f'[dynamics]\nx = "-x + {big}"\n' if where == "expression" else
             f'[parameters]\nk = {big}\n[dynamics]\nx = "-k*x"\n') + '[output]\ny = "x"\n')
    with pytest.raises(ModelFileError) as err:
        loads_model(text, path="b.toml")
    msg = str(err.value)
    assert "set_int_max_str_digits" not in msg and "hexadecimal" not in msg
    assert "an integer of 4,301 digits" in msg and "at most 1e300 in magnitude" in msg
    assert ("key `dynamics.x`" in msg) if where == "expression" else ("(line 5)" in msg)
