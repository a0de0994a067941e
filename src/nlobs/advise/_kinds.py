r"""One trial per registered observer kind: check whether it applies, tune it automatically, design it.

Each trial takes the shared :class:`~nlobs.advise._context.Context` and returns a
:class:`~nlobs.advise.Candidate`. A precondition that fails comes back with the design's own message
(the failed condition and its numbers). Kinds registered later without a trial here are listed as
"not tuned" with the options their design function takes.
"""

from __future__ import annotations

import os
import re
import time
import warnings
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import sympy as sp

from ..design import DESIGNS, ObserverDesign, design_from_config
from ..design._high_gain import triangular_chains
from ..design._kkl import MAX_FEATURES, _max_degree
from ..design._registry import options_of
from ..engine import compile_system
from ..errors import FormError, ModelError, NlobsError, PreconditionError, ShapeError, SymbolicBudgetError
from ..model._budget import symbolic_budget, symbolic_seconds
from ..model import LTI, TIME, System
from ..references import cite
from ._advice import Candidate
from ._constructions import (banks_gain, banks_necessary, cascade_partition, derivative_map, evaluate, find_chains, kkl_linear,
                             pebo_linear, text)
from ._context import Context

__all__ = ["TRIALS", "REFERENCES", "try_kind", "MHE_SAMPLE_BUDGET"]

#: The largest number of measurement updates `--run` gives a moving-horizon estimator (one NLP each).
MHE_SAMPLE_BUDGET = 200

#: Seconds of symbolic work (SymPy) one kind's trial may take in the advisor before it is reported as "not checked
#: within budget" (a design called directly keeps the larger budget of one step, NLOBS_SYMBOLIC_SECONDS); the
#: environment variable NLOBS_KIND_SECONDS overrides it.
KIND_SECONDS = 5.0


def kind_seconds() -> float:
    """The advisor's symbolic budget per kind: ``$NLOBS_KIND_SECONDS``, else :data:`KIND_SECONDS`."""
    try:
        return max(0.1, float(os.environ.get("NLOBS_KIND_SECONDS", KIND_SECONDS)))
    except ValueError:
        return KIND_SECONDS

#: The work each kind implements, as a user reads it.
REFERENCES: dict[str, str] = {
    "luenberger": f"{cite('002', 'Result [Luenberger]')}",
    "output_injection": f"{cite('002', 'Result [Error linearization]')}",
    "ekf": cite("kalman1961") + " (extended, continuous-discrete)",
    "ukf": cite("julier2004"),
    "srukf": cite("vandermerwe2001") + " (square root by QR, " + cite("arasaratnam2009") + ")",
    "srekf": cite("kaminski1971") + " (square-root covariance, QR Joseph update)",
    "iekf": cite("bell1993"),
    "pf": cite("gordon1993") + "; " + cite("pitt1999") + " (auxiliary)",
    "mhe": f"{cite('002', 'trajectory-based observers')}" + " (moving horizon)",
    "high_gain": f"{cite('002', 'Result [High Gain Observer]')}",
    "high_gain_derivatives": f"{cite('004', 'Table I (HGO with linear dynamics)')}",
    "lipschitz": cite("thau1973") + "; " + f"{cite('002', 'LTI + Lipschitz NL')}",
    "kalman_bucy": cite("kalman1961"),
    "kalman_like": f"{cite('002', 'Kalman-like observer for state-affine systems')}",
    "high_gain_kalman": f"{cite('002', 'LTV-based high-gain Kalman observer')}",
    "banks": f"{cite('003', 'Theorem 2.6')}",
    "augmented": f"{cite('001', 'Theorem 1, Lemma 1')}",
    "custom": "your own observer equations",
    "gradient": f"{cite('000', 'eq. 16a (gradient)')}",
    "least_squares": f"{cite('000', 'regression estimators')}" + " (least squares)",
    "drem": cite("aranovskiy2017"),
    "gd": f"{cite('000', 'Lemma 2')}",
    "gpebo": f"{cite('000', 'Lemma 1')}" + " with least squares",
    "gpebo_2gd": f"{cite('000', 'Proposition 1')}",
    "kkl": f"{cite('004', 'Proposition 1')}",
    "kkl_learned": cite("andrieu2006") + " (KKL with a learned inverse)",
    "pebo": f"{cite('004', 'Proposition 2')}",
    "kkl_pebo": f"{cite('004', 'Proposition 3')}",
    "kkl_pebo_cascade": f"{cite('004', 'Proposition 7')}",
    "iandi": f"{cite('004', 'Proposition 4')}",
}

_PREFIX = re.compile(r"^(design_\w+|\w+): (?=\S)")


def _clean(e: BaseException) -> str:
    text = str(e).strip()
    for _ in range(3):
        m = _PREFIX.match(text)
        if not m:
            break
        text = text[m.end():]
    return text


def _fmt(v: Any) -> str:
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.3g}"
    return str(v)


def _vanishes(lo: float, hi: float) -> str:
    """How a quantity that must stay away from 0 fails to, over its range [lo, hi] on the run."""
    if lo == 0.0 and hi == 0.0:
        return "is identically 0"
    return "changes sign" if lo * hi <= 0 else "comes close to 0"


def _poles(n: int, omega: float) -> list[float]:
    return [round(-omega * (1 + 0.25 * k), 6) for k in range(n)]


def _guarantee(d: ObserverDesign) -> str:
    checks = d.certificate.checks
    held = [c for c in checks if c.status == "holds"]
    assumed = [c for c in checks if c.status == "assumed"]
    text = f"{len(held)} certificate check(s) hold"
    if assumed:
        text += "; assumed, not verified: " + "; ".join(c.condition for c in assumed)
    return text


def _sq(M: np.ndarray) -> list[list[float]]:
    return [[float(v) for v in row] for row in np.asarray(M, dtype=float)]


class _Trial:
    """Helpers bound to one kind and context."""

    def __init__(self, ctx: Context, kind: str):
        self.ctx, self.kind = ctx, kind

    def fail(self, why: str, **options: Any) -> Candidate:
        return Candidate(self.kind, "fails", why, options, REFERENCES.get(self.kind, ""))

    def needs(self, what: str, **options: Any) -> Candidate:
        return Candidate(self.kind, "needs input", f"needs input: {what}", options, REFERENCES.get(self.kind, ""))

    def design(self, options: Mapping[str, Any], tuning: str, *, runnable: bool = True, extra: str = "") -> Candidate:
        ctx = self.ctx
        opts = dict(options)
        if "xhat0" in options_of(DESIGNS[self.kind]) and "xhat0" not in opts:
            opts["xhat0"] = [float(v) for v in ctx.xhat0]
        try:
            d = design_from_config(ctx.system, self.kind, opts)
        except (PreconditionError, FormError, ShapeError, ModelError) as e:
            return self.fail(_clean(e), **opts)
        why = f"{tuning}; {_guarantee(d)}" + (f"; {extra}" if extra else "")
        return Candidate(self.kind, "applies", why, opts, REFERENCES.get(self.kind, ""), d, runnable)


