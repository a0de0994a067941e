"""Option objects for simulations: how measurements are sampled, and the noise on them."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from ..errors import ShapeError

__all__ = ["Sampling", "Noise", "ProcessNoise", "Adaptive"]


@dataclass(frozen=True)
class Sampling:
    """Measurements taken every `period` seconds and held (zero-order hold) in between.

    `period` is one number for all outputs, or a mapping ``{output: period}`` with one period per output
    (multi-rate sensors: a GPS at 1 s beside an IMU at 0.01 s). Each period must be a whole multiple of
    the integration step ``dt``. At an instant where only some outputs are sampled, the observers update
    with those (the others are masked out, as a recording's NaN cells are), and each output is held
    between its own samples. Without a ``Sampling``, observers see the output continuously (at every RK4
    stage).
    """

    period: float | Mapping[str, float]

    def __post_init__(self) -> None:
        values = list(self.period.values()) if isinstance(self.period, Mapping) else [self.period]
        for v in values:
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not (np.isfinite(v) and v > 0):
                raise ValueError(f"Sampling: `period` must be a positive number (or one per output), got {self.period!r}")
        if isinstance(self.period, Mapping) and not self.period:
            raise ValueError("Sampling: `period` is an empty mapping; give one period per output")

    @property
    def multirate(self) -> bool:
        """Whether the outputs have periods of their own."""
        return isinstance(self.period, Mapping)

    def periods(self, outputs: Sequence[str]) -> np.ndarray:
        """The period of each of `outputs` (a mapping must name every output, and only outputs)."""
        if not isinstance(self.period, Mapping):
            return np.full(len(outputs), float(self.period))
        unknown = [k for k in self.period if k not in outputs]
        if unknown:
            raise ShapeError(f"Sampling: {unknown[0]!r} is not an output; the outputs are {', '.join(outputs)}")
        missing = [k for k in outputs if k not in self.period]
        if missing:
            raise ShapeError(f"Sampling: no sample period for {', '.join(missing)}; give one period per output "
                             f"({', '.join(outputs)}) or one number for all")
        return np.array([float(self.period[k]) for k in outputs])

    def every(self, dt: float) -> int:
        """Steps of size `dt` per sample (the shortest period's, for per-output periods)."""
        period = min(self.period.values()) if isinstance(self.period, Mapping) else self.period
        return _steps(period, dt)

    def every_each(self, dt: float, outputs: Sequence[str]) -> np.ndarray:
        """Steps of size `dt` per sample, for each output."""
        return np.array([_steps(p, dt) for p in self.periods(outputs)], dtype=int)


def _steps(period: float, dt: float) -> int:
    rel = max([1e-9] + [4 * float(np.finfo(v.dtype).eps) for v in (period, dt) if isinstance(v, np.floating)])
    m = float(period) / float(dt)
    if abs(m - round(m)) > rel * max(1.0, m) or round(m) < 1:
        raise ValueError(f"Sampling: the period {period:g} must be a whole multiple of dt = {dt:g}")
    return int(round(m))


Kind = Literal["gaussian", "uniform"]

#: The noise streams of a seed: each channel of each stream has a generator of its own.
STREAMS = {"measurement": 0, "process": 1}


def channel_generators(seed: int | np.random.SeedSequence | None, stream: str, n: int) -> list[np.random.Generator]:
    """One generator per channel (output or state) of `stream` ("measurement" or "process"), each a child of the
    seed's SeedSequence keyed by (stream, channel). A channel's generator is drawn sample by sample in time order, so
    the noise of sample k depends on the seed, the stream, the channel and k only: a 10 s run has the noise of the first
    10 s of a 20 s run with the same seed, and adding process noise does not change the measurement noise."""
    key = STREAMS[stream]
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        # SeedSequence(seed) keeps the integer as its entropy and has no spawn key: the children directly
        entropy, spawn_key = int(seed), ()
    else:
        root = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        entropy, spawn_key = root.entropy, tuple(root.spawn_key)
    return [np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy, spawn_key=(*spawn_key, key, j))))
            for j in range(n)]


def _generators(rng: Any, n: int) -> list[np.random.Generator]:
    """Per-channel generators from one generator (shared by every channel, drawn channel after channel) or a list."""
    if isinstance(rng, np.random.Generator):
        return [rng] * n
    rngs = list(rng)
    if len(rngs) != n:
        raise ValueError(f"noise: {len(rngs)} generators for {n} channels")
    return rngs


