r"""Tuning a Kalman-family filter from a recording: diagonal Q, R (and optionally P(0)) by maximum likelihood.

**Objective.** The innovations log-likelihood of the recording under the filter (Schweppe (1965); Harvey (1989),
sec. 3.4; :mod:`._likelihood`)

.. math::

    \ell(\theta) = \sum_k -\tfrac12\big(\log\det(2\pi S_k) + \nu_k^\top S_k^{-1}\nu_k\big),

exact for a linear-Gaussian model and the usual approximation for a nonlinear one, as a function of
θ = (log q_1 … log q_n, log r_1 … log r_p [, log p0_1 … log p0_n]) with Q = diag(q), R = diag(r), P(0) = diag(p0).
With a reference trajectory (``truth=``) the objective is instead the mean squared state error of the filtered
estimate, each state in units of its initial standard deviation √P0_ii (as MATLAB's ``tune`` minimises the error
against ground truth).

**Method.** The filter's recursion (the same CasADi pieces as the likelihood: :class:`._likelihood._Filter`, RK4
sub-steps between samples, maps, multi-rate masks, censored outputs) is one step ``s_{k+1} = Φ(s_k, a_k, c)`` run
by the compiled loop of :mod:`nlobs.simulate._loop` over the samples. Its gradient is computed by the adjoint
(reverse-mode) recursion

.. math::

    \lambda_k = \partial_s\ell_k^\top + \partial_s\Phi_k^\top\lambda_{k+1}, \qquad
    \nabla_c\ell = \sum_k \partial_c\ell_k^\top + \partial_c\Phi_k^\top\lambda_{k+1},

whose step is CasADi's reverse-mode derivative of Φ (``jtimes(..., tr=True)``), run by the same compiled loop
backwards over the stored forward states. Its cost is a few forward passes whatever the number of variances (the
forward sensitivities of :mod:`._likelihood` cost one pass per unknown: 40 unknowns on 16 states is 40 passes of a
272-entry state). Both loops run as the compiled loop decides (:mod:`nlobs.simulate._loop`): on CasADi's virtual machine
until the time spent there reaches the predicted compile time, then as C built once per machine and cached on disk
(on a 16-state INS the adjoint's C takes minutes to compile on a loaded machine, once). The gradient in P(0) is λ₀
read at P(0)'s entries. SciPy's L-BFGS-B maximises ℓ in the
log-variances within bounds relative to reference scales (the start design's variances: a variance of Q between
10⁻⁸ and 10⁸ times its reference, R and P(0) between 10⁻⁶ and 10⁶ times theirs; a zero reference Q of a constant
state or parameter is replaced by P0_ii / T, the random walk that covers its initial uncertainty over the
recording), from several starts (the reference, then Q × 100 and Q / 100, then perturbations of the best).

**Convergence, stated honestly.** At the best start the Hessian of −ℓ over the variances not held at a bound is
taken by central differences of the exact gradient (the observed information); Newton steps polish the optimum,
and the tuning has converged when a further Newton step would move the estimate by less than 0.01 standard errors
(gᵀH⁻¹g < 10⁻⁴) with H positive definite. Only then are the standard errors of the log-variances (√diag H⁻¹)
reported. A variance whose gradient pushes against its bound is reported "at its lower/upper bound" (the data ask
for less process noise than the bound allows: a constant, or a random walk the recording cannot resolve); so is a
variance 10⁻³ below its reference that the likelihood cannot tell from its lower bound (log p changes by less than
10⁻³ there): drifting to 0, its logarithm has a vanishing slope and curvature, where the optimiser crawls and the
Hessian is singular.

**Check.** The normalised innovation squared of the tuned filter, NIS_k = ν_kᵀS_k⁻¹ν_k, summed over the samples is
χ² with Σ_k dim ν_k degrees of freedom for a consistent filter (Bar-Shalom, Li & Kirubarajan (2001), sec. 5.4); its
time average must lie in the two-sided 95 % band of that χ² divided by the number of samples.

The EKF's likelihood serves the srekf and iekf (the same filter up to rounding and, for the iekf, the iterated
update), the UKF's the srukf; the particle filter takes Q and R from an EKF tuning. Delayed samples enter the
likelihood at the times they were taken (the filter recalculation of :mod:`nlobs.simulate._delays` gives the same
innovations once every sample has arrived).
"""

from __future__ import annotations

import re
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import casadi as ca
import numpy as np

from ..design import ObserverDesign
from ..engine import Backend
from ..errors import DataError, ModelError, PreconditionError, ShapeError
from ..references import cite
from ..simulate._loop import Loop
from ..estimation import Recording
from ._likelihood import _Problem, _Recursion

__all__ = ["tune", "TuneResult", "tuned_kinds"]

def tuned_kinds() -> dict[str, str]:
    """Kinds tune takes, and the filter whose likelihood tunes each: read from the registry (``@kind(likelihood=...)``).
    MHE declares the EKF's likelihood for the weights of its cost, which ``design --run`` shares; tune itself designs
    filters, not an estimator of a different kind."""
    from ..design import KINDS

    return {k: v.likelihood for k, v in KINDS.items() if v.likelihood and k != "mhe"}
#: Bounds of each variance relative to its reference (Q, R, P(0)).
Q_RANGE, R_RANGE, P0_RANGE = (1e-8, 1e8), (1e-6, 1e6), (1e-6, 1e6)
#: Converged when a further Newton step would move the estimate by less than 0.01 standard errors (squared).
DECREMENT_TOL = 1e-4
#: Step of the central differences of the exact gradient that give the Hessian (in log-variance).
FD_STEP = 1e-4
#: Perturbed starts move every log-variance by N(0, SPREAD²) from the best so far (3: a factor 20, the modes of the
#: likelihood over noise variances lie decades apart).
SPREAD = 3.0
#: Two starts whose objectives (−log p) differ by less than this have found the same optimum.
AGREE = 1e-2
#: Directions along which the curvature of −log p (in log-variance) is below this are undetermined by the data: a
#: standard error above 5, a factor e^5 ≈ 150 each way.
FLAT = 0.04
#: Largest Newton step of the polish, in log-variance.
MAX_STEP = 2.0
#: A variance far below its reference is put on its lower bound when the objective changes by less than this there.
SNAP_TOL = 1e-3
#: A log-variance within this distance of a bound its gradient pushes against is held there.
AT_BOUND = 1e-3


