"""Sub-steps between samples on a flow with a kink (sign, abs, min, max): the stiffness rule must not
chase it. Across a jump of the vector field the RK4 rate estimate ‖k3 − k2‖/‖Y3 − Y2‖ grows as 1/h,
so h·rate does not shrink when the step does; refining until it does never ends (it took minutes
and ~10⁸ sub-steps per interval on a relay model and on the cascaded tanks' overflow)."""

from __future__ import annotations

import signal

import numpy as np
import pytest

import nlobs
from nlobs.design import design_ekf

RELAY = nlobs.System(states=["x"], outputs=["y"], f=["-sign(x) - 0.1*x"], h=["x"], name="relay")


@pytest.fixture
def time_limit():
    def expire(*_):
        raise TimeoutError("the run did not finish within 60 s: the sub-step rule is chasing the kink")

    old = signal.signal(signal.SIGALRM, expire)
    signal.alarm(60)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


def _recording():
    t = np.arange(0.0, 20.0, 1.0)  # 1 s between samples: many sub-steps of a flow that chatters around x = 0
    y = np.maximum(3.0 - t, 0.0) + 0.01 * np.sin(t)
    return nlobs.Recording.from_arrays(RELAY, t, y[:, None])


def test_a_relay_flow_is_integrated_with_few_substeps_on_both_engines(time_limit):
    rec = _recording()
    runs = {e: nlobs.estimate({"ekf": design_ekf(RELAY, Q=[[1e-2]], R=[[1e-4]], xhat0=[2.5])}, rec, engine=e)
            for e in ("vm", "c")}
    for e, run in runs.items():
        info = run.info["integration"]["ekf"]
        # the smooth part needs 1 sub-step per second (rate 0.1); each sample that sits on the kink at most
        # doubles its count once (3), and the kink's step-doubling check once more (6: its end state then moves by
        # less than 1 % of itself): the measured total is 99 on both engines (51 before the check)
        assert info["max_substeps"] <= 8 and info["substeps"] <= 8 * (rec.t.size - 1), (e, info)
        assert np.isfinite(run.observers["ekf"].xhat).all()
    # the two engines run the same rule: the same sub-steps, the same estimates to round-off
    assert runs["vm"].info["integration"]["ekf"]["substeps"] == runs["c"].info["integration"]["ekf"]["substeps"]
    assert np.abs(runs["vm"].observers["ekf"].xhat - runs["c"].observers["ekf"].xhat).max() < 1e-12
    # the estimate follows the recording down to the relay's sliding set x = 0 (chattering of order h there)
    assert np.abs(runs["c"].observers["ekf"].xhat[4:, 0]).max() < 0.05


def test_a_stiff_mode_is_still_refined(time_limit):
    """A genuinely fast mode keeps its rate as h shrinks: the rule still refines (h·rate ≤ target)."""
    fast = nlobs.System(states=["x1", "x2"], outputs=["y"], f=["-x1 + x2", "-400*x2"], h=["x1"], name="fast")
    t = np.arange(0.0, 2.0, 0.5)
    rec = nlobs.Recording.from_arrays(fast, t, np.exp(-t)[:, None])
    run = nlobs.estimate({"ekf": design_ekf(fast, Q=np.eye(2) * 1e-3, R=[[1e-4]], xhat0=[1.0, 1.0])}, rec, engine="vm")
    info = run.info["integration"]["ekf"]
    # rate 400 (x2) and 800 (its covariance entry P22' = -800 P22 + ...): h·rate ≤ 1 needs ≥ 400 sub-steps per 0.5 s
    assert info["max_substeps"] >= 400, info
    assert np.isfinite(run.observers["ekf"].xhat).all()
    # at rest (x2 ~ 1e-9, P at its steady state) the fast mode is all but absent from the RK4 stages' first quotient;
    # one 0.5 s step amplifies it by ~1e9 and took P22 to -20 (issue 44 item 4): the last two stages see it. P22's
    # steady state: P22' = -800 P22 + Q22 (x2 is not measured, and its coupling to x1 is one-way), 1e-3/800.
    o = run.observers["ekf"]
    P22 = o.z[:, list(o.z_names).index("P_1_1")]
    assert np.all(np.abs(P22[1:] / (1e-3 / 800) - 1) < 0.05), P22


# -- the step-doubling check of an interval taken for a kink (engine/_intervals.py, KINK_*) ---------------------------

