"""Sensor selection (issue 37): minimal sets by the exact generic rank, Cramér–Rao bounds from the Fisher information of
the [simulation] run, ranking under a budget. Every reference value is computed here independently: matrix exponentials
(LTI), an exhaustive SymPy rank check of Lie derivatives, finite differences of SciPy's solve_ivp, and the known sink
components of a network built for the test."""

from __future__ import annotations

import itertools
import math
import random

import numpy as np
import pytest
import scipy.linalg as sl
import sympy as sp
from scipy.integrate import solve_ivp
from sympy import QQ
from sympy.polys.matrices import DomainMatrix

from nlobs.analysis import select_sensors
from nlobs.analysis.sensors._quality import greedy_path
from nlobs.errors import ModelError
from nlobs.model import loads_model

# -- an LTI model: x' = A x + B u, candidates C_i x ------------------------------------------------------------------
A_LTI = np.array([[0.0, 1.0, 0.0, 0.0], [-2.0, -0.3, 1.0, 0.0], [0.0, 0.0, -0.5, 0.4], [0.0, 0.0, -0.4, -0.1]])
C_LTI = {"p": [1.0, 0.0, 0.0, 0.0], "v": [0.0, 1.0, 0.0, 0.0], "q": [0.0, 0.0, 1.0, 0.0], "pq": [1.0, 0.0, 0.0, 2.0]}
NOISE_LTI = {"p": 0.05, "v": 0.2, "q": 0.1, "pq": 0.02}
COST_LTI = {"p": 1, "v": 2, "q": 1, "pq": 3}


def _lti_text() -> str:
    names = ["x1", "x2", "x3", "x4"]
    dyn = []
    for i, row in enumerate(A_LTI):
        terms = [f"({float(a)!r})*{names[j]}" for j, a in enumerate(row) if a]
        dyn.append(f'{names[i]} = "{" + ".join(terms)}{" + u" if i == 1 else ""}"')
    sensors = []
    for k, c in C_LTI.items():
        expr = " + ".join(f"({float(a)!r})*{names[j]}" for j, a in enumerate(c) if a)
        sensors += [f"[sensors.{k}]", f'expr = "{expr}"', f"noise = {NOISE_LTI[k]}", f"cost = {COST_LTI[k]}"]
    return "\n".join(['name = "lti4"', f"states = {names!r}".replace("'", '"'), 'inputs = ["u"]', 'outputs = ["y"]',
                      "[dynamics]", *dyn, "[output]", 'y = "x1"', "[simulation]", "t_final = 3.0", "dt = 0.01",
                      "sample_period = 0.1", "x0 = [1.0, 0.0, 0.5, -0.5]", 'inputs = { u = "sin(2*t)" }', *sensors]) + "\n"


def _lti_information(members: list[str]) -> np.ndarray:
    """Σ_k (C e^{A t_k})ᵀ R⁻¹ (C e^{A t_k}) over t_k = 0, 0.1, ..., 3 (matrix exponentials: independent of the code)."""
    C = np.array([C_LTI[m] for m in members])
    Rinv = np.diag([1 / NOISE_LTI[m] ** 2 for m in members])
    out = np.zeros((4, 4))
    for t in np.arange(31) * 0.1:
        O = C @ sl.expm(A_LTI * t)
        out += O.T @ Rinv @ O
    return out


def _lti_scales() -> np.ndarray:
    """The largest |x_i| at the samples t = 0, 0.1, ..., 3 of x' = A x + e2 sin(2t) from the file's x0 (SciPy)."""
    sol = solve_ivp(lambda t, x: A_LTI @ x + np.array([0.0, np.sin(2 * t), 0.0, 0.0]), (0.0, 3.0), [1.0, 0.0, 0.5, -0.5],
                    t_eval=np.arange(31) * 0.1, rtol=1e-11, atol=1e-13)
    return np.max(np.abs(sol.y), axis=1)


