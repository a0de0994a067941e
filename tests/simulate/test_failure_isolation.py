"""One failing observer does not discard a run (issue 20 §3): simulate, estimate and the CLI keep the
others' results, give the failing one a row with what happened and when, and exit with status 3."""

from __future__ import annotations

import json

import numpy as np
import pytest

import nlobs
from nlobs import FiniteEscapeError, SolverError, System, design_ekf, design_mhe, simulate
from nlobs.cli import main
from nlobs.simulate import Noise, Recording

PEND = System(states=["x1", "x2"], inputs=["u"], outputs=["y"], f=["x2", "-9.81*sin(x1) - 0.5*x2 + u"], h=["x1"],
              name="pendulum")
# the same measurements explained by a model whose x2 escapes in finite time (x2' = x2²), with a filter that
# hardly trusts them (R huge): its estimate blows up at t ≈ 1/20 s
WRONG = System(states=["x1", "x2"], inputs=["u"], outputs=["y"], f=["x2", "x2**2 + u"], h=["x1"], name="pendulum")
RUN = dict(t_final=3.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": "sin(t)"}, noise=Noise.gaussian(0.01), seed=1)


def _good():
    return design_ekf(PEND, R=[[1e-4]], Q=np.diag([1e-4, 1e-2]), xhat0=[0.5, 0.0])


def _bad():
    return design_ekf(WRONG, R=[[1e9]], Q=np.diag([1e-4, 1e-2]), xhat0=[0.5, 20.0])


def test_a_blow_up_leaves_the_other_observers_run_whole():
    run = simulate(PEND, {"ekf": _good(), "bad": _bad(), "ekf2": _good()}, **RUN)
    alone = simulate(PEND, {"ekf": _good()}, **RUN)       # the reference: the good filter without the bad one
    assert list(run.observers) == ["ekf", "ekf2"] and list(run.failures) == ["bad"]
    assert run.t.size == alone.t.size == 3001             # not cut at the failure
    np.testing.assert_array_equal(run.y, alone.y)          # the same measurements (the noise depends only on the seed)
    np.testing.assert_allclose(run.observers["ekf"].xhat, alone.observers["ekf"].xhat, rtol=0, atol=1e-12)
    f = run.failures["bad"]
    # x2' = x2² from 20 escapes at t = 1/20; the step after the last finite one holds the covariance entries that overflowed
    assert f.error == "FiniteEscapeError" and 0.045 <= f.t <= 0.06   # RK4 lags the exact escape a little
    assert f.reason.startswith(f"blew up after t = {f.t:.6g} (P_") and "in the next step" in f.reason
    text = str(run.summary())
    assert "FAILED after t = " in text and "bad failed: blew up" in text and "the other observers ran without it" in text
    d = run.summary_dict()
    assert d["failed"] == ["bad"] and d["observers"]["bad"]["failed"] is True and "final_error" in d["observers"]["ekf"]
    with pytest.raises(KeyError, match="observer 'bad' failed in this run: blew up"):
        run.metrics("bad")


def test_when_every_observer_fails_the_first_error_is_raised_and_a_plant_blow_up_still_stops_the_run():
    with pytest.raises(FiniteEscapeError, match="observer 'bad' blew up"):
        simulate(PEND, {"bad": _bad(), "bad2": _bad()}, **RUN)
    escaping = System(states=["x"], outputs=["y"], f=["x**2"], h=["x"], name="escape")   # x(t) = 1/(1 - t)
    obs = design_ekf(escaping, R=[[1.0]], Q=[[1.0]], xhat0=[1.0])
    with pytest.raises(FiniteEscapeError, match="^plant blew up"):
        simulate(escaping, {"ekf": obs}, t_final=2.0, dt=1e-3, x0=[1.0])


def test_a_long_state_is_shown_by_its_largest_entries_and_the_ones_that_blew_up():
    # a 6-state filter carries 6 + 36 entries: the message names the culprits, not all 42 numbers
    n = 6
    chain = System(states=[f"x{i}" for i in range(n)], outputs=["y"], f=[f"x{i + 1}" for i in range(n - 1)] + ["x5**2"],
                   h=["x0"], name="chain")
    bad = design_ekf(chain, R=[[1e9]], Q=np.eye(n) * 1e-4, xhat0=[0, 0, 0, 0, 0, 30.0])
    good = design_ekf(chain, R=[[1e-4]], Q=np.eye(n) * 1e-4, xhat0=[0.0] * n)
    run = simulate(chain, {"good": good, "bad": bad}, t_final=0.5, dt=1e-3, x0=[0.0] * n)
    msg = run.failures["bad"].message
    assert "(the largest 6 of 42 entries)" in msg and msg.count("=") < 16


def _noisy_pendulum():
    sim = simulate(PEND, None, **RUN)
    return Recording.from_arrays(PEND, sim.t[::10], sim.y[::10], sim.u[::10], x=sim.x[::10])


def test_estimate_keeps_the_others_when_an_mhe_window_cannot_be_solved():
    rec = _noisy_pendulum()
    mhe = design_mhe(PEND, horizon=6, R=[[1e-4]], Q=0.01 * np.eye(2), P0=100 * np.eye(2), xhat0=[8.0, -8.0], max_iter=1)
    run = nlobs.estimate({"mhe": mhe, "ekf": _good()}, rec)
    alone = nlobs.estimate({"ekf": _good()}, rec)
    assert list(run.observers) == ["ekf"] and run.failures["mhe"].error == "SolverError"
    assert run.failures["mhe"].reason.startswith("its optimisation failed on the data up to t = ")
    assert "the window at t = " in run.failures["mhe"].message      # not "t in [0, 0]"
    np.testing.assert_array_equal(run.observers["ekf"].xhat, alone.observers["ekf"].xhat)
    with pytest.raises(SolverError):
        nlobs.estimate({"mhe": mhe}, rec)


MODEL = """
name = "pendulum"
states = ["x1", "x2"]
inputs = ["u"]
outputs = ["y"]
[dynamics]
x1 = "x2"
x2 = "-9.81*sin(x1) - 0.5*x2 + u + 0.001*x2**3"
[output]
y = "x1"
[simulation]
t_final = 2.0
dt = 1e-3
x0 = [1.0, 0.0]
inputs = { u = "sin(t)" }
noise = { y = 0.01 }
seed = 1
[observers.ekf]
kind = "ekf"
xhat0 = [0.5, 0.0]
Q = [[1e-4, 0.0], [0.0, 1e-2]]
R = [[1e-4]]
[observers.bad]
kind = "ekf"
xhat0 = [0.5, 100.0]
Q = [[1e-4, 0.0], [0.0, 1e-2]]
R = [[1e9]]
"""


def test_the_command_line_writes_the_others_and_exits_with_status_3(tmp_path, capsys):
    # the cubic term is harmless where the pendulum swings (|x2| < 3) but makes an estimate started at x2 = 100
    # escape in finite time (x2' ≈ 0.001·x2³: t = 1/(2·0.001·100²) = 0.05 s), and R = 1e9 keeps the data from helping
    model = tmp_path / "pendulum.toml"
    model.write_text(MODEL, encoding="utf-8")
    out = tmp_path / "run.csv"
    status = main(["simulate", str(model), "--json", "--output", str(out)])
    cap = capsys.readouterr()
    assert status == 3
    d = json.loads(cap.out)
    assert d["failed"] == ["bad"] and d["observers"]["bad"]["failed"] and d["observers"]["ekf"]["final_error"] < 0.1
    assert "nlobs: observer 'bad' failed: observer 'bad' blew up after t = 0.0" in cap.err
    header = out.read_text(encoding="utf-8").splitlines()[0].split(",")
    assert "ekf.x1" in header and "bad.x1" not in header


def test_montecarlo_counts_a_failure_against_the_failing_observer_only():
    kw = dict(t_final=3.0, dt=1e-3, x0=[1.0, 0.0], runs=4, inputs={"u": "sin(t)"}, noise=Noise.gaussian(0.01))
    mc = nlobs.montecarlo(PEND, {"ekf": _good(), "bad": _bad()}, **kw)
    ref = nlobs.montecarlo(PEND, {"ekf": _good()}, **kw)          # the good filter without the bad one
    assert mc.stats("ekf")["failed"] == 0 and mc.stats("bad")["failed"] == 4 and mc.failed.size == 0
    np.testing.assert_allclose(mc.observers["ekf"].xhat, ref.observers["ekf"].xhat, rtol=0, atol=1e-12)
    assert mc.stats("ekf")["rms_error_median"] == ref.stats("ekf")["rms_error_median"]
    assert all(reason.startswith("observer 'bad' blew up after t = ") for _, reason in mc.failures)
    df_failed = [bool(v) for v in np.isnan(mc.observers["bad"].final_error)]
    assert df_failed == [True] * 4
