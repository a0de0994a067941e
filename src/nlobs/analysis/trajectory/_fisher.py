r"""The Fisher information of x(0) (and unknown parameters) that each candidate sensor gives along one run.

A candidate measures :math:`y_c(t_k) = g_c(t_k, x(t_k), u(t_k), \theta) + v_k`, :math:`v_k \sim N(0, \sigma_c^2)`
independent, at the sample times :math:`t_k`. With :math:`z = (x(0), \theta)` the unknowns, its Fisher information is

.. math::

    F_c = \sum_k \frac{1}{\sigma_c^2} \Big(\frac{\partial y_c(t_k)}{\partial z}\Big)^\top \frac{\partial y_c(t_k)}{\partial z},

the noise-weighted empirical observability Gramian of the sampled run (Krener & Ide (2009)); independent sensors add
their information, so a set's is :math:`F_S = \sum_{c \in S} F_c` and the Cramér–Rao bound of an unbiased estimate of
z from the set's samples is :math:`F_S^{-1}`. The sensitivities :math:`\partial x(t_k)/\partial z` are exact derivatives
of the RK4 steps of the run (forward automatic differentiation by CasADi, one step at a time, on the compiled engine).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ...errors import DataError, ModelError
from ...model import TIME, System, input_signals
from ...references import cite

__all__ = ["CandidateFisher", "candidate_fisher"]


@dataclass(frozen=True, eq=False)
class CandidateFisher:
    """Each candidate's Fisher information of the unknowns along one run (see the module's documentation).

    Attributes
    ----------
    names : tuple of str
        The candidates.
    unknowns : tuple of str
        x(0) of every state, then the unknown parameters: the rows and columns of each matrix.
    information : numpy.ndarray of shape (candidates, m, m)
        :math:`F_c`, noise-weighted.
    times : numpy.ndarray
        The sample times :math:`t_k`.
    dt : float
        The RK4 step of the run.
    states : numpy.ndarray of shape (len(times), n)
        The run's states at the sample times.
    outputs : numpy.ndarray of shape (len(times), candidates)
        What each candidate reads without noise.
    sensitivities : numpy.ndarray of shape (len(times), candidates, m) or None
        :math:`\\partial y_c(t_k)/\\partial z` (kept when asked for).
    method : str
    """

    names: tuple[str, ...]
    unknowns: tuple[str, ...]
    information: np.ndarray
    times: np.ndarray
    dt: float
    states: np.ndarray
    outputs: np.ndarray
    sensitivities: np.ndarray | None
    method: str

    def of(self, members: Sequence[int]) -> np.ndarray:
        """The Fisher information of a set of candidates (the sum of theirs)."""
        m = len(self.unknowns)
        return np.sum(self.information[list(members)], axis=0) if len(members) else np.zeros((m, m))


def _grid(t_final: float, dt: float, sample_period: float | None) -> tuple[float, int, int, str]:
    """The RK4 step (dt, or the largest step <= dt dividing the sample period), the number of steps and the steps
    per sample; and a note when dt was refined."""
    if not (math.isfinite(t_final) and t_final > 0):
        raise DataError(f"the run's t_final must be a positive number, got {t_final!r}")
    if not (math.isfinite(dt) and 0 < dt <= t_final):
        raise DataError(f"the run's dt must be a positive number <= t_final = {t_final:g}, got {dt!r}")
    note = ""
    if sample_period is None:
        every = 1
    else:
        if not (math.isfinite(sample_period) and 0 < sample_period <= t_final):
            raise DataError(f"the sample period must be a positive number <= t_final = {t_final:g}, got {sample_period!r}")
        ratio = sample_period / dt
        every = max(1, round(ratio))
        if abs(ratio - every) > 1e-9 * max(1.0, ratio):
            every = math.ceil(ratio)
            note = (f"the RK4 step is {sample_period / every:.6g} (dt = {dt:g} does not divide the sample period "
                    f"{sample_period:g})")
        dt = sample_period / every
    steps = int(math.floor(t_final / dt + 1e-9))
    steps -= steps % every
    return dt, steps, every, note


def _sensitivity_step(system: System, exprs: Sequence[sp.Expr], unknown: Sequence[str], dt: float) -> ca.Function:
    """The RK4 step of (x, ∂x/∂z) and the per-step output (y_c, ∂y_c/∂z) of every candidate, one CasADi function
    (s, a, p) -> (s_next, o) with a = (t, u at t, t + dt/2, t + dt)."""
    from ...engine import compile_system, rk4_step, to_casadi

    cs = compile_system(system)
    n, q, nu = system.n_states, len(unknown), system.n_inputs
    m = n + q
    qi = [system.param_names.index(k) for k in unknown]
    x, p, t = cs.x, cs.p, cs.t
    S = ca.SX.sym("S", n, m)
    us = [ca.SX.sym(f"u{i}", nu) for i in range(3)]
    f = ca.Function("f", [t, x, cs.u, p], [cs.f_sx])
    xn = rk4_step(lambda tt, xx, k: f(tt, xx, us[k], p), t, x, dt)
    Jx = ca.jacobian(xn, x)
    Jp = ca.jacobian(xn, p)
    dz = ca.horzcat(ca.SX(n, n), *[Jp[:, j] for j in qi]) if q else ca.SX(n, n)
    Sn = ca.mtimes(Jx, S) + dz
    leaves = {TIME: t, **{s: x[i] for i, s in enumerate(system.x)}, **{s: us[0][i] for i, s in enumerate(system.u)},
              **{s: p[i] for i, s in enumerate(system.p)}}
    y = to_casadi(list(exprs), leaves)
    gx = ca.jacobian(y, x)
    gp = ca.jacobian(y, p)
    G = ca.mtimes(gx, S) + (ca.horzcat(ca.SX(len(exprs), n), *[gp[:, j] for j in qi]) if q else 0)
    s = ca.vertcat(x, ca.vec(S))
    a = ca.vertcat(t, *us)
    o = ca.vertcat(y, ca.vec(G.T))   # candidate-major: row c of G, then the next
    return ca.Function("sens_step", [s, a, p], [ca.vertcat(xn, ca.vec(Sn)), o])


def candidate_fisher(system: System, exprs: Sequence[sp.Expr], noise: Sequence[float], *, x0: Sequence[float],
                     t_final: float, dt: float = 1e-3, inputs: Any = None, sample_period: float | None = None,
                     unknown_params: Sequence[str] = (), names: Sequence[str] | None = None, engine: str = "auto",
                     keep_sensitivities: bool = False, sample_every: Sequence[int] | None = None) -> CandidateFisher:
    """The Fisher information of (x(0), unknown parameters) each candidate gives along one noise-free run.

    Parameters
    ----------
    system : System
        The plant, with its parameters at the values of the run (``[simulation] true_parameters``).
    exprs : sequence of sympy.Expr
        What each candidate measures.
    noise : sequence of float
        Each candidate's noise standard deviation (> 0).
    x0 : sequence of float
        The run's initial state.
    t_final, dt : float
        Horizon and RK4 step.
    inputs : mapping, optional
        The known inputs, as for :func:`nlobs.simulate`.
    sample_period : float, optional
        Samples at 0, T, 2T, ... up to t_final; default every RK4 step.
    unknown_params : sequence of str
        Parameters estimated with x(0): columns of the information after the states.
    names : sequence of str, optional
        The candidates' names.
    engine : {"auto", "vm", "c"}
        Where the run is computed (see :func:`nlobs.simulate`).
    keep_sensitivities : bool
        Keep every sample's sensitivity rows (``sensitivities``).
    sample_every : sequence of int, optional
        Each candidate's own rate: it is sampled at every k-th sample of the run (k ≥ 1, one per candidate; its
        information sums over those samples only). Default: every candidate at every sample.

    Returns
    -------
    CandidateFisher

    Raises
    ------
    DataError
        On a bad grid, or a run that blows up.
    """
    from ...engine import run_batch

    noise = np.asarray(noise, dtype=float)
    if noise.shape != (len(exprs),) or not np.all(np.isfinite(noise)) or np.any(noise <= 0):
        raise ModelError(f"candidate_fisher: `noise` must hold one positive standard deviation per candidate ({len(exprs)}), "
                         f"got {noise}")
    bad = [k for k in unknown_params if k not in system.params]
    if bad:
        raise ModelError(f"candidate_fisher: {bad[0]!r} is not a parameter of {system.name!r}")
    x0 = np.asarray(x0, dtype=float).ravel()
    if x0.size != system.n_states or not np.all(np.isfinite(x0)):
        raise DataError(f"candidate_fisher: `x0` must hold {system.n_states} finite numbers, got {x0.size}")
    dt, steps, every, note = _grid(float(t_final), float(dt), sample_period)
    n, q, nc = system.n_states, len(unknown_params), len(exprs)
    m = n + q
    step = _sensitivity_step(system, exprs, list(unknown_params), dt)
    t = np.arange(steps + 1) * dt
    sigs = input_signals(system, inputs, system.params)

    def at(tt: np.ndarray) -> np.ndarray:
        rows = [np.broadcast_to(np.asarray(s(tt), dtype=float), tt.shape) for s in sigs]
        return np.array(rows).reshape(len(sigs), tt.size)

    A = np.vstack([t[None, :], at(t), at(t + dt / 2), at(t + dt)]).T
    s0 = np.concatenate([x0, np.eye(n, m).ravel(order="F")])
    S, O, status = run_batch(step, s0[None, :], A, system.param_values, steps, stride=every, backend=engine)
    if status[0] < steps or not np.all(np.isfinite(O)):
        where = t[min(int(status[0]), steps)]
        raise DataError(f"the [simulation] run of {system.name!r} blows up near t = {where:.4g} (the sensitivities are not "
                        "finite); shorten t_final or change x0")
    O = O[0]
    G = O[:, nc:].reshape(O.shape[0], nc, m)
    if sample_every is None:
        W = np.einsum("kci,kcj->cij", G, G) / (noise ** 2)[:, None, None]
    else:
        k_each = np.asarray(sample_every, dtype=int).reshape(-1)
        if k_each.size != nc or np.any(k_each < 1):
            raise ModelError(f"candidate_fisher: `sample_every` must hold one whole number >= 1 per candidate ({nc}), "
                             f"got {sample_every}")
        taken = (np.arange(G.shape[0])[:, None] % k_each[None, :] == 0).astype(float)
        W = np.einsum("kc,kci,kcj->cij", taken, G, G) / (noise ** 2)[:, None, None]
    method = (f"exact sensitivities of the RK4 steps (dt = {dt:g}) by forward automatic differentiation, "
              f"{O.shape[0]} samples" + (f" every {sample_period:g}" if sample_period else " (every step)")
              + f"; {cite('krener2009')}" + (f"; {note}" if note else ""))
    return CandidateFisher(tuple(names) if names is not None else tuple(f"c{i}" for i in range(nc)),
                           (*system.states, *unknown_params), W, t[::every], dt, S[0][:, :n], O[:, :nc],
                           G if keep_sensitivities else None, method)