def test_the_unobservability_index_is_finite_in_mixed_units_where_every_bound_is():
    """Unknowns in units decades apart (a quaternion, a position in mm, a bias): F = D⁻¹ M D⁻¹ with M well
    conditioned and D = diag(1e-6, 1, 1e6) spans 24 decades. Its plain eigenvalues read singular (the index was ∞)
    though every bound is finite. The index is √λmax of the Cramér–Rao covariance D M⁻¹ D (computed here), and with
    the unknowns' scales D it is that of M: 1/√λmin(M)."""
    from nlobs.analysis.sensors._quality import quality

    M = np.array([[2.0, 0.5, 0.1], [0.5, 1.0, 0.3], [0.1, 0.3, 0.7]])
    D = np.diag([1e-6, 1.0, 1e6])
    Di = np.diag(1 / np.diag(D))
    F = Di @ M @ Di
    q = quality(F, [0, 1, 2])
    cov = D @ np.linalg.inv(M) @ D
    assert np.all(np.isfinite(q.crb)) and q.crb == pytest.approx(np.sqrt(np.diag(cov)), rel=1e-9)
    assert q.unobservability_index == pytest.approx(math.sqrt(np.linalg.eigvalsh(cov)[-1]), rel=1e-9)
    qs = quality(F, [0, 1, 2], np.diag(D))
    lam = np.linalg.eigvalsh(M)
    assert qs.unobservability_index == pytest.approx(1 / math.sqrt(lam[0]), rel=1e-9)
    assert qs.condition == pytest.approx(math.sqrt(lam[-1] / lam[0]), rel=1e-9)
    # an uninformed direction stays infinite
    Fz = F.copy()
    Fz[2, :] = Fz[:, 2] = 0.0
    assert quality(Fz, [0, 1, 2], np.diag(D)).unobservability_index == math.inf


@pytest.fixture(scope="module")
def lti():
    return select_sensors(loads_model(_lti_text(), path="lti4.toml"), budget=3)


def test_lti_bounds_equal_the_matrix_exponential_gramian(lti):
    checked = 0
    for s in lti.sets:
        W = _lti_information(list(s.sensors))
        lam = np.linalg.eigvalsh(W)
        if lam[0] <= 1e-9 * lam[-1]:
            assert not all(math.isfinite(v) for v in s.crb.values()), s.sensors
            continue
        want = np.sqrt(np.diag(np.linalg.inv(W)))
        got = np.array([s.crb[x] for x in ("x1", "x2", "x3", "x4")])
        assert np.max(np.abs(got / want - 1)) < 1e-6, s.sensors
        assert abs(s.log_det - np.linalg.slogdet(W)[1]) < 1e-6 * abs(s.log_det)
        # the unobservability index of Krener & Ide (2009): 1/√λmin of the (noise-weighted) Gramian, in units of each
        # state's scale (no initial_std: its largest magnitude at the run's samples)
        Sc = np.diag(_lti_scales())
        assert s.unobservability_index == pytest.approx(1 / math.sqrt(np.linalg.eigvalsh(Sc @ W @ Sc)[0]), rel=1e-6)
        checked += 1
    assert checked >= 3


def test_lti_best_set_and_pareto_front_are_the_brute_force_ones(lti):
    names = list(C_LTI)
    scored = []
    for r in range(1, len(names) + 1):
        for S in itertools.combinations(names, r):
            sign, ld = np.linalg.slogdet(_lti_information(list(S)))
            scored.append((sum(COST_LTI[m] for m in S), ld if sign > 0 and np.linalg.cond(_lti_information(list(S))) < 1e12
                           else -np.inf, S))
    within = [x for x in scored if x[0] <= 3 and np.isfinite(x[1])]
    best = max(within, key=lambda x: x[1])
    assert set(lti.best.sensors) == set(best[2])
    front, top = [], -np.inf
    for cost, ld, S in sorted(scored, key=lambda x: (x[0], -x[1])):
        if np.isfinite(ld) and ld > top + 1e-9:
            front.append(set(S))
            top = ld
    assert [set(p) for p in lti.pareto] == front


def test_lti_minimal_sets_from_the_kalman_rank(lti):
    names = list(C_LTI)
    ok = {}
    for r in range(1, len(names) + 1):
        for S in itertools.combinations(names, r):
            C = np.array([C_LTI[m] for m in S])
            O = np.vstack([C @ np.linalg.matrix_power(A_LTI, k) for k in range(4)])
            ok[S] = np.linalg.matrix_rank(O) == 4
    minimal = {S for S, v in ok.items() if v and not any(ok[T] for T in ok if set(T) < set(S))}
    assert set(lti.minimal_sets) == minimal


