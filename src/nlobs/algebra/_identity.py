r"""Deciding symbolic identities exactly: is :math:`e(x) \equiv 0`?

Every identity check of nlobs (the PDE and left inverse of KKL/PEBO/I&I, the mimicking
identities of an augmentation, Ψ of a high-gain observer, symmetries) goes through
:func:`decide_identity`. It never accepts a floating-point agreement as a proof.

1. **Rational expressions** (numbers, symbols, ``+ - * /`` and integer powers) are evaluated at
   random integer points in **exact rational arithmetic**. A non-zero value proves
   :math:`e \not\equiv 0` (a witness is returned). If e is not identically zero, its numerator
   after putting everything over one denominator is a non-zero polynomial N of total degree at
   most d (bounded from the expression tree), and by the Schwartz-Zippel lemma a point drawn
   uniformly from :math:`\{1, \dots, B\}^m`, B = 2⁴⁰, is a root of N with probability at most
   d/B. Points where a denominator vanishes are redrawn, which raises the bound to at most
   d/(B - d'), d' the degree of the denominators. k independent points that all give 0 leave a
   probability at most :math:`(d/(B - d'))^k` that a non-identity is declared to hold; k is chosen
   so that this is below 2⁻⁶⁴ and the bound is reported. Degrees d + d' above 10⁵ (values of
   more than 4·10⁶ bits) are not evaluated: the identity is then decided by steps 2-3 or left
   undecided. If a denominator vanishes at 50 points it is taken to be identically zero and the
   identity is undecided.
2. **Expressions with sin, cos, tan, exp, sinh, ... and other functions** are made rational by
   substitution: after :func:`sympy.expand_trig`, :math:`\sin a = 2\tau/(1+\tau^2)`,
   :math:`\cos a = (1-\tau^2)/(1+\tau^2)`, :math:`\tan a = 2\tau/(1-\tau^2)` with a fresh τ per
   argument a (the rational parametrisation of the circle, τ = tan(a/2)); :math:`e^{k g} = E_g^k`
   (k an integer) with a fresh :math:`E_g`; hyperbolic functions through exp; every other
   non-rational sub-term (log, atan, abs, x**y, ...) becomes a fresh variable, and so does the
   principal root :math:`b^{1/q}` of :math:`b^{p/q} = b^m (b^{1/q})^r` (p = mq + r, 0 ≤ r < q).
   If the result is
   identically zero *with the new variables independent*, the original identity holds (substituting
   the actual functions back is a ring homomorphism), and the test of step 1 decides that with the
   same error bound. A non-zero result proves nothing (the functions may be related), so then
3. the difference is evaluated at 6 random points of the grid {0.1, 0.100001, ..., 0.9}^m to 30
   significant digits (points where it is not a finite number are skipped): clearly non-zero there
   (relative size above 1e-20 of its largest term) means the identity **fails**, with the point.
   Otherwise :func:`sympy.simplify` is tried for at most 5 s (a symbolic proof when it reaches 0);
   agreement at every point without a proof leaves the identity **undecided**, reported as such,
   never as holding.

References
----------
J. T. Schwartz, "Fast probabilistic algorithms for verification of polynomial identities",
J. ACM 27 (1980); R. Zippel, "Probabilistic algorithms for sparse polynomials", EUROSAM 1979.
"""

from __future__ import annotations

import cmath
import math
import random
from collections.abc import Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import mpmath
import sympy as sp

from ..model._budget import SymbolicTimeLimit, symbolic_time_limit

__all__ = ["Identity", "decide_identity", "ExactRank", "exact_generic_rank", "is_rational"]

