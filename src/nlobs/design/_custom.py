"""An observer written by its equations: z' = F(t, z, u, y), x̂ = H(t, z, u, y)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import casadi as ca
import numpy as np

from ..engine import to_casadi
from ..errors import ModelError
from ..model import TIME, System, symbol
from ..model._system import RESERVED, ExprLike, _equations, exact
from ._base import Certificate, Check, ObserverDesign, Symbols
from ._tune import needs_only
from ._kind import kind
from ._common import require_system

__all__ = ["design_custom"]


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
tune_custom = needs_only("your own observer equations: `states`, `flow` (their derivatives in u, y and the states) and "
                         "`estimate` (x̂ in terms of them)", states="...", flow="...", estimate="...")


@kind('custom', summary='an observer given by its equations (one from a paper, or your own)',
      references=(), tune=tune_custom)
def design_custom(system: System, *, states: Sequence[str], flow: Sequence[ExprLike] | Mapping[str, ExprLike],
                  estimate: Sequence[ExprLike] | Mapping[str, ExprLike] | None = None,
                  params: Mapping[str, float] | None = None, initial: Sequence[ExprLike] | None = None,
                  xhat0: Any = None) -> ObserverDesign:
    r"""An observer given by its equations (an observer from a paper, or your own).

    .. math::

        \dot z = F(t, z, u, y), \qquad \hat x = H(t, z, u, y)

    Expressions may use the observer's `states`, the plant's inputs and outputs (the
    measurement), ``t``, the plant's parameters and the extra `params`. Strings are parsed
    safely (never evaluated).

    Parameters
    ----------
    system : System
        The plant model (its inputs, outputs and parameter values).
    states : sequence of str
        Names of the observer's internal states z.
    flow : sequence or mapping of expressions
        dz/dt, one per observer state.
    estimate : sequence or mapping of expressions, optional
        x̂, one per plant state (by plant state name when a mapping). Default: z itself
        (requires as many observer states as plant states).
    params : mapping of str to float, optional
        Tuning constants used in the expressions (e.g. a gain ``L``).
    initial : sequence of expressions in the plant's state names, optional
        z(0) as a function of the initial estimate x̂(0) (default: z(0) = x̂(0)).
    xhat0 : array_like, optional
        Default initial estimate (zeros).

    Examples
    --------
    A high-gain observer written by hand for Van der Pol with y = x1 (gains 2L and L²):

    >>> import nlobs
    >>> vdp = nlobs.System(states=["x1", "x2"], f=["x2", "(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"])
    >>> obs = design_custom(vdp, states=["xh1", "xh2"], params={"L": 5.0},
    ...                     flow=["xh2 + 2*L*(y - xh1)", "(1 - xh1**2)*xh2 - xh1 + L**2*(y - xh1)"])
    >>> obs.z_names
    ('xh1', 'xh2')
    """
    require_system(system, "design_custom")
    caller = "design_custom"
    names = tuple(states)
    extra = dict(params or {})
    taken = set(system.inputs) | set(system.outputs) | set(system.params) | {"t"}
    for n in (*names, *extra):
        if n in taken or n in RESERVED:
            raise ModelError(f"{caller}: the name `{n}` is already used by the plant (or reserved); rename it")
    allowed = {n: symbol(n) for n in (*names, *system.inputs, *system.outputs, *system.params, *extra)}
    allowed["t"] = TIME
    F = _equations("flow", flow, names, allowed)
    if estimate is None:
        if len(names) != system.n_states:
            raise ModelError(f"{caller}: give `estimate` (x̂ as a function of z): the observer has {len(names)} states, "
                             f"the plant {system.n_states}")
        H = tuple(allowed[n] for n in names)
    else:
        H = _equations("estimate", estimate, system.states, allowed)
    values = {**{k: exact(v) for k, v in system.params.items()}, **{k: exact(v) for k, v in extra.items()}}
    subs = {symbol(k): v for k, v in values.items()}
    s = Symbols.make(system, len(names))
    leaves = {TIME: s.t}
    leaves.update({symbol(n): s.z[i] for i, n in enumerate(names)})
    leaves.update({sym: s.u[i] for i, sym in enumerate(system.u)})
    leaves.update({sym: s.y[i] for i, sym in enumerate(system.y)})
    dz = to_casadi([e.xreplace(subs) for e in F], leaves)
    xhat = to_casadi([e.xreplace(subs) for e in H], leaves)
    x0 = ca.SX.sym("xhat0", system.n_states)
    if initial is None:
        if len(names) != system.n_states:
            raise ModelError(f"{caller}: give `initial` (z(0) as a function of x̂(0)): the observer has {len(names)} states, "
                             f"the plant {system.n_states}")
        z0 = x0
    else:
        init_allowed = {n: symbol(n) for n in (*system.states, *system.params, *extra)}
        Z0 = _equations("initial", initial, names, init_allowed)
        z0 = to_casadi([e.xreplace(subs) for e in Z0], {sym: x0[i] for i, sym in enumerate(system.x)})
    cert = Certificate("Observer given by its equations (no precondition checked)", "user-supplied",
                       (Check("equations parse and use only declared names", True),),
                       {"flow": [str(e) for e in F], "estimate": [str(e) for e in H], "params": extra})
    return ObserverDesign.build("custom", system, s, z_names=names, flow=dz, xhat=xhat, xhat0_sym=x0, z0=z0,
                                xhat0=np.zeros(system.n_states) if xhat0 is None else xhat0, certificate=cert)
