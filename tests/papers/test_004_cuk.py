"""Acceptance, M8 #9: 004_f1e237c45ff4719e.txt §V-C — the Ćuk converter (50) and the observers of Table I.

The observers come from models/cuk.toml; their equations are checked here against formulas derived
by hand from (50) (independently of the design code), the I&I and KKL error laws against their closed
forms, the noise level of the KKLO's v4 estimate against the variance of a first-order filter driven
by held uniform noise, and the example's comparison against the paper's claims.
"""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import simulate
from nlobs.examples import cuk_converter as ex

P = dict(L1=0.01, C2=22.0e-6, L3=0.01, C4=22.9e-6, G=0.0447, E=12.0)   # 004 §V-C (L3 = 10 mH is our choice)
G1, G2 = 50.0, 1.0


@pytest.fixture(scope="module")
def designs():
    return ex.designs()


@pytest.fixture(scope="module")
def result():
    return ex.run()


def _flow(d, z, u, y):
    return np.asarray(d.flow(0.0, z, [u], y)).ravel(), np.asarray(d.output(0.0, z, [u], y)).ravel()


def test_model_parameters_are_the_papers():
    s = ex.model()
    for k, v in P.items():
        assert s.params["Vin" if k == "E" else k] == pytest.approx(v)


def test_iandi_is_eq_18_with_the_corrected_signs(designs):
    # ξ1' = -γ1(1-u)(ξ1 + C2γ1y1) - γ1 u y2 + (E - (1-u)y1)/L1,  x̂1 = ξ1 + C2γ1y1
    # ξ2' = (y2 - G(ξ2 - L3γ2y2))/C4 - γ2(u y1 + ξ2 - L3γ2y2), x̂2 = ξ2 - L3γ2y2   (Table I, derived again from (50))
    L1, C2, L3, C4, G, E = (P[k] for k in ("L1", "C2", "L3", "C4", "G", "E"))
    z, u, y = np.array([0.3, -2.0]), 0.6, np.array([31.0, -0.9])
    flow, xhat = _flow(designs["I&IO"], z, u, y)
    x1, x2 = z[0] + C2 * G1 * y[0], z[1] - L3 * G2 * y[1]
    assert flow[0] == pytest.approx(-G1 * (1 - u) * x1 - G1 * u * y[1] + (E - (1 - u) * y[0]) / L1, rel=1e-12)
    assert flow[1] == pytest.approx((y[1] - G * x2) / C4 - G2 * (u * y[0] + x2), rel=1e-12)
    assert xhat[:2] == pytest.approx([x1, x2], rel=1e-12)


def test_iandi_error_law(designs):
    # off the manifold: ḋ1 = -γ1(1-u)d1, ḋ2 = -(γ2 + G/C4)d2 (from (16) with the maps of Table I)
    s = ex.model()
    x0 = ex.equilibrium(20.0, s.params)
    run = simulate(s, {"ii": designs["I&IO"]}, t_final=0.05, dt=5e-6, x0=x0, inputs={"u": 0.625})
    e = run.error("ii")
    d0 = e[0, :2]
    assert np.allclose(e[:, 0], d0[0] * np.exp(-G1 * 0.375 * run.t), atol=1e-9 * abs(d0[0]) + 1e-12)
    assert np.allclose(e[:, 1], d0[1] * np.exp(-(G2 + P["G"] / P["C4"]) * run.t), atol=1e-6)


