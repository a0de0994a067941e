r"""Observers of discrete-time models x[k+1] = f(x[k], u[k], t[k]), y[k] = h(x[k], u[k], t[k]).

The designs keep the runnable contract of every observer: the internal state z changes only at the samples,
``update(t_k, z, u_k, y_k, m_k)``, and its flow between samples is zero. z carries the input of the previous
step, so that the update at t_k first predicts from t_{k-1} (with u_{k-1}) and then corrects with y_k; at the first
sample there is nothing to predict from (x̂(0), P(0) are the prior of x[0]). The estimate at t_k is the filtered
x̂[k|k] (filterpy's ``x`` after ``predict(); update(y)``).

- EKF (Simon (2006), §13.2): x̂⁻ = f(x̂, u), P⁻ = F P Fᵀ + Q with F = ∂f/∂x at x̂; K = P⁻Hᵀ(HP⁻Hᵀ + R)⁻¹,
  x̂ = x̂⁻ + K(y − h(x̂⁻)), P = (I − KH)P⁻(I − KH)ᵀ + KRKᵀ (Joseph form). Q is the covariance of the
  process noise per step.
- UKF (Wan & van der Merwe (2000)): the scaled sigma points of filterpy's ``MerweScaledSigmaPoints``
  (α, β, κ), propagated through f; the update reuses the propagated points (as filterpy does).

The square-root UKF and EKF and the iterated EKF of a map are in :mod:`._robust_maps` (the same semantics); the particle
filter of a map is :func:`nlobs.design.design_pf` with its compiled loop stepping the map.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from ...engine import compile_system
from ...errors import PreconditionError
from ...model import System
from ...references import cite
from .._base import Certificate, Check, ObserverDesign, Symbols, check_vector
from .._checks import check_matrix
from .._common import symmetric_part

__all__ = ["discrete_ekf", "discrete_ukf"]

REF_DEKF = f"Discrete-time extended Kalman filter ({cite('simon2006', '§13.2')}), Joseph-form update"
REF_DUKF = f"Discrete-time unscented Kalman filter ({cite('wan2000')}), scaled sigma points"


def _weights(system: System, Q: Any, R: Any, P0: Any, xhat0: Any, caller: str) -> tuple[np.ndarray, ...]:
    n, p = system.n_states, system.n_outputs
    Qm = check_matrix(Q, n, n, "Q", caller, definite="semidefinite")
    Rm = check_matrix(R, p, p, "R", caller, definite="positive")
    P0m = np.eye(n) if P0 is None else check_matrix(P0, n, n, "P0", caller, definite="positive")
    x0v = check_vector(np.zeros(n) if xhat0 is None else xhat0, n, "xhat0", caller)
    return Qm, Rm, P0m, np.asarray(x0v, dtype=float)


def _layout(system: System, n_core: int) -> tuple[Symbols, ca.SX, ca.SX, ca.SX]:
    """Symbols for z = [core (n_core), u of the previous step (nu), started (1)] and those three parts."""
    nu = system.n_inputs
    s = Symbols.make(system, n_core + nu + 1)
    return s, s.z[:n_core], s.z[n_core:n_core + nu], s.z[n_core + nu]


def _masked_correction(x: ca.SX, P: ca.SX, hx: ca.SX, H: ca.SX, Rd: ca.DM, y: ca.SX, m: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Kalman correction with the outputs not measured (m = 0) left out, Joseph form."""
    n = x.shape[0]
    Md = ca.diag(m)
    Hm = Md @ H
    Rmask = Md @ Rd @ Md + ca.diag(1 - m)   # an unmeasured output: a decoupled unit block, zero gain
    S = symmetric_part(Hm @ P @ Hm.T + Rmask)
    K = ca.solve(S, Hm @ P).T
    x_plus = x + K @ (m * (y - hx))
    IKH = ca.DM.eye(n) - K @ Hm
    return x_plus, symmetric_part(IKH @ P @ IKH.T + K @ Rmask @ K.T)


def _names(system: System, core: list[str]) -> list[str]:
    return core + [f"u_prev_{v}" for v in system.inputs] + ["started"]


def discrete_ekf(system: System, *, Q: Any, R: Any, P0: Any = None, xhat0: Any = None,
                 caller: str = "design_ekf") -> ObserverDesign:
    """The discrete-time EKF of a map (see the module's docstring); called by :func:`nlobs.design_ekf`."""
    n = system.n_states
    Qm, Rm, P0m, x0v = _weights(system, Q, R, P0, xhat0, caller)
    f, h = compile_system(system).bind()
    s, core, u_prev, started = _layout(system, n + n * n)
    x, P = core[:n], symmetric_part(ca.reshape(core[n:], n, n))
    t_prev = s.t - system.sample_time
    fx = f(t_prev, x, u_prev)
    F = ca.jacobian(fx, x)
    x_pred = ca.if_else(started, fx, x)
    P_pred = ca.if_else(started, symmetric_part(F @ P @ F.T + ca.DM(Qm)), P)
    xv = ca.SX.sym("xv", n)                      # H = ∂h/∂x at the prediction
    hv = h(s.t, xv, s.u)
    hx, H = ca.substitute([hv, ca.jacobian(hv, xv)], [xv], [x_pred])
    x_new, P_new = _masked_correction(x_pred, P_pred, hx, H, ca.DM(Rm), s.y, s.m)
    update = ca.vertcat(x_new, ca.vec(P_new), s.u, 1)
    checks = (Check("Q positive semidefinite (per step)", True, f"min eig {np.linalg.eigvalsh(Qm).min():.3g}"),
              Check("R positive definite", True, f"min eig {np.linalg.eigvalsh(Rm).min():.3g}"),
              Check("P0 positive definite", True, f"min eig {np.linalg.eigvalsh(P0m).min():.3g}"))
    cert = Certificate("Extended Kalman filter (discrete time)", REF_DEKF, checks,
                       {"Q": Qm, "R": Rm, "P0": P0m, "sample_time": system.sample_time})
    x0 = ca.SX.sym("xhat0", n)
    z0 = ca.vertcat(x0, ca.DM(P0m.reshape(-1, order="F")), ca.DM.zeros(system.n_inputs), 0)
    names = _names(system, [f"xhat_{v}" for v in system.states] + [f"P_{i}_{j}" for j in range(n) for i in range(n)])
    return ObserverDesign.build("ekf", system, s, z_names=names, flow=ca.SX.zeros(s.z.shape[0]), xhat=x, xhat0_sym=x0,
                                z0=z0, xhat0=x0v, certificate=cert, update=update, covariance=P)


