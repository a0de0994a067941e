"""The input-output route of the global check (analysis/structural/_io.py) against independent results.

References: the equation of the linear two-compartment model is derived by hand below (its characteristic
polynomial); verdicts are the published ones of tests/analysis/published_models.py and, for every model, those
of the SIAN route (a different algorithm on a different polynomial system).
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from published_models import MODELS
from test_global import ENGINE, SLOW, needs_engine

from nlobs import System
from nlobs.analysis.structural._global import _to_rational, global_identifiability
from nlobs.analysis.structural._identifiable import find_identifiable_functions
from nlobs.analysis.structural._inputs import _input_classes
from nlobs.analysis.structural._io import io_equations

BY_NAME = {m.name: m for m in MODELS}


def _io(system: System, params):
    rm = _to_rational(system, list(params), _input_classes(system, "generic", {}), {})
    return rm, io_equations(rm.params, rm.states, [u for u, _ in rm.inputs], rm.f, rm.h, np.random.default_rng(3))


def test_two_compartment_equation_by_hand():
    # x0' = -(a01 + a21) x0 + a12 x1, x1' = a21 x0 - a12 x1, y = x0: with A the system matrix, y satisfies its
    # characteristic polynomial s^2 - tr(A) s + det(A): y'' + (a01 + a21 + a12) y' + a01 a12 y = 0
    two = BY_NAME["two_compartment"].system()
    _, io = _io(two, ("a01", "a21", "a12"))
    assert io.orders == [2]
    R = io.ring
    a01, a21, a12 = (sp.Symbol(f"p{j}") for j in range(3))  # internal names, in the order given
    y0, y1, y2 = (sp.Symbol(f"y0_{k}") for k in range(3))
    hand = sp.Poly(y2 + (a01 + a21 + a12) * y1 + a01 * a12 * y0, *[sp.Symbol(n) for n in R.names])
    got = sp.Poly(sp.sympify(str(io.eqs[0]).replace("^", "**")), *[sp.Symbol(n) for n in R.names])
    ratio = sp.cancel(got.as_expr() / hand.as_expr())
    assert ratio.is_number and ratio != 0


def test_equation_vanishes_on_a_solution():
    # Goodwin's oscillator (a rational right-hand side): the equation holds along a power-series solution at a
    # random point of GF(P), computed independently of the elimination (a fresh point, 12 orders)
    from nlobs.analysis.structural._io import _big_prime, _Points

    m = BY_NAME["goodwin"]
    _, io = _io(m.system(), m.params)
    assert io.orders == [4]
    rng = np.random.default_rng(11)
    P = _big_prime(rng)
    pts = _Points(io.ring, io.f, io.h, rng, P)
    for i in range(3):
        assert pts.vanishes(io.eqs[0], i)
    # and a perturbed equation does not (the test can fail)
    assert not pts.vanishes(io.eqs[0] + io.ring.var("y0_4"), 0)


def _picard(R, f, h, n, params, x0, u, P):
    """The series solution by Picard's iteration, one correct order per pass (an independent reference)."""
    import flint

    from nlobs.analysis.structural._io import _series_eval

    one = flint.nmod_poly([1], P)
    base = {R.index[q]: one * v for q, v in params.items()}
    for w in R.inputs:
        base[R.index[f"{w}_0"]] = u[w]
    x = {s: one * x0[s] for s in R.states}
    for m in range(1, n):
        vals = {**base, **{R.index[s]: x[s] for s in R.states}}
        x = {s: one * x0[s] + _series_eval(F, vals, one, m).mul_low(_series_eval(Q, vals, one, m).inverse_series_trunc(m),
                                                                     m).integral()
             for s, (F, Q) in zip(R.states, f)}
    vals = {**base, **{R.index[s]: x[s] for s in R.states}}
    return x, [_series_eval(G, vals, one, n).mul_low(_series_eval(S, vals, one, n).inverse_series_trunc(n), n)
               for G, S in h]


@pytest.mark.parametrize("name", ["goodwin", "sliqr", "enzyme"])
def test_newton_series_equal_picard(name):
    # the generic points and the Wronskians use power-series solutions by Newton's iteration (_solve_series): exactly
    # the series of Picard's iteration, to 40 orders, on a rational model (Goodwin), one with an input (SLIQR) and
    # one of ours
    from nlobs.analysis.structural._io import _big_prime, _solve_series

    if name == "enzyme":
        rm = _to_rational(ENZYME, list(ENZYME.params), _input_classes(ENZYME, "generic", {}), {})
        io = io_equations(rm.params, rm.states, [], rm.f, rm.h, np.random.default_rng(3))
    else:
        _, io = _io(BY_NAME[name].system(), BY_NAME[name].params)
    rng = np.random.default_rng(5)
    P = _big_prime(rng)
    sol = _solve_series(io.ring, io.f, io.h, 40, rng, P)
    x0 = {s: int(sol.x[s].coeffs()[0]) for s in io.ring.states}
    x, y = _picard(io.ring, io.f, io.h, 40, sol.params, x0, sol.u, P)
    for s in io.ring.states:
        assert sol.x[s].coeffs()[:40] == x[s].coeffs()[:40]
    assert [q.coeffs() for q in sol.y] == [q.coeffs() for q in y]
    assert len(sol.y[0].coeffs()) > 30  # the comparison covers the orders Newton's doublings produce