def _region_states(ctx: Context) -> dict[str, tuple[float, float]] | None:
    if not ctx.region:
        return None
    return {s: ctx.region[s] for s in ctx.system.states}


def _region_inputs(ctx: Context) -> dict[str, tuple[float, float]]:
    return {k: ctx.region[k] for k in ctx.system.inputs if k in ctx.region}


def _round(M: Any) -> Any:
    return np.round(np.asarray(M, dtype=float), 12).tolist()


# -- linear gains -------------------------------------------------------------------------------------------------
def _luenberger(ctx: Context) -> Candidate:
    t = _Trial(ctx, "luenberger")
    try:
        LTI.from_system(ctx.system)
    except FormError as e:
        return t.fail(f"not linear time-invariant: {_clean(e)}")
    poles = _poles(ctx.n, ctx.omega_o)
    return t.design({"poles": poles}, f"LTI; eig(A − LC) placed at {_fmt(poles)} (ω_o = 3 ω_p)")


def _output_injection(ctx: Context) -> Candidate:
    t = _Trial(ctx, "output_injection")
    holds, why = ctx.form("output injection")
    if not holds:
        return t.fail(why)
    poles = _poles(ctx.n, ctx.omega_o)
    return t.design({"poles": poles}, f"ẋ = Ax + B(u, y), y = Cx; eig(A − KC) placed at {_fmt(poles)}: the error is linear, "
                    "convergence is global")


# -- filters on the full model --------------------------------------------------------------------------------------
def _domain_bounds(ctx: Context) -> dict[str, list[float | None]]:
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


def _filters(ctx: Context, kind: str) -> Candidate:
    t = _Trial(ctx, kind)
    opts: dict[str, Any] = {"Q": _sq(ctx.Q), "R": _sq(ctx.R), "P0": _sq(ctx.P0)}
    if kind == "ekf":
        opts["mode"] = "continuous-discrete"
    bounds = _domain_bounds(ctx)
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
    return t.design(opts, f"{local}; {ctx.noise_note}; P(0) = diag(σ₀²) with σ₀ the offset of x̂(0) (at least 10 % of the "
                    f"state's range on the run){spread}. A local method: it converges from an x̂(0) close enough, with no "
                    "global certificate", extra=extra)


def _sigma_spread(ctx: Context) -> tuple[dict[str, float], str]:
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


def _robust_filters(ctx: Context, kind: str) -> Candidate:
    """Square-root UKF/EKF and the iterated EKF: the tuning of the EKF/UKF (Q, R, P0 from the run)."""
    t = _Trial(ctx, kind)
    opts: dict[str, Any] = {"Q": _sq(ctx.Q), "R": _sq(ctx.R), "P0": _sq(ctx.P0)}
    spread = ""
    if kind == "srukf":
        extra_opts, spread = _sigma_spread(ctx)
        opts.update(extra_opts)
    local = "locally observable (generic rank condition)" if ctx.report.observable else "observability not established"
    use = {"srukf": "the UKF carrying a Cholesky factor (QR updates, no Cholesky factorisation or downdate): for a tiny R or an "
                    "ill-conditioned P, where the UKF's P loses definiteness",
           "srekf": "the EKF carrying a square root of P (QR Joseph update): for a tiny R or an ill-conditioned P",
           "iekf": "Gauss-Newton iterations of the EKF's update: for a strongly nonlinear output (ranges, angles, squares), "
                   "where one linearisation at x̂⁻ overshoots"}[kind]
    extra = ""
    ratio = float(np.linalg.eigvalsh(np.atleast_2d(ctx.R)).min() / np.linalg.eigvalsh(np.atleast_2d(ctx.P0)).max())
    if kind in ("srukf", "srekf") and ratio < TINY_R:
        extra = (f"R is {ratio:.1g} of the largest prior variance (below {TINY_R:g}): the covariance forms' P − KSKᵀ then "
                 "loses definiteness in floating point and their Cholesky factorisation fails; the square-root form is the "
                 "choice here")
        if ctx.choice is None and kind == "srukf":
            ctx.choice = ("srukf", extra)
            ctx.notes.append(f"R is {ratio:.1g} of the prior variance: the square-root UKF (kind 'srukf') is the choice")
    return t.design(opts, f"{local}; {ctx.noise_note}; P(0) = diag(σ₀²) with σ₀ the offset of x̂(0){spread}; {use}. "
                    "A local method: it converges from an x̂(0) close enough, with no global certificate", extra=extra)


#: Below this ratio λmin(R)/λmax(P(0)) the advisor marks the square-root UKF as the choice: P − KSKᵀ keeps
#: only −log10(ratio) of the 16 digits of P, and its rounding (about 1e-16·‖P‖) reaches the smallest eigenvalue
TINY_R = 1e-8


def output_symmetries(system: Any, *, samples: int = 4, seed: int = 0) -> list[tuple[str, ...]]:
    """Sign flips of states that leave every output unchanged at generic points: h(x) = h(σx).

    Each state the outputs depend on is flipped alone, then all of them together; a flip counts when
    h(σx) − h(x) expands to zero (SymPy), or, when that is not decided quickly, when it vanishes at
    `samples` random points (the inputs and t random too) to 1e-9 relative.
    """
    import sympy as sp

    _, h = system.substituted()
    xs = list(system.x)
    used = [i for i, x in enumerate(xs) if any(x in e.free_symbols for e in h)]
    flips = [(i,) for i in used] + ([tuple(used)] if len(used) > 1 else [])
    rng = np.random.default_rng(seed)
    _, h_num = compile_system(system).bind()  # CasADi, at generic points (no evaluation of model strings)
    n, nu = system.n_states, system.n_inputs
    found = []
    for flip in flips:
        sign = np.ones(n)
        sign[list(flip)] = -1
        sub = {xs[i]: -xs[i] for i in flip}
        if all(sp.expand(e.xreplace(sub) - e) == 0 for e in h):
            found.append(tuple(system.states[i] for i in flip))
            continue
        ok = True
        for _ in range(samples):
            x = rng.uniform(0.3, 1.7, n) * rng.choice([-1.0, 1.0], n)
            t, u = float(rng.uniform(0.3, 1.7)), rng.uniform(0.3, 1.7, nu)
            a = np.asarray(h_num(t, x, u), dtype=float).ravel()
            b = np.asarray(h_num(t, sign * x, u), dtype=float).ravel()
            if not (np.all(np.isfinite(a)) and np.allclose(a, b, rtol=1e-9, atol=1e-12)):
                ok = False
                break
        if ok:
            found.append(tuple(system.states[i] for i in flip))
    return found


