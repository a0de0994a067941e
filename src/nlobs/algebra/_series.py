r"""Truncated power series of a model's solution, with gradients, over GF(p) or in floating point.

A model's right-hand side and output are turned into a *straight-line program* (a list of
elementary operations, shared sub-expressions computed once). The program is then run on
truncated power series in t: the solution is :math:`x(t) = \sum_k x_k t^k` with
:math:`x_{k+1} = [f(x(t), u(t), t)]_k / (k+1)`, each coefficient computed from the earlier ones
("relaxed" evaluation, as in Sedoglavic's algorithm). Every coefficient is a *dual number*: its
value and its gradient with respect to the unknowns (x(0), unknown parameters, coefficients of
unknown inputs), so the Jacobian of the output jets comes out of one pass (forward mode).

Non-rational functions get auxiliary series that satisfy a first-order ODE
:math:`\dot v = w\,\dot g` (``exp``: w = v; ``log``: w = 1/g; ``g**a``: w = a v/g; ``sin``/``cos``:
w = cos / -sin; ``atan``: w = 1/(1+g²)). Their initial values are *free generic values* when the
function is transcendental (exp, log, atan: the graph of a transcendental function of x is
Zariski-dense, so a generic value gives the same generic rank), a random point of the unit circle
for a sin/cos pair, and an exact r-th root modulo p for rational powers ``g**(q/r)``.
Over floats the true values are used.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from ..errors import ModelError
from ..model._budget import expand as budget_expand
from ..model._budget import short_str
from ._modular import MAX_TERMS, inv, root

__all__ = ["Program", "build_program", "SeriesRun", "Resample", "ModField", "FloatField"]


class Resample(Exception):
    """The random point hit a zero denominator or a non-residue: draw another point."""


# ----------------------------------------------------------------------------------------------
# straight-line program
# ----------------------------------------------------------------------------------------------
@dataclass
class Node:
    op: str  # const cfree x theta u w t add scale mul recip aux
    args: tuple[int, ...] = ()
    data: Any = None  # const: Rational; cfree: float; x/theta/u/w: index; add: const term; scale: Rational; aux: (kind, extra)
    w: int = -1  # aux: the node w with v' = w g'
    pair: int = -1  # sin/cos: the partner node


@dataclass
class Program:
    """A straight-line program for (f, h) and optional extra functions of the state."""

    nodes: list[Node]
    f: list[int]
    h: list[int]
    extra: list[int]
    roots: frozenset[int]  # odd parts of the denominators of rational exponents
    notes: tuple[str, ...]
    rational: bool  # no division and no auxiliary series: a polynomial program
    #: The largest power of two dividing a rational exponent's denominator (1: no square roots). Modulo p ≡ 3 (mod 4)
    #: only half the elements are squares, so a random point has a square root of each of k radicands with
    #: probability 2^-k (twelve tanks' sqrt(h_i): 1/4096); leaves drawn as this power of a random element make every
    #: radicand that is a monomial of leaves (sqrt(x), sqrt(k*x), max(x, 0)**0.5) a square, and the points stay
    #: generic (Schwartz-Zippel: a polynomial of degree d in r**e vanishes at a random r with probability <= e*d/p).
    square_power: int = 1


class _Builder:
    def __init__(self, leaves: Mapping[sp.Symbol, Node], regime: Callable[[sp.Expr], float] | None = None):
        self.regime = regime  # evaluates an expression at the regime point (None: the default branches)
        self.nodes: list[Node] = []
        self.memo: dict[sp.Basic, int] = {}
        self.leaf: dict[sp.Symbol, int] = {}
        for s, node in leaves.items():
            self.leaf[s] = self.push(node)
        self.exp_lcm: dict[sp.Expr, int] = {}
        self.trig_lcm: dict[sp.Expr, int] = {}
        self.exp_base: dict[sp.Expr, int] = {}
        self.trig_base: dict[sp.Expr, tuple[int, int]] = {}
        self.roots: set[int] = set()
        self.square_power = 1
        self.notes: set[str] = set()
        self.polynomial = True

    def push(self, node: Node) -> int:
        self.nodes.append(node)
        return len(self.nodes) - 1

    def const(self, q: sp.Rational) -> int:
        key = ("const", q)
        if key not in self.memo:
            self.memo[key] = self.push(Node("const", data=sp.Rational(q)))
        return self.memo[key]

    # -- prepass: groups of exp / trig arguments, so exp(x) and exp(2x) share one series --------
    @staticmethod
    def _terms(arg: sp.Expr) -> list[tuple[sp.Rational, sp.Expr]]:
        out = []
        for term in sp.Add.make_args(budget_expand(arg, what="analyze (exponential and trigonometric arguments)")):
            c, m = term.as_coeff_Mul()
            c = sp.Rational(repr(float(c))) if isinstance(c, sp.Float) else c
            if not isinstance(c, sp.Rational):
                c, m = sp.Integer(1), term
            out.append((c, m))
        return out

    def prepass(self, exprs: Sequence[sp.Expr]) -> None:
        for e in exprs:
            for a in e.atoms(sp.exp):
                for c, m in self._terms(a.args[0]):
                    self.exp_lcm[m] = sp.ilcm(self.exp_lcm.get(m, 1), c.q)
            for a in (*e.atoms(sp.sin), *e.atoms(sp.cos)):
                for c, m in self._terms(a.args[0]):
                    self.trig_lcm[m] = sp.ilcm(self.trig_lcm.get(m, 1), c.q)

    # -- nodes -----------------------------------------------------------------------------
    def add(self, items: list[int], c: sp.Rational = sp.Integer(0)) -> int:
        if not items:
            return self.const(c)
        if len(items) == 1 and c == 0:
            return items[0]
        return self.push(Node("add", tuple(items), data=sp.Rational(c)))

    def scale(self, a: int, c: sp.Rational) -> int:
        if c == 1:
            return a
        return self.push(Node("scale", (a,), data=sp.Rational(c)))

    def mul(self, a: int, b: int) -> int:
        return self.push(Node("mul", (a, b)))

    def recip(self, a: int) -> int:
        self.polynomial = False
        return self.push(Node("recip", (a,)))

    def ipow(self, a: int, n: int) -> int:
        if n == 0:
            return self.const(sp.Integer(1))
        if n < 0:
            return self.recip(self.ipow(a, -n))
        out, base = -1, a
        while n:
            if n & 1:
                out = base if out < 0 else self.mul(out, base)
            n >>= 1
            if n:
                base = self.mul(base, base)
        return out

    def aux(self, kind: str, g: int, extra: Any = None) -> int:
        self.polynomial = False
        return self.push(Node("aux", (g,), data=(kind, extra)))

    def exp_of(self, arg: sp.Expr) -> int:
        factors = []
        for c, m in self._terms(arg):
            L = self.exp_lcm.get(m, c.q)
            if m not in self.exp_base:
                v = self.aux("exp", self.build(m / L))
                self.nodes[v].w = v
                self.exp_base[m] = v
            factors.append(self.ipow(self.exp_base[m], int(c * L)))
        out = factors[0]
        for fct in factors[1:]:
            out = self.mul(out, fct)
        return out

    def trig_of(self, fn: type, arg: sp.Expr) -> int:
        dummies, subs = [], {}
        total = sp.Integer(0)
        for c, m in self._terms(arg):
            L = self.trig_lcm.get(m, c.q)
            if m not in self.trig_base:
                g = self.build(m / L)
                s = self.aux("sin", g)
                co = self.aux("cos", g)
                self.nodes[s].w, self.nodes[s].pair = co, co
                self.nodes[co].w, self.nodes[co].pair = self.scale(s, sp.Integer(-1)), s
                self.trig_base[m] = (s, co)
            th = sp.Dummy("th")
            dummies.append(th)
            s, co = self.trig_base[m]
            subs[sp.sin(th)], subs[sp.cos(th)] = s, co
            total += int(c * L) * th
        expanded = budget_expand(sp.expand_trig(fn(total)), what="analyze (trigonometric expansion)")
        saved = dict(self.memo)
        self.memo.update(subs)
        try:
            return self.build(expanded)
        finally:
            self.memo = {**saved, **{k: v for k, v in self.memo.items() if not (k in subs or k.has(*dummies) if isinstance(k, sp.Basic) else False)}}

    def build(self, e: sp.Basic) -> int:
        if e in self.memo:
            return self.memo[e]
        out = self._build(e)
        self.memo[e] = out
        return out

    def _build(self, e: sp.Basic) -> int:
        if e.is_Symbol:
            if e in self.leaf:
                return self.leaf[e]
            raise ModelError(f"cannot analyse: the symbol `{e}` has no role here (not a state, input or parameter)")
        if e.is_Rational:
            return self.const(e)
        if e.is_Float:
            return self.const(sp.Rational(repr(float(e))))
        if e.is_number:  # pi, E, sqrt(2), exp(3): an irrational constant
            self.notes.add("irrational constants are treated as generic values (exact for transcendental ones such as pi)")
            return self.push(Node("cfree", data=float(e)))
        if e.is_Add:
            c, rest = e.as_coeff_Add()
            c = sp.Rational(repr(float(c))) if isinstance(c, sp.Float) else c
            return self.add([self.build(a) for a in sp.Add.make_args(rest)], c)
        if e.is_Mul:
            c, rest = e.as_coeff_Mul()
            c = sp.Rational(repr(float(c))) if isinstance(c, sp.Float) else c
            factors = [self.build(a) for a in sp.Mul.make_args(rest)]
            out = factors[0]
            for fct in factors[1:]:
                out = self.mul(out, fct)
            return self.scale(out, c)
        if e.is_Pow:
            b, ex = e.args
            if b.has(sp.Abs, sp.sign, sp.Min, sp.Max):
                # the branch first, then the power: sqrt(max(x, 0)) on the branch max = 0 is 0, not a root of 0
                # (whose series has no derivative: every random point would be refused)
                resolved = b.replace(lambda a: isinstance(a, (sp.Abs, sp.sign, sp.Min, sp.Max)), self._branch)
                return self.build(sp.Pow(resolved, ex))
            if isinstance(ex, sp.Float):
                ex = sp.Rational(repr(float(ex)))
            if ex.is_Integer:
                return self.ipow(self.build(b), int(ex))
            if ex.is_Rational:
                q, r = int(ex.p), int(ex.q)
                odd = r
                while odd % 2 == 0:
                    odd //= 2
                if odd > 1:
                    self.roots.add(odd)
                self.square_power = max(self.square_power, r // odd)
                g = self.build(b)
                v = self.aux("pow", g, sp.Rational(q, r))
                self.nodes[v].w = self.scale(self.mul(v, self.recip(g)), sp.Rational(q, r))
                return v
            # b**ex with a symbolic or irrational exponent: exp(ex * log(b))
            lg = self._log(self.build(b))
            return self._exp_node(self.mul(self.build(ex), lg))
        if isinstance(e, sp.exp):
            return self.exp_of(e.args[0])
        if isinstance(e, sp.log):
            return self._log(self.build(e.args[0]))
        if isinstance(e, (sp.sin, sp.cos)):
            return self.trig_of(type(e), e.args[0])
        if isinstance(e, sp.tan):
            return self.build(sp.sin(e.args[0]) / sp.cos(e.args[0]))
        if isinstance(e, sp.sinh):
            a = e.args[0]
            return self.build((sp.exp(a) - sp.exp(-a)) / 2)
        if isinstance(e, sp.cosh):
            a = e.args[0]
            return self.build((sp.exp(a) + sp.exp(-a)) / 2)
        if isinstance(e, sp.tanh):
            a = e.args[0]
            return self.build((sp.exp(2 * a) - 1) / (sp.exp(2 * a) + 1))
        if isinstance(e, sp.atan):
            return self._atan(self.build(e.args[0]))
        if isinstance(e, sp.atan2):
            a, b = (self.build(x) for x in e.args)
            return self._atan(self.mul(a, self.recip(b)), two=(a, b))
        if isinstance(e, sp.asin):
            a = e.args[0]
            return self.build(sp.atan(a / sp.sqrt(1 - a**2)))
        if isinstance(e, sp.acos):
            a = e.args[0]
            return self.build(sp.pi / 2 - sp.atan(a / sp.sqrt(1 - a**2)))
        if isinstance(e, (sp.Abs, sp.sign, sp.Min, sp.Max)):
            return self.build(self._branch(e))
        raise ModelError(f"cannot analyse `{e}`: the function `{e.func}` is not supported by the generic-rank test")

    def _branch(self, e: sp.Expr) -> sp.Expr:
        """The smooth expression a piecewise node (abs, sign, min, max) equals in the analysed regime, with a note.

        With a regime point, the branch active there; without one: abs(g) = g and sign(g) = 1 (g > 0),
        and min/max equal their argument that is not a constant (the unsaturated regime of sat),
        else their first argument.
        """
        g = e.args[0]
        if isinstance(e, (sp.Abs, sp.sign)):
            if self.regime is None:
                s, why = 1, "assumed; choose the regime with `regime=`"
            else:
                v = self.regime(g)
                s, why = (1 if v >= 0 else -1), f"its argument is {v:.3g} at the regime point"
            what = "abs" if isinstance(e, sp.Abs) else "sign"
            value = s * g if what == "abs" else sp.Integer(s)
            self.notes.add(f"{what}({_short(g)}) is analysed where {_short(g)} {'>' if s > 0 else '<'} 0, as "
                           f"{_short(value)} ({why})")
            return value
        args = list(e.args)
        if self.regime is None:
            free = [a for a in args if not a.is_number]
            pick = free[0] if free else args[0]
            why = ("the unsaturated branch" if len(free) == 1 else "the first argument; choose the regime with `regime=`")
        else:
            vals = [self.regime(a) for a in args]
            best = min(vals) if isinstance(e, sp.Min) else max(vals)
            pick = next(a for a, v in zip(args, vals) if v == best and not a.is_number) if any(
                v == best and not a.is_number for a, v in zip(args, vals)) else args[vals.index(best)]
            why = "active at the regime point"
        name = "min" if isinstance(e, sp.Min) else "max"
        self.notes.add(f"{name}({', '.join(_short(a) for a in args)}) is analysed as {_short(pick)} ({why})")
        return pick

    def _exp_node(self, g: int) -> int:
        v = self.aux("exp", g)
        self.nodes[v].w = v
        return v

    def _log(self, g: int) -> int:
        v = self.aux("log", g)
        self.nodes[v].w = self.recip(g)
        return v

    def _atan(self, g: int, two: tuple[int, int] | None = None) -> int:
        v = self.aux("atan", g, two)
        self.nodes[v].w = self.recip(self.add([self.mul(g, g)], sp.Integer(1)))
        return v


def pretty(e: sp.Expr, limit: int = 40) -> str:
    """An expression as a model file writes it (abs, min, max), shortened for a message."""
    text = short_str(e, limit).strip("'")
    for a, b in (("Abs(", "abs("), ("Min(", "min("), ("Max(", "max(")):
        text = text.replace(a, b)
    return text


_short = pretty


def build_program(f: Sequence[sp.Expr], h: Sequence[sp.Expr], leaves: Mapping[sp.Symbol, Node],
                  extra: Sequence[sp.Expr] = (), regime: Callable[[sp.Expr], float] | None = None) -> Program:
    """Compile f, h (and `extra` functions) into one straight-line program over the given leaves.

    Piecewise functions (abs, sign, min, max) are replaced by their branch in the analysed regime:
    the one active where `regime` (an evaluator at a point) says, else the default branch.
    """
    b = _Builder(leaves, regime)
    exprs = [sp.expand_log(e, force=True) for e in (*f, *h, *extra)]
    b.prepass(exprs)
    idx = [b.build(e) for e in exprs]
    nf, nh = len(f), len(h)
    notes = tuple(sorted(b.notes))
    return Program(b.nodes, idx[:nf], idx[nf:nf + nh], idx[nf + nh:], frozenset(b.roots), notes, b.polynomial,
                   b.square_power)


# ----------------------------------------------------------------------------------------------
# fields
# ----------------------------------------------------------------------------------------------
class ModField:
    """GF(p) on int64 arrays."""

    exact = True

    def __init__(self, p: int):
        self.p = p
        self.dtype = np.int64

    def num(self, q: sp.Rational) -> int:
        den = int(q.q) % self.p
        if den == 0:
            raise Resample("a constant's denominator is divisible by the prime")
        return int(q.p) % self.p * inv(den, self.p) % self.p

    def red(self, a: np.ndarray) -> np.ndarray:
        return a % self.p

    def smul(self, a: Any, b: Any) -> int:
        return int(a) * int(b) % self.p

    def inv(self, a: Any) -> int:
        try:
            return inv(int(a), self.p)
        except ZeroDivisionError:
            raise Resample("a denominator vanished at the random point") from None

    def dot(self, a: np.ndarray, B: np.ndarray) -> np.ndarray:
        p = self.p
        if a.shape[0] <= MAX_TERMS:
            return (a @ B) % p
        out = np.zeros(B.shape[1:], dtype=np.int64)
        for i in range(0, a.shape[0], MAX_TERMS):
            out = (out + (a[i:i + MAX_TERMS] @ B[i:i + MAX_TERMS]) % p) % p
        return out


class FloatField:
    """float64 arithmetic (for kernel directions at a real point)."""

    exact = False
    dtype = np.float64

    def num(self, q: sp.Rational) -> float:
        return float(q)

    def red(self, a: np.ndarray) -> np.ndarray:
        return a

    def smul(self, a: Any, b: Any) -> float:
        return float(a) * float(b)

    def inv(self, a: Any) -> float:
        a = float(a)
        if a == 0.0 or not math.isfinite(a):
            raise Resample("a denominator vanished at the point")
        return 1.0 / a

    def dot(self, a: np.ndarray, B: np.ndarray) -> np.ndarray:
        return a @ B


# ----------------------------------------------------------------------------------------------
# evaluation
# ----------------------------------------------------------------------------------------------
#: Longest linear combination inlined into the nodes that use it (larger ones are computed once).
_INLINE = 32
#: Most terms of one row of a linear map evaluated in one product: 256 products of two reduced
#: values (< 2**27 each) stay below 2**62, so int64 cannot overflow; longer rows are split.
_ROW_TERMS = 256


@dataclass
class _Schedule:
    """How a program is run, one coefficient order at a time (computed once per program).

    Linear nodes (``add``, ``scale``) are flattened into linear combinations of the nodes that
    are actually stored ("materialised": leaves, non-linear nodes, and the linear nodes that are
    read again or too large to inline). Materialised nodes are sorted into levels (a node's level
    exceeds those of the nodes its current coefficient depends on); in each level the linear
    ones are evaluated together as one sparse product, the non-linear ones (``mul``, ``recip``,
    ``aux``) one by one. The next state coefficients x_{k+1} = f_k / (k+1) come from one more
    sparse product. Only the nodes whose earlier coefficients are read again keep a history
    (``hist``), so memory is O(nodes · M + history nodes · K · M), not O(nodes · K · M).
    """

    levels: list[list[tuple[str, Any]]]  # ("linear", (nodes, expansions, constants)) or ("node", index)
    hist: frozenset[int]
    scalar: dict[int, tuple[int, int]]  # mul nodes with a constant-in-t factor: (constant, series)
    leaves: list[int]
    f_rows: list[tuple[dict[int, sp.Rational], sp.Rational]]  # each f as a combination of stored nodes


_UNBOUNDED = 1 << 40


def _supports(nodes: Sequence[Node], leaf_support: Mapping[int, int]) -> list[int]:
    """How many leading coefficients of each node's series can be nonzero (static bound)."""
    sup = [_UNBOUNDED] * len(nodes)
    for i, nd in enumerate(nodes):
        op = nd.op
        if op in ("theta", "const", "cfree"):
            sup[i] = 1
        elif op == "t":
            sup[i] = 2
        elif op in ("u", "w"):
            sup[i] = leaf_support.get(i, _UNBOUNDED)
        elif op in ("add",):
            sup[i] = max(sup[a] for a in nd.args)
        elif op == "scale":
            sup[i] = sup[nd.args[0]]
        elif op == "mul":
            sa, sb = (sup[a] for a in nd.args)
            sup[i] = min(_UNBOUNDED, sa + sb - 1)
        elif op in ("recip", "aux"):
            sup[i] = 1 if sup[nd.args[0]] == 1 else _UNBOUNDED
    return sup


