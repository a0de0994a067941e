r"""State augmentation (Viegas, Batista, Oliveira & Silvestre (2015)): mimicking LTV systems, injectivity, left inverses, and an automatic
augmentation by closing the span of the output's time derivatives.

A system :math:`\dot w = A(t, u, y)w + b(t, u, y)`, :math:`z = C(t, u, y)w` *mimics*
:math:`\dot x = f(x, u)`, :math:`y = h(x)` through :math:`w = T(x)` (Viegas, Batista, Oliveira & Silvestre (2015), Def. 3, eq. 2) when,
identically,

.. math::

    \frac{\partial T}{\partial x}(x)\,f(x, u) = A(t, u, h(x))\,T(x) + b(t, u, h(x)), \qquad C\,T(x) = h(x).

Then (Viegas, Batista, Oliveira & Silvestre (2015), Theorem 1) if the LTV system is observable along the input and output, the model is
observable iff T is injective, and an observer for w gives :math:`\hat x = T'(\hat w)` through a
left inverse (Lemmas 1-2).

Beyond the paper (its stated future work, §V): :func:`propose_augmentation` builds T, A, b, C
automatically for polynomial dynamics. Starting from the states and the output, it takes the time
derivative of each new function, splits it into groups of terms that share the same coefficient
(a function of the known signals u, y, t and the parameters), keeps the groups already in the
span, and adds the others as new states, until the span is closed. Grouping by coefficient is what
keeps x1·x3 − x2·x2 as *one* state in Viegas, Batista, Oliveira & Silvestre (2015), §IV-B instead of the two that make (19) unobservable.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from ..._deprecate import renamed
from ...errors import FormError, ModelError, ShapeError
from ...model import TIME, System, symbol
from ...model._forms import matrix_of
from ...model._system import ExprLike, exact
from ..trajectory._gramian import GramianResult, ltv_gramian
from ...algebra._identity import decide_identity, exact_generic_rank
from .._reports import clean_direction, fmt_vec
from ...references import cite

__all__ = ["Augmentation", "MimickingCheck", "check_mimicking", "propose_augmentation", "InjectivityCheck",
           "injectivity", "LeftInverseBounds", "left_inverse_bounds", "AugmentedObservability", "augmented_observability"]

REF = f"{cite('001')}"


def _known(system: System) -> dict[str, sp.Symbol]:
    out = {k: symbol(k) for k in (*system.inputs, *system.outputs, *system.params)}
    out["t"] = TIME
    return out


@dataclass(frozen=True, eq=False)
class Augmentation:
    r"""A mimicking system :math:`\dot w = A(u, y, t)w + b(u, y, t)`, :math:`y = Cw`, with :math:`w = T(x)` (Viegas, Batista, Oliveira & Silvestre (2015), eq. 2)."""

    system: System
    T: tuple[sp.Expr, ...]
    A: sp.Matrix
    b: sp.Matrix
    C: sp.Matrix
    names: tuple[str, ...] = ()
    left_inverse: tuple[sp.Expr, ...] | None = None

    @property
    def n_w(self) -> int:
        return len(self.T)

    def __str__(self) -> str:
        lines = [f"augmentation of {self.system.name!r} to {self.n_w} states ({cite('001')} Def. 5):"]
        for i, e in enumerate(self.T):
            lines.append(f"  w{i + 1} = {e}")
        lines.append(f"  A(u, y, t) = {self.A.tolist()}")
        if any(e != 0 for e in self.b):
            lines.append(f"  b(u, y, t) = {list(self.b)}")
        lines.append(f"  C = {self.C.tolist()}")
        return "\n".join(lines)


@dataclass(frozen=True)
class MimickingCheck:
    """Whether (A, b, C) mimics the model through T (Viegas, Batista, Oliveira & Silvestre (2015), Def. 3), with the failing row if not.

    Attributes
    ----------
    status : {"holds", "fails", "undecided"}
        Decided by :func:`nlobs.analysis.decide_identity` row by row.
    reason : str
        The failing (or undecided) row and its residual.
    residuals : tuple of SymPy expressions
    evidence : str
        The kind of evidence behind the verdict.
    """

    status: str
    reason: str
    residuals: tuple[sp.Expr, ...] = ()
    evidence: str = ""

    @property
    def holds(self) -> bool:
        return self.status == "holds"

    def __str__(self) -> str:
        if self.holds:
            return (f"mimics the model: dT/dt = A T + b along f and C T = h, identically ({cite('001')} Def. 3; "
                    f"{self.evidence})")
        if self.status == "undecided":
            return f"mimicking NOT decided: {self.reason}"
        return f"does NOT mimic the model: {self.reason}"


def _as_augmentation(system: System, T: Sequence[ExprLike], A: Any, C: Any, b: Any = None, B: Any = None,
                     left_inverse: Sequence[ExprLike] | None = None) -> Augmentation:
    allowed = {**_known(system), **{k: symbol(k) for k in system.states}}
    p = len(T)
    Tm = matrix_of(list(T), p, 1, allowed, name="T")
    known = _known(system)
    Am = matrix_of(A, p, p, known, name="A")
    Cm = matrix_of(C, system.n_outputs, p, known, name="C")
    if b is not None and B is not None:
        raise ModelError("give the input term either as `b` (a vector in u, y, t) or as `B` (so that b = B u), not both")
    if B is not None:
        Bm = matrix_of(B, p, system.n_inputs, known, name="B")
        bm = Bm * sp.Matrix(system.u) if system.n_inputs else sp.zeros(p, 1)
    else:
        bm = matrix_of(list(b) if b is not None else [0] * p, p, 1, known, name="b")
    inv = None
    if left_inverse is not None:
        ws = {f"w{i + 1}": symbol(f"w{i + 1}") for i in range(p)}
        inv = tuple(matrix_of(list(left_inverse), system.n_states, 1, {**known, **ws}, name="left_inverse"))
    return Augmentation(system, tuple(Tm), Am, bm, Cm, tuple(f"w{i + 1}" for i in range(p)), inv)


def check_mimicking(system: System, T: Sequence[ExprLike] | Augmentation, A: Any = None, C: Any = None, *,
                    b: Any = None, B: Any = None) -> MimickingCheck:
    r"""Verify symbolically that :math:`\dot w = A w + b`, :math:`y = Cw` mimics the model through w = T(x).

    Checks :math:`\partial T/\partial x\,f = A(u, h(x), t)\,T + b` and :math:`C\,T = h` identically in
    (x, u, t) (outputs inside A, b, C are replaced by h(x)).

    Parameters
    ----------
    system : System
    T : sequence of expressions in the states, or an :class:`Augmentation`
    A : (p, p) matrix of expressions in the inputs, outputs, t and parameters
    C : (n_outputs, p) matrix
    b : sequence of p expressions, optional
        Input term b(u, y, t); or give `B` with b = B u (Viegas, Batista, Oliveira & Silvestre (2015), eq. 2 with v = u).

    Returns
    -------
    MimickingCheck
        With the first failing row and its residual when the identity does not hold.

    References
    ----------
    Viegas, Batista, Oliveira & Silvestre (2015), Definition 3, eq. (2); eqs. (16), (18), (19), (21).
    """
    aug = T if isinstance(T, Augmentation) else _as_augmentation(system, T, A, C, b, B)
    x = sp.Matrix(system.x)
    y_of_x = dict(zip(system.y, system.h))
    Tm = sp.Matrix(aug.T)
    lhs = Tm.jacobian(x) * sp.Matrix(system.f)
    rhs = aug.A.xreplace(y_of_x) * Tm + aug.b.xreplace(y_of_x)
    residuals = []
    verdicts = []
    for i in range(aug.n_w):
        r = lhs[i] - rhs[i]
        residuals.append(r)
        v = decide_identity(r, 0, seed=i)
        verdicts.append(v)
        if not v.holds:
            why = f"row {i + 1} (w{i + 1} = {aug.T[i]}): dT/dt - (A T + b) = {sp.simplify(r)}"
            return MimickingCheck(v.status, why + (f", not 0{v.where()}" if v.fails else f": {v.method}"), tuple(residuals),
                                  v.evidence)
    out = aug.C.xreplace(y_of_x) * Tm
    for j, name in enumerate(system.outputs):
        v = decide_identity(out[j], system.h[j], seed=j)
        verdicts.append(v)
        if not v.holds:
            return MimickingCheck(v.status, f"C T(x) differs from the output {name} = {system.h[j]} by "
                                  f"{sp.simplify(out[j] - system.h[j])}{v.where()}", tuple(residuals), v.evidence)
    bound = sum(v.error_bound for v in verdicts)
    kinds = ", ".join(sorted({v.evidence.split(" (Schwartz")[0] for v in verdicts}))
    return MimickingCheck("holds", "", tuple(residuals), kinds + (f"; P(wrong) <= {bound:.0e} (Schwartz-Zippel)" if bound else ""))


def _to_signal(e: sp.Expr, system: System) -> sp.Expr:
    """Replace every power of an output's radicand by powers of y: sqrt(s) -> y, s**(-1/2) -> 1/y, s -> y**2."""
    for ysym, h in zip(system.y, system.h):
        if h.is_Pow and h.exp.is_Rational and not h.exp.is_Integer:
            s, ex = h.base, h.exp
            e = e.replace(lambda z: z.is_Pow and z.base == s, lambda z: ysym ** (z.exp / ex))
        else:
            e = e.xreplace({h: ysym})
    return e