def _pf(ctx: Context) -> Candidate:
    t = _Trial(ctx, "pf")
    n = ctx.system.n_states
    particles = int(min(20000, 1000 * max(2, n)))
    opts: dict[str, Any] = {"Q": _sq(ctx.Q), "R": _sq(ctx.R), "P0": _sq(4 * np.asarray(ctx.P0)), "particles": particles, "seed": 0}
    sym = output_symmetries(ctx.system)
    if sym:
        flips = "; ".join(("−" + ", −".join(f)) if len(f) > 1 else f"{f[0]} → −{f[0]}" for f in sym)
        why = (f"the output is symmetric in the state: h(x) = h(σx) for the sign flip {flips} at generic points (decided "
               "symbolically, or at random points), so the posterior of x̂ can have two modes that the measurements alone "
               "cannot tell apart; a Gaussian filter (EKF, UKF and their square-root and iterated forms) commits to one mode and "
               "can converge to the mirror state; the particle filter carries both until the dynamics separate them — the "
               "choice here")
        ctx.notes.append(f"output symmetric under {flips}: multimodal posterior, the particle filter (kind 'pf') is the choice")
        ctx.choice = ("pf", why)
    else:
        why = ("no sign symmetry of the output found: a Gaussian filter (EKF/UKF) is cheaper here; the particle filter fits "
               "multimodal or non-Gaussian posteriors")
    return t.design(opts, f"{ctx.noise_note}; {particles} particles, systematic resampling when ESS < N/2, P(0) = 4·diag(σ₀²) "
                    f"(a wide cloud), seed 0; {why}")


def _mhe(ctx: Context) -> Candidate:
    t = _Trial(ctx, "mhe")
    sc = ctx.scenario
    Ts = (sc.sample_period or sc.dt) if sc is not None else 0.01
    horizon = int(np.clip(round(2.0 / (ctx.omega_p * Ts)), 10, 30))
    runnable = sc is not None and sc.samples <= MHE_SAMPLE_BUDGET
    note = "" if runnable or sc is None else (f"left out of --run: {sc.samples} measurement updates, each an NLP solve (budget "
                                              f"{MHE_SAMPLE_BUDGET}); run it with `nlobs simulate` on a sampled model")
    opts: dict[str, Any] = {"horizon": horizon, "R": _sq(ctx.R), "Q": _sq(ctx.Q), "P0": _sq(ctx.P0)}
    bounds = _domain_bounds(ctx)
    if bounds:
        opts["bounds"] = bounds
    return t.design(opts, f"window of {horizon} samples (≈ 2/ω_p); R = σ², Q and P(0) as for the EKF", runnable=runnable,
                    extra=note)


def _lipschitz(ctx: Context) -> Candidate:
    t = _Trial(ctx, "lipschitz")
    if not ctx.region:
        return t.needs("a region (box of states and inputs) to bound the Lipschitz constant: add [simulation] x0")
    region = {k: list(v) for k, v in {**_region_states(ctx), **_region_inputs(ctx)}.items()}
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
        return t.fail("the Jacobian of f is not finite at the centre of the region")
    quick = _thau_precheck(ctx, A, J)
    if quick:
        return t.fail(quick, region=region, A=_round(A))
    return t.design({"region": region, "A": _round(A)}, "A = ∂f/∂x at the centre of the visited region, φ = f − Ax; γ bounded "
                    "over the region (valid while x and x̂ stay in it)")


def _thau_precheck(ctx: Context, A: np.ndarray, J: sp.Matrix) -> str:
    """A quick refusal when the best Thau margin of the gain search is already below a *lower* bound of γ
    (the sup of ‖∂f/∂x − A‖₂ over the run's points): the full design would refuse too, only slower."""
    from ..design._lipschitz import _search

    _, h = ctx.system.substituted()
    C = h.jacobian(sp.Matrix(ctx.system.x))
    if C.free_symbols:
        return ""
    best = _search(A, np.array(C, dtype=float), 0.0)[1]
    F = _jacobians_on_run(ctx)
    if F is None:
        return ""
    gam = float(np.max(np.linalg.norm(F - A, 2, axis=(1, 2))))
    if best <= gam:
        return (f"the Thau condition eigmin(Q)/(2 eigmax(P)) > γ cannot hold: the best margin of the gain search is {best:.4g}, "
                f"but already along the run γ ≥ sup‖∂f/∂x − A‖₂ = {gam:.4g} ({cite('002', 'LTI + Lipschitz NL')}). "
                "Shrink the region, change the A/φ split, or use a high-gain or Kalman-type observer")
    return ""


def _jacobians_on_run(ctx: Context) -> np.ndarray | None:
    from ._context import _jacobians

    if ctx.nominal is None:
        return None
    F = _jacobians(ctx.system, ctx.samples(300))
    F = F[np.all(np.isfinite(F), axis=(1, 2))]
    return F if len(F) else None


# -- triangular / high gain -----------------------------------------------------------------------------------------
def _chains(ctx: Context) -> tuple[Any, list[list[str]] | None, str]:
    try:
        return triangular_chains(ctx.system, caller="high_gain"), None, ""
    except (FormError, PreconditionError) as first:
        reason: list[str] = []
        alt = find_chains(ctx.system, reason)
        if alt is None:
            return None, None, (f"not in triangular form: {reason[0]}" if reason else _clean(first))
        try:
            return triangular_chains(ctx.system, alt, caller="high_gain"), alt, ""
        except (FormError, PreconditionError) as e:
            return None, None, _clean(e)


def _theta_star(chs: Any, gamma: float, n: int) -> float:
    import scipy.linalg

    from ..design._common import chain_gain

    blocks = []
    for c in chs:
        m = len(c.states)
        g = chain_gain([float(a) for a in c.couplings], np.full(m, -1.0 + 0j))
        A = np.zeros((m, m))
        for i, a in enumerate(c.couplings):
            A[i, i + 1] = float(a)
        blocks.append(A - np.outer(g, np.eye(m)[0]))
    Ab = scipy.linalg.block_diag(*blocks)
    P0 = scipy.linalg.solve_continuous_lyapunov(Ab.T, -np.eye(n))
    return max(1.0, 2.0 * np.sqrt(n) * gamma * float(np.linalg.eigvalsh((P0 + P0.T) / 2).max()))


def _saturation(ctx: Context) -> dict[str, float]:
    """Khalil's remedy against peaking: the estimate fed to the model is clipped to twice the largest magnitude each
    state reaches on the run."""
    if not ctx.region:
        return {}
    return {s: float(f"{2.0 * max(abs(ctx.region[s][0]), abs(ctx.region[s][1])):.4g}") for s in ctx.system.states}


