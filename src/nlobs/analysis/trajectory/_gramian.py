r"""Observability along a trajectory: LTV Gramians and the UCO test (Wang, Ortega & Bobtsov (2021)), empirical Gramians,
numerical indistinguishability (Besançon (2010)).

For an LTV pair (A(t), C(t)) — or a state-affine model frozen along a measured input and output —
the observability Gramian (Wang, Ortega & Bobtsov (2021), eq. 3)

.. math::

    W(t_0, t_1) = \int_{t_0}^{t_1} \Phi^\top(\tau, t_0)\, C^\top(\tau) C(\tau)\, \Phi(\tau, t_0)\, d\tau

is integrated together with :math:`\dot\Phi = A\Phi` by RK4 on the time grid. Observability on
[t0, t1] is rank W = n; uniform complete observability (Wang, Ortega & Bobtsov (2021), eq. 4) asks W(t, t+T) ≥ δI for all t,
and :func:`uco_test` reports :math:`\delta(t) = \lambda_{\min} W(t, t+T)` so the user sees where
excitation is lost.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from ...errors import DataError, ModelError, ShapeError
from ...model import StateAffine, System
from .._reports import fmt_directions, fmt_vec
from ...references import cite

__all__ = ["GramianResult", "ltv_gramian", "UCOResult", "uco_test", "state_affine_ltv", "EmpiricalGramian",
           "empirical_gramian", "Indistinguishability", "indistinguishable", "check_timepts"]

#: Default relative threshold λ/λ_max under which a Gramian eigenvalue counts as zero. RK4 with
#: the grid's step integrates a smooth integrand with relative error far below 1e-9 on the grids
#: used here, and round-off in the accumulated sums is ~1e-13 relative, so 1e-9 separates
#: "exactly zero" from "small but present" without hiding weak excitation (report δ for that).
RTOL = 1e-9


def check_timepts(timepts: Any, caller: str, *, uniform: bool = False) -> np.ndarray:
    """A strictly increasing, finite 1-D time grid with at least two points."""
    t = np.asarray(timepts, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ShapeError(f"{caller}: `timepts` must be a 1-D grid with at least 2 times, got shape {t.shape}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise DataError(f"{caller}: `timepts` must be finite and strictly increasing")
    if uniform:
        dt = np.diff(t)
        if np.ptp(dt) > 1e-9 * max(1.0, abs(dt.mean())):
            raise DataError(f"{caller}: the sliding-window test needs a uniform grid; the steps of `timepts` range over "
                            f"[{dt.min():.3g}, {dt.max():.3g}]. Resample on a uniform grid.")
    return t


def _matrix_path(M: Any, t: np.ndarray, rows: int | None, cols: int, name: str, caller: str) -> tuple[np.ndarray, np.ndarray]:
    """Values of a matrix signal at the grid points and at the midpoints (shapes (N, r, c), (N-1, r, c))."""
    mid = (t[:-1] + t[1:]) / 2
    if callable(M):
        try:
            vals = np.array([np.atleast_2d(np.asarray(M(tt), dtype=float)) for tt in t])
            mids = np.array([np.atleast_2d(np.asarray(M(tt), dtype=float)) for tt in mid])
        except (TypeError, ValueError) as e:
            raise ShapeError(f"{caller}: `{name}(t)` must return a numeric matrix: {e}") from None
    else:
        arr = np.asarray(M, dtype=float)
        if arr.ndim <= 2:
            arr2 = np.atleast_2d(arr)
            vals = np.broadcast_to(arr2, (t.size, *arr2.shape)).copy()
        elif arr.ndim == 3:
            if arr.shape[0] != t.size:
                raise ShapeError(f"{caller}: `{name}` is sampled at {arr.shape[0]} times but the grid `timepts` has {t.size}; "
                                 "give one matrix per grid time")
            vals = arr
        else:
            raise ShapeError(f"{caller}: `{name}` must be a matrix, a callable of t, or an array of shape (N, rows, cols)")
        mids = (vals[:-1] + vals[1:]) / 2
    want_r = rows if rows is not None else vals.shape[1]
    if vals.shape[1:] != (want_r, cols):
        raise ShapeError(f"{caller}: incompatible dimensions of `{name}`: expected ({want_r}, {cols}), found {vals.shape[1:]}")
    if not (np.all(np.isfinite(vals)) and np.all(np.isfinite(mids))):
        bad = int(np.flatnonzero(~np.isfinite(vals).all(axis=(1, 2)))[0]) if not np.all(np.isfinite(vals)) else 0
        raise DataError(f"{caller}: `{name}` has non-finite entries (first at t = {t[bad]:g})")
    return vals, mids


def _pair_paths(A: Any, C: Any, t: np.ndarray, caller: str) -> tuple[np.ndarray, ...]:
    A0 = A(t[0]) if callable(A) else np.asarray(A, dtype=float)
    A0 = np.asarray(A0, dtype=float)
    shape = A0.shape[-2:] if A0.ndim >= 2 else A0.shape
    if len(shape) != 2 or shape[0] != shape[1]:
        raise ShapeError(f"{caller}: `A` must be square, found shape {tuple(shape)}")
    n = shape[0]
    Av, Am = _matrix_path(A, t, n, n, "A", caller)
    Cv, Cm = _matrix_path(C, t, None, n, "C", caller)
    return Av, Am, Cv, Cm


def _integrate(Av: np.ndarray, Am: np.ndarray, Cv: np.ndarray, Cm: np.ndarray, dt: np.ndarray,
               starts: np.ndarray, L: int) -> np.ndarray:
    """W(t_s, t_{s+j}) for j = 0..L, batched over the start indices `starts`; shape (L+1, K, n, n)."""
    K, n = starts.size, Av.shape[1]
    Phi = np.broadcast_to(np.eye(n), (K, n, n)).copy()
    W = np.zeros((K, n, n))
    out = np.empty((L + 1, K, n, n))
    out[0] = W
    CtC_v = np.einsum("kpi,kpj->kij", Cv, Cv)
    CtC_m = np.einsum("kpi,kpj->kij", Cm, Cm)

    def rhs(A: np.ndarray, Q: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return A @ P, np.swapaxes(P, 1, 2) @ Q @ P

    for j in range(L):
        idx = starts + j
        h = dt[idx][:, None, None]
        A0, A1, Ah = Av[idx], Av[idx + 1], Am[idx]
        Q0, Q1, Qh = CtC_v[idx], CtC_v[idx + 1], CtC_m[idx]
        k1p, k1w = rhs(A0, Q0, Phi)
        k2p, k2w = rhs(Ah, Qh, Phi + h / 2 * k1p)
        k3p, k3w = rhs(Ah, Qh, Phi + h / 2 * k2p)
        k4p, k4w = rhs(A1, Q1, Phi + h * k3p)
        Phi = Phi + h / 6 * (k1p + 2 * k2p + 2 * k3p + k4p)
        W = W + h / 6 * (k1w + 2 * k2w + 2 * k3w + k4w)
        out[j + 1] = W
    return out


def _sym_eig(W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.linalg.eigh((W + W.T) / 2)


@dataclass(frozen=True, eq=False)
class GramianResult:
    r"""Observability Gramian :math:`W(t_0, t_1)` of an LTV pair (Wang, Ortega & Bobtsov (2021), eq. 3) and its rank test.

    Attributes
    ----------
    W : numpy.ndarray of shape (n, n)
        W(t0, t1) over the whole grid.
    timepts : numpy.ndarray
    W_path : numpy.ndarray of shape (N, n, n)
        W(t0, t) at every grid time (when the rank becomes full).
    eigenvalues : numpy.ndarray
        Eigenvalues of W, ascending.
    rank : int
        Number of eigenvalues above ``rtol * max``.
    observable : bool
        rank = n: the LTV system is observable on [t0, t1] (Wang, Ortega & Bobtsov (2021), Prop. 1's assumption).
    unobservable_directions : numpy.ndarray
        Eigenvectors of the eigenvalues counted as zero.
    t_full_rank : float or None
        First grid time at which W(t0, t) has full rank.
    """

    W: np.ndarray
    timepts: np.ndarray
    W_path: np.ndarray
    eigenvalues: np.ndarray
    rank: int
    observable: bool
    unobservable_directions: np.ndarray
    t_full_rank: float | None
    rtol: float

    @property
    def evidence(self) -> str:
        """What kind of evidence the rank verdict is: a floating-point Gramian on the time grid, with a threshold."""
        return (f"floating point: Gramian by quadrature on {self.timepts.size} grid points; eigenvalues of the Jacobi-scaled W "
                f"below {self.rtol:g}·λ_max count as zero (a threshold, not a proof)")

    def __str__(self) -> str:
        n = self.W.shape[0]
        t0, t1 = self.timepts[0], self.timepts[-1]
        if self.observable:
            return (f"observable on [{t0:g}, {t1:g}]: rank W = {n}; λ_min(W) = {self.eigenvalues[0]:.4g}, "
                    f"λ_max(W) = {self.eigenvalues[-1]:.4g}; full rank from t = {self.t_full_rank:g} ({cite('000')} eq. 3)")
        dirs = fmt_directions(self.unobservable_directions)
        return (f"NOT observable on [{t0:g}, {t1:g}]: rank W = {self.rank} < {n} (eigenvalues of the Jacobi-scaled W below "
                f"{self.rtol:g}·λ_max count as zero); unobservable direction(s) {dirs}")


def _rank_of(W: np.ndarray, rtol: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Eigenvalues of W, a basis of its numerical kernel (columns of V beyond the rank), and the rank.

    The rank is decided on the Jacobi-scaled Gramian S = D^-½ W D^-½ (D = diag W): a congruence
    with a positive diagonal keeps the rank and the kernel (ker W = D^-½ ker S), and removes the
    effect of units and magnitudes, so that one relative threshold `rtol` is meaningful (the
    augmented systems of Viegas, Batista, Oliveira & Silvestre (2015) mix positions and products of positions, with diagonal entries
    spanning ten orders of magnitude).
    """
    lam = np.linalg.eigvalsh((W + W.T) / 2)
    d = np.sqrt(np.clip(np.diag(W), 0.0, None))
    d[d == 0] = 1.0
    S = W / np.outer(d, d)
    mu, U = np.linalg.eigh((S + S.T) / 2)
    top = max(mu[-1], 0.0)
    zero = mu <= rtol * top if top > 0 else np.ones_like(mu, dtype=bool)
    rank = int(np.sum(~zero))
    K = U[:, zero] / d[:, None]
    K = K / np.linalg.norm(K, axis=0, keepdims=True) if K.size else K
    if K.shape[1] > 1:
        K, _ = np.linalg.qr(K)
    V = np.hstack([K, np.zeros((W.shape[0], W.shape[0] - K.shape[1]))])
    return lam, V, rank


def ltv_gramian(A: Any, C: Any, timepts: Any, *, rtol: float = RTOL) -> GramianResult:
    r"""The observability Gramian W(t0, t1) of :math:`\dot x = A(t)x`, :math:`y = C(t)x` (Wang, Ortega & Bobtsov (2021), eq. 3).

    Parameters
    ----------
    A : (n, n) matrix, callable t -> (n, n), or array of shape (N, n, n) sampled on `timepts`
    C : (p, n) matrix, callable t -> (p, n), or array of shape (N, p, n); y = C x
    timepts : array_like of shape (N,)
        Strictly increasing grid; [t0, t1] = [timepts[0], timepts[-1]]. Sampled A and C are
        interpolated linearly between grid points (RK4 midpoints).

    Other Parameters
    ----------------
    rtol : float
        Eigenvalues below ``rtol * λ_max`` count as zero (see :data:`RTOL`).

    Returns
    -------
    GramianResult

    Raises
    ------
    ShapeError
        If A is not square, C does not have n columns, or a sampled matrix has another length than the grid.
    DataError
        If the grid is not increasing or a matrix has non-finite entries.

    References
    ----------
    Wang, Ortega & Bobtsov (2021), eq. (3) and Proposition 1 (rank W(0, T) = n).
    """
    t = check_timepts(timepts, "ltv_gramian")
    Av, Am, Cv, Cm = _pair_paths(A, C, t, "ltv_gramian")
    path = _integrate(Av, Am, Cv, Cm, np.diff(t), np.array([0]), t.size - 1)[:, 0]
    W = (path[-1] + path[-1].T) / 2
    lam, V, rank = _rank_of(W, rtol)
    n = W.shape[0]
    kernel = V[:, : n - rank].T.copy()
    t_full = None
    if rank == n:
        for k in range(1, t.size):
            if _rank_of(path[k], rtol)[2] == n:
                t_full = float(t[k])
                break
    return GramianResult(W, t, path, lam, rank, rank == n, kernel, t_full, rtol)


@dataclass(frozen=True, eq=False)
class UCOResult:
    r"""Sliding-window Gramian test of uniform complete observability (Wang, Ortega & Bobtsov (2021), eq. 4).

    Attributes
    ----------
    starts : numpy.ndarray
        Window start times t.
    delta : numpy.ndarray
        :math:`\delta(t) = \lambda_{\min} W(t, t + T)` for each start.
    window : float
        T.
    threshold : float
        The δ asked for (or, if none was given, ``ratio * max δ``).
    uniform : bool
        δ(t) ≥ threshold for every window on the grid (a finite-horizon check of eq. 4).
    worst_start : float
        The window start with the smallest δ.
    """

    starts: np.ndarray
    delta: np.ndarray
    window: float
    threshold: float
    uniform: bool
    worst_start: float
    given_threshold: bool

    @property
    def evidence(self) -> str:
        """What kind of evidence the verdict is: a finite-horizon check on a grid of windows against a threshold
        (a heuristic one, 1e-3 of the largest δ, unless δ was given)."""
        thr = "the δ given" if self.given_threshold else "a heuristic threshold (1e-3 of the largest δ on the grid)"
        return (f"floating point: {self.starts.size} windows on a finite horizon compared with {thr}; uniformity beyond the "
                "horizon is not checked")

    def __str__(self) -> str:
        head = (f"UCO test with T = {self.window:g} on {self.starts.size} windows from t = {self.starts[0]:g} to "
                f"{self.starts[-1]:g}: δ(t) = λ_min W(t, t+T) ranges over [{self.delta.min():.3g}, {self.delta.max():.3g}]")
        how = f"δ = {self.threshold:.3g}" if self.given_threshold else f"{self.threshold:.3g} (1e-3 of its maximum)"
        if self.uniform:
            return (head + f"; W(t, t+T) ≥ {how}·I on every window: uniformly observable on this horizon ({cite('000')} eq. 4)"
                    + ("" if self.given_threshold else "; heuristic threshold"))
        first = float(self.starts[np.argmax(self.delta < self.threshold)])
        return (head + f"; NOT uniformly observable: δ(t) falls below {how} from t = {first:g} on "
                f"(smallest at t = {self.worst_start:g}): excitation is lost ({cite('000')} eq. 4)"
                + ("" if self.given_threshold else "; heuristic threshold"))


def uco_test(A: Any, C: Any, timepts: Any, window: float, *, delta: float | None = None, stride: int = 1,
             ratio: float = 1e-3) -> UCOResult:
    r"""δ(t) = λ_min W(t, t+T) on a uniform grid: the UCO condition W(t, t+T) ≥ δI (Wang, Ortega & Bobtsov (2021), eq. 4).

    Parameters
    ----------
    A, C : as for :func:`ltv_gramian`
    timepts : array_like
        A uniform grid; windows start at every `stride`-th point whose window fits in the grid.
    window : float
        T, the window length (a multiple of the grid step, rounded).
    delta : float, optional
        The δ to check. Without it the verdict asks δ(t) ≥ ``ratio`` · max δ on the horizon.

    Returns
    -------
    UCOResult

    Raises
    ------
    ShapeError, DataError
        As for :func:`ltv_gramian`; also a window longer than the grid or a non-uniform grid.

    References
    ----------
    Wang, Ortega & Bobtsov (2021), eq. (4); Besançon (2010) "Regularly persistent inputs"
    (the same integral for state-affine systems).
    """
    t = check_timepts(timepts, "uco_test", uniform=True)
    dt = float(t[1] - t[0])
    if not np.isfinite(window) or window <= 0:
        raise DataError(f"uco_test: `window` must be positive and finite, got {window}")
    L = int(round(window / dt))
    if L < 1 or L >= t.size:
        raise DataError(f"uco_test: the window T = {window:g} needs {L} steps but the grid has only {t.size - 1}; "
                        "shorten the window or extend the grid")
    if stride < 1:
        raise DataError(f"uco_test: `stride` must be >= 1, got {stride}")
    Av, Am, Cv, Cm = _pair_paths(A, C, t, "uco_test")
    starts = np.arange(0, t.size - L, stride)
    W = _integrate(Av, Am, Cv, Cm, np.diff(t), starts, L)[-1]
    d = np.array([_sym_eig(w)[0][0] for w in W])
    thr = float(delta) if delta is not None else ratio * float(d.max())
    return UCOResult(t[starts], d, L * dt, thr, bool(np.all(d >= thr)), float(t[starts][np.argmin(d)]), delta is not None)


def _signal(values: Any, t: np.ndarray, width: int, name: str, caller: str) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, None] if width == 1 else arr[None, :]
    if arr.shape[0] != t.size:
        raise ShapeError(f"{caller}: the trajectory `{name}` has {arr.shape[0]} samples but the time grid has {t.size}; "
                         "give one sample per grid time")
    if arr.shape[1] != width:
        raise ShapeError(f"{caller}: `{name}` must have {width} column(s), found {arr.shape[1]}")
    if not np.all(np.isfinite(arr)):
        k = int(np.flatnonzero(~np.isfinite(arr).all(axis=1))[0])
        raise DataError(f"{caller}: `{name}` is not finite at t = {t[k]:g} (row {k})")
    return arr


