"""The search for identifiable functions (nlobs.analysis.structural._identifiable), piece by piece.

Reference values are derived by hand in each test: the modified Lotka-Volterra model of StructuralIdentifiability.jl's
benchmarks (x1' = (a + b) x1 - c x1 x2, x2' = -a b x2 + d x1 x2, y = x1) has the symmetries a <-> b and
(c, x2) -> (k c, x2 / k), and nothing else: its field is Q(x1, d, a + b, a b, c x2), of transcendence degree 5 of 6
unknowns; the functions of the parameters alone are Q(d, a + b, a b), of degree 3.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_global import ENGINE, _same_field, needs_engine

from nlobs import System
from nlobs.algebra._groebner import get_engine
from nlobs.analysis.structural import _identifiable as I
from nlobs.analysis import find_identifiable_functions
from nlobs.analysis.structural._global import _prepare, _prepare_io

LV_FIELD = ["x1", "d", "a + b", "a*b", "c*x2"]
P = 2_147_483_647  # 2^31 - 1, a prime msolve accepts


def _lv() -> System:
    return System(states=["x1", "x2"], f=["(a + b)*x1 - c*x1*x2", "-a*b*x2 + d*x1*x2"], outputs=["y"], h=["x1"],
                  params={"a": 1.0, "b": 2.0, "c": 3.0, "d": 4.0}, name="LV")


@needs_engine
def test_select_keeps_an_algebraic_candidate_that_is_not_a_rational_function():
    # a + b and a b are algebraically independent; a - b is algebraic over Q(a + b, a b) (a root of
    # z^2 - (a + b)^2 + 4 a b) but not in it (it is not symmetric), so it is kept; a^2 + b^2 = (a + b)^2 - 2 a b and
    # (a - b)^2 are in Q(a + b, a b), and a = ((a + b) + (a - b)) / 2 is in Q(a + b, a b, a - b): all three dropped.
    # The gradients decide a + b and a b without the engine; the four algebraic ones take two runs (a - b is found
    # outside, then the last three inside), where testing one candidate at a time took four
    eng = get_engine(ENGINE)
    cands = [_sym(t) for t in ["a + b", "a*b", "a - b", "a**2 + b**2", "(a - b)**2", "a"]]
    got = I._select(cands, ["a", "b"], eng, P, np.random.default_rng(1))
    assert [str(g) for g in got] == ["a + b", "a*b", "a - b"]
    assert eng.calls == 2


@needs_engine
def test_select_from_kept_functions():
    # c is kept already; c**2 + a is independent of it, a is then a function of the two: one engine run, one kept
    eng = get_engine(ENGINE)
    got = I._select([_sym("c**2 + a"), _sym("a"), _sym("a*c")], ["a", "c"], eng, P,
                    np.random.default_rng(2), kept=[_sym("c")])
    assert [str(g) for g in got] == ["c", "a + c**2"]
    assert eng.calls == 1


def _sym(text: str):
    import sympy as sp

    from nlobs.model import symbol

    return sp.sympify(text, locals={n: symbol(n) for n in ("a", "b", "c")})


@needs_engine
def test_field_rank_on_both_routes_with_and_without_the_states():
    eng = get_engine(ENGINE)
    lv = _lv()
    for prep in (_prepare_io(lv, unknown_params="all", seed=0, eng=eng), _prepare(lv, unknown_params="all", seed=0)):
        assert I._Search(prep, eng, list(prep.unknown_names), 2).field_rank() == 5
        # the parameters alone: the state columns are outside U, and only d, a + b, a b remain
        assert I._Search(prep, eng, ["a", "b", "c", "d"], 2).field_rank() == 3


@needs_engine
def test_lv_searches_without_the_globally_identifiable_unknowns():
    # x1 and d are globally identifiable: the first search leaves them out of the monomials, finds a + b, a b, c x2,
    # and its completeness check passes, so the search over every monomial never runs. Engine runs: 19 before (the
    # full search, one membership test per kept candidate, two verification points)
    eng = get_engine(ENGINE)
    r = I.find_identifiable_functions(_lv(), engine=eng, route="io", reparametrize_model=False)
    assert r.complete is True and all(r.local_checks)
    assert _same_field(list(r.functions), LV_FIELD, ["x1", "x2", "a", "b", "c", "d"]), r.functions
    assert eng.calls <= 11, eng.calls


@needs_engine
def test_a_generator_that_needs_a_globally_identifiable_unknown(monkeypatch):
    # y'' + (a + b) y' + a b y = 0 with y(0) = x1, y'(0) = c x2 - a x1: the field is Q(x1, a + b, a b, c x2 - a x1)
    # (by hand). x1 is globally identifiable, but no function free of x1 completes the field: c x2 is locally
    # identifiable (a is, up to the swap with b) but not globally, so the first search reaches the transcendence
    # degree after its local points (x1, a + b, a b, c x2) and falls short after its global ones; the search over
    # every monomial then finds c x2 - a x1
    fed = System(states=["x1", "x2"], f=["-a*x1 + c*x2", "-b*x2"], outputs=["y"], h=["x1"],
                 params={"a": 1.0, "b": 1.0, "c": 1.0})
    seen, searches = [], []
    without, search = I._Search.without, I._search_and_select

    def spy(self, names):
        seen.append(tuple(names))
        return without(self, names)

    def count(*args, **kw):
        searches.append(args[0])
        return search(*args, **kw)

    monkeypatch.setattr(I._Search, "without", spy)
    monkeypatch.setattr(I, "_search_and_select", count)
    r = I.find_identifiable_functions(fed, engine=ENGINE, route="io", reparametrize_model=False)
    assert seen == [("x1",)] and len(searches) == 2
    assert r.complete is True
    assert _same_field(list(r.functions), ["x1", "a*b", "a + b", "c*x2 - a*x1"], ["x1", "x2", "a", "b", "c"])


@needs_engine
def test_candidates_of_points_that_ran_out_are_verified(monkeypatch):
    # with two global points per denominator the LV search cannot cut its locally identifiable candidates down to the
    # globally identifiable ones (a and b are each locally identifiable, not globally): those denominators are
    # marked, their candidates go through the fresh-point check, and the result is still the field of LV
    eng = get_engine(ENGINE)
    prep = _prepare_io(_lv(), unknown_params="all", seed=0, eng=eng)
    s = I._Search(prep, eng, list(prep.unknown_names), 3)
    q1 = tuple(0 for _ in s.U)
    k2 = s.solve(q1, max_points=2)
    assert q1 in s.unconverged
    assert k2.shape[0] > s.solve(q1).shape[0]  # the full run cuts further
    orig = I._Search.solve
    monkeypatch.setattr(I._Search, "solve", lambda self, Q, max_points=12: orig(self, Q, max_points=2))
    r = I.find_identifiable_functions(_lv(), engine=ENGINE, route="io", reparametrize_model=False)
    assert r.complete is True and all(r.local_checks)
    assert _same_field(list(r.functions), LV_FIELD, ["x1", "x2", "a", "b", "c", "d"]), r.functions


@needs_engine
def test_the_first_search_stops_after_its_local_points(monkeypatch):
    # HIV (StructuralIdentifiability.jl's benchmarks): the functions free of its globally identifiable unknowns are
    # short of the transcendence degree already among the locally identifiable ones, so the first search ends before
    # any global point; so are all the degree-2 candidates (HIV has 14 unknowns: degree 2 by default), so the search
    # goes straight to degree 3 (the published c*q*x needs it), which finds the published field
    from test_io_route import _si_benchmark_model, _si_published

    s = _si_benchmark_model("hiv")
    searches = []
    search = I._search_and_select

    def count(*args, **kw):
        searches.append(args[0])
        return search(*args, **kw)

    monkeypatch.setattr(I, "_search_and_select", count)
    r = I.find_identifiable_functions(s, engine=ENGINE, route="io", reparametrize_model=False)
    assert len(searches) == 1 and searches[0]._parent is None  # only the full search of degree 3 ran
    assert max(sum(e) for e in searches[0].monos) == 3
    assert r.complete is True and all(r.local_checks)
    assert _same_field(list(r.functions), _si_published("hiv"), [*s.states, *s.params]), r.functions


@needs_engine
def test_local_rows_are_the_reduced_quotient_rule():
    # the constraints at a local point are the gradients of P/Q (numerator of the quotient rule, Q grad m - m grad Q
    # for each monomial m) reduced modulo the tangent rows; the search computes them from the monomials' reduced
    # gradients shared by every Q. Here directly, one Q at a time
    from nlobs.algebra._modular import monomial_value

    eng = get_engine(ENGINE)
    for prep in (_prepare_io(_lv(), unknown_params="all", seed=0, eng=eng), _prepare(_lv(), unknown_params="all", seed=0)):
        s = I._Search(prep, eng, list(prep.unknown_names), 2)
        for i in range(3):
            ech, uvals, ucol, n, _, _ = s._local_point(i)
            for Q in I._denominators(s.U, []):
                p = s.p
                G = np.zeros((len(s.monos), n), dtype=object)
                for r, m in enumerate(s.monos):
                    for c, u in enumerate(ucol):
                        dm = m[c] * monomial_value([e - (j == c) for j, e in enumerate(m)], uvals, p) if m[c] else 0
                        dq = Q[c] * monomial_value([e - (j == c) for j, e in enumerate(Q)], uvals, p) if Q[c] else 0
                        G[r, u] = (monomial_value(Q, uvals, p) * dm - monomial_value(m, uvals, p) * dq) % p
                R = ech.reduce_many(np.array(G, dtype=np.int64)).T
                want = R[R.any(axis=1)]
                got = np.array(s.local_rows(Q, i)).reshape(-1, len(s.monos))
                assert np.array_equal(got, want)


def test_widened_echelon_keeps_its_rows():
    from nlobs.algebra._modular import RowEchelon

    rng = np.random.default_rng(3)
    ech = RowEchelon(6, P)
    ech.add_many(rng.integers(0, P, size=(4, 6)))
    w = ech.widened(3)
    assert w.ncols == 9 and w.pivots == ech.pivots
    assert np.array_equal(w.basis[:, :6], ech.basis) and not w.basis[:, 6:].any()
    v = rng.integers(0, P, size=9)
    assert w.add(v) and w.rank == 5  # still a working echelon form
    assert w.contains(v)


def test_a_model_file_instead_of_a_system_is_named():
    from nlobs import load_model
    from nlobs.analysis import global_identifiability
    from nlobs.errors import ModelError

    mf = load_model("dc_motor")  # a model of the library, as a parsed file
    for call, name in ((I.find_identifiable_functions, "find_identifiable_functions"),
                       (global_identifiability, "global_identifiability")):
        with pytest.raises(ModelError, match=rf"{name}: `system` must be an nlobs.System, got ModelFile "
                                             r"\(a parsed model file: pass its \.system\)"):
            call(mf)
    with pytest.raises(ModelError, match=r"got str \(a model file's name\? load it with nlobs.load_model"):
        I.find_identifiable_functions("lv.toml")


@needs_engine
@pytest.mark.parametrize("model", ["lv", "rate"])
def test_candidates_are_exact_terms_that_print_as_their_function(model):
    # the search's candidates stay exact terms until printed: each must print as the function P/Q its terms say
    # (checked against SymPy's own expansion of the printed expression), equal the unknown itself where it is one (the
    # globally identifiable x1 is recognised among them, so it is not kept twice), read the same over a wider list of
    # unknowns (the completeness check on SIAN's system uses every unknown), and be identifiable. "rate": x' = -(a +
    # 2 b) x, y = x, whose candidates a + 2 b, a**2 + 4*a*b + 4*b**2... have coefficients other than 1
    import sympy as sp

    from nlobs.analysis import global_identifiability
    from nlobs.model import symbol

    system = _lv() if model == "lv" else System(states=["x1"], f=["-(a + 2*b)*x1"], outputs=["y"], h=["x1"],
                                                 params={"a": 1.0, "b": 1.0})
    eng = get_engine(ENGINE)
    prep = _prepare_io(system, unknown_params="all", seed=0, eng=eng)
    U = list(prep.unknown_names)
    s = I._Search(prep, eng, U, 2)
    found = s.functions(s.solve(tuple(0 for _ in U)), tuple(0 for _ in U))
    assert I._Candidate.unknown("x1", U) in found
    syms = [symbol(u) for u in U]
    for c in found:
        num, den = sp.fraction(sp.cancel(c.expr))
        k = None  # SymPy may scale N and D by one constant
        for part, terms in ((num, c.num), (den, c.den)):
            want = {tuple(e): sp.Rational(a, b) for e, a, b in terms}
            got = sp.Poly(part, *syms).as_dict()
            k = k or next(iter(got.values())) / want[next(iter(got))]
            assert {e: v / k for e, v in got.items()} == want, (c, part)
        wider = ["z", *reversed(U)]
        tn, td = c.terms_over(wider)
        assert tn == tuple(((0, *reversed(e)), a, b) for e, a, b in c.num) and len(td) == len(c.den)
        if len(c.num) <= I._PRINTED_TERMS:
            assert I._complexity(c) == I._complexity(c.expr)  # the printed order of step 4 is kept
    # the global check's own verdict on the printed functions (a coefficient recovered wrongly, 1/2 for 2, gives a
    # function that is not identifiable)
    texts = [str(c) for c in found]
    assert model == "lv" or "a + 2*b" in texts, texts
    res = global_identifiability(system, unknown_params="all", functions=texts, engine=ENGINE, route="io")
    assert [v for _, v, _ in res.functions] == ["globally"] * len(texts), res.functions


@needs_engine
@pytest.mark.parametrize("model, chosen, counts", [
    # x' = -(a + b) x, y = x: the field is Q(x, a + b); the random cut (a line in the (a, b) plane) meets the line
    # a + b = const of both fibres in one point, so the identifiability fibre's count (at most that of the chosen
    # functions', at least 1) is not computed
    ("sum", ["x", "a + b"], 1),
    # x' = -a b x: the cut meets the hyperbola a b = const in two points: both counts are computed, and agree
    ("product", ["x", "a*b"], 2),
    # Modified LV: a <-> b leaves two points on the cut in both fibres: both counts are computed, and agree
    ("lv", LV_FIELD, 2),
])
def test_completeness_counts_the_identifiability_fibre_only_when_needed(monkeypatch, model, chosen, counts):
    import sympy as sp

    rhs = {"sum": "-(a + b)*x", "product": "-a*b*x"}
    system = _lv() if model == "lv" else System(states=["x"], f=[rhs[model]], outputs=["y"], h=["x"],
                                                params={"a": 1.0, "b": 2.0}, name=model)
    eng = get_engine(ENGINE)
    prep = _prepare(system, unknown_params="all", seed=0)
    U = list(prep.unknown_names)
    calls = []
    count = I._count
    monkeypatch.setattr(I, "_count", lambda *a, **k: calls.append(a[1]) or count(*a, **k))
    funcs = [sp.sympify(c, locals={u: I.symbol(u) for u in U}) for c in chosen]
    assert I._complete(prep, eng, funcs, U, np.random.default_rng(1)) is True
    assert len(calls) == counts


def test_the_command_line_gives_the_parameters_field_on_request(tmp_path, capsys):
    # StructuralIdentifiability.jl's default is the field of the parameters (with_states = false): for the
    # two-compartment model its documented answer is a01*a12 and a01 + a12 + a21 (its README's example)
    import json

    from nlobs.cli import main

    model = tmp_path / "two.toml"
    model.write_text('name = "two"\nstates = ["x0", "x1"]\noutputs = ["y"]\n[parameters]\na01 = 1.0\na21 = 2.0\n'
                     'a12 = 3.0\n[dynamics]\nx0 = "-(a01 + a21)*x0 + a12*x1"\nx1 = "a21*x0 - a12*x1"\n[output]\ny = "x0"\n',
                     encoding="utf-8")
    assert main(["analyze", str(model), "--params", "all", "--params-only", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert sorted(d["identifiable_functions"]) == ["a01 + a12 + a21", "a01*a12"]
    assert d["identifiable_functions_field"] == "parameters" and d["identifiable_functions_detail"]["with_states"] is False
    assert main(["analyze", str(model), "--params", "all", "--identifiable-functions"]) == 0
    text = capsys.readouterr().out
    assert "identifiable functions of states and parameters" in text and "x0" in text.split("simplest first):")[1]
    assert main(["analyze", str(model), "--params", "all", "--params-only"]) == 0
    assert "identifiable functions of the parameters (generators, simplest first): a01*a12, a01 + a12 + a21" in \
        capsys.readouterr().out


# -- non-rational models (issue 38 §2): rewritten for the search, the generators written back in the user's names -----

@pytest.mark.parametrize("f, expected", [
    # the issue's example: y = x, y' = -a e^b y + c u determines a e^b and c, nothing else of (a, b, c)
    ("-a*exp(b)*x + c*u", {"a*exp(b)", "c"}),
    # y' = -sqrt(k) y: sqrt(k) (and so k) is determined
    ("-sqrt(k)*x + 0*u", {"sqrt(k)"}),
    # y' = -a y + b sin(c) + u: a and b sin(c); b and c only through it
    ("-a*x + b*sin(c) + u", {"a", "b*sin(c)"}),
])
def test_non_rational_models_give_the_hand_derived_parameter_fields(f, expected):
    params = {k: v for k, v in {"a": 1.0, "b": 0.5, "c": 2.0, "k": 2.0}.items() if k in f}
    s = System(states=["x"], f=[f], inputs=["u"], outputs=["y"], h=["x"], params=params)
    r = find_identifiable_functions(s, unknown_params="all", with_states=False)
    assert not r.refused and set(r.functions) == expected and r.complete is True
    assert all(r.local_checks) and any("as a new parameter" in n for n in r.notes)


def test_a_function_of_a_state_gives_identifiable_generators_and_no_false_completeness():
    # x' = -a exp(x), y = x: a IS identifiable (a = -y'/exp(y)); the rewritten model with z = exp(x) and a free z(0)
    # finds only a*exp(x): sound (checked locally on the original model), and completeness is said to be undecided
    s = System(states=["x"], f=["-a*exp(x)"], outputs=["y"], h=["x"], params={"a": 1.0})
    r = find_identifiable_functions(s, unknown_params="all", with_states=True)
    assert set(r.functions) == {"x", "a*exp(x)"} and all(r.local_checks)
    assert r.complete is None and any("completeness not decided" in n for n in r.notes)
    assert "not identifiable" not in " ".join(r.describe())


def test_a_function_mixing_a_parameter_and_the_sine_of_another_is_checked_against_the_same_angle():
    # the local check of b*sin(c) once used a second random point of the circle for the function's sin(c) (a run of
    # its own) and found it not observable although y' = -a y + b sin(c) measures it
    from nlobs.analysis import observable_function

    s = System(states=["x"], f=["-a*x + b*sin(c)"], outputs=["y"], h=["x"], params={"a": 1.0, "b": 0.5, "c": 0.3})
    assert observable_function(s, "b*sin(c)", unknown_params="all").observable
    assert not observable_function(s, "sin(c)", unknown_params="all").observable


# -- a large fibre on fewer coefficients (issue 46: EAIHRD's 362,211 terms) ------------------------------------------

@needs_engine
def test_fewer_coefficients_give_the_published_field(monkeypatch):
    # Goodwin's oscillator (SI.jl test/bodies/identifiable_functions.jl: sigma, delta + beta, c, b, delta*beta, of the
    # parameters), with the size threshold at 0 so that the small model takes the path of the large ones
    from published_models import BY_NAME

    monkeypatch.setattr(I, "_FEWER_ABOVE", 0)
    m = BY_NAME["goodwin_funcs"]
    r = find_identifiable_functions(m.system(), with_states=False, route="io", engine=ENGINE)
    note = [n for n in r.notes if n.startswith("the fibre on ")]
    assert note and "of the 89 coefficients" in note[0], r.notes
    assert r.complete is True and all(r.local_checks)
    assert _same_field(list(r.functions), list(m.ident), list(m.params)), r.functions


@needs_engine
def test_fewer_coefficients_generate_every_coefficient(monkeypatch):
    # the kept coefficients generate the field of all 89 (what the completeness checks rely on), checked
    # independently: every coefficient ratio is constant on the fibre of the kept ones through a rational point (a
    # Gröbner basis over QQ in SymPy). The smallest coefficients that reach the rank (5 of them) do not: 58 ratios
    # lie outside their field, and only the rounds that add coefficients make the set generate it
    import sympy as sp
    from published_models import BY_NAME

    monkeypatch.setattr(I, "_FEWER_ABOVE", 0)
    eng = get_engine(ENGINE)
    prep = _prepare_io(BY_NAME["goodwin_funcs"].system(), unknown_params="all", seed=0, eng=eng)
    every = list(prep.io[0].params)
    I._fewer_generators(prep, eng, np.random.default_rng([0, 46]), [])
    kept = list(prep.io[0].params)
    assert len(kept) < len(every) == 89
    names = every[0][0].context().names()
    X = sp.symbols(names)
    loc = dict(zip(names, X))
    pt = {x: sp.Rational(3 + 2 * i, 5 + 3 * i) for i, x in enumerate(X)}
    z = sp.Symbol("z_")

    def relation(a, b):
        A, B = sp.sympify(str(a), locals=loc), sp.sympify(str(b), locals=loc)
        return sp.expand(A * B.subs(pt) - A.subs(pt) * B), B

    eqs, den = [], sp.Integer(1)
    for a, b in kept:
        rel, B = relation(a, b)
        eqs.append(rel)
        den *= B
    G = sp.groebner([*eqs, sp.expand(z * den - 1)], z, *X, order="grevlex")
    outside = [k for k, (a, b) in enumerate(every) if G.reduce(relation(a, b)[0])[1] != 0]
    assert not outside, (len(outside), len(kept))