def propose_augmentation(system: System, *, max_degree: int = 4, max_states: int = 60) -> Augmentation:
    r"""Build a state augmentation w = T(x) = [x; T_a(x)] and a mimicking system automatically.

    Polynomial dynamics are required (outputs may be a fractional power of a polynomial, such as
    the range ‖p‖ = (p·p)^½, which then enters A as y). The span of {x, h} is closed under the time
    derivative: each derivative is split into groups of terms with a common coefficient in the
    known signals (u, y, t, parameters); a group already in the span contributes a column of A, a
    group with no state contributes to b, and any other group becomes a new state.

    Parameters
    ----------
    system : System
    max_degree : int
        Largest total degree of a new state (in x).
    max_states : int
        Largest number of augmented states.

    Returns
    -------
    Augmentation
        T, A(u, y, t), b(u, y, t), C and the left inverse [I 0] (Viegas, Batista, Oliveira & Silvestre (2015), Def. 5). The result is
        re-verified with :func:`check_mimicking`.

    Raises
    ------
    FormError
        If the dynamics are not polynomial, or the span does not close within the limits (naming
        the function that kept growing).

    References
    ----------
    Viegas, Batista, Oliveira & Silvestre (2015), Def. 5, §IV-A eq. (16), §IV-B eq. (18), §IV-C eq. (21), §V (future work).
    """
    x = list(system.x)
    xs = set(x)
    f = [sp.expand(e) for e in system.f]
    for name, e in zip(system.states, f):
        if not e.is_polynomial(*x):
            raise FormError(f"propose_augmentation: {name}' = {e} is not polynomial in the states; the span closure needs "
                            "polynomial dynamics")
    funcs: list[sp.Expr] = list(x)  # the functions w_j(x)
    polys: list[sp.Poly | None] = [sp.Poly(s, *x) for s in x]
    for h in system.h:
        if h.is_polynomial(*x):
            P = sp.Poly(h, *x)
            if not _in_span(P, [q for q in polys if q is not None])[0]:
                funcs.append(h)
                polys.append(P)
        else:
            funcs.append(h)  # kept as an opaque state equal to the output (its derivative is computed directly)
            polys.append(None)
    rows: dict[int, list[tuple[sp.Expr, sp.Poly]]] = {}
    consts: dict[int, sp.Expr] = {}
    k = 0
    while k < len(funcs):
        if len(funcs) > max_states:
            raise FormError(f"propose_augmentation: more than {max_states} states needed; the span does not close "
                            f"(last added: {funcs[-1]}). Raise `max_states` or choose another output")
        w = funcs[k]
        dw = sum((sp.diff(w, s) * fi for s, fi in zip(x, f)), sp.Integer(0))
        dw = sp.expand(_to_signal(sp.expand(dw), system))
        if not dw.free_symbols & xs:
            groups: dict[sp.Expr, sp.Expr] = {}
        else:
            groups = {}
            for term in sp.Add.make_args(dw):
                coeff, mono = sp.Integer(1), sp.Integer(1)
                for fac in sp.Mul.make_args(term):
                    if fac.free_symbols & xs:
                        mono *= fac
                    else:
                        coeff *= fac
                num, c0 = coeff.as_coeff_Mul()
                groups[c0] = groups.get(c0, sp.Integer(0)) + num * mono
        const = sp.Integer(0)
        entries: list[tuple[sp.Expr, sp.Poly]] = []
        for c0, P in groups.items():
            if not (P.free_symbols & xs):
                const += c0 * P
                continue
            if not P.is_polynomial(*x):
                raise FormError(f"propose_augmentation: the derivative of {w} has the term {c0 * P}, which is not polynomial "
                                "in the states once the output is replaced by y")
            poly = sp.Poly(P, *x)
            entries.append((c0, poly))
        if not dw.free_symbols & xs:
            const = dw
        consts[k] = const
        rows[k] = entries
        for c0, poly in entries:
            ok, _ = _in_span(poly, [q for q in polys if q is not None])
            if not ok:
                if poly.total_degree() > max_degree:
                    raise FormError(f"propose_augmentation: the derivative of {w} needs the new function {poly.as_expr()} of "
                                    f"degree {poly.total_degree()} > max_degree = {max_degree}; the span does not close")
                content, prim = poly.primitive()
                lead = prim.coeffs()[0]
                new = sp.Poly(prim.as_expr() * sp.sign(lead), *x)
                funcs.append(new.as_expr())
                polys.append(new)
        k += 1
    p = len(funcs)
    A = sp.zeros(p, p)
    b = sp.zeros(p, 1)
    basis_idx = [i for i, q in enumerate(polys) if q is not None]
    basis = [polys[i] for i in basis_idx]
    for j in range(p):
        for c0, poly in rows[j]:
            ok, lam = _in_span(poly, basis)
            for i, l in zip(basis_idx, lam):
                if l != 0:
                    A[j, i] += c0 * l
        b[j] = consts[j]
    C = sp.zeros(system.n_outputs, p)
    for r, h in enumerate(system.h):
        if h in funcs and polys[funcs.index(h)] is None:
            C[r, funcs.index(h)] = 1
        else:
            ok, lam = _in_span(sp.Poly(h, *x), basis)
            for i, l in zip(basis_idx, lam):
                C[r, i] = l
    names = tuple(f"w{i + 1}" for i in range(p))
    inv = tuple(symbol(f"w{i + 1}") for i in range(system.n_states))
    aug = Augmentation(system, tuple(funcs), A.applyfunc(sp.simplify), b.applyfunc(sp.simplify), C, names, inv)
    chk = check_mimicking(system, aug)
    if not chk.holds:  # a guard on this function itself, not on user input
        raise FormError(f"propose_augmentation: internal check failed: {chk.reason}")
    return aug


