"""Observers on a mimicking augmented system (001): a linear observer in w = T(x), x̂ = T⁺(ŵ)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ..engine import to_casadi
from ..errors import PreconditionError
from ..model import TIME, System, symbol
from ..model._forms import matrix_of
from ..model._system import ExprLike, exact
from ._base import Certificate, Check, ObserverDesign, Symbols
from ._checks import observer_gain

__all__ = ["design_augmented"]

REF = ("001_1b4027b3a70d560f.txt: mimicking systems (2), Def. 3, Theorem 1 (observable iff T injective), "
       "Lemma 1 (observer through a left inverse); §IV-C eqs. (20)-(22)")


def design_augmented(system: System, *, T: Sequence[ExprLike], A: Any, C: Any, left_inverse: Sequence[ExprLike],
                     b: Sequence[ExprLike] | None = None, poles: Any = None, L: Any = None, Q: Any = None, R: Any = None,
                     xhat0: Any = None) -> ObserverDesign:
    r"""Luenberger observer on an LTI system that mimics the model through w = T(x) (001).

    The augmented system :math:`\dot w = Aw + b(u, t)`, :math:`y = Cw` mimics
    :math:`\dot x = f(x, u, t)`, :math:`y = h(x)` when, identically in (x, u, t),

    .. math::

        \frac{\partial T}{\partial x} f(x, u, t) = A\,T(x) + b(u, t), \qquad C\,T(x) = h(x).

    Then :math:`\dot{\hat w} = A\hat w + b(u, t) - L(C\hat w - y)` and
    :math:`\hat x = T^+(\hat w)` with a left inverse :math:`T^+(T(x)) = x`. Both identities and
    the left inverse are checked symbolically before the gain is computed.

    Parameters
    ----------
    system : System
    T : sequence of expressions in the states (and parameters)
        The state augmentation w = T(x).
    A : (n_w, n_w) matrix of numbers or expressions in the parameters
    C : (p, n_w) matrix
    left_inverse : sequence of expressions in ``w1, w2, ...``
        x = T⁺(w), one expression per state.
    b : sequence of expressions in the inputs, ``t`` and the parameters, optional
        The input term of the augmented system (default zero).
    poles, L, Q, R :
        The gain of the linear observer (see :func:`nlobs.design.observer_gain`).
    xhat0 : array_like, optional
        Initial estimate in x; the observer starts at ŵ = T(xhat0).

    Raises
    ------
    PreconditionError
        If the augmented system does not mimic the model (naming the row and the residual),
        T⁺ is not a left inverse of T, (A, C) is not observable, or the gain is not Hurwitz.

    References
    ----------
    001_1b4027b3a70d560f.txt eqs. (2), (20)-(22), Def. 3, Theorem 1, Lemma 1.
    """
    caller = "design_augmented"
    n = system.n_states
    params = {symbol(k): exact(v) for k, v in system.params.items()}
    f, h = system.substituted()
    base = {k: symbol(k) for k in (*system.states, *system.inputs, *system.params)}
    base["t"] = TIME
    Tm = matrix_of(list(T), len(T), 1, base, name="T").xreplace(params)
    nw = Tm.shape[0]
    Am = matrix_of(A, nw, nw, base, name="A").xreplace(params)
    Cm = matrix_of(C, system.n_outputs, nw, base, name="C").xreplace(params)
    bm = matrix_of(list(b) if b is not None else [0] * nw, nw, 1, base, name="b").xreplace(params)
    for label, M in (("A", Am), ("C", Cm)):
        if M.free_symbols:
            raise PreconditionError(f"{caller}: `{label}` must be constant (numbers and parameters); it contains "
                                    f"{', '.join(sorted(s.name for s in M.free_symbols))}. Use a time-varying design for LTV systems.")
    x = sp.Matrix(system.x)
    checks = []
    residual = (Tm.jacobian(x) * f - (Am * Tm + bm)).applyfunc(lambda e: sp.simplify(e))
    for i in range(nw):
        if residual[i] != 0:
            raise PreconditionError(f"{caller}: the augmented system does not mimic the model: row {i} of dT/dt - (A T + b) is "
                                    f"{residual[i]}, not 0 (001 eq. 2). Check T, A and b.")
    checks.append(Check("mimicking: dT/dt = A T(x) + b(u, t) along f (001 eq. 2)", True, "residual simplifies to 0"))
    out_res = (Cm * Tm - h).applyfunc(sp.simplify)
    for i in range(system.n_outputs):
        if out_res[i] != 0:
            raise PreconditionError(f"{caller}: C T(x) differs from the output {system.outputs[i]} by {out_res[i]}; C T(x) = h(x) is required")
    checks.append(Check("output: C T(x) = h(x)", True))
    wsyms = [symbol(f"w{i + 1}") for i in range(nw)]
    inv = matrix_of(list(left_inverse), n, 1, {**base, **{s.name: s for s in wsyms}}, name="left_inverse").xreplace(params)
    inv_res = (inv.xreplace(dict(zip(wsyms, Tm))) - x).applyfunc(sp.simplify)
    for i in range(n):
        if inv_res[i] != 0:
            raise PreconditionError(f"{caller}: the given left inverse does not recover {system.states[i]}: T⁺(T(x)) - x = "
                                    f"{inv_res[i]}; T must be injective with T⁺(T(x)) = x (001 Theorem 1)")
    checks.append(Check("left inverse: T⁺(T(x)) = x, so T is injective (001 Theorem 1)", True))
    An, Cn = np.array(Am, dtype=float), np.array(Cm, dtype=float)
    gain, gchecks, values = observer_gain(An, Cn, poles=poles, L=L, Q=Q, R=R, caller=caller)
    s = Symbols.make(system, nw)
    leaves = {TIME: s.t}
    leaves.update({sym: s.u[i] for i, sym in enumerate(system.u)})
    bw = to_casadi(list(bm), leaves)
    dz = ca.DM(An) @ s.z + bw - ca.DM(gain) @ (ca.DM(Cn) @ s.z - s.y)
    xhat = to_casadi(list(inv), {w: s.z[i] for i, w in enumerate(wsyms)})
    x0 = ca.SX.sym("xhat0", n)
    z0 = to_casadi(list(Tm), {sym: x0[i] for i, sym in enumerate(system.x)})
    values = {**values, "A": An, "C": Cn, "T(x)": str(list(Tm)), "left inverse": str(list(inv))}
    cert = Certificate("Luenberger observer on a mimicking augmented LTI system", REF, (*checks, *gchecks), values)
    return ObserverDesign.build("augmented", system, s, z_names=[f"what_{i + 1}" for i in range(nw)], flow=dz, xhat=xhat,
                                xhat0_sym=x0, z0=z0, xhat0=np.zeros(n) if xhat0 is None else xhat0, certificate=cert)
