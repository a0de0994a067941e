r"""Identifiable (observable) functions: generators of everything the output determines.

When single unknowns are not identifiable, combinations of them may be: for the two-compartment
model :math:`a_{01} a_{12}` and :math:`a_{01} + a_{12} + a_{21}`. The functions of the unknowns
that the output determines form a field E; this module returns a small generating set of E, the
simplest functions first (the role of StructuralIdentifiability.jl's
``find_identifiable_functions``).

Method (everything over GF(p), on the system of the global check: the fibre of the input-output route's generators
where that route applies (``_io.py``; its tangent rows are the generators' differentials, and completeness is
checked exactly: every generator lies in the field of the chosen functions), else SIAN's systems of ``_global.py``;
a route's fibre above ``_FEWER_ABOVE`` terms is rebuilt first on fewer of its coefficients that generate the same
field, :func:`_fewer_generators`):

0. *Unknowns set aside.* An unknown whose axis is itself a direction of the local kernel (no row of the output-jet
   Jacobian involves it: a state no output sees, a parameter only such a state uses) is in no identifiable function
   (its gradient would have to be orthogonal to that axis), and steps 1-6 leave it out. When every other unknown is
   globally identifiable (the global check's verdict, computed first), those generate E and nothing is searched.
1. *Candidates.* Functions P/Q with P a polynomial of degree <= ``max_degree`` in the unknowns
   and Q = 1 or a single unknown not globally identifiable. First only the monomials free of the globally
   identifiable unknowns (they are in the field already; LV: 35 monomials instead of 84, half the time of the whole
   search), kept when the generators found, with those unknowns, reach the field's transcendence degree (checked
   after the local points, then after the global ones) and pass step 6's completeness check; else the search runs
   again on every monomial, on the same points (a generator may need a globally identifiable unknown: SLIQR's
   (In + L + Q)/S). When even every monomial of the automatic degree 2 falls short of that degree after the local
   points, the search goes straight to degree 3 (step 6's raise; HIV).
2. *Locally identifiable* candidates: the gradient of P/Q lies in the row space of the Jacobian of
   the truncated jet equations at a random point (the tangent space of the set of unknowns giving
   the same output is its kernel). Linear in the coefficients of P; repeated at random points until
   the solution space stops shrinking.
3. *Globally identifiable*: P - λ_j Q vanishes on the solutions at the random point j, i.e. its
   normal form modulo the Gröbner basis is zero, for an unknown value λ_j per point; linear in
   (coefficients of P, λ_1, λ_2, ...). Points are added until one cuts nothing: a candidate that is not
   identifiable is cut at a random point but with probability at most (degree / p). Where the points run out
   first (12), the candidates are checked again at fresh points.
4. *Generators, simplest first.* The solutions, brought to reduced echelon form (each with few
   terms), coefficients recovered from GF(p) as small rationals, are sorted by size (terms, degree, then printed
   text; candidates of more than ten terms are not printed, their ties go by their exact terms); one is kept
   when it is not already a function of those kept before (membership: its value is constant on the
   fibre of the kept functions, a normal form modulo their fibre ideal). A candidate whose gradient is independent
   of the kept ones' at a random point is kept without that test (it is not even algebraic over them); the others
   are tested together in one engine run (see :func:`_select`).
5. *Checks.* Every returned function is checked with :func:`nlobs.analysis.observable_function`
   (local) and by the global check; with states included the field is compared with the
   identifiable field itself (the numbers of points of the two fibres on the same random cut).
6. *Completion* (input-output route; without the states, from its coefficients alone). Where the simple forms of step 1 miss part of the field
   (generators with polynomial denominators, as StructuralIdentifiability.jl finds for its St and QY benchmarks),
   the route's own generators (coefficient ratios of the input-output equations and the outputs' Lie derivatives,
   which together generate the field) are added, smallest first, each kept unless it is a function of those kept
   (step 4's test). The result is then complete but its last generators are not simplified: a note says so.
   StructuralIdentifiability.jl simplifies further with Gröbner bases over the field of the coefficients (Demin,
   Ovchinnikov & Pogudin); nlobs does not.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from ...errors import EngineError, ModelError
from ...model import System, symbol
from ...algebra._modular import monomial_exponents
from ...algebra._modular import monomial_value as _mono_value
from ...algebra._modular import monomial_values as _mono_values
from ...algebra._modular import ratrec as _ratrec
from ._global import IO_METHOD, NO_ENGINE, SIAN_METHOD, NotRational, _decide, _local_of, _prepare, _prepare_io, _System
from ._rationalise import is_rational
from ._budget import committed
from ._inputs import require_system
from ._io import NotApplicable
from ._reparam import reparametrize
from ...algebra._groebner import GroebnerEngine, Poly, get_engine
from ...algebra._modular import RowEchelon, inv
from ...algebra._modular import matmul_mod
from ...algebra._modular import distinct_roots as _distinct_roots
from ...algebra._modular import minimal_polynomial as _minimal_polynomial

__all__ = ["IdentifiableFunctions", "find_identifiable_functions"]


@dataclass(frozen=True)
class IdentifiableFunctions:
    """Generators of the identifiable (observable) functions, simplest first.

    Attributes
    ----------
    functions : tuple of str
        The generators, as expressions in the model's names.
    with_states : bool
        Whether functions of the states (observable functions) are included, or parameters only.
    complete : bool or None
        True when the generators were shown to give every identifiable function (on the input-output
        route: every generator of the route lies in their field; on SIAN's: the fibre counts agree);
        False when some are missing (the search space was too small: raise ``max_degree``); None when
        not checked (``notes`` says so).
    local_checks : tuple of bool
        :func:`nlobs.analysis.observable_function` on each generator (all True when correct).
    refused : str
        Why nothing was computed (model outside the class, no engine), or "".
    notes : tuple of str
    seconds, engine_seconds : float
    reparametrization : Reparametrization or None
        The model rewritten in these functions (with states included; ``found`` False when no
        rational rewriting of low degree exists), or None when not attempted.
    method : str
        The system the functions were searched on (input-output equations or SIAN's), with references.
    """

    functions: tuple[str, ...] = ()
    with_states: bool = True
    complete: bool | None = None
    local_checks: tuple[bool, ...] = ()
    refused: str = ""
    notes: tuple[str, ...] = ()
    seconds: float = 0.0
    engine_seconds: float = 0.0
    reparametrization: Any = None
    method: str = ""

    def to_list(self) -> list[str]:
        """The generators as strings (``"identifiable_functions"`` of the JSON output)."""
        return list(self.functions)

    def to_dict(self) -> dict[str, Any]:
        """Generators with the evidence."""
        if self.refused:
            return {"refused": self.refused}
        out = {"functions": list(self.functions), "with_states": self.with_states, "complete": self.complete,
               "local_checks": list(self.local_checks), "notes": list(self.notes), "seconds": self.seconds,
               "engine_seconds": self.engine_seconds, "method": self.method}
        if self.reparametrization is not None:
            out["reparametrization"] = self.reparametrization.to_dict()
        return out

    def describe(self) -> list[str]:
        """The result in words."""
        if self.refused:
            return [f"identifiable functions not computed: {self.refused}"]
        what = "functions of states and parameters" if self.with_states else "functions of the parameters"
        head = f"identifiable {what} (generators, simplest first): {', '.join(self.functions) or '(none but constants)'}"
        lines = [head]
        if self.complete is True:
            lines.append("  every identifiable function is a rational function of these (checked)")
        elif self.complete is False:
            lines.append("  INCOMPLETE: some identifiable functions are not generated by these; raise max_degree")
        else:
            lines.append("  completeness not checked: these may not generate every identifiable function (notes)")
        for n in self.notes:
            lines.append(f"  note: {n}")
        if self.method:
            lines.append(f"  searched on {self.method} ({self.seconds:.2f} s)")
        if self.reparametrization is not None:
            lines += [f"  {t}" for t in self.reparametrization.describe()]
        return lines


# ----------------------------------------------------------------------------------------------
def _mono_grad(e: Sequence[int], vals: Sequence[int], p: int) -> list[int]:
    out = []
    for i, k in enumerate(e):
        if not k:
            out.append(0)
            continue
        ee = list(e)
        ee[i] -= 1
        out.append(k * _mono_value(ee, vals, p) % p)
    return out


# ----------------------------------------------------------------------------------------------
#: exact terms of a polynomial: (exponents, numerator, denominator of the coefficient), as :func:`_qq_terms` gives them
Terms = tuple[tuple[tuple[int, ...], int, int], ...]
#: candidates with more terms than this are ordered by their exact terms, not by their printed text (step 4)
_PRINTED_TERMS = 10


class _Candidate:
    """A rational function N/D of the unknowns `names`, kept as the exact terms of N and D.

    The search returns candidates in one normal form (P monic, no monomial factor shared with its monomial
    denominator Q), so equal functions have equal terms. The SymPy expression is built only when asked for: a 10-state
    model gives thousands of candidates, and building them all was half the search's time, while only the kept ones
    are printed.
    """

    __slots__ = ("_expr", "_over", "den", "names", "num")

    def __init__(self, num: Terms, den: Terms, names: Sequence[str], expr: sp.Expr | None = None):
        self.num, self.den, self.names, self._expr = num, den, tuple(names), expr
        self._over: dict[tuple[str, ...], tuple[Terms, Terms]] = {}

    @classmethod
    def unknown(cls, u: str, names: Sequence[str]) -> _Candidate:
        """The unknown `u` itself."""
        zero = tuple(0 for _ in names)
        return cls(((tuple(int(v == u) for v in names), 1, 1),), ((zero, 1, 1),), names, symbol(u))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _Candidate) and (self.num, self.den, self.names) == (other.num, other.den, other.names)

    def __hash__(self) -> int:
        return hash((self.num, self.den))

    @property
    def expr(self) -> sp.Expr:
        if self._expr is None:
            syms = [symbol(u) for u in self.names]
            num, den = (sp.Add(*[sp.Rational(a, b) * sp.Mul(*[s**k for s, k in zip(syms, e) if k]) for e, a, b in t])
                        for t in (self.num, self.den))
            self._expr = num / den
        return self._expr

    def __str__(self) -> str:
        return str(self.expr)

    __repr__ = __str__

    def terms_over(self, X: Sequence[str]) -> tuple[Terms, Terms]:
        """Numerator and denominator terms with exponents over the unknowns `X` (which include `names`)."""
        X = tuple(X)
        if X == self.names:
            return self.num, self.den
        if X not in self._over:
            col = [X.index(u) for u in self.names]

            def widen(t: Terms) -> Terms:
                out = []
                for e, a, b in t:
                    ee = [0] * len(X)
                    for j, k in zip(col, e):
                        ee[j] += k
                    out.append((tuple(ee), a, b))
                return tuple(out)

            self._over[X] = (widen(self.num), widen(self.den))
        return self._over[X]


def _terms_of(f: _Candidate | sp.Expr, X: Sequence[str], cancel: bool) -> tuple[Terms, Terms]:
    """Exact numerator and denominator terms of `f` over `X` (a candidate's are known, and in lowest terms)."""
    if isinstance(f, _Candidate):
        return f.terms_over(X)
    return _qq_terms(f, tuple(X), cancel)


#: Global points whose normal forms one engine call computes together when the system is small (:meth:`_Search.nf_monos`)
_POINTS_TOGETHER = 4
#: "Small": at most this many terms in the system of the first point (Modified LV: 30, SEIR_1: 136; SLIQR: 222,
#: where 4 copies took 46 ms and one 11 ms: the engine's work on the copies grows faster than their number)
_SMALL_TERMS = 150


class _Search:
    """Steps 2-3 of the module docstring for every denominator Q, on points shared by all of them.

    The random points are drawn once and cached: at a local point, the row echelon form of the jet Jacobian and
    the values of the unknowns; at a global point, the normal forms of every candidate monomial (one Gröbner
    basis per point, whatever the number of denominators: each Q is itself a candidate monomial).
    """

    def __init__(self, prep: Any, eng: GroebnerEngine, U: list[str], max_degree: int, top: Sequence[str] | None = None,
                 powers: Mapping[str, int] | None = None, without: Sequence[str] = ()):
        self.prep, self.eng, self.U = prep, eng, U
        self.p = prep.p
        self.monos = monomial_exponents(len(U), max_degree)
        if top is not None:  # monomials of the top degree only in the unknowns `top`
            keep = [i for i, u in enumerate(U) if u in top]
            self.monos = [e for e in self.monos if sum(e) < max_degree or sum(e[i] for i in keep) == max_degree]
        for u, top_power in (powers or {}).items():  # pure powers u^d above max_degree (p53's p22^4)
            for d in range(max_degree + 1, top_power + 1):
                self.monos.append(tuple(d if v == u else 0 for v in U))
        if without:  # monomials free of the unknowns `without` (step 1's first try: the globally identifiable ones)
            drop = [i for i, u in enumerate(U) if u in without]
            self.monos = [e for e in self.monos if not any(e[i] for i in drop)]
        # most complex first: pivots of the reduced echelon form fall on the complex monomials
        self.monos.sort(key=lambda e: (-sum(e), tuple(-x for x in e)))
        self.mono_index = {e: i for i, e in enumerate(self.monos)}
        # position of each monomial in the lexicographic order of the names (a candidate's leading term, step 4)
        order = sorted(range(len(U)), key=lambda i: U[i])
        self._lex = np.empty(len(self.monos), dtype=np.int64)
        self._lex[sorted(range(len(self.monos)), key=lambda m: tuple(self.monos[m][i] for i in order))] = \
            np.arange(len(self.monos))
        self.E = np.array(self.monos, dtype=np.int64).reshape(len(self.monos), len(U))
        self.var = {u: prep.hs.unknown_var[u] for u in U}
        #: a small system (:data:`_SMALL_TERMS`): its fresh global points go several to one engine call, else side by side
        self._small = sum(map(len, prep.hs.F)) <= _SMALL_TERMS
        #: local points (echelon form of the jet Jacobian, values and columns of the unknowns, number of columns),
        #: shared with the searches made by :meth:`without`
        self._tangents: list[tuple[RowEchelon, list[int], list[int], int]] = []
        self._local: list[tuple[np.ndarray, np.ndarray]] = []
        self._reduced: list[tuple[list[int], np.ndarray]] = []
        self._local_ech: dict[tuple[int, ...], RowEchelon] = {}
        #: the denominators whose global points ran out (``max_points``) before a point cut nothing
        self.unconverged: set[tuple[int, ...]] = set()
        self._global: list[list[Poly]] = []
        #: the systems of global points 1, 2, ... (a search of another degree on the same unknowns reuses them)
        self._systems: list[_System] = []
        self._nf_matrices: list[np.ndarray] = []
        self._args = (max_degree, top, powers)
        #: the search this one is a part of (:meth:`without`) and the positions of its monomials there
        self._parent: tuple[_Search, list[int]] | None = None

    def without(self, names: Sequence[str]) -> _Search:
        """The same search on the monomials free of `names`, on the same points: the normal forms at a global point
        are computed for every monomial of this search (the same engine run), so that this search reuses them."""
        sub = _Search(self.prep, self.eng, self.U, self._args[0], top=self._args[1], powers=self._args[2],
                      without=names)
        sub.share_points(self)
        sub._parent = (self, [self.mono_index[e] for e in sub.monos])
        return sub

    def share_points(self, other: _Search) -> None:
        """Use the random points of `other`, a search on the same unknowns (of another degree, or a part of it): its
        local tangents and its global systems depend on the unknowns only."""
        if other.U != self.U:
            raise ValueError("searches on different unknowns have different points")
        self._tangents, self._systems = other._tangents, other._systems

    # -- local rows -----------------------------------------------------------------------------
    def tangent(self, i: int) -> tuple[RowEchelon, list[int], list[int], int]:
        """The i-th local point: echelon form of the jet Jacobian there, values and columns of the unknowns, number
        of columns."""
        while len(self._tangents) <= i:
            ech, uv, uc, n = self.prep.tangent()
            self._tangents.append((ech, [uv[u] for u in self.U], [uc[u] for u in self.U], n))
        return self._tangents[i]

    def _local_point(self, i: int) -> tuple[RowEchelon, list[int], list[int], int, np.ndarray, np.ndarray]:
        """The i-th local point (:meth:`tangent`) with the values and gradients of the candidate monomials there."""
        ech, uvals, ucol, n = self.tangent(i)
        while len(self._local) <= i:
            self._local.append(_mono_values(self.E, self.tangent(len(self._local))[1], self.p))
        return (ech, uvals, ucol, n, *self._local[i])

    def field_rank(self) -> int:
        """Transcendence degree of the identifiable functions of the unknowns U (at local point 0): the dimension of
        the rows' span inside the coordinates of U, rank(rows) - rank(rows outside U's columns)."""
        ech, _, ucol, n = self.tangent(0)
        inside = set(ucol)
        other = [j for j in range(n) if j not in inside]
        return ech.rank - (_rank(ech.basis[:, other], self.p) if other else 0)

    def local_rows(self, Q: tuple[int, ...], i: int) -> list[np.ndarray]:
        """Constraints on the coefficients of P at local point `i`: the gradient of P/Q reduced modulo the rows of
        the jet Jacobian (zero iff P/Q is locally identifiable to first order there)."""
        p = self.p
        ech, uvals, ucol, n, mv, mg = self._local_point(i)
        free, RM = self._reduced_gradients(i)
        qv = _mono_value(Q, uvals, p)
        G = np.zeros(n, dtype=np.int64)
        G[ucol] = _mono_grad(Q, uvals, p)
        rq = ech.reduce(G)[free]
        # the quotient rule's numerator Q grad P - P grad Q, reduced (reduction is linear: the monomials' reduced
        # gradients are shared by every Q at this point); rows: coordinates, columns: candidates
        R = ((qv * RM % p - (mv[:, None] * rq[None, :]) % p) % p).T
        return list(R[R.any(axis=1)])

    def _reduced_gradients(self, i: int) -> tuple[list[int], np.ndarray]:
        """At local point `i`: the columns outside the pivots of the jet Jacobian's echelon form, and there the
        gradients of the candidate monomials reduced modulo its rows (k x that many)."""
        while len(self._reduced) <= i:
            ech, _, ucol, n, _, mg = self._local_point(len(self._reduced))
            pivots = set(ech.pivots)
            free = [j for j in range(n) if j not in pivots]
            G = np.zeros((len(self.monos), n), dtype=np.int64)
            G[:, ucol] = mg
            self._reduced.append((free, ech.reduce_many(G)[:, free]))
        return self._reduced[i]

    # -- global rows ----------------------------------------------------------------------------
    def mono_polys(self, hs: _System) -> list[Poly]:
        """The candidate monomials as polynomials of the system `hs` (weighted variables: u = V^w)."""
        names = hs.names
        idx = [names.index(self.var[u]) for u in self.U]
        ws = [hs.weight.get(self.var[u], 1) for u in self.U]
        G = []
        for e in self.monos:
            m = [0] * len(names)
            for i, k, w in zip(idx, e, ws):
                if k:
                    m[i] += k * w
            G.append({tuple(m): 1})
        return G

    def known_point(self, nfs: list[Poly]) -> None:
        """Normal forms of :meth:`mono_polys` modulo the system of `prep` (point 0), computed by the caller."""
        if self._global:
            raise ValueError("the first global point is already known")
        self._global.append(nfs)

    def nf_monos(self, j: int) -> list[Poly]:
        """Normal forms of every candidate monomial at global point `j` (0: the system of `prep`, then fresh ones)."""
        while len(self._global) <= j:
            if self._parent is not None:
                parent, pick = self._parent
                nfs = parent.nf_monos(len(self._global))
                self._global.append([nfs[i] for i in pick])
                continue
            k = len(self._global)
            if not k:  # point 0 is the system of `prep`; the others fresh, kept for other searches
                hs = self.prep.hs
                self._global.append(self.eng.normal_forms(hs.names, self.p, hs.F, self.mono_polys(hs)))
                continue
            # small systems a few points per engine call: msolve's start-up is most of their time (Modified LV: 8
            # points, 7 ms each), and a point drawn ahead costs little more than its start-up; larger ones a point
            # per core, side by side (the wall time of one; at most one point per search more than needed)
            ahead = _POINTS_TOGETHER if self._small else self.eng.workers
            while len(self._systems) < k - 1 + ahead:
                self._systems.append(self.prep.point())
            batch = [(hs.names, hs.F, self.mono_polys(hs)) for hs in self._systems[k - 1:k - 1 + ahead]]
            self._global += (self.eng.normal_forms_together(self.p, batch) if self._small
                             else self.eng.normal_forms_side_by_side(self.p, batch))
        return self._global[j]

    def nf_matrix(self, j: int) -> np.ndarray:
        """The normal forms at global point `j` as a matrix: one row per monomial of their support, one column per
        candidate monomial (shared by every Q)."""
        while len(self._nf_matrices) <= j:
            nfm = self.nf_monos(len(self._nf_matrices))
            support: dict[tuple[int, ...], int] = {}
            for g in nfm:
                for m in g:
                    support.setdefault(m, len(support))
            A = np.zeros((len(support), len(nfm)), dtype=np.int64)
            for ci, g in enumerate(nfm):
                for m, c in g.items():
                    A[support[m], ci] = c % self.p
            self._nf_matrices.append(A)
        return self._nf_matrices[j]

    def local_space(self, Q: tuple[int, ...]) -> RowEchelon:
        """Step 2: the local constraints on the coefficients of P (echelon form over them), at local points until the
        space stops shrinking (twice in a row); cached by Q.

        A point gives as many constraints as the local kernel has dimensions (often one), so some k / that many
        points are needed: their rows are eliminated together (FLINT), then points are added one at a time until
        two in a row cut nothing."""
        if Q not in self._local_ech:
            k = len(self.monos)
            ech = RowEchelon(k, self.p)
            rows = self.local_rows(Q, 0)
            first = max(1, -(-k // max(1, len(rows))))  # ceil(k / rows per point)
            for i in range(1, min(first, k + 3)):
                rows += self.local_rows(Q, i)
            if rows:
                ech.add_many(np.array(rows, dtype=np.int64))
            still = 0
            for i in range(first, k + 3):
                more = self.local_rows(Q, i)
                still = 0 if more and ech.add_many(np.array(more, dtype=np.int64)) else still + 1
                if still == 2:
                    break
            self._local_ech[Q] = ech
        return self._local_ech[Q]

    def local_gradients(self, Q: tuple[int, ...]) -> np.ndarray:
        """Gradients at local point 0 (up to the factor 1/Q^2: Q grad P - P grad Q) of a basis of the locally
        identifiable candidates P/Q, one row each."""
        p = self.p
        K = self.local_space(Q).kernel()
        _, uvals, _, _, mv, mg = self._local_point(0)
        qv = _mono_value(Q, uvals, p)
        qg = np.array(_mono_grad(Q, uvals, p), dtype=np.int64)
        PV = matmul_mod(K, mv[:, None], p)
        return (qv * matmul_mod(K, mg, p) % p - PV * qg[None, :] % p) % p

    def solve(self, Q: tuple[int, ...], max_points: int = 12) -> np.ndarray:
        """Basis of the coefficient vectors c with (sum c_m m)/Q identifiable (rows).

        The constraints are kept in one row echelon form over the coefficients of P and one unknown
        value λ_j per global point (columns k + j), grown as points are added.
        """
        p, k = self.p, len(self.monos)
        width = k + max_points
        local = self.local_space(Q)
        ech = local.widened(max_points)
        prev = [k - local.rank]
        qi = self.mono_index[Q]
        for j in range(max_points):
            A = self.nf_matrix(j)
            M = np.zeros((A.shape[0], width), dtype=np.int64)
            M[:, :k] = A
            M[:, k + j] = (-A[:, qi]) % p
            ech.add_many(M[M.any(axis=1)])
            # the dimension of the candidates' space, the projection of the kernel on the first k coordinates: the
            # kernel's dimension minus that of its part with P = 0 (the λ with A[:, k:] λ = 0, A the constraints;
            # its rank is that of the basis' last columns); the basis itself only once the dimension is stable
            r = k - ech.rank + _rank(ech.basis[:, k:], p)
            if r == prev[-1]:
                # a point that cuts nothing: every candidate left is globally identifiable, but with probability
                # at most (degree / p): a candidate that is not is cut at a random point (step 3)
                break
            prev.append(r)
        else:
            self.unconverged.add(Q)
        return _row_space(ech.kernel()[:, :k], p)

    def functions(self, Kc: np.ndarray, Q: tuple[int, ...]) -> list[_Candidate]:
        """The candidates P/Q of the rows of `Kc`: coefficients recovered as small rationals, the monomial factor
        common to P and Q cancelled, P made monic (leading term in the lexicographic order of the names) and, when Q
        is 1, without its constant term (a function is identifiable up to a constant factor, and a polynomial up to
        an additive constant too). On exponent arrays: SymPy's cancel on hundreds of candidates, then building
        thousands of expressions, was most of the search's time."""
        p = self.p
        Qa = np.array(Q, dtype=np.int64)
        out = []
        for row in _rref(Kc, p):
            nz = np.flatnonzero(row)
            coef = [_ratrec(int(c), p) for c in row[nz]]
            if not coef or any(c is None for c in coef):
                continue
            E = self.E[nz]
            g = np.minimum(E.min(axis=0), Qa)
            q = tuple(int(x) for x in Qa - g)
            E = (E - g).tolist()
            keep = [i for i in np.argsort(-self._lex[nz], kind="stable").tolist()
                    if any(q) or any(E[i])]  # P's terms, leading first; a polynomial's constant term dropped
            if not keep:
                continue
            la, lb = coef[keep[0]]
            num = []
            for i in keep:
                a, b = coef[i][0] * lb, coef[i][1] * la
                d = math.gcd(a, b) * (1 if b > 0 else -1)
                num.append((tuple(E[i]), a // d, b // d))
            out.append(_Candidate(tuple(num), ((q, 1, 1),), self.U))
        return out


def _rank(K: np.ndarray, p: int) -> int:
    import flint

    if K.size == 0:
        return 0
    return flint.nmod_mat(K.shape[0], K.shape[1], (K % p).ravel().tolist(), p).rank()


def _row_space(K: np.ndarray, p: int) -> np.ndarray:
    ech = RowEchelon(K.shape[1], p)
    ech.add_many(K)
    return np.array(ech.basis, dtype=np.int64).reshape(len(ech.basis), K.shape[1])


def _rref(K: np.ndarray, p: int) -> list[np.ndarray]:
    if K.shape[0] == 0:
        return []
    ech = RowEchelon(K.shape[1], p)
    ech.add_many(K)
    return [b for _, b in sorted(zip(ech.pivots, ech.basis), key=lambda t: t[0])]


def _complexity(f: _Candidate | sp.Expr) -> tuple:
    """Step 4's order: fewest terms, then lowest degree, then shortest printed text; candidates of more than
    ``_PRINTED_TERMS`` terms are not printed (chain10: thousands of them), their ties are ordered by their exact terms."""
    if isinstance(f, _Candidate):  # the same terms and degree as SymPy's (tests), from the exact terms
        size = (len(f.num) + len(f.den) - 1, max(sum(e) for e, _, _ in f.num) + max(sum(e) for e, _, _ in f.den))
        if size[0] > _PRINTED_TERMS:
            return (*size, 0, (f.num, f.den))
        text = str(f)
        return (*size, len(text), text)
    num, den = sp.fraction(f)
    terms = len(sp.Add.make_args(sp.expand(num))) + len(sp.Add.make_args(sp.expand(den))) - 1
    deg = sp.Poly(num, *num.free_symbols).total_degree() if num.free_symbols else 0
    ddeg = sp.Poly(den, *den.free_symbols).total_degree() if den.free_symbols else 0
    return (terms, deg + ddeg, len(str(f)), str(f))


@functools.lru_cache(maxsize=4096)
def _qq_terms(f: sp.Expr, X: tuple[str, ...], cancel: bool) -> tuple[tuple[tuple[tuple[int, ...], int, int], ...], ...]:
    """Numerator and denominator of `f` as exact terms (exponents over `X`, numerator, denominator of the
    coefficient); cached, since the same candidates are converted at every point and in every selection round."""
    syms = [symbol(u) for u in X]

    def exact(num: sp.Expr, den: sp.Expr) -> tuple[tuple[tuple[tuple[int, ...], int, int], ...], ...]:
        out = []
        for part in (num, den):
            P = sp.Poly(sp.expand(part), *syms, domain="QQ")
            out.append(tuple((tuple(mono), int(sp.Rational(c).p), int(sp.Rational(c).q)) for mono, c in P.terms()))
        return tuple(out)

    if not cancel:
        # a candidate P/Q of the search is a polynomial over a monomial already: its numerator and denominator are
        # those of `together` up to one constant factor, which changes no relation's zero set (SymPy's `together`
        # on every candidate was most of the verification time)
        try:
            return exact(*sp.fraction(f))
        except sp.PolynomialError:
            pass
    e = sp.together(f)
    return exact(*sp.fraction(sp.cancel(e) if cancel else e))


def _terms_mod(terms: Sequence[tuple[tuple[int, ...], int, int]], p: int) -> list[tuple[tuple[int, ...], int]]:
    return [(mono, a % p * inv(b % p, p) % p) for mono, a, b in terms]


def _fibre_system(funcs: Sequence[_Candidate | sp.Expr], X: list[str], p: int, rng: np.random.Generator,
                  point: dict[str, int] | None = None) -> tuple[list[str], list[Poly], dict[str, int]]:
    """Ideal of {x : f(x) = f(x̂)} at a random x̂ (saturated by the denominators), over GF(p)."""
    names = list(X) + ["z_sat"]
    xhat = point or {u: int(rng.integers(1, p)) for u in X}
    nv = len(names)
    F: list[Poly] = []
    den_all: Poly = {tuple([0] * nv): 1}

    def to_poly(terms: Sequence[tuple[tuple[int, ...], int, int]]) -> Poly:
        out: Poly = {}
        for mono, c in _terms_mod(terms, p):
            out[mono + (0,)] = c
        return {k: v for k, v in out.items() if v}

    def value(P: Poly) -> int:
        acc = 0
        for m, c in P.items():
            acc += c * _mono_value(m[:-1], [xhat[u] for u in X], p)
        return acc % p

    from ...algebra._modular import poly_mul as _mul

    for f in funcs:
        tn, td = _terms_of(f, X, True)
        N, D = to_poly(tn), to_poly(td)
        dv = value(D)
        if dv == 0:
            raise ZeroDivisionError
        fv = value(N) * inv(dv, p) % p
        eq = dict(N)
        for m, c in D.items():
            eq[m] = (eq.get(m, 0) - fv * c) % p
        F.append({k: v for k, v in eq.items() if v})
        if not (len(D) == 1 and all(e == 0 for e in next(iter(D)))):
            den_all = _mul(den_all, D, p)
    sat = {(*m[:-1], 1): c for m, c in den_all.items()}
    sat[tuple([0] * nv)] = (sat.get(tuple([0] * nv), 0) - 1) % p
    F.append(sat)
    return names, F, xhat


def _relation(f: _Candidate | sp.Expr, X: list[str], xhat: dict[str, int], p: int) -> Poly:
    """num(x) den(x̂) - num(x̂) den(x): zero on the fibre iff f is constant there."""
    tn, td = _terms_of(f, X, False)  # candidates are already P/Q in lowest terms
    vals = [xhat[u] for u in X]
    num, den = _terms_mod(tn, p), _terms_mod(td, p)
    nv = sum(c * _mono_value(mono, vals, p) for mono, c in num) % p
    dv = sum(c * _mono_value(mono, vals, p) for mono, c in den) % p
    out: Poly = {}
    for terms, scale in ((num, dv), (den, (-nv) % p)):
        for mono, c in terms:
            key = mono + (0,)
            out[key] = (out.get(key, 0) + c * scale) % p
    return {k: v for k, v in out.items() if v}


def _gradient(f: _Candidate | sp.Expr, X: list[str], vals: Sequence[int], p: int) -> np.ndarray:
    """The gradient of f = N/D at the point `vals` over GF(p), up to the factor 1/D^2: D grad N - N grad D."""
    tn, td = _terms_of(f, X, False)
    out = []
    for terms in (tn, td):
        v, g = 0, np.zeros(len(X), dtype=object)
        for mono, a, b in terms:
            c = a % p * inv(b % p, p) % p
            v += c * _mono_value(mono, vals, p)
            g += c * np.array(_mono_grad(mono, vals, p), dtype=object)
        out.append((v % p, g % p))
    (nv, ng), (dv, dg) = out
    return np.array((dv * ng - nv * dg) % p, dtype=np.int64)


def _select(cands: list[Any], X: list[str], eng: GroebnerEngine, p: int, rng: np.random.Generator,
            kept: Sequence[Any] = (), deadline: float | None = None) -> list[Any] | None:
    """Greedy, simplest first: keep a candidate unless it is a function of those kept (constant on their fibre),
    starting from `kept`. With a `deadline` (time.perf_counter()) every engine run is stopped there, and None is
    returned when one does not finish.

    A candidate whose gradient at a random point is outside the span of the kept ones' gradients is algebraically
    independent of them, so not a function of them: it is kept without an engine run. The others (algebraic over
    those kept before them) are tested together, in one run on the fibre of everything kept: a candidate algebraic
    over the field K of those kept before it lies in K(t1, ..., tk), the tk kept after it being algebraically
    independent over K, only if it lies in K (K is algebraically closed in a purely transcendental extension). The
    first that is not a function of them is kept, and the pass resumes after it.
    """
    vals = [int(v) for v in rng.integers(1, p, size=len(X))]
    grads: dict[Any, np.ndarray] = {}

    def gradient(g: Any) -> np.ndarray:  # each candidate's once, whatever the number of passes
        if g not in grads:
            grads[g] = _gradient(g, X, vals, p)
        return grads[g]

    chosen = list(kept)
    rest = list(cands)
    limit = eng.timeout
    try:
        while rest:
            ech = RowEchelon(len(X), p)
            for g in chosen:
                ech.add(gradient(g))
            pending, after = [], []
            for g in rest:  # the local pass: keep the independent, set aside the algebraic ones for the engine
                if ech.add(gradient(g)):
                    chosen.append(g)
                else:
                    pending.append(g)
                after.append(len(chosen))
            if not pending:
                break
            if deadline is not None:
                left = deadline - time.perf_counter()
                if left <= 0:
                    return None
                eng.timeout = min(left, limit) if limit else left
            names, F, xhat = _fibre_system(chosen, X, p, rng)
            rels = [_relation(g, X, xhat, p) for g in pending]
            try:
                nfs = eng.normal_forms(names, p, F, rels)
            except EngineError:
                if deadline is None:
                    raise
                return None
            outside = [g for g, nf in zip(pending, nfs) if nf]
            if not outside:
                break
            # keep the first candidate that is not a function of those kept before it; the candidates after it
            # are decided again (the kept ones after it stay kept: the local pass keeps them again)
            first = outside[0]
            i = rest.index(first)
            chosen = chosen[:after[i]] + [first]
            rest = rest[i + 1:]
    finally:
        eng.timeout = limit
    return chosen


def _count(eng: GroebnerEngine, names: list[str], F: list[Poly], ell: Poly, p: int, cap: int) -> int | None:
    """Number of points of a zero-dimensional system: degree of the minimal polynomial of a random linear form."""
    names = [*names, "ell_sep"]
    F = [{(*m, 0): c for m, c in f.items()} for f in F]
    eq = {(*m, 0): (-c) % p for m, c in ell.items()}
    eq[(*([0] * (len(names) - 1)), 1)] = 1
    F.append(eq)
    powers = [{(*([0] * (len(names) - 1)), k): 1} for k in range(cap + 1)]
    nfs = eng.normal_forms(names, p, F, powers)
    mp = _minimal_polynomial(nfs, p)
    return None if mp is None else _distinct_roots(mp, p)


def _complete(prep: Any, eng: GroebnerEngine, chosen: list[_Candidate], U: list[str], rng: np.random.Generator,
              cap: int = 48) -> bool | None:
    """Same number of points on one random cut for the identifiability fibre and the fibre of `chosen`.

    The chosen functions are identifiable, so the identifiability fibre (projected on U) lies in their fibre: its
    count is at most theirs, and at least 1 (the point itself). When their fibre has one point, so does it, and its
    Gröbner basis with one more variable is not computed (Covid model (Gevertz): 27 of 41 s)."""
    hs, p = prep.hs, prep.p
    var = {u: hs.unknown_var[u] for u in U}
    r = {u: int(rng.integers(1, p)) for u in U}
    # the fibre of the chosen functions at the same point, on the same cut
    xhat = {u: hs.value[var[u]] for u in U}
    names, F, _ = _fibre_system(chosen, U, p, rng, point=xhat)
    index = {v: names.index(u) for u, v in var.items()}
    for sl in hs.slices:
        eq: Poly = {}
        for m, c in sl.items():
            mm = [0] * len(names)
            for i, e in enumerate(m):
                if e:
                    mm[index[hs.names[i]]] += e
            eq[tuple(mm)] = c
        F.append(eq)
    ell2: Poly = {}
    for u in U:
        mm = [0] * len(names)
        mm[names.index(u)] = 1
        ell2[tuple(mm)] = r[u]
    n_fun = _count(eng, names, F, ell2, p, cap)
    if n_fun == 1:
        return True
    # the SIAN side (weighted variables: u = V^w)
    nv = len(hs.names)
    ell: Poly = {}
    for u in U:
        m = [0] * nv
        m[hs.names.index(var[u])] = hs.weight.get(var[u], 1)
        ell[tuple(m)] = r[u]
    n_sian = _count(eng, hs.names, hs.F, ell, p, cap)
    if n_sian is None or n_fun is None:
        return None
    return n_sian == n_fun


def _verified(prep: Any, eng: GroebnerEngine, cands: list[_Candidate], U: list[str], rounds: int = 2
              ) -> list[_Candidate]:
    """Keep the candidates that are constant on the solutions at fresh random points (normal forms)."""
    for _ in range(rounds):
        if not cands:
            break
        hs = prep.point()
        p = prep.p
        var = [hs.unknown_var[u] for u in U]
        xhat = {u: hs.value[v] for u, v in zip(U, var)}
        idx = [hs.names.index(v) for v in var]
        ws = [hs.weight.get(v, 1) for v in var]
        rels = []
        for g in cands:
            rel = _relation(g, U, xhat, p)
            out: Poly = {}
            for m, c in rel.items():
                mm = [0] * len(hs.names)
                for i, e in enumerate(m[:-1]):
                    if e:
                        mm[idx[i]] += e * ws[i]
                out[tuple(mm)] = (out.get(tuple(mm), 0) + c) % p
            rels.append({k: v for k, v in out.items() if v})
        nfs = eng.normal_forms(hs.names, p, hs.F, rels)
        cands = [g for g, nf in zip(cands, nfs) if not nf]
    return cands


#: Largest number of new degree-3 monomials the automatic degree raise accepts (in 15 unknowns: 680).
_MAX_MONOMIALS = 1000
#: Highest power u^s searched for an unknown with s solutions.
_MAX_POWER = 8


def _denominators(U: list[str], single: Sequence[str]) -> list[tuple[int, ...]]:
    """Step 1's denominators Q: 1 and every unknown not globally identifiable."""
    return [tuple(0 for _ in U)] + [tuple(int(i == j) for j in range(len(U))) for i, u in enumerate(U) if u not in single]


def _search_and_select(search: _Search, prep: Any, eng: GroebnerEngine, U: list[str], single: list[str],
                       rng: np.random.Generator) -> list[_Candidate]:
    """Steps 1-4 of the module docstring: candidates per denominator, verified, then the simplest generators."""
    cands: list[_Candidate] = []
    unsure: set[_Candidate] = set()
    for Q in _denominators(U, single):
        Kc = search.solve(Q)
        found = search.functions(Kc, Q)
        cands += found
        if Q in search.unconverged:
            unsure.update(found)
    singles = [_Candidate.unknown(u, search.U) for u in single]
    pool = list(dict.fromkeys(c for c in cands if c not in singles))
    # the candidates of a denominator whose points ran out are checked at fresh points (the others passed a point
    # that cut nothing, step 3)
    bad = set(unsure) - set(_verified(prep, eng, [c for c in pool if c in unsure], U))
    pool = sorted([c for c in pool if c not in bad], key=_complexity)  # sort the survivors only
    # the globally identifiable unknowns are distinct variables, none a function of the others: kept without a test
    # (one engine run each saved; HIV's 27 runs of the selection were mostly these)
    return _select(pool, U, eng, prep.p, rng, kept=singles)


def _short_locally(search: _Search, U: list[str], single: list[str]) -> bool:
    """Whether the locally identifiable candidates of `search`, with the globally identifiable unknowns, fall short of
    the field's transcendence degree: then no generators found among them give the whole field (local points only,
    no engine run)."""
    rows = [np.eye(len(U), dtype=np.int64)[[U.index(u) for u in single]]]
    rows += [search.local_gradients(Q) for Q in _denominators(U, single)]
    return _rank(np.concatenate(rows), search.p) < search.field_rank()


def _degree_too_low(search: _Search, U: list[str], single: list[str], may_raise: bool) -> bool:
    """Whether the candidates of the automatic degree 2 cannot give the whole field (:func:`_short_locally`; HIV), where
    the degree may be raised to 3: then the search of degree 2 is skipped, since the raise would discard its result."""
    return may_raise and _degree_three_fits(U, single) and _short_locally(search, U, single)


def _degree_three_fits(U: list[str], single: Sequence[str]) -> bool:
    """Whether the degree may be raised to 3: the new monomials (in the unknowns not globally identifiable) stay
    within ``_MAX_MONOMIALS``."""
    return len(monomial_exponents(len([u for u in U if u not in single]), 3)) <= _MAX_MONOMIALS


def _without_singles(search: _Search, prep: Any, eng: GroebnerEngine, U: list[str], all_unknowns: list[str],
                     single: list[str], rng: np.random.Generator) -> list[_Candidate] | None:
    """Step 1's first try: candidates free of the globally identifiable unknowns (they are in the field already;
    LV: 35 monomials instead of 84). Returns the generators when they are shown complete with those unknowns, else
    None (the search then runs on every monomial: a generator may need them, SLIQR's (In + L + Q)/S)."""
    sub = search.without(single)
    # cheap first (local points only): the candidates and the globally identifiable unknowns must reach the field's
    # transcendence degree (SLIQR, SEIR_1, HIV... do not: they need a globally identifiable unknown in a generator)
    if _short_locally(sub, U, single):
        return None
    chosen = _search_and_select(sub, prep, eng, U, single, rng)
    # then the generators themselves (the search's global points may have left out some directions)
    vals = [int(v) for v in rng.integers(1, prep.p, size=len(U))]
    ech = RowEchelon(len(U), prep.p)
    for f in chosen:
        ech.add(_gradient(f, U, vals, prep.p))
    if ech.rank < search.field_rank():
        return None
    complete = (_complete_io(prep, eng, chosen, U, rng) if prep.io is not None
                else _complete(prep, eng, chosen, all_unknowns, rng))
    return chosen if complete else None


def _complete_io(prep: Any, eng: GroebnerEngine, chosen: list[_Candidate], U: list[str],
                 rng: np.random.Generator) -> bool:
    """On the input-output route: every generator of the route (which together give every identifiable function;
    the coefficients alone every identifiable function of the parameters, Ovchinnikov, Pogudin & Thompson (2023)) is
    constant on the fibre of `chosen` at a random point, i.e. lies in their field (normal forms of its relation
    num(v) den(v̂) - num(v̂) den(v) modulo their fibre ideal). U without states: the coefficients only."""
    from ._io import Columns

    gens, _ = prep.io
    p = prep.p
    names, F, xhat = _fibre_system(chosen, U, p, rng)
    model = {v: u for u, v in prep.hs.unknown_var.items()}  # ring name -> model name
    conv = Columns({v: names.index(u) for v, u in model.items() if u in U}, len(names), p)
    with_states = any(u in prep.system.states for u in U)
    rels: list[Poly] = []
    for a, b in (*gens.params, *(gens.states if with_states else ())):
        at = [xhat.get(model.get(v, ""), 0) for v in a.context().names()]
        rels.append(conv(a * (int(b(*at)) % p) - b * (int(a(*at)) % p)))
    return not any(eng.normal_forms(names, p, F, rels))


def _route_generators(prep: Any, U: list[str], single: Sequence[str] = ()) -> list[_Candidate]:
    """The input-output route's generators (coefficient ratios and the outputs' Lie derivatives, which together give
    every identifiable function) over the unknowns U, smallest first; those involving other variables (inputs) are
    left out. Monomial factors in the globally identifiable unknowns `single` are cancelled (they change no field the
    singles are in), and integer contents."""
    gens, _ = prep.io
    model = {v: u for u, v in prep.hs.unknown_var.items()}  # ring name -> model name
    col = {u: i for i, u in enumerate(U)}
    out = []
    for a, b in (*gens.params, *gens.states):
        g = a.gcd(b)
        if not g.is_constant():
            a, b = a / g, b / g
        idx = [col.get(model.get(v, "")) for v in a.context().names()]
        parts = []
        for q in (a, b):
            terms = []
            for m, c in zip(q.monoms(), q.coeffs()):
                if any(e and idx[k] is None for k, e in enumerate(m)):
                    terms = None
                    break
                e = [0] * len(U)
                for k, x in enumerate(m):
                    if x:
                        e[idx[k]] += x
                terms.append((tuple(e), int(c), 1))
            if terms is None:
                break
            parts.append(tuple(terms))
        if len(parts) < 2:
            continue
        # f and f*m/k (m a monomial in the singles, k a rational) generate the same field with the singles: the
        # numerator and the denominator each lose their own such factor, and both get positive leading coefficients
        out_parts = []
        for t in parts:
            shift = [min(e[i] for e, _, _ in t) if U[i] in single else 0 for i in range(len(U))]
            k = math.gcd(*[c for _, c, _ in t]) * (1 if t[0][1] > 0 else -1)
            out_parts.append(tuple((tuple(x - y for x, y in zip(e, shift)), c // k, d) for e, c, d in t))
        parts = out_parts
        if parts[0] == parts[1] or not any(any(e) for t in parts for e, _, _ in t):  # a constant
            continue
        out.append((len(a) + len(b), _Candidate(*parts, U)))  # printed only if kept (CGV1990: 1 s for all of them)
    # fewest terms first, then lowest degree; ties in a fixed order of the exact terms (printing hundreds of large
    # expressions to sort them by their text took most of this function's time, CGV1990)
    out.sort(key=lambda t: (t[0], max(sum(e) for part in (t[1].num, t[1].den) for e, _, _ in part), t[1].num, t[1].den))
    return [c for _, c in out]


def _add_route_generators(prep: Any, eng: GroebnerEngine, chosen: list[_Candidate], U: list[str],
                          rng: np.random.Generator, deadline: float) -> list[_Candidate] | None:
    """`chosen` completed by the route's own generators, smallest first, each kept unless it is a function of those
    kept (:func:`_select` from `chosen`): where the search's simple forms (numerators of degree <= 3 over monomials)
    miss part of the field (StructuralIdentifiability.jl's St, QY: generators with polynomial denominators), the
    result is still a complete generating set, in the route's coefficients. None when the Gröbner bases of the
    growing fibres do not finish before `deadline`."""
    single = [u for u in U if _Candidate.unknown(u, U) in chosen]
    return _select(_route_generators(prep, U, single), U, eng, prep.p, rng, kept=chosen, deadline=deadline)


def _completed_on_the_route(prep: Any, eng: GroebnerEngine, search: _Search, chosen: list[_Candidate], U: list[str],
                            single: list[str], rng: np.random.Generator, max_degree: int, auto_degree: bool,
                            powers: dict, notes: list[str], t0: float) -> tuple[list[_Candidate], bool, int]:
    """On the input-output route: the completeness check (exact), a search one degree higher when
    it fails and the degree was automatic, then step 6 of the module docstring, given as long as the search took
    (at least 10 s; Linear_compartment_hard: the growing fibres take minutes, the search 12 s). Returns (chosen,
    complete, degree)."""
    complete = _complete_io(prep, eng, chosen, U, rng)
    rest = [u for u in U if u not in single]
    if complete is False and auto_degree and (max_degree < 3 or powers) and _degree_three_fits(U, single):
        # a generator of the field needs a numerator of degree 3 (HIV: c*q*x) or a power: search again one degree
        # higher, the new monomials only in the unknowns not globally identifiable, with the powers (the
        # completeness check below says whether that was enough)
        max_degree = 3
        prev, search = search, _Search(prep, eng, U, max_degree, top=rest, powers=powers)
        if prev.U == U:
            search.share_points(prev)  # CGV1990: 122 of its 328 local points
        chosen = _search_and_select(search, prep, eng, U, single, rng)
        complete = _complete_io(prep, eng, chosen, U, rng)
    if complete is False:
        spent = time.perf_counter() - t0
        more = _add_route_generators(prep, eng, chosen, U, rng, time.perf_counter() + max(10.0, spent))
        if more is None:
            notes.append(f"completing the generators with the input-output coefficients stopped after "
                         f"{max(10.0, spent):.0f} s (as long as the search took)")
        elif _complete_io(prep, eng, more, U, rng):
            notes.append(f"the last {len(more) - len(chosen)} generator(s) are input-output coefficients (or the "
                         f"outputs' Lie derivatives): the simple forms searched (numerators of degree <= {max_degree} "
                         "over monomials) do not give every identifiable function")
            chosen, complete = more, True
    return chosen, complete, max_degree


def _set_aside(prep: Any, eng: GroebnerEngine, search: _Search, U: list[str], single: list[str], max_degree: int,
               powers: dict, notes: list[str]) -> tuple[list[str], _Search, dict, list[_Candidate] | None]:
    """Step 0 of the module docstring. Unknowns whose axis is a direction of the local kernel (a state that no output
    sees, a parameter only it uses; NF-kB's x15): no identifiable function depends on them, and the search leaves them
    out. Returns (the unknowns searched, the search, the powers, the generators when nothing is left to search: every
    other unknown globally identifiable; PK2: the search doubled the global check's time, NF-kB: 15 min of it)."""
    axes = set(prep.local.extra.get("unseen_unknowns", ()))
    unseen = [u for u in U if u in axes and u not in single]
    rest = [u for u in U if u not in unseen]
    if all(u in single for u in rest):
        notes.append("every unknown is globally identifiable: the unknowns themselves generate every identifiable "
                     "function" if not unseen else
                     f"the globally identifiable unknowns generate every identifiable function: the others "
                     f"({', '.join(unseen)}) are each a direction of the local kernel by themselves, so no "
                     "identifiable function depends on them")
        return rest, search, powers, [_Candidate.unknown(u, rest) for u in single]
    if unseen:
        notes.append(f"{', '.join(unseen)}: each a direction of the local kernel by itself, so in no identifiable "
                     "function; the search leaves them out")
        powers = {u: k for u, k in powers.items() if u in rest}
        search = _Search(prep, eng, rest, max_degree, powers=powers)
    return rest, search, powers, None


#: Fibre systems of the input-output route above this many terms are rebuilt on a part of the route's coefficients
#: that generates the same field (:func:`_fewer_generators`). EAIHRD: 328 equations, 362,211 terms, 77 s per random
#: point in msolve; on 6 of its 316 coefficients, 1,094 terms and 19 s.
_FEWER_ABOVE = 50_000


def _fewer_generators(prep: Any, eng: GroebnerEngine, rng: np.random.Generator, notes: list[str]) -> None:
    """The input-output route's fibre on fewer coefficients (in place): the smallest coefficient ratios whose
    differentials reach the rank of all of them, then every other coefficient shown to lie in their field (the normal
    form of its relation modulo their fibre ideal is 0: :func:`_complete_io`'s test), adding the smallest that do not
    (three a round, four rounds) until all do. The two sets then generate the same field, so the fibre, the global
    verdicts at its points and the completeness checks are the same, and every random point of the search is a
    Gröbner basis of a much smaller system (the route's coefficients are highly redundant: the large ones are
    polynomials in the small ones; Ovchinnikov, Pogudin & Thompson (2023) for why all of them generate the field). The
    outputs' Lie derivatives are kept. Nothing changes when the system is small or the rounds run out."""
    import dataclasses

    from ._io import Columns, fibre, tangent_rows

    gens, extra = prep.io
    n = len(gens.params)
    if sum(map(len, prep.hs.F)) <= _FEWER_ABOVE or n < 2:
        return
    t0 = time.perf_counter()
    p, hs = prep.p, prep.hs
    variables = [hs.unknown_var[u] for u in prep.unknown_names]
    rows, _ = tangent_rows(gens, variables, p, rng)
    full = RowEchelon(len(variables), p)
    full.add_many(rows[:n])

    def size(i: int) -> int:
        return len(gens.params[i][0]) + len(gens.params[i][1])

    chosen: list[int] = []
    ech = RowEchelon(len(variables), p)
    for i in sorted(range(n), key=size):
        if ech.rank == full.rank:
            break
        if ech.add(rows[i]):
            chosen.append(i)
    own = set(gens.params[0][0].context().names())
    names = [v for v in hs.names if v == "z_sat" or v in own]
    conv = Columns({v: names.index(v) for v in names if v != "z_sat"}, len(names), p)
    for _ in range(4):
        sub = dataclasses.replace(gens, params=[gens.params[i] for i in chosen], states=[], cache={})
        F, values = fibre(sub, names, [], p, rng)
        rest = [i for i in range(n) if i not in chosen]
        rels = []
        for i in rest:
            a, b = gens.params[i]
            at = [values.get(v, 0) for v in a.context().names()]
            rels.append(conv(a * (int(b(*at)) % p) - b * (int(a(*at)) % p)))
        bad = [i for i, nf in zip(rest, eng.normal_forms(names, p, F, rels)) if nf]
        if not bad:
            break
        chosen += sorted(bad, key=size)[:3]
    else:
        return
    before = sum(map(len, hs.F))
    prep.io = (dataclasses.replace(gens, params=[gens.params[i] for i in sorted(chosen)], cache={}), extra)
    prep.hs = prep.point()
    notes.append(f"the fibre on {len(chosen)} of the {n} coefficients, which generate the same field (the others shown "
                 f"to lie in it): {sum(map(len, prep.hs.F))} terms instead of {before} "
                 f"({time.perf_counter() - t0:.1f} s)")


def find_identifiable_functions(system: System, *, unknown_params: Any = "all", inputs: Any = "generic",
                                with_states: bool = True, max_degree: int | None = None, local: Any = None,
                                engine: str | GroebnerEngine = "auto", seed: int = 0,
                                reparametrize_model: bool = True, route: str = "auto") -> IdentifiableFunctions:
    r"""Generators of the identifiable (observable) functions of a rational model, simplest first.

    Parameters
    ----------
    system : System
        A model; exp, log, sin, cos, atan and non-integer powers are rewritten first (:mod:`._identifiable_rewrite`).
    unknown_params : sequence of str or "all", default "all"
        The unknown parameters.
    inputs : "generic", "constant" or int, optional
        As for :func:`analyze`.
    with_states : bool, default True
        Include the states (initial values): observable functions; False gives functions of the
        parameters only (as StructuralIdentifiability.jl's default).
    max_degree : int, optional
        Degree of the numerators searched (denominators: 1 or one unknown). Default 3 for up to 8
        unknowns, else 2; parameters only on SIAN's system (where completeness is not checked), 3 up to 12.
    reparametrize_model : bool, default True
        With ``with_states``, also rewrite the model in the generators found
        (:func:`nlobs.analysis.reparametrize`, ``reparametrization``).
    route : {"auto", "io", "sian"}, default "auto"
        As for :func:`global_identifiability`: ``"io"`` the fibre of the input-output equations' coefficients and
        the outputs' Lie derivatives (one output, generic inputs), ``"sian"`` SIAN's system of output derivatives,
        ``"auto"`` the first where it applies (why not: in ``notes``).

    Other Parameters
    ----------------
    local : ObservabilityReport, optional
        The local analysis of the same question, if already computed.
    engine : str or GroebnerEngine, default "auto"
    seed : int, default 0

    Returns
    -------
    IdentifiableFunctions

    Examples
    --------
    >>> from nlobs import System
    >>> two = System(states=["x0", "x1"], f=["-(a01 + a21)*x0 + a12*x1", "a21*x0 - a12*x1"], outputs=["y"],
    ...              h=["x0"], params={"a01": 1.0, "a21": 1.0, "a12": 1.0})
    >>> find_identifiable_functions(two, with_states=False).functions   # doctest: +SKIP
    ('a01*a12', 'a01 + a12 + a21')
    """
    from ._lie import function_checks

    t0 = time.perf_counter()
    require_system(system, "find_identifiable_functions")
    eng = engine if isinstance(engine, GroebnerEngine) else get_engine(engine)
    if eng is None:
        return IdentifiableFunctions(with_states=with_states, refused=NO_ENGINE)
    if not all(is_rational(e) for e in (*system.f, *system.h)):   # rewritten, the generators written back
        return _non_rational(system, unknown_params, inputs, with_states, max_degree, engine, seed, route)
    if route not in ("auto", "io", "sian"):
        raise ModelError(f"`route` must be 'auto', 'io' or 'sian', got {route!r}")
    prep = None
    notes: list[str] = []
    if route == "auto":
        return _race(system, dict(unknown_params=unknown_params, inputs=inputs, with_states=with_states,
                                  max_degree=max_degree, local=local, engine=engine, seed=seed,
                                  reparametrize_model=reparametrize_model))
    if local is None:  # the real-valued kernel directions are not used here
        local = _local_of(system, unknown_params, inputs, None, (), seed)
    try:
        if route != "sian":
            try:
                prep = _prepare_io(system, unknown_params=unknown_params, inputs=inputs, local=local, seed=seed,
                                   eng=eng)
            except NotApplicable as e:
                spent = time.perf_counter() - t0
                return IdentifiableFunctions(with_states=with_states, seconds=spent,
                                             refused=f"the input-output route does not apply: {e} (known after "
                                                     f"{spent:.1f} s)")
            committed()  # under route="auto": the equations are known, the search runs to its end
            _fewer_generators(prep, eng, np.random.default_rng([seed, 46]), notes)
        if prep is None:
            prep = _prepare(system, unknown_params=unknown_params, inputs=inputs, local=local, seed=seed)
    except NotRational as e:
        return IdentifiableFunctions(with_states=with_states, refused=f"{e} (the global check rewrites exp, sin, sqrt... "
                                     "into a rational model by adding states; identifiable functions do not yet)")
    method = IO_METHOD if prep.io is not None else SIAN_METHOD
    rng = np.random.default_rng([seed, 99])
    params = [u for u in prep.unknown_names if u not in system.states]
    U = list(prep.unknown_names) if with_states else params
    auto_degree = max_degree is None
    if max_degree is None:
        max_degree = _default_degree(len(U), with_states, prep.io is not None)
    if max_degree < 1:
        raise ModelError(f"`max_degree` must be >= 1, got {max_degree}")
    search = _Search(prep, eng, U, max_degree)
    dec = _decide(prep, eng, 8, also=search.mono_polys(prep.hs))  # the search's first point: the same basis
    if prep.partial and (dec["locally_only"] or dec["non_identifiable"]):
        # several outputs: the projections' generators may generate only part of the identifiable functions; they
        # settle the question only when every unknown is globally identifiable (then the unknowns generate it all)
        notes.append(f"on SIAN's system, not the input-output route: with {system.n_outputs} outputs the projections "
                     "decide only when every unknown is globally identifiable")
        prep = _prepare(system, unknown_params=unknown_params, inputs=inputs, local=prep.local, seed=seed)
        method = SIAN_METHOD
        if auto_degree:
            max_degree = _default_degree(len(U), with_states, False)
        search = _Search(prep, eng, U, max_degree)
        dec = _decide(prep, eng, 8, also=search.mono_polys(prep.hs))
    nfs = dec.pop("also_nfs")
    # an unknown with s solutions is a root of a polynomial of degree s with identifiable coefficients; when the
    # solutions differ by roots of unity its s-th power is identifiable (p53 in SI.jl's benchmarks: p22^4): the
    # search includes those powers from the start (its first point's normal forms are then computed anew)
    powers = {lo.name: lo.solutions for lo in dec["locally_only"]
              if lo.name in U and lo.solutions is not None and max(3, max_degree) < lo.solutions <= _MAX_POWER}
    if powers:
        search = _Search(prep, eng, U, max_degree, powers=powers)
    else:
        search.known_point(nfs)
    single = [u for u in U if u in dec["globally"]]
    io_complete = prep.io is not None  # the route's generators decide completeness, with or without the states
    complete: bool | None = None
    rest, search, powers, chosen = _set_aside(prep, eng, search, U, single, max_degree, powers, notes)
    if chosen is not None:
        complete, io_complete = True, True
    elif single and (io_complete or with_states) and (chosen := _without_singles(search, prep, eng, rest, U, single,
                                                                                 rng)) is not None:
        complete = True
    elif _degree_too_low(search, rest, single, io_complete and auto_degree and max_degree < 3 and not powers):
        # the completeness check below fails on these and raises the degree
        chosen = [_Candidate.unknown(u, rest) for u in single]
    else:
        chosen = _search_and_select(search, prep, eng, rest, single, rng)
    if io_complete and complete is None:
        chosen, complete, max_degree = _completed_on_the_route(prep, eng, search, chosen, rest, single, rng, max_degree,
                                                               auto_degree, powers, notes, t0)
    texts = tuple(_text(f) for f in chosen)
    # the local check of every generator in one local analysis (each is a gradient-in-row-space test)
    checks = tuple(c.observable for c in function_checks(system, list(texts), unknown_params=prep.local.unknown_params,
                                                         inputs=inputs, seed=seed)) if texts else ()
    if not all(checks):
        notes.append("a returned function failed the local check: " + ", ".join(t for t, c in zip(texts, checks) if not c))
    complete = _completeness(prep, eng, chosen, U, rng, complete, with_states, io_complete, max_degree, notes)
    rep = None
    if with_states and reparametrize_model and texts and all(checks):
        rep = reparametrize(system, texts, unknown_params=prep.local.unknown_params, seed=seed)
    return IdentifiableFunctions(functions=texts, with_states=with_states, complete=complete, local_checks=checks,
                                 notes=tuple(notes), seconds=time.perf_counter() - t0, engine_seconds=eng.seconds,
                                 reparametrization=rep, method=method)


def _completeness(prep: Any, eng: GroebnerEngine, chosen: Any, U: list[str], rng: np.random.Generator,
                  complete: bool | None, with_states: bool, io_complete: bool, max_degree: int,
                  notes: list[str]) -> bool | None:
    """Whether the generators `chosen` give every identifiable function (checked where it can be: with the states, or
    on the input-output route), with a note saying what was not checked; None when it was not."""
    if not (with_states or io_complete):
        notes.append(f"completeness NOT checked: on SIAN's system it is checked with the states included "
                     f"(with_states=True); numerators of degree <= {max_degree} were searched, and an identifiable "
                     "function of the parameters that needs a higher degree may be missing (raise max_degree)")
        return complete
    if complete is None and not io_complete:
        complete = _complete(prep, eng, chosen, U, rng)
    if complete is False:
        notes.append(f"the generators found with numerators of degree <= {max_degree} and monomial denominators "
                     "do not give every identifiable function")
    elif complete is None:
        notes.append("completeness NOT checked: the fibres have more points on the random cut than are counted "
                     "(48); some identifiable functions may be missing")
    return complete


#: Unknowns up to which the search's numerators go to degree 3 by default (beyond: 2). Parameters only on SIAN's
#: system, whose completeness is not checked (it is with the states, and on the input-output route), the degree is
#: the only guard, and degree 3 is kept up to :data:`_DEGREE_3_UNCHECKED` unknowns: Example 6 of Meshkat,
#: Eisenberg & DiStefano, "An algorithm for finding globally identifiable parameter combinations of nonlinear ODE
#: models using Gröbner bases" (2009; in StructuralIdentifiability.jl's tests) has 10 parameters and a generator of
#: degree 3, c*k1*mu2 + c*mu1*mu2, that degree 2 misses (3.0 s against 1.1 s on this VM; 286 monomials against 66).
_DEGREE_3 = 8
_DEGREE_3_UNCHECKED = 12


def _default_degree(n_unknowns: int, with_states: bool, on_io_route: bool) -> int:
    """The default ``max_degree`` of :func:`find_identifiable_functions` (see :data:`_DEGREE_3`)."""
    if n_unknowns <= _DEGREE_3 or (not with_states and not on_io_route and n_unknowns <= _DEGREE_3_UNCHECKED):
        return 3
    return 2


def _non_rational(system: System, unknown_params: Any, inputs: Any, with_states: bool, max_degree: int | None, engine: Any,
                  seed: int, route: str) -> IdentifiableFunctions:
    """A model with exp, log, sin, cos, atan or non-integer powers: rewritten into a rational one, the generators
    written back in its names (:mod:`._identifiable_rewrite`); refused, with the reason, where that does not apply."""
    from ._identifiable_rewrite import nonrational_functions

    kw = dict(inputs=inputs, with_states=with_states, max_degree=max_degree, engine=engine, seed=seed, route=route)
    unknown = list(system.param_names) if unknown_params == "all" else list(unknown_params or ())
    try:
        return nonrational_functions(system, unknown, find_identifiable_functions, kw, IdentifiableFunctions)
    except NotRational as e:
        return IdentifiableFunctions(with_states=with_states, refused=f"{e}; the local verdicts stand")


def _race(system: System, kw: dict[str, Any]) -> IdentifiableFunctions:
    """route="auto": the input-output route with a head start, SIAN's system beside it when the head start runs out
    or after a refusal (module _budget); the local analysis is done here once for both."""
    from ._global import race_routes

    if kw["local"] is None:
        kw["local"] = _local_of(system, kw["unknown_params"], kw["inputs"], None, (), kw["seed"])
    return race_routes(find_identifiable_functions, system, kw, lambda r: not r.refused, "on SIAN's system")


def _text(f: _Candidate | sp.Expr) -> str:
    return str(f)