def state_affine_ltv(model: StateAffine, timepts: Any, *, u: Any = None, y: Any = None) -> tuple[np.ndarray, np.ndarray]:
    r"""Freeze a state-affine model (Wang, Ortega & Bobtsov (2021), eq. 1) along measured u(t), y(t): A(t) = A(u, y, t), C(t) = C(u, t)ᵀ.

    Returns the sampled A of shape (N, n, n) and C of shape (N, p, n) (y = C(t) x) for
    :func:`ltv_gramian` and :func:`uco_test`.

    Parameters
    ----------
    model : StateAffine
    timepts : array_like of shape (N,)
    u : array_like of shape (N, m), optional
        Measured inputs on the grid (default zero).
    y : array_like of shape (N, p), optional
        Measured outputs on the grid (needed when A or b depends on y).

    Raises
    ------
    ShapeError
        If a trajectory has another number of samples than the grid, or the wrong number of columns.
    """
    from ...model import TIME, symbol
    from ...model._translate import NUMPY, translate

    caller = "state_affine_ltv"
    t = check_timepts(timepts, caller)
    leaves: dict[sp.Symbol, Any] = {TIME: t}
    if model.inputs:
        U = _signal(u if u is not None else np.zeros((t.size, len(model.inputs))), t, len(model.inputs), "u", caller)
        leaves.update({symbol(k): U[:, i] for i, k in enumerate(model.inputs)})
    if y is not None or any(model.A.has(symbol(k)) for k in model.outputs) or any(model.b.has(symbol(k)) for k in model.outputs):
        if y is None:
            raise ShapeError(f"{caller}: A depends on the outputs {', '.join(model.outputs)}; give their trajectory `y`")
        Y = _signal(y, t, len(model.outputs), "y", caller)
        leaves.update({symbol(k): Y[:, i] for i, k in enumerate(model.outputs)})
    pv = {symbol(k): v for k, v in model.params.items()}
    n, p = model.n_states, len(model.outputs)

    def sample(Mx: sp.Matrix) -> np.ndarray:
        out = np.empty((t.size, *Mx.shape))
        for (i, j), e in np.ndenumerate(np.array(Mx.xreplace(pv), dtype=object)):
            out[:, i, j] = np.broadcast_to(np.asarray(translate(e, leaves, NUMPY), dtype=float), t.shape)
        return out

    return sample(model.A), np.swapaxes(sample(model.C), 1, 2).reshape(t.size, p, n)


