"""nlobs.advise: verdicts per observer kind, the constructions behind them, and the ranking of a run.

The models here are written for these tests (none is a paper's example, except the vanishing-excitation
system of 000_6cd8bea7ca1db43b.txt §6 for the ranking claim). Reference values are computed independently:
eigenvalues with NumPy, PDEs and left inverses with SymPy at random points, Jacobians by finite differences.
"""

from __future__ import annotations

import textwrap
import numpy as np
import pytest
import sympy as sp

import nlobs
from nlobs.advise import advise
from nlobs.advise._advice import Score
from nlobs.advise._rank import rank
from nlobs.design import DESIGNS, register_design
from nlobs.model import SimulationConfig, parse_expression, symbol

SIM = SimulationConfig(t_final=10.0, dt=1e-3, x0=(1.0, 0.5), inputs={"u": symbol("t") * 0 + sp.sin(symbol("t"))},
                       noise={"y": 0.01}, sample_period=0.01, seed=1)


def _sim(x0, inputs=None, **kw):
    ins = {k: parse_expression(v, {"t": symbol("t")}) for k, v in (inputs or {}).items()}
    return SimulationConfig(t_final=kw.pop("t_final", 10.0), dt=kw.pop("dt", 1e-3), x0=tuple(x0), inputs=ins,
                            noise=kw.pop("noise", {}), sample_period=kw.pop("sample_period", 0.01), seed=1)


def msd():
    """Mass-spring-damper, position measured (LTI)."""
    return nlobs.System(states=["p", "v"], f=["v", "-4*p - 0.4*v + u"], inputs=["u"], outputs=["y"], h=["p"], name="msd")


def test_lti_gets_luenberger_with_poles_from_its_time_scale():
    adv = advise(msd(), simulation=_sim([1.0, 0.0], {"u": "sin(t)"}, noise={"y": 0.01}), kinds=["luenberger", "high_gain"])
    c = adv.candidate("luenberger")
    assert c.applies and c.design is not None
    A, C = np.array([[0.0, 1.0], [-4.0, -0.4]]), np.array([[1.0, 0.0]])
    omega_p = np.abs(np.linalg.eigvals(A)).max()                    # |eig| = 2: the undamped frequency
    assert c.options["poles"][0] == pytest.approx(-3 * omega_p, rel=1e-9)
    L = c.design.certificate.values["L"]
    got = np.sort(np.linalg.eigvals(A - L @ C).real)
    assert got == pytest.approx(np.sort(c.options["poles"]), rel=1e-8)
    assert adv.candidate("high_gain").applies                          # constant coupling 1: triangular


def test_an_unobservable_state_blocks_every_full_state_observer_and_is_named_with_its_detectability():
    # x2 is driven by x1 but never reaches y; its own dynamics contract (∂f2/∂x2 = -1 - 3 x2² <= -1)
    s = nlobs.System(states=["x1", "x2"], f=["-x1 + u", "-x2 - x2**3 + sin(x1)"], inputs=["u"], outputs=["y"], h=["x1"])
    adv = advise(s, simulation=_sim([1.0, 0.5], {"u": "sin(t)"}))
    assert not adv.observability.observable and adv.blockers
    assert "x2" in adv.blockers[0] and "never reaches the output" in adv.blockers[0]
    assert "detectable" in adv.blockers[0] and "NOT" not in adv.blockers[0]
    det = adv.extra["detectability"]["detectable"]
    assert det["detectable"] is True and det["rate"] >= 1.0 - 1e-9          # the contraction rate is at least 1
    for c in adv.candidates:
        assert not c.applies and c.design is None
        assert (c.status == "needs input") if c.kind == "custom" else ("x2" in c.why)