def test_kklo_and_pebo_maps(designs):
    L1, C2, L3, C4, G, E = (P[k] for k in ("L1", "C2", "L3", "C4", "G", "E"))
    z, u, y = np.array([-19.0, 0.02]), 0.6, np.array([31.0, -0.9])
    flow, xhat = _flow(designs["KKLO"], z, u, y)
    assert flow == pytest.approx([-G / C4 * z[0] + y[1] / C4,
                                  -(1 - u) / L1 * z[1] + (1 + C2 / L1) * (u - 1) * y[0] + E - u * y[1]], rel=1e-12)
    assert xhat[:2] == pytest.approx([(z[1] + C2 * y[0]) / L1, z[0]], rel=1e-12)
    d = designs["PEBO"]
    zp = np.zeros(d.n_z)
    flow, _ = _flow(d, zp, u, y)
    # ξ' = B(y, u) with B2 = (y2 + G u y1)/C4 (the printed "y2 + G u_1" derived again from (50))
    assert flow[:2] == pytest.approx([(E - (1 - u) * y[0]) / L1, (y[1] + G * u * y[0]) / C4], rel=1e-12)


def test_kklo_v4_noise_matches_a_first_order_filter(result):
    # ξ1' = -(G/C4)ξ1 + y2/C4: held uniform noise ±b every Δ on y2 gives, stationary, with φ(τ) = e^{-aτ}, g = 1/G:
    # E η² averaged over a hold interval = V mean(φ²) + g² σ² mean((1 - φ)²), V = g²σ²(1 - φ_Δ)²/(1 - φ_Δ²)
    a, g, s2, D = P["G"] / P["C4"], 1 / P["G"], (2e-4) ** 2 / 3, 1e-4
    phD = np.exp(-a * D)
    V = g * g * s2 * (1 - phD) ** 2 / (1 - phD**2)
    ph = np.exp(-a * np.linspace(0, D, 2001)[:-1])
    predicted = np.sqrt(V * np.mean(ph**2) + g * g * s2 * np.mean((1 - ph) ** 2))
    row = [r for r in result.table if r["observer"] == "KKLO" and r["run"].startswith("v4")][0]
    assert row["noise_induced_rms"] == pytest.approx(predicted, rel=0.1)


def test_example_claims(result):
    by = {c.text: c for c in result.claims}
    must_hold = [t for t in by if not by[t].paper]
    assert all(by[t].holds for t in must_hold), [str(by[t]) for t in must_hold if not by[t].holds]
    # the paper's claims that the numbers contradict (the finding of test_the_papers_noise_claims_as_measured) are
    # shown as what they are: checked, not true, and why; the example does not fail for them
    not_true = [c for c in result.claims if c.not_true]
    assert [c.text for c in not_true] == ["KKLO is the least sensitive to noise — i1 estimate",
                                          "the high-gain observers perform worst — RMS v4 error under noise"]
    assert "HGO (linear) is less noise-sensitive than KKLO in i1" in not_true[0].why and "C2 = 22 µF" in not_true[0].why
    assert "PEBO" in not_true[1].why and "drifts" in not_true[1].why
    assert result.ok and result.tally == "claims 8/10 hold, 2 of the paper's checked and not true"
    assert len(result.table) == 12 and {r["order"] for r in result.table if r["observer"] in ("KKLO", "I&IO")} == {2}


def test_the_papers_noise_claims_as_measured(result):
    # the measured outcome (a partial confirmation), kept as a regression of the finding reported in the notes
    rows = {(r["observer"], r["run"][:2]): r for r in result.table}
    noise = {k: v["noise_induced_rms"] for k, v in rows.items()}
    others = [o for o in ex.LABELS.values() if o != "KKLO"]
    assert all(noise[("KKLO", "v4")] <= 1.01 * noise[(o, "v4")] for o in others)        # KKLO least sensitive: v4
    assert noise[("HGO (linear)", "i1")] < noise[("KKLO", "i1")]                          # ... but not for i1
    rms = {k: v["rms_error"] for k, v in rows.items()}
    hg = ("HGO (time-varying)", "HGO (linear)")
    rest = [o for o in ex.LABELS.values() if o not in hg]
    assert min(rms[(h, "i1")] for h in hg) > max(rms[(o, "i1")] for o in rest)         # HGOs worst: i1
    assert rms[("PEBO", "v4")] > rms[("HGO (time-varying)", "v4")]                      # not in v4: PEBO's drift
