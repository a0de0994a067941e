r"""Structural observability: the generic rank of the observation space (Besançon (2010)), computed fast.

The observation space :math:`\mathcal O(h)` of Besançon (2010) is the smallest vector space of functions that
contains the outputs and is closed under Lie derivation along :math:`f_u = f(\cdot, u)` for
every constant u; the observability rank condition is :math:`\dim d\mathcal O(h)|_x = n`. Its
generic value equals the rank of the Jacobian, with respect to the unknowns, of the output's
successive time derivatives for a generic input (the derivatives of the input enter as free
values). That Jacobian is not built symbolically: the solution is expanded as a truncated power
series at a random point of GF(p), with gradients carried along (Sedoglavic (2002)), and the rank is
taken over GF(p).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from ...errors import ModelError
from ...algebra._identity import decide_identity
from ...model import TIME, System, symbol
from ...model._budget import symbolic_budget
from ...model._translate import NUMPY, translate
from ...model._system import ExprLike, exact
from ...algebra._modular import RowEchelon, random_prime
from .._reports import FunctionCheck, ObservabilityReport, Symmetry
from ._inputs import InputClass, _input_classes, _parse_functions, _unknown_params, require_system
from ...algebra._series import AffineJets, FloatField, ModField, Node, Program, Resample, SeriesRun, affine_structure, build_program
from ...references import cite

__all__ = ["local_analysis", "observable_function"]

_REF = f"{cite('002')} (observation space, rank condition); {cite('sedoglavic2002')}"


@dataclass
class _Setup:
    prog: Program
    unknowns: tuple[str, ...]
    n: int
    q: int
    classes: dict[str, InputClass]
    unknown_inputs: dict[str, int]
    node_of: dict[str, int]
    param_values: dict[str, float]
    affine: Any = None  # (A, B, C, D) when f and h are affine in the unknowns with constant coefficients


def _setup(system: System, params_unknown: tuple[str, ...], classes: dict[str, InputClass],
           unknown_inputs: dict[str, int], functions: list[tuple[str, sp.Expr]],
           regime: Callable[[sp.Expr], float] | None = None) -> _Setup:
    known = {symbol(k): exact(v) for k, v in system.params.items() if k not in params_unknown}
    signals = {symbol(k): c.expr for k, c in classes.items() if c.kind == "signal"}
    f = [e.xreplace(known).xreplace(signals) for e in system.f]
    h = [e.xreplace(known).xreplace(signals) for e in system.h]
    extra = [e.xreplace(known) for _, e in functions]
    leaves: dict[sp.Symbol, Node] = {}
    for i, s in enumerate(system.x):
        leaves[s] = Node("x", data=i)
    for j, k in enumerate(params_unknown):
        leaves[symbol(k)] = Node("theta", data=j)
    for i, k in enumerate(system.inputs):
        if k in unknown_inputs:
            leaves[symbol(k)] = Node("w", data=i)
        elif classes[k].kind != "signal":
            leaves[symbol(k)] = Node("u", data=i)
    leaves[TIME] = Node("t")
    prog = build_program(f, h, leaves, extra, regime)
    coeffs = tuple(f"{k}_{d}" for k, deg in unknown_inputs.items() for d in range(deg + 1))
    node_of = {s.name: i for i, s in enumerate(leaves)}  # the builder pushes the leaves first, in this order
    unknowns = (*system.states, *params_unknown, *coeffs)
    affine = None if unknown_inputs else affine_structure(f, h, system.x, [symbol(k) for k in params_unknown])
    return _Setup(prog, unknowns, system.n_states, len(params_unknown), classes, unknown_inputs, node_of,
                  dict(system.params), affine)


def _jets(st: _Setup, system: System, field: Any, rng: np.random.Generator, N: int, x0: Any, coef: Any,
          keep: Sequence[int]) -> Any:
    """The run that produces the output jets' gradient rows: the affine shortcut or the power series."""
    if st.affine is not None:
        return AffineJets(st.affine, field, st.n, st.q, st.prog.h)
    M = len(st.unknowns)
    support = {st.node_of[k]: c.degree + 1 for k, c in st.classes.items() if c.kind == "polynomial"}
    support.update({st.node_of[k]: d + 1 for k, d in st.unknown_inputs.items()})
    return SeriesRun(st.prog, field, M, x0, [st.node_of[s] for s in system.states], coef, rng, keep=keep,
                     leaf_support=support)


