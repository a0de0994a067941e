"""Luenberger observer (LTI, and on linear maps with poles inside the unit circle) and the error-linearisation / output-injection observer (Besançon (2010))."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from ...engine import to_casadi
from ...errors import FormError, PreconditionError
from ...model import LTI, TIME, OutputInjectionForm, System
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign, Symbols, check_vector
from .._checks import check_matrix, observer_gain
from .._common import require_system
from .._kind import Tuning, kind, renamed
from .._tune import clean_message, fmt, poles_for

__all__ = ["design_luenberger", "design_output_injection"]

REF_LUENBERGER = f"{cite('002')}, 'Result [Luenberger]': x̂' = Ax̂ + Bu - K(Cx̂ - y), A - KC stable"
REF_DLUEN = f"Discrete-time Luenberger observer ({cite('002', 'Result [Luenberger]')}, stated for maps)"
REF_INJECTION = f"{cite('002')}, 'Result [Error linearization]': x̂' = Ax̂ + B(u, y) - K(Cx̂ - y)"


def _dm(M: np.ndarray) -> ca.DM:
    return ca.DM(np.asarray(M, dtype=float))


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def tune_luenberger(ctx: Any) -> Tuning:
    try:
        LTI.from_system(ctx.system)
    except FormError as e:
        return Tuning.fails(f"not linear time-invariant: {clean_message(e)}")
    poles = poles_for(ctx.n, ctx.omega_o)
    if ctx.system.is_discrete:   # the same rates as poles of the map: z = exp(s T_s), inside the unit circle
        Ts = ctx.system.sample_time
        poles = [round(float(np.exp(max(p_ * Ts, -5.0))), 6) for p_ in poles]
        return Tuning.tuned({"poles": poles}, f"linear map; eig(A − LC) placed at {fmt(poles)} = exp(−ω T_s) for the rates "
                            f"ω_o·(1, 1.25, ...) (ω_o = 3 ω_p), inside the unit circle")
    return Tuning.tuned({"poles": poles}, f"LTI; eig(A − LC) placed at {fmt(poles)} (ω_o = 3 ω_p)")


def tune_output_injection(ctx: Any) -> Tuning:
    holds, why = ctx.form("output injection")
    if not holds:
        return Tuning.fails(why)
    poles = poles_for(ctx.n, ctx.omega_o)
    return Tuning.tuned({"poles": poles}, f"ẋ = Ax + B(u, y), y = Cx; eig(A − KC) placed at {fmt(poles)}: the error is linear, "
                    "convergence is global")


@kind('luenberger', summary='Luenberger observer for an LTI model ẋ = Ax + Bu, y = Cx + Du: poles placed, or a Kalman gain from Q, R',
      references=(work("002", "Result [Luenberger]"),), time_base="both", tune=tune_luenberger)
def design_luenberger(system: System, *, poles: Any = None, L: Any = None, Q: Any = None, R: Any = None,
                      xhat0: Any = None) -> ObserverDesign:
    r"""Luenberger observer for an LTI model x' = Ax + Bu, y = Cx + Du.

    .. math::

        \dot{\hat x} = A\hat x + Bu - L(C\hat x + Du - y), \qquad
        \dot e = (A - LC)e .

    Parameters
    ----------
    system : System
        An LTI model (recognised with :meth:`nlobs.model.LTI.from_system`).
    poles : sequence of complex, optional
        Eigenvalues of A - LC (pole placement; needs (A, C) observable).
    L : array_like of shape (n, p), optional
        The gain, given directly (checked: A - LC Hurwitz).
    Q, R : array_like, optional
        Process and measurement noise intensities for the steady-state Kalman (LQE) gain.
    xhat0 : array_like of shape (n,), optional
        Default initial estimate (zeros).

    Returns
    -------
    ObserverDesign
        With ``L``, the achieved ``eigenvalues`` and the ``decay_rate`` in its certificate.

    Raises
    ------
    PreconditionError
        If the model is not LTI, (A, C) is not observable (with the rank and the unobservable
        direction), the poles are unstable or cannot be placed, or a given L is not Hurwitz.

    References
    ----------
    Besançon (2010), "Result [Luenberger]".
    Viegas, Batista, Oliveira & Silvestre (2015), §IV-C: L = [1+√2, 1, 1+√2] places eig(A - LC) at -1, -√2/2 ± j√2/2.

    Examples
    --------
    >>> import nlobs
    >>> sys = nlobs.System.lti([[0, 1], [0, 0]], None, [[1, 0]])
    >>> d = design_luenberger(sys, poles=[-2, -3])
    >>> [round(float(v), 9) for v in sorted(d.certificate.values["eigenvalues"].real)]
    [-3.0, -2.0]
    """
    require_system(system, "design_luenberger")
    caller = "design_luenberger"
    if system.is_discrete:   # a linear map: poles inside the unit circle
        if Q is not None or R is not None:
            raise PreconditionError(f"{caller}: for a discrete-time model give `poles` or `L` (the LQE gain is not available)")
        return discrete_luenberger(system, poles=poles, L=L, xhat0=xhat0, caller=caller)
    try:
        lti = LTI.from_system(system)
    except FormError as e:
        raise PreconditionError(f"{caller}: {e}. For a nonlinear model use design_output_injection or design_ekf.") from e
    gain, checks, values = observer_gain(lti.A, lti.C, poles=poles, L=L, Q=Q, R=R, caller=caller)
    n = system.n_states
    s = Symbols.make(system, n)
    xh = s.z
    innovation = _dm(lti.C) @ xh + (_dm(lti.D) @ s.u if system.n_inputs else 0) - s.y
    dz = _dm(lti.A) @ xh + (_dm(lti.B) @ s.u if system.n_inputs else 0) - _dm(gain) @ innovation
    x0 = ca.SX.sym("xhat0", n)
    cert = Certificate(
        "Luenberger observer (" + ("pole placement" if poles is not None else "given gain" if L is not None else "LQE gain") + ")",
        REF_LUENBERGER, (Check("model is LTI", True, f"A {lti.A.shape}, C {lti.C.shape}"), *checks), values)
    return ObserverDesign.build("luenberger", system, s, z_names=[f"xhat_{v}" for v in system.states], flow=dz, xhat=xh,
                                xhat0_sym=x0, z0=x0, xhat0=np.zeros(n) if xhat0 is None else xhat0, certificate=cert)


@kind('output_injection', summary='error-linearisation (output-injection) observer for ẋ = Ax + B(u, y, t), y = Cx: a linear error, global convergence',
      references=(work("002", "Result [Error linearization]"),), tune=tune_output_injection)
@renamed(K="L")
def design_output_injection(system: System, *, poles: Any = None, L: Any = None, Q: Any = None, R: Any = None,
                            xhat0: Any = None) -> ObserverDesign:
    r"""Error-linearisation (output-injection) observer for x' = Ax + B(u, y, t), y = Cx.

    .. math::

        \dot{\hat x} = A\hat x + B(u, y, t) - K(C\hat x - y), \qquad \dot e = (A - KC)e .

    The form is recognised from the model (see :class:`nlobs.model.OutputInjectionForm`);
    the error dynamics are linear, so any K with A - KC Hurwitz gives global exponential
    convergence at the rate -max Re eig(A - KC).

    Parameters
    ----------
    system : System
    poles : sequence of complex, optional
        Eigenvalues of A - KC (needs (A, C) observable).
    L : array_like of shape (n, p), optional
        The gain (K in the equations above), given directly.
    Q, R : array_like, optional
        Weights for an LQE-type gain.
    xhat0 : array_like of shape (n,), optional

    Raises
    ------
    PreconditionError
        If the model is not in the form (naming the entry that breaks it), (A, C) is not
        observable, or the gain is not Hurwitz.

    References
    ----------
    Besançon (2010), "Result [Error linearization]" and the robot-arm example
    (x1' = x2, x2' = -a1 sin x1 - a2 x2 + b u, y = x1).
    """
    require_system(system, "design_output_injection")
    caller = "design_output_injection"
    try:
        form = OutputInjectionForm.from_system(system)
    except FormError as e:
        raise PreconditionError(f"{caller}: {e}.") from e
    gain, checks, values = observer_gain(form.A, form.C, poles=poles, L=L, Q=Q, R=R, caller=caller)
    values = {"K": values.pop("L"), **values, "A": form.A, "C": form.C,
              "B(u, y, t)": "[" + ", ".join(str(b) for b in form.B) + "]"}
    n = system.n_states
    s = Symbols.make(system, n)
    leaves = {TIME: s.t}
    leaves.update({sym: s.u[i] for i, sym in enumerate(system.u)})
    leaves.update({sym: s.y[i] for i, sym in enumerate(system.y)})
    B = to_casadi(list(form.B), leaves)
    xh = s.z
    dz = _dm(form.A) @ xh + B - _dm(gain) @ (_dm(form.C) @ xh - s.y)
    x0 = ca.SX.sym("xhat0", n)
    cert = Certificate("Output-injection (error linearisation) observer", REF_INJECTION,
                       (Check("model in output-injection form x' = Ax + B(u, y), y = Cx", True), *checks), values)
    return ObserverDesign.build("output_injection", system, s, z_names=[f"xhat_{v}" for v in system.states], flow=dz,
                                xhat=xh, xhat0_sym=x0, z0=x0, xhat0=np.zeros(n) if xhat0 is None else xhat0,
                                certificate=cert)


def discrete_luenberger(system: System, *, poles: Any = None, L: Any = None, xhat0: Any = None,
                        caller: str = "design_luenberger") -> ObserverDesign:
    """The discrete-time Luenberger observer of a linear map (see the module's docstring)."""
    from ...analysis import kalman_rank  # here, not at the top: a Monte Carlo worker loads no analysis
    import scipy.signal

    try:
        lti = LTI.from_system(system)
    except FormError as e:
        raise PreconditionError(f"{caller}: {e}") from e
    A, B, C, D = (np.asarray(M, dtype=float) for M in (lti.A, lti.B, lti.C, lti.D))
    n, p = A.shape[0], C.shape[0]
    obs = kalman_rank(A, C)
    if not obs.observable:
        raise PreconditionError(f"{caller}: {obs}. Pole placement needs (A, C) observable")
    if (poles is None) == (L is None):
        raise PreconditionError(f"{caller}: give `poles` (inside the unit circle) or the gain `L`, one of the two")
    if L is None:
        want = np.asarray(poles, dtype=complex).ravel()
        if want.size != n:
            raise PreconditionError(f"{caller}: `poles` needs {n} values (one per state), got {want.size}")
        outside = want[np.abs(want) >= 1]
        if outside.size:
            raise PreconditionError(f"{caller}: the pole {complex(outside[0]):.4g} is not inside the unit circle "
                                    f"(|z| = {abs(outside[0]):.4g} ≥ 1); a discrete-time observer needs |z| < 1 "
                                    "(e.g. 0.5 for an error that halves every step)")
        try:
            Lm = scipy.signal.place_poles(A.T, C.T, want).gain_matrix.T
        except ValueError as e:
            raise PreconditionError(f"{caller}: these poles cannot be placed: {e}") from e
    else:
        Lm = check_matrix(L, n, p, "L", caller)
    ev = np.linalg.eigvals(A - Lm @ C)
    if np.max(np.abs(ev)) >= 1:
        raise PreconditionError(f"{caller}: A − LC has the eigenvalue {complex(ev[np.argmax(np.abs(ev))]):.4g} with |z| = "
                                f"{np.max(np.abs(ev)):.4g} ≥ 1: the error does not decay")
    x0v = check_vector(np.zeros(n) if xhat0 is None else xhat0, n, "xhat0", caller)
    nu = system.n_inputs
    s = Symbols.make(system, n + nu + p + 1)
    x, u_prev, y_prev, started = s.z[:n], s.z[n:n + nu], s.z[n + nu:n + nu + p], s.z[n + nu + p]
    Ad, Bd, Cd, Dd, Ld = (ca.DM(M) for M in (A, B, C, D, Lm))
    step = Ad @ x + (Bd @ u_prev if nu else 0) + Ld @ (s.m * (y_prev - Cd @ x - (Dd @ u_prev if nu else 0)))
    x_new = ca.if_else(started, step, x)
    update = ca.vertcat(x_new, s.u, s.m * s.y, 1)
    rate = float(np.max(np.abs(ev)))
    checks = (Check("(A, C) observable (Kalman rank)", True, f"rank {obs.rank} = n"),
              Check("eig(A − LC) inside the unit circle", True, f"max |z| = {rate:.4g}", "floating point"))
    cert = Certificate("Luenberger observer (discrete time)", REF_DLUEN, checks,
                       {"L": Lm, "eigenvalues": ev, "contraction per step": rate, "A": A, "C": C,
                        "sample_time": system.sample_time})
    x0 = ca.SX.sym("xhat0", n)
    z0 = ca.vertcat(x0, ca.DM.zeros(nu + p), 0)
    names = ([f"xhat_{v}" for v in system.states] + [f"u_prev_{v}" for v in system.inputs]
             + [f"y_prev_{v}" for v in system.outputs] + ["started"])
    return ObserverDesign.build("luenberger", system, s, z_names=names, flow=ca.SX.zeros(s.z.shape[0]), xhat=x,
                                xhat0_sym=x0, z0=z0, xhat0=x0v, certificate=cert, update=update)