# an enzyme-binding model of ours, observed through the sum of two states (as Pivastatin in SI.jl's benchmarks):
# the prolonged output equation is linear in x1 with coefficient a*k*(T - x2) - ..., which the change of variables
# of _shift_state straightens
ENZYME = System(states=["x1", "x2", "x3"], f=["-a*x1*(T - x2) + b*x2", "a*x1*(T - x2) - (b + c)*x2", "c*x2 - d*x3"],
                outputs=["y"], h=["k*(x2 + x3)"], params={p: 1.0 for p in ("a", "b", "c", "d", "k", "T")})


@pytest.mark.parametrize("name", ["enzyme", "sirs_forced"])
def test_change_of_variables_keeps_the_equations(name):
    # the change of variables only shortens the way: the input-output equations are the same polynomials (up to
    # sign) as those of the plain elimination, and the change did happen (the test exercises it)
    if name == "enzyme":
        rm = _to_rational(ENZYME, list(ENZYME.params), _input_classes(ENZYME, "generic", {}), {})
    else:
        m = BY_NAME[name]
        rm = _to_rational(m.system(), list(m.params), _input_classes(m.system(), "generic", {}), {})
    args = (rm.params, rm.states, [u for u, _ in rm.inputs], rm.f, rm.h)
    a = io_equations(*args, np.random.default_rng(3))
    b = io_equations(*args, np.random.default_rng(3), var_change=False)
    assert a.shifted and not b.shifted
    assert a.orders == b.orders
    for x, y in zip(a.eqs, b.eqs):
        assert x == y or x == -y


SINGLE = [m.name for m in MODELS if m.name not in SLOW and (m.verdicts or m.ident is not None)]


@needs_engine
@pytest.mark.parametrize("name", SINGLE)
def test_io_route_equals_sian(name):
    # the two routes: same verdicts, same numbers of solutions, same function verdicts; with several outputs the
    # projections decide only when all they leave open is non-identifiable (known locally), else they refuse
    m = BY_NAME[name]
    s = m.system()
    fn = [k for k in m.verdicts if k not in m.states and k not in m.params]
    a = global_identifiability(s, unknown_params="all", functions=fn, engine=ENGINE, route="io")
    b = global_identifiability(s, unknown_params="all", functions=fn, engine=ENGINE, route="sian")
    if a.refused:
        if "corank" in a.refused:  # a projection's coefficients may need several experiments: SIAN decides
            assert len(m.outputs) > 1 or name == "me_example_7_7"
            return
        # several outputs: refused only where SIAN finds some unknown or function locally, not globally
        assert len(m.outputs) > 1 and "prove global identifiability only" in a.refused
        assert b.locally_only or any(v == "locally" for _, v, _ in b.functions)
        return
    key = lambda r: (r.globally, tuple((lo.name, lo.solutions) for lo in r.locally_only), r.non_identifiable,
                     r.functions)
    assert key(a) == key(b)


@needs_engine
@pytest.mark.parametrize("name", ["goodwin", "sliqr", "seuir", "siwr"])
def test_io_route_published_slow_for_sian(name):
    # models whose SIAN system takes from seconds to minutes (benchmarks/results/global.md); published verdicts
    m = BY_NAME[name]
    fn = [k for k in m.verdicts if k not in m.states and k not in m.params]
    res = global_identifiability(m.system(), unknown_params="all", functions=fn, engine=ENGINE, route="io")
    assert res.ok, res.refused
    want = {"globally": "globally", "locally": "locally", "non": "non-identifiable"}
    assert {k: res.verdict(k) for k in m.verdicts} == {k: want[v] for k, v in m.verdicts.items()}
    assert res.method.startswith("input-output equations")


@needs_engine
def test_goodwin_counts():
    # beta and delta swap (SI.jl: "locally"): exactly two solutions each, as SIAN counts them
    res = global_identifiability(BY_NAME["goodwin"].system(), unknown_params="all", engine=ENGINE)
    assert {lo.name: lo.solutions for lo in res.locally_only} == {"beta": 2, "delta": 2}


