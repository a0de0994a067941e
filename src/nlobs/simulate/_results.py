"""The result of a simulation or of an estimation on recorded data."""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from .._display import MISSING, Column, SummaryTable, fmt_number, short_repr
from ._metrics import PER_STATE_RULE, Metrics, error_metrics, state_metrics
from ._whiteness import Whiteness, ljung_box

__all__ = ["ObserverFailure", "ObserverTrace", "Run", "lean_traces", "write_csv"]


def write_csv(path: Any, header: Sequence[str], data: np.ndarray) -> None:
    """A CSV of `data` under `header`: floats in their shortest exact form (``repr``), NaN as an empty cell."""
    import csv

    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        w.writerows([("" if v != v else repr(v)) for v in row] for row in data.tolist())



@dataclass(frozen=True, eq=False)
class ObserverTrace:
    """One observer's signals in a :class:`Run` (time on the first axis).

    Attributes
    ----------
    name, method : str
    z_names : tuple of str
    z : numpy.ndarray of shape (N, n_z)
        Internal state at each time (after the sample-time update, for sampled observers).
    xhat : numpy.ndarray of shape (N, n)
        The estimate.
    xhat_prior : numpy.ndarray of shape (n,), optional
        The initial estimate before any measurement.
    innovation : numpy.ndarray of shape (N, p), optional
        Output prediction errors y_k − h(x̂_k⁻) on recorded data (see :meth:`Run.whiteness`).
    """

    name: str
    method: str
    z_names: tuple[str, ...]
    z: np.ndarray
    xhat: np.ndarray
    xhat_prior: np.ndarray | None = None  #: the initial estimate before any measurement (sets the default tolerance)
    #: y_k − h(x̂_k⁻): each output sample against the output predicted before the sample was used
    #: (shape (N, p), NaN where missing); set by :func:`nlobs.estimate`.
    innovation: np.ndarray | None = None
    #: The design's covariance of x̂ as a function of z (None for observers that carry none); see :attr:`std`.
    covariance: Any = field(default=None, repr=False)
    #: With ``estimate(..., smooth=True)``: the filtered estimates (N, n); `xhat` then holds the smoothed ones.
    filtered: np.ndarray | None = field(default=None, repr=False)
    #: With ``estimate(..., smooth=True)``: the smoothed covariance of x̂ at each sample, shape (N, n, n).
    smoothed_covariance: np.ndarray | None = field(default=None, repr=False)

    @property
    def smoothed(self) -> bool:
        """Whether `xhat` holds fixed-interval smoothed estimates (see :func:`nlobs.estimate`)."""
        return self.smoothed_covariance is not None

    @cached_property
    def std(self) -> np.ndarray | None:
        """(N, n) standard deviation of each estimate, from the covariance the observer carries (None
        for observers without one; the smoothed covariance for a smoothed run). Computed when first
        read: runs that never ask do not pay for it."""
        if self.smoothed_covariance is not None:
            var = np.diagonal(self.smoothed_covariance, axis1=1, axis2=2)
            with np.errstate(invalid="ignore"):
                return np.where(var >= 0, np.sqrt(np.abs(var)), np.nan)
        return _std(self.covariance, self.z, self.xhat.shape[1])

    def __post_init__(self) -> None:
        if _LEAN.get() and self.z.shape[1] and self.smoothed_covariance is None:
            self.__dict__["std"] = self.std   # read from z while it is here (cached_property's slot)
            object.__setattr__(self, "z", np.empty((self.z.shape[0], 0)))
            object.__setattr__(self, "z_names", ())

    def __repr__(self) -> str:
        return short_repr(self, {"name": self.name, "method": self.method, "z": self.z, "xhat": self.xhat})


#: Set by :func:`lean_traces`: traces made while it is set keep no internal state.
_LEAN: ContextVar[bool] = ContextVar("nlobs_lean_traces", default=False)


