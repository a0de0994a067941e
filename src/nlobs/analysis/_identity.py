r"""Deciding symbolic identities exactly: is :math:`e(x) \equiv 0`?

Every identity check of nlobs (the PDE and left inverse of KKL/PEBO/I&I, the mimicking
identities of an augmentation, Ψ of a high-gain observer, symmetries) goes through
:func:`decide_identity`. It never accepts a floating-point agreement as a proof.

1. **Rational expressions** (numbers, symbols, ``+ - * /`` and integer powers) are evaluated at
   random integer points in **exact rational arithmetic**. A non-zero value proves
   :math:`e \not\equiv 0` (a witness is returned). If e is not identically zero, its numerator
   after putting everything over one denominator is a non-zero polynomial N of total degree at
   most d (bounded from the expression tree), and by the Schwartz-Zippel lemma a point drawn
   uniformly from :math:`\{1, \dots, B\}^m` is a root of N with probability at most d/B. Points
   where a denominator vanishes are redrawn, which raises the bound to at most d/(B - d'), d' the
   degree of the denominators. k independent points that all give 0 leave a probability at most
   :math:`(d/(B - d'))^k` that a non-identity is declared to hold; k is chosen so that this is
   below 2⁻⁶⁴ and the bound is reported.
2. **Expressions with sin, cos, tan, exp, sinh, ... and other functions** are made rational by
   substitution: after :func:`sympy.expand_trig`, :math:`\sin a = 2\tau/(1+\tau^2)`,
   :math:`\cos a = (1-\tau^2)/(1+\tau^2)`, :math:`\tan a = 2\tau/(1-\tau^2)` with a fresh τ per
   argument a (the rational parametrisation of the circle, τ = tan(a/2)); :math:`e^{k g} = E_g^k`
   (k an integer) with a fresh :math:`E_g`; hyperbolic functions through exp; every other
   non-rational sub-term (log, sqrt, atan, abs, ...) becomes a fresh variable. If the result is
   identically zero *with the new variables independent*, the original identity holds (substituting
   the actual functions back is a ring homomorphism), and the test of step 1 decides that with the
   same error bound. A non-zero result proves nothing (the functions may be related), so then
3. :func:`sympy.simplify` is tried (a symbolic proof when it reaches 0), and otherwise the
   difference is evaluated at random points to 30 significant digits: clearly non-zero there
   (relative size above 1e-20) means the identity **fails**, with the point; agreement at every
   point leaves the identity **undecided**, reported as such, never as holding.

References
----------
J. T. Schwartz, "Fast probabilistic algorithms for verification of polynomial identities",
J. ACM 27 (1980); R. Zippel, "Probabilistic algorithms for sparse polynomials", EUROSAM 1979.
"""

from __future__ import annotations

import random
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import sympy as sp

__all__ = ["Identity", "decide_identity", "decide_identities", "ExactRank", "exact_generic_rank", "is_rational"]

#: The largest probability of a wrong "holds" verdict that :func:`decide_identity` accepts.
TARGET_ERROR = 2.0 ** -64
#: Sample points are drawn from {1, ..., B}.
_BOUND = 2 ** 40
#: Largest estimated size (bits) of one exact evaluation before the test gives up (undecided).
_MAX_BITS = 4_000_000
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
        text = f"{self.status}: {self.method}"
        if self.witness:
            text += f" (at {self.at()} the difference is {self.value})"
        return text


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
        elif isinstance(e, (sp.Rational, sp.Float)) or e.is_Number:
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
            if k >= 0:
                out = (k * n, k * d)
            else:
                self.inverted += n
                out = (-k * d, -k * n)
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
        elif isinstance(node, sp.Mul):
            val = Fraction(1)
            for a in node.args:
                val *= ev(a)
                if val == 0:
                    break
        elif isinstance(node, sp.Pow):
            b, k = ev(node.base), int(node.exp)
            if k < 0:
                if b == 0:
                    raise ZeroDivisionError
                b, k = 1 / b, -k
            val = b ** k
        else:  # pragma: no cover - excluded by _Degrees
            raise _Undecidable(type(node).__name__)
        cache[node] = val
        return val

    try:
        return ev(e)
    except ZeroDivisionError:
        return None