def _high_gain(ctx: Context) -> Candidate:
    t = _Trial(ctx, "high_gain")
    chs, alt, why = _chains(ctx)
    if chs is None:
        return t.fail(why)
    opts: dict[str, Any] = {}
    if alt is not None:
        opts["chains"] = alt
    sat = _saturation(ctx)
    if sat:
        opts["saturation"] = sat
    order = "; ".join(" -> ".join(ctx.system.states[j] for j in c.states) for c in chs)
    if sat:
        order += " (estimate saturated at twice the run's magnitudes, against peaking)"
    limit = ctx.step_limit()
    varying = [(c, i, a) for c in chs for i, a in enumerate(c.couplings) if a.free_symbols]
    if varying:
        if ctx.nominal is None:
            return t.needs("K0 (the couplings vary: " + ", ".join(str(a) for _, _, a in varying) + ") and a run to check them")
        pts = ctx.samples(400)
        ysub = {ctx.system.x[j]: ctx.system.y[k] for k, j in enumerate(c.states[0] for c in chs)}
        vals = evaluate([a.xreplace(ysub) for _, _, a in varying], ctx.system, pts)
        for (c, i, a), col in zip(varying, vals.T):
            lo, hi = float(col.min()), float(col.max())
            if lo * hi <= 0 or min(abs(lo), abs(hi)) < 1e-3 * max(abs(lo), abs(hi)):
                s0, s1 = ctx.system.states[c.states[i]], ctx.system.states[c.states[i + 1]]
                return t.fail(f"the coupling ∂{s0}'/∂{s1} = {a} takes values in [{lo:.3g}, {hi:.3g}] on the run: it "
                              f"{_vanishes(lo, hi)}, and the high-gain observer needs it "
                              f"bounded away from 0 with a fixed sign ({cite('002')}, extension of the high-gain observer)")
        from ..design._common import chain_gain

        means = {id(a): float(np.mean(col)) for (_, _, a), col in zip(varying, vals.T)}
        K0 = []
        for c in chs:
            cpl = [means[id(a)] if a.free_symbols else float(a) for a in c.couplings]
            K0.extend(chain_gain(cpl, np.full(len(c.states), -1.0 + 0j)).tolist())
        theta = float(min(max(ctx.omega_o, 1.0), limit))
        opts.update({"theta": round(theta, 6), "K0": K0})
        return t.design(opts, f"chains {order}; couplings vary but keep their sign on the run: K0 from their mean values "
                        f"(binomial poles), θ = {theta:.3g} from the time scale")
    if not ctx.region:
        theta = float(max(ctx.omega_o, 1.0))
        opts["theta"] = round(theta, 6)
        return t.design(opts, f"chains {order}; θ = {theta:.3g} from the time scale (no region to bound the nonlinearity)")
    from ..design._lipschitz import lipschitz_constant

    A0 = sp.zeros(ctx.n, ctx.n)
    for c in chs:
        for i, a in enumerate(c.couplings):
            A0[c.states[i], c.states[i + 1]] = a
    f, _ = ctx.system.substituted()
    phi = list(f - A0 * sp.Matrix(ctx.system.x))
    region = {**_region_states(ctx), **_region_inputs(ctx)}
    if ctx.system.is_time_varying:
        region["t"] = (0.0, float(ctx.scenario.t_final))
    try:
        gamma, _ = lipschitz_constant(ctx.system, phi, region, caller="high_gain")
    except (PreconditionError, ShapeError) as e:
        gamma, why_g = None, _clean(e)
    if gamma is not None and np.isfinite(gamma):
        ts = _theta_star(chs, gamma, ctx.n)
        if 1.2 * ts <= limit:
            theta = float(min(max(1.2 * ts, ctx.omega_o), limit))
            opts.update({"theta": round(theta, 6), "lipschitz": round(float(gamma), 9)})
            return t.design(opts, f"chains {order}; γ ≈ {gamma:.3g} (Lipschitz constant of the triangular part on the region), "
                            f"θ = {theta:.3g} > θ* = {ts:.3g}: convergence guaranteed while the state stays in the region")
        theta = float(min(max(ctx.omega_o, 1.0), limit))
        opts["theta"] = round(theta, 6)
        return t.design(opts, f"chains {order}; θ = {theta:.3g} from the time scale; the sufficient bound θ* = {ts:.3g} (γ ≈ "
                        f"{gamma:.3g} on the region) is beyond what the step allows (θ ≤ {limit:.3g}), so convergence is not "
                        "certified (the bound is conservative)")
    theta = float(min(max(ctx.omega_o, 1.0), limit))
    opts["theta"] = round(theta, 6)
    return t.design(opts, f"chains {order}; θ = {theta:.3g} from the time scale (no Lipschitz bound: {why_g})")


def _high_gain_derivatives(ctx: Context) -> Candidate:
    t = _Trial(ctx, "high_gain_derivatives")
    lie: dict[sp.Symbol, sp.Expr] = {}
    try:
        psi, why = derivative_map(ctx.system, lie=lie)
    except (NotImplementedError, ValueError, TypeError) as e:  # SymPy giving up
        psi, why = None, f"the output derivatives could not be solved for the state ({type(e).__name__})"
    if psi is None:
        return t.needs(f"xhat = Ψ(D0_y, D1_y, ...): {why}", xhat="expressions of the output derivatives D{i}_{output}")
    theta = float(min(max(ctx.omega_o, 1.0), ctx.step_limit()))
    dens = sorted({d.as_coeff_Mul()[1] for e in psi.values() for d in [sp.fraction(sp.together(e))[1]] if d.free_symbols},
                  key=str)
    extra = ""
    if dens:
        extra = f"Ψ is singular where {', '.join(map(str, dens))} = 0"
        if ctx.nominal is not None:
            vals = evaluate([d.xreplace(lie) for d in dens], ctx.system, ctx.samples(400))
            for d, col in zip(dens, vals.T):
                lo, hi = float(np.min(col)), float(np.max(col))
                small = float(np.min(np.abs(col))) < 1e-3 * float(np.max(np.abs(col)))
                if lo * hi <= 0 or small:
                    return t.fail(f"Ψ (x from the output derivatives, solved by nlobs) divides by {d}, which "
                                  f"{_vanishes(lo, hi)} on the run (from {lo:.3g} to "
                                  f"{hi:.3g}): the estimate blows up where it vanishes", xhat={k: text(v) for k, v in psi.items()})
    return t.design({"xhat": {k: text(v) for k, v in psi.items()}, "theta": round(theta, 6)},
                    f"Ψ solved from the Lie derivatives of the output(s); θ = {theta:.3g} (binomial α)", extra=extra)


