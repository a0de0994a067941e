"""Extended Kalman filter: continuous-time and continuous-discrete (Joseph form)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

import casadi as ca
import numpy as np

from ...engine import compile_system
from ...errors import PreconditionError
from ...model import System
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign, Symbols, check_vector
from .._tune import gaussian_filter
from ._maps import discrete_ekf
from .._kind import Tuning
from .._kind import kind
from .._bounds import POLICY, bounds_check, check_start, clip_const, parse_bounds
from .._checks import check_matrix
from .._common import require_system, symmetric_part

__all__ = ["design_ekf"]

REF_EKF = (f"Extended Kalman filter ({cite('jazwinski1970')}; {cite('simon2006', 'ch. 13')}); "
           f"Joseph-form update ({cite('bucy1968')})")


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def tune_ekf(ctx: Any) -> Tuning:
    """Q, R, P(0) from the run's scales, continuous-discrete (see :func:`~nlobs.design._tune.gaussian_filter`)."""
    return gaussian_filter(ctx, "ekf")


@kind('ekf', likelihood='ekf', summary='extended Kalman filter (continuous-discrete or continuous), exact Jacobians by automatic differentiation',
      references=(work("jazwinski1970", "continuous-discrete extended Kalman filter"), work("kalman1961"),
                  work("simon2006", "§13.2, discrete time")), time_base="both", tune=tune_ekf,
      map_smoother="extended")
