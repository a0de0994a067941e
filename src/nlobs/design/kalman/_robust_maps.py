r"""The square-root UKF and EKF and the iterated EKF of a discrete-time map x[k+1] = f(x[k], u[k], t[k]) + w[k],
y[k] = h(x[k], u[k], t[k]) + v[k], with the semantics of the map EKF and UKF (:mod:`._maps`): z carries the input of
the previous step and a flag; the update at t_k predicts from t_{k−1} with u_{k−1} (nothing at the first sample, where
x̂(0), P(0) are the prior of x[0]) and corrects with y_k; Q is the covariance of w per step; the estimate at t_k is
x̂[k|k].

- Square-root EKF (Kaminski, Bryson & Schmidt (1971); the array form of Arasaratnam & Haykin (2009)): S with
  P = SSᵀ, :math:`S^- = \mathrm{Tria}[FS,\ Q^{1/2}]` (F = ∂f/∂x at x̂), :math:`S_y = \mathrm{Tria}[HS^-,\ R^{1/2}]`,
  :math:`K = S^-(HS^-)^\top S_y^{-\top}S_y^{-1}`, :math:`S^+ = \mathrm{Tria}[(I - KH)S^-,\ KR^{1/2}]`: in exact
  arithmetic the map EKF with its Joseph form, P never formed.
- Square-root UKF (van der Merwe & Wan (2001)): the map UKF's scaled sigma points :math:`\hat x \pm \sqrt{c}\,S_i`
  through f, :math:`\hat x^- = \sum W^m_i f(\mathcal X_i)`; with the weighted deviations
  :math:`\tilde X = \sqrt{W^c}(f(\mathcal X) - \hat x^-)` and :math:`\tilde Y = \sqrt{W^c}(\mathcal Y - \hat y)` of the
  propagated points and their outputs (the update reuses the propagated points, as the map UKF and filterpy do),
  :math:`S_y = \mathrm{Tria}[\tilde Y,\ R^{1/2}]`, :math:`K = \tilde X\tilde Y^\top S_y^{-\top}S_y^{-1}` and

  .. math:: S^+ = \mathrm{Tria}\big[\tilde X - K\tilde Y,\ Q^{1/2},\ KR^{1/2}\big],

  an exact factor of the map UKF's :math:`P^- - KSK^\top` with :math:`P^- = \tilde X\tilde X^\top + Q` (expand the
  product and use :math:`KS_yS_y^\top = \tilde X\tilde Y^\top`). Sums of squares only: the covariance weights must
  be ≥ 0.
- Iterated EKF (Bell & Cathey (1993)): the map EKF's prediction, then Gauss-Newton steps on the update from
  :math:`x_0 = \hat x^-`: :math:`x_{i+1} = \hat x^- + K_i(y - h(x_i) - H_i(\hat x^- - x_i))`,
  :math:`K_i = P^-H_i^\top(H_iP^-H_i^\top + R)^{-1}`, stopping below `tol`; the Joseph form with the last K, H.

Outputs not measured at a step (m = 0) are left out of the update.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from ...engine import compile_system
from ...errors import PreconditionError
from ...model import System
from ...references import cite
from .._base import Certificate, Check, ObserverDesign
from .._common import symmetric_part
from ._maps import _layout, _names, _sigma_weights, _weights
from ._sqrt import lower_solve, lower_t_solve, sqrt_psd, tria

__all__ = ["discrete_srekf", "discrete_srukf", "discrete_iekf"]

REF_SREKF = (f"Square-root extended Kalman filter, discrete time ({cite('kaminski1971')}; array form of "
             f"{cite('arasaratnam2009')}); {cite('simon2006', '§13.2')}")
REF_SRUKF = (f"Square-root unscented Kalman filter, discrete time ({cite('vandermerwe2001')}), the update as one QR "
             f"triangularisation ({cite('arasaratnam2009')}); scaled sigma points of {cite('wan2000')}")
REF_IEKF = (f"Iterated extended Kalman filter, discrete time: the update as Gauss-Newton iterations ({cite('bell1993')}); "
            f"{cite('simon2006', '§13.2')}")


def _checks(Qm: np.ndarray, Rm: np.ndarray, P0m: np.ndarray) -> list[Check]:
    return [Check("Q positive semidefinite (per step), R and P0 positive definite", True,
                  f"min eig Q {np.linalg.eigvalsh(Qm).min():.3g}, R {np.linalg.eigvalsh(Rm).min():.3g}, "
                  f"P0 {np.linalg.eigvalsh(P0m).min():.3g}")]


def _factor_names(system: System, letter: str = "S") -> list[str]:
    n = system.n_states
    return [f"xhat_{v}" for v in system.states] + [f"{letter}_{i}_{j}" for j in range(n) for i in range(n)]


def _start(system: System, P0m: np.ndarray) -> tuple[ca.SX, ca.SX]:
    """x̂(0) as a symbol and z(0) = [x̂(0), chol(P0), u_prev = 0, started = 0]."""
    n = system.n_states
    x0 = ca.SX.sym("xhat0", n)
    return x0, ca.vertcat(x0, ca.vec(ca.DM(np.linalg.cholesky(P0m))), ca.DM.zeros(system.n_inputs), 0)


def _sqrt_gain(Sy: ca.SX, Yt: ca.SX, Xt: ca.SX) -> ca.SX:
    """K = Xt Ytᵀ (Sy Syᵀ)⁻¹ by a forward and a back substitution (Sy lower triangular)."""
    return lower_t_solve(Sy, lower_solve(Sy, Yt @ Xt.T)).T


def discrete_srekf(system: System, *, Q: Any, R: Any, P0: Any = None, xhat0: Any = None,
                   caller: str = "design_srekf") -> ObserverDesign:
    """The square-root EKF of a map (see the module's docstring); called by :func:`nlobs.design_srekf`."""
    n = system.n_states
    Qm, Rm, P0m, x0v = _weights(system, Q, R, P0, xhat0, caller)
    f, h = compile_system(system).bind()
    s, core, u_prev, started = _layout(system, n + n * n)
    x, S = core[:n], ca.reshape(core[n:], n, n)
    fx = f(s.t - system.sample_time, x, u_prev)
    F = ca.jacobian(fx, x)
    Lq = ca.DM(sqrt_psd(Qm))
    x_pred = ca.if_else(started, fx, x)
    S_pred = ca.if_else(started, tria(ca.horzcat(F @ S, Lq)), S)
    xv = ca.SX.sym("xv", n)
    hv = h(s.t, xv, s.u)
    hx, H = ca.substitute([hv, ca.jacobian(hv, xv)], [xv], [x_pred])
    Md = ca.diag(s.m)
    HS = Md @ H @ S_pred
    Rh = Md @ ca.DM(sqrt_psd(Rm))
    Sy = tria(ca.horzcat(HS, Rh, ca.diag(1 - s.m)))   # an unmeasured output: a decoupled unit block, zero gain
    K = _sqrt_gain(Sy, HS, S_pred)
    x_new = x_pred + K @ (s.m * (s.y - hx))
    S_new = tria(ca.horzcat(S_pred - K @ HS, K @ Rh))
    x0, z0 = _start(system, P0m)
    values = {"Q": Qm, "R": Rm, "P0": P0m, "sample_time": system.sample_time,
              "square root": "lower Cholesky factor S (P = SSᵀ) from Householder QR at each step; no Cholesky factorisation"}
    cert = Certificate("Square-root extended Kalman filter (discrete time)", REF_SREKF, tuple(_checks(Qm, Rm, P0m)), values)
    return ObserverDesign.build("srekf", system, s, z_names=_names(system, _factor_names(system)),
                                flow=ca.SX.zeros(s.z.shape[0]), xhat=x, xhat0_sym=x0, z0=z0, xhat0=x0v, certificate=cert,
                                update=ca.vertcat(x_new, ca.vec(S_new), s.u, 1), covariance=S @ S.T)


def discrete_srukf(system: System, *, Q: Any, R: Any, P0: Any = None, xhat0: Any = None, alpha: float = 1.0,
                   beta: float = 0.0, kappa: float = 0.0, caller: str = "design_srukf") -> ObserverDesign:
    """The square-root UKF of a map (see the module's docstring); called by :func:`nlobs.design_srukf`."""
    n = system.n_states
    Qm, Rm, P0m, x0v = _weights(system, Q, R, P0, xhat0, caller)
    if not (alpha > 0 and np.isfinite(alpha)) or not np.isfinite(beta) or not (np.isfinite(kappa) and n + kappa > 0):
        raise PreconditionError(f"{caller}: need α > 0, finite β and n + κ > 0; got α = {alpha}, β = {beta}, κ = {kappa}")
    lam, Wm, Wc = _sigma_weights(n, float(alpha), float(beta), float(kappa))
    if Wc.min() < -1e-12 * float(np.abs(Wc).max()):
        raise PreconditionError(f"{caller}: the covariance weight W0 = {Wc[0]:g} is negative (α = {alpha:g}, β = {beta:g}, "
                                f"κ = {kappa:g}); the square-root form needs non-negative weights: take β ≥ {beta - Wc[0]:.10g}, "
                                "or the defaults α = 1, β = 0, κ = 0")
    sw = [float(np.sqrt(max(w, 0.0))) for w in Wc]
    sc = float(np.sqrt(n + lam))
    f, h = compile_system(system).bind()
    s, core, u_prev, started = _layout(system, n + n * n)
    x, S = core[:n], ca.reshape(core[n:], n, n)
    drawn = [x] + [x + sc * S[:, i] for i in range(n)] + [x - sc * S[:, i] for i in range(n)]
    prop = [f(s.t - system.sample_time, c, u_prev) for c in drawn]
    pts = [ca.if_else(started, a, b) for a, b in zip(prop, drawn)]   # at the first sample: the prior's points
    x_pred = sum((float(w) * c for w, c in zip(Wm, pts)), ca.SX.zeros(n))
    ys = [h(s.t, c, s.u) for c in pts]
    yhat = sum((float(w) * c for w, c in zip(Wm, ys)), ca.SX.zeros(system.n_outputs))
    Md = ca.diag(s.m)
    Xt = ca.horzcat(*[w * (c - x_pred) for w, c in zip(sw, pts)])
    Yt = Md @ ca.horzcat(*[w * (c - yhat) for w, c in zip(sw, ys)])
    Rh = Md @ ca.DM(sqrt_psd(Rm))
    Lq = started * ca.DM(sqrt_psd(Qm))      # no process noise before the first prediction
    Sy = tria(ca.horzcat(Yt, Rh, ca.diag(1 - s.m)))   # an unmeasured output: a decoupled unit block, zero gain
    K = _sqrt_gain(Sy, Yt, Xt)
    x_new = x_pred + K @ (s.m * (s.y - yhat))
    S_new = tria(ca.horzcat(Xt - K @ Yt, Lq, K @ Rh))
    x0, z0 = _start(system, P0m)
    checks = _checks(Qm, Rm, P0m) + [Check("sigma-point spread n + λ > 0 and covariance weights ≥ 0", True,
                                           f"n + λ = {n + lam:g}, min W = {Wc.min():g}")]
    values = {"Q": Qm, "R": Rm, "P0": P0m, "alpha": float(alpha), "beta": float(beta), "kappa": float(kappa), "lambda": lam,
              "weights_mean": Wm, "weights_cov": Wc, "sample_time": system.sample_time,
              "square root": "lower Cholesky factor S (P = SSᵀ) from Householder QR; no Cholesky factorisation or downdate"}
    cert = Certificate("Square-root unscented Kalman filter (discrete time)", REF_SRUKF, tuple(checks), values)
    return ObserverDesign.build("srukf", system, s, z_names=_names(system, _factor_names(system)),
                                flow=ca.SX.zeros(s.z.shape[0]), xhat=x, xhat0_sym=x0, z0=z0, xhat0=x0v, certificate=cert,
                                update=ca.vertcat(x_new, ca.vec(S_new), s.u, 1), covariance=S @ S.T)


def iterated_update(h: Any, s: Any, x_prior: Any, P_prior: Any, Rm: np.ndarray, iterations: int,
                    tol: float) -> tuple[Any, Any]:
    """The iterated EKF's measurement update (Bell & Cathey (1993): Gauss-Newton on the MAP cost, the gain and the
    Joseph update at the last iterate), with the per-output mask ``s.m`` (an unmeasured output: a decoupled unit
    block of R, zero gain); stops iterating once a step moves x̂ by less than `tol`. Returns (x̂⁺, P⁺)."""
    n = x_prior.shape[0]
    xv = ca.SX.sym("xv", n)
    hv = h(s.t, xv, s.u)
    h_and_H = ca.Function("h_and_H", [xv, s.t, s.u], [hv, ca.jacobian(hv, xv)])
    Md = ca.diag(s.m)
    Rmask = Md @ ca.DM(Rm) @ Md + ca.diag(1 - s.m)
    xi, done = x_prior, ca.SX(0)
    K = Hm = None
    for _ in range(int(iterations)):
        hi, Hi = h_and_H(xi, s.t, s.u)
        Hi_m = Md @ Hi
        Ki = ca.solve(symmetric_part(Hi_m @ P_prior @ Hi_m.T + Rmask), Hi_m @ P_prior).T
        x_next = x_prior + Ki @ (s.m * (s.y - hi - Hi @ (x_prior - xi)))
        step = ca.mmax(ca.fabs(x_next - xi))
        K = Ki if K is None else ca.if_else(done, K, Ki)
        Hm = Hi_m if Hm is None else ca.if_else(done, Hm, Hi_m)
        xi = ca.if_else(done, xi, x_next)
        done = ca.logic_or(done, step < float(tol))
    IKH = ca.DM.eye(n) - K @ Hm
    return xi, symmetric_part(IKH @ P_prior @ IKH.T + K @ Rmask @ K.T)


def discrete_iekf(system: System, *, Q: Any, R: Any, P0: Any = None, xhat0: Any = None, iterations: int = 5,
                  tol: float = 1e-10, caller: str = "design_iekf") -> ObserverDesign:
    """The iterated EKF of a map (see the module's docstring); called by :func:`nlobs.design_iekf`."""
    n = system.n_states
    Qm, Rm, P0m, x0v = _weights(system, Q, R, P0, xhat0, caller)
    f, h = compile_system(system).bind()
    s, core, u_prev, started = _layout(system, n + n * n)
    x, P = core[:n], symmetric_part(ca.reshape(core[n:], n, n))
    fx = f(s.t - system.sample_time, x, u_prev)
    F = ca.jacobian(fx, x)
    xp = ca.if_else(started, fx, x)
    Pp = ca.if_else(started, symmetric_part(F @ P @ F.T + ca.DM(Qm)), P)
    xi, P_new = iterated_update(h, s, xp, Pp, Rm, iterations, tol)
    x0 = ca.SX.sym("xhat0", n)
    z0 = ca.vertcat(x0, ca.DM(P0m.reshape(-1, order="F")), ca.DM.zeros(system.n_inputs), 0)
    checks = _checks(Qm, Rm, P0m) + [Check("Gauss-Newton iterations", True,
                                           f"at most {int(iterations)} per step, stop below {tol:g}")]
    values = {"Q": Qm, "R": Rm, "P0": P0m, "iterations": int(iterations), "tol": float(tol),
              "sample_time": system.sample_time}
    cert = Certificate("Iterated extended Kalman filter (discrete time)", REF_IEKF, tuple(checks), values)
    names = [f"xhat_{v}" for v in system.states] + [f"P_{i}_{j}" for j in range(n) for i in range(n)]
    return ObserverDesign.build("iekf", system, s, z_names=_names(system, names), flow=ca.SX.zeros(s.z.shape[0]), xhat=x,
                                xhat0_sym=x0, z0=z0, xhat0=x0v, certificate=cert,
                                update=ca.vertcat(xi, ca.vec(P_new), s.u, 1), covariance=P)