#: The largest probability of a wrong "holds" verdict that :func:`decide_identity` accepts.
TARGET_ERROR = 2.0 ** -64
#: Sample points are drawn from {1, ..., B}.
_BOUND = 2 ** 40
#: Largest degree bound d + d' evaluated exactly (a value then has at most ~4·10⁶ bits); far below B.
_MAX_DEGREE = 100_000
#: Denominators that vanish at this many random points in a row are taken as identically zero.
_REDRAWS = 50
#: Points of the floating-point evaluation (step 3).
_SAMPLES = 6
#: Time SymPy's simplify may take on one identity (step 3) before the identity is left undecided.
_SIMPLIFY_SECONDS = 5.0
#: Relative size above which a high-precision value counts as certainly non-zero.
_NONZERO = 1e-20
_DIGITS = 30


class _Undecidable(Exception):
    """The exact evaluation is not possible (a non-rational node) or too large."""


@dataclass(frozen=True)
class Identity:
    """The verdict on one identity lhs = rhs.

    Attributes
    ----------
    status : {"holds", "fails", "undecided"}
    method : str
        How the verdict was reached, in words (with the numbers: points, degree bound).
    evidence : str
        The kind of evidence: ``"exact arithmetic (Schwartz-Zippel, P(wrong) <= ...)"``,
        ``"symbolic (SymPy simplify)"``, ``"exact arithmetic at a witness point"``,
        ``"evaluation to 30 digits"``, or why it is undecided.
    error_bound : float
        Probability that a ``"holds"`` verdict is wrong (0 for a proof; 0 for ``"fails"``).
    witness : mapping of symbol name to value, or None
        For ``"fails"``: a point where lhs - rhs is not zero, and its value in `value`.
    value : str
        The difference at the witness point.
    """

    status: str
    method: str
    evidence: str
    error_bound: float = 0.0
    witness: Mapping[str, str] | None = None
    value: str = ""

    @property
    def holds(self) -> bool:
        return self.status == "holds"

    @property
    def fails(self) -> bool:
        return self.status == "fails"

    @property
    def decided(self) -> bool:
        return self.status != "undecided"

    def at(self) -> str:
        """The witness point as text (``"x1 = 3, x2 = 7"``), or ''."""
        return ", ".join(f"{k} = {v}" for k, v in (self.witness or {}).items())

    def where(self) -> str:
        """`` (at x1 = 3, x2 = 7 the difference is -1/5)`` for a failed identity with a witness, else ''."""
        return f" (at {self.at()} the difference is {self.value})" if self.witness else ""

    def __str__(self) -> str:
        return f"{self.status}: {self.method}{self.where()}"


# ---------------------------------------------------------------------------------------------
# Exact evaluation of rational expressions
# ---------------------------------------------------------------------------------------------
def is_rational(e: sp.Expr) -> bool:
    """Whether `e` is built from numbers, symbols, + and * and integer powers only."""
    for node in sp.preorder_traversal(e):
        if isinstance(node, (sp.Symbol, sp.Rational, sp.Float)) or isinstance(node, (sp.Add, sp.Mul)):
            continue
        if isinstance(node, sp.Pow) and node.exp.is_Integer:
            continue
        return False
    return True


@dataclass
class _Degrees:
    """Degree bounds of (numerator, denominator) per node, and of every inverted quantity."""

    cache: dict[sp.Basic, tuple[int, int]] = field(default_factory=dict)
    inverted: int = 0

    def of(self, e: sp.Basic) -> tuple[int, int]:
        got = self.cache.get(e)
        if got is not None:
            return got
        if isinstance(e, sp.Symbol):
            out = (1, 0)
        elif isinstance(e, (sp.Rational, sp.Float)):
            out = (0, 0)
        elif isinstance(e, sp.Add):
            parts = [self.of(a) for a in e.args]
            dd = sum(p[1] for p in parts)
            out = (max(p[0] + dd - p[1] for p in parts), dd)
        elif isinstance(e, sp.Mul):
            parts = [self.of(a) for a in e.args]
            out = (sum(p[0] for p in parts), sum(p[1] for p in parts))
        elif isinstance(e, sp.Pow) and e.exp.is_Integer:
            n, d = self.of(e.base)
            k = int(e.exp)
            if k < 0:
                self.inverted += n
                out = (-k * d, -k * n)
            else:
                out = (k * n, k * d)
        else:
            raise _Undecidable(f"not rational: {type(e).__name__}")
        self.cache[e] = out
        return out