def _leaf_coefficients(st: _Setup, system: System, field: Any, rng: np.random.Generator, N: int,
                       values: Mapping[str, float] | None, exact_field: bool) -> tuple[list[Any], dict[int, Any]]:
    """Initial state values and the coefficient functions of the other leaves."""
    p = getattr(field, "p", None)

    def draw(real_default: float | None = None) -> Any:
        if exact_field:   # a power of a random element: monomial radicands are squares (Program.square_power)
            return pow(int(rng.integers(1, p)), st.prog.square_power, p)
        return float(real_default) if real_default is not None else float(rng.uniform(0.5, 1.5))

    values = values or {}
    x0 = [draw(values.get(s)) for s in system.states]
    coef: dict[int, Any] = {}
    for i, s in enumerate(system.states):
        coef[st.node_of[s]] = i
    for j, k in enumerate(st.unknowns[st.n: st.n + st.q]):
        pv = values.get(k, st.param_values[k] if st.param_values[k] != 0 else None)
        val = draw(pv)
        col = st.n + j
        coef[st.node_of[k]] = (lambda kk, v=val, c=col: (v, c, 1) if kk == 0 else (0, -1, 0))
    col = st.n + st.q
    for name, deg in st.unknown_inputs.items():
        vals = [draw() for _ in range(deg + 1)]
        cols = list(range(col, col + deg + 1))
        col += deg + 1
        coef[st.node_of[name]] = (lambda kk, v=vals, c=cols: (v[kk], c[kk], 1) if kk < len(v) else (0, -1, 0))
    for name, cls in st.classes.items():
        if cls.kind == "signal":
            continue
        deg = N + 1 if cls.kind == "generic" else cls.degree
        if exact_field:
            vals = [pow(int(rng.integers(1, p)), st.prog.square_power if k == 0 else 1, p) for k in range(deg + 1)]
        else:
            vals = [float(rng.uniform(-1, 1)) for _ in range(deg + 1)]
        coef[st.node_of[name]] = (lambda kk, v=vals: (v[kk], -1, 1) if kk < len(v) else (0, -1, 0))
    t0 = int(rng.integers(1, p)) if exact_field else 0.0
    coef[st.node_of["t"]] = lambda kk: (t0, -1, 1) if kk == 0 else ((1, -1, 0) if kk == 1 else (0, -1, 0))
    for i, nd in enumerate(st.prog.nodes):
        if nd.op == "const":
            c0 = field.num(nd.data)
            coef[i] = (lambda kk, c=c0: (c, -1, 0) if kk == 0 else (0, -1, 0))
        elif nd.op == "cfree":
            c0 = pow(int(rng.integers(1, p)), st.prog.square_power, p) if exact_field else nd.data
            coef[i] = (lambda kk, c=c0: (c, -1, 1) if kk == 0 else (0, -1, 0))
    return x0, coef


@dataclass
class _ModResult:
    rank: int
    ech: RowEchelon
    pivot_rows: list[tuple[int, int]]
    row_degrees: list[int]
    extra_degree: int
    prime: int
    function_rows: list[np.ndarray]
    max_order: int
    square_power: int = 1   # the leaves were drawn as this power of random elements (Program.square_power)


def _mod_run(st: _Setup, system: System, rng: np.random.Generator) -> _ModResult:
    M = len(st.unknowns)
    N = M  # derivative orders 0..M suffice: the jet ranks increase strictly until they stabilise
    for _ in range(20):
        p = random_prime(rng, st.prog.roots)
        F = ModField(p)
        try:
            x0, coef = _leaf_coefficients(st, system, F, rng, N, None, True)
            run = _jets(st, system, F, rng, N, x0, coef, [*st.prog.h, *st.prog.extra])
            frows: list[np.ndarray] | None = []
            if st.prog.extra and isinstance(run, SeriesRun):
                # the functions' rows from the jets' own run, after its first step: the same values of the auxiliary
                # series (exp, log, atan: free generic values; sin/cos: a random point of the circle) as the jets. A
                # second run would draw others, and a function such as b*sin(c) would be checked against the jets
                # of another angle (found not observable where it is)
                frows = None
            elif st.prog.extra:   # the affine shortcut has no auxiliary series: the functions' own are consistent
                extra_run = SeriesRun(st.prog, F, M, x0, [st.node_of[s] for s in system.states], coef, rng, keep=st.prog.extra)
                extra_run.step()
                frows = [extra_run.row(e, 0)[1:].copy() for e in st.prog.extra]
            ech = RowEchelon(M, p)
            pivots: list[tuple[int, int]] = []
            degrees: list[int] = []
            for k in range(N + 1):
                run.step()
                if frows is None:
                    frows = [run.row(e, 0)[1:].copy() for e in st.prog.extra]
                for j, hj in enumerate(st.prog.h):
                    degrees.append(run.degree(hj, k))
                    if ech.add(run.row(hj, k)[1:]):
                        pivots.append((j, k))
                if ech.rank == M:
                    break
            return _ModResult(ech.rank, ech, pivots, degrees, run.extra_degree, p, frows, k, st.prog.square_power)
        except Resample:
            continue
    raise ModelError(f"{system.name!r}: the generic-rank test hit a zero denominator at 20 random points; "
                     "the model's expressions may be undefined almost everywhere (check divisions and logarithms)")


