"""The innovations log-likelihood of a recording under a continuous-discrete EKF or UKF.

The filter's innovations ν_k = y_k − ŷ_k⁻ with covariances S_k give the prediction-error decomposition

.. math::

    \\log p(y_{0:N-1} \\mid \\theta) = \\sum_k -\\tfrac12\\big(\\log\\det(2\\pi S_k) + \\nu_k^\\top S_k^{-1} \\nu_k\\big)

(Schweppe (1965); Harvey (1989), sec. 3.4), exact for a linear-Gaussian model and the usual approximate
likelihood for a nonlinear one. θ holds model parameters and, optionally, log-scalings of Q and R
(Q = e^{ρ_Q} Q₀, R = e^{ρ_R} R₀). Outputs missing at a sample are left out of its term.

On a piecewise model (abs, sign, min, max, sat) the filter runs the model of :mod:`._regimes`: an output
that saturates at a known limit is censored where the recording sits at the limit (its term is
log Φ((ŷ − c)/√S), no update there; elsewhere the filter updates with the unsaturated branch), and the other
switches are smoothed over the distance their argument moves in one integration step, so that the
likelihood is a continuous, smooth function of θ (the EKF's on the exact switches is not).

For a discrete-time model (a map) the prediction is one step of the map, as in the map's EKF and UKF
(the UKF's update reusing its propagated sigma points).

The filter recursion is a CasADi function of (state, sample, θ): between samples RK4 of the same mean
and covariance flows as :func:`nlobs.design_ekf` / :func:`nlobs.design_ukf` (a fixed number of
sub-steps per interval, from the filter's own rule at the initial guess, so the likelihood is a smooth
function of θ; inputs held between samples, zero-order hold), then the same update. Its derivatives in θ are
carried along the recursion by CasADi's forward-mode automatic differentiation (one directional derivative per
unknown, no finite differences), in one compiled loop over the samples, which also accumulates the Fisher
information of the innovations (the expected Hessian of −log p; Harvey (1989), sec. 3.4)

.. math::

    \\mathcal I_{ij} = \\sum_k \\partial_i\\nu_k^\\top S_k^{-1} \\partial_j\\nu_k
    + \\tfrac12 \\operatorname{tr}\\big(S_k^{-1}\\partial_i S_k\\, S_k^{-1}\\partial_j S_k\\big)

(plus, for a censored sample, the outer product of its term's gradient). :func:`nlobs.fit_likelihood`
maximises log p (see :mod:`._fit_likelihood`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Literal

import casadi as ca
import numpy as np
import sympy as sp

from ..design import ObserverDesign
from ..engine import Backend, compile_system, rows
from ..engine._integrate import rk4_step_rate
from ..errors import DataError, FiniteEscapeError, ModelError, PreconditionError
from ..simulate._loop import Loop
from ..estimation import Recording
from ._regimes import FilterModel, filter_model, log_ndtr

__all__ = ["log_likelihood", "LIKELIHOOD_KINDS", "NOISE_NAMES"]

#: Observer kinds whose innovations give a likelihood here (continuous-discrete, without state bounds).
LIKELIHOOD_KINDS = ("ekf", "ukf")
#: The names of the learnt noise log-scalings ρ_Q, ρ_R among the unknowns.
NOISE_NAMES = ("log_Q_scale", "log_R_scale")
#: The most RK4 sub-steps per interval in the likelihood's recursion (all intervals take the same number).
MAX_SUBSTEPS = 4096
#: The most sub-steps one step of the recursion unrolls: above it, each interval is run as several rows of the
#: recursion (equal parts of the interval, the last with the sample's update; the others predict only, their outputs
#: masked), so that a finer step costs rows, not a larger graph.
MAX_UNROLLED = 64
#: Above MAX_UNROLLED, the same count in every interval is refused where it would cost more than UNEVEN times the
#: sub-steps the filter's own run takes (one long gap in a recording: split it there instead).
UNEVEN = 8
#: A fit whose estimate would move by more than this many standard errors when the smoothing widths and the
#: integration step are halved says so.
ACCURACY = 0.5
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


def _sym(M: Any) -> Any:
    return (M + M.T) / 2


class _Filter:
    """The filter's pieces as CasADi expressions: flow between samples, one step of a map, update."""

    def __init__(self, d: ObserverDesign, system: Any):
        self.n = n = system.n_states
        self.ukf = d.method == "ukf"
        cs = compile_system(system)
        args = [cs.t, cs.x, cs.u, cs.p]
        self.f = ca.Function("f", args, [cs.f_sx])
        self.fF = ca.Function("fF", args, [cs.f_sx, ca.jacobian(cs.f_sx, cs.x)])
        self.h = ca.Function("h", args, [cs.h_sx])
        self.hH = ca.Function("hH", args, [cs.h_sx, ca.jacobian(cs.h_sx, cs.x)])
        if self.ukf:
            from ..design.kalman._ukf import unscented_weights

            v = d.certificate.values
            self.wm, self.wc, self.spread = unscented_weights(n, float(v["alpha"]), float(v["beta"]), float(v["kappa"]))

    def sigma(self, m: Any, P: Any) -> list[Any]:
        n = self.n
        L = ca.chol(P).T * np.sqrt(self.spread)
        return [m] + [m + L[:, i] for i in range(n)] + [m - L[:, i] for i in range(n)]

    def mean(self, pts: list[Any], w: Any, size: int) -> Any:
        return sum((float(w[i]) * pts[i] for i in range(len(pts))), ca.SX.zeros(size))

    def cov(self, A: list[Any], a: Any, B: list[Any], b: Any) -> Any:
        return sum((float(self.wc[i]) * (A[i] - a) @ (B[i] - b).T for i in range(len(A))),
                   ca.SX.zeros(A[0].numel(), B[0].numel()))

    def flow(self, tt: Any, z: Any, u: Any, p: Any, Q: Any) -> Any:   # design_ekf / design_ukf, continuous-discrete
        n = self.n
        x, P = z[:n], _sym(ca.reshape(z[n:], n, n))
        if not self.ukf:
            fx, F = self.fF(tt, x, u, p)
            return ca.vertcat(fx, ca.vec(_sym(F @ P + P @ F.T + Q)))
        X = self.sigma(x, P)
        Fs = [self.f(tt, xi, u, p) for xi in X]
        fbar = self.mean(Fs, self.wm, n)
        cross = self.cov(X, x, Fs, fbar)
        return ca.vertcat(fbar, ca.vec(_sym(cross + cross.T + Q)))

    def map_step(self, t: Any, dt: Any, x0: Any, P0: Any, u: Any, p: Any, Q: Any) -> tuple[Any, Any, Any]:
        """One step of a map from t_k with u_k (none before the first sample: dt = 0); the UKF's propagated points."""
        if not self.ukf:
            fx, F = self.fF(t, x0, u, p)
            return ca.if_else(dt > 0, fx, x0), ca.if_else(dt > 0, _sym(F @ P0 @ F.T + Q), P0), None
        X0 = self.sigma(x0, P0)
        Fs = [self.f(t, xi, u, p) for xi in X0]
        fbar = self.mean(Fs, self.wm, self.n)
        Pf = self.cov(Fs, fbar, Fs, fbar)
        pts = [ca.if_else(dt > 0, a_, b_) for a_, b_ in zip(Fs, X0)]
        return ca.if_else(dt > 0, fbar, x0), ca.if_else(dt > 0, _sym(Pf + Q), P0), pts

    def predicted_output(self, tk: Any, x: Any, P: Any, u: Any, p: Any, R: Any, pts: Any) -> tuple[Any, ...]:
        """ŷ, the full predicted output covariance, and the gain's numerator (P Hᵀ, or the sigma points' cross
        covariance) with H for the EKF's Joseph form."""
        if not self.ukf:
            yhat, H = self.hH(tk, x, u, p)
            return yhat, _sym(H @ P @ H.T + R), P @ H.T, H
        X = self.sigma(x, P) if pts is None else pts
        Y = [self.h(tk, xi, u, p) for xi in X]
        yhat = self.mean(Y, self.wm, Y[0].numel())
        return yhat, self.cov(Y, yhat, Y, yhat) + R, self.cov(X, x, Y, yhat), None


