"""Identifiable functions of models with roots (issue 46): the root solved into the model as a new unknown with its
polynomial tie (analysis/structural/_identifiable_rewrite.py, step 0), the generators written back.

The reference fields are derived by hand in each test, on the real branch the models mean (arguments of the roots
positive, principal roots). Two independent checks, both in SymPy, neither using nlobs's algebra:

- *rank*: the Jacobians of the returned functions, of the hand-derived generators and of both together have the same
  rank at random rational points (exact SymPy ranks; the states under a root are squares of rationals there, so the
  roots stay rational). Equal ranks show that each set is algebraic over the field of the other: the same
  transcendence degree, the same algebraic closure. They do not separate k/A from (k/A)^2 (a sign lost to the other
  branch of the root);
- *field*: that is what ``_same_field`` of test_global does (each set constant on the fibre of the other through a
  rational point, over QQ): on the parameters alone, and with the states after writing the root in as a variable
  (h = w^2, sqrt(h) = w).
"""

from __future__ import annotations

import random

import pytest
import sympy as sp
from test_global import _same_field, needs_engine

from nlobs import System
from nlobs.analysis import find_identifiable_functions


def _jacobian_rank(funcs: list[sp.Expr], X: list[sp.Symbol], point: dict[sp.Symbol, sp.Rational]) -> int:
    J = sp.Matrix([[sp.diff(f, x) for x in X] for f in funcs]).subs(point)
    return J.rank(simplify=True)


def _same_rank(returned: list[str], known: list[str], names: list[str], squares: tuple[str, ...] = (),
               points: int = 3) -> tuple[int, int, int]:
    """Rank of [returned], [known], [both] (the first point where they differ, else the last); states in `squares` are
    drawn as squares of random rationals (their roots stay rational)."""
    X = [sp.Symbol(n, positive=True) for n in names]
    loc = dict(zip(names, X))
    A = [sp.sympify(e, locals=loc) for e in returned]
    B = [sp.sympify(e, locals=loc) for e in known]
    rng = random.Random(46)
    for _ in range(points):
        pt = {}
        for n, x in zip(names, X):
            r = sp.Rational(rng.randint(1, 40), rng.randint(1, 40))
            pt[x] = r**2 if n in squares else r
        ranks = (_jacobian_rank(A, X, pt), _jacobian_rank(B, X, pt), _jacobian_rank(A + B, X, pt))
        if len(set(ranks)) > 1:
            return ranks
    return ranks


def _with_roots_as_variables(funcs: tuple[str, ...] | list[str], roots: dict[str, str]) -> list[str]:
    """The functions with each state under a root written as the square of a new variable (h -> w**2): sqrt(h) = w on
    the real branch, and the field comparison is over QQ again."""
    X = {n: sp.Symbol(n, positive=True) for n in roots}
    W = {w: sp.Symbol(w, positive=True) for w in roots.values()}
    out = []
    for e in funcs:
        ex = sp.sympify(e, locals={**X, **W})
        ex = ex.subs({X[n]: W[w]**2 for n, w in roots.items()})
        out.append(str(sp.simplify(ex)))
    return out


def _torricelli() -> System:
    # a tank filled by a pump (gain b) and drained by Torricelli's law through an outlet k, area A: the issue's model
    return System(states=["h"], f=["(b*u - k*sqrt(h))/A"], inputs=["u"], outputs=["y"], h=["h"],
                  params={"b": 1.0, "k": 0.5, "A": 2.0}, name="torricelli")


def _root_output() -> System:
    # two compartments, the first measured through a power 3/2 (a flow meter reading h^(3/2), say)
    return System(states=["x1", "x2"], f=["-a*x1 + x2", "-b*x2 + u"], inputs=["u"], outputs=["y"], h=["x1**(3/2)"],
                  params={"a": 1.0, "b": 2.0}, name="root_output")


def _cascade() -> System:
    # two Torricelli tanks in cascade, the lower one's level measured
    return System(states=["h1", "h2"], f=["(b*u - k1*sqrt(h1))/A1", "(k1*sqrt(h1) - k2*sqrt(h2))/A2"], inputs=["u"],
                  outputs=["y"], h=["h2"], params={"b": 1.0, "k1": 0.5, "k2": 0.4, "A1": 2.0, "A2": 1.5},
                  name="cascade")