# ----------------------------------------------------------------------------------------------
# nonlinear: simulation-based
# ----------------------------------------------------------------------------------------------
def _simulator(system: System, t_final: float, dt: float, inputs: Any, params: Mapping[str, float] | None, caller: str,
               with_inputs: bool = False) -> tuple[Any, ...]:
    """CasADi functions x0 -> output samples (N+1, p) and their sensitivity, by RK4, plus the grid
    (and the input samples (N+1, m) when `with_inputs`)."""
    import casadi as ca

    from ...engine import compile_system, rk4_step
    from ...model import input_signals

    if not (np.isfinite(t_final) and t_final > 0 and np.isfinite(dt) and 0 < dt <= t_final):
        raise DataError(f"{caller}: need 0 < dt <= t_final (finite), got dt = {dt}, t_final = {t_final}")
    N = int(round(t_final / dt))
    t = np.linspace(0.0, N * dt, N + 1)
    sys_ = system.with_params(**params) if params else system
    sigs = input_signals(sys_, inputs, sys_.params)
    U0 = np.array([s(t[:-1]) for s in sigs]).reshape(len(sigs), N)
    Um = np.array([s(t[:-1] + dt / 2) for s in sigs]).reshape(len(sigs), N)
    U1 = np.array([s(t[1:]) for s in sigs]).reshape(len(sigs), N)
    f, h = compile_system(sys_).bind()
    x = ca.SX.sym("x", system.n_states)
    tk = ca.SX.sym("t")
    us = [ca.SX.sym(f"u{i}", system.n_inputs) for i in range(3)]
    step = ca.Function("step", [x, ca.vertcat(tk, *us)], [rk4_step(lambda tt, s, k: f(tt, s, us[k]), tk, x, dt)])
    acc = step.mapaccum("acc", N)
    x0 = ca.MX.sym("x0", system.n_states)
    data = np.vstack([t[:-1], U0, Um, U1])
    X = ca.horzcat(x0, acc(x0, ca.DM(data)))  # (n, N+1)
    T = ca.DM(t).T
    Uall = ca.DM(np.hstack([U0, U1[:, -1:]]))
    hmap = h.map(N + 1)
    Y = hmap(T, X, Uall)  # (p, N+1)
    out = (ca.Function("sim", [x0], [Y.T]), ca.Function("sens", [x0], [ca.jacobian(ca.vec(Y.T), x0)]), t)
    return (*out, np.array(Uall).T.reshape(t.size, system.n_inputs)) if with_inputs else out