@dataclass(frozen=True, eq=False)
class TuneResult:
    """The result of :func:`tune`.

    Attributes
    ----------
    kind : str
        The kind of the design that was tuned; ``likelihood_kind`` the filter whose likelihood (or RMS) was used.
    objective : {"likelihood", "truth"}
    names : tuple of str
        The variances, ``"Q[x1]"``, ``"R[y]"``, ``"P0[x1]"``.
    log_variance, std : numpy.ndarray
        The estimates (natural log of the variances) and their standard errors (NaN where they do not hold: not
        converged, held at a bound, or the truth objective).
    Q, R : numpy.ndarray
        The tuned matrices (R the declared one with ``fix_r``); ``P0`` the tuned P(0) or None.
    loglik, loglik_start : float
        log p(y | θ) of the tuned filter and of the start design.
    rms, rms_start : float or None
        With ``truth=``: the normalised RMS state error of the tuned and the start design.
    converged : bool
    message : str
    iterations, evaluations : int
    at_bound : dict of name to "lower"/"upper"
    nis : dict
        ``mean``, ``band`` (two-sided 95 %), ``ok``, ``dof``, ``samples``.
    attempts : tuple of dict
    notes : tuple of str
    seconds : float
    """

    kind: str
    likelihood_kind: str
    objective: str
    names: tuple[str, ...]
    log_variance: np.ndarray
    std: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    P0: np.ndarray | None
    loglik: float
    loglik_start: float
    converged: bool
    message: str
    iterations: int
    evaluations: int
    at_bound: Mapping[str, str]
    nis: Mapping[str, Any]
    rms: float | None = None
    rms_start: float | None = None
    attempts: tuple[Mapping[str, Any], ...] = ()
    notes: tuple[str, ...] = ()
    seconds: float = 0.0
    info: Mapping[str, Any] = field(default_factory=dict)

    @property
    def nis_ok(self) -> bool:
        return bool(self.nis["ok"])

    @property
    def variances(self) -> dict[str, float]:
        return {n: float(np.exp(v)) for n, v in zip(self.names, self.log_variance)}

    def apply(self, design: Any = None) -> ObserverDesign:
        """`design` (default: the one tuned) with the tuned Q, R (and P(0)), of its own kind and options."""
        from ..design import KINDS, options_of

        d = self.info["design"] if design is None else getattr(design, "design", design)
        if not _is_design(d) or d.method not in tuned_kinds():
            raise PreconditionError(f"TuneResult.apply: give a design of kind {', '.join(tuned_kinds())}, got "
                                    f"{getattr(d, 'method', type(d).__name__)!r}")
        if d.system.n_states != self.Q.shape[0] or d.system.n_outputs != self.R.shape[0]:
            raise ShapeError(f"TuneResult.apply: the design has {d.system.n_states} states and {d.system.n_outputs} outputs; "
                             f"the tuning {self.Q.shape[0]} and {self.R.shape[0]}")
        return KINDS[d.method].design(d.system, **self._options(d, options_of(KINDS[d.method].design)))

    def design(self) -> ObserverDesign:
        """The tuned design (the kind that was given, with its other options)."""
        return self.apply()

    def _options(self, d: ObserverDesign, accepted: Sequence[str]) -> dict[str, Any]:
        v = d.certificate.values
        opts: dict[str, Any] = {}
        for k in accepted:   # the design's own attribute (a particle filter's), else its certificate's number
            val = getattr(d, k, v.get(k)) if k not in ("bounds", "Q", "R", "P0", "xhat0") else None
            if val is not None and (not isinstance(val, str) or k in ("scheme", "mode")):
                opts[k] = val
        if "bounds" in accepted and isinstance(v.get("bounds"), str) and v["bounds"]:
            opts["bounds"] = _parse_bounds(v["bounds"])
        opts["Q"], opts["R"] = self.Q, self.R
        opts["P0"] = self.P0 if self.P0 is not None else np.asarray(v["P0"], dtype=float)
        if "xhat0" in accepted:
            opts["xhat0"] = np.asarray(d.xhat0, dtype=float).reshape(-1)
        return opts

    def toml(self, name: str | None = None) -> str:
        """An ``[observers.NAME]`` table with the tuned values, to paste into the model file."""
        from ..design import KINDS, options_of

        d = self.info["design"]
        opts = self._options(d, options_of(KINDS[d.method].design))
        name = name or f"{d.method}_tuned"
        lines = [f"[observers.{name}]", f'kind = "{d.method}"']
        for k, val in opts.items():
            lines.append(f"{k} = {_toml_value(val)}")
        return "\n".join(lines) + "\n"

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "likelihood_kind": self.likelihood_kind, "objective": self.objective,
                "Q": self.Q.tolist(), "R": self.R.tolist(), "P0": None if self.P0 is None else self.P0.tolist(),
                "variances": {n: {"variance": float(np.exp(v)), "log_variance": float(v), "log_std": float(s),
                                  "bound": self.at_bound.get(n)} for n, v, s in zip(self.names, self.log_variance, self.std)},
                "loglik": self.loglik, "loglik_start": self.loglik_start, "rms": self.rms, "rms_start": self.rms_start,
                "converged": self.converged, "message": self.message, "iterations": self.iterations,
                "evaluations": self.evaluations, "undetermined": list(self.info.get("undetermined", [])),
                "nis": dict(self.nis), "attempts": [dict(a) for a in self.attempts],
                "notes": list(self.notes), "seconds": self.seconds}

    def summary(self) -> str:
        what = ("innovations likelihood" if self.objective == "likelihood" else "RMS error against the reference trajectory")
        state = "converged" if self.converged else "NOT converged"
        lines = [f"tuned {self.kind.upper()} by the {what} of its {self.likelihood_kind.upper()}"
                 + (f" ({cite('schweppe1965')})" if self.objective == "likelihood" else "") + f": {state} after {self.iterations} iterations, {self.evaluations} gradient "
                 f"evaluations of L-BFGS-B ({cite('byrd1995')}) and Newton steps, {self.seconds:.1f} s ({self.message})"]
        if self.objective == "truth":
            lines.append(f"normalised RMS error {self.rms_start:.6g} with the start design, {self.rms:.6g} tuned")
        lines.append(f"log-likelihood {self.loglik_start:.8g} with the start design, {self.loglik:.8g} tuned")
        w = max(8, *(len(n) for n in self.names))
        head = f"{'variance':<{w}} {'value':>12} {'std(log)':>9} {'×/÷ 2σ':>8}  bound"
        lines += [head, "-" * len(head)]
        for n, v, s in zip(self.names, self.log_variance, self.std):
            b = self.at_bound.get(n, "")
            fac = f"{np.exp(2 * s):>8.3g}" if np.isfinite(s) else f"{'—':>8}"
            lines.append(f"{n:<{w}} {np.exp(v):>12.4g} {(f'{s:.3g}' if np.isfinite(s) else '—'):>9} {fac}  "
                         + (f"at its {b} bound" if b else "undetermined by the data" if s == np.inf else ""))
        nis = self.nis
        lines.append(f"NIS ({cite('barshalom2001', 'sec. 5.4')}): time average {nis['mean']:.4g}, 95 % band [{nis['band'][0]:.4g}, {nis['band'][1]:.4g}] "
                     f"({nis['dof']} innovation components over {nis['samples']} samples): "
                     + ("inside" if nis["ok"] else "OUTSIDE — the tuned filter is not consistent with the data"))
        if not self.converged:
            lines.append("standard errors are not shown: they hold only at a converged maximum; try more starts or "
                         "iterations (starts=, max_iter=; --starts, --max-iter)")
        elif self.objective == "truth":
            lines.append("no standard errors: the RMS objective is not a likelihood")
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()


