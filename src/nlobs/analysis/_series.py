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
    return Program(b.nodes, idx[:nf], idx[nf:nf + nh], idx[nf + nh:], frozenset(b.roots), notes, b.polynomial)


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
    leaf_series : mapping node index -> function k -> (value, gradient column or -1)
        Values of the other leaves' coefficients.
    rng : numpy.random.Generator
        For the free initial values of auxiliary series.
    """

    prog: Program
    field: Any
    M: int
    x0: Sequence[Any]
    state_nodes: Sequence[int]
    leaf_coef: Mapping[int, Any]
    rng: np.random.Generator
    S: list[np.ndarray] = field(default_factory=list)
    deg: list[list[int]] = field(default_factory=list)
    order: int = -1
    extra_degree: int = 0

    def __post_init__(self) -> None:
        self.K = 0
        self.S = [np.zeros((0, self.M + 1), dtype=self.field.dtype) for _ in self.prog.nodes]
        self.deg = [[] for _ in self.prog.nodes]
        self.state_index = {nd: i for i, nd in enumerate(self.state_nodes)}

    def _grow(self, K: int) -> None:
        if K <= self.K:
            return
        newK = max(K, 2 * self.K, 8)
        for i, s in enumerate(self.S):
            g = np.zeros((newK, self.M + 1), dtype=self.field.dtype)
            g[: s.shape[0]] = s
            self.S[i] = g
        self.K = newK

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

    def step(self) -> int:
        """Compute coefficient k = order + 1 of every node; return k."""
        k = self.order + 1
        self._grow(k + 2)
        F = self.field
        nodes = self.prog.nodes
        S, D = self.S, self.deg
        for i, nd in enumerate(nodes):
            op = nd.op
            row = S[i]
            if op == "x":
                if k == 0:
                    row[0, 0] = self.x0[nd.data]
                    col = self.leaf_coef[i]
                    if col >= 0:
                        row[0, 1 + col] = 1
                    D[i].append(1)
                # k >= 1 is filled in at the end of the previous step
            elif op in ("theta", "u", "w", "t", "const", "cfree"):
                val, col, d = self.leaf_coef[i](k)
                row[k, 0] = val
                if col >= 0:
                    row[k, 1 + col] = 1
                D[i].append(d)
            elif op == "add":
                acc = S[nd.args[0]][k].copy()
                for a in nd.args[1:]:
                    acc += S[a][k]
                if k == 0 and nd.data != 0:
                    acc[0] += F.num(nd.data)
                row[k] = F.red(acc)
                D[i].append(max(D[a][k] for a in nd.args))
            elif op == "scale":
                row[k] = F.red(S[nd.args[0]][k] * F.num(nd.data))
                D[i].append(D[nd.args[0]][k])
            elif op == "mul":
                a, b = S[nd.args[0]], S[nd.args[1]]
                row[k] = self._conv(a[: k + 1], b[k::-1])
                da, db = D[nd.args[0]], D[nd.args[1]]
                D[i].append(max(da[j] + db[k - j] for j in range(k + 1)))
            elif op == "recip":
                a = S[nd.args[0]]
                if k == 0:
                    row[0] = self._dual_inv(a[0])
                else:
                    s = self._conv(a[1: k + 1], row[k - 1:: -1][:k])
                    row[k] = self._dual_mul(F.red(-s), row[0])
                da = D[nd.args[0]]
                if k == 0:  # 1/a(0) counts as a new variable r with r·a(0) = 1 (see `degree_factor`)
                    D[i].append(1)
                    self.extra_degree += da[0]
                else:
                    D[i].append(D[i][0] + max(da[j] + D[i][k - j] for j in range(1, k + 1)))
            elif op == "aux":
                g = S[nd.args[0]]
                if k == 0:
                    self._aux_init(i, nd)
                else:
                    weights = np.arange(1, k + 1, dtype=F.dtype)
                    Ag = F.red(g[1: k + 1] * weights[:, None])
                    s = self._conv(Ag, S[nd.w][k - 1:: -1][:k])
                    row[k] = F.red(s * F.num(sp.Rational(1, k)))
                    dg, dw = D[nd.args[0]], D[nd.w]
                    D[i].append(max(dg[j] + dw[k - j] for j in range(1, k + 1)))
        # the state coefficients of the next order: x_{k+1} = f_k / (k+1)
        c = F.num(sp.Rational(1, k + 1))
        for nd_idx, fi in zip(self.state_nodes, self.prog.f):
            S[nd_idx][k + 1] = F.red(S[fi][k] * c)
            D[nd_idx].append(D[fi][k])
        self.order = k
        return k

    def _aux_init(self, i: int, nd: Node) -> None:
        F = self.field
        g0 = self.S[nd.args[0]][0]
        kind, extra = nd.data
        gv = g0[0]
        row = self.S[i]
        D = self.deg
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
                        v0 = math.atan2(float(self.S[extra[0]][0, 0]), float(self.S[extra[1]][0, 0]))
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
        if kind == "sin":
            co = nd.pair
            row[0, 0] = s0
            self.S[co][0, 0] = c0
            row[0, 1:] = F.red(g0[1:] * c0)
            self.S[co][0, 1:] = F.red(-g0[1:] * s0)
            D[i].append(1)
            D[co].append(1)
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
        row[0, 0] = v0
        row[0, 1:] = F.red(g0[1:] * w0)
        D[i].append(1)
        if kind == "pow":
            self.extra_degree += (int(extra.q) - 1) * D[nd.args[0]][0]