def _schedule(prog: Program, keep: Sequence[int], leaf_support: Mapping[int, int] | None = None) -> _Schedule:
    nodes = prog.nodes
    hist = set(keep)
    must = set(keep)
    sup = _supports(nodes, leaf_support or {})
    scalar: dict[int, tuple[int, int]] = {}  # mul by a series that is constant in t: (constant arg, series arg)
    for i, nd in enumerate(nodes):
        if nd.op == "mul" and min(sup[a] for a in nd.args) == 1:
            a, b = nd.args
            c, other = (a, b) if sup[a] == 1 else (b, a)
            scalar[i] = (c, other)
            must.update((c, other))  # stored (the series argument needs only its current coefficient)
        elif nd.op == "mul":
            hist.update(nd.args)
        elif nd.op == "recip":
            hist.update((i, nd.args[0]))
        elif nd.op == "aux":
            hist.update((i, nd.args[0], nd.w))
            if nd.pair >= 0:
                hist.add(nd.pair)
            if nd.data[0] == "atan" and nd.data[1] is not None:
                must.update(nd.data[1])
    must |= hist
    linear = {"add", "scale"}
    stored = [nd.op not in linear for nd in nodes]
    expansion: list[tuple[dict[int, sp.Rational], sp.Rational]] = []
    computing: dict[int, tuple[dict[int, sp.Rational], sp.Rational]] = {}

    def combine(i: int) -> tuple[dict[int, sp.Rational], sp.Rational]:
        nd = nodes[i]
        terms: dict[int, sp.Rational] = {}
        if nd.op == "add":
            const = sp.Rational(nd.data)
            parts = [(a, sp.Integer(1)) for a in nd.args]
        else:
            const = sp.Integer(0)
            parts = [(nd.args[0], sp.Rational(nd.data))]
        for a, c in parts:
            sub, sc = expansion[a]
            const += c * sc
            for j, v in sub.items():
                terms[j] = terms.get(j, 0) + c * v
        return {j: v for j, v in terms.items() if v != 0}, const

    for i, nd in enumerate(nodes):
        if stored[i]:
            expansion.append(({i: sp.Integer(1)}, sp.Integer(0)))
            continue
        terms, const = combine(i)
        if i not in must and len(terms) <= _INLINE:
            expansion.append((terms, const))
            continue
        stored[i] = True
        computing[i] = (terms, const)
        expansion.append(({i: sp.Integer(1)}, sp.Integer(0)))
    level = [0] * len(nodes)
    for i, nd in enumerate(nodes):
        if not stored[i] or nd.op in ("x", "theta", "u", "w", "t", "const", "cfree"):
            continue
        if i in computing:
            refs = computing[i][0] or {}
            level[i] = 1 + max((level[j] for j in refs), default=0)
        elif nd.op == "aux":  # coefficient k uses g up to k and w up to k - 1 only
            level[i] = 1 + level[nd.args[0]]
            if nd.data[0] == "atan" and nd.data[1] is not None:
                level[i] = max(level[i], 1 + max(level[j] for j in nd.data[1]))
        else:
            level[i] = 1 + max(level[a] for a in nd.args)
    by_level: dict[int, list[int]] = {}
    for i, lv in enumerate(level):
        if lv:
            by_level.setdefault(lv, []).append(i)
    levels = []
    for lv in sorted(by_level):
        items: list[tuple[str, Any]] = []
        lin = [i for i in by_level[lv] if i in computing]
        if lin:
            items.append(("linear", (lin, [computing[i][0] for i in lin], [computing[i][1] for i in lin])))
        sc = [i for i in by_level[lv] if i in scalar]
        if sc:
            items.append(("scalar", sc))
        items += [("node", i) for i in by_level[lv] if i not in computing and i not in scalar]
        levels.append(items)
    leaves = [i for i, nd in enumerate(nodes) if nd.op in ("x", "theta", "u", "w", "t", "const", "cfree")]
    return _Schedule(levels, frozenset(hist), scalar, leaves, [expansion[fi] for fi in prog.f])


