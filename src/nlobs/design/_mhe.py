"""Moving-horizon estimation: the "corrected trajectory-based" observer of Besançon (2010), solved with CasADi and IPOPT.

The window of past samples lives inside the observer's state z, so MHE fits the observer
contract: the flow predicts the current estimate between samples, and the update at each
sample shifts the window and solves the NLP over the window's initial state. The update is an
MX CasADi function that embeds :func:`casadi.nlpsol`; it runs on CasADi's virtual machine
(no C code generation).
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from ..engine import compile_system, rk4_step
from ..errors import PreconditionError
from ..model import System
from ._base import Certificate, Check, ObserverDesign, check_vector
from ._checks import check_matrix
from ..references import cite

__all__ = ["design_mhe"]

REF = (f"{cite('002')}, 'I. \"Corrected trajectory-based\" approach': min over z_(t-T) of "
       "∫_(t-T)^t ‖h(χ_u(τ, z_(t-T))) - y(τ)‖² dτ; discretised on the samples of the window, with an arrival cost "
       f"({cite('rao2003')}) and warm start from the previous solution")


def design_mhe(system: System, *, horizon: int = 20, R: Any = None, P_arrival: Any = None, substeps: int = 2,
               max_iter: int = 50, tol: float = 1e-8, xhat0: Any = None) -> ObserverDesign:
    r"""Moving-horizon estimator over the last `horizon` samples (single shooting on the initial state).

    At a sample time :math:`t_k`, with the samples :math:`(t_i, u_i, y_i)` of the window
    :math:`i = k-N+1, \dots, k`:

    .. math::

        \xi^* = \arg\min_\xi \; \|\xi - \bar x\|^2_{P_a^{-1}}
            + \sum_i m_i \odot \|y_i - h(\chi(t_i; \xi))\|^2_{R^{-1}}, \qquad
        \hat x(t_k) = \chi(t_k; \xi^*),

    where χ integrates the model from the window's first sample (RK4, `substeps` steps per
    sample interval, input held), :math:`\bar x` (the arrival prior) is the previous solution
    propagated to the new window start, and :math:`m_i` masks missing outputs. This is Besançon (2010)'s
    "corrected trajectory-based" estimator (the integral replaced by the sum over samples) with
    an arrival cost. IPOPT is warm-started at :math:`\bar x`. Between samples the estimate is
    predicted with the model. While the window fills up, its empty slots carry no weight
    and no time.

    Parameters
    ----------
    system : System
    horizon : int
        N, the number of samples in the window (>= 2).
    R : array_like of shape (p, p), optional
        Output weight (measurement covariance), positive definite (identity).
    P_arrival : array_like of shape (n, n), optional
        Arrival-cost covariance P_a, positive definite (identity). Large values trust the data more.

    Other Parameters
    ----------------
    substeps : int
        RK4 steps per sample interval inside the window.
    max_iter : int
        IPOPT iteration limit per sample (IPOPT is warm-started, so few are needed).
    tol : float
        IPOPT tolerance.
    xhat0 : array_like of shape (n,), optional
        Initial estimate, also the first arrival prior.

    Returns
    -------
    ObserverDesign
        Sampled (its ``update`` runs at sample instants); z holds the estimate, the window's
        initial state and the window of (t, u, y, mask, filled) samples.

    Raises
    ------
    PreconditionError, ShapeError
        For a horizon below 2, non-positive substeps, or weights of the wrong shape/definiteness.

    Notes
    -----
    The update is a CasADi MX function calling IPOPT: simulations with an MHE run on the
    CasADi virtual machine (the engine switches automatically); expect milliseconds per sample.
    IPOPT failures do not stop the run (``error_on_fail`` is off): the last iterate is used.

    References
    ----------
    Besançon (2010), "Some observer problem formulations - About methods", approach I.
    """
    caller = "design_mhe"
    n, p, nu = system.n_states, system.n_outputs, system.n_inputs
    N = int(horizon)
    if N < 2:
        raise PreconditionError(f"{caller}: `horizon` must be at least 2 samples, got {horizon}")
    if int(substeps) < 1 or int(max_iter) < 1:
        raise PreconditionError(f"{caller}: `substeps` and `max_iter` must be positive integers")
    Rm = np.eye(p) if R is None else check_matrix(R, p, p, "R", caller, definite="positive")
    Pa = np.eye(n) if P_arrival is None else check_matrix(P_arrival, n, n, "P_arrival", caller, definite="positive")
    Rinv, Painv = np.linalg.inv(Rm), np.linalg.inv(Pa)
    f, h = compile_system(system).bind()

    # one sample interval of the model, input held: x(t + dt) (dt may be 0 for empty slots)
    xs, us, ts, dts = ca.SX.sym("x", n), ca.SX.sym("u", nu), ca.SX.sym("t"), ca.SX.sym("dt")
    hstep = dts / int(substeps)
    xe = xs
    for i in range(int(substeps)):
        xe = rk4_step(lambda tt, xx, _k: f(tt, xx, us), ts + i * hstep, xe, hstep)
    advance = ca.Function("mhe_advance", [xs, us, ts, dts], [xe])

    # the NLP over the window's initial state; parameters: times, inputs, outputs, masks, filled, prior
    T_, U_, Y_, M_, F_ = ca.SX.sym("T", N), ca.SX.sym("U", nu, N), ca.SX.sym("Y", p, N), ca.SX.sym("M", p, N), ca.SX.sym("F", N)
    xbar, xi = ca.SX.sym("xbar", n), ca.SX.sym("xi", n)
    cost = (xi - xbar).T @ ca.DM(Painv) @ (xi - xbar)
    x = xi
    for i in range(N):
        if i > 0:
            x = advance(x, U_[:, i - 1], T_[i - 1], (T_[i] - T_[i - 1]) * F_[i - 1])
        r = M_[:, i] * (Y_[:, i] - h(T_[i], x, U_[:, i]))
        cost += r.T @ ca.DM(Rinv) @ r
    par = ca.vertcat(T_, ca.vec(U_), ca.vec(Y_), ca.vec(M_), F_, xbar)
    solver = ca.nlpsol(f"mhe_{system.name}", "ipopt", {"x": xi, "p": par, "f": cost},
                       {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.max_iter": int(max_iter),
                        "ipopt.tol": float(tol), "error_on_fail": False})

    # z = [xhat, x_start, T (N), U (nu N), Y (p N), M (p N), F (N)]
    sizes = [n, n, N, nu * N, p * N, p * N, N]
    offs = np.concatenate([[0], np.cumsum(sizes)])
    nz = int(offs[-1])

    def split(z: Any) -> list[Any]:
        return [z[int(offs[i]):int(offs[i + 1])] for i in range(len(sizes))]

    # flow (SX): predict the estimate, keep the window
    t, z, u, y = ca.SX.sym("t"), ca.SX.sym("z", nz), ca.SX.sym("u", nu), ca.SX.sym("y", p)
    flow = ca.vertcat(f(t, split(z)[0], u), ca.SX.zeros(nz - n))
    ins, names = [t, z, u, y], ["t", "z", "u", "y"]
    # update (MX): shift the window, propagate the prior, solve, predict to the newest sample
    tM, zM, uM, yM, mM = ca.MX.sym("t"), ca.MX.sym("z", nz), ca.MX.sym("u", nu), ca.MX.sym("y", p), ca.MX.sym("m", p)
    _, xstart, Tz, Uz, Yz, Mz, Fz = split(zM)
    Uz, Yz, Mz = ca.reshape(Uz, nu, N), ca.reshape(Yz, p, N), ca.reshape(Mz, p, N)
    prior = advance(xstart, Uz[:, 0], Tz[0], (Tz[1] - Tz[0]) * Fz[0])
    T1 = ca.vertcat(Tz[1:], tM)
    U1 = ca.horzcat(Uz[:, 1:], uM)
    Y1 = ca.horzcat(Yz[:, 1:], yM)
    M1 = ca.horzcat(Mz[:, 1:], mM)
    F1 = ca.vertcat(Fz[1:], 1)
    sol = solver(x0=prior, p=ca.vertcat(T1, ca.vec(U1), ca.vec(Y1), ca.vec(M1), F1, prior))
    xi_opt = sol["x"]
    xk = xi_opt
    for i in range(1, N):
        xk = advance(xk, U1[:, i - 1], T1[i - 1], (T1[i] - T1[i - 1]) * F1[i - 1])
    z_plus = ca.vertcat(xk, xi_opt, T1, ca.vec(U1), ca.vec(Y1), ca.vec(M1), F1)
    x0 = ca.SX.sym("xhat0", n)
    z0 = ca.vertcat(x0, x0, ca.SX.zeros(nz - 2 * n))
    x0v = np.zeros(n) if xhat0 is None else xhat0
    cert = Certificate(
        f"Moving-horizon estimator (window of {N} samples, IPOPT)", REF,
        (Check("R and the arrival covariance positive definite", True,
               f"min eig R = {np.linalg.eigvalsh(Rm).min():.3g}, P_arrival = {np.linalg.eigvalsh(Pa).min():.3g}"),
         Check.assumed("the model is observable over the window for the data",
                       "not checked at design time: an unobservable window leaves the arrival cost in charge")),
        {"horizon": N, "R": Rm, "P_arrival": Pa, "substeps": int(substeps), "max_iter": int(max_iter), "tol": float(tol)})
    z_names = ([f"xhat_{v}" for v in system.states] + [f"xstart_{v}" for v in system.states] + [f"t_{i}" for i in range(N)]
               + [f"u{j}_{i}" for i in range(N) for j in range(nu)] + [f"y{j}_{i}" for i in range(N) for j in range(p)]
               + [f"m{j}_{i}" for i in range(N) for j in range(p)] + [f"filled_{i}" for i in range(N)])
    return ObserverDesign(
        "mhe", system, tuple(z_names),
        ca.Function("mhe_flow", ins, [flow], names, ["dz"]),
        ca.Function("mhe_output", ins, [split(z)[0]], names, ["xhat"]),
        ca.Function("mhe_initial", [x0], [z0], ["xhat0"], ["z0"]),
        check_vector(x0v, n, "xhat0", caller), cert,
        ca.Function("mhe_update", [tM, zM, uM, yM, mM], [z_plus], [*names, "m"], ["z_plus"]))
