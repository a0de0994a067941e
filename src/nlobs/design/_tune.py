r"""What the automatic tunings of several kinds share (see each design module's ``tune_<kind>``).

A tuning reads the advisor's context (:class:`~nlobs.design._kind.TuningContext`: the system, its nominal run, the
visited region, Q/R/P0 from the run's scales, the observer's target rate ω_o) and returns a
:class:`~nlobs.design._kind.Tuning`: options for the design with the reasons, or why the kind does not apply, or what
it needs from the user.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ..engine import to_casadi
from ..references import cite
from ._constructions import evaluate, jacobians_at
from ._kind import Tuning

__all__ = ["clean_message", "fmt", "vanishes", "poles_for", "square", "rounded", "region_states", "region_inputs",
           "domain_bounds", "gaussian_filter", "sigma_points", "robust_filter", "TINY_R", "prior_output_ratio", "CA_on_run",
           "output_injection_form", "jacobians_on_run", "needs_only"]

_PREFIX = re.compile(r"^(design_\w+|\w+): (?=\S)")


def clean_message(e: BaseException) -> str:
    text = str(e).strip()
    for _ in range(3):
        m = _PREFIX.match(text)
        if not m:
            break
        text = text[m.end():]
    return text


def fmt(v: Any) -> str:
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(fmt(x) for x in v) + "]"
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.3g}"
    return str(v)


def vanishes(lo: float, hi: float) -> str:
    """How a quantity that must stay away from 0 fails to, over its range [lo, hi] on the run."""
    if lo == 0.0 and hi == 0.0:
        return "is identically 0"
    return "changes sign" if lo * hi <= 0 else "comes close to 0"


def poles_for(n: int, omega: float) -> list[float]:
    return [round(-omega * (1 + 0.25 * k), 6) for k in range(n)]


def square(M: np.ndarray) -> list[list[float]]:
    return [[float(v) for v in row] for row in np.asarray(M, dtype=float)]


def rounded(M: Any) -> Any:
    return np.round(np.asarray(M, dtype=float), 12).tolist()


def region_states(ctx: Any) -> dict[str, tuple[float, float]] | None:
    if not ctx.region:
        return None
    return {s: ctx.region[s] for s in ctx.system.states}


def region_inputs(ctx: Any) -> dict[str, tuple[float, float]]:
    return {k: ctx.region[k] for k in ctx.system.inputs if k in ctx.region}


def _singular_bases(e: sp.Expr) -> list[sp.Expr]:
    """The expressions whose zero (or sign change) leaves the domain of `e`: the base of a fractional or negative power,
    a logarithm's argument, the cosine under tan and sec, the sine under cot and csc."""
    out = []
    for a in e.atoms(sp.Pow, sp.log, sp.tan, sp.cot, sp.sec, sp.csc):
        if isinstance(a, sp.log):
            out.append(a.args[0])
        elif isinstance(a, sp.Pow):
            if not a.exp.is_integer or a.exp.is_negative:
                out.append(a.base)
        elif isinstance(a, (sp.tan, sp.sec)):
            out.append(sp.cos(a.args[0]))
        else:
            out.append(sp.sin(a.args[0]))
    return out


def _vectorised(expr: sp.Expr, sym: sp.Symbol) -> Callable[[np.ndarray], np.ndarray]:
    """`expr` of the one symbol `sym` as a NumPy-vectorised function, through CasADi (never lambdify: nothing from a
    model file is evaluated as Python)."""
    x = ca.SX.sym("x")
    fn = ca.Function("g", [x], [to_casadi([expr], {sym: x})])

    def g(v: np.ndarray) -> np.ndarray:
        v = np.atleast_1d(np.asarray(v, dtype=float))
        return np.asarray(fn.map(v.size)(v.reshape(1, -1)), dtype=float).reshape(v.shape)
    return g


