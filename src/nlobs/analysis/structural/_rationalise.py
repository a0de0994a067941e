r"""Rewriting a model with exp, log, sin, cos, atan and non-integer powers into an equivalent rational one.

SIAN (Hong, Ovchinnikov, Pogudin & Yap (2019); Hong, Ovchinnikov, Pogudin & Yap (2020), Algorithm 1) works on
rational right-hand sides and outputs. A model
:math:`x' = f(x, \theta, t)`, :math:`y = h(x, \theta, t)` whose expressions contain a smooth elementary function
:math:`\varphi(g)` of a rational argument g is rewritten, innermost function first, by a new state
:math:`z = \varphi(g)` that obeys an ODE rational in (x, z), with :math:`g' = \sum_i \partial g/\partial x_i\, f_i +
\partial g/\partial t` (the Lie derivative of g along f):

=====================  ====================================================  ===================================
function               new state(s) and ODE                                  tie at t = 0 (and at every t)
=====================  ====================================================  ===================================
exp(g)                 :math:`z' = z g'`                                     :math:`z = e^{g}` (transcendental)
log(g)                 :math:`w' = g'/g`                                     :math:`e^{w} = g` (transcendental)
atan(g)                :math:`w' = g'/(1 + g^2)`                             :math:`\tan w = g` (transcendental)
sin(g), cos(g)         :math:`s' = c g'`, :math:`c' = -s g'`                 :math:`s^2 + c^2 = 1` (polynomial),
                                                                             angle g (transcendental)
:math:`g^{p/q}`        :math:`w = g^{1/Q}`, :math:`w' = w g'/(Q g)`          :math:`w^Q = g` (polynomial)
=====================  ====================================================  ===================================

(tan, sinh, cosh, tanh become sin/cos or exp first; :math:`b^{e}` with a symbolic exponent becomes
:math:`\exp(e \log b)`; all powers of one base share :math:`w = g^{1/Q}`, Q the lcm of their denominators, and
:math:`g^{p/q} = w^{pQ/q}`; identical sub-expressions share one state, :math:`e^{-g} = 1/e^{g}`.) The substitution
is made everywhere, inside the arguments of the other functions too, and repeated until nothing is left: the
result is rational. On the tie the rewritten trajectories are exactly the original ones.

What the global verdicts of the rewritten model say about the original
------------------------------------------------------------------------
The new states' initial values are not free: they are functions of the old unknowns (the *tie*). The rewritten
model with the new initial values as extra unknowns has a fibre (the unknowns compatible with one output)
:math:`F_r \supseteq F_o`, the original fibre embedded by the tie. Hence:

* *globally identifiable in the rewritten model* implies *globally identifiable in the original*: sound. Generic
  points transfer because the original points are Zariski-dense in the rewritten unknowns' space once every
  polynomial tie is imposed: the graph of exp, log, atan (and the angle of sin/cos) over a nonconstant argument
  lies in no proper algebraic subset. A polynomial tie (:math:`w^Q = g`, :math:`s^2 + c^2 = 1`) must be imposed,
  or the original points would lie in a proper subset where the generic verdict need not hold: it enters SIAN as
  an extra output known to be identically 0 (:math:`y_{tie} = w^Q - g`, whose derivatives are then all forced),
  and the random point of SIAN is drawn on it (a Q-th root of g in GF(p)).
* *Pinning.* If the argument g is globally identifiable in the rewritten model, then on :math:`F_o` the new
  initial value :math:`\varphi(g(x_0, \theta))` is one known number; adding "new initial value = its value at the
  random point" keeps :math:`F_o` inside the cut fibre, and the check is run again (until nothing more is
  pinned). This recovers, e.g., :math:`x' = a e^{x}`, y = x (SI.jl issue #144: with :math:`z = e^{x}` free, a is
  not identifiable; x is, so z(0) is known, and so is a).
* When every new state is pinned the cut fibre *is* :math:`F_o` (a point of it has g equal to the known value, so
  its new initial value is :math:`\varphi(g)`, on the principal branch of the root that was pinned): every
  verdict, including "locally, k solutions", holds for the original model.
* Otherwise a verdict weaker than "globally" may be an artefact of the unused tie (an extra degree of freedom
  for exp/log/atan and the angle of sin/cos; the other branches :math:`w \ne g^{1/Q}` for a root, which the real
  model excludes): it is reported as *undecided*, with the count as an upper bound, never as "not identifiable".
  Non-identifiability itself comes from the local test on the original model, which handles these functions
  directly.

Not rewritable: abs, sign, min/max, Heaviside, piecewise expressions, lookup tables (not differentiable
everywhere, or no finite ODE), and any function whose argument contains an input (its ODE would need the
input's derivative, which the model does not give). They keep a refusal naming the function.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from math import lcm

import sympy as sp

from ...errors import ModelError
from ...model import TIME, System, symbol
from ...model._system import exact

__all__ = ["NotRational", "AddedState", "Tie", "Rewriting", "rationalise", "is_rational"]

#: The functions the rewriting handles (after tan, sinh, cosh, tanh become sin/cos and exp).
_FUNCS = (sp.exp, sp.log, sp.sin, sp.cos, sp.atan)
_PREFIX = {"exp": "e", "log": "ln", "atan": "at", "sin": "s", "cos": "c", "root": "r"}


class NotRational(ModelError):
    """The model is outside the class of the global algorithm (a non-rational right-hand side that cannot be
    rewritten)."""


@dataclass(frozen=True)
class AddedState:
    """One state added by the rewriting.

    Attributes
    ----------
    name : str
    kind : {"exp", "log", "atan", "sin", "cos", "root"}
    definition : sympy.Expr
        What it stands for, in the original model's variables (``exp(a*x)``).
    rhs : sympy.Expr
        Its right-hand side in the rewritten (rational) model.
    """

    name: str
    kind: str
    definition: sp.Expr
    rhs: sp.Expr


@dataclass(frozen=True)
class Tie:
    """How the initial values of new states are tied to the old unknowns.

    Attributes
    ----------
    kind : {"free", "circle", "root"}
        "free": transcendental (exp, log, atan), not imposed; "circle": :math:`s^2 + c^2 = 1` imposed, the angle
        not; "root": :math:`w^Q = g` imposed.
    states : tuple of str
        The new states (one; two for sin/cos).
    argument : sympy.Expr
        g, in the rewritten model's variables (rational).
    degree : int
        Q for a root, else 0.
    output : str
        The tie output (identically 0) of the rewritten model, or "" when nothing is imposed.
    """

    kind: str
    states: tuple[str, ...]
    argument: sp.Expr
    degree: int = 0
    output: str = ""

    @property
    def constant(self) -> bool:
        """True when g involves no state and no unknown (numbers and time only): pinned from the start."""
        return not (self.argument.free_symbols - {TIME})


@dataclass(frozen=True)
class Rewriting:
    """A rational model equivalent to a non-rational one on its tie.

    Attributes
    ----------
    system : System
        The rational model: the original states, then the new ones; the original outputs, then the tie outputs
        (identically 0 on the tie). Known parameters and input signals are substituted.
    added : tuple of AddedState
    ties : tuple of Tie
    """

    system: System
    added: tuple[AddedState, ...]
    ties: tuple[Tie, ...]

    @property
    def tie_outputs(self) -> tuple[str, ...]:
        return tuple(t.output for t in self.ties if t.output)

    def describe(self) -> list[str]:
        """One line per added state: what it stands for, its ODE, its tie."""
        lines = []
        tie_of = {s: t for t in self.ties for s in t.states}
        for a in self.added:
            t = tie_of[a.name]
            if t.kind == "root":
                rel = f"{a.name}**{t.degree} = {t.argument} imposed (the principal root is {a.name}(0) = {a.definition} at t = 0)"
            elif t.kind == "circle":
                s, c = t.states
                rel = f"{s}**2 + {c}**2 = 1 imposed; {a.name}(0) = {a.definition} at t = 0 (the angle) is transcendental"
            else:
                rel = f"{a.name}(0) = {a.definition} at t = 0 is transcendental"
            lines.append(f"{a.name} = {a.definition}: {a.name}' = {a.rhs}; tie: {rel}")
        return lines


def is_rational(e: sp.Expr) -> bool:
    """True when `e` is a rational function of its symbols (integer powers only, no function)."""
    for a in sp.preorder_traversal(e):
        if a.is_Atom or isinstance(a, (sp.Add, sp.Mul)):
            continue
        if isinstance(a, sp.Pow) and a.exp.is_Integer:
            continue
        return False
    return True


def _normalise(e: sp.Expr) -> sp.Expr:
    """Floats to exact rationals; tan to sin/cos; hyperbolic functions to exp; b**e (symbolic e) to exp(e*log(b))."""
    floats = {a: exact(float(a)) for a in e.atoms(sp.Float)}
    e = e.xreplace(floats) if floats else e
    e = e.replace(lambda a: isinstance(a, (sp.sinh, sp.cosh, sp.tanh)), lambda a: a.rewrite(sp.exp))
    e = e.replace(lambda a: isinstance(a, sp.tan), lambda a: sp.sin(a.args[0]) / sp.cos(a.args[0]))
    return e.replace(lambda a: isinstance(a, sp.Pow) and not a.exp.is_Number,
                     lambda a: sp.exp(a.exp * sp.log(a.base)))


def _candidates(e: sp.Expr, where: str) -> list[sp.Expr]:
    """The non-rational sub-expressions of `e` (functions and non-integer powers); NotRational for the others."""
    out = []
    for a in sp.preorder_traversal(e):
        if a.is_Atom or isinstance(a, (sp.Add, sp.Mul)):
            continue
        if isinstance(a, sp.Pow):
            if not a.exp.is_Integer:
                out.append(a)
            continue
        if isinstance(a, _FUNCS):
            out.append(a)
            continue
        name = getattr(a.func, "__name__", str(a.func)).lower()
        raise NotRational(
            f"{where}: `{name}` ({a}) is not a rational function and cannot be rewritten into one; the global "
            "algorithm (SIAN) works on rational right-hand sides and outputs, and only exp, log, sin, cos, tan, "
            "sinh, cosh, tanh, atan and non-integer powers are rewritten (a new state with its own ODE). abs, sign, "
            "min/max, Heaviside, piecewise expressions and lookup tables are not: replace the function by a smooth "
            "one, or use the local verdict")
    return out


def _argument(a: sp.Expr) -> sp.Expr:
    return a.base if isinstance(a, sp.Pow) else a.args[0]


class _Rewriter:
    """The state of the rewriting: current right-hand sides and outputs, the new states, the caches."""

    def __init__(self, system: System, f: list[sp.Expr], h: list[sp.Expr], inputs: set[sp.Symbol]):
        self.system = system
        self.states = list(system.states)
        self.f = f
        self.h = h
        self.inputs = inputs
        self.taken = {*system.states, *system.inputs, *system.outputs, *system.params, "t"}
        self.added: list[AddedState] = []
        self.ties: list[Tie] = []
        self.tie_h: list[tuple[str, sp.Expr]] = []
        self.back: dict[sp.Symbol, sp.Expr] = {}  # new state -> its definition in the original variables
        self.cache: dict[tuple[str, sp.Expr], sp.Expr] = {}  # (kind, argument) -> replacement
        self.counter = 0

    def fresh(self, kind: str, suffix: str = "") -> sp.Symbol:
        """A new state name: the kind's prefix and a number (`suffix`: the number of the partner, for cos)."""
        name = f"{_PREFIX[kind]}{suffix}"
        while not suffix or name in self.taken:
            self.counter += 1
            suffix = str(self.counter)
            name = f"{_PREFIX[kind]}{suffix}"
        self.taken.add(name)
        return symbol(name)

    def lie(self, g: sp.Expr) -> sp.Expr:
        """g' along the current right-hand sides (the new states included) plus its explicit time derivative."""
        out = sp.diff(g, TIME)
        for s, rhs in zip(self.states, self.f):
            d = sp.diff(g, symbol(s))
            if d != 0:
                out += d * rhs
        return out

    def add_state(self, z: sp.Symbol, kind: str, atom: sp.Expr, rhs: sp.Expr) -> None:
        self.states.append(z.name)
        self.f.append(rhs)
        self.back[z] = atom.xreplace(self.back)
        self.added.append(AddedState(z.name, kind, self.back[z], rhs))

    def check_inputs(self, atom: sp.Expr, g: sp.Expr) -> None:
        bad = sorted(s.name for s in g.free_symbols & self.inputs)
        if bad:
            raise NotRational(
                f"{atom.xreplace(self.back)}: its argument depends on the input(s) {', '.join(bad)}; a new state for it "
                f"would need the derivative of {bad[0]}, which the model does not give, so the model cannot be "
                f"rewritten into a rational one for the global algorithm (SIAN). Make {bad[0]} a state with its own "
                "ODE, or use the local verdict")

    def rewrite(self, atom: sp.Expr) -> sp.Expr:
        """The rational replacement of `atom` (whose argument is rational), adding its state(s) the first time."""
        if isinstance(atom, sp.Pow):
            return self._root(atom)
        g = atom.args[0]
        self.check_inputs(atom, g)
        if isinstance(atom, (sp.sin, sp.cos)):
            key = ("circle", g)
            if key not in self.cache:
                s = self.fresh("sin")
                c = self.fresh("cos", s.name[len(_PREFIX["sin"]):])
                dg = self.lie(g)
                self.add_state(s, "sin", sp.sin(g), c * dg)
                self.add_state(c, "cos", sp.cos(g), -s * dg)
                out = self.fresh_output(s.name)
                self.ties.append(Tie("circle", (s.name, c.name), g, 0, out))
                self.tie_h.append((out, s**2 + c**2 - 1))
                self.cache[key] = sp.Tuple(s, c)
            s, c = self.cache[key]
            return s if isinstance(atom, sp.sin) else c
        kind = type(atom).__name__
        if kind == "exp" and ("exp", -g) in self.cache:
            return 1 / self.cache[("exp", -g)]
        if (kind, g) not in self.cache:
            z = self.fresh(kind)
            dg = self.lie(g)
            rhs = {"exp": z * dg, "log": dg / g, "atan": dg / (1 + g**2)}[kind]
            self.add_state(z, kind, atom, rhs)
            self.ties.append(Tie("free", (z.name,), g))
            self.cache[(kind, g)] = z
        return self.cache[(kind, g)]

    def fresh_output(self, base: str) -> str:
        name = f"tie_{base}"
        while name in self.taken:
            name = "_" + name
        self.taken.add(name)
        return name

    def _root(self, atom: sp.Pow) -> sp.Expr:
        g, r = atom.base, sp.Rational(atom.exp)
        self.check_inputs(atom, g)
        key = ("root", g)
        if key in self.cache and self.cache[key][1] % r.q == 0:
            w, Q = self.cache[key]
            return w ** int(r * Q)
        Q = self.pending.get(g, r.q)
        w = self.fresh("root")
        dg = self.lie(g)
        self.add_state(w, "root", g ** sp.Rational(1, Q), w * dg / (Q * g))
        num, den = sp.fraction(sp.cancel(sp.together(g)))
        relation = sp.expand(w**Q * den - num)
        self._check_irreducible(relation, w, atom)
        out = self.fresh_output(w.name)
        self.ties.append(Tie("root", (w.name,), g, Q, out))
        self.tie_h.append((out, relation))
        self.cache[key] = (w, Q)
        return w ** int(r * Q)

    def _check_irreducible(self, relation: sp.Expr, w: sp.Symbol, atom: sp.Expr) -> None:
        if not relation.free_symbols - {w}:
            return  # a root of a number: one branch is pinned (the variety is a set of points)
        _, factors = sp.factor_list(relation)
        if sum(1 for fac, _ in factors if fac.has(w)) > 1:
            raise NotRational(f"{atom.xreplace(self.back)}: its argument is a perfect power, so the root is piecewise "
                              "(e.g. |...|); simplify the model (write the root out) before the global check")

    def run(self) -> None:
        for _ in range(1000):
            where = self._where()
            cands: dict[sp.Expr, None] = {}
            for text, e in where:
                for a in _candidates(e, text):
                    cands[a] = None
            if not cands:
                return
            inner = [a for a in cands if not _candidates(_argument(a), "")]
            self.pending: dict[sp.Expr, int] = {}
            for a in inner:
                if isinstance(a, sp.Pow):
                    self.pending[a.base] = lcm(self.pending.get(a.base, 1), int(sp.Rational(a.exp).q))
            repl = {a: self.rewrite(a) for a in inner}
            self.f = [e.xreplace(repl) for e in self.f]
            self.h = [e.xreplace(repl) for e in self.h]
            self.tie_h = [(n, e.xreplace(repl)) for n, e in self.tie_h]
        raise NotRational("the rewriting into a rational model did not terminate")  # pragma: no cover

    def _where(self) -> list[tuple[str, sp.Expr]]:
        sysm = self.system
        out = []
        for k, (s, e) in enumerate(zip(self.states, self.f)):
            text = f"{s}' = {sysm.f[k]}" if k < sysm.n_states else f"{s}' (added)"
            out.append((text, e))
        out += [(f"{y} = {sysm.h[j]}", e) for j, (y, e) in enumerate(zip(sysm.outputs, self.h))]
        return out


