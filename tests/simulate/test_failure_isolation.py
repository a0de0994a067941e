"""One failing observer does not discard a run (issue 20 §3): simulate, estimate and the CLI keep the
others' results, give the failing one a row with what happened and when, and exit with status 3."""

from __future__ import annotations

import json

import numpy as np
import pytest

import nlobs
from nlobs import FiniteEscapeError, SolverError, System, design_ekf, design_mhe, simulate
from nlobs.errors import EngineError
from nlobs.cli import main
from nlobs.estimation import Recording
from nlobs.simulate import Noise

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


# -- every path keeps the others (issue 36 §3): one candidate fails, every other one equals its run alone ---------------

def _cart():
    return System(states=["p", "v", "b"], inputs=["a"], outputs=["gps", "wheel"], f=["v", "a - 0.1*v", "0"],
                  h=["p", "v + b"], name="cart")


def _cart_wrong():
    # the same measurements explained by a velocity that escapes in finite time (v' = v²): started at v = 40 with a
    # filter that hardly trusts the data, its estimate blows up at t ≈ 1/40 s
    return System(states=["p", "v", "b"], inputs=["a"], outputs=["gps", "wheel"], f=["v", "a + v**2", "0"],
                  h=["p", "v + b"], name="cart")


def _cart_ekfs():
    good = nlobs.design_ekf(_cart(), R=np.diag([0.25, 0.01]), Q=np.diag([1e-4, 1e-3, 1e-6]), xhat0=[5.0, 0.0, 0.0])
    other = nlobs.design_ekf(_cart(), R=np.diag([1.0, 0.04]), Q=np.diag([1e-3, 1e-2, 1e-5]), xhat0=[-3.0, 2.0, 0.1])
    bad = nlobs.design_ekf(_cart_wrong(), R=np.diag([1e9, 1e9]), Q=np.diag([1e-4, 1e-3, 1e-6]), xhat0=[0.0, 40.0, 0.0])
    return good, other, bad


CART_RUN = dict(t_final=3.0, dt=0.01, x0=[0.0, 1.0, 0.3], inputs={"a": "sin(0.5*t)"},
                noise=Noise.per_output({"gps": 0.5, "wheel": 0.1}), sampling=nlobs.Sampling({"gps": 0.25, "wheel": 0.1}),
                seed=3)


@pytest.mark.parametrize("path", ["multirate", "delayed", "estimate", "estimate_delayed"])
def test_one_failing_candidate_leaves_every_other_result_as_it_is_alone(path):
    good, other, bad = _cart_ekfs()
    delay = {"gps": 0.15} if "delayed" in path else None
    if path.startswith("estimate"):
        plant = simulate(_cart(), None, **{**CART_RUN, "delay": delay})
        rec = Recording.from_arrays(_cart(), plant.t, np.where(plant.info["measured"], plant.y, np.nan), plant.u, x=plant.x)

        def run(obs):
            return nlobs.estimate(obs, rec, on_missing="skip", delay=delay)
    else:
        def run(obs):
            return simulate(_cart(), obs, **{**CART_RUN, "delay": delay})
    both = run({"good": good, "bad": bad, "other": other})
    assert list(both.observers) == ["good", "other"] and list(both.failures) == ["bad"]
    assert both.failures["bad"].error == "FiniteEscapeError"
    for name, d in (("good", good), ("other", other)):
        alone = run({name: d})
        np.testing.assert_allclose(both.observers[name].xhat, alone.observers[name].xhat, rtol=0, atol=1e-12)