def test_an_unobservable_integrator_is_not_detectable():
    s = nlobs.System(states=["x1", "x2"], f=["-x1 - x1**3", "0"], outputs=["y"], h=["x1"])
    adv = advise(s, simulation=_sim([1.0, 2.0]), kinds=["ekf"])
    assert "NOT detectable" in adv.blockers[0] and "no dynamics of its own" in adv.blockers[0]
    lti = nlobs.System.lti([[-1, 0], [1, -3]], None, [[1, 0]])          # LTI: decided by the PBH test
    adv = advise(lti, simulation=_sim([1.0, 2.0]), kinds=["luenberger"])
    assert "detectable" in adv.blockers[0] and "NOT detectable" not in adv.blockers[0]


def test_an_unidentifiable_parameter_is_reported_before_any_estimation():
    s = nlobs.System(states=["x"], f=["-a*b*x + u"], inputs=["u"], outputs=["y"], h=["x"], params={"a": 1.0, "b": 2.0})
    adv = advise(s, unknown_params=["a", "b"], simulation=_sim([1.0], {"u": "sin(t)"}), run=True)
    assert adv.system.estimated_params == ("a", "b")
    assert any("not identifiable" in b and "a, b" in b for b in adv.blockers)
    assert all(c.design is None for c in adv.candidates)
    assert adv.scores == () and adv.run is None                        # nothing was run: no divergent estimation


def test_identifiable_parameter_is_estimated_by_the_filters():
    s = nlobs.System(states=["x"], f=["-k*x + u"], inputs=["u"], outputs=["y"], h=["x"], params={"k": 0.5}, name="tank")
    sim = _sim([1.0], {"u": "1 + sin(t)"}, noise={"y": 0.001}, t_final=20.0)
    adv = advise(s, unknown_params=["k"], true_parameters={"k": 1.0}, simulation=sim, kinds=["ekf", "kalman_like"], run=True)
    assert adv.observability.identifiable_params == ("k",)
    from nlobs.report import parameter_estimates

    rows = {r["observer"]: r for r in parameter_estimates(adv)}
    assert rows["ekf"]["true"] == 1.0 and abs(rows["ekf"]["error"]) < 0.05
    assert rows["ekf"]["pm2sigma"] is not None and abs(rows["ekf"]["error"]) < 3 * rows["ekf"]["pm2sigma"]


def test_chains_out_of_declared_order_are_found():
    # the Rössler equations measured through x2: chain x2 -> x1 -> x3 (x2' = x1 + a x2, x1' = -x2 - x3, x3' = b + x3(x1 - c))
    mf = nlobs.load_model("rossler")
    adv = advise(mf, kinds=["high_gain", "high_gain_kalman"])
    hg = adv.candidate("high_gain")
    assert hg.applies and hg.options["chains"] == [["x2", "x1", "x3"]]
    hk = adv.candidate("high_gain_kalman")
    assert not hk.applies and "x2 -> x1 -> x3" in hk.why


def test_a_vanishing_coupling_refuses_the_high_gain_observer_with_its_range():
    adv = advise("vanishing_excitation", kinds=["high_gain", "high_gain_derivatives"])
    hg = adv.candidate("high_gain")
    assert hg.status == "fails" and "∂x1'/∂x2 = u" in hg.why and "comes close to 0" in hg.why
    assert "divides by u" in adv.candidate("high_gain_derivatives").why