def _high_gain_kalman(ctx: Context) -> Candidate:
    t = _Trial(ctx, "high_gain_kalman")
    if ctx.p != 1:
        return t.fail(f"one output measuring the first state is required; the model has {ctx.p}")
    try:
        (chain,) = triangular_chains(ctx.system, caller="high_gain_kalman")
    except (FormError, PreconditionError, ValueError) as e:
        alt = find_chains(ctx.system)
        hint = f" (the chain here is {' -> '.join(alt[0])}: declare the states in that order)" if alt and len(alt) == 1 else ""
        return t.fail(_clean(e) + hint)
    if not ctx.region:
        return t.needs("a region of the inputs and output for δ > 2 sup‖A0(u, y)‖: add [simulation] x0")
    from ..design._kalman import StateAffineParts, _sup_norm

    x1, y = ctx.system.x[0], ctx.system.y[0]
    A0 = sp.zeros(ctx.n, ctx.n)
    for i, a in enumerate(chain.couplings):
        A0[i, i + 1] = a.xreplace({x1: y})
    region = {k: list(v) for k, v in {**_region_inputs(ctx), ctx.system.outputs[0]: ctx.region[ctx.system.outputs[0]]}.items()}
    try:
        sup, _ = _sup_norm(StateAffineParts(ctx.system, A0, sp.zeros(ctx.n, 1), sp.zeros(1, ctx.n)), region, "high_gain_kalman")
    except (PreconditionError, ShapeError) as e:
        return t.fail(_clean(e))
    delta = round(2.2 * sup + 1e-3, 6)
    lam = float(min(max(1.0, ctx.omega_o / max(delta, 1e-9)), ctx.step_limit() / max(delta, 1e-9), 50.0))
    lam = max(1.0, lam)
    opts = {"lam": round(lam, 6), "delta": delta, "region": region}
    return t.design(opts, f"δ = 2.2 sup‖A0‖ = {delta:.3g} over the visited (u, y), λ = {lam:.3g}")


# -- state-affine ---------------------------------------------------------------------------------------------------
def _state_affine(ctx: Context) -> tuple[Any, str]:
    from ..design._kalman import state_affine_parts

    try:
        return state_affine_parts(ctx.system, "state_affine"), ""
    except (FormError, TypeError) as e:
        return None, _clean(e)


def _CA(ctx: Context, CA: sp.Matrix) -> np.ndarray:
    """C A(u, y, t) at points of the run, shape (k, p, n) (how the unmeasured states reach the output's derivative);
    one matrix when constant, none (shape (0, p, n)) without a run."""
    p, n = CA.shape
    if not CA.free_symbols:
        return np.array(CA, dtype=float).reshape(1, p, n)
    if ctx.nominal is None:
        return np.zeros((0, p, n))
    vals = evaluate(list(CA.T), ctx.system, ctx.samples(300)).reshape(-1, n, p).transpose(0, 2, 1)
    return vals[np.all(np.isfinite(vals), axis=(1, 2))]


def _constant_C(parts: Any) -> np.ndarray | None:
    C = parts.C
    return None if C.free_symbols else np.array(C, dtype=float)


def _kalman_bucy(ctx: Context) -> Candidate:
    t = _Trial(ctx, "kalman_bucy")
    parts, why = _state_affine(ctx)
    if parts is None:
        return t.fail(why)
    W, M0, note = ctx.riccati_weights(ctx.R_rate, ctx.P0, ctx.Q, _constant_C(parts), _CA(ctx, parts.C * parts.A))
    return t.design({"Q": _sq(ctx.Q), "R": _sq(W), "P0": _sq(M0)},
                    f"state-affine ẋ = A(u, y, t)x + b; Q, R as intensities ({ctx.noise_note})", extra=note)


def _kalman_like(ctx: Context) -> Candidate:
    t = _Trial(ctx, "kalman_like")
    parts, why = _state_affine(ctx)
    if parts is None:
        return t.fail(why)
    delta = round(float(ctx.omega_p), 6)
    W, M0, note = ctx.riccati_weights(ctx.R_rate, ctx.P0, ctx.Q, _constant_C(parts), _CA(ctx, parts.C * parts.A))
    return t.design({"W": _sq(W), "V": _sq(ctx.Q), "delta": delta, "M0": _sq(M0)},
                    f"state-affine; W = R, V = Q, forgetting δ = ω_p = {delta:.3g}", extra=note)


def _gpebo_common(ctx: Context, t: _Trial) -> tuple[dict[str, Any] | None, str, Candidate | None]:
    parts, why = _state_affine(ctx)
    if parts is None:
        return None, "", t.fail(why)
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
        L, bad = _injection(An, Cn, ctx, "A", t)
        if bad is not None:
            return None, "", bad
        opts["L"] = _round(L)
        return opts, (f"A has an unstable or a repeated mode on the imaginary axis, so Φ_A grows ({cite('000')} assumption 5): "
                      f"output injection L puts eig(A − LCᵀ) at {_fmt(_poles(ctx.n, ctx.omega_o))}"), None
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
    L, bad = _injection(np.mean(At, axis=0), Cn, ctx, "the run's mean of A", t)
    if bad is not None:
        return None, "", bad
    peak2, end2 = _phi_growth(At - (L @ Cn)[None], tt)
    if peak2 < 1e3 and end2 < _GROWING:
        opts["L"] = _round(L)
        return opts, (f"along the run ‖Φ_A‖ grows {grows} ({cite('000')} assumption 5 fails there): output injection L "
                      f"from the run's mean A (eig(mean A − LCᵀ) at {_fmt(_poles(ctx.n, ctx.omega_o))}) keeps ‖Φ_(A−LCᵀ)‖ ≤ "
                      f"{peak2:.3g} along the run"), None
    grows2 = "without bound" if not np.isfinite(peak2) else f"to {peak2:.3g}"
    return None, "", t.fail(f"the homogeneous part is not uniformly stable along the run ({cite('000')} assumption 5): ‖Φ_A‖ grows "
                            f"{grows}, and an output injection from the run's mean A leaves ‖Φ‖ growing {grows2}; give `L`")


#: ‖Φ(T)‖ over its largest value on [0, T/2] at or above which Φ counts as still growing: a bounded Φ gives about 1,
#: a Φ that grows linearly (a parameter appended as a constant state: a Jordan block at 0) 2·(1 + cT)/(2 + cT) → 2.
_GROWING = 1.5


def _injection(A: np.ndarray, C: np.ndarray, ctx: Context, what: str, t: _Trial) -> tuple[np.ndarray | None, Candidate | None]:
    from ..design import observer_gain

    try:
        L, _, _ = observer_gain(A, C, poles=_poles(ctx.n, ctx.omega_o), caller="gpebo")
    except (PreconditionError, ValueError) as e:
        return None, t.fail(f"{what} is not uniformly stable ({cite('000')} assumption 5) and no output injection fixes it: "
                            f"{_clean(e)}")
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


