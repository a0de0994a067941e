"""Acceptance, M8 #4: 003_a2c72ccb4281ea3f.txt examples 3.1 (Kou et al.) and 3.2, with and without perturbations."""

import numpy as np
import pytest

from nlobs import design_banks, simulate
from nlobs.examples import banks as ex


@pytest.mark.parametrize("perturbed", [False, True])
def test_example_3_1_rate(perturbed):
    # 003 ex. 3.1: P = (-2, 1)ᵀ, λ([[-1, -2], [2, -1]]) = -1; perturbations of slope <= δ = 0.5 < 1 (Lemma 2.4).
    s = ex.example_31(perturbed)
    d = design_banks(s, L=[[-2.0], [1.0]], region={"x2": (-5.0, 1e6)},
                     perturbation=["0.5*sin(x1)", "0.5*sin(x2)"] if perturbed else None,
                     perturbation_bound=0.5 if perturbed else None)
    assert d.certificate.values["epsilon"] == pytest.approx(1.0, abs=1e-12)
    rate = 0.5 if perturbed else 1.0
    assert d.certificate.values["guaranteed_rate"] == pytest.approx(rate)
    run = simulate(s, d, t_final=8.0, dt=1e-3, x0=[1.0, 0.0], xhat0=[-1.0, 1.0])
    assert ex.bound_ratio(run.t, run.error_norm(), rate) <= 1 + 1e-6


@pytest.mark.parametrize("perturbed", [False, True])
def test_example_3_2_rate(perturbed):
    # 003 ex. 3.2: gains (-1, 4), λ(Df + P·DB) <= -1, f1, f2 Lipschitz K = 0.5 < 1 (Theorem 2.6): rate ε - K.
    s = ex.example_32(perturbed)
    d = design_banks(s, L=[[-1.0], [4.0]], region={"x1": (-3.0, 3.0), "x2": (-3.0, 3.0)},
                     perturbation=["0.5*sin(x1)", "0.5*tanh(x2)"] if perturbed else None)
    rate = 0.5 if perturbed else 1.0
    assert d.certificate.values["guaranteed_rate"] == pytest.approx(rate, abs=1e-9)
    for x0, xhat0 in (((1.0, -1.0), (-1.0, 2.0)), ((-0.5, 1.5), (1.0, -1.0))):
        run = simulate(s, d, t_final=10.0, dt=1e-3, x0=x0, xhat0=xhat0)
        assert ex.bound_ratio(run.t, run.error_norm(), rate) <= 1 + 1e-6
        assert np.abs(run.observers["banks"].xhat).max() <= 3.0  # stays in the certified region


def test_example_claims_hold_and_noise_rows_are_reported():
    result = ex.run()
    assert all(c.holds is True for c in result.claims), [str(c) for c in result.claims if c.holds is not True]
    noisy = [r for r in result.table if "σ=" in r["run"]]
    assert len(noisy) == 4 and all(np.isfinite(r["rms_error"]) for r in noisy)
