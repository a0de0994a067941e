r"""The error a filter achieves beside each Cramér–Rao bound of ``nlobs sensors`` (``--run``).

For a set S of sensors, an extended Kalman filter is designed on the model with the set's expressions as its outputs
(the unknown parameters appended to the state), R = diag(σ_c²), a prior :math:`P_0 = \mathrm{diag}(\sigma_0^2)` with
:math:`\sigma_0 = 3\times` the set's bound of each unknown, and a process noise floor
:math:`Q = 10^{-10}\,\mathrm{diag}(\sigma_0^2)` per unit time (the run has none, but with Q = 0 the smoother's gain
:math:`G_k = P_k \Phi^\top (\Phi P_k \Phi^\top)^{-1} = \Phi^{-1}` inverts a contracting flow and the backward pass
amplifies rounding without bound). On each of
`seeds` noise draws it runs on the run's noise-free readings plus Gaussian noise of each sensor's σ (a recording of
the run's samples, the inputs linearly interpolated between them), from
:math:`\hat z(0) = z(0) + \sigma_0 \xi`, and is smoothed (Rauch, Tung & Striebel (1965)); the error of the smoothed
:math:`\hat z(0)` is what the bound is about. With the prior, the bound an estimator can reach is the posterior one,
:math:`\sqrt{\mathrm{diag}(P_0^{-1} + F_S)^{-1}}` (about 0.95 of the Cramér–Rao bound when the information is
diagonal); a linear model's smoother reaches it exactly on average, a nonlinear one's is near it when the
linearisation holds over the errors.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._memory import release_free_memory
from ..design import design_ekf
from ..errors import DataError, FiniteEscapeError, NlobsError
from ..model import ModelFile, input_signals
from ..references import cite
from ._recorded import Recording, estimate
from ._smooth import forget

__all__ = ["SensorErrors", "sensor_errors", "PRIOR_FACTOR", "Q_FLOOR", "DIVERGED"]

#: The filter's prior standard deviation of each unknown, in units of the set's Cramér–Rao bound.
PRIOR_FACTOR = 3.0
#: The filter's process noise, per unit time, in units of its prior variance (see the module's documentation).
Q_FLOOR = 1e-10
#: A smoothed x̂(0) farther from the truth than DIVERGED prior standard deviations is a diverged run, not an error figure
#: (a draw from the prior is within 6 σ₀ with probability 1 − 2e-9).
DIVERGED = 100.0


@dataclass(frozen=True, eq=False)
class SensorErrors:
    """Per listed set: the RMS error of the smoothed x̂(0) over the noise draws, beside its bounds.

    Attributes
    ----------
    sets : tuple of tuple of str
    rms, posterior, crb : mapping of set to mapping of unknown to float
        RMS error of the smoothed initial estimate; the posterior bound with the filter's prior; the Cramér–Rao bound.
    seeds : int
    failures : mapping of set to str
        Sets whose filter could not run or diverged, and why (never an error figure).
    method : str
    """

    sets: tuple[tuple[str, ...], ...]
    rms: dict[tuple[str, ...], dict[str, float]]
    posterior: dict[tuple[str, ...], dict[str, float]]
    crb: dict[tuple[str, ...], dict[str, float]]
    seeds: int
    failures: dict[tuple[str, ...], str] = field(default_factory=dict)
    method: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: per set, the RMS error, the posterior bound and the Cramér–Rao bound of each unknown."""
        def clean(d: dict[str, float]) -> dict[str, float | None]:
            return {k: (v if math.isfinite(v) else None) for k, v in d.items()}

        return {"seeds": self.seeds, "method": self.method,
                "sets": [{"sensors": list(s), "rms_error": clean(self.rms[s]), "posterior_bound": clean(self.posterior[s]),
                          "crb": clean(self.crb[s])} for s in self.sets if s in self.rms],
                "failures": [{"sensors": list(s), "status": "diverged" if e.startswith("diverged") else "not run",
                              "error": e} for s, e in self.failures.items()]}

    def __str__(self) -> str:
        lines = [f"Smoothed EKF on the run, {self.seeds} noise draws (the RMS of {self.seeds} draws is itself uncertain by about "
                 f"{100 / math.sqrt(2 * self.seeds):.0f} %): RMS error of x̂(0) / posterior bound / Cramér–Rao bound"]
        for s in self.sets:
            label = "{" + ", ".join(s) + "}"
            if s in self.failures:
                why = self.failures[s]
                lines.append(f"  {label}: {why}" if why.startswith("diverged") else f"  {label}: not run ({why})")
                continue
            parts = [f"{u} {self.rms[s][u]:.3g} / {self.posterior[s][u]:.3g} / {self.crb[s][u]:.3g}" for u in self.rms[s]]
            lines.append(f"  {label}: " + "; ".join(parts))
        lines.append(f"  ({self.method})")
        return "\n".join(lines)


