"""Piecewise models (abs, sign, min, max, sat) analysed one regime at a time (issue 9 item 3)."""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pytest

import nlobs
from nlobs import System
from nlobs.cli import main
from nlobs.analysis import visited_regimes

# the cascaded-tanks shape: the lower tank is measured through a saturating sensor
TANKS = dict(states=["x1", "x2"], f=["u - sqrt(max(x1, 0))", "sqrt(max(x1, 0)) - sqrt(max(x2, 0))"], inputs=["u"],
             outputs=["y"], h=["sat(x2, 0, ymax)"], params={"ymax": 10.0})


def test_default_regime_is_the_unsaturated_one_and_says_so():
    rep = nlobs.analyze(System(**TANKS))
    assert rep.observable
    assert any("min(10, max(0, x2)) is analysed as max(0, x2) (the unsaturated branch)" in n for n in rep.notes)


def test_saturated_regime_is_not_observable_and_equals_the_smooth_model():
    """In saturation y = ymax carries no information: rank 0, as for the model written with y = 10 (independent)."""
    sat = nlobs.analyze(System(**TANKS), regime={"x1": 1.0, "x2": 12.0})
    smooth = nlobs.analyze(System(**{**TANKS, "h": ["ymax"]}))
    assert sat.rank == smooth.rank == 0
    inside = nlobs.analyze(System(**TANKS), regime={"x1": 1.0, "x2": 4.0})
    smooth_inside = nlobs.analyze(System(**{**TANKS, "f": ["u - sqrt(x1)", "sqrt(x1) - sqrt(x2)"], "h": ["x2"]}))
    assert inside.rank == smooth_inside.rank == 2


def test_abs_branch_follows_the_regime_not_sympys_argument_order():
    """SymPy stores abs(ymax - x2) as Abs(x2 - ymax): the default (argument > 0) would take the wrong side for
    x2 < ymax; with a regime point, the branch active there is taken and named."""
    s = System(states=["x1", "x2"], f=["-x1 + u + x2/10", "x1 - abs(ymax - x2)"], inputs=["u"], outputs=["y"], h=["x1"],
               params={"ymax": 10.0})
    rep = nlobs.analyze(s, regime={"x1": 1.0, "x2": 3.0})
    assert any("abs(x2 - 10) is analysed where x2 - 10 < 0, as 10 - x2" in n for n in rep.notes), rep.notes
    assert rep.observable  # x2 enters x1' = -x1 + u + x2/10, and x1 = y


def test_regime_point_is_checked():
    s = System(**TANKS)
    with pytest.raises(nlobs.ModelError, match="every state.*missing: x2"):
        nlobs.analyze(s, regime={"x1": 1.0})
    with pytest.raises(nlobs.ModelError, match="'zz'"):
        nlobs.analyze(s, regime={"x1": 1.0, "x2": 1.0, "zz": 0})


def test_visited_regimes_fractions_match_the_trajectory():
    """x2 rises linearly from 0 to 15: it is above ymax = 10 for exactly the samples with 1.5 t > 10."""
    t = np.linspace(0, 10, 1001)
    x2 = 1.5 * t
    regs = visited_regimes(System(**TANKS), {"x1": np.ones_like(t), "x2": x2, "t": t})
    assert len(regs) == 2 and abs(sum(r.fraction for r in regs) - 1) < 1e-15
    above = np.count_nonzero(x2 > 10.0) / t.size
    assert abs(regs[1].fraction - above) < 1e-15 and regs[1].point["x2"] > 10
    assert "min(10, max(0, x2)) = 10" in regs[1].branches and "min(10, max(0, x2)) = max(0, x2)" in regs[0].branches
    assert visited_regimes(System(states=["x"], f=["-x"], outputs=["y"], h=["x"]), {"x": [1.0, 2.0]}) == []


FILE = textwrap.dedent('''
    name = "sat_tanks"
    states = ["x1", "x2"]
    inputs = ["u"]
    outputs = ["y"]
    [parameters]
    ymax = 2.0
    k = { value = 0.5, unknown = true }
    [dynamics]
    x1 = "u - sqrt(max(x1, 0))"
    x2 = "sqrt(max(x1, 0)) - k*sqrt(max(x2, 0))"
    [output]
    y = "sat(x2, 0, ymax)"
    [simulation]
    t_final = 30.0
    dt = 0.01
    x0 = [0.5, 0.5]
    inputs = { u = "1.2" }
''')


def test_cli_analyze_uses_the_regimes_the_simulation_visits(tmp_path, capsys):
    """With u = 1.2 the levels settle at x1 = 1.44, x2 = 5.76 > ymax: the sensor saturates for most of the run."""
    p = tmp_path / "sat.toml"
    p.write_text(FILE)
    assert main(["analyze", str(p), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["unknown_params"] == ["k"]  # the file's unknown parameters, without --params
    regs = out["regimes"]
    assert len(regs) == 2 and regs[0]["fraction"] > 0.5
    assert "min(2, max(0, x2)) = 2" in regs[0]["branches"] and regs[0]["report"]["rank"] == 0
    assert regs[1]["report"]["observable"] and regs[1]["report"]["identifiable_params"] == ["k"]
    assert main(["analyze", str(p), "--regime", "default", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["observable"]
    assert main(["analyze", str(p), "--regime", "x1=1,x2=3", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["rank"] == 0


def test_cli_params_errors_name_the_flag(tmp_path, capsys):
    p = tmp_path / "sat.toml"
    p.write_text(FILE)
    assert main(["analyze", str(p), "--params", "zz"]) == 1
    err = capsys.readouterr().err
    assert "--params: 'zz' is not a parameter" in err and "unknown_params" not in err
    assert main(["analyze", str(p), "--regime", "x1=one"]) == 1
    assert "--regime: 'one' is not a number" in capsys.readouterr().err