# -- a nonlinear model of six states and an unknown rate ---------------------------------------------------------------
NL6 = """
name = "cascade6"
states = ["A", "B", "C", "D", "E", "F"]
outputs = ["y"]
[parameters]
k = { value = 0.7, unknown = true }
[dynamics]
A = "1 - A - A*B"
B = "A - 2*B"
C = "B - k*C"
D = "C*E - D"
E = "D - E**2"
F = "C - F"
[output]
y = "F"
[simulation]
t_final = 8.0
dt = 0.01
x0 = [0.2, 0.1, 0.5, 0.3, 0.8, 0.0]
sample_period = 0.1
[sensors.sA]
expr = "A"
noise = 0.01
[sensors.sC]
expr = "C"
noise = 0.02
[sensors.sD]
expr = "D"
noise = 0.01
cost = 2
[sensors.sE]
expr = "E"
noise = 0.05
[sensors.sF]
expr = "F"
noise = 0.01
[sensors.sDF]
expr = "D + F"
noise = 0.02
cost = 3
[sensors.sCE]
expr = "C*E"
noise = 0.01
"""
_A, _B, _C, _D, _E, _F, _k = sp.symbols("A B C D E F k")
NL6_UNKNOWNS = [_A, _B, _C, _D, _E, _F, _k]
NL6_F = [1 - _A - _A * _B, _A - 2 * _B, _B - _k * _C, _C * _E - _D, _D - _E ** 2, _C - _F, sp.Integer(0)]
NL6_CANDIDATES = {"sA": _A, "sC": _C, "sD": _D, "sE": _E, "sF": _F, "sDF": _D + _F, "sCE": _C * _E}
NL6_NOISE = {"sA": 0.01, "sC": 0.02, "sD": 0.01, "sE": 0.05, "sF": 0.01, "sDF": 0.02, "sCE": 0.01}


@pytest.fixture(scope="module")
def nl6():
    return select_sensors(loads_model(NL6, path="cascade6.toml"))


@pytest.fixture(scope="module")
def sympy_rows():
    """Each candidate's Lie-derivative Jacobian (orders 0..6, the parameter as a constant state) at two random rational
    points: an exhaustive SymPy check written for this test."""
    rng = random.Random(1)
    points = [{s: sp.Rational(rng.randint(1, 97), rng.randint(1, 97)) for s in NL6_UNKNOWNS} for _ in range(2)]
    rows = {}
    f = [sp.Poly(fi, *NL6_UNKNOWNS, domain=QQ) for fi in NL6_F]
    for name, h in NL6_CANDIDATES.items():
        L = [sp.Poly(h, *NL6_UNKNOWNS, domain=QQ)]
        for _ in range(len(NL6_UNKNOWNS) - 1):   # L_f^{j+1} h = Σ_s ∂(L_f^j h)/∂s · f_s
            L.append(sum((L[-1].diff(s) * fi for s, fi in zip(NL6_UNKNOWNS, f)), sp.Poly(0, *NL6_UNKNOWNS, domain=QQ)))
        J = [[Lj.diff(s) for s in NL6_UNKNOWNS] for Lj in L]
        rows[name] = [sp.Matrix([[d.eval(tuple(p[s] for s in NL6_UNKNOWNS)) for d in row] for row in J]) for p in points]
    return rows


def _sympy_minimal(rows, targets=None):
    """The inclusion-minimal sets whose stacked rows have full rank (or contain each target's unit vector) at either
    point: exact ranks over the rationals (SymPy's DomainMatrix over QQ)."""
    names = list(NL6_CANDIDATES)
    m = len(NL6_UNKNOWNS)
    cols = [] if targets is None else [NL6_UNKNOWNS.index(sp.Symbol(t)) for t in targets]
    units = [DomainMatrix.from_Matrix(sp.Matrix([[1 if j == c else 0 for j in range(m)]])).convert_to(QQ) for c in cols]
    dm = {n: [DomainMatrix.from_Matrix(r).convert_to(QQ) for r in rows[n]] for n in names}

    def observes(S):
        for i in range(2):
            J = DomainMatrix.vstack(*[dm[n][i] for n in S])
            r = J.rank()
            if r == m or (cols and all(DomainMatrix.vstack(J, e).rank() == r for e in units)):
                return True
        return False

    ok = {S: observes(S) for r in range(1, len(names) + 1) for S in itertools.combinations(names, r)}
    return {S for S, v in ok.items() if v and not any(ok[T] for T in ok if set(T) < set(S))}