class _Diverged(NlobsError):
    """A set's filter or smoother diverged on a draw (the reason is shown in place of its errors)."""


def _plain(text: str, renames: dict[str, str]) -> str:
    """An engine message in the sensors' own names: the observer's internal renames of the outputs (a sensor named as a
    state gets a trailing _) and of the recording back to the sensors."""
    import re

    text = re.sub(r"^(recording \(arrays\): )?observer 'ekf'( on the recording arrays)?: ", "", text)
    text = text.replace("the smoother diverged going backwards: ", "")
    for tail in ("; last finite state", ". Check ", ". With little", ". Split "):  # the engine's advice is not ours
        text = text.split(tail)[0]
    for inner, outer in renames.items():
        text = re.sub(rf"(?<![\w.]){re.escape(inner)}(?![\w])", outer, text)
    return text.rstrip(". ")


def _output_names(names: Sequence[str], taken: Sequence[str]) -> list[str]:
    """The filter's names for the sensors' outputs: each sensor's own, unless it is a model name (a sensor named as the
    state it reads: then with a trailing _) or cannot name a model's output (a [sensors] table may be called `lambda`
    or `sin`: then `sensorK`); the text maps them back."""
    import keyword

    from ..model._system import RESERVED

    used, out = set(taken), []
    for k, n in enumerate(names):
        name = n if n.isidentifier() and not keyword.iskeyword(n) and n not in RESERVED else f"sensor{k}"
        while name in used:
            name += "_"
        used.add(name)
        out.append(name)
    return out


def _set_errors(mf: ModelFile, sel: Any, members: Sequence[int], seeds: int, engine: str) -> tuple[dict, dict]:
    """The RMS error of the smoothed x̂(0) of one set over `seeds` draws, and its posterior bound. Raises _Diverged
    when a draw's filter or smoother diverges, or its x̂(0) is not finite or lies beyond DIVERGED prior σ."""
    fi = sel.fisher
    pool = sel.pool
    unknown = sel.unknowns[mf.system.n_states:]
    names = [pool[i].name for i in members]
    outputs = _output_names(names, (*sel.unknowns, *mf.system.inputs, *mf.system.params))
    obs = mf.system.augmented(unknown)
    obs = obs._copy(outputs=outputs, h=[pool[i].expr for i in members])
    F = fi.information[list(members)].sum(axis=0)
    crb = np.array([sel.set_of(names).crb[u] for u in sel.unknowns])
    if not np.all(np.isfinite(crb)):
        raise NlobsError("an unknown is not informed on the run (infinite bound)")
    s0 = PRIOR_FACTOR * crb
    post = np.sqrt(np.diag(np.linalg.inv(np.diag(1 / s0 ** 2) + F)))
    sigma = np.array([pool[i].noise for i in members])
    renames = {o: n for o, n in zip(outputs, names) if o != n}
    design = design_ekf(obs, Q=np.diag(Q_FLOOR * s0 ** 2), R=np.diag(sigma ** 2), P0=np.diag(s0 ** 2))
    true = dict(sel.run["true_parameters"])
    z0 = np.array([*sel.run["x0"], *[true.get(k, mf.system.params[k]) for k in unknown]])
    # the recording's rows are the run's samples, the inputs linearly interpolated between them (hold="linear"); a
    # recording on the RK4 grid with the samples on their rows only would carry the inputs exactly, but the smoother's
    # covariance then loses its positive definiteness over the many rows without a sample (NaN standard deviations)
    t = fi.times
    sigs = input_signals(mf.system, dict(mf.simulation.inputs), mf.system.params)
    u = np.array([np.broadcast_to(np.asarray(s(t), dtype=float), t.shape) for s in sigs]).reshape(len(sigs), t.size).T
    y_true = fi.outputs[:, list(members)].copy()
    periods = sel.run.get("periods")
    if periods and sel.run.get("sample_period"):  # each sensor at its own rate: not measured (NaN) between its samples
        for j, name in enumerate(names):
            k = int(round(periods[name] / sel.run["sample_period"]))
            y_true[np.arange(t.size) % k != 0, j] = np.nan
    try:
        errors = []
        rng = np.random.default_rng(mf.simulation.seed if mf.simulation.seed is not None else 0)
        for draw in range(seeds):
            rec = Recording.from_arrays(obs, t, y_true + sigma * rng.standard_normal(y_true.shape), u)
            start = z0 + s0 * rng.standard_normal(z0.size)
            try:
                run = estimate({"ekf": design}, rec, smooth=True, xhat0=start, engine=engine, hold="linear",
                               max_step=fi.dt * (1 + 1e-12))
            except (FiniteEscapeError, DataError) as e:  # non-finite, or rates so large an interval needs 1e8 steps
                what = "the smoother, going backwards," if "smoother diverged" in str(e) else "the filter"
                raise _Diverged(f"diverged: {what} on draw {draw + 1}: {_plain(str(e).splitlines()[0], renames)} (a prior "
                                f"σ₀ = {PRIOR_FACTOR:g} × bound too wide for the EKF's linearisation?)") from None
            err = run.observers["ekf"].xhat[0] - z0
            far = np.flatnonzero(~np.isfinite(err) | (np.abs(err) > DIVERGED * s0))
            if far.size:
                i = int(far[0])
                raise _Diverged(f"diverged: on draw {draw + 1} the smoothed {sel.unknowns[i]}(0) is off by {abs(err[i]):.3g}, "
                                f"beyond {DIVERGED:g} × its prior σ₀ = {s0[i]:.3g}")
            errors.append(err)
    finally:
        forget(design)   # this set's design is not used again: its smoother's replay must not stay cached
        release_free_memory()
    rms = np.sqrt(np.mean(np.square(errors), axis=0))
    return dict(zip(sel.unknowns, map(float, rms))), dict(zip(sel.unknowns, map(float, post)))


