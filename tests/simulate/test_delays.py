"""Known measurement delays (issue 21 §3): late samples re-applied at the time they were taken."""

from __future__ import annotations

import json

import numpy as np
import pytest

import nlobs
from nlobs import System
from nlobs.cli import main
from nlobs.simulate import Noise, Sampling
from nlobs.simulate._delays import Events, run_delayed

CART = System(states=["p", "v", "b"], inputs=["a"], outputs=["gps", "wheel"], f=["v", "a - 0.1*v", "0"],
              h=["p", "v + b"], name="cart")
# the issue's check: a 10 Hz and a 4 Hz sensor
CLOCKS = Sampling({"gps": 0.25, "wheel": 0.1})
KW = dict(dt=0.01, x0=[0.0, 1.0, 0.3], inputs={"a": "sin(0.5*t)"}, noise=Noise.per_output({"gps": 0.5, "wheel": 0.1}),
          sampling=CLOCKS, seed=3)


def _ekf():
    return nlobs.design_ekf(CART, R=np.diag([0.25, 0.01]), Q=np.diag([1e-4, 1e-3, 1e-6]), xhat0=[5.0, 0.0, 0.0])


def _samples(run):
    """The run's samples as a recording stamped when they were taken (NaN where an output was not sampled)."""
    return nlobs.Recording.from_arrays(CART, run.t, np.where(run.info["measured"], run.y, np.nan), run.u, x=run.x)


def test_without_delay_the_recalculation_is_the_plain_filter():
    # run_delayed with zero delays against estimate()'s interval runner on the same samples: two code paths
    plant = nlobs.simulate(CART, None, t_final=10.0, **KW)
    rec = _samples(plant)
    ref = nlobs.estimate({"ekf": _ekf()}, rec, on_missing="skip")   # rows between samples measure nothing
    obs = nlobs.Observer(_ekf())
    ev = Events.from_rows(rec.t, rec.y, np.isfinite(rec.y), np.zeros(2), stamped_at_arrival=False)
    Z, X = run_delayed(obs, rec.t, rec.u, ev, obs.initial_state())
    np.testing.assert_allclose(X, ref.observers["ekf"].xhat, rtol=0, atol=1e-9)


def test_the_estimate_at_t_is_the_plain_filter_on_the_samples_arrived_by_t():
    # the definition of exact delay handling, checked at a few times against estimate() on the arrived samples only
    delay = {"gps": 0.15, "wheel": 0.15}
    run = nlobs.simulate(CART, {"ekf": _ekf()}, t_final=6.0, delay=delay, **KW)
    rec = _samples(nlobs.simulate(CART, None, t_final=6.0, **KW))
    for k in (101, 333, 517, 600):
        tk = rec.t[k]
        y = rec.y[:k + 1].copy()
        y[rec.t[:k + 1] + 0.15 > tk + 1e-12] = np.nan          # not arrived by t_k
        part = nlobs.Recording.from_arrays(CART, rec.t[:k + 1], y, rec.u[:k + 1])
        plain = nlobs.estimate({"ekf": _ekf()}, part, on_missing="skip")
        np.testing.assert_allclose(run.observers["ekf"].xhat[k], plain.observers["ekf"].xhat[-1], rtol=0, atol=1e-8)


