"""Batch estimation of unknown parameters: simulation-error least squares on a recording.

The model is simulated over the whole recording from an initial state (some of whose entries may
be unknown too), driven by the recorded input, and the unknowns θ minimise

.. math::

    \\sum_k \\sum_j w_j^2 \\, (y_{k,j} - \\hat y_j(t_k; \\theta))^2 ,

the output (simulation) error. The simulation is a CasADi graph (RK4 steps unrolled with
``mapaccum``), so the Jacobian ∂ŷ/∂θ is exact (automatic differentiation); SciPy's
trust-region least squares (``scipy.optimize.least_squares``) minimises. Standard errors come
from the Jacobian at the optimum: with σ̂_j² the residual variance of output j,

.. math::

    \\operatorname{cov}\\hat\\theta \\approx \\Big(\\sum_j J_j^\\top J_j / \\hat\\sigma_j^2\\Big)^{-1},
    \\qquad J_j = \\partial \\hat y_j / \\partial \\theta ,

the usual asymptotic covariance of nonlinear least squares with independent Gaussian output
errors (it ignores model error and correlated noise: read it as a lower bound on the uncertainty).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import casadi as ca
import numpy as np

from ..design import check_positive
from ..engine import compile_system, rk4_step, rows
from ..errors import DataError, ModelError
from ..model import System
from ..estimation import Recording

__all__ = ["fit_parameters", "FitResult"]


@dataclass(frozen=True, eq=False)
class FitResult:
    """The result of :func:`fit_parameters`.

    Attributes
    ----------
    names : tuple of str
        The unknowns: parameter names, then ``"x2(t0)"`` for each fitted initial state.
    estimate, std : numpy.ndarray of shape (q,)
        The estimates and their standard errors (NaN where not identifiable).
    covariance : numpy.ndarray of shape (q, q)
    initial : numpy.ndarray of shape (q,)
        The initial guesses.
    system : System
        The model with the fitted parameter values.
    x0 : numpy.ndarray of shape (n,)
        The initial state with the fitted entries.
    t : numpy.ndarray of shape (N,)
    y, y_fit : numpy.ndarray of shape (N, p)
        Recorded and simulated outputs at the fit.
    output_names : tuple of str
    rmse : dict of output name to float
        RMS of the output error per output.
    success : bool
    message : str
        The optimiser's own message.
    nfev : int
        Simulations run.
    singular_values : numpy.ndarray
        Of the weighted Jacobian with columns scaled by max(abs(θ), 1e-12) (relative sensitivity).
    unidentifiable : tuple of str
        Directions the data do not determine (combinations of unknowns), empty when all are.
    integration_change : float
        Largest change of the simulated outputs when the integration step is halved: the
        integration error is negligible when this is well below the RMS errors.
    substeps : int
        RK4 steps per sample interval.
    """

    names: tuple[str, ...]
    estimate: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    initial: np.ndarray
    system: System
    x0: np.ndarray
    t: np.ndarray
    y: np.ndarray
    y_fit: np.ndarray
    output_names: tuple[str, ...]
    rmse: Mapping[str, float]
    success: bool
    message: str
    nfev: int
    singular_values: np.ndarray
    unidentifiable: tuple[str, ...]
    integration_change: float
    substeps: int
    info: Mapping[str, Any] = field(default_factory=dict)

    @property
    def residuals(self) -> np.ndarray:
        """y − ŷ at the fit, shape (N, p) (NaN where a sample is missing)."""
        return self.y - self.y_fit

    @property
    def parameters(self) -> dict[str, dict[str, float]]:
        """``{name: {"estimate": ..., "std": ...}}``."""
        return {n: {"estimate": float(v), "std": float(s)} for n, v, s in zip(self.names, self.estimate, self.std)}

    def to_dict(self) -> dict[str, Any]:
        return {"parameters": self.parameters, "covariance": self.covariance.tolist(), "names": list(self.names),
                "initial": dict(zip(self.names, self.initial.tolist())), "x0": self.x0.tolist(), "rmse": dict(self.rmse),
                "success": self.success, "message": self.message, "simulations": self.nfev,
                "unidentifiable": list(self.unidentifiable), "integration_change": self.integration_change,
                "substeps": self.substeps}

    def summary(self) -> str:
        w = max(8, *(len(n) for n in self.names))
        head = f"{'unknown':<{w}} {'initial':>12} {'estimate':>12} {'std':>10} {'±2σ (rel.)':>11}"
        lines = [f"simulation-error least squares on {self.info.get('source', 'the recording')}: {self.t.size} samples, "
                 f"{self.nfev} simulations, {'converged' if self.success else 'NOT converged'} ({self.message})",
                 head, "-" * len(head)]
        for n, v0, v, s in zip(self.names, self.initial, self.estimate, self.std):
            rel = f"{200 * s / abs(v):.2g} %" if np.isfinite(s) and v != 0 else "—"
            lines.append(f"{n:<{w}} {v0:>12.6g} {v:>12.6g} {s:>10.3g} {rel:>11}")
        lines.append("output RMS error: " + ", ".join(f"{o} {r:.4g}" for o, r in self.rmse.items()))
        if self.unidentifiable:
            lines.append("NOT identifiable from these data: " + "; ".join(self.unidentifiable)
                         + " (their std is not finite; fix some of them or use a more exciting input)")
        worst = max(self.rmse.values()) if self.rmse else 0.0
        note = "negligible" if self.integration_change < 0.1 * max(worst, 1e-300) else \
            "NOT negligible against the output errors: give a smaller max_step"
        lines.append(f"integration: RK4, {self.substeps} step(s) per sample interval; halving the step changes the outputs "
                     f"by {self.integration_change:.2g} ({note})")
        lines.append("std: from the Jacobian at the optimum, assuming independent Gaussian output errors (a lower bound "
                     "when the model is not exact or the errors are correlated)")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()


def fit_parameters(
    system: System,
    recording: Recording,
    params: Sequence[str],
    *,
    x0: Sequence[float] | None = None,
    fit_x0: Sequence[str] = (),
    initial: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float | None, float | None]] | None = None,
    output_std: Mapping[str, float] | None = None,
    max_step: float | None = None,
    hold: Literal["zoh", "linear"] = "zoh",
    max_nfev: int | None = None,
) -> FitResult:
    """Fit unknown parameters (and initial states) by simulation-error least squares.

    Parameters
    ----------
    system : System
        The model; its parameter values are the initial guesses of the unknown ones and the
        values of the others.
    recording : Recording
        t, the inputs and the measured outputs (NaN: missing, left out). True states, if any,
        are not used (except their first row as the default `x0`).
    params : sequence of str
        The unknown parameters.
    x0 : sequence of float, optional
        The initial state at the recording's first time (default: the recording's true state
        there, if it has one). Entries named in `fit_x0` are initial guesses.
    fit_x0 : sequence of str
        States whose initial value is unknown too.
    initial : mapping, optional
        Initial guesses by name (parameters, or ``"x2(t0)"``), replacing the model's values.
    bounds : mapping of name to (lower, upper), optional
        Bounds on unknowns (None: unbounded on that side), e.g. ``{"k": (0, None)}``.
    output_std : mapping of output name to float, optional
        Measurement noise standard deviations: the residuals are weighted by 1/std (default:
        each output scaled by its own spread in the data); the standard errors always use the
        residual variances at the optimum.
    max_step : float, optional
        Largest RK4 step (default: one step per sample interval). The step is checked along the run at the estimate:
        where halving it moves a state by more than 1 % of its range or an output by more than a tenth of its RMS error
        at any sample, the step is halved and the fit polished, up to 64 steps per interval; beyond, the fit is not
        successful and its message names the sample time where the step is too coarse.
    hold : {"zoh", "linear"}
        How the recorded input is held between samples.
    max_nfev : int, optional
        Largest number of simulations (default: SciPy's).

    Returns
    -------
    FitResult

    Raises
    ------
    ModelError
        For unknown names. DataError for missing inputs or a recording without measured outputs.
    """

    if not isinstance(system, System):
        raise TypeError(f"fit_parameters: `system` must be an nlobs.System, got {type(system).__name__}")
    if not isinstance(recording, Recording):
        raise TypeError(f"fit_parameters: `recording` must be an nlobs.Recording, got {type(recording).__name__}")
    recording.check_columns(system, f"fit_parameters: the model {system.name!r}")
    if hold not in ("zoh", "linear"):
        raise ValueError(f"fit_parameters: `hold` must be 'zoh' or 'linear', got {hold!r}")
    params, fit_x0 = list(params), list(fit_x0)
    for name, pool, what in ((params, system.param_names, "parameter"), (fit_x0, system.states, "state")):
        bad = [p for p in name if p not in pool]
        if bad:
            raise ModelError(f"fit_parameters: {bad[0]!r} is not a {what} of {system.name!r}; "
                             f"its {what}s: {', '.join(pool) or '(none)'}")
        if len(set(name)) != len(name):
            raise ModelError(f"fit_parameters: a {what} is named twice in {name}")
    if not params and not fit_x0:
        raise ModelError(f"fit_parameters: nothing to fit: name unknown parameters ({', '.join(system.param_names) or 'none'}) "
                         "or initial states")
    mask = recording.check_finite("skip")
    if not mask.any():
        raise DataError(f"fit_parameters: the recording ({recording.source}) has no measured output sample")
    if max_step is not None:
        max_step = check_positive(max_step, "max_step", "fit_parameters")
    n = system.n_states
    if x0 is None:
        if recording.x is not None:
            x0 = recording.x[0]
        elif len(fit_x0) == n:
            x0 = np.zeros(n)
        else:
            raise ModelError(f"fit_parameters: give `x0` (the state at t = {recording.t[0]:g}), or name every state in `fit_x0`")
    x0 = np.asarray(x0, dtype=float).reshape(-1)
    if x0.size != n or not np.all(np.isfinite(x0)):
        raise ModelError(f"fit_parameters: `x0` must be {n} finite numbers ({', '.join(system.states)}), got {x0.tolist()}")
    names = tuple(params) + tuple(f"{s}(t0)" for s in fit_x0)
    theta0 = np.array([system.params[p] for p in params] + [x0[system.states.index(s)] for s in fit_x0], dtype=float)
    theta0, lo, hi = _start_and_bounds(names, theta0, initial, bounds)

    t, u, y = recording.t, recording.u, recording.y
    dts = np.diff(t)
    n_sub = 1 if max_step is None else max(1, int(np.ceil(dts.max() / max_step - 1e-9)))
    weights = _weights(system, y, mask, output_std)
    sim = _Simulator(system, params, fit_x0, x0, t, u, hold)
    meas = mask > 0
    yw = np.where(meas, y, 0.0) * weights

    sol, n_sub, check, nfev = _solve(sim, theta0, names, lo, hi, n_sub, meas, weights, yw, y, max_nfev)
    message, success = str(sol.message), bool(sol.success)
    if check is not None:
        success = False
        message = (f"{message}; but the integration step is too coarse: {check} with {n_sub} RK4 steps per sample "
                   f"interval (the most the fit refines to): give a smaller max_step there, or resample the recording")
    theta = sol.x
    y_fit = sim.outputs(theta, n_sub)
    y_fit_half = sim.outputs(theta, 2 * n_sub)
    change = float(np.max(np.abs(y_fit_half - y_fit)))
    err = np.where(meas, y - y_fit, np.nan)
    m_j = meas.sum(axis=0)
    q = len(names)
    dof = max(int(meas.sum()) - q, 1)
    rss_j = np.nansum(err**2, axis=0)
    sigma2 = rss_j / np.maximum(m_j * dof / meas.sum(), 1)  # residual variance per output, dof shared in proportion
    Ju = sim.output_jacobian(theta, n_sub)  # (N, p, q), unweighted ∂ŷ/∂θ
    F = np.zeros((q, q))
    for j in range(y.shape[1]):
        Jj = Ju[meas[:, j], j, :]
        if sigma2[j] > 0:
            F += Jj.T @ Jj / sigma2[j]
    svals, weak = _weak_directions(names, np.asarray(sol.jac), theta)
    try:
        cov = np.linalg.inv(F) if not weak else np.full((q, q), np.nan)
    except np.linalg.LinAlgError:
        cov = np.full((q, q), np.nan)
    std = np.sqrt(np.where(np.diag(cov) >= 0, np.diag(cov), np.nan))
    fitted = system.with_params(**{p: float(v) for p, v in zip(params, theta[:len(params)])}) if params else system
    x0_fit = x0.copy()
    for s, v in zip(fit_x0, theta[len(params):]):
        x0_fit[system.states.index(s)] = v
    rmse = {o: float(np.sqrt(rss_j[j] / m_j[j])) if m_j[j] else float("nan") for j, o in enumerate(system.outputs)}
    return FitResult(names, theta, std, cov, theta0, fitted, x0_fit, t, y, y_fit, tuple(system.outputs), rmse,
                     success, message, nfev, svals, tuple(weak), change, n_sub,
                     info={"source": recording.source, "hold": hold, "max_step": max_step, "weights": weights.tolist()})


def _solve(sim: _Simulator, theta0: np.ndarray, names: Sequence[str], lo: np.ndarray, hi: np.ndarray, n_sub: int,
           meas: np.ndarray, weights: np.ndarray, yw: np.ndarray, y: np.ndarray, max_nfev: int | None) -> tuple[Any, int, str | None, int]:
    """The least-squares fit with its step checked along the run at every iterate and at the estimate, halved while
    it matters (see :func:`_step_check`): SciPy's result, the RK4 steps per interval, what the last check found (None:
    nothing) and the simulations run."""
    from scipy.optimize import least_squares

    fns = [sim.residual_functions(n_sub, meas, weights)]
    count = [0]
    good = [theta0]   # the last iterate whose step passed the check

    def r(theta: np.ndarray) -> np.ndarray:
        count[0] += 1
        return np.asarray(fns[-1][0](theta, yw[meas])).ravel()

    def J(theta: np.ndarray) -> np.ndarray:
        # at every iterate of the fit (not only at its end: on its way it may cross a region the step cannot run,
        # a steep weir, and end where the run no longer depends on what went wrong there), the step is checked
        # along the run; where it fails, the fit starts again from the last iterate that passed, with half the step
        if 2 * n_sub_now[0] <= MAX_FIT_SUBSTEPS:
            if _step_check(sim, theta, n_sub_now[0], meas, y, PATH_SLACK) is not None:
                raise _Refine()
            good[0] = np.array(theta, dtype=float)
        return np.asarray(fns[-1][1](theta))

    n_sub_now = [n_sub]
    r0 = r(theta0)
    if not np.all(np.isfinite(r0)):
        raise DataError(f"fit_parameters: the simulation from the initial guess ({_pairs(names, theta0)}) is not finite; "
                        "start from other values, bound the unknowns, or give a smaller max_step")
    while True:   # the step checked along the run, at every iterate and at the end: halved while it still matters
        try:
            sol = least_squares(r, good[0], jac=J, bounds=(lo, hi), x_scale="jac", method="trf", max_nfev=max_nfev)
            check = _step_check(sim, sol.x, n_sub, meas, y)
            if check is None or 2 * n_sub > MAX_FIT_SUBSTEPS:
                break
            good[0] = sol.x
        except _Refine:
            pass
        n_sub *= 2
        n_sub_now[0] = n_sub
        fns.append(sim.residual_functions(n_sub, meas, weights))
    return sol, n_sub, check, count[0]


class _Refine(Exception):
    """Raised inside the least-squares iterations when an iterate's step fails the check along the run."""


