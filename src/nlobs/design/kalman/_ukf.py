"""Continuous-discrete unscented Kalman filter (baseline)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import casadi as ca
import numpy as np

from ...engine import compile_system
from ...errors import PreconditionError
from ...model import System
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign, Symbols, check_vector
from .._tune import gaussian_filter
from ._maps import discrete_ukf
from .._kind import Tuning
from .._kind import kind
from .._bounds import POLICY, bounds_check, check_start, clip_const, parse_bounds
from .._checks import check_matrix
from .._common import require_system, symmetric_part

__all__ = ["design_ukf", "unscented_weights"]

REF = (f"Continuous-discrete UKF: {cite('sarkka2007')} (prediction ODEs); scaled sigma points of {cite('wan2000')}")


def unscented_weights(n: int, alpha: float, beta: float, kappa: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Mean and covariance weights of the 2n + 1 scaled sigma points, and the spread c = n + λ."""
    lam = alpha**2 * (n + kappa) - n
    c = n + lam
    if c <= 0:
        raise PreconditionError(f"design_ukf: n + λ = α²(n + κ) = {c:g} must be positive; increase α or κ")
    wm = np.full(2 * n + 1, 1.0 / (2 * c))
    wc = wm.copy()
    wm[0] = lam / c
    wc[0] = lam / c + (1 - alpha**2 + beta)
    return wm, wc, c


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def tune_ukf(ctx: Any) -> Tuning:
    """As the EKF, with the sigma points kept within half the visited box (α, β = 2)."""
    return gaussian_filter(ctx, "ukf")


@kind('ukf', likelihood='ukf', summary='unscented Kalman filter (continuous-discrete)',
      references=(work("julier2004"), work("wan2000", "discrete time")), time_base="both",
      tune=tune_ukf, map_smoother="unscented")
