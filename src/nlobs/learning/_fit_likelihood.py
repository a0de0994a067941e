"""Learning parameters (and noise levels) by maximising the innovations likelihood of an EKF or UKF.

The negative log-likelihood of the filter (:mod:`._likelihood`) is a sum over samples of squared whitened
innovations and log-determinants; its Fisher information (the Gauss-Newton matrix of both parts) and its exact
gradient come from forward automatic differentiation through the filter. The optimiser is SciPy's trust-region
method ``minimize(method="trust-exact")`` with that information as its Hessian model — Fisher scoring in a trust
region, the classical prediction-error method (Ljung (1999), ch. 7 and 10) globalised — on scaled unknowns:

- a parameter whose initial guess is positive is fitted as log θ (it stays positive, and relative changes are what
  the steps measure), unless its bounds allow a non-positive value; others as θ/|θ₀|;
- the noise scalings ρ_Q, ρ_R are already logarithms, kept within ±log 10⁶ unless bounded otherwise; they are fitted
  alone first (far from the optimum the innovations are many standard deviations, where Gauss-Newton crawls);
- bounds (``bounds={"k5": (0, 1)}``) by an active set: a step out of the box is rejected, an unknown that ends near a
  bound its gradient pushes against (within two standard errors) is held there and the others fitted again, until
  no unknown changes sides.

It has **converged** when a further scoring step, g^T 𝓘^{-1} g with the gradient g and information 𝓘 over the
unknowns not held at a bound, would move the estimate by less than 0.01 standard errors (and no unknown drifted off
by a factor e^12, where the information vanishes with the parameter). Only then are the standard errors (from
𝓘^{-1}) reported; a fit that stops elsewhere reports none (they hold only at a stationary point) and says what to
try next. When the first start does not converge, the fit starts again from the simulation-error fit
(:func:`nlobs.fit_parameters`), then from perturbations of the best point so far.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from ..engine import Backend
from ..errors import DataError, ModelError
from ..references import cite
from ..estimation import Recording
from ._likelihood import ACCURACY, INFORMATION, MAX_SUBSTEPS, NOISE_NAMES, _Problem

__all__ = ["fit_likelihood", "LikelihoodFit"]

#: Converged when a scoring step would move the estimate by less than this many standard errors (squared).
DECREMENT_TOL = 1e-4
#: An unknown within this (relative) distance of a bound its gradient pushes against is held there.
HELD = 1e-3
#: Default bounds ±log(10⁶) of the noise log-scalings ρ_Q, ρ_R (Q and R within a factor 10⁶ of the design's).
NOISE_BOUND = float(np.log(1e6))
#: An unknown that moved further than this from its start (scaled: a factor e^12 for a log-parameter) is drifting.
DRIFT = 12.0
#: Spread of the perturbed starts in the scaled unknowns (log θ: a factor of about e^±0.5).
PERTURBATION = 0.5


@dataclass(frozen=True, eq=False)
class LikelihoodFit:
    """The result of :func:`fit_likelihood`.

    Attributes
    ----------
    names : tuple of str
        The unknowns: parameter names, then ``"log_Q_scale"``, ``"log_R_scale"`` when the noise was learnt.
    estimate : numpy.ndarray
    std : numpy.ndarray
        Standard errors from the inverse Fisher information — only where they hold: NaN for every unknown when the
        fit did not converge (not a stationary point), and for an unknown held at one of its bounds.
    covariance : numpy.ndarray
        NaN when the fit did not converge.
    initial : numpy.ndarray
        The guesses the fit started from (the first start).
    loglik, loglik_initial : float
        log p(y | θ) of the filter model at the estimate and at the initial guess.
    system : System
        The model (as given, not smoothed) with the fitted parameter values.
    kind : str
        ``"ekf"`` or ``"ukf"``.
    substeps : int
        RK4 sub-steps per sample interval in the filter recursion.
    success : bool
        Converged (see the module docstring).
    message : str
    iterations : int
        Of the start that gave the estimate.
    gradient : numpy.ndarray
        Of log p at the estimate.
    at_bound : tuple of str
        Unknowns held at one of their bounds.
    attempts : tuple of dict
        Each start: where from, log p reached, converged, iterations, seconds.
    notes : tuple of str
        What the filter model changes (censored outputs, smoothed switches).
    """

    names: tuple[str, ...]
    estimate: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    initial: np.ndarray
    loglik: float
    loglik_initial: float
    system: Any
    kind: str
    substeps: int
    success: bool
    message: str
    iterations: int
    gradient: np.ndarray
    at_bound: tuple[str, ...] = ()
    attempts: tuple[Mapping[str, Any], ...] = ()
    notes: tuple[str, ...] = ()
    info: Mapping[str, Any] = field(default_factory=dict)

    @property
    def parameters(self) -> dict[str, dict[str, float]]:
        """``{name: {"estimate", "std"}}`` of the model parameters (std NaN where it does not hold)."""
        return {n: {"estimate": float(v), "std": float(s)} for n, v, s in zip(self.names, self.estimate, self.std)
                if n not in NOISE_NAMES}

    @property
    def noise(self) -> dict[str, dict[str, float]]:
        """``{"Q": {"scale", "log_scale", "log_std"}, "R": ...}`` when the noise was learnt (else empty)."""
        out = {}
        for key in ("Q", "R"):
            name = f"log_{key}_scale"
            if name in self.names:
                i = self.names.index(name)
                out[key] = {"scale": float(np.exp(self.estimate[i])), "log_scale": float(self.estimate[i]),
                            "log_std": float(self.std[i])}
        return out

    @property
    def Q(self) -> np.ndarray:
        """The process noise covariance of the fitted filter (the design's Q, scaled when learnt)."""
        return self.info["Q0"] * (self.noise["Q"]["scale"] if "Q" in self.noise else 1.0)

    @property
    def R(self) -> np.ndarray:
        """The measurement noise covariance of the fitted filter (the design's R, scaled when learnt)."""
        return self.info["R0"] * (self.noise["R"]["scale"] if "R" in self.noise else 1.0)

    @property
    def one_step(self) -> tuple[np.ndarray, np.ndarray]:
        """The fitted filter's one-step predictions ŷ_k⁻ of the recording and their standard deviations, (N, p) each
        (the filter model's: a censored sample is predicted, not used)."""
        return self.info["one_step"]

    def design(self) -> Any:
        """The filter of the fitted model with the fitted noise levels, for :func:`nlobs.estimate` or online use.

        The same kind (``design_ekf`` / ``design_ukf``), P0, x̂0 and sigma-point scaling as the design that was fitted;
        the model as given (its switches exact, its saturating outputs as written)."""
        from ..design import design_ekf, design_ukf

        v = self.info["design_values"]
        if self.kind == "ekf":
            return design_ekf(self.system, Q=self.Q, R=self.R, P0=v["P0"], xhat0=self.info["xhat0"])
        return design_ukf(self.system, Q=self.Q, R=self.R, P0=v["P0"], xhat0=self.info["xhat0"],
                          alpha=float(v["alpha"]), beta=float(v["beta"]), kappa=float(v["kappa"]))

    def to_dict(self) -> dict[str, Any]:
        return {"method": "likelihood", "observer": self.kind, "parameters": self.parameters, "noise_scaling": self.noise,
                "names": list(self.names), "covariance": self.covariance.tolist(),
                "initial": dict(zip(self.names, self.initial.tolist())), "loglik": self.loglik,
                "loglik_initial": self.loglik_initial, "gradient": self.gradient.tolist(), "success": self.success,
                "message": self.message, "iterations": self.iterations, "substeps": self.substeps,
                "std_from": INFORMATION if self.success else None, "std_valid": self.success,
                "at_bound": list(self.at_bound), "attempts": [dict(a) for a in self.attempts], "notes": list(self.notes)}

    def summary(self) -> str:
        w = max(12, *(len(n) for n in self.names))
        head = f"{'unknown':<{w}} {'initial':>12} {'estimate':>12} {'std':>10}"
        state = "converged" if self.success else "NOT converged"
        lines = [f"innovations likelihood ({self.kind.upper()}; {cite('schweppe1965')}, {cite('harvey1989', 'sec. 3.4')}) on "
                 f"{self.info.get('source', 'the recording')}: {self.info.get('samples', '?')} samples, {state} after "
                 f"{self.iterations} iterations ({self.message})",
                 f"log-likelihood {self.loglik_initial:.6g} at the initial guess, {self.loglik:.6g} at the estimate"]
        if len(self.attempts) > 1 or (self.attempts and self.attempts[0]["start"] != "initial guess"):
            lines.append("starts: " + "; ".join(f"{a['start']}: log p {a['loglik']:.6g}, "
                                                 f"{'converged' if a['converged'] else 'not converged'}, {a['seconds']:.1f} s"
                                                 for a in self.attempts))
        lines += [head, "-" * len(head)]
        for n, v0, v, s in zip(self.names, self.initial, self.estimate, self.std):
            std = f"{s:>10.3g}" if np.isfinite(s) else f"{'(at bound)' if n in self.at_bound else '—':>10}"
            lines.append(f"{n:<{w}} {v0:>12.6g} {v:>12.6g} {std}")
        for key, d in self.noise.items():
            if np.isfinite(d["log_std"]):
                lo, hi = np.exp(d["log_scale"] - 2 * d["log_std"]), np.exp(d["log_scale"] + 2 * d["log_std"])
                lines.append(f"{key} scaled by {d['scale']:.4g} (±2σ: {lo:.3g} to {hi:.3g})")
            else:
                lines.append(f"{key} scaled by {d['scale']:.4g}")
        for n in self.at_bound:
            if n in NOISE_NAMES and self.info.get("default_bounds", {}).get(n):
                what = "R" if n == "log_R_scale" else "Q"
                lines.append(f"{n} is held at its default bound ({'−' if self.estimate[self.names.index(n)] < 0 else '+'}"
                             f"log 10⁶): the likelihood keeps rising as {what} {'shrinks' if self.estimate[self.names.index(n)] < 0 else 'grows'}"
                             f"{' (the data are explained without ' + ('measurement' if what == 'R' else 'process') + ' noise)' if self.estimate[self.names.index(n)] < 0 else ''}; "
                             + ("the other standard errors hold with it fixed there" if self.success else
                                "held there while the others are fitted"))
        lines += [f"filter model: {n}" for n in self.notes]
        shift = self.info.get("smoothing_shift", 0.0)
        if shift > ACCURACY:
            lines.append(f"halving the smoothing widths (and the step) would move the estimate by {shift:.2g} standard "
                         "errors: the smoothing is part of the model here (try narrower widths: --smoothing 0.5, or smoothing=0.5 "
                         "in Python)")
        if self.success:
            lines.append(f"std: from the {INFORMATION}; integration: RK4, {self.substeps} step(s) per sample interval")
        else:
            lines.append("standard errors are not shown: they hold only at a stationary point of the likelihood, and "
                         "this is not one")
            lines.append(f"try next: {self.info.get('advice', '')}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()


class _Scaling:
    """Scaled unknowns φ: log θ for positive parameters, θ/|θ₀| for others, ρ itself for the noise scalings."""

    def __init__(self, names: Sequence[str], theta0: np.ndarray, lo: np.ndarray, hi: np.ndarray, explicit: set[str]):
        self.log = np.array([n not in NOISE_NAMES and theta0[i] > 0 and (lo[i] >= 0 or (n not in explicit))
                             for i, n in enumerate(names)])
        self.scale = np.where(self.log | np.isin(names, NOISE_NAMES) | (theta0 == 0), 1.0, np.abs(theta0))
        with np.errstate(divide="ignore"):
            self.lo = np.where(self.log, np.log(np.maximum(lo, 0.0)), lo / self.scale)
            self.hi = np.where(self.log, np.log(hi), hi / self.scale)

    def phi(self, theta: np.ndarray) -> np.ndarray:
        return np.where(self.log, np.log(np.where(self.log, theta, 1.0)), theta / self.scale)

    def admissible(self, theta: np.ndarray, theta0: np.ndarray) -> np.ndarray:
        """A start with every log-scaled (positive) unknown positive: one that another start (a simulation-error fit,
        which knows no sign) put at or below 0 starts at a thousandth of its initial guess instead."""
        return np.where(self.log & ~(theta > 0), 1e-3 * np.abs(theta0), theta)

    def theta(self, phi: np.ndarray) -> np.ndarray:
        return np.where(self.log, np.exp(np.where(self.log, phi, 0.0)), phi * self.scale)

    def dtheta(self, phi: np.ndarray) -> np.ndarray:
        return np.where(self.log, self.theta(phi), self.scale)

    def inside(self, phi: np.ndarray) -> np.ndarray:
        """φ moved strictly inside its bounds."""
        span = np.where(np.isfinite(self.hi - self.lo), self.hi - self.lo, 1.0)
        return np.clip(phi, self.lo + 1e-6 * span, self.hi - 1e-6 * span)


class _Objective:
    """−log p, its gradient and information in φ, memoised (the optimiser asks for them separately)."""

    def __init__(self, prob: _Problem, sc: _Scaling):
        self.prob, self.sc = prob, sc
        self.key: bytes | None = None
        self.value: tuple[float, np.ndarray, np.ndarray, float, np.ndarray, np.ndarray] | None = None
        self.evaluations = 0

    def __call__(self, phi: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
        key = phi.tobytes()
        if key != self.key:
            self.evaluations += 1
            theta = self.sc.theta(phi)
            ll, g, info = self.prob(theta)
            J = self.sc.dtheta(phi)
            if not np.isfinite(ll) or not np.all(np.isfinite(g)) or not np.all(np.isfinite(info)):
                # a step where the filter's value, slope or information is not finite (a root at 0, a blow-up) is
                # rejected like a step out of the bounds: the optimiser shrinks its trust region
                self.value = (np.inf, np.zeros_like(phi), np.eye(phi.size), -np.inf, g, info)
            else:
                self.value = (-ll, -g * J, info * np.outer(J, J), ll, g, info)
            self.key = key
        assert self.value is not None
        return self.value

    def decrement(self, phi: np.ndarray) -> tuple[float, np.ndarray]:
        """g^T 𝓘^{-1} g over the unknowns not held at a bound (NaN when 𝓘 is singular there), and that hold mask."""
        f, g, H = self(phi)[:3]
        tol = HELD * np.maximum(1.0, np.abs(phi))
        held = ((phi <= self.sc.lo + tol) & (g > 0)) | ((phi >= self.sc.hi - tol) & (g < 0))
        free = ~held
        if not free.any():
            return 0.0, held
        try:
            step = np.linalg.solve(H[np.ix_(free, free)], g[free])
        except np.linalg.LinAlgError:
            return float("nan"), held
        return float(g[free] @ step), held


@dataclass
class _Attempt:
    start: str
    phi: np.ndarray
    loglik: float
    converged: bool
    message: str
    iterations: int
    seconds: float
    decrement: float
    held: np.ndarray


#: Trust-region iterations per start, over its phases. Fisher scoring crawls where the model is misspecified and two
#: unknowns trade off (a record's Q and R scalings): the Cascaded Tanks grey-box fit from its guesses takes ~880 (16 s),
#: and a budget of 200 stopped it 0.4 standard errors short.
MAX_ITER = 1000


def _free(obj: _Objective, phi: np.ndarray, held: np.ndarray, max_iter: int) -> tuple[np.ndarray, int, str]:
    """SciPy's trust-exact on the unknowns not held (Fisher information as the Hessian; a step out of the bounds is
    rejected), stopped as soon as the scoring step is below DECREMENT_TOL."""
    from scipy.optimize import minimize

    sc, free = obj.sc, ~held
    full = phi.copy()

    def put(x: np.ndarray) -> np.ndarray:
        out = full.copy()
        out[free] = x
        return out

    def fun(x: np.ndarray) -> tuple[float, np.ndarray]:
        ph = put(x)
        if np.any(ph < sc.lo) or np.any(ph > sc.hi):
            return np.inf, np.zeros(x.size)
        f, g = obj(ph)[:2]
        return f, g[free]

    def hess(x: np.ndarray) -> np.ndarray:
        ph = put(x)
        return obj(ph)[2][np.ix_(free, free)] if np.all((ph >= sc.lo) & (ph <= sc.hi)) else np.eye(x.size)

    def stop(intermediate_result: Any) -> None:
        if obj.decrement(put(intermediate_result.x))[0] < DECREMENT_TOL:
            raise StopIteration

    with warnings.catch_warnings():   # a rejected step (out of bounds, or the filter blew up) has f = inf
        warnings.simplefilter("ignore", RuntimeWarning)
        sol = minimize(fun, phi[free], jac=True, hess=hess, method="trust-exact", callback=stop,
                       options={"maxiter": max_iter, "gtol": 1e-10, "initial_trust_radius": 0.5})
    return put(np.asarray(sol.x, dtype=float)), int(sol.nit), str(sol.message)


def _hold(obj: _Objective, phi: np.ndarray) -> np.ndarray:
    """Unknowns to hold at a bound: within two standard errors (or HELD) of a bound their gradient pushes against."""
    sc = obj.sc
    f, g, H = obj(phi)[:3]
    try:
        se = np.sqrt(np.maximum(np.diag(np.linalg.inv(H)), 0.0))
    except np.linalg.LinAlgError:
        se = np.zeros(phi.size)
    near = np.maximum(2 * se, HELD * np.maximum(1.0, np.abs(phi)))
    return ((phi - sc.lo <= near) & (g > 0)) | ((sc.hi - phi <= near) & (g < 0))


def _optimise(obj: _Objective, phi0: np.ndarray, start: str, max_iter: int) -> _Attempt:
    """One start: the noise levels alone, then all unknowns by trust-exact with an active set (unknowns near a bound
    their gradient pushes against held there) until no unknown changes sides."""
    sc, t0 = obj.sc, time.perf_counter()
    bounded = bool(np.any(np.isfinite(sc.lo)) or np.any(np.isfinite(sc.hi)))
    phi, nit, msg = phi0.copy(), 0, "the start is already stationary"
    noise = np.isin(obj.prob.names, NOISE_NAMES)
    if not obj.decrement(phi)[0] < DECREMENT_TOL and noise.any() and not noise.all():
        # the noise levels first, the parameters held: far from the optimum the innovations are many σ, and Fisher
        # scoring (Gauss-Newton) crawls on such large residuals; scaled to them, the joint problem is well posed
        phi, nit, msg = _free(obj, phi, ~noise, max_iter)
    if not obj.decrement(phi)[0] < DECREMENT_TOL:
        held = _hold(obj, phi) if bounded else np.zeros(phi.size, dtype=bool)
        for _ in range(phi.size + 1):
            phi = np.where(held & (obj(phi)[1] > 0), sc.lo, np.where(held, sc.hi, phi)) if held.any() else phi
            if obj.decrement(phi)[0] < DECREMENT_TOL or held.all():
                break
            if nit >= max_iter:   # the budget is per start, over its phases
                msg = f"the {max_iter} iterations of this start are spent"
                break
            phi, k, msg = _free(obj, phi, held, max_iter - nit)
            nit += k
            again = held | (_hold(obj, phi) if bounded else held)
            again &= ~(held & (obj.decrement(phi)[1] == 0))     # released: its gradient now points inside
            if np.array_equal(again, held):
                break
            held = again
    dec, held = obj.decrement(phi)
    ll = obj(phi)[3]
    drift = (np.abs(phi - phi0) > DRIFT) & ~held   # e.g. log a → −∞: the information vanishes with a, not the slope
    converged = bool(np.isfinite(ll) and dec < DECREMENT_TOL and not drift.any())
    if drift.any():
        msg = (f"{msg.rstrip('.')}; {', '.join(obj.prob.names[i] for i in np.flatnonzero(drift))} drifted by more than "
               f"a factor e^{DRIFT:g} (or {DRIFT:g} scales) from the start")
    elif converged:
        msg = (f"a further scoring step would move the estimate by {np.sqrt(max(dec, 0.0)):.2g} standard errors"
               + (f", {int(held.sum())} unknown(s) held at a bound" if held.any() else ""))
    elif np.isfinite(dec):
        msg = f"{msg.rstrip('.')}; a scoring step would still move the estimate by {np.sqrt(dec):.3g} standard errors"
    else:
        msg = f"{msg.rstrip('.')}; the Fisher information is singular here"
    return _Attempt(start, phi, float(ll), converged, msg, nit, time.perf_counter() - t0, dec, held)


def _simulation_start(prob: _Problem, names: Sequence[str], theta0: np.ndarray, bounds: Mapping[str, Any],
                      fit_x0: Sequence[str] | None, max_step: float | None) -> np.ndarray:
    """The unknowns with the parameters replaced by the simulation-error fit's (started from theta0)."""
    from ._simulation_error import fit_parameters

    system = prob.system
    if system.is_discrete:
        raise ModelError(f"{prob.caller}: start='simulation' needs a continuous-time model (the simulation-error fit "
                         "integrates it); start from the initial guess")
    params = list(prob.params)
    if not params:
        return theta0
    x0 = np.asarray(prob.d.xhat0, dtype=float).reshape(-1)[:system.n_states]
    sim = fit_parameters(system, prob.recording, params, x0=x0,
                         fit_x0=list(system.states) if fit_x0 is None else list(fit_x0),
                         initial=dict(zip(params, theta0[:len(params)])),
                         bounds={k: v for k, v in bounds.items() if k in params}, max_step=max_step)
    out = theta0.copy()
    out[:len(params)] = sim.estimate[:len(params)]
    return out


def _advice(att: _Attempt, names: Sequence[str], obj: _Objective, tried_simulation: bool, phi0: np.ndarray) -> str:
    """What to try after a fit that did not converge, from where it stopped."""
    tips = []
    g, H = obj(att.phi)[1:3]
    drift = [i for i in range(len(names)) if abs(att.phi[i] - phi0[i]) > DRIFT and not att.held[i]]
    for i in drift:   # far from the start and still pushed on: the optimum is at the edge of the parameter space
        side = "−∞" if att.phi[i] < phi0[i] else "+∞"
        what = {"log_R_scale": " (R → 0: the data are explained without measurement noise)" if side == "−∞" else "",
                "log_Q_scale": " (Q → 0: the data are explained without process noise)" if side == "−∞" else ""}
        scaled = "its log " if obj.sc.log[i] else ""
        tips.append(f"{names[i]} is drifting towards {scaled}{side}{what.get(names[i], '')}: bound it "
                    f"(bounds={{'{names[i]}': (lo, hi)}}, --bound {names[i]}=LO:HI)")
    if not tried_simulation:
        tips.append("start from the simulation-error fit (start='simulation', --start simulation)")
    if np.all(np.isfinite(H)):
        ev, V = np.linalg.eigh(H)
        if ev[0] <= 1e-10 * max(ev[-1], 1e-300) and not drift:
            big = np.argsort(-np.abs(V[:, 0]))[:2]
            tips.append(f"fix one of {', '.join(names[i] for i in big)} (the data hardly tell them apart)")
    exact = [str(n) for n in obj.prob.model.exact_switches]
    if exact:
        tips.append(f"smooth the switches {', '.join(exact[:3])} (smoothing > 0; drop --smoothing 0): on exact switches "
                    "the filter's likelihood jumps where its estimate crosses one")
    if not drift:
        tips.append("bound the unknowns that drift (bounds={'k': (0, 1)}, --bound k=0:1)")
    tips.append("more iterations or starts (max_iter, starts; --max-iter, --starts)")
    return "; ".join(tips)


def fit_likelihood(design: Any, recording: Recording, params: Sequence[str], *, learn_noise: bool = False,
                   initial: Mapping[str, float] | None = None,
                   bounds: Mapping[str, tuple[float | None, float | None]] | None = None,
                   start: Literal["initial", "simulation"] = "initial", starts: int = 4,
                   fit_x0: Sequence[str] | None = None, smoothing: float = 1.0, censor: bool = True,
                   max_step: float | None = None, on_missing: Literal["error", "skip"] = "error",
                   engine: Backend = "auto", max_iter: int = MAX_ITER, seed: int = 0) -> LikelihoodFit:
    """Estimate model parameters (and optionally scalings of Q and R) by maximising the innovations likelihood.

    The likelihood of `recording` under the continuous-discrete EKF or UKF `design` (see
    :func:`nlobs.log_likelihood`: saturating outputs censored at their limits, switches smoothed) is maximised by
    Fisher scoring in a trust region on scaled unknowns, with bounds (see the module docstring); the standard errors
    are from the inverse Fisher information at the optimum, and only reported when the fit converged. Unlike
    :func:`nlobs.fit_parameters` (simulation error) it accounts for process noise and can learn Q and R.

    Parameters
    ----------
    design : ObserverDesign or Observer
        :func:`nlobs.design_ekf` or :func:`nlobs.design_ukf` on the model (continuous-discrete, no bounds): its
        system's parameter values are the initial guesses; its Q, R, P0 and x̂0 are used (Q and R up to the
        learnt scalings).
    recording : Recording
    params : sequence of str
        The unknown parameters.
    learn_noise : bool
        Also estimate ρ_Q, ρ_R with Q = e^{ρ_Q} Q₀, R = e^{ρ_R} R₀ (started at 0).
    initial : mapping, optional
        Initial guesses by name, replacing the model's values.
    bounds : mapping of name to (lower, upper), optional
        Bounds of unknowns (None: unbounded on that side), e.g. ``{"k5": (0, 1)}``; an unknown with a positive
        initial guess is kept positive unless its bounds say otherwise (``(None, None)``: any sign).
    start : {"initial", "simulation"}
        Start from the initial guesses, or from the simulation-error fit (:func:`nlobs.fit_parameters` from the
        design's x̂0, with the initial states `fit_x0` fitted too).
    starts : int
        Most starts: when one does not converge, the next is the simulation-error fit (if not tried yet), then
        perturbations of the best point so far.
    fit_x0 : sequence of str, optional
        States whose initial value the simulation-error start fits (default: all).
    smoothing, censor
        As for :func:`nlobs.log_likelihood`.
    max_step, on_missing, engine
        As for :func:`nlobs.estimate`.
    max_iter : int
        Most optimiser iterations per start (default :data:`MAX_ITER`).
    seed : int
        Of the perturbed starts.

    Returns
    -------
    LikelihoodFit

    Raises
    ------
    ModelError
        For unknown names, bounds that exclude the initial guess, or nothing to fit.
    DataError
        When the filter's state is not finite at the initial guess (with where).
    """
    prob = _Problem(design, recording, params, learn_noise, max_step, on_missing, engine, "fit_likelihood",
                    smoothing, censor)
    if not prob.names:
        raise ModelError("fit_likelihood: nothing to fit: name unknown parameters or learn the noise")
    if int(starts) < 1:
        raise ModelError(f"fit_likelihood: `starts` must be at least 1, got {starts!r}")
    if start not in ("initial", "simulation"):
        raise ModelError(f"fit_likelihood: `start` must be 'initial' or 'simulation', got {start!r}")
    names = prob.names
    theta0, lo, hi = _guesses_and_bounds(prob, initial, bounds)
    ll0 = prob(theta0)[0]
    if not np.isfinite(ll0):
        raise DataError(f"fit_likelihood: the filter's state is not finite {prob.where_not_finite(theta0)} at the initial "
                        f"guess ({', '.join(f'{n} = {v:.6g}' for n, v in zip(names, theta0))}); start elsewhere, bound "
                        "the unknowns, or give a smaller max_step")
    sc = _Scaling(names, theta0, lo, hi, set(bounds or {}))
    obj = _Objective(prob, sc)
    rng = np.random.default_rng(seed)
    attempts: list[_Attempt] = []
    tried_sim = start == "simulation"
    first = _simulation_start(prob, names, theta0, bounds or {}, fit_x0, max_step) if tried_sim else theta0
    plan = [("simulation-error fit" if tried_sim else "initial guess", first)]
    while plan and len(attempts) < int(starts):
        label, th = plan.pop(0)
        att = _optimise(obj, sc.phi(sc.admissible(np.clip(th, lo, hi), theta0)), label, max_iter)
        if att.converged:   # polished at the integration its estimate needs: a start that loses it there did not
            att, obj = _refine(prob, obj, att, max_iter)   # converge, and the next one is tried (at that integration)
        attempts.append(att)
        if attempts[-1].converged or len(attempts) >= int(starts):
            break   # (a start not taken is not planned: the simulation-error fit costs a fit of its own)
        if not tried_sim and not prob.system.is_discrete and prob.params:
            tried_sim = True
            plan.append(("simulation-error fit", _simulation_start(prob, names, theta0, bounds or {}, fit_x0, max_step)))
        else:
            best = max(attempts, key=lambda a: a.loglik)
            phi = best.phi + PERTURBATION * rng.standard_normal(best.phi.size)
            plan.append((f"perturbed start {len(attempts)}", sc.theta(sc.inside(phi))))
    return _result(prob, obj, attempts, theta0, ll0, tried_sim, set(bounds or {}))


def _refine(prob: _Problem, obj: _Objective, best: _Attempt, max_iter: int) -> tuple[_Attempt, _Objective]:
    """At a converged estimate: integrate finer while the flow's stiffness there asks for it (polishing each time)."""
    sc = obj.sc
    while best.converged:
        need = prob.needed_substeps(sc.theta(best.phi))
        if need <= prob.n_sub:
            break
        if need > MAX_SUBSTEPS:
            best.converged = False
            best.message = (f"{best.message}; but the flow at the estimate needs {need} RK4 sub-steps per sample "
                            f"interval, above the {MAX_SUBSTEPS} the recursion takes: bound the unknowns that make it stiff")
            break
        prob.set_substeps(need)
        obj = _Objective(prob, sc)
        best = _optimise(obj, best.phi, f"{best.start}, integrated with {need} sub-steps", max_iter)
    return best, obj


def _guesses_and_bounds(prob: _Problem, initial: Mapping[str, float] | None,
                        bounds: Mapping[str, Any] | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    names = prob.names
    theta0 = prob.theta0()
    for k, v in (initial or {}).items():
        if k not in names:
            raise ModelError(f"fit_likelihood: `initial` names {k!r}, which is not an unknown ({', '.join(names)})")
        theta0[names.index(k)] = float(v)
    lo, hi = np.full(len(names), -np.inf), np.full(len(names), np.inf)
    for k, pair in (bounds or {}).items():
        if k not in names:
            raise ModelError(f"fit_likelihood: `bounds` names {k!r}, which is not an unknown ({', '.join(names)})")
        try:
            a, b = pair
        except (TypeError, ValueError):
            raise ModelError(f"fit_likelihood: the bounds of {k!r} must be a pair (lower, upper), got {pair!r}") from None
        lo[names.index(k)] = -np.inf if a is None else float(a)
        hi[names.index(k)] = np.inf if b is None else float(b)
    for i, n in enumerate(names):   # a noise scaling within a factor 10⁶ of the design's unless bounded otherwise
        if n in NOISE_NAMES and n not in (bounds or {}):
            lo[i], hi[i] = -NOISE_BOUND, NOISE_BOUND
    bad = np.flatnonzero((lo >= hi) | (theta0 < lo) | (theta0 > hi))
    if bad.size:
        k = int(bad[0])
        raise ModelError(f"fit_likelihood: the initial guess {names[k]} = {theta0[k]:g} is not inside its bounds "
                         f"[{lo[k]:g}, {hi[k]:g}]; change the guess (initial=) or the bounds")
    return theta0, lo, hi


def _result(prob: _Problem, obj: _Objective, attempts: list[_Attempt], theta0: np.ndarray, ll0: float,
            tried_sim: bool, explicit: set[str]) -> LikelihoodFit:
    names, sc = prob.names, obj.sc
    conv = [a for a in attempts if a.converged]
    best = conv[0] if conv else max(attempts, key=lambda a: a.loglik)
    theta = sc.theta(best.phi)
    ll, g, info = prob(theta)
    q = len(names)
    cov, std = np.full((q, q), np.nan), np.full(q, np.nan)
    if best.converged:
        free = ~best.held
        try:
            sub = np.linalg.inv(info[np.ix_(free, free)])
            if np.all(np.isfinite(sub)) and np.all(np.diag(sub) > 0):
                cov[np.ix_(free, free)] = sub
                std = np.sqrt(np.where(np.isnan(np.diag(cov)), np.nan, np.abs(np.diag(cov))))
        except np.linalg.LinAlgError:
            pass
    params = list(prob.params)
    fitted = prob.system.with_params(**{p: float(v) for p, v in zip(params, theta)}) if params else prob.system
    v = prob.d.certificate.values
    extra = {"source": prob.source, "samples": prob.N, "information": info.tolist(), "decrement": best.decrement,
             "Q0": np.asarray(v["Q"], dtype=float), "R0": np.asarray(v["R"], dtype=float), "design_values": dict(v),
             "xhat0": np.asarray(prob.d.xhat0, dtype=float), "censored_samples": int(np.count_nonzero(prob.codes)),
             "smoothing_widths": {s.text: s.width for s in prob.model.smoothed}, "one_step": prob.one_step(theta),
             "default_bounds": {n: n not in explicit for n in names if n in NOISE_NAMES},
             "smoothing_shift": prob.refinement_shift(theta) if best.converged and prob.model.smoothed else 0.0}
    if not best.converged:
        extra["advice"] = _advice(best, names, obj, tried_sim, sc.phi(theta0))
    att = tuple({"start": a.start, "loglik": a.loglik, "converged": a.converged, "iterations": a.iterations,
                 "seconds": a.seconds, "message": a.message} for a in attempts)
    return LikelihoodFit(names, theta, std, cov, theta0, ll, ll0, fitted, prob.d.method, prob.n_sub, best.converged,
                         best.message, best.iterations, g, tuple(n for n, h in zip(names, best.held) if h), att,
                         tuple(prob.model.notes(prob.codes)), info=extra)
