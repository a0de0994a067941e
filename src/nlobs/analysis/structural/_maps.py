r"""Local observability and identifiability of a discrete-time model x[k+1] = f(x[k], u[k], t[k]), y[k] = h(...).

The discrete counterpart of the rank condition: x[0] (and the unknown parameters θ, appended as constant states
θ[k+1] = θ[k]) are locally observable when the Jacobian of the output sequence

.. math::

    J = \frac{\partial\,(y[0], y[1], \dots, y[K-1])}{\partial(x[0], \theta)}, \qquad K = n + q,

has full rank n + q for generic inputs u[0], u[1], ... (a new random value at each step). Its rows are built by
the chain rule along the trajectory: J_x[0] = I, J_x[k+1] = ∂f/∂x · J_x[k], and ∂y[k] = ∂h/∂x · J_x[k] (the
Kalman observability matrix when f and h are linear). K = n + q steps suffice: the rank of the first k blocks stops
growing once it does not grow for one step.

A rational model (polynomials and quotients, no exp, sin, ...) is evaluated exactly in GF(p) at a random point (p a
random 27-bit prime): a full rank there proves local observability; a deficient rank is confirmed at a second point
and prime (error probability bounded as for the continuous test). A model with other functions is evaluated in
floating point at two random real points, the rank read from the singular values (the gap is reported).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ...algebra._modular import RowEchelon, inv, random_prime
from ...errors import ModelError
from ...engine import to_casadi
from ...model import TIME, System, parse_expression
from ...references import cite
from .._reports import ObservabilityReport
from ._inputs import _unknown_params

__all__ = ["map_analysis"]


class _NotRational(Exception):
    pass


def _modular(expr: sp.Expr, env: Mapping[sp.Symbol, int], p: int, memo: dict[sp.Basic, int]) -> int:
    """`expr` evaluated in GF(p) at the point `env` (ZeroDivisionError where a denominator vanishes)."""
    if expr in memo:
        return memo[expr]
    if expr.is_Symbol:
        v = env[expr]
    elif expr.is_Integer:
        v = int(expr) % p
    elif expr.is_Rational:
        v = int(expr.p) % p * inv(int(expr.q), p) % p
    elif expr.is_Add:
        v = sum(_modular(a, env, p, memo) for a in expr.args) % p
    elif expr.is_Mul:
        v = 1
        for a in expr.args:
            v = v * _modular(a, env, p, memo) % p
    elif expr.is_Pow and expr.exp.is_Integer:
        b = _modular(expr.base, env, p, memo)
        e = int(expr.exp)
        v = pow(b, e, p) if e >= 0 else pow(inv(b, p), -e, p)
    else:
        raise _NotRational(str(expr.func))
    memo[expr] = v
    return v


def _is_rational(exprs: list[sp.Expr]) -> bool:
    return all(all(a.is_Symbol or a.is_Rational or a.is_Add or a.is_Mul or (a.is_Pow and a.exp.is_Integer)
                   for a in sp.preorder_traversal(e)) for e in exprs)


def _input_values(system: System, inputs: Any, K: int, rng: np.random.Generator, modular: int | None) -> list[list[Any]]:
    """u[k] for k < K: generic (random each step), one generic constant, or the given signals at t[k]."""
    nu = system.n_inputs
    draw = (lambda: int(rng.integers(1, modular))) if modular else (lambda: float(rng.uniform(0.5, 1.5)))
    if inputs in ("generic", None):
        return [[draw() for _ in range(nu)] for _ in range(K)]
    if inputs == "constant":
        const = [draw() for _ in range(nu)]
        return [list(const) for _ in range(K)]
    if not isinstance(inputs, Mapping):
        raise ModelError(f"analyze: for a discrete-time model `inputs` is \"generic\", \"constant\" or a mapping "
                         f"{{input: number or expression of t}}; got {inputs!r}")
    unknown = [k for k in inputs if k not in system.inputs]
    if unknown:
        raise ModelError(f"analyze: `inputs` names {unknown[0]!r}, not an input of {system.name!r}")
    out = []
    for k in range(K):
        row = []
        for name in system.inputs:
            spec = inputs.get(name, "generic")
            if spec == "generic":
                row.append(draw())
                continue
            e = spec if isinstance(spec, sp.Basic) else parse_expression(str(spec), {"t": TIME})
            e = e.xreplace({TIME: sp.Rational(k) * sp.nsimplify(system.sample_time)})
            if modular:
                if not e.is_Rational:
                    raise _NotRational(str(e))
                row.append(_modular(e, {}, modular, {}))
            else:
                row.append(float(e))
        out.append(row)
    return out


def _rows(system: System, f: list[sp.Expr], h: list[sp.Expr], point: list[Any], U: list[list[Any]], K: int,
          evaluate: Callable[[sp.Expr, dict[sp.Symbol, Any]], Any], mat: Callable[[list[list[Any]]], Any],
          mul: Callable[[Any, Any], Any], add_row: Callable[[Any], Any]) -> None:
    """Feed the rows ∂y[k]/∂(x[0], θ) = ∂h/∂x · J_x[k], k < K, to `add_row` (J_x[k+1] = ∂f/∂x · J_x[k])."""
    X, Ut = list(system.x), list(system.u)
    Fx = sp.Matrix(f).jacobian(X)
    Hx = sp.Matrix(h).jacobian(X)
    n = len(X)
    J = mat([[1 if i == j else 0 for j in range(n)] for i in range(n)])
    x = list(point)
    for k in range(K):
        env = {**dict(zip(X, x)), **dict(zip(Ut, U[k])), TIME: evaluate(sp.Rational(k) * sp.nsimplify(system.sample_time), {})}
        for r in mul(mat([[evaluate(Hx[i, j], env) for j in range(n)] for i in range(Hx.shape[0])]), J):
            add_row(r)
        if k + 1 < K:
            J = mul(mat([[evaluate(Fx[i, j], env) for j in range(n)] for i in range(n)]), J)
            x = [evaluate(e, env) for e in f]


def _float_rows(system: System, f: list[sp.Expr], h: list[sp.Expr], inputs: Any, K: int,
                rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The Jacobian's rows in floating point at a random real point (and the point): one compiled CasADi function
    of (x, u, t) gives f, ∂f/∂x and ∂h/∂x."""
    n = system.n_states
    x, u, t = ca.SX.sym("x", n), ca.SX.sym("u", system.n_inputs), ca.SX.sym("t")
    leaves = {**dict(zip(system.x, ca.vertsplit(x))), **dict(zip(system.u, ca.vertsplit(u))), TIME: t}
    fx, hx = to_casadi(f, leaves), to_casadi(h, leaves)
    step = ca.Function("map_jacobians", [x, u, t], [fx, ca.jacobian(fx, x), ca.jacobian(hx, x)])
    point = rng.uniform(0.5, 1.5, n)
    U = _input_values(system, inputs, K, rng, None)
    J, xk, rows = np.eye(n), point.copy(), []
    for k in range(K):
        fk, Fk, Hk = (np.asarray(v, dtype=float) for v in step(xk, U[k], k * system.sample_time))
        rows.append(Hk.reshape(-1, n) @ J)
        J, xk = Fk @ J, fk.ravel()
    return np.vstack(rows), point