def _fraction(num: sp.Basic) -> Fraction:
    r = sp.Rational(num)  # exact for Float too (its binary value)
    return Fraction(int(r.p), int(r.q))


def _evaluate(e: sp.Expr, point: Mapping[sp.Symbol, int]) -> Fraction | None:
    """e at `point` in exact arithmetic; None when a denominator vanishes."""
    cache: dict[sp.Basic, Fraction] = {}

    def ev(node: sp.Basic) -> Fraction:
        got = cache.get(node)
        if got is not None:
            return got
        if isinstance(node, sp.Symbol):
            val = Fraction(point[node])
        elif node.is_Number:
            val = _fraction(node)
        elif isinstance(node, sp.Add):
            val = Fraction(0)
            for a in node.args:
                val += ev(a)
        elif isinstance(node, sp.Mul):   # every factor, even after a 0: a vanishing denominator anywhere means None
            val = Fraction(1)
            for a in node.args:
                val *= ev(a)
        elif isinstance(node, sp.Pow):
            b, k = ev(node.base), int(node.exp)
            val = b ** k   # a negative k with b == 0 raises ZeroDivisionError
        else:  # pragma: no cover - excluded by _Degrees
            raise _Undecidable(type(node).__name__)
        cache[node] = val
        return val

    try:
        return ev(e)
    except ZeroDivisionError:
        return None


def _draw(rng: random.Random, syms: list[sp.Symbol]) -> dict[sp.Symbol, int]:
    """A point drawn uniformly from {1, ..., B}^m (B = 2⁴⁰), the sample space of the Schwartz-Zippel bound."""
    return {s: rng.randint(1, _BOUND) for s in syms}


def _sorted_symbols(e: sp.Basic) -> list[sp.Symbol]:
    return sorted(e.free_symbols, key=lambda s: s.name)


def _rational_test(e: sp.Expr, rng: random.Random, what: str) -> Identity:
    """Decide a rational expression by exact evaluation at random integer points (see the module)."""
    deg = _Degrees()
    dn, dd = deg.of(e)
    syms = _sorted_symbols(e)
    d_bad = dd + deg.inverted
    if not syms:
        val = _evaluate(e, {})
        if val is None:
            return Identity("undecided", f"{what}: a constant with a zero denominator", "division by zero")
        return (Identity("holds", f"{what}: the difference is the constant 0", "exact arithmetic") if val == 0 else
                Identity("fails", f"{what}: the difference is the non-zero constant {_short(val)}", "exact arithmetic",
                         witness={}, value=_short(val)))
    if dn + d_bad > _MAX_DEGREE:
        raise _Undecidable(f"degree bound {dn + d_bad} too large for exact evaluation")
    q = dn / (_BOUND - d_bad)
    k, bound, redraws = 0, 1.0, 0
    while bound > TARGET_ERROR:
        point = _draw(rng, syms)
        val = _evaluate(e, point)
        if val is None:
            redraws += 1
            if redraws == _REDRAWS:
                return Identity("undecided", f"{what}: a denominator vanished at {redraws} random points",
                                "division by zero")
            continue
        k += 1
        if val != 0:
            wit = {s.name: str(v) for s, v in point.items()}
            return Identity("fails", f"{what}: not identically zero", "exact arithmetic at a witness point", 0.0, wit,
                            _short(val))
        bound *= q
    how = (f"{what}: 0 at {k} random integer point(s) in [1, 2^{_BOUND.bit_length() - 1}]^{len(syms)}, exact arithmetic; "
           f"numerator degree <= {dn}, so P(wrong) <= {bound:.1e} (Schwartz-Zippel)")
    return Identity("holds", how, f"exact arithmetic (Schwartz-Zippel, P(wrong) <= {bound:.0e})", bound)


