r"""Structure nlobs can build for the user, where the kind needs more than gains.

* :func:`find_chains`: the triangular chains of a model whose states are not listed chain by chain
  (the Rössler system measured through its second state: x2 -> x1 -> x3).
* :func:`derivative_map`: Ψ with x = Ψ(y, ẏ, ..., u) from the Lie derivatives of the outputs, solved one
  state at a time, for the output-derivative high-gain observer.
* :func:`kkl_linear`: for the output-injection form ẋ = Ax + B(u, y), y = Cx, the KKL map φ(x) = Tx with
  TA − ΛT = B_k C (a Sylvester equation, solved exactly): ∇φ·f = Λφ + B_k y + T B(u, y).
* :func:`pebo_linear`: for the same form, φ(x) = Tx with TA = KC (rows whose derivative is measured),
  and [C; T] invertible: ∇φ·f = Ky + T B(u, y), the PEBO of Yi, Ortega & Zhang (2019) Proposition 2.
* :func:`banks_gain`: a gain P with λ(∂f/∂x + P ∂h/∂x) < 0 on the region (Banks' condition), by
  minimising the largest matrix measure over points of the region.
* :func:`cascade_partition`: the blocks (x2, x3, x4, k) of the class of Proposition 7, if a split exists.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp
from sympy.printing.str import StrPrinter

from ..engine import to_casadi
from ..errors import FormError, PreconditionError
from ..model import TIME, System, symbol
from ..model._budget import SymbolicTimeLimit, symbolic_time_limit
from ._checks import observer_gain

__all__ = ["jacobians_at", "find_chains", "derivative_map", "exact_output_injection", "kkl_linear", "pebo_linear", "banks_gain", "banks_necessary",
           "cascade_partition", "rational"]


class _FilePrinter(StrPrinter):
    """SymPy's text, spelled the way model files and observer options are read back (min/max in lower case)."""

    def _print_Min(self, expr: sp.Expr) -> str:
        return self._nested("min", expr.args)

    def _print_Max(self, expr: sp.Expr) -> str:
        return self._nested("max", expr.args)

    def _nested(self, name: str, args: tuple) -> str:  # the parser's min/max take two arguments
        first, *rest = args
        out = self._print(first)
        for a in rest:
            out = f"{name}({out}, {self._print(a)})"
        return out


def text(expr: Any) -> str:
    """An expression as option text the model parser reads back (``Min`` -> ``min``; see ``parse_expression``)."""
    return _FilePrinter().doprint(expr)


def rational(v: float) -> sp.Rational:
    """The exact rational of a float's shortest decimal form."""
    return sp.Rational(repr(float(v)))


def _measured(system: System) -> list[int] | None:
    _, h = system.substituted()
    out = []
    for k in range(system.n_outputs):
        hit = [j for j, xs in enumerate(system.x) if sp.expand(h[k]) == xs]
        if not hit:
            return None
        out.append(hit[0])
    return out


def find_chains(system: System, why: list[str] | None = None) -> list[list[str]] | None:
    """Chains for the triangular form, following each measured state to the one unmeasured state its equation
    uses; None when an output is not a single state or the states do not split into chains that way (then the
    reason is appended to `why`)."""
    meas = _measured(system)
    if meas is None or len(set(meas)) != len(meas):
        return None
    f, _ = system.substituted()
    taken = set(meas)
    chains = []
    for j in meas:
        chain = [j]
        while True:
            nxt = [m for m, xs in enumerate(system.x) if m not in taken and xs in f[chain[-1]].free_symbols]
            if len(nxt) != 1:
                if len(nxt) > 1 and why is not None:
                    why.append(f"following the chain {' -> '.join(system.states[k] for k in chain)}, the equation of "
                               f"{system.states[chain[-1]]} brings in {', '.join(system.states[k] for k in nxt)} at once: "
                               "the triangular form needs each equation to add one new state")
                break
            chain.append(nxt[0])
            taken.add(nxt[0])
        chains.append(chain)
    if len(taken) != system.n_states:
        if why is not None and not why:
            why.append(f"the chains from the measured states reach only {', '.join(system.states[k] for k in sorted(taken))}")
        return None
    return [[system.states[j] for j in ch] for ch in chains]


def _lie(system: System, expr: sp.Expr, f: sp.Matrix) -> sp.Expr:
    return sp.expand(sum((sp.diff(expr, xs) * fi for xs, fi in zip(system.x, f)), sp.S.Zero) + sp.diff(expr, TIME))