def _keep_away(g: Any, lo: float, hi: float, floor: float, sign: float, x_hat: float) -> tuple[float | None, float | None]:
    """The interval around the run's range [lo, hi] of one state on which g keeps `sign` and |g| ≥ `floor`: scanned
    outward in steps of 1 % of the range, up to 20 ranges (None: no bound on that side within it). None, None when
    x̂(0) is not inside it (the design would refuse its start)."""
    width = max(hi - lo, 1e-3 * max(1.0, abs(lo), abs(hi)))
    steps = np.arange(1, 2001) * 0.01 * width
    ends: list[float | None] = []
    for xs in (lo - steps, hi + steps):
        with np.errstate(all="ignore"):
            v = np.asarray(g(xs), dtype=float) * sign * np.ones_like(xs)
        bad = np.flatnonzero(~(v >= floor))
        if not bad.size:
            ends.append(None)
            continue
        k = int(bad[0])
        if k == 0:
            return None, None
        good, out = float(xs[k - 1]), float(xs[k])
        for _ in range(40):          # bisect the step in which g leaves: the edge to round-off
            mid = 0.5 * (good + out)
            with np.errstate(all="ignore"):
                ok = float(np.asarray(g(np.array([mid])), dtype=float).ravel()[0]) * sign >= floor
            good, out = (mid, out) if ok else (good, mid)
        ends.append(good)
    lo_b, hi_b = ends
    if (lo_b is not None and x_hat < lo_b) or (hi_b is not None and x_hat > hi_b):
        return None, None
    return lo_b, hi_b


def _inward(v: float, direction: float) -> float:
    """v to 4 significant digits, rounded towards `direction` (+1 up, −1 down): a bound printed shorter stays inside."""
    if v == 0:
        return 0.0
    q = 10.0 ** (np.floor(np.log10(abs(v))) - 3)
    return float(f"{(np.ceil(v / q) if direction > 0 else np.floor(v / q)) * q:.4g}")


def domain_bounds(ctx: Any) -> dict[str, list[float | None]]:
    """Bounds where the model's own domain needs them.

    - A state under a square root (or another fractional power), in a denominator or a logarithm, which keeps its
      sign along the run, is kept on that side of 0 (tank levels ≥ 0).
    - A state that changes sign on the run but enters such a term alone, g(x_i) (cos θ under a quadrotor's
      ψ' = …/cos θ, or under tan θ), where g keeps its sign along the run, is kept where g keeps that sign and at least
      half its smallest size on the run: |θ| ≤ 1.52 when the run reaches θ = 1.47 (cos θ ≥ 0.05). Sigma points and
      integration stages beyond would see 1/cos θ → ∞: the filter's covariance then grows at rates no step resolves.
    """
    if ctx.nominal is None:
        return {}
    f, h = ctx.system.substituted()
    bases = [b for e in (*f, *h) for b in _singular_bases(e)]
    out: dict[str, list[float | None]] = {}
    xhat0 = np.asarray(getattr(ctx, "xhat0", ctx.nominal.x[0]), dtype=float)
    for i, (name, sym) in enumerate(zip(ctx.system.states, ctx.system.x)):
        mine = [b for b in bases if sym in b.free_symbols]
        if not mine:
            continue
        col = ctx.nominal.x[:, i]
        edge = float(f"{1e-3 * float(np.min(np.abs(col))):.3g}")   # just inside the domain: √ has an infinite slope at 0
        if np.all(col > 0):
            out[name] = [edge, None]
            continue
        if np.all(col < 0):
            out[name] = [None, -edge]
            continue
        lo, hi = float(np.min(col)), float(np.max(col))
        lo_b, hi_b = -np.inf, np.inf
        for b in mine:
            if b.free_symbols != {sym}:
                continue
            g = _vectorised(b, sym)
            with np.errstate(all="ignore"):
                v = np.asarray(g(col), dtype=float) * np.ones_like(col)
            if not (np.all(v > 0) or np.all(v < 0)):
                continue
            sign = 1.0 if v[0] > 0 else -1.0
            a, z = _keep_away(g, lo, hi, 0.5 * float(np.min(np.abs(v))), sign, float(xhat0[i]))
            lo_b = max(lo_b, a) if a is not None else lo_b
            hi_b = min(hi_b, z) if z is not None else hi_b
        if np.isfinite(lo_b) or np.isfinite(hi_b):
            out[name] = [_inward(lo_b, 1.0) if np.isfinite(lo_b) else None, _inward(hi_b, -1.0) if np.isfinite(hi_b) else None]
    return out


