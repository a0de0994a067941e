"""The JAX engine (engine/_jax.py) against CasADi's own evaluation and against the C engine.

References: CasADi evaluating the same function (the translation must not change a single operation), and
the C batch driver on the same Monte Carlo (same seeds, so the same noise): equal to rounding (1e-12).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import nlobs
from nlobs.engine import run_batch
from nlobs.engine._jax import to_jax
from nlobs.errors import EngineError



def check_every_operation_matches_casadi():
    import jax   # the test extra installs it; the README's demo command does not need it

    x = ca.SX.sym("x", 3)
    a, b, c = x[0], x[1], x[2]
    exprs = [a + b, a - b, a * b, a / b, -a, ca.exp(a), ca.log(b), b ** c, a ** 3, ca.sqrt(b), a ** 2, 2 * a,
             ca.sin(a), ca.cos(a), ca.tan(a), ca.asin(a / 4), ca.acos(a / 4), ca.atan(a), a < b, a <= b, a == b,
             a != b, ca.logic_not(a), ca.logic_and(a, b), ca.logic_or(a - a, b), ca.floor(b), ca.ceil(b), ca.fmod(b, a),
             ca.fabs(a - 2), ca.sign(a - 2), ca.copysign(b, a - 2), ca.if_else(a > 1, b, c), ca.erf(a), ca.fmin(a, b),
             ca.fmax(a, b), 1 / a, ca.sinh(a), ca.cosh(a), ca.tanh(a), ca.asinh(a), ca.acosh(b + 1), ca.atanh(a / 4),
             ca.atan2(a, b - 3), ca.log1p(b), ca.expm1(a), ca.hypot(a, b), ca.remainder(b * 3, a)]
    f = ca.Function("f", [x], [ca.vertcat(*exprs)])
    fj = to_jax(f)   # switches JAX to float64 before anything is traced
    g = jax.jit(lambda v: fj(v)[0])
    rng = np.random.default_rng(0)
    for _ in range(5):
        v = np.array([rng.uniform(0.3, 2.5), rng.uniform(0.5, 3.0), rng.uniform(-1, 1)])
        want = np.asarray(f(v), dtype=float).ravel()
        got = np.asarray(g(v))
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-14)


def check_erfinv_matches_scipy():
    # CasADi's own evaluation of erfinv is an approximation (8e-9 relative); the C engine refines it (engine/_codegen.py)
    from scipy.special import erfinv

    x = ca.SX.sym("x")
    fj = to_jax(ca.Function("f", [x], [ca.erfinv(x)]))
    v = np.linspace(-0.999, 0.999, 41)
    got = np.array([float(fj(np.array([a]))[0][0]) for a in v])
    np.testing.assert_allclose(got, erfinv(v), rtol=1e-13)


def check_unknown_operation_is_refused_by_name():
    x = ca.MX.sym("x", 2)
    lut = ca.interpolant("lut", "linear", [np.linspace(0, 1, 5)], np.arange(5.0))
    f = ca.Function("f", [x], [lut(x[0]) + x[1]])
    with pytest.raises(EngineError, match="engine='c'"):
        to_jax(f)


def check_batch_equals_c_with_escapes_and_per_run_constants():
    s, a, c = ca.SX.sym("s", 2), ca.SX.sym("a", 1), ca.SX.sym("c", 1)
    h = 0.01
    nxt = ca.vertcat(s[0] + h * s[1], s[1] + h * (c[0] * s[0] + a[0]))   # c > 0 escapes
    step = ca.Function("step", [s, a, c], [nxt, ca.vertcat(s[0] ** 2, a[0])])
    rng = np.random.default_rng(1)
    B, N = 6, 400
    S0 = rng.normal(size=(B, 2))
    A = rng.normal(size=(B, N + 1, 1))
    C = np.array([[-1.0], [-2.0], [300.0], [-0.5], [900.0], [-3.0]])
    ref = run_batch(step, S0, A, C, N, stride=7, bound=50.0, backend="c")
    got = run_batch(step, S0, A, C, N, stride=7, bound=50.0, backend="jax")
    np.testing.assert_array_equal(got[2], ref[2])
    assert (ref[2] < N).sum() == 2   # the two escaping runs stop, with their step
    for r, g in zip(ref[:2], got[:2]):
        assert np.array_equal(np.isnan(r), np.isnan(g))
        np.testing.assert_allclose(g, r, rtol=1e-12, atol=1e-12)


def check_montecarlo_jax_equals_c():
    vdp = nlobs.System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], params={"mu": 1.0})
    ekf = nlobs.design_ekf(vdp, Q=np.eye(2) * 1e-2, R=np.eye(1) * 1e-2, P0=np.eye(2), xhat0=[0.0, 0.0])
    x0 = np.random.default_rng(2).normal(size=(40, 2))
    kw = dict(t_final=2.0, dt=1e-3, x0=x0, noise=nlobs.Noise.gaussian(0.05), sampling=nlobs.Sampling(0.01), seed=3,
              save_every=20)
    ref = nlobs.montecarlo(vdp, {"ekf": ekf}, engine="c", **kw)
    got = nlobs.montecarlo(vdp, {"ekf": ekf}, engine="jax", **kw)
    np.testing.assert_array_equal(got.status, ref.status)
    np.testing.assert_allclose(got.x, ref.x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.observers["ekf"].xhat, ref.observers["ekf"].xhat, rtol=1e-12, atol=1e-12)


def check_montecarlo_jax_noise_inputs_stay_under_their_budget():
    """With noise, each run's per-step inputs are drawn on the host (as the C engine draws them) and sent to the
    device: runs whose inputs pass JAX_CHUNK_BYTES go in equal chunks under it, with the same results (to rounding)."""
    from nlobs.simulate import _montecarlo as mcm

    vdp = nlobs.System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], params={"mu": 1.0})
    ekf = nlobs.design_ekf(vdp, Q=np.eye(2) * 1e-2, R=np.eye(1) * 1e-2, P0=np.eye(2), xhat0=[0.0, 0.0])
    kw = dict(t_final=0.5, dt=1e-3, x0=np.random.default_rng(4).normal(size=(30, 2)), noise=nlobs.Noise.gaussian(0.05),
              seed=5, save_every=50)
    whole = nlobs.montecarlo(vdp, {"ekf": ekf}, engine="jax", **kw)
    budget = mcm.JAX_CHUNK_BYTES
    try:
        mcm.JAX_CHUNK_BYTES = 1   # less than one run's inputs: one run a chunk
        split = nlobs.montecarlo(vdp, {"ekf": ekf}, engine="jax", **kw)
    finally:
        mcm.JAX_CHUNK_BYTES = budget
    assert whole.info["chunk"] == 30 and split.info["chunk"] == 1, (whole.info, split.info)
    # (XLA compiles a batch of one run and one of 30 apart: equal to rounding, not bit for bit)
    np.testing.assert_allclose(split.x, whole.x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(split.observers["ekf"].xhat, whole.observers["ekf"].xhat, rtol=1e-12, atol=1e-12)


def _integrated_noise(noise, process, draws, M=2000, chunk=None, seed=7):
    """x' = 0 (x(0) = 0) with process noise, y = x + v, and an observer q' = y: q(T) = dt * sum of the held y_k.
    Returns (x(T), q(T)) over M runs."""
    plant = nlobs.System(states=["x"], f=["0"], outputs=["y"], h=["x"])
    obs = nlobs.design_custom(plant, states=["q"], flow=["y"])
    mc = nlobs.montecarlo(plant, {"o": obs}, t_final=1.0, dt=1e-2, x0=np.zeros((M, 1)), noise=noise, process_noise=process,
                          seed=seed, engine="jax", draws=draws, chunk=chunk, save_every=100)
    return mc, mc.x[:, -1, 0], mc.observers["o"].xhat[:, -1, 0]


def check_noise_drawn_on_the_device_has_the_host_noise_statistics():
    """draws='device': JAX draws each step's noise inside the runs. Reference: the variances of the sums, derived
    (N = 100 steps of dt = 0.01): process noise σ√dt·ξ per step, x(T) = Σ w_i, Var = σ²T; Σ_k dt·x_k = dt·Σ_i (N−1−i)w_i,
    Var = σ²dt³·(N−1)N(2N−1)/6; measurement noise Σ_k dt·v_k, Var = s²·dt·T (Gaussian), (s²/3)·dt·T (uniform in ±s),
    s²·h·dt·T with a fresh draw every h = 5 steps held; 2,000 runs, each variance within 12 % (about 4 standard errors)."""
    sig, s, dt, N = 0.3, 0.5, 1e-2, 100
    _, x, q = _integrated_noise(None, nlobs.ProcessNoise(sig), "device")
    np.testing.assert_allclose(x.var(), sig ** 2 * 1.0, rtol=0.12)
    np.testing.assert_allclose(q.var(), sig ** 2 * dt ** 3 * (N - 1) * N * (2 * N - 1) / 6, rtol=0.12)
    for noise, var in ((nlobs.Noise.gaussian(s), s ** 2 * dt), (nlobs.Noise.uniform(s), s ** 2 / 3 * dt),
                       (nlobs.Noise.gaussian(s, hold=0.05), s ** 2 * 5 * dt)):
        mc, x, q = _integrated_noise(noise, None, "device")
        assert np.all(x == 0)
        np.testing.assert_allclose(q.var(), var, rtol=0.12)
        assert abs(q.mean()) < 4 * np.sqrt(var / q.size)
        _, _, q_host = _integrated_noise(noise, None, "host")
        np.testing.assert_allclose(q_host.var(), var, rtol=0.12)   # the derivation holds for the host's noise too
        assert not np.allclose(q, q_host)   # other generator, other numbers


def check_noise_drawn_on_the_device_mixes_kinds_per_output():
    """Gaussian noise on one output, uniform on the other (Noise.per_output): each sum's variance as derived above."""
    s, dt = 0.5, 1e-2
    plant = nlobs.System(states=["xa", "xb"], f=["0", "0"], outputs=["ya", "yb"], h=["xa", "xb"])
    obs = nlobs.design_custom(plant, states=["qa", "qb"], flow=["ya", "yb"])
    mc = nlobs.montecarlo(plant, {"o": obs}, t_final=1.0, dt=dt, x0=np.zeros((2000, 2)), seed=3, engine="jax",
                          noise=nlobs.Noise.per_output(gaussian={"ya": s}, uniform={"yb": s}), draws="device", save_every=100)
    qa, qb = mc.observers["o"].xhat[:, -1, 0], mc.observers["o"].xhat[:, -1, 1]
    np.testing.assert_allclose(qa.var(), s ** 2 * dt, rtol=0.12)
    np.testing.assert_allclose(qb.var(), s ** 2 / 3 * dt, rtol=0.12)


