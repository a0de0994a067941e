"""Helpers for the classical-observer examples: A(t, u, y) of a state-affine model and LTV Gramians."""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca
import numpy as np

from ..design._base import Symbols
from ..design._common import leaves_of, to_sx
from ..design.kalman._riccati import state_affine_parts
from ..model import StateAffine, System

__all__ = ["a_matrix", "gramian", "gramian_min_eig"]


def a_matrix(model: System | StateAffine) -> Callable[[float, np.ndarray, np.ndarray], np.ndarray]:
    """A(t, u, y) of the model's state-affine form (as read by the Kalman-type designs)."""
    parts = state_affine_parts(model, "a_matrix")
    n = parts.A.shape[0]
    s = Symbols.make(parts.system, 0)
    fn = ca.Function("A", [s.t, s.u, s.y], [ca.reshape(to_sx(list(parts.A.T), leaves_of(parts.system, s)), n, n)])
    return lambda t, u, y: np.array(fn(t, u, y))


def gramian(A: Callable[[float, np.ndarray, np.ndarray], np.ndarray], C: np.ndarray, t: np.ndarray, u: np.ndarray,
            y: np.ndarray) -> np.ndarray:
    r"""The observability Gramian over the whole grid `t` (Wang, Ortega & Bobtsov (2021), eq. 3),

    .. math:: W(t_0, t_1) = \int_{t_0}^{t_1} \Phi(\tau, t_0)^\top C^\top C\,\Phi(\tau, t_0)\,d\tau ,

    with Φ from RK4 on the sample grid (A at the samples, averaged at the midpoint) and the
    trapezoidal rule.
    """
    Phi = np.eye(C.shape[1])
    W = np.zeros_like(Phi)
    prev = C.T @ C
    Ak = A(t[0], u[0], y[0])
    for k in range(t.size - 1):
        h = t[k + 1] - t[k]
        An = A(t[k + 1], u[k + 1], y[k + 1])
        Am = (Ak + An) / 2
        k1 = Ak @ Phi
        k2 = Am @ (Phi + h / 2 * k1)
        k3 = Am @ (Phi + h / 2 * k2)
        Phi = Phi + h / 6 * (k1 + 2 * k2 + 2 * k3 + An @ (Phi + h * k3))
        cur = Phi.T @ C.T @ C @ Phi
        W += h / 2 * (prev + cur)
        prev, Ak = cur, An
    return (W + W.T) / 2


def gramian_min_eig(A: Callable[[float, np.ndarray, np.ndarray], np.ndarray], C: np.ndarray, t: np.ndarray,
                    u: np.ndarray, y: np.ndarray | None = None, *, window: float) -> float:
    """min over consecutive windows of length `window` of λmin of the :func:`gramian`."""
    y = np.zeros((t.size, 0)) if y is None else y
    worst = np.inf
    k0 = 0
    while k0 < t.size - 1:
        k1 = int(np.searchsorted(t, t[k0] + window - 1e-12))
        if k1 >= t.size:
            break
        sl = slice(k0, k1 + 1)
        worst = min(worst, float(np.linalg.eigvalsh(gramian(A, C, t[sl], u[sl], y[sl])).min()))
        k0 = k1
    return worst