@needs_engine
def test_auto_falls_back_with_the_reason(monkeypatch):
    # several outputs whose projections are not shown prime (forced here: seir_n's are prime), and an unknown only
    # locally identifiable (published "locally"): the projections cannot prove it, SIAN decides, and says why
    import nlobs.analysis.structural._io as io_mod

    monkeypatch.setattr(io_mod, "projections_prime", lambda *a, **k: False)
    res = global_identifiability(BY_NAME["seir_n"].system(), unknown_params="all", engine=ENGINE)
    assert res.method.startswith("SIAN") and res.locally_only
    assert any("2 outputs the input-output projections prove global identifiability only" in n for n in res.notes)
    r = global_identifiability(BY_NAME["seir_n"].system(), unknown_params="all", engine=ENGINE, route="io")
    assert not r.ok and "prove global identifiability only" in r.refused
    monkeypatch.undo()
    # proven prime: the projections decide, with the same verdicts as SIAN (test_io_route_equals_sian)
    res2 = global_identifiability(BY_NAME["seir_n"].system(), unknown_params="all", engine=ENGINE)
    assert res2.method.startswith("input-output") and any("prime ideal" in n for n in res2.notes)
    # the multi-experiment example: the Wronskian has corank 2, so the coefficients need not be identifiable from
    # one experiment; the route refuses and SIAN gives the single-experiment verdict
    me = BY_NAME["me_example_7_7"].system()
    r = global_identifiability(me, unknown_params="all", engine=ENGINE, route="io")
    assert not r.ok and "corank 2" in r.refused
    r2 = global_identifiability(me, unknown_params="all", engine=ENGINE)
    assert r2.ok and r2.method.startswith("SIAN") and any("corank" in n for n in r2.notes)


def test_bad_route_is_named():
    from nlobs.errors import ModelError

    with pytest.raises(ModelError, match="route"):
        global_identifiability(BY_NAME["two_compartment"].system(), route="fast")


@needs_engine
def test_constant_denominators_and_my_own_model():
    # a model of ours (not from the papers): a halved decay rate and a third of an input (constant denominators
    # that the rational form keeps), a Hill-type uptake and a scaled output; the routes agree
    s = System(states=["x", "z"], f=["-a*x/2 + u/3 - k*x*z/(1 + x)", "k*x*z/(1 + x) - b*z"], outputs=["y"],
               h=["c*z"], inputs=["u"], params={"a": 1.0, "k": 1.0, "b": 1.0, "c": 1.0})
    a = global_identifiability(s, unknown_params="all", engine=ENGINE, route="io")
    b = global_identifiability(s, unknown_params="all", engine=ENGINE, route="sian")
    assert a.ok, a.refused
    key = lambda r: (r.globally, tuple((lo.name, lo.solutions) for lo in r.locally_only), r.non_identifiable)
    assert key(a) == key(b)


def test_growth_is_bounded():
    # a 10-state chain of ours with one saturating loss: the equation of order 10 would need tens of gigabytes;
    # the route stops at a named bound (the caller then takes SIAN) instead of exhausting the memory
    n = 10
    f = []
    for i in range(n):
        prev = f"k{i}*x{i - 1}" if i else "u"
        f.append(f"{prev} - k{i + 1}*x{i}" + (f" - v*x{i}/(1 + x{i})" if i == 4 else ""))
    s = System(states=[f"x{i}" for i in range(n)], f=f, outputs=["y"], h=[f"x{n - 1}"], inputs=["u"],
               params={**{f"k{i}": 1.0 for i in range(1, n + 1)}, "v": 1.0})
    r = global_identifiability(s, unknown_params="all", route="io")
    assert not r.ok and "too large" in r.refused


# ----------------------------------------------------------------------------------------------
# identifiable functions searched on the fibre of the IO generators (the tangent rows are their differentials)
# ----------------------------------------------------------------------------------------------
FUNCS = [m.name for m in MODELS if len(m.outputs) == 1 and m.ident is not None and m.name not in SLOW]