def _short(v: Fraction) -> str:
    """v exactly if that takes at most 60 characters, else to 6 digits (any size: no float overflow, and
    no decimal string of a huge integer, which Python refuses above 4300 digits)."""
    if abs(v.numerator).bit_length() + v.denominator.bit_length() <= 256:
        s = str(v)
        if len(s) <= 60:
            return s
    return mpmath.nstr(mpmath.mpf(v.numerator) / v.denominator, strip_zeros=False)   # nstr's default: 6 digits


# ---------------------------------------------------------------------------------------------
# Making non-rational expressions rational by substitution
# ---------------------------------------------------------------------------------------------
class _Rationaliser:
    """Replaces non-rational sub-terms by fresh variables (see the module docstring, step 2).

    Each fresh variable is keyed by what it stands for: ``("tan", a)`` for tan(a/2), ``("exp", g)``
    for exp(g), ``("root", b, q)`` for the principal root b^(1/q) (b expanded, so equal bases written
    differently share it), and any other non-rational term by itself (its arguments expanded).
    """

    def __init__(self) -> None:
        self.atoms: dict[object, sp.Symbol] = {}

    def _fresh(self, key: object) -> sp.Symbol:
        if key not in self.atoms:
            self.atoms[key] = sp.Dummy()
        return self.atoms[key]

    def __call__(self, e: sp.Expr) -> sp.Expr:
        if e.is_Atom:
            return e if (e.is_Symbol or e.is_Rational or e.is_Float) else self._fresh(e)  # pi, E, I: fresh
        if isinstance(e, (sp.Add, sp.Mul)):
            return e.func(*[self(a) for a in e.args])
        if isinstance(e, sp.Pow):
            if e.exp.is_Integer:
                return self(e.base) ** e.exp
            if e.exp.is_Rational:  # b**(p/q) = b**m * (b**(1/q))**r, p = m q + r, 0 <= r < q (principal branch)
                m, r = divmod(int(e.exp.p), int(e.exp.q))
                return self(e.base) ** m * self._fresh(("root", sp.expand(e.base), int(e.exp.q))) ** r
            return self._fresh(sp.expand(e))
        if isinstance(e, (sp.sin, sp.cos, sp.tan)):
            tau = self._fresh(("tan", sp.expand(e.args[0])))   # multiple angles were expanded by expand_trig
            if isinstance(e, sp.sin):
                return 2 * tau / (1 + tau**2)
            if isinstance(e, sp.cos):
                return (1 - tau**2) / (1 + tau**2)
            return 2 * tau / (1 - tau**2)
        if isinstance(e, sp.exp):
            out = sp.Integer(1)
            for term in sp.Add.make_args(sp.expand(e.args[0])):
                c, g = term.as_coeff_Mul()
                if c.is_Integer and abs(c) <= 64:
                    out *= self._fresh(("exp", g)) ** c
                else:
                    out *= self._fresh(("exp", term))
            return out
        if isinstance(e, (sp.sinh, sp.cosh, sp.tanh)):
            return self(e.rewrite(sp.exp))
        return self._fresh(e.func(*[sp.expand(a) if isinstance(a, sp.Expr) else a for a in e.args]))  # Piecewise: pairs


# ---------------------------------------------------------------------------------------------
# The decision
# ---------------------------------------------------------------------------------------------
def _grid_point(rng: random.Random, syms: list[sp.Symbol]) -> dict[sp.Symbol, sp.Rational]:
    """A point of the grid {0.1, 0.100001, ..., 0.9}^m (exact rationals), away from 0 and 1."""
    return {s: sp.Rational(rng.randint(100_000, 900_000), 1_000_000) for s in syms}