def _float_kernel(st: _Setup, system: System, res: _ModResult, rng: np.random.Generator,
                  at: Mapping[str, float] | None) -> tuple[np.ndarray, np.ndarray, float, list[str]]:
    """Kernel directions at a real point, given the exact rank (no rank tolerance needed)."""
    M = len(st.unknowns)
    notes: list[str] = []
    if res.rank == M:
        return np.zeros((0, M)), _real_point(st, system, rng, at), float("inf"), notes
    if res.rank == 0:
        return np.eye(M), _real_point(st, system, rng, at), float("inf"), notes
    kmax = max(k for _, k in res.pivot_rows)
    for attempt in range(10):
        use_at = at if attempt == 0 else None
        F = FloatField()
        try:
            x0, coef = _leaf_coefficients(st, system, F, rng, kmax, use_at, False)
            run = _jets(st, system, F, rng, kmax, x0, coef, st.prog.h)
            for _ in range(kmax + 1):
                run.step()
        except Resample:
            continue
        J = np.array([run.row(st.prog.h[j], k)[1:] for j, k in res.pivot_rows], dtype=float)
        if not np.all(np.isfinite(J)):
            continue
        norms = np.linalg.norm(J, axis=1)
        if np.any(norms == 0):
            if use_at:
                notes.append("the given point is singular (an output derivative has zero gradient there); "
                             "directions are shown at a random point instead")
            continue
        J = J / norms[:, None]
        _, s, Vt = np.linalg.svd(J)
        gap = float(s[-1] / s[0]) if s.size else float("inf")
        if gap < 1e-10:
            if use_at:
                notes.append(f"at the given point the rank drops below {res.rank} (singular point); "
                             "directions are shown at a random point instead")
            continue
        point = np.array([*x0, *[coef[st.node_of[k]](0)[0] for k in st.unknowns[st.n: st.n + st.q]],
                          *_input_coefficient_values(st, coef)], dtype=float)
        return Vt[res.rank:], point, gap, notes
    notes.append("could not find a regular real point for the directions")
    return np.full((M - res.rank, M), np.nan), np.full(M, np.nan), 0.0, notes


def _input_coefficient_values(st: _Setup, coef: Mapping[int, Any]) -> list[float]:
    out = []
    for name, deg in st.unknown_inputs.items():
        out += [coef[st.node_of[name]](d)[0] for d in range(deg + 1)]
    return out


def _real_point(st: _Setup, system: System, rng: np.random.Generator, at: Mapping[str, float] | None) -> np.ndarray:
    x0, coef = _leaf_coefficients(st, system, FloatField(), rng, 0, at, False)
    return np.array([*x0, *[coef[st.node_of[k]](0)[0] for k in st.unknowns[st.n: st.n + st.q]],
                     *_input_coefficient_values(st, coef)], dtype=float)


