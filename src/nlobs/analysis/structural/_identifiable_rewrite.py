r"""Identifiable functions of a non-rational model: rewritten into a rational one, the generators written back.

The search of :func:`find_identifiable_functions` works on rational models. A model with exp, log, sin, cos, atan or
non-integer powers is rewritten first, in two steps, and the generators found are expressed back in the user's
names:

1. *Constants of the parameters.* Each largest non-rational sub-expression of parameters only
   (:math:`e^{b}`, :math:`\sqrt{k}`, :math:`\sin c`) becomes a new parameter :math:`q = \varphi(\theta)`. This is a
   reparametrisation: the output depends on the parameters through the new ones, so a function of the new
   parameters is identifiable in the rewritten model exactly when it is, written in the old ones, in the original
   (the original fibre is the preimage of the rewritten one). When every replaced parameter occurs only inside its
   :math:`\varphi`, the field found is the whole answer (its completeness carries over); when one also occurs
   elsewhere (:math:`b e^{b}`), the search treats :math:`b` and :math:`e^{b}` as independent and the relation between
   them is unused: the generators are identifiable, but completeness is *not decided*.
2. *Functions of the states.* What is left (:math:`e^{x}`, :math:`\sin(x_1 - x_2)`) is rewritten by the global check's
   rule (:mod:`._rationalise`): new states with rational ODEs whose initial values are tied to the old unknowns.
   Only transcendental ties (exp, log, atan) are accepted here, left free: the rewritten fibre contains the
   original one, so every generator found is identifiable in the original model (sound), but the unused tie may
   hide more identifiable functions (:math:`x' = a e^{x}`, y = x: the output determines a, the free tie only
   :math:`a e^{x}`), so completeness is *not decided*. A polynomial tie (a root, sin/cos) is refused, with the
   reason, for now.

Nothing that does not transfer is ever reported as "not identifiable": the non-identifiable verdicts come from the
local test on the original model, and every generator written back is checked by it on the original model.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import sympy as sp

from ...model import System, symbol
from ...model._expr import parse_expression
from ...model._system import exact
from ._rationalise import NotRational, is_rational, rationalise

__all__ = ["nonrational_functions"]

_FUNCS = (sp.exp, sp.log, sp.sin, sp.cos, sp.tan, sp.atan, sp.asin, sp.acos, sp.sinh, sp.cosh, sp.tanh)


def _non_rational_node(e: sp.Expr) -> bool:
    return isinstance(e, _FUNCS) or (isinstance(e, sp.Pow) and not e.exp.is_Integer)


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
    from ._lie import function_checks

    work, new_unknown, back, tied = _constants_as_parameters(system, unknown)
    notes = []
    if back:
        notes.append("rewritten for the search: " + ", ".join(f"{e} as a new parameter {q}" for q, e in back.items())
                     + (" (the relation between a parameter and a function of it that both occur is not used: "
                        "completeness not decided)" if tied else ""))
    if not all(is_rational(e) for e in (*work.f, *work.h)):
        known = {symbol(k): exact(v) for k, v in work.params.items() if k not in new_unknown}
        rw = rationalise(work, known)
        bound = [t for t in rw.ties if t.kind != "free"]
        if bound:
            raise NotRational(f"{', '.join(f'{s} (a {t.kind} tie)' for t in bound for s in t.states)}: identifiable "
                              "functions do not yet impose a polynomial tie; the global check does")
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
                local_checks=checks, notes=(*notes, *found.notes), seconds=found.seconds,
                engine_seconds=found.engine_seconds, method=found.method)
