"""The generic-rank engine against independent computations: GF(p) ranks, jets from Lie derivatives."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import sympy as sp
from sympy.polys.domains import GF
from sympy.polys.matrices import DomainMatrix

from nlobs import System
from nlobs.analysis import analyze
from nlobs.analysis.structural._inputs import _input_classes
from nlobs.analysis.structural._lie import _leaf_coefficients, _setup
from nlobs.algebra._modular import RowEchelon, random_prime
from nlobs.algebra._series import AffineJets, ModField, SeriesRun, affine_structure
from nlobs.model import symbol

P = 134217689  # a prime below 2**27


def _rank_gf(rows: np.ndarray, p: int) -> int:
    return DomainMatrix([[GF(p)(int(v)) for v in r] for r in rows], rows.shape, GF(p)).rank()


@pytest.mark.parametrize("seed", range(4))
def test_row_echelon_rank_and_kernel_match_an_independent_gf_p_computation(seed):
    rng = np.random.default_rng(seed)
    n, r = 9, 5
    basis = rng.integers(0, P, size=(r, n))
    mix = rng.integers(0, P, size=(12, r))
    rows = np.array([[sum(int(m) * int(b) for m, b in zip(mr, col)) % P for col in basis.T] for mr in mix], dtype=np.int64)
    ech = RowEchelon(n, P)
    for row in rows:
        ech.add(row)
    assert ech.rank == _rank_gf(rows, P) == r
    K = ech.kernel()
    assert K.shape == (n - r, n)
    assert not np.any((rows.astype(object) @ K.T.astype(object)) % P)
    assert ech.contains(rows[3]) and ech.contains((rows[1] + 5 * rows[7]) % P)
    free = next(j for j in range(n) if j not in ech.pivots)
    assert not ech.contains(np.eye(n, dtype=np.int64)[free])  # zero on every pivot column, so not in the row space


@pytest.mark.parametrize("seed", range(10))
def test_row_echelon_add_many_is_add_row_by_row(seed):
    # the identifiable-function search adds its constraints in blocks (issue 23): same pivots, same basis, same
    # kernel as one row at a time, with rows already in the space, zero rows, and a full rank reached midway;
    # blocks of FLINT_BATCH rows or more, in FLINT_COLUMNS columns or more, go to FLINT's rref (the same rows, in pivot
    # order)
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 14)) if seed < 5 else int(rng.integers(48, 80))  # FLINT from 48 columns (FLINT_COLUMNS)
    r = int(rng.integers(1, n + 1))
    rows = (rng.integers(0, 4, size=(int(rng.integers(1, 30 if seed < 5 else 90)), r))
            @ rng.integers(0, 4, size=(r, n))) % P
    rows[rng.random(rows.shape[0]) < 0.2] = 0
    start = rng.integers(0, P, size=(int(rng.integers(0, 3)), n))
    one, many = RowEchelon(n, P), RowEchelon(n, P)
    for row in start:
        one.add(row)
        many.add(row)
    for row in rows:
        one.add(row)
    before = many.rank
    assert many.add_many(rows) == many.rank - before
    assert sorted(many.pivots) == sorted(one.pivots)
    order_many, order_one = np.argsort(many.pivots), np.argsort(one.pivots)
    assert np.array_equal(many.basis[order_many], one.basis[order_one])
    assert np.array_equal(many.kernel(), one.kernel())
    probe = rng.integers(0, P, size=(5, n))
    assert np.array_equal(many.reduce_many(probe), np.array([one.reduce(v) for v in probe]))


def _jets_by_lie_derivatives(system: System, unknown: list[str], point: dict, K: int, p: int) -> np.ndarray:
    """Rows ∂y_k/∂(x0, θ) with y_k = L_f^k h / k!, by SymPy, evaluated modulo p (no power series)."""
    x = list(system.x)
    th = [symbol(k) for k in unknown]
    known = {symbol(k): sp.Rational(v) for k, v in system.params.items() if k not in unknown}
    f = [e.xreplace(known) for e in system.f]
    L = [e.xreplace(known) for e in system.h]
    rows = []
    for k in range(K):
        for e in L:
            grad = [sp.diff(e, v) / sp.factorial(k) for v in (*x, *th)]
            vals = [sp.Rational(g.xreplace(point)) for g in grad]
            rows.append([int(v.p) * pow(int(v.q), -1, p) % p for v in vals])
        L = [sum(sp.diff(e, xi) * fi for xi, fi in zip(x, f)) for e in L]
    return np.array(rows, dtype=np.int64)


def _series_rows(system: System, unknown: list[str], K: int, seed: int = 3):
    st = _setup(system, tuple(unknown), _input_classes(system, "generic", {}), {}, [])
    rng = np.random.default_rng(seed)
    F = ModField(P)
    x0, coef = _leaf_coefficients(st, system, F, rng, K, None, True)
    run = SeriesRun(st.prog, F, len(st.unknowns), x0, [st.node_of[s] for s in system.states], coef, rng, keep=st.prog.h)
    rows = []
    for k in range(K):
        run.step()
        rows += [run.row(hj, k)[1:] for hj in st.prog.h]
    point = {**{s: sp.Integer(v) for s, v in zip(system.x, x0)},
             **{symbol(k): sp.Integer(coef[st.node_of[k]](0)[0]) for k in unknown}}
    return np.array(rows), point, st


def test_series_gradients_equal_lie_derivative_jets_exactly():
    """A nonlinear autonomous model with a product, a square, a division and an unknown parameter."""
    s = System(states=["x1", "x2", "x3"], f=["x2 - k*x1**2", "x3*x1 + 2", "-x3/(1 + x1**2)"], outputs=["y"],
               h=["x1 + x3**2"], params={"k": 0.7})
    rows, point, _ = _series_rows(s, ["k"], K=5)
    ref = _jets_by_lie_derivatives(s, ["k"], point, 5, P)
    assert np.array_equal(rows % P, ref)


def test_a_broken_product_rule_is_caught():
    """The same comparison fails when the series' product drops a term (so the test above can fail)."""
    import nlobs.algebra._series as series

    s = System(states=["x1", "x2"], f=["x2", "-k*x1*x2"], outputs=["y"], h=["x1"], params={"k": 2.0})
    orig = series.SeriesRun._conv

    def broken(self, A, B):
        out = orig(self, A, B)
        if A.shape[0] > 1:
            out = orig(self, A[:-1], B[:-1])
        return out

    series.SeriesRun._conv = broken
    try:
        rows, point, _ = _series_rows(s, ["k"], K=5)
    finally:
        series.SeriesRun._conv = orig
    assert not np.array_equal(rows % P, _jets_by_lie_derivatives(s, ["k"], point, 5, P))


