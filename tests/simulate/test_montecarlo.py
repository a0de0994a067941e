"""Monte Carlo: runs reproduce simulate(), statistics, failures with reasons, Dask gives the same numbers."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import Noise, ShapeError, System, design_ekf, design_output_injection, montecarlo, simulate
from nlobs.simulate._metrics import state_metrics

PEND = System(states=["x1", "x2"], f=["x2", "-a*sin(x1) - 0.5*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"],
              params={"a": 9.81}, name="pend")
INJ = design_output_injection(PEND, poles=[-2, -3])
EKF = design_ekf(PEND, Q=np.eye(2) * 1e-3, R=[[1e-4]])
X0 = np.random.default_rng(1).uniform(-1, 1, (12, 2))


@pytest.fixture(scope="module")
def mc():
    return montecarlo(PEND, {"inj": INJ, "ekf": EKF}, t_final=4.0, dt=1e-3, x0=X0, inputs={"u": "sin(t)"},
                      noise=Noise.gaussian(0.01), params={"a": np.linspace(9, 10.5, 12)}, seed=5, save_every=10, chunk=5)


def test_each_run_is_the_simulation_with_its_seed(mc):
    for j in (0, 7, 11):
        run = simulate(PEND.with_params(a=float(np.linspace(9, 10.5, 12)[j])), {"inj": INJ, "ekf": EKF}, t_final=4.0, dt=1e-3,
                       x0=X0[j], inputs={"u": "sin(t)"}, noise=Noise.gaussian(0.01), seed=int(mc.seeds[j]))
        assert np.max(np.abs(run.x[::10] - mc.x[j])) < 1e-12
        for name in ("inj", "ekf"):
            assert np.max(np.abs(run.observers[name].xhat[::10] - mc.observers[name].xhat[j])) < 1e-12
        again = mc.trajectory(j)
        assert np.array_equal(again.x, run.x)


def test_statistics_match_the_per_run_numbers(mc):
    o = mc.observers["inj"]
    assert o.error_norm.shape == (12, 401) and mc.t[-1] == pytest.approx(4.0)
    for j in range(12):  # each run judged as in Run.metrics (per state, the same rule, on the saved grid; x̂(0) = 0)
        tc = state_metrics(mc.t, o.xhat[j] - mc.x[j], -X0[j], ["x1", "x2"], noisy=True).convergence_time
        assert (np.isnan(o.convergence_time[j]) and tc is None) or o.convergence_time[j] == tc
    # a run that starts on the true state has converged at t = 0, which is not "never" (NaN)
    exact = montecarlo(PEND, {"ekf": EKF}, t_final=1.0, dt=1e-3, x0=X0[:3], xhat0=X0[:3], inputs={"u": "sin(t)"}, seed=5)
    assert np.array_equal(exact.observers["ekf"].convergence_time, np.zeros(3))
    s = mc.stats("inj")
    assert s["runs"] == 12 and s["failed"] == 0
    assert s["rms_error_median"] == pytest.approx(np.median(o.rms_error))
    assert "inj" in str(mc.summary()) and "ekf" in str(mc.summary())
    df = mc.to_pandas()
    assert len(df) == 24 and set(df.observer) == {"inj", "ekf"}
    fig = mc.plot()
    assert len(fig.axes) == 1


def test_failed_runs_are_reported_with_their_reason_and_the_others_go_on():
    blow = System(states=["x"], f=["x**2"], outputs=["y"], h=["x"], name="riccati")  # escapes at t = 1/x0
    mc = montecarlo(blow, {}, t_final=1.5, dt=1e-3, x0=np.array([[0.1], [1.0], [0.2], [2.0]]), escape_bound=1e6)
    assert list(mc.failed) == [1, 3]
    assert mc.status[0] == mc.n_steps and 0.9 < mc.status[1] * 1e-3 <= 1.0
    reasons = dict(mc.failures)
    assert "plant blew up after t = " in reasons[1] and "plant blew up" in reasons[3]
    assert np.isnan(mc.x[1, -1, 0]) and np.isfinite(mc.x[0, -1, 0])


def test_argument_checks():
    with pytest.raises(ShapeError, match="nothing varies between runs"):
        montecarlo(PEND, {"inj": INJ}, t_final=1.0, dt=1e-2, x0=[1.0, 0.0])
    with pytest.raises(ShapeError, match="disagree on the number of runs"):
        montecarlo(PEND, {"inj": INJ}, t_final=1.0, dt=1e-2, x0=X0, params={"a": [1.0, 2.0]})
    with pytest.raises(ShapeError, match="not a parameter"):
        montecarlo(PEND, {"inj": INJ}, t_final=1.0, dt=1e-2, x0=X0, params={"b": 1.0})
    only_noise = montecarlo(PEND, {"inj": INJ}, t_final=1.0, dt=1e-2, x0=[1.0, 0.0], runs=3, noise=Noise.gaussian(0.1))
    assert only_noise.runs == 3 and len(set(only_noise.seeds)) == 3
    assert not np.allclose(only_noise.observers["inj"].xhat[0], only_noise.observers["inj"].xhat[1])


def test_vm_and_compiled_paths_agree():
    a = montecarlo(PEND, {"inj": INJ}, t_final=1.0, dt=1e-3, x0=X0[:3], save_every=50, engine="vm")
    b = montecarlo(PEND, {"inj": INJ}, t_final=1.0, dt=1e-3, x0=X0[:3], save_every=50, engine="c")
    assert np.max(np.abs(a.x - b.x)) < 1e-12 and np.max(np.abs(a.observers["inj"].xhat - b.observers["inj"].xhat)) < 1e-12


def test_dask_cluster_gives_the_same_numbers():
    distributed = pytest.importorskip("dask.distributed", reason="the Dask path needs nlobs[dask] (in the test extra)")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        kw = dict(t_final=2.0, dt=1e-3, x0=X0[:6], inputs={"u": "sin(t)"}, noise=Noise.gaussian(0.01), seed=9, save_every=20,
                  chunk=2)
        local = montecarlo(PEND, {"inj": INJ, "ekf": EKF}, **kw)
        remote = montecarlo(PEND, {"inj": INJ, "ekf": EKF}, scheduler=cluster.scheduler_address, **kw)
    assert remote.info["dask"] and not local.info["dask"]
    assert np.array_equal(local.x, remote.x)
    for name in ("inj", "ekf"):
        assert np.array_equal(local.observers[name].xhat, remote.observers[name].xhat)


def test_a_tolerance_must_be_positive():
    with pytest.raises(ValueError, match="`tol` must be a positive number"):
        montecarlo(PEND, {"ekf": EKF}, t_final=0.1, dt=1e-2, x0=X0[:2], tol=-1.0)


def test_metrics_are_computed_only_when_read(monkeypatch):
    """A Monte Carlo run that reads only the final states does no per-run metric work."""
    import importlib

    mcm = importlib.import_module("nlobs.simulate._montecarlo")

    calls = []
    real = mcm.state_convergence
    monkeypatch.setattr(mcm, "state_convergence", lambda *a, **k: calls.append(1) or real(*a, **k))
    sys_ = System(states=["x"], f=["-x"], outputs=["y"], h=["x"], name="decay")
    obs = design_output_injection(sys_, poles=[-3])
    mc = montecarlo(sys_, {"o": obs}, t_final=2.0, dt=0.01, x0=np.linspace(-1, 1, 12)[:, None], engine="vm")
    assert mc.observers["o"].xhat[:, -1].shape == (12, 1) and calls == []
    conv = mc.observers["o"].convergence_time
    assert len(calls) == 12 and conv.shape == (12,)
    assert mc.observers["o"].convergence_time is conv and len(calls) == 12  # computed once