def _rational_test(e: sp.Expr, rng: random.Random, what: str) -> Identity:
    """Decide a rational expression by exact evaluation at random integer points (see the module)."""
    deg = _Degrees()
    dn, dd = deg.of(e)
    syms = sorted(e.free_symbols, key=lambda s: s.name)
    d_bad = dd + deg.inverted
    if dn == 0 and not syms:
        val = _evaluate(e, {})
        if val is None:
            return Identity("undecided", f"{what}: a constant with a zero denominator", "division by zero")
        return (Identity("holds", f"{what}: the difference is the constant 0", "exact arithmetic", 0.0) if val == 0 else
                Identity("fails", f"{what}: the difference is the non-zero constant {val}", "exact arithmetic",
                         witness={}, value=str(val)))
    B = max(_BOUND, 2 ** 20 * (dn + d_bad + 1))
    if (dn + d_bad + 1) * B.bit_length() > _MAX_BITS:
        raise _Undecidable(f"degree bound {dn} too large for exact evaluation")
    q = dn / (B - d_bad) if B > d_bad else 1.0
    k, bound = 0, 1.0
    redraws = 0
    while bound > TARGET_ERROR:
        point = {s: rng.randint(1, B) for s in syms}
        val = _evaluate(e, point)
        if val is None:
            redraws += 1
            if redraws > 50:
                return Identity("undecided", f"{what}: a denominator vanished at 50 random points", "division by zero")
            continue
        k += 1
        if val != 0:
            wit = {s.name: str(v) for s, v in point.items()}
            return Identity("fails", f"{what}: not identically zero", "exact arithmetic at a witness point", 0.0, wit,
                            _short(val))
        if q == 0:
            bound = 0.0
            break
        bound *= q
    how = (f"{what}: 0 at {k} random integer point(s) in [1, 2^{B.bit_length() - 1}]^{len(syms)}, exact arithmetic; "
           f"numerator degree <= {dn}, so P(wrong) <= {bound:.1e} (Schwartz-Zippel)")
    return Identity("holds", how, f"exact arithmetic (Schwartz-Zippel, P(wrong) <= {bound:.0e})", bound)


def _short(v: Fraction) -> str:
    s = str(v)
    return s if len(s) <= 60 else f"{float(v):.6g}"


# ---------------------------------------------------------------------------------------------
# Making non-rational expressions rational by substitution
# ---------------------------------------------------------------------------------------------
class _Rationaliser:
    """Replaces non-rational sub-terms by fresh variables (see the module docstring, step 2)."""

    def __init__(self) -> None:
        self.atoms: dict[tuple[str, sp.Expr], sp.Symbol] = {}
        self.count = 0

    def _fresh(self, kind: str, key: sp.Expr) -> sp.Symbol:
        k = (kind, key)
        if k not in self.atoms:
            self.count += 1
            self.atoms[k] = sp.Dummy(f"{kind}{self.count}")
        return self.atoms[k]

    def __call__(self, e: sp.Expr) -> sp.Expr:
        if e.is_Atom:
            return e if (e.is_Symbol or e.is_Rational or e.is_Float) else self._fresh("const", e)  # pi, E, I: fresh
        if isinstance(e, (sp.Add, sp.Mul)):
            return e.func(*[self(a) for a in e.args])
        if isinstance(e, sp.Pow):
            if e.exp.is_Integer:
                return self(e.base) ** e.exp
            if e.base == sp.E:
                return self(sp.exp(e.exp))
            if e.exp.is_Rational:  # b**(p/q) = (b**(1/q))**p (principal branch)
                return self._fresh("root", sp.Pow(sp.expand(e.base), sp.Rational(1, e.exp.q), evaluate=False)) ** int(e.exp.p)
            return self._fresh("pow", sp.expand(e))
        if isinstance(e, (sp.sin, sp.cos, sp.tan)):
            tau = self._fresh("tau", sp.expand(e.args[0]))   # multiple angles were expanded by expand_trig
            if isinstance(e, sp.sin):
                return 2 * tau / (1 + tau**2)
            if isinstance(e, sp.cos):
                return (1 - tau**2) / (1 + tau**2)
            return 2 * tau / (1 - tau**2)
        if isinstance(e, sp.exp):
            arg = sp.expand(e.args[0])
            out = sp.Integer(1)
            for term in sp.Add.make_args(arg):
                c, g = term.as_coeff_Mul()
                if c.is_Integer and abs(int(c)) <= 64:
                    out *= self._fresh("E", g) ** int(c)
                else:
                    out *= self._fresh("E", term)
            return out
        if isinstance(e, (sp.sinh, sp.cosh, sp.tanh)):
            return self(e.rewrite(sp.exp))
        return self._fresh(type(e).__name__, e.func(*[sp.expand(a) for a in e.args]))


# ---------------------------------------------------------------------------------------------
# The decision
# ---------------------------------------------------------------------------------------------
def _numeric(e: sp.Expr, rng: random.Random, samples: int = 6) -> tuple[str, dict[str, str] | None, str, float]:
    """Evaluate e at random points in (0.1, 0.9) to 30 digits: ("nonzero", point, value) or ("zero", ...)."""
    syms = sorted(e.free_symbols, key=lambda s: s.name)
    terms = sp.Add.make_args(e)
    worst = 0.0
    seen = 0
    for _ in range(samples):
        point = {s: sp.Rational(rng.randint(100, 900), 1000) + sp.Rational(rng.randint(1, 999), 10**6) for s in syms}
        try:
            v = sp.N(e.xreplace(point), _DIGITS)
            scale = max([abs(complex(sp.N(t.xreplace(point), 15))) for t in terms] + [1e-300])
        except (TypeError, ValueError, ZeroDivisionError, OverflowError):
            continue
        if not v.is_number or v.has(sp.zoo, sp.nan, sp.oo, -sp.oo):
            continue
        try:
            cv = complex(v)
        except (TypeError, ValueError):
            continue
        if cv != cv or abs(cv) == float("inf"):
            continue
        seen += 1
        rel = abs(cv) / max(scale, 1e-300)
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
    floats = e.atoms(sp.Float)
    return e.xreplace({f: sp.Rational(repr(float(f))) for f in floats}) if floats else e


