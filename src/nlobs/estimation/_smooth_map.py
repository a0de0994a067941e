r"""Fixed-interval smoothing of a discrete-time Gaussian filter's run (a map x[k+1] = f(x[k], u[k], t[k]) + w[k]): the
EKF and the filters that predict as it does (square-root EKF, iterated EKF), the UKF and the square-root UKF.

The filter gives the filtered mean and covariance (x̂_k, P_k) at every step. The Rauch–Tung–Striebel backward pass
(Rauch, Tung & Striebel (1965); Simon (2006), §9.4.2 for the extended form)

.. math::

    G_k = C_k (P^-_{k+1})^{-1}, \quad x^s_k = \hat x_k + G_k (x^s_{k+1} - \hat x^-_{k+1}), \quad
    P^s_k = P_k + G_k (P^s_{k+1} - P^-_{k+1}) G_k^\top ,

with the one-step prediction :math:`\hat x^-_{k+1}, P^-_{k+1}` the filter made from step k, and C_k the
cross-covariance of x[k] and x[k+1]:

- EKF, square-root EKF, iterated EKF: :math:`\hat x^-_{k+1} = f(\hat x_k, u_k)`, :math:`F_k = \partial f/\partial x` there,
  :math:`P^-_{k+1} = F_k P_k F_k^\top + Q`, :math:`C_k = P_k F_k^\top`;
- UKF and square-root UKF (the unscented RTS smoother of Särkkä (2008)): the filter's sigma points 𝒳ᵢ of (x̂_k, P_k)
  through f (the square-root filter's factor is the Cholesky factor of P_k, so its points are the same),
  :math:`\hat x^-_{k+1} = \sum W^m_i f(𝒳_i)`, :math:`P^-_{k+1} = \sum W^c_i (f(𝒳_i) - \hat x^-)(\cdot)^\top + Q`,
  :math:`C_k = \sum W^c_i (𝒳_i - \hat x_k)(f(𝒳_i) - \hat x^-_{k+1})^\top`.

The predictions are those of the filter (the same map, the same sigma points), so the smoother and the filter agree
at the last step. For a linear map both are the Kalman smoother.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..design import KINDS, ObserverDesign
from ..engine import compile_system, evaluate_many

__all__ = ["rts_smooth_map"]


def _prediction(design: ObserverDesign) -> ca.Function:
    """(t, x, P, u) -> (x⁻, P⁻, C): the filter's one-step prediction and the cross-covariance of x[k] and x[k+1]."""
    system = design.system
    n = system.n_states
    f, _ = compile_system(system).bind()
    t, x, u = ca.SX.sym("t"), ca.SX.sym("x", n), ca.SX.sym("u", system.n_inputs)
    P = ca.SX.sym("P", n, n)
    Q = ca.DM(design.certificate.values["Q"])
    if KINDS[design.method].map_smoother == "extended":
        fx = f(t, x, u)
        F = ca.jacobian(fx, x)
        xp, Pp, C = fx, F @ P @ F.T + Q, P @ F.T
    else:
        v = design.certificate.values
        lam = float(v["lambda"])
        Wm = np.full(2 * n + 1, 1.0 / (2 * (n + lam)))
        Wc = Wm.copy()
        Wm[0] = lam / (n + lam)
        Wc[0] = lam / (n + lam) + (1 - float(v["alpha"]) ** 2 + float(v["beta"]))
        L = ca.chol((n + lam) * P).T
        pts = [x] + [x + L[:, i] for i in range(n)] + [x - L[:, i] for i in range(n)]
        fs = [f(t, s, u) for s in pts]
        xp = sum(float(w) * fi for w, fi in zip(Wm, fs))
        Pp = sum(float(w) * (fi - xp) @ (fi - xp).T for w, fi in zip(Wc, fs)) + Q
        C = sum(float(w) * (s - x) @ (fi - xp).T for w, s, fi in zip(Wc, pts, fs))
    Pp = (Pp + Pp.T) / 2
    return ca.Function("map_prediction", [t, x, ca.vec(P), u], [ca.vertcat(xp, ca.vec(Pp), ca.vec(C))])


def rts_smooth_map(design: ObserverDesign, t: np.ndarray, u: np.ndarray, X: np.ndarray,
                   P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smoothed means (N, n) and covariances (N, n, n) from the filtered ones (see the module docstring)."""
    N, n = X.shape
    pred = _prediction(design)
    Pf = P.reshape(N, n * n, order="C")   # P[k] row-major; the prediction takes vec (column-major): P is symmetric
    out = evaluate_many(pred, t[:-1, None], X[:-1], Pf[:-1], u[:-1]) if N > 1 else np.zeros((0, 2 * n * n + n))
    xp = out[:, :n]
    Pp = out[:, n:n + n * n].reshape(-1, n, n, order="F")
    C = out[:, n + n * n:].reshape(-1, n, n, order="F")
    xs, Ps = X.copy(), P.copy()
    for k in range(N - 2, -1, -1):
        G = np.linalg.solve(Pp[k].T, C[k].T).T          # C_k (P⁻_{k+1})⁻¹
        xs[k] = X[k] + G @ (xs[k + 1] - xp[k])
        Ps[k] = P[k] + G @ (Ps[k + 1] - Pp[k]) @ G.T
        Ps[k] = (Ps[k] + Ps[k].T) / 2
    return xs, Ps