def test_a_map_observer_that_fails_leaves_the_others():
    plant = System(states=["x"], outputs=["y"], f=["0.9*x"], h=["x"], time="discrete", sample_time=0.1, name="decay")
    # a filter whose model neither sees x in its output nor stays bounded: x[k+1] = 2x² from 3 overflows in ~10 steps
    wrong = System(states=["x"], outputs=["y"], f=["2*x**2"], h=["0*x"], time="discrete", sample_time=0.1, name="decay")
    good = nlobs.design_ekf(plant, Q=[[1e-4]], R=[[1e-2]], xhat0=[0.5])
    bad = nlobs.design_ekf(wrong, Q=[[1e-4]], R=[[1e-2]], xhat0=[3.0])
    both = simulate(plant, {"good": good, "bad": bad}, t_final=5.0, x0=[1.0], noise=Noise.gaussian(0.01), seed=2)
    alone = simulate(plant, {"good": good}, t_final=5.0, x0=[1.0], noise=Noise.gaussian(0.01), seed=2)
    assert list(both.observers) == ["good"] and both.failures["bad"].error == "FiniteEscapeError"
    np.testing.assert_array_equal(both.observers["good"].xhat, alone.observers["good"].xhat)


def test_a_particle_filter_that_fails_leaves_the_others():
    good, _, _ = _cart_ekfs()
    pf = nlobs.design_pf(_cart_wrong(), Q=np.diag([1e-4, 1e-3, 1e-6]), R=np.diag([1e9, 1e9]), xhat0=[0.0, 40.0, 0.0],
                         P0=np.diag([1e-2, 1e-2, 1e-2]), particles=200)
    both = simulate(_cart(), {"good": good, "pf": pf}, **CART_RUN)
    alone = simulate(_cart(), {"good": good}, **CART_RUN)
    assert list(both.observers) == ["good"] and "pf" in both.failures
    np.testing.assert_allclose(both.observers["good"].xhat, alone.observers["good"].xhat, rtol=0, atol=1e-12)


def test_an_mhe_whose_window_cannot_be_solved_leaves_the_others_in_simulate():
    mhe = design_mhe(PEND, horizon=6, R=[[1e-4]], Q=0.01 * np.eye(2), P0=100 * np.eye(2), xhat0=[8.0, -8.0], max_iter=1)
    kw = {**RUN, "t_final": 1.0, "sampling": nlobs.Sampling(0.01)}
    both = simulate(PEND, {"mhe": mhe, "ekf": _good()}, **kw)
    alone = simulate(PEND, {"ekf": _good()}, **kw)
    assert list(both.observers) == ["ekf"] and both.failures["mhe"].error == "SolverError"
    np.testing.assert_allclose(both.observers["ekf"].xhat, alone.observers["ekf"].xhat, rtol=0, atol=1e-12)


def test_a_failed_compile_is_that_candidates_failure(monkeypatch):
    # gcc refusing one observer's code (an EngineError while building its step) fails that observer, not the run
    from nlobs.engine import _codegen

    good, other, _ = _cart_ekfs()
    real = _codegen._compile_driver
    calls = []

    def picky(step, template, tag, no, sig=None):
        calls.append(step)
        if len(calls) == 1:
            raise EngineError("the C compiler /usr/bin/gcc failed on the generated code for loop: (simulated)")
        return real(step, template, tag, no, sig)

    monkeypatch.setattr(_codegen, "_compile_driver", picky)
    import nlobs.engine._integrate as integ
    monkeypatch.setattr(integ, "_LOOPS", {})
    run = simulate(_cart(), {"good": good, "other": other}, **{**CART_RUN, "engine": "c"})
    assert len(run.observers) == 1 and len(run.failures) == 1
    (name, f), = run.failures.items()
    assert f.error == "EngineError" and "C compiler" in f.reason


def test_with_the_automatic_engine_a_failed_compile_falls_back_to_the_virtual_machine(monkeypatch):
    from nlobs.engine import _codegen
    import nlobs.engine._integrate as integ

    good, _, _ = _cart_ekfs()
    vm = simulate(_cart(), {"good": good}, **{**CART_RUN, "engine": "vm"})

    def refuse(*args, **kw):
        raise EngineError("the C compiler /usr/bin/gcc failed on the generated code for loop: (simulated)")

    monkeypatch.setattr(_codegen, "_compile_driver", refuse)
    monkeypatch.setattr(integ, "_LOOPS", {})
    monkeypatch.setattr(integ, "choose_backend", lambda *a, **k: "c")   # "auto" decides to compile
    with pytest.warns(nlobs.ConvergenceWarning, match="C compiler .* running on CasADi's virtual machine instead"):
        run = simulate(_cart(), {"good": good}, **CART_RUN)
    np.testing.assert_allclose(run.observers["good"].xhat, vm.observers["good"].xhat, rtol=0, atol=1e-12)