@pytest.mark.slow
def test_on_the_vanishing_excitation_example_2gd_ranks_above_the_kalman_like_observer():
    # 000_6cd8bea7ca1db43b.txt Proposition 1: observability on [0, T] suffices for 2G+D; the Kalman-like observer
    # of 002 rests on uniform complete observability, which u = exp(-t) destroys.
    adv = advise("vanishing_excitation", run=True)
    assert "NOT uniformly completely observable" in " ".join(adv.notes)
    assert not adv.extra["uco"]["uco_uniform"] and adv.extra["uco"]["observable_on_run"]
    ranking = adv.ranking
    assert ranking.index("gpebo_2gd") < ranking.index("kalman_like")
    score = {s.kind: s for s in adv.scores}
    # x2 is a constant (x2' = 0): x̂2(0) is offset from it (by |x2(0)|/2), not started at the true value
    assert adv.run.observers["kalman_like"].xhat[0, 1] != -1.0
    assert score["gpebo_2gd"].normalised_rms < score["kalman_like"].normalised_rms
    run = adv.run
    k10 = int(np.searchsorted(run.t, 10.0))
    e_kl, e_gd = run.error_norm("kalman_like"), run.error_norm("gpebo_2gd")
    assert abs(e_kl[-1] - e_kl[k10]) < 0.1 * e_kl[k10]                    # the Kalman-like observer stalls after t = 10 ...
    assert e_gd[-1] < 0.5 * e_gd[k10]                                     # ... while 2G+D keeps converging
    assert e_gd[-1] < e_kl[-1]                                            # ... below it
    # forgetting without excitation: M blows up; "applies" means it runs, so the kind moves to "does not apply"
    assert "high_gain_kalman" not in score
    hgk = next(c for c in adv.candidates if c.kind == "high_gain_kalman")
    assert hgk.status == "fails" and "blew up on the [simulation] run" in hgk.why
    d = adv.to_dict()
    assert d["ranking"] == list(ranking) and d["scores"][0]["kind"] == ranking[0]


def test_kkl_and_pebo_are_constructed_for_the_output_injection_form_and_solve_their_pdes():
    s = nlobs.System(states=["x1", "x2"], f=["x2", "-3*sin(x1) - 0.5*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"], name="arm")
    adv = advise(s, simulation=_sim([1.0, 0.0], {"u": "sin(t)"}, noise={"y": 0.01}), kinds=["kkl", "pebo"])
    x1, x2, u, y = (symbol(n) for n in ("x1", "x2", "u", "y"))
    f = sp.Matrix([x2, -3 * sp.sin(x1) - sp.Rational(1, 2) * x2 + u])
    names = {n: symbol(n) for n in ("x1", "x2", "u", "y", "xi1", "xi2")}
    rng = np.random.default_rng(3)
    kkl, pebo = adv.candidate("kkl"), adv.candidate("pebo")
    assert kkl.applies and pebo.applies
    for cand, lam in ((kkl, [parse_expression(v, {}) for v in kkl.options["Lambda"]]), (pebo, [0])):
        phi = sp.Matrix([parse_expression(e, names) for e in cand.options["phi"]])
        B = sp.Matrix([parse_expression(e, names) for e in cand.options["B"]])
        left = [parse_expression(e, names) for e in cand.options["left_inverse"]]
        lhs = phi.jacobian(sp.Matrix([x1, x2])) * f
        rhs = sp.diag(*lam) * phi + B.xreplace({y: x1}) if len(lam) == phi.shape[0] else B.xreplace({y: x1})
        for _ in range(5):
            pt = {x1: rng.normal(), x2: rng.normal(), u: rng.normal()}
            assert float((lhs - rhs).xreplace(pt).norm()) < 1e-12          # ∇φ·f = Λφ + B(h(x), u)
            xi = {symbol(f"xi{i + 1}"): v for i, v in enumerate(phi.xreplace(pt))}
            back = [float(e.xreplace({**xi, y: pt[x1]})) for e in left]
            assert back == pytest.approx([float(pt[x1]), float(pt[x2])], abs=1e-12)   # φᴸ(φ(x), h(x)) = x
    assert all(float(parse_expression(v, {})) < 0 for v in kkl.options["Lambda"])