def gaussian_filter(ctx: Any, kind: str) -> Tuning:
    opts: dict[str, Any] = {"Q": square(ctx.Q), "R": square(ctx.R), "P0": square(ctx.P0)}
    if kind == "ekf" and not ctx.system.is_discrete:   # a map's EKF is the discrete-time filter: no mode
        opts["mode"] = "continuous-discrete"
    bounds = domain_bounds(ctx) if not ctx.system.is_discrete else {}
    if bounds:
        opts["bounds"] = bounds
    spread = ""
    if kind == "ukf":
        extra_opts, spread = sigma_points(ctx)
        opts.update(extra_opts)
    local = "locally observable (generic rank condition)" if ctx.report.observable else "observability not established"
    extra = ("bounds " + ", ".join(f"{k} ≥ {v[0]:g}" if v[1] is None else f"{k} ≤ {v[1]:g}" if v[0] is None else
                                   f"{v[0]:g} ≤ {k} ≤ {v[1]:g}" for k, v in bounds.items())
             + " (inside the domain of the model's square roots, logarithms and denominators)") if bounds else ""
    return Tuning.tuned(opts, f"{local}; {ctx.noise_note}; P(0) = diag(σ₀²) with σ₀ the offset of x̂(0) (at least 10 % of the "
                    f"state's local scale ℓ){spread}. A local method: it converges from an x̂(0) close enough, with no "
                    "global certificate", extra=extra)


def sigma_points(ctx: Any) -> tuple[dict[str, float], str]:
    r"""α, β, κ of the UKF's and the square-root UKF's 2n + 1 sigma points :math:`\hat x,\ \hat x \pm \sqrt{c}\,L_i`
    (:math:`c = n + \lambda = \alpha^2(n + \kappa)`, :func:`~nlobs.design.kalman._ukf.unscented_weights`), and the sentence
    that says why.

    - **Spread.** Julier & Uhlmann (2004)'s central weight W₀ = 1 − n/3 for a Gaussian prior (κ = 3 − n) matches some of
      its fourth moments; then c = 3 and the points sit at √3 σ whatever n. With κ = 0 (the cubature rule of Arasaratnam & Haykin
      (2009), the designs' default) they sit at √n σ: 3.6σ at n = 13, 4.9σ at n = 24, beyond where a model with a
      singularity (a quadrotor's ψ' = …/cos θ) or a periodic term (sin φ over a ±10 rad spread) is what the filter
      linearises. So κ = 3 − n for n > 3, κ = 0 (c = n ≤ 3) otherwise.
    - **Weights.** With c = 3 < n the central mean weight λ/c = 1 − n/3 is negative (the mean keeps its
      second-order correction). β is set so that the central *covariance* weight
      :math:`W^c_0 = \lambda/c + 1 - \alpha^2 + \beta` is 0: every covariance weight is then 1/(2c) ≥ 0, the
      covariance sums are sums of squares (the square-root form needs this), and
      :math:`P^+ = P - C_{xy}S^{-1}C_{xy}^\top` stays positive semidefinite: with
      :math:`\sum_{i\ge1}W_i(\mathcal X_i - m)(\mathcal X_i - m)^\top = P` for the points drawn from P, the joint matrix
      :math:`[[P, C_{xy}], [C_{xy}^\top, S]] = \sum_{i\ge1}W_i z_iz_i^\top + \mathrm{diag}(0, R) \succeq 0` and
      :math:`P^+` is its Schur complement.
    - **Box.** α < 1 only where the points would leave half the box the run visits around x̂ (α√c σ_i ≤ width_i/2),
      over the states that move on the run by more than it resolves (a constant's and a parameter's box is the single value the simulation
      uses, not a range the estimate may take: sizing α on it gave α ≈ 1e-3 and a central weight of −10⁶).
      β then also keeps :math:`W^c_0 \ge 0` (at least 2, Wan & van der Merwe (2000)'s choice for a Gaussian).

    The classic small α (1e-3) of Wan & van der Merwe (2000) makes the central weights 1 − 1/α² ≈ −10⁶: the mean and
    covariance are then differences of numbers 10⁶ times larger, and a continuous-discrete filter integrating them
    between samples loses them."""
    n = ctx.system.n_states
    kappa = 3.0 - n if n > 3 else 0.0
    c1 = n + kappa                                    # c at α = 1
    alpha = 1.0
    if ctx.region and getattr(ctx, "nominal", None) is not None:
        x = ctx.nominal.x
        moving = (x.max(axis=0) - x.min(axis=0)) > 1e-12 * np.maximum(np.abs(x).max(axis=0), 1.0)
        n_plant = len(ctx.system.states) - len(getattr(ctx.system, "estimated_params", ()) or ())
        moving[n_plant:] = False
        moving[list(getattr(ctx, "quiet", ()))] = False   # moves by less than the run resolves (a flat road's height)
        if np.any(moving):
            width = np.array([ctx.region[s][1] - ctx.region[s][0] for s in ctx.system.states])
            sd = np.sqrt(np.diag(ctx.P0))
            ratio = 0.5 * width[moving] / (np.sqrt(c1) * np.maximum(sd[moving], 1e-300))
            alpha = float(min(1.0, np.min(ratio)))
            if alpha < 1.0:
                alpha = float(f"{max(alpha, 1e-3):.3g}")
    lam = alpha ** 2 * (n + kappa) - n
    c = n + lam
    beta = max(2.0 if alpha < 1.0 else 0.0, -(lam / c + 1.0 - alpha ** 2))   # W0c = λ/c + 1 − α² + β ≥ 0
    opts: dict[str, float] = {}
    why = []
    if kappa != 0.0:
        opts["kappa"] = kappa
        why.append(f"κ = 3 − n = {kappa:g} ({cite('julier2004')}: the sigma points at √3 σ, not √n σ = {np.sqrt(n):.2g} σ)")
    if alpha < 1.0:
        opts["alpha"] = alpha
        why.append(f"sigma points within half the visited box (α = {alpha:g})")
    if beta != 0.0:
        opts["beta"] = beta
        w0 = lam / c + 1.0 - alpha ** 2 + beta
        why.append(f"β = {beta:.4g}: central covariance weight {0.0 if abs(w0) < 1e-12 else w0:.3g} ≥ 0, so P stays a sum "
                   "of squares")
    return opts, ("; " + "; ".join(why)) if why else ""