def test_a_150_ms_latency_costs_less_than_10_percent_of_rms_error_and_ignoring_it_costs_more():
    ref = nlobs.simulate(CART, {"ekf": _ekf()}, t_final=60.0, **KW).metrics("ekf").rms_error
    late = nlobs.simulate(CART, {"ekf": _ekf()}, t_final=60.0, delay={"gps": 0.15, "wheel": 0.15}, **KW)
    assert late.metrics("ekf").rms_error <= 1.10 * ref
    # the same late samples used as if they were current (a recording stamped at arrival, no delay given)
    plant = nlobs.simulate(CART, None, t_final=60.0, **KW)
    shifted = np.full_like(plant.y, np.nan)
    shifted[15:] = np.where(plant.info["measured"], plant.y, np.nan)[:-15]
    naive = nlobs.estimate({"ekf": _ekf()}, nlobs.Recording.from_arrays(CART, plant.t, shifted, plant.u, x=plant.x),
                           on_missing="skip")
    told = nlobs.estimate({"ekf": _ekf()}, nlobs.Recording.from_arrays(CART, plant.t, shifted, plant.u, x=plant.x),
                          on_missing="skip", delay={"gps": 0.15, "wheel": 0.15})
    np.testing.assert_allclose(told.observers["ekf"].xhat, late.observers["ekf"].xhat, rtol=0, atol=1e-9)
    assert naive.metrics("ekf").rms_error > 1.5 * late.metrics("ekf").rms_error


def test_errors_name_what_to_change():
    with pytest.raises(nlobs.ModelError, match="need sampled measurements"):
        nlobs.simulate(CART, {"ekf": _ekf()}, t_final=1.0, dt=0.01, x0=[0, 1, 0.3], delay={"gps": 0.1})
    with pytest.raises(nlobs.ShapeError, match="`delay` names 'z', which is not an output"):
        nlobs.simulate(CART, {"ekf": _ekf()}, t_final=1.0, delay={"z": 0.1}, **{**KW, "sampling": CLOCKS})
    lue = nlobs.design_luenberger(System(states=["x"], outputs=["y"], f=["-x"], h=["x"]), poles=[-2.0])
    with pytest.raises(nlobs.ModelError, match="takes the output continuously; measurement delays are handled by the "
                                               "continuous-discrete observers"):
        nlobs.simulate(System(states=["x"], outputs=["y"], f=["-x"], h=["x"]), {"l": lue}, t_final=1.0, dt=0.01, x0=[1.0],
                       sampling=Sampling(0.1), delay={"y": 0.05})


MODEL = """
name = "cart"
states = ["p", "v", "b"]
inputs = ["a"]
outputs = ["gps", "wheel"]
[dynamics]
p = "v"
v = "a - 0.1*v"
b = "0"
[output]
gps = "p"
wheel = "v + b"
[simulation]
t_final = 10.0
dt = 0.01
x0 = [0.0, 1.0, 0.3]
inputs = { a = "sin(0.5*t)" }
noise = { gps = 0.5, wheel = 0.1 }
sample_period = { gps = 0.25, wheel = 0.1 }
delay = { gps = 0.15, wheel = 0.15 }
seed = 3
[observers.ekf]
kind = "ekf"
xhat0 = [5.0, 0.0, 0.0]
R = [[0.25, 0.0], [0.0, 0.01]]
Q = [[1e-4, 0.0, 0.0], [0.0, 1e-3, 0.0], [0.0, 0.0, 1e-6]]
"""