def derivative_map(system: System, *, max_order: int | None = None,
                   lie: dict[sp.Symbol, sp.Expr] | None = None) -> tuple[dict[str, sp.Expr] | None, str]:
    r"""x = Ψ(D, y, u) from the output derivatives :math:`D_{i,k} = L_f^i h_k` (inputs held constant).

    Equations :math:`D_{i,k} = L_f^i h_k(x)` are taken in order of increasing i; one with a single state not yet
    expressed, entering linearly (or with exactly one solution), gives that state. Returns the map in the
    ``D{i}_{output}`` symbols of :func:`nlobs.design.design_high_gain_derivatives`, or None and the reason.
    When `lie` is a dict, it receives each D symbol's Lie derivative in (x, u, t), to evaluate Ψ along a run.
    """
    try:
        with symbolic_time_limit(DERIVATIVE_MAP_SECONDS):
            return _derivative_map(system, max_order, lie)
    except SymbolicTimeLimit:
        if lie is not None:
            lie.clear()
        return None, (f"not checked within budget (solving the output derivatives for the states took more than "
                      f"{DERIVATIVE_MAP_SECONDS:g} s of symbolic work); give `xhat` = Ψ(D0_y, D1_y, ...) yourself")


#: Symbolic seconds the search for x = Ψ(output derivatives) may take before the advisor gives up on it.
DERIVATIVE_MAP_SECONDS = 3.0


def _derivative_map(system: System, max_order: int | None,
                    lie: dict[sp.Symbol, sp.Expr] | None) -> tuple[dict[str, sp.Expr] | None, str]:
    n = system.n_states
    order = max_order if max_order is not None else n
    f, h = system.substituted()
    D = {(i, yk): symbol(f"D{i}_{yk}") for yk in system.outputs for i in range(order)}
    eqs: list[tuple[int, str, sp.Expr]] = []
    for k, yk in enumerate(system.outputs):
        e = h[k]
        for i in range(order):
            eqs.append((i, yk, e))
            if lie is not None:
                lie[D[(i, yk)]] = e
            if i + 1 < order:
                e = _lie(system, e, f)
                if sp.count_ops(e) > 400:
                    break
    eqs.sort(key=lambda t: t[0])
    known: dict[sp.Symbol, sp.Expr] = {}
    progress = True
    while progress and len(known) < n:
        progress = False
        for i, yk, e in eqs:
            ei = e.xreplace(known)
            free = [xs for xs in system.x if xs in ei.free_symbols]
            if len(free) != 1:
                continue
            v = free[0]
            eq = sp.expand(ei - D[(i, yk)])
            c = sp.diff(eq, v)
            sol = None
            if v not in c.free_symbols and c != 0:
                sol = sp.simplify(-(eq - c * v) / c)
            else:
                try:
                    sols = sp.solve(eq, v, dict=False)
                except (NotImplementedError, ValueError):
                    sols = []
                if len(sols) == 1 and not sols[0].has(sp.I):
                    sol = sp.simplify(sols[0])
            if sol is not None:
                known[v] = sol
                progress = True
    missing = [s for s, xs in zip(system.states, system.x) if xs not in known]
    if missing:
        return None, (f"{', '.join(missing)} could not be solved one at a time from the output derivatives (up to order "
                      f"{order - 1}); give `xhat` = Ψ(D0_y, D1_y, ...) yourself")
    ysub = {symbol(yk): D[(0, yk)] for yk in system.outputs}
    return {s: known[xs].xreplace(ysub) for s, xs in zip(system.states, system.x)}, ""


def exact_output_injection(system: System) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
    """(A, C, B(u, y, t)) of the output-injection form in exact arithmetic (as OutputInjectionForm.from_system)."""
    f, h = system.substituted()
    x = sp.Matrix(system.x)
    C = h.jacobian(x)
    if C.free_symbols:
        raise FormError("the output is not Cx with a constant C")
    n = system.n_states
    K = sp.Matrix.hstack(*C.nullspace()) if C.rank() < n else sp.zeros(n, 0)
    G = (f.jacobian(x) * K).applyfunc(sp.simplify) if K.shape[1] else sp.zeros(n, 0)
    if G.free_symbols & set(system.x) or any(e.free_symbols for e in G):
        raise FormError("not in output-injection form")
    A = G * (K.T * K).inv() * K.T if K.shape[1] else sp.zeros(n, n)
    B = (f - A * x).applyfunc(sp.expand)
    ysub = dict(zip(system.x, C.pinv() * sp.Matrix(system.y)))
    B = B.xreplace(ysub).applyfunc(sp.simplify)
    return A, C, B