def test_nonlinear_minimal_sets_equal_an_exhaustive_sympy_rank_check(nl6, sympy_rows):
    want = _sympy_minimal(sympy_rows)
    assert set(nl6.minimal_sets) == want
    assert any(len(s) == 2 for s in want) and any(len(s) == 1 for s in want)   # the test model is not trivial
    assert nl6.search.complete and nl6.search.error_probability < 1e-9


def test_nonlinear_minimal_sets_for_targets_equal_the_sympy_check(sympy_rows):
    sel = select_sensors(loads_model(NL6, path="cascade6.toml"), targets="F,k", quality_part=False)
    assert set(sel.minimal_sets) == _sympy_minimal(sympy_rows, ["F", "k"])
    assert sel.targets == ("F", "k") and sel.run is None


def _nl6_rhs(t, z):
    A, B, C, D, E, F, k = z
    return [1 - A - A * B, A - 2 * B, B - k * C, C * E - D, D - E ** 2, C - F, 0.0]


def test_nonlinear_bounds_equal_finite_difference_sensitivities(nl6):
    tk = np.arange(81) * 0.1
    z0 = np.array([0.2, 0.1, 0.5, 0.3, 0.8, 0.0, 0.7])

    def readings(z):
        A, B, C, D, E, F, k = solve_ivp(_nl6_rhs, (0, 8), z, t_eval=tk, rtol=1e-12, atol=1e-14, method="DOP853").y
        return {"sA": A, "sC": C, "sD": D, "sE": E, "sF": F, "sDF": D + F, "sCE": C * E}

    S = {c: np.zeros((tk.size, 7)) for c in NL6_NOISE}
    h = 1e-5
    for j in range(7):
        dz = np.zeros(7)
        dz[j] = h
        up, down = readings(z0 + dz), readings(z0 - dz)
        for c in S:
            S[c][:, j] = (up[c] - down[c]) / (2 * h)
    assert len(nl6.sets) >= 5
    for s in nl6.sets:
        F = sum(S[c].T @ S[c] / NL6_NOISE[c] ** 2 for c in s.sensors)
        want = np.sqrt(np.diag(np.linalg.inv(F)))
        got = np.array([s.crb[u] for u in nl6.unknowns])
        assert np.max(np.abs(got / want - 1)) < 1e-4, s.sensors


# -- a 20-state network with three sink components ------------------------------------------------------------------
GROUPS = {"A": range(0, 5), "B": range(5, 10), "C": range(10, 14), "D": range(14, 17), "E": range(17, 20)}


def network_text() -> str:
    """Components A (source) -> B -> sinks C and D; A -> sink E; a cycle with a saturating coupling inside each."""
    f = {}
    for idx in GROUPS.values():
        idx = list(idx)
        for j, i in enumerate(idx):
            prev = idx[j - 1]
            f[i] = f"-{0.5 + 0.1 * i:.2f}*x{i} + 0.8*x{prev}**2/(1 + x{prev}**2)"
    f[5] += " + 0.5*x4"
    f[10] += " + 0.4*x9"
    f[14] += " + 0.3*x7"
    f[17] += " + 0.6*x2"
    f[0] += " + 1 + 0.5*sin(t)"
    lines = ['name = "net20"', "states = [" + ", ".join(f'"x{i}"' for i in range(20)) + "]", 'outputs = ["y"]', "[dynamics]"]
    lines += [f'x{i} = "{f[i]}"' for i in range(20)]
    lines += ["[output]", 'y = "x0"', "[simulation]", "t_final = 10.0", "dt = 0.01", "sample_period = 0.1",
              "x0 = [" + ", ".join(f"{0.2 + 0.05 * i:.2f}" for i in range(20)) + "]"]
    for i in range(20):
        lines += [f"[sensors.m{i}]", f'expr = "x{i}"', f"noise = {0.01 * (1 + i % 3):g}", f"cost = {1 + i % 2}"]
    return "\n".join(lines) + "\n"


