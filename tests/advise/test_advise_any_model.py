"""The advisor on models a practitioner brings (issue 20): tuning that stays inside what the run visits,
"applies" meaning the design runs, budgets that keep large models answering, and a ranking that no single
state's units decide.

Every model here is written for these tests (none is a paper's example). Reference values are computed
independently in the tests (binomial coefficients, the run's own range, the error by hand).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import nlobs
from nlobs.advise import advise
from nlobs.advise._advice import Score
from nlobs.advise._rank import rank
from nlobs.errors import PreconditionError
from nlobs.model import SimulationConfig, parse_expression, symbol


def _sim(x0, inputs=None, **kw):
    ins = {k: parse_expression(v, {"t": symbol("t")}) for k, v in (inputs or {}).items()}
    return SimulationConfig(t_final=kw.pop("t_final", 10.0), dt=kw.pop("dt", 1e-3), x0=tuple(x0), inputs=ins,
                            noise=kw.pop("noise", {}), sample_period=kw.pop("sample_period", 0.01), seed=1)


def lorenz96(n: int) -> nlobs.System:
    """Lorenz-96 with n sites, every other site measured."""
    f = [f"(x{(i + 1) % n} - x{(i - 2) % n})*x{(i - 1) % n} - x{i} + 8" for i in range(n)]
    return nlobs.System(states=[f"x{i}" for i in range(n)], f=f, outputs=[f"y{i}" for i in range(0, n, 2)],
                        h=[f"x{i}" for i in range(0, n, 2)], name=f"lorenz96_{n}")


def test_learned_kkl_refuses_a_feature_count_it_cannot_fit_before_simulating():
    # n = 8 states, p = 4 outputs: n_ξ = (n + 1)p = 36, so (ξ, y) has 40 entries; degree 3 has C(43, 3) monomials
    sys8 = lorenz96(8)
    features = math.comb(40 + 3, 3)
    assert features == 12341
    with pytest.raises(PreconditionError, match=r"12,341 monomial features.*limit is 2,000.*degree 2 fits"):
        nlobs.design_kkl_learned(sys8, region=[(-10.0, 10.0)] * 8, degree=3)


def test_the_advisor_tunes_the_learned_kkl_degree_to_the_feature_limit():
    sys8 = lorenz96(8)
    adv = advise(sys8, simulation=_sim([8.01] + [8.0] * 7, t_final=2.0, noise={f"y{i}": 0.05 for i in range(0, 8, 2)},
                                        sample_period=0.02), kinds=["kkl_learned"])
    c = adv.candidate("kkl_learned")
    assert c.applies, c.why
    assert c.options["degree"] == 2 and math.comb(42, 2) <= 2000 < math.comb(43, 3)


def battery() -> nlobs.System:
    """A cell with a 1-RC circuit: SOC falls under a positive current from 0.9; the output saturates near SOC = 1."""
    return nlobs.System(states=["soc", "v1"], f=["-I/8280", "-v1/40 + I/2000"], inputs=["I"], outputs=["V"],
                        h=["3 + 1.1*soc - 0.9*soc**2 + 0.55*soc**3 - v1 - 0.015*I"], name="cell")


def test_initial_estimate_inside_the_visited_box_and_p0_from_its_offset():
    sim = _sim([0.9, 0.0], {"I": "2.3 + 2*sin(0.01*t)"}, t_final=1800.0, dt=0.1, sample_period=1.0, noise={"V": 0.002})
    adv = advise(battery(), simulation=sim, kinds=["ekf"])
    ctx_x0 = np.array([0.9, 0.0])
    soc = np.array([0.9 - (2.3 * t + 200 * (1 - np.cos(0.01 * t))) / 8280 for t in np.linspace(0, 1800, 1801)])
    ekf = adv.candidate("ekf")
    xhat0 = np.asarray(ekf.options["xhat0"])
    assert soc.min() - 1e-9 <= xhat0[0] <= soc.max() + 1e-9        # a state of charge stays in what the run visits (< 1)
    assert xhat0[0] != ctx_x0[0]
    P0 = np.asarray(ekf.options["P0"])
    span = soc.max() - soc.min()
    sd0 = np.sqrt(P0[0, 0])
    assert sd0 == pytest.approx(abs(xhat0[0] - 0.9), rel=1e-3)   # the offset (a one-σ error), not the range
    assert sd0 < span


def chemostat() -> nlobs.System:
    """Monod growth; the substrate sits in a denominator (S/(Ks + S)): sigma points must not cross S = -Ks."""
    return nlobs.System(states=["S", "X"], f=["D*(10 - S) - 0.65*S/(0.8 + S)*X/0.5", "0.65*S/(0.8 + S)*X - D*X"],
                        inputs=["D"], outputs=["y"], h=["X"], name="chemostat")


def test_ukf_keeps_its_sigma_points_in_the_box_and_runs():
    sim = _sim([2.0, 1.0], {"D": "0.3 + 0.1*sin(0.3*t)"}, t_final=30.0, dt=0.01, sample_period=0.1, noise={"y": 0.02})
    adv = advise(chemostat(), simulation=sim, kinds=["ukf", "ekf"], run=True)
    ukf = adv.candidate("ukf")
    assert ukf.applies, ukf.why
    assert ukf.options["bounds"]["S"][0] > 0                        # S in a denominator and positive on the run
    # the sigma points x̂ ± α√n σ_i stay within half the width of the box the run visits (padded by 10 % + 1e-3)
    alpha = ukf.options.get("alpha", 1.0)
    sd = np.sqrt(np.diag(np.asarray(ukf.options["P0"])))
    x = adv.run.x[:, :2]
    lo, hi = x.min(axis=0), x.max(axis=0)
    width = (hi - lo) * 1.2 + 2e-3 * np.maximum(1.0, np.maximum(np.abs(lo), np.abs(hi)))
    assert np.all(alpha * np.sqrt(2) * sd <= 0.5 * width * (1 + 1e-3))
    scores = {s.kind: s for s in adv.scores}
    assert scores["ukf"].status == "ok" and scores["ukf"].rms_error < 0.1


def test_ranking_uses_each_state_relative_to_its_range():
    # a: error 1 in a state whose range is 100; b: error 0.5 in a state whose range is 0.1. In raw units a is worse;
    # relative to the ranges b is 50x worse.
    a = Score("a", "ok", rms_error=1.0, convergence_time=1.0, final_error=1.0, normalised_rms=0.01)
    b = Score("b", "ok", rms_error=0.5, convergence_time=1.0, final_error=0.5, normalised_rms=5.0)
    assert [s.kind for s in rank([b, a])] == ["a", "b"]


def test_normalised_error_is_the_scaled_rms_of_the_last_fifth():
    sim = _sim([2.0, 1.0], {"D": "0.3 + 0.1*sin(0.3*t)"}, t_final=20.0, dt=0.01, sample_period=0.1, noise={"y": 0.02})
    adv = advise(chemostat(), simulation=sim, kinds=["ekf"], run=True)
    run, s = adv.run, adv.scores[0]
    err = run.observers["ekf"].xhat[:, :2] - run.x[:, :2]
    tail = run.t >= run.t[-1] - 0.2 * (run.t[-1] - run.t[0])
    span = run.x.max(axis=0) - run.x.min(axis=0)
    mag = np.abs(run.x).max(axis=0)
    scale = np.where(span > 0.05 * mag, span, 0.5 * mag)
    assert s.normalised_rms == pytest.approx(float(np.sqrt(np.mean((err[tail] / scale) ** 2))), rel=0.05)


def test_a_design_that_blows_up_is_not_listed_as_applying():
    # an EKF whose R is far too small for the noise and whose Q is 0 on a stiff exponential output: with the screen the
    # advisor moves what blows up to "does not apply" with the measured time (the same path as --run)
    from nlobs.advise._advice import Candidate
    from nlobs.advise._rank import demoted

    c = Candidate("ekf", "applies", "tuned", {}, "", None, True)
    out = demoted([c], [Score("ekf", "diverged", detail="blew up after t = 0.3")], "the [simulation] run")
    assert out[0].status == "fails" and "blew up after t = 0.3" in out[0].why and "tuned" in out[0].why


def test_symbolic_search_for_the_derivative_map_has_a_budget(monkeypatch):
    from nlobs.design import _constructions as cons

    monkeypatch.setattr(cons, "DERIVATIVE_MAP_SECONDS", 0.2)
    # tyre-like transcendental coupling: solving for vy from r's derivative is a transcendental equation
    veh = nlobs.System(states=["vy", "r"], f=["(7000*sin(1.9*atan(10*(d - atan((vy + 1.2*r)/20)))) "
                                              "+ 7500*sin(1.9*atan(-10*atan((vy - 1.4*r)/20))))/1500 - 20*r",
                                              "(1.2*7000*sin(1.9*atan(10*(d - atan((vy + 1.2*r)/20)))) "
                                              "- 1.4*7500*sin(1.9*atan(-10*atan((vy - 1.4*r)/20))))/2500"],
                       inputs=["d"], outputs=["yr"], h=["r"], name="vehicle")
    psi, why = cons.derivative_map(veh)
    assert psi is None
    assert "within budget" in why or "could not be solved" in why


def vehicle() -> nlobs.System:
    """Single-track vehicle with Pacejka-like tyres (D sin(C atan(B α))), yaw rate measured."""
    ff = "7000*sin(1.9*atan(10*(d - atan((vy + 1.2*r)/20))))"
    fr = "7500*sin(1.9*atan(-10*atan((vy - 1.4*r)/20)))"
    return nlobs.System(states=["vy", "r"], f=[f"({ff}*cos(d) + {fr})/1500 - 20*r", f"(1.2*{ff}*cos(d) - 1.4*{fr})/2500"],
                        inputs=["d"], outputs=["yr"], h=["r"], name="vehicle")


def test_a_kind_whose_symbolic_work_explodes_is_not_checked_within_budget(monkeypatch):
    monkeypatch.setenv("NLOBS_KIND_SECONDS", "0.5")
    sim = _sim([0.0, 0.0], {"d": "0.05*sin(0.8*t)"}, t_final=2.0, noise={"yr": 0.002})
    adv = advise(vehicle(), simulation=sim, kinds=["banks", "ekf"])
    banks = adv.candidate("banks")
    assert banks.status == "fails" and banks.why.startswith("not checked within budget") and "0.5 s" in banks.why
    assert adv.candidate("ekf").applies


def test_the_text_shows_the_model_as_written_once(tmp_path):
    path = tmp_path / "cell.toml"
    path.write_text('''name = "cell"
states = ["soc", "v1"]
inputs = ["I"]
outputs = ["V"]
[parameters]
R0 = 0.015
g = 9.81
[definitions]
ocv = "3.0 + 1.1*soc - 0.9*soc**2 + 0.55*soc**3"
[dynamics]
soc = "-I/8280"
v1 = "-v1/40 + I/2000 + 0*g"
[output]
V = "ocv - v1 - R0*I"
[simulation]
t_final = 100.0
dt = 0.1
x0 = [0.9, 0.0]
inputs = { I = "2.3" }
noise = { V = 0.002 }
sample_period = 1.0
''')
    text = str(advise(str(path), kinds=["luenberger", "kalman_like", "high_gain"]))
    assert "V = ocv - v1 - R0*I" in text and "where ocv = 3.0 + 1.1*soc" in text
    substituted = "-3*I/200 + 11*soc**3/20 - 9*soc**2/10 + 11*soc/10 - v1 + 3"
    assert substituted not in text and text.count("[V above]") >= 2


def test_progress_names_a_kind_that_takes_long(monkeypatch):
    from nlobs.advise import _advise as mod

    monkeypatch.setattr(mod, "SLOW_KIND", 0.0)     # every kind counts as slow: its name must appear on its own line
    said: list[str] = []
    sim = _sim([2.0, 1.0], {"D": "0.3"}, t_final=2.0, dt=0.01, sample_period=0.1, noise={"y": 0.02})
    advise(chemostat(), simulation=sim, kinds=["ekf", "luenberger"], progress=said.append)
    import time as _t
    _t.sleep(0.05)
    assert any("still trying ekf" in m for m in said) or any("still trying luenberger" in m for m in said)


def test_an_output_with_feedthrough_is_not_augmented_and_says_why():
    # a battery: v = ocv(soc) − v1 − R0·i feeds the current through; the span of its derivatives holds i, so no
    # T(x) of the states alone exists (was: "the automatic design failed: ... the symbol `R0` has no value here")
    cell = nlobs.System(states=["soc", "v1"], inputs=["i"], outputs=["v"], params={"Q": 9000.0, "R0": 0.02, "R1": 0.015,
                                                                               "C1": 2000.0},
                        f=["-i/Q", "-v1/(R1*C1) + i/C1"], h=["3.2 + 0.9*soc - 0.4*soc**2 - v1 - R0*i"])
    adv = advise(cell, simulation=_sim([0.9, 0.0], {"i": "2.5 + 2*sin(0.01*t)"}, t_final=100.0, dt=0.5,
                                       sample_period=1.0), kinds=["augmented"])
    c = adv.candidate("augmented")
    assert c.status == "fails" and "needs the input (i) inside T" in c.why and "direct feedthrough" in c.why
    with pytest.raises(PreconditionError, match="T depends on the input i; w = T"):
        nlobs.design_augmented(cell, T=["soc", "v1", "v1 + i"], A=[["0", "0", "0"]] * 3, C=[["0", "0", "1"]],
                               left_inverse=["w1", "w2"], poles=[-1, -2, -3])
