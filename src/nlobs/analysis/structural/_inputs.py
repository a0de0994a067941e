"""What the structural analyses are asked about, parsed once: input classes, unknown parameters, functions.

The parsers behind the ``inputs=``, ``unknown_params=`` and ``functions`` arguments of :func:`~nlobs.analysis.analyze`,
:func:`~nlobs.analysis.global_identifiability`, :func:`~nlobs.analysis.reparametrize` and their neighbours, each
raising a :class:`~nlobs.errors.ModelError` that names the argument and what it accepts. The local route
(``_lie``), the global one (``_global``) and the reparametrisation (``_reparam``) all read their arguments here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import sympy as sp

from ...errors import ModelError
from ...model import TIME, System, symbol
from ...model._expr import ExpressionError, parse_expression
from ...model._system import ExprLike, exact, to_expr

__all__ = ["InputClass"]


@dataclass(frozen=True)
class InputClass:
    """How a known input is taken in the structural test.

    ``kind`` is ``"generic"`` (a generic analytic input: every derivative a free value, which gives
    the rank of Besançon (2010)'s observation space), ``"polynomial"`` (a generic polynomial of `degree`;
    ``degree=0`` is a generic constant) or ``"signal"`` (the given expression of t, e.g. ``0``).
    """

    kind: str
    degree: int | None = None
    expr: sp.Expr | None = None

    @classmethod
    def generic(cls) -> InputClass:
        return cls("generic")

    @classmethod
    def constant(cls) -> InputClass:
        return cls("polynomial", 0)

    @classmethod
    def polynomial(cls, degree: int) -> InputClass:
        return cls("polynomial", int(degree))

    def describe(self) -> str:
        if self.kind == "generic":
            return "generic"
        if self.kind == "polynomial":
            return "generic constant" if self.degree == 0 else f"generic polynomial of degree {self.degree}"
        return f"= {self.expr}"


def _input_class(value: Any, name: str, params: Mapping[str, float]) -> InputClass:
    if isinstance(value, InputClass):
        return value
    if isinstance(value, str) and value in ("generic", "constant"):
        return InputClass.generic() if value == "generic" else InputClass.constant()
    allowed = {"t": TIME, **{k: symbol(k) for k in params}}
    try:
        expr = to_expr(value, allowed, where=f"inputs[{name}]")
    except ModelError as e:
        raise ModelError(f"{e}; an input is 'generic', 'constant', InputClass.polynomial(d), or a signal: a number or "
                         "an expression of t") from None
    return InputClass("signal", expr=expr.xreplace({symbol(k): exact(v) for k, v in params.items()}))


def _input_classes(system: System, inputs: Any, unknown: Mapping[str, int]) -> dict[str, InputClass]:
    if isinstance(inputs, bool):
        raise ModelError("`inputs` must be 'generic', 'constant', a polynomial degree, or a mapping {input: class or signal}")
    if isinstance(inputs, int):
        if inputs < 0:
            raise ModelError(f"`inputs` as a polynomial degree must be >= 0, got {inputs}")
        default = InputClass.polynomial(inputs)
        per: Mapping[str, Any] = {}
    elif isinstance(inputs, (str, InputClass)):
        default = _input_class(inputs, "*", {}) if isinstance(inputs, InputClass) or inputs in ("generic", "constant") else None
        if default is None:
            raise ModelError(f"`inputs` = {inputs!r} is not understood; use 'generic', 'constant', an int degree, or a mapping")
        per = {}
    elif isinstance(inputs, Mapping):
        default, per = InputClass.generic(), inputs
        bad = [k for k in per if k not in system.inputs]
        if bad:
            raise ModelError(f"`inputs` names {', '.join(map(repr, bad))}, not an input of {system.name!r}; its inputs are: "
                             f"{', '.join(system.inputs) or '(none)'}")
    else:
        raise ModelError(f"`inputs` must be a string, an int or a mapping, got {type(inputs).__name__}")
    return {n: _input_class(per[n], n, system.params) if n in per else default for n in system.inputs if n not in unknown}


def _unknown_params(system: System, unknown_params: Any) -> tuple[str, ...]:
    if unknown_params is True or unknown_params == "all":
        return system.param_names
    if unknown_params in (False, None):
        return ()
    if isinstance(unknown_params, str):
        unknown_params = [unknown_params]
    names = tuple(unknown_params)
    dup = sorted({k for k in names if names.count(k) > 1})
    if dup:
        raise ModelError(f"`unknown_params` lists {', '.join(map(repr, dup))} more than once; name each parameter once")
    bad = [k for k in names if k not in system.params]
    if bad:
        raise ModelError(f"`unknown_params` names {', '.join(map(repr, bad))}, not a parameter of {system.name!r}; its "
                         f"parameters are: {', '.join(system.param_names) or '(none)'}")
    return names


def _parse_functions(system: System, functions: Sequence[ExprLike]) -> list[tuple[str, sp.Expr]]:
    allowed = {n: symbol(n) for n in (*system.states, *system.params)}
    out = []
    for k, e in enumerate(functions):
        if isinstance(e, str):
            try:
                expr = parse_expression(e, allowed)
            except ExpressionError as err:
                raise ModelError(f"functions[{k}]: {e!r}: {err}") from None
        else:
            expr = to_expr(e, allowed, where=f"functions[{k}]")
        out.append((str(e) if isinstance(e, str) else str(expr), expr))
    return out


def require_system(system: Any, caller: str) -> System:
    """`system` if it is an nlobs.System, else a ModelError naming `caller`, what it got and what to pass instead."""
    if isinstance(system, System):
        return system
    hint = ""
    if isinstance(getattr(system, "system", None), System):
        hint = " (a parsed model file: pass its .system)"
    elif isinstance(system, str):
        hint = " (a model file's name? load it with nlobs.load_model(path).system)"
    raise ModelError(f"{caller}: `system` must be an nlobs.System, got {type(system).__name__}{hint}")