def test_the_derivative_map_recovers_the_state_from_the_lie_derivatives():
    mf = nlobs.load_model("duffing")
    adv = advise(mf, kinds=["high_gain_derivatives"])
    c = adv.candidate("high_gain_derivatives")
    assert c.applies
    x1, x2, u = symbol("x1"), symbol("x2"), symbol("u")
    f = [x2, -0.3 * x2 + x1 - x1 ** 3 + u]            # delta = 0.3, alpha = -1, beta = 1
    lie = [x1, sp.expand(sp.diff(x1, x1) * f[0])]
    names = {"D0_y": symbol("D0_y"), "D1_y": symbol("D1_y"), "u": u}
    rng = np.random.default_rng(0)
    for _ in range(5):
        pt = {x1: rng.normal(), x2: rng.normal(), u: rng.normal()}
        D = {names["D0_y"]: lie[0].xreplace(pt), names["D1_y"]: lie[1].xreplace(pt), u: pt[u]}
        got = [float(parse_expression(c.options["psi"][s], names).xreplace(D)) for s in ("x1", "x2")]
        assert got == pytest.approx([float(pt[x1]), float(pt[x2])], abs=1e-12)


def test_banks_gain_meets_the_matrix_measure_condition_on_the_region():
    s = nlobs.System(states=["x1", "x2"], f=["-x1 + x2", "-x2 - 0.3*sin(x1)"], outputs=["y"], h=["x1"], name="damped")
    adv = advise(s, simulation=_sim([1.0, -1.0]), kinds=["banks"])
    c = adv.candidate("banks")
    assert c.applies
    P = np.array(c.options["L"], dtype=float)
    box = c.options["region"]
    rng = np.random.default_rng(1)

    def fx(x):
        return np.array([-x[0] + x[1], -x[1] - 0.3 * np.sin(x[0])])

    for _ in range(50):
        x = np.array([rng.uniform(*box["x1"]), rng.uniform(*box["x2"])])
        J = np.column_stack([(fx(x + 1e-6 * e) - fx(x - 1e-6 * e)) / 2e-6 for e in np.eye(2)])
        M = J + P @ np.array([[1.0, 0.0]])
        assert np.linalg.eigvalsh((M + M.T) / 2).max() < 0                # 003_a2c72ccb4281ea3f.txt Theorem 2.6


def test_a_kind_without_automatic_tuning_says_what_to_supply():
    def design_mine(system, *, gain, xhat0=None):  # noqa: ANN001, ANN202 - a user's own registered design
        raise AssertionError("never called")

    register_design("mine", design_mine)
    try:
        c = advise(msd(), simulation=_sim([1.0, 0.0], {"u": "sin(t)"}), kinds=["mine"]).candidate("mine")
    finally:
        del DESIGNS["mine"]
    assert c.status == "not tuned" and "gain" in c.why and set(c.options) == {"gain", "xhat0"}


def test_json_contract():
    d = advise(msd(), simulation=_sim([1.0, 0.0], {"u": "sin(t)"}), kinds=["luenberger", "kkl_pebo"]).to_dict()
    assert {"model", "observability", "candidates"} <= set(d) and "ranking" not in d
    for c in d["candidates"]:
        assert {"kind", "applies", "why", "options", "reference"} <= set(c)
        assert isinstance(c["applies"], bool) and isinstance(c["why"], str)
    assert d["candidates"][1]["why"].startswith("needs input")
    import json

    json.dumps(d)                                                          # JSON-ready as it is


def test_rank_orders_by_error_then_convergence_time_within_a_tie():
    s = [Score("slow_best", "ok", 1.0, 9.0, 1.0), Score("fast_tie", "ok", 1.2, 1.0, 1.0),
         Score("worse", "ok", 2.0, 0.1, 1.0), Score("never", "ok", 1.1, None, 1.0), Score("bad", "diverged", detail="x")]
    assert [x.kind for x in rank(s)] == ["fast_tie", "slow_best", "never", "worse", "bad"]


def test_model_report_has_the_table_the_runs_and_the_bibliography(tmp_path):
    from nlobs.report import write_model_report

    adv = advise("vanishing_excitation", kinds=["gpebo_2gd", "kalman_like", "banks", "kkl"], run=True, engine="vm")
    path = write_model_report(adv, tmp_path / "rep")
    text = path.read_text()
    for kind in ("gpebo_2gd", "kalman_like", "banks", "kkl"):
        assert f">{kind}<" in text
    assert text.count("data:image/png") >= 2 and "Wang, Ortega &amp; Bobtsov" in text and "References" in text