def _gpebo_2gd(ctx: Context) -> Candidate:
    t = _Trial(ctx, "gpebo_2gd")
    opts, note, bad = _gpebo_common(ctx, t)
    if bad is not None:
        return bad
    lim = ctx.step_limit()
    psi2, peak = _regressor_level(ctx)
    gg = float(min(5.0 * ctx.omega_o / psi2, 0.5 * lim / peak))   # the gradient stage acts at γ_g‖ψ‖²
    gm = float(min(10.0 * gg, lim))                                  # the mixed stage at γΔ² ≤ γ (0 ≤ Δ ≤ 1)
    opts.update({"gamma_g": float(f"{gg:.6g}"), "gamma": float(f"{gm:.6g}")})
    return t.design(opts, f"state-affine; γ_g = {gg:.3g} (5 ω_o / mean ‖ψ‖², ‖ψ‖² up to {peak:.3g} on the run), γ = {gm:.3g} "
                    "(10 γ_g; both within the step limit); observable on an interval suffices (no UCO)", extra=note)


def _regressor_level(ctx: Context) -> tuple[float, float]:
    """mean and peak ‖ψ‖² of the GPEBO regressor ψ = Φ_Aᵀ C along the run (d/dt trace W(0, t) = ‖ψ‖²; at least 1)."""
    info = ctx.uco or {}
    mean = peak = 1.0
    if info.get("gramian_trace") and info.get("horizon"):
        mean = max(1.0, float(info["gramian_trace"]) / float(info["horizon"]))
    if info.get("regressor_peak"):
        peak = max(1.0, float(info["regressor_peak"]))
    return mean, max(mean, peak)


def _gpebo(ctx: Context) -> Candidate:
    t = _Trial(ctx, "gpebo")
    opts, note, bad = _gpebo_common(ctx, t)
    if bad is not None:
        return bad
    _, peak = _regressor_level(ctx)
    P0 = np.minimum(np.diag(ctx.P0) * ctx.omega_o, 0.5 * ctx.step_limit() / peak)   # the LS gain acts at ‖P‖‖ψ‖²
    opts["estimator"] = {"kind": "least_squares", "P0": _sq(np.diag(P0))}
    return t.design(opts, "state-affine; least-squares estimator of θ = x(0) − ξ(0) with P(0) = ω_o·diag(range²) (capped at "
                    "the step limit)", extra=note)


# -- regression models ----------------------------------------------------------------------------------------------
def _regression(kind: str) -> Callable[[Context], Candidate]:
    def trial(ctx: Context) -> Candidate:
        t = _Trial(ctx, kind)
        f, h = ctx.system.substituted()
        moving = [f"{s}' = {e}" for s, e in zip(ctx.system.states, f) if e != 0]
        if moving:
            return t.fail(f"estimates constant parameters θ of a linear regression y = ψ(u, t)ᵀθ (θ' = 0); here {moving[0]}. "
                          "For a state-affine model, gpebo and gpebo_2gd build such a regression from the state")
        if ctx.nominal is None:
            return t.needs("a run ([simulation] x0) to scale the gains")
        H = sp.Matrix(h).jacobian(sp.Matrix(ctx.system.x))
        psi = evaluate(list(H), ctx.system, ctx.samples(400))
        level = float(np.mean(np.sum(psi ** 2, axis=1))) or 1.0
        g = round(float(ctx.omega_o / level), 9)
        opts = {"gradient": {"gamma": g}, "least_squares": {"P0": g}, "drem": {"gamma": g},
                "gd": {"gamma_g": g, "gamma": round(10 * g, 9)}}[kind]
        return t.design(opts, f"regression model; gains from ω_o / mean ‖ψ‖² = {g:.3g}")

    return trial


# -- immersions: KKL, PEBO, augmentation ----------------------------------------------------------------------------
def _is_oi(ctx: Context) -> str:
    holds, why = ctx.form("output injection")
    return "" if holds else why


def _kkl(ctx: Context) -> Candidate:
    t = _Trial(ctx, "kkl")
    why = _is_oi(ctx)
    need = ("φ(x), a stable Λ and B(y, u) with ∇φ·f = Λφ + B(h(x), u) (the PDE of " + f"{cite('004', 'eq. 4')}"
            + "), and a left inverse φᴸ(ξ, y); or use kkl_learned, which learns φᴸ numerically")
    if why:
        return t.needs(need + f" (nlobs constructs φ only for the output-injection form: {why})",
                       phi="...", left_inverse="...", B="...", Lambda="...")
    try:
        opts, reason = kkl_linear(ctx.system, ctx.omega_o)
    except (FormError, ValueError, ZeroDivisionError) as e:
        opts, reason = None, _clean(e)
    if opts is None:
        return t.needs(need + f" ({reason})")
    return t.design(opts, "constructed: φ = Tx with TA − ΛT = B_kC (Sylvester, exact), Λ = −ω_o·diag(1, 1.25, ...)")


def _pebo(ctx: Context) -> Candidate:
    t = _Trial(ctx, "pebo")
    why = _is_oi(ctx)
    need = "φ(x) with ∇φ·f = B(h(x), u) (a function whose derivative is measured), B, and a left inverse φᴸ(ξ, y)"
    if why:
        return t.needs(need + f" (nlobs constructs φ only for the output-injection form: {why})", phi="...", left_inverse="...", B="...")
    try:
        opts, reason, b = pebo_linear(ctx.system)
    except (FormError, ValueError, ZeroDivisionError) as e:
        opts, reason, b = None, _clean(e), None
    if opts is None:
        return t.needs(need + f" ({reason})")
    level = float(np.sum(np.array(b, dtype=float) ** 2)) or 1.0
    alpha = round(float(min(ctx.omega_o, ctx.step_limit())), 6)
    opts.update({"alpha": alpha, "estimator": {"kind": "gradient", "gamma": round(ctx.omega_o / level, 9)}})
    return t.design(opts, f"constructed: φ = Tx with TA = KC (derivatives measured), [C; T] invertible; filters α = {alpha:.3g}, "
                    "gradient estimator (the regressor is constant, so θ converges exponentially)")