@contextmanager
def lean_traces() -> Iterator[None]:
    """Within it, each :class:`ObserverTrace` keeps the estimate and its standard deviations but not the observer's
    internal state z (its `z` has no columns): for runs that only compare estimates, such as the advisor's ranking,
    where a 24-state square-root UKF's internal state (1,177 numbers per sample) would take 114 MB on twelve thousand samples.
    Threads started with a copy of the context (as the observers' threads are) inherit it."""
    token = _LEAN.set(True)
    try:
        yield
    finally:
        _LEAN.reset(token)


@dataclass(frozen=True)
class ObserverFailure:
    """An observer that failed in a run while the others completed (see :attr:`Run.failures`).

    Attributes
    ----------
    name, method : str
    t : float or None
        The last time with a finite estimate (for an optimisation: the end of the data it was given).
    reason : str
        One line: what happened, when, and the one or two quantities that blew up.
    message : str
        The full error message, with what to try.
    error : str
        The error's class (``FiniteEscapeError``, ``SolverError``).
    partial : ObserverTrace, optional
        Its signals up to the failure, when kept (on the time grid of the run up to `t`).
    """

    name: str
    method: str
    t: float | None
    reason: str
    message: str
    error: str
    partial: ObserverTrace | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, Any]:
        return {"method": self.method, "failed": True, "t_failed": self.t, "reason": self.reason, "error": self.error,
                "message": self.message}


def _std(cov: Any, z: np.ndarray, n: int) -> np.ndarray | None:
    """The standard deviation of each entry of x̂ along a trajectory of z, from a design's
    ``covariance`` function (None for observers that carry none). Negative variances (a covariance
    that lost definiteness) give NaN, not a number that looks fine."""
    if cov is None or z.shape[0] == 0:
        return None
    from ..engine import evaluate_many

    var = evaluate_many(_diagonal_of(cov), z)
    with np.errstate(invalid="ignore"):
        return np.where(var >= 0, np.sqrt(np.abs(var)), np.nan)


_DIAGONALS: dict[int, tuple[Any, Any]] = {}


def _diagonal_of(cov: Any) -> Any:
    """The diagonal of `cov(z)` as a function of z: only the operations the diagonal needs (a square-root UKF's
    P = D Dᵀ from its 49 sigma points: 1.2 thousand of 28 thousand for 24 states)."""
    hit = _DIAGONALS.get(id(cov))
    if hit is not None and hit[0] is cov:
        return hit[1]
    import casadi as ca

    X = ca.SX if cov.is_a("SXFunction") else ca.MX
    z = X.sym("z", cov.sparsity_in(0))
    diag = ca.Function("covariance_diagonal", [z], [ca.densify(ca.diag(cov(z)))])
    if len(_DIAGONALS) > 64:
        _DIAGONALS.clear()
    _DIAGONALS[id(cov)] = (cov, diag)   # cov kept: its id is not reused while it is here
    return diag


