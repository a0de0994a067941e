"""Model files as real models are written (issue 9): definitions, min/max/sat, units, unknown parameters."""

from __future__ import annotations

import re
import textwrap

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

import nlobs
from nlobs import ModelFileError, loads_model
from nlobs.model import symbol

TANKS = textwrap.dedent('''
    name = "tanks"
    states = ["x1", "x2"]
    inputs = ["u"]
    outputs = ["y"]
    [parameters]
    k1 = 0.5
    k2 = { value = 0.3, unknown = true }
    ymax = 10.0
    [definitions]
    q1 = "k1*sqrt(max(x1, 0))"
    q2 = "k2*sqrt(max(x2, 0))"
    inflow = "0.5 + 0.2*sin(t)"
    [dynamics]
    x1 = "-q1 + u"
    x2 = "q1 - q2"
    [output]
    y = "sat(x2, 0, ymax)"
    [units]
    x1 = "m"
    u = "V"
    t = "s"
    [simulation]
    t_final = 10.0
    dt = 0.01
    x0 = [1.0, 0.5]
    inputs = { u = "inflow" }
    true_parameters = { k2 = 0.25 }
    [observers.ekf]
    kind = "ekf"
    Q = [[1e-4, 0, 0], [0, 1e-4, 0], [0, 0, 1e-5]]
    R = [[1e-4]]
''')


def test_definitions_are_substituted_in_order():
    mf = loads_model(TANKS)
    x1, x2, k1, k2, u = (symbol(n) for n in ("x1", "x2", "k1", "k2", "u"))
    q1 = k1 * sp.sqrt(sp.Max(x1, 0))
    assert sp.simplify(mf.system.f[0] - (-q1 + u)) == 0
    assert sp.simplify(mf.system.f[1] - (q1 - k2 * sp.sqrt(sp.Max(x2, 0)))) == 0
    assert mf.system.h[0] == sp.Min(sp.Max(x2, 0), symbol("ymax"))
    assert list(mf.definitions) == ["q1", "q2", "inflow"]
    assert mf.units == {"x1": "m", "u": "V", "t": "s"}


def test_definitions_used_in_simulation_inputs_and_observer_options():
    mf = loads_model(TANKS)
    t = symbol("t")
    assert sp.simplify(mf.simulation.inputs["u"] - (sp.Rational(1, 2) + sp.Rational(1, 5) * sp.sin(t))) == 0
    text = TANKS.replace('[observers.ekf]', '[observers.own]\nkind = "custom"\nstates = ["a", "b", "c"]\n'
                         'flow = ["-q1 + u", "q1", "0"]\n\n[observers.ekf]')
    own = loads_model(text).observers["own"]
    assert isinstance(own.options["flow"][0], sp.Expr)
    assert sp.simplify(own.options["flow"][0] - (-symbol("k1") * sp.sqrt(sp.Max(symbol("x1"), 0)) + symbol("u"))) == 0
    assert own.options["states"] == ["a", "b", "c"]  # strings without definitions are untouched


@pytest.mark.parametrize("change, key, fragment", [
    (('q1 = "k1*sqrt(max(x1, 0))"', 'q1 = "q2 + 1"'), "definitions.q1", "defined further down"),
    (('q1 = "k1', 'x1 = "k1'), "definitions.x1", "already declared"),
    (('q1 = "k1', 'sin = "k1'), "definitions.sin", "reserved"),
    (('q1 = "k1', '"1q" = "k1'), "definitions.1q", "starts with a letter"),
    (('q1 = "k1*sqrt(max(x1, 0))"', 'q1 = "k1*zz"'), "definitions.q1", "unknown name `zz`"),
    (('inputs = { u = "inflow" }', 'inputs = { u = "q1" }'), "simulation.inputs.u", "depends on states"),
    (('y = "sat(x2, 0, ymax)"', 'y = "sat(x2, 1, 0)"'), "output.y", "lo <= hi"),
    (('x1 = "m"', 'q9 = "m"'), "units.q9", "not a state"),
    (('k2 = { value = 0.3, unknown = true }', 'k2 = { value = 0.3, unknown = "yes" }'), "parameters.k2.unknown", "true or false"),
    (('k2 = { value = 0.3, unknown = true }', 'k2 = { unknown = true }'), "parameters.k2", "needs `value`"),
    (('k2 = { value = 0.3, unknown = true }', 'k2 = { value = 0.3, bounds = 1 }'), "parameters.k2.bounds", "unknown key"),
    (('true_parameters = { k2 = 0.25 }', 'true_parameters = { k9 = 0.25 }'), "simulation.true_parameters.k9",
     "not a parameter"),
])
def test_bad_new_syntax_is_refused_with_file_key_and_reason(change, key, fragment):
    with pytest.raises(ModelFileError, match=fragment) as info:
        loads_model(TANKS.replace(*change), path="t.toml")
    assert info.value.key == key