@dataclass(frozen=True, eq=False)
class EmpiricalGramian:
    r"""Observability Gramian of a nonlinear model along one trajectory.

    :math:`W = \int_0^{T} S(t)^\top S(t)\,dt` with :math:`S = \partial y(t)/\partial x_0` (the
    sensitivity of the output to the initial state, by automatic differentiation through the RK4
    steps), or its central-difference approximation (the classic empirical Gramian).
    """

    W: np.ndarray
    eigenvalues: np.ndarray
    rank: int
    observable: bool
    unobservable_directions: np.ndarray
    states: tuple[str, ...]
    method: str
    rtol: float

    def __str__(self) -> str:
        n = self.W.shape[0]
        cond = self.eigenvalues[-1] / self.eigenvalues[0] if self.eigenvalues[0] > 0 else np.inf
        if self.observable:
            return (f"observable along this trajectory: empirical Gramian of rank {n}, eigenvalues "
                    f"[{self.eigenvalues[0]:.3g} .. {self.eigenvalues[-1]:.3g}] (condition {cond:.3g}); {self.method}")
        dirs = fmt_directions(self.unobservable_directions)
        return (f"NOT observable along this trajectory: empirical Gramian rank {self.rank} < {n}; unobservable "
                f"direction(s) in ({', '.join(self.states)}): {dirs}; {self.method}")