def _sign_symmetries(system: System, st: _Setup, params_unknown: tuple[str, ...], rng: np.random.Generator,
                     budget: int = 4096, max_proofs: int = 64) -> tuple[tuple[Symmetry, ...], str]:
    """Sign changes of unknowns that leave the model invariant: f(σz) = σ f(z), h(σz) = h(z).

    Screened numerically at a random point, then decided exactly (:func:`decide_identity`). With at
    most 12 unknowns every sign pattern is screened (up to `budget`); beyond, the sign changes of one or two
    unknowns. Screening is sparse: an expression is evaluated only on the patterns that flip one
    of its variables (or its own state), since every other pattern leaves it unchanged, so the
    cost grows like m · Σ|vars of f_i|² rather than m² · (size of f). Each symmetry gives pairs of
    indistinguishable states (Viegas, Batista, Oliveira & Silvestre (2015), §IV-C: x2 -> -x2 when c = 0).
    """
    from ...model._translate import NUMPY, translate

    known = {symbol(k): exact(v) for k, v in system.params.items() if k not in params_unknown}
    f = [e.xreplace(known) for e in system.f]
    h = [e.xreplace(known) for e in system.h]
    syms = [*system.x, *[symbol(k) for k in params_unknown]]
    m = len(syms)
    index = {s: i for i, s in enumerate(syms)}
    exhaustive = m <= 12 and 2**m - 1 <= budget
    if exhaustive:
        patterns = np.array([[(1 - 2 * ((b >> i) & 1)) for i in range(m)] for b in range(1, 2**m)], dtype=float)
        searched = f"all {2**m - 1} sign changes of the unknowns were screened"
    else:
        pairs = [(i, j) for i in range(m) for j in range(i, m)]
        searched = f"the {len(pairs)} sign changes of one or two unknowns were screened"
    z = rng.uniform(0.5, 1.5, size=m)
    fixed: dict[sp.Symbol, float] = {s: float(rng.uniform(-1, 1)) for s in system.u}
    fixed[TIME] = float(rng.uniform(0, 1))
    exprs = [(e, i) for i, e in enumerate(f)] + [(e, None) for e in h]
    if exhaustive:
        ok = np.ones(patterns.shape[0], dtype=bool)
    else:
        failed = np.zeros((m, m), dtype=bool)  # failed[i, j] (i <= j): flipping unknowns i and j breaks an equation
    with np.errstate(all="ignore"):
        for e, own in exprs:
            deps = sorted(index[s] for s in e.free_symbols if s in index)
            touch = sorted(set(deps) | ({own} if own is not None else set()))
            if not touch:
                continue
            if exhaustive:
                cols = {i: patterns[:, i] for i in touch}
                P = patterns.shape[0]
            else:  # the patterns (a, b), a <= b, with a or b in `touch`
                js = np.arange(m)
                codes = np.unique(np.concatenate([np.minimum(t, js) * m + np.maximum(t, js) for t in touch]))
                lo, hi = codes // m, codes % m
                cols = {i: np.where((lo == i) | (hi == i), -1.0, 1.0) for i in touch}
                P = codes.size
            leaves: dict[sp.Symbol, Any] = {syms[i]: cols[i] * z[i] for i in deps}
            base: dict[sp.Symbol, Any] = {syms[i]: z[i] for i in deps}
            leaves.update(fixed)
            base.update(fixed)
            a = np.broadcast_to(np.asarray(translate(e, leaves, NUMPY), dtype=float), (P,))
            b = float(np.asarray(translate(e, base, NUMPY), dtype=float))
            bb = b * cols[own] if own is not None else np.full(P, b)
            good = np.isfinite(a) & np.isclose(a, bb, rtol=1e-9, atol=1e-12)
            if exhaustive:
                ok &= good
            else:
                failed[lo[~good], hi[~good]] = True
    if exhaustive:
        survivors: Any = sorted(patterns[ok], key=lambda r: int(np.sum(r < 0)))
        n_survivors = len(survivors)
    else:
        passed = np.triu(~failed)
        ii, jj = np.nonzero(passed)
        order = np.argsort(ii != jj, kind="stable")  # single flips first, then pairs
        n_survivors = int(ii.size)

        def pattern(k: int) -> np.ndarray:
            r = np.ones(m)
            r[ii[k]] = r[jj[k]] = -1
            return r

        survivors = (pattern(k) for k in order)
    found: list[np.ndarray] = []
    group: set[tuple[int, ...]] = set()
    proofs = 0
    for r in survivors:
        key = tuple(int(v) for v in r)
        if key in group:
            continue
        if proofs >= max_proofs:
            searched += (f"; further candidates passed the screening ({n_survivors} in all) but were not proved "
                         f"(limit {max_proofs})")
            break
        proofs += 1
        sub = {s: -s for s, v in zip(syms, r) if v < 0}
        flipped = set(sub)
        # only the equations that involve a flipped unknown, or whose own state flips, can change
        proved = all(decide_identity(e.xreplace(sub), sgn * e).holds for e, sgn in zip(f, r[: len(f)])
                     if sgn < 0 or e.free_symbols & flipped) and all(
            decide_identity(e.xreplace(sub), e).holds for e in h if e.free_symbols & flipped)
        if not proved:
            continue
        found.append(r)
        new = {key}
        for g in group:
            new.add(tuple(a * b for a, b in zip(g, key)))
        group |= new
    names = [s.name for s in syms]
    return tuple(Symmetry(tuple(n for n, v in zip(names, r) if v < 0)) for r in found), searched