def _kkl_learned(ctx: Context) -> Candidate:
    t = _Trial(ctx, "kkl_learned")
    if not ctx.region:
        return t.needs("`region` (a box of initial states): add [simulation] x0")
    sc = ctx.scenario
    consts: dict[str, float] = {}
    for k in ctx.system.inputs:
        v = sc.inputs.get(k, 0.0) if sc is not None else 0.0
        try:
            val = float(v)
        except (TypeError, ValueError):
            expr = v if isinstance(v, sp.Basic) else None
            if expr is not None and not expr.free_symbols:
                val = float(expr)
            else:
                return t.fail(f"learns φᴸ for constant inputs only; the run drives {k} = {v} (time-varying). Use kkl with a φ "
                              "that holds for every input, or a constant input")
        consts[k] = val
    box = [list(ctx.region[s]) for s in ctx.system.states]
    # Λ on the observer's time scale: the data start after the ξ transient (16/min|λ|) and cover ~10 plant time constants
    lam = [float(f"{-ctx.omega_o * (1 + k / ctx.n):.6g}") for k in range(ctx.n + 1)]
    t_final = 16.0 / ctx.omega_o + 10.0 / ctx.omega_p
    # RK4 at 5 % of the fastest rate (ξ's, which is faster than the plant's: |λ| ≥ 2ω_o = 6ω_p): about 1,800 steps
    # whatever the run's own dt (which the comparison needs, not the training data; a slow model on a fine dt would
    # otherwise integrate tens of thousands of steps here)
    dt = 0.05 / abs(lam[-1])
    t_final = float(f"{max(t_final, 20 * dt):.6g}")
    dt = t_final / max(1, round(t_final / dt))
    n_vars = (ctx.n + 1) * len(ctx.system.outputs) + len(ctx.system.outputs)   # (ξ, y)
    degree = _max_degree(n_vars)
    if not degree:
        return t.fail(f"learning φᴸ needs more than {MAX_FEATURES:,} polynomial features even at degree 1 ((ξ, y) has {n_vars} "
                      "entries for this many states and outputs); not tried")
    opts: dict[str, Any] = {"region": box, "eigenvalues": lam, "n_trajectories": 40, "t_final": t_final, "dt": dt,
                            "degree": degree}
    if consts:
        opts["inputs"] = consts
    return t.design(opts, f"φᴸ learned by least squares on 40 simulated runs from the visited box (polynomial features of "
                    f"degree {degree}), Λ = −ω_o·diag(1, ..., 2); valid inside the box")


def _augmented(ctx: Context) -> Candidate:
    t = _Trial(ctx, "augmented")
    from ..analysis import propose_augmentation

    try:
        aug = propose_augmentation(ctx.system, max_degree=3, max_states=min(4 * ctx.n + 2, 18))
    except (FormError, ModelError) as e:
        return t.needs(f"T(x), A(u, y, t), C and a left inverse such that the augmented system mimics the model "
                       f"({cite('001', 'Def. 3')}); nlobs could not close the span automatically: {_clean(e)}",
                       T="...", A="...", C="...", left_inverse="...")
    if aug.n_w == ctx.n:
        return t.fail("not needed: the model is already state-affine in its own coordinates (the span of the outputs' "
                      "derivatives closes on x itself); this would be the filter of `kalman_bucy`")
    opts: dict[str, Any] = {"T": [text(e) for e in aug.T], "A": [[text(e) for e in row] for row in aug.A.tolist()],
                            "C": [[text(e) for e in row] for row in aug.C.tolist()],
                            "left_inverse": [text(e) for e in aug.left_inverse], "b": [text(e) for e in aug.b]}
    tuning = f"constructed: w = T(x) with {aug.n_w} states mimics the model (span of the output derivatives closed)"
    params = {sp.Symbol(k, real=True): v for k, v in ctx.system.params.items()}
    ys = set(ctx.system.y)
    if not any(e.xreplace(params).free_symbols for e in aug.A) and not any(e.free_symbols & ys for e in aug.b):
        opts["poles"] = _poles(aug.n_w, ctx.omega_o)
        return t.design(opts, tuning + f"; A constant: Luenberger with poles {_fmt(opts['poles'])}")
    if ctx.nominal is None:
        return t.needs("Q and R for the Kalman–Bucy filter on the augmented system, and a run to scale them", **opts)
    W = evaluate(list(aug.T), ctx.system, ctx.samples(300))
    span, mag = W.max(axis=0) - W.min(axis=0), np.abs(W).max(axis=0)
    sw = np.maximum(np.where(span > 0.05 * mag, span, 0.5 * mag), 1e-6)        # the states' scale rule, for w = T(x)
    for i, e in enumerate(aug.T):                                                 # components that are states: their P(0)
        if e in ctx.system.x:
            sw[i] = float(np.sqrt(ctx.P0[ctx.system.x.index(e), ctx.system.x.index(e)]))
    Qw = np.diag((0.01 * sw) ** 2 * ctx.omega_p)
    Cw = np.array(aug.C.xreplace(params), dtype=float) if not aug.C.xreplace(params).free_symbols else None
    W, M0, note = ctx.riccati_weights(ctx.R_rate, np.diag(sw ** 2), Qw, Cw, _CA(ctx, (aug.C * aug.A).xreplace(params)))
    opts.update({"Q": _sq(Qw), "R": _sq(W), "P0": _sq(M0)})
    return t.design(opts, tuning + "; A(u, y, t) or b(u, y, t) varies: Kalman–Bucy filter on the augmented system, Q, R as for kalman_bucy",
                    extra=note)


def _cascade(ctx: Context) -> Candidate:
    t = _Trial(ctx, "kkl_pebo_cascade")
    part, why = cascade_partition(ctx.system)
    if part is None:
        return t.fail(f"not in the class of {cite('004', 'Proposition 7')}: {why}")
    alpha = round(float(min(ctx.omega_o, ctx.step_limit())), 6)
    gamma = float(ctx.omega_o)
    if ctx.nominal is not None:  # the gradient acts at the rate γ‖F[b]‖²: scale γ by the regressor b along the run
        f, _ = ctx.system.substituted()
        fk = f[ctx.system.states.index(part["k"])]
        b = [sp.diff(fk, sp.Symbol(v, real=True)) for v in part["x4"]]
        vals = evaluate(b, ctx.system, ctx.samples(300))
        b2 = np.sum(vals ** 2, axis=1)
        if np.all(np.isfinite(b2)) and b2.max() > 0:
            gamma = float(min(ctx.omega_o / max(b2.mean(), 1e-300), ctx.step_limit() / b2.max()))
    opts = {**part, "alpha": alpha, "estimator": {"kind": "gradient", "gamma": float(f"{gamma:.6g}")}}
    return t.design(opts, f"blocks found: x2 = {part['x2']}, x3 = {part['x3']}, x4 = {part['x4']}, k = {part['k']}; "
                    f"gradient gain γ = {gamma:.3g} = ω_o / mean ‖b‖² on the run; θ converges if b is persistently exciting")


def _needs(kind: str, what: str, **opts: Any) -> Callable[[Context], Candidate]:
    def trial(ctx: Context) -> Candidate:
        return _Trial(ctx, kind).needs(what, **opts)

    return trial


