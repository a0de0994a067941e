"""The run's schedule: which output is sampled when, when each sample arrives, and the noise, built once and read by the
compiled loop, the delayed re-processing, the maps and Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest

import nlobs
from nlobs import Noise, ProcessNoise, Sampling, System
from nlobs.simulate._schedule import SampleSchedule, run_seeds

CART = System(states=["p", "v", "b"], inputs=["a"], outputs=["gps", "wheel"], f=["v", "a - 0.1*v", "0"],
              h=["p", "v + b"], name="cart")
MAP = System(states=["a", "b"], f=["0.9*a + 0.1*b", "-0.2*a + 0.8*b"], outputs=["y"], h=["a"], name="lmap",
             time="discrete", sample_time=0.1)


def _grid(t_final, dt):
    return np.arange(int(round(t_final / dt)) + 1) * dt


def test_each_output_is_sampled_at_the_multiples_of_its_period():
    t = _grid(2.0, 0.01)
    s = SampleSchedule.on_grid(t, 0.01, CART.outputs, CART.states, sampling=Sampling({"gps": 0.25, "wheel": 0.1}))
    # independent: the rows whose time is a whole multiple of the period (to rounding)
    ref = np.column_stack([np.isclose(t / p, np.round(t / p), rtol=0, atol=1e-9) for p in (0.25, 0.1)])
    assert s.multirate and np.array_equal(s.measured(), ref)
    assert np.array_equal(s.sample_rows(), np.flatnonzero(ref.any(axis=1)))
    one = SampleSchedule.on_grid(t, 0.01, CART.outputs, CART.states, sampling=Sampling(0.1))
    assert not one.multirate and one.flags().shape == (t.size, 1)
    assert np.array_equal(one.measured(), np.repeat(ref[:, [1]], 2, axis=1))
    assert SampleSchedule.on_grid(t, 0.01, CART.outputs, CART.states).measured().all()   # continuous: every row


def test_a_sample_arrives_its_delay_after_it_was_taken_and_a_recording_is_stamped_at_arrival():
    t = _grid(1.0, 0.05)
    s = SampleSchedule.on_grid(t, 0.05, CART.outputs, CART.states, sampling=Sampling(0.1), delay={"gps": 0.15})
    y = np.arange(2 * t.size, dtype=float).reshape(-1, 2)
    ev = s.events(y)
    rows = np.flatnonzero(np.isclose(t / 0.1, np.round(t / 0.1), rtol=0, atol=1e-9))
    assert ev.taken.size == 2 * rows.size
    assert np.allclose(ev.arrived - ev.taken, np.where(ev.output == 0, 0.15, 0.0), rtol=0, atol=1e-12)
    assert np.array_equal(np.sort(ev.taken[ev.output == 0]), t[rows])   # a run's rows: when its samples were taken
    assert np.array_equal(np.sort(ev.taken[ev.output == 1]), t[rows])
    assert list(s.arrival_lag("to_csv")) == [3, 0]   # 0.15 s on a 0.05 s grid: written three rows later
    off = SampleSchedule.on_grid(t, 0.05, CART.outputs, CART.states, sampling=Sampling(0.1), delay={"gps": 0.12})
    with pytest.raises(ValueError, match="0.12 s.*not a whole number of steps of dt = 0.05"):
        off.arrival_lag("to_csv")
    rec = SampleSchedule.of_recording(t, np.isfinite(np.where(y > 10, y, np.nan)), CART.outputs, delay={"wheel": 0.2})
    ev = rec.events(y)
    assert np.allclose(ev.arrived - ev.taken, np.where(ev.output == 1, 0.2, 0.0), rtol=0, atol=1e-12)
    assert np.all(ev.value > 10)
    assert np.all(np.isin(ev.arrived, t)) and not np.all(np.isin(ev.taken, t))   # a recording's: when they arrived
    with pytest.raises(nlobs.ShapeError, match="not an output"):
        SampleSchedule.of_recording(t, np.ones((t.size, 2), bool), CART.outputs, delay={"speed": 0.1})


def test_the_noise_of_a_sample_depends_on_the_seed_and_its_row_only():
    noise, w = Noise.gaussian({"gps": 0.5, "wheel": 0.1}), ProcessNoise([0.1, 0.2, 0.0])
    short = SampleSchedule.on_grid(_grid(1.0, 0.01), 0.01, CART.outputs, CART.states, noise=noise, process_noise=w, seed=4)
    long = SampleSchedule.on_grid(_grid(2.0, 0.01), 0.01, CART.outputs, CART.states, noise=noise, seed=4)
    V, W = short.measurement_noise(), short.process_increments()
    assert V.shape == (101, 2) and W.shape == (100, 3) and np.all(W[:, 2] == 0)
    assert np.array_equal(long.measurement_noise()[:101], V)        # a longer horizon, no process noise: the same draws
    assert not np.array_equal(short.with_seed(5).measurement_noise(), V)
    # sample k of output j is draw k of the generator keyed by (seed, stream 0 "measurement", j)
    for j, scale in enumerate((0.5, 0.1)):
        g = np.random.Generator(np.random.PCG64(np.random.SeedSequence(4, spawn_key=(0, j))))
        assert np.array_equal(V[:, j], scale * g.standard_normal(101))
    # the standard deviations are the scales (2 x 101 draws per channel, loose bounds)
    assert 0.3 < np.std(V[:, 0]) < 0.7 and 0.06 < np.std(V[:, 1]) < 0.14
    assert np.std(W[:, 0]) == pytest.approx(0.1 * np.sqrt(0.01), rel=0.35)


def test_the_compiled_loop_and_a_map_measure_with_the_schedules_noise():
    run = nlobs.simulate(CART, None, t_final=2.0, dt=0.01, x0=[0.0, 1.0, 0.3], inputs={"a": "sin(t)"},
                         noise=Noise.gaussian({"gps": 0.5, "wheel": 0.1}), sampling=Sampling({"gps": 0.25, "wheel": 0.1}),
                         seed=3)
    s = SampleSchedule.on_grid(run.t, 0.01, CART.outputs, CART.states, noise=Noise.gaussian({"gps": 0.5, "wheel": 0.1}),
                               sampling=Sampling({"gps": 0.25, "wheel": 0.1}), seed=3)
    m = s.measured()
    assert np.array_equal(run.info["measured"], m)
    assert np.allclose((run.y - run.y_true)[m], s.measurement_noise()[m], rtol=0, atol=1e-12)
    mrun = nlobs.simulate(MAP, None, t_final=3.0, x0=[1.0, 0.5], noise=Noise.gaussian(0.1), process_noise=ProcessNoise(0.05),
                          seed=8)
    ms = SampleSchedule.on_map(mrun.t, 0.1, MAP.outputs, MAP.states, noise=Noise.gaussian(0.1),
                               process_noise=ProcessNoise(0.05), seed=8)
    assert np.allclose(mrun.y - mrun.y_true, ms.measurement_noise(), rtol=0, atol=1e-12)
    # the plant's map by hand: x[k+1] = A x[k] + w[k]
    A = np.array([[0.9, 0.1], [-0.2, 0.8]])
    x, W = np.array([1.0, 0.5]), ms.process_increments()
    for k in range(W.shape[0]):
        x = A @ x + W[k]
    assert np.allclose(mrun.x[-1], x, rtol=0, atol=1e-12)


def test_monte_carlo_run_j_has_the_schedule_of_its_seed():
    mc = nlobs.montecarlo(MAP, None, t_final=1.0, x0=[1.0, 0.5], runs=3, noise=Noise.gaussian(0.1), seed=7)
    seeds = run_seeds(7, 3)
    assert np.array_equal(mc.seeds, seeds)
    assert np.array_equal(seeds, np.random.SeedSequence(7).generate_state(3).astype(np.int64))
    one = mc.trajectory(2)
    s = SampleSchedule.on_map(one.t, 0.1, MAP.outputs, MAP.states, noise=Noise.gaussian(0.1), seed=int(seeds[2]))
    assert np.allclose(one.y - one.y_true, s.measurement_noise(), rtol=0, atol=1e-12)