def _regime_evaluator(system: System, regime: Mapping[str, float] | None,
                      classes: Mapping[str, InputClass]) -> Callable[[sp.Expr], float] | None:
    """A function evaluating an expression of the model at the regime point (None without one)."""
    if regime is None:
        return None
    if not isinstance(regime, Mapping):
        raise ModelError(f"`regime` must be a mapping {{name: value}} of the states (and optionally inputs, parameters, t), "
                         f"got {type(regime).__name__}")
    names = (*system.states, *system.inputs, *system.params, "t")
    bad = [k for k in regime if k not in names]
    if bad:
        raise ModelError(f"`regime` names {', '.join(map(repr, bad[:3]))}, not a state, input, parameter or t of {system.name!r}")
    missing = [k for k in system.states if k not in regime]
    if missing:
        raise ModelError(f"`regime` needs a value for every state (it is a point of the state space); missing: {', '.join(missing)}")
    values: dict[sp.Symbol, Any] = {symbol(k): float(v) for k, v in system.params.items()}
    values.update({symbol(k): 0.0 for k in system.inputs})
    values[TIME] = 0.0
    for k, v in regime.items():
        fv = float(v)
        if not np.isfinite(fv):
            raise ModelError(f"`regime[{k!r}]` must be finite, got {v!r}")
        values[TIME if k == "t" else symbol(k)] = fv

    def evaluate(e: sp.Expr) -> float:
        with np.errstate(all="ignore"):
            v = float(np.asarray(translate(e, values, NUMPY), dtype=float))
        if not np.isfinite(v):
            raise ModelError(f"`regime`: the expression {e} is not finite at the regime point {dict(regime)}; choose another point")
        return v

    return evaluate


def local_analysis(system: System, *, unknown_params: Any = (), inputs: Any = "generic",
                   unknown_inputs: Mapping[str, int] | None = None, functions: Sequence[ExprLike] = (),
                   at: Mapping[str, float] | None = None, symmetries: bool = True, seed: int = 0,
                   regime: Mapping[str, float] | None = None, directions: bool = True) -> ObservabilityReport:
    """The local route of :func:`nlobs.analyze` (generic rank of the output jets; see its documentation for the
    arguments): what the global routes build on, without their parts. `directions` False leaves out the real-valued
    kernel directions (``unobservable_directions`` then has no rows; the global routes do not use them)."""
    require_system(system, "analyze")
    with symbolic_budget(f"analyze {system.name!r}"):
        return _analyze(system, unknown_params, inputs, unknown_inputs, functions, at, symmetries, seed, regime,
                        directions=directions)


def function_checks(system: System, functions: Sequence[ExprLike], *, unknown_params: Any = (),
                    inputs: Any = "generic", unknown_inputs: Mapping[str, int] | None = None,
                    at: Mapping[str, float] | None = None, seed: int = 0,
                    regime: Mapping[str, float] | None = None) -> tuple[FunctionCheck, ...]:
    """The local check of each of `functions` (as :func:`local_analysis` makes it), without the real-valued kernel
    directions that only the report shows (most of the time of a small model's analysis); `at` is accepted as there
    and checked, but only those directions use it."""
    with symbolic_budget(f"analyze {system.name!r}"):
        return _analyze(system, unknown_params, inputs, unknown_inputs, functions, at, False, seed, regime,
                        directions=False).functions


