r"""Reparametrisation of a model in its identifiable (observable) functions.

Given generators :math:`g_1, \dots, g_k` of the identifiable functions of states and parameters
(``find_identifiable_functions(..., with_states=True)``), the model is rewritten in new variables
:math:`X_i = g_i` (new states: the generators that involve a state) and :math:`P_j = g_j` (new
parameters: those that do not), the role of StructuralIdentifiability.jl's
``reparametrize_global`` (Falkensteiner, Ovchinnikov, Pogudin & Sendra).

For each new state the time derivative :math:`\dot X_i = \sum_s \partial g_i/\partial x_s\, f_s`
and for each output :math:`h_j` must be a rational function of the new variables (and the
inputs). It is searched with undetermined coefficients,
:math:`N(X, P, u) - \dot X_i(x)\, D(X, P, u) = 0` identically, numerator and denominator of growing
degree, the coefficients solved over GF(p) at random points and recovered as small rationals; a
candidate is accepted only when SymPy confirms the identity exactly (``cancel`` to zero). When
no candidate is found within the degree bounds, the reparametrisation is reported as not found
(nothing is guessed).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from ...model import System, symbol
from ...algebra._modular import inv

__all__ = ["Reparametrization", "reparametrize"]

#: Degrees (numerator, denominator) tried in turn for each new right-hand side.
_DEGREES = ((1, 0), (2, 0), (3, 0), (1, 1), (2, 1), (2, 2), (3, 1), (3, 2), (4, 1), (4, 2))
#: Largest number of unknown coefficients tried (beyond it the degree pair is skipped).
_MAX_WIDTH = 700
_PRIME = 134217689  # the largest prime below 2^27 (RowEchelon is exact in int64 there)


@dataclass(frozen=True)
class Reparametrization:
    """The model rewritten in its identifiable functions.

    Attributes
    ----------
    found : bool
        True when every new right-hand side and output was found and verified exactly.
    states, params : tuple of str
        New state and parameter names.
    definitions : dict of str to str
        New name -> its expression in the original names (an identifiable function).
    f : dict of str to str
        New state -> its derivative in the new names (and the inputs).
    h : dict of str to str
        Output -> its expression in the new names.
    system : System or None
        The reparametrised model (parameter values from the original's), when found.
    missing : tuple of str
        What could not be expressed in the new variables (when not found).
    not_needed : bool
        Every state and unknown parameter is identifiable itself: the model is its own reparametrisation.
    """

    found: bool
    states: tuple[str, ...] = ()
    params: tuple[str, ...] = ()
    definitions: dict[str, str] = field(default_factory=dict)
    f: dict[str, str] = field(default_factory=dict)
    h: dict[str, str] = field(default_factory=dict)
    system: System | None = None
    missing: tuple[str, ...] = ()
    not_needed: bool = False

    def to_dict(self) -> dict[str, Any]:
        if self.not_needed:
            return {"found": False, "not_needed": True}
        out: dict[str, Any] = {"found": self.found, "states": list(self.states), "params": list(self.params),
                               "definitions": dict(self.definitions), "dynamics": dict(self.f), "outputs": dict(self.h)}
        if self.missing:
            out["missing"] = list(self.missing)
        return out

    def describe(self) -> list[str]:
        if self.not_needed:
            return ["reparametrisation not needed: every state and unknown parameter is identifiable itself"]
        if not self.found:
            return ["reparametrisation in these functions not found: no rational right-hand side of low degree for "
                    + ", ".join(self.missing)]
        lines = ["reparametrisation in identifiable functions (every new state and parameter is identifiable):"]
        lines += [f"    {k} = {v}" for k, v in self.definitions.items()]
        lines += [f"    {k}' = {v}" for k, v in self.f.items()]
        lines += [f"    {k} = {v}" for k, v in self.h.items()]
        return lines


def _names(funcs: Sequence[sp.Expr], system: System) -> list[str]:
    """Keep a generator's own name when it is a single model symbol, else X1, X2, ... / P1, P2, ..."""
    states = {symbol(s) for s in system.states}
    taken = {*system.states, *system.params, *system.inputs, *system.outputs}
    out, kx, kp = [], 0, 0
    for g in funcs:
        if g.is_Symbol:
            out.append(g.name)
            continue
        is_state = bool(g.free_symbols & states)
        while True:
            if is_state:
                kx += 1
                nm = f"X{kx}"
            else:
                kp += 1
                nm = f"P{kp}"
            if nm not in taken:
                break
        taken.add(nm)
        out.append(nm)
    return out


def _express(target: sp.Expr, gens: Sequence[sp.Expr], new: Sequence[sp.Symbol], old: Sequence[sp.Symbol],
             rng: np.random.Generator) -> sp.Expr | None:
    """`target` (in the old symbols) as a rational function of `gens` (named `new`), verified exactly; or None."""
    from ...algebra._modular import poly_value as _eval_poly
    from ...algebra._modular import kernel_mod_p as _kernel
    from ...algebra._modular import monomial_exponents
    from ...algebra._modular import ratrec as _ratrec

    direct = _by_substitution(target, gens, new, old)
    if direct is not None and sp.cancel(sp.together(direct.xreplace(dict(zip(new, gens))) - target)) == 0:
        return direct
    p = _PRIME
    n = len(gens)
    def compile_(e: sp.Expr) -> tuple[list, list]:
        num, den = sp.fraction(sp.cancel(sp.together(e)))
        out = []
        for part in (num, den):
            P = sp.Poly(sp.expand(part), *old, domain="QQ")
            out.append({m: int(sp.Rational(c).p) % p * inv(int(sp.Rational(c).q) % p, p) % p for m, c in P.terms()})
        return out[0], out[1]

    def ev(poly: dict, vals: list[int]) -> int:
        return _eval_poly(poly, vals, p)

    gl = [compile_(g) for g in gens]
    tl = compile_(target)
    samples: list[tuple[list[int], int]] = []

    def sample() -> None:
        vals = [int(rng.integers(1, p)) for _ in old]
        gv = []
        for num, den in gl:
            d = ev(den, vals)
            if not d:
                return
            gv.append(ev(num, vals) * inv(d, p) % p)
        td = ev(tl[1], vals)
        if not td:
            return
        samples.append((gv, ev(tl[0], vals) * inv(td, p) % p))

    for dn, dd in _DEGREES:
        mn, md = monomial_exponents(n, dn), monomial_exponents(n, dd)
        width = len(mn) + len(md)
        if width > _MAX_WIDTH:
            continue
        for _ in range(3 * (width + 12)):
            if len(samples) >= width + 12:
                break
            sample()
        use = samples[: width + 12]
        G = np.array([gv for gv, _ in use], dtype=np.int64).reshape(len(use), n)
        tv = np.array([t for _, t in use], dtype=np.int64)
        # N(g) - target * D(g) = 0, one row per sample: the monomials' values, all samples at once
        rows = list(np.concatenate([_values(G, mn, p), (-tv[:, None] % p) * _values(G, md, p) % p], axis=1))
        K = _kernel(rows, width, p)
        for vec in K:
            if not np.any(vec[len(mn):]):
                continue
            rr = [_ratrec(int(c), p) if c else (0, 1) for c in vec]
            if any(c is None for c in rr):
                continue
            coeffs = [sp.Rational(a, b) for a, b in rr]
            N = sum(c * sp.Mul(*[s**k for s, k in zip(new, e)]) for c, e in zip(coeffs[:len(mn)], mn))
            D = sum(c * sp.Mul(*[s**k for s, k in zip(new, e)]) for c, e in zip(coeffs[len(mn):], md))
            if D == 0:
                continue
            cand = sp.cancel(N / D)
            back = cand.xreplace(dict(zip(new, gens)))
            if sp.cancel(sp.together(back - target)) == 0:  # exact check in the original variables
                return cand
    return None


def _values(G: np.ndarray, monos: Sequence[Sequence[int]], p: int) -> np.ndarray:
    """Values mod p of the monomials `monos` (exponent tuples) at every row of `G` (samples x variables)."""
    E = np.array(monos, dtype=np.int64).reshape(len(monos), G.shape[1])
    top = int(E.max()) if E.size else 0
    table = np.ones((G.shape[0], G.shape[1], top + 1), dtype=np.int64)  # table[s, i, d] = G[s, i]^d
    for d in range(1, top + 1):
        table[:, :, d] = table[:, :, d - 1] * G % p
    out = np.ones((G.shape[0], len(monos)), dtype=np.int64)
    for i in range(G.shape[1]):
        out = out * table[:, i, E[:, i]] % p
    return out


def _by_substitution(target: sp.Expr, gens: Sequence[sp.Expr], new: Sequence[sp.Symbol],
                     old: Sequence[sp.Symbol]) -> sp.Expr | None:
    """Solve each compound generator X = g for one old variable it holds linearly (and no generator is), substitute.

    Exact by construction; accepted only when nothing but new variables remains.
    """
    plain = {g: n for g, n in zip(gens, new) if g.is_Symbol}
    sub: dict[sp.Symbol, sp.Expr] = {}
    for g, n in zip(gens, new):
        if g.is_Symbol:
            continue
        for v in sorted(g.free_symbols - set(plain) - set(sub), key=str):
            num, den = sp.fraction(sp.together(g))
            if v not in old or sp.degree(num, v) != 1 or den.has(v):
                continue
            # n = (a v + b) / den, linear in v: v = (n den - b) / a (SymPy's solve gave the same, through simplify)
            a, b = (sp.Poly(num, v).coeff_monomial(m) for m in (v, 1))
            if a == 0:
                continue
            sub[v] = sp.cancel((n * den - b) / a)
            break
    if _cyclic(sub):
        # v1 = f(v2), v2 = g(v1): substituting again and again never removes the old variables and the expressions
        # double at every pass (llw1987 spent minutes in SymPy's cancel); the sampling search does the job
        return None
    e = target.xreplace(plain)
    for _ in range(len(sub) + 1):
        e = sp.cancel(sp.together(e.xreplace(sub)))
    return e if e.free_symbols <= set(new) else None


def _cyclic(sub: Mapping[sp.Symbol, sp.Expr]) -> bool:
    """Whether the substitutions `sub` refer to each other in a cycle (v -> the substituted variables in sub[v])."""
    edges = {v: e.free_symbols & set(sub) for v, e in sub.items()}
    state: dict[sp.Symbol, int] = {}  # 1: on the current path, 2: done

    def visit(v: sp.Symbol) -> bool:
        state[v] = 1
        for w in edges[v]:
            if state.get(w) == 1 or (w not in state and visit(w)):
                return True
        state[v] = 2
        return False

    return any(v not in state and visit(v) for v in sub)


def reparametrize(system: System, functions: Sequence[str], *, unknown_params: Sequence[str] = (),
                  seed: int = 0) -> Reparametrization:
    """Rewrite `system` in the identifiable functions `functions` (generators with states included).

    Parameters
    ----------
    system : System
    functions : sequence of str
        Generators of the identifiable functions of states and unknown parameters
        (:attr:`IdentifiableFunctions.functions` with ``with_states=True``).
    unknown_params : sequence of str
        The unknown parameters (the others keep their values and stay numbers).
    seed : int, default 0
        Seed of the random points of the coefficient search (the result is verified exactly either way).

    Returns
    -------
    Reparametrization
    """
    from ...model import TIME
    from ...model._system import exact

    if any(e.has(TIME) for e in (*system.f, *system.h)):
        return Reparametrization(False, missing=("the model depends on t explicitly (only autonomous models are "
                                                 "rewritten)",))
    known = {symbol(k): exact(v) for k, v in system.params.items() if k not in unknown_params}
    from ._inputs import _parse_functions

    gens = [e for _, e in _parse_functions(system, functions)]
    names = _names(gens, system)
    new = [sp.Symbol(f"_new_{n}") for n in names]
    states = [symbol(s) for s in system.states]
    inputs = [symbol(u) for u in system.inputs]
    old = [*states, *(symbol(k) for k in unknown_params), *inputs]
    # inputs are available to the new model as they are
    gens_all = [*gens, *inputs]
    new_all = [*new, *(sp.Symbol(f"_new_{u}") for u in system.inputs)]
    rng = np.random.default_rng([seed, 31])
    is_state = [bool(g.free_symbols & set(states)) for g in gens]
    f_old = [e.xreplace(known) for e in system.f]
    fout: dict[str, str] = {}
    hout: dict[str, str] = {}
    missing: list[str] = []
    back = {s: symbol(n) for s, n in zip(new_all, [*names, *system.inputs])}
    new_f: list[sp.Expr] = []
    for g, nm, st in zip(gens, names, is_state):
        if not st:
            continue
        dg = sp.cancel(sp.together(sum(sp.diff(g, x) * fx for x, fx in zip(states, f_old))))
        e = _express(dg, gens_all, new_all, old, rng)
        if e is None:
            missing.append(f"{nm}'")
            continue
        new_f.append(e.xreplace(back))
        fout[nm] = str(new_f[-1])
    new_h = []
    for y, h in zip(system.outputs, system.h):
        e = _express(h.xreplace(known), gens_all, new_all, old, rng)
        if e is None:
            missing.append(y)
            continue
        new_h.append(e.xreplace(back))
        hout[y] = str(new_h[-1])
    st_names = tuple(n for n, s in zip(names, is_state) if s)
    unknown = {*system.states, *unknown_params}
    if all(g.is_Symbol for g in gens) and {g.name for g in gens} == unknown:
        return Reparametrization(False, missing=(), not_needed=True)
    pa_names = tuple(n for n, s in zip(names, is_state) if not s)
    definitions = {n: str(g) for n, g in zip(names, gens) if str(g) != n}
    if missing:
        return Reparametrization(False, st_names, pa_names, definitions, fout, hout, None, tuple(missing))
    values = {symbol(k): exact(v) for k, v in system.params.items()}
    pvals = {n: float(g.xreplace(values)) for n, g, s in zip(names, gens, is_state) if not s}
    fixed = {k: v for k, v in system.params.items() if k not in unknown_params}
    new_sys = System(states=list(st_names), f=new_f, outputs=list(system.outputs), h=new_h,
                     inputs=list(system.inputs), params={**fixed, **pvals}, name=f"{system.name} (reparametrised)")
    return Reparametrization(True, st_names, pa_names, definitions, fout, hout, new_sys)