def test_network_sets_are_one_sensor_in_each_sink_component():
    sel = select_sensors(loads_model(network_text(), path="net20.toml"))
    want = {tuple(f"m{i}" for i in c) for c in itertools.product(GROUPS["C"], GROUPS["D"], GROUPS["E"])}
    assert {tuple(sorted(s, key=lambda n: int(n[1:]))) for s in sel.minimal_sets} == want
    assert {frozenset(c) for c in sel.graph.sinks} == {frozenset(f"x{i}" for i in GROUPS[g]) for g in "CDE"}
    assert sel.search.proven_minimum and not sel.search.complete
    assert sel.search.checked == len(want)          # every other set of up to 3 was ruled out by the graph
    assert all(math.isfinite(v) for s in sel.sets if "minimal" in s.roles for v in s.crb.values())


def test_the_graph_pruning_is_sound_on_the_nonlinear_model(nl6):
    """Without the influence graph (every candidate made to see everything) the rank alone gives the same sets."""
    from nlobs.analysis.structural._sensors import InfluenceGraph, candidate_jets, minimal_sets

    mf = loads_model(NL6, path="cascade6.toml")
    jets = candidate_jets(mf.system, [c.expr for c in mf.sensors.values()], names=list(mf.sensors), unknown_params=["k"])
    blind = InfluenceGraph(jets.unknowns, (), (), tuple([(1 << 7) - 1] * 7))
    plain = minimal_sets(jets, blind, jets.unknowns)
    assert {tuple(jets.names[i] for i in m) for m in plain.minimal} == set(nl6.minimal_sets)
    assert plain.pruned == 0 and plain.checked > nl6.search.checked


# -- the greedy ranking ---------------------------------------------------------------------------------------------
def test_greedy_meets_its_guarantee_against_brute_force():
    rng = np.random.default_rng(4)
    m, nc = 5, 9
    info = np.array([(lambda G: G.T @ G)(rng.normal(size=(2, m)) * rng.uniform(0.2, 3)) for _ in range(nc)])
    info[0] *= 1e-3                                       # a poor first candidate
    prior = np.eye(m) * 0.1
    base = np.linalg.slogdet(prior)[1]
    path = greedy_path(info, np.ones(nc), prior, math.inf, per_cost=False)
    chosen: list[int] = []                                # the greedy sequence, recomputed here
    for _ in range(nc):
        gains = {c: np.linalg.slogdet(prior + info[chosen + [c]].sum(0))[1] for c in range(nc) if c not in chosen}
        chosen.append(max(gains, key=gains.get))
        assert sorted(path[len(chosen) - 1]) == sorted(chosen)
    for k, S in enumerate(path, 1):
        best = max(np.linalg.slogdet(prior + info[list(T)].sum(0))[1] for T in itertools.combinations(range(nc), k))
        got = np.linalg.slogdet(prior + info[S].sum(0))[1]
        assert got - base >= (1 - 1 / math.e) * (best - base) - 1e-12


def test_greedy_ranking_above_the_quality_limit_says_so(lti):
    sel = select_sensors(loads_model(_lti_text(), path="lti4.toml"), budget=3, quality_limit=2)
    assert "greedy" in sel.ranking and "1 − 1/e" in sel.ranking
    assert sel.best is not None and sel.best.cost <= 3 and math.isfinite(sel.best.log_det)
    assert all(math.isfinite(sel.set_of(p).log_det) for p in sel.pareto)


# -- the pool and bad input -----------------------------------------------------------------------------------------
PLAIN = """
name = "plain"
states = ["x", "v"]
outputs = ["pos", "energy"]
[dynamics]
x = "v"
v = "-x"
[output]
pos = "x"
energy = "x**2 + v**2"
[simulation]
t_final = 5.0
x0 = [2.0, 0.0]
noise = { pos = 0.03 }
sample_period = 0.5
"""