def _toml_value(v: Any) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if v is None:
        return '"none"'
    a = np.asarray(v, dtype=float) if not isinstance(v, (list, tuple)) or all(
        isinstance(x, (int, float, np.number, list, tuple, np.ndarray)) for x in v) else None
    if a is not None and a.ndim == 0:
        return repr(float(a))
    if a is not None and a.ndim == 1:
        return "[" + ", ".join(repr(float(x)) for x in a) + "]"
    if a is not None and a.ndim == 2:
        return "[" + ", ".join("[" + ", ".join(repr(float(x)) for x in row) + "]" for row in a) + "]"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(v)


def _parse_bounds(text: str) -> dict[str, list[float | None]]:
    out: dict[str, list[float | None]] = {}
    for m in re.finditer(r"(\w+) in \[([^,\]]+), ([^\]]+)\]", text):
        lo, hi = float(m.group(2)), float(m.group(3))
        out[m.group(1)] = [lo if np.isfinite(lo) else None, hi if np.isfinite(hi) else None]
    return out


# -- the start design and the recording -------------------------------------------------------------------------------
def _start_design(design: Any, observer: str, caller: str) -> ObserverDesign:
    from ..model import ModelFile

    if isinstance(design, ModelFile):
        from ..design import design_from_config

        configured = design.observers
        name = observer if observer in configured else None
        if name is None:
            same = [n for n, c in configured.items() if c.kind == observer]
            if len(same) != 1:
                raise PreconditionError(
                    f"{caller}: the model file {design.path} configures {len(same) or 'no'} observer(s) of kind "
                    f"{observer!r}; name one ({', '.join(configured) or 'none configured'}), give a design "
                    f"(nlobs.design_{observer}(...)), or run `nlobs tune`, which starts from the advisor's tuning")
            name = same[0]
        c = configured[name]
        design = design_from_config(design.observer_system, c.kind, c.options, where=f"{design.path}: observers.{name}")
    d = getattr(design, "design", design)
    if not _is_design(d):
        raise TypeError(f"{caller}: give an observer design of kind {', '.join(tuned_kinds())} (nlobs.design_ekf(...), an "
                        f"advisor's candidate's .design) or a model file that configures one; got {type(design).__name__}")
    if d.method not in tuned_kinds():
        raise PreconditionError(f"{caller}: observer kind {d.method!r} has no noise covariances to tune here; supported: "
                                f"{', '.join(tuned_kinds())}")
    if d.method == "ekf" and getattr(d, "update", None) is None and not d.system.is_discrete:
        raise PreconditionError(f"{caller}: the EKF in continuous mode takes R as an intensity and no samples; tune the "
                                "continuous-discrete EKF (mode='continuous-discrete', the default)")
    return d


def _is_design(d: Any) -> bool:
    from ..design.kalman._pf import ParticleDesign

    return isinstance(d, (ObserverDesign, ParticleDesign))


def _likelihood_design(d: ObserverDesign, notes: list[str]) -> ObserverDesign:
    from ..design import design_ekf, design_ukf

    v = d.certificate.values
    kind = tuned_kinds()[d.method]
    common = {"Q": v["Q"], "R": v["R"], "P0": v["P0"], "xhat0": np.asarray(d.xhat0, dtype=float).reshape(-1)}
    if d.method != kind:   # a square-root form (the same filter up to rounding), the iterated EKF, the pf
        from ..design import KINDS

        what = KINDS[d.method].summary.split(" (")[0]
        notes.append(f"the {what} ({d.method}) takes Q and R from the {kind.upper()}'s innovations likelihood on the "
                     "recording")
    if v.get("bounds"):
        notes.append(f"the likelihood runs the filter without the design's state bounds ({v['bounds']}); the tuned "
                     "design keeps them")
    if kind == "ukf" and d.method in ("ukf", "srukf"):
        return design_ukf(d.system, **common, alpha=float(v["alpha"]), beta=float(v["beta"]), kappa=float(v["kappa"]))
    return design_ekf(d.system, **common) if kind == "ekf" else design_ukf(d.system, **common)