#: The most RK4 steps per sample interval the fit refines to when halving its step still matters (see _step_check).
MAX_FIT_SUBSTEPS = 64
#: Halving the step must move every state by less than STATE_RTOL of its range on the run, and every output by less
#: than OUTPUT_FRACTION of its RMS error (floored at 1e-6 of the output's spread), at every sample.
STATE_RTOL, OUTPUT_FRACTION = 1e-2, 0.1
#: On the fit's way (every iterate) the tolerances are PATH_SLACK times looser: what must not pass there is a run
#: the step cannot follow (an unstable RK4 step on a steep weir), accuracy is checked at the estimate.
PATH_SLACK = 3.0


def _step_check(sim: _Simulator, theta: np.ndarray, n_sub: int, meas: np.ndarray, y: np.ndarray,
                slack: float = 1.0) -> str | None:
    """The run at θ with `n_sub` RK4 steps per interval against 2·n_sub, at every sample (states and outputs: a state
    diverging between samples shows there even where the output hides it, e.g. saturated): None when halving the
    step changes nothing that matters, else where it does (the first sample over the tolerance, and the worst).
    `slack` multiplies the tolerances (the iterates on the fit's way: a run the step cannot follow, not accuracy)."""
    xc, xf = sim.states(theta, n_sub), sim.states(theta, 2 * n_sub)
    yc, yf = sim.outputs(theta, n_sub), sim.outputs(theta, 2 * n_sub)
    with np.errstate(invalid="ignore"):
        rmse = np.sqrt(np.nanmean(np.where(meas, y - yc, np.nan) ** 2, axis=0))
        spread = np.nanmax(np.where(meas, y, np.nan), axis=0) - np.nanmin(np.where(meas, y, np.nan), axis=0)
        y_tol = OUTPUT_FRACTION * np.maximum(np.nan_to_num(rmse), 1e-6 * np.maximum(np.nan_to_num(spread), 1e-300))
        x_tol = STATE_RTOL * np.maximum(np.nanmax(np.abs(np.where(np.isfinite(xf), xf, np.nan)), axis=0), 1e-12)
        ratio = np.hstack([np.abs(xf - xc) / x_tol, np.abs(yf - yc) / y_tol]) / slack
    ratio = np.where(np.isfinite(ratio), ratio, np.inf)
    per_k = ratio.max(axis=1)
    if np.all(per_k <= 1):
        return None
    names = [*sim.system.states, *sim.system.outputs]
    t = sim.t

    def at(k: int) -> str:
        i = int(np.argmax(ratio[k]))
        d = (xf - xc)[k, i] if i < xc.shape[1] else (yf - yc)[k, i - xc.shape[1]]
        tol = x_tol[i] if i < xc.shape[1] else y_tol[i - xc.shape[1]]
        return f"t = {t[k]:g} (halving the step moves {names[i]} by {d:.3g}, tolerance {tol:.3g})"

    first, worst = int(np.argmax(per_k > 1)), int(np.argmax(per_k))
    return f"first at {at(first)}" + ("" if worst == first else f", most at {at(worst)}")


