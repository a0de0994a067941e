r"""GPEBO for state-affine systems and the 2G+D observer (Wang, Ortega & Bobtsov (2021)).

For :math:`\dot x = A(u, y, t)x + b(u, y, t)`, :math:`y = C(u, t)^\top x` (Wang, Ortega & Bobtsov (2021), eq. 1), Lemma 1 turns
state observation into the estimation of a constant vector: with

.. math::

    \dot\xi = A\xi + b, \qquad \dot\Phi_A = A\Phi_A, \quad \Phi_A(0) = I_n

(Wang, Ortega & Bobtsov (2021), eq. 13), :math:`x = \xi + \Phi_A\theta` with :math:`\theta = x(0) - \xi(0)` (eq. 8), and θ
satisfies the LRE :math:`\mathcal Y = \psi^\top\theta` with :math:`\mathcal Y = y - C^\top\xi`,
:math:`\psi = \Phi_A^\top C` (eqs. 9-10). Any estimator of :mod:`nlobs.design` then gives
:math:`\hat x = \xi + \Phi_A\hat\theta` (eq. 12); with the G+D estimator (eqs. 16-17) this is the
*2G+D observer*, which converges whenever the system is observable on some [0, T]
(Wang, Ortega & Bobtsov (2021), Proposition 1), uniform complete observability is not needed.

Where the homogeneous part is not uniformly stable (assumption 5), an output injection L
is added, as the paper suggests after eq. (5): :math:`\dot\xi = A\xi + b + L(y - C^\top\xi)`,
:math:`\dot\Phi_A = (A - LC^\top)\Phi_A`. The error :math:`e = x - \xi` then obeys
:math:`\dot e = (A - LC^\top)e`, and Lemma 1 holds with A replaced by :math:`A - LC^\top`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import sympy as sp

from ..errors import FormError, PreconditionError
from ..model import TIME, StateAffine, System, symbol
from ..model._forms import matrix_of
from ._base import Certificate, Check, ObserverDesign
from ._kalman import state_affine_parts
from ._regression import GD, AbstractEstimator, ExcitationMonitor, Regression, StateStack, estimator_from, sx_matrix
from ..references import cite

__all__ = ["design_gpebo", "design_2gd"]

REF = (f"{cite('000')} Lemma 1 (eqs. 8-10, 13), eq. (12); G+D estimator eqs. (16)-(17); "
       "order (3 + 2n)n, §6")


def _uniform_stability(A: sp.Matrix, caller: str, injected: bool) -> Check | None:
    """Assumption (5) for a constant homogeneous matrix: eigenvalues in Re < 0, or on the axis
    and semisimple. Returns None when A is not constant (not checkable symbolically)."""
    if A.free_symbols:
        return None
    An = np.array(A, dtype=float)
    eig = np.linalg.eigvals(An)
    worst = eig[np.argmax(eig.real)] if eig.size else 0.0
    what = "A - LCᵀ" if injected else "A"
    hint = (f"choose an output injection `L` with A - LCᵀ Hurwitz ({cite('000')}, remark after eq. 5)" if not injected
            else "choose another `L`")
    tol = 1e-9 * max(1.0, float(np.abs(An).max(initial=0.0)))
    if eig.size and worst.real > tol:
        raise PreconditionError(f"{caller}: the homogeneous part is not uniformly stable ({cite('000')} assumption 5): {what} has the "
                                f"eigenvalue {complex(worst):.4g} with positive real part, so Φ_A grows without bound; {hint}")
    axis = eig[np.abs(eig.real) <= tol]
    for lam in np.unique(np.round(axis, 9)):
        alg = int(np.sum(np.abs(eig - lam) <= 1e-6))
        geo = An.shape[0] - np.linalg.matrix_rank(An - lam * np.eye(An.shape[0]), tol=1e-8)
        if geo < alg:
            raise PreconditionError(f"{caller}: the homogeneous part is not uniformly stable ({cite('000')} assumption 5): {what} has the "
                                    f"eigenvalue {complex(lam):.3g} on the imaginary axis with a Jordan block (algebraic "
                                    f"multiplicity {alg} > geometric {geo}), so Φ_A grows polynomially; {hint}")
    return Check(f"uniform stability of the homogeneous part ({cite('000')} assumption 5), {what} constant", True,
                 f"max Re eig = {eig.real.max():.4g}")


def design_gpebo(system: StateAffine | System, *, estimator: AbstractEstimator | Any = None, L: Any = None,
                 xhat0: Any = None) -> ObserverDesign:
    r"""GPEBO observer for a state-affine system (Wang, Ortega & Bobtsov (2021), Lemma 1), with any regression estimator.

    .. math::

        \dot\xi &= A\xi + b + L(y - C^\top\xi), \qquad \dot\Phi_A = (A - LC^\top)\Phi_A,\quad \Phi_A(0) = I, \\
        \mathcal Y &= y - C^\top\xi, \qquad \psi = \Phi_A^\top C, \qquad \hat x = \xi + \Phi_A\hat\theta,

    with θ̂ from `estimator` on :math:`\mathcal Y = \psi^\top\theta` (L = 0 unless given).
    ξ(0) = `xhat0` and θ̂(0) = 0, so :math:`\hat x(0)` = `xhat0`; the true θ is
    :math:`x(0) - \hat x(0)`.

    Parameters
    ----------
    system : StateAffine or System
        The model :math:`\dot x = A(u, y, t)x + b(u, y, t)`, :math:`y = C(u, t)^\top x`; a System is
        read as state-affine after replacing the measured states by the outputs (as
        :func:`nlobs.design.design_kalman_like` does).
    estimator : estimator or mapping, optional
        :class:`GD` (default, gains 1: the 2G+D observer), :class:`DREM`, :class:`Gradient`,
        :class:`LeastSquares`, or a model-file table ``{kind = "gd", gamma_g = 5, gamma = 50}``.
    L : (n, p) matrix, optional
        Output injection (numbers or expressions in u, y, t and the parameters) making the
        homogeneous part uniformly stable where assumption (5) fails.
    xhat0 : array_like of shape (n,), optional
        Initial estimate (zeros).

    Returns
    -------
    ObserverDesign
        Internal state ``(ξ, Φ_A, estimator states)``; for G+D ``(ξ, Φ_A, θ̂_g, Ω, θ̂)`` of order
        (3 + 2n)n, which the certificate checks.

    Raises
    ------
    PreconditionError
        If the model is not state-affine, or A (or A - LCᵀ) is constant and not uniformly
        stable (an eigenvalue with positive real part or a Jordan block on the imaginary axis).

    Notes
    -----
    Assumption (5) cannot be decided symbolically when A depends on u, y or t; the certificate
    then says so, and the growth of Φ_A shows in the internal states of a run.

    References
    ----------
    Wang, Ortega & Bobtsov (2021), Lemma 1, eqs. (5), (8)-(13), Proposition 1, §6.
    """
    caller = "design_gpebo"
    try:
        parts = state_affine_parts(system, caller)
    except FormError as e:
        raise PreconditionError(f"{e}. Write the model as a StateAffine, with A(u, y, t) using the measured output y where "
                                f"the equation needs it ({cite('000')} eq. 1).") from e
    est = estimator_from(estimator, default=GD(1.0, 1.0), caller=caller)
    plant = parts.system
    n, p = plant.n_states, plant.n_outputs
    A, b, C = parts.A, parts.b, parts.C.T            # parameters substituted; C is n x p as in y = Cᵀx (000 eq. 1)
    allowed = {k: symbol(k) for k in (*plant.inputs, *plant.outputs, *plant.params)}
    allowed["t"] = TIME
    params = {symbol(k): v for k, v in plant.params.items()}
    Lm = sp.zeros(n, p) if L is None else matrix_of(L, n, p, allowed, name="L").xreplace(params)
    stab = _uniform_stability(A - Lm * C.T, caller, L is not None)

    stack = StateStack(plant)
    leaves = stack.leaves()
    A_, b_, C_, L_ = (sx_matrix(M, leaves) for M in (A, b, C, Lm))
    xi = stack.add("xi", n, init=stack.xhat0)
    Phi = stack.add("Phi", n, n, init=np.eye(n))
    Yr = stack.y - C_.T @ xi                        # (10a)
    stack.set_flow(xi, A_ @ xi + b_ + L_ @ Yr)      # (13a), with output injection
    stack.set_flow(Phi, (A_ - L_ @ C_.T) @ Phi)     # (13b)
    reg = Regression(Yr, Phi.T @ C_, tuple(f"theta{i + 1}" for i in range(n)))  # (9), (10b)
    out = est.build(stack, reg, np.zeros(n))
    xhat = xi + Phi @ out.theta                     # (12)

    order = stack.n_z
    checks = [Check(f"model is state-affine: x' = A(u, y, t)x + b(u, y, t), y = C(u, t)ᵀx ({cite('000')} eq. 1)", True, f"n = {n}, p = {p}")]
    if stab is not None:
        checks.append(stab)
    if isinstance(est, GD):
        paper = (3 + 2 * n) * n
        checks.append(Check(f"observer order n_χ = (3 + 2n)n as stated in {cite('000')} §6", order == paper,
                            f"{order} internal states = n (ξ) + n² (Φ_A) + n (θ̂_g) + n² (Ω) + n (θ̂); (3 + 2n)n = {paper}"))
    values: dict[str, Any] = {
        "A": str(A.tolist()), "b": str(list(b)), "C": str(C.tolist()), **({"L": str(Lm.tolist())} if L is not None else {}),
        **est.describe(), "internal states": order,
        "assumption (5)": ("checked (A constant)" if stab is not None else
                           "not decidable symbolically (A depends on u, y or t): ‖Φ_A‖ must stay bounded along the input"),
        "excitation monitor": ExcitationMonitor.of(stack, out, est),
    }
    name = "2G+D observer" if isinstance(est, GD) else f"GPEBO observer with {type(est).__name__} estimator"
    cert = Certificate(name + (" and output injection" if L is not None else ""), REF + "; " + est.reference, tuple(checks), values)
    return stack.build("gpebo_2gd" if isinstance(est, GD) else "gpebo", xhat=xhat, certificate=cert, xhat0=xhat0)


def design_2gd(system: StateAffine | System, *, gamma_g: float = 1.0, gamma: float = 1.0, L: Any = None,
               xhat0: Any = None) -> ObserverDesign:
    r"""The 2G+D observer of Wang, Ortega & Bobtsov (2021), Proposition 1: GPEBO (Lemma 1) with the G+D estimator (Lemma 2).

    Globally exponentially convergent for every state-affine system that is *observable* on
    some interval [0, T] (rank W(0, T) = n), under assumption (5); UCO is not needed.
    See :func:`design_gpebo` for the equations.

    Parameters
    ----------
    system : StateAffine or System
    gamma_g, gamma : float
        Gains of the gradient and of the mixed scalar stage of G+D (Wang, Ortega & Bobtsov (2021), eqs. 16a, 16c).
    L : (n, p) matrix, optional
        Output injection where assumption (5) fails.
    xhat0 : array_like, optional

    References
    ----------
    Wang, Ortega & Bobtsov (2021), Proposition 1, Lemmas 1-2, eqs. (12)-(17).

    Examples
    --------
    >>> import nlobs
    >>> sa = nlobs.StateAffine([[0, "u"], [0, 0]], [0, 0], [[1], [0]], inputs=["u"])
    >>> design_2gd(sa, gamma_g=5, gamma=50).n_z        # (3 + 2n)n with n = 2
    14
    """
    return design_gpebo(system, estimator=GD(gamma_g, gamma), L=L, xhat0=xhat0)