# Hand-derived fields.
# Torricelli: y' = (b/A) u - (k/A) sqrt(y): b/A and k/A, and with the states y = h (so sqrt(h), on the real branch).
TORRICELLI = (["b/A", "k/A"], ["sqrt(h)", "b/A", "k/A"], ["b", "k", "A"], ["h"])
# Root in the output: y determines x1 = y^(2/3); x1' = x2 - a x1; x1'' = -(a + b) x1' - a b x1 + u: a + b and a b
# (a <-> b swaps with x2 -> x2 + (b - a) x1), and with the states x1 (so sqrt(x1)) and x2 - a x1.
ROOT_OUTPUT = (["a + b", "a*b"], ["sqrt(x1)", "a + b", "a*b", "x2 - a*x1"], ["a", "b"], ["x1", "x2"])
# Cascade: with z = k1 sqrt(h1)/A2, y' = z - (k2/A2) sqrt(y) and z z' = (b k1^2/(2 A1 A2^2)) u - (k1^2/(2 A1 A2)) z:
# the coefficients k2/A2, b k1^2/(A1 A2^2), k1^2/(A1 A2) generate the parameters' field, = Q(k2/A2, b/A2,
# k1^2/(A1 A2)) (the symmetries: every parameter times mu; h1 times lam with k1 / sqrt(lam), A1 / lam). With the
# states: sqrt(h2) and z. The root of h1 keeps its branch open (h1 is not identifiable): k1 -> -k1, sqrt(h1) ->
# -sqrt(h1) is a symmetry of the rewritten model, so completeness is not decided.
CASCADE = (["k2/A2", "b/A2", "k1**2/(A1*A2)"], ["sqrt(h2)", "k2/A2", "b/A2", "k1**2/(A1*A2)", "k1*sqrt(h1)/A2"],
           ["b", "k1", "k2", "A1", "A2"], ["h1", "h2"])
MODELS = {"torricelli": (_torricelli, TORRICELLI), "root_output": (_root_output, ROOT_OUTPUT),
          "cascade": (_cascade, CASCADE)}


@needs_engine
@pytest.mark.parametrize("name", list(MODELS))
def test_parameters_only_generate_the_hand_derived_field(name):
    make, (known, _, params, _) = MODELS[name]
    r = find_identifiable_functions(make(), with_states=False)
    assert not r.refused, r.refused
    assert all(r.local_checks) and r.functions
    ranks = _same_rank(list(r.functions), known, params)
    assert ranks[0] == ranks[1] == ranks[2], (r.functions, ranks)
    # the exact field, which the ranks cannot tell from (k/A)^2: the branch of the root fixed by the output
    assert _same_field(list(r.functions), known, params), r.functions
    assert r.complete is (None if name == "cascade" else True), r.notes
    assert any("roots solved into the model" in n for n in r.notes)


@needs_engine
@pytest.mark.parametrize("name", list(MODELS))
def test_with_the_states_generate_the_hand_derived_field(name):
    make, (_, known, params, states) = MODELS[name]
    r = find_identifiable_functions(make(), with_states=True)
    assert not r.refused, r.refused
    assert all(r.local_checks) and r.functions
    names = [*states, *params]
    ranks = _same_rank(list(r.functions), known, names, squares=tuple(states))
    assert ranks[0] == ranks[1] == ranks[2], (r.functions, ranks)
    roots = {x: f"w_{x}" for x in states}
    assert _same_field(_with_roots_as_variables(r.functions, roots), _with_roots_as_variables(known, roots),
                       [*roots.values(), *[x for x in states if x not in roots], *params]), r.functions
    if name == "cascade":
        assert r.complete is None and any("branch NOT fixed" in n for n in r.notes)
        assert "not identifiable" not in " ".join(r.describe())
    else:
        assert r.complete is True


def test_the_rank_check_itself_can_fail():
    # the independent check: k/A alone does not reach b/A (rank 1 against 2, and 2 together)
    assert _same_rank(["k/A"], ["b/A", "k/A"], ["b", "k", "A"]) == (1, 2, 2)
    # and the ranks do not see a square: what the field check is there for
    assert _same_rank(["b/A", "k**2/A**2"], ["b/A", "k/A"], ["b", "k", "A"]) == (2, 2, 2)
    assert not _same_field(["b/A", "k**2/A**2"], ["b/A", "k/A"], ["b", "k", "A"])