def _per_channel(scale: float | Sequence[float] | Mapping[str, float], names: Sequence[str], what: str) -> np.ndarray:
    if isinstance(scale, Mapping):
        unknown = [k for k in scale if k not in names]
        if unknown:
            raise ShapeError(f"{what}: {unknown[0]!r} is not one of {', '.join(names)}")
        s = np.array([float(scale.get(n, 0.0)) for n in names])
    else:
        s = np.broadcast_to(np.asarray(scale, dtype=float), (len(names),)).copy() if np.ndim(scale) == 0 else np.asarray(scale, dtype=float).ravel()
    if s.size != len(names):
        raise ShapeError(f"{what}: {s.size} value(s) for {len(names)} channel(s) ({', '.join(names)})")
    if not np.all(np.isfinite(s)) or np.any(s < 0):
        raise ShapeError(f"{what}: values must be finite and non-negative, got {s}")
    return s


@dataclass(frozen=True)
class Noise:
    """Measurement noise added to each output sample.

    Build with :meth:`gaussian` (standard deviation) or :meth:`uniform` (bound b, uniform in
    [-b, b], as in Yi, Ortega & Zhang (2019), §V), or combine per output with :meth:`per_output`.
    Scales are a scalar (every output), a sequence (one per output) or a mapping by name.
    With `hold` (seconds, a whole multiple of the integration step) a new noise sample is
    drawn only every `hold` seconds and held in between — a noise source with its own sample
    time over a continuously measured output (Yi, Ortega & Zhang (2019), §V-C: noise "sampled every 10⁻⁴ s").
    """

    kinds: Mapping[str, Kind] | Kind
    scale: float | Sequence[float] | Mapping[str, float]
    hold: float | None = None

    def __post_init__(self) -> None:
        if self.hold is not None and not (np.isfinite(self.hold) and self.hold > 0):
            raise ValueError(f"Noise: `hold` must be a positive number of seconds, got {self.hold!r}")

    @classmethod
    def gaussian(cls, std: float | Sequence[float] | Mapping[str, float], *, hold: float | None = None) -> Noise:
        return cls("gaussian", std, hold)

    @classmethod
    def uniform(cls, bound: float | Sequence[float] | Mapping[str, float], *, hold: float | None = None) -> Noise:
        return cls("uniform", bound, hold)

    @classmethod
    def per_output(cls, gaussian: Mapping[str, float] | None = None, uniform: Mapping[str, float] | None = None, *,
                   hold: float | None = None) -> Noise:
        """Gaussian noise on some outputs and uniform noise on others (by name)."""
        gaussian, uniform = dict(gaussian or {}), dict(uniform or {})
        both = set(gaussian) & set(uniform)
        if both:
            raise ValueError(f"Noise.per_output: output {sorted(both)[0]!r} has both Gaussian and uniform noise")
        kinds = {**{k: "gaussian" for k in gaussian}, **{k: "uniform" for k in uniform}}
        return cls(kinds, {**gaussian, **uniform}, hold)

    def scales(self, names: Sequence[str]) -> np.ndarray:
        return _per_channel(self.scale, names, "Noise")

    def draw(self, rng: np.random.Generator | Sequence[np.random.Generator], n_rows: int, names: Sequence[str],
             dt: float | None = None) -> np.ndarray:
        """Samples of shape (n_rows, len(names)), one per step of size `dt` (needed with `hold`). `rng`: one generator,
        or one per output (:func:`channel_generators`: the noise of a sample then does not depend on `n_rows`)."""
        out = np.zeros((n_rows, len(names)))
        self.fill(_generators(rng, len(names)), out, self.scales(names), self.kind_of(names), dt)
        return out

    def kind_of(self, names: Sequence[str]) -> tuple[str, ...]:
        """The kind ("gaussian" or "uniform") of each of `names`."""
        kinds = tuple(self.kinds.get(n, "gaussian") if isinstance(self.kinds, Mapping) else self.kinds for n in names)
        bad = [k for k in kinds if k not in ("gaussian", "uniform")]
        if bad:
            raise ValueError(f"Noise: unknown kind {bad[0]!r}; use 'gaussian' or 'uniform'")
        return kinds

    def fill(self, rngs: Sequence[np.random.Generator], out: np.ndarray, scales: np.ndarray, kinds: Sequence[str],
             dt: float | None = None, scratch: np.ndarray | None = None) -> None:
        """:meth:`draw` with one generator per output (the same numbers), written into `out` (a view of shape
        (n_rows, len(rngs)), e.g. the noise columns of a Monte Carlo chunk's inputs), with the scales and kinds
        computed once (:meth:`scales`, :meth:`kind_of`); `scratch`, a float array of at least n_rows, spares an
        allocation per output."""
        if self.hold is not None:
            if dt is None:
                raise ValueError("Noise with `hold` needs the step `dt` to draw")
            every = Sampling(self.hold).every(dt)
            fresh = self._fill(rngs, np.zeros((-(-out.shape[0] // every), len(rngs))), scales, kinds, scratch)
            out[...] = np.repeat(fresh, every, axis=0)[:out.shape[0]]
            return
        self._fill(rngs, out, scales, kinds, scratch)

    @staticmethod
    def _fill(rngs: Sequence[np.random.Generator], out: np.ndarray, s: np.ndarray, kinds: Sequence[str],
              scratch: np.ndarray | None = None) -> np.ndarray:
        n_rows = out.shape[0]
        buf = scratch[:n_rows] if scratch is not None and scratch.size >= n_rows else np.empty(n_rows)
        for j, (g, kind) in enumerate(zip(rngs, kinds)):
            if kind == "gaussian":  # (the same product as s[j] * g.standard_normal(n_rows))
                np.multiply(s[j], g.standard_normal(out=buf), out=out[:, j])
            else:
                out[:, j] = g.uniform(-s[j], s[j], n_rows)
        return out


@dataclass(frozen=True)
class ProcessNoise:
    """Additive process noise dx = f dt + σ dW on the plant (Euler-Maruyama increment σ√dt·ξ per step).

    `std` is σ: a scalar, one value per state, or a mapping by state name.
    """

    std: float | Sequence[float] | Mapping[str, float]

    def draw(self, rng: np.random.Generator | Sequence[np.random.Generator], n_rows: int, names: Sequence[str],
             dt: float) -> np.ndarray:
        """Increments of shape (n_rows, len(names)); `rng` as for :meth:`Noise.draw`."""
        s = self.scales(names)
        if isinstance(rng, np.random.Generator):
            return s * np.sqrt(dt) * rng.standard_normal((n_rows, len(names)))
        out = np.zeros((n_rows, len(names)))
        self.fill(_generators(rng, len(names)), out, s * np.sqrt(dt))
        return out

    def scales(self, names: Sequence[str]) -> np.ndarray:
        """σ of each of `names`."""
        return _per_channel(self.std, names, "ProcessNoise")

    @staticmethod
    def fill(rngs: Sequence[np.random.Generator], out: np.ndarray, scales: np.ndarray, scratch: np.ndarray | None = None) -> None:
        """:meth:`draw` with one generator per state, written into `out` (a view of shape (n_rows, len(rngs)));
        `scales` is σ·√dt per state (``scales(names) * np.sqrt(dt)``); `scratch` as for :meth:`Noise.fill`."""
        n_rows = out.shape[0]
        buf = scratch[:n_rows] if scratch is not None and scratch.size >= n_rows else np.empty(n_rows)
        for j, g in enumerate(rngs):  # (the same product as (σ·√dt) * ξ, column by column)
            np.multiply(scales[j], g.standard_normal(out=buf), out=out[:, j])


@dataclass(frozen=True)
class Adaptive:
    """Adaptive integration (CVODES, variable order and step with error control) over each step.

    The default integrator is fixed-step RK4 (compiled to C, the fast path). With
    ``integrator=Adaptive(...)`` every step of size dt is integrated by CVODES to the given
    tolerances instead (on CasADi's virtual machine: slower, for stiff models or as an accuracy
    reference). Inputs are interpolated through their values at the start, middle and end of
    each step (exact for held and linear signals).

    The tolerances hold *within* each step: CVODES restarts at every step (inputs, noise and
    sample-time updates may jump there), so the global error grows with the number of steps —
    on Van der Pol over 400 steps, rtol = 1e-8 gives about 4e-5 and rtol = 1e-12 about 5e-9.
    """

    rtol: float = 1e-8
    atol: float = 1e-10
    method: Literal["bdf", "adams"] = "bdf"

    def __post_init__(self) -> None:
        for name in ("rtol", "atol"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"Adaptive: `{name}` must be a positive number, got {v!r}")
        if self.method not in ("bdf", "adams"):
            raise ValueError(f"Adaptive: `method` must be 'bdf' or 'adams', got {self.method!r}")


def xhat0_for(xhat0: Any, name: str, n: int) -> Any:
    """The initial estimate of the observer `name`: from a mapping by observer name, or one vector for all."""
    if xhat0 is None:
        return None
    if isinstance(xhat0, Mapping):
        return xhat0.get(name)
    return xhat0