#: Below this ratio R_kk / (H P(0) Hᵀ)_kk (some output's noise variance against the prior variance of that output) the
#: advisor marks the square-root UKF as the choice: the update P − KSKᵀ removes all but about that fraction of the prior
#: variance along the measured direction, so its result keeps only −log10(ratio) of the 16 digits of P, and its
#: rounding (about 1e-16·‖P‖) reaches the smallest eigenvalue
TINY_R = 1e-8


def prior_output_ratio(ctx: Any) -> tuple[float, str]:
    """min over outputs k of R_kk / max (H P(0) Hᵀ)_kk, H = ∂h/∂x along the run (at x̂(0) without one), and the output.

    Both are variances of the same output, in its units: how much of its prior variance one sample leaves. (The ratio
    of λmin(R) to λmax(P(0)) mixed units: a gyro's 1e-4 (rad/s)² against a position's 3e5 m² read as a tiny R.)"""
    R = np.atleast_2d(np.asarray(ctx.R, dtype=float))
    P0 = np.atleast_2d(np.asarray(ctx.P0, dtype=float))
    if getattr(ctx, "nominal", None) is not None:
        pts = ctx.samples(50)
        H = jacobians_at(ctx.system, pts["t"], pts["x"], pts["u"])[1]
    else:
        x = np.asarray(ctx.xhat0, dtype=float).reshape(1, -1)
        H = jacobians_at(ctx.system, np.zeros(1), x, np.zeros((1, ctx.system.n_inputs)))[1]
    H = H[np.all(np.isfinite(H), axis=(1, 2))]
    if not len(H):
        return np.inf, ""
    prior = np.max(np.einsum("kpi,ij,kpj->kp", H, P0, H), axis=0)     # (H P0 Hᵀ)_pp, largest along the run
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(prior > 0, np.diag(R) / prior, np.inf)
    k = int(np.argmin(r))
    return float(r[k]), ctx.system.outputs[k]