def design_ukf(system: System, *, Q: Any, R: Any, P0: Any = None, xhat0: Any = None, alpha: float = 1.0,
               beta: float = 0.0, kappa: float = 0.0, bounds: Mapping[str, Any] | None = None) -> ObserverDesign:
    r"""Continuous-discrete unscented Kalman filter.

    Sigma points :math:`\mathcal X = m + \sqrt{c}\,[0, L, -L]` with :math:`P = LL^\top` (Cholesky).
    Between samples (Särkkä (2007)):

    .. math::

        \dot m = \sum_i W^m_i f(\mathcal X_i), \qquad
        \dot P = \sum_i W^c_i\big[(\mathcal X_i - m)(f_i - \bar f)^\top + (f_i - \bar f)(\mathcal X_i - m)^\top\big] + Q .

    At a sample: :math:`\mathcal Y_i = h(\mathcal X_i)`, :math:`\hat y = \sum W^m_i\mathcal Y_i`,
    :math:`S = \sum W^c_i(\mathcal Y_i - \hat y)(\cdot)^\top + R`,
    :math:`C_{xy} = \sum W^c_i(\mathcal X_i - m)(\mathcal Y_i - \hat y)^\top`, :math:`K = C_{xy}S^{-1}`,
    :math:`m^+ = m + K(y - \hat y)`, :math:`P^+ = P - KSK^\top`; outputs missing at a sample are
    left out (their rows of K are zero). P is kept exactly symmetric. For a linear model the
    unscented transform is exact and the filter coincides with the Kalman filter.

    Parameters
    ----------
    system : System
    Q : array_like of shape (n, n)
        Process-noise intensity, positive semidefinite.
    R : array_like of shape (p, p)
        Covariance of one measurement sample, positive definite.
    P0 : array_like of shape (n, n), optional
        Initial covariance (identity), positive definite.
    bounds : mapping of state name to (lo, hi), optional
        State bounds, e.g. ``{"x1": (0, None)}`` (None: no bound on that side). Policy: f and h are
        evaluated at the sigma points clipped to the bounds (the spreads in the covariance sums are
        the unclipped ones); the mean is projected onto the bounds (clipped) after each update and
        the reported estimate is the clipped mean; P is left as the update made it (Simon (2010),
        estimate projection with the identity weight). Without bounds the filter is unchanged.

    Other Parameters
    ----------------
    xhat0 : array_like of shape (n,), optional
    alpha, beta, kappa : float
        Sigma-point scaling (default α = 1, β = 0, κ = 0: all weights 1/(2n), none negative, so the
        predicted P stays positive semidefinite).

    Raises
    ------
    PreconditionError, ShapeError
        For matrices of the wrong shape or definiteness, or a non-positive spread n + λ.

    References
    ----------
    Särkkä (2007); Wan & van der Merwe (2000); Julier & Uhlmann (2004); the continuous-discrete EKF of this package for comparison.
    """
    require_system(system, "design_ukf")
    caller = "design_ukf"
    if system.is_discrete:   # a map: the discrete-time UKF (filterpy's MerweScaledSigmaPoints)
        if bounds is not None:
            raise PreconditionError(f"{caller}: `bounds` are not available for a discrete-time model yet")
        return discrete_ukf(system, Q=Q, R=R, P0=P0, xhat0=xhat0, alpha=alpha, beta=beta, kappa=kappa, caller=caller)
    n, p = system.n_states, system.n_outputs
    Qm = check_matrix(Q, n, n, "Q", caller, definite="semidefinite")
    Rm = check_matrix(R, p, p, "R", caller, definite="positive")
    P0m = np.eye(n) if P0 is None else check_matrix(P0, n, n, "P0", caller, definite="positive")
    wm, wc, c = unscented_weights(n, float(alpha), float(beta), float(kappa))
    box = parse_bounds(system, bounds, caller)
    evidence = check_start(system, box, np.array(check_vector(np.zeros(n) if xhat0 is None else xhat0, n, "xhat0", caller)), caller)
    f, h = compile_system(system).bind()
    s = Symbols.make(system, n + n * n)
    m = s.z[:n]
    P = symmetric_part(ca.reshape(s.z[n:], n, n))

    def sigma(mean: ca.SX, cov: ca.SX) -> list[ca.SX]:
        L = ca.chol(cov).T * np.sqrt(c)  # chol gives upper R with cov = RᵀR
        return [mean] + [mean + L[:, i] for i in range(n)] + [mean - L[:, i] for i in range(n)]

    X = sigma(m, P)
    F = [f(s.t, clip_const(xi, box), s.u) for xi in X]
    fbar = sum((float(wm[i]) * F[i] for i in range(2 * n + 1)), ca.SX.zeros(n))
    cross = sum((float(wc[i]) * (X[i] - m) @ (F[i] - fbar).T for i in range(2 * n + 1)), ca.SX.zeros(n, n))
    dP = symmetric_part(cross + cross.T + ca.DM(Qm))
    Y = [h(s.t, clip_const(xi, box), s.u) for xi in X]
    yhat = sum((float(wm[i]) * Y[i] for i in range(2 * n + 1)), ca.SX.zeros(p))
    S = sum((float(wc[i]) * (Y[i] - yhat) @ (Y[i] - yhat).T for i in range(2 * n + 1)), ca.SX.zeros(p, p)) + ca.DM(Rm)
    Cxy = sum((float(wc[i]) * (X[i] - m) @ (Y[i] - yhat).T for i in range(2 * n + 1)), ca.SX.zeros(n, p))
    Md = ca.diag(s.m)
    Sm = symmetric_part(Md @ S @ Md + ca.diag(1 - s.m))  # unmeasured outputs: decoupled unit block, zero gain
    K = ca.solve(Sm, (Cxy @ Md).T).T
    m_plus = clip_const(m + K @ (s.m * (s.y - yhat)), box)  # projected onto the bounds (identity without)
    P_plus = symmetric_part(P - K @ Sm @ K.T)
    x0 = ca.SX.sym("xhat0", n)
    checks = [Check("Q positive semidefinite", True, f"min eig {np.linalg.eigvalsh(Qm).min():.3g}"),
              Check("R positive definite", True, f"min eig {np.linalg.eigvalsh(Rm).min():.3g}"),
              Check("P0 positive definite", True, f"min eig {np.linalg.eigvalsh(P0m).min():.3g}"),
              Check("sigma-point spread n + λ > 0", True, f"{c:g}")]
    values: dict[str, Any] = {"Q": Qm, "R": Rm, "P0": P0m, "alpha": float(alpha), "beta": float(beta), "kappa": float(kappa),
                              "weights_mean": wm, "weights_cov": wc}
    if box is not None:
        checks.append(bounds_check(box, evidence))
        values.update({"bounds": box.describe(), "bounds policy": POLICY})
    cert = Certificate("Unscented Kalman filter (continuous-discrete)", REF, tuple(checks), values)
    names = [f"xhat_{v}" for v in system.states] + [f"P_{i}_{j}" for j in range(n) for i in range(n)]
    return ObserverDesign.build("ukf", system, s, z_names=names, flow=ca.vertcat(fbar, ca.vec(dP)), xhat=clip_const(m, box),
                                xhat0_sym=x0,
                                z0=ca.vertcat(x0, ca.DM(P0m.reshape(-1, order="F"))),
                                xhat0=np.zeros(n) if xhat0 is None else xhat0, certificate=cert,
                                update=ca.vertcat(m_plus, ca.vec(P_plus)), covariance=P)