def _at_taken_times(rec: Recording, delay: Mapping[str, float], mask: np.ndarray,
                    truth: np.ndarray | None) -> tuple[Recording, np.ndarray, np.ndarray | None, np.ndarray, int]:
    """The recording re-stamped at the times its samples were taken (rows at the union of the row times and the taken
    times, inputs held from the row before); the mask, the truth on the new rows (NaN between rows) and which rows
    are the recording's; the samples taken before its first time (left out)."""
    from ..simulate._delays import _merged, _tol
    from ..simulate._schedule import SampleSchedule

    ev = SampleSchedule.of_recording(rec.t, mask > 0, rec.output_names, delay=delay, caller="tune").events(rec.y)
    keep = ev.taken >= rec.t[0] - _tol(rec.t[0])
    early = int(np.count_nonzero(~keep))
    taken, out, val = ev.taken[keep], ev.output[keep], ev.value[keep]
    T = _merged(np.concatenate([rec.t, taken]))
    k = np.clip(np.searchsorted(T, taken - _tol(taken), side="left"), 0, T.size - 1)
    row = np.clip(np.searchsorted(rec.t, T + _tol(T), side="right") - 1, 0, rec.t.size - 1)
    Y = np.full((T.size, rec.y.shape[1]), np.nan)
    Y[k, out] = val
    is_row = np.abs(rec.t[row] - T) <= _tol(T)
    X = None
    if truth is not None:
        X = np.full((T.size, truth.shape[1]), np.nan)
        X[is_row] = truth[row[is_row]]
    new = Recording(T, rec.u[row], Y, rec.input_names, rec.output_names, None, (), rec.source)
    return new, np.isfinite(Y).astype(float), X, is_row, early


def _read_truth(truth: Any, rec: Recording, system: Any, caller: str) -> tuple[np.ndarray, list[int]]:
    """The reference trajectory at the recording's rows (interpolated from a CSV's times) and the states it gives."""
    names = list(system.states)
    if isinstance(truth, (str, Path)):
        import csv

        p = Path(truth)
        try:
            with p.open(newline="", encoding="utf-8-sig") as fh:
                rows = list(csv.reader(fh))
        except OSError as e:
            raise DataError(f"{caller}: cannot read the reference trajectory {p}: {e.strerror}") from None
        header = [h.strip() for h in rows[0]] if rows else []
        if "t" not in header:
            raise DataError(f"{caller}: the reference trajectory {p} has no column t; its header must name t and states "
                            f"({', '.join(names)})")
        idx = [i for i, s in enumerate(names) if s in header]
        if not idx:
            raise DataError(f"{caller}: the reference trajectory {p} names none of the states {', '.join(names)}")
        try:
            data = np.array([[float(r[header.index(c)]) for c in ["t", *(names[i] for i in idx)]] for r in rows[1:]])
        except (ValueError, IndexError):
            raise DataError(f"{caller}: the reference trajectory {p} has a cell that is not a number") from None
        tt, vals = data[:, 0], data[:, 1:]
        if tt[0] > rec.t[0] + 1e-9 * max(1.0, abs(rec.t[0])) or tt[-1] < rec.t[-1] - 1e-9 * max(1.0, abs(rec.t[-1])):
            raise DataError(f"{caller}: the reference trajectory {p} covers t = {tt[0]:g} to {tt[-1]:g}; the recording "
                            f"{rec.t[0]:g} to {rec.t[-1]:g}")
        X = np.column_stack([np.interp(rec.t, tt, vals[:, j]) for j in range(len(idx))])
        return X, idx
    X = np.asarray(truth, dtype=float)
    if X.ndim == 1:
        X = X[:, None]
    n_plant = system.n_states - len(system.estimated_params or ())
    if X.shape[0] != rec.t.size or X.shape[1] not in (n_plant, system.n_states):
        raise ShapeError(f"{caller}: `truth` must have shape ({rec.t.size}, {n_plant}) (the states at the recording's "
                         f"times){f' or ({rec.t.size}, {system.n_states})' if n_plant != system.n_states else ''}; "
                         f"found {X.shape}")
    if not np.all(np.isfinite(X)):
        raise DataError(f"{caller}: `truth` has non-finite entries")
    return X, list(range(X.shape[1]))