def decide_identity(lhs: Any, rhs: Any = 0, *, seed: int = 0, simplify: bool = True) -> Identity:
    """Decide whether ``lhs - rhs`` is identically zero in its free symbols.

    Parameters
    ----------
    lhs, rhs : SymPy expressions (or numbers)
    seed : int
        Seed of the random points (the verdict is reproducible for a seed).
    simplify : bool
        Try :func:`sympy.simplify` when the exact tests cannot decide (it can be slow on large
        expressions; it is skipped above 3000 operations).

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
            got = _rational_test(er, rng, "with sin/cos/tan by tan(a/2), exp(k g) by E_g^k and other functions as independent "
                                          "variables")
            if got.holds:
                return got
    except _Undecidable:
        pass
    nonzero = _numeric(e, rng)
    if nonzero[0] == "nonzero":
        return Identity("fails", "the difference is not zero at a random point", f"evaluation to {_DIGITS} digits", 0.0,
                        nonzero[1], nonzero[2])
    if simplify and sp.count_ops(e) <= 3000:
        try:
            if sp.simplify(e) == 0:
                return Identity("holds", "SymPy simplify reduces the difference to 0", "symbolic (SymPy simplify)")
        except (TypeError, ValueError, RecursionError, NotImplementedError):
            pass
    if nonzero[0] == "zero":
        return Identity("undecided", f"not proved; |difference| <= {max(nonzero[3], 1e-30):.0e} × the size of its terms at "
                        f"{nonzero[2]} random point(s) in (0.1, 0.9), evaluated to {_DIGITS} digits",
                        f"numerical agreement only (not a proof)")
    return Identity("undecided", "not proved, and the difference could not be evaluated at random points",
                    "no evidence")


def decide_identities(pairs: Iterable[tuple[Any, Any]], *, seed: int = 0) -> list[Identity]:
    """:func:`decide_identity` for each (lhs, rhs) pair."""
    return [decide_identity(a, b, seed=seed + k) for k, (a, b) in enumerate(pairs)]


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


def _exact_rank(rows: list[list[Fraction]]) -> int:
    M = [r[:] for r in rows]
    rank, ncol = 0, len(M[0]) if M else 0
    for c in range(ncol):
        piv = next((i for i in range(rank, len(M)) if M[i][c] != 0), None)
        if piv is None:
            continue
        M[rank], M[piv] = M[piv], M[rank]
        for i in range(rank + 1, len(M)):
            if M[i][c] != 0:
                f = M[i][c] / M[rank][c]
                M[i] = [a - f * b for a, b in zip(M[i], M[rank])]
        rank += 1
    return rank


def exact_generic_rank(M: sp.Matrix, *, seed: int = 0, tries: int = 3) -> ExactRank:
    """Generic rank of a matrix of expressions.

    Rational entries: the exact rank at random integer points (the largest seen); a full rank is
    a proof, a lower rank is the generic rank with probability at least 1 - (d/B)^tries.
    Otherwise the entries are evaluated in floating point at random points in (0.1, 0.9) and the
    rank is numpy's (evidence says so).

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

    rng = random.Random(seed)
    full = min(M.shape)
    syms = sorted(M.free_symbols, key=lambda s: s.name)
    if all(is_rational(e) for e in M):
        deg = _Degrees()
        d = sum(max((deg.of(e)[0] + deg.of(e)[1] for e in M.row(i)), default=0) for i in range(M.shape[0]))
        d_bad = d + deg.inverted
        best, k = 0, 0
        for _ in range(tries + 20):
            pt = {s: rng.randint(1, _BOUND) for s in syms}
            vals = [[_evaluate(e, pt) for e in M.row(i)] for i in range(M.shape[0])]
            if any(v is None for row in vals for v in row):
                continue
            k += 1
            best = max(best, _exact_rank(vals))
            if best == full or k >= tries:
                break
        if best == full:
            return ExactRank(best, "exact arithmetic at a random point (full rank: a proof)", 0.0)
        bound = min(1.0, (d / max(_BOUND - d_bad, 1))) ** max(k, 1)
        return ExactRank(best, f"exact arithmetic at {k} random point(s); the generic rank is larger with probability "
                               f"<= {bound:.0e} (Schwartz-Zippel)", bound)
    from ..model._translate import NUMPY, translate

    ranks = []
    nrng = np.random.default_rng(seed)
    for _ in range(6):
        pt = {s: float(nrng.uniform(0.1, 0.9)) for s in syms}
        with np.errstate(all="ignore"):
            A = np.array([[float(translate(e, pt, NUMPY)) for e in M.row(i)] for i in range(M.shape[0])], dtype=float)
        if np.all(np.isfinite(A)):
            ranks.append(int(np.linalg.matrix_rank(A)))
    best = max(ranks) if ranks else 0
    return ExactRank(best, f"floating point at {len(ranks)} random point(s) (numpy matrix_rank)", float("nan"))