def empirical_gramian(system: System, x0: Any, *, t_final: float, dt: float = 1e-2, inputs: Any = None,
                      params: Mapping[str, float] | None = None, method: str = "sensitivity", eps: float = 1e-4,
                      rtol: float = RTOL) -> EmpiricalGramian:
    r"""Observability Gramian of a nonlinear model along the trajectory from `x0` under `inputs`.

    .. math::

        W = \int_0^{T} \Big(\frac{\partial y(t)}{\partial x_0}\Big)^\top \frac{\partial y(t)}{\partial x_0}\, dt
        \quad\text{or}\quad
        W_{ij} = \frac{1}{4\varepsilon^2}\int_0^T (y^{+i} - y^{-i})^\top (y^{+j} - y^{-j})\, dt .

    A rank-deficient W means two nearby initial states give (to first order) the same output under
    this input: the input is singular for this trajectory (Besançon (2010), "Universal input").

    Parameters
    ----------
    system : System
    x0 : array_like of shape (n,)
    t_final : float
    dt : float
        RK4 step (also the output sampling; trapezoidal rule for the integral).
    inputs : signal-like or mapping, optional
        As for :func:`nlobs.simulate` (numbers, expressions of t, callables); default zero.
    params : mapping of str to float, optional
        Parameter values overriding the model's.
    method : {"sensitivity", "difference"}
        Exact sensitivities by automatic differentiation (default), or central differences with `eps`.
    eps : float
        Perturbation of the central differences.
    rtol : float
        Rank threshold on the Jacobi-scaled Gramian (see :data:`RTOL`).

    Returns
    -------
    EmpiricalGramian

    Raises
    ------
    ShapeError, DataError, ModelError
        On a wrong x0 length, a bad grid, or an unknown input name.

    References
    ----------
    Besançon (2010) "Universal input", "Regularly persistent inputs" (the output-difference
    integral); Wang, Ortega & Bobtsov (2021), eq. (3) (the linear case, of which this is the linearisation).
    """
    caller = "empirical_gramian"
    x0 = np.asarray(x0, dtype=float).ravel()
    if x0.size != system.n_states or not np.all(np.isfinite(x0)):
        raise ShapeError(f"{caller}: `x0` must hold {system.n_states} finite numbers, got {x0.size}")
    if method not in ("sensitivity", "difference"):
        raise ModelError(f"{caller}: `method` must be 'sensitivity' or 'difference', got {method!r}")
    sim, sens, t = _simulator(system, t_final, dt, inputs, params, caller)
    n, p = system.n_states, system.n_outputs
    w = np.full(t.size, dt)
    w[[0, -1]] = dt / 2
    if method == "sensitivity":
        S = np.array(sens(x0)).reshape(p, t.size, n)  # vec of (N+1, p) is column-major: output-major
        W = np.einsum("k,pki,pkj->ij", w, S, S)
        how = "exact output sensitivities ∂y/∂x0 (AD through RK4)"
    else:
        D = []
        for i in range(n):
            e = np.zeros(n)
            e[i] = eps
            D.append((np.array(sim(x0 + e)) - np.array(sim(x0 - e))) / (2 * eps))
        D = np.array(D)  # (n, N+1, p)
        W = np.einsum("k,ikp,jkp->ij", w, D, D)
        how = f"central differences with ε = {eps:g}"
    if not np.all(np.isfinite(W)):
        raise DataError(f"{caller}: the trajectory from x0 = {x0} blew up before t = {t_final:g}; shorten the horizon")
    lam, V, rank = _rank_of(W, rtol)
    return EmpiricalGramian(W, lam, rank, rank == n, V[:, : n - rank].T.copy(), system.states, how, rtol)


