"""simulate(): accuracy against SciPy, inputs, noise, sampling, blow-ups, results and metrics."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from nlobs import FiniteEscapeError, ModelError, Noise, ProcessNoise, Sampling, ShapeError, System, design_output_injection, simulate
from nlobs.model import Sampled
from nlobs.simulate import convergence_time, error_metrics

VDP = System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1 + u"], inputs=["u"], outputs=["y"], h=["x1"],
             params={"mu": 1.0}, name="vdp")
PEND = System(states=["x1", "x2"], f=["x2", "-9.81*sin(x1) - 0.5*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"], name="pend")


def test_plant_trajectory_matches_scipy_solve_ivp():
    run = simulate(VDP, t_final=10.0, dt=1e-3, x0=[2.0, 0.0], inputs={"u": "0.5*sin(t)"}, params={"mu": 1.3})
    ref = solve_ivp(lambda t, x: [x[1], 1.3 * (1 - x[0] ** 2) * x[1] - x[0] + 0.5 * np.sin(t)], (0, 10), [2.0, 0.0],
                    t_eval=run.t, rtol=1e-11, atol=1e-12, method="DOP853")
    assert np.max(np.abs(run.x - ref.y.T)) < 1e-8
    assert np.allclose(run.y_true[:, 0], run.x[:, 0]) and np.array_equal(run.y, run.y_true)


def test_input_forms_agree():
    base = dict(t_final=2.0, dt=1e-3, x0=[1.0, 0.0])
    a = simulate(VDP, inputs={"u": "cos(2*t)"}, **base)
    b = simulate(VDP, inputs={"u": lambda t: np.cos(2 * t)}, **base)
    assert np.max(np.abs(a.x - b.x)) < 1e-14
    tt = np.linspace(0, 2, 20001)
    c = simulate(VDP, inputs={"u": Sampled(tt, np.cos(2 * tt), hold="linear")}, **base)
    assert np.max(np.abs(a.x - c.x)) < 1e-8


def test_piecewise_input_switches_on_the_grid():
    sys = System(states=["x"], f=["u"], inputs=["u"], outputs=["y"], h=["x"])
    run = simulate(sys, t_final=1.0, dt=0.1, x0=[0.0], inputs={"u": Sampled.piecewise([0, 0.5], [1.0, -1.0])})
    assert np.allclose(run.x[:, 0], np.r_[np.arange(6) * 0.1, 0.5 - np.arange(1, 6) * 0.1])


def test_noise_is_seeded_and_has_the_requested_statistics():
    kw = dict(t_final=20.0, dt=1e-3, x0=[1.0, 0.0])
    a = simulate(PEND, noise=Noise.gaussian(0.05), seed=7, **kw)
    b = simulate(PEND, noise=Noise.gaussian(0.05), seed=7, **kw)
    c = simulate(PEND, noise=Noise.gaussian(0.05), seed=8, **kw)
    assert np.array_equal(a.y, b.y) and not np.array_equal(a.y, c.y)
    n = (a.y - a.y_true)[:, 0]
    assert abs(n.std() - 0.05) < 0.002 and abs(n.mean()) < 0.002
    u = simulate(PEND, noise=Noise.uniform(0.02), seed=1, **kw)
    nu = (u.y - u.y_true)[:, 0]
    assert np.max(np.abs(nu)) <= 0.02 and np.max(np.abs(nu)) > 0.0199 and abs(nu.std() - 0.02 / np.sqrt(3)) < 5e-4


def test_sampled_measurements_are_held():
    run = simulate(PEND, t_final=1.0, dt=1e-3, x0=[1.0, 0.0], noise=Noise.gaussian(0.01), sampling=Sampling(0.05), seed=0)
    y = run.y[:, 0]
    blocks = y[:-1].reshape(20, 50)
    assert np.all(blocks == blocks[:, :1])  # constant between samples
    assert np.allclose(blocks[:, 0], run.y_true[::50, 0][:20] + (run.y - run.y_true)[::50, 0][:20])
    with pytest.raises(ValueError, match="whole multiple of dt"):
        simulate(PEND, t_final=1.0, dt=1e-3, x0=[1.0, 0.0], sampling=Sampling(0.0015))


def test_process_noise_is_brownian():
    sys = System(states=["x"], f=["0"], outputs=["y"], h=["x"])
    runs = [simulate(sys, t_final=1.0, dt=1e-3, x0=[0.0], process_noise=ProcessNoise(0.5), seed=s).x[-1, 0] for s in range(300)]
    assert abs(np.std(runs) - 0.5) < 0.06  # Var x(1) = sigma^2 * 1


def test_finite_escape_is_reported_with_time_state_and_partial_result():
    blow = System(states=["x"], f=["x**2"], outputs=["y"], h=["x"], name="riccati")  # x(t) = 1/(1 - t)
    with pytest.raises(FiniteEscapeError, match="plant blew up after t = ") as info:
        simulate(blow, t_final=2.0, dt=1e-3, x0=[1.0], escape_bound=1e6)
    err = info.value
    assert 0.99 < err.t <= 1.01 and err.x[0] > 1e2  # the exact solution 1/(1 - t) escapes at t = 1
    assert err.partial.t[-1] == pytest.approx(err.t) and np.all(np.isfinite(err.partial.x))


def test_observer_blow_up_names_the_observer():
    bad = System(states=["x1", "x2"], f=["x2", "-9.81*sin(x1) - 0.5*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"])
    from nlobs import design_ekf

    stiff = design_ekf(bad, Q=np.eye(2), R=[[1e-9]], mode="continuous")
    with pytest.raises(FiniteEscapeError, match="observer 'stiff' blew up") as info:
        simulate(PEND, {"stiff": stiff}, t_final=1.0, dt=1e-3, x0=[1.0, 0.0])
    assert "xhat_x1=" in str(info.value)


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        (dict(t_final=1.0, dt=0.3, x0=[1.0, 0.0]), ShapeError, "whole multiple of dt"),
        (dict(t_final=-1.0, dt=0.1, x0=[1.0, 0.0]), ShapeError, "`t_final` must be a positive number"),
        (dict(t_final=1.0, dt=0.1, x0=[1.0]), ShapeError, "`x0` must be 2 finite numbers"),
        (dict(t_final=1.0, dt=0.1, x0=[1.0, np.nan]), ShapeError, "`x0` must be 2 finite numbers"),
        (dict(t_final=1.0, dt=0.1, x0=[1.0, 0.0], inputs={"v": 1}), ModelError, "'v', which is not an input"),
        (dict(t_final=1.0, dt=0.1, x0=[1.0, 0.0], params={"mass": 2}), ModelError, "not a parameter"),
        (dict(t_final=1.0, dt=0.1, x0=[1.0, 0.0], inputs={"u": lambda t: np.where(t > 0.5, np.nan, 0.0)}), ShapeError, "inputs must be finite"),
    ],
)
def test_bad_arguments(kwargs, error, match):
    with pytest.raises(error, match=match):
        simulate(PEND, **kwargs)


def test_observer_must_match_the_plant_signals():
    other = System(states=["a", "b"], f=["b", "-a"], outputs=["y"], h=["a"])
    d = design_output_injection(other, poles=[-1, -2])
    with pytest.raises(ModelError, match="designed for inputs \\[\\], but the plant 'pend' has \\['u'\\]"):
        simulate(PEND, {"o": d}, t_final=1.0, dt=0.1, x0=[1.0, 0.0])


def test_observer_keeps_its_design_model_when_plant_parameters_change():
    lin = System(states=["x1", "x2"], f=["x2", "-k*x1"], outputs=["y"], h=["x1"], params={"k": 1.0})
    obs = design_output_injection(lin, poles=[-2, -3])
    exact = simulate(lin, {"o": obs}, t_final=10.0, dt=1e-3, x0=[1.0, 0.0])
    mismatch = simulate(lin, {"o": obs}, t_final=10.0, dt=1e-3, x0=[1.0, 0.0], params={"k": 1.5})
    assert exact.metrics("o").final_error < 1e-6 and mismatch.metrics("o").final_error > 1e-2


def test_results_export_and_plot(tmp_path):
    obs = design_output_injection(PEND, poles=[-2, -3])
    run = simulate(PEND, {"oi": obs}, t_final=2.0, dt=1e-2, x0=[1.0, 0.0], inputs={"u": "sin(t)"})
    df = run.to_pandas()
    assert list(df.columns) == ["x1", "x2", "u", "y", "y_true", "oi.x1", "oi.x2", "oi.error"]
    assert df.index.name == "t" and len(df) == 201
    arrays = run.to_numpy()
    assert arrays["xhat[oi]"].shape == (201, 2) and arrays["z[oi]"].shape == (201, 2)
    fig = run.plot(str(tmp_path / "run.png"))
    assert (tmp_path / "run.png").stat().st_size > 10_000 and len(fig.axes) == 3
    s = run.summary_dict()
    assert set(s["observers"]["oi"]) >= {"final_error", "rms_error", "convergence_time"}
    assert "oi" in str(run.summary())
    with pytest.raises(KeyError, match="no observer named 'x'"):
        run.metrics("x")


def test_metrics_on_a_known_error_signal():
    t = np.linspace(0, 10, 1001)
    e = np.exp(-t)
    assert convergence_time(t, e, 0.05) == pytest.approx(np.log(20), abs=0.01)
    m = error_metrics(t, e)  # default tolerance: 2 % of the initial error
    assert m.tol == pytest.approx(0.02) and m.convergence_time == pytest.approx(np.log(50), abs=0.01)
    assert m.peak_error == 1.0 and m.final_error == pytest.approx(np.exp(-10))
    tail = e[t >= 8]
    assert m.rms_error == pytest.approx(np.sqrt(np.mean(tail**2)), rel=1e-12)
    assert convergence_time(t, np.ones_like(t), 0.5) is None


@pytest.mark.parametrize("engine", ["vm", "c"])
@pytest.mark.parametrize("t_final", [1.001, 1.2])
def test_escape_reports_the_last_good_state_even_on_the_final_step(engine, t_final):
    """x' = x², x(0) = 1 escapes at t = 1; the RK4 solution with dt = 1e-3 jumps from 8.2e3 at
    t = 1.000 to 1e14 at t = 1.001, so with t_final = 1.001 the bound 1e6 is crossed on the very
    last step (a case the runner once could not tell from success)."""
    blow = System(states=["x"], f=["x**2"], outputs=["y"], h=["x"])
    bound = 1e6
    ref = simulate(blow, t_final=0.99, dt=1e-3, x0=[1.0])  # all below the bound
    assert ref.x.max() < bound
    first_bad = None
    for tf in (t_final,):
        try:
            simulate(blow, t_final=tf, dt=1e-3, x0=[1.0], escape_bound=bound, engine=engine)
        except FiniteEscapeError as err:
            first_bad = err
    assert first_bad is not None, "the escape was not detected"
    assert abs(first_bad.x[0]) <= bound and np.isfinite(first_bad.x[0])
    assert first_bad.partial.x[-1, 0] == first_bad.x[0] and first_bad.partial.t[-1] == pytest.approx(first_bad.t)
    # the next RK4 step from the reported state does leave the bound
    nxt = simulate(blow, t_final=1e-3, dt=1e-3, x0=first_bad.x, escape_bound=np.inf).x[-1, 0]
    assert not abs(nxt) <= bound


def test_noise_with_its_own_hold_period():
    run = simulate(PEND, t_final=0.1, dt=1e-4, x0=[1.0, 0.0], noise=Noise.uniform(0.02, hold=1e-3), seed=2)
    n = (run.y - run.y_true)[:, 0]
    blocks = n[:1000].reshape(100, 10)
    # (y - y_true recovers the noise up to round-off) a new value every 1e-3 s, held in between
    assert np.allclose(blocks, blocks[:, :1], atol=1e-12, rtol=0) and np.all(np.abs(np.diff(blocks[:, 0])) > 1e-9)
    assert np.all(np.abs(n) <= 0.02)
    with pytest.raises(ValueError, match="whole multiple of dt"):
        simulate(PEND, t_final=0.1, dt=1e-4, x0=[1.0, 0.0], noise=Noise.gaussian(0.1, hold=1.5e-4), seed=2)


def test_adaptive_cvodes_matches_a_tight_scipy_reference():
    from nlobs import Adaptive, design_ekf

    ekf = design_ekf(VDP, Q=np.eye(2) * 1e-3, R=[[1e-4]])
    tight = Adaptive(rtol=1e-12, atol=1e-13)  # local per-step tolerances: the global error accumulates over 400 steps
    # autonomous: only the integrator's tolerance matters
    run = simulate(VDP, {"ekf": ekf}, t_final=8.0, dt=0.02, x0=[2.0, 0.0], params={"mu": 1.3}, integrator=tight)
    ref = solve_ivp(lambda t, x: [x[1], 1.3 * (1 - x[0] ** 2) * x[1] - x[0]], (0, 8), [2.0, 0.0],
                    t_eval=run.t, rtol=1e-12, atol=1e-13, method="DOP853")
    assert np.max(np.abs(run.x - ref.y.T)) < 1e-8 and run.info["integrator"].startswith("cvodes")
    # a smooth input is interpolated quadratically through its stage values within each step: error O(dt^3)
    run = simulate(VDP, t_final=8.0, dt=0.02, x0=[2.0, 0.0], inputs={"u": "0.5*sin(t)"}, params={"mu": 1.3}, integrator=tight)
    ref = solve_ivp(lambda t, x: [x[1], 1.3 * (1 - x[0] ** 2) * x[1] - x[0] + 0.5 * np.sin(t)], (0, 8), [2.0, 0.0],
                    t_eval=run.t, rtol=1e-12, atol=1e-13, method="DOP853")
    assert np.max(np.abs(run.x - ref.y.T)) < 1e-6
    with pytest.raises(ValueError, match="`rtol` must be a positive number"):
        Adaptive(rtol=0)
    with pytest.raises(TypeError, match="must be an nlobs.Adaptive"):
        simulate(VDP, t_final=1.0, dt=0.1, x0=[1.0, 0.0], integrator="cvodes")  # type: ignore[arg-type]


def test_a_plant_output_that_becomes_nan_is_the_plants_not_the_observers():
    """y = sqrt(x) with x(t) = 1 - t: the output is undefined from t = 1 on; the observers that receive it stop,
    but the failure is the plant's output map, reported with its time and state."""
    from nlobs import design_ekf

    plant = System(states=["x"], f=["-1"], outputs=["y"], h=["sqrt(x)"], name="drain")
    ekf = design_ekf(plant, Q=[[1e-3]], R=[[1e-4]], xhat0=[1.0])
    for sampling in (None, Sampling(0.05)):
        with pytest.raises(FiniteEscapeError, match=r"the plant's output y = sqrt\(x\) is nan at t = 1(\.\d*)? \(plant state x=") \
                as info:
            simulate(plant, {"ekf": ekf}, t_final=2.0, dt=1e-2, x0=[1.0], sampling=sampling)
        assert info.value.where == "the plant's output" and 0.99 <= info.value.t <= 1.06
    # an observer that blows up on a well-defined output is still the observer's failure (see above)