def check_noise_drawn_on_the_device_depends_on_the_seeds_alone():
    noise, process = nlobs.Noise.gaussian(0.5), nlobs.ProcessNoise(0.3)
    mc, x, q = _integrated_noise(noise, process, "device", M=300)
    _, x2, q2 = _integrated_noise(noise, process, "device", M=300, chunk=70)   # other chunks: the same runs
    np.testing.assert_allclose(x2, x, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(q2, q, rtol=1e-12, atol=1e-15)
    _, x3, _ = _integrated_noise(nlobs.Noise.uniform(0.5), process, "device", M=300)
    np.testing.assert_allclose(x3, x, rtol=1e-12, atol=1e-15)   # the process noise of a run does not depend on the other stream
    _, x4, _ = _integrated_noise(noise, process, "device", M=300, seed=8)
    assert not np.allclose(x4, x)
    with pytest.raises(ValueError, match="draws='device'"):
        mc.trajectory(0)
    plant = nlobs.System(states=["x"], f=["0"], outputs=["y"], h=["x"])
    with pytest.raises(nlobs.errors.ShapeError, match="needs engine='jax'"):
        nlobs.montecarlo(plant, {}, t_final=0.1, dt=1e-2, x0=np.zeros((2, 1)), noise=noise, draws="device")


def check_a_step_too_large_for_xla_is_refused_before_compiling():
    """The 12-state quadrotor's EKF step (34,545 operations) took XLA more than 4 minutes and 19 GB: refused at once,
    naming the engine that runs it; the limit can be lowered (and raised) by the environment."""
    import os
    import time

    m = nlobs.load_model("quadrotor")
    s, sc = m.system, m.simulation
    ekf = nlobs.design_ekf(s, Q=np.eye(12) * 1e-3, R=np.eye(13) * 1e-2, P0=np.eye(12), xhat0=np.array(sc.x0) + 0.1)
    t0 = time.perf_counter()
    with pytest.raises(EngineError, match=r"has 3\d,\d{3} scalar operations.*engine='c'"):
        nlobs.montecarlo(s, {"ekf": ekf}, t_final=0.01, dt=sc.dt, x0=np.tile(sc.x0, (2, 1)), inputs=dict(sc.inputs),
                         engine="jax")
    assert time.perf_counter() - t0 < 60
    vdp = nlobs.System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], params={"mu": 1.0})
    small = nlobs.design_ekf(vdp, Q=np.eye(2) * 1e-2, R=np.eye(1) * 1e-2, P0=np.eye(2), xhat0=[0.0, 0.0])
    os.environ["NLOBS_JAX_MAX_OPERATIONS"] = "100"
    try:
        with pytest.raises(EngineError, match="more than the 100 "):
            nlobs.montecarlo(vdp, {"ekf": small}, t_final=0.1, dt=1e-2, x0=np.ones((2, 2)), engine="jax")
    finally:
        del os.environ["NLOBS_JAX_MAX_OPERATIONS"]