@dataclass(frozen=True, eq=False)
class Indistinguishability:
    r"""Output distance of two initial states under the same input (Besançon (2010), "Indistinguishability")."""

    x0_a: np.ndarray
    x0_b: np.ndarray
    max_difference: float
    l2_distance: float
    tolerance: float
    indistinguishable: bool
    t_final: float

    def __str__(self) -> str:
        verdict = "indistinguishable" if self.indistinguishable else "distinguishable"
        return (f"x0 = {fmt_vec(self.x0_a)} and {fmt_vec(self.x0_b)} are {verdict} on [0, {self.t_final:g}]: "
                f"max |y_a - y_b| = {self.max_difference:.3g} (tolerance {self.tolerance:.3g}), "
                f"(∫|y_a - y_b|²)^½ = {self.l2_distance:.3g}")


def indistinguishable(system: System, x0_a: Any, x0_b: Any, *, t_final: float, dt: float = 1e-2, inputs: Any = None,
                      params: Mapping[str, float] | None = None, rtol: float = 1e-6, atol: float = 1e-9) -> Indistinguishability:
    r"""Do two initial states give the same output under the same input? (numerically, on [0, T])

    The pair is reported indistinguishable when
    :math:`\max_t |y_a(t) - y_b(t)| \le \text{atol} + \text{rtol}\,\max_t |y_a(t)|` (RK4 with the same
    step on both trajectories; the default tolerances sit well above its round-off).

    Parameters
    ----------
    system : System
    x0_a, x0_b : array_like of shape (n,)
        The two initial states.
    t_final : float
    dt : float
        RK4 step and output sampling.
    inputs : signal-like or mapping, optional
        The common known input (default zero).
    params : mapping of str to float, optional
        Parameter values overriding the model's.
    rtol, atol : float
        Tolerances of the verdict.

    Returns
    -------
    Indistinguishability

    References
    ----------
    Besançon (2010) "Indistinguishability": h(χ_u(t, x0)) = h(χ_u(t, x0')) for all t.
    """
    caller = "indistinguishable"
    xa = np.asarray(x0_a, dtype=float).ravel()
    xb = np.asarray(x0_b, dtype=float).ravel()
    for name, v in (("x0_a", xa), ("x0_b", xb)):
        if v.size != system.n_states or not np.all(np.isfinite(v)):
            raise ShapeError(f"{caller}: `{name}` must hold {system.n_states} finite numbers, got {v.size}")
    sim, _, t = _simulator(system, t_final, dt, inputs, params, caller)
    ya, yb = np.array(sim(xa)), np.array(sim(xb))
    if not (np.all(np.isfinite(ya)) and np.all(np.isfinite(yb))):
        raise DataError(f"{caller}: a trajectory blew up before t = {t_final:g}; shorten the horizon")
    d = np.abs(ya - yb)
    tol = atol + rtol * float(np.abs(ya).max(initial=0.0))
    w = np.full(t.size, dt)
    w[[0, -1]] = dt / 2
    l2 = float(np.sqrt(np.sum(w[:, None] * d**2)))
    return Indistinguishability(xa, xb, float(d.max()), l2, tol, bool(d.max() <= tol), float(t[-1]))

