"""simulate(): a plant and any number of observers on the same measured signals.

The plant and every observer are integrated together as one ODE with fixed-step RK4,
compiled through CasADi (see :mod:`nlobs.engine`). Two measurement modes:

- continuous (no ``sampling``): observers see y(t) = h(x(t), u(t), t) + n_k at every RK4
  stage, with the noise sample n_k held over step k; continuous-discrete observers update at
  every step;
- sampled (``sampling=Sampling(period)``): y_k = h(x(t_k)) + n_k is taken every `period`
  seconds and held (zero-order hold); continuous-discrete observers update at the samples.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import casadi as ca
import numpy as np

from .._progress import as_progress
from ..design import ObserverDesign
from ..engine import Backend, StepRunner, compile_system, evaluate_many, rk4_step, rows
from ..errors import FiniteEscapeError, ModelError, ShapeError
from ..model import System, input_signals
from ..observer import AbstractObserver, Observer, as_observer
from ._options import Noise, ProcessNoise, Sampling
from ._results import ObserverTrace, Run

__all__ = ["simulate", "named_observers", "check_compatible", "stage_inputs"]


def named_observers(observers: Any) -> dict[str, AbstractObserver]:
    """Observers by name, from a mapping, a sequence, or a single observer/design."""
    if observers is None:
        return {}
    if isinstance(observers, Mapping):
        return {str(k): as_observer(v, str(k)) for k, v in observers.items()}
    if isinstance(observers, (ObserverDesign, AbstractObserver)):
        observers = [observers]
    out: dict[str, AbstractObserver] = {}
    for obj in observers:
        obs = as_observer(obj)
        base = obs.name if isinstance(obs, Observer) else obs.design.method
        name, i = base, 2
        while name in out:
            name, i = f"{base}_{i}", i + 1
        out[name] = obs
    return out


def check_compatible(plant: System, name: str, obs: AbstractObserver) -> None:
    """An observer must consume the plant's inputs and outputs and estimate its states."""
    s = obs.system
    for what, mine, theirs in (("inputs", s.inputs, plant.inputs), ("outputs", s.outputs, plant.outputs),
                               ("states", s.states, plant.states)):
        if tuple(mine) != tuple(theirs):
            raise ModelError(f"observer {name!r} was designed for {what} {list(mine)}, but the plant {plant.name!r} has "
                             f"{list(theirs)}; design it on a model with the same {what}")