def _analyze(system: System, unknown_params: Any, inputs: Any, unknown_inputs: Mapping[str, int] | None,
             functions: Sequence[ExprLike], at: Mapping[str, float] | None, symmetries: bool, seed: int,
             regime: Mapping[str, float] | None, directions: bool = True) -> ObservabilityReport:
    t_start = time.perf_counter()
    rng = np.random.default_rng(seed)
    params_unknown = _unknown_params(system, unknown_params)
    ui = dict(unknown_inputs or {})
    bad = [k for k in ui if k not in system.inputs]
    if bad:
        raise ModelError(f"`unknown_inputs` names {', '.join(map(repr, bad))}, not an input of {system.name!r}")
    for k, d in ui.items():
        if not isinstance(d, (int, np.integer)) or d < 0:
            raise ModelError(f"`unknown_inputs[{k!r}]` must be a polynomial degree >= 0, got {d!r}")
    classes = _input_classes(system, inputs, ui)
    funcs = _parse_functions(system, functions)
    if at is not None:
        extra_keys = [k for k in at if k not in system.states and k not in params_unknown]
        if extra_keys:
            raise ModelError(f"`at` names {', '.join(map(repr, extra_keys))}, which is not a state or an unknown parameter of "
                             f"{system.name!r}")
    st = _setup(system, params_unknown, classes, ui, funcs, _regime_evaluator(system, regime, classes))
    M = len(st.unknowns)
    res = _mod_run(st, system, rng)
    error = 0.0
    runs = 1
    if res.rank < M:  # confirm at a second independent point and prime
        res2 = _mod_run(st, system, rng)
        runs = 2
        error = _error_bound(res, M) * _error_bound(res2, M)
        if res2.rank > res.rank:
            res = res2
        if res.rank == M:  # a full rank at one point is a proof
            error = 0.0
    kernel = res.ech.kernel()
    observable_unknowns = [name for j, name in enumerate(st.unknowns) if not np.any(kernel[:, j])]
    # unknowns whose axis is itself a kernel direction (no row involves them): no observable function depends on them
    unseen_unknowns = [name for j, name in enumerate(st.unknowns) if not np.any(res.ech.basis[:, j])]
    checks = tuple(FunctionCheck(text, res.ech.contains(row)) for (text, _), row in zip(funcs, res.function_rows))
    if directions:
        dirs, point, gap, notes = _float_kernel(st, system, res, rng, at)
    else:
        dirs, point, gap, notes = np.zeros((0, M)), np.zeros(0), float("inf"), []
    syms: tuple[Symmetry, ...] = ()
    searched = ""
    if symmetries:
        syms, searched = _sign_symmetries(system, st, params_unknown, rng)
    orders = []
    for j in range(system.n_outputs):
        ks = [k for jj, k in res.pivot_rows if jj == j]
        orders.append(max(ks) if ks else -1)
    input_desc = ", ".join(f"{k} {c.describe()}" for k, c in classes.items()) or "none"
    if ui:
        input_desc += "; unknown inputs: " + ", ".join(f"{k} (polynomial of degree {d})" for k, d in ui.items())
    method = (f"generic rank of the output-jet Jacobian (orders 0..{res.max_order}) by truncated power series at a random "
              f"point modulo the prime {res.prime}; {runs} point(s); {_REF}")
    notes = [*st.prog.notes, *notes]
    if res.rank < M and gap < 1e-6:
        notes.append(f"the real Jacobian at the direction point is ill-conditioned (smallest kept singular value ratio "
                     f"{gap:.1e}); the directions may be inaccurate")
    report = ObservabilityReport(
        model=system.name, states=system.states, unknown_params=params_unknown,
        unknown_input_coefficients=st.unknowns[st.n + st.q:], inputs=input_desc, rank=res.rank, observable=res.rank == M,
        observable_states=tuple(s for s in system.states if s in observable_unknowns),
        identifiable_params=tuple(k for k in params_unknown if k in observable_unknowns),
        unobservable_directions=dirs, point=point, orders=tuple(orders), method=method, prime=res.prime,
        error_probability=float(min(1.0, error)), symmetries=syms, symmetry_search=searched, functions=checks,
        notes=tuple(notes), seconds=time.perf_counter() - t_start, numerical_gap=gap,
        extra={"observable_unknowns": tuple(observable_unknowns), "unseen_unknowns": tuple(unseen_unknowns),
               "degree_bound": _degree(res, M)},
    )
    return report


def _degree(res: _ModResult, M: int) -> int:
    top = sorted(res.row_degrees, reverse=True)[:M]
    # a leaf drawn as r**e multiplies the degree in the random elements by e (Schwartz-Zippel over r)
    return int(sum(top)) * (1 + res.extra_degree) * res.square_power


def _error_bound(res: _ModResult, M: int) -> float:
    return min(1.0, _degree(res, M) / res.prime)


def observable_function(system: System, expr: ExprLike, **options: Any) -> FunctionCheck:
    r"""Is the function φ(x) (or φ(x, θ) with unknown parameters) observable?

    φ is locally observable iff :math:`d\varphi` lies in :math:`d\mathcal O(h)` (generically): its
    gradient is in the row space of the output-jet Jacobian. Range-only localisation with u = 0
    (p' = v, v' = 0, y = ‖p‖²) observes ‖p‖², p·v and ‖v‖² but not p1.

    Parameters
    ----------
    system : System
    expr : str or SymPy expression in the states (and parameters)
    **options
        As for :func:`analyze`.

    Returns
    -------
    FunctionCheck
    """
    return function_checks(system, [expr], **options)[0]