def design_ekf(system: System, *, Q: Any, R: Any, P0: Any = None, xhat0: Any = None,
               mode: Literal["continuous", "continuous-discrete"] = "continuous-discrete",
               bounds: Mapping[str, Any] | None = None) -> ObserverDesign:
    r"""Extended Kalman filter, with exact Jacobians from automatic differentiation.

    Continuous-discrete (the default, ``mode="continuous-discrete"``): between samples
    :math:`\dot{\hat x} = f`, :math:`\dot P = FP + PF^\top + Q`; at each sample
    :math:`K = PH^\top(HPH^\top + R)^{-1}`, :math:`\hat x^+ = \hat x + K(y - h(\hat x))`,
    :math:`P^+ = (I - KH)P(I - KH)^\top + KRK^\top` (Joseph form). Outputs missing at a
    sample are left out of the update. R is then the covariance of one measurement sample
    (σ² for Gaussian noise of standard deviation σ).

    Continuous time (``mode="continuous"``), with :math:`F = \partial f/\partial x`,
    :math:`H = \partial h/\partial x` at :math:`\hat x`:

    .. math::

        \dot{\hat x} = f(\hat x, u) + P H^\top R^{-1}(y - h(\hat x, u)), \qquad
        \dot P = FP + PF^\top + Q - PH^\top R^{-1} H P .

    Here R is an intensity: white noise sampled with standard deviation σ every Δt has
    intensity σ²Δt, and a small R makes the gain P Hᵀ R⁻¹ H large, so the integration step
    must resolve it (RK4 is stable for Δt·abs(λ) < 2.8).

    P is stored in full and kept exactly symmetric: every derivative and update is
    symmetrised, so P stays symmetric to the last bit and positive definite as long as the
    integration step resolves its dynamics.

    Parameters
    ----------
    system : System
    Q : array_like of shape (n, n)
        Process-noise intensity (continuous time), positive semidefinite.
    R : array_like of shape (p, p)
        Measurement noise: the intensity (spectral density) in continuous mode; the
        covariance of one sample in continuous-discrete mode. Positive definite. (A sampled
        white noise of standard deviation σ every Δt has intensity σ²Δt.)
    P0 : array_like of shape (n, n), optional
        Initial covariance (identity), positive definite.
    xhat0 : array_like of shape (n,), optional
        Default initial estimate (zeros).
    mode : {"continuous-discrete", "continuous"}
    bounds : mapping of state name to (lo, hi), optional
        State bounds, e.g. ``{"x1": (0, None)}`` (None: no bound on that side). Policy: f, h and
        their Jacobians are evaluated at the estimate clipped to the bounds; the estimate is
        projected onto the bounds (clipped) after each measurement update, and the reported
        estimate is the clipped one; P is left as the update made it (estimate projection with
        the identity weight, Simon (2010)). Without bounds the filter is unchanged.

    Raises
    ------
    PreconditionError, ShapeError
        For matrices of the wrong shape, not symmetric, or not (semi)definite.
    """
    require_system(system, "design_ekf")
    caller = "design_ekf"
    if system.is_discrete:   # a map x[k+1] = f(x[k], u[k]): the discrete-time EKF (filterpy's semantics)
        if bounds is not None:
            raise PreconditionError(f"{caller}: `bounds` are not available for a discrete-time model yet")
        if mode == "continuous":
            raise PreconditionError(f"{caller}: mode='continuous' is a filter of an ODE; {system.name!r} is a discrete-time "
                                    "model, whose EKF is the discrete-time filter: leave `mode` out")
        return discrete_ekf(system, Q=Q, R=R, P0=P0, xhat0=xhat0, caller=caller)
    if mode not in ("continuous", "continuous-discrete"):
        raise PreconditionError(f"{caller}: `mode` must be 'continuous' or 'continuous-discrete', got {mode!r}")
    n, p = system.n_states, system.n_outputs
    Qm = check_matrix(Q, n, n, "Q", caller, definite="semidefinite")
    Rm = check_matrix(R, p, p, "R", caller, definite="positive")
    P0m = np.eye(n) if P0 is None else check_matrix(P0, n, n, "P0", caller, definite="positive")
    box = parse_bounds(system, bounds, caller)
    x0v = check_vector(np.zeros(n) if xhat0 is None else xhat0, n, "xhat0", caller)
    evidence = check_start(system, box, np.array(x0v), caller)
    f, h = compile_system(system).bind()
    s = Symbols.make(system, n + n * n)
    xh = s.z[:n]
    P = symmetric_part(ca.reshape(s.z[n:], n, n))
    if box is None:
        fx = f(s.t, xh, s.u)
        hx = h(s.t, xh, s.u)
        F = ca.jacobian(fx, xh)
        H = ca.jacobian(hx, xh)
    else:  # the model and its Jacobians at the estimate clipped to the bounds
        xv = ca.SX.sym("xv", n)
        fv, hv = f(s.t, xv, s.u), h(s.t, xv, s.u)
        fx, hx, F, H = ca.substitute([fv, hv, ca.jacobian(fv, xv), ca.jacobian(hv, xv)], [xv], [clip_const(xh, box)])
    Qd, Rd = ca.DM(Qm), ca.DM(Rm)
    update = None
    if mode == "continuous":
        Rinv = ca.DM(np.linalg.inv(Rm))
        PHt = P @ H.T
        dx = fx + PHt @ Rinv @ (s.y - hx)
        dP = symmetric_part(F @ P + P @ F.T + Qd - PHt @ Rinv @ PHt.T)
    else:
        dx = fx
        dP = symmetric_part(F @ P + P @ F.T + Qd)
        Mdiag = ca.diag(s.m)
        Hm = Mdiag @ H
        Rmask = Mdiag @ Rd @ Mdiag + ca.diag(1 - s.m)  # unmeasured outputs: decoupled unit block, zero gain
        S = symmetric_part(Hm @ P @ Hm.T + Rmask)
        K = ca.solve(S, Hm @ P).T
        x_plus = clip_const(xh + K @ (s.m * (s.y - hx)), box)  # projected onto the bounds (identity without)
        IKH = ca.DM.eye(n) - K @ Hm
        P_plus = symmetric_part(IKH @ P @ IKH.T + K @ Rmask @ K.T)
        update = ca.vertcat(x_plus, ca.vec(P_plus))
    x0 = ca.SX.sym("xhat0", n)
    checks = [Check("Q positive semidefinite", True, f"min eig {np.linalg.eigvalsh(Qm).min():.3g}"),
              Check("R positive definite", True, f"min eig {np.linalg.eigvalsh(Rm).min():.3g}"),
              Check("P0 positive definite", True, f"min eig {np.linalg.eigvalsh(P0m).min():.3g}")]
    values: dict[str, Any] = {"Q": Qm, "R": Rm, "P0": P0m}
    if box is not None:
        checks.append(bounds_check(box, evidence))
        values.update({"bounds": box.describe(), "bounds policy": POLICY})
    cert = Certificate(f"Extended Kalman filter ({mode})", REF_EKF, tuple(checks), values)
    names = [f"xhat_{v}" for v in system.states] + [f"P_{i}_{j}" for j in range(n) for i in range(n)]
    return ObserverDesign.build("ekf", system, s, z_names=names, flow=ca.vertcat(dx, ca.vec(dP)), xhat=clip_const(xh, box),
                                xhat0_sym=x0, z0=ca.vertcat(x0, ca.DM(P0m.reshape(-1, order="F"))),
                                xhat0=np.zeros(n) if xhat0 is None else xhat0, certificate=cert, update=update,
                                covariance=P)