def test_affine_shortcut_gives_the_kalman_rows_and_the_same_verdicts():
    A = [[0, 1, 0, 0], [-2, -0.5, 1, 0], [0, 0, 0, 1], [0, 0, -3, 0]]
    s = System.lti(A, C=[[1, 0, 0, 0]])
    st = _setup(s, (), _input_classes(s, "generic", {}), {}, [])
    assert st.affine is not None
    jets = AffineJets(st.affine, ModField(P), 4, 0, st.prog.h)
    Am = sp.Matrix(A).applyfunc(sp.nsimplify)
    V = sp.Matrix([[1, 0, 0, 0]])
    for k in range(5):
        jets.step()
        ref = [int(sp.Rational(v).p) * pow(int(sp.Rational(v).q), -1, P) % P for v in V]
        assert list(jets.row(st.prog.h[0], k)[1:]) == ref
        V = V * Am
    # observable LTI, and the same system with a zero coupling (x3, x4 never reach y)
    assert analyze(s).observable
    cut = System.lti([[0, 1, 0, 0], [-2, -0.5, 0, 0], [0, 0, 0, 1], [0, 0, -3, 0]], C=[[1, 0, 0, 0]])
    rep = analyze(cut)
    assert rep.rank == 2 and rep.observable_states == ("x1", "x2")


def test_affine_structure_refuses_what_is_not_affine_with_constant_coefficients():
    x1, x2, th, u = symbol("x1"), symbol("x2"), symbol("th"), symbol("u")
    assert affine_structure([x2, -x1 + u], [x1], [x1, x2], []) is not None
    assert affine_structure([x2, -x1 * x2], [x1], [x1, x2], []) is None  # product of states
    assert affine_structure([x2, -th * x1], [x1], [x1, x2], [th]) is None  # parameter times state
    assert affine_structure([u * x2, -x1], [x1], [x1, x2], []) is None  # input-dependent coefficient
    assert affine_structure([2 * (x1 + x2), -x1], [x1], [x1, x2], []) is not None  # not expanded


def test_sign_symmetries_beyond_the_exhaustive_search():
    """15 unknowns (above the exhaustive limit of 12): flipping x14 and x15 together leaves the model invariant
    (x14' = x15 and x15' = -x14 - x14³ are odd, x13 sees the even product x14·x15); no single flip does."""
    n = 15
    f = [f"x{i + 1} - x{i}" for i in range(1, n - 2)] + [f"-x{n - 2} + x{n - 1}*x{n}", f"x{n}", f"-x{n - 1} - x{n - 1}**3"]
    s = System(states=[f"x{i}" for i in range(1, n + 1)], f=f, outputs=["y"], h=["x1"])
    rep = analyze(s)
    assert rep.observable
    assert [sym.flipped for sym in rep.symmetries] == [("x14", "x15")]
    assert "one or two unknowns" in rep.symmetry_search