class _Recursion:
    """The filter with its forward sensitivities: one compiled step per sample (see the module docstring).

    Step state: [x, vec P, vec ∂(x, P)/∂θ, log p so far, ∂ log p/∂θ, vec 𝓘]; constant c: [all model parameters
    of the filter model, ρ_Q, ρ_R]; θ are the entries `free` of c. Data row: [t_k, dt_k, u_k, u_{k+1}, y_{k+1},
    m_{k+1}, z_{k+1}, ℓ_{k+1}] (dt = 0 for the first sample: the update of the prior; z = ±1 where an output is
    censored at its limit ℓ, else 0)."""

    def __init__(self, d: ObserverDesign, model: FilterModel, free: Sequence[int], n_sub: int):
        system = model.system
        n, nu, ny, npar = system.n_states, system.n_inputs, system.n_outputs, system.n_params
        q = len(free)
        self.n, self.q = n, q
        self.core = self._core(d, system, n_sub)
        core_n = n + n * n
        self.ns = core_n + core_n * q + 1 + q + q * q
        st, cc, a = ca.SX.sym("st", self.ns), ca.SX.sym("cc", npar + 2), ca.SX.sym("a", 2 + 2 * nu + 4 * ny)
        sc = st[:core_n]
        sens = ca.reshape(st[core_n:core_n + core_n * q], core_n, q)
        o = core_n + core_n * q
        acc_ll, acc_g, acc_I = st[o], st[o + 1:o + 1 + q], ca.reshape(st[o + 1 + q:], q, q)
        cn, lln, llc, nun, Sv = self.core(sc, a, cc)[:5]
        seed_c = ca.DM.zeros(npar + 2, q)
        for j, k in enumerate(free):
            seed_c[k, j] = 1
        out = ca.vertcat(cn, lln, llc, nun, Sv)
        D = ca.jtimes(out, ca.vertcat(sc, cc), ca.vertcat(sens, seed_c)) if q else ca.SX.zeros(out.numel(), 0)
        dcore, dll, dllc = D[:core_n, :], D[core_n, :], D[core_n + 1, :]
        dnu, dS = D[core_n + 2:core_n + 2 + ny, :], D[core_n + 2 + ny:, :]
        Sinv = ca.inv(ca.reshape(Sv, ny, ny))
        info = ca.SX.zeros(q, q)
        Si_dS = [Sinv @ ca.reshape(dS[:, j], ny, ny) for j in range(q)]
        for i in range(q):
            for j in range(i, q):   # the censored term's information: the outer product of its gradient
                e = ca.dot(dnu[:, i], Sinv @ dnu[:, j]) + 0.5 * ca.trace(Si_dS[i] @ Si_dS[j]) + dllc[i] * dllc[j]
                info[i, j] = e
                info[j, i] = e
        nxt = ca.vertcat(cn, ca.vec(dcore), acc_ll + lln + llc, acc_g + (dll + dllc).T, ca.vec(acc_I + info))
        self.step = ca.Function(f"{d.method}_likelihood_step", [st, a, cc], [ca.densify(nxt)])
        self.loop = Loop(self.step)

    @staticmethod
    def _core(d: ObserverDesign, system: Any, n_sub: int, noise: Any = None, n_noise: int = 2) -> ca.Function:
        """(state, row, c) -> (next state, Gaussian term, censored term, masked innovation, its covariance, the
        predicted output ŷ⁻, the variances of its full predicted covariance, and the squared whitened innovation
        νᵀS⁻¹ν). c = [model parameters, `n_noise` noise entries]; `noise` maps those entries to (Q, R) (default: the
        log-scalings ρ_Q, ρ_R of the design's Q, R)."""
        n, nu, ny, npar = system.n_states, system.n_inputs, system.n_outputs, system.n_params
        fl = _Filter(d, system)
        v = d.certificate.values
        Q0, R0 = ca.DM(np.asarray(v["Q"], dtype=float)), ca.DM(np.asarray(v["R"], dtype=float))
        s, a, c = ca.SX.sym("s", n + n * n), ca.SX.sym("a", 2 + 2 * nu + 4 * ny), ca.SX.sym("c", npar + n_noise)
        p = c[:npar]
        Q, R = (ca.exp(c[npar]) * Q0, ca.exp(c[npar + 1]) * R0) if noise is None else noise(c[npar:])
        t, dt = a[0], a[1]
        u0, u1 = rows(a, 2, 2 + nu), rows(a, 2 + nu, 2 + 2 * nu)
        o = 2 + 2 * nu
        y1, m1, z1, lim1 = (rows(a, o + i * ny, o + (i + 1) * ny) for i in range(4))
        pts = None
        if system.is_discrete:
            x, P, pts = fl.map_step(t, dt, s[:n], _sym(ca.reshape(s[n:], n, n)), u0, p, Q)
        else:
            z, hh = s, dt / n_sub
            for i in range(n_sub):
                z, _ = rk4_step_rate(lambda tt, zz, _k: fl.flow(tt, zz, u0, p, Q), t + i * hh, z, hh)
            x, P = z[:n], _sym(ca.reshape(z[n:], n, n))
        yhat, S_full, cross, H = fl.predicted_output(t + dt, x, P, u1, p, R, pts)
        m = m1 * (1 - z1 * z1)   # a censored output does not update
        Md = ca.diag(m)
        S = _sym(Md @ S_full @ Md + ca.diag(1 - m))
        K = ca.solve(S, (cross @ Md).T).T
        if H is None:   # as design_ukf
            P_plus = _sym(P - K @ S @ K.T)
        else:           # Joseph form, as design_ekf
            IKH = ca.DM.eye(n) - K @ Md @ H
            P_plus = _sym(IKH @ P @ IKH.T + K @ (Md @ R @ Md + ca.diag(1 - m)) @ K.T)
        nu_ = m * (y1 - yhat)
        Lc = ca.chol(S)  # upper: S = LᵀL
        w = ca.solve(Lc.T, nu_)
        ll = -0.5 * (ca.sum1(m) * np.log(2 * np.pi) + 2 * ca.sum1(ca.log(ca.diag(Lc))) + ca.dot(w, w))
        zc = z1 * (yhat - lim1) / ca.sqrt(ca.diag(S_full))
        llc = ca.sum1(z1 * z1 * log_ndtr(zc)) if ny else ca.SX(0)
        core_next = ca.vertcat(x + K @ nu_, ca.vec(P_plus))
        return ca.Function("lik_core", [s, a, c], [core_next, ll, llc, nu_, ca.vec(S), yhat, ca.diag(S_full), ca.dot(w, w)])

    def __call__(self, s0core: np.ndarray, A: np.ndarray, c: np.ndarray, engine: Backend) -> tuple[float, np.ndarray, np.ndarray, int]:
        """log p, its gradient, the information, and the first row whose state is not finite (−1 if none)."""
        q = self.q
        s0 = np.zeros(self.ns)
        s0[:s0core.size] = s0core
        states = self.loop(s0, A, c, engine)
        last = states[-1]
        if not np.all(np.isfinite(last)):
            bad = int(np.argmax(~np.all(np.isfinite(states), axis=1)))
            return -np.inf, np.full(q, np.nan), np.full((q, q), np.nan), bad
        o = self.ns - 1 - q - q * q
        return float(last[o]), last[o + 1:o + 1 + q].copy(), last[o + 1 + q:].reshape(q, q), -1