def test_default_pool_is_every_state_and_output():
    sel = select_sensors(loads_model(PLAIN, path="plain.toml"))
    pool = {c.name: c for c in sel.pool}
    assert list(pool) == ["v", "pos", "energy"]      # pos = x replaces the candidate x
    assert pool["pos"].noise == 0.03 and "[simulation] noise" in pool["pos"].noise_source
    v = 2 * np.sin(np.arange(11) * 0.5)                                   # v = -2 sin t at the samples
    assert pool["v"].noise == pytest.approx(0.01 * np.max(np.abs(v)), rel=1e-6)   # 1 % of max |v| at the samples
    assert pool["energy"].noise == pytest.approx(0.01 * 4.0, rel=1e-9)   # energy = 4 throughout
    assert set(sel.minimal_sets) == {("v",), ("pos",)}      # the energy alone does not give the phase


def test_process_noise_is_said_to_be_left_out():
    sel = select_sensors(loads_model(PLAIN.replace("sample_period", "process_noise = { v = 0.1 }\nsample_period"),
                                     path="plain.toml"))
    assert any("process_noise is not in them" in n for n in sel.notes)
    assert not any("process_noise" in n for n in select_sensors(loads_model(PLAIN, path="plain.toml")).notes)


def test_without_x0_only_the_structural_part_with_a_note():
    sel = select_sensors(loads_model(PLAIN.replace("x0 = [2.0, 0.0]\n", ""), path="plain.toml"))
    assert sel.run is None and sel.best is None and all(s.crb is None for s in sel.sets)
    assert any("no bounds" in n for n in sel.notes)


@pytest.mark.parametrize("candidates, message", [
    ({}, "the pool is empty"),
    ({"a": {"expr": "x + w", "noise": 1}}, "unknown name `w`"),
    ({"a": {"expr": "x", "noise": 0}}, "noise must be positive"),
    ({"a": {"expr": "x", "noise": 1, "gain": 2}}, "unknown key 'gain'"),
    ({"1a": "x"}, "not a sensor name"),
])
def test_bad_candidates_get_one_line_errors(candidates, message):
    with pytest.raises(ModelError, match=message) as e:
        select_sensors(loads_model(PLAIN, path="plain.toml"), candidates, quality_part=False)
    assert "\n" not in str(e.value)


def test_a_system_with_its_run_and_a_discrete_model():
    from nlobs import System

    s = System(states=["x", "v"], f=["v", "-x + u"], inputs=["u"], outputs=["y"], h=["x"])
    sel = select_sensors(s, {"pos": {"expr": "x", "noise": 0.1}, "vel": {"expr": "v", "noise": 0.1}},
                         simulation={"x0": [1, 0], "t_final": 5, "dt": 0.01, "sample_period": 0.1, "inputs": {"u": "sin(t)"}})
    assert sel.minimal_sets == (("pos",), ("vel",)) and sel.run["samples"] == 51 and sel.best.sensors == ("pos", "vel")
    d = System(states=["x"], f=["0.5*x"], outputs=["y"], h=["x"], time="discrete", sample_time=1.0)
    with pytest.raises(ModelError, match="discrete-time model"):
        select_sensors(d)


def test_bad_target_is_named():
    with pytest.raises(ModelError, match="'z' is not a state or an unknown parameter"):
        select_sensors(loads_model(PLAIN, path="plain.toml"), targets="x,z", quality_part=False)


def test_to_dict_has_the_issue_contract(nl6):
    out = nl6.to_dict()
    assert out["minimal_sets"] == [list(s) for s in nl6.minimal_sets]
    first = out["sets"][0]
    assert {"sensors", "observable", "crb", "cost"} <= set(first) and set(first["crb"]) == set(nl6.unknowns)
    assert all(list(s) in [e["sensors"] for e in out["sets"]] for s in nl6.minimal_sets)


# -- nlobs sensors --run: a smoothed filter beside the bound ------------------------------------------------------
def test_a_smoothed_kalman_filter_reaches_the_posterior_bound_on_the_lti_model(lti):
    """Linear and Gaussian: the RTS-smoothed x̂(0) of the EKF (here the Kalman filter) has the posterior covariance
    (P0⁻¹ + F)⁻¹ exactly, so over 300 noise draws its RMS error is that bound within sampling error (±4 % one σ)."""
    from nlobs.estimation._sensors import PRIOR_FACTOR, sensor_errors

    mf = loads_model(_lti_text(), path="lti4.toml")
    best = lti.best.sensors
    out = sensor_errors(mf, lti, sets=[best], seeds=300)
    crb = np.array([lti.best.crb[x] for x in ("x1", "x2", "x3", "x4")])
    W = _lti_information(list(best))
    want = np.sqrt(np.diag(np.linalg.inv(np.diag(1 / (PRIOR_FACTOR * crb) ** 2) + W)))
    post = np.array([out.posterior[best][x] for x in ("x1", "x2", "x3", "x4")])
    rms = np.array([out.rms[best][x] for x in ("x1", "x2", "x3", "x4")])
    assert np.max(np.abs(post / want - 1)) < 1e-6
    assert np.all(np.abs(rms / want - 1) < 0.12), rms / want      # 3 σ of the RMS of 300 draws
    assert "RMS error of x̂(0)" in str(out) and out.to_dict()["sets"][0]["sensors"] == list(best)