def _banks(ctx: Context) -> Candidate:
    t = _Trial(ctx, "banks")
    if not ctx.region or ctx.nominal is None:
        return t.needs("P (n × p) and a region Ω: add [simulation] x0 so that nlobs can search P over the visited region")
    box = _region_states(ctx)
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
        return t.fail(blocked)
    P, best, _ = banks_gain(ctx.system, X, U, T, limit=ctx.step_limit())
    if P is None or not np.isfinite(best):
        return t.fail("the Jacobians are not finite on the region")
    if best >= 0:
        return t.fail(f"no gain P found with λ(∂f/∂x + P ∂h/∂x) < 0 on the visited region: the best max matrix measure is "
                      f"{best:.3g} ≥ 0 ({cite('003', 'Theorem 2.6')} needs it negative everywhere on Ω, a much stronger "
                      "condition than a stable linearisation)", P=_round(P))
    speed = float(np.linalg.norm(P, 2)) * ctx.output_gain
    if speed > ctx.step_limit():
        return t.fail(f"a gain with λ(∂f/∂x + P ∂h/∂x) < 0 on the region needs ‖P‖·‖∂h/∂x‖ ≈ {speed:.3g} s⁻¹, beyond what the "
                      f"step allows ({ctx.step_limit():.3g} s⁻¹); reduce dt / the sample period, or shrink the region", P=_round(P))
    region = {k: list(v) for k, v in {**box, **_region_inputs(ctx)}.items()}
    if ctx.system.is_time_varying:
        region["t"] = [0.0, float(ctx.scenario.t_final)]
    return t.design({"P": _round(P), "region": region},
                    f"P searched over the visited region (max matrix measure {best:.3g} on the sampled points)")


#: The trial of each kind known to nlobs.
TRIALS: dict[str, Callable[[Context], Candidate]] = {
    "luenberger": _luenberger,
    "output_injection": _output_injection,
    "ekf": lambda ctx: _filters(ctx, "ekf"),
    "ukf": lambda ctx: _filters(ctx, "ukf"),
    "srukf": lambda ctx: _robust_filters(ctx, "srukf"),
    "srekf": lambda ctx: _robust_filters(ctx, "srekf"),
    "iekf": lambda ctx: _robust_filters(ctx, "iekf"),
    "pf": _pf,
    "mhe": _mhe,
    "high_gain": _high_gain,
    "high_gain_derivatives": _high_gain_derivatives,
    "lipschitz": _lipschitz,
    "kalman_bucy": _kalman_bucy,
    "kalman_like": _kalman_like,
    "high_gain_kalman": _high_gain_kalman,
    "banks": _banks,
    "augmented": _augmented,
    "custom": _needs("custom", "your own observer equations: `states`, `flow` (their derivatives in u, y and the states) "
                     "and `estimate` (x̂ in terms of them)", states="...", flow="...", estimate="..."),
    "gradient": _regression("gradient"),
    "least_squares": _regression("least_squares"),
    "drem": _regression("drem"),
    "gd": _regression("gd"),
    "gpebo": _gpebo,
    "gpebo_2gd": _gpebo_2gd,
    "kkl": _kkl,
    "kkl_learned": _kkl_learned,
    "pebo": _pebo,
    "kkl_pebo": _needs("kkl_pebo", "φ(x), Λ with zeros for the components that have no dynamics of their own (PEBO part) and "
                       "negative entries for the others (KKL part), B(y, u) and a left inverse φᴸ(ξ, y) with ∇φ·f = Λφ + B "
                       f"({cite('004', 'Proposition 3')}; its example (31) is the pattern)",
                       phi="...", left_inverse="...", B="...", Lambda="..."),
    "kkl_pebo_cascade": _cascade,
    "iandi": _needs("iandi", f"β(y, χ), φ(x) and a left inverse φᴸ(ξ, y) ({cite('004', 'Proposition 4')}); the manifold "
                    "condition is the designer's part", beta="...", phi="...", left_inverse="..."),
}


def _from_file(ctx: Context, kind: str, auto: Candidate) -> Candidate:
    """A kind nlobs cannot tune by itself, designed with what the user supplied in the file's ``[observers.NAME]``."""
    name, options = ctx.configs[kind]
    xh = options.get("xhat0")
    if isinstance(xh, (list, tuple)) and ctx.unknown and len(xh) == ctx.model.n_states:  # the guesses go at the end
        options = {**options, "xhat0": [*xh, *(float(ctx.model.params[k]) for k in ctx.unknown)]}
    cand = _Trial(ctx, kind).design(options, f"designed from the file's [observers.{name}] (nlobs cannot tune this kind by "
                                    "itself)")
    if not cand.applies:
        return Candidate(kind, "fails", f"the file's [observers.{name}] does not design: {cand.why}", cand.options,
                         auto.reference or REFERENCES.get(kind, ""))
    return Candidate(kind, "applies", cand.why, cand.options, auto.reference or REFERENCES.get(kind, ""), cand.design,
                     cand.runnable)


def try_kind(ctx: Context, kind: str) -> Candidate:
    """The candidate for one kind: blocked by an unobservable state, tried by its trial, or not tuned."""
    t0 = time.perf_counter()
    if ctx.blockers and kind != "custom":
        cand = Candidate(kind, "fails", "; ".join(ctx.blockers), {}, REFERENCES.get(kind, ""))
    elif kind in TRIALS:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                with symbolic_budget(f"advise: {kind}", seconds=min(kind_seconds(), symbolic_seconds())):
                    cand = TRIALS[kind](ctx)
            except SymbolicBudgetError:
                limit = min(kind_seconds(), symbolic_seconds())
                cand = Candidate(kind, "fails", f"not checked within budget (its symbolic work took more than {limit:g} s, the "
                                 "advisor's budget per kind; the environment variable NLOBS_KIND_SECONDS raises it)", {},
                                 REFERENCES.get(kind, ""))
            except (NlobsError, ValueError, TypeError, ArithmeticError, np.linalg.LinAlgError) as e:
                cand = Candidate(kind, "fails", f"the automatic design failed: {type(e).__name__}: {_clean(e)}", {},
                                 REFERENCES.get(kind, ""))
        msgs = sorted({str(w.message).splitlines()[0] for w in caught if not issubclass(w.category, DeprecationWarning)})
        if msgs:  # numerical warnings of the design's linear algebra are part of its evidence, not noise on stderr
            cand = Candidate(cand.kind, cand.status, cand.why + "; numerical warning: " + "; ".join(msgs), cand.options,
                             cand.reference, cand.design, cand.runnable)
    else:
        fn = DESIGNS[kind]
        cand = Candidate(kind, "not tuned", f"no automatic tuning is known for this kind; give its options in the model file "
                         f"([observers.NAME] kind = {kind!r} with {', '.join(options_of(fn))}) and `nlobs design` uses them",
                         {k: "..." for k in options_of(fn)}, "")
    if cand.status in ("needs input", "not tuned") and kind in ctx.configs and not ctx.blockers:
        cand = _from_file(ctx, kind, cand)
    return Candidate(cand.kind, cand.status, cand.why, cand.options, cand.reference, cand.design, cand.runnable,
                     time.perf_counter() - t0)