def kkl_linear(system: System, omega: float) -> tuple[dict[str, Any] | None, str]:
    r"""KKL (Yi, Ortega & Zhang (2019) Proposition 1) for ẋ = Ax + B(u, y), y = Cx: φ = Tx, TA − ΛT = B_kC.

    Λ = −ω·diag(1, 1.25, 1.5, ...) (exact rationals), B_k with entries 1 + ((i + 1)(k + 1) mod 3); T is the exact
    solution of the Sylvester equation, invertible when (A, C) is observable and the pair (Λ, B_k) controllable.
    """
    A, C, B = exact_output_injection(system)
    n, p = A.shape[0], C.shape[0]
    w = rational(round(omega, 3)) if omega > 0 else sp.Integer(1)
    lam = [-w * (1 + sp.Rational(k, 4)) for k in range(n)]
    L = sp.diag(*lam)
    Bk = sp.Matrix(n, p, lambda i, k: 1 + ((i + 1) * (k + 1)) % 3)
    T = sp.Matrix(n, n, sp.symbols(f"t0:{n * n}"))
    sol = sp.solve(list(T * A - L * T - Bk * C), list(T), dict=True)
    if not sol:
        return None, "the Sylvester equation TA − ΛT = B_kC has no solution"
    Tn = T.xreplace(sol[0])
    if Tn.free_symbols or Tn.det() == 0:
        return None, "T is singular for this Λ, B_k: (A, C) is not observable, or a spectrum overlaps"
    Ti = Tn.inv()
    xi = sp.Matrix(sp.symbols(f"xi1:{n + 1}"))
    Bx = (Bk * sp.Matrix(system.y) + Tn * B).applyfunc(sp.expand)
    return {"phi": [text(e) for e in Tn * sp.Matrix(system.x)], "left_inverse": [text(e) for e in Ti * xi],
            "B": [text(e) for e in Bx], "Lambda": [text(v) for v in lam]}, ""


def pebo_linear(system: System) -> tuple[dict[str, Any] | None, str, sp.Matrix | None]:
    r"""PEBO (Yi, Ortega & Zhang (2019) Proposition 2) for ẋ = Ax + B(u, y), y = Cx: rows t with tA = kC give
    φ = Tx with ∇φ·f = Ky + T B(u, y); with [C; T] invertible, x = [C; T]⁻¹(y, ξ + θ).

    Returns the options, the reason when there is none, and the regressor b of ẏ = a + bᵀθ (constant here).
    """
    A, C, B = exact_output_injection(system)
    n, p = A.shape[0], C.shape[0]
    if n == p:
        return None, "every state is measured: nothing to estimate", None
    M = sp.Matrix.hstack(A.T, -C.T)
    null = M.nullspace()
    rows, ks = [], []
    for v in null:
        t, k = v[:n, 0].T, v[n:, 0].T
        cand = sp.Matrix.vstack(C, *rows, t) if rows else sp.Matrix.vstack(C, t)
        if cand.rank() > p + len(rows):
            rows.append(t)
            ks.append(k)
        if len(rows) == n - p:
            break
    if len(rows) < n - p:
        return None, (f"only {len(rows)} of the n − p = {n - p} needed directions have a measured derivative (tA = kC); "
                      "give φ with ∇φ·f = B(h(x), u) yourself"), None
    T = sp.Matrix.vstack(*rows)
    Kt = sp.Matrix.vstack(*ks)
    Mi = sp.Matrix.vstack(C, T).inv()
    xi = sp.Matrix(sp.symbols(f"xi1:{n - p + 1}"))
    y = sp.Matrix(system.y)
    left = Mi * sp.Matrix.vstack(y, xi)
    Bx = (Kt * y + T * B).applyfunc(sp.expand)
    b = C * A * Mi[:, p:]     # ẏ = C(Ax + B) with x = Mi (y, ξ + θ): the θ-coefficient
    return {"phi": [text(e) for e in T * sp.Matrix(system.x)], "left_inverse": [text(sp.expand(e)) for e in left],
            "B": [text(e) for e in Bx]}, "", b


