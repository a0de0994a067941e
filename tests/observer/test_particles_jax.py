"""The particle filter on the JAX engine against the compiled C loop, fed the same random numbers.

Reference: the C loop of observer/_particles.py (an independent implementation of the same algorithm, in C)
with the same draws (`draws=`): every output equal to rounding. With its own generator, the JAX filter must
track the plant as the C one does.
"""

from __future__ import annotations

import numpy as np
import pytest

import nlobs
from nlobs.errors import PreconditionError
from nlobs.observer._particles import _Job, draws_needed, particle_runner



VDP = nlobs.System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], params={"mu": 1.0})


def _data(system, t_final, dt, period, x0, seed=2):
    run = nlobs.simulate(system, {}, t_final=t_final, dt=dt, x0=x0, noise=nlobs.Noise.gaussian(0.05),
                         sampling=nlobs.Sampling(period), seed=seed)
    idx = np.round(np.arange(0, t_final + 1e-9, period) / dt).astype(int)
    return run.t[idx], run.y[idx], run.x[idx]


def _same(a, b):
    for f in ("xhat", "P", "loglik", "xhat_prior", "particles", "weights"):
        np.testing.assert_allclose(getattr(b, f), getattr(a, f), rtol=1e-11, atol=1e-12, err_msg=f)
    np.testing.assert_allclose(b.ess, a.ess, rtol=1e-12)
    np.testing.assert_array_equal(b.resampled, a.resampled)


def check_jax_equals_c_given_the_same_draws():
    for max_step in (None, 0.02):
        _same_draws(max_step)


def _same_draws(max_step):
    pf = nlobs.design_pf(VDP, Q=np.eye(2) * 1e-2, R=np.eye(1) * 0.05 ** 2, P0=np.eye(2), xhat0=[0.5, 0.0], particles=300,
                         seed=4, max_step=max_step)
    t, y, _ = _data(VDP, 3.0, 1e-3, 0.05, [2.0, 0.0])
    c, j = particle_runner(pf, "c"), particle_runner(pf, "jax")
    job = _Job.of(c, t, (), None, y, None, None, None, None, None)
    rng = np.random.default_rng(0)
    draws = (rng.standard_normal(draws_needed(pf, job.nsub, job.N, job.M)), rng.random(job.N))
    a, b = c.run(t, y=y, draws=draws), j.run(t, y=y, draws=draws)
    assert a.resampled.sum() > 3   # the resampling path is exercised
    _same(a, b)


def check_jax_equals_c_on_a_map_with_inputs_and_missing_samples():
    sys_ = nlobs.System(states=["p", "v"], f=["p + 0.1*v", "0.95*v + 0.1*u - 0.02*sin(p)"], inputs=["u"], outputs=["y"],
                        h=["atan(p)"], time="discrete", sample_time=0.1)
    pf = nlobs.design_pf(sys_, Q=np.diag([1e-4, 1e-3]), R=np.eye(1) * 0.02 ** 2, P0=np.eye(2) * 0.5, particles=200, seed=1)
    rng = np.random.default_rng(5)
    N = 60
    t, u = np.arange(N) * 0.1, np.sin(np.arange(N) * 0.3)[:, None]
    y = rng.normal(size=(N, 1)) * 0.02 + np.arctan(np.linspace(0, 2, N))[:, None]
    mask = np.ones((N, 1))
    mask[10:15] = 0
    c, j = particle_runner(pf, "c"), particle_runner(pf, "jax")
    job = _Job.of(c, t, (), u, y, mask, None, None, None, None)
    draws = (rng.standard_normal(draws_needed(pf, job.nsub, job.N, job.M)), rng.random(N))
    _same(c.run(t, u=u, y=y, mask=mask, draws=draws), j.run(t, u=u, y=y, mask=mask, draws=draws))


def check_jax_engine_tracks_with_its_own_generator():
    pf = nlobs.design_pf(VDP, Q=np.eye(2) * 1e-2, R=np.eye(1) * 0.05 ** 2, P0=np.eye(2), xhat0=[0.5, 0.0], particles=500,
                         seed=4, engine="jax")
    t, y, x = _data(VDP, 5.0, 1e-3, 0.05, [2.0, 0.0])
    run = particle_runner(pf).run(t, y=y)
    again = particle_runner(pf).run(t, y=y)
    np.testing.assert_array_equal(run.xhat, again.xhat)   # seeded: reproducible
    err = np.sqrt(np.mean((run.xhat[20:] - x[20:]) ** 2))
    ref = np.sqrt(np.mean((particle_runner(pf, "c").run(t, y=y).xhat[20:] - x[20:]) ** 2))
    assert err < 2 * ref + 0.02


def check_jax_engine_refuses_the_auxiliary_scheme():
    with pytest.raises(PreconditionError, match="bootstrap"):
        nlobs.design_pf(VDP, Q=np.eye(2), R=np.eye(1), particles=10, scheme="auxiliary", engine="jax")


def test_in_a_process_of_its_own():
    """JAX starts threads, and a process that has imported it must not fork afterwards (the global check races its
    routes in forked children): these checks run in a fresh interpreter, one after another, and each failure is shown."""
    import subprocess
    import sys

    code = ("import runpy, traceback, sys; g = runpy.run_path(sys.argv[1]); bad = 0\n"
            "for k in [k for k in g if k.startswith('check_')]:\n"
            "    try:\n        g[k]()\n    except Exception:\n        bad += 1; print('FAILED', k); traceback.print_exc()\n"
            "sys.exit(1 if bad else 0)")
    out = subprocess.run([sys.executable, "-c", code, __file__], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout[-6000:] + out.stderr[-6000:]
