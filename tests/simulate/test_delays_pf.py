"""The particle filter on late samples: re-processed from saved clouds, it equals the same particle filter (same seed)
run on time on the samples that have arrived (the definition of exact delay handling, simulate/_delays.py)."""

from __future__ import annotations

import numpy as np

import nlobs
from nlobs import System
from nlobs.observer._particles import particle_runner
from nlobs.simulate import Noise, Sampling

CART = System(states=["p", "v", "b"], inputs=["a"], outputs=["gps", "wheel"], f=["v", "a - 0.1*v", "0"],
              h=["p", "v + b"], name="cart")
KW = dict(dt=0.01, x0=[0.0, 1.0, 0.3], inputs={"a": "sin(0.5*t)"}, noise=Noise.per_output({"gps": 0.5, "wheel": 0.1}),
          sampling=Sampling({"gps": 0.25, "wheel": 0.1}), seed=3)
DELAY = {"gps": 0.37, "wheel": 0.12}   # late by more than a sample period of each, so passes restart behind each other


def _pf(scheme="bootstrap"):
    return nlobs.design_pf(CART, R=np.diag([0.25, 0.01]), Q=np.diag([1e-4, 1e-3, 1e-6]), P0=np.diag([25.0, 1.0, 0.25]),
                           xhat0=[5.0, 0.0, 0.0], particles=400, seed=7, scheme=scheme)


def _on_time(pf, plant, k):
    """The plain filter, run at the sample instants up to row k, on the samples arrived by t_k."""
    t, y, u, measured = plant.t, plant.y, plant.u, plant.info["measured"]
    rows = np.flatnonzero(measured.any(axis=1) & (np.arange(t.size) <= k))
    d = np.array([DELAY["gps"], DELAY["wheel"]])
    arrived = measured[rows] & (t[rows, None] + d[None, :] <= t[k] + 1e-9)
    return particle_runner(pf).run(t[rows], u=u[rows], y=y[rows], mask=arrived.astype(float))


def test_a_particle_filter_on_late_samples_equals_it_on_time_on_the_arrived_samples():
    for scheme in ("bootstrap", "auxiliary"):
        pf = _pf(scheme)
        late = nlobs.simulate(CART, {"pf": pf}, t_final=4.0, delay=DELAY, **KW)
        plant = nlobs.simulate(CART, None, t_final=4.0, **KW)
        xhat = late.observers["pf"].xhat
        assert np.all(np.isfinite(xhat))
        for k in (37, 150, 212, 399, 400):
            ref = _on_time(pf, plant, k)
            np.testing.assert_allclose(xhat[k], ref.xhat[-1], rtol=0, atol=1e-10, err_msg=f"{scheme}, row {k}")
        # the estimate uses the late samples: it converges as the on-time filter does
        ontime = nlobs.simulate(CART, {"pf": pf}, t_final=4.0, **KW).observers["pf"].xhat
        assert np.abs(xhat[-1] - ontime[-1]).max() < 0.5


def test_estimate_on_a_recording_stamped_at_arrival_runs_the_particle_filter(tmp_path):
    run = nlobs.simulate(CART, {"pf": _pf()}, t_final=6.0, delay=DELAY, **KW)
    path = tmp_path / "late.csv"
    run.to_csv(path)
    rec = nlobs.Recording.from_csv(path, CART)
    est = nlobs.estimate({"pf": _pf()}, rec, delay=DELAY, on_missing="skip")
    x = np.interp(est.t, run.t, run.x[:, 0])
    err = np.abs(est.observers["pf"].xhat[:, 0] - x)
    assert np.all(np.isfinite(err)) and err[-20:].max() < 1.0 < err[0]   # starts 5 m off, ends within a metre