def _runner(grow: bool, backend: str):
    """A sub-step whose measured rate is 3/h whatever h (so more sub-steps never shrink h·rate: it is taken for a
    kink: h·rate = 3 > reject = 2). grow=False: a relay x' = -sign(x) (a true kink: the end state converges as h shrinks); grow=True: each
    sub-step multiplies x by (1 + 0.05/h) (an end state that runs away as the sub-steps double: a diverging
    interval, finite at every count)."""
    import casadi as ca

    from nlobs.engine._intervals import IntervalRunner

    s, a, th = ca.SX.sym("s", 1), ca.SX.sym("a", 2), ca.SX.sym("th", 2)
    h = th[1]
    nxt = s * (1 + 0.05 / h) if grow else s - h * ca.sign(s)
    sub = ca.Function("sub", [s, a, th], [nxt, 3 / h])
    jump = ca.Function("jump", [s, a], [s, s])
    return IntervalRunner(sub, jump, backend=backend)


@pytest.mark.parametrize("backend", ["vm", "c"])
def test_an_interval_taken_for_a_kink_is_refused_when_step_doubling_shows_it_diverging(backend, time_limit):
    A = np.array([[0.0, 1.0], [1.0, 1.0]])
    res = _runner(True, backend).run(np.array([1e-3]), A, np.ones(2), rate0=1.0)
    assert res.failed == 0 and res.unconverged is not None and res.unconverged > 10, res
    ok = _runner(False, backend).run(np.array([0.3]), A, np.ones(2), rate0=1.0)
    assert ok.failed is None and ok.unconverged is None and np.isfinite(ok.states).all()
    assert abs(ok.states[-1, 0]) < 0.05   # chattering around the relay's sliding set, of the order of h
    assert ok.substeps.max() <= 16 * 16   # the check costs at most 2 + 4 + 8 times a kink's sub-steps more


def test_the_kink_constants_of_the_c_driver_are_the_python_ones():
    from nlobs.engine import _intervals as I

    for name in ("KINK_DOUBLINGS", "KINK_RTOL", "KINK_ATOL", "KINK_SHRINK", "REDO_GROWTH", "BLOWUP_REDOS"):
        line = next(ln for ln in I._C_DRIVER.splitlines() if ln.startswith(f"#define {name} "))
        assert float(line.split()[-1]) == float(getattr(I, name))


# -- a fast mode that only the last RK4 stage enters (issue 44 item 4) -------------------------------------------------

def test_a_weir_that_only_the_last_stage_overflows_is_refined_on_both_engines(tmp_path, time_limit):
    """The grey-box Cascaded Tanks file with the weir as steep as the likelihood fit clamps it (w = 4610) on the real
    record: at t = 584 s the upper tank sits 2e-4 above its top. One RK4 step of 4 s has Y2, Y3 below the weir's
    steep part or past the Torricelli outflow's domain (its Jacobian NaN at x1 < 0), and only Y4 on it: the
    equal-time quotient ‖k3 − k2‖/‖Y3 − Y2‖ saw nothing, the step was taken and x1 went to −1400 (a non-finite state
    at t = 588). The rate now includes the last two stages' quotient over their finite entries; the run must go
    through and agree with one at a forced step 400 times finer (0.01 s: the converged solution, whatever the
    rate rule says)."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    text = (root / "benchmarks" / "models" / "cascaded_tanks_greybox.toml").read_text(encoding="utf-8")
    path = tmp_path / "steep_weir.toml"
    path.write_text(text.replace("\nw = 1.0\n", "\nw = 4610.0\n"), encoding="utf-8")
    system = nlobs.load_model(path).system
    assert dict(zip(system.param_names, system.param_values))["w"] == 4610.0
    rec = nlobs.Recording.from_csv(root / "tests" / "data" / "cascaded_tanks_estimation.csv", system)
    d = design_ekf(system, Q=np.eye(2) * 1e-4, R=[[1e-4]], xhat0=[6.0, 5.2], P0=np.diag([4.0, 0.04]))
    ref = nlobs.estimate({"ekf": d}, rec, engine="c", max_step=0.01).observers["ekf"].xhat
    k = int(np.flatnonzero(rec.t == 584.0)[0])
    for e in ("vm", "c"):
        run = nlobs.estimate({"ekf": d}, rec, engine=e)
        x = run.observers["ekf"].xhat
        assert np.isfinite(x).all() and x[:, 0].min() > 2.0 and x[:, 0].max() < 10.1, e
        assert np.abs(x - ref).max() < 1e-4, (e, np.abs(x - ref).max(axis=0))
        assert abs(x[k + 1, 0] - 10.0) < 0.01, (e, x[k + 1])


@pytest.mark.parametrize("grow", [True, False])
def test_the_rows_after_a_failure_or_a_refusal_read_the_same_on_both_engines(grow, time_limit):
    """The compiled driver leaves the rows it did not reach unwritten (its arrays are not pre-filled): they must read
    as the VM's do, NaN states and rates and 0 sub-steps from the interval that failed (or was refused) on."""
    A = np.array([[0.0, 1.0], [1.0, 1.0], [2.0, 1.0], [3.0, 1.0]])
    runs = {}
    for b in ("vm", "c"):
        r = _runner(grow, b)
        runs[b] = r.run(np.array([1e-3 if grow else 0.3]), A, np.ones(4), rate0=1.0,
                        **({} if grow else {"max_substeps": 2}))   # the relay refused: its kink needs more than 2
    vm, c = runs["vm"], runs["c"]
    assert (vm.failed, vm.refused) == (c.failed, c.refused) and (c.failed is not None or c.refused is not None)
    k = c.failed if c.failed is not None else c.refused[0]
    for res in (vm, c):
        assert np.isnan(res.states[k + 1:]).all() and np.isnan(res.rate[k + 1:]).all()
        assert (res.substeps[k + 1:] == 0).all()
    if c.refused is not None:
        assert np.isnan(c.rate[k]) and c.substeps[k] == 0 and np.isnan(c.states[k]).all()
    np.testing.assert_array_equal(vm.substeps, c.substeps)


