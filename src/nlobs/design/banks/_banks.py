"""Banks' exponential observer (Banks (1980)): x̂' = f(x̂) + P·(B(x̂) - y), conditions checked with the matrix measure.

The matrix measure and the supremum over a box come from ``nlobs.analysis``
(:func:`~nlobs.analysis.matrix_measure`, :func:`~nlobs.analysis.banks_condition` for the stand-alone
check); :func:`banks_conditions` evaluates them for this design's model and gain.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ..._text import shorten
from ...engine import compile_system, to_casadi
from ...errors import PreconditionError, ShapeError
from ...model import TIME, System, symbol
from ...model._system import ExprLike, exact, to_expr
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign, Symbols
from .._checks import check_matrix
from .._common import batch, box_of, require_system, sup_over_box
from .._constructions import banks_gain, banks_necessary
from .._kind import Tuning, kind, renamed
from .._tune import region_inputs, region_states, rounded

__all__ = ["design_banks", "banks_conditions", "BanksConditions"]

REF = (f"{cite('003')}: Lemma 2.3 (λ(A + PB) <= -ε, f1 dissipative), Lemma 2.4 (μ_f1 <= δ < ε), "
       "Theorem 2.6 (λ(Df1(x) + P·DB(x)) <= -ε on convex Ω, f2 Lipschitz K < ε: rate ε - K); "
       "observer x̂' = f(x̂) + P·(ŷ - y) (the example's 'P(x1 + x2)' is a typo, see Lemma 2.3's proof)")


@dataclass(frozen=True)
class BanksConditions:
    """What :func:`banks_conditions` found.

    Attributes
    ----------
    epsilon : float
        -sup λ(Df1(x) + P·DB(x)) over the region (exact when the matrix is constant).
    where : dict
        Where the sup was attained.
    K : float
        Lipschitz constant of the perturbation f2 (given or sup ‖Df2‖₂).
    slope : float
        sup λ(Df2) (the one-sided "maximum slope" μ of Lemma 2.4), <= K (= K when K is given).
    exact : bool
        Whether ε was computed exactly (constant matrix) rather than over a grid.
    """

    epsilon: float
    where: dict[str, float]
    K: float
    slope: float
    exact: bool

    @property
    def rate(self) -> float:
        """The guaranteed rate ε - K (Theorem 2.6)."""
        return self.epsilon - self.K


def _exact(M: np.ndarray) -> sp.Matrix:
    return sp.Matrix(M.shape[0], M.shape[1], [exact(v) for v in np.asarray(M, dtype=float).ravel()])


def _free_names(system: System, exprs: Sequence[sp.Expr]) -> list[str]:
    free = set().union(*(e.free_symbols for e in exprs)) if exprs else set()
    table = [*zip(system.states, system.x), *zip(system.inputs, system.u), ("t", TIME)]
    return [nm for nm, sym in table if sym in free]


def banks_conditions(system: System, P: np.ndarray, perturbation: Sequence[sp.Expr], *,
                     region: Mapping[str, Sequence[float]] | None, perturbation_bound: float | None,
                     caller: str = "banks_conditions") -> BanksConditions:
    r"""Evaluate Banks' conditions for the gain P over a box.

    :math:`\varepsilon = -\sup_\Omega \lambda(Df_1(x) + P\,DB(x))` with :math:`f_1 = f - f_2`
    (the perturbation f2), and the Lipschitz constant K of f2. The sup is exact when the
    matrix does not depend on the state; otherwise it is taken over `region` (grid + local
    polish, see :func:`nlobs.analysis.box_sup`), and only the variables the
    matrices depend on need bounds.
    """
    from ...analysis import matrix_measure  # here, not at the top: a Monte Carlo worker loads no analysis
    f, h = system.substituted()
    x = sp.Matrix(system.x)
    f2 = sp.Matrix(list(perturbation))
    J = ((f - f2).jacobian(x) + _exact(P) * h.jacobian(x)).applyfunc(sp.simplify)
    D2 = f2.jacobian(x)
    names = _free_names(system, list(J) + (list(D2) if perturbation_bound is None else []))
    lookup = {**dict(zip(system.states, system.x)), **dict(zip(system.inputs, system.u)), "t": TIME}
    if names:
        sub = {k: v for k, v in (region or {}).items() if k in names}
        lo, hi = box_of(system, sub if region is not None else None, names, caller)
    pt = ca.SX.sym("pt", max(len(names), 1))
    leaves = {lookup[nm]: pt[i] for i, nm in enumerate(names)}

    def fn(M: sp.Matrix) -> ca.Function:
        return ca.Function("M", [pt], [ca.reshape(to_casadi(list(M.T), leaves), M.shape[0], M.shape[1])])

    Jf = fn(J)
    Df = fn(D2) if perturbation_bound is None else None
    exact_ = not (J.free_symbols & set(lookup.values()))
    if exact_:
        lam = float(matrix_measure(np.array(J, dtype=float)))
        where: dict[str, float] = {}
    else:
        lam, arg = sup_over_box(lambda Q: matrix_measure(batch(Jf, Q)), lo, hi)
        where = dict(zip(names, np.round(arg, 6).tolist()))
    if perturbation_bound is not None:
        K = slope = float(perturbation_bound)
    elif D2.free_symbols & set(lookup.values()):   # Df2 varies (a linear f2 has a constant Df2: exact)
        K, _ = sup_over_box(lambda Q: np.linalg.norm(batch(Df, Q), 2, axis=(1, 2)), lo, hi)
        slope, _ = sup_over_box(lambda Q: matrix_measure(batch(Df, Q)), lo, hi)
    else:
        D2n = np.array(D2, dtype=float)
        K, slope = float(np.linalg.norm(D2n, 2)), float(matrix_measure(D2n))
    return BanksConditions(-lam, where, K, slope, exact_)


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def tune_banks(ctx: Any) -> Tuning:
    if not ctx.region or ctx.nominal is None:
        return Tuning.needs("P (n × p) and a region Ω: add [simulation] x0 so that nlobs can search P over the visited region")
    box = region_states(ctx)
    pts = ctx.samples(100)
    rng = np.random.default_rng(0)
    lo = np.array([box[s][0] for s in ctx.system.states])
    hi = np.array([box[s][1] for s in ctx.system.states])
    rand = lo + (hi - lo) * rng.random((100, ctx.n))
    ulo = np.array([ctx.region[k][0] for k in ctx.system.inputs]) if ctx.system.inputs else np.zeros(0)
    uhi = np.array([ctx.region[k][1] for k in ctx.system.inputs]) if ctx.system.inputs else np.zeros(0)
    urand = ulo + (uhi - ulo) * rng.random((100, ctx.system.n_inputs))
    X = np.vstack([pts["x"], rand])
    U = np.vstack([pts["u"], urand]) if ctx.system.inputs else np.zeros((X.shape[0], 0))
    T = np.concatenate([pts["t"], rng.random(100) * (ctx.scenario.t_final if ctx.scenario else 1.0)])
    blocked = banks_necessary(ctx.system, X, U, T)
    if blocked:
        return Tuning.fails(blocked)
    P, best, _ = banks_gain(ctx.system, X, U, T, limit=ctx.step_limit())
    if P is None or not np.isfinite(best):
        return Tuning.fails("the Jacobians are not finite on the region")
    if best >= 0:
        return Tuning.fails(f"no gain P found with λ(∂f/∂x + P ∂h/∂x) < 0 on the visited region: the best max matrix measure is "
                      f"{best:.3g} ≥ 0 ({cite('003', 'Theorem 2.6')} needs it negative everywhere on Ω, a much stronger "
                      "condition than a stable linearisation)", L=rounded(P))
    speed = float(np.linalg.norm(P, 2)) * ctx.output_gain
    if speed > ctx.step_limit():
        return Tuning.fails(f"a gain with λ(∂f/∂x + P ∂h/∂x) < 0 on the region needs ‖P‖·‖∂h/∂x‖ ≈ {speed:.3g} {ctx.rate_unit}, beyond what the "
                      f"step allows ({ctx.step_limit():.3g} {ctx.rate_unit}); reduce dt / the sample period, or shrink the region", L=rounded(P))
    region = {k: list(v) for k, v in {**box, **region_inputs(ctx)}.items()}
    if ctx.system.is_time_varying:
        region["t"] = [0.0, float(ctx.scenario.t_final)]
    return Tuning.tuned({"L": rounded(P), "region": region},
                    f"P searched over the visited region (max matrix measure {best:.3g} on the sampled points)")


@kind('banks', summary="Banks' exponential observer, his conditions checked over a region",
      references=(work("003", "Theorem 2.6"),), tune=tune_banks)
@renamed(P="L")
def design_banks(system: System, *, L: Any, region: Mapping[str, Sequence[float]] | None = None,
                 perturbation: Sequence[ExprLike] | None = None, perturbation_bound: float | None = None,
                 xhat0: Any = None) -> ObserverDesign:
    r"""Banks' exponential observer (Banks (1980)) with his conditions checked over a region.

    For :math:`\dot x = f(x, t) = f_1(x, t) + f_2(x, t)`, :math:`y = B(x)`:

    .. math::

        \dot{\hat x} = f(\hat x, t) + P\,(B(\hat x) - y), \qquad
        \lambda\big(Df_1(x) + P\,DB(x)\big) \le -\varepsilon \;\; \forall x \in \Omega, \qquad
        \|f_2(x) - f_2(z)\| \le K\|x - z\|, \; K < \varepsilon ,

    where :math:`\lambda(M) = \max\operatorname{eig}((M + M^\top)/2)` is the matrix measure.
    Then (Theorem 2.6) :math:`\|\hat x(t) - x(t)\| \le \|\hat x(0) - x(0)\|\,e^{-(\varepsilon - K)t}`
    while x and x̂ stay in the convex Ω. With B linear and f1 = Ax + (a dissipative or
    slope-bounded part) this contains Lemmas 2.3 and 2.4: the slope of the nonlinear part is
    then inside λ(Df1 + PB).

    The sign convention is the paper's: β = P·(B x̂ - B x) (Lemma 2.3's proof); example 3.1
    prints the injection as "P(x1 + x2)", a typo for P·(ŷ - y) (see the papers' README).

    Parameters
    ----------
    system : System
    L : array_like of shape (n, p)
        The gain, P in Banks (1980) (example 3.1: P = (-2, 1)ᵀ; example 3.2: (-1, 4)ᵀ).
    region : mapping of name to (lo, hi), optional
        The convex box Ω for the state variables (and inputs, t) the conditions depend on;
        not needed when λ(Df1 + P DB) and Df2 are constant.
    perturbation : sequence of expressions, optional
        f2, the part of f treated as a Lipschitz perturbation (default zero).
    perturbation_bound : float, optional
        K, the Lipschitz constant of f2; estimated over `region` when omitted.

    Other Parameters
    ----------------
    xhat0 : array_like of shape (n,), optional

    Returns
    -------
    ObserverDesign
        Certificate values: ``P``, ``epsilon``, ``K``, ``slope`` (sup λ(Df2)),
        ``guaranteed_rate`` ε - K, ``jacobian`` (Df1 + P DB, symbolic).

    Raises
    ------
    PreconditionError
        If λ(Df1 + P DB) is not negative on Ω (with the point), or K >= ε.

    References
    ----------
    Banks (1980), Lemmas 2.3, 2.4, Theorem 2.6, examples 3.1 and 3.2.
    """
    P = L  # Banks (1980)'s name for the gain
    require_system(system, "design_banks")
    caller = "design_banks"
    n, p = system.n_states, system.n_outputs
    Pm = check_matrix(P, n, p, "L", caller)
    allowed = {k: symbol(k) for k in (*system.states, *system.inputs, *system.params)}
    allowed["t"] = TIME
    params = {symbol(k): exact(v) for k, v in system.params.items()}
    if isinstance(perturbation, (str, sp.Basic)):
        raise ShapeError(f"{caller}: `perturbation` must be a list of {n} expressions, one per state "
                         f"({', '.join(system.states)}), e.g. {['0'] * (n - 1) + ['0.1*sin(x)']}; got the single "
                         f"{'string' if isinstance(perturbation, str) else 'expression'} {shorten(str(perturbation), 40)}")
    if perturbation is None:
        f2 = [sp.S.Zero] * n
    else:
        f2 = [to_expr(e, allowed, where=f"perturbation[{i}]").xreplace(params) for i, e in enumerate(perturbation)]
        if len(f2) != n:
            raise ShapeError(f"{caller}: `perturbation` needs {n} expressions (one per state), got {len(f2)}")
    if perturbation_bound is not None and not (np.isfinite(perturbation_bound) and perturbation_bound >= 0):
        raise PreconditionError(f"{caller}: `perturbation_bound` must be a non-negative number, got {perturbation_bound}")
    cond = banks_conditions(system, Pm, f2, region=region, perturbation_bound=perturbation_bound, caller=caller)
    at = f" at {cond.where}" if cond.where else ""
    if cond.epsilon <= 0:
        raise PreconditionError(f"{caller}: λ(Df1 + P·DB) = {-cond.epsilon:.4g} >= 0{at}: the condition λ(Df1(x) + P·DB(x)) <= -ε < 0 "
                                f"of {cite('003')} Theorem 2.6 fails on the region; choose another P or a smaller region")
    if cond.K >= cond.epsilon:
        raise PreconditionError(f"{caller}: the perturbation's Lipschitz constant K = {cond.K:.4g} is not below ε = {cond.epsilon:.4g} "
                                f"({cite('003')} Theorem 2.6 needs K < ε); reduce the perturbation or find a P with larger ε")
    f, h = system.substituted()
    J = ((f - sp.Matrix(f2)).jacobian(sp.Matrix(system.x)) + _exact(Pm) * h.jacobian(sp.Matrix(system.x))).applyfunc(sp.simplify)
    how = "exact (constant matrix)" if cond.exact else "sup over the region (grid + local polish)"
    sampled = "sampled over Ω (random points, corners, centre, L-BFGS-B): the supremum is estimated from below, not proved"
    checks = [Check(f"λ(Df1(x) + P·DB(x)) <= -ε < 0 on Ω ({cite('003')} Lemma 2.3 / Theorem 2.6)", True, f"ε = {cond.epsilon:.6g}, {how}{at}",
                    "exact (constant matrix)" if cond.exact else sampled),
              Check(f"perturbation Lipschitz K < ε ({cite('003')} Theorem 2.6; Lemma 2.4 with slope μ <= K)", True,
                    f"K = {cond.K:.4g}" + (" (given)" if perturbation_bound is not None else " (sup ‖Df2‖₂ over Ω)")
                    + f", slope μ = {cond.slope:.4g}",
                    "K as given, compared exactly" if perturbation_bound is not None else
                    ("exact (f2 linear)" if not any(e.free_symbols & set(system.x) for e in sp.Matrix(f2).jacobian(sp.Matrix(system.x)))
                     else sampled))]
    if perturbation_bound is not None:
        checks.append(Check.assumed(f"the perturbation f2 is Lipschitz with the constant K = {cond.K:.4g} given",
                                    "stated by the user (perturbation_bound); not verified"))
    if region is not None:
        checks.append(Check.assumed("x and x̂ stay in the convex region Ω", f"{cite('003')} Theorem 2.6: " +
                            ", ".join(f"{k} in [{v[0]:g}, {v[1]:g}]" for k, v in region.items())))
    values = {"P": Pm, "epsilon": cond.epsilon, "K": cond.K, "slope": cond.slope, "guaranteed_rate": cond.rate,
              "jacobian": str(J.tolist()), "perturbation": [str(e) for e in f2]}
    s = Symbols.make(system, n)
    fx, hx = compile_system(system).bind()
    dz = fx(s.t, s.z, s.u) + ca.DM(Pm) @ (hx(s.t, s.z, s.u) - s.y)
    x0 = ca.SX.sym("xhat0", n)
    cert = Certificate("Banks exponential observer", REF, tuple(checks), values)
    return ObserverDesign.build("banks", system, s, z_names=[f"xhat_{v}" for v in system.states], flow=dz, xhat=s.z,
                                xhat0_sym=x0, z0=x0, xhat0=np.zeros(n) if xhat0 is None else xhat0, certificate=cert)
