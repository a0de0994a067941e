"""Monte Carlo: runs reproduce simulate(), statistics, failures with reasons, threads and Dask give the same numbers."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import numpy as np
import pytest

import nlobs

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


def test_a_multirate_run_is_the_simulation_with_its_seed_and_so_is_its_rerun():
    # one clock per output in the batch; trajectory(j) re-runs it with the same clocks (it once ran every output on the
    # fastest clock)
    cart = System(states=["p", "v", "b"], inputs=["a"], outputs=["gps", "wheel"], f=["v", "a - 0.1*v", "0"],
                  h=["p", "v + b"], name="cart")
    ekf = design_ekf(cart, R=np.diag([0.25, 0.01]), Q=np.diag([1e-4, 1e-3, 1e-6]), xhat0=[5.0, 0.0, 0.0])
    clocks = nlobs.Sampling({"gps": 0.25, "wheel": 0.1})
    kw = dict(t_final=2.0, dt=0.01, inputs={"a": "sin(0.5*t)"}, noise=Noise.per_output({"gps": 0.5, "wheel": 0.1}),
              sampling=clocks)
    mc = montecarlo(cart, {"ekf": ekf}, x0=[0.0, 1.0, 0.3], runs=3, seed=3, save_every=1, **kw)
    for j in (0, 2):
        run = simulate(cart, {"ekf": ekf}, x0=[0.0, 1.0, 0.3], seed=int(mc.seeds[j]), **kw)
        assert np.max(np.abs(run.observers["ekf"].xhat - mc.observers["ekf"].xhat[j])) < 1e-12
        again = mc.trajectory(j)
        assert again.info["sampling"] == clocks.period
        assert np.array_equal(again.observers["ekf"].xhat, run.observers["ekf"].xhat)


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


def _pend_kw(engine="c", **kw):
    return dict(t_final=1.0, dt=1e-3, x0=X0, inputs={"u": "sin(t)"}, noise=Noise.gaussian(0.01),
                params={"a": np.linspace(9, 10.5, 12)}, seed=3, save_every=25, engine=engine, **kw)


@pytest.mark.parametrize("engine", ["c", "vm"])
def test_threads_run_the_chunks_side_by_side_with_the_serial_numbers(monkeypatch, engine):
    """The chunks run on two threads at once (each thread's first chunk waits until the other thread has one), and the
    result is bit for bit the serial one, however the runs are chunked; compiled and on CasADi's VM."""
    import importlib

    mcm = importlib.import_module("nlobs.simulate._montecarlo")
    serial = montecarlo(PEND, {"inj": INJ, "ekf": EKF}, workers=1, chunk=12, **_pend_kw(engine))
    assert serial.info["workers"] == 1
    real, seen, both = mcm.run_batch, set(), threading.Event()

    def spy(*a, **k):  # the first chunk of each thread waits (at most 10 s) until the other thread runs one too
        seen.add(threading.get_ident())
        if len(seen) >= 2:
            both.set()
        both.wait(timeout=10)
        both.set()
        return real(*a, **k)

    monkeypatch.setattr(mcm, "run_batch", spy)
    for chunk in (3, 5, None):
        seen.clear()
        both.clear()
        par = montecarlo(PEND, {"inj": INJ, "ekf": EKF}, workers=2, chunk=chunk, **_pend_kw(engine))
        assert len(seen) == 2 and par.info["workers"] == 2
        assert np.array_equal(par.x, serial.x) and np.array_equal(par.status, serial.status)
        for name in ("inj", "ekf"):
            assert np.array_equal(par.observers[name].xhat, serial.observers[name].xhat)


def test_every_usable_core_by_default():
    from nlobs.engine import usable_cores

    mc = montecarlo(PEND, {"inj": INJ}, chunk=3, **_pend_kw())   # 4 chunks
    assert mc.info["workers"] == min(usable_cores(), 4) and mc.info["chunk"] == 3
    if hasattr(os, "sched_getaffinity"):
        assert usable_cores() == len(os.sched_getaffinity(0))


def test_workers_and_chunk_are_checked():
    with pytest.raises(ShapeError, match="`workers` must be a positive whole number"):
        montecarlo(PEND, {"inj": INJ}, workers=0, **_pend_kw())
    with pytest.raises(ShapeError, match="`chunk` must be a positive whole number"):
        montecarlo(PEND, {"inj": INJ}, chunk=2.5, **_pend_kw())
    with pytest.raises(ShapeError, match="not both"):
        montecarlo(PEND, {"inj": INJ}, workers=2, scheduler="tcp://127.0.0.1:1", **_pend_kw())


def _run_python(code: str, timeout: float, **env: str) -> subprocess.CompletedProcess:
    """`code` in a fresh interpreter that imports this nlobs; killed (and the test failed) after `timeout` seconds."""
    path = os.pathsep.join([str(Path(nlobs.__file__).parents[1]), os.environ.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "PYTHONPATH": path, **env})


def test_repeated_and_concurrent_calls_on_one_dask_client_return():
    """An identical call again on the same client, and calls at once from two threads, all return the local numbers.
    (Sending the spec under its content hash made the second identical call wait for good.) In a child process with a
    time limit: a hang fails the test instead of blocking the run."""
    pytest.importorskip("dask.distributed", reason="the Dask path needs nlobs[dask] (in the test extra)")
    code = """
        import threading
        import numpy as np
        from dask.distributed import Client, LocalCluster
        from nlobs import Noise, System, design_output_injection, montecarlo
        plant = System(states=["x1", "x2"], f=["x2", "-a*sin(x1) - 0.5*x2"], outputs=["y"], h=["x1"], params={"a": 9.81})
        obs = {"inj": design_output_injection(plant, poles=[-2, -3])}
        kw = dict(t_final=0.5, dt=1e-2, x0=np.random.default_rng(1).uniform(-1, 1, (6, 2)), noise=Noise.gaussian(0.01),
                  seed=4, chunk=2)
        local = montecarlo(plant, obs, workers=1, **kw).x
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            for _ in range(3):
                assert np.array_equal(montecarlo(plant, obs, scheduler=client, **kw).x, local)
            out = {}
            calls = [threading.Thread(target=lambda i=i: out.__setitem__(i, montecarlo(plant, obs, scheduler=client, **kw).x))
                     for i in range(3)]
            for c in calls:
                c.start()
            for c in calls:
                c.join()
            assert len(out) == 3 and all(np.array_equal(x, local) for x in out.values())
            sized = montecarlo(plant, obs, scheduler=client, **{**kw, "chunk": None})
            assert sized.info["dask_threads"] == 2 and np.array_equal(sized.x, local)
        print("returned")
    """
    proc = _run_python(code, timeout=120)
    assert proc.returncode == 0 and "returned" in proc.stdout, proc.stderr[-3000:]


def test_a_monte_carlo_worker_imports_only_what_it_runs(tmp_path):
    """What a Dask worker runs (unpickling a chunk's task and its spec, then running it) loads no python-flint (the
    IO route's FLINT loads with its first use), no analysis room (nlobs.analysis and its SymPy-heavy rooms load with
    their first name used) and no SciPy. SymPy itself picks python-flint as its ground types when it is installed,
    so the child runs with SYMPY_GROUND_TYPES=gmpy (a worker can too) to see nlobs' own imports."""
    from nlobs.simulate._montecarlo import _chunk_task

    mc = montecarlo(PEND, {"inj": INJ, "ekf": EKF}, workers=1, **_pend_kw())
    (tmp_path / "task.pkl").write_bytes(pickle.dumps((_chunk_task, mc._spec)))
    code = f"""
        import pickle, sys
        task, spec = pickle.loads(open({str(tmp_path / "task.pkl")!r}, "rb").read())
        S, O, status = task(spec, 0, 4)
        assert S.shape[0] == 4 and (status == spec.prep.n_steps).all()
        print(sorted(m for m in sys.modules if m.split(".")[0] in ("flint", "scipy") or m.startswith("nlobs.analysis")))
    """
    proc = _run_python(code, timeout=120, SYMPY_GROUND_TYPES="gmpy")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip() == "[]"


def test_the_analysis_names_load_on_first_use():
    """``nlobs.analysis`` offers every name it did (each loads its room on first use), and a name it lacks is an
    AttributeError (so ``from nlobs.analysis import forms`` still finds the sub-package)."""
    import nlobs.analysis as an
    from nlobs.analysis import forms
    from nlobs.analysis.structural import analyze

    assert an.analyze is analyze and an.kalman_rank is forms.kalman_rank and "select_sensors" in dir(an)
    assert set(an.__all__) >= {"analyze", "global_identifiability", "select_sensors", "decide_identity", "uco_test"}
    with pytest.raises(AttributeError, match="no attribute 'nonesuch'"):
        an.nonesuch  # noqa: B018


@pytest.mark.parametrize("case", ["gaussian", "hold", "process", "multirate"])
def test_a_chunk_draws_each_seeds_noise_in_place_bit_for_bit(case):
    """A chunk's noise inputs, drawn in place into one array for the chunk, are bit for bit the per-step inputs that
    :func:`nlobs.simulate` makes for each seed (``Prepared.inputs_for``), and the measurement noise is the seeding
    contract written in plain NumPy: output j of seed s draws from PCG64(SeedSequence(s, spawn_key=(0, j))), sample by
    sample (so the first N + 1 samples, whatever the horizon)."""
    from nlobs import ProcessNoise, Sampling
    from nlobs.simulate._montecarlo import _Buffers, seeded_inputs
    from nlobs.simulate._run import prepare

    plant = System(states=["p", "v"], f=["v", "-p - 0.2*v + u"], inputs=["u"], outputs=["y1", "y2"], h=["p", "v"])
    kw = {"gaussian": dict(noise=Noise.gaussian([0.1, 0.02])),
          "hold": dict(noise=Noise.per_output({"y1": 0.1}, {"y2": 0.05}, hold=0.03)),
          "process": dict(noise=Noise.uniform(0.05), process_noise=ProcessNoise([0.01, 0.02])),
          "multirate": dict(process_noise=ProcessNoise({"v": 0.03}), sampling=Sampling({"y1": 0.02, "y2": 0.05}))}[case]
    prep = prepare(plant, None, t_final=0.5, dt=0.01, inputs={"u": "sin(t)"}, params=None, caller="montecarlo",
                   **{"noise": None, "process_noise": None, "sampling": None, **kw})
    seeds = np.random.SeedSequence(9).generate_state(5).astype(np.int64)
    expected = np.stack([prep.inputs_for(int(s)) for s in seeds])
    flat = _Buffers().take(expected.size + 7)
    flat[:] = np.nan   # a lent array holds the last chunk's numbers: every cell must be written
    assert np.array_equal(seeded_inputs(prep, seeds, flat), expected)
    assert np.array_equal(seeded_inputs(prep, seeds), expected)
    if case == "gaussian":
        nb = prep.base.shape[1]
        for r, s in enumerate(seeds):
            for j, std in enumerate((0.1, 0.02)):
                g = np.random.Generator(np.random.PCG64(np.random.SeedSequence(int(s), spawn_key=(0, j))))
                assert np.array_equal(expected[r, :, nb + j], std * np.array([g.standard_normal() for _ in range(51)]))
