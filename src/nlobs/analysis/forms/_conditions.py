r"""Banks' conditions for exponential observers (Banks (1980)) and sup-over-a-box estimates.

* Matrix measure (Banks (1980), §1): :math:`\lambda(A) = \max\operatorname{spec}((A + A^\top)/2)`.
* Maximum slope (Banks (1980), before Lemma 2.4): :math:`\mu_N = \sup_{x\ne z}\langle Nx - Nz, x - z\rangle/\|x - z\|^2`;
  for a C¹ map on a convex region it equals :math:`\sup_x \lambda(DN(x))`. N is dissipative
  (Lemma 2.3) iff :math:`\mu_N \le 0`.
* Theorem 2.6: :math:`\lambda(Df_1(x) + P\,DB(x)) \le -\varepsilon` on Ω, and a Lipschitz perturbation
  f2 with constant K < ε.

Sups over a box are estimated by random sampling plus a bounded local maximisation from the best
samples (L-BFGS-B); the worst point is returned with the value. Sampling can only under-estimate
a sup, so a reported margin should be read with that in mind (refine with more `samples`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from ..._deprecate import renamed
from ...errors import DataError, ModelError, ShapeError
from ...model import parse_expression, symbol
from ...model._expr import ExpressionError
from ...model._system import to_expr
from .._reports import fmt_point, fmt_vec
from ...references import cite

__all__ = ["check_box", "region_pairs", "matrix_measure", "box_sup", "SlopeResult", "max_slope", "BanksCheck", "banks_condition", "LipschitzEstimate",
           "lipschitz_bound"]

REF = f"{cite('003')}"

#: The kind of evidence behind every supremum over a box in this module (see :func:`box_sup`).
SAMPLED = ("sampled over the box ({n} random points, corners, centre, then L-BFGS-B from the best {r}): "
           "a lower bound of the supremum, not a proof")


def check_box(box: Any, n: int, name: str, caller: str, names: Sequence[str] | None = None) -> np.ndarray:
    """A region (a box) as an array (n, 2) of finite [low, high] bounds with low <= high.

    Parameters
    ----------
    box : mapping of str to (low, high), or array_like of shape (n, 2)
        A mapping names each coordinate (the vocabulary's ``region``: ``{"x1": (-1, 1), ...}``; every
        name of `names` once, no other); an array gives the pairs in the order of `names`.
    n : int
        Number of coordinates.
    name, caller : str
        The argument's name and the calling function, for the error message.
    names : sequence of str, optional
        The coordinates' names, in order (needed for a mapping).

    Raises
    ------
    ShapeError, DataError
        Wrong shape; NaN or infinite bounds; low > high.
    """
    if isinstance(box, Mapping):
        box = region_pairs(box, names, name, caller)
    try:
        b = np.array(box, dtype=float)
    except (TypeError, ValueError) as e:
        raise ShapeError(f"{caller}: `{name}` must be a list of [low, high] pairs: {e}") from None
    if b.ndim == 1 and b.size == 2 and n == 1:
        b = b.reshape(1, 2)
    if b.shape != (n, 2):
        raise ShapeError(f"{caller}: `{name}` must have one [low, high] pair per coordinate ({n}), found shape {b.shape}")
    if not np.all(np.isfinite(b)):
        i = int(np.flatnonzero(~np.isfinite(b).all(axis=1))[0])
        raise DataError(f"{caller}: `{name}` row {i} has a NaN or infinite bound {b[i].tolist()}; give finite bounds")
    if np.any(b[:, 0] > b[:, 1]):
        i = int(np.flatnonzero(b[:, 0] > b[:, 1])[0])
        raise DataError(f"{caller}: `{name}` row {i} has low > high: {b[i].tolist()}")
    return b


def region_pairs(box: Mapping[str, Any], names: Sequence[str] | None, name: str, caller: str) -> list[Any]:
    """The [low, high] pairs of a region given as ``{name: (low, high)}``, in the order of `names` (every name once,
    no other; the design functions' ``box_of`` checks its regions with it too)."""
    if names is None:
        raise ShapeError(f"{caller}: `{name}` must be a list of [low, high] pairs here (no names to key a mapping by)")
    unknown = [k for k in box if k not in names]
    if unknown:
        raise ShapeError(f"{caller}: `{name}` names {unknown[0]!r}, which is not one of {', '.join(names)}")
    missing = [k for k in names if k not in box]
    if missing:
        raise ShapeError(f"{caller}: `{name}` has no bounds for {', '.join(missing)}; give (lo, hi) for each of "
                         f"{', '.join(names)}")
    return [box[k] for k in names]


def matrix_measure(A: Any) -> Any:
    r"""Banks' matrix measure :math:`\lambda(A) = \sup_{x}\langle Ax, x\rangle/\|x\|^2 = \max\operatorname{spec}((A+A^\top)/2)`.

    Parameters
    ----------
    A : array_like of shape (n, n), or a stack (N, n, n)

    Returns
    -------
    float, or numpy.ndarray of shape (N,) for a stack

    Raises
    ------
    ShapeError
        If A is not a finite square matrix (or stack of them).

    References
    ----------
    Banks (1980), §1 and Lemma 2.3.

    Examples
    --------
    >>> matrix_measure([[-1, -2], [2, -1]])  # Banks (1980), example 3.1
    -1.0
    """
    a = np.array(A, dtype=float)
    if a.ndim not in (2, 3) or a.shape[-1] != a.shape[-2]:
        raise ShapeError(f"matrix_measure: `A` must be square (or a stack of square matrices), found shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ShapeError("matrix_measure: `A` has non-finite entries")
    lam = np.linalg.eigvalsh((a + np.swapaxes(a, -1, -2)) / 2)[..., -1]
    return float(lam) if a.ndim == 2 else lam


def box_sup(fun: Callable[[np.ndarray], np.ndarray], box: np.ndarray, *, samples: int = 2000, refine: int = 3,
            seed: int = 0) -> tuple[float, np.ndarray]:
    """sup of a scalar function over a box: vectorised random samples (corners included), then L-BFGS-B.

    `fun` maps an array of points (k, d) to values (k,).
    """
    from scipy.optimize import minimize

    rng = np.random.default_rng(seed)
    d = box.shape[0]
    lo, hi = box[:, 0], box[:, 1]
    pts = lo + (hi - lo) * rng.random((samples, d))
    corners = min(2**d, 256)
    for c in range(corners):
        pts[c] = np.where([(c >> i) & 1 for i in range(d)], hi, lo)
    pts[corners % samples] = (lo + hi) / 2
    vals = np.asarray(fun(pts), dtype=float)
    if not np.all(np.isfinite(vals)):
        k = int(np.flatnonzero(~np.isfinite(vals))[0])
        raise ModelError(f"the function is not finite at {fmt_vec(pts[k])} inside the box; shrink the box")
    order = np.argsort(vals)[::-1][:refine]
    best_v, best_x = float(vals[order[0]]), pts[order[0]].copy()
    for k in order:
        res = minimize(lambda z: -float(fun(z[None, :])[0]), pts[k], bounds=list(map(tuple, box)), method="L-BFGS-B",
                       options={"maxiter": 100})
        if np.isfinite(res.fun) and -res.fun > best_v:
            best_v, best_x = float(-res.fun), np.asarray(res.x, dtype=float)
    return best_v, best_x


def _exprs(exprs: Any, variables: Sequence[str], name: str, caller: str) -> list[sp.Expr]:
    allowed = {v: symbol(v) for v in variables}
    if isinstance(exprs, (str, sp.Basic)):
        exprs = [exprs]
    out = []
    for k, e in enumerate(exprs):
        if isinstance(e, str):
            try:
                out.append(parse_expression(e, allowed))
            except ExpressionError as err:
                raise ModelError(f"{caller}: `{name}`[{k}] = {e!r}: {err}") from None
        else:
            out.append(to_expr(e, allowed, where=f"{caller}: `{name}`[{k}]"))
    return out


def _jacobian_fn(exprs: list[sp.Expr], variables: Sequence[str], wrt: int | None = None) -> Callable[[np.ndarray], np.ndarray]:
    """A vectorised Jacobian with respect to the first `wrt` variables: points (k, d) -> (k, len(exprs), wrt)."""
    import casadi as ca

    from ...engine import to_casadi

    x = ca.SX.sym("x", len(variables))
    e = to_casadi(exprs, {symbol(v): x[i] for i, v in enumerate(variables)})
    d = len(variables) if wrt is None else wrt
    J = ca.Function("J", [x], [ca.jacobian(e, x[:d])])
    r = len(exprs)

    def jac(pts: np.ndarray) -> np.ndarray:
        k = pts.shape[0]
        out = np.array(J.map(k)(pts.T))  # (r, k*d), blocks per point
        return out.reshape(r, k, d).transpose(1, 0, 2)

    return jac


def _sym_max(Js: np.ndarray) -> np.ndarray:
    return np.linalg.eigvalsh((Js + np.swapaxes(Js, 1, 2)) / 2)[:, -1]


@dataclass(frozen=True, eq=False)
class SlopeResult:
    r"""Maximum slope :math:`\mu_N` of a nonlinearity over a box (Banks (1980)), with the worst point."""

    mu: float
    worst_point: np.ndarray
    variables: tuple[str, ...]
    dissipative: bool
    tol: float
    samples: int = 2000

    def __str__(self) -> str:
        where = fmt_point(self.variables, self.worst_point)
        verdict = "dissipative (Lemma 2.3)" if self.dissipative else "NOT dissipative"
        return f"maximum slope μ_N ≈ {self.mu:.4g} over the box, at ({where}): {verdict} ({cite('003')}; {self.evidence})"

    @property
    def evidence(self) -> str:
        """A "NOT dissipative" verdict has a witness point; "dissipative" rests on sampling (a lower bound of μ_N)."""
        return "witness point" if not self.dissipative else SAMPLED.format(n=self.samples, r=3)


@renamed(box="region")
def max_slope(exprs: Any, variables: Sequence[str], region: Any, *, samples: int = 2000, seed: int = 0,
              tol: float = 1e-9) -> SlopeResult:
    r"""Maximum slope :math:`\mu_N = \sup \langle Nx - Nz, x - z\rangle/\|x - z\|^2` of N over a box.

    For C¹ N on a convex box, :math:`\mu_N = \sup_x\lambda(DN(x))` (mean-value theorem), estimated
    by :func:`box_sup`. N is dissipative (Banks (1980), Lemma 2.3) iff μ_N ≤ 0 (up to `tol`).

    Parameters
    ----------
    exprs : sequence of str or SymPy expressions
        The components of N (as many as `variables`).
    variables : sequence of str
    region : mapping of str to (low, high), or array_like of shape (d, 2)
        The box, by variable name (``{"x1": (-1, 1), ...}``) or as [low, high] pairs in the order of `variables`
        (its old name ``box`` is accepted until the next release).
    samples, seed : int
        Random points of the box and their seed; see :func:`box_sup`.
    tol : float
        μ_N ≤ tol counts as dissipative.

    Returns
    -------
    SlopeResult

    Raises
    ------
    ShapeError, DataError, ModelError
        Wrong box shape, NaN bounds, or unknown names in the expressions.

    References
    ----------
    Banks (1980), Lemma 2.3 (dissipative f1), Lemma 2.4 (μ_{f1} ≤ δ < ε).
    """
    caller = "max_slope"
    variables = tuple(variables)
    ex = _exprs(exprs, variables, "exprs", caller)
    if len(ex) != len(variables):
        raise ShapeError(f"{caller}: N must map R^{len(variables)} to itself: {len(ex)} components for {len(variables)} variables")
    b = check_box(region, len(variables), "region", caller, variables)
    jac = _jacobian_fn(ex, variables)
    mu, x = box_sup(lambda P: _sym_max(jac(P)), b, samples=samples, seed=seed)
    return SlopeResult(mu, x, variables, mu <= tol, tol, samples)


@dataclass(frozen=True, eq=False)
class BanksCheck:
    r"""Banks' condition :math:`\lambda(Df_1(x) + P\,DB(x)) \le -\varepsilon` over a region (Banks (1980), Thm 2.6)."""

    lam_max: float
    worst_point: np.ndarray
    variables: tuple[str, ...]
    epsilon: float
    holds: bool
    P: np.ndarray
    samples: int = 2000

    @property
    def evidence(self) -> str:
        """A failure has a witness point; "holds" rests on sampling (the max of λ is estimated from below)."""
        return "witness point" if not self.holds else SAMPLED.format(n=self.samples, r=3)

    @property
    def margin(self) -> float:
        """The largest ε for which the condition holds on the region (−λ_max)."""
        return -self.lam_max

    def __str__(self) -> str:
        where = fmt_point(self.variables, self.worst_point)
        bound = f"≤ -ε = {-self.epsilon:.4g}" if self.epsilon > 0 else "< 0"
        if self.holds:
            return (f"Banks' condition holds: max over the region of λ(Df1 + P·DB) = {self.lam_max:.4g} {bound} "
                    f"(worst point {where}); any Lipschitz perturbation with K < {self.margin:.4g} keeps an exponential "
                    f"observer ({cite('003')} Thm 2.6). Evidence: {self.evidence}")
        return (f"Banks' condition FAILS: λ(Df1 + P·DB) reaches {self.lam_max:.4g}, not {bound}, at {where}; "
                f"choose another injection gain P or a smaller region ({cite('003')} Thm 2.6)")


def banks_condition(f1: Any, B: Any, P: Any, variables: Sequence[str], region: Any, *, epsilon: float | None = None,
                    samples: int = 2000, seed: int = 0) -> BanksCheck:
    r"""Check :math:`\lambda(Df_1(x) + P\,DB(x)) \le -\varepsilon` for all x in a box (Banks (1980), Theorem 2.6).

    Parameters
    ----------
    f1 : sequence of expressions (n)
        The analytic part of the vector field.
    B : sequence of expressions (m)
        The observation map y = B(x).
    P : array_like of shape (n, m)
        The injection gain: x̂' = f(x̂) + P(B(x̂) − y).
    variables : sequence of str
        The state names (n).
    region : mapping of str to (low, high), or array_like of shape (n, 2)
        The box Ω (convex, as the theorem requires), by variable name or in the order of `variables`.
    epsilon : float, optional
        The ε to check; default: the condition holds when the max is < 0 (any ε up to the margin).
    samples, seed : int
        Random points of the box (corners and centre included) and their seed; see :func:`box_sup`.

    Returns
    -------
    BanksCheck
        With the worst point and the margin ε = −max λ.

    Raises
    ------
    ShapeError, DataError, ModelError
        On shapes, a region with NaN bounds, or unknown names.

    References
    ----------
    Banks (1980), Theorem 2.6; examples 3.1 (P = (−2, 1)ᵀ, λ = −1) and 3.2 (gains (−1, 4), λ ≤ −1).
    (Example 3.1's text prints the injection as P(x1 + x2); Lemma 2.3's proof shows it is P·(ŷ − y).)
    """
    caller = "banks_condition"
    variables = tuple(variables)
    n = len(variables)
    f = _exprs(f1, variables, "f1", caller)
    b = _exprs(B, variables, "B", caller)
    if len(f) != n:
        raise ShapeError(f"{caller}: `f1` must have {n} components (one per variable), found {len(f)}")
    Pm = np.array(P, dtype=float)
    if Pm.ndim == 1:
        Pm = Pm.reshape(n, -1) if Pm.size == n * len(b) else Pm
    if Pm.shape != (n, len(b)):
        raise ShapeError(f"{caller}: incompatible dimensions of `P`: expected ({n}, {len(b)}), found {Pm.shape}")
    if not np.all(np.isfinite(Pm)):
        raise ShapeError(f"{caller}: `P` has non-finite entries")
    box = check_box(region, n, "region", caller, variables)
    jf = _jacobian_fn(f, variables)
    jb = _jacobian_fn(b, variables)
    lam, x = box_sup(lambda X: _sym_max(jf(X) + Pm @ jb(X)), box, samples=samples, seed=seed)
    eps = 0.0 if epsilon is None else float(epsilon)
    return BanksCheck(lam, x, variables, eps, lam <= -eps and (epsilon is not None or lam < 0), Pm, samples)


@dataclass(frozen=True, eq=False)
class LipschitzEstimate:
    r"""Estimate of a Lipschitz constant :math:`\gamma = \sup_{box}\|DN\|_2` on a convex box, with the worst point.

    Sampling can only under-estimate the sup (a lower estimate of the true constant).
    """

    gamma: float
    worst_point: np.ndarray
    variables: tuple[str, ...]
    samples: int
    what: str = "N"
    A: np.ndarray | None = None

    def __str__(self) -> str:
        return (f"Lipschitz constant of {self.what} over the box: γ ≈ {self.gamma:.4g} (largest ‖D{self.what.split()[0]}‖₂, at "
                f"{fmt_point(self.variables, self.worst_point)}; {self.evidence})")

    @property
    def evidence(self) -> str:
        return SAMPLED.format(n=self.samples, r=3)


@renamed(box="region")
def lipschitz_bound(exprs: Any, variables: Sequence[str], region: Any, *, wrt: int | None = None, samples: int = 2000,
                    seed: int = 0) -> LipschitzEstimate:
    r"""Estimate the Lipschitz constant :math:`\sup_x\|DN(x)\|_2` of N over a (convex) box, with the worst point.

    For Banks' perturbation f2 (Banks (1980), Theorem 2.6 needs K < ε) and the Lipschitz form of Besançon (2010). With
    `wrt` = k only the first k variables are differentiated (the rest, e.g. inputs, range over the box).

    Parameters
    ----------
    exprs : sequence of str or SymPy expressions
        The components of N.
    variables : sequence of str
    region : mapping of str to (low, high), or array_like of shape (d, 2)
        The box, by variable name (``{"x1": (-1, 1), ...}``) or as [low, high] pairs in the order of `variables`
        (its old name ``box`` is accepted until the next release).
    wrt : int, optional
        Differentiate with respect to the first `wrt` variables only.
    samples, seed : int
        Random points of the box and their seed; see :func:`box_sup`.

    Returns
    -------
    LipschitzEstimate
    """
    caller = "lipschitz_bound"
    variables = tuple(variables)
    ex = _exprs(exprs, variables, "exprs", caller)
    b = check_box(region, len(variables), "region", caller, variables)
    jac = _jacobian_fn(ex, variables, wrt)
    gamma, x = box_sup(lambda P: np.linalg.norm(jac(P), ord=2, axis=(1, 2)), b, samples=samples, seed=seed)
    return LipschitzEstimate(gamma, x, variables, samples)