def robust_filter(ctx: Any, kind: str) -> Tuning:
    """Square-root UKF/EKF and the iterated EKF: the tuning of the EKF/UKF (Q, R, P0 from the run)."""
    opts: dict[str, Any] = {"Q": square(ctx.Q), "R": square(ctx.R), "P0": square(ctx.P0)}
    spread = ""
    if kind == "srukf":
        extra_opts, spread = sigma_points(ctx)
        opts.update(extra_opts)
        bounds = domain_bounds(ctx) if not ctx.system.is_discrete else {}   # the map filters take no bounds yet
        if bounds:
            opts["bounds"] = bounds
            spread += ("; bounds " + ", ".join(f"{k} in [{'-inf' if v[0] is None else f'{v[0]:g}'}, "
                                              f"{'inf' if v[1] is None else f'{v[1]:g}'}]" for k, v in bounds.items())
                       + " (the model evaluated at the sigma points clipped to where its square roots, logarithms and "
                       "denominators are defined and away from 0)")
    local = "locally observable (generic rank condition)" if ctx.report.observable else "observability not established"
    use = {"srukf": "the UKF carrying a Cholesky factor (QR updates, no Cholesky factorisation or downdate): for a tiny R or an "
                    "ill-conditioned P, where the UKF's P loses definiteness",
           "srekf": "the EKF carrying a square root of P (QR Joseph update): for a tiny R or an ill-conditioned P",
           "iekf": "Gauss-Newton iterations of the EKF's update: for a strongly nonlinear output (ranges, angles, squares), "
                   "where one linearisation at x̂⁻ overshoots"}[kind]
    extra = choice = ""
    ratio, out = prior_output_ratio(ctx) if kind in ("srukf", "srekf") else (np.inf, "")
    if ratio < TINY_R:
        extra = (f"R of {out} is {ratio:.1g} of its prior variance (H P(0) Hᵀ; below {TINY_R:g}): the covariance forms' "
                 "P − KSKᵀ then loses definiteness in floating point and their Cholesky factorisation fails; the square-root "
                 "form is the choice here")
        if kind == "srukf":
            choice = (f"R of {out} is {ratio:.1g} of its prior variance: the square-root UKF (kind 'srukf') is the choice")
    return Tuning.tuned(opts, f"{local}; {ctx.noise_note}; P(0) = diag(σ₀²) with σ₀ the offset of x̂(0){spread}; {use}. "
                        "A local method: it converges from an x̂(0) close enough, with no global certificate", extra=extra,
                        choice=choice, choice_reason=extra if choice else "", choice_rank=1)


def CA_on_run(ctx: Any, CA: sp.Matrix) -> np.ndarray:
    """C A(u, y, t) at points of the run, shape (k, p, n) (how the unmeasured states reach the output's derivative);
    one matrix when constant, none (shape (0, p, n)) without a run."""
    p, n = CA.shape
    if not CA.free_symbols:
        return np.array(CA, dtype=float).reshape(1, p, n)
    if ctx.nominal is None:
        return np.zeros((0, p, n))
    vals = evaluate(list(CA.T), ctx.system, ctx.samples(300)).reshape(-1, n, p).transpose(0, 2, 1)
    return vals[np.all(np.isfinite(vals), axis=(1, 2))]


def output_injection_form(ctx: Any) -> str:
    holds, why = ctx.form("output injection")
    return "" if holds else why


def jacobians_on_run(ctx: Any) -> np.ndarray | None:
    """∂f/∂x at (up to) 300 points of the nominal run, the non-finite ones dropped; None without a run."""
    if ctx.nominal is None:
        return None
    pts = ctx.samples(300)
    F = jacobians_at(ctx.system, pts["t"], pts["x"], pts["u"])[0]
    F = F[np.all(np.isfinite(F), axis=(1, 2))]
    return F if len(F) else None


def needs_only(what: str, **opts: Any) -> Callable[[Any], Tuning]:
    """The tuning of a kind whose design needs what only the user can give (`what`; `opts` shows the keys)."""
    def tune(ctx: Any) -> Tuning:
        return Tuning.needs(what, **opts)

    return tune