# -- time budgets (nlobs design --run --budget): a candidate that does not finish in time is its own failure -----------

def test_a_compiled_loop_stops_at_its_deadline():
    import time as _time

    import casadi as ca

    from nlobs.engine import StepRunner
    from nlobs.engine._budget import time_budget

    s, a, c = ca.SX.sym("s", 2), ca.SX.sym("a", 1), ca.SX.sym("c", 1)
    step = ca.Function("slow", [s, a, c], [ca.vertcat(s[0] + c * ca.sin(s[1]), s[1] + c * ca.cos(s[0]))])
    runner = StepRunner(step, backend="c")
    runner.run(np.zeros(2), np.zeros((10, 1)), np.array([1e-3]))   # compiled (cached) before the clock starts
    t0 = _time.perf_counter()
    with time_budget(0.2), pytest.raises(nlobs.TimeBudgetError, match=r"did not finish within 0.2 s .*compiled loop"):
        runner.run(np.zeros(2), np.zeros((3 * 10**8, 1)), np.array([1e-3]))
    assert _time.perf_counter() - t0 < 5.0                        # stopped, not run to the end (minutes)


def test_design_run_reports_a_candidate_over_its_budget_and_ranks_the_others(tmp_path, monkeypatch):
    import time as _time

    import importlib

    run_mod = importlib.import_module("nlobs.simulate._run")

    model = tmp_path / "pendulum.toml"
    model.write_text(MODEL.split("[observers.ekf]")[0], encoding="utf-8")
    real = run_mod.Simulation._run_all

    def slow_ukf(self, *args, **kw):   # the ukf's part takes longer than its budget, then checks its deadline
        if "ukf" in self._prep.obs:
            _time.sleep(0.6)
            from nlobs.engine._budget import check_time
            check_time("running on CasADi's virtual machine")
        return real(self, *args, **kw)

    monkeypatch.setattr(run_mod.Simulation, "_run_all", slow_ukf)
    adv = nlobs.advise(str(model), kinds=["ekf", "ukf"], run=True, budget=0.5)
    by = {s.kind: s for s in adv.scores}
    assert by["ekf"].status == "ok" and by["ukf"].status == "failed"
    assert by["ukf"].detail.startswith("did not finish within 0.5 s")
    assert "ukf" in str(adv) and "did not finish within 0.5 s" in str(adv)


def test_a_filter_whose_covariance_turns_indefinite_is_reported_where_it_did_not_where_it_overflowed():
    """Issue 44, item 4 (acceptance): on a stiff overflow (rate 300/s above a tank's rim) RK4 at the run's dt = 0.01
    is unstable for the EKF's covariance. Its variances turned negative steps before anything left |x| <= 1e12, and
    the error showed that state (P_0_0 = -4e9, P_1_1 = -666) as the "last finite state". It must name the step where
    the covariance lost its positive definiteness and show the last state before it, every variance >= 0."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "benchmarks" / "models" / "relay_overflow_tanks.toml").read_text()
    mf = nlobs.loads_model(text.replace("c = 2000.0", "c = 150.0"), path="relay.toml")
    with pytest.raises(FiniteEscapeError) as info:
        simulate(mf, ["ekf"])
    err, msg = info.value, str(info.value)
    assert "covariance" in msg and "last finite state" not in msg and "reduce `dt`" in msg
    P = {k: v for k, v in zip(("P_0_0", "P_1_0", "P_0_1", "P_1_1"), err.x[2:6])}
    assert P["P_0_0"] >= 0 and P["P_1_1"] >= 0 and P["P_0_0"] * P["P_1_1"] >= P["P_1_0"] ** 2 * (1 - 1e-9)
    assert err.t < 2.0   # before the sample at t = 2, where the old report stood