def map_analysis(system: System, *, unknown_params: Any = (), inputs: Any = "generic", seed: int = 0) -> ObservabilityReport:
    """Local observability (and identifiability of `unknown_params`) of a discrete-time model; see the module."""
    t_start = time.perf_counter()
    params = _unknown_params(system, unknown_params)
    aug = system.augmented(params) if params else system
    f, h = (list(m) for m in aug.substituted())
    n_unk = aug.n_states
    K = n_unk + 1
    rng = np.random.default_rng(seed)
    names = aug.states
    notes = [f"discrete-time model: rank of ∂(y[0], ..., y[k])/∂(x[0]{', θ' if params else ''}) along the map "
             f"(K ≤ {K} steps), inputs {inputs if isinstance(inputs, str) else 'as given'}; the rank condition is local "
             f"({cite('002', 'Observability rank condition')}, stated for maps)"]
    rational = _is_rational(f + h)
    prime, gap, error = 0, float("inf"), 0.0
    ranks: list[int] = []
    basis = None
    for _ in range(2):
        if rational:
            p = random_prime(rng)
            try:
                point = [int(v) for v in rng.integers(1, p, n_unk)]
                U = _input_values(aug, inputs, K, rng, p)
                ech = RowEchelon(n_unk, p)
                _rows(aug, f, h, point, U, K, lambda e, env, p=p: _modular(e, env, p, {}),
                      lambda rows: np.array(rows, dtype=object), lambda A, B, p=p: A.dot(B) % p,
                      lambda r: ech.add(np.array(r, dtype=np.int64)))
            except _NotRational:
                rational = False
            except ZeroDivisionError:   # a denominator vanishes at this point: another point
                continue
            else:
                ranks.append(ech.rank)
                prime, basis = p, ech
        if not rational:
            M, _ = _float_rows(aug, f, h, inputs, K, rng)
            sv = np.linalg.svd(M / max(np.abs(M).max(), 1e-300), compute_uv=False)
            tol = max(M.shape) * np.finfo(float).eps * 1e3
            r = int(np.sum(sv > tol))
            gap = float(sv[r - 1] / sv[r]) if 0 < r < sv.size and sv[r] > 0 else float("inf")
            ranks.append(r)
        if ranks and ranks[-1] == n_unk:
            break
    rank = max(ranks) if ranks else 0
    # the unobservable directions, at a real point (floating point)
    M, point_r = _float_rows(aug, f, h, inputs, K, rng)
    _, _, vt = np.linalg.svd(M, full_matrices=True)
    directions = vt[rank:] if rank < n_unk else np.zeros((0, n_unk))
    if rational and basis is not None:
        observable = [nm for i, nm in enumerate(names) if basis.contains(np.eye(n_unk, dtype=np.int64)[i])]
        method = (f"rank of the output-sequence Jacobian of the map, exact in GF({prime}) at a random point with generic "
                  f"inputs per step ({len(ranks)} point(s))")
        if rank < n_unk:
            error = 0.0 if len(ranks) < 2 else 1e-6   # two independent points and primes agree on the deficiency
    else:
        observable = [nm for i, nm in enumerate(names) if directions.size == 0 or np.all(np.abs(directions[:, i]) < 1e-8)]
        method = (f"rank of the output-sequence Jacobian of the map in floating point at {len(ranks)} random point(s) "
                  f"(singular-value gap {gap:.3g}); the model has functions other than polynomials and quotients")
        notes.append("numerical rank (floating point): an ill-conditioned map can hide or fake a rank; the gap is "
                     "reported as numerical_gap")
    return ObservabilityReport(
        model=system.name, states=system.states, unknown_params=params, unknown_input_coefficients=(),
        inputs=inputs if isinstance(inputs, str) else ", ".join(f"{k} = {v}" for k, v in inputs.items()),
        rank=rank, observable=rank == n_unk,
        observable_states=tuple(s for s in system.states if s in observable),
        identifiable_params=tuple(k for k in params if k in observable),
        unobservable_directions=directions, point=point_r, orders=(K - 1,) * system.n_outputs, method=method,
        prime=prime, error_probability=error, notes=tuple(notes), seconds=time.perf_counter() - t_start,
        numerical_gap=gap, extra={"observable_unknowns": tuple(observable), "time": "discrete"})