_CACHE: dict[tuple[Any, ...], tuple[ObserverDesign, _Recursion]] = {}


def _recursion(d: ObserverDesign, model: FilterModel, free: Sequence[int], n_sub: int) -> _Recursion:
    key = (id(d), model.system.key, tuple(free), n_sub)
    hit = _CACHE.get(key)
    if hit is not None and hit[0] is d:
        return hit[1]
    rec = _Recursion(d, model, free, n_sub)
    _CACHE[key] = (d, rec)  # keeps the design alive, so its id is not reused
    if len(_CACHE) > 32:
        _CACHE.pop(next(iter(_CACHE)))
    return rec


def check_names(system: Any, params: Sequence[str], learn_noise: bool, caller: str) -> list[str]:
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
    return params


class _Problem:
    """The likelihood of one recording as a function of θ (the named parameters, then ρ_Q, ρ_R if learnt)."""

    def __init__(self, design: Any, recording: Recording, params: Sequence[str], learn_noise: bool,
                 max_step: float | None, on_missing: str, engine: Backend, caller: str, smoothing: float = 1.0,
                 censor: bool = True):
        d = _check(design, caller)
        system = d.system
        if not isinstance(recording, Recording):
            raise TypeError(f"{caller}: `recording` must be an nlobs.Recording, got {type(recording).__name__}")
        recording.check_columns(system, f"{caller}: the model {system.name!r}")
        params = check_names(system, params, learn_noise, caller)
        mask = recording.check_finite(on_missing)
        if not mask.any():
            raise DataError(f"{caller}: the recording ({recording.source}) has no measured output sample")
        self.d, self.system, self.params, self.learn_noise = d, system, params, learn_noise
        self.caller, self.engine, self.source, self.recording = caller, engine, recording.source, recording
        t, u = recording.t, recording.u
        self.t, self.N = t, t.size
        y = np.where(mask > 0, recording.y, 0.0)
        switches = smoothing > 0 and any(e.has(sp.Abs, sp.sign, sp.Min, sp.Max) for e in (*system.f, *system.h))
        traj = self._substeps(t, u, y, mask, max_step, switches)
        run = None if traj is None else {"x": traj.xhat, "u": u, "t": t}
        self.s0 = np.concatenate([np.asarray(d.xhat0, dtype=float).reshape(-1),
                                  np.asarray(d.certificate.values["P0"], dtype=float).reshape(-1, order="F")])
        self._args = (run, y, mask, smoothing, censor, learn_noise)
        self.width_scale = 1.0
        self._build(*self._args)
        self.set_substeps(min(max(self.n_sub, self.model.substeps), MAX_SUBSTEPS))
        if self.exact_stiff:   # the exact run chattered at a switch: the smoothed model's own stiffness decides
            need = self.needed_substeps(self.theta0())
            if need > MAX_SUBSTEPS:
                n, k = self.exact_stiff
                raise DataError(f"{caller}: the filter takes {n} RK4 sub-steps in the interval from t = {t[k]:g} to "
                                f"{t[k + 1]:g} on the model as written, and {need} on its smoothed switches (its "
                                f"fastest rate times the sample interval); the likelihood's recursion takes at most "
                                f"{MAX_SUBSTEPS} per interval: give a wider smoothing (smoothing > 1, --smoothing), "
                                "or a recording sampled faster")
            if need > self.n_sub:
                self.set_substeps(need)

    def _build(self, run: Any, y: np.ndarray, mask: np.ndarray, smoothing: float, censor: bool, learn_noise: bool) -> None:
        """The filter model (widths for the current sub-steps), the unknowns' places in c, and the data rows."""
        t, u, rec = self.t, self.recording.u, self.recording
        self.model = filter_model(self.system, self.params, run, smoothing * self.width_scale, censor,
                                  readings=(rec.y, mask))
        fsys = self.model.system
        npar = fsys.n_params
        self.free = [fsys.param_names.index(p) for p in self.params] + ([npar, npar + 1] if learn_noise else [])
        self.names = tuple(self.params) + (NOISE_NAMES if learn_noise else ())
        self.c = np.concatenate([np.asarray(fsys.param_values, dtype=float), [0.0, 0.0]])
        self.codes, limits = self.model.censoring(rec.y, mask)
        first = np.concatenate([[t[0], 0.0], u[0], u[0], y[0], mask[0], self.codes[0], limits[0]])
        rest = np.hstack([t[:-1, None], np.diff(t)[:, None], u[:-1], u[1:], y[1:], mask[1:], self.codes[1:], limits[1:]])
        self.A = np.vstack([first, rest])

    def refinement_shift(self, theta: np.ndarray) -> float:
        """How far, in standard errors, halving the smoothing widths and the integration step would move the estimate
        from θ: √(Δgᵀ 𝓘⁻¹ Δg) with Δg the change of the gradient of log p (a scoring step's worth)."""
        if self.system.is_discrete:
            return 0.0
        ll, g, info, _ = self.evaluate(theta)
        fine = _Problem.__new__(_Problem)
        fine.__dict__.update(self.__dict__)
        fine.width_scale = self.width_scale / 2
        fine._build(*self._args)
        fine.set_substeps(min(2 * self.n_sub, max(MAX_SUBSTEPS, self.n_sub)))
        llf, gf, _, _ = fine.evaluate(theta)
        if not (np.isfinite(ll) and np.isfinite(llf)):
            return float("inf")
        try:
            return float(np.sqrt(max((gf - g) @ np.linalg.solve(info, gf - g), 0.0)))
        except np.linalg.LinAlgError:
            return float("inf")

    def _substeps(self, t: np.ndarray, u: np.ndarray, y: np.ndarray, mask: np.ndarray, max_step: float | None,
                  switches: bool = False) -> Any:
        """Sub-steps per interval: the filter's own rule, run at the initial guess (the most it takes in one); the run.

        With `switches` to be smoothed, a count above MAX_UNROLLED is not final: on the model as written the run
        chatters where a switch's argument crosses zero (Coulomb friction, sign(w) at rest), which the smoothed
        model does not; ``exact_stiff`` keeps it for the check on the smoothed model."""
        from ..observer._compiled import compiled_observer

        system, caller = self.system, self.caller
        if system.is_discrete:   # a map: one step per sample, on the model's grid
            from ..simulate._discrete import check_map_grid

            check_map_grid(system, t, f"{caller}: recording ({self.source})")
            self.n_sub, self.exact_stiff = 1, None
            return None
        traj = compiled_observer(self.d).run(t, u=u, y=y, mask=mask, max_step=max_step, engine=self.engine, name=caller)
        self.n_sub = max(1, int(traj.substeps.max()))
        self.exact_stiff: tuple[int, int] | None = None
        if self.n_sub > MAX_UNROLLED and switches:
            self.exact_stiff = (self.n_sub, int(np.argmax(traj.substeps)))
            # the smoothed model's own count decides, but never a step longer than the user's max_step
            dts = np.diff(t)
            self.n_sub = 1 if max_step is None or dts.size == 0 else int(np.ceil(dts.max() / max_step - 1e-9))
        elif self.n_sub > MAX_SUBSTEPS or (self.n_sub > MAX_UNROLLED and
                                           self.n_sub * traj.substeps.size > UNEVEN * traj.substeps.sum()):
            k = int(np.argmax(traj.substeps))
            raise DataError(f"{caller}: the filter takes {self.n_sub} RK4 sub-steps in the interval from t = {t[k]:g} to "
                            f"{t[k + 1]:g} (the most in any interval, {int(traj.substeps.sum())} in all); the likelihood's "
                            f"recursion takes the same number in every interval (at most {MAX_SUBSTEPS}; above "
                            f"{MAX_UNROLLED}, only where the intervals need about as many: not {UNEVEN} times the "
                            "filter's own work): split the recording at long gaps, or resample it")
        return traj

    def theta0(self) -> np.ndarray:
        return self.c[self.free].copy()

    def needed_substeps(self, theta: np.ndarray) -> int:
        """RK4 sub-steps per interval for which h·|λ| ≤ 2 (inside RK4's stability interval, |λ| the largest
        eigenvalue of ∂f/∂x) at every sample of the filter's run at θ; the fixed count was chosen at the initial
        guess, and a fit can move into stiffer dynamics (a weir spilling hard)."""
        if self.system.is_discrete:
            return 1
        c = self.c.copy()
        c[self.free] = theta
        n = self.system.n_states
        X = self.rec.loop(np.concatenate([self.s0, np.zeros(self.rec.ns - self.s0.size)]), self.A_run, c,
                          self.engine)[self.split - 1::self.split, :n]
        if not np.all(np.isfinite(X)):
            return self.n_sub
        fx = compile_system(self.model.system).f_x.map(self.N)
        p = np.asarray(self.model.system.param_values, dtype=float)
        p[[i for i in self.free if i < p.size]] = theta[:len(self.params)]
        F = np.asarray(fx(self.t, X.T, self.recording.u.T, np.repeat(p[:, None], self.N, axis=1)))  # [F_0 F_1 ...]
        F = F.reshape(n, self.N, n).transpose(1, 0, 2)
        lam = max(float(np.max(np.abs(np.linalg.eigvals(Fk)))) for Fk in F)
        dt = float(np.max(np.diff(self.t))) if self.N > 1 else 0.0
        return max(self.n_sub, int(np.ceil(dt * lam / 2.0)))

    def one_step(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The filter's one-step predictions ŷ_k⁻ at θ and their standard deviations √diag(H P⁻ Hᵀ + R), (N, p) each."""
        c = self.c.copy()
        c[self.free] = theta
        rows = self.A_run.shape[0]
        run = self.rec.core.mapaccum("lik_one_step", rows)
        out = run(self.s0, self.A_run.T, c)
        ny, last = self.system.n_outputs, slice(self.split - 1, None, self.split)
        return (np.asarray(out[5]).reshape(ny, rows).T[last],
                np.sqrt(np.maximum(np.asarray(out[6]).reshape(ny, rows).T[last], 0.0)))

    def set_substeps(self, n_sub: int) -> None:
        """Integrate with at least `n_sub` RK4 steps per interval: above MAX_UNROLLED, each interval is `split` rows
        of the recursion with an equal share of them (``n_sub`` becomes the count taken, split·share)."""
        self.split = max(1, -(-int(n_sub) // MAX_UNROLLED))
        inner = -(-int(n_sub) // self.split)
        self.n_sub = self.split * inner
        self.rec = _recursion(self.d, self.model, self.free, inner)
        self.A_run = _split_rows(self.A, self.split, self.system.n_inputs, self.system.n_outputs)

    def evaluate(self, theta: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, int]:
        """log p, gradient, information, and the first sample whose filter state is not finite (−1 if none)."""
        c = self.c.copy()
        c[self.free] = theta
        ll, g, info, bad = self.rec(self.s0, self.A_run, c, self.engine)
        return ll, g, info, (bad // self.split if bad >= 0 else bad)

    def __call__(self, theta: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        ll, g, info, _ = self.evaluate(theta)
        return ll, g, info

    def where_not_finite(self, theta: np.ndarray) -> str:
        """'at t = …' of the first sample where the filter's state is not finite at θ ('' if it stays finite)."""
        bad = self.evaluate(theta)[3]
        if bad < 0:
            return ""
        return (f"at t = {self.t[bad]:g} (predicting from t = {self.t[bad - 1]:g}, then updating)" if bad
                else f"at the first sample (t = {self.t[0]:g})")


def _split_rows(A: np.ndarray, m: int, nu: int, ny: int) -> np.ndarray:
    """The recursion's data rows with each interval cut into `m` equal parts: the first m - 1 predict only (nothing
    measured: the update is the identity, the terms 0), the last carries the sample. Row layout as in _Recursion."""
    if m == 1:
        return A
    N = A.shape[0]
    rows = np.repeat(A, m, axis=0)
    j = np.tile(np.arange(m), N)
    rows[:, 1] = A[:, 1].repeat(m) / m
    rows[:, 0] = A[:, 0].repeat(m) + j * rows[:, 1]
    rows[j < m - 1, 2 + 2 * nu:] = 0.0     # y, mask, censoring code and limit of the parts before the sample
    return np.ascontiguousarray(rows)


def log_likelihood(design: Any, recording: Recording, *, params: Sequence[str] = (), learn_noise: bool = False,
                   values: Mapping[str, float] | None = None, smoothing: float = 1.0, censor: bool = True,
                   max_step: float | None = None, on_missing: Literal["error", "skip"] = "error",
                   engine: Backend = "auto") -> tuple[float, np.ndarray]:
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
    smoothing : float
        Factor on the widths over which the model's switches (abs, sign, min, max) are smoothed, see the module
        docstring; 0 keeps them exact (the likelihood is then discontinuous where the filter crosses one).
    censor : bool
        Read an output saturating at a known limit (``min(g, 10)``, ``sat(g, 0, 10)``) as censored where the
        recording sits at the limit (default); False treats it as any other switch.
    max_step, on_missing, engine
        As for :func:`nlobs.estimate` (the sub-steps per interval are the most the filter takes in one).

    Returns
    -------
    (float, numpy.ndarray)
        log p(y | θ) and its gradient in θ (automatic differentiation through the filter).

    Raises
    ------
    FiniteEscapeError
        When the filter's state becomes non-finite at these values: with the sample and its time (the likelihood is
        not a number there; a fit reads it as −∞ and steps back).
    """
    prob = _Problem(design, recording, params, learn_noise, max_step, on_missing, engine, "log_likelihood",
                    smoothing, censor)
    theta = prob.theta0()
    for k, v in (values or {}).items():
        if k not in prob.names:
            raise ModelError(f"log_likelihood: `values` names {k!r}, which is not one of {', '.join(prob.names) or '(none)'}")
        theta[prob.names.index(k)] = float(v)
    ll, g, _, bad = prob.evaluate(theta)
    if bad >= 0:
        t = recording.t
        k = min(int(bad), t.size - 1)
        raise FiniteEscapeError("the filter of log_likelihood", float(t[max(k - 1, 0)]), np.full(1, np.nan), ["state"], np.inf,
                                message=f"log_likelihood: the filter's state became non-finite at sample {k} (t = {t[k]:.6g}) "
                                        f"of the recording ({recording.source}) at these parameter values: the likelihood "
                                        "is not a number there. Check the values, or pass a smaller `max_step`")
    return ll, g