def test_mhe_runs_on_its_own_and_joins_the_ranking():
    # MHE's update is an NLP: it runs in its own simulation on the same measurements (same seed), the others
    # keep the compiled joint step; both end up in one ranking and one Run
    sim = _sim([1.0, 0.0], {"u": "sin(t)"}, noise={"y": 0.01}, t_final=2.0, sample_period=0.02)
    adv = advise(msd(), simulation=sim, kinds=["mhe", "ekf"], run=True)
    assert adv.candidate("mhe").runnable and set(adv.ranking) == {"mhe", "ekf"}
    assert set(adv.run.observers) == {"mhe", "ekf"}
    long = _sim([1.0, 0.0], {"u": "sin(t)"}, noise={"y": 0.01}, t_final=10.0, sample_period=0.01)
    c = advise(msd(), simulation=long, kinds=["mhe"]).candidate("mhe")
    assert c.applies and not c.runnable and "left out of --run: 1000 measurement updates" in c.why


def test_constructed_maps_of_a_model_with_a_saturation_are_written_as_the_parser_reads_them():
    # sat(u, 0, 3) reaches SymPy as Min(3, Max(0, u)); the KKL/PEBO maps and Ψ carry it into option text, which the
    # model parser must read back (it knows min/max, not Min/Max)
    s = nlobs.System(states=["Tr", "Tw"], f=["-2*Tr + 2*Tw + sat(u, 0, 3)", "0.4*Tr - 0.5*Tw"], inputs=["u"],
                     outputs=["y"], h=["Tr"], name="room")
    adv = advise(s, simulation=_sim([2.0, 1.0], {"u": "2 + 2*sin(0.2*t)"}, noise={"y": 0.01}),
                 kinds=["kkl", "pebo", "high_gain_derivatives"])
    for kind in ("kkl", "pebo", "high_gain_derivatives"):
        c = adv.candidate(kind)
        assert c.applies, c.why
    B = adv.candidate("kkl").options["B"]
    assert any("min(3, max(0, u))" in b for b in B) and not any("Min" in b for b in B)
    u = symbol("u")
    got = parse_expression(adv.candidate("pebo").options["B"][0], {"u": u, "y": symbol("y")})
    at = [float(got.xreplace({u: v, symbol("y"): 0.0})) for v in (5.0, 3.0, 1.0)]
    assert at[0] == at[1] != at[2]                                                     # saturated above 3


def test_a_parameter_appended_as_a_state_makes_phi_grow_and_gpebo_injects_the_output():
    # S' = -V S/(K + S) + u with V unknown: A(y) = [[0, -y/(K + y)], [0, 0]], so Φ_A = [[1, -∫y/(K + y)], [0, 1]] grows
    # linearly, which Wang, Ortega & Bobtsov (2021) assumption (5) excludes (000_6cd8bea7ca1db43b.txt eq. (5))
    s = nlobs.System(states=["S"], f=["-V*S/(0.5 + S) + u"], inputs=["u"], outputs=["y"], h=["S"], params={"V": 1.5},
                     name="uptake")
    sim = _sim([2.0], {"u": "0.6 + 0.4*sin(0.5*t)"}, noise={"y": 0.01}, t_final=20.0, sample_period=0.05)
    adv = advise(s, unknown_params=["V"], true_parameters={"V": 1.0}, simulation=sim, kinds=["gpebo_2gd"], run=True)
    c = adv.candidate("gpebo_2gd")
    assert c.applies and "L" in c.options and "grows" in c.why
    (score,) = adv.scores
    assert abs(score.parameters["V"]["estimate"] - 1.0) < 0.05