def test_numpy_numbers_are_numbers():
    run = simulate(PEND, t_final=np.float32(1.0), dt=np.float32(0.1), x0=[1.0, 0.0], sampling=Sampling(np.float32(0.2)))
    assert len(run.t) == 11
    run = simulate(PEND, t_final=np.int64(1), dt=np.float64(0.5), x0=[1.0, 0.0])
    assert len(run.t) == 3
    with pytest.raises(ShapeError, match="`dt` must be a positive number"):
        simulate(PEND, t_final=1.0, dt=True, x0=[1.0, 0.0])  # type: ignore[arg-type]


def test_a_held_input_switching_on_the_grid_never_leaks_into_the_previous_step():
    """t_k + dt can exceed t_{k+1} by an ulp (0.059 + 0.001 > 0.06): the last RK4 stage of step k then saw the new
    value of a held input switching at t_{k+1} (111 of 400 switches here). The integral of a held input is exact."""
    integ = System(states=["x"], f=["u"], inputs=["u"], outputs=["y"], h=["x"])
    t = np.round(np.arange(0, 8.0001, 0.02), 10)
    u = np.sign(np.sin(1.1 * t))
    run = simulate(integ, t_final=8.0, dt=1e-3, x0=[0.0], inputs={"u": Sampled(t, u)})
    exact = np.r_[0.0, np.cumsum(u[:-1] * 0.02)]
    assert np.max(np.abs(run.x[::20, 0] - exact)) < 1e-12