@needs_engine
@pytest.mark.parametrize("name", FUNCS)
def test_identifiable_functions_io_equals_sian_and_published(name):
    from test_global import _same_field

    from nlobs.analysis import find_identifiable_functions

    m = BY_NAME[name]
    s = m.system()
    a = find_identifiable_functions(s, with_states=m.with_states, engine=ENGINE, route="io", reparametrize_model=False)
    b = find_identifiable_functions(s, with_states=m.with_states, engine=ENGINE, route="sian",
                                    reparametrize_model=False)
    assert a.method.startswith("input-output") and b.method.startswith("SIAN")
    assert all(a.local_checks)
    if m.with_states:
        assert a.complete == b.complete
    else:  # without the states only the route checks completeness (its coefficients generate the parameters' field),
        # except where nothing is searched (step 0: the globally identifiable parameters generate it all)
        step0 = any(n.startswith(("every unknown is globally identifiable", "the globally identifiable unknowns"))
                    for n in b.notes)
        assert b.complete is (True if step0 else None) and a.complete is True
    names = [*(m.states if m.with_states else ()), *m.params]
    assert _same_field(list(a.functions), list(b.functions), names), (a.functions, b.functions)
    assert _same_field(list(a.functions), list(m.ident), names), (a.functions, m.ident)


@needs_engine
@pytest.mark.parametrize("name", ["goodwin_funcs", "sliqr", "seuir"])
def test_identifiable_functions_io_published_slow_for_sian(name):
    # SIAN's system takes 6 s to minutes here (benchmarks/results/global.md); the IO route's search is below 2 s
    from test_global import _same_field

    from nlobs.analysis import find_identifiable_functions

    m = BY_NAME[name]
    a = find_identifiable_functions(m.system(), with_states=m.with_states, engine=ENGINE, reparametrize_model=False)
    assert a.method.startswith("input-output") and all(a.local_checks)
    names = [*(m.states if m.with_states else ()), *m.params]
    assert _same_field(list(a.functions), list(m.ident), names), (a.functions, m.ident)
    if m.with_states:
        assert a.complete is True


@needs_engine
def test_identifiable_functions_route_io_refuses_with_the_reason():
    from nlobs.analysis import find_identifiable_functions

    r = find_identifiable_functions(BY_NAME["me_example_7_7"].system(), engine=ENGINE, route="io")
    assert r.refused.startswith("the input-output route does not apply") and "corank 2" in r.refused
    import nlobs.analysis.structural._io as io_mod

    mp = pytest.MonkeyPatch()
    mp.setattr(io_mod, "projections_prime", lambda *a, **k: False)  # several outputs, projections not shown prime
    try:
        r2 = find_identifiable_functions(BY_NAME["seir_n"].system(), engine=ENGINE)
    finally:
        mp.undo()
    assert not r2.refused and r2.method.startswith("SIAN") and any("2 outputs" in n for n in r2.notes)


@needs_engine
def test_tangent_rows_are_the_identifiable_differentials():
    # two-compartment model, parameters a01, a21, a12 and states x0, x1 (y = x0): the identifiable functions are
    # generated by a01*a12 and a01 + a12 + a21 (the hand-derived equation above), y = x0 and
    # y' = a12*x1 - (a01 + a21)*x0: four, one short of the five unknowns; at a random point the gradient of each
    # lies in the span of the tangent rows, and the gradients of a01 and of x1 alone do not
    from nlobs.analysis.structural._global import _prepare_io

    prep = _prepare_io(BY_NAME["two_compartment"].system(), unknown_params="all")
    ech, vals, col, n = prep.tangent()
    assert ech.rank == 4 and n == 5
    p = prep.p
    a01, a21, a12, x0, x1 = (vals[k] for k in ("a01", "a21", "a12", "x0", "x1"))

    def grad(d: dict[str, int]) -> np.ndarray:
        g = np.zeros(n, dtype=np.int64)
        for k, v in d.items():
            g[col[k]] = v % p
        return g

    inside = [grad({"x0": 1}), grad({"a01": a12, "a12": a01}), grad({"a01": 1, "a21": 1, "a12": 1}),
              grad({"a12": x1, "x1": a12, "a01": -x0, "a21": -x0, "x0": -(a01 + a21)})]
    assert all(not ech.reduce(g).any() for g in inside)
    assert ech.reduce(grad({"a01": 1})).any()
    assert ech.reduce(grad({"x1": 1})).any()


# ----------------------------------------------------------------------------------------------
# several outputs: the primality check of the projections (SI.jl's check_primality)
# ----------------------------------------------------------------------------------------------
@needs_engine
@pytest.mark.parametrize("polys, prime", [
    # SI.jl test/bodies/check_primality_zerodim.jl, in x = v0, y = v1 (its expected answers)
    (({(2, 0): 1, (0, 0): -1}, {(0, 2): 1, (0, 0): -4}), False),
    (({(4, 0): 1, (3, 0): 5, (1, 0): -7, (0, 0): -35}, {(0, 1): 1, (0, 0): -3}), False),  # (x + 5)(x^3 - 7), y - 3
    (({(3, 0): 1, (0, 0): -5}, {(0, 1): 1, (0, 0): -1}), True),
    (({(2, 0): 1, (0, 0): 1}, {(0, 3): 1, (1, 0): -2, (0, 0): 5}), True),  # x^2 + 1, y^3 - 3x + x + 5
])
def test_zerodim_primality_published_cases(polys, prime):
    from nlobs.algebra._groebner import get_engine
    from nlobs.analysis.structural._io import zerodim_prime

    assert zerodim_prime(list(polys), 2, get_engine(ENGINE), np.random.default_rng(0)) is prime