def stage_inputs(plant: System, inputs: Any, params: Mapping[str, float], t: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Inputs at the RK4 stages of each step: shape (N, 3·nu), blocks [u(t_k), u(t_k + dt/2), u(t_k + dt)].

    Held (piecewise-constant) signals use their left limit at t_k + dt, so a switch exactly
    on the grid takes effect in the next step.
    """
    signals = input_signals(plant, inputs, params)
    N, nu = t.size, plant.n_inputs
    out = np.empty((N, 3 * nu))
    for j, sig in enumerate(signals):
        end = np.nextafter(t + dt, -np.inf) if sig.held else t + dt
        for k, times in enumerate((t, t + dt / 2, end)):
            v = sig(times)
            bad = np.flatnonzero(~np.isfinite(v))
            if bad.size:
                raise ShapeError(f"input `{plant.inputs[j]}` is {v[bad[0]]} at t = {times[bad[0]]:g}; inputs must be finite")
            out[:, k * nu + j] = v
    return out


def simulate(
    plant: System,
    observers: Any = None,
    *,
    t_final: float,
    dt: float,
    x0: Sequence[float],
    inputs: Any = None,
    params: Mapping[str, float] | None = None,
    noise: Noise | None = None,
    process_noise: ProcessNoise | None = None,
    sampling: Sampling | None = None,
    seed: int | None = None,
    xhat0: Mapping[str, Sequence[float]] | Sequence[float] | None = None,
    engine: Backend = "auto",
    progress: bool | Callable[[float], None] | None = None,
    escape_bound: float = 1e12,
) -> Run:
    """Simulate a plant and observers on the same measurements, with fixed-step RK4.

    Parameters
    ----------
    plant : System
        The true system.
    observers : mapping of name to observer/design, or a sequence, optional
        Observers (or designs, made runnable with :class:`nlobs.Observer`).
    t_final, dt : float
        Horizon [0, t_final] and step; t_final must be a whole multiple of dt.
    x0 : sequence of float
        Initial plant state.
    inputs : mapping of input name to signal, optional
        Numbers, expressions of ``t`` (``"0.5*sin(t)"``), callables ``u(t)``, or
        :mod:`nlobs.model` signals. Inputs not given are zero.

    Other Parameters
    ----------------
    params : mapping, optional
        Plant parameter overrides (the observers keep the model they were designed on).
    noise : Noise, optional
        Measurement noise on each output sample.
    process_noise : ProcessNoise, optional
        Additive noise on the plant state.
    sampling : Sampling, optional
        Sampled measurements with zero-order hold; default: continuous measurements.
    seed : int, optional
        Seed for all random draws (measurement noise first, then process noise).
    xhat0 : mapping of observer name to vector, or one vector for all, optional
        Initial estimates (default: each design's).
    engine : {"auto", "vm", "c"}
        ``"c"`` generates and compiles C (cached on disk); ``"vm"`` runs on CasADi's virtual
        machine; ``"auto"`` compiles long runs when a compiler exists.
    progress : bool or callable, optional
        Show progress on stderr (True) or call ``progress(fraction)``.
    escape_bound : float
        A state larger than this in magnitude counts as a blow-up.

    Returns
    -------
    Run

    Raises
    ------
    FiniteEscapeError
        When the plant or an observer blows up; it carries the time and state where it
        happened and the partial result as ``partial``.
    ModelError, ShapeError
        For inconsistent arguments (wrong sizes, unknown names, incompatible observers).
    """
    if not isinstance(plant, System):
        raise TypeError(f"simulate: `plant` must be an nlobs.System, got {type(plant).__name__}")
    for label, v in (("t_final", t_final), ("dt", dt)):
        if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
            raise ShapeError(f"simulate: `{label}` must be a positive number, got {v!r}")
    N = int(round(t_final / dt))
    if N < 1 or abs(N * dt - t_final) > 1e-9 * max(1.0, t_final):
        raise ShapeError(f"simulate: t_final = {t_final:g} must be a whole multiple of dt = {dt:g}")
    plant = plant.with_params(**params) if params else plant
    n, nu, ny = plant.n_states, plant.n_inputs, plant.n_outputs
    x0v = np.asarray(x0, dtype=float).reshape(-1)
    if x0v.size != n or not np.all(np.isfinite(x0v)):
        raise ShapeError(f"simulate: `x0` must be {n} finite numbers (one per state: {', '.join(plant.states)}), got {list(x0v)}")
    obs = named_observers(observers)
    if obs and ny == 0:
        raise ModelError(f"simulate: the plant {plant.name!r} has no outputs; an observer needs a measurement")
    for name, o in obs.items():
        check_compatible(plant, name, o)
    z0s = {name: o.initial_state(_xhat0_for(xhat0, name, n)) for name, o in obs.items()}

    t = np.arange(N + 1) * dt
    U = stage_inputs(plant, inputs, plant.params, t[:-1], np.full(N, dt))
    u_grid = np.vstack([U[:, :nu], U[-1:, 2 * nu:3 * nu]]) if nu else np.zeros((N + 1, 0))
    rng = np.random.default_rng(seed)
    meas_noise = noise.draw(rng, N + 1, plant.outputs) if noise is not None else np.zeros((N + 1, ny))
    w = process_noise.draw(rng, N, plant.states, dt) if process_noise is not None else np.zeros((N, n))
    every = sampling.every(dt) if sampling is not None else 1
    flags = (np.arange(N + 1) % every == 0).astype(float)

    step, layout = _joint_step(plant, obs, sampled=sampling is not None)
    A = np.hstack([t[:-1, None], np.full((N, 1), dt), U, meas_noise[:-1], w, flags[:-1, None]])
    s0 = np.concatenate([x0v, *z0s.values(), np.zeros(ny if sampling is not None else 0)])
    c = plant.param_values if plant.n_params else np.zeros(1)
    report = as_progress(progress, f"simulate {plant.name}")

    def assemble(states: np.ndarray) -> Run:
        k = states.shape[0]
        S = np.vstack([s0, states])
        return _assemble(plant, obs, layout, S, t[:k + 1], u_grid[:k + 1], meas_noise[:k + 1], flags[:k + 1], every, c,
                         info={"dt": dt, "sampling": None if sampling is None else sampling.period, "seed": seed,
                               "engine": engine})

    checked = [0]

    def on_chunk(states: np.ndarray, k: int) -> None:
        block = states[checked[0]:k]
        bad = ~np.isfinite(block) | (np.abs(block) > escape_bound)
        if bad.any():
            r = checked[0] + int(np.flatnonzero(bad.any(axis=1))[0])
            col = int(np.flatnonzero(bad[r - checked[0]])[0])
            where, sl, names = layout.owner(col)
            last = s0 if r == 0 else states[r - 1]
            err = FiniteEscapeError(where, float(t[r]), last[sl], names, escape_bound)
            err.partial = assemble(states[:r])  # type: ignore[attr-defined]
            raise err
        checked[0] = k
        if report is not None:
            report(k / N)

    states = StepRunner(step, backend=engine).run(s0, A, c, on_chunk=on_chunk)
    return assemble(states)


def _xhat0_for(xhat0: Any, name: str, n: int) -> Any:
    if xhat0 is None:
        return None
    if isinstance(xhat0, Mapping):
        return xhat0.get(name)
    return xhat0


class _Layout:
    """Where each subsystem lives in the joint state vector."""

    def __init__(self, plant: System, obs: Mapping[str, AbstractObserver], sampled: bool):
        self.n = plant.n_states
        self.slices: dict[str, slice] = {}
        self.names: dict[str, Sequence[str]] = {"plant": plant.states}
        off = self.n
        for name, o in obs.items():
            self.slices[name] = slice(off, off + o.n_z)
            self.names[name] = o.design.z_names
            off += o.n_z
        self.held = slice(off, off + (plant.n_outputs if sampled else 0))
        self.size = self.held.stop

    def owner(self, col: int) -> tuple[str, slice, Sequence[str]]:
        if col < self.n:
            return "plant", slice(0, self.n), self.names["plant"]
        for name, sl in self.slices.items():
            if sl.start <= col < sl.stop:
                return f"observer {name!r}", sl, self.names[name]
        return "measurement hold", self.held, [f"y{i}" for i in range(self.held.stop - self.held.start)]


def _joint_step(plant: System, obs: Mapping[str, AbstractObserver], *, sampled: bool) -> tuple[ca.Function, _Layout]:
    comp = compile_system(plant)
    n, nu, ny = plant.n_states, plant.n_inputs, plant.n_outputs
    layout = _Layout(plant, obs, sampled)
    s = ca.SX.sym("s", layout.size)
    na = 2 + 3 * nu + ny + n + 1
    a = ca.SX.sym("a", na)
    c = ca.SX.sym("c", max(plant.n_params, 1))
    p = rows(c, 0, plant.n_params)
    t, dt = a[0], a[1]
    U = [rows(a, 2 + k * nu, 2 + (k + 1) * nu) for k in range(3)]
    off = 2 + 3 * nu
    noise, w, flag = rows(a, off, off + ny), rows(a, off + ny, off + ny + n), a[off + ny + n]
    x = rows(s, 0, n)
    y_now = comp.h(t, x, U[0], p) + noise
    y_s = ca.if_else(flag, y_now, rows(s, layout.held.start, layout.held.stop)) if sampled else y_now
    zs = {}
    for name, o in obs.items():
        sl = layout.slices[name]
        z = rows(s, sl.start, sl.stop)
        d = o.design
        if d.update is not None:
            z = ca.if_else(flag, d.update(t, z, U[0], y_s, ca.DM.ones(ny)), z)
        zs[name] = z

    def rhs(tt: ca.SX, S: ca.SX, k: int) -> ca.SX:
        xx, u = rows(S, 0, n), U[k]
        y = y_s if sampled else comp.h(tt, xx, u, p) + noise
        parts = [comp.f(tt, xx, u, p)]
        off_ = n
        for o in obs.values():
            parts.append(o.design.flow(tt, rows(S, off_, off_ + o.n_z), u, y))
            off_ += o.n_z
        return ca.vertcat(*parts)

    joint = ca.vertcat(x, *zs.values())
    S_next = rk4_step(rhs, t, joint, dt)
    s_next = ca.vertcat(rows(S_next, 0, n) + w, rows(S_next, n, joint.shape[0]), y_s if sampled else ca.SX(0, 1))
    return ca.Function("joint_step", [s, a, c], [s_next]), layout


def _assemble(plant: System, obs: Mapping[str, AbstractObserver], layout: _Layout, S: np.ndarray, t: np.ndarray,
              u: np.ndarray, noise: np.ndarray, flags: np.ndarray, every: int, c: np.ndarray, info: dict[str, Any]) -> Run:
    comp = compile_system(plant)
    K = t.size
    x = S[:, :layout.n]
    p = c[:plant.n_params]
    y_true = evaluate_many(comp.h, t[:, None], x, u, p) if plant.n_outputs else np.zeros((K, 0))
    held_idx = (np.arange(K) // every) * every
    y = y_true[held_idx] + noise[held_idx]
    ones = np.ones((K, plant.n_outputs))
    traces = {}
    for name, o in obs.items():
        z = S[:, layout.slices[name]]
        d = o.design
        if d.update is not None:
            jumped = evaluate_many(d.update, t[:, None], z, u, y, ones)
            z = np.where(flags[:, None] > 0, jumped, z)
        xhat = evaluate_many(d.output, t[:, None], z, u, y)
        prior = evaluate_many(d.output, t[:1, None], S[:1, layout.slices[name]], u[:1], y[:1])[0]
        traces[name] = ObserverTrace(name, d.method, d.z_names, z, xhat, prior)
    return Run(plant.name, t, plant.states, plant.inputs, plant.outputs, u, y, traces, x=x, y_true=y_true, info=info)
