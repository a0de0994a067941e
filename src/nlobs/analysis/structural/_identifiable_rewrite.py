r"""Identifiable functions of a non-rational model: rewritten into a rational one, the generators written back.

The search of :func:`find_identifiable_functions` works on rational models. A model with exp, log, sin, cos, atan or
non-integer powers is rewritten first, in three steps, and the generators found are expressed back in the user's
names:

0. *Roots, solved into the model* (the polynomial tie of the global check, :mod:`._rationalise`, imposed by
   elimination). A power :math:`g^{p/q}` of a rational argument g of the unknowns (:math:`\sqrt{h}`,
   :math:`x^{3/2}`, :math:`\sqrt{k}`, :math:`\sqrt{x_1 - x_2}`) becomes :math:`w^{pQ/q}` for a new unknown
   :math:`w = g^{1/Q}` (Q the lcm of the denominators of g's powers), and the tie :math:`w^Q = g` is solved for an
   unknown v in which it is linear (a state when g involves one, else an unknown parameter): v is replaced by that
   solution everywhere, and w takes v's place, a state with :math:`w' = \dot g / (Q w^{Q-1})` (g' the Lie
   derivative, as in :mod:`._rationalise`) or a parameter. The rewritten model is rational with no tie left, so
   both routes and the completeness checks apply to it unchanged. On the real branch the model means (g > 0, w the
   principal root :math:`g^{1/Q} > 0`) the map between v and w is one-to-one, and the two models have the same
   fibres; over the complex numbers, where the algebra works, the other branches :math:`\zeta w` are in the
   fibre too (the Torricelli tank :math:`h' = (b u - k\sqrt{h})/A`: :math:`(w, k) \mapsto (-w, -k)` keeps
   :math:`w^2 = y`, so only :math:`(k/A)^2` would be found). The branch is therefore *pinned* as the global check
   pins it: where the argument g (:math:`= w^Q`) is globally identifiable and w is not, the output determines the
   real positive root w, and w is added as an output (an output :math:`c\, w^m` is replaced by w itself, with no
   check: y = h gives :math:`\sqrt{y}`), until no more is pinned (the global check's rounds, Hong, Ovchinnikov,
   Pogudin & Yap (2020) Algorithm 1 on the pinned system). A root whose argument is not identifiable keeps its
   branch open: every generator found is still identifiable (the complex fibre contains the real one), but the
   branch may hide more, so completeness is *not decided*. A root whose tie is linear in no unknown
   (:math:`\sqrt{x^2 + 1}`) is left to step 2, which refuses it.
1. *Constants of the parameters.* Each largest non-rational sub-expression of parameters only
   (:math:`e^{b}`, :math:`\sin c`, a root of known parameters) becomes a new parameter
   :math:`q = \varphi(\theta)`. This is a reparametrisation: the output depends on the parameters through the new
   ones, so a function of the new parameters is identifiable in the rewritten model exactly when it is, written in
   the old ones, in the original (the original fibre is the preimage of the rewritten one). When every replaced
   parameter occurs only inside its :math:`\varphi`, the field found is the whole answer (its completeness carries
   over); when one also occurs elsewhere (:math:`b e^{b}`), the search treats :math:`b` and :math:`e^{b}` as
   independent and the relation between them is unused: the generators are identifiable, but completeness is
   *not decided*.
2. *Functions of the states.* What is left (:math:`e^{x}`, :math:`\sin(x_1 - x_2)`) is rewritten by the global check's
   rule (:mod:`._rationalise`): new states with rational ODEs whose initial values are tied to the old unknowns.
   Only transcendental ties (exp, log, atan) are accepted here, left free: the rewritten fibre contains the
   original one, so every generator found is identifiable in the original model (sound), but the unused tie may
   hide more identifiable functions (:math:`x' = a e^{x}`, y = x: the output determines a, the free tie only
   :math:`a e^{x}`), so completeness is *not decided*. A polynomial tie (sin/cos, a root step 0 could not solve) is
   refused, with the reason, for now.

Nothing that does not transfer is ever reported as "not identifiable": the non-identifiable verdicts come from the
local test on the original model, and every generator written back is checked by it on the original model.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from math import lcm
from typing import Any

import sympy as sp

from ...model import TIME, System, symbol
from ...model._expr import parse_expression
from ...model._system import exact
from ._rationalise import NotRational, is_rational, rationalise

__all__ = ["nonrational_functions"]

_FUNCS = (sp.exp, sp.log, sp.sin, sp.cos, sp.tan, sp.atan, sp.asin, sp.acos, sp.sinh, sp.cosh, sp.tanh)


def _non_rational_node(e: sp.Expr) -> bool:
    return isinstance(e, _FUNCS) or (isinstance(e, sp.Pow) and not e.exp.is_Integer)


@dataclass
class _Root:
    """A root solved into the model (step 0): the new unknown `w`, with :math:`w^Q` = its argument."""

    w: sp.Symbol
    Q: int
    definition: sp.Expr  # g**(1/Q) in the original model's names
    solved: str  # the unknown the tie was solved for, and how ("h = r1**2")
    state: bool  # w is a state (else an unknown parameter)
    pinned: str = ""  # how its branch is fixed ("" while open)


def _root_atoms(exprs: Sequence[sp.Expr]) -> list[sp.Pow]:
    out: dict[sp.Pow, None] = {}
    for e in exprs:
        for a in sp.preorder_traversal(e):
            if isinstance(a, sp.Pow) and a.exp.is_Rational and not a.exp.is_Integer:
                out[a] = None
    return list(out)


def _roots_solved(system: System, unknown: Sequence[str]) -> tuple[System, list[str], dict[sp.Symbol, sp.Expr],
                                                                   list[_Root]]:
    """Step 0 of the module docstring: every root of a rational argument of the unknowns whose tie is linear in one
    of them, solved into the model. Returns the rewritten system, its unknown parameters, the new names' meaning in the
    original names, and the roots (innermost first)."""
    f, h = list(system.f), list(system.h)
    states, params, unknown = list(system.states), dict(system.params), list(unknown)
    inputs = {symbol(u) for u in system.inputs}
    taken = {*system.states, *system.inputs, *system.outputs, *system.param_names, "t"}
    back: dict[sp.Symbol, sp.Expr] = {}
    roots: list[_Root] = []
    skip: set[sp.Expr] = set()
    # roots of numbers (sqrt(2*h) is sqrt(2)*sqrt(h) to SymPy) are constants: their values, as a known parameter's
    numbers = {a: sp.Float(a.evalf(20)) for a in _root_atoms(f + h) if not a.free_symbols and a.is_real}
    if numbers:
        f, h = [e.xreplace(numbers) for e in f], [e.xreplace(numbers) for e in h]
    for _ in range(100):
        atoms = _root_atoms(f + h)
        todo = [a for a in atoms if a.base not in skip and a.base.free_symbols and is_rational(a.base)
                and not (a.base.free_symbols & inputs)]
        if not todo:
            break
        g = todo[0].base
        Q = lcm(*(int(a.exp.q) for a in atoms if a.base == g))
        free = g.free_symbols
        in_states = [symbol(x) for x in states if symbol(x) in free]
        if TIME in free and not in_states:  # a root of parameters and t is no constant: left to steps 1-2
            skip.add(g)
            continue
        choices = in_states or [symbol(q) for q in unknown if symbol(q) in free]
        k = 1
        while f"r{k}" in taken:
            k += 1
        w = symbol(f"r{k}")
        num = sp.fraction(sp.together(w**Q - g))[0]
        v = sol = None
        for c in choices:
            P = sp.Poly(sp.expand(num), c)
            if P.degree() == 1:
                c1, c0 = P.all_coeffs()
                v, sol = c, sp.cancel(-c0 / c1)
                break
        if v is None:  # the tie is linear in no unknown (or g involves known parameters only): left to steps 1-2
            skip.add(g)
            continue
        taken.add(w.name)
        repl = {a: w ** int(a.exp * Q) for a in atoms if a.base == g}
        f, h = [e.xreplace(repl) for e in f], [e.xreplace(repl) for e in h]
        if in_states:
            i = states.index(v.name)
            lie = sp.diff(g, TIME) + sum((sp.diff(g, symbol(x)) * fx for x, fx in zip(states, f)), sp.Integer(0))
            f[i] = lie / (Q * w ** (Q - 1))
            states[i] = w.name
        else:
            value = complex(sp.N(g.xreplace({symbol(n): sp.Float(x) for n, x in params.items()})))
            params.pop(v.name)
            params[w.name] = abs(value) ** (1.0 / Q) if value != 0 else 1.0  # nominal only (the search is generic)
            unknown[unknown.index(v.name)] = w.name
        f = [sp.cancel(e.xreplace({v: sol})) for e in f]
        h = [sp.cancel(e.xreplace({v: sol})) for e in h]
        back[w] = g.xreplace(back) ** sp.Rational(1, Q)
        roots.append(_Root(w, Q, back[w], f"{v} = {sol}", bool(in_states)))
    if not roots and not numbers:
        return system, unknown, {}, []
    used = set().union(*(e.free_symbols for e in (*f, *h)))
    out = System(states=states, f=f, outputs=system.outputs, h=h, inputs=system.inputs,
                 params={n: x for n, x in params.items() if symbol(n) in used or n in unknown}, name=system.name)
    return out, [u for u in unknown if symbol(u) in used], back, roots


def _pin_roots(work: System, unknown: list[str], roots: list[_Root], kw: dict[str, Any],
               original: System) -> System:
    """Step 0's pinning: each root whose branch the output fixes becomes an output of the rewritten model (an output
    c w^m is replaced by w; else w when its argument w^Q is globally identifiable and w is not, in rounds)."""
    from ._global import global_identifiability

    h = list(work.h)
    for r in roots:
        for j, e in enumerate(h):
            c, rest = e.as_coeff_Mul()
            base, m = rest.as_base_exp()
            if c != 0 and base == r.w and m.is_Integer and m != 0:
                h[j] = r.w
                r.pinned = f"the output {work.outputs[j]} = {original.h[j]} determines it"
    outputs = list(work.outputs)
    taken = {*work.states, *work.inputs, *work.outputs, *work.param_names, "t"}
    for _ in range(len(roots)):
        cur = work if h == list(work.h) and outputs == list(work.outputs) else \
            System(states=work.states, f=work.f, outputs=outputs, h=h, inputs=work.inputs, params=dict(work.params),
                   name=work.name)
        open_ = [r for r in roots if not r.pinned]
        if not open_:
            return cur
        g = global_identifiability(cur, unknown_params=unknown, inputs=kw.get("inputs", "generic"),
                                   functions=[str(r.w**r.Q) for r in open_], engine=kw.get("engine", "auto"),
                                   seed=kw.get("seed", 0))
        if g.refused:
            return cur
        verdict = {text: v for text, v, _ in g.functions}
        new = [r for r in open_ if verdict.get(str(r.w**r.Q)) == "globally"]
        if not new:
            return cur
        for r in new:
            r.pinned = "its argument is globally identifiable"
            if r.w.name in g.globally:
                continue
            name = f"{r.w.name}_branch"
            while name in taken:
                name = "_" + name
            taken.add(name)
            outputs.append(name)
            h.append(r.w)
    return System(states=work.states, f=work.f, outputs=outputs, h=h, inputs=work.inputs, params=dict(work.params),
                  name=work.name)


def _constants_as_parameters(system: System, unknown: Sequence[str]) -> tuple[System, list[str], dict[sp.Symbol, sp.Expr],
                                                                               bool]:
    """Step 1: each largest non-rational sub-expression of parameters only as a new parameter. Returns the new
    system, its unknown parameters, the new parameters' definitions and whether a replaced unknown parameter still
    occurs elsewhere (the relation unused)."""
    params = {symbol(p) for p in system.param_names}
    taken = set(system.states) | set(system.inputs) | set(system.outputs) | set(system.param_names) | {"t"}
    defs: dict[sp.Expr, sp.Symbol] = {}
    values = dict(system.params)

    def new_name() -> str:
        k = len(defs) + 1
        while f"q{k}" in taken:
            k += 1
        taken.add(f"q{k}")
        return f"q{k}"

    def walk(e: sp.Expr) -> sp.Expr:
        if e.is_Atom:
            return e
        if _non_rational_node(e) and e.free_symbols and e.free_symbols <= params:
            if e not in defs:
                name = new_name()
                defs[e] = symbol(name)
                values[name] = float(e.subs({symbol(p): v for p, v in system.params.items()}))
            return defs[e]
        return e.func(*[walk(a) for a in e.args])

    f, h = [walk(e) for e in system.f], [walk(e) for e in system.h]
    if not defs:
        return system, list(unknown), {}, False
    used = set().union(*(e.free_symbols for e in (*f, *h)))
    unknown_syms = {symbol(u) for u in unknown}
    new_unknown = [u for u in unknown if symbol(u) in used]
    new_unknown += [q.name for e, q in defs.items() if e.free_symbols & unknown_syms]
    inside = [e.free_symbols & unknown_syms for e in defs]
    tied = any(s & used for s in inside) or any(a & b for i, a in enumerate(inside) for b in inside[i + 1:])
    kept = {p: v for p, v in values.items() if symbol(p) in used}
    out = System(states=system.states, f=f, outputs=system.outputs, h=h, inputs=system.inputs, params=kept,
                 name=system.name)
    return out, new_unknown, {q: e for e, q in defs.items()}, tied


def nonrational_functions(system: System, unknown: Sequence[str], search: Callable[..., Any], kw: dict[str, Any],
                          make: Callable[..., Any]) -> Any:
    """The identifiable functions of a non-rational `system` (module docstring): `search` is
    :func:`find_identifiable_functions` run on the rewritten rational model with the keyword arguments `kw`; `make`
    builds the result (``IdentifiableFunctions``). Raises NotRational when the rewriting does not apply."""
    import time

    from ._lie import function_checks

    t0 = time.perf_counter()
    work, new_unknown, back, roots = _roots_solved(system, unknown)
    notes = []
    if roots:
        work = _pin_roots(work, new_unknown, roots, kw, system)
        notes.append("roots solved into the model (their polynomial ties imposed by elimination; the principal real "
                     "root of a positive argument assumed): " + "; ".join(
                         f"{r.definition} as a new {'state' if r.state else 'parameter'} {r.w} ({r.solved}), "
                         + (f"branch fixed: {r.pinned}" if r.pinned else "branch NOT fixed (its argument is not "
                            "globally identifiable): completeness not decided") for r in roots))
    work, new_unknown, back1, tied = _constants_as_parameters(work, new_unknown)
    back.update({q: e.xreplace(back) for q, e in back1.items()})
    tied = tied or any(not r.pinned for r in roots)
    if back1:
        notes.append("rewritten for the search: " + ", ".join(f"{e} as a new parameter {q}" for q, e in back.items()
                                                                if q in back1)
                     + (" (the relation between a parameter and a function of it that both occur is not used: "
                        "completeness not decided)" if tied else ""))
    if not all(is_rational(e) for e in (*work.f, *work.h)):
        known = {symbol(k): exact(v) for k, v in work.params.items() if k not in new_unknown}
        rw = rationalise(work, known)
        bound = [t for t in rw.ties if t.kind != "free"]
        if bound:
            what = {a.name: a.definition.xreplace(back) for a in rw.added}
            raise NotRational("; ".join(
                f"{what[t.states[0]]}: its tie {t.states[0]}**{t.degree} = {t.argument} is linear in no unknown, so it "
                "cannot be solved into the model" if t.kind == "root" else
                f"{', '.join(str(what[x]) for x in t.states)} (a {t.kind} tie)" for t in bound)
                + ": identifiable functions do not yet impose such a polynomial tie otherwise; the global check does")
        for a in rw.added:
            back[symbol(a.name)] = a.definition.xreplace(back)
        notes.append("functions of the states rewritten as new states (" + ", ".join(f"{a.name} = {a.definition}"
                                                                                     for a in rw.added)
                     + ") whose initial values are left free: every generator is identifiable, completeness not decided")
        tied = True
        work = rw.system
    found = search(work, **{**kw, "unknown_params": new_unknown, "reparametrize_model": False})
    if found.refused:
        return make(with_states=found.with_states, refused=found.refused)
    names = {n: symbol(n) for n in (*work.states, *work.param_names, *work.inputs)}
    texts = tuple(str(parse_expression(t, names).xreplace(back)) for t in found.functions)
    checks = tuple(c.observable for c in function_checks(system, list(texts), unknown_params=list(unknown),
                                                         inputs=kw.get("inputs", "generic"), seed=kw.get("seed", 0))) \
        if texts else ()
    if not all(checks):
        notes.append("a returned function failed the local check on the original model: "
                     + ", ".join(t for t, c in zip(texts, checks) if not c))
    return make(functions=texts, with_states=found.with_states, complete=None if tied else found.complete,
                local_checks=checks, notes=(*notes, *found.notes), seconds=time.perf_counter() - t0,
                engine_seconds=found.engine_seconds, method=found.method)