def test_the_run_of_each_set_does_not_keep_its_smoother_alive(lti):
    """Issue 44, item 2 (acceptance, memory): each listed set's filter is designed for that set and used for its draws
    only; its smoother's compiled replay (about 100 MB for a 17-state navigation model) must not stay in the smoother's
    cache after the set is done (eight sets of a drone's pool took `sensors --run` to 1.3 GB)."""
    from nlobs.estimation import _smooth
    from nlobs.estimation._sensors import sensor_errors
    from nlobs.observer import _compiled

    mf = loads_model(_lti_text(), path="lti4.toml")
    before, prepared = set(_smooth._CACHE), set(_compiled._CACHE)
    sets = [s.sensors for s in lti.sets][:3]
    out = sensor_errors(mf, lti, sets=sets, seeds=2)
    assert all(s in out.rms for s in sets)
    assert set(_smooth._CACHE) <= before and set(_compiled._CACHE) <= prepared


LEVEL = """
name = "level"
states = ["px", "vx", "th", "vz", "b"]
inputs = ["ax"]
outputs = ["gx"]
[dynamics]
px = "vx"
vx = "ax - b"
th = "0.3"
vz = "vx*(sin(th)**2 + cos(th)**2 - 1)"
b = "0"
[output]
gx = "px"
[simulation]
t_final = 20.0
dt = 0.01
x0 = [0.0, 1.0, 0.0, 0.0, 0.05]
inputs = { ax = "sin(t)" }
sample_period = 0.1
"""


def test_a_default_candidate_that_reads_only_rounding_gets_a_noise_in_its_own_units():
    """Issue 44, item 2: the vertical speed of a level run is sin² + cos² − 1 times the speed, rounding only (about
    1e-16 on the run). Its default noise was 1 % of that (about 1e-18): the most precise sensor of the pool by twelve
    orders of magnitude, whose information swamps every other's. It now gets 0.01 in its own units, said so, and
    the whole pool is at least as informative as each of its subsets (F_pool >= F_S, so log det too)."""
    sel = select_sensors(loads_model(LEVEL))
    run_max = float(np.max(np.abs(sel.fisher.outputs[:, [c.name for c in sel.pool].index("vz")])))
    assert run_max < 1e-12   # rounding, not a speed
    vz = next(c for c in sel.pool if c.name == "vz")
    assert vz.noise == 0.01 and "reads 0 on the run" in vz.noise_source
    pool = next(s for s in sel.sets if "pool" in s.roles)
    assert all(math.isfinite(v) for v in pool.crb.values())
    assert all(pool.log_det >= s.log_det - 1e-9 for s in sel.sets if s.log_det is not None and math.isfinite(s.log_det))


RATES = """
name = "cart2"
states = ["p", "v", "b"]
inputs = ["a"]
outputs = ["gps", "wheel"]
[dynamics]
p = "v"
v = "a - 0.1*v"
b = "0"
[output]
gps = "p"
wheel = "v + b"
[simulation]
t_final = 10.0
dt = 0.01
x0 = [0.0, 1.0, 0.3]
inputs = { a = "sin(t)" }
noise = { gps = 1.0, wheel = 0.1 }
sample_period = { gps = 1.0, wheel = 0.1 }
"""


