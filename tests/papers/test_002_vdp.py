"""Acceptance, M8 #6: 002_613af42269ea26a7.txt Van der Pol with unknown γ, ω² (state-affine ż = A(y)z, Kalman-like)."""

import numpy as np
import pytest

from nlobs import Noise, design_kalman_like, simulate
from nlobs.design import design_from_config
from nlobs.examples import van_der_pol_unknown as ex
from nlobs.examples._util import bundled


def test_kalman_like_with_forgetting_recovers_gamma_and_omega2():
    mf = bundled("van_der_pol_unknown")
    cfg = mf.observers["kalman_like"]
    d = design_from_config(mf.system, cfg.kind, cfg.options)
    assert d.certificate.values["delta"] > 2 * d.certificate.values["sup_norm_A"]
    run = simulate(mf.system, d, t_final=30.0, dt=1e-3, x0=mf.simulation.x0, xhat0=cfg.options["xhat0"])
    g, w2 = run.observers["kalman_like"].xhat[-1, 2:]
    assert g == pytest.approx(ex.TRUE["gamma"], abs=1e-6)
    assert w2 == pytest.approx(ex.TRUE["omega2"], abs=1e-6)
    # the plant really is Van der Pol: ẋ = z2 + γ(y - y³/3) satisfies ẍ - γ(1 - x²)ẋ + ω²x = 0
    z1, z2 = run.x[:, 0], run.x[:, 1]
    xdot = z2 + 1.5 * (z1 - z1**3 / 3)
    xddot = np.gradient(xdot, run.t)
    resid = xddot - 1.5 * (1 - z1**2) * xdot + 2.0 * z1
    assert np.abs(resid[10:-10]).max() < 1e-4


def test_noise_keeps_the_parameter_estimates_close():
    s = ex.van_der_pol_unknown()
    d = design_kalman_like(s, Q=1e-2 * np.eye(4), R=[[1e-3]])
    run = simulate(s, d, t_final=40.0, dt=1e-3, x0=[2.0, 1.0, 1.5, 2.0], xhat0=[0, 0, 0.5, 1.0],
                   noise=Noise.gaussian(0.01), seed=1)
    g, w2 = run.observers["kalman_like"].xhat[-1, 2:]
    assert abs(g - 1.5) < 0.02 and abs(w2 - 2.0) < 0.02


def test_example_claims_hold():
    result = ex.run()
    assert all(c.holds is True for c in result.claims), [str(c) for c in result.claims if c.holds is not True]
    assert any("σ=" in r["run"] and np.isfinite(r["rms_error"]) for r in result.table)
