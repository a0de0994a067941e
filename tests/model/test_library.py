"""The bundled model library: every model loads, cites its source, simulates, and is usable by name."""

from __future__ import annotations

import numpy as np
import pytest

import nlobs
from nlobs.model import bundled_names, bundled_path, library, load_model
from nlobs.references import REFERENCES, cited_keys


def test_at_least_fifteen_classic_models_each_citing_a_known_source():
    entries = library()
    names = {e.name for e in entries}
    assert len(entries) >= 15
    assert {"pendulum", "van_der_pol", "duffing", "lorenz", "rossler", "lotka_volterra", "sir", "seir", "cstr",
            "cascaded_tanks", "unicycle", "dc_motor", "cart_pole", "bioreactor", "cuk", "range_localisation"} <= names
    for e in entries:
        keys = cited_keys(e.description)
        assert keys and all(k in REFERENCES for k in keys), e.name        # the source, by author and year
        assert "00" not in e.description.replace("(200", "").replace("(201", ""), e.name   # no bare paper numbers


@pytest.mark.parametrize("name", bundled_names())
def test_every_bundled_model_has_a_simulation_that_runs(name):
    mf = load_model(name)
    cfg = mf.simulation
    assert cfg.x0 is not None and cfg.t_final and cfg.dt, name
    dt = max(cfg.dt, cfg.t_final / 2000)                                  # a coarse pass: finite and bounded
    dt = cfg.t_final / round(cfg.t_final / dt)
    run = nlobs.simulate(mf.system, None, t_final=cfg.t_final, dt=dt, x0=cfg.x0, inputs=dict(cfg.inputs), engine="vm")
    assert np.all(np.isfinite(run.x)) and np.abs(run.x).max() < 1e6


def test_a_bundled_name_works_wherever_a_path_does(tmp_path, monkeypatch):
    assert load_model("lorenz").system.n_states == 3
    assert load_model("lorenz.toml").path == str(bundled_path("lorenz"))
    own = tmp_path / "lorenz"                                             # a user's file of the same name wins
    own.write_text('states = ["a"]\noutputs = ["y"]\n[dynamics]\na = "-a"\n[output]\ny = "a"\n')
    monkeypatch.chdir(tmp_path)
    assert load_model("lorenz").system.states == ("a",)
    with pytest.raises(nlobs.ModelFileError, match="not a bundled model name either"):
        load_model("no_such_model")
    assert bundled_path("../models/lorenz") is None and bundled_path("a/b") is None
