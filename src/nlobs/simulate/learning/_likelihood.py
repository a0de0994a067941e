"""The innovations log-likelihood of a recording under a continuous-discrete EKF or UKF, and learning from it.

The filter's innovations ν_k = y_k − ŷ_k⁻ with covariances S_k give the prediction-error decomposition

.. math::

    \\log p(y_{0:N-1} \\mid \\theta) = \\sum_k -\\tfrac12\\big(\\log\\det(2\\pi S_k) + \\nu_k^\\top S_k^{-1} \\nu_k\\big)

(Schweppe (1965); Harvey (1989), sec. 3.4), exact for a linear-Gaussian model and the usual approximate
likelihood for a nonlinear one. θ holds model parameters and, optionally, log-scalings of Q and R
(Q = e^{ρ_Q} Q₀, R = e^{ρ_R} R₀). Outputs missing at a sample are left out of its term.

For a discrete-time model (a map) the prediction is one step of the map, as in the map's EKF and UKF
(the UKF's update reusing its propagated sigma points).

The filter recursion is a CasADi function of (state, sample, θ): between samples RK4 of the same mean
and covariance flows as :func:`nlobs.design_ekf` / :func:`nlobs.design_ukf` (a fixed number of
sub-steps per interval, from the filter's own rule at the initial guess, so the likelihood is a smooth
function of θ; inputs held between samples, zero-order hold), then the same update. Its derivatives in θ are carried along the recursion by CasADi's
forward-mode automatic differentiation (one directional derivative per unknown, no finite differences),
in one compiled loop over the samples, which also accumulates the Fisher information of the
innovations (the expected Hessian of −log p; Harvey (1989), sec. 3.4)

.. math::

    \\mathcal I_{ij} = \\sum_k \\partial_i\\nu_k^\\top S_k^{-1} \\partial_j\\nu_k
    + \\tfrac12 \\operatorname{tr}\\big(S_k^{-1}\\partial_i S_k\\, S_k^{-1}\\partial_j S_k\\big).

The fit maximises log p by a trust-region Newton method on (gradient, 𝓘) (Fisher scoring), and the
standard errors are the square roots of the diagonal of 𝓘⁻¹ at the optimum.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import casadi as ca
import numpy as np

from ...design import ObserverDesign
from ...engine import Backend, compile_system, rows
from ...engine._integrate import rk4_step_rate
from ...errors import DataError, ModelError, PreconditionError
from ...references import cite
from .._loop import Loop
from .._recorded import Recording

__all__ = ["log_likelihood", "fit_likelihood", "LikelihoodFit", "LIKELIHOOD_KINDS"]

#: Observer kinds whose innovations give a likelihood here (continuous-discrete, without state bounds).
LIKELIHOOD_KINDS = ("ekf", "ukf")
#: The names of the learnt noise log-scalings ρ_Q, ρ_R among the unknowns.
NOISE_NAMES = ("log_Q_scale", "log_R_scale")
#: The most RK4 sub-steps per interval in the likelihood's recursion (all intervals take the same number).
MAX_SUBSTEPS = 64
INFORMATION = ("Fisher information of the innovations (expected Hessian of −log-likelihood, exact derivatives by "
               "forward automatic differentiation through the filter)")


def _check(design: Any, caller: str) -> ObserverDesign:
    d = getattr(design, "design", design)
    if not isinstance(d, ObserverDesign):
        raise TypeError(f"{caller}: give an EKF or UKF design (nlobs.design_ekf / design_ukf), got {type(design).__name__}")
    if d.method not in LIKELIHOOD_KINDS or d.update is None:
        raise PreconditionError(f"{caller}: observer kind {d.method!r}{' in continuous mode' if d.method == 'ekf' else ''} "
                                f"has no innovations likelihood here; supported: the continuous-discrete kinds "
                                f"{', '.join(LIKELIHOOD_KINDS)}")
    if "bounds" in d.certificate.values:
        raise PreconditionError(f"{caller}: the {d.method} design has state bounds; the likelihood supports "
                                f"{', '.join(LIKELIHOOD_KINDS)} without bounds only")
    return d


class _Recursion:
    """The filter with its forward sensitivities: one compiled step per sample (see the module docstring).

    Step state: [x, vec P, vec ∂(x, P)/∂θ, log p so far, ∂ log p/∂θ, vec 𝓘]; constant c: [all model parameters,
    ρ_Q, ρ_R]; θ are the entries `free` of c. Data row: [t_k, dt_k, u_k, u_{k+1}, y_{k+1}, m_{k+1}] (dt = 0 for
    the first sample: the update of the prior)."""

    def __init__(self, d: ObserverDesign, free: Sequence[int], n_sub: int):
        system = d.system
        n, nu, ny, npar = system.n_states, system.n_inputs, system.n_outputs, system.n_params
        nn, q = n * n, len(free)
        self.n, self.q, self.nc = n, q, npar + 2
        cs = compile_system(system)
        f = ca.Function("f", [cs.t, cs.x, cs.u, cs.p], [cs.f_sx])
        fF = ca.Function("fF", [cs.t, cs.x, cs.u, cs.p], [cs.f_sx, ca.jacobian(cs.f_sx, cs.x)])
        h = ca.Function("h", [cs.t, cs.x, cs.u, cs.p], [cs.h_sx])
        hH = ca.Function("hH", [cs.t, cs.x, cs.u, cs.p], [cs.h_sx, ca.jacobian(cs.h_sx, cs.x)])
        v = d.certificate.values
        Q0, R0 = ca.DM(np.asarray(v["Q"], dtype=float)), ca.DM(np.asarray(v["R"], dtype=float))
        core_n = n + nn
        s, a, c = ca.SX.sym("s", core_n), ca.SX.sym("a", 2 + 2 * nu + 2 * ny), ca.SX.sym("c", npar + 2)
        p, Q, R = c[:npar], ca.exp(c[npar]) * Q0, ca.exp(c[npar + 1]) * R0
        t, dt = a[0], a[1]
        u0, u1 = rows(a, 2, 2 + nu), rows(a, 2 + nu, 2 + 2 * nu)
        y1, m1 = rows(a, 2 + 2 * nu, 2 + 2 * nu + ny), rows(a, 2 + 2 * nu + ny, 2 + 2 * nu + 2 * ny)
        sym = lambda M: (M + M.T) / 2  # noqa: E731
        ukf = d.method == "ukf"
        if ukf:
            from ...design._ukf import unscented_weights

            wm, wc, spread = unscented_weights(n, float(v["alpha"]), float(v["beta"]), float(v["kappa"]))

            def sigma(m_: Any, P_: Any) -> list[Any]:
                L = ca.chol(P_).T * np.sqrt(spread)
                return [m_] + [m_ + L[:, i] for i in range(n)] + [m_ - L[:, i] for i in range(n)]

        def flow(tt: Any, z: Any, _k: int) -> Any:  # design_ekf / design_ukf, continuous-discrete, Q scaled
            x, P = z[:n], sym(ca.reshape(z[n:], n, n))
            if not ukf:
                fx, F = fF(tt, x, u0, p)
                return ca.vertcat(fx, ca.vec(sym(F @ P + P @ F.T + Q)))
            X = sigma(x, P)
            Fs = [f(tt, xi, u0, p) for xi in X]
            fbar = sum((float(wm[i]) * Fs[i] for i in range(2 * n + 1)), ca.SX.zeros(n))
            cross = sum((float(wc[i]) * (X[i] - x) @ (Fs[i] - fbar).T for i in range(2 * n + 1)), ca.SX.zeros(n, n))
            return ca.vertcat(fbar, ca.vec(sym(cross + cross.T + Q)))

        pts = None   # a map's UKF updates with its propagated sigma points (as design_ukf's discrete form)
        if system.is_discrete:   # one step of the map from t_k with u_k (none before the first sample: dt = 0)
            x0_, P0_ = s[:n], sym(ca.reshape(s[n:], n, n))
            if not ukf:
                fx, F = fF(t, x0_, u0, p)
                x = ca.if_else(dt > 0, fx, x0_)
                P = ca.if_else(dt > 0, sym(F @ P0_ @ F.T + Q), P0_)
            else:
                X0 = sigma(x0_, P0_)
                Fs = [f(t, xi, u0, p) for xi in X0]
                fbar = sum((float(wm[i]) * Fs[i] for i in range(2 * n + 1)), ca.SX.zeros(n))
                Pf = sum((float(wc[i]) * (Fs[i] - fbar) @ (Fs[i] - fbar).T for i in range(2 * n + 1)), ca.SX.zeros(n, n))
                x = ca.if_else(dt > 0, fbar, x0_)
                P = ca.if_else(dt > 0, sym(Pf + Q), P0_)
                pts = [ca.if_else(dt > 0, a_, b_) for a_, b_ in zip(Fs, X0)]
        else:
            z = s
            hh = dt / n_sub
            for i in range(n_sub):
                z, _ = rk4_step_rate(flow, t + i * hh, z, hh)
            x, P = z[:n], sym(ca.reshape(z[n:], n, n))
        tk = t + dt
        Md = ca.diag(m1)
        if not ukf:  # Joseph form, as design_ekf
            yhat, Hx = hH(tk, x, u1, p)
            Hm = Md @ Hx
            Rm = Md @ R @ Md + ca.diag(1 - m1)
            S = sym(Hm @ P @ Hm.T + Rm)
            K = ca.solve(S, Hm @ P).T
            IKH = ca.DM.eye(n) - K @ Hm
            P_plus = sym(IKH @ P @ IKH.T + K @ Rm @ K.T)
        else:  # as design_ukf
            X = sigma(x, P) if pts is None else pts
            Y = [h(tk, xi, u1, p) for xi in X]
            yhat = sum((float(wm[i]) * Y[i] for i in range(2 * n + 1)), ca.SX.zeros(ny))
            Sf = sum((float(wc[i]) * (Y[i] - yhat) @ (Y[i] - yhat).T for i in range(2 * n + 1)), ca.SX.zeros(ny, ny)) + R
            Cxy = sum((float(wc[i]) * (X[i] - x) @ (Y[i] - yhat).T for i in range(2 * n + 1)), ca.SX.zeros(n, ny))
            S = sym(Md @ Sf @ Md + ca.diag(1 - m1))
            K = ca.solve(S, (Cxy @ Md).T).T
            P_plus = sym(P - K @ S @ K.T)
        nu_ = m1 * (y1 - yhat)
        x_plus = x + K @ nu_
        Lc = ca.chol(S)  # upper: S = LᵀL
        logdet = 2 * ca.sum1(ca.log(ca.diag(Lc)))
        w = ca.solve(Lc.T, nu_)
        ll = -0.5 * (ca.sum1(m1) * np.log(2 * np.pi) + logdet + ca.dot(w, w))
        core_next = ca.vertcat(x_plus, ca.vec(P_plus))
        self.core = ca.Function("lik_core", [s, a, c], [core_next, ll, nu_, ca.vec(S)])
        self.ns = core_n + core_n * q + 1 + q + q * q
        st, cc = ca.SX.sym("st", self.ns), ca.SX.sym("cc", npar + 2)
        sc = st[:core_n]
        sens = ca.reshape(st[core_n:core_n + core_n * q], core_n, q)
        o = core_n + core_n * q
        acc_ll, acc_g, acc_I = st[o], st[o + 1:o + 1 + q], ca.reshape(st[o + 1 + q:], q, q)
        cn, lln, nun, Sv = self.core(sc, a, cc)
        Sm = ca.reshape(Sv, ny, ny)
        seed_c = ca.DM.zeros(npar + 2, q)
        for j, k in enumerate(free):
            seed_c[k, j] = 1
        out = ca.vertcat(cn, lln, nun, Sv)
        D = ca.jtimes(out, ca.vertcat(sc, cc), ca.vertcat(sens, seed_c)) if q else ca.SX.zeros(out.numel(), 0)
        dcore, dll = D[:core_n, :], D[core_n, :]
        dnu, dS = D[core_n + 1:core_n + 1 + ny, :], D[core_n + 1 + ny:, :]
        Sinv = ca.inv(Sm)
        info = ca.SX.zeros(q, q)
        Si_dS = [Sinv @ ca.reshape(dS[:, j], ny, ny) for j in range(q)]
        for i in range(q):
            for j in range(i, q):
                e = ca.dot(dnu[:, i], Sinv @ dnu[:, j]) + 0.5 * ca.trace(Si_dS[i] @ Si_dS[j])
                info[i, j] = e
                info[j, i] = e
        nxt = ca.vertcat(cn, ca.vec(dcore), acc_ll + lln, acc_g + dll.T, ca.vec(acc_I + info))
        self.step = ca.Function(f"{d.method}_likelihood_step", [st, a, cc], [ca.densify(nxt)])
        self.loop = Loop(self.step)

    def __call__(self, s0core: np.ndarray, A: np.ndarray, c: np.ndarray, engine: Backend) -> tuple[float, np.ndarray, np.ndarray]:
        q = self.q
        s0 = np.zeros(self.ns)
        s0[:s0core.size] = s0core
        last = self.loop(s0, A, c, engine)[-1]
        if not np.all(np.isfinite(last)):
            return -np.inf, np.full(q, np.nan), np.full((q, q), np.nan)
        o = self.ns - 1 - q - q * q
        return float(last[o]), last[o + 1:o + 1 + q].copy(), last[o + 1 + q:].reshape(q, q)


_CACHE: dict[tuple[Any, ...], tuple[ObserverDesign, _Recursion]] = {}


def _recursion(d: ObserverDesign, free: Sequence[int], n_sub: int) -> _Recursion:
    key = (id(d), tuple(free), n_sub)
    hit = _CACHE.get(key)
    if hit is not None and hit[0] is d:
        return hit[1]
    rec = _Recursion(d, free, n_sub)
    _CACHE[key] = (d, rec)  # keeps the design alive, so its id is not reused
    if len(_CACHE) > 32:
        _CACHE.pop(next(iter(_CACHE)))
    return rec


class _Problem:
    """The likelihood of one recording as a function of θ (the named parameters, then ρ_Q, ρ_R if learnt)."""

    def __init__(self, design: Any, recording: Recording, params: Sequence[str], learn_noise: bool,
                 max_step: float | None, on_missing: str, engine: Backend, caller: str):
        d = _check(design, caller)
        system = d.system
        if not isinstance(recording, Recording):
            raise TypeError(f"{caller}: `recording` must be an nlobs.Recording, got {type(recording).__name__}")
        if tuple(recording.output_names) != tuple(system.outputs) or tuple(recording.input_names) != tuple(system.inputs):
            raise ModelError(f"{caller}: the model {system.name!r} has outputs {list(system.outputs)} and inputs "
                             f"{list(system.inputs)}; the recording has {list(recording.output_names)} and "
                             f"{list(recording.input_names)}")
        params = list(params)
        bad = [p for p in params if p not in system.param_names]
        if bad:
            raise ModelError(f"{caller}: {bad[0]!r} is not a parameter of {system.name!r}; its parameters: "
                             f"{', '.join(system.param_names) or '(none)'}")
        if len(set(params)) != len(params):
            raise ModelError(f"{caller}: a parameter is named twice in {params}")
        if learn_noise and set(params) & set(NOISE_NAMES):
            raise ModelError(f"{caller}: a model parameter named {sorted(set(params) & set(NOISE_NAMES))[0]!r} clashes with the "
                             "learnt noise scalings; rename it")
        mask = recording.check_finite(on_missing)
        if not mask.any():
            raise DataError(f"{caller}: the recording ({recording.source}) has no measured output sample")
        self.d, self.system, self.params, self.learn_noise = d, system, params, learn_noise
        npar = system.n_params
        self.free = [system.param_names.index(p) for p in params] + ([npar, npar + 1] if learn_noise else [])
        self.names = tuple(params) + (NOISE_NAMES if learn_noise else ())
        self.c = np.concatenate([np.asarray(system.param_values, dtype=float), [0.0, 0.0]])
        t, u = recording.t, recording.u
        y = np.where(mask > 0, recording.y, 0.0)
        # sub-steps: the filter's own rule, run at the initial guess (the most it takes in one interval)
        from ...observer._compiled import compiled_observer

        if system.is_discrete:   # a map: one step per sample, on the model's grid
            from .._discrete import check_map_grid

            check_map_grid(system, t, f"{caller}: recording ({recording.source})")
            traj = None
            self.n_sub = 1
        else:
            traj = compiled_observer(d).run(t, u=u, y=y, mask=mask, max_step=max_step, engine=engine, name=caller)
            self.n_sub = max(1, int(traj.substeps.max()))
        if self.n_sub > MAX_SUBSTEPS:
            k = int(np.argmax(traj.substeps))
            raise DataError(f"{caller}: the filter takes {self.n_sub} RK4 sub-steps in the interval from t = {t[k]:g} to "
                            f"{t[k + 1]:g} (the most in any interval); the likelihood's recursion takes the same number in "
                            f"every interval, at most {MAX_SUBSTEPS}: split the recording at long gaps, or resample it")
        first = np.concatenate([[t[0], 0.0], u[0], u[0], y[0], mask[0]])
        rest = np.hstack([t[:-1, None], np.diff(t)[:, None], u[:-1], u[1:], y[1:], mask[1:]])
        self.A = np.vstack([first, rest])
        self.s0 = np.concatenate([np.asarray(d.xhat0, dtype=float).reshape(-1),
                                  np.asarray(d.certificate.values["P0"], dtype=float).reshape(-1, order="F")])
        self.engine = engine
        self.rec = _recursion(d, self.free, self.n_sub)
        self.source = recording.source
        self.N = t.size

    def theta0(self) -> np.ndarray:
        return self.c[self.free].copy()

    def __call__(self, theta: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        c = self.c.copy()
        c[self.free] = theta
        return self.rec(self.s0, self.A, c, self.engine)


def log_likelihood(design: Any, recording: Recording, *, params: Sequence[str] = (), learn_noise: bool = False,
                   values: Mapping[str, float] | None = None, max_step: float | None = None,
                   on_missing: Literal["error", "skip"] = "error", engine: Backend = "auto") -> tuple[float, np.ndarray]:
    """The innovations log-likelihood of `recording` under an EKF or UKF design, and its gradient.

    Parameters
    ----------
    design : ObserverDesign or Observer
        A continuous-discrete :func:`nlobs.design_ekf` or :func:`nlobs.design_ukf` (its Q, R, P0, x̂0 and,
        for the UKF, its sigma-point scaling are used; the model's parameter values are those of its system).
    recording : Recording
    params : sequence of str
        Parameters to differentiate with respect to (the gradient's first entries, in this order).
    learn_noise : bool
        Also differentiate with respect to ρ_Q, ρ_R (Q = e^{ρ_Q} Q, R = e^{ρ_R} R), the gradient's last two entries.
    values : mapping, optional
        Values replacing the model's (names from `params`, and ``"log_Q_scale"``, ``"log_R_scale"``).
    max_step, on_missing, engine
        As for :func:`nlobs.estimate` (the sub-steps per interval are the most the filter takes in one).

    Returns
    -------
    (float, numpy.ndarray)
        log p(y | θ) and its gradient in θ (automatic differentiation through the filter; -inf and NaN when the
        filter's state becomes non-finite).
    """
    prob = _Problem(design, recording, params, learn_noise, max_step, on_missing, engine, "log_likelihood")
    theta = prob.theta0()
    for k, v in (values or {}).items():
        if k not in prob.names:
            raise ModelError(f"log_likelihood: `values` names {k!r}, which is not one of {', '.join(prob.names) or '(none)'}")
        theta[prob.names.index(k)] = float(v)
    ll, g, _ = prob(theta)
    return ll, g


@dataclass(frozen=True, eq=False)
class LikelihoodFit:
    """The result of :func:`fit_likelihood`.

    Attributes
    ----------
    names : tuple of str
        The unknowns: parameter names, then ``"log_Q_scale"``, ``"log_R_scale"`` when the noise was learnt.
    estimate, std : numpy.ndarray
        Estimates and standard errors (from the inverse Fisher information; NaN where it is singular).
    covariance : numpy.ndarray
    initial : numpy.ndarray
    loglik, loglik_initial : float
        log p(y | θ) at the estimate and at the initial guess.
    system : System
        The model with the fitted parameter values.
    kind : str
        ``"ekf"`` or ``"ukf"``.
    substeps : int
        RK4 sub-steps per sample interval in the filter recursion.
    success : bool
    message : str
    iterations : int
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
    info: Mapping[str, Any] = field(default_factory=dict)

    @property
    def parameters(self) -> dict[str, dict[str, float]]:
        """``{name: {"estimate", "std"}}`` of the model parameters."""
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

    def to_dict(self) -> dict[str, Any]:
        return {"method": "likelihood", "observer": self.kind, "parameters": self.parameters, "noise_scaling": self.noise,
                "names": list(self.names), "covariance": self.covariance.tolist(),
                "initial": dict(zip(self.names, self.initial.tolist())), "loglik": self.loglik,
                "loglik_initial": self.loglik_initial, "gradient": self.gradient.tolist(), "success": self.success,
                "message": self.message, "iterations": self.iterations, "substeps": self.substeps,
                "std_from": INFORMATION}

    def summary(self) -> str:
        w = max(12, *(len(n) for n in self.names))
        head = f"{'unknown':<{w}} {'initial':>12} {'estimate':>12} {'std':>10}"
        lines = [f"innovations likelihood ({self.kind.upper()}; {cite('schweppe1965')}, {cite('harvey1989', 'sec. 3.4')}) on {self.info.get('source', 'the recording')}: "
                 f"{self.info.get('samples', '?')} samples, {self.iterations} iterations, "
                 f"{'converged' if self.success else 'NOT converged'} ({self.message})",
                 f"log-likelihood {self.loglik_initial:.6g} at the initial guess, {self.loglik:.6g} at the estimate",
                 head, "-" * len(head)]
        for n, v0, v, s in zip(self.names, self.initial, self.estimate, self.std):
            lines.append(f"{n:<{w}} {v0:>12.6g} {v:>12.6g} {s:>10.3g}")
        for key, d in self.noise.items():
            lo, hi = np.exp(d["log_scale"] - 2 * d["log_std"]), np.exp(d["log_scale"] + 2 * d["log_std"])
            lines.append(f"{key} scaled by {d['scale']:.4g} (±2σ: {lo:.3g} to {hi:.3g})")
        lines.append(f"std: from the {INFORMATION}; integration: RK4, {self.substeps} step(s) per sample interval")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()


def fit_likelihood(design: Any, recording: Recording, params: Sequence[str], *, learn_noise: bool = False,
                   initial: Mapping[str, float] | None = None, max_step: float | None = None,
                   on_missing: Literal["error", "skip"] = "error", engine: Backend = "auto",
                   max_iter: int = 100) -> LikelihoodFit:
    """Estimate model parameters (and optionally scalings of Q and R) by maximising the innovations likelihood.

    The likelihood of `recording` under the continuous-discrete EKF or UKF `design` (see the module
    docstring) is maximised by a trust-region Newton method on its exact gradient and the Fisher
    information of the innovations (Fisher scoring), both from forward automatic differentiation through
    the compiled filter; the standard errors are from the inverse Fisher information at the optimum. Unlike
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
    max_step, on_missing, engine
        As for :func:`nlobs.estimate`.
    max_iter : int
        Most optimiser iterations.

    Returns
    -------
    LikelihoodFit
    """
    from scipy.optimize import minimize

    prob = _Problem(design, recording, params, learn_noise, max_step, on_missing, engine, "fit_likelihood")
    if not prob.names:
        raise ModelError("fit_likelihood: nothing to fit: name unknown parameters or learn the noise")
    theta0 = prob.theta0()
    for k, v in (initial or {}).items():
        if k not in prob.names:
            raise ModelError(f"fit_likelihood: `initial` names {k!r}, which is not an unknown ({', '.join(prob.names)})")
        theta0[prob.names.index(k)] = float(v)
    scale = np.where(np.arange(theta0.size) < len(prob.params), np.maximum(np.abs(theta0), 1e-8), 1.0)
    ll0, g0, _ = prob(theta0)
    if not np.isfinite(ll0):
        raise DataError(f"fit_likelihood: the filter's state is not finite at the initial guess "
                        f"({', '.join(f'{n} = {v:.6g}' for n, v in zip(prob.names, theta0))}); start elsewhere or give a "
                        "smaller max_step")
    memo: dict[bytes, tuple[float, np.ndarray, np.ndarray]] = {}

    def evaluate(phi: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        key = phi.tobytes()
        if key not in memo:
            memo.clear()
            ll, g, info = prob(phi * scale)
            if not np.isfinite(ll):
                memo[key] = (np.inf, np.zeros_like(phi), np.eye(phi.size))
            else:
                memo[key] = (-ll, -g * scale, info * np.outer(scale, scale))
        return memo[key]

    sol = minimize(lambda ph: evaluate(ph)[:2], theta0 / scale, jac=True, hess=lambda ph: evaluate(ph)[2],
                   method="trust-exact", options={"gtol": 1e-5, "maxiter": max_iter})
    theta = sol.x * scale
    ll, g, info = prob(theta)
    try:
        cov = np.linalg.inv(info)
        if not np.all(np.isfinite(cov)) or np.any(np.diag(cov) < 0):
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        cov = np.full_like(info, np.nan)
    std = np.sqrt(np.diag(cov))
    # converged when a further scoring step would move θ by far less than its standard error: the Newton
    # decrement gᵀ𝓘⁻¹g (the log-likelihood a step could still gain) is below 1e-6
    decrement = float(g @ cov @ g) if np.all(np.isfinite(cov)) else float("nan")
    success = bool(sol.success) or decrement < 1e-6
    message = str(sol.message) if sol.success else (
        f"Newton decrement gᵀ𝓘⁻¹g = {decrement:.2g} < 1e-6: no scoring step can gain more" if success else str(sol.message))
    fitted = prob.system.with_params(**{p: float(v) for p, v in zip(prob.params, theta)}) if prob.params else prob.system
    return LikelihoodFit(prob.names, theta, std, cov, theta0, ll, ll0, fitted, prob.d.method, prob.n_sub,
                         success, message, int(sol.nit), g,
                         info={"source": prob.source, "samples": prob.N, "information": info.tolist(), "decrement": decrement})
