r"""Known measurement delays: a sample of output j taken at :math:`t_s` reaches the observer at :math:`t_s + d_j`.

Method: filter recalculation from a state history. The observer keeps the samples it has used, sorted by the
time they were *taken*, and its state after each one. When a sample arrives that was taken before the last one
used (a late GPS fix behind the wheel encoder's samples), it goes back to its state just before that time,
applies the samples again in the order they were taken (now with the late one), and runs forward to the
present. The estimate reported at time t is therefore exactly the one the same observer gives without delays on
the samples that have *arrived* by t: a delay costs only the information that is not there yet, never a sample
applied at the wrong time. The price is re-running at most the last max_j d_j of the run at each late arrival
(samples older than that can no longer be preceded by a new one and are dropped from the history).

This holds for every continuous-discrete observer (a flow between samples and an update at each: EKF, UKF, the
square-root filters, ...): the update uses the sample at the time it was taken, with the state predicted to that
time. Observers that take the output continuously have no sample to re-apply and are refused.

Used by :func:`nlobs.simulate` (``delay={output: seconds}``, with sampled measurements) and :func:`nlobs.estimate`
(a recording stamped at arrival: a delayed output's row holds what was measured `d` earlier).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError, ShapeError
from ..observer import AbstractObserver
from ..observer._base import integrate

__all__ = ["delays_of", "Events", "run_delayed"]


def delays_of(delay: Mapping[str, float] | None, outputs: Sequence[str], caller: str) -> np.ndarray:
    """The delay of each of `outputs` (0 for those not named), checked."""
    d = np.zeros(len(outputs))
    if not delay:
        return d
    if not isinstance(delay, Mapping):
        raise ShapeError(f"{caller}: `delay` must be a mapping {{output: seconds}}, got {type(delay).__name__}")
    for k, v in delay.items():
        if k not in outputs:
            raise ShapeError(f"{caller}: `delay` names {k!r}, which is not an output; the outputs are {', '.join(outputs)}")
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not (np.isfinite(v) and v >= 0):
            raise ShapeError(f"{caller}: the delay of {k!r} must be a finite number of seconds >= 0, got {v!r}")
        d[outputs.index(k)] = float(v)
    return d


@dataclass
class Events:
    """Samples as (time taken, time arrived, output index, value), one entry per measured output."""

    taken: np.ndarray
    arrived: np.ndarray
    output: np.ndarray
    value: np.ndarray

    @classmethod
    def from_rows(cls, t: np.ndarray, y: np.ndarray, measured: np.ndarray, delays: np.ndarray, *,
                  stamped_at_arrival: bool) -> Events:
        """One event per measured cell: rows stamped when the sample was taken (a simulation) or when it arrived (a
        recording: taken = stamp − delay)."""
        rows, cols = np.nonzero(measured)
        stamp, d = t[rows], delays[cols]
        taken, arrived = (stamp - d, stamp) if stamped_at_arrival else (stamp, stamp + d)
        return cls(taken, arrived, cols, y[rows, cols])


@dataclass
class _History:
    """The samples used so far (sorted by the time taken, same-time samples merged) and the state after each."""

    t0: float
    z0: np.ndarray
    times: list[float] = field(default_factory=list)
    ys: list[np.ndarray] = field(default_factory=list)
    masks: list[np.ndarray] = field(default_factory=list)
    states: list[np.ndarray] = field(default_factory=list)

    def insert(self, t: float, j: int, v: float, ny: int) -> int:
        """Add the sample of output j taken at t; the index of its entry (its state must be recomputed)."""
        i = int(np.searchsorted(np.asarray(self.times), t, side="left")) if self.times else 0
        if i < len(self.times) and abs(self.times[i] - t) <= 1e-12 * max(1.0, abs(t)):
            self.ys[i][j], self.masks[i][j] = v, 1.0
            return i
        y, m = np.zeros(ny), np.zeros(ny)
        y[j], m[j] = v, 1.0
        self.times.insert(i, t)
        self.ys.insert(i, y)
        self.masks.insert(i, m)
        self.states.insert(i, np.full_like(self.z0, np.nan))
        return i

    def before(self, i: int) -> tuple[float, np.ndarray]:
        return (self.t0, self.z0) if i == 0 else (self.times[i - 1], self.states[i - 1])

    def settle(self, horizon: float) -> None:
        """Drop the entries taken before `horizon` (no later arrival can precede them), keeping the last one's state."""
        k = int(np.searchsorted(np.asarray(self.times), horizon, side="left"))
        if k > 0:
            self.t0, self.z0 = self.times[k - 1], self.states[k - 1]
            del self.times[:k], self.ys[:k], self.masks[:k], self.states[:k]