def _in_span(P: sp.Poly, basis: list[sp.Poly]) -> tuple[bool, list[sp.Expr]]:
    """Is P a linear combination (rational coefficients) of the basis polynomials? Return the coefficients."""
    if not basis:
        return P.is_zero, []
    monos = sorted({m for q in (*basis, P) for m in q.as_dict()})
    idx = {m: i for i, m in enumerate(monos)}
    M = sp.zeros(len(monos), len(basis))
    for j, q in enumerate(basis):
        for m, c in q.as_dict().items():
            M[idx[m], j] = c
    v = sp.zeros(len(monos), 1)
    for m, c in P.as_dict().items():
        v[idx[m], 0] = c
    try:
        sol, params = M.gauss_jordan_solve(v)
    except ValueError:
        return False, []
    sol = sol.xreplace({t: 0 for t in params})
    return True, list(sol)


@dataclass(frozen=True)
class InjectivityCheck:
    """Is T injective? (Viegas, Batista, Oliveira & Silvestre (2015), Theorem 1: the model is observable iff T is, given an observable mimicking system.)"""

    injective: bool | None
    reason: str

    def __str__(self) -> str:
        verdict = {True: "T is injective", False: "T is NOT injective", None: "injectivity of T not decided"}[self.injective]
        return f"{verdict}: {self.reason}"


