"""Helpers for the classical-observer examples: A(t, u, y) of a state-affine model and LTV Gramians."""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca
import numpy as np

from ..design._common import leaves_of, to_sx
from ..design._base import Symbols
from ..design._kalman import state_affine_parts
from ..model import StateAffine, System

__all__ = ["a_matrix", "gramian_min_eig"]


def a_matrix(model: System | StateAffine) -> Callable[[float, np.ndarray, np.ndarray], np.ndarray]:
    """A(t, u, y) of the model's state-affine form (as read by the Kalman-type designs)."""
    parts = state_affine_parts(model, "a_matrix")
    n = parts.A.shape[0]
    s = Symbols.make(parts.system, 0)
    fn = ca.Function("A", [s.t, s.u, s.y], [ca.reshape(to_sx(list(parts.A.T), leaves_of(parts.system, s)), n, n)])
    return lambda t, u, y: np.array(fn(t, u, y))


def gramian_min_eig(A: Callable[[float, np.ndarray, np.ndarray], np.ndarray], C: np.ndarray, t: np.ndarray,
                    u: np.ndarray, y: np.ndarray | None = None, *, window: float) -> float:
    r"""min over consecutive windows of λmin of the observability Gramian (000 eq. 3)

    .. math:: W(t_0, t_0 + T) = \int_{t_0}^{t_0+T} \Phi(\tau, t_0)^\top C^\top C\,\Phi(\tau, t_0)\,d\tau ,

    with Φ from RK4 on the sample grid (A held at its sample values, the midpoint averaged) and
    the integral by the trapezoidal rule.
    """
    y = np.zeros((t.size, 0)) if y is None else y
    worst = np.inf
    k0 = 0
    while k0 < t.size - 1:
        k1 = int(np.searchsorted(t, t[k0] + window - 1e-12))
        if k1 >= t.size:
            break
        Phi = np.eye(C.shape[1])
        W = np.zeros_like(Phi)
        prev = Phi.T @ C.T @ C @ Phi
        Ak = A(t[k0], u[k0], y[k0])
        for k in range(k0, k1):
            h = t[k + 1] - t[k]
            An = A(t[k + 1], u[k + 1], y[k + 1])
            Am = (Ak + An) / 2
            k1_ = Ak @ Phi
            k2_ = Am @ (Phi + h / 2 * k1_)
            k3_ = Am @ (Phi + h / 2 * k2_)
            k4_ = An @ (Phi + h * k3_)
            Phi = Phi + h / 6 * (k1_ + 2 * k2_ + 2 * k3_ + k4_)
            cur = Phi.T @ C.T @ C @ Phi
            W += h / 2 * (prev + cur)
            prev, Ak = cur, An
        worst = min(worst, float(np.linalg.eigvalsh((W + W.T) / 2).min()))
        k0 = k1
    return worst
