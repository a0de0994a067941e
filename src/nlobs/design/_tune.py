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

import numpy as np
import sympy as sp

from ._constructions import evaluate, jacobians_at
from ._kind import Tuning

__all__ = ["clean_message", "fmt", "vanishes", "poles_for", "square", "rounded", "region_states", "region_inputs",
           "domain_bounds", "gaussian_filter", "sigma_spread", "robust_filter", "TINY_R", "CA_on_run",
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


def domain_bounds(ctx: Any) -> dict[str, list[float | None]]:
    """Bounds where the model's own domain needs them: a state under a square root (or another fractional power), in a denominator
    or a logarithm, which keeps its sign along the run, is kept on that side of 0 (tank levels ≥ 0)."""
    if ctx.nominal is None:
        return {}
    f, h = ctx.system.substituted()
    args = [a for e in (*f, *h) for a in e.atoms(sp.Pow, sp.log)
            if isinstance(a, sp.log) or (isinstance(a, sp.Pow) and (not a.exp.is_integer or a.exp.is_negative))]
    out: dict[str, list[float | None]] = {}
    for i, (name, sym) in enumerate(zip(ctx.system.states, ctx.system.x)):
        if not any(sym in a.args[0].free_symbols for a in args):
            continue
        col = ctx.nominal.x[:, i]
        edge = float(f"{1e-3 * float(np.min(np.abs(col))):.3g}")   # just inside the domain: √ has an infinite slope at 0
        if np.all(col > 0):
            out[name] = [edge, None]
        elif np.all(col < 0):
            out[name] = [None, -edge]
    return out


def gaussian_filter(ctx: Any, kind: str) -> Tuning:
    opts: dict[str, Any] = {"Q": square(ctx.Q), "R": square(ctx.R), "P0": square(ctx.P0)}
    if kind == "ekf":
        opts["mode"] = "continuous-discrete"
    bounds = domain_bounds(ctx) if not ctx.system.is_discrete else {}
    if bounds:
        opts["bounds"] = bounds
    spread = ""
    if kind == "ukf" and ctx.region:
        # sigma points at x̂ ± α·√n·σ_i: keep them within half the visited box's width around x̂ (alpha <= 1)
        width = np.array([ctx.region[s][1] - ctx.region[s][0] for s in ctx.system.states])
        sd = np.sqrt(np.diag(ctx.P0))
        alpha = float(min(1.0, np.min(0.5 * width / (np.sqrt(ctx.system.n_states) * np.maximum(sd, 1e-300)))))
        if alpha < 1.0:
            alpha = float(f"{max(alpha, 1e-3):.3g}")
            opts.update({"alpha": alpha, "beta": 2.0})
            spread = f"; sigma points within half the visited box (α = {alpha:g}, β = 2)"
    local = "locally observable (generic rank condition)" if ctx.report.observable else "observability not established"
    extra = (f"bounds {', '.join(f'{k} ≥ {v[0]:g}' if v[0] is not None else f'{k} ≤ {v[1]:g}' for k, v in bounds.items())} "
             "(just inside the domain of the model's square roots, logarithms and denominators)") if bounds else ""
    return Tuning.tuned(opts, f"{local}; {ctx.noise_note}; P(0) = diag(σ₀²) with σ₀ the offset of x̂(0) (at least 10 % of the "
                    f"state's range on the run){spread}. A local method: it converges from an x̂(0) close enough, with no "
                    "global certificate", extra=extra)


def sigma_spread(ctx: Any) -> tuple[dict[str, float], str]:
    """α keeping the sigma points within half the visited box around x̂ (as for the UKF)."""
    if not ctx.region:
        return {}, ""
    width = np.array([ctx.region[s][1] - ctx.region[s][0] for s in ctx.system.states])
    sd = np.sqrt(np.diag(ctx.P0))
    alpha = float(min(1.0, np.min(0.5 * width / (np.sqrt(ctx.system.n_states) * np.maximum(sd, 1e-300)))))
    if alpha >= 1.0:
        return {}, ""
    alpha = float(f"{max(alpha, 1e-3):.3g}")
    beta = float(f"{max(2.0, (1 / alpha - alpha) ** 2):.6g}")  # W0 of the covariance ≥ 0: β ≥ (1/α − α)²
    return {"alpha": alpha, "beta": beta}, f"; sigma points within half the visited box (α = {alpha:g}, β = {beta:g})"


#: Below this ratio λmin(R)/λmax(P(0)) the advisor marks the square-root UKF as the choice: P − KSKᵀ keeps
#: only −log10(ratio) of the 16 digits of P, and its rounding (about 1e-16·‖P‖) reaches the smallest eigenvalue
TINY_R = 1e-8


def robust_filter(ctx: Any, kind: str) -> Tuning:
    """Square-root UKF/EKF and the iterated EKF: the tuning of the EKF/UKF (Q, R, P0 from the run)."""
    opts: dict[str, Any] = {"Q": square(ctx.Q), "R": square(ctx.R), "P0": square(ctx.P0)}
    spread = ""
    if kind == "srukf":
        extra_opts, spread = sigma_spread(ctx)
        opts.update(extra_opts)
    local = "locally observable (generic rank condition)" if ctx.report.observable else "observability not established"
    use = {"srukf": "the UKF carrying a Cholesky factor (QR updates, no Cholesky factorisation or downdate): for a tiny R or an "
                    "ill-conditioned P, where the UKF's P loses definiteness",
           "srekf": "the EKF carrying a square root of P (QR Joseph update): for a tiny R or an ill-conditioned P",
           "iekf": "Gauss-Newton iterations of the EKF's update: for a strongly nonlinear output (ranges, angles, squares), "
                   "where one linearisation at x̂⁻ overshoots"}[kind]
    extra = choice = ""
    ratio = float(np.linalg.eigvalsh(np.atleast_2d(ctx.R)).min() / np.linalg.eigvalsh(np.atleast_2d(ctx.P0)).max())
    if kind in ("srukf", "srekf") and ratio < TINY_R:
        extra = (f"R is {ratio:.1g} of the largest prior variance (below {TINY_R:g}): the covariance forms' P − KSKᵀ then "
                 "loses definiteness in floating point and their Cholesky factorisation fails; the square-root form is the "
                 "choice here")
        if kind == "srukf":
            choice = f"R is {ratio:.1g} of the prior variance: the square-root UKF (kind 'srukf') is the choice"
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