@needs_engine
def test_zerodim_prime_over_q_never_mod_p_is_not_claimed():
    # [x, y^4 + 1]: prime over Q, but y^4 + 1 splits mod every prime: SI.jl then works over Q; here the check says
    # "not proven", and the caller keeps the weaker conclusion (projections decide "globally" only)
    from nlobs.algebra._groebner import get_engine
    from nlobs.analysis.structural._io import zerodim_prime

    assert zerodim_prime([{(1, 0): 1}, {(0, 4): 1, (0, 0): 1}], 2, get_engine(ENGINE), np.random.default_rng(0)) is False


@needs_engine
def test_projections_not_prime_on_the_published_remark_3_example():
    # Dong, Goodbrake, Harrington & Pogudin, remark 3 (SI.jl test/bodies/io_projections.jl asserts
    # !check_primality): our rational_outputs model; the IO route then proves only "globally" verdicts
    from nlobs.algebra._groebner import get_engine
    from nlobs.analysis.structural._io import projections_prime

    m = BY_NAME["rational_outputs"]
    _, io = _io(m.system(), m.params)
    assert projections_prime(io, get_engine(ENGINE), np.random.default_rng(0)) is False
    _, io2 = _io(BY_NAME["bruno2016"].system(), BY_NAME["bruno2016"].params)
    assert projections_prime(io2, get_engine(ENGINE), np.random.default_rng(0)) is True


@needs_engine
def test_a_projection_too_large_for_the_wronskian_goes_to_sian(monkeypatch):
    # several outputs, a projection with more jet monomials than the bound: the route refuses and says so, and
    # route="auto" takes SIAN with that reason (Biohydrogenation's projections have more than 10 monomials)
    import nlobs.analysis.structural._io as io_mod

    monkeypatch.setattr(io_mod, "MAX_MONOMIALS_SEVERAL_OUTPUTS", 10)
    s = BY_NAME["biohydrogenation"].system()
    a = global_identifiability(s, unknown_params="all", engine=ENGINE, route="io")
    assert "jet monomials (more than 10 with several outputs)" in a.refused
    b = global_identifiability(s, unknown_params="all", engine=ENGINE)
    assert b.ok and b.method.startswith("SIAN") and any("jet monomials" in n for n in b.notes)


@needs_engine
def test_a_power_beyond_the_search_degree():
    # a model of ours: y' = -a^4 y + b u (by hand, from x' = -a^4 x + b u, y = x): a^4 and b are the coefficients,
    # a has four complex solutions (a times the fourth roots of unity) and no identifiable function of a has degree
    # below 4; the search adds the powers of an unknown up to its number of solutions (as SI.jl's p22^4 in p53)
    s = System(states=["x"], f=["-a**4*x + b*u"], outputs=["y"], h=["x"], inputs=["u"], params={"a": 1.0, "b": 1.0})
    g = global_identifiability(s, unknown_params="all", engine=ENGINE, route="io")
    assert [(lo.name, lo.solutions) for lo in g.locally_only] == [("a", 4)]
    res = find_identifiable_functions(s, with_states=True, reparametrize_model=False, engine=ENGINE, route="io")
    assert set(res.functions) == {"x", "b", "a**4"} and res.complete is True


def _pgrep(pattern: str) -> str:
    import subprocess

    return subprocess.run(["pgrep", "-f", pattern], capture_output=True, text=True).stdout.strip()