def injectivity(system: System, T: Sequence[ExprLike] | Augmentation, *, left_inverse: Sequence[ExprLike] | None = None,
                samples: int = 20, seed: int = 0) -> InjectivityCheck:
    r"""Test injectivity of w = T(x) (Viegas, Batista, Oliveira & Silvestre (2015), Theorem 1).

    Proofs: T contains every state as a component (a state augmentation function, Viegas, Batista, Oliveira & Silvestre (2015), Def. 5, with
    left inverse [I 0]), or the given left inverse satisfies T'(T(x)) = x identically. Disproof: the
    Jacobian ∂T/∂x has rank < n at every sampled point (T is then not an immersion, hence not
    injective on any open set). Otherwise undecided.

    Parameters
    ----------
    system : System
    T : sequence of expressions in the states, or an Augmentation
    left_inverse : sequence of expressions in ``w1, w2, ...``, optional
        A candidate T' with T'(T(x)) = x.
    samples : int
        Random points for the Jacobian-rank disproof.
    seed : int
        Seed of those points.

    Returns
    -------
    InjectivityCheck
    """
    if isinstance(T, Augmentation):
        T = list(T.T)
    allowed = {**_known(system), **{k: symbol(k) for k in system.states}}
    Tm = matrix_of(list(T), len(T), 1, allowed, name="T")
    x = list(system.x)
    pos = [next((i for i, e in enumerate(Tm) if e == s), None) for s in x]
    if all(p is not None for p in pos):
        return InjectivityCheck(True, "every state is a component of T (w" + ", w".join(str(p + 1) for p in pos)
                                + f"), so T'(w) = [I 0] w is a left inverse ({cite('001')} Def. 5)")
    if left_inverse is not None:
        ws = [symbol(f"w{i + 1}") for i in range(len(T))]
        inv = matrix_of(list(left_inverse), system.n_states, 1, {**allowed, **{w.name: w for w in ws}}, name="left_inverse")
        back = inv.xreplace(dict(zip(ws, Tm)))
        verdicts = [decide_identity(back[i], x[i], seed=i) for i in range(system.n_states)]
        bad = [i for i, v in enumerate(verdicts) if not v.holds]
        if not bad:
            kinds = ", ".join(sorted({v.evidence for v in verdicts}))
            return InjectivityCheck(True, f"the given left inverse satisfies T'(T(x)) = x identically ({cite('001')} Def. 4; "
                                    f"{kinds})")
        v = verdicts[bad[0]]
        return InjectivityCheck(None, f"the given left inverse does not recover {system.states[bad[0]]}: T'(T(x)) = {back[bad[0]]}"
                                + (v.where() if v.fails else f" ({v.method})"))
    pv = {symbol(k): exact(v) for k, v in system.params.items()}
    J = Tm.jacobian(x).xreplace(pv)
    gr = exact_generic_rank(J, seed=seed, tries=max(1, min(samples, 5)))
    if gr.rank < len(x):
        return InjectivityCheck(False, f"∂T/∂x has generic rank {gr.rank} < {len(x)} ({gr.evidence}): T collapses a "
                                "direction and cannot be injective")
    return InjectivityCheck(None, f"∂T/∂x has full rank ({gr.evidence}; T is an immersion), which proves local, not global, "
                            "injectivity; give a left inverse to prove injectivity")


