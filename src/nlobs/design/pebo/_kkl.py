r"""A KKL observer without a closed-form φ: the left inverse learned from simulated data.

Beyond Yi, Ortega & Zhang (2019), Proposition 1, which needs φ and φ^L in closed form. Andrieu and Praly (Yi, Ortega & Zhang (2019), ref. [1])
show that for an autonomous system observable in a backward-distinguishable sense, with
:math:`n_\xi = (n + 1)p` and :math:`\Lambda` diagonal with distinct negative eigenvalues (each
output driving n + 1 filters :math:`\dot\xi = \Lambda\xi + By`, B = ones), the map φ solving the
PDE :math:`\nabla\phi^\top f = \Lambda\phi + Bh` exists and is injective (for Λ fast enough),
so a left inverse exists. It is not needed in closed form: simulating (x, ξ) from sampled
initial states and discarding the transient of ξ (it forgets ξ(0) like :math:`e^{\Lambda t}`)
gives pairs (ξ, y) → x on the manifold ξ = φ(x), and φ^L is fitted by regression — here
polynomial features of the normalised (ξ, y) and ridge least squares (NumPy only). The fit error
is measured on held-out trajectories.

References
----------
Yi, Ortega & Zhang (2019), Proposition 1 and ref. [1] (Andrieu & Praly, SIAM J. Control Optim. 45,
2006); learning φ^L from simulated data as in Ramos, Bernard, Pinto et al. (IFAC 2020) and
Buisson-Fenet, Bahr, Di Meglio (2022), here without a neural network.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ...algebra._modular import monomial_exponents
from ...engine import compile_system, rk4_step
from ...errors import PreconditionError, ShapeError
from ...model import System
from ...model._expr import as_written
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign
from .._kind import Tuning, kind
from ._regression import StateStack

__all__ = ["design_kkl_learned"]

REF = (f"{cite('004')} Proposition 1 (KKL observer), ref. [1] {cite('andrieu2006')} (n_ξ = (n+1)p, existence "
       "and injectivity of φ); φ^L learned by polynomial ridge regression on simulated (ξ, y) → x pairs")


def _features(V: Any, exps: list[tuple[int, ...]], lib: Any) -> Any:
    """Monomials of the columns of V (NumPy rows, or a CasADi column with lib=ca)."""
    if lib is np:
        return np.stack([np.prod(V ** np.array(e), axis=1) for e in exps], axis=1)
    cols = []
    for e in exps:
        term = ca.SX(1)
        for i, k in enumerate(e):
            if k:
                term = term * V[i] ** k
        cols.append(term)
    return ca.vertcat(*cols)


#: The most polynomial features the learned inverse fits (a dense normal matrix of this size is solved).
MAX_FEATURES = 2000


def _max_degree(n_vars: int, cap: int = 3) -> int:
    """The largest polynomial degree ≤ `cap` whose monomials in `n_vars` variables stay within MAX_FEATURES (0: none)."""
    return max((d for d in range(1, cap + 1) if math.comb(n_vars + d, d) <= MAX_FEATURES), default=0)


def _training_runs(f: ca.Function, h: ca.Function, uv: ca.DM, Lam: np.ndarray, Bm: np.ndarray, box: np.ndarray, *,
                   dt: float, steps: int, burn: float, count: int, seed: int) -> np.ndarray:
    """(x, ξ) along `count` runs from random points of `box` (RK4, step `dt`), every 0.05 s after `burn`:
    shape (frames, n + n_ξ, count); a run that escapes (|s| ≥ 1e8 or not finite) is NaN from then on."""
    n, n_xi = box.shape[0], Lam.shape[0]
    s = ca.SX.sym("s", n + n_xi)

    def rhs(t: Any, S: Any, _k: int) -> Any:
        x, xi = S[:n], S[n:]
        return ca.vertcat(f(t, x, uv), ca.DM(Lam) @ xi + ca.DM(Bm) @ h(t, x, uv))

    step = ca.Function("kkl_train_step", [s], [rk4_step(rhs, 0.0, s, dt)])   # autonomous: t enters only through f, h
    rng = np.random.default_rng(seed)
    x0 = box[:, 0] + (box[:, 1] - box[:, 0]) * rng.random((count, n))
    S = np.vstack([x0.T, np.zeros((n_xi, count))])
    stride = max(1, int(round(0.05 / dt)))
    first = int(np.ceil(burn / dt))
    batch = step.map(count)
    frames = []
    with np.errstate(all="ignore"):
        for k in range(1, steps + 1):
            S = np.asarray(batch(S))
            S[:, ~np.all(np.isfinite(S) & (np.abs(S) < 1e8), axis=0)] = np.nan
            if k >= first and (k - first) % stride == 0:
                frames.append(S.copy())
    return np.stack(frames)


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def tune_kkl_learned(ctx: Any) -> Tuning:
    if not ctx.region:
        return Tuning.needs("`region` (a box of initial states): add [simulation] x0")
    sc = ctx.scenario
    consts: dict[str, float] = {}
    for k in ctx.system.inputs:
        v = sc.inputs.get(k, 0.0) if sc is not None else 0.0
        try:
            val = float(v)
        except (TypeError, ValueError):
            expr = v if isinstance(v, sp.Basic) else None
            if expr is not None and not expr.free_symbols:
                val = float(expr)
            else:
                return Tuning.fails(f"learns φᴸ for constant inputs only; the run drives {k} = {as_written(v)} (time-varying). Use kkl "
                              "with a φ "
                              "that holds for every input, or a constant input")
        consts[k] = val
    box = [list(ctx.region[s]) for s in ctx.system.states]
    # Λ on the observer's time scale: the data start after the ξ transient (16/min|λ|) and cover ~10 plant time constants
    lam = [float(f"{-ctx.omega_o * (1 + k / ctx.n):.6g}") for k in range(ctx.n + 1)]
    t_final = 16.0 / ctx.omega_o + 10.0 / ctx.omega_p
    # RK4 at 5 % of the fastest rate (ξ's, which is faster than the plant's: |λ| ≥ 2ω_o = 6ω_p): about 1,800 steps
    # whatever the run's own dt (which the comparison needs, not the training data; a slow model on a fine dt would
    # otherwise integrate tens of thousands of steps here)
    dt = 0.05 / abs(lam[-1])
    t_final = float(f"{max(t_final, 20 * dt):.6g}")
    dt = t_final / max(1, round(t_final / dt))
    n_vars = (ctx.n + 1) * len(ctx.system.outputs) + len(ctx.system.outputs)   # (ξ, y)
    degree = _max_degree(n_vars)
    if not degree:
        return Tuning.fails(f"learning φᴸ needs more than {MAX_FEATURES:,} polynomial features even at degree 1 ((ξ, y) has {n_vars} "
                      "entries for this many states and outputs); not tried")
    opts: dict[str, Any] = {"region": box, "eigenvalues": lam, "n_trajectories": 40, "t_final": t_final, "dt": dt,
                            "degree": degree}
    if consts:
        opts["inputs"] = consts
    return Tuning.tuned(opts, f"φᴸ learned by least squares on 40 simulated runs from the visited box (polynomial features of "
                    f"degree {degree}), Λ = −ω_o·diag(1, ..., 2); valid inside the box")


@kind('kkl_learned', summary='KKL observer with a left inverse learned from simulated runs',
      references=(work("andrieu2006", "KKL with a learned inverse"),), tune=tune_kkl_learned)
def design_kkl_learned(system: System, *, region: Sequence[Sequence[float]], eigenvalues: Sequence[float] | None = None,
                       degree: int = 3, n_trajectories: int = 60, t_final: float = 30.0, dt: float = 0.01,
                       burn_in: float | None = None, held_out: float = 0.25, ridge: float = 1e-8,
                       inputs: Mapping[str, float] | None = None, seed: int = 0, xhat0: Any = None) -> ObserverDesign:
    r"""KKL observer with a learned left inverse (beyond Yi, Ortega & Zhang (2019), Proposition 1).

    .. math::

        \dot\xi = \Lambda\xi + B y, \qquad \hat x = \hat\phi^L(\xi, y) = W^\top m\Big(\frac{(\xi, y) - \mu}{\sigma}\Big),

    with :math:`\Lambda = \operatorname{diag}(\lambda_1, \dots, \lambda_{n+1})` per output (Andrieu-Praly
    dimension :math:`n_\xi = (n + 1)p`), B the ones vector per output, m the monomials of degree
    ≤ `degree`, and W by ridge least squares on pairs sampled from `n_trajectories` simulated
    runs (initial states uniform in `region`, ξ(0) = 0, samples after `burn_in`).

    Parameters
    ----------
    system : System
        Autonomous (or with inputs held at the constant values `inputs`; the learned map is
        then valid for those values only).
    region : sequence of (low, high) pairs
        A box of initial states, one pair per state.
    eigenvalues : sequence of float, optional
        λ_1..λ_{n+1} < 0, distinct (default -1, -2, ..., -(n+1)); the same for every output.
    degree : int
        Degree of the polynomial features.
    n_trajectories : int
        Simulated trajectories (a fraction `held_out` of them is kept for the fit error).
    t_final, dt : float
        Horizon and RK4 step of each simulated trajectory.
    burn_in : float, optional
        Samples before this time are discarded (default 16 / min|λ|, when
        :math:`e^{\lambda t}` < 1.2e-7: the transient of ξ left in the data is a floor for the fit error).
    held_out : float
        Fraction of trajectories held out, in (0, 1).
    ridge : float
        Ridge regularisation (relative to the trace of the normal matrix).
    inputs : mapping of input name to float, optional
        Constant inputs for the training runs (required when the model has inputs).
    seed : int
        Seed of the sampled initial states (the design is deterministic for a seed).
    xhat0 : array_like, optional
        Default initial estimate; the observer starts from ξ(0) = 0.

    Returns
    -------
    ObserverDesign
        The certificate reports the held-out RMS fit error per state, its ratio to the spread of
        each state, and how many trajectories were dropped (escaped).

    Raises
    ------
    PreconditionError
        For a wrong region, positive or repeated eigenvalues, missing inputs, too few
        trajectories left after dropping escapes, or a rank-deficient feature matrix.
    """
    caller = "design_kkl_learned"
    if not isinstance(system, System):
        raise TypeError(f"{caller}: expected a System, got {type(system).__name__}")
    n, p = system.n_states, system.n_outputs
    if p == 0:
        raise PreconditionError(f"{caller}: the model has no output")
    box = np.asarray(region, dtype=float)
    if box.shape != (n, 2) or not np.all(np.isfinite(box)) or np.any(box[:, 1] <= box[:, 0]):
        raise ShapeError(f"{caller}: `region` must be {n} pairs (low, high) with low < high, one per state "
                         f"({', '.join(system.states)}); got {np.asarray(region).tolist()}")
    lam = np.arange(-1.0, -(n + 2.0), -1.0) if eigenvalues is None else np.asarray(eigenvalues, dtype=float).ravel()
    if lam.size != n + 1:
        raise ShapeError(f"{caller}: `eigenvalues` must have n + 1 = {n + 1} entries (Andrieu-Praly dimension), got {lam.size}")
    if np.any(lam >= 0) or len(np.unique(lam)) != lam.size or not np.all(np.isfinite(lam)):
        raise PreconditionError(f"{caller}: `eigenvalues` must be distinct and negative (a stable, controllable (Λ, B)); got {lam}")
    if int(degree) != degree or degree < 1:
        raise PreconditionError(f"{caller}: `degree` must be an integer >= 1, got {degree!r}")
    if not 0 < held_out < 1:
        raise PreconditionError(f"{caller}: `held_out` must be in (0, 1), got {held_out!r}")
    if int(n_trajectories) != n_trajectories or n_trajectories < 4:
        raise PreconditionError(f"{caller}: `n_trajectories` must be an integer >= 4, got {n_trajectories!r}")
    u_vals = dict(inputs or {})
    missing = [k for k in system.inputs if k not in u_vals]
    unknown = [k for k in u_vals if k not in system.inputs]
    if missing or unknown:
        raise PreconditionError(f"{caller}: `inputs` must give one constant per input ({', '.join(system.inputs) or 'none'}); "
                                f"missing {missing}, unknown {unknown}. The learned map holds for these input values only.")
    burn = 16.0 / float(np.min(np.abs(lam))) if burn_in is None else float(burn_in)
    steps = int(round(t_final / dt))
    if burn >= t_final or steps < 2:
        raise PreconditionError(f"{caller}: `burn_in` = {burn:g} must be shorter than `t_final` = {t_final:g}")

    n_xi = (n + 1) * p
    n_features = math.comb(n_xi + p + int(degree), int(degree))
    if n_features > MAX_FEATURES:
        raise PreconditionError(
            f"{caller}: the learned inverse would need {n_features:,} monomial features (degree ≤ {int(degree)} in the "
            f"n_ξ + p = {n_xi + p} inputs (ξ, y)); the limit is {MAX_FEATURES:,} (the least-squares fit grows as the cube of "
            f"the feature count). Lower `degree`" + (f" (degree {_max_degree(n_xi + p)} fits)" if _max_degree(n_xi + p) else "")
            + " or use another observer for a model with this many states and outputs")
    Lam = np.kron(np.eye(p), np.diag(lam))
    Bm = np.kron(np.eye(p), np.ones((n + 1, 1)))
    f, h = compile_system(system).bind()
    uv = ca.DM([u_vals[k] for k in system.inputs])
    N = int(n_trajectories)
    data = _training_runs(f, h, uv, Lam, Bm, box, dt=dt, steps=steps, burn=burn, count=N, seed=seed)   # (frames, n + n_xi, N)
    alive = np.all(np.isfinite(data), axis=(0, 1))
    dropped = int(N - alive.sum())
    idx = np.flatnonzero(alive)
    n_test = max(1, int(round(held_out * idx.size)))
    if idx.size - n_test < 2:
        raise PreconditionError(f"{caller}: only {idx.size} of {N} trajectories stayed bounded; shrink `region` or `t_final`")
    test, train = idx[:n_test], idx[n_test:]

    def pairs(sel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        block = data[:, :, sel]                                 # (frames, n + n_xi, k)
        X = block[:, :n, :].transpose(0, 2, 1).reshape(-1, n)
        Xi = block[:, n:, :].transpose(0, 2, 1).reshape(-1, n_xi)
        Y = np.asarray(h.map(X.shape[0])(0.0, X.T, np.tile(np.asarray(uv).reshape(-1, 1), (1, X.shape[0])))).T
        return np.hstack([Xi, Y]), X

    V_tr, X_tr = pairs(train)
    V_te, X_te = pairs(test)
    mu, sd = V_tr.mean(axis=0), V_tr.std(axis=0)
    sd[sd == 0] = 1.0
    exps = monomial_exponents(n_xi + p, int(degree))
    M = _features((V_tr - mu) / sd, exps, np)
    G = M.T @ M
    if np.linalg.matrix_rank(G, tol=1e-12 * np.trace(G)) < len(exps) and ridge == 0:
        raise PreconditionError(f"{caller}: the {len(exps)} features are linearly dependent on the data; lower `degree` or "
                                "set `ridge` > 0")
    W = np.linalg.solve(G + ridge * np.trace(G) / len(exps) * np.eye(len(exps)), M.T @ X_tr)
    pred = _features((V_te - mu) / sd, exps, np) @ W
    rms = np.sqrt(np.mean((pred - X_te) ** 2, axis=0))
    spread = X_te.std(axis=0)
    rel = rms / np.where(spread > 0, spread, 1.0)

    stack = StateStack(system)
    xi = stack.add("xi", n_xi)
    stack.set_flow(xi, ca.DM(Lam) @ xi + ca.DM(Bm) @ stack.y)
    V = (ca.vertcat(xi, stack.y) - ca.DM(mu)) / ca.DM(sd)
    xhat = ca.DM(W).T @ _features(V, exps, ca)
    checks = (Check("Λ diagonal with distinct negative eigenvalues, n_ξ = (n + 1)p (Andrieu-Praly)", True,
                    f"λ = {lam.tolist()}, n_ξ = {n_xi}"),)
    values = {"eigenvalues": lam, "n_xi": n_xi, "features": f"{len(exps)} monomials of degree ≤ {degree} in (ξ, y)",
              "trajectories": f"{train.size} training, {test.size} held out, {dropped} dropped (escaped)",
              "samples": f"{V_tr.shape[0]} training pairs after burn-in {burn:g}",
              "held-out RMS fit error": rms, "held-out relative error (RMS / std)": rel, "held_out_rms": float(np.sqrt(np.mean(rms ** 2)))}
    cert = Certificate("KKL observer with a learned left inverse", REF, checks, values)
    return stack.build("kkl_learned", xhat=xhat, certificate=cert, xhat0=xhat0)