def test_race_of_two_routes_under_a_budget():
    import subprocess
    import time

    from nlobs.analysis.structural._budget import committed, race
    from nlobs.errors import ModelError

    def ok(v):
        return True

    # the first route answers within its budget: the second never starts
    out = race(lambda: 6 * 7, 10, lambda: 1 / 0, ok)
    assert (out.winner, out.value, out.first_lost) == ("first", 42, None)

    # the first route sits in a grandchild (as in msolve) past its budget: the second answers, the first goes with
    # its whole process group
    def slow():
        subprocess.run(["sleep", "31"])
        return "slow"

    t = time.perf_counter()
    out = race(slow, 0.5, lambda: "quick", ok)
    assert (out.winner, out.value) == ("second", "quick") and "more than 0.5 s" in out.first_lost
    assert time.perf_counter() - t < 5 and not _pgrep("^sleep 31$")

    # an unusable answer hands over to the second route, and says why
    out = race(lambda: "refused", 10, lambda: "sian", lambda r: r != "refused")
    assert (out.winner, out.value, out.first_lost) == ("second", "sian", "refused")

    # once committed, the first route is no longer timed: a second route already started is stopped
    def committing():
        time.sleep(0.6)
        committed()
        time.sleep(0.6)
        return "io"

    def stalled():
        subprocess.run(["sleep", "32"])
        return "sian"

    out = race(committing, 0.2, stalled, ok)
    assert (out.winner, out.value, out.first_lost) == ("first", "io", None) and not _pgrep("^sleep 32$")

    # errors of either route reach the caller
    def bad():
        raise ModelError("named condition")

    with pytest.raises(ModelError, match="named condition"):
        race(bad, 10, lambda: 1, ok)
    with pytest.raises(ModelError, match="named condition"):
        race(lambda: "refused", 10, bad, lambda r: False)


@needs_engine
def test_killing_the_caller_takes_the_routes_and_their_engine_runs_along():
    # a caller with its own time limit kills the process that runs route="auto": the racing children (their own
    # process groups) and the engine subprocesses they started must not outlive it (nlobs._process)
    import signal
    import subprocess
    import sys
    import textwrap
    import time

    code = textwrap.dedent(f"""
        from nlobs.algebra._groebner import get_engine
        from nlobs.analysis.structural._budget import race
        eng = get_engine({ENGINE!r})
        def stuck(n):
            return lambda: eng._run(["sleep", str(n)], "a test")
        race(stuck(34), 0.1, stuck(35), lambda r: True)
    """)
    caller = subprocess.Popen([sys.executable, "-c", code])
    deadline = time.monotonic() + 20
    while not (_pgrep("^sleep 34$") and _pgrep("^sleep 35$")) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _pgrep("^sleep 34$") and _pgrep("^sleep 35$"), "the race did not start both routes"
    caller.send_signal(signal.SIGKILL)
    caller.wait()
    deadline = time.monotonic() + 5
    while (_pgrep("^sleep 34$") or _pgrep("^sleep 35$")) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _pgrep("^sleep 34$") and not _pgrep("^sleep 35$")


@needs_engine
def test_auto_takes_sian_when_the_io_budget_runs_out(monkeypatch):
    import nlobs.analysis.structural._global as g

    import time

    slow_prepare = g._prepare_io

    def stalled(*a, **k):  # the equations take longer than the budget (the child inherits the patch)
        time.sleep(20)
        return slow_prepare(*a, **k)

    monkeypatch.setattr(g, "IO_BUDGET", 0.2)
    monkeypatch.setattr(g, "_prepare_io", stalled)
    s = BY_NAME["two_compartment"].system()
    t = time.perf_counter()
    res = global_identifiability(s, unknown_params="all", engine=ENGINE)
    assert res.method.startswith("SIAN") and any("budget" in n for n in res.notes)
    assert time.perf_counter() - t < 15
    monkeypatch.setattr(g, "_prepare_io", slow_prepare)
    ref = global_identifiability(s, unknown_params="all", engine=ENGINE, route="io")
    assert (res.globally, res.non_identifiable) == (ref.globally, ref.non_identifiable)


@needs_engine
def test_my_ten_state_chain_with_three_sampled_compartments():
    # a model of ours: ten compartments in a chain, dose u into x1, a saturating loss in x5, x1, x5 and x10 sampled.
    # By hand: between the sampled x1 and x5 the chain x2 -> x3 -> x4 passes x1 to x5 through the transfer function
    # k1 k2 k3 k4 / ((s + k2)(s + k3)(s + k4)) (x1 known, k1 from x1' = u - k1 x1): k2, k3, k4 are its poles, known
    # only as a set (3 values each); from x5 to x10 the poles are k6..k10 and the gain k5 k6 k7 k8 k9 gives
    # k6 k7 k8 k9, so k10 (the product of all five over it) is unique and k6..k9 are a set (4 values each)
    n = 10
    f = ["u - k1*x1"] + [f"k{i - 1}*x{i - 1} - k{i}*x{i}" for i in range(2, n + 1)]
    f[4] += " - vm*x5/(1 + x5)"
    s = System(states=[f"x{i}" for i in range(1, n + 1)], f=f, outputs=["y1", "y5", "y10"], h=["x1", "x5", "x10"],
               inputs=["u"], params={**{f"k{i}": 1.0 for i in range(1, n + 1)}, "vm": 1.0})
    a = global_identifiability(s, unknown_params="all", engine=ENGINE, route="io")
    assert a.ok, a.refused
    sols = {lo.name: lo.solutions for lo in a.locally_only}
    assert set(a.globally) == {"x1", "x5", "x10", "k1", "k5", "k10", "vm"}
    assert {k: sols[k] for k in ("k2", "k3", "k4", "k6", "k7", "k8", "k9")} == {
        "k2": 3, "k3": 3, "k4": 3, "k6": 4, "k7": 4, "k8": 4, "k9": 4}
    b = global_identifiability(s, unknown_params="all", engine=ENGINE, route="sian")
    assert (a.globally, a.locally_only, a.non_identifiable) == (b.globally, b.locally_only, b.non_identifiable)