@dataclass(frozen=True)
class LeftInverseBounds:
    """Lipschitz constants of a left inverse T' (Viegas, Batista, Oliveira & Silvestre (2015), Lemma 1: upper α; Lemma 2: also a lower bound)."""

    upper: float
    lower: float
    linear: bool

    @property
    def lemma1(self) -> bool:
        return bool(np.isfinite(self.upper))

    @property
    def lemma2(self) -> bool:
        return self.lower > 0 and self.lemma1

    def __str__(self) -> str:
        s = f"‖T'(wa) − T'(wb)‖ ≤ {self.upper:.4g}‖wa − wb‖ ({cite('001')} Lemma 1 holds: exponential convergence of x̂ = T'(ŵ))"
        if self.lemma2:
            return s + f"; and ≥ {self.lower:.4g}‖wa − wb‖ (Lemma 2: global exponential convergence)"
        return s + "; no positive lower bound (Lemma 2 does not apply: T' maps a larger space onto x)"


@renamed(box="region")
def left_inverse_bounds(left_inverse: Sequence[ExprLike], n_w: int, *, region: Any = None) -> LeftInverseBounds:
    r"""Lipschitz bounds of a left inverse T': R^p -> R^n (Viegas, Batista, Oliveira & Silvestre (2015), Lemmas 1-2).

    Linear T'(w) = L w: the exact bounds σ_max(L) and, when p = n, σ_min(L) (for p > n the lower
    bound is 0: Lemma 2 cannot hold, as Viegas, Batista, Oliveira & Silvestre (2015) notes for [I 0]). Nonlinear T': the upper bound is
    estimated as sup ‖DT'‖₂ over `region` (required).

    Parameters
    ----------
    left_inverse : sequence of expressions in ``w1, ..., wp``
        T'(w), one expression per original state.
    n_w : int
        p, the dimension of w.
    region : mapping of ``w1..wp`` to (low, high), or array_like of shape (p, 2), optional
        Region of w for a nonlinear T' (old name ``box``).

    Returns
    -------
    LeftInverseBounds

    References
    ----------
    Viegas, Batista, Oliveira & Silvestre (2015), Lemma 1 eq. (3), Lemma 2 eq. (9), remark after Def. 5.
    """
    from ._conditions import lipschitz_bound

    ws = [symbol(f"w{i + 1}") for i in range(n_w)]
    inv = matrix_of(list(left_inverse), len(left_inverse), 1, {w.name: w for w in ws}, name="left_inverse")
    J = inv.jacobian(ws)
    if not J.free_symbols:
        L = np.array(J, dtype=float)
        s = np.linalg.svd(L, compute_uv=False)
        lower = float(s.min()) if L.shape[0] == L.shape[1] else 0.0
        return LeftInverseBounds(float(s.max()), lower, True)
    if region is None:
        raise ShapeError("left_inverse_bounds: a nonlinear left inverse needs `region` ([low, high] per w) to bound its slope")
    up = lipschitz_bound(list(inv), [w.name for w in ws], region).gamma
    return LeftInverseBounds(up, 0.0, False)