def _start_and_bounds(names: Sequence[str], theta0: np.ndarray, initial: Mapping[str, float] | None,
                      bounds: Mapping[str, Sequence[float | None]] | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The initial guess (the model's values, overridden by `initial`) and the bounds of the unknowns, checked."""
    theta0 = theta0.copy()
    for k, v in (initial or {}).items():
        if k not in names:
            raise ModelError(f"fit_parameters: `initial` names {k!r}, which is not an unknown ({', '.join(names)})")
        theta0[names.index(k)] = float(v)
    lo, hi = np.full(len(names), -np.inf), np.full(len(names), np.inf)
    for k, (a, b) in (bounds or {}).items():
        if k not in names:
            raise ModelError(f"fit_parameters: `bounds` names {k!r}, which is not an unknown ({', '.join(names)})")
        lo[names.index(k)] = -np.inf if a is None else float(a)
        hi[names.index(k)] = np.inf if b is None else float(b)
    if np.any(lo >= hi) or np.any(theta0 < lo) or np.any(theta0 > hi):
        k = int(np.flatnonzero((lo >= hi) | (theta0 < lo) | (theta0 > hi))[0])
        raise ModelError(f"fit_parameters: the initial guess {names[k]} = {theta0[k]:g} is not inside its bounds "
                         f"[{lo[k]:g}, {hi[k]:g}]")
    return theta0, lo, hi


def _weak_directions(names: Sequence[str], jac: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Singular values of the scaled Jacobian of the residuals and the directions along which it is (numerically) zero."""
    Jw = jac * np.maximum(np.abs(theta), 1e-12)
    _, svals, vt = np.linalg.svd(Jw, full_matrices=False)
    tolerance = max(Jw.shape) * np.finfo(float).eps * 1e3 * (svals[0] if svals.size else 0.0)
    return svals, [_direction(names, v) for s_, v in zip(svals, vt) if s_ <= tolerance]


def _pairs(names: Sequence[str], values: np.ndarray) -> str:
    return ", ".join(f"{n} = {v:.6g}" for n, v in zip(names, values))


def _direction(names: Sequence[str], v: np.ndarray) -> str:
    """A null direction of the relative-sensitivity Jacobian: relative changes of the unknowns that,
    to first order, leave the simulated outputs unchanged."""
    v = v if v[np.argmax(np.abs(v))] > 0 else -v
    keep = [i for i in np.argsort(-np.abs(v)) if abs(v[i]) > 0.1]
    return (f"changing ({', '.join(names[i] for i in keep)}) in proportion to ({', '.join(f'{v[i]:+.2f}' for i in keep)}) "
            "(relative changes) leaves the outputs unchanged")


def _weights(system: System, y: np.ndarray, mask: np.ndarray, output_std: Mapping[str, float] | None) -> np.ndarray:
    w = np.ones(system.n_outputs)
    given = dict(output_std or {})
    bad = [k for k in given if k not in system.outputs]
    if bad:
        raise ModelError(f"fit_parameters: `output_std` names {bad[0]!r}, which is not an output ({', '.join(system.outputs)})")
    for j, o in enumerate(system.outputs):
        if o in given:
            w[j] = 1.0 / check_positive(given[o], f"output_std[{o!r}]", "fit_parameters")
        else:
            col = y[mask[:, j] > 0, j]
            spread = float(np.std(col)) if col.size > 1 else 0.0
            w[j] = 1.0 / spread if spread > 0 else 1.0
    return w


class _Simulator:
    """The model on the recording's time grid as a CasADi graph of the unknowns θ."""

    def __init__(self, system: System, params: Sequence[str], fit_x0: Sequence[str], x0: np.ndarray, t: np.ndarray,
                 u: np.ndarray, hold: str):
        self.system, self.t, self.u, self.hold = system, t, u, hold
        cs = compile_system(system)
        self.cs = cs
        q_p, q_x = len(params), len(fit_x0)
        theta = ca.MX.sym("theta", q_p + q_x)
        p_full = [ca.MX(v) for v in system.param_values]
        for i, name in enumerate(params):
            p_full[system.param_names.index(name)] = theta[i]
        x_full = [ca.MX(v) for v in x0]
        for i, name in enumerate(fit_x0):
            x_full[system.states.index(name)] = theta[q_p + i]
        self.theta = theta
        self.p = ca.vertcat(*p_full) if p_full else ca.MX(0, 1)
        self.x0 = ca.vertcat(*x_full)
        self._cache: dict[int, ca.MX] = {}
        self._X: dict[int, ca.MX] = {}
        self._runs: dict[int, ca.Function] = {}

    def _Y(self, n_sub: int) -> ca.MX:
        """Simulated outputs, shape (p, N), as an expression of θ (the states, (n, N), in ``_X[n_sub]``)."""
        if n_sub in self._cache:
            return self._cache[n_sub]
        cs, sys_ = self.cs, self.system
        n, nu, npar = sys_.n_states, sys_.n_inputs, sys_.n_params
        x, a, p = ca.SX.sym("x", n), ca.SX.sym("a", 2 + 2 * nu), ca.SX.sym("p", npar)
        t0, dt = a[0], a[1]
        u0, u1 = rows(a, 2, 2 + nu), rows(a, 2 + nu, 2 + 2 * nu)
        slope = (u1 - u0) / dt if self.hold == "linear" else ca.DM.zeros(nu)
        f = ca.Function("f", [cs.t, cs.x, cs.u, cs.p], [cs.f_sx])

        def rhs(tt: Any, xx: Any, _k: int) -> Any:
            return f(tt, xx, u0 + (tt - t0) * slope, p)

        h_ = dt / n_sub
        xk = x
        for i in range(n_sub):
            xk = rk4_step(rhs, t0 + i * h_, xk, h_)
        step = ca.Function("fit_step", [x, a, p], [xk])
        N = self.t.size
        A = np.column_stack([self.t[:-1], np.diff(self.t), self.u[:-1], self.u[1:]]).T
        X = step.mapaccum("fit_sim", N - 1)(self.x0, ca.DM(A), ca.repmat(self.p, 1, N - 1))
        Xall = ca.horzcat(self.x0, X)
        h = ca.Function("h", [cs.t, cs.x, cs.u, cs.p], [cs.h_sx]).map(N)
        Y = h(ca.DM(self.t).T, Xall, ca.DM(self.u.T) if nu else ca.DM(0, N), ca.repmat(self.p, 1, N))
        self._cache[n_sub] = Y
        self._X[n_sub] = Xall
        return Y

    def residual_functions(self, n_sub: int, meas: np.ndarray, weights: np.ndarray) -> tuple[ca.Function, ca.Function]:
        """r(θ, y_w) = y_w − w·ŷ(θ) over the measured samples, and its Jacobian in θ."""
        Y = self._Y(n_sub).T  # (N, p)
        idx = np.flatnonzero(meas.ravel())  # row-major: sample k, output j
        Yw = Y * ca.repmat(ca.DM(weights).T, Y.shape[0], 1)
        flat = ca.reshape(Yw.T, -1, 1)  # column-major of (p, N) = row-major of (N, p)
        sel = flat[idx.tolist()]
        yw = ca.MX.sym("yw", idx.size)
        res = yw - sel
        fun = ca.Function("fit_residual", [self.theta, yw], [res])
        jac = ca.Function("fit_jacobian", [self.theta], [ca.jacobian(-sel, self.theta)])
        return fun, jac

    def _run(self, n_sub: int) -> ca.Function:
        fn = self._runs.get(n_sub)
        if fn is None:
            Y = self._Y(n_sub)
            fn = self._runs[n_sub] = ca.Function("run", [self.theta], [self._X[n_sub], Y])
        return fn

    def states(self, theta: np.ndarray, n_sub: int) -> np.ndarray:
        """The simulated states at the samples, shape (N, n)."""
        return np.asarray(self._run(n_sub)(theta)[0]).T

    def outputs(self, theta: np.ndarray, n_sub: int) -> np.ndarray:
        return np.asarray(self._run(n_sub)(theta)[1]).T

    def output_jacobian(self, theta: np.ndarray, n_sub: int) -> np.ndarray:
        Y = self._Y(n_sub)  # (p, N)
        N, p, q = self.t.size, Y.shape[0], self.theta.shape[0]
        J = np.asarray(ca.Function("dy", [self.theta], [ca.jacobian(ca.reshape(Y.T, -1, 1), self.theta)])(theta))
        # rows of reshape(Y.T) run over N fastest: entry (j, k) at j*N + k
        return J.reshape(p, N, q).transpose(1, 0, 2)