def rationalise(system: System, substitutions: Mapping[sp.Symbol, sp.Expr] | None = None,
                inputs: Sequence[str] | None = None) -> Rewriting:
    """Rewrite `system` into a rational model by adding states (module docstring).

    Parameters
    ----------
    system : System
    substitutions : mapping, optional
        Known values substituted first (known parameters as exact rationals, input signals as functions of t).
    inputs : sequence of str, optional
        The inputs left as symbols (default: all of `system.inputs`); a function of one of them is refused.

    Returns
    -------
    Rewriting
        With no added state when `system` is rational already.

    Raises
    ------
    NotRational
        For a function that cannot be rewritten (abs, sign, min/max, Heaviside, piecewise, tables) or one whose
        argument depends on an input; the message names it.

    Examples
    --------
    >>> s = System(states=["x"], f=["-k*exp(a*x)"], outputs=["y"], h=["x"], params={"k": 1.0, "a": 1.0})
    >>> rationalise(s).describe()
    ["e1 = exp(a*x): e1' = -a*e1**2*k; tie: e1(0) = exp(a*x) at t = 0 is transcendental"]
    """
    sub = dict(substitutions or {})
    f = [_normalise(e.xreplace(sub)) for e in system.f]
    h = [_normalise(e.xreplace(sub)) for e in system.h]
    names = system.inputs if inputs is None else inputs
    rw = _Rewriter(system, f, h, {symbol(u) for u in names})
    rw.run()
    if not rw.added:
        return Rewriting(system, (), ())
    f_out = [sp.expand(e) if i >= system.n_states else e for i, e in enumerate(rw.f)]
    new = System(states=rw.states, f=f_out, outputs=[*system.outputs, *(n for n, _ in rw.tie_h)],
                 h=[*rw.h, *(e for _, e in rw.tie_h)], inputs=system.inputs, params=dict(system.params),
                 name=system.name)
    added = tuple(AddedState(a.name, a.kind, a.definition, f_out[rw.states.index(a.name)]) for a in rw.added)
    return Rewriting(new, added, tuple(rw.ties))