class _LinearMap:
    """Rows of linear combinations of stored nodes, evaluated as sparse products in a field."""

    def __init__(self, field: Any, n_nodes: int, rows: Sequence[Mapping[int, sp.Rational]], consts: Sequence[sp.Rational]):
        import scipy.sparse

        self.field = field
        parts: list[tuple[list[int], list[int], list[Any]]] = []
        refs_r, refs_c = [], []
        for r, terms in enumerate(rows):
            for t, (j, v) in enumerate(sorted(terms.items())):
                b = t // _ROW_TERMS
                while len(parts) <= b:
                    parts.append(([], [], []))
                parts[b][0].append(r), parts[b][1].append(j), parts[b][2].append(field.num(v))
                refs_r.append(r), refs_c.append(j)
        shape = (len(rows), n_nodes)
        self.parts = [scipy.sparse.csr_matrix((np.array(v, dtype=field.dtype), (rr, cc)), shape=shape) for rr, cc, v in parts]
        self.base = [m.data.copy() for m in self.parts]
        self.const = np.array([field.num(c) for c in consts], dtype=field.dtype)
        # which stored nodes each row reads (for the degree bound: the largest degree among them)
        order = np.lexsort((refs_c, refs_r)) if refs_r else np.zeros(0, dtype=np.int64)
        self.ref_rows = np.array(refs_r, dtype=np.int64)[order]
        self.ref_cols = np.array(refs_c, dtype=np.int64)[order]
        counts = np.bincount(self.ref_rows, minlength=len(rows)) if refs_r else np.zeros(len(rows), dtype=np.int64)
        self.starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        self.nonempty = counts > 0

    def scaled(self, c: Any) -> None:
        """Multiply every coefficient by `c` (a field element), from the original coefficients."""
        F = self.field
        for m, b in zip(self.parts, self.base):
            m.data = F.red(b * c)

    def apply(self, cur: np.ndarray, dcur: np.ndarray, first: bool, c: Any = None) -> tuple[np.ndarray, np.ndarray]:
        F = self.field
        if not self.parts:
            out = np.zeros((self.const.shape[0], cur.shape[1]), dtype=F.dtype)
        else:
            out = F.red(self.parts[0] @ cur)
            for m in self.parts[1:]:
                out = F.red(out + F.red(m @ cur))
        if first:
            out[:, 0] = F.red(out[:, 0] + (self.const if c is None else F.red(self.const * c)))
        deg = np.zeros(self.const.shape[0], dtype=np.int64)
        if self.ref_cols.size:
            d = np.maximum.reduceat(dcur[self.ref_cols], self.starts[self.nonempty])
            deg[self.nonempty] = d
        return out, deg


