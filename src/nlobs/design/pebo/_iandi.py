r"""Immersion and invariance observer with the pseudo-inverse (Yi, Ortega & Zhang (2019), Proposition 4).

Given :math:`\beta(y, \chi) \in \mathbb R^{n_z}`, :math:`\phi(x) \in \mathbb R^{n_z}` and a left
inverse :math:`\phi^L(\phi(x), y) = x`, the observer makes the manifold
:math:`\beta(h(x), \chi) = \phi(x)` invariant:

.. math::

    \dot\chi &= -[\nabla_\chi\beta^\top]^\dagger\big(\nabla_y\beta^\top\nabla h^\top(\hat x)
               - \nabla\phi^\top(\hat x)\big)f(\hat x, u)
               + \big(I - [\nabla_\chi\beta^\top]^\dagger\nabla_\chi\beta^\top\big)Q(y, \chi, u), \\
    \hat x &= \phi^L(\beta(y, \chi), y)

(Yi, Ortega & Zhang (2019), eqs. 18-19), where :math:`\nabla_\chi\beta^\top = \partial\beta/\partial\chi` is the
:math:`n_z \times n_\chi` Jacobian and † the Moore-Penrose pseudo-inverse. A4 asks this Jacobian
to have full row rank :math:`n_z`, so that :math:`JJ^\dagger = I` and the off-the-manifold
coordinate :math:`d = \beta - \phi(x)` obeys (16); A5 (its zero equilibrium is asymptotically
stable) depends on the design and is not checked.

Re-derivation (the PDF conversion prints Q as :math:`\mathbb R^{n_x \times n_x}`-valued): for
:math:`(I - J^\dagger J)Q` to be a vector field on χ, Q maps into :math:`\mathbb R^{n_\chi}`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ...algebra._identity import decide_identity, exact_generic_rank
from ...engine import to_casadi
from ...errors import PreconditionError, ShapeError
from ...model import TIME, System, symbol
from ...model._forms import matrix_of
from ...model._system import exact
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign
from .._tune import needs_only
from .._kind import kind
from .._checks import identity_check
from ._regression import StateStack

__all__ = ["design_iandi"]

REF = f"{cite('004')} Proposition 4: A4, A5, eqs. (16)-(19); remarks R7-R8"


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
tune_iandi = needs_only(f"β(y, χ), φ(x) and a left inverse φᴸ(ξ, y) ({cite('004', 'Proposition 4')}); the manifold condition "
                        "is the designer's part", beta="...", phi="...", left_inverse="...")


@kind('iandi', summary='immersion-and-invariance (I&I) observer with the pseudo-inverse of ∂β/∂χ',
      references=(work("004", "Proposition 4"),), tune=tune_iandi)
def design_iandi(system: System, *, beta: Sequence[Any], phi: Sequence[Any], left_inverse: Sequence[Any],
                 n_chi: int | None = None, Q: Sequence[Any] | None = None, chi0: Any = None,
                 xhat0: Any = None) -> ObserverDesign:
    r"""I&I observer (Yi, Ortega & Zhang (2019), Proposition 4, eqs. 18-19) with the pseudo-inverse of :math:`\partial\beta/\partial\chi`.

    Parameters
    ----------
    system : System
        ẋ = f(x, u), y = h(x).
    beta : sequence of expressions in the outputs and ``chi1, chi2, ...``
        β(y, χ), n_z components.
    phi : sequence of expressions in the states
        φ(x), n_z components.
    left_inverse : sequence of expressions in ``xi1, ..., xi{n_z}`` and the outputs
        φ^L(ξ, y) with φ^L(φ(x), h(x)) = x (checked); one expression per state.
    n_chi : int, optional
        Dimension of χ (default n_z); n_χ ≥ n_z.
    Q : sequence of expressions in the outputs, ``chi1, ...`` and the inputs, optional
        The free term of (18), n_χ components (default 0).
    chi0 : array_like of shape (n_chi,), optional
        A fixed χ(0), whatever the initial estimate asked for.
    xhat0 : array_like of shape (n,), optional
        Default initial estimate (zeros). Without `chi0`, when β is affine in χ with a constant
        Jacobian J, the observer starts on the manifold of the estimate:
        :math:`\chi(0) = J^\dagger(\phi(\hat x_0) - \beta(h(\hat x_0), 0))` (so x̂0 = 0 gives χ(0) = 0
        when φ(0) = 0 and β(0, 0) = 0, the "dynamic extensions at 0" of Yi, Ortega & Zhang (2019), §V-C); otherwise χ(0) = 0.

    Returns
    -------
    ObserverDesign

    Raises
    ------
    PreconditionError
        If φ^L is not a left inverse of φ, n_χ < n_z, or A4 fails: the generic rank of
        ∂β/∂χ is below n_z (the pseudo-inverse then does not keep the manifold invariant).

    Notes
    -----
    A4 is checked at random points (generic rank); the observer also needs it along the
    trajectory, where ∂β/∂χ (∂β/∂χ)ᵀ is inverted. A5 is the designer's part: the
    certificate lists it as not verified.

    References
    ----------
    Yi, Ortega & Zhang (2019), Proposition 4, eqs. (16)-(19), R7-R8.
    """
    caller = "design_iandi"
    if not isinstance(system, System):
        raise TypeError(f"{caller}: expected a System, got {type(system).__name__}")
    n = system.n_states
    if isinstance(beta, (str, sp.Basic)) or isinstance(phi, (str, sp.Basic)):
        raise ShapeError(f"{caller}: `beta` and `phi` must be lists of expressions")
    nz = len(beta)
    if len(phi) != nz:
        raise ShapeError(f"{caller}: `beta` has {nz} components but `phi` has {len(phi)}; both map into R^n_z")
    nchi = nz if n_chi is None else int(n_chi)
    if nchi < nz:
        raise PreconditionError(f"{caller}: n_chi = {nchi} < n_z = {nz}; Proposition 4 needs n_χ ≥ n_z")
    params = {symbol(k): exact(v) for k, v in system.params.items()}
    base = {k: symbol(k) for k in system.params}
    base["t"] = TIME
    chi = [symbol(f"chi{i + 1}") for i in range(nchi)]
    xi = [symbol(f"xi{i + 1}") for i in range(nz)]
    ys = {k: symbol(k) for k in system.outputs}
    clash = [s.name for s in (*chi, *xi) if s.name in (*system.states, *system.inputs, *system.outputs, *system.params)]
    if clash:
        raise PreconditionError(f"{caller}: the model declares `{clash[0]}`, a name nlobs reserves here for χ or ξ; rename it")
    beta_m = matrix_of(list(beta), nz, 1, {**base, **ys, **{s.name: s for s in chi}}, name="beta").xreplace(params)
    phi_m = matrix_of(list(phi), nz, 1, {**base, **{k: symbol(k) for k in system.states}}, name="phi").xreplace(params)
    left_m = matrix_of(list(left_inverse), n, 1, {**base, **ys, **{s.name: s for s in xi}}, name="left_inverse").xreplace(params)
    Q_m = (sp.zeros(nchi, 1) if Q is None else
           matrix_of(list(Q), nchi, 1, {**base, **ys, **{s.name: s for s in chi}, **{k: symbol(k) for k in system.inputs}},
                     name="Q").xreplace(params))
    f, h = system.substituted()
    if any(s in (*system.u, TIME) for e in h for s in e.free_symbols):
        raise PreconditionError(f"{caller}: the outputs must be functions of the state only, y = h(x) ({cite('004')} eq. 1)")
    checks = []
    hsub = {symbol(k): h[i] for i, k in enumerate(system.outputs)}
    verdicts = []
    for i, x in enumerate(system.x):
        back = left_m[i].xreplace({**dict(zip(xi, phi_m)), **hsub})
        v = decide_identity(back, x, seed=i)
        if v.fails:
            raise PreconditionError(f"{caller}: `left_inverse` is not a left inverse of φ: φ^L(φ(x), h(x)) gives "
                                    f"{sp.simplify(back)} for {system.states[i]}{v.where()}")
        verdicts.append(v)
    checks.append(identity_check("φ^L(φ(x), h(x)) = x", verdicts, [f"state {s_}" for s_ in system.states]))
    Jchi = beta_m.jacobian(sp.Matrix(chi))
    gr = exact_generic_rank(Jchi)
    rank = gr.rank
    if rank < nz:
        raise PreconditionError(f"{caller}: A4 fails: ∂β/∂χ = {Jchi.tolist()} has generic rank {rank} < n_z = {nz} ({cite('004')} A4; "
                                f"{gr.evidence}); the pseudo-inverse in (18) cannot keep β(y, χ) = φ(x) invariant. Make β depend "
                                "on χ in n_z independent directions.")
    checks.append(Check(f"A4: generic rank ∂β/∂χ = n_z ({cite('004')})", True, f"generic rank {rank} = n_z = {nz}", gr.evidence))
    checks.append(Check.assumed(f"A4 along the trajectory: ∂β/∂χ keeps rank n_z where the observer runs ({cite('004')})",
                                "the generic rank is verified; a point of lower rank on the trajectory makes (18) singular"))
    checks.append(Check.assumed(f"A5: the zero equilibrium of the off-the-manifold dynamics (16) is asymptotically stable "
                                f"({cite('004')})", "the designer's part; not verified"))

    stack = StateStack(system)
    if chi0 is not None:
        if np.asarray(chi0).size != nchi:
            raise ShapeError(f"{caller}: `chi0` must have {nchi} entries, got {np.asarray(chi0).size}")
        init: Any = np.asarray(chi0, dtype=float).reshape(-1)
    elif Jchi.free_symbols:
        init = np.zeros(nchi)
    else:  # start on the manifold β(h(x̂0), χ) = φ(x̂0) of the initial estimate
        J0 = np.array(Jchi, dtype=float)
        x0l = {s: stack.xhat0[i] for i, s in enumerate(system.x)}
        b0 = to_casadi(list(beta_m.xreplace({**hsub, **{c: 0 for c in chi}})), x0l)
        init = ca.DM(np.linalg.pinv(J0)) @ (to_casadi(list(phi_m), x0l) - b0)
    chi_sx = stack.add("chi", nchi, init=init)
    lv = {**stack.leaves(), **{s: chi_sx[i] for i, s in enumerate(chi)}}
    beta_sx = to_casadi(list(beta_m), lv)
    xhat = to_casadi(list(left_m), {**lv, **{s: beta_sx[i] for i, s in enumerate(xi)}})        # (19)
    X = ca.SX.sym("x", n)
    xl = stack.leaves(X)
    f_x, h_x, phi_x = to_casadi(list(f), xl), to_casadi(list(h), xl), to_casadi(list(phi_m), xl)
    drift = ca.Function("drift", [X, stack.y, stack.u, stack.t, chi_sx],
                        [(ca.jacobian(beta_sx, stack.y) @ ca.jacobian(h_x, X) - ca.jacobian(phi_x, X)) @ f_x])
    J = ca.jacobian(beta_sx, chi_sx)
    JJt = J @ J.T
    dchi = -J.T @ ca.solve(JJt, drift(xhat, stack.y, stack.u, stack.t, chi_sx))                  # (18), J† = Jᵀ(JJᵀ)⁻¹
    if Q is not None:
        q = to_casadi(list(Q_m), lv)
        dchi = dchi + q - J.T @ ca.solve(JJt, J @ q)
    stack.set_flow(chi_sx, dchi)
    values = {"beta": str(list(beta_m)), "phi": str(list(phi_m)), "left inverse": str(list(left_m)),
              "d beta / d chi": str(Jchi.tolist()), **({"Q": str(list(Q_m))} if Q is not None else {}),
              "internal states": nchi}
    cert = Certificate("I&I observer with pseudo-inverse", REF, tuple(checks), values)
    return stack.build("iandi", xhat=xhat, certificate=cert, xhat0=xhat0)