@dataclass(frozen=True, eq=False)
class Run:
    """Time, true states (when known), inputs, measurements and every observer's estimate.

    All arrays have time on the first axis; signals are labelled by the model's own names.

    With unknown parameters estimated jointly (:meth:`nlobs.System.augmented`), they are the
    last entries of `state_names` and are listed in `estimated_params`; :meth:`parameters`
    reports their estimates (with ±2σ where the observer carries a covariance). `x` may then
    hold only the model's own states (recorded data): errors compare those.
    """

    model: str
    t: np.ndarray
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    u: np.ndarray
    y: np.ndarray
    observers: Mapping[str, ObserverTrace]
    x: np.ndarray | None = None
    y_true: np.ndarray | None = None
    info: Mapping[str, Any] = field(default_factory=dict)
    #: Names of the parameters estimated jointly with the states (the last entries of the state names).
    estimated_params: tuple[str, ...] = ()
    #: Observers that failed while the others completed (by name; not in `observers`); see :class:`ObserverFailure`.
    failures: Mapping[str, ObserverFailure] = field(default_factory=dict)

    # -- errors and metrics -------------------------------------------------------------
    def _trace(self, name: str | None) -> ObserverTrace:
        if name is None:
            if len(self.observers) != 1:
                raise KeyError(f"this run has {len(self.observers)} observers; name one of: {', '.join(self.observers)}")
            return next(iter(self.observers.values()))
        if name in self.failures:
            raise KeyError(f"observer {name!r} failed in this run: {self.failures[name].reason} (see run.failures[{name!r}])")
        if name not in self.observers:
            raise KeyError(f"no observer named {name!r} in this run; observers: {', '.join(self.observers) or '(none)'}")
        return self.observers[name]

    def error(self, name: str | None = None) -> np.ndarray:
        """x̂ - x, shape (N, n). Needs the true state (when it holds only the model's own states and
        not the estimated parameters, the error is over those states)."""
        if self.x is None:
            raise ValueError("this run has no true state (recorded data without states): errors cannot be computed")
        xhat = self._trace(name).xhat
        return xhat[:, :self.x.shape[1]] - self.x

    # -- estimated parameters ---------------------------------------------------------------
    def parameters(self, name: str | None = None, *, at: int = -1) -> dict[str, dict[str, float | None]]:
        """Each estimated parameter at sample `at` (default the last), with its standard deviation.

        Returns ``{k: {"estimate": value, "std": value or None, "true": value or None}}``.

        ``std`` is the standard deviation of the estimate from the covariance the observer
        carries (EKF, UKF, Kalman filters), None otherwise; ±2σ is ``2*std``. ``true`` is the
        value the plant had, when known (a simulation).
        """
        trace = self._trace(name)
        out: dict[str, dict[str, float | None]] = {}
        for k in self.estimated_params:
            i = self.state_names.index(k)
            std = None if trace.std is None or not np.isfinite(trace.std[at, i]) else float(trace.std[at, i])
            true = float(self.x[at, i]) if self.x is not None and i < self.x.shape[1] else None
            out[k] = {"estimate": float(trace.xhat[at, i]), "std": std, "true": true}
        return out

    def error_norm(self, name: str | None = None) -> np.ndarray:
        """‖x̂(t) - x(t)‖₂ at each time."""
        return np.linalg.norm(self.error(name), axis=1)

    def metrics(self, name: str | None = None, *, tol: float | None = None, tail: float = 0.2) -> Metrics:
        """Convergence time, RMS and peak errors of one observer (see :class:`Metrics`).

        The convergence band is `tol` when given (on ‖x̂ − x‖), else judged per state in its own
        units (:data:`nlobs.simulate._metrics.PER_STATE_RULE`): each state's band is the larger of
        2 % of its initial error before any measurement, ``|x̂ᵢ(0⁻) − xᵢ(0)|`` (which filters updating
        at t = 0 cannot game), and twice its steady-state error (the noise floor), at most 20 % of
        its initial error unless that floor is zero-mean noise; the time is the latest state's and
        ``set_by`` names those states. It does not depend on the run length, beyond the slow growth
        of the largest noise peak with it.
        """
        trace = self._trace(name)
        E = self.error(name)
        e0 = E[0]
        if trace.xhat_prior is not None and self.x is not None:
            e0 = trace.xhat_prior[:self.x.shape[1]] - self.x[0]
        if tol is None:  # each state in its own units (PER_STATE_RULE)
            noisy = bool(self.info.get("noisy", True))  # a simulation says; recorded data has noise
            return state_metrics(self.t, E, e0, self.state_names[:E.shape[1]], tail=tail, noisy=noisy)
        return error_metrics(self.t, np.linalg.norm(E, axis=1), tol=tol, e0=float(np.linalg.norm(e0)), tail=tail)

    def noise_gain(self, name: str | None = None, *, tail: float = 0.2) -> float:
        """RMS estimation error over the last `tail` of the run divided by the RMS of the
        measurement noise y − y_true over the same window (SPEC M5). Needs a noisy simulation."""
        if self.y_true is None or self.x is None:
            raise ValueError("noise_gain needs a simulated run (true states and noise-free outputs)")
        sel = self.t >= self.t[-1] - tail * (self.t[-1] - self.t[0])
        noise = self.y[sel] - self.y_true[sel]
        noise_rms = float(np.sqrt(np.mean(np.sum(noise**2, axis=1))))
        if noise_rms == 0:
            raise ValueError("noise_gain: this run has no measurement noise")
        return float(np.sqrt(np.mean(self.error_norm(name)[sel] ** 2)) / noise_rms)

    def innovations(self, name: str | None = None) -> np.ndarray:
        """y_k − h(x̂_k⁻) of one observer, shape (N, p), NaN where a sample is missing. Needs a run
        of :func:`nlobs.estimate` (recorded data)."""
        tr = self._trace(name)
        if tr.innovation is None:
            raise ValueError("innovations are recorded by nlobs.estimate (observers on recorded data); this run has none")
        return tr.innovation

    def whiteness(self, name: str | None = None, *, lags: int | None = None, alpha: float = 0.05,
                  burn_in: float = 0.1) -> dict[str, Whiteness]:
        """Ljung–Box test of each output's innovations (see :func:`nlobs.simulate.ljung_box`): an
        observer that uses all the information in the data leaves white innovations.

        The first `burn_in` fraction of the samples (default 10 %) is left out: the initial
        transient from a wrong x̂0 is not noise, and its large values would hide correlation.
        Returns one :class:`Whiteness` per output name (mean, RMS and the test, over the rest).
        """
        if not 0 <= burn_in < 1:
            raise ValueError(f"whiteness: `burn_in` must be a fraction in [0, 1), got {burn_in!r}")
        inn = self.innovations(name)
        start = int(np.ceil(burn_in * inn.shape[0]))
        return {o: ljung_box(inn[start:, j], lags=lags, alpha=alpha) for j, o in enumerate(self.output_names)}

    def residual_table(self) -> SummaryTable:
        """Per observer and output: the innovations' mean and RMS and the Ljung–Box whiteness test
        (a table: ``print()`` it, show it in a notebook, or ``.to_pandas()`` it)."""
        cols = [Column("observer", "observer", str, numeric=False), Column("output", "output", str, numeric=False),
                Column("mean", "mean"), Column("rms", "RMS"), Column("q", "Ljung-Box Q"), Column("lags", "lags"),
                Column("p_value", "p"), Column("white", "white?", str, numeric=False)]
        rows = []
        for name, tr in self.observers.items():
            if tr.innovation is None:
                rows.append({"observer": name, "output": "(no innovations recorded)", "white": MISSING})
                continue
            for o, w in self.whiteness(name).items():
                rows.append({"observer": name, "output": o, "mean": w.mean, "rms": w.rms, "q": w.q, "lags": w.lags,
                             "p_value": w.p_value, "white": MISSING if w.p_value is None else ("yes" if w.white else "no")})
        return SummaryTable("innovations y_k − h(x̂_k⁻) (each sample against the output predicted before it was used), "
                            "after the first 10 % of the samples:", cols, rows,
                            ("white?: Ljung–Box test at the 5 % level; 'no' means the innovations are correlated in time: "
                             "the model, the tuning (Q, R) or the data leave information unused",))

    def _parameter_lines(self) -> list[str]:
        """The estimated parameters at the final time, with ±2σ and the true value when known."""
        if not self.estimated_params:
            return []
        lines = [f"estimated parameters at t = {self.t[-1]:g}:"]
        for name in self.observers:
            for k, v in self.parameters(name).items():
                text = f"{v['estimate']:.6g}" + ("" if v["std"] is None else f" ± {2 * v['std']:.3g} (2σ)")
                if v["true"] is not None:
                    text += f", true {v['true']:.6g}"
                lines.append(f"  {name:<16} {k} = {text}")
        return lines

    def summary(self, *, tol: float | None = None) -> SummaryTable:
        """Every observer's metrics (with the convergence band of each) as a table: ``print()`` it,
        show it in a notebook, or ``.to_pandas()`` it. For recorded data without true states, the
        innovations and their whiteness instead (see :meth:`innovations` and :meth:`whiteness`).

        Parameters
        ----------
        tol : float, optional
            Absolute convergence tolerance on ‖x̂ − x‖ (default: each state judged in its own units,
            :data:`nlobs.simulate.PER_STATE_RULE`).
        """
        title = f"{self.model}: t in [{self.t[0]:g}, {self.t[-1]:g}], {len(self.t)} samples"
        if self.x is None:
            res = self.residual_table()
            failed = [{"observer": n, "output": "(failed)", "white": MISSING} for n in self.failures]
            return SummaryTable(f"{title}\n{res.title}", res.columns, [*res.rows, *failed],
                                (*res.notes, *self._failure_lines(), *self._parameter_lines()))
        cols = [Column("observer", "observer", str, numeric=False), Column("final_error", "final err"),
                Column("rms_error", "RMS (last 20%)"), Column("peak_error", "peak err"),
                Column("convergence_time", "conv. time")]
        cols.append(Column("tol", "band", lambda v: fmt_number(v, 2)) if tol is not None else
                    Column("set_by", "set by", lambda v: ", ".join(v) if v else MISSING, numeric=False))
        rows = [{"observer": n, **self.metrics(n, tol=tol).to_dict()} for n in self.observers]
        if self.failures:
            cols.append(Column("status", "status", str, numeric=False))
            for r in rows:
                r["status"] = "ok"
            rows += [{"observer": n, "status": f"FAILED after t = {f.t:.4g}" if f.t is not None else "FAILED"}
                     for n, f in self.failures.items()]
        first = (f"band: the tolerance given; conv. time: from then on ‖x̂ − x‖ stays within it ({MISSING}: not within "
                 "the run)" if tol is not None else
                 "conv. time: from then on every state's error stays within its own band, in its own units: max(2 % of "
                 "its initial error, 2 × its steady-state error), at most 20 % of its initial error unless that floor "
                 f"is zero-mean noise ({MISSING}: not within the run); set by: the states that settle last, or do not "
                 "settle")
        return SummaryTable(title, cols, rows, (first, *self._failure_lines(),
                                                *self._parameter_lines(),
                                                *(f"note: {n}" for n in self.info.get("notes", ()))))

    def _failure_lines(self) -> list[str]:
        """One line per failed observer: its reason (the full message is in ``run.failures[name].message``)."""
        return [f"{n} failed: {f.reason}; the other observers ran without it" for n, f in self.failures.items()]

    def __repr__(self) -> str:
        return short_repr(self, {"model": self.model, "t": (float(self.t[0]), float(self.t[-1])), "samples": int(self.t.size),
                                 "states": self.state_names, "observers": tuple(self.observers),
                                 "true_state": self.x is not None})

    def _repr_html_(self) -> str:
        return self.summary()._repr_html_()

    # -- export -------------------------------------------------------------------------
    def to_numpy(self) -> dict[str, np.ndarray]:
        """Every signal as a NumPy array, keyed ``t``, ``x``, ``u``, ``y``, ``y_true``, ``xhat[NAME]``, ``z[NAME]``."""
        out = {"t": self.t, "u": self.u, "y": self.y}
        if self.x is not None:
            out["x"] = self.x
        if self.y_true is not None:
            out["y_true"] = self.y_true
        for name, tr in self.observers.items():
            out[f"xhat[{name}]"] = tr.xhat
            out[f"z[{name}]"] = tr.z
        return out

    def to_pandas(self) -> Any:
        """A DataFrame indexed by time: ``x1 ...`` (true states), inputs, measured outputs,
        ``<output>_true``, then ``<observer>.<state>`` estimates and ``<observer>.error``."""
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("to_pandas needs pandas: pip install 'nlobs[pandas]'") from e
        cols: dict[str, np.ndarray] = {}
        if self.x is not None:
            cols.update({n: self.x[:, i] for i, n in zip(range(self.x.shape[1]), self.state_names)})
        cols.update({n: self.u[:, i] for i, n in enumerate(self.input_names)})
        cols.update({n: self.y[:, i] for i, n in enumerate(self.output_names)})
        if self.y_true is not None:
            cols.update({f"{n}_true": self.y_true[:, i] for i, n in enumerate(self.output_names)})
        for name, tr in self.observers.items():
            cols.update({f"{name}.{n}": tr.xhat[:, i] for i, n in enumerate(self.state_names)})
            if self.x is not None:
                cols[f"{name}.error"] = self.error_norm(name)
        return pd.DataFrame(cols, index=pd.Index(self.t, name="t"))

    def summary_dict(self, *, tol: float | None = None) -> dict[str, Any]:
        """``{"model", "t_final", "samples", "convergence_rule", "observers": {NAME: {...}}}``.

        Per observer: ``method``, ``estimate`` (the final estimate by state name),
        ``final_estimate`` (the same as a list); with true states the :class:`Metrics`
        (``final_error``, ``rms_error``, ``convergence_time`` with its band ``tol``, ...); on
        recorded data the ``innovations`` per output (mean, RMS, Ljung–Box test). An observer that failed has
        ``{"method", "failed": true, "t_failed", "reason", "error", "message"}`` instead, and its name is in the
        top-level ``"failed"`` list.
        With estimated parameters, each observer also has ``"parameters": {k: {"estimate", "std", "true"}}``;
        a smoothed run (``estimate(..., smooth=True)``) has ``"smoothed": true`` (its estimates and metrics are the
        smoothed ones, its innovations the filter's).
        """
        obs: dict[str, Any] = {}
        for name, tr in self.observers.items():
            entry: dict[str, Any] = {"method": tr.method,
                                     "estimate": {s: float(v) for s, v in zip(self.state_names, tr.xhat[-1])},
                                     "final_estimate": tr.xhat[-1].tolist()}
            if self.x is not None:
                entry.update(self.metrics(name, tol=tol).to_dict())
                if self.y_true is not None and not np.array_equal(self.y, self.y_true):
                    entry["noise_gain"] = self.noise_gain(name)
            if self.estimated_params:
                entry["parameters"] = self.parameters(name)
            if tr.innovation is not None:
                entry["innovations"] = {o: w.to_dict() for o, w in self.whiteness(name).items()}
            if tr.smoothed:  # the estimates and metrics above are the smoothed ones; the innovations the filter's
                entry["smoothed"] = True
            obs[name] = entry
        obs.update({name: f.to_dict() for name, f in self.failures.items()})
        out = {"model": self.model, "t_final": float(self.t[-1]), "samples": int(self.t.size), "observers": obs}
        if self.failures:
            out["failed"] = list(self.failures)
        if self.x is not None:
            given = "convergence time: the first time after which ‖x̂ − x‖ stays within `tol`"
            out["convergence_rule"] = given if tol is not None else PER_STATE_RULE
        if self.info.get("notes"):
            out["notes"] = list(self.info["notes"])
        return out

    def to_csv(self, path: Any, *, every: int | None = None) -> None:
        """Write the run as a CSV that :meth:`nlobs.Recording.from_csv` (and ``nlobs estimate``) reads back.

        Columns: ``t``, the inputs, the measured outputs, the true states (when known), then
        ``NAME.STATE`` for each observer's estimate. Numbers are written in their shortest form
        that reads back to the same double (Python's ``repr``); missing values as empty cells.
        `every` > 1 (a sampled run: `every` steps per sample; by default the run's own, from its sample period and
        step, so a sampled run's held outputs are never written as new measurements) keeps the sample instants, rows 0, k, 2k, ... (with
        per-output sample periods, the rows where any output was sampled), and every row where an input changes:
        every input sample the run saw reaches the file (a 200 Hz input beside a 50 Hz sensor is written at
        200 Hz), so ``estimate`` holding the inputs between rows drives its observers with the inputs of the run. An
        output is written in the rows where it was sampled and left empty (NaN: not measured) in the others. With
        measurement delays
        (``simulate(..., delay=...)``) a delayed output is written in the row where its sample arrived, as a logger
        records it: ``estimate`` with the same `delay` reads it back.
        """
        from ._schedule import SampleSchedule

        if every is None:   # the run's own: its one sample period in steps (per-output periods: `measured` says)
            period, dt = self.info.get("sampling"), self.info.get("dt")
            k = float(period) / float(dt) if isinstance(period, (int, float)) and period and dt else 1.0
            every = int(round(k)) if abs(k - round(k)) <= 1e-9 * k else 1
        every = int(every)
        if every < 1:
            raise ValueError(f"to_csv: `every` must be a positive whole number of rows, got {every!r}")
        N = self.t.size
        keep = np.arange(0, N, every)
        header = ["t", *self.input_names, *self.output_names]
        y = self.y
        measured = self.info.get("measured")
        if measured is None and every > 1:   # one clock: the rows 0, k, 2k, ... are the samples
            measured = SampleSchedule(self.t, tuple(self.output_names), clock=(every,)).measured()
        if measured is not None:   # each output in the rows where it was sampled, empty elsewhere
            y = np.where(measured, y, np.nan)
            y, measured = self._stamped_at_arrival(y, measured)
            if every > 1:   # (and the first row: the run's start, where the observers start, even before anything arrived)
                u = np.asarray(self.u, dtype=float).reshape(N, -1)
                changed = np.r_[False, np.any(u[1:] != u[:-1], axis=1)] if N else np.zeros(0, dtype=bool)
                keep = np.flatnonzero(measured.any(axis=1) | changed | (np.arange(N) == 0))
        blocks = [self.t[:, None], self.u, y]
        if self.x is not None:
            header += list(self.state_names[:self.x.shape[1]])  # recorded truth may lack the estimated parameters
            blocks.append(self.x)
        for name, tr in self.observers.items():
            header += [f"{name}.{s}" for s in self.state_names]
            blocks.append(tr.xhat)
        data = np.hstack([np.asarray(b, dtype=float).reshape(self.t.size, -1) for b in blocks])[keep]
        write_csv(path, header, data)

    def _stamped_at_arrival(self, y: np.ndarray, measured: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """With measurement delays, each delayed output moved to the row where its sample arrived (a recording is
        stamped at arrival; :func:`nlobs.estimate` with the same `delay` takes it back to when it was taken)."""
        from ._schedule import SampleSchedule

        delay = self.info.get("delay") or {}
        if not any(v > 0 for v in delay.values()):
            return y, measured
        dt = float(self.info.get("dt") or np.median(np.diff(self.t)))
        y, measured = y.copy(), measured.copy()
        delays = np.array([float(delay.get(name, 0.0)) for name in self.output_names])
        lag = SampleSchedule(self.t, tuple(self.output_names), delays=delays, step=dt).arrival_lag("to_csv")
        for j, k in enumerate(lag):
            if k:
                y[k:, j], y[:k, j] = y[:-k, j].copy(), np.nan
                measured[k:, j], measured[:k, j] = measured[:-k, j].copy(), False
        return y, measured

    def plot(self, path: str | None = None, *, observers: Sequence[str] | None = None, width: float = 6.4,
             title: str | None = None) -> Any:
        """States vs estimates, and the error norms on a log scale; saved to `path` if given.

        Parameters
        ----------
        path : str, optional
            File to save the figure to (png, pdf, svg, ...).
        observers : sequence of str, optional
            Observers to draw (default: all).
        width : float
            Figure width in inches.
        title : str, optional
            A title above the panels.

        Returns
        -------
        matplotlib.figure.Figure
        """
        from ._plot import plot_run

        return plot_run(self, path, observers=observers, width=width, title=title)