def test_riccati_weight_floor_is_taken_in_the_states_own_scales():
    # Bergman's minimal model (glucose G ~ 100-300 measured; insulin action X ~ 1e-3): C A = [-(p1 + X), -G, 0] is
    # large only towards X, whose prior is small. The step-limit floor of W is max λ(CA M0 CAᵀ)/ω_lim², about
    # (p1 s_G)² + (G s_X)² ≈ 1e2, not λmax(M0)‖CA‖² ≈ 1e9 (which made the filter crawl)
    s = nlobs.System(states=["G", "X", "Ins"], f=["-(p1 + X)*G + p1*Gb", "-p2*X + p3*(Ins - Ib)", "-n*(Ins - Ib) + u"],
                     inputs=["u"], outputs=["y"], h=["G"],
                     params={"p1": 0.03, "p2": 0.02, "p3": 1e-5, "n": 0.1, "Gb": 90.0, "Ib": 10.0}, name="glucose")
    sim = _sim([200.0, 0.0, 10.0], {"u": "5 + 5*sin(0.05*t)"}, noise={"y": 1.0}, t_final=300.0, dt=0.01, sample_period=1.0)
    adv = advise(s, simulation=sim, kinds=["kalman_bucy"], run=True)
    c = adv.candidate("kalman_bucy")
    W = np.array(c.options["R"])[0, 0]
    assert 1.0 <= W < 1e4                                     # σ²T_s = 1, raised only as far as the step limit needs
    e = adv.run.error_norm("kalman_bucy")
    assert e[-1] < 0.01 * e[0]


def test_rank_of_candidates_equal_as_shown_is_by_name_whatever_the_order_they_finished():
    # filters that compute the same estimate in another order (ekf, iekf, ukf on a linear output) differ in the last
    # bits; the ranking shows 6 figures, so its order among them must not follow rounding or completion order
    a = [Score("ukf", "ok", 1.0 + 3e-15, 0.47, 1.0), Score("ekf", "ok", 1.0, 0.47, 1.0),
         Score("iekf", "ok", 1.0 + 1e-15, 0.47 + 1e-16, 1.0)]
    for order in (a, a[::-1], [a[1], a[0], a[2]]):
        assert [x.kind for x in rank(order)] == ["ekf", "iekf", "ukf"]


def test_rates_are_written_in_the_models_time_unit():
    # a model in hours: its rates are per hour (a note that says s⁻¹ misreads ω_p by a factor 3600)
    from nlobs import loads_model

    text = '''
    name = "decay"
    states = ["x"]
    outputs = ["y"]
    [dynamics]
    x = "-2*x"
    [output]
    y = "x"
    [units]
    t = "{unit}"
    [simulation]
    t_final = 5.0
    dt = 0.01
    x0 = [1.0]
    '''
    for unit, per in (("h", "h⁻¹"), ("s", "s⁻¹"), ("min", "min⁻¹")):
        adv = advise(loads_model(textwrap.dedent(text.format(unit=unit))), kinds=["ekf"])
        note = next(n for n in adv.notes if n.startswith("time scale"))
        assert f"ω_p = 2 {per}" in note and f"ω_o = 6 {per}" in note, note


def test_the_ranking_scenario_says_each_output_is_sampled_at_its_own_period():
    """Issue 44, item 2 (acceptance): a run with a 0.2 s GNSS beside a 0.02 s magnetometer was described as
    "measurements every 0.02" (the fastest clock), as if every sensor ran at 50 Hz; the run itself samples each at its
    own period, and the description says so."""
    from nlobs.advise._context import Scenario

    sc = Scenario(10.0, 0.01, np.zeros(2), {}, None, None, None, 0.02, 1, periods={"gps": 0.2, "mag": 0.02})
    text = sc.describe()
    assert "gps every 0.2" in text and "mag every 0.02" in text and "measurements every 0.02," not in text
    one = Scenario(10.0, 0.01, np.zeros(2), {}, None, None, None, 0.05, 1)
    assert "measurements every 0.05" in one.describe()