def test_a_prepared_simulation_runs_many_times_like_simulate():
    from nlobs import Simulation

    sys_ = System(states=["x1", "x2"], f=["x2", "-x1 - 0.3*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"], name="osc")
    obs = design_output_injection(sys_, poles=[-3, -4])
    sim = Simulation(sys_, {"o": obs}, t_final=2.0, dt=0.01, inputs={"u": "sin(t)"}, noise=Noise.gaussian(0.01))
    for x0, seed in (([1.0, 0.0], 1), ([0.0, -1.0], 2)):
        a = sim.run(x0, seed=seed)
        b = simulate(sys_, {"o": obs}, t_final=2.0, dt=0.01, x0=x0, inputs={"u": "sin(t)"}, noise=Noise.gaussian(0.01), seed=seed)
        assert np.array_equal(a.x, b.x) and np.array_equal(a.observers["o"].xhat, b.observers["o"].xhat) and np.array_equal(a.y, b.y)
    assert sim.t.shape == (201,) and sim.plant is sys_


class TestInputArrays:
    """python-control's habit: inputs as arrays on the run's grid, or (t, values) pairs (issue 20 §6)."""

    PEND = None

    @staticmethod
    def _run(inputs, t_final=2.0, plant=None):
        import nlobs
        from nlobs import System
        plant = plant or System(states=["x1", "x2"], inputs=["u"], outputs=["y"], f=["x2", "-9.81*sin(x1) - 0.5*x2 + u"],
                                h=["x1"])
        return nlobs.simulate(plant, None, t_final=t_final, dt=1e-3, x0=[1.0, 0.0], inputs=inputs)

    def test_an_array_on_the_grid_is_the_signal_it_samples(self):
        t = np.arange(2001) * 1e-3
        ref = self._run({"u": "sin(t)"})
        for given in ({"u": np.sin(t)}, np.sin(t), {"u": list(np.sin(t))}):
            run = self._run(given)
            np.testing.assert_array_equal(run.u[:, 0], np.sin(t))
            # between grid points the array is interpolated linearly (RK4's half step): O(dt²) from sin itself
            np.testing.assert_allclose(run.x, ref.x, rtol=0, atol=1e-7)

    def test_a_t_values_pair_is_interpolated_linearly(self):
        run = self._run({"u": ([0.0, 1.0, 2.0], [0.0, 2.0, 0.0])})
        np.testing.assert_allclose(run.u[[0, 500, 1000, 1500, 2000], 0], [0.0, 1.0, 2.0, 1.0, 0.0], rtol=0, atol=1e-12)

    def test_a_2d_array_gives_every_input_and_wrong_sizes_say_what_is_needed(self):
        import nlobs
        from nlobs import System
        two = System(states=["x"], inputs=["a", "b"], outputs=["y"], f=["-x + a - b"], h=["x"])
        t = np.arange(1001) * 1e-3
        run = nlobs.simulate(two, None, t_final=1.0, dt=1e-3, x0=[0.0], inputs=np.vstack([np.ones_like(t), t]))
        np.testing.assert_array_equal(run.u, np.column_stack([np.ones_like(t), t]))
        with pytest.raises(nlobs.ShapeError, match=r"one value per time of the run \(2001 times.*got 1000; or pass a \(t, values\)"):
            self._run({"u": np.zeros(1000)})
        with pytest.raises(nlobs.ShapeError, match="as many values as times"):
            self._run({"u": ([0.0, 1.0, 2.0], [0.0, 2.0])})


