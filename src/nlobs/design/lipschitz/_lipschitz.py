"""Lipschitz (Thau) observer for x' = Ax + φ(x, u), y = Cx (Besançon (2010)), with a Riccati-based gain search."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ...engine import compile_system, to_casadi
from ...errors import PreconditionError
from ...model import TIME, System
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign, Symbols
from .._checks import check_matrix
from .._common import batch, box_of, require_system, sup_over_box
from .._kind import Tuning, kind, renamed
from .._tune import jacobians_on_run, region_inputs, region_states, rounded

__all__ = ["design_lipschitz", "region_lipschitz", "thau_margin", "thau_gain_search"]

REF = (f"{cite('002')}, \"'Uniformly observable' systems - LTI + Lipschitz NL\": if K, P, Q > 0 with "
       "P(A - KC) + (A - KC)ᵀP = -Q and eigmin(Q)/(2 eigmax(P)) > γ, then x̂' = Ax̂ + B(u, x̂) - K(Cx̂ - y) is an observer (Thau)")


def thau_margin(A: np.ndarray, C: np.ndarray, K: np.ndarray) -> tuple[float, np.ndarray]:
    r"""The best Thau margin of a gain: :math:`\max_{P, Q} \lambda_{min}(Q)/(2\lambda_{max}(P))`.

    For a fixed Hurwitz :math:`A - KC` the maximum is reached at Q = I: any Q ⪰ qI gives
    :math:`P_Q \succeq q P_I` (the Lyapunov operator's inverse is monotone), so
    :math:`\lambda_{min}(Q)/\lambda_{max}(P_Q) \le 1/\lambda_{max}(P_I)`.

    Returns
    -------
    margin : float
        :math:`1/(2\lambda_{max}(P_I))`, 0 when A - KC is not Hurwitz.
    P : numpy.ndarray
        :math:`P_I`, solution of :math:`P(A - KC) + (A - KC)^\top P = -I`.
    """
    Acl = A - K @ C
    if np.max(np.linalg.eigvals(Acl).real) >= 0:
        return 0.0, np.full(A.shape, np.nan)
    import scipy.linalg  # deferred: keeps `import nlobs` fast

    P = scipy.linalg.solve_continuous_lyapunov(Acl.T, -np.eye(A.shape[0]))
    P = (P + P.T) / 2
    return float(1.0 / (2.0 * np.linalg.eigvalsh(P).max())), P


def _riccati_gain(A: np.ndarray, C: np.ndarray, alpha: float, rho: float) -> np.ndarray | None:
    r"""K = ΣCᵀ/ρ with :math:`(A + \alpha I)\Sigma + \Sigma(A + \alpha I)^\top - \Sigma C^\top C\Sigma/\rho + I = 0`
    (eig(A - KC) then lie left of -α)."""
    n = A.shape[0]
    # CARE ÃᵀΣ + ΣÃ - ΣCᵀCΣ/ρ + I = 0 with Ã = (A + αI)ᵀ, from the stable invariant subspace of the
    # Hamiltonian (small n: an eigen-decomposition is fast and, checked below, accurate enough here)
    At = (A + alpha * np.eye(n)).T
    H = np.block([[At, -C.T @ C / rho], [-np.eye(n), -At.T]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        try:
            w, V = np.linalg.eig(H)
            stable = np.argsort(w.real)[:n]
            if np.max(w.real[stable]) >= 0:
                return None
            U1, U2 = V[:n, stable], V[n:, stable]
            S = np.real(U2 @ np.linalg.inv(U1))
        except np.linalg.LinAlgError:
            return None
    S = (S + S.T) / 2
    res = At.T @ S + S @ At - S @ C.T @ C @ S / rho + np.eye(n)
    if not np.all(np.isfinite(S)) or np.abs(res).max() > 1e-6 * max(1.0, np.abs(S).max() ** 2 / rho):
        return None
    K = S @ C.T / rho
    return K if np.all(np.isfinite(K)) else None


def thau_gain_search(A: np.ndarray, C: np.ndarray, gamma: float) -> tuple[float, float, np.ndarray, dict[str, float]]:
    """Search the Riccati family K(α, ρ) on a logarithmic grid.

    The margin grows with the gain and saturates (the cheap-observer limit), so the largest
    margin is reached only with huge gains. The chosen member is the one with the smallest
    ‖K‖ whose margin reaches γ + (μ_best - γ)/2: half the best achievable guaranteed rate.

    Returns (chosen margin, best margin found, K, {"alpha", "rho"}).
    """
    scale = max(1.0, float(np.abs(A).max()))
    alphas = np.concatenate([[0.0], scale * np.logspace(-2, 1.5, 8)])
    rhos = scale ** 2 * np.logspace(-10, 4, 22)
    found = []
    for a in alphas:
        for r in rhos:
            K = _riccati_gain(A, C, float(a), float(r))
            if K is not None:
                m, _ = thau_margin(A, C, K)
                found.append((m, float(np.linalg.norm(K, 2)), K, float(a), float(r)))
    if not found:
        return 0.0, 0.0, np.zeros((A.shape[0], C.shape[0])), {}
    best = max(f[0] for f in found)
    target = gamma + 0.5 * (best - gamma) if best > gamma else best
    ok = [f for f in found if f[0] >= target - 1e-12]
    m, _, K, a, r = min(ok, key=lambda f: f[1])
    return m, best, K, {"alpha": a, "rho": r}


def region_lipschitz(system: System, phi: Sequence[sp.Expr], region: Mapping[str, Sequence[float]], *,
                    caller: str = "region_lipschitz") -> tuple[float, dict[str, float]]:
    r"""Estimate :math:`\gamma = \sup \|\partial\varphi/\partial x\|_2` of a given φ over a region of states, inputs and t.

    The designs' own estimate (deterministic grid, a region mapping with t): the public
    :func:`nlobs.analysis.lipschitz_constant` answers the user's question for φ = f − Ax over a state box (random
    samples, a LipschitzEstimate).

    The sup of the Jacobian's spectral norm over a convex box is the Lipschitz constant of φ in
    x there. It is computed on a grid refined by local maximisation (see
    :func:`nlobs.design._common.sup_over_box`): an estimate from below, exact when the
    maximum sits on the grid.

    Parameters
    ----------
    system : System
    phi : sequence of SymPy expressions, one per state
    region : mapping of name to (lo, hi)
        Bounds for every state, every input and, for a time-varying φ, ``t``.

    Returns
    -------
    gamma : float
    where : dict
        The point where the sup was found.
    """
    phi = [e if isinstance(e, sp.Basic) else sp.Float(float(e)) for e in phi]
    names = list(system.states) + list(system.inputs)
    f_free = set().union(*(e.free_symbols for e in phi)) if phi else set()
    if TIME in f_free:
        names.append("t")
    lo, hi = box_of(system, region, names, caller)
    n = system.n_states
    pt = ca.SX.sym("pt", len(names))
    leaves = {sym: pt[i] for i, sym in enumerate(system.x)}
    leaves.update({sym: pt[n + i] for i, sym in enumerate(system.u)})
    leaves[TIME] = pt[len(names) - 1] if "t" in names else 0.0
    params = {sp.Symbol(k, real=True): v for k, v in system.params.items()}
    J = ca.jacobian(to_casadi([e.xreplace(params) for e in phi], leaves), pt[:n])
    Jf = ca.Function("J", [pt], [J])

    def norms(P: np.ndarray) -> np.ndarray:
        return np.linalg.norm(batch(Jf, P), 2, axis=(1, 2))

    val, arg = sup_over_box(norms, lo, hi)
    return val, dict(zip(names, map(float, arg)))


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def tune_lipschitz(ctx: Any) -> Tuning:
    if not ctx.region:
        return Tuning.needs("a region (box of states and inputs) to bound the Lipschitz constant: add [simulation] x0")
    region = {k: list(v) for k, v in {**region_states(ctx), **region_inputs(ctx)}.items()}
    if ctx.system.is_time_varying:
        region["t"] = [0.0, float(ctx.scenario.t_final)]
    centre = {k: 0.5 * (a + b) for k, (a, b) in region.items()}
    f, _ = ctx.system.substituted()
    J = f.jacobian(sp.Matrix(ctx.system.x))
    sub = {s: centre[s.name] for s in (*ctx.system.x, *ctx.system.u)}
    sub[TIME] = centre.get("t", 0.0)
    try:
        A = np.array(J.xreplace({k: sp.Float(v) for k, v in sub.items()}).evalf(), dtype=float)
    except (TypeError, ValueError):
        return Tuning.fails("the Jacobian of f is not finite at the centre of the region")
    quick = _thau_precheck(ctx, A, J)
    if quick:
        return Tuning.fails(quick, region=region, A=rounded(A))
    return Tuning.tuned({"region": region, "A": rounded(A)}, "A = ∂f/∂x at the centre of the visited region, φ = f − Ax; γ bounded "
                    "over the region (valid while x and x̂ stay in it)")


def _thau_precheck(ctx: Any, A: np.ndarray, J: sp.Matrix) -> str:
    """A quick refusal when the best Thau margin of the gain search is already below a *lower* bound of γ
    (the sup of ‖∂f/∂x − A‖₂ over the run's points): the full design would refuse too, only slower."""
    _, h = ctx.system.substituted()
    C = h.jacobian(sp.Matrix(ctx.system.x))
    if C.free_symbols:
        return ""
    best = thau_gain_search(A, np.array(C, dtype=float), 0.0)[1]
    F = jacobians_on_run(ctx)
    if F is None:
        return ""
    gam = float(np.max(np.linalg.norm(F - A, 2, axis=(1, 2))))
    if best <= gam:
        return (f"the Thau condition eigmin(Q)/(2 eigmax(P)) > γ cannot hold: the best margin of the gain search is {best:.4g}, "
                f"but already along the run γ ≥ sup‖∂f/∂x − A‖₂ = {gam:.4g} ({cite('002', 'LTI + Lipschitz NL')}). "
                "Shrink the region, change the A/φ split, or use a high-gain or Kalman-type observer")
    return ""


@kind('lipschitz', summary="Thau's observer for a Lipschitz nonlinearity, with a Riccati-based gain search",
      references=(work("thau1973"), work("002", "LTI + Lipschitz NL")), tune=tune_lipschitz)
@renamed(gamma="lipschitz", K="L")
def design_lipschitz(system: System, *, lipschitz: float | None = None, region: Mapping[str, Sequence[float]] | None = None,
                     A: Any = None, L: Any = None, xhat0: Any = None) -> ObserverDesign:
    r"""Thau's observer for a Lipschitz nonlinearity, with a Riccati-based gain search (Besançon (2010)).

    For :math:`\dot x = Ax + \varphi(x, u)`, :math:`y = Cx`, with
    :math:`\|\varphi(x, u) - \varphi(z, u)\| \le \gamma\|x - z\|`:

    .. math::

        \dot{\hat x} = A\hat x + \varphi(\hat x, u) - K(C\hat x - y),\qquad
        P(A - KC) + (A - KC)^\top P = -Q,\qquad \mu = \frac{\lambda_{min}(Q)}{2\lambda_{max}(P)} > \gamma .

    Then :math:`V = e^\top Pe` gives
    :math:`\|e(t)\| \le \sqrt{\kappa(P)}\,e^{-(\mu - \gamma)t}\|e(0)\|`: the guaranteed rate is μ - γ.

    The gain search: for a given K the best (P, Q) has Q = I (see :func:`thau_margin`), so the
    margin depends on K alone. K is taken from the family of shifted filter Riccati equations
    :math:`(A + \alpha I)\Sigma + \Sigma(A + \alpha I)^\top - \Sigma C^\top C\Sigma/\rho + I = 0`,
    :math:`K = \Sigma C^\top/\rho` (every member makes A - KC Hurwitz with decay > α), and
    (α, ρ) is chosen to maximise μ: a logarithmic grid, then Nelder-Mead. No LMI solver is
    needed: the achieved μ is reported, and when it does not exceed γ the design is refused
    with the number.

    Parameters
    ----------
    system : System
        y = Cx must be linear with constant coefficients.
    lipschitz : float, optional
        The Lipschitz constant γ of φ in x (uniform in u). If omitted it is estimated over `region`
        by :func:`region_lipschitz`.
    region : mapping of name to (lo, hi), optional
        Box of states and inputs for the estimate of γ (the guarantee then holds while the
        state and the estimate stay in it).
    A : array_like of shape (n, n), optional
        The linear part; default the Jacobian of f at x = 0, u = 0 (t = 0). φ = f - Ax.
    L : array_like of shape (n, p), optional
        Use this gain (the paper's K) instead of searching (it is checked).

    Other Parameters
    ----------------
    xhat0 : array_like of shape (n,), optional

    Returns
    -------
    ObserverDesign
        Certificate values: ``K``, ``P``, ``Q`` (= I), ``margin`` μ, ``gamma``,
        ``guaranteed_rate`` μ - γ, ``overshoot`` √κ(P), ``eigenvalues`` of A - KC.

    Raises
    ------
    PreconditionError
        If the output is not linear, (A, C) is not observable (with the unobservable direction),
        neither γ nor `region` is given, or the achieved margin μ ≤ γ.

    References
    ----------
    Besançon (2010), "LTI + Lipschitz NL", "First idea" (Thau (1973)).
    """
    from ...analysis import kalman_rank  # here, not at the top: a Monte Carlo worker loads no analysis
    gamma, K = lipschitz, L  # Besançon (2010)'s γ and K
    require_system(system, "design_lipschitz")
    caller = "design_lipschitz"
    n, p = system.n_states, system.n_outputs
    f, h = system.substituted()
    x = sp.Matrix(system.x)
    Cs = h.jacobian(x)
    if any(e.free_symbols for e in Cs) or any(sp.expand(h[i] - (Cs.row(i) * x)[0]) != 0 for i in range(p)):
        raise PreconditionError(f"{caller}: the output must be y = Cx with constant C; got {list(h)}")
    C = np.array(Cs, dtype=float)
    if A is None:
        zero = {s: 0 for s in (*system.x, *system.u, TIME)}
        Js = f.jacobian(x).xreplace(zero)
        try:
            Am = np.array(Js.evalf(), dtype=float)
        except TypeError:
            raise PreconditionError(f"{caller}: the Jacobian of f at x = 0, u = 0 is not finite ({Js}); give `A`") from None
        if not np.all(np.isfinite(Am)):
            raise PreconditionError(f"{caller}: the Jacobian of f at x = 0, u = 0 is not finite; give `A`")
    else:
        Am = check_matrix(A, n, n, "A", caller)
    A_sym = sp.Matrix(n, n, [sp.nsimplify(v) if float(v).is_integer() else sp.Float(v) for v in Am.ravel()])
    phi = [sp.expand(e) for e in (f - A_sym * x)]
    obs = kalman_rank(Am, C)
    if not obs.observable:
        raise PreconditionError(f"{caller}: {obs}. The Thau observer needs (A, C) observable.")
    checks = [Check("y = Cx with constant C", True), Check("(A, C) observable (Kalman rank)", True, f"rank {obs.rank} = n")]
    values: dict[str, Any] = {"A": Am, "C": C, "phi": [str(e) for e in phi]}
    if gamma is None:
        if region is None:
            raise PreconditionError(f"{caller}: give the Lipschitz constant `lipschitz` of φ = f - Ax, or a `region` (box of "
                                    "states and inputs) to estimate it over")
        gam, where = region_lipschitz(system, phi, region, caller=caller)
        checks.append(Check("γ estimated over the region (sup of ‖∂φ/∂x‖₂; valid while x and x̂ stay in it)", True,
                            f"γ ≈ {gam:.4g} at {where}", "sampled over the region: a lower bound of the supremum, not a proof"))
        checks.append(Check.assumed("x and x̂ stay in the region where γ was estimated",
                                    ", ".join(f"{k} in [{v[0]:g}, {v[1]:g}]" for k, v in region.items())))
        values["region"] = dict(region)
        gamma_kind = "with γ sampled from below over the region"
    else:
        gam = float(gamma)
        if not (np.isfinite(gam) and gam >= 0):
            raise PreconditionError(f"{caller}: `lipschitz` must be a non-negative number, got {gamma}")
        checks.append(Check.assumed(f"φ = f - Ax is Lipschitz with the γ = {gam:g} given", "stated by the user; not verified"))
        gamma_kind = "with the γ given"
    if K is not None:
        Km = check_matrix(K, n, p, "L", caller)
        margin, P = thau_margin(Am, C, Km)
        if margin == 0.0:
            ev = np.linalg.eigvals(Am - Km @ C)
            raise PreconditionError(f"{caller}: the given L does not make A - LC Hurwitz (eigenvalue "
                                    f"{complex(ev[np.argmax(ev.real)]):.4g}); choose another K or omit it to search")
        how = "given gain"
    else:
        margin, best, Km, search = thau_gain_search(Am, C, gam)
        _, P = thau_margin(Am, C, Km)
        values.update({"search": search, "best_margin": best})
        how = "Riccati-based search"
    if margin <= gam:
        raise PreconditionError(
            f"{caller}: the Thau condition eigmin(Q)/(2 eigmax(P)) > γ fails: the best margin found ({how}) is "
            f"{margin:.4g} <= γ = {gam:.4g}, with K = {np.round(Km.ravel(), 4).tolist()}. Shrink the region (smaller γ), "
            "change the A/φ split, or use a high-gain or Kalman-type observer")
    ev = np.linalg.eigvals(Am - Km @ C)
    ev = ev[np.lexsort((ev.imag, ev.real))]
    lam = np.linalg.eigvalsh(P)
    checks.append(Check("Thau condition eigmin(Q)/(2 eigmax(P)) > γ (Q = I)", True, f"{margin:.4g} > {gam:.4g}",
                        f"floating point, {gamma_kind}"))
    values.update({"K": Km, "P": P, "Q": np.eye(n), "margin": margin, "gamma": gam, "guaranteed_rate": margin - gam,
                   "overshoot": float(np.sqrt(lam.max() / lam.min())), "eigenvalues": ev})
    s = Symbols.make(system, n)
    fx, _ = compile_system(system).bind()
    dz = fx(s.t, s.z, s.u) - ca.DM(Km) @ (ca.DM(C) @ s.z - s.y)
    x0 = ca.SX.sym("xhat0", n)
    cert = Certificate(f"Lipschitz (Thau) observer ({how})", REF, tuple(checks), values)
    return ObserverDesign.build("lipschitz", system, s, z_names=[f"xhat_{v}" for v in system.states], flow=dz, xhat=s.z,
                                xhat0_sym=x0, z0=x0, xhat0=np.zeros(n) if xhat0 is None else xhat0, certificate=cert)