# -- an interval whose state becomes non-finite before its rate is measured (issue 44 item 4, acceptance) -------------

WEIR = nlobs.System(states=["h1", "h2"], inputs=["d"], outputs=["y"],
                    f=["(0.25 - 0.15*sqrt(max(h1, 0)) - 2000*max(h1 - 1, 0))/0.5", "0.15*sqrt(max(h1, 0)) - 0.08*sqrt(max(h2, 0)) - d"],
                    h=["h2"], name="weir")


@pytest.mark.parametrize("engine", ["vm", "c"])
def test_an_interval_that_blows_up_before_its_rate_is_seen_is_redone_with_more_substeps(engine, time_limit):
    """A UKF starting at h1 = 0.6 with P0 = 0.2 puts sigma points at h1 = 1.37, over a weir of rate 4000/s: the first
    interval's rate (the flow's Jacobian at the start estimate) sees no weir, and its one RK4 step of 0.01 s turned the
    state non-finite before any stage could measure the rate: 'its state became non-finite ... (1 RK4 steps)', while
    the same filter at max_step 1e-4 runs through. The EKF's estimate crosses the rim at t = 0.14: that interval's rate
    does not shrink with more sub-steps (a kink), its 24 sub-steps are unstable past the rim (rate 8000/s on P), and
    the kink's step-doubling check refused it as diverging. Such an interval is now redone with REDO_GROWTH times the
    sub-steps and the rate rule on (at most twice) before it is called a failure: both runs go through and agree with
    the fine ones."""
    from nlobs.design import design_ukf

    t = np.round(np.arange(0.0, 3.0, 0.01), 10)
    y = 0.2 + 0.1 * t + 0.005 * np.sin(7 * t)
    rec = nlobs.Recording.from_arrays(WEIR, t, y[:, None], np.full((t.size, 1), 0.01))
    for design in (design_ukf, design_ekf):
        d = design(WEIR, Q=np.diag([1e-5, 1e-6]), R=[[2.5e-5]], P0=np.diag([0.2, 0.01]), xhat0=[0.6, 0.25])
        run = nlobs.estimate({"o": d}, rec, engine=engine)
        fine = nlobs.estimate({"o": d}, rec, engine="c", max_step=1e-4)
        x = run.observers["o"].xhat
        assert np.isfinite(x).all() and x[:, 0].max() < 1.05   # an update may lift h1 a little over the rim
        assert np.abs(x - fine.observers["o"].xhat).max() < 1e-3, design
        other = nlobs.estimate({"o": d}, rec, engine="c" if engine == "vm" else "vm")   # the same rule on both engines
        assert run.info["integration"]["o"]["substeps"] == other.info["integration"]["o"]["substeps"]
        assert np.abs(x - other.observers["o"].xhat).max() < 1e-10
    # a true finite escape (x' = x², from 1 at t = 0: infinite at t = 1) still fails, on both engines
    from nlobs.design import design_custom

    decay = nlobs.System(states=["x"], outputs=["y"], f=["-x"], h=["x"], name="decay")
    ts = np.arange(0.0, 2.0, 0.5)
    with pytest.raises(nlobs.errors.FiniteEscapeError, match="from the sample at t = 1 "):
        nlobs.estimate(design_custom(decay, states=["xh"], flow=["xh**2"], xhat0=[1.0]),
                       nlobs.Recording.from_arrays(decay, ts, np.ones((ts.size, 1))), engine=engine)