def check_xla_programs_are_kept_beside_the_c_builds():
    """JAX's persistent cache is nlobs's cache directory's ``jax`` folder, so a compiled program outlives the process
    (the threshold lowered here: this program compiles in well under JAX's default second)."""
    import jax

    from nlobs.engine import cache_dir

    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0)
    folder = cache_dir() / "jax"
    before = set(folder.glob("*")) if folder.exists() else set()
    plant = nlobs.System(states=["x"], f=["-1.5*x + sin(x)"], outputs=["y"], h=["x"])
    nlobs.montecarlo(plant, {}, t_final=0.3, dt=1e-2, x0=np.ones((3, 1)), engine="jax")
    assert jax.config.jax_compilation_cache_dir == str(folder)
    assert set(folder.glob("*")) - before, f"nothing written to {folder}"


def check_batch_programs_on_the_cpu_compile_without_the_fusion_emitters():
    """XLA's CPU fusion emitters recompute a fused value at each use: a step's run time then grew exponentially with its
    depth (a 6-state chain integrated by 5 RK4 steps, 64 runs: 9.2 s a call, 0.5 ms without them). The batch program
    is compiled with them off on the CPU, and only there."""
    import jax

    from nlobs.engine import _jax as J

    x, a, c = ca.SX.sym("x", 2), ca.SX.sym("a", 1), ca.SX.sym("c", 1)
    step = ca.Function("step", [x, a, c], [x * c + a, x])
    seen = []
    real = jax.jit
    jax.jit = lambda fn, **kw: (seen.append(kw), real(fn, **kw))[1]
    try:
        J._batch_program(step, 1e6, True, True)
    finally:
        jax.jit = real
    assert jax.default_backend() != "cpu" or {"compiler_options": {"xla_cpu_use_fusion_emitters": False}} in seen


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