def _sigma_weights(n: int, alpha: float, beta: float, kappa: float) -> tuple[float, np.ndarray, np.ndarray]:
    """filterpy's MerweScaledSigmaPoints: λ = α²(n + κ) − n; Wm, Wc."""
    lam = alpha ** 2 * (n + kappa) - n
    Wm = np.full(2 * n + 1, 1.0 / (2 * (n + lam)))
    Wc = Wm.copy()
    Wm[0] = lam / (n + lam)
    Wc[0] = lam / (n + lam) + (1 - alpha ** 2 + beta)
    return lam, Wm, Wc


def _sigma_points(x: ca.SX, P: ca.SX, n: int, lam: float) -> list[ca.SX]:
    U = ca.chol((n + lam) * P).T          # lower factor: columns are the spreads (filterpy uses the rows of the upper)
    return [x] + [x + U[:, i] for i in range(n)] + [x - U[:, i] for i in range(n)]


def discrete_ukf(system: System, *, Q: Any, R: Any, P0: Any = None, xhat0: Any = None, alpha: float = 1.0,
                 beta: float = 2.0, kappa: float = 0.0, caller: str = "design_ukf") -> ObserverDesign:
    """The discrete-time UKF of a map (see the module's docstring); called by :func:`nlobs.design_ukf`."""
    n, p = system.n_states, system.n_outputs
    Qm, Rm, P0m, x0v = _weights(system, Q, R, P0, xhat0, caller)
    if not (alpha > 0 and np.isfinite(alpha)) or not np.isfinite(beta) or not (np.isfinite(kappa) and n + kappa > 0):
        raise PreconditionError(f"{caller}: need α > 0, finite β and n + κ > 0; got α = {alpha}, β = {beta}, κ = {kappa}")
    lam, Wm, Wc = _sigma_weights(n, float(alpha), float(beta), float(kappa))
    f, h = compile_system(system).bind()
    s, core, u_prev, started = _layout(system, n + n * n)
    x, P = core[:n], symmetric_part(ca.reshape(core[n:], n, n))
    t_prev = s.t - system.sample_time

    def mean_cov(points: list[ca.SX], noise: ca.DM) -> tuple[ca.SX, ca.SX]:
        mean = sum(float(w) * c for w, c in zip(Wm, points))
        cov = sum(float(w) * (c - mean) @ (c - mean).T for w, c in zip(Wc, points)) + noise
        return mean, symmetric_part(cov)

    prop = [f(t_prev, c, u_prev) for c in _sigma_points(x, P, n, lam)]
    x_f, P_f = mean_cov(prop, ca.DM(Qm))
    x_pred = ca.if_else(started, x_f, x)
    P_pred = ca.if_else(started, P_f, P)
    drawn = _sigma_points(x, P, n, lam)                         # at the first sample: the prior's points
    pts = [ca.if_else(started, a, b) for a, b in zip(prop, drawn)]
    ys = [h(s.t, c, s.u) for c in pts]
    yhat = sum(float(w) * c for w, c in zip(Wm, ys))
    Md = ca.diag(s.m)
    S = sum(float(w) * (c - yhat) @ (c - yhat).T for w, c in zip(Wc, ys))
    S = symmetric_part(Md @ (S + ca.DM(Rm)) @ Md + ca.diag(1 - s.m))
    Pxy = sum(float(w) * (a - x_pred) @ (b - yhat).T for w, a, b in zip(Wc, pts, ys)) @ Md
    K = ca.solve(S, Pxy.T).T
    x_new = x_pred + K @ (s.m * (s.y - yhat))
    P_new = symmetric_part(P_pred - K @ S @ K.T)
    update = ca.vertcat(x_new, ca.vec(P_new), s.u, 1)
    checks = (Check("Q positive semidefinite (per step), R and P0 positive definite", True,
                    f"min eig Q {np.linalg.eigvalsh(Qm).min():.3g}, R {np.linalg.eigvalsh(Rm).min():.3g}, "
                    f"P0 {np.linalg.eigvalsh(P0m).min():.3g}"),)
    cert = Certificate("Unscented Kalman filter (discrete time)", REF_DUKF, checks,
                       {"Q": Qm, "R": Rm, "P0": P0m, "alpha": alpha, "beta": beta, "kappa": kappa, "lambda": lam,
                        "sample_time": system.sample_time, "outputs": p})
    x0 = ca.SX.sym("xhat0", n)
    z0 = ca.vertcat(x0, ca.DM(P0m.reshape(-1, order="F")), ca.DM.zeros(system.n_inputs), 0)
    names = _names(system, [f"xhat_{v}" for v in system.states] + [f"P_{i}_{j}" for j in range(n) for i in range(n)])
    return ObserverDesign.build("ukf", system, s, z_names=names, flow=ca.SX.zeros(s.z.shape[0]), xhat=x, xhat0_sym=x0,
                                z0=z0, xhat0=x0v, certificate=cert, update=update, covariance=P)