@dataclass
class SeriesRun:
    r"""Run a program on truncated power series with gradients.

    Parameters
    ----------
    prog : Program
    field : ModField or FloatField
    M : int
        Number of unknowns (gradient length).
    x0 : sequence
        Initial state values (field elements); state i has gradient :math:`e_{i}` if
        ``state_cols[i] >= 0``.
    state_nodes : sequence of int
        The program's node of each state.
    leaf_coef : mapping node index -> function k -> (value, gradient column or -1, degree)
        Values of the other leaves' coefficients.
    rng : numpy.random.Generator
        For the free initial values of auxiliary series.
    keep : sequence of int
        Nodes whose every coefficient the caller reads after the run (:meth:`row`,
        :meth:`degree`); other nodes may keep only their current coefficient, or none.
    leaf_support : mapping node index -> int
        For input leaves with finitely many nonzero coefficients (polynomial inputs), how many.
    """

    prog: Program
    field: Any
    M: int
    x0: Sequence[Any]
    state_nodes: Sequence[int]
    leaf_coef: Mapping[int, Any]
    rng: np.random.Generator
    keep: Sequence[int] = ()
    leaf_support: Mapping[int, int] = field(default_factory=dict)
    order: int = -1
    extra_degree: int = 0

    def __post_init__(self) -> None:
        self.K = 0
        nodes = self.prog.nodes
        F = self.field
        self.sched = _schedule(self.prog, self.keep, self.leaf_support)
        self.cur = np.zeros((len(nodes), self.M + 1), dtype=F.dtype)
        self.dcur = np.zeros(len(nodes), dtype=np.int64)
        self.H = {i: np.zeros((0, self.M + 1), dtype=F.dtype) for i in self.sched.hist}
        self.DH = {i: np.zeros(0, dtype=np.int64) for i in self.sched.hist}
        # the highest order with a nonzero coefficient, per history node: convolutions skip the zero
        # terms (a parameter times a state costs one product per order, not k)
        self.last = {i: -1 for i in self.sched.hist}
        self.state_index = {nd: i for i, nd in enumerate(self.state_nodes)}
        self._next = np.zeros((len(self.state_nodes), self.M + 1), dtype=F.dtype)
        self._next_deg = np.zeros(len(self.state_nodes), dtype=np.int64)
        self._state_nodes = np.array(self.state_nodes, dtype=np.int64)
        self._state_hist = [i for i in self.state_nodes if i in self.H]
        self._other_leaves = [i for i in self.sched.leaves if nodes[i].op != "x"]
        self._lin = []
        self._scalar = []
        for items in self.sched.levels:
            for kind, what in items:
                if kind == "scalar":
                    idx = np.array(what, dtype=np.int64)
                    cs = np.array([self.sched.scalar[i][0] for i in what], dtype=np.int64)
                    ss = np.array([self.sched.scalar[i][1] for i in what], dtype=np.int64)
                    self._scalar.append([idx, cs, ss, None, None, [(r, i) for r, i in enumerate(what) if i in self.H]])
                if kind == "linear":
                    idx, rows, consts = what
                    self._lin.append((np.array(idx), _LinearMap(F, len(nodes), rows, consts),
                                      [(r, i) for r, i in enumerate(idx) if i in self.H]))
        self._f = _LinearMap(F, len(nodes), [t for t, _ in self.sched.f_rows], [c for _, c in self.sched.f_rows])

    # -- reading the results --------------------------------------------------------------------
    def row(self, i: int, k: int) -> np.ndarray:
        """Coefficient k of node i (value in column 0, gradient in 1:); node i must be kept."""
        return self.H[i][k]

    def degree(self, i: int, k: int) -> int:
        """Degree bound of coefficient k of node i (see ``degree_factor`` in ``_lie.py``)."""
        return int(self.DH[i][k])

    # -- internals ------------------------------------------------------------------------------
    def _grow(self, K: int) -> None:
        if K <= self.K:
            return
        newK = max(K, 2 * self.K, 8)
        for i, s in self.H.items():
            g = np.zeros((newK, self.M + 1), dtype=self.field.dtype)
            g[: s.shape[0]] = s
            self.H[i] = g
            d = np.zeros(newK, dtype=np.int64)
            d[: self.DH[i].shape[0]] = self.DH[i]
            self.DH[i] = d
        self.K = newK

    def _set(self, i: int, k: int, row: np.ndarray, deg: int) -> None:
        self.cur[i] = row
        self.dcur[i] = deg
        if i in self.H:
            self.H[i][k] = row
            self.DH[i][k] = deg
            if row.any():
                self.last[i] = k

    # dual-number helpers on rows (value in column 0, gradient in 1:)
    def _dual_mul(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        F = self.field
        out = F.red(a[0] * b + b[0] * a)
        out[0] = F.red(a[0] * b[0])
        return out

    def _dual_inv(self, a: np.ndarray) -> np.ndarray:
        F = self.field
        i0 = F.inv(a[0])
        out = F.red(-a * F.smul(i0, i0))
        out[0] = i0
        return out

    def _conv(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """Σ_i A[i] ⊗ B[i] for paired rows (dual products)."""
        F = self.field
        if A.shape[0] == 0:
            return np.zeros(self.M + 1, dtype=F.dtype)
        out = F.red(F.dot(A[:, 0], B) + F.dot(B[:, 0], A))
        out[0] = F.dot(A[:, 0], B[:, 0])
        return out

    def _leaf(self, i: int, k: int) -> None:
        nd = self.prog.nodes[i]
        if nd.op == "x":
            if k == 0:
                row = np.zeros(self.M + 1, dtype=self.field.dtype)
                row[0] = self.x0[nd.data]
                col = self.leaf_coef[i]
                if col >= 0:
                    row[1 + col] = 1
                self._set(i, 0, row, 1)
            else:
                j = self.state_index[i]
                self._set(i, k, self._next[j], int(self._next_deg[j]))
            return
        val, col, d = self.leaf_coef[i](k)
        row = np.zeros(self.M + 1, dtype=self.field.dtype)
        row[0] = val
        if col >= 0:
            row[1 + col] = 1
        self._set(i, k, row, d)

    def step(self) -> int:
        """Compute coefficient k = order + 1 of every node; return k."""
        k = self.order + 1
        self._grow(k + 2)
        F = self.field
        nodes = self.prog.nodes
        H, DH = self.H, self.DH
        if k == 0:
            for i in self.sched.leaves:
                self._leaf(i, 0)
        else:
            sn = self._state_nodes
            self.cur[sn] = self._next
            self.dcur[sn] = self._next_deg
            for i in self._state_hist:
                H[i][k] = self.cur[i]
                DH[i][k] = self.dcur[i]
                if H[i][k].any():
                    self.last[i] = k
            for i in self._other_leaves:
                self._leaf(i, k)
        lin = iter(self._lin)
        scal = iter(self._scalar)

        def store(idx, block, deg, kept, k):  # a batch of nodes' coefficient k, and the ones whose history is kept
            self.cur[idx] = block
            self.dcur[idx] = deg
            for r, i in kept:
                H[i][k] = block[r]
                DH[i][k] = deg[r]
                if block[r].any():
                    self.last[i] = k

        for items in self.sched.levels:
            for kind, what in items:
                if kind == "scalar":  # c(t) = c0 constant: coefficient k of c·s is c0 ⊗ s_k
                    group = next(scal)
                    idx, cs, ss, C0, D0, kept = group
                    if k == 0:
                        group[3] = C0 = self.cur[cs].copy()
                        group[4] = D0 = self.dcur[cs].copy()
                    S_ = self.cur[ss]
                    block = F.red(C0[:, :1] * S_ + S_[:, :1] * C0)
                    block[:, 0] = F.red(C0[:, 0] * S_[:, 0])
                    store(idx, block, D0 + self.dcur[ss], kept, k)
                    continue
                if kind == "linear":
                    idx, lmap, kept = next(lin)
                    store(idx, *lmap.apply(self.cur, self.dcur, k == 0), kept, k)
                    continue
                i = what
                nd = nodes[i]
                if nd.op == "mul":
                    a, b = nd.args
                    lo, hi = max(0, k - self.last[b]), min(k, self.last[a])  # a_j b_(k-j) = 0 outside
                    row = self._conv(H[a][lo: hi + 1], H[b][k - lo:: -1][: max(0, hi + 1 - lo)])
                    deg = int(np.max(DH[a][: k + 1] + DH[b][k::-1]))
                    self._set(i, k, row, deg)
                elif nd.op == "recip":
                    a = H[nd.args[0]]
                    da = DH[nd.args[0]]
                    if k == 0:
                        # 1/a(0) counts as a new variable r with r·a(0) = 1 (see `degree_factor`)
                        self._set(i, 0, self._dual_inv(a[0]), 1)
                        self.extra_degree += int(da[0])
                    else:
                        lo, hi = max(1, k - self.last[i]), min(k, self.last[nd.args[0]])
                        s = self._conv(a[lo: hi + 1], H[i][k - lo:: -1][: max(0, hi + 1 - lo)])
                        deg = int(DH[i][0] + np.max(da[1: k + 1] + DH[i][k - 1:: -1][:k]))
                        self._set(i, k, self._dual_mul(F.red(-s), H[i][0]), deg)
                elif nd.op == "aux":
                    if k == 0:
                        self._aux_init(i, nd)
                    else:
                        g = H[nd.args[0]]
                        lo, hi = max(1, k - self.last[nd.w]), min(k, self.last[nd.args[0]])
                        weights = np.arange(lo, hi + 1, dtype=F.dtype)
                        Ag = F.red(g[lo: hi + 1] * weights[:, None]) if hi >= lo else g[0:0]
                        s = self._conv(Ag, H[nd.w][k - lo:: -1][: max(0, hi + 1 - lo)])
                        dg, dw = DH[nd.args[0]], DH[nd.w]
                        deg = int(np.max(dg[1: k + 1] + dw[k - 1:: -1][:k]))
                        self._set(i, k, F.red(s * F.num(sp.Rational(1, k))), deg)
        # the state coefficients of the next order: x_{k+1} = f_k / (k+1)
        c = F.num(sp.Rational(1, k + 1))
        self._f.scaled(c)
        self._next, self._next_deg = self._f.apply(self.cur, self.dcur, k == 0, c)
        self.order = k
        return k

    def _aux_init(self, i: int, nd: Node) -> None:
        F = self.field
        g0 = self.H[nd.args[0]][0]
        kind, extra = nd.data
        gv = g0[0]
        if kind == "cos":  # initialised together with its sin partner
            return
        if F.exact:
            p = F.p
            if kind in ("exp", "log", "atan"):
                v0 = int(self.rng.integers(1, p))
            elif kind == "sin":
                t = int(self.rng.integers(1, p))
                den = F.inv(1 + t * t)
                s0, c0 = 2 * t * den % p, (1 - t * t) * den % p
            elif kind == "pow":
                a = extra
                base = int(gv) % p
                if base == 0:
                    raise Resample("zero base of a fractional power")
                b = pow(base, int(a.p), p) if a.p >= 0 else pow(F.inv(base), -int(a.p), p)
                v0 = root(b, int(a.q), p)
                if v0 is None:
                    raise Resample("no root modulo p at this point")
        else:
            gv = float(gv)
            with np.errstate(all="ignore"):
                if kind == "exp":
                    v0 = math.exp(gv) if gv < 700 else math.inf
                elif kind == "log":
                    v0 = math.log(gv) if gv > 0 else math.nan
                elif kind == "atan":
                    if extra is not None:
                        v0 = math.atan2(float(self.cur[extra[0], 0]), float(self.cur[extra[1], 0]))
                    else:
                        v0 = math.atan(gv)
                elif kind == "sin":
                    s0, c0 = math.sin(gv), math.cos(gv)
                elif kind == "pow":
                    a = extra
                    if gv < 0 and a.q % 2 == 0 or gv == 0:
                        v0 = math.nan
                    else:
                        v0 = math.copysign(abs(gv) ** float(a), gv if a.p % 2 else 1.0)
        # value of w at order 0 (v' = w g'), for the chain rule ∂v0 = w0 ∂g0
        row = np.zeros(self.M + 1, dtype=F.dtype)
        if kind == "sin":
            co = nd.pair
            row[0] = s0
            row[1:] = F.red(g0[1:] * c0)
            other = np.zeros(self.M + 1, dtype=F.dtype)
            other[0] = c0
            other[1:] = F.red(-g0[1:] * s0)
            self._set(i, 0, row, 1)
            self._set(co, 0, other, 1)
            self.extra_degree += 2
            return
        if not F.exact and not math.isfinite(v0):
            raise Resample("a function is undefined at the point")
        if kind == "exp":
            w0 = v0
        elif kind == "log":
            w0 = F.inv(gv)
        elif kind == "atan":
            w0 = F.inv(F.smul(gv, gv) + 1)
        else:  # pow
            w0 = F.smul(F.smul(F.num(extra), v0), F.inv(gv))
        row[0] = v0
        row[1:] = F.red(g0[1:] * w0)
        self._set(i, 0, row, 1)
        if kind == "pow":
            self.extra_degree += (int(extra.q) - 1) * int(self.DH[nd.args[0]][0])


# ----------------------------------------------------------------------------------------------
# systems affine in the unknowns: the jets' Jacobian without power series
# ----------------------------------------------------------------------------------------------
def affine_structure(f: Sequence[sp.Expr], h: Sequence[sp.Expr], x: Sequence[sp.Symbol],
                     theta: Sequence[sp.Symbol]) -> tuple[dict[tuple[int, int], sp.Rational], ...] | None:
    """The constant matrices of f = A x + B θ + g(u, t), h = C x + D θ + g₂(u, t), or None.

    Returned as sparse maps ``{(row, col): coefficient}`` (A, B, C, D). None when an expression
    is not affine in the unknowns (x, θ) or a coefficient is not a constant (depends on u or t).
    """
    unknown = [*x, *theta]
    index = {s: i for i, s in enumerate(unknown)}
    n = len(x)
    A: dict[tuple[int, int], sp.Rational] = {}
    B: dict[tuple[int, int], sp.Rational] = {}
    C: dict[tuple[int, int], sp.Rational] = {}
    D: dict[tuple[int, int], sp.Rational] = {}
    def terms_of(e: sp.Expr, deps: list[sp.Symbol]) -> dict[sp.Symbol, sp.Rational] | None:
        # fast path: a flat sum of (rational) * (unknown) and unknown-free terms
        out: dict[sp.Symbol, sp.Rational] = {}
        for term in sp.Add.make_args(e):
            c, m = term.as_coeff_Mul()
            if m in index and c.is_Rational:
                out[m] = out.get(m, 0) + c
            elif m.free_symbols & set(deps):
                break
        else:
            return out
        # general path: polynomial of degree one with constant coefficients
        if not e.is_polynomial(*deps):
            return None
        out = {}
        for s in deps:
            c = sp.diff(e, s)
            if not c.is_Rational:
                return None  # non-constant (depends on x, θ, u or t) or irrational coefficient
            out[s] = c
        return out

    for exprs, (X, T) in ((f, (A, B)), (h, (C, D))):
        for r, e in enumerate(exprs):
            deps = [s for s in e.free_symbols if s in index]
            if not deps:
                continue
            coeffs = terms_of(e, deps)
            if coeffs is None:
                return None
            for s, c in coeffs.items():
                if c != 0:
                    j = index[s]
                    (X if j < n else T)[(r, j if j < n else j - n)] = sp.Rational(c)
    return A, B, C, D


class AffineJets:
    r"""The rows of the output-jet Jacobian of an affine system, without power series.

    For :math:`\dot x = A x + B θ + g(u, t)`, :math:`y = C x + D θ + g_2(u, t)`, the k-th Taylor
    coefficient of y has the gradient :math:`(C A^k,\; C A^{k-1} B)/k!` with respect to (x(0), θ)
    (and :math:`(C, D)` for k = 0), independent of the point; the rows are computed as
    :math:`V_{k+1} = V_k A` (one sparse product of a p×n block per order: O(nnz(A)) per output)
    instead of O(nnz · M) for the dual-number series. The factor 1/k! is dropped (it does not
    change the rank or the row space). The interface mirrors :class:`SeriesRun` for the outputs.
    """

    def __init__(self, structure: tuple[dict[tuple[int, int], sp.Rational], ...], field: Any, n: int, q: int,
                 h_nodes: Sequence[int]):
        import scipy.sparse

        A, B, C, D = structure
        self.field, self.n, self.q = field, n, q
        p = len(h_nodes)
        self.out_index = {node: j for j, node in enumerate(h_nodes)}

        def parts(terms: Mapping[tuple[int, int], sp.Rational], shape: tuple[int, int], transpose: bool) -> list[Any]:
            rows: dict[int, list[tuple[int, Any]]] = {}
            for (r, c), v in terms.items():
                rr, cc = (c, r) if transpose else (r, c)
                rows.setdefault(rr, []).append((cc, field.num(v)))
            out: list[tuple[list[int], list[int], list[Any]]] = []
            for rr, items in rows.items():
                for t, (cc, v) in enumerate(items):
                    b = t // _ROW_TERMS
                    while len(out) <= b:
                        out.append(([], [], []))
                    out[b][0].append(rr), out[b][1].append(cc), out[b][2].append(v)
            shp = (shape[1], shape[0]) if transpose else shape
            return [scipy.sparse.csr_matrix((np.array(v, dtype=field.dtype), (r, c)), shape=shp) for r, c, v in out]

        self.At = parts(A, (n, n), True)  # V A = (Aᵀ Vᵀ)ᵀ
        self.Bt = parts(B, (n, q), True)
        self.V = np.zeros((p, n), dtype=field.dtype)
        for (r, c), v in C.items():
            self.V[r, c] = field.num(v)
        self.Dm = np.zeros((p, q), dtype=field.dtype)
        for (r, c), v in D.items():
            self.Dm[r, c] = field.num(v)
        self.rows: list[np.ndarray] = []  # per order: (p, 1 + n + q), column 0 unused (no values)
        self.order = -1
        self.extra_degree = 0

    def _times(self, mats: Sequence[Any], V: np.ndarray, width: int) -> np.ndarray:
        F = self.field
        if not mats:
            return np.zeros((V.shape[0], width), dtype=F.dtype)
        out = F.red(mats[0] @ V.T)
        for m in mats[1:]:
            out = F.red(out + F.red(m @ V.T))
        return out.T

    def step(self) -> int:
        k = self.order + 1
        F = self.field
        p = self.V.shape[0]
        row = np.zeros((p, 1 + self.n + self.q), dtype=F.dtype)
        if k == 0:
            row[:, 1:1 + self.n] = self.V
            row[:, 1 + self.n:] = self.Dm
        else:
            prev = self.V
            self.V = self._times(self.At, prev, self.n)
            if not F.exact:  # keep the float rows in range (only directions matter)
                scale = np.abs(self.V).max(initial=0.0)
                if scale > 0:
                    self.V = self.V / scale
                    prev = prev / scale
            row[:, 1:1 + self.n] = self.V
            row[:, 1 + self.n:] = self._times(self.Bt, prev, self.q)
        self.rows.append(row)
        self.order = k
        return k

    def row(self, node: int, k: int) -> np.ndarray:
        return self.rows[k][self.out_index[node]]

    def degree(self, node: int, k: int) -> int:
        return 1