# -- the objective and its adjoint -----------------------------------------------------------------------------------
class _Objective:
    """The likelihood (or the RMS error) as a function of the log-variances, with its gradient by the adjoint loop."""

    def __init__(self, prob: _Problem, d: ObserverDesign, fix_r: bool, tune_p0: bool, truth: np.ndarray | None,
                 truth_idx: Sequence[int], scale: np.ndarray, engine: Backend):
        fsys = prob.model.system
        n, ny, npar = fsys.n_states, fsys.n_outputs, fsys.n_params
        self.n, self.ny, self.npar, self.prob, self.engine = n, ny, npar, prob, engine
        self.fix_r, self.tune_p0 = fix_r, tune_p0
        self.nq, self.nr = n, (0 if fix_r else ny)
        self.nc = npar + self.nq + self.nr
        self.q = self.nq + self.nr + (n if tune_p0 else 0)
        R0 = ca.DM(np.asarray(d.certificate.values["R"], dtype=float))

        def noise(cn: Any) -> tuple[Any, Any]:
            Q = ca.diag(ca.exp(cn[:n]))
            R = R0 if fix_r else ca.diag(ca.exp(cn[n:n + ny]))
            return Q, R

        self.core = _Recursion._core(prob.d, fsys, prob.n_sub, noise, self.nq + self.nr)
        core_n = n + n * n
        self.core_n = core_n
        na = prob.A.shape[1]
        self.truth = truth is not None
        nt = len(truth_idx) if truth is not None else 0
        s, a, c = ca.SX.sym("s", core_n), ca.SX.sym("a", na + (nt + 1 if truth is not None else 0)), ca.SX.sym("c", self.nc)
        out = self.core(s, a[:na], c)
        if truth is None:
            inc = out[1] + out[2]
        else:
            xt, w = a[na:na + nt], a[na + nt]
            e = (out[0][list(truth_idx)] - xt) / ca.DM(scale)
            inc = w * ca.dot(e, e)
        acc = ca.SX.sym("acc")
        self.fwd = Loop(ca.Function("tune_forward", [ca.vertcat(s, acc), a, c], [ca.densify(ca.vertcat(out[0], acc + inc))]))
        lam, gacc = ca.SX.sym("lam", core_n), ca.SX.sym("g", self.nc)
        adj = ca.jtimes(ca.vertcat(out[0], inc), ca.vertcat(s, c), ca.vertcat(lam, 1), True)
        row = ca.vertcat(s, a)
        self.bwd = Loop(ca.Function("tune_adjoint", [ca.vertcat(lam, gacc), row, c],
                                    [ca.densify(ca.vertcat(adj[:core_n], gacc + adj[core_n:]))]))
        A = prob.A
        if truth is not None:
            w = np.all(np.isfinite(truth), axis=1).astype(float)
            self.weight_total = float(w.sum()) * nt
            A = np.hstack([A, np.where(np.isfinite(truth), truth, 0.0), w[:, None]])
        self.A = A
        self.p = np.asarray(fsys.param_values, dtype=float)
        self.s0 = prob.s0.copy()
        self.evaluations = 0
        self._memo: tuple[bytes, float, np.ndarray] | None = None

    def parts(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = self.n
        c = np.concatenate([self.p, theta[:self.nq + self.nr]])
        s0 = self.s0.copy()
        if self.tune_p0:
            s0[n:] = np.diag(np.exp(theta[self.nq + self.nr:])).reshape(-1, order="F")
        return c, s0

    def __call__(self, theta: np.ndarray) -> tuple[float, np.ndarray]:
        """f(θ) to minimise (−log p, or the mean squared normalised error) and its gradient."""
        key = np.asarray(theta, dtype=float).tobytes()
        if self._memo is not None and self._memo[0] == key:
            return self._memo[1], self._memo[2].copy()
        self.evaluations += 1
        c, s0 = self.parts(theta)
        S = self.fwd(np.r_[s0, 0.0], self.A, c, self.engine)
        J = float(S[-1, -1])
        if not np.isfinite(J) or not np.all(np.isfinite(S[-1])):
            self._memo = (key, np.inf, np.zeros(self.q))
            return np.inf, np.zeros(self.q)
        prev = np.vstack([s0[None, :], S[:-1, :self.core_n]])
        rows = np.hstack([prev, self.A])[::-1]
        B = self.bwd(np.zeros(self.core_n + self.nc), rows, c, self.engine)
        lam0, gc = B[-1, :self.core_n], B[-1, self.core_n:]
        g = gc[self.npar:]
        if self.tune_p0:
            n = self.n
            dp = lam0[n + np.arange(n) * (n + 1)] * np.exp(theta[self.nq + self.nr:])
            g = np.concatenate([g, dp])
        if self.truth:
            f, g = J / self.weight_total, g / self.weight_total
        else:
            f, g = -J, -g
        if not np.all(np.isfinite(g)):
            f, g = np.inf, np.zeros(self.q)
        self._memo = (key, f, g.copy())
        return f, g

    def run(self, theta: np.ndarray) -> dict[str, Any]:
        """The filter at θ: log p, the NIS terms, and the filtered states (rows)."""
        c, s0 = self.parts(theta)
        N = self.A.shape[0]
        out = self.core.mapaccum("tune_run", N)(s0, self.prob.A.T, c)
        ll = float(np.sum(np.asarray(out[1])) + np.sum(np.asarray(out[2])))
        X = np.asarray(out[0]).T[:, :self.n]
        return {"loglik": ll, "nis": np.asarray(out[7]).reshape(-1), "x": X}


def _hessian(obj: _Objective, theta: np.ndarray, free: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Central differences of the exact gradient over the free unknowns (one-sided next to a bound)."""
    q = theta.size
    H = np.zeros((q, q))
    g0 = obj(theta)[1]
    for j in np.flatnonzero(free):
        e = np.zeros(q)
        e[j] = FD_STEP
        up, down = theta[j] + FD_STEP <= hi[j], theta[j] - FD_STEP >= lo[j]
        if up and down:
            H[:, j] = (obj(theta + e)[1] - obj(theta - e)[1]) / (2 * FD_STEP)
        elif up:
            H[:, j] = (obj(theta + e)[1] - g0) / FD_STEP
        else:
            H[:, j] = (g0 - obj(theta - e)[1]) / FD_STEP
    F = np.ix_(free, free)
    H[F] = 0.5 * (H[F] + H[F].T)
    return H


def _held(theta: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return ((theta <= lo + AT_BOUND) & (g > 0)) | ((theta >= hi - AT_BOUND) & (g < 0))


def _snap(obj: _Objective, theta: np.ndarray, lo: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Variances far below their reference (10⁻³ of it) that the objective cannot tell from their lower bound (it
    changes by less than SNAP_TOL there) are put on that bound: a variance drifting to 0 has a vanishing slope and
    curvature in its logarithm, where the optimiser crawls and the Hessian is singular."""
    f = obj(theta)[0]
    tol = SNAP_TOL if not obj.truth else 1e-4 * abs(f)   # log p, or a relative change of the mean squared error
    snapped = np.zeros(theta.size, dtype=bool)
    for i in np.argsort(theta - ref):
        if theta[i] > ref[i] - np.log(1e3) or theta[i] <= lo[i] + AT_BOUND:
            continue
        trial = theta.copy()
        trial[i] = lo[i]
        ft = obj(trial)[0]
        if ft <= f + tol:
            theta, f = trial, min(f, ft)
            snapped[i] = True
    return theta, snapped


@dataclass
class _Stationary:
    """Where the polish ended: θ, the Hessian, the variances held at a bound, the Newton decrement over the determined
    directions, whether it is a maximum there, the covariance of the log-variances, and the undetermined ones."""

    theta: np.ndarray
    H: np.ndarray
    held: np.ndarray
    decrement: float
    maximum: bool
    cov: np.ndarray
    undetermined: np.ndarray


def _newton(H: np.ndarray, g: np.ndarray, flat: float) -> tuple[np.ndarray, float, bool, np.ndarray, np.ndarray]:
    """The Newton step over the directions whose curvature exceeds `flat` (|H| in place of H where it is negative: the
    saddle-free step), the decrement gᵀH⁻¹g over them, whether they all curve up and the gradient along the flat ones
    is below `flat` too, the pseudo-inverse of H over them, and which unknowns lie mostly along flat directions."""
    ev, V = np.linalg.eigh(H)
    big = np.abs(ev) > flat
    proj = V.T @ g
    step = V[:, big] @ (proj[big] / np.abs(ev[big]))
    dec = float(np.sum(proj[big] ** 2 / np.abs(ev[big])))
    maximum = bool(np.all(ev[big] > 0) and np.all(np.abs(proj[~big]) <= flat))
    cov = (V[:, big] / np.where(ev[big] > 0, ev[big], np.inf)) @ V[:, big].T
    undetermined = np.sum(V[:, ~big] ** 2, axis=1) > 0.5
    return step, dec, maximum, cov, undetermined


def _polish(obj: _Objective, theta: np.ndarray, fixed: np.ndarray, lo: np.ndarray, hi: np.ndarray,
            rounds: int = 6) -> _Stationary:
    """Newton steps with the finite-difference Hessian until the decrement is below DECREMENT_TOL (see _newton)."""
    q = theta.size
    for k in range(rounds + 1):
        f, g = obj(theta)
        held = _held(theta, g, lo, hi) | fixed
        free = ~held
        if not free.any():
            return _Stationary(theta, np.zeros((q, q)), held, 0.0, True, np.zeros((q, q)), np.zeros(q, dtype=bool))
        H = _hessian(obj, theta, free, lo, hi)
        Hf, gf = H[np.ix_(free, free)], g[free]
        if not np.all(np.isfinite(Hf)):
            return _Stationary(theta, H, held, float("nan"), False, np.full((q, q), np.nan), np.zeros(q, dtype=bool))
        ev_max = float(np.max(np.abs(np.linalg.eigvalsh(Hf))))
        flat = FLAT if not obj.truth else 1e-8 * ev_max   # the likelihood's curvature is in units of log p
        step, dec, maximum, cov_f, und_f = _newton(Hf, gf, max(flat, 1e-12 * ev_max))
        cov = np.full((q, q), np.nan)
        cov[np.ix_(free, free)] = cov_f
        und = np.zeros(q, dtype=bool)
        und[free] = und_f
        if (maximum and dec < DECREMENT_TOL) or k == rounds:
            return _Stationary(theta, H, held, dec, maximum, cov, und)
        biggest = float(np.max(np.abs(step))) if step.size else 0.0
        if biggest > MAX_STEP:   # at most a factor e² on a variance per step
            step = step * (MAX_STEP / biggest)
        for a in (1.0, 0.5, 0.25, 0.125):
            trial = theta.copy()
            trial[free] = np.clip(theta[free] - a * step, lo[free], hi[free])
            if obj(trial)[0] < f:
                theta = trial
                break
        else:
            return _Stationary(theta, H, held, dec, maximum, cov, und)
    raise AssertionError("unreachable")


def tune(design_or_model: Any, recording: Recording, *, observer: str = "ekf", fix_r: bool = False,
         tune_p0: bool = False, truth: Any = None, starts: int = 3, max_iter: int = 200,
         delay: Mapping[str, float] | None = None, on_missing: Literal["error", "skip"] = "error",
         max_step: float | None = None, engine: Backend = "auto",
         progress: bool | Callable[[float], None] | None = None, seed: int = 0) -> TuneResult:
    """Tune the noise covariances of a Kalman-family filter on a recording: diagonal Q, R (and P(0)).

    Maximises the filter's innovations likelihood (or, with `truth`, minimises its RMS state error) over one
    log-variance per state, per output and, with `tune_p0`, per initial state; see :mod:`._tune_noise` for the method
    (adjoint gradient through the compiled filter loop, L-BFGS-B from several starts, Newton polishing, standard
    errors from the observed information, and the NIS check).

    Parameters
    ----------
    design_or_model : ObserverDesign, Observer, candidate or ModelFile
        The start: an ekf, ukf, srekf, srukf, iekf or pf design (its Q, R, P0, x̂0 and options; its variances are the
        reference scales of the bounds), or a model file that configures an observer named or of kind `observer`.
    recording : Recording
    observer : str
        With a model file: the name or kind of its configured observer.
    fix_r : bool
        Keep the design's R (then it may be a full matrix).
    tune_p0 : bool
        Also tune diag P(0).
    truth : array of shape (N, n) or CSV path, optional
        The true states at the recording's times (a CSV with t and state columns is interpolated onto them): minimise
        the mean squared error of the filtered estimate, each state in units of its initial standard deviation √P0_ii.
    starts : int
        Most starts of L-BFGS-B (with R tuned too: first Q fitted with R fixed; then the reference; Q × 100; Q / 100;
        then perturbations of the best by a factor of about 20).
    max_iter : int
        Most L-BFGS-B iterations per start.
    delay : mapping of output to seconds, optional
        Known measurement delays of a recording stamped at arrival (as :func:`nlobs.estimate`): the likelihood takes
        each sample at the time it was taken. Continuous-time models only.
    on_missing, max_step, engine
        As for :func:`nlobs.estimate`.
    progress : bool or callable
        True: a bar on stderr; a callable gets the fraction done.
    seed : int
        Seed of the random perturbations of the best start (the starts after the first three).

    Returns
    -------
    TuneResult
    """
    caller = "tune"
    t_start = time.perf_counter()
    notes: list[str] = []
    d = _start_design(design_or_model, observer, caller)
    if not isinstance(recording, Recording):
        raise TypeError(f"{caller}: `recording` must be an nlobs.Recording, got {type(recording).__name__}")
    if int(starts) < 1 or int(max_iter) < 1:
        raise ModelError(f"{caller}: `starts` and `max_iter` must be at least 1, got {starts!r} and {max_iter!r}")
    system = d.system
    lik = _likelihood_design(d, notes)
    recording.check_columns(system, f"{caller}: the model {system.name!r}")
    X_truth, idx = (None, [])
    if truth is not None:
        X_truth, idx = _read_truth(truth, recording, system, caller)
    rec, miss = recording, on_missing
    delayed = bool(delay) and any(float(v) > 0 for v in (delay or {}).values())
    if delayed:
        if system.is_discrete:
            raise ModelError(f"{caller}: measurement delays are handled for continuous-time models; a map steps from "
                             "sample to sample: shift the delayed output's column by its delay in steps instead")
        mask = recording.check_finite(on_missing)
        rec, _, X_truth, _, early = _at_taken_times(recording, delay or {}, mask, X_truth)
        miss = "skip"
        notes.append(f"delayed outputs ({', '.join(k for k, v in (delay or {}).items() if float(v) > 0)}) enter the "
                     "likelihood at the times they were taken" + (f"; {early} sample(s) taken before the recording's "
                                                                  "first time were left out" if early else ""))
    prob = _Problem(lik, rec, (), False, max_step, miss, engine, caller)
    v = d.certificate.values
    Q0, R0, P00 = (np.atleast_2d(np.asarray(v[k], dtype=float)) for k in ("Q", "R", "P0"))
    n, ny = system.n_states, system.n_outputs
    span = float(rec.t[-1] - rec.t[0]) if not system.is_discrete else float(rec.t.size)
    qref = np.diag(Q0).copy()
    zero = qref <= 1e-300
    qref[zero] = np.maximum(np.diag(P00)[zero], 1e-300) / max(span, 1e-300)
    if zero.any():
        notes.append(f"Q of {', '.join(system.states[i] for i in np.flatnonzero(zero))} is 0 in the start design: its "
                     f"reference is P0_ii / {'N' if system.is_discrete else 'T'} (the random walk that covers the initial "
                     "uncertainty over the recording)")
    names = [f"Q[{s}]" for s in system.states]
    ref, rng_lo, rng_hi = [qref], [np.full(n, Q_RANGE[0])], [np.full(n, Q_RANGE[1])]
    if not fix_r:
        names += [f"R[{o}]" for o in system.outputs]
        ref.append(np.diag(R0))
        rng_lo.append(np.full(ny, R_RANGE[0]))
        rng_hi.append(np.full(ny, R_RANGE[1]))
    if tune_p0:
        names += [f"P0[{s}]" for s in system.states]
        ref.append(np.diag(P00))
        rng_lo.append(np.full(n, P0_RANGE[0]))
        rng_hi.append(np.full(n, P0_RANGE[1]))
    theta_ref = np.log(np.maximum(np.concatenate(ref), 1e-300))
    lo = theta_ref + np.log(np.concatenate(rng_lo))
    hi = theta_ref + np.log(np.concatenate(rng_hi))
    scale = np.sqrt(np.maximum(np.diag(P00)[idx], 1e-300)) if X_truth is not None else np.ones(0)
    obj = _Objective(prob, lik, fix_r, tune_p0, X_truth, idx, scale, engine)
    # the start design's own values (a full Q or R: their diagonals)
    theta0 = np.log(np.maximum(np.concatenate([np.diag(Q0)] + ([] if fix_r else [np.diag(R0)])
                                              + ([np.diag(P00)] if tune_p0 else [])), 1e-300))
    theta0 = np.clip(theta0, lo, hi)
    f0 = obj(theta0)[0]
    if not np.isfinite(f0):
        raise DataError(f"{caller}: the {lik.method} with the start design's Q and R does not stay finite on the "
                        f"recording ({prob.where_not_finite(prob.theta0()) or 'its state becomes non-finite'}); start from "
                        "a design that runs on it (nlobs estimate shows where it fails)")
    from .._progress import as_progress

    bar = as_progress(progress, "tune")
    extra = [] if fix_r or X_truth is not None else [_fixed_r_start(prob, lik, theta0, lo, hi, n, ny, tune_p0, idx, scale,
                                                                     engine, int(starts), int(max_iter), seed, caller)]
    best, attempts, total_iter = _multistart(obj, theta0, lo, hi, n, int(starts), int(max_iter), seed, bar, caller,
                                             extra)
    st = _polish(obj, *_snap(obj, best[1], lo, theta_ref), lo, hi)
    theta, held, dec = st.theta, st.held, st.decrement
    f_best, g = obj(theta)
    converged = bool(st.maximum and np.isfinite(dec) and dec < DECREMENT_TOL)
    std = np.full(theta.size, np.nan)
    undetermined = [names[i] for i in np.flatnonzero(st.undetermined)]
    if converged and X_truth is None:
        std = np.sqrt(np.maximum(np.diag(st.cov), 0.0))
        std[st.undetermined] = np.inf
        std[held] = np.nan
    message = _verdict(converged, st.maximum, dec, undetermined, X_truth is None)
    at_bound = {names[i]: ("lower" if theta[i] <= lo[i] + AT_BOUND else "upper") for i in np.flatnonzero(held)}
    Q = np.diag(np.exp(theta[:n]))
    R = R0.copy() if fix_r else np.diag(np.exp(theta[n:n + ny]))
    P0 = np.diag(np.exp(theta[-n:])) if tune_p0 else None
    run = obj.run(theta)
    run0 = obj.run(theta0)
    nis = _nis(run["nis"], prob)
    rms = rms0 = None
    if X_truth is not None:
        rms, rms0 = float(np.sqrt(max(f_best, 0.0))), float(np.sqrt(max(f0, 0.0)))
    if bar is not None:
        bar(1.0)
    notes += list(prob.model.notes(prob.codes))
    return TuneResult(d.method, lik.method, "likelihood" if X_truth is None else "truth", tuple(names), theta, std, lo, hi,
                      Q, R, P0, run["loglik"], run0["loglik"], converged, message, total_iter, obj.evaluations, at_bound,
                      nis, rms, rms0, tuple(attempts), tuple(notes), time.perf_counter() - t_start,
                      info={"design": d, "likelihood_design": lik, "substeps": prob.n_sub, "samples": prob.N,
                            "gradient": g, "hessian": st.H, "held": held, "decrement": dec, "undetermined": undetermined,
                            "source": recording.source})




def _verdict(converged: bool, maximum: bool, dec: float, undetermined: list[str], likelihood: bool) -> str:
    """The result's message: converged (by how little a Newton step would move it), or why not; what the data leave
    undetermined."""
    what = "standard errors" if likelihood else "(in units of the objective's curvature)"
    if converged:
        message = f"a further Newton step would move the estimate by {np.sqrt(max(dec, 0.0)):.2g} {what}"
    elif not maximum:
        message = ("not a maximum: the Hessian over the free variances has a direction of negative curvature at the "
                   "best point; try more starts or iterations (starts=, max_iter=; --starts, --max-iter)")
    else:
        message = f"a Newton step would still move the estimate by {np.sqrt(dec):.3g} {what}"
    if undetermined:
        message += (f"; the data do not determine {', '.join(undetermined)} (log p changes by less than "
                    f"{FLAT / 2:g} over a factor e of each: any value there serves)")
    return message


def _fixed_r_start(prob: Any, lik: Any, theta0: np.ndarray, lo: np.ndarray, hi: np.ndarray, n: int, ny: int,
                   tune_p0: bool, idx: Any, scale: np.ndarray, engine: Any, starts: int, max_iter: int, seed: int,
                   caller: str) -> tuple[str, np.ndarray]:
    """A start for the joint fit of Q and R: Q (and P(0)) fitted with R at the design's value. Q and R trade off (a
    position's random walk against its sensor's noise), with modes decades apart; this start lies in the basin the
    declared R points to, and the joint fit then moves R too (a coordinated turn: log p 3135.8 from here, 3093 from the
    design)."""
    keep = np.r_[np.arange(n), n + ny + np.arange(n if tune_p0 else 0)]
    obj_r = _Objective(prob, lik, True, tune_p0, None, idx, scale, engine)
    best, _, _ = _multistart(obj_r, theta0[keep], lo[keep], hi[keep], n, min(starts, 3), max_iter, seed, None, caller)
    th = theta0.copy()
    th[keep] = best[1]
    return "Q fitted with R fixed", th

def _multistart(obj: Any, theta0: np.ndarray, lo: np.ndarray, hi: np.ndarray, n: int, starts: int, max_iter: int,
                seed: int, bar: Any, caller: str, extra: Sequence[tuple[str, np.ndarray]] = ()
                ) -> tuple[tuple[float, np.ndarray, int], list[dict[str, Any]], int]:
    """L-BFGS-B from the `extra` starts, the start design, Q × 100, Q / 100, then perturbations of the best, until two
    starts agree or `starts` are spent: the best (objective, θ, iterations), every attempt, and the iterations in all."""
    rng = np.random.default_rng(seed)
    plan = [*((label, np.clip(th, lo, hi)) for label, th in extra), ("start design", theta0)]
    nq = n
    for label, fac in (("Q × 100", 100.0), ("Q / 100", 0.01)):
        th = theta0.copy()
        th[:nq] += np.log(fac)
        plan.append((label, np.clip(th, lo, hi)))
    attempts: list[dict[str, Any]] = []
    best: tuple[float, np.ndarray, int] | None = None
    total_iter = 0
    from scipy.optimize import minimize

    k = 0
    while k < starts:
        if k < len(plan):
            label, th = plan[k]
        else:
            assert best is not None
            label, th = f"perturbed start {k - len(plan) + 1}", np.clip(best[1] + rng.normal(0, SPREAD, best[1].size), lo, hi)
        k += 1
        t1, e1 = time.perf_counter(), obj.evaluations
        if not np.isfinite(obj(th)[0]):
            attempts.append({"start": label, "objective": None, "iterations": 0, "seconds": 0.0,
                             "message": "the filter does not stay finite at this start"})
            continue
        count = [0]

        def cb(*_: Any) -> None:
            count[0] += 1
            if bar is not None:
                bar(min(((k - 1) + 1 - 0.5 ** (count[0] / 10)) / starts, 0.999))

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            # L-BFGS-B's first step is the gradient itself (its inverse Hessian starts as I): with −log p of thousands of
            # samples that step runs to the box's corner, where the filter diverges (f = ∞), and the line search gives up
            # at once. Scaled to the start's |f|, the first step is a fraction of a unit of log-variance.
            f_scale = max(abs(float(obj(th)[0])), 1.0)

            def scaled(x: np.ndarray) -> tuple[float, np.ndarray]:
                f, g = obj(x)
                return f / f_scale, g / f_scale

            sol = minimize(scaled, th, jac=True, method="L-BFGS-B", bounds=list(zip(lo, hi)), callback=cb,
                           options={"maxiter": max_iter, "ftol": 1e-11, "gtol": 1e-7, "maxcor": 20})
        x = np.asarray(sol.x, dtype=float)
        fx = obj(x)[0]
        total_iter += int(sol.nit)
        attempts.append({"start": label, "objective": float(fx), "iterations": int(sol.nit),
                         "evaluations": obj.evaluations - e1, "seconds": time.perf_counter() - t1,
                         "message": str(sol.message)})
        if best is None or fx < best[0]:
            best = (float(fx), x, int(sol.nit))
        done = [a["objective"] for a in attempts if a["objective"] is not None]
        if len(done) >= 2 and sum(abs(o - best[0]) <= AGREE for o in done) >= 2:
            break   # two starts agree on the optimum (to less than a hundredth of a standard error's worth of log p)
    if best is None:
        raise DataError(f"{caller}: the filter does not stay finite at any start; start from a design that runs on the "
                        "recording")
    return best, attempts, total_iter

def _nis(terms: np.ndarray, prob: _Problem) -> dict[str, Any]:
    """The time-average NIS and its two-sided 95 % χ² band (Bar-Shalom, Li & Kirubarajan (2001), sec. 5.4)."""
    from scipy.stats import chi2

    ny = prob.system.n_outputs
    A = prob.A
    o = A.shape[1] - 4 * ny
    m, z = A[:, o + ny:o + 2 * ny], A[:, o + 2 * ny:o + 3 * ny]
    m_eff = m * (1 - z * z)
    dims = m_eff.sum(axis=1)
    K = int(np.count_nonzero(dims > 0))
    dof = int(round(dims.sum()))
    mean = float(terms[dims > 0].sum() / max(K, 1))
    band = (float(chi2.ppf(0.025, dof) / max(K, 1)), float(chi2.ppf(0.975, dof) / max(K, 1)))
    return {"mean": mean, "band": band, "ok": bool(band[0] <= mean <= band[1]), "dof": dof, "samples": K,
            "expected": dof / max(K, 1)}
