r"""GPEBO for state-affine systems and the 2G+D observer (Wang, Ortega & Bobtsov (2021)).

For :math:`\dot x = A(u, y, t)x + b(u, y, t)`, :math:`y = C(u, t)^\top x` (Wang, Ortega & Bobtsov (2021), eq. 1), Lemma 1 turns
state observation into the estimation of a constant vector: with

.. math::

    \dot\xi = A\xi + b, \qquad \dot\Phi_A = A\Phi_A, \quad \Phi_A(0) = I_n

(Wang, Ortega & Bobtsov (2021), eq. 13), :math:`x = \xi + \Phi_A\theta` with :math:`\theta = x(0) - \xi(0)` (eq. 8), and θ
satisfies the LRE :math:`\mathcal Y = \psi^\top\theta` with :math:`\mathcal Y = y - C^\top\xi`,
:math:`\psi = \Phi_A^\top C` (eqs. 9-10). Any estimator of :mod:`nlobs.design` then gives
:math:`\hat x = \xi + \Phi_A\hat\theta` (eq. 12); with the G+D estimator (eqs. 16-17) this is the
*2G+D observer*, which converges whenever the system is observable on some [0, T]
(Wang, Ortega & Bobtsov (2021), Proposition 1), uniform complete observability is not needed.

Where the homogeneous part is not uniformly stable (assumption 5), an output injection L
is added, as the paper suggests after eq. (5): :math:`\dot\xi = A\xi + b + L(y - C^\top\xi)`,
:math:`\dot\Phi_A = (A - LC^\top)\Phi_A`. The error :math:`e = x - \xi` then obeys
:math:`\dot e = (A - LC^\top)e`, and Lemma 1 holds with A replaced by :math:`A - LC^\top`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import sympy as sp

from ...errors import FormError, PreconditionError
from ...model import TIME, StateAffine, System, symbol
from ...model._forms import matrix_of
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign
from .._constructions import evaluate
from ..kalman._riccati import state_affine, state_affine_parts
from .._kind import Tuning, kind
from ._regression import GD, AbstractEstimator, ExcitationMonitor, Regression, StateStack, estimator_from, sx_matrix
from .._tune import clean_message, fmt, poles_for, rounded, square

__all__ = ["design_gpebo", "design_gpebo_2gd"]

REF = (f"{cite('000')} Lemma 1 (eqs. 8-10, 13), eq. (12); G+D estimator eqs. (16)-(17); "
       "order (3 + 2n)n, §6")


def _uniform_stability(A: sp.Matrix, caller: str, injected: bool) -> Check | None:
    """Assumption (5) for a constant homogeneous matrix: eigenvalues in Re < 0, or on the axis
    and semisimple. Returns None when A is not constant (not checkable symbolically)."""
    if A.free_symbols:
        return None
    An = np.array(A, dtype=float)
    eig = np.linalg.eigvals(An)
    worst = eig[np.argmax(eig.real)] if eig.size else 0.0
    what = "A - LCᵀ" if injected else "A"
    hint = (f"choose an output injection `L` with A - LCᵀ Hurwitz ({cite('000')}, remark after eq. 5)" if not injected
            else "choose another `L`")
    tol = 1e-9 * max(1.0, float(np.abs(An).max(initial=0.0)))
    if eig.size and worst.real > tol:
        raise PreconditionError(f"{caller}: the homogeneous part is not uniformly stable ({cite('000')} assumption 5): {what} has the "
                                f"eigenvalue {complex(worst):.4g} with positive real part, so Φ_A grows without bound; {hint}")
    axis = eig[np.abs(eig.real) <= tol]
    for lam in np.unique(np.round(axis, 9)):
        alg = int(np.sum(np.abs(eig - lam) <= 1e-6))
        geo = An.shape[0] - np.linalg.matrix_rank(An - lam * np.eye(An.shape[0]), tol=1e-8)
        if geo < alg:
            raise PreconditionError(f"{caller}: the homogeneous part is not uniformly stable ({cite('000')} assumption 5): {what} has the "
                                    f"eigenvalue {complex(lam):.3g} on the imaginary axis with a Jordan block (algebraic "
                                    f"multiplicity {alg} > geometric {geo}), so Φ_A grows polynomially; {hint}")
    return Check(f"uniform stability of the homogeneous part ({cite('000')} assumption 5), {what} constant", True,
                 f"max Re eig = {eig.real.max():.4g}")


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def _gpebo_common(ctx: Any) -> tuple[dict[str, Any] | None, str, Tuning | None]:
    parts, why = state_affine(ctx)
    if parts is None:
        return None, "", Tuning.fails(why)
    A, C = parts.A, parts.C
    opts: dict[str, Any] = {}
    note = ""
    varying = sorted(s.name for s in A.free_symbols)
    if C.free_symbols:
        return opts, "C depends on u or t: no output injection is tried; assumption 5 is checked by the run", None
    Cn = np.array(C, dtype=float)
    if not varying:
        An = np.array(A, dtype=float)
        eig = np.linalg.eigvals(An)
        if not (eig.real.max() > 1e-9 or _jordan_on_axis(An)):
            return opts, "", None
        L, bad = _injection(An, Cn, ctx, "A")
        if bad is not None:
            return None, "", bad
        opts["L"] = rounded(L)
        return opts, (f"A has an unstable or a repeated mode on the imaginary axis, so Φ_A grows ({cite('000')} assumption 5): "
                      f"output injection L puts eig(A − LCᵀ) at {fmt(poles_for(ctx.n, ctx.omega_o))}"), None
    if ctx.nominal is None:
        return opts, (f"A depends on {', '.join(varying)}: assumption 5 (Φ_A bounded) is not decidable symbolically; a run "
                      "shows it"), None
    # A(u, y, t): assumption 5 is checked along the run, where Φ_A is integrated on the nominal signals
    At = evaluate(list(A.T), ctx.system, ctx.samples(2001)).reshape(-1, ctx.n, ctx.n).transpose(0, 2, 1)
    tt = ctx.samples(2001)["t"]
    peak, end = _phi_growth(At, tt)
    grows = "without bound (beyond 1e12)" if not np.isfinite(peak) else f"to {peak:.3g}"
    if peak < 1e3 and end < _GROWING:
        return opts, (f"A depends on {', '.join(varying)}: along the run ‖Φ_A‖ stays ≤ {peak:.3g} ({cite('000')} assumption 5 "
                      "holds there)"), None
    L, bad = _injection(np.mean(At, axis=0), Cn, ctx, "the run's mean of A")
    if bad is not None:
        return None, "", bad
    peak2, end2 = _phi_growth(At - (L @ Cn)[None], tt)
    if peak2 < 1e3 and end2 < _GROWING:
        opts["L"] = rounded(L)
        return opts, (f"along the run ‖Φ_A‖ grows {grows} ({cite('000')} assumption 5 fails there): output injection L "
                      f"from the run's mean A (eig(mean A − LCᵀ) at {fmt(poles_for(ctx.n, ctx.omega_o))}) keeps ‖Φ_(A−LCᵀ)‖ ≤ "
                      f"{peak2:.3g} along the run"), None
    grows2 = "without bound" if not np.isfinite(peak2) else f"to {peak2:.3g}"
    return None, "", Tuning.fails(f"the homogeneous part is not uniformly stable along the run ({cite('000')} assumption 5): ‖Φ_A‖ grows "
                            f"{grows}, and an output injection from the run's mean A leaves ‖Φ‖ growing {grows2}; give `L`")


#: ‖Φ(T)‖ over its largest value on [0, T/2] at or above which Φ counts as still growing: a bounded Φ gives about 1,
#: a Φ that grows linearly (a parameter appended as a constant state: a Jordan block at 0) 2·(1 + cT)/(2 + cT) → 2.
_GROWING = 1.5


def _injection(A: np.ndarray, C: np.ndarray, ctx: Any, what: str) -> tuple[np.ndarray | None, Tuning | None]:
    from .._checks import observer_gain

    try:
        L, _, _ = observer_gain(A, C, poles=poles_for(ctx.n, ctx.omega_o), caller="gpebo")
    except (PreconditionError, ValueError) as e:
        return None, Tuning.fails(f"{what} is not uniformly stable ({cite('000')} assumption 5) and no output injection fixes it: "
                            f"{clean_message(e)}")
    return L, None


def _phi_growth(At: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """max ‖Φ(t)‖ of Φ' = A(t)Φ, Φ(0) = I on the grid (A held over each interval), and ‖Φ(T)‖ / max over the first half
    (> 1: still growing at the end)."""
    n = At.shape[1]
    h = np.diff(t)
    M = At[:-1] * h[:, None, None]
    # exp(M) for the whole stack: scaling and squaring with a degree-6 Taylor polynomial (‖M/2^s‖ ≤ 1/4)
    s = max(0, int(np.ceil(np.log2(max(float(np.max(np.linalg.norm(M, 1, axis=(1, 2)))), 1e-300) / 0.25))))
    X = M / 2.0 ** s
    E = np.broadcast_to(np.eye(n), M.shape).copy()
    term = E.copy()
    for j in range(1, 7):
        term = term @ X / j
        E = E + term
    for _ in range(s):
        E = E @ E
    Phi = np.eye(n)
    norms = [1.0]
    for k in range(len(h)):
        Phi = E[k] @ Phi
        nm = float(np.abs(Phi).sum(axis=0).max())          # ‖Φ‖₁: cheap, and equivalent to ‖Φ‖₂ within √n
        if not np.isfinite(nm) or nm > 1e12:
            return np.inf, np.inf
        norms.append(nm)
    norms_a = np.array(norms)
    half = max(1, len(norms_a) // 2)
    return float(norms_a.max()), float(norms_a[-1] / max(norms_a[:half].max(), 1e-300))


def _jordan_on_axis(A: np.ndarray) -> bool:
    eig = np.linalg.eigvals(A)
    for lam in eig[np.abs(eig.real) <= 1e-9]:
        alg = int(np.sum(np.abs(eig - lam) <= 1e-6))
        geo = A.shape[0] - np.linalg.matrix_rank(A - lam * np.eye(A.shape[0]), tol=1e-8)
        if geo < alg:
            return True
    return False


def _regressor_level(ctx: Any) -> tuple[float, float]:
    """mean and peak ‖ψ‖² of the GPEBO regressor ψ = Φ_Aᵀ C along the run (d/dt trace W(0, t) = ‖ψ‖²; at least 1)."""
    info = ctx.uco or {}
    mean = peak = 1.0
    if info.get("gramian_trace") and info.get("horizon"):
        mean = max(1.0, float(info["gramian_trace"]) / float(info["horizon"]))
    if info.get("regressor_peak"):
        peak = max(1.0, float(info["regressor_peak"]))
    return mean, max(mean, peak)


def tune_gpebo_2gd(ctx: Any) -> Tuning:
    opts, note, bad = _gpebo_common(ctx)
    if bad is not None:
        return bad
    lim = ctx.step_limit()
    psi2, peak = _regressor_level(ctx)
    gg = float(min(5.0 * ctx.omega_o / psi2, 0.5 * lim / peak))   # the gradient stage acts at γ_g‖ψ‖²
    gm = float(min(10.0 * gg, lim))                                  # the mixed stage at γΔ² ≤ γ (0 ≤ Δ ≤ 1)
    opts.update({"gamma_g": float(f"{gg:.6g}"), "gamma": float(f"{gm:.6g}")})
    return Tuning.tuned(opts, f"state-affine; γ_g = {gg:.3g} (5 ω_o / mean ‖ψ‖², ‖ψ‖² up to {peak:.3g} on the run), γ = {gm:.3g} "
                    "(10 γ_g; both within the step limit); observable on an interval suffices (no UCO)", extra=note)


def tune_gpebo(ctx: Any) -> Tuning:
    opts, note, bad = _gpebo_common(ctx)
    if bad is not None:
        return bad
    _, peak = _regressor_level(ctx)
    P0 = np.minimum(np.diag(ctx.P0) * ctx.omega_o, 0.5 * ctx.step_limit() / peak)   # the LS gain acts at ‖P‖‖ψ‖²
    opts["estimator"] = {"kind": "least_squares", "P0": square(np.diag(P0))}
    return Tuning.tuned(opts, "state-affine; least-squares estimator of θ = x(0) − ξ(0) with P(0) = ω_o·diag(range²) (capped at "
                    "the step limit)", extra=note)


@kind('gpebo', summary='GPEBO observer for a state-affine system, with any regression estimator',
      references=(work("000", "Lemma 1 with least squares"),), tune=tune_gpebo)
def design_gpebo(system: StateAffine | System, *, estimator: AbstractEstimator | Any = None, L: Any = None,
                 xhat0: Any = None) -> ObserverDesign:
    r"""GPEBO observer for a state-affine system (Wang, Ortega & Bobtsov (2021), Lemma 1), with any regression estimator.

    .. math::

        \dot\xi &= A\xi + b + L(y - C^\top\xi), \qquad \dot\Phi_A = (A - LC^\top)\Phi_A,\quad \Phi_A(0) = I, \\
        \mathcal Y &= y - C^\top\xi, \qquad \psi = \Phi_A^\top C, \qquad \hat x = \xi + \Phi_A\hat\theta,

    with θ̂ from `estimator` on :math:`\mathcal Y = \psi^\top\theta` (L = 0 unless given).
    ξ(0) = `xhat0` and θ̂(0) = 0, so :math:`\hat x(0)` = `xhat0`; the true θ is
    :math:`x(0) - \hat x(0)`.

    Parameters
    ----------
    system : StateAffine or System
        The model :math:`\dot x = A(u, y, t)x + b(u, y, t)`, :math:`y = C(u, t)^\top x`; a System is
        read as state-affine after replacing the measured states by the outputs (as
        :func:`nlobs.design.design_kalman_like` does).
    estimator : estimator or mapping, optional
        :class:`GD` (default, gains 1: the 2G+D observer), :class:`DREM`, :class:`Gradient`,
        :class:`LeastSquares`, or a model-file table ``{kind = "gd", gamma_g = 5, gamma = 50}``.
    L : (n, p) matrix, optional
        Output injection (numbers or expressions in u, y, t and the parameters) making the
        homogeneous part uniformly stable where assumption (5) fails.
    xhat0 : array_like of shape (n,), optional
        Initial estimate (zeros).

    Returns
    -------
    ObserverDesign
        Internal state ``(ξ, Φ_A, estimator states)``; for G+D ``(ξ, Φ_A, θ̂_g, Ω, θ̂)`` of order
        (3 + 2n)n, which the certificate checks.

    Raises
    ------
    PreconditionError
        If the model is not state-affine, or A (or A - LCᵀ) is constant and not uniformly
        stable (an eigenvalue with positive real part or a Jordan block on the imaginary axis).

    Notes
    -----
    Assumption (5) cannot be decided symbolically when A depends on u, y or t; the certificate
    then says so, and the growth of Φ_A shows in the internal states of a run.

    References
    ----------
    Wang, Ortega & Bobtsov (2021), Lemma 1, eqs. (5), (8)-(13), Proposition 1, §6.
    """
    caller = "design_gpebo"
    try:
        parts = state_affine_parts(system, caller)
    except FormError as e:
        raise PreconditionError(f"{e}. Write the model as a StateAffine, with A(u, y, t) using the measured output y where "
                                f"the equation needs it ({cite('000')} eq. 1).") from e
    est = estimator_from(estimator, default=GD(1.0, 1.0), caller=caller)
    plant = parts.system
    n, p = plant.n_states, plant.n_outputs
    A, b, C = parts.A, parts.b, parts.C.T            # parameters substituted; C is n x p as in y = Cᵀx (000 eq. 1)
    allowed = {k: symbol(k) for k in (*plant.inputs, *plant.outputs, *plant.params)}
    allowed["t"] = TIME
    params = {symbol(k): v for k, v in plant.params.items()}
    Lm = sp.zeros(n, p) if L is None else matrix_of(L, n, p, allowed, name="L").xreplace(params)
    stab = _uniform_stability(A - Lm * C.T, caller, L is not None)

    stack = StateStack(plant)
    leaves = stack.leaves()
    A_, b_, C_, L_ = (sx_matrix(M, leaves) for M in (A, b, C, Lm))
    xi = stack.add("xi", n, init=stack.xhat0)
    Phi = stack.add("Phi", n, n, init=np.eye(n))
    Yr = stack.y - C_.T @ xi                        # (10a)
    stack.set_flow(xi, A_ @ xi + b_ + L_ @ Yr)      # (13a), with output injection
    stack.set_flow(Phi, (A_ - L_ @ C_.T) @ Phi)     # (13b)
    reg = Regression(Yr, Phi.T @ C_, tuple(f"theta{i + 1}" for i in range(n)))  # (9), (10b)
    out = est.build(stack, reg, np.zeros(n))
    xhat = xi + Phi @ out.theta                     # (12)

    order = stack.n_z
    checks = [Check(f"model is state-affine: x' = A(u, y, t)x + b(u, y, t), y = C(u, t)ᵀx ({cite('000')} eq. 1)", True, f"n = {n}, p = {p}")]
    if stab is not None:
        checks.append(stab)
    if isinstance(est, GD):
        paper = (3 + 2 * n) * n
        checks.append(Check(f"observer order n_χ = (3 + 2n)n as stated in {cite('000')} §6", order == paper,
                            f"{order} internal states = n (ξ) + n² (Φ_A) + n (θ̂_g) + n² (Ω) + n (θ̂); (3 + 2n)n = {paper}"))
    values: dict[str, Any] = {
        "A": str(A.tolist()), "b": str(list(b)), "C": str(C.tolist()), **({"L": str(Lm.tolist())} if L is not None else {}),
        **est.describe(), "internal states": order,
        "assumption (5)": ("checked (A constant)" if stab is not None else
                           "not decidable symbolically (A depends on u, y or t): ‖Φ_A‖ must stay bounded along the input"),
        "excitation monitor": ExcitationMonitor.of(stack, out, est),
    }
    name = "2G+D observer" if isinstance(est, GD) else f"GPEBO observer with {type(est).__name__} estimator"
    cert = Certificate(name + (" and output injection" if L is not None else ""), REF + "; " + est.reference, tuple(checks), values)
    return stack.build("gpebo_2gd" if isinstance(est, GD) else "gpebo", xhat=xhat, certificate=cert, xhat0=xhat0)


@kind('gpebo_2gd', summary='2G+D observer: GPEBO with the G+D estimator (interval excitation, no UCO needed)',
      references=(work("000", "Proposition 1"),), tune=tune_gpebo_2gd)
def design_gpebo_2gd(system: StateAffine | System, *, gamma_g: float = 1.0, gamma: float = 1.0, L: Any = None,
               xhat0: Any = None) -> ObserverDesign:
    r"""The 2G+D observer of Wang, Ortega & Bobtsov (2021), Proposition 1: GPEBO (Lemma 1) with the G+D estimator (Lemma 2).

    Globally exponentially convergent for every state-affine system that is *observable* on
    some interval [0, T] (rank W(0, T) = n), under assumption (5); UCO is not needed.
    See :func:`design_gpebo` for the equations.

    Parameters
    ----------
    system : StateAffine or System
    gamma_g, gamma : float
        Gains of the gradient and of the mixed scalar stage of G+D (Wang, Ortega & Bobtsov (2021), eqs. 16a, 16c).
    L : (n, p) matrix, optional
        Output injection where assumption (5) fails.
    xhat0 : array_like, optional

    References
    ----------
    Wang, Ortega & Bobtsov (2021), Proposition 1, Lemmas 1-2, eqs. (12)-(17).

    Examples
    --------
    >>> import nlobs
    >>> sa = nlobs.StateAffine([[0, "u"], [0, 0]], [0, 0], [[1], [0]], inputs=["u"])
    >>> design_gpebo_2gd(sa, gamma_g=5, gamma=50).n_z        # (3 + 2n)n with n = 2
    14
    """
    return design_gpebo(system, estimator=GD(gamma_g, gamma), L=L, xhat0=xhat0)