def test_each_candidate_is_sampled_at_its_own_rate():
    """Issue 44, item 2: with a GPS at 1 s beside a wheel encoder at 0.1 s, the GPS candidate's information is that of
    its 11 samples (the same as on a run sampled every 1 s), not of 101 samples at the fastest clock; a [sensors] table
    sets its own `period`."""
    mixed = select_sensors(loads_model(RATES))
    alone = select_sensors(loads_model(RATES.replace("sample_period = { gps = 1.0, wheel = 0.1 }", "sample_period = 1.0")))
    fast = select_sensors(loads_model(RATES.replace("sample_period = { gps = 1.0, wheel = 0.1 }", "sample_period = 0.1")))
    i = [c.name for c in mixed.pool].index("gps")
    j = [c.name for c in mixed.pool].index("wheel")
    F_gps, F_alone = mixed.fisher.information[i], alone.fisher.information[[c.name for c in alone.pool].index("gps")]
    assert np.allclose(F_gps, F_alone, rtol=1e-9, atol=1e-12 * np.abs(F_alone).max())
    assert np.allclose(mixed.fisher.information[j], fast.fisher.information[[c.name for c in fast.pool].index("wheel")],
                       rtol=1e-9, atol=0)
    assert mixed.run["periods"]["gps"] == pytest.approx(1.0) and mixed.run["periods"]["wheel"] == pytest.approx(0.1)
    table = RATES + '[sensors.gnss]\nexpr = "p"\nnoise = 1.0\nperiod = 1.0\n[sensors.odo]\nexpr = "v + b"\nnoise = 0.1\n'
    sel = select_sensors(loads_model(table))
    assert np.allclose(sel.fisher.information[0], F_alone, rtol=1e-9, atol=1e-12 * np.abs(F_alone).max())
    assert any("odo" in n and "fastest" in n for n in sel.notes)


def test_periods_that_are_not_multiples_of_the_fastest():
    """Issue 44, item 2: a 20 Hz and a 50 Hz sensor (0.05 s and 0.02 s, both whole multiples of dt, as `simulate`
    takes them) are each sampled at their own rate on the grid of their common divisor (0.01 s), not refused for 0.05
    not being a multiple of 0.02: each candidate's information equals that of a run sampled at its period alone."""
    both = RATES.replace("sample_period = { gps = 1.0, wheel = 0.1 }", "sample_period = { gps = 0.05, wheel = 0.02 }")
    mixed = select_sensors(loads_model(both))
    names = [c.name for c in mixed.pool]
    for name, period in (("gps", "0.05"), ("wheel", "0.02")):
        alone = select_sensors(loads_model(RATES.replace("sample_period = { gps = 1.0, wheel = 0.1 }",
                                                         f"sample_period = {period}")))
        F_alone = alone.fisher.information[[c.name for c in alone.pool].index(name)]
        assert np.allclose(mixed.fisher.information[names.index(name)], F_alone, rtol=1e-9,
                           atol=1e-12 * np.abs(F_alone).max())
        assert mixed.run["periods"][name] == pytest.approx(float(period))
    table = both + '[sensors.gnss]\nexpr = "p"\nnoise = 1.0\nperiod = 0.05\n[sensors.odo]\nexpr = "v + b"\nnoise = 0.1\nperiod = 0.02\n'
    sel = select_sensors(loads_model(table))
    assert sel.run["periods"] == {"gnss": pytest.approx(0.05), "odo": pytest.approx(0.02)}


def test_the_run_takes_sensors_named_as_no_model_name_could_be():
    """Issue 44, item 1 (acceptance): a [sensors] table's name is any TOML key — `lambda` (a Python keyword),
    `sin` (a function), `for`. The bounds were computed, but --run said "not run (output name 'lambda' is not
    valid ...)": the filter's outputs need names of their own, and the text keeps the user's."""
    from nlobs.estimation._sensors import sensor_errors

    table = (RATES + '[sensors.lambda]\nexpr = "p"\nnoise = 1.0\n[sensors.wheel_speed]\nexpr = "v + b"\nnoise = 0.1\n'
             '[sensors.sin]\nexpr = "v"\nnoise = 0.1\n')
    mf = loads_model(table, path="names.toml")
    sel = select_sensors(mf)
    sets = [("lambda", "wheel_speed"), ("lambda", "sin", "wheel_speed")]
    out = sensor_errors(mf, sel, sets=sets, seeds=2)
    assert not out.failures, out.failures
    assert all(np.isfinite(list(out.rms[s].values())).all() for s in sets)
    assert "{lambda, wheel_speed}" in str(out)
