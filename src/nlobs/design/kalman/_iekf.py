"""Iterated extended Kalman filter, continuous-discrete: Gauss-Newton iterations of the measurement update."""

from __future__ import annotations

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
from .._common import require_system, symmetric_part
from ._robust_maps import discrete_iekf, iterated_update
from ._sqrt import covariance_inputs

__all__ = ["design_iekf"]

REF = (f"Iterated extended Kalman filter: the measurement update as Gauss-Newton iterations ({cite('bell1993')}); "
       f"{cite('jazwinski1970')}; Joseph-form covariance ({cite('bucy1968')})")


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def tune_iekf(ctx: Any) -> Tuning:
    """The EKF/UKF tuning (Q, R, P(0) from the run; see :func:`~nlobs.design._tune.robust_filter`)."""
    return robust_filter(ctx, "iekf")


@kind('iekf', likelihood='ekf', summary='iterated extended Kalman filter (continuous-discrete, or on a map): Gauss-Newton iterations of the update',
      references=(work("bell1993"),), time_base="both", tune=tune_iekf, map_smoother="extended")
def design_iekf(system: System, *, Q: Any, R: Any, P0: Any = None, xhat0: Any = None, iterations: int = 5,
                tol: float = 1e-10) -> ObserverDesign:
    r"""Iterated extended Kalman filter (continuous-discrete; Bell & Cathey (1993)).

    Between samples as :func:`design_ekf`: :math:`\dot{\hat x} = f`, :math:`\dot P = FP + PF^\top + Q`.
    At a sample, from :math:`x_0 = \hat x^-`, Gauss-Newton steps on
    :math:`\tfrac12\|y - h(x)\|^2_{R^{-1}} + \tfrac12\|x - \hat x^-\|^2_{P^{-1}}`:

    .. math::

        H_i = \frac{\partial h}{\partial x}(x_i), \quad K_i = PH_i^\top(H_iPH_i^\top + R)^{-1}, \quad
        x_{i+1} = \hat x^- + K_i\big(y - h(x_i) - H_i(\hat x^- - x_i)\big),

    stopping after `iterations` steps or when :math:`\max_j|x_{i+1} - x_i|_j <` `tol` (the remaining
    steps then keep the iterate). :math:`\hat x^+` is the last iterate and
    :math:`P^+ = (I - K H)P(I - KH)^\top + KRK^\top` with the K, H of the last step taken. One iteration
    is the EKF. Outputs missing at a sample are left out.

    Parameters
    ----------
    system : System
    Q : array_like of shape (n, n)
        Process-noise intensity, positive semidefinite.
    R : array_like of shape (p, p)
        Covariance of one measurement sample, positive definite.
    P0 : array_like of shape (n, n), optional
        Initial covariance (identity), positive definite.
    iterations : int
        Largest number of Gauss-Newton steps per sample (≥ 1; 1 is the EKF).
    tol : float
        Stop when the step is below `tol` in every state (≥ 0).

    Other Parameters
    ----------------
    xhat0 : array_like of shape (n,), optional

    Raises
    ------
    PreconditionError, ShapeError
        For matrices of the wrong shape or definiteness, or iterations < 1, tol < 0.
    """
    require_system(system, "design_iekf")
    caller = "design_iekf"
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 1:
        raise PreconditionError(f"{caller}: `iterations` must be an integer ≥ 1 (1 is the EKF), got {iterations!r}")
    if not (np.isfinite(tol) and tol >= 0):
        raise PreconditionError(f"{caller}: `tol` must be a non-negative number, got {tol!r}")
    if system.is_discrete:   # a map: the map EKF's prediction, then the Gauss-Newton update
        return discrete_iekf(system, Q=Q, R=R, P0=P0, xhat0=xhat0, iterations=int(iterations), tol=float(tol), caller=caller)
    n, p = system.n_states, system.n_outputs
    Qm, Rm, P0m, checks = covariance_inputs(Q, R, P0, n, p, caller)
    x0v = check_vector(np.zeros(n) if xhat0 is None else xhat0, n, "xhat0", caller)
    f, h = compile_system(system).bind()
    s = Symbols.make(system, n + n * n)
    xh = s.z[:n]
    P = symmetric_part(ca.reshape(s.z[n:], n, n))
    fx = f(s.t, xh, s.u)
    F = ca.jacobian(fx, xh)
    dP = symmetric_part(F @ P + P @ F.T + ca.DM(Qm))
    xi, P_plus = iterated_update(h, s, xh, P, Rm, iterations, tol)
    x0 = ca.SX.sym("xhat0", n)
    checks.append(Check("Gauss-Newton iterations", True, f"at most {int(iterations)} per sample, stop below {tol:g}"))
    values: dict[str, Any] = {"Q": Qm, "R": Rm, "P0": P0m, "iterations": int(iterations), "tol": float(tol)}
    cert = Certificate("Iterated extended Kalman filter (continuous-discrete)", REF, tuple(checks), values)
    names = [f"xhat_{v}" for v in system.states] + [f"P_{i}_{j}" for j in range(n) for i in range(n)]
    return ObserverDesign.build("iekf", system, s, z_names=names, flow=ca.vertcat(fx, ca.vec(dP)), xhat=xh, xhat0_sym=x0,
                                z0=ca.vertcat(x0, ca.DM(P0m.reshape(-1, order="F"))), xhat0=x0v, certificate=cert,
                                update=ca.vertcat(xi, ca.vec(P_plus)), covariance=P)
