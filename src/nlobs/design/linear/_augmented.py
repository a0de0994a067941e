"""Observers on a mimicking augmented system (Viegas, Batista, Oliveira & Silvestre (2015)): a linear observer in w = T(x), x̂ = T⁺(ŵ)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ...algebra._identity import decide_identity
from ...engine import to_casadi
from ...errors import FormError, ModelError, PreconditionError
from ...model import TIME, System, symbol
from ...model._forms import matrix_of
from ...model._system import ExprLike, exact
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign, Symbols
from .._checks import identity_check, observer_gain
from .._common import require_system
from .._constructions import evaluate, text
from ..kalman._riccati import StateAffineParts, _riccati_design
from .._kind import Tuning, kind
from .._tune import CA_on_run, clean_message, fmt, poles_for, square

__all__ = ["design_augmented"]

REF = (f"{cite('001')}: mimicking systems (2), Def. 3, Theorem 1 (observable iff T injective), "
       "Lemma 1 (observer through a left inverse); §IV-A eqs. (15)-(16), §IV-B (17)-(18), §IV-C (20)-(22)")


def _states_only(Tm: sp.Matrix, system: System, caller: str) -> sp.Matrix:
    """T, refused by name when it depends on an input: w = T(x) must be a function of the states."""
    through = sorted({v.name for v in Tm.free_symbols & set(system.u)})
    if through:
        raise PreconditionError(f"{caller}: T depends on the input {', '.join(through)}; w = T(x) must be a function of the "
                                f"states (its initial value is T(x̂0), and the mimicking of {cite('001', 'Def. 3')} holds for "
                                "every input): write T in the states only")
    return Tm


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def tune_augmented(ctx: Any) -> Tuning:
    from ...analysis import propose_augmentation

    try:
        aug = propose_augmentation(ctx.system, max_degree=3, max_states=min(4 * ctx.n + 2, 18))
    except (FormError, ModelError) as e:
        return Tuning.needs(f"T(x), A(u, y, t), C and a left inverse such that the augmented system mimics the model "
                       f"({cite('001', 'Def. 3')}); nlobs could not close the span automatically: {clean_message(e)}",
                       T="...", A="...", C="...", left_inverse="...")
    through = sorted({v.name for e in aug.T for v in e.free_symbols & set(ctx.system.u)})
    if through:   # w = T(x) must be a function of the states: its initial value and the mimicking rest on it
        return Tuning.fails(f"the span of the outputs' derivatives needs the input ({', '.join(through)}) inside T: an output "
                            "with direct feedthrough is not a function of the states, and T(x) must be one "
                            f"({cite('001', 'Def. 3')})")
    if aug.n_w == ctx.n:
        return Tuning.fails("not needed: the model is already state-affine in its own coordinates (the span of the outputs' "
                      "derivatives closes on x itself); this would be the filter of `kalman_bucy`")
    opts: dict[str, Any] = {"T": [text(e) for e in aug.T], "A": [[text(e) for e in row] for row in aug.A.tolist()],
                            "C": [[text(e) for e in row] for row in aug.C.tolist()],
                            "left_inverse": [text(e) for e in aug.left_inverse], "b": [text(e) for e in aug.b]}
    tuning = f"constructed: w = T(x) with {aug.n_w} states mimics the model (span of the output derivatives closed)"
    params = {sp.Symbol(k, real=True): v for k, v in ctx.system.params.items()}
    ys = set(ctx.system.y)
    if not any(e.xreplace(params).free_symbols for e in aug.A) and not any(e.free_symbols & ys for e in aug.b):
        opts["poles"] = poles_for(aug.n_w, ctx.omega_o)
        return Tuning.tuned(opts, tuning + f"; A constant: Luenberger with poles {fmt(opts['poles'])}")
    if ctx.nominal is None:
        return Tuning.needs("Q and R for the Kalman–Bucy filter on the augmented system, and a run to scale them", **opts)
    W = evaluate(list(aug.T), ctx.system, ctx.samples(300))
    span, mag = W.max(axis=0) - W.min(axis=0), np.abs(W).max(axis=0)
    sw = np.maximum(np.where(span > 0.05 * mag, span, 0.5 * mag), 1e-6)        # the states' scale rule, for w = T(x)
    for i, e in enumerate(aug.T):                                                 # components that are states: their P(0)
        if e in ctx.system.x:
            sw[i] = float(np.sqrt(ctx.P0[ctx.system.x.index(e), ctx.system.x.index(e)]))
    Qw = np.diag((0.01 * sw) ** 2 * ctx.omega_p)
    Cw = np.array(aug.C.xreplace(params), dtype=float) if not aug.C.xreplace(params).free_symbols else None
    W, M0, note = ctx.riccati_weights(ctx.R_rate, np.diag(sw ** 2), Qw, Cw, CA_on_run(ctx, (aug.C * aug.A).xreplace(params)))
    opts.update({"Q": square(Qw), "R": square(W), "P0": square(M0)})
    return Tuning.tuned(opts, tuning + "; A(u, y, t) or b(u, y, t) varies: Kalman–Bucy filter on the augmented system, Q, R as for kalman_bucy",
                    extra=note)


@kind('augmented', summary='linear observer on a system that mimics the model through w = T(x)',
      references=(work("001", "Theorem 1, Lemma 1"),), tune=tune_augmented)
def design_augmented(system: System, *, T: Sequence[ExprLike], A: Any, C: Any, left_inverse: Sequence[ExprLike],
                     b: Sequence[ExprLike] | None = None, poles: Any = None, L: Any = None, Q: Any = None, R: Any = None,
                     P0: Any = None, xhat0: Any = None) -> ObserverDesign:
    r"""Linear observer on a system that mimics the model through w = T(x) (Viegas, Batista, Oliveira & Silvestre (2015)).

    The augmented system :math:`\dot w = A(u, y, t)w + b(u, y, t)`, :math:`y = Cw` mimics
    :math:`\dot x = f(x, u, t)`, :math:`y = h(x)` when, identically in (x, u, t) and with
    y replaced by h(x) inside A and b,

    .. math::

        \frac{\partial T}{\partial x} f(x, u, t) = A(u, h(x), t)\,T(x) + b(u, h(x), t), \qquad C\,T(x) = h(x).

    Both identities and the left inverse :math:`T^+(T(x)) = x` are decided exactly (:func:`nlobs.analysis.decide_identity`) before
    the gain is computed; the estimate is :math:`\hat x = T^+(\hat w)` (Viegas, Batista, Oliveira & Silvestre (2015), Lemma 1).

    - A constant (LTI, Viegas, Batista, Oliveira & Silvestre (2015), §IV-C): Luenberger :math:`\dot{\hat w} = A\hat w + b - L(C\hat w - y)`
      with L from `poles`, `L`, or the LQE weights `Q`, `R`.
    - A depending on (u, y, t) (LTV, Viegas, Batista, Oliveira & Silvestre (2015), §IV-A/B): Kalman-Bucy filter
      :math:`\dot{\hat w} = A\hat w + b - PC^\top R^{-1}(C\hat w - y)`,
      :math:`\dot P = AP + PA^\top + Q - PC^\top R^{-1}CP` (`Q` > 0 and `R` > 0 required),
      evaluated on the measured input and output.

    Parameters
    ----------
    system : System
    T : sequence of expressions in the states (and parameters)
        The state augmentation w = T(x).
    A : (n_w, n_w) matrix of numbers or expressions in the inputs, outputs, ``t`` and parameters
    C : (p, n_w) matrix of numbers
    left_inverse : sequence of expressions in ``w1, w2, ...``
        x = T⁺(w), one expression per state.
    b : sequence of expressions in the inputs, outputs, ``t`` and the parameters, optional
        The input term of the augmented system (default zero).
    poles, L, Q, R :
        The gain: for constant A see :func:`nlobs.design.observer_gain`; for a time-varying A,
        the Kalman-Bucy intensities Q (n_w x n_w) and R (p x p).
    P0 : array_like of shape (n_w, n_w), optional
        Initial covariance of the Kalman-Bucy filter (identity).
    xhat0 : array_like, optional
        Initial estimate in x; the observer starts at ŵ = T(xhat0).

    Raises
    ------
    PreconditionError
        If the augmented system does not mimic the model (naming the row and the residual),
        T⁺ is not a left inverse of T, (A, C) is not observable (constant A), the gain is not
        Hurwitz, or a constant gain is asked for a time-varying A.

    References
    ----------
    Viegas, Batista, Oliveira & Silvestre (2015), eqs. (2), (15)-(18), (20)-(22), Def. 3, Theorem 1, Lemma 1.
    """
    require_system(system, "design_augmented")
    caller = "design_augmented"
    n = system.n_states
    params = {symbol(k): exact(v) for k, v in system.params.items()}
    f, h = system.substituted()
    base = {k: symbol(k) for k in (*system.states, *system.inputs, *system.params)}
    base["t"] = TIME
    with_y = {**base, **{k: symbol(k) for k in system.outputs}}
    Tm = _states_only(matrix_of(list(T), len(T), 1, base, name="T").xreplace(params), system, caller)
    nw = Tm.shape[0]
    Am = matrix_of(A, nw, nw, with_y, name="A").xreplace(params)
    Cm = matrix_of(C, system.n_outputs, nw, base, name="C").xreplace(params)
    bm = matrix_of(list(b) if b is not None else [0] * nw, nw, 1, with_y, name="b").xreplace(params)
    xset = set(system.x)
    for label, M in (("A", Am), ("b", bm)):
        if M.free_symbols & xset:
            raise PreconditionError(f"{caller}: `{label}` may depend on the inputs, outputs and t, not on the states; it contains "
                                    f"{', '.join(sorted(s.name for s in M.free_symbols & xset))}")
    if Cm.free_symbols:
        raise PreconditionError(f"{caller}: `C` must be constant (numbers and parameters); it contains "
                                f"{', '.join(sorted(s.name for s in Cm.free_symbols))}")
    x = sp.Matrix(system.x)
    y_of_x = {symbol(k): h[i] for i, k in enumerate(system.outputs)}
    checks = []
    rows = Tm.jacobian(x) * f - (Am.xreplace(y_of_x) * Tm + bm.xreplace(y_of_x))
    verdicts = []
    for i in range(nw):
        v = decide_identity(rows[i], 0, seed=i)
        if v.fails:
            raise PreconditionError(f"{caller}: the augmented system does not mimic the model: row {i} of dT/dt - (A T + b) is "
                                    f"{sp.simplify(rows[i])}, not 0{v.where()} ({cite('001')} eq. 2). Check T, A and b.")
        verdicts.append(v)
    checks.append(identity_check(f"mimicking: dT/dt = A(u, h(x), t) T(x) + b along f ({cite('001')} eq. 2, Def. 3)", verdicts,
                                 [f"row {i + 1}" for i in range(nw)]))
    out_res = Cm * Tm - h
    verdicts = []
    for i in range(system.n_outputs):
        v = decide_identity(out_res[i], 0, seed=i)
        if v.fails:
            raise PreconditionError(f"{caller}: C T(x) differs from the output {system.outputs[i]} by {sp.simplify(out_res[i])}"
                                    f"{v.where()}; C T(x) = h(x) is required")
        verdicts.append(v)
    checks.append(identity_check("output: C T(x) = h(x)", verdicts, list(system.outputs)))
    wsyms = [symbol(f"w{i + 1}") for i in range(nw)]
    inv = matrix_of(list(left_inverse), n, 1, {**base, **{s.name: s for s in wsyms}}, name="left_inverse").xreplace(params)
    inv_res = inv.xreplace(dict(zip(wsyms, Tm))) - x
    verdicts = []
    for i in range(n):
        v = decide_identity(inv_res[i], 0, seed=i)
        if v.fails:
            raise PreconditionError(f"{caller}: the given left inverse does not recover {system.states[i]}: T⁺(T(x)) - x = "
                                    f"{sp.simplify(inv_res[i])}{v.where()}; T must be injective with T⁺(T(x)) = x ({cite('001')} Theorem 1)")
        verdicts.append(v)
    checks.append(identity_check(f"left inverse: T⁺(T(x)) = x, so T is injective ({cite('001')} Theorem 1)", verdicts,
                                 [f"state {s_}" for s_ in system.states]))
    lin = inv.jacobian(sp.Matrix(wsyms))
    if not lin.free_symbols:
        checks.append(Check(f"left inverse globally Lipschitz ({cite('001')} Lemma 1, eq. 3)", True,
                            f"linear, α = ‖∂T⁺/∂w‖ = {np.linalg.norm(np.array(lin, dtype=float), 2):.4g}"))

    def estimate(zw: ca.SX) -> ca.SX:
        return to_casadi(list(inv), {w: zw[i] for i, w in enumerate(wsyms)})

    def initial(x0: ca.SX) -> ca.SX:
        return to_casadi(list(Tm), {sym: x0[i] for i, sym in enumerate(system.x)})

    info = {"T(x)": str(list(Tm)), "left inverse": str(list(inv))}
    if Am.free_symbols or bm.free_symbols & set(system.y):
        if poles is not None or L is not None:
            raise PreconditionError(f"{caller}: A depends on {', '.join(sorted(s.name for s in Am.free_symbols))}, so a constant gain "
                                    "(`poles`/`L`) does not apply; give `Q` and `R` for the Kalman-Bucy filter on the LTV system")
        if Q is None or R is None:
            raise PreconditionError(f"{caller}: the augmented system is time-varying (A depends on "
                                    f"{', '.join(sorted(s.name for s in Am.free_symbols))}): give `Q` (n_w x n_w, positive "
                                    "definite) and `R` for its Kalman-Bucy filter")
        return _riccati_design("augmented", "Kalman-Bucy filter on a mimicking augmented LTV system", REF,
                               StateAffineParts(system, Am, bm, Cm), V=Q, W=R, delta=0.0, M0=P0, xhat0=xhat0, region=None,
                               caller=caller, extra_checks=checks, extra_values=info, estimate=estimate, initial=initial,
                               state_names=[f"what_{i + 1}" for i in range(nw)])
    An, Cn = np.array(Am, dtype=float), np.array(Cm, dtype=float)
    gain, gchecks, values = observer_gain(An, Cn, poles=poles, L=L, Q=Q, R=R, caller=caller)
    s = Symbols.make(system, nw)
    leaves = {TIME: s.t}
    leaves.update({sym: s.u[i] for i, sym in enumerate(system.u)})
    leaves.update({sym: s.y[i] for i, sym in enumerate(system.y)})
    bw = to_casadi(list(bm), leaves)
    dz = ca.DM(An) @ s.z + bw - ca.DM(gain) @ (ca.DM(Cn) @ s.z - s.y)
    x0 = ca.SX.sym("xhat0", n)
    values = {**values, "A": An, "C": Cn, **info}
    cert = Certificate("Luenberger observer on a mimicking augmented LTI system", REF, (*checks, *gchecks), values)
    return ObserverDesign.build("augmented", system, s, z_names=[f"what_{i + 1}" for i in range(nw)], flow=dz,
                                xhat=estimate(s.z), xhat0_sym=x0, z0=initial(x0),
                                xhat0=np.zeros(n) if xhat0 is None else xhat0, certificate=cert)