@needs_engine
def test_the_issue_example_in_words():
    r = find_identifiable_functions(_torricelli(), with_states=False)
    text = "\n".join(r.describe())
    assert "identifiable functions of the parameters" in text and "(checked)" in text
    assert "sqrt(h) as a new state r1 (h = r1**2)" in text and "branch fixed: the output y = h determines it" in text


@needs_engine
def test_a_root_of_a_parameter_used_elsewhere_is_solved_not_left_free():
    # y' = -k y + sqrt(k) u: k and sqrt(k) are one unknown (k = q^2); before, q and k were searched as independent and
    # completeness was undecided. y' determines k and sqrt(k) (the coefficients of y and u)
    s = System(states=["x"], f=["-k*x + sqrt(k)*u"], inputs=["u"], outputs=["y"], h=["x"], params={"k": 2.0})
    r = find_identifiable_functions(s, with_states=False)
    assert not r.refused and r.complete is True and all(r.local_checks)
    assert _same_rank(list(r.functions), ["k"], ["k"]) == (1, 1, 1)
    assert r.functions == ("sqrt(k)",)


@needs_engine
def test_a_number_under_the_root_and_a_root_that_cannot_be_solved():
    # Torricelli's law as written from physics, k*sqrt(2*g*h) with g = 9.81: SymPy splits off sqrt(19.62), a number
    tank = System(states=["h"], f=["(b*u - k*sqrt(2*9.81*h))/A"], inputs=["u"], outputs=["y"], h=["h"],
                  params={"b": 1.0, "k": 0.5, "A": 2.0})
    r = find_identifiable_functions(tank, with_states=False)
    assert not r.refused and r.complete is True
    assert _same_field(list(r.functions), ["b/A", "k/A"], ["b", "k", "A"]), r.functions
    # w^2 = x^2 + 1 is linear in no unknown: refused, saying so, with the local verdicts standing
    s = System(states=["x"], f=["-a*sqrt(x**2 + 1) + u"], inputs=["u"], outputs=["y"], h=["x"], params={"a": 1.0})
    r = find_identifiable_functions(s, with_states=False)
    assert "sqrt(x**2 + 1)" in r.refused and "linear in no unknown" in r.refused and "local verdicts stand" in r.refused


@needs_engine
def test_branches_pinned_by_the_global_check():
    # y = h + 1 is no power of the root, but determines h: the global check finds r1**2 (= h) globally identifiable
    # and the branch is pinned; without it only (k/A)^2 would come back
    tank = System(states=["h"], f=["(b*u - k*sqrt(h))/A"], inputs=["u"], outputs=["y"], h=["h + 1"],
                  params={"b": 1.0, "k": 0.5, "A": 2.0})
    r = find_identifiable_functions(tank, with_states=False)
    assert r.complete is True and _same_field(list(r.functions), ["b/A", "k/A"], ["b", "k", "A"]), r.functions
    assert any("branch fixed: its argument is globally identifiable" in n for n in r.notes)
    # a root of a parameter: y' = -k y + sqrt(k) z + u, z' = 0 gives k (y'' = -k y' ...) and sqrt(k) z; over the
    # complex numbers (sqrt(k), z) -> (-sqrt(k), -z) keeps them, on the real branch sqrt(k) > 0 and z is determined
    s = System(states=["x", "z"], f=["-k*x + sqrt(k)*z + u", "0"], inputs=["u"], outputs=["y"], h=["x"],
               params={"k": 2.0})
    r = find_identifiable_functions(s, with_states=True)
    assert r.complete is True and all(r.local_checks)
    assert _same_rank(list(r.functions), ["x", "z", "k"], ["x", "z", "k"]) == (3, 3, 3)
    w = {"k": "w_k"}
    assert _same_field(_with_roots_as_variables(r.functions, w), _with_roots_as_variables(["x", "z", "sqrt(k)"], w),
                       ["x", "z", "w_k"]), r.functions