@pytest.mark.parametrize("sampling, hold", [(None, None), (Sampling(0.05), None), (None, 0.03)])
def test_a_seed_fixes_the_noise_of_every_sample_whatever_the_horizon(sampling, hold):
    """Issue 44, item 6: a 10 s run's measurement noise and process noise equal the first 10 s of a 20 s run's with the
    same seed (before, one generator drew every output's noise, then the process noise, so each depended on t_final);
    the measurement noise does not change when process noise is added; another seed gives other noise."""
    plant = System(states=["p", "v"], f=["v", "-p - 0.2*v"], outputs=["y1", "y2"], h=["p", "v"])
    noise = Noise.per_output({"y1": 0.1}, {"y2": 0.05}, hold=hold)
    kw = dict(dt=0.01, x0=[1.0, 0.0], noise=noise, process_noise=ProcessNoise([0.01, 0.02]), sampling=sampling)
    short, long_ = (simulate(plant, None, t_final=T, seed=7, **kw) for T in (10.0, 20.0))
    n = short.t.size
    v_short, v_long = short.y - short.y_true, long_.y - long_.y_true
    assert np.std(v_short[:, 0]) > 0.05 and np.array_equal(v_short, v_long[:n])
    assert np.std(np.diff(short.x[:, 1])) > 0 and np.array_equal(short.x, long_.x[:n])   # the same process noise path
    quiet = simulate(plant, None, t_final=10.0, seed=7, **{**kw, "process_noise": None})
    at = slice(None, None, 5) if sampling else slice(None)  # a sampled output is held between its samples
    assert np.allclose((quiet.y - quiet.y_true)[at], v_short[at], rtol=0, atol=1e-12)  # (y = y_true + v, rounded)
    other = simulate(plant, None, t_final=10.0, seed=8, **kw)
    assert not np.allclose(other.y - other.y_true, v_short)


def test_a_discrete_time_run_keeps_its_noise_when_the_horizon_grows():
    plant = System(states=["x"], f=["0.9*x"], outputs=["y"], h=["x"], time="discrete", sample_time=0.1)
    kw = dict(x0=[1.0], noise=Noise.gaussian(0.1), process_noise=ProcessNoise(0.05), seed=3)
    short, long_ = simulate(plant, None, t_final=5.0, **kw), simulate(plant, None, t_final=9.0, **kw)
    n = short.t.size
    assert np.array_equal(short.y, long_.y[:n]) and np.array_equal(short.x, long_.x[:n])