def _numeric(e: sp.Expr, rng: random.Random) -> tuple[str, dict[str, str] | None, str, float]:
    """Evaluate e to 30 digits at `_SAMPLES` grid points: ("nonzero", point, value, |e|/scale) at the first
    point where it is clearly not zero, else ("zero", None, points evaluated, largest |e|/scale), or
    ("none", ...) if it is not a finite number at any point. The scale is the largest |term| of e there."""
    syms = _sorted_symbols(e)
    terms = sp.Add.make_args(e)
    worst, seen = 0.0, 0
    for _ in range(_SAMPLES):
        point = _grid_point(rng, syms)
        try:
            cv = complex(sp.N(e.xreplace(point), _DIGITS))
            scale = max(abs(complex(sp.N(t.xreplace(point), _DIGITS))) for t in terms)
        except (TypeError, ValueError, ZeroDivisionError, OverflowError):
            continue
        if not (cmath.isfinite(cv) and math.isfinite(scale)):
            continue
        seen += 1
        rel = abs(cv) / scale if scale else 0.0
        if rel > _NONZERO:
            return "nonzero", {s.name: str(p) for s, p in point.items()}, f"{cv.real:.6g}" if cv.imag == 0 else f"{cv:.6g}", rel
        worst = max(worst, rel)
    return ("zero" if seen else "none"), None, str(seen), worst


def _as_expr(v: Any) -> sp.Expr:
    """A SymPy expression or a number (never text: nothing is parsed here)."""
    if isinstance(v, sp.Basic):
        return v
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise TypeError(f"decide_identity: expected SymPy expressions or numbers, got {type(v).__name__}")
    return sp.Integer(v) if isinstance(v, int) else sp.Rational(repr(float(v)))


def _exact_floats(e: sp.Expr) -> sp.Expr:
    """Floats as the exact rationals of their shortest decimal form (0.1 -> 1/10), as the model does
    with parameters; SymPy would otherwise compare 0.1 and 1/10 in floating point."""
    return e.xreplace({f: sp.Rational(repr(float(f))) for f in e.atoms(sp.Float)})


def decide_identity(lhs: Any, rhs: Any = 0, *, seed: int = 0, simplify: bool = True) -> Identity:
    """Decide whether ``lhs - rhs`` is identically zero in its free symbols.

    Parameters
    ----------
    lhs, rhs : SymPy expressions (or numbers)
    seed : int
        Seed of the random points (the verdict is reproducible for a seed).
    simplify : bool
        Try :func:`sympy.simplify` when the exact tests cannot decide (it can be slow on large
        expressions: it is skipped above 3000 operations and given up after 5 s inside SymPy).

    Returns
    -------
    Identity
        ``"holds"`` (exact: a proof, or Schwartz-Zippel with error probability at most 2⁻⁶⁴),
        ``"fails"`` (with a witness point), or ``"undecided"`` (with the numeric evidence).
    """
    e = _exact_floats(_as_expr(lhs)) - _exact_floats(_as_expr(rhs))
    rng = random.Random(seed)
    if e == 0:
        return Identity("holds", "the difference is 0 as written", "symbolic (structural)")
    try:
        if is_rational(e):
            return _rational_test(e, rng, "rational expression")
        r = _Rationaliser()
        er = r(sp.expand_trig(e))
        if is_rational(er):
            got = _rational_test(er, rng, "with sin/cos/tan by tan(a/2), exp(k g) by E_g^k, roots b^(1/q) and other functions "
                                          "as independent variables")
            if got.holds:
                return got
    except _Undecidable:
        pass
    nonzero = _numeric(e, rng)
    if nonzero[0] == "nonzero":
        return Identity("fails", "the difference is not zero at a random point", f"evaluation to {_DIGITS} digits", 0.0,
                        nonzero[1], nonzero[2])
    gave_up = ""
    if simplify and sp.count_ops(e) <= 3000:
        try:
            with symbolic_time_limit(_SIMPLIFY_SECONDS):
                if sp.simplify(e) == 0:
                    return Identity("holds", "SymPy simplify reduces the difference to 0", "symbolic (SymPy simplify)")
        except SymbolicTimeLimit:
            gave_up = f"; SymPy simplify gave up after {_SIMPLIFY_SECONDS:g} s"
        except (TypeError, ValueError, RecursionError, NotImplementedError):
            pass   # a step's SymbolicBudgetError (a ValueError) caught here is raised again by the budget itself
    if nonzero[0] == "zero":
        return Identity("undecided", f"not proved; |difference| <= {max(nonzero[3], 1e-30):.0e} × the size of its terms at "
                        f"{nonzero[2]} random point(s) in (0.1, 0.9), evaluated to {_DIGITS} digits{gave_up}",
                        "numerical agreement only (not a proof)")
    return Identity("undecided", f"not proved, and the difference could not be evaluated at random points{gave_up}",
                    "no evidence")


