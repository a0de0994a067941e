"""Square-root unscented Kalman filter, continuous-discrete: the Cholesky factor S of P is propagated, P never formed."""

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
from .._tune import robust_filter
from .._kind import Tuning
from .._kind import kind
from .._bounds import POLICY, bounds_check, check_start, clip_const, parse_bounds
from .._common import require_system
from ._sqrt import covariance_inputs, lower_solve, lower_t_solve, sqrt_psd, tria
from ._robust_maps import discrete_srukf
from ._ukf import unscented_weights

__all__ = ["design_srukf"]

REF = (f"Square-root UKF ({cite('vandermerwe2001')}); sigma points through the model's flow between samples; "
       f"measurement update by one QR triangularisation without Cholesky downdates ({cite('arasaratnam2009')})")


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def tune_srukf(ctx: Any) -> Tuning:
    """The EKF/UKF tuning (Q, R, P(0) from the run; see :func:`~nlobs.design._tune.robust_filter`)."""
    return robust_filter(ctx, "srukf")


@kind('srukf', likelihood='ukf', summary='square-root unscented Kalman filter (continuous-discrete, or on a map): P is never formed, its Cholesky factor is updated by QR',
      references=(work("vandermerwe2001", "square root by QR"), work("arasaratnam2009")), time_base="both", tune=tune_srukf,
      map_smoother="unscented")