def test_the_model_file_and_the_command_line(tmp_path, capsys):
    model = tmp_path / "cart.toml"
    model.write_text(MODEL, encoding="utf-8")
    assert main(["simulate", str(model), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    kw = {**KW, "inputs": {"a": "sin(0.5*t)"}}
    ref = nlobs.simulate(CART, {"ekf": _ekf()}, t_final=10.0, delay={"gps": 0.15, "wheel": 0.15}, **kw)
    assert d["observers"]["ekf"]["final_estimate"] == pytest.approx(ref.observers["ekf"].xhat[-1].tolist(), abs=1e-9)
    model.write_text(MODEL.replace("delay = { gps = 0.15, wheel = 0.15 }", "delay = { gps = -1 }"), encoding="utf-8")
    assert main(["simulate", str(model)]) == 1
    assert "simulation.delay.gps" in capsys.readouterr().err


def test_a_delayed_run_written_to_csv_is_stamped_at_arrival_and_estimated_back(tmp_path):
    delay = {"gps": 0.15, "wheel": 0.15}
    run = nlobs.simulate(CART, {"ekf": _ekf()}, t_final=6.0, delay=delay, **KW)
    path = tmp_path / "late.csv"
    run.to_csv(path)
    rec = nlobs.Recording.from_csv(path, CART)
    k_gps = np.flatnonzero(np.isfinite(rec.y[:, 0]))
    np.testing.assert_allclose(rec.t[k_gps[:3]], [0.15, 0.4, 0.65], atol=1e-12)   # taken at 0, 0.25, 0.5; 0.15 s late
    back = nlobs.estimate({"ekf": _ekf()}, rec, delay=delay, on_missing="skip")
    np.testing.assert_allclose(back.observers["ekf"].xhat, run.observers["ekf"].xhat, rtol=0, atol=1e-9)


@pytest.mark.parametrize("engine", ["c", "vm"])
def test_compiled_and_vm_replays_equal_the_plain_filter_on_the_arrived_samples(engine):
    # the definition (issue 36): the estimate at t_k is the undelayed filter run on the samples arrived by t_k, here
    # computed by estimate() on a recording holding only those samples; the replay runs once over the whole run
    delay = {"gps": 0.15, "wheel": 0.03}
    rec = _samples(nlobs.simulate(CART, None, t_final=4.0, **KW))
    obs = nlobs.Observer(_ekf())
    ev = Events.from_rows(rec.t, rec.y, np.isfinite(rec.y), np.array([0.15, 0.03]), stamped_at_arrival=False)
    _, X = run_delayed(obs, rec.t, rec.u, ev, obs.initial_state(), engine=engine)
    for k in (2, 15, 16, 27, 140, 263, 400):
        y = rec.y[:k + 1].copy()
        for j, d in enumerate(delay.values()):
            y[rec.t[:k + 1] + d > rec.t[k] + 1e-12, j] = np.nan
        part = nlobs.Recording.from_arrays(CART, rec.t[:k + 1], y, rec.u[:k + 1])
        plain = nlobs.estimate({"ekf": _ekf()}, part, on_missing="skip", engine=engine)
        np.testing.assert_allclose(X[k], plain.observers["ekf"].xhat[-1], rtol=0, atol=1e-8)


def test_a_delay_between_rows_applies_the_sample_when_it_was_taken():
    # rows every 0.1 s; the gps fix in row k arrived then, 0.037 s late: it was taken at t_k - 0.037, between two
    # rows. Reference: the plain filter on a recording with a row at each taken time of the fixes arrived by t_k (the
    # input held from the row before), the fix in it
    d, rows = 0.037, np.round(np.arange(0.0, 3.0 + 1e-9, 0.1), 12)
    fine = nlobs.simulate(CART, None, t_final=3.0, dt=0.001, x0=[0.0, 1.0, 0.3], inputs={"a": "sin(0.5*t)"})
    at = lambda tt: fine.y_true[np.rint(np.asarray(tt) / 0.001).astype(int)]   # noqa: E731  (outputs on the fine grid)
    u = np.sin(0.5 * rows)[:, None]
    y = np.column_stack([np.r_[np.nan, at(rows[1:] - d)[:, 0]], at(rows)[:, 1]])   # row k: the fix taken at t_k - d
    late = nlobs.estimate({"ekf": _ekf()}, nlobs.Recording.from_arrays(CART, rows, y, u), on_missing="skip",
                          delay={"gps": d})
    for k in (1, 2, 9, 30):
        taken = rows[1:k + 1] - d                            # the fixes arrived by t_k
        grid = np.union1d(rows[:k + 1], taken)
        y_ref = np.full((grid.size, 2), np.nan)
        y_ref[np.searchsorted(grid, rows[:k + 1]), 1] = y[:k + 1, 1]
        y_ref[np.searchsorted(grid, taken), 0] = y[1:k + 1, 0]
        u_ref = np.sin(0.5 * rows[np.searchsorted(rows, grid + 1e-12, side="right") - 1])[:, None]
        ref = nlobs.estimate({"ekf": _ekf()}, nlobs.Recording.from_arrays(CART, grid, y_ref, u_ref), on_missing="skip")
        np.testing.assert_allclose(late.observers["ekf"].xhat[k], ref.observers["ekf"].xhat[-1], rtol=0, atol=1e-8)


def test_the_replay_re_integrates_the_latency_share_of_the_run():
    # gps every 0.25 s and 0.15 s late on a 0.01 s grid: each fix sends the filter back 15 intervals (60 % of the
    # time is integrated twice); the wheel is not late and costs nothing more
    run = nlobs.simulate(CART, {"ekf": _ekf()}, t_final=6.0, delay={"gps": 0.15}, **KW)
    fixes = int(np.sum(np.arange(0.0, 6.0 - 0.15 + 1e-9, 0.25) + 0.15 <= 6.0 + 1e-9))
    assert run.info["replayed"] == 15 * fixes


def test_a_latency_no_sample_outlives_gets_a_note(capsys, tmp_path):
    run = nlobs.simulate(CART, {"ekf": _ekf()}, t_final=1.0, delay={"gps": 1e9}, **KW)
    assert any("no sample of gps arrives within the run" in n and "unit" in n for n in run.info["notes"])
    model = tmp_path / "cart.toml"
    model.write_text(MODEL.replace("delay = { gps = 0.15, wheel = 0.15 }", "delay = { gps = 150 }"), encoding="utf-8")
    assert main(["simulate", str(model)]) == 0
    assert "no sample of gps arrives within the run" in capsys.readouterr().out


def test_samples_taken_a_rounding_error_apart_are_one_knot():
    # t − d rounds either way: 0.35 − 0.3 and 0.55 − 0.5 are 0.04999999999999999 and 0.050000000000000044; the two
    # samples were taken at the same time and are applied together (one update), between the rows 0 and 0.1
    from nlobs.simulate._delays import plan

    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    ev = Events(taken=np.array([0.35 - 0.3, 0.55 - 0.5]), arrived=np.array([0.35, 0.55]), output=np.array([0, 1]),
                value=np.array([1.0, 2.0]))
    assert ev.taken[0] != ev.taken[1]
    p = plan(t, np.zeros((7, 1)), ev, 2)
    at = p.knot_time[(p.knot_time > 0.0) & (p.knot_time < 0.1)]
    assert np.unique(at).size == 1                                 # one knot between rows 0 and 0.1
    last = p.table[p.pass_row == 6]                                # the last pass: both samples at that knot
    mask_cols = slice(2 + 1 + 2 * 2 + 1 + 2, None)
    assert (last[:, mask_cols].sum(axis=1) == 2).sum() == 1


def test_the_particle_filter_applies_to_late_samples(tmp_path):
    # it re-processes from saved particle clouds (tests/simulate/test_delays_pf.py): the advisor offers it
    model = tmp_path / "cart.toml"
    model.write_text(MODEL, encoding="utf-8")
    pf = nlobs.advise(str(model), kinds=["pf"]).candidate("pf")
    assert pf.applies, pf.why


def test_a_delayed_run_written_at_its_samples_keeps_its_first_row(tmp_path):
    # `nlobs simulate --output` writes the rows where a sample arrived; the first row (t = 0, where the observers start
    # and the wheel's first sample was taken) is kept although nothing arrived there yet (the gps fix of t = 0 arrives
    # at 0.15 s): estimate() on the file starts where the run started
    run = nlobs.simulate(CART, {"ekf": _ekf()}, t_final=2.0, delay={"gps": 0.15, "wheel": 0.15}, **KW)
    path = tmp_path / "late.csv"
    run.to_csv(path, every=10)
    rec = nlobs.Recording.from_csv(path, CART)
    assert rec.t[0] == 0.0 and np.all(np.isnan(rec.y[0]))
    assert rec.t[1] == pytest.approx(0.15)