def jacobians_at(system: System, t: np.ndarray, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """∂f/∂x and ∂h/∂x at N points (t (N,), x (N, n), u (N, m)): arrays (N, n, n) and (N, p, n)."""
    from ..engine import compile_system

    comp = compile_system(system)
    N, n, p = x.shape[0], system.n_states, system.n_outputs
    args = (ca.DM(np.asarray(t, dtype=float)).T, ca.DM(x.T), ca.DM(u.T) if system.n_inputs else ca.DM(0, N),
            ca.repmat(ca.DM(system.param_values), 1, N))
    F = np.asarray(comp.f_x.map(N)(*args), dtype=float).reshape(n, N, n).transpose(1, 0, 2)
    H = np.asarray(comp.h_x.map(N)(*args), dtype=float).reshape(p, N, n).transpose(1, 0, 2)
    return F, H


def banks_gain(system: System, samples: np.ndarray, u: np.ndarray, t: np.ndarray, *, limit: float = np.inf,
               iterations: int = 150) -> tuple[np.ndarray | None, float, str]:
    r"""A gain P (n × p) with :math:`\max_k \lambda(\partial f/\partial x(x_k) + P\,\partial h/\partial x(x_k)) < 0`
    over the given points (Banks (1980) Theorem 2.6 with f2 = 0), by Nelder–Mead on the largest matrix measure
    from the sign-flipped pole-placement gain of the linearisation at the centre. Returns (P, best value, how).
    """
    from ..analysis import matrix_measure  # here, not at the top: a Monte Carlo worker loads no analysis
    import scipy.optimize

    n, p = system.n_states, system.n_outputs
    F, H = jacobians_at(system, t, samples, u)
    ok = np.all(np.isfinite(F), axis=(1, 2)) & np.all(np.isfinite(H), axis=(1, 2))
    F, H = F[ok], H[ok]
    if not len(F):
        return None, np.inf, "the Jacobians are not finite on the region"

    hmax = float(np.max(np.linalg.norm(H, 2, axis=(1, 2)))) or 1.0

    def worst(Pflat: np.ndarray) -> float:
        P = Pflat.reshape(n, p)
        M = F + np.einsum("ij,kjl->kil", P, H)
        excess = np.linalg.norm(P, 2) * hmax / limit - 1.0 if np.isfinite(limit) else -1.0
        return float(matrix_measure(M).max()) + 10.0 * max(0.0, excess) * (1.0 + abs(float(np.max(np.abs(F)))))

    starts = []
    Fc, Hc = F.mean(axis=0), H.mean(axis=0)
    try:
        w = max(1.0, float(np.max(np.abs(np.linalg.eigvals(Fc)))))
        L, _, _ = observer_gain(Fc, Hc, poles=-w * (1 + 0.25 * np.arange(n)), caller="banks_gain")
        starts.append(-L.reshape(-1))
    except (PreconditionError, ValueError, np.linalg.LinAlgError):
        pass
    starts.append((-(Fc @ np.linalg.pinv(Hc)) - np.linalg.pinv(Hc)).reshape(-1) if p else np.zeros(0))
    starts.append(-np.ones(n * p))
    best, bestP = np.inf, None
    for s0 in starts:
        if s0.size != n * p:
            continue
        if np.isfinite(limit) and np.linalg.norm(s0) * hmax > limit:
            s0 = s0 * (0.9 * limit / (np.linalg.norm(s0) * hmax))
        res = scipy.optimize.minimize(worst, s0, method="Nelder-Mead",
                                      options={"maxiter": iterations, "xatol": 1e-6, "fatol": 1e-9})
        if res.fun < best:
            best, bestP = float(res.fun), res.x.reshape(n, p)
        if best < 0:
            break
    if bestP is not None:
        best = float(matrix_measure(F + np.einsum("ij,kjl->kil", bestP, H)).max())
    return bestP, best, "Nelder–Mead on the largest matrix measure over the sampled region"


def banks_necessary(system: System, samples: np.ndarray, u: np.ndarray, t: np.ndarray) -> str:
    r"""Why no gain P can meet Banks' condition, or "" when that is not excluded.

    For v in the kernel of ∂h/∂x(x), :math:`v^\top(\partial f/\partial x + P\,\partial h/\partial x)v = v^\top
    \partial f/\partial x\, v` whatever P is: the matrix measure is at least the largest eigenvalue of the symmetric
    part of ∂f/∂x restricted to that kernel. If it is ≥ 0 at a point of the region, the condition fails for every P.
    """
    N = samples.shape[0]
    F, H = jacobians_at(system, t, samples, u)
    worst, where = -np.inf, None
    for k in range(N):
        if not (np.all(np.isfinite(F[k])) and np.all(np.isfinite(H[k]))):
            continue
        _, sv, Vt = np.linalg.svd(H[k])
        rank = int(np.sum(sv > 1e-9 * max(1.0, sv.max(initial=0.0))))
        K = Vt[rank:].T
        if K.shape[1] == 0:
            continue
        S = K.T @ ((F[k] + F[k].T) / 2) @ K
        lam = float(np.linalg.eigvalsh(S).max())
        if lam > worst:
            worst, where = lam, samples[k]
    if worst >= 0:
        pt = ", ".join(f"{nm}={v:.3g}" for nm, v in zip(system.states, where))
        return (f"no gain can work: along the unmeasured directions (the kernel of ∂h/∂x) the symmetric part of ∂f/∂x has the "
                f"eigenvalue {worst:.3g} ≥ 0 (at {pt}), and P·∂h/∂x vanishes there, so λ(∂f/∂x + P ∂h/∂x) ≥ {worst:.3g} for "
                "every P (Banks' condition needs the unmeasured dynamics to contract by themselves)")
    return ""


def cascade_partition(system: System) -> tuple[dict[str, Any] | None, str]:
    """Blocks x2, x3 (stable, linear in themselves), x4 (equations free of x4) and k (the measured state whose
    equation is affine in x4) of Yi, Ortega & Zhang (2019) Proposition 7, by a structural search (≤ 3⁶ splits)."""
    meas = _measured(system)
    if meas is None:
        return None, "the outputs must be states themselves (y = x1)"
    f, _ = system.substituted()
    names = list(system.states)
    xs = dict(zip(names, system.x))
    U = [s for j, s in enumerate(names) if j not in meas]
    X1 = [names[j] for j in meas]
    if not U:
        return None, "every state is measured"
    if len(U) > 6:
        return None, f"{len(U)} unmeasured states: the split search is limited to 6"
    fx = dict(zip(names, f))

    def dep(e: sp.Expr, group: Sequence[str]) -> set[str]:
        return {s for s in group if xs[s] in e.free_symbols}

    best = None
    for labels in itertools.product((2, 3, 4), repeat=len(U)):
        blk = {b: [s for s, lab in zip(U, labels) if lab == b] for b in (2, 3, 4)}
        if not blk[4]:
            continue
        ok = True
        for b, allowed in ((2, blk[2]), (3, blk[2] + blk[3])):
            for s in blk[b]:
                e = fx[s]
                if dep(e, [v for v in U if v not in allowed]):
                    ok = False
                    break
                J = sp.Matrix([e]).jacobian(sp.Matrix([xs[v] for v in blk[b]]))
                if any(J[0, j].free_symbols for j in range(J.shape[1])):
                    ok = False
                    break
            if not ok:
                break
        if not ok or any(dep(fx[s], blk[4]) for s in blk[4]):
            continue
        ks = []
        for k in X1:
            e = fx[k]
            if dep(e, blk[4]):
                b = sp.Matrix([e]).jacobian(sp.Matrix([xs[v] for v in blk[4]]))
                if not any(dep(c, blk[4]) for c in b):
                    ks.append(k)
        if len(ks) != 1:
            continue
        stable = True
        for b in (2, 3):
            if blk[b]:
                F = sp.Matrix([fx[s] for s in blk[b]]).jacobian(sp.Matrix([xs[v] for v in blk[b]]))
                if np.max(np.linalg.eigvals(np.array(F, dtype=float)).real) >= 0:
                    stable = False
        if not stable:
            continue
        cand = {"x2": blk[2], "x3": blk[3], "x4": blk[4], "k": ks[0]}
        if best is None or len(cand["x4"]) < len(best["x4"]):
            best = cand
    if best is None:
        return None, ("no split of the unmeasured states " + ", ".join(U) + " fits the class: stable blocks x2, x3 linear in "
                      "themselves, a block x4 whose equations do not involve x4, and one measured equation affine in x4")
    return best, ""


def evaluate(exprs: Sequence[sp.Expr], system: System, points: Mapping[str, np.ndarray]) -> np.ndarray:
    """Expressions of (t, x, u, y) at the sampled points of a run: shape (N, len(exprs))."""
    N = points["t"].size
    tt = ca.SX.sym("t")
    x = ca.SX.sym("x", system.n_states)
    u = ca.SX.sym("u", system.n_inputs)
    y = ca.SX.sym("y", system.n_outputs)
    leaves: dict[sp.Symbol, Any] = {TIME: tt}
    leaves.update({s: x[i] for i, s in enumerate(system.x)})
    leaves.update({s: u[i] for i, s in enumerate(system.u)})
    leaves.update({s: y[i] for i, s in enumerate(system.y)})
    leaves.update({symbol(k): ca.SX(float(v)) for k, v in system.params.items()})   # the model's parameter values
    fn = ca.Function("e", [tt, x, u, y], [to_casadi(list(exprs), leaves)])
    out = fn.map(N)(ca.DM(points["t"]).T, ca.DM(points["x"].T), ca.DM(points["u"].T) if system.n_inputs else ca.DM(0, N),
                    ca.DM(points["y"].T))
    return np.asarray(out, dtype=float).T.reshape(N, len(exprs))