def _random_poly(ctx, rng, terms, degree):
    import flint

    n = len(ctx.names())
    out = {}
    for _ in range(terms):
        m = tuple(int(e) for e in rng.integers(0, degree + 1, size=n))
        out[m] = int(rng.integers(-9, 10)) or 1
    return ctx.from_dict(out) + ctx.gen(int(rng.integers(0, n)))  # never constant


@pytest.mark.parametrize("seed", range(8))
def test_fast_factoring_agrees_with_full_factoring(seed):
    # _factors (StructuralIdentifiability.jl's fast_factor) against FLINT's complete factorisation, on products of
    # random polynomials with a content in one variable, a repeated factor and a linear factor: the same set of
    # irreducible factors up to sign
    import flint

    from nlobs.analysis.structural._io import _factors

    rng = np.random.default_rng(seed)
    ctx = flint.fmpz_mpoly_ctx.get(("a", "b", "c", "d"), "degrevlex")
    a, b, c, d = ctx.gens()
    p1, p2 = _random_poly(ctx, rng, 6, 2), _random_poly(ctx, rng, 5, 3)
    q = 6 * p1 * p2 * (a * b + c) ** 2 * (d**2 + 3 * a)
    want = [g for g, _ in q.factor()[1]]
    got = _factors(q, rng)
    assert len(got) == len(want)
    assert all(g in want or -g in want for g in got)
    assert _factors(a * b + c, rng) == [a * b + c]  # linear in c and primitive: irreducible without a test


def test_parameter_factors_are_split_off():
    # a resultant's factors in the parameters alone never vanish on the generic solution: _without_parameter_factor
    # divides them out (here squares of binomials, as MAPK's resultants carry), leaving the factors in the jets
    import flint

    from nlobs.analysis.structural._io import _without_parameter_factor

    ctx = flint.fmpz_mpoly_ctx.get(("a", "b", "c", "y0", "y1"), "degrevlex")
    a, b, c, y0, y1 = ctx.gens()
    jets = (a * y1 + b * y0**2 + c) * (y1 - a * y0)
    q = (a - b) ** 2 * (a * c + 3 * b) * jets
    assert _without_parameter_factor(q, 3) in (jets, -jets)
    assert _without_parameter_factor(jets, 3) == jets


@needs_engine
def test_mapk_with_five_outputs_published():
    # StructuralIdentifiability.jl's benchmark model "MAPK model (5 outputs)" (benchmarks/si_models.py, transcribed
    # from its benchmarking/benchmarks.jl) and its published result (benchmarking/IdentifiableFunctions/results/
    # MAPK model (5 outputs)/result_(normalforms, 2)_with_states): all 12 states and 22 parameters identifiable.
    # The route's resultants here reach a million terms that are a 6,488-term factor times parameter binomials
    s = _si_benchmark_model("mapk_5out")
    r = global_identifiability(s, unknown_params="all", route="io")
    assert "input-output" in r.method
    assert set(r.globally) == set(s.states) | set(s.params) and len(r.globally) == 34
    assert not r.locally_only and not r.non_identifiable


def _benchmark_module(name: str):
    """A data module of benchmarks/ (si_models: the models; si_published: SI.jl's published generators)."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location(name, Path(__file__).parents[2] / "benchmarks" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _si_benchmark_model(key: str):
    """A model of StructuralIdentifiability.jl's benchmark set, as benchmarks/si_models.py transcribes it."""
    return _benchmark_module("si_models").system(key)


def _si_published(key: str) -> list[str]:
    """SI.jl's published identifiable functions (with states) of that model (benchmarks/si_published.py, from
    benchmarking/IdentifiableFunctions/results/<name>/result_(normalforms, 2)_with_states)."""
    return _benchmark_module("si_published").PUBLISHED[key]