def test_a_400_state_chain_needs_little_memory():
    """SPEC P4: memory grows like nodes × unknowns, not nodes × orders × unknowns (it was 1.3 GB here)."""
    code = textwrap.dedent("""
        import json, resource, sys
        from nlobs import System, analyze
        n = 400
        s = System(states=[f"x{i}" for i in range(1, n + 1)], f=[f"x{i + 1} - k*x{i}" for i in range(1, n)] + [f"-x{n}"],
                   outputs=["y"], h=["x1"], params={"k": 0.5})
        rep = analyze(s, unknown_params=["k"])
        # VmHWM is this process's own peak; ru_maxrss keeps the parent's peak across fork + exec (the test process's)
        hwm = [int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:")]
        print(json.dumps({"rank": rep.rank, "maxrss": hwm[0] if hwm else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}))
    """)
    out = json.loads(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)
    assert out["rank"] == 401
    assert out["maxrss"] < 400_000  # kB


def test_affine_shortcut_with_an_additive_parameter_matches_the_lie_derivatives():
    s = System(states=["x1", "x2", "x3"], f=["x2", "-x1 + 2*x3 + th", "-x3 + 3*th"], outputs=["y"], h=["x1"], params={"th": 1.0})
    st = _setup(s, ("th",), _input_classes(s, "generic", {}), {}, [])
    assert st.affine is not None
    jets = AffineJets(st.affine, ModField(P), 3, 1, st.prog.h)
    point = {symbol("x1"): 3, symbol("x2"): 5, symbol("x3"): 7, symbol("th"): 11}  # rows do not depend on it
    ref = _jets_by_lie_derivatives(s, ["th"], point, 6, P)
    for k in range(6):
        jets.step()
        fact = int(sp.factorial(k)) % P
        assert list(jets.row(st.prog.h[0], k)[1:]) == list(ref[k] * fact % P)
    rep = analyze(s, unknown_params=["th"])
    assert rep.observable and rep.identifiable_params == ("th",)


@pytest.mark.parametrize("seed", range(6))
def test_kernel_mod_p_by_flint_equals_row_echelon_kernel(seed):
    # the reparametrisation's kernels come from FLINT's rref (issue 23); the same basis as RowEchelon's, vector
    # for vector, and annihilated by the rows in exact integer arithmetic
    from nlobs.algebra._modular import kernel_mod_p

    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 16))
    r = int(rng.integers(0, n + 1))
    rows = (rng.integers(0, P, size=(int(rng.integers(1, 24)), max(r, 1))) @ rng.integers(0, 3, size=(max(r, 1), n))) % P
    rows[:, rng.random(n) < 0.2] = 0  # zero columns: free, with a unit kernel vector
    ech = RowEchelon(n, P)
    ech.add_many(rows.astype(np.int64))
    K = kernel_mod_p(list(rows), n, P)
    assert np.array_equal(K, ech.kernel())
    assert not np.any((rows.astype(object) @ K.T.astype(object)) % P)
    assert K.shape[0] == n - _rank_gf(rows, P)


def test_monomial_values_and_gradients_against_sympy():
    from nlobs.algebra._modular import monomial_values

    E = np.array([[0, 0, 0], [2, 1, 0], [0, 3, 1], [1, 1, 1]], dtype=np.int64)
    x = sp.symbols("a b c")
    for vals in ([5, 7, 11], [0, 3, 2], [4, 0, 9]):  # a zero value takes the other branch of the gradient
        mv, mg = monomial_values(E, vals, P)
        for k, e in enumerate(E):
            m = sp.Mul(*[xi**int(ei) for xi, ei in zip(x, e)])
            at = dict(zip(x, vals))
            assert int(m.subs(at)) % P == mv[k]
            assert [int(sp.diff(m, xi).subs(at)) % P for xi in x] == list(mg[k])


@pytest.mark.parametrize("p,shape", [(P, (4, 12000, 30)), (P, (30, 300, 200)), (P, (3, 4, 5)),
                                     (2_147_483_647, (6, 50, 9)), (2_147_483_629, (2, 3, 2))])
def test_matmul_mod_is_exact_against_python_integers(p, shape):
    # the large products go through BLAS in doubles (14-bit halves, chunks of 4096 terms: every partial sum below
    # 2^53); the worst case puts p - 1 everywhere in the first columns. Primes above 2^27 (tests use 2^31 - 1) take
    # the integer path in chunks that cannot overflow (a single product of two values reaches 2^62). Reference: exact
    # Python integers
    from nlobs.algebra._modular import matmul_mod

    m, r, n = shape
    rng = np.random.default_rng(r)
    C, B = rng.integers(0, p, size=(m, r)), rng.integers(0, p, size=(r, n))
    C[:, : r // 2 + 1], B[: r // 2 + 1] = p - 1, p - 1
    want = (C.astype(object) @ B.astype(object)) % p
    assert np.array_equal(matmul_mod(C, B, p).astype(object), want)
