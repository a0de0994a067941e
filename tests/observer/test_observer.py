"""The runnable observer: step, update, online use, agreement with the batch paths."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import DataError, Observer, Recording, Sampling, System, design_ekf, design_output_injection, estimate, simulate

PEND = System(states=["x1", "x2"], f=["x2", "-9.81*sin(x1) - 0.5*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"], name="pend")


def test_step_matches_an_independent_rk4():
    d = design_output_injection(PEND, poles=[-2, -3])
    obs = Observer(d)
    z, y, u, dt = np.array([0.2, -0.1]), 0.5, 0.3, 0.05

    def f(zz):
        return obs.rhs(0.0, zz, [u], [y])

    k1 = f(z); k2 = f(z + dt / 2 * k1); k3 = f(z + dt / 2 * k2); k4 = f(z + dt * k3)  # noqa: E702
    assert np.allclose(obs.step(0.0, z, dt, [u], [y]), z + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4), atol=1e-15)
    # substeps converge to the same flow
    assert np.allclose(obs.step(0.0, z, dt, [u], [y], substeps=50), obs.step(0.0, z, dt, [u], [y], substeps=100), atol=1e-12)


def test_online_observer_equals_the_batch_estimate():
    run = simulate(PEND, t_final=3.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": "sin(t)"}, sampling=Sampling(0.01))
    rec = Recording.from_run(run, every=10)
    for design in (design_output_injection(PEND, poles=[-2, -3]), design_ekf(PEND, Q=np.eye(2) * 1e-3, R=[[1e-4]])):
        batch = estimate(design, rec, max_step=2e-3).observers[design.method].xhat
        online = Observer(design).start()
        online.max_step = 2e-3
        xs = np.array([online.update(t, y=y, u=u) for t, y, u in zip(rec.t, rec.y, rec.u)])
        assert np.max(np.abs(xs - batch)) < 1e-12


def test_online_observer_checks_time_and_handles_missing_outputs():
    d = design_ekf(PEND, Q=np.eye(2) * 1e-3, R=[[1e-4]])
    online = Observer(d).start(xhat0=[0.1, 0.0])
    online.update(0.0, y=[0.2], u=[0.0])
    before = online.z.copy()
    online.update(0.01, y=[np.nan], u=[0.0])  # missing: prediction only
    pred = Observer(d).step(0.0, before, 0.01, [0.0], [0.2])
    assert np.allclose(online.z, pred)
    with pytest.raises(DataError, match="time must increase .* got t = 0.005 after t = 0.01"):
        online.update(0.005, y=[0.2], u=[0.0])
    with pytest.raises(DataError, match="must be finite"):
        online.update(0.02, y=[np.inf], u=[0.0])


def test_online_observer_refuses_the_same_time_twice():
    """estimate() refuses duplicate times; so does the online path: a second update at the same t would count the
    measurement twice (the EKF's P shrank at every repetition)."""
    d = design_ekf(PEND, Q=np.eye(2) * 1e-3, R=[[1e-4]])
    online = Observer(d).start()
    online.update(0.0, y=[0.2], u=[0.0])
    online.update(0.01, y=[0.2], u=[0.0])
    z = online.z.copy()
    with pytest.raises(DataError, match="the same time again: a second update would count the measurement twice"):
        online.update(0.01, y=[0.2], u=[0.0])
    assert np.array_equal(online.z, z) and online.t == 0.01  # nothing changed
    with pytest.raises(DataError, match="`t` must be a number"):
        online.update("soon", y=[0.2], u=[0.0])  # type: ignore[arg-type]
    with pytest.raises(DataError, match="the input u = .* must be finite"):
        online.update(0.02, y=[0.2], u=[np.nan])


def test_online_observer_options_and_non_finite_states():
    d = design_ekf(PEND, Q=np.eye(2) * 1e-3, R=[[1e-4]])
    for bad in (0, -1e-3, np.inf):
        with pytest.raises(ValueError, match="`max_step` must be a positive number"):
            Observer(d).start(max_step=bad)
    with pytest.raises(TypeError, match="needs an observer"):
        from nlobs import OnlineObserver

        OnlineObserver(d)  # type: ignore[arg-type]
    online = Observer(d).start(max_step=1e-3)
    online.update(0.0, y=[0.2], u=[0.0])
    z = online.z.copy()
    from nlobs import FiniteEscapeError

    with pytest.raises(FiniteEscapeError, match="became .* at t = 0.01 .*the state before this sample is kept"):
        online.update(0.01, y=[1e308], u=[0.0])
    assert np.array_equal(online.z, z) and online.t == 0.0


def test_observer_needs_a_design():
    with pytest.raises(TypeError, match="needs an ObserverDesign"):
        Observer(PEND)  # type: ignore[arg-type]