def design_srukf(system: System, *, Q: Any, R: Any, P0: Any = None, xhat0: Any = None, alpha: float = 1.0,
                 beta: float = 0.0, kappa: float = 0.0, bounds: Mapping[str, Any] | None = None) -> ObserverDesign:
    r"""Square-root unscented Kalman filter (continuous-discrete, van der Merwe & Wan (2001)): P is never formed;
    its lower Cholesky factor S is rebuilt at each sample by QR triangularisations of sums of squares.

    Between samples each sigma point :math:`\mathcal X_i` follows the model, :math:`\dot{\mathcal X}_i = f(\mathcal X_i)`
    (RK4 sub-steps), and the time τ since the last sample is counted. At a sample the prior is
    :math:`m^- = \sum_i W^m_i\mathcal X_i`, :math:`S^- = \mathrm{Tria}[\sqrt{W^c}(\mathcal X - m^-),\; \sqrt{\tau}\,Q^{1/2}]`
    (process noise Q·τ over the interval), sigma points are redrawn as :math:`m^- + \sqrt{c}[0, S^-, -S^-]`,
    and with the weighted deviations :math:`\tilde X = \sqrt{W^c}(\mathcal X - m^-)`,
    :math:`\tilde Y = \sqrt{W^c}(\mathcal Y - \hat y)`, :math:`R = R^{1/2}R^{\top/2}`:
    :math:`S_y = \mathrm{Tria}[\tilde Y, R^{1/2}]`, :math:`K = \tilde X\tilde Y^\top S_y^{-\top}S_y^{-1}`,
    :math:`m^+ = m^- + K(y - \hat y)` and

    .. math::

        S^+ = \mathrm{Tria}\big[\tilde X - K\tilde Y,\; K R^{1/2}\big],

    an exact factor of the UKF's :math:`P^- - KS_yS_y^\top K^\top` (expand the product and use
    :math:`KS_yS_y^\top = \tilde X\tilde Y^\top`; Arasaratnam & Haykin (2009)). It is built from a sum of
    squares, so unlike the Cholesky downdate of van der Merwe & Wan (2001) it cannot fail when R is
    tiny (1e-10). Tria is a QR triangularisation by Householder reflections. The new sigma points
    :math:`m^+ + \sqrt{c}[0, S^+, -S^+]` are the filter's internal state. Outputs missing at a sample are
    left out.

    Unlike :func:`design_ukf` (Särkkä (2007): ODEs for the mean and P) the prediction maps the sigma
    points through the flow over the whole interval, with Q·τ added at its end: the two agree to
    round-off in the measurement update, and over an interval up to O(τ²) terms in Q (exactly, up
    to RK4's error, when Q = 0). The square-root form of Särkkä's ODE is stiff when S is nearly
    singular (its rate grows as the ratio of S's diagonal entries), which a tiny R makes it.

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
        State bounds, as for :func:`~nlobs.design.design_ukf`: f and h are evaluated at the sigma points clipped to
        the bounds (the points themselves, and the spreads of the square roots, are the unclipped ones); the mean is
        projected onto the bounds (clipped) at each update and the reported estimate is the clipped mean.

    Other Parameters
    ----------------
    xhat0 : array_like of shape (n,), optional
    alpha, beta, kappa : float
        Sigma-point scaling as in :func:`design_ukf`; the covariance weights must be non-negative
        (the square-root update sums squares).

    Raises
    ------
    PreconditionError, ShapeError
        For matrices of the wrong shape or definiteness, a non-positive spread, or a negative weight.
    """
    require_system(system, "design_srukf")
    caller = "design_srukf"
    if system.is_discrete:   # a map: the map UKF's sigma points and semantics, in square-root form
        if bounds is not None:
            raise PreconditionError(f"{caller}: `bounds` are not available for a discrete-time model yet")
        return discrete_srukf(system, Q=Q, R=R, P0=P0, xhat0=xhat0, alpha=alpha, beta=beta, kappa=kappa, caller=caller)
    n, p = system.n_states, system.n_outputs
    Qm, Rm, P0m, checks = covariance_inputs(Q, R, P0, n, p, caller)
    wm, wc, c = unscented_weights(n, float(alpha), float(beta), float(kappa))
    if wc.min() < -1e-12 * float(np.abs(wc).max()):
        bound = float(wc[0] - beta)   # W0 = λ/(n + λ) + 1 − α² + β
        raise PreconditionError(f"{caller}: the covariance weight W0 = {wc[0]:g} is negative (α = {alpha:g}, β = {beta:g}, "
                                f"κ = {kappa:g}); the square-root form needs non-negative weights: take β ≥ α² − 1 − λ/(n + λ) "
                                f"= {-bound:.10g}, or the defaults α = 1, β = 0, κ = 0")
    wc = np.maximum(wc, 0.0)   # a W0 of −1e-16 from rounding β: 0
    x0v = check_vector(np.zeros(n) if xhat0 is None else xhat0, n, "xhat0", caller)
    box = parse_bounds(system, bounds, caller)
    evidence = check_start(system, box, np.array(x0v, dtype=float), caller)
    f, h = compile_system(system).bind()
    npts = 2 * n + 1
    s = Symbols.make(system, n * npts + 1)
    pts = [s.z[i * n:(i + 1) * n] for i in range(npts)]
    tau = s.z[n * npts]
    sc, sw = float(np.sqrt(c)), [float(np.sqrt(w)) for w in wc]

    def sigma(mean: Any, L: Any) -> list[Any]:
        return [mean] + [mean + sc * L[:, i] for i in range(n)] + [mean - sc * L[:, i] for i in range(n)]

    def mean_of(P: list[Any]) -> Any:
        return sum((float(wm[i]) * P[i] for i in range(npts)), ca.SX.zeros(n))

    flow = ca.vertcat(*[f(s.t, clip_const(xi, box), s.u) for xi in pts], 1)
    # time update: the propagated points and Q·τ, triangularised (never P)
    m = mean_of(pts)
    Lq = ca.DM(sqrt_psd(Qm))
    Sm = tria(ca.horzcat(*[sw[i] * (pts[i] - m) for i in range(npts)], ca.sqrt(tau) * Lq))
    X = sigma(m, Sm)
    Y = [h(s.t, clip_const(xi, box), s.u) for xi in X]
    yhat = sum((float(wm[i]) * Y[i] for i in range(npts)), ca.SX.zeros(p))
    Md = ca.diag(s.m)
    Xt = ca.horzcat(*[sw[i] * (X[i] - m) for i in range(npts)])
    Yt = Md @ ca.horzcat(*[sw[i] * (Y[i] - yhat) for i in range(npts)])
    Rh = Md @ ca.DM(sqrt_psd(Rm))
    Sy = tria(ca.horzcat(Yt, Rh, ca.diag(1 - s.m)))  # unmeasured outputs: a decoupled unit block, zero gain
    K = lower_t_solve(Sy, lower_solve(Sy, Yt @ Xt.T)).T  # Kᵀ = Sy⁻ᵀ Sy⁻¹ Pxyᵀ, i.e. K = Pxy (Sy Syᵀ)⁻¹
    m_plus = clip_const(m + K @ (s.m * (s.y - yhat)), box)   # projected onto the bounds (identity without)
    S_plus = tria(ca.horzcat(Xt - K @ Yt, K @ Rh))
    update = ca.vertcat(*sigma(m_plus, S_plus), 0)
    dev = ca.horzcat(*[sw[i] * (pts[i] - m) for i in range(npts)])
    x0 = ca.SX.sym("xhat0", n)
    checks.append(Check("sigma-point spread n + λ > 0 and covariance weights ≥ 0", True, f"n + λ = {c:g}, min W = {wc.min():g}"))
    values: dict[str, Any] = {"Q": Qm, "R": Rm, "P0": P0m, "alpha": float(alpha), "beta": float(beta), "kappa": float(kappa),
                              "weights_mean": wm, "weights_cov": wc,
                              "square root": "lower Cholesky factor S (P = SSᵀ) from Householder QR; no Cholesky factorisation or downdate"}
    if box is not None:
        checks.append(bounds_check(box, evidence))
        values.update({"bounds": box.describe(), "bounds policy": POLICY})
    cert = Certificate("Square-root unscented Kalman filter (continuous-discrete)", REF, tuple(checks), values)
    names = [f"X{i}_{v}" for i in range(npts) for v in system.states] + ["tau"]
    return ObserverDesign.build("srukf", system, s, z_names=names, flow=flow, xhat=clip_const(m, box), xhat0_sym=x0,
                                z0=ca.vertcat(*sigma(x0, ca.DM(np.linalg.cholesky(P0m))), 0), xhat0=x0v,
                                certificate=cert, update=update, covariance=dev @ dev.T + tau * ca.DM(Qm))
