"""Square-root extended Kalman filter, continuous-discrete: a factor of P is propagated, P never formed."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from ...engine import compile_system
from ...model import System
from ...references import cite, work
from .._base import Certificate, ObserverDesign, Symbols, check_vector
from .._tune import robust_filter
from .._kind import Tuning
from .._kind import kind
from .._common import require_system
from ._robust_maps import discrete_srekf
from ._sqrt import covariance_inputs, lower_solve, lower_t_solve, sqrt_psd, tria

__all__ = ["design_srekf"]

REF = (f"Square-root covariance filter ({cite('kaminski1971')}) with the array (QR) form of the Joseph update "
       f"({cite('arasaratnam2009')}, Tria); extended Kalman filter ({cite('jazwinski1970')})")


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def tune_srekf(ctx: Any) -> Tuning:
    """The EKF/UKF tuning (Q, R, P(0) from the run; see :func:`~nlobs.design._tune.robust_filter`)."""
    return robust_filter(ctx, "srekf")


@kind('srekf', likelihood='ekf', summary='square-root extended Kalman filter (continuous-discrete, or on a map): the EKF carrying a square root of P (QR Joseph update)',
      references=(work("kaminski1971", "square-root covariance, QR Joseph update"),), time_base="both", tune=tune_srekf, map_smoother="extended")
def design_srekf(system: System, *, Q: Any, R: Any, P0: Any = None, xhat0: Any = None) -> ObserverDesign:
    r"""Square-root extended Kalman filter (continuous-discrete): the EKF of :func:`design_ekf` carrying a
    square root of P, rebuilt at each sample as a lower Cholesky factor S by QR triangularisation; P is never
    formed and no Cholesky factorisation or downdate is taken.

    Between samples, with :math:`F = \partial f/\partial x` at :math:`\hat x`:

    .. math::

        \dot{\hat x} = f(\hat x), \qquad \dot G = F G, \qquad \dot G_q = F G_q, \qquad \dot\tau = 1,

    from :math:`G = S^+`, :math:`G_q = Q^{1/2}` and τ = 0 at the last sample, so that G Gᵀ = Φ P⁺ Φᵀ (Φ the
    transition of the linearised flow) and :math:`G_qG_q^\top = \Phi Q\Phi^\top`. At the next sample the
    process noise :math:`\int_0^\tau\Phi Q\Phi^\top` is taken by the trapezoid rule (error O(τ³)):

    .. math::

        S^- = \mathrm{Tria}\big[G,\; \sqrt{\tau/2}\,G_q,\; \sqrt{\tau/2}\,Q^{1/2}\big],

    then with :math:`H = \partial h/\partial x` at :math:`\hat x^-`: :math:`S_y = \mathrm{Tria}[HS^-, R^{1/2}]`,
    :math:`K = S^-(HS^-)^\top S_y^{-\top}S_y^{-1}`, :math:`\hat x^+ = \hat x^- + K(y - h(\hat x^-))` and the Joseph
    form as one triangularisation, :math:`S^+ = \mathrm{Tria}[(I - KH)S^-,\; KR^{1/2}]`. With Q = 0 this is the
    EKF exactly (up to RK4's error); with Q it differs from the EKF's Riccati ODE by the trapezoid rule's O(τ³).
    Outputs missing at a sample are left out.

    Parameters
    ----------
    system : System
    Q : array_like of shape (n, n)
        Process-noise intensity, positive semidefinite.
    R : array_like of shape (p, p)
        Covariance of one measurement sample, positive definite.
    P0 : array_like of shape (n, n), optional
        Initial covariance (identity), positive definite.

    Other Parameters
    ----------------
    xhat0 : array_like of shape (n,), optional

    Raises
    ------
    PreconditionError, ShapeError
        For matrices of the wrong shape, not symmetric, or not (semi)definite.
    """
    require_system(system, "design_srekf")
    caller = "design_srekf"
    if system.is_discrete:   # a map x[k+1] = f(x[k], u[k]): the map EKF's semantics, in square-root form
        return discrete_srekf(system, Q=Q, R=R, P0=P0, xhat0=xhat0, caller=caller)
    n, p = system.n_states, system.n_outputs
    Qm, Rm, P0m, checks = covariance_inputs(Q, R, P0, n, p, caller)
    x0v = check_vector(np.zeros(n) if xhat0 is None else xhat0, n, "xhat0", caller)
    f, h = compile_system(system).bind()
    nn = n * n
    s = Symbols.make(system, n + 2 * nn + 1)
    x = s.z[:n]
    G = ca.reshape(s.z[n:n + nn], n, n)
    Gq = ca.reshape(s.z[n + nn:n + 2 * nn], n, n)
    tau = s.z[n + 2 * nn]
    fx, hx = f(s.t, x, s.u), h(s.t, x, s.u)
    F, H = ca.jacobian(fx, x), ca.jacobian(hx, x)
    flow = ca.vertcat(fx, ca.vec(F @ G), ca.vec(F @ Gq), 1)
    Lq = ca.DM(sqrt_psd(Qm))
    half = ca.sqrt(tau / 2)
    Sm = tria(ca.horzcat(G, half * Gq, half * Lq))
    Md = ca.diag(s.m)
    HS = Md @ H @ Sm
    Rh = Md @ ca.DM(sqrt_psd(Rm))
    Sy = tria(ca.horzcat(HS, Rh, ca.diag(1 - s.m)))  # unmeasured outputs: a decoupled unit block, zero gain
    K = lower_t_solve(Sy, lower_solve(Sy, HS @ Sm.T)).T  # Kᵀ = Sy⁻ᵀ Sy⁻¹ (HS⁻)S⁻ᵀ, i.e. K = S⁻(HS⁻)ᵀ (Sy Syᵀ)⁻¹
    x_plus = x + K @ (s.m * (s.y - hx))
    S_plus = tria(ca.horzcat(Sm - K @ HS, K @ Rh))
    update = ca.vertcat(x_plus, ca.vec(S_plus), ca.vec(Lq), 0)
    P = G @ G.T + tau / 2 * (Gq @ Gq.T + ca.DM(Qm))
    x0 = ca.SX.sym("xhat0", n)
    values: dict[str, Any] = {"Q": Qm, "R": Rm, "P0": P0m,
                              "square root": "lower Cholesky factor S (P = SSᵀ) from Householder QR at each sample; "
                                             "between samples G = ΦS, process noise by the trapezoid rule"}
    cert = Certificate("Square-root extended Kalman filter (continuous-discrete)", REF, tuple(checks), values)
    names = ([f"xhat_{v}" for v in system.states] + [f"G_{i}_{j}" for j in range(n) for i in range(n)]
             + [f"Gq_{i}_{j}" for j in range(n) for i in range(n)] + ["tau"])
    z0 = ca.vertcat(x0, ca.vec(ca.DM(np.linalg.cholesky(P0m))), ca.vec(Lq), 0)
    return ObserverDesign.build("srekf", system, s, z_names=names, flow=flow, xhat=x, xhat0_sym=x0, z0=z0, xhat0=x0v,
                                certificate=cert, update=update, covariance=P)