@needs_engine
@pytest.mark.parametrize("key", ["hiv2", "cgv1990"])
def test_route_generators_complete_what_the_search_misses(key):
    # the simple forms searched miss part of the field (HIV2_io: two published generators have a non-monomial
    # denominator or degree 4; CGV1990 likewise); the route's own generators complete it, and the result generates
    # the published field
    from test_global import _same_field

    from nlobs.analysis import find_identifiable_functions

    s, published = _si_benchmark_model(key), _si_published(key)
    r = find_identifiable_functions(s, with_states=True, route="io", reparametrize_model=False)
    assert r.complete is True and all(r.local_checks)
    assert any("input-output coefficients" in n for n in r.notes)
    assert _same_field(list(r.functions), published, [*s.states, *s.params]), r.functions


@needs_engine
@pytest.mark.parametrize("key", ["pk1", "cd8", "cholera", "phos", "glv2"])
def test_published_table_models_outside_benchmarks_jl(key):
    # models of SI.jl's published identifiable-functions table that its benchmarks.jl lacks (transcribed from their
    # 2023 files): PK1 has a published generator with a polynomial denominator, (k2*s2)/(k3*k2 + k3*k1); CD8 has
    # P*rho_E, delta_NE*P, rho_P*P; the others are identifiable throughout
    from test_global import _same_field

    from nlobs.analysis import find_identifiable_functions

    s, published = _si_benchmark_model(key), _si_published(key)
    r = find_identifiable_functions(s, with_states=True, reparametrize_model=False)
    assert r.complete is True and all(r.local_checks)
    assert r.method.startswith("input-output")
    assert _same_field(list(r.functions), published, [*s.states, *s.params, *s.inputs]), r.functions
    # cholera, Phosphorylation and gLV (2o): every unknown is globally identifiable (as published), so the unknowns
    # are the generators and no search is run; PK1 and CD8 are searched
    every = set(published) == {*s.states, *s.params}
    assert any(n.startswith("every unknown is globally identifiable") for n in r.notes) is every
    assert (set(r.functions) == {*s.states, *s.params}) is every



@needs_engine
@pytest.mark.parametrize("route", ["io", "sian"])
def test_unknowns_outside_the_output_are_set_aside_without_a_search(route):
    # x2, x3, b and k never reach y: each axis is a local kernel direction by itself, so the globally identifiable
    # x1, a, c generate everything (no search). With x2 feeding x1 through c the kernel direction mixes x2 and c,
    # and the search must run: y'' + (a + b) y' + a b y = 0 with y(0) = x1, y'(0) = c x2 - a x1, so the field is
    # Q(x1, a + b, a b, c x2 - a x1) (by hand; a and b only as a pair)
    from test_global import _same_field

    from nlobs import System
    from nlobs.analysis import find_identifiable_functions

    apart = System(states=["x1", "x2", "x3"], f=["-a*x1 + c*x1**2", "-b*x2 + x1", "k*x3"], outputs=["y"], h=["x1"],
                   params={"a": 1.0, "b": 1.0, "c": 1.0, "k": 1.0})
    r = find_identifiable_functions(apart, with_states=True, route=route, reparametrize_model=False)
    assert r.complete is True and set(r.functions) == {"x1", "a", "c"}
    assert any("(x2, x3, b, k) are each a direction of the local kernel by themselves" in n for n in r.notes)
    fed = System(states=["x1", "x2"], f=["-a*x1 + c*x2", "-b*x2"], outputs=["y"], h=["x1"],
                 params={"a": 1.0, "b": 1.0, "c": 1.0})
    r = find_identifiable_functions(fed, with_states=True, route=route, reparametrize_model=False)
    assert not any("direction of the local kernel" in n for n in r.notes)
    assert r.complete is True
    assert _same_field(list(r.functions), ["x1", "a*b", "a + b", "c*x2 - a*x1"], ["x1", "x2", "a", "b", "c"]), r.functions


@needs_engine
def test_unseen_unknowns_are_left_out_of_the_search():
    # the fed model above plus a branch no output sees (z with its own rate e): z and e are set aside, the search runs
    # on the rest and finds the same field Q(x1, a + b, a b, c x2 - a x1) (by hand, as above)
    from test_global import _same_field

    from nlobs import System
    from nlobs.analysis import find_identifiable_functions

    s = System(states=["x1", "x2", "z"], f=["-a*x1 + c*x2", "-b*x2", "x1 - e*z"], outputs=["y"], h=["x1"],
               params={"a": 1.0, "b": 1.0, "c": 1.0, "e": 1.0})
    for route in ("io", "sian"):
        r = find_identifiable_functions(s, with_states=True, route=route, reparametrize_model=False)
        assert any(n.startswith("z, e: each a direction of the local kernel by itself") for n in r.notes), r.notes
        assert r.complete is True and all(r.local_checks)
        assert _same_field(list(r.functions), ["x1", "a*b", "a + b", "c*x2 - a*x1"], ["x1", "x2", "z", "a", "b", "c", "e"])