def test_unknown_parameters_and_the_systems_of_a_file():
    mf = loads_model(TANKS)
    assert mf.unknown_params == ("k2",)
    assert mf.system.params["k2"] == 0.3  # the model as written: the guess
    assert mf.observer_system.states == ("x1", "x2", "k2") and mf.observer_system.estimated_params == ("k2",)
    assert mf.true_system.params["k2"] == 0.25 and mf.guesses == {"k2": 0.3}
    cfg = mf.observers["ekf"]
    assert cfg.system == mf.observer_system and dict(cfg.guesses) == {"k2": 0.3}


def test_min_max_sat_simulate_exactly():
    """x' = -x + sat(u, -1, 1) + 0.1*max(x, 0) - 0.1*min(x, 0) against SciPy's solver (an independent integrator)."""
    s = nlobs.System(states=["x"], f=["-x + sat(u, -1, 1) + 0.1*max(x, 0) - 0.1*min(x, 0)"], inputs=["u"], outputs=["y"],
                     h=["x"])
    run = nlobs.simulate(s, None, t_final=6.0, dt=1e-3, x0=[0.2], inputs={"u": "2*sin(t)"}, engine="vm")

    def rhs(t, x):
        u = np.clip(2 * np.sin(t), -1, 1)
        return -x + u + 0.1 * np.maximum(x, 0) - 0.1 * np.minimum(x, 0)

    ref = solve_ivp(rhs, (0, 6), [0.2], t_eval=run.t, rtol=1e-11, atol=1e-12, max_step=1e-3)
    # RK4 over kinks of sat (u crosses ±1) loses an order there: ~dt² per kink
    assert np.max(np.abs(run.x[:, 0] - ref.y[0])) < 1e-6


def test_derivatives_of_min_max_translate():
    """SymPy writes d/dx min(x, 1) with Heaviside; the engine evaluates it (H(0) = 1/2)."""
    from nlobs.engine import to_casadi
    import casadi as ca

    x = symbol("x")
    d = sp.diff(sp.Min(sp.Max(x, 0), 1), x)  # Heaviside(x)*Heaviside(1 - Max(0, x))
    X = ca.SX.sym("x")
    f = ca.Function("f", [X], [to_casadi([d], {x: X})])
    assert [float(f(v)) for v in (-1.0, 0.5, 2.0, 0.0)] == [0.0, 1.0, 0.0, 0.5]


def test_bundled_models_still_load():
    from importlib import resources

    for f in resources.files("nlobs.models").iterdir():
        if f.name.endswith(".toml"):
            mf = nlobs.load_model(f)
            # a bundled model may declare unknown parameters (quadrotor: kd); the observers' system appends them
            assert mf.observer_system.states == mf.system.states + mf.unknown_params


def test_the_reference_model_file_loads_and_recovers_its_parameter():
    """The annotated file of the docs' model-file reference, verbatim: it parses, and a simulation recovers k2
    within 2σ."""
    from pathlib import Path

    page = (Path(__file__).parents[2] / "docs" / "model_files.rst").read_text(encoding="utf-8")
    start = page.index(".. code-block:: toml\n\n", page.index("An annotated file")) + len(".. code-block:: toml\n\n")
    block = re.match(r"((?:   .*\n|\n)+)", page[start:]).group(1)   # the indented lines of the code block
    mf = loads_model(textwrap.dedent(block), path="docs/model_files.rst")
    assert mf.unknown_params == ("k2",) and mf.units["t"] == "s"
    level = mf.sensors["level1"]   # the candidate sensor table, each key as the page says
    assert (str(level.expr), level.noise, level.cost, level.period) == ("x1", 0.02, 2.0, 0.5)
    run = nlobs.simulate(mf, t_final=60.0)
    p = run.parameters("ekf")["k2"]
    assert p["true"] == 0.25 and abs(p["estimate"] - 0.25) < 2 * p["std"]