def sensor_errors(mf: ModelFile, sel: Any, *, sets: Sequence[Sequence[str]] | None = None, seeds: int = 20,
                  engine: str = "auto") -> SensorErrors:
    """Run a smoothed EKF with each listed set of sensors on the selection's run (see the module's documentation).

    Parameters
    ----------
    mf : ModelFile
        The model file the selection was made on.
    sel : SensorSelection
        With its run (``select_sensors`` with a ``[simulation]`` x0).
    sets : sequence of sequences of str, optional
        The sets to run (default: those :func:`nlobs.report._sensors.plotted_sets` would draw: the best set, the
        minimal sets, the Pareto front, at most 8).
    seeds : int
        Noise draws per set.
    engine : {"auto", "vm", "c"}

    Returns
    -------
    SensorErrors
    """
    if sel.fisher is None or sel.run is None:
        raise NlobsError("--run: the selection has no run (the model's [simulation] needs x0)")
    if sets is None:
        order = [s for r in ("best", "minimal", "pareto") for s in sel.sets if r in s.roles]
        sets = list(dict.fromkeys(s.sensors for s in order))[:8]
    index = {c.name: i for i, c in enumerate(sel.pool)}
    rms, post, crb, failures = {}, {}, {}, {}
    for s in sets:
        key = tuple(s)
        crb[key] = dict(sel.set_of(key).crb)
        try:
            rms[key], post[key] = _set_errors(mf, sel, [index[n] for n in key], seeds, engine)
        except _Diverged as e:
            failures[key] = str(e)
        except (NlobsError, ValueError, np.linalg.LinAlgError) as e:
            failures[key] = str(e).splitlines()[0]
    method = (f"EKF with R = diag(σ²), P0 = diag(({PRIOR_FACTOR:g} × bound)²), Q = {Q_FLOOR:g} P0 per unit time, x̂(0) "
              "drawn from that prior, smoothed "
              f"({cite('rauch1965')}); posterior bound √diag((P0⁻¹ + F)⁻¹)")
    return SensorErrors(tuple(tuple(s) for s in sets), rms, post, crb, seeds, failures, method)