def run_delayed(obs: AbstractObserver, t: np.ndarray, u: np.ndarray, events: Events, z0: np.ndarray, *,
                max_step: float | None = None, name: str = "observer") -> tuple[np.ndarray, np.ndarray]:
    """The observer's state and estimate at each time of `t`, from the samples that have arrived by then (see the
    module docstring). `u` is held (zero-order) between the times of `t`; returns ``(Z, X)``."""
    from ..observer import ParticleObserver

    if isinstance(obs, ParticleObserver):
        raise ModelError(f"observer {name!r} is a particle filter, which runs on a whole recording at once; measurement "
                         "delays are handled by the continuous-discrete observers (ekf, ukf, srekf, srukf, iekf, ...)")
    if not obs.sampled:
        raise ModelError(f"observer {name!r} ({obs.design.method}) takes the output continuously; measurement delays are "
                         "handled by the continuous-discrete observers (a flow between samples and an update at each: "
                         "ekf, ukf, srekf, srukf, iekf, ...)")
    ny = obs.system.n_outputs
    keep = (events.taken >= t[0] - 1e-12) & (events.arrived <= t[-1] + 1e-12)
    order = np.lexsort((events.taken[keep], events.arrived[keep]))
    ev = [(float(events.arrived[keep][i]), float(events.taken[keep][i]), int(events.output[keep][i]),
           float(events.value[keep][i])) for i in order]
    horizon = float(np.max(events.arrived - events.taken)) if events.taken.size else 0.0
    hist = _History(float(t[0]), np.asarray(z0, dtype=float))
    y_held = np.zeros(ny)
    Z, X = np.empty((t.size, hist.z0.size)), np.empty((t.size, obs.system.n_states))
    e = 0
    carry = [np.nan]   # the flow's rate at the present state (its next interval starts there)
    for k, tk in enumerate(t):
        first = None
        while e < len(ev) and ev[e][0] <= tk + 1e-12 * max(1.0, abs(tk)):
            _, taken, j, v = ev[e]
            i = hist.insert(taken, j, v, ny)
            first = i if first is None else min(first, i)
            e += 1
        if first is not None:   # go back to the state before the earliest new sample and apply them again in order
            for i in range(first, len(hist.times)):
                ti, z = hist.before(i)
                z = _flow(obs, t, u, ti, z, hist.times[i], y_held, max_step, name)
                ui = u[_row(t, hist.times[i])]
                y_i = np.where(hist.masks[i] > 0, hist.ys[i], y_held)
                hist.states[i] = np.asarray(obs.update(hist.times[i], z, ui, y_i, hist.masks[i]), dtype=float)
                y_held = np.where(hist.masks[i] > 0, hist.ys[i], y_held)
        if first is None and k > 0:   # nothing new: the present state follows from the previous one
            Z[k] = _flow(obs, t, u, float(t[k - 1]), Z[k - 1], float(tk), y_held, max_step, name, carry)
        else:
            t_last, z_last = hist.before(len(hist.times))
            carry = [np.nan]
            Z[k] = _flow(obs, t, u, t_last, z_last, float(tk), y_held, max_step, name, carry)
        X[k] = obs.estimate(float(tk), Z[k], u[k], y_held)
        hist.settle(float(tk) - horizon)
    return Z, X


def _row(t: np.ndarray, s: float) -> int:
    """The row of `t` whose hold interval [t_r, t_{r+1}) contains s."""
    return int(np.clip(np.searchsorted(t, s + 1e-12 * max(1.0, abs(s)), side="right") - 1, 0, t.size - 1))


def _flow(obs: AbstractObserver, t: np.ndarray, u: np.ndarray, a: float, z: np.ndarray, b: float, y: np.ndarray,
          max_step: float | None, name: str, rate: list[float] | None = None) -> np.ndarray:
    """The flow from (a, z) to b, holding each row's input over its interval of `t`. `rate` carries the flow's rate
    from one interval to the next (see ``integrate``): a first guess of the step only, since the rate at each
    interval's end is measured and the interval redone if its steps were too long."""
    rate = [np.nan] if rate is None else rate
    while b - a > 1e-12 * max(1.0, abs(b)):
        r = _row(t, a)
        end = min(b, float(t[r + 1])) if r + 1 < t.size else b
        z = integrate(obs, a, z, end, u[r], y, max_step=max_step, where=f"observer {name!r}", rate=rate)
        a = end
    return z
