"""Kalman-type observers with a Riccati differential equation (Besançon (2010)): Kalman-Bucy for LTV systems,
the Kalman-like observer for state-affine systems (forgetting δ or noise V), and the LTV-based
high-gain Kalman observer."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ...errors import FormError, PreconditionError, ShapeError
from ...model import TIME, StateAffine, System, symbol
from ...model._budget import expand
from ...model._system import exact
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign, Symbols
from .._checks import check_matrix
from .._common import box_of, leaves_of, measured_states, require_system, sup_over_box, to_sx
from .._constructions import find_chains
from ..high_gain._high_gain import _theta, triangular_chains
from .._kind import Tuning, kind, renamed
from .._tune import CA_on_run, clean_message, region_inputs, square

__all__ = ["design_kalman_like", "design_kalman_bucy", "design_high_gain_kalman", "StateAffineParts", "state_affine_parts"]

REF_KALMAN = (f"{cite('002')}, \"'Non uniformly observable' systems - LTV\" (Result [Kalman]): "
              "Ṁ = AM + MAᵀ - MCᵀW⁻¹CM + V + δM, K = MCᵀW⁻¹, δ > 2‖A(t)‖ or V > 0")
REF_LIKE = (f"{cite('002')}, \"'Non uniformly observable' systems - LTV-like with I/O NL\": "
            "x̂' = A(u, y)x̂ + B(u, y) - K(t)(Cx̂ - y), K(t) as in the Kalman observer; u regularly persistent")
REF_HGK = (f"{cite('002')}, \"LTV-like with structured NL\": x̂' = A0(u, y)x̂ + φ(x̂, u) - diag(λ..λⁿ)K0(t)(C0x̂ - y), "
           "Ṁ = λ[MAᵀ + AM - MCᵀW⁻¹CM + δM], K0 = MCᵀW⁻¹, δ > 2‖A(u, y)‖, λ large enough")


@dataclass(frozen=True)
class StateAffineParts:
    """ẋ = A(u, y, t)x + b(u, y, t), y = C(u, t)x, read off a model (C is p x n here)."""

    system: System
    A: sp.Matrix
    b: sp.Matrix
    C: sp.Matrix


def state_affine_parts(model: System | StateAffine, caller: str) -> StateAffineParts:
    """The state-affine structure of a :class:`StateAffine` or of a :class:`System`.

    For a System, outputs that are single states are replaced by the output symbol wherever
    they appear in f; the rest must be affine in the state with coefficients in (u, y, t).

    Raises
    ------
    FormError
        Naming the equation that is not affine in the unmeasured state.
    """
    if isinstance(model, StateAffine):
        system = model.to_system()
        params = {symbol(k): exact(v) for k, v in model.params.items()}
        return StateAffineParts(system, model.A.xreplace(params), model.b.xreplace(params), model.C.T.xreplace(params))
    if not isinstance(model, System):
        raise TypeError(f"{caller}: expected a System or a StateAffine model, got {type(model).__name__}")
    system = model
    f, h = system.substituted()
    x = sp.Matrix(system.x)
    C = h.jacobian(x)
    for i, name in enumerate(system.outputs):
        if C.row(i).free_symbols & set(system.x) or expand(h[i] - (C.row(i) * x)[0], what=caller) != 0:
            raise FormError(f"{caller}: output {name} = {h[i]} is not linear in the state (y = C(u, t)x is required)")
    try:
        meas = measured_states(system, caller)
    except PreconditionError:
        meas = []
    ysub = {system.x[j]: system.y[k] for k, j in enumerate(meas)}
    xs = set(system.x)

    def affine(term: sp.Expr) -> bool:
        return all(not (sp.diff(term, v).free_symbols & xs) for v in system.x)

    # keep the terms already affine in x (so an LTV/LTI model keeps its A); replace the measured
    # states by the outputs only in the others (A(u, y, t) of 002's state-affine form)
    fy = sp.Matrix([sp.Add(*(t if affine(t) else t.xreplace(ysub) for t in sp.Add.make_args(expand(e, what=caller))))
                    for e in f])
    A = fy.jacobian(x)
    for i, name in enumerate(system.states):
        bad = A.row(i).free_symbols & set(system.x)
        if bad:
            raise FormError(f"{caller}: {system.name!r} is not state-affine: {name}' = {f[i]} is not affine in the unmeasured "
                            f"state(s) (a coefficient depends on {', '.join(sorted(s.name for s in bad))}); "
                            "only the measured outputs, inputs and t may enter A(u, y, t)")
    b = (fy - A * x).applyfunc(lambda e: expand(e, what=caller))
    return StateAffineParts(system, A, b, C)


def _sup_norm(parts: StateAffineParts, region: Mapping[str, Sequence[float]] | None, caller: str) -> tuple[float, str]:
    """sup ‖A(u, y, t)‖₂ over the box `region` (exact when A is constant)."""
    sysm = parts.system
    free = parts.A.free_symbols
    if not free:
        return float(np.linalg.norm(np.array(parts.A, dtype=float), 2)), "A constant"
    names = [nm for nm, sym in [*zip(sysm.inputs, sysm.u), *zip(sysm.outputs, sysm.y), ("t", TIME)] if sym in free]
    if region is None:
        raise PreconditionError(f"{caller}: A depends on {', '.join(names)}, so δ > 2 sup‖A‖ needs a `region` with bounds "
                                f"for {', '.join(names)}; or use V > 0 (positive definite) instead of forgetting alone")
    region = {k: v for k, v in region.items() if k in names}
    lo, hi = box_of(sysm, region, names, caller)
    pt = ca.SX.sym("pt", len(names))
    lookup = {**dict(zip(sysm.inputs, sysm.u)), **dict(zip(sysm.outputs, sysm.y)), "t": TIME}
    Af = ca.Function("A", [pt], [to_sx(list(parts.A), {lookup[nm]: pt[i] for i, nm in enumerate(names)})])

    def norms(P: np.ndarray) -> np.ndarray:
        return np.array([np.linalg.norm(np.array(Af(row)).reshape(parts.A.shape, order="F"), 2) for row in P])

    val, arg = sup_over_box(norms, lo, hi)
    return val, "over " + ", ".join(f"{nm} in [{a:g}, {b:g}]" for nm, a, b in zip(names, lo, hi)) + \
        f" (attained at {dict(zip(names, np.round(arg, 4).tolist()))})"


def _riccati_design(method: str, title: str, ref: str, parts: StateAffineParts, *, V: Any, W: Any, delta: float,
                    M0: Any, xhat0: Any, region: Mapping[str, Sequence[float]] | None, caller: str,
                    lam: float | None = None, phi: sp.Matrix | None = None, extra_checks: Sequence[Check] = (),
                    extra_values: Mapping[str, Any] | None = None, estimate: Callable[[ca.SX], ca.SX] | None = None,
                    initial: Callable[[ca.SX], ca.SX] | None = None, state_names: Sequence[str] | None = None) -> ObserverDesign:
    """The observer x̂' = A x̂ + b - K(Cx̂ - y) with the Riccati equation of Besançon (2010), (see design_kalman_like).

    `estimate` maps the filter state to the plant estimate and `initial` maps xhat0 to the
    filter's initial state (both identity by default): used for augmented systems (Viegas, Batista, Oliveira & Silvestre (2015)).
    """
    system = parts.system
    n, p = parts.A.shape[0], system.n_outputs
    # the papers' W, V, M0 (Besançon (2010)) are the options R, Q, P0
    Wm = check_matrix(W, p, p, "R", caller, definite="positive")
    Vm = np.zeros((n, n)) if V is None else check_matrix(V, n, n, "Q", caller, definite="semidefinite")
    M0m = np.eye(n) if M0 is None else check_matrix(M0, n, n, "P0", caller, definite="positive")
    d = float(delta)
    if not (np.isfinite(d) and d >= 0):
        raise PreconditionError(f"{caller}: the forgetting factor `delta` must be a non-negative number, got {delta}")
    checks = list(extra_checks)
    vmin = float(np.linalg.eigvalsh(Vm).min())
    values: dict[str, Any] = {"V": Vm, "W": Wm, "delta": d, "M0": M0m, **(extra_values or {})}
    if vmin > 0:
        checks.append(Check(f"V positive definite ({cite('002')}: δ > 2‖A‖ or V > 0)", True, f"min eig V = {vmin:.3g}"))
    elif d > 0:
        normA, where = _sup_norm(parts, region, caller)
        if d <= 2 * normA:
            raise PreconditionError(f"{caller}: the forgetting factor δ = {d:g} is not above 2 sup‖A‖ = {2 * normA:.4g} ({where}); "
                                    f"take δ > {2 * normA:.4g}, or give V positive definite ({cite('002')}: δ > 2‖A(t)‖ or V > 0)")
        checks.append(Check(f"δ > 2 sup‖A‖ ({cite('002')})", True, f"{d:g} > {2 * normA:.4g}, {where}",
                            "exact (A constant)" if not parts.A.free_symbols else
                            "sampled over the region: sup‖A‖ is estimated from below, not proved"))
        if parts.A.free_symbols:
            checks.append(Check.assumed("the inputs and outputs stay in the region where sup‖A‖ was estimated",
                                        "not checked at design time"))
        values["sup_norm_A"] = normA
    else:
        raise PreconditionError(f"{caller}: neither forgetting nor noise: give δ > 2‖A‖ (`delta`) or V positive definite "
                                f"(`Q`); with δ = 0 and Q singular the gain may vanish ({cite('002')}, Kalman observer)")
    # stiffness of the Riccati ODE at t = 0: the correction term MCᵀW⁻¹CM acts at rate ~ λmax(M0)‖C‖²/λmin(W);
    # explicit RK4 needs dt·rate below ~2.8 (reported so a blow-up can be traced to the step size)
    values["riccati_rate0"] = float(np.linalg.eigvalsh(M0m).max() / np.linalg.eigvalsh(Wm).min()) * (lam or 1.0)
    checks.append(Check.assumed(f"input regularly persistent / (A, C) uniformly completely observable ({cite('002')})",
                                "not checked at design time: it depends on the input and output trajectory"))
    s = Symbols.make(system, n + n * n)
    xh = s.z[:n]
    M = ca.reshape(s.z[n:], n, n)
    M = (M + M.T) / 2
    L = leaves_of(system, s)
    A = ca.reshape(to_sx(list(parts.A.T), L), n, n)  # list(Aᵀ) is A column-major
    b = to_sx(list(parts.b), L)
    C = ca.reshape(to_sx(list(parts.C.T), L), p, n)
    Winv = ca.DM(np.linalg.inv(Wm))
    K = M @ C.T @ Winv
    Ric = A @ M + M @ A.T - K @ ca.DM(Wm) @ K.T + d * M
    if lam is None:
        dM = Ric + ca.DM(Vm)
        dx = A @ xh + b - K @ (C @ xh - s.y)
    else:
        Lx = dict(L)
        Lx.update({sym: xh[i] for i, sym in enumerate(system.x)})
        dM = lam * Ric + ca.DM(Vm)
        Lam = ca.diag(ca.DM([lam ** (i + 1) for i in range(n)]))
        dx = A @ xh + to_sx(list(phi), Lx) - Lam @ K @ (C @ xh - s.y)
    dM = (dM + dM.T) / 2
    nx = system.n_states
    x0 = ca.SX.sym("xhat0", nx)
    w0 = x0 if initial is None else initial(x0)
    first = list(state_names) if state_names is not None else [f"xhat_{v}" for v in system.states]
    names = first + [f"M_{i}_{j}" for j in range(n) for i in range(n)]
    values.update({"A(u, y, t)": str(parts.A.tolist()), "C": str(parts.C.tolist())})
    cert = Certificate(title, ref, tuple(checks), values)
    # M is the error covariance (V, W the noise intensities) only for the plain Riccati equation without
    # forgetting, on the plant's own coordinates: not with δ > 0, the high-gain λ, or an augmentation map
    cov = M if (d == 0 and lam is None and estimate is None) else None
    return ObserverDesign.build(method, system, s, z_names=names, flow=ca.vertcat(dx, ca.vec(dM)),
                                xhat=xh if estimate is None else estimate(xh), xhat0_sym=x0,
                                z0=ca.vertcat(w0, ca.DM(M0m.reshape(-1, order="F"))),
                                xhat0=np.zeros(nx) if xhat0 is None else xhat0, certificate=cert, covariance=cov)


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def state_affine(ctx: Any) -> tuple[Any, str]:
    try:
        return state_affine_parts(ctx.system, "state_affine"), ""
    except (FormError, TypeError) as e:
        return None, clean_message(e)


def constant_C(parts: Any) -> np.ndarray | None:
    C = parts.C
    return None if C.free_symbols else np.array(C, dtype=float)


def tune_high_gain_kalman(ctx: Any) -> Tuning:
    if ctx.p != 1:
        return Tuning.fails(f"one output measuring the first state is required; the model has {ctx.p}")
    try:
        (chain,) = triangular_chains(ctx.system, caller="high_gain_kalman")
    except (FormError, PreconditionError, ValueError) as e:
        alt = find_chains(ctx.system)
        hint = f" (the chain here is {' -> '.join(alt[0])}: declare the states in that order)" if alt and len(alt) == 1 else ""
        return Tuning.fails(clean_message(e) + hint)
    if not ctx.region:
        return Tuning.needs("a region of the inputs and output for δ > 2 sup‖A0(u, y)‖: add [simulation] x0")
    x1, y = ctx.system.x[0], ctx.system.y[0]
    A0 = sp.zeros(ctx.n, ctx.n)
    for i, a in enumerate(chain.couplings):
        A0[i, i + 1] = a.xreplace({x1: y})
    region = {k: list(v) for k, v in {**region_inputs(ctx), ctx.system.outputs[0]: ctx.region[ctx.system.outputs[0]]}.items()}
    try:
        sup, _ = _sup_norm(StateAffineParts(ctx.system, A0, sp.zeros(ctx.n, 1), sp.zeros(1, ctx.n)), region, "high_gain_kalman")
    except (PreconditionError, ShapeError) as e:
        return Tuning.fails(clean_message(e))
    delta = round(2.2 * sup + 1e-3, 6)
    lam = float(min(max(1.0, ctx.omega_o / max(delta, 1e-9)), ctx.step_limit() / max(delta, 1e-9), 50.0))
    lam = max(1.0, lam)
    opts = {"lam": round(lam, 6), "delta": delta, "region": region}
    return Tuning.tuned(opts, f"δ = 2.2 sup‖A0‖ = {delta:.3g} over the visited (u, y), λ = {lam:.3g}")


def tune_kalman_bucy(ctx: Any) -> Tuning:
    parts, why = state_affine(ctx)
    if parts is None:
        return Tuning.fails(why)
    W, M0, note = ctx.riccati_weights(ctx.R_rate, ctx.P0, ctx.Q, constant_C(parts), CA_on_run(ctx, parts.C * parts.A))
    return Tuning.tuned({"Q": square(ctx.Q), "R": square(W), "P0": square(M0)},
                    f"state-affine ẋ = A(u, y, t)x + b; Q, R as intensities ({ctx.noise_note})", extra=note)


def tune_kalman_like(ctx: Any) -> Tuning:
    parts, why = state_affine(ctx)
    if parts is None:
        return Tuning.fails(why)
    delta = round(float(ctx.omega_p), 6)
    W, M0, note = ctx.riccati_weights(ctx.R_rate, ctx.P0, ctx.Q, constant_C(parts), CA_on_run(ctx, parts.C * parts.A))
    return Tuning.tuned({"R": square(W), "Q": square(ctx.Q), "delta": delta, "P0": square(M0)},
                    f"state-affine; R and Q from the run (the paper's W and V), forgetting δ = ω_p = {delta:.3g}", extra=note)


@kind('kalman_like', summary='Kalman-like observer for a state-affine system, with forgetting δ and/or process noise',
      references=(work("002", "Kalman-like observer for state-affine systems"),), tune=tune_kalman_like)
@renamed(model="system", W="R", V="Q", M0="P0")
def design_kalman_like(system: System | StateAffine, *, R: Any = None, Q: Any = None, delta: float = 0.0, P0: Any = None,
                       region: Mapping[str, Sequence[float]] | None = None, xhat0: Any = None) -> ObserverDesign:
    r"""Kalman-like observer for a state-affine system (Besançon (2010)), with forgetting δ and/or process noise Q.

    The options are named as for every covariance-based kind: R, Q and P0 are Besançon (2010)'s W, V and M0
    (the equations below keep the paper's letters).

    For :math:`\dot x = A(u, y, t)x + b(u, y, t)`, :math:`y = C(u, t)x`:

    .. math::

        \dot{\hat x} = A(u, y, t)\hat x + b(u, y, t) - K(t)(C\hat x - y), \qquad K = MC^\top W^{-1},

        \dot M = AM + MA^\top - MC^\top W^{-1}CM + V + \delta M,

    with :math:`\delta > 2\|A\|` or V > 0 (Besançon (2010)). Noise-free, :math:`V_e = e^\top M^{-1}e` satisfies
    :math:`\dot V_e = -\delta V_e - e^\top(C^\top W^{-1}C + M^{-1}VM^{-1})e \le -\delta V_e`, so
    :math:`e^\top M^{-1} e` decays at least like :math:`e^{-\delta t}`. Convergence needs the
    input to be regularly persistent (A, C uniformly completely observable along the
    trajectory), which depends on the data and is not checked here.

    M is integrated in full and kept exactly symmetric (every derivative is symmetrised). The
    certificate's ``riccati_rate0`` (≈ λmax(M0)‖C‖²/λmin(W) for unit C rows) is the fastest rate of
    the Riccati equation at the start: with fixed-step RK4 keep dt·riccati_rate0 below about 2.8.

    Parameters
    ----------
    system : StateAffine or System
        A System is read as state-affine after replacing the measured states by the outputs.
    R : array_like of shape (p, p)
        Output weight W (measurement noise intensity), positive definite (default identity).
    Q : array_like of shape (n, n), optional
        State noise intensity V, positive semidefinite.
    delta : float
        Forgetting factor δ ≥ 0.
    P0 : array_like of shape (n, n), optional
        Initial M, M0, positive definite (identity).
    region : mapping of name to (lo, hi), optional
        Bounds on the inputs, outputs and t that A depends on, to check δ > 2 sup‖A‖ when V is
        not positive definite.

    Other Parameters
    ----------------
    xhat0 : array_like of shape (n,), optional

    Raises
    ------
    FormError
        If the model is not state-affine (naming the equation).
    PreconditionError
        If δ ≤ 2 sup‖A‖ with Q not positive definite, or the weights are not (semi)definite.

    References
    ----------
    Besançon (2010), Result [Kalman] and "LTV-like with I/O NL"; the robot arm with
    unknown b and the Van der Pol oscillator with unknown γ, ω² (examples of the slides).
    """
    caller = "design_kalman_like"
    parts = state_affine_parts(system, caller)
    p = parts.system.n_outputs
    return _riccati_design("kalman_like", "Kalman-like observer for a state-affine system", REF_LIKE, parts,
                           V=Q, W=np.eye(p) if R is None else R, delta=delta, M0=P0, xhat0=xhat0, region=region, caller=caller)


@kind('kalman_bucy', summary='Kalman-Bucy filter for a linear time-varying / state-affine model ẋ = A(u, y, t)x + b, y = C x',
      references=(work("kalman1961"),), tune=tune_kalman_bucy)
@renamed(model="system")
def design_kalman_bucy(system: System | StateAffine, *, Q: Any, R: Any, P0: Any = None, xhat0: Any = None) -> ObserverDesign:
    r"""Kalman-Bucy filter for a linear time-varying model :math:`\dot x = A(u, t)x + b(u, t)`, :math:`y = C(u, t)x`.

    .. math::

        \dot{\hat x} = A\hat x + b - PC^\top R^{-1}(C\hat x - y), \qquad
        \dot P = AP + PA^\top + Q - PC^\top R^{-1}CP ,

    the Kalman observer of Besançon (2010) with δ = 0 and V = Q > 0. A may also depend on the measured
    output (as the augmented systems of Viegas, Batista, Oliveira & Silvestre (2015) do); the filter then evaluates it on the
    measurement.

    Parameters
    ----------
    system : StateAffine or System
    Q : array_like of shape (n, n)
        Process noise intensity, positive definite (Besançon (2010): V > 0 when δ = 0).
    R : array_like of shape (p, p)
        Measurement noise intensity, positive definite.
    P0 : array_like of shape (n, n), optional
        Initial covariance (identity).

    Other Parameters
    ----------------
    xhat0 : array_like of shape (n,), optional

    Raises
    ------
    FormError, PreconditionError

    References
    ----------
    Besançon (2010), Result [Kalman]; Kalman & Bucy (1961).
    """
    caller = "design_kalman_bucy"
    parts = state_affine_parts(system, caller)
    n = parts.system.n_states
    Qm = check_matrix(Q, n, n, "Q", caller, definite="semidefinite")
    if np.linalg.eigvalsh(Qm).min() <= 0:
        raise PreconditionError(f"{caller}: `Q` must be positive definite (smallest eigenvalue {np.linalg.eigvalsh(Qm).min():.3g}); "
                                "with a singular Q use design_kalman_like with forgetting δ > 2‖A‖")
    Rm = check_matrix(R, parts.system.n_outputs, parts.system.n_outputs, "R", caller, definite="positive")
    P0m = None if P0 is None else check_matrix(P0, n, n, "P0", caller, definite="positive")
    return _riccati_design("kalman_bucy", "Kalman-Bucy filter (LTV)", REF_KALMAN, parts, V=Qm, W=Rm, delta=0.0, M0=P0m,
                           xhat0=xhat0, region=None, caller=caller)


@kind('high_gain_kalman', summary='LTV-based high-gain Kalman observer for ẋ = A₀(u, y)x + φ(x, u), y = x₁',
      references=(work("002", "LTV-based high-gain Kalman observer"),), tune=tune_high_gain_kalman)
@renamed(W="R", M0="P0")
def design_high_gain_kalman(system: System, *, lam: float, delta: float, R: Any = None, P0: Any = None,
                            region: Mapping[str, Sequence[float]] | None = None, xhat0: Any = None) -> ObserverDesign:
    r"""LTV-based high-gain Kalman observer (Besançon (2010)) for :math:`\dot x = A_0(u, y)x + \varphi(x, u)`, :math:`y = x_1`.

    :math:`A_0` has only the superdiagonal :math:`a_{i,i+1}(u, y)` and φ is triangular
    (:math:`\partial\varphi_i/\partial x_j = 0` for j ≥ i+1):

    .. math::

        \dot{\hat x} = A_0(u, y)\hat x + \varphi(\hat x, u)
            - \mathrm{diag}(\lambda, \dots, \lambda^n) K_0(t)(C_0\hat x - y),

        \dot M = \lambda[MA^\top + AM - MC^\top W^{-1}CM + \delta M], \qquad K_0 = MC^\top W^{-1},

    with :math:`\delta > 2\|A_0(u, y)\|` and λ large enough; u must be locally regular. The options R and P0 are
    the paper's W and M(0).

    Parameters
    ----------
    system : System
        One output measuring the first state; the states in chain order.
    lam : float
        λ ≥ 1.
    delta : float
        δ > 2 sup‖A0(u, y)‖ over `region` (checked).
    R : array_like of shape (1, 1), optional
        The output weight W (identity).
    P0 : array_like of shape (n, n), optional
        M(0) (identity).
    region : mapping of name to (lo, hi), optional
        Bounds on the inputs and the output that A0 depends on (needed when A0 is not constant).

    Other Parameters
    ----------------
    xhat0 : array_like of shape (n,), optional

    Raises
    ------
    FormError
        If the structure is broken (naming the entry).
    PreconditionError
        If δ ≤ 2 sup‖A0‖, λ < 1, or the system has more than one output.

    References
    ----------
    Besançon (2010), "'Non uniformly observable' systems - LTV-like with structured NL".
    """
    require_system(system, "design_high_gain_kalman")
    caller = "design_high_gain_kalman"
    if system.n_outputs != 1:
        raise PreconditionError(f"{caller}: one output is required ({cite('002')}'s form has y = x1); the model has {system.n_outputs}")
    lam_v = _theta(lam, None, caller)
    if lam_v < 1:
        raise PreconditionError(f"{caller}: λ = {lam_v:g} must be at least 1 (the high gain)")
    try:
        (chain,) = triangular_chains(system, caller=caller)
    except FormError as e:
        raise FormError(f"{e}. The LTV-based high-gain Kalman observer needs x_i' = a_i(u, y) x_(i+1) + φ_i(x_1..x_i, u)") from e
    n = system.n_states
    if chain.states != tuple(range(n)):
        raise PreconditionError(f"{caller}: list the states in chain order starting with the measured one")
    f, _ = system.substituted()
    x1, y = system.x[0], system.y[0]
    A0 = sp.zeros(n, n)
    for i, a in enumerate(chain.couplings):
        A0[i, i + 1] = a.xreplace({x1: y})
    phi = (f - A0.xreplace({y: x1}) * sp.Matrix(system.x)).applyfunc(sp.expand)
    C = sp.zeros(1, n)
    C[0, 0] = 1
    parts = StateAffineParts(system, A0, sp.zeros(n, 1), C)
    extra = [Check("structure: x_i' = a_i(u, y) x_(i+1) + φ_i(x_1..x_i, u), y = x_1", True)]
    return _riccati_design("high_gain_kalman", f"LTV-based high-gain Kalman observer (λ = {lam_v:g})", REF_HGK, parts,
                           V=None, W=np.eye(1) if R is None else R, delta=delta, M0=P0, xhat0=xhat0, region=region,
                           caller=caller, lam=lam_v, phi=phi, extra_checks=extra,
                           extra_values={"lambda": lam_v, "phi": [str(e) for e in phi]})
