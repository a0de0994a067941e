r"""The error a filter achieves beside each Cramér–Rao bound of ``nlobs sensors`` (``--run``).

For a set S of sensors, an extended Kalman filter is designed on the model with the set's expressions as its outputs
(the unknown parameters appended to the state), R = diag(σ_c²), no process noise, and a prior
:math:`P_0 = \mathrm{diag}(\sigma_0^2)` with :math:`\sigma_0 = 3\times` the set's bound of each unknown. On each of
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

from ..design import design_ekf
from ..errors import NlobsError
from ..model import ModelFile, input_signals
from ..references import cite
from ._recorded import Recording, estimate

__all__ = ["SensorErrors", "sensor_errors", "PRIOR_FACTOR"]

#: The filter's prior standard deviation of each unknown, in units of the set's Cramér–Rao bound.
PRIOR_FACTOR = 3.0


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
        Sets whose filter could not run, and why.
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
                "failures": [{"sensors": list(s), "error": e} for s, e in self.failures.items()]}

    def __str__(self) -> str:
        lines = [f"Smoothed EKF on the run, {self.seeds} noise draws (the RMS of {self.seeds} draws is itself uncertain by about "
                 f"{100 / math.sqrt(2 * self.seeds):.0f} %): RMS error of x̂(0) / posterior bound / Cramér–Rao bound"]
        for s in self.sets:
            label = "{" + ", ".join(s) + "}"
            if s in self.failures:
                lines.append(f"  {label}: not run ({self.failures[s]})")
                continue
            parts = [f"{u} {self.rms[s][u]:.3g} / {self.posterior[s][u]:.3g} / {self.crb[s][u]:.3g}" for u in self.rms[s]]
            lines.append(f"  {label}: " + "; ".join(parts))
        lines.append(f"  ({self.method})")
        return "\n".join(lines)


def _set_errors(mf: ModelFile, sel: Any, members: Sequence[int], seeds: int, engine: str) -> tuple[dict, dict]:
    """The RMS error of the smoothed x̂(0) of one set over `seeds` draws, and its posterior bound."""
    fi = sel.fisher
    pool = sel.pool
    unknown = sel.unknowns[mf.system.n_states:]
    names = [pool[i].name for i in members]
    outputs = [f"{n}_" if n in (*sel.unknowns, *mf.system.inputs, *mf.system.params) else n for n in names]
    obs = mf.system.augmented(unknown)
    obs = obs._copy(outputs=outputs, h=[pool[i].expr for i in members])
    F = fi.information[list(members)].sum(axis=0)
    crb = np.array([sel.set_of(names).crb[u] for u in sel.unknowns])
    if not np.all(np.isfinite(crb)):
        raise NlobsError("an unknown is not informed on the run (infinite bound)")
    s0 = PRIOR_FACTOR * crb
    post = np.sqrt(np.diag(np.linalg.inv(np.diag(1 / s0 ** 2) + F)))
    sigma = np.array([pool[i].noise for i in members])
    design = design_ekf(obs, Q=np.zeros((obs.n_states, obs.n_states)), R=np.diag(sigma ** 2), P0=np.diag(s0 ** 2))
    true = dict(sel.run["true_parameters"])
    z0 = np.array([*sel.run["x0"], *[true.get(k, mf.system.params[k]) for k in unknown]])
    # the recording's rows are the run's samples, the inputs linearly interpolated between them (hold="linear"); a
    # recording on the RK4 grid with the samples on their rows only would carry the inputs exactly, but the smoother's
    # covariance then loses its positive definiteness over the many rows without a sample (NaN standard deviations)
    t = fi.times
    sigs = input_signals(mf.system, dict(mf.simulation.inputs), mf.system.params)
    u = np.array([np.broadcast_to(np.asarray(s(t), dtype=float), t.shape) for s in sigs]).reshape(len(sigs), t.size).T
    y_true = fi.outputs[:, list(members)]
    errors = []
    rng = np.random.default_rng(mf.simulation.seed if mf.simulation.seed is not None else 0)
    for _ in range(seeds):
        rec = Recording.from_arrays(obs, t, y_true + sigma * rng.standard_normal(y_true.shape), u)
        start = z0 + s0 * rng.standard_normal(z0.size)
        run = estimate({"ekf": design}, rec, smooth=True, xhat0=start, engine=engine, hold="linear",
                       max_step=fi.dt * (1 + 1e-12))
        errors.append(run.observers["ekf"].xhat[0] - z0)
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
        except (NlobsError, ValueError, np.linalg.LinAlgError) as e:
            failures[key] = str(e).splitlines()[0][:200]
    method = (f"EKF with R = diag(σ²), Q = 0, P0 = diag(({PRIOR_FACTOR:g} × bound)²), x̂(0) drawn from that prior, smoothed "
              f"({cite('rauch1965')}); posterior bound √diag((P0⁻¹ + F)⁻¹)")
    return SensorErrors(tuple(tuple(s) for s in sets), rms, post, crb, seeds, failures, method)