@dataclass(frozen=True, eq=False)
class AugmentedObservability:
    """The augmented LTV system along one trajectory of the model: Gramian rank and unobservable combinations."""

    gramian: GramianResult
    names: tuple[str, ...]
    T: tuple[sp.Expr, ...]

    @property
    def observable(self) -> bool:
        return self.gramian.observable

    def __str__(self) -> str:
        head = str(self.gramian)
        if self.observable:
            return "augmented system " + head
        lines = ["augmented system " + head.split(";")[0] + "; unobservable combinations of w:"]
        for v in self.gramian.unobservable_directions:
            c = clean_direction(v)
            terms = [f"{c[i]:+.3g}·{self.names[i]}" for i in range(len(c)) if c[i] != 0]
            lines.append("  " + " ".join(terms) + f"   ({fmt_vec(c, 3)})")
        return "\n".join(lines)


def augmented_observability(system: System, aug: Augmentation, x0: Any, *, t_final: float, dt: float = 1e-2,
                            inputs: Any = None, rtol: float = 1e-9) -> AugmentedObservability:
    r"""Observability of the mimicking LTV system along the model's trajectory from x0 (Viegas, Batista, Oliveira & Silvestre (2015), Theorem 1).

    The model is simulated (RK4) under `inputs`; A(t) = A(u(t), y(t), t) is sampled on the grid
    and the Gramian W(0, T) of (A(t), C) is computed (Wang, Ortega & Bobtsov (2021), eq. 3). With T injective, a full rank
    proves observability of the model for this input (Viegas, Batista, Oliveira & Silvestre (2015), Theorem 1); the unobservable directions
    are reported as combinations of the w's (Viegas, Batista, Oliveira & Silvestre (2015), §IV-B: only w6 + w7 is seen in (19)).

    Parameters
    ----------
    system : System
        The model (simulated to get u(t) and y(t)).
    aug : Augmentation
        T, A(u, y, t), b and C (from :func:`propose_augmentation`, or a user's, checked with
        :func:`check_mimicking`).
    x0 : array_like of shape (n,)
        Initial state of the model.
    t_final : float
        Horizon T of W(0, T).
    dt : float
        RK4 step and sampling of A(t).
    inputs : signal-like or mapping, optional
        The known inputs (numbers, expressions of t, callables); default zero.
    rtol : float
        Rank threshold on the Jacobi-scaled Gramian (see :func:`ltv_gramian`).

    Returns
    -------
    AugmentedObservability

    Raises
    ------
    ShapeError
        If x0 does not have n finite entries.
    """
    from ...model._translate import NUMPY, translate
    from ..trajectory._gramian import _simulator

    caller = "augmented_observability"
    x0 = np.asarray(x0, dtype=float).ravel()
    if x0.size != system.n_states or not np.all(np.isfinite(x0)):
        raise ShapeError(f"{caller}: `x0` must hold {system.n_states} finite numbers, got {x0.size}")
    sim, _, t, U = _simulator(system, t_final, dt, inputs, None, caller, with_inputs=True)
    Y = np.array(sim(x0))
    leaves: dict[sp.Symbol, Any] = {TIME: t}
    leaves.update({s: U[:, i] for i, s in enumerate(system.u)})
    leaves.update({s: Y[:, i] for i, s in enumerate(system.y)})
    pv = {symbol(k): v for k, v in system.params.items()}
    p = aug.n_w
    Avals = np.empty((t.size, p, p))
    for (i, j), e in np.ndenumerate(np.array(aug.A.xreplace(pv), dtype=object)):
        Avals[:, i, j] = np.broadcast_to(np.asarray(translate(e, leaves, NUMPY), dtype=float), t.shape)
    Cvals = np.empty((t.size, system.n_outputs, p))
    for (i, j), e in np.ndenumerate(np.array(aug.C.xreplace(pv), dtype=object)):
        Cvals[:, i, j] = np.broadcast_to(np.asarray(translate(e, leaves, NUMPY), dtype=float), t.shape)
    g = ltv_gramian(Avals, Cvals, t, rtol=rtol)
    return AugmentedObservability(g, aug.names or tuple(f"w{i + 1}" for i in range(p)), aug.T)