# ---------------------------------------------------------------------------------------------
# Generic rank
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ExactRank:
    """The generic rank of a symbolic matrix, with the kind of evidence.

    ``rank`` is a lower bound of the generic rank that is exact (a proof) when it equals the
    number of rows or columns; otherwise it equals the generic rank with probability at least
    1 - `error_bound` (exact evaluation), or is a floating-point estimate.
    """

    rank: int
    evidence: str
    error_bound: float


def exact_generic_rank(M: sp.Matrix, *, seed: int = 0, tries: int = 3) -> ExactRank:
    """Generic rank of a matrix of expressions.

    Rational entries: the exact rank (SymPy's DomainMatrix over QQ) at random integer points, the
    largest seen; a full rank is a proof, a lower rank is the generic rank with probability at
    least 1 - (d/(B - d'))^tries, d the sum over rows of the largest degree bound of an entry (a
    bound of the degree of any minor over a common denominator) and d' that of the denominators.
    Otherwise the entries are evaluated in floating point at random points of (0.1, 0.9) and the
    rank is numpy's (evidence says so; error_bound is nan).

    Parameters
    ----------
    M : sympy.Matrix
    seed : int
        Seed of the random points.
    tries : int
        Points evaluated (more lower the error probability of a rank-deficient verdict).

    Returns
    -------
    ExactRank
    """
    import numpy as np
    from sympy import QQ
    from sympy.polys.matrices import DomainMatrix

    rng = random.Random(seed)
    full = min(M.shape)
    syms = _sorted_symbols(M)
    rows = [list(M.row(i)) for i in range(M.shape[0])]
    if full == 0:
        return ExactRank(0, "an empty matrix", 0.0)
    if all(is_rational(e) for e in M):
        deg = _Degrees()
        d = sum(max(sum(deg.of(e)) for e in row) for row in rows)
        d_bad = d + deg.inverted
        best, k, attempts = 0, 0, 0
        while attempts < tries + 20:
            attempts += 1
            pt = _draw(rng, syms)
            vals = [[_evaluate(e, pt) for e in row] for row in rows]
            if any(v is None for row in vals for v in row):
                continue
            k += 1
            best = max(best, DomainMatrix([[QQ(v.numerator, v.denominator) for v in row] for row in vals], M.shape, QQ).rank())
            if best == full:
                return ExactRank(best, "exact arithmetic at a random point (full rank: a proof)", 0.0)
            if k == tries:
                break
        if k == 0:
            return ExactRank(0, f"no evidence: a denominator vanished at all {attempts} random points", 1.0)
        bound = (d / (_BOUND - d_bad)) ** k
        return ExactRank(best, f"exact arithmetic at {k} random point(s); the generic rank is larger with probability "
                               f"<= {bound:.0e} (Schwartz-Zippel)", bound)
    from ..model._translate import NUMPY, translate

    ranks = []
    for _ in range(_SAMPLES):
        pt = {s: float(v) for s, v in _grid_point(rng, syms).items()}
        with np.errstate(all="ignore"):
            A = np.array([[float(translate(e, pt, NUMPY)) for e in row] for row in rows])
        if np.all(np.isfinite(A)):
            ranks.append(int(np.linalg.matrix_rank(A)))
    return ExactRank(max(ranks, default=0), f"floating point at {len(ranks)} of {_SAMPLES} random point(s) "
                                            "(numpy matrix_rank)", float("nan"))
