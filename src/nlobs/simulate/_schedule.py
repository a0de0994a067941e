"""One schedule per run: which output is sampled at which instant, when each sample reaches the observers, and the
noise of every sample and step.

A :class:`SampleSchedule` is built once, from the run's time grid (or a recording's rows), its sampling, its known
measurement delays and its noise, and then read by everything that needs to know: the compiled loop (its per-step
inputs: the noise columns and the sample flags, :meth:`nlobs.simulate._run.Prepared.inputs_for`), the particle
filters run after the plant (the rows they step at), the delayed re-processing (:meth:`SampleSchedule.events`, the
samples with the time each was taken and the time it arrived), the discrete-time runs (the noise of a map's steps),
and Monte Carlo (run j's seed, :func:`run_seeds`, and its re-run). Nothing here depends on the estimates: who is
sampled and when, and what noise each sample gets, are fixed before anything runs.

The noise of a seed is drawn per (stream, channel) (:func:`nlobs.simulate._options.channel_generators`), sample by
sample in time order: the noise of sample k depends on the seed, the stream, the channel and k only, whatever the
horizon.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..observer._signals import delays_of
from ._options import Noise, ProcessNoise, Sampling, channel_generators

__all__ = ["SampleSchedule", "run_seeds"]


def run_seeds(seed: int | None, runs: int) -> np.ndarray:
    """The seed of each of `runs` runs drawn from one base `seed` (Monte Carlo's run j is ``simulate(seed=seeds[j])``)."""
    return np.random.SeedSequence(seed).generate_state(runs).astype(np.int64)


@dataclass(frozen=True, eq=False)
class SampleSchedule:
    """What is sampled when, when each sample arrives, and the noise (see the module's documentation).

    Attributes
    ----------
    t : numpy.ndarray of shape (N + 1,)
        The rows: a run's time grid, or a recording's sample times.
    outputs, states : tuple of str
        The measured outputs (columns of the samples) and the plant's states (columns of the process noise).
    clock : tuple of int, optional
        Rows per sample: one number (every output on one clock) or one per output (multi-rate); None: every row is a
        sample of every output (continuous measurements, a discrete-time model's steps), or `mask` says which.
    mask : numpy.ndarray of shape (N + 1, len(outputs)), optional
        A recording's measured cells (True: measured), read from its NaN.
    delays : numpy.ndarray of shape (len(outputs),)
        Each output's known measurement delay in seconds (0: none).
    stamped_at_arrival : bool
        Whether a row is stamped when its samples arrived (a recording) or when they were taken (a simulation).
    noise, process_noise : Noise, ProcessNoise, optional
    step : float
        The grid's step, over which a noise sample is held (:class:`Noise` ``hold``).
    process_step : float
        The step of the process noise: dt for an ODE (increments σ√dt·ξ), 1 for a map (σ per step).
    sampling : Sampling, optional
        The sampling the clock was read from (to run the same schedule again).
    seed : int, optional
        The seed of the noise draws.
    """

    t: np.ndarray
    outputs: tuple[str, ...]
    states: tuple[str, ...] = ()
    clock: tuple[int, ...] | None = None
    mask: np.ndarray | None = None
    delays: np.ndarray | None = None
    stamped_at_arrival: bool = False
    noise: Noise | None = None
    process_noise: ProcessNoise | None = None
    step: float = 1.0
    process_step: float = 1.0
    sampling: Sampling | None = None
    seed: int | None = None

    @classmethod
    def on_grid(cls, t: np.ndarray, dt: float, outputs: Sequence[str], states: Sequence[str], *,
                sampling: Sampling | None = None, noise: Noise | None = None, process_noise: ProcessNoise | None = None,
                delay: Mapping[str, float] | None = None, seed: int | None = None, caller: str = "simulate") -> SampleSchedule:
        """A continuous-time run on the grid `t` of step `dt`: sampled every `sampling` period (one clock, or one per
        output), or continuously measured without it; `delay` in seconds per output; the noise of `seed`."""
        outputs = tuple(outputs)
        clock = None
        if sampling is not None:
            clock = tuple(int(v) for v in sampling.every_each(dt, outputs)) if sampling.multirate else (sampling.every(dt),)
        return cls(t, outputs, tuple(states), clock, None, delays_of(delay, list(outputs), caller), False, noise,
                   process_noise, float(dt), float(dt), sampling, seed)

    @classmethod
    def on_map(cls, t: np.ndarray, sample_time: float, outputs: Sequence[str], states: Sequence[str], *,
               noise: Noise | None = None, process_noise: ProcessNoise | None = None,
               seed: int | None = None) -> SampleSchedule:
        """A discrete-time model's run: every output measured at every step, the process noise σ per step."""
        outputs = tuple(outputs)
        return cls(t, outputs, tuple(states), None, None, np.zeros(len(outputs)), False, noise, process_noise,
                   float(sample_time), 1.0, None, seed)

    @classmethod
    def of_recording(cls, t: np.ndarray, measured: np.ndarray, outputs: Sequence[str], *,
                     delay: Mapping[str, float] | None = None, caller: str = "estimate") -> SampleSchedule:
        """A recording: its rows, the cells `measured` (True where a sample is), stamped when they arrived, each
        output `delay` seconds after it was taken."""
        outputs = tuple(outputs)
        return cls(np.asarray(t, dtype=float), outputs, (), None, np.asarray(measured, dtype=bool),
                   delays_of(delay, list(outputs), caller), True)

    def with_seed(self, seed: int | None) -> SampleSchedule:
        """The same schedule with the noise of `seed`."""
        return replace(self, seed=seed)

    @property
    def sampled(self) -> bool:
        """Whether the outputs are sampled on a clock (and held in between)."""
        return self.clock is not None

    @property
    def multirate(self) -> bool:
        """Whether the outputs have clocks of their own."""
        return self.clock is not None and self.sampling is not None and self.sampling.multirate

    @property
    def every(self) -> int:
        """Rows per sample of the fastest clock (1 without a clock)."""
        return min(self.clock) if self.clock is not None else 1

    @property
    def delayed(self) -> bool:
        """Whether some output arrives late."""
        return self.delays is not None and bool(np.any(self.delays > 0))

    def flags(self) -> np.ndarray:
        """The sample flags of the compiled step: (N + 1, 1) for one clock, (N + 1, ny) per output; 1 where a sample
        is taken."""
        k = np.arange(self.t.size)[:, None]
        return (k % np.asarray(self.clock)[None, :] == 0).astype(float)

    def measured(self) -> np.ndarray:
        """(N + 1, ny) bool: which output is sampled at which row."""
        if self.mask is not None:
            return self.mask
        if self.clock is None:
            return np.ones((self.t.size, len(self.outputs)), dtype=bool)
        F = self.flags() > 0
        return F if F.shape[1] == len(self.outputs) else np.repeat(F, len(self.outputs), axis=1)

    def sample_rows(self) -> np.ndarray:
        """The rows where at least one output is sampled."""
        return np.flatnonzero(self.measured().any(axis=1))

    def arrival_lag(self, caller: str) -> np.ndarray:
        """Rows from a sample's row to the row it arrives in, per output, on a grid of step `step` (a recording
        written at arrival: :meth:`nlobs.Run.to_csv`). ValueError for a delay that is not a whole number of steps."""
        lag = np.zeros(len(self.outputs), dtype=int)
        for j, (name, d) in enumerate(zip(self.outputs, self.delays)):
            k = int(round(d / self.step))
            if abs(k * self.step - d) > 1e-9 * max(1.0, d):
                raise ValueError(f"{caller}: the delay of {name!r} ({d:g} s) is not a whole number of steps of dt = "
                                 f"{self.step:g}; a recording stamped at arrival needs it on the grid (choose dt dividing "
                                 "the delay)")
            lag[j] = k
        return lag

    def events(self, y: np.ndarray) -> Any:
        """The samples of `y` (rows as `t`) as events: the time each was taken, the time it arrived (taken + its
        output's delay), its output and its value (:class:`nlobs.simulate._delays.Events`)."""
        from ._delays import Events

        return Events.from_rows(self.t, y, self.measured(), self.delays, stamped_at_arrival=self.stamped_at_arrival)

    def measurement_noise(self) -> np.ndarray | None:
        """(N + 1, ny): the measurement noise of each row (None without noise)."""
        if self.noise is None:
            return None
        root = np.random.SeedSequence(self.seed)
        return self.noise.draw(channel_generators(root, "measurement", len(self.outputs)), self.t.size, self.outputs,
                               self.step)

    def process_increments(self) -> np.ndarray | None:
        """(N, n): the process noise of each step, from row k to row k + 1 (None without process noise)."""
        if self.process_noise is None:
            return None
        root = np.random.SeedSequence(self.seed)
        return self.process_noise.draw(channel_generators(root, "process", len(self.states)), self.t.size - 1,
                                       self.states, self.process_step)
