"""High-gain observers: the triangular form (Gauthier-Hammouri-Kupka, Besançon (2010)) and the
output-derivative observer of Khalil-Esfandiari used in Yi, Ortega & Zhang (2019), Table I."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ...algebra._identity import decide_identity
from ...engine import compile_system
from ...errors import FormError, PreconditionError, ShapeError
from ...model import TIME, System, symbol
from ...model._system import ExprLike, exact, to_expr
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign, Symbols
from .._checks import identity_check
from .._common import chain_gain, leaves_of, measured_states, require_system, saturate, saturation_bounds, to_sx
from .._constructions import derivative_map, evaluate, find_chains, text
from .._kind import Tuning, kind, renamed
from .._tune import clean_message, region_inputs, region_states, vanishes

__all__ = ["design_high_gain", "design_high_gain_derivatives", "triangular_chains", "Chain"]

REF_GHK = (f"{cite('002')}, 'Result [High Gain Observer]' (Gauthier-Hammouri-Kupka): "
           "x̂' = A0x̂ + B(u, x̂) - diag(λ, ..., λⁿ)K0(C0x̂ - y), ∂B_i/∂x_j = 0 for j ≥ i+1; "
           "and its extension ∂f_i/∂x_j = 0 for j > i+1, ∂f_i/∂x_{i+1} ≥ α_i > 0")
REF_KE = (f"{cite('004')} §V-C and Table I, 'HGO (linear dynamics)': output derivatives estimated by "
          "integrator chains with injections α_i r^(-i)(y - ξ_1) (Khalil-Esfandiari), x̂ from the estimated derivatives")


@dataclass(frozen=True)
class Chain:
    """One chain of the triangular form: the output it starts from and its states in order.

    Attributes
    ----------
    output : int
        Index of the output measuring ``states[0]``.
    states : tuple of int
        State indices, level 1 (measured) first.
    couplings : tuple of sympy.Expr
        ∂f_{i}/∂x_{i+1} along the chain (length ``len(states) - 1``).
    """

    output: int
    states: tuple[int, ...]
    couplings: tuple[sp.Expr, ...]

    @property
    def constant(self) -> bool:
        return all(not c.free_symbols for c in self.couplings)


def triangular_chains(system: System, chains: Sequence[Sequence[str]] | None = None, *,
                      caller: str = "triangular_chains") -> list[Chain]:
    r"""Recognise the (multi-output) triangular form of Besançon (2010), or say which entry breaks it.

    The states are grouped in one chain per output, :math:`(x_{k,1}, \dots, x_{k,n_k})` with
    :math:`y_k = x_{k,1}`. The form requires, for every state :math:`x_{k,i}` at level i:

    - :math:`f_{k,i}` depends only on states of levels :math:`\le i` (of any chain) and on
      the next state of its own chain :math:`x_{k,i+1}`;
    - it depends on :math:`x_{k,i+1}` linearly, through a nonzero coupling
      :math:`a_{k,i} = \partial f_{k,i}/\partial x_{k,i+1}` (1 in the GHK form; a constant, or
      a function bounded away from 0, in the extension of Besançon (2010)).

    Parameters
    ----------
    system : System
    chains : sequence of sequences of state names, optional
        One chain per output, in output order, each starting with the measured state.
        Default: the states in declared order, cut at each measured state.

    Raises
    ------
    PreconditionError
        If an output is not a single state, or the chains are malformed.
    FormError
        Naming the entry of f that breaks the triangular structure.
    """
    meas = measured_states(system, caller)
    n = system.n_states
    names = system.states
    if chains is None:
        order = sorted(range(len(meas)), key=lambda k: meas[k])
        if len(set(meas)) != len(meas) or meas[order[0]] != 0:
            raise PreconditionError(f"{caller}: cannot split the states into chains: list the states chain by chain, each "
                                    f"starting with its measured state, or pass `chains` (the outputs measure "
                                    f"{', '.join(names[j] for j in meas)})")
        cuts = [meas[k] for k in order] + [n]
        groups = {order[i]: list(range(cuts[i], cuts[i + 1])) for i in range(len(order))}
        idx = [groups[k] for k in range(len(meas))]
    else:
        if isinstance(chains, str) or len(chains) != len(meas):
            raise ShapeError(f"{caller}: `chains` must list {len(meas)} chain(s) of state names, one per output")
        idx = []
        for k, ch in enumerate(chains):
            if isinstance(ch, str):
                raise ShapeError(f"{caller}: chain {k} must be a list of state names, got the string {ch!r}")
            try:
                ids = [names.index(s) for s in ch]
            except ValueError:
                raise ShapeError(f"{caller}: chain {k} = {list(ch)} names an unknown state; states: {', '.join(names)}") from None
            if not ids or ids[0] != meas[k]:
                raise PreconditionError(f"{caller}: chain {k} must start with {names[meas[k]]}, the state measured by output "
                                        f"{system.outputs[k]}")
            idx.append(ids)
        flat = sorted(j for ch in idx for j in ch)
        if flat != list(range(n)):
            raise PreconditionError(f"{caller}: the chains must cover every state exactly once; got {[list(map(names.__getitem__, c)) for c in idx]}")
    level = {j: i + 1 for ch in idx for i, j in enumerate(ch)}
    nxt = {ch[i]: ch[i + 1] for ch in idx for i in range(len(ch) - 1)}
    chain_of = {j: k for k, ch in enumerate(idx) for j in ch}
    f, _ = system.substituted()
    x = system.x
    unmeasured = {x[j] for j in range(n) if j not in meas}
    result = []
    for k, ch in enumerate(idx):
        couplings = []
        for j in ch:
            fj = f[j]
            for m in range(n):
                if x[m] not in fj.free_symbols:
                    continue
                if level[m] <= level[j] or nxt.get(j) == m:
                    continue
                raise FormError(
                    f"{system.name!r} is not in triangular form: {names[j]}' = {fj} depends on {names[m]} (∂/∂{names[m]} = "
                    f"{sp.diff(fj, x[m])}); {names[j]} is at level {level[j]} of the chain of {system.outputs[k]} and may depend "
                    f"only on states of levels <= {level[j]}" + (f" and linearly on {names[nxt[j]]}" if j in nxt else "")
                    + f" ({names[m]} is at level {level[m]} of the chain of {system.outputs[chain_of[m]]})")
            if j in nxt:
                m = nxt[j]
                a = sp.simplify(sp.diff(fj, x[m]))
                if a == 0:
                    raise FormError(f"{system.name!r} is not in triangular form: {names[j]}' = {fj} does not depend on "
                                    f"{names[m]}, the next state of its chain, so {names[m]} cannot be reconstructed through it")
                if x[m] in a.free_symbols:
                    raise FormError(f"{system.name!r} is not in triangular form: {names[j]}' = {fj} is not linear in {names[m]} "
                                    f"(∂/∂{names[m]} = {a})")
                bad = sorted(s.name for s in a.free_symbols & unmeasured)
                if bad:
                    raise FormError(f"{system.name!r} is not in triangular form: the coupling ∂{names[j]}'/∂{names[m]} = {a} "
                                    f"depends on the unmeasured state(s) {', '.join(bad)}")
                couplings.append(a)
        result.append(Chain(k, tuple(ch), tuple(couplings)))
    return result


def _theta(theta: Any, r: Any, caller: str) -> float:
    if (theta is None) == (r is None):
        raise PreconditionError(f"{caller}: give exactly one of `theta` (the high gain) or `r` = 1/theta")
    val = float(theta) if theta is not None else 1.0 / float(r) if float(r) != 0 else np.inf
    if not (np.isfinite(val) and val > 0):
        raise PreconditionError(f"{caller}: the gain parameter must be positive and finite; got "
                                f"{'theta' if theta is not None else 'r'} = {theta if theta is not None else r}")
    return val


def _per_chain(value: Any, sizes: Sequence[int], name: str, caller: str, *, complex_ok: bool = False) -> list[np.ndarray]:
    """A vector per chain, from a nested sequence, or a flat one (all chains, or one reused for equal chains)."""
    dtype = complex if complex_ok else float
    try:
        if len(sizes) > 1 and len(value) == len(sizes) and all(np.ndim(v) == 1 for v in value):
            out = [np.asarray(v, dtype=dtype).reshape(-1) for v in value]
        else:
            flat = np.asarray(value, dtype=dtype).reshape(-1)
            if flat.size == sum(sizes):
                out = np.split(flat, np.cumsum(sizes)[:-1])
            elif len(set(sizes)) == 1 and flat.size == sizes[0]:
                out = [flat.copy() for _ in sizes]
            else:
                raise ShapeError(f"{caller}: `{name}` must have {sum(sizes)} entries (chains of lengths {list(sizes)}), "
                                 f"got {flat.size}")
    except (TypeError, ValueError) as e:
        raise ShapeError(f"{caller}: `{name}` must be numbers, one per state of each chain: {e}") from None
    for k, (v, m) in enumerate(zip(out, sizes)):
        if v.size != m:
            raise ShapeError(f"{caller}: `{name}` for chain {k} must have {m} entries, got {v.size}")
        if not np.all(np.isfinite(v)):
            raise ShapeError(f"{caller}: `{name}` has non-finite entries")
    return out


def _chain_matrix(couplings: Sequence[float]) -> np.ndarray:
    m = len(couplings) + 1
    A = np.zeros((m, m))
    for i, a in enumerate(couplings):
        A[i, i + 1] = a
    return A


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def _chains(ctx: Any) -> tuple[Any, list[list[str]] | None, str]:
    try:
        return triangular_chains(ctx.system, caller="high_gain"), None, ""
    except (FormError, PreconditionError) as first:
        reason: list[str] = []
        alt = find_chains(ctx.system, reason)
        if alt is None:
            return None, None, (f"not in triangular form: {reason[0]}" if reason else clean_message(first))
        try:
            return triangular_chains(ctx.system, alt, caller="high_gain"), alt, ""
        except (FormError, PreconditionError) as e:
            return None, None, clean_message(e)


def _theta_star(chs: Any, gamma: float, n: int) -> float:
    import scipy.linalg

    from .._common import chain_gain

    blocks = []
    for c in chs:
        m = len(c.states)
        g = chain_gain([float(a) for a in c.couplings], np.full(m, -1.0 + 0j))
        A = np.zeros((m, m))
        for i, a in enumerate(c.couplings):
            A[i, i + 1] = float(a)
        blocks.append(A - np.outer(g, np.eye(m)[0]))
    Ab = scipy.linalg.block_diag(*blocks)
    P0 = scipy.linalg.solve_continuous_lyapunov(Ab.T, -np.eye(n))
    return max(1.0, 2.0 * np.sqrt(n) * gamma * float(np.linalg.eigvalsh((P0 + P0.T) / 2).max()))


def _saturation(ctx: Any) -> dict[str, float]:
    """Khalil's remedy against peaking: the estimate fed to the model is clipped to twice the largest magnitude each
    state reaches on the run."""
    if not ctx.region:
        return {}
    return {s: float(f"{2.0 * max(abs(ctx.region[s][0]), abs(ctx.region[s][1])):.4g}") for s in ctx.system.states}


def tune_high_gain(ctx: Any) -> Tuning:
    chs, alt, why = _chains(ctx)
    if chs is None:
        return Tuning.fails(why)
    opts: dict[str, Any] = {}
    if alt is not None:
        opts["chains"] = alt
    sat = _saturation(ctx)
    if sat:
        opts["saturation"] = sat
    order = "; ".join(" -> ".join(ctx.system.states[j] for j in c.states) for c in chs)
    if sat:
        order += " (estimate saturated at twice the run's magnitudes, against peaking)"
    limit = ctx.step_limit()
    varying = [(c, i, a) for c in chs for i, a in enumerate(c.couplings) if a.free_symbols]
    if varying:
        if ctx.nominal is None:
            return Tuning.needs("L0 (the couplings vary: " + ", ".join(str(a) for _, _, a in varying) + ") and a run to check them")
        pts = ctx.samples(400)
        ysub = {ctx.system.x[j]: ctx.system.y[k] for k, j in enumerate(c.states[0] for c in chs)}
        vals = evaluate([a.xreplace(ysub) for _, _, a in varying], ctx.system, pts)
        for (c, i, a), col in zip(varying, vals.T):
            lo, hi = float(col.min()), float(col.max())
            if lo * hi <= 0 or min(abs(lo), abs(hi)) < 1e-3 * max(abs(lo), abs(hi)):
                s0, s1 = ctx.system.states[c.states[i]], ctx.system.states[c.states[i + 1]]
                return Tuning.fails(f"the coupling ∂{s0}'/∂{s1} = {a} takes values in [{lo:.3g}, {hi:.3g}] on the run: it "
                              f"{vanishes(lo, hi)}, and the high-gain observer needs it "
                              f"bounded away from 0 with a fixed sign ({cite('002')}, extension of the high-gain observer)")
        from .._common import chain_gain

        means = {id(a): float(np.mean(col)) for (_, _, a), col in zip(varying, vals.T)}
        K0 = []
        for c in chs:
            cpl = [means[id(a)] if a.free_symbols else float(a) for a in c.couplings]
            K0.extend(chain_gain(cpl, np.full(len(c.states), -1.0 + 0j)).tolist())
        theta = float(min(max(ctx.omega_o, 1.0), limit))
        opts.update({"theta": round(theta, 6), "L0": K0})
        return Tuning.tuned(opts, f"chains {order}; couplings vary but keep their sign on the run: K0 from their mean values "
                        f"(binomial poles), θ = {theta:.3g} from the time scale")
    if not ctx.region:
        theta = float(max(ctx.omega_o, 1.0))
        opts["theta"] = round(theta, 6)
        return Tuning.tuned(opts, f"chains {order}; θ = {theta:.3g} from the time scale (no region to bound the nonlinearity)")
    from ..lipschitz._lipschitz import region_lipschitz

    A0 = sp.zeros(ctx.n, ctx.n)
    for c in chs:
        for i, a in enumerate(c.couplings):
            A0[c.states[i], c.states[i + 1]] = a
    f, _ = ctx.system.substituted()
    phi = list(f - A0 * sp.Matrix(ctx.system.x))
    region = {**region_states(ctx), **region_inputs(ctx)}
    if ctx.system.is_time_varying:
        region["t"] = (0.0, float(ctx.scenario.t_final))
    try:
        gamma, _ = region_lipschitz(ctx.system, phi, region, caller="high_gain")
    except (PreconditionError, ShapeError) as e:
        gamma, why_g = None, clean_message(e)
    if gamma is not None and np.isfinite(gamma):
        ts = _theta_star(chs, gamma, ctx.n)
        if 1.2 * ts <= limit:
            theta = float(min(max(1.2 * ts, ctx.omega_o), limit))
            opts.update({"theta": round(theta, 6), "lipschitz": round(float(gamma), 9)})
            return Tuning.tuned(opts, f"chains {order}; γ ≈ {gamma:.3g} (Lipschitz constant of the triangular part on the region), "
                            f"θ = {theta:.3g} > θ* = {ts:.3g}: convergence guaranteed while the state stays in the region")
        theta = float(min(max(ctx.omega_o, 1.0), limit))
        opts["theta"] = round(theta, 6)
        return Tuning.tuned(opts, f"chains {order}; θ = {theta:.3g} from the time scale; the sufficient bound θ* = {ts:.3g} (γ ≈ "
                        f"{gamma:.3g} on the region) is beyond what the step allows (θ ≤ {limit:.3g}), so convergence is not "
                        "certified (the bound is conservative)")
    theta = float(min(max(ctx.omega_o, 1.0), limit))
    opts["theta"] = round(theta, 6)
    return Tuning.tuned(opts, f"chains {order}; θ = {theta:.3g} from the time scale (no Lipschitz bound: {why_g})")


def tune_high_gain_derivatives(ctx: Any) -> Tuning:
    lie: dict[sp.Symbol, sp.Expr] = {}
    try:
        psi, why = derivative_map(ctx.system, lie=lie)
    except (NotImplementedError, ValueError, TypeError) as e:  # SymPy giving up
        psi, why = None, f"the output derivatives could not be solved for the state ({type(e).__name__})"
    if psi is None:
        return Tuning.needs(f"psi: x = Ψ(D0_y, D1_y, ...): {why}", psi="expressions of the output derivatives D{i}_{output}")
    theta = float(min(max(ctx.omega_o, 1.0), ctx.step_limit()))
    dens = sorted({d.as_coeff_Mul()[1] for e in psi.values() for d in [sp.fraction(sp.together(e))[1]] if d.free_symbols},
                  key=str)
    extra = ""
    if dens:
        extra = f"Ψ is singular where {', '.join(map(str, dens))} = 0"
        if ctx.nominal is not None:
            vals = evaluate([d.xreplace(lie) for d in dens], ctx.system, ctx.samples(400))
            for d, col in zip(dens, vals.T):
                lo, hi = float(np.min(col)), float(np.max(col))
                small = float(np.min(np.abs(col))) < 1e-3 * float(np.max(np.abs(col)))
                if lo * hi <= 0 or small:
                    return Tuning.fails(f"Ψ (x from the output derivatives, solved by nlobs) divides by {d}, which "
                                  f"{vanishes(lo, hi)} on the run (from {lo:.3g} to "
                                  f"{hi:.3g}): the estimate blows up where it vanishes", psi={k: text(v) for k, v in psi.items()})
    return Tuning.tuned({"psi": {k: text(v) for k, v in psi.items()}, "theta": round(theta, 6)},
                    f"Ψ solved from the Lie derivatives of the output(s); θ = {theta:.3g} (binomial α)", extra=extra)


@kind('high_gain', summary='high-gain observer for the triangular form (Gauthier-Hammouri-Kupka)',
      references=(work("002", "Result [High Gain Observer]"),), tune=tune_high_gain)
@renamed(K0="L0")
def design_high_gain(system: System, *, theta: float | None = None, r: float | None = None, L0: Any = None,
                     poles: Any = None, chains: Sequence[Sequence[str]] | None = None, lipschitz: float | None = None,
                     saturation: Mapping[str, float] | Sequence[float] | None = None,
                     xhat0: Any = None) -> ObserverDesign:
    r"""High-gain observer for the triangular form (Gauthier-Hammouri-Kupka; Besançon (2010)).

    For :math:`\dot x = A_0 x + B(u, x)`, :math:`y = C_0 x` with :math:`A_0` the shift matrix
    and B triangular (:math:`\partial B_i/\partial x_j = 0` for :math:`j \ge i+1`),

    .. math::

        \dot{\hat x} = f(\hat x, u) - \Delta_\theta K_0 (C_0\hat x - y), \qquad
        \Delta_\theta = \mathrm{diag}(\theta, \theta^2, \dots, \theta^n),

    with :math:`A_0 - K_0C_0` Hurwitz and θ large enough. Several outputs give several chains
    (each state may depend on states of lower or equal level in any chain); the coupling
    :math:`a_i = \partial f_i / \partial x_{i+1}` may be any nonzero constant (K0 is then
    computed for :math:`A_c - K_0C_0`) or, as in the extension of Besançon (2010), a function of (u, y, t)
    bounded away from zero (K0 must then be given). In the scaled error
    :math:`\varepsilon_i = e_i/\theta^{i-1}` the linear part is
    :math:`\theta(A_c - K_0C_0)`, so its eigenvalues are θ times those of
    :math:`A_c - K_0 C_0` (the certificate's ``nominal_rate``).

    With `lipschitz` γ (each :math:`B_{k,i}` Lipschitz with constant γ in the states of levels
    ≤ i), :math:`V = \varepsilon^\top P_0 \varepsilon`, :math:`(A_c - K_0C_0)^\top P_0 + P_0(A_c - K_0C_0) = -I`
    gives :math:`\dot V \le -(\theta - 2\sqrt n\,\gamma\,\lambda_{max}(P_0))|\varepsilon|^2`:
    convergence for :math:`\theta > \theta^* = \max(1, 2\sqrt n\,\gamma\,\lambda_{max}(P_0))` at the
    guaranteed rate :math:`(\theta - \theta^*)/(2\lambda_{max}(P_0))`.

    Parameters
    ----------
    system : System
        Each output a single state; the states listed chain by chain (or see `chains`).
    theta : float, optional
        The high gain θ (> 0); give θ or `r`.
    r : float, optional
        1/θ, as in Yi, Ortega & Zhang (2019), Table I.
    L0 : array_like, optional
        Gains, one per state of each chain (flat in chain order, or nested per chain).
    poles : array_like, optional
        Eigenvalues of :math:`A_c - K_0C_0` per chain (default: all at -1, i.e. binomial gains:
        (2, 1) for chains of length 2, as in Yi, Ortega & Zhang (2019), Table I). Not with `L0`.
    chains : sequence of sequences of state names, optional
        The chains, one per output, each starting with its measured state.
    lipschitz : float, optional
        γ above; when given, θ > θ* is required and the guaranteed rate is reported.

    Other Parameters
    ----------------
    saturation : mapping of state name to bound, or sequence, optional
        The estimate fed to the model and returned is clipped to [-M, M] (Khalil's
        saturation against peaking); the internal state is not.
    xhat0 : array_like of shape (n,), optional
        Default initial estimate (zeros).

    Returns
    -------
    ObserverDesign
        Certificate values: ``theta``, ``K0``, ``eigenvalues`` (of A_c - K0C0),
        ``nominal_rate`` (θ · min abs(Re eig)), and with `lipschitz` ``theta_min``, ``P0`` and
        ``guaranteed_rate``.

    Raises
    ------
    FormError
        If the model is not triangular (naming the entry that breaks it).
    PreconditionError
        If θ/r are missing or invalid, K0 is not Hurwitz, a coupling is not constant and K0
        was not given, or θ ≤ θ* with `lipschitz`.

    References
    ----------
    Besançon (2010), "'Uniformly observable' systems - LTI + structured NL", Result
    [High Gain Observer] and "about high gain" (extension). Yi, Ortega & Zhang (2019), Table I,
    "HGO (time-varying dynamics)" (r1 = 0.05, α = (2, 1)).

    Examples
    --------
    >>> import nlobs
    >>> sys = nlobs.System(states=["x1", "x2"], f=["x2", "-sin(x1)"], outputs=["y"], h=["x1"])
    >>> d = design_high_gain(sys, theta=10.0)
    >>> d.certificate.values["K0"], round(d.certificate.values["nominal_rate"], 9)
    ([array([2., 1.])], 10.0)
    """
    K0 = L0  # the normalised gain (K0 in Besançon (2010))
    require_system(system, "design_high_gain")
    caller = "design_high_gain"
    th = _theta(theta, r, caller)
    try:
        chs = triangular_chains(system, chains, caller=caller)
    except FormError as e:
        raise FormError(f"{caller}: {e}. Use design_ekf or design_lipschitz for models not in triangular form.") from e
    n = system.n_states
    checks = [Check("outputs measure the first state of each chain", True,
                    "; ".join(f"{system.outputs[c.output]}: " + " -> ".join(system.states[j] for j in c.states) for c in chs)),
              Check("triangular structure: f_i depends on levels <= i and linearly on the next state", True)]
    if K0 is not None and poles is not None:
        raise PreconditionError(f"{caller}: give `L0` or `poles`, not both")
    nonconst = [(c, i, a) for c in chs for i, a in enumerate(c.couplings) if a.free_symbols]
    if nonconst and K0 is None:
        c, i, a = nonconst[0]
        raise PreconditionError(
            f"{caller}: the coupling ∂{system.states[c.states[i]]}'/∂{system.states[c.states[i + 1]]} = {a} is not constant, so "
            f"no K0 can be computed from poles; give `L0` explicitly (the extension of {cite('002')} needs the coupling bounded away "
            "from 0 with a fixed sign), or use design_high_gain_kalman for couplings a(u, y)")
    gains = _chain_gains(chs, K0, poles, caller)
    eigs, blocks = _error_blocks(system, chs, gains, checks, caller)
    values: dict[str, Any] = {"theta": th, "K0": gains}
    if len(blocks) == len(chs):
        checks.append(Check("A_c - K0 C0 Hurwitz (every chain)", True, f"max Re eig = {max(e.real.max() for e in eigs):.4g}"))
        rho0 = float(min(-e.real.max() for e in eigs))
        values.update({"eigenvalues": eigs, "nominal_rate": th * rho0})
        if lipschitz is not None:
            values.update(_lipschitz_bound(blocks, th, lipschitz, checks, caller))
    elif lipschitz is not None:
        raise PreconditionError(f"{caller}: the Lipschitz bound needs constant couplings; with a coupling depending on (u, y) "
                                "no θ* is computed. Drop `lipschitz` or use design_high_gain_kalman")
    sat = saturation_bounds(saturation, system.states, caller)
    s = Symbols.make(system, n)
    xs = s.z if sat is None else saturate(s.z, sat)
    f, _ = compile_system(system).bind()
    inj = [ca.SX(0)] * n
    for c, g in zip(chs, gains):
        innov = s.y[c.output] - s.z[c.states[0]]
        for i, j in enumerate(c.states):
            inj[j] = float(g[i]) * th ** (i + 1) * innov
    dz = f(s.t, xs, s.u) + ca.vertcat(*inj)
    if sat is not None:
        values["saturation"] = sat
        checks.append(Check("estimate saturated in the model and the output", True,
                            ", ".join(f"|{nm}| <= {b:g}" for nm, b in zip(system.states, sat) if np.isfinite(b))))
    x0 = ca.SX.sym("xhat0", n)
    cert = Certificate(f"High-gain observer (triangular form, θ = {th:g})", REF_GHK, tuple(checks), values)
    return ObserverDesign.build("high_gain", system, s, z_names=[f"xhat_{v}" for v in system.states], flow=dz, xhat=xs,
                                xhat0_sym=x0, z0=x0, xhat0=np.zeros(n) if xhat0 is None else xhat0, certificate=cert)


def _error_blocks(system: System, chs: Sequence[Chain], gains: Sequence[np.ndarray], checks: list[Check],
                  caller: str) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """A_c − K0 C0 of each chain with constant couplings (refused unless Hurwitz) and its sorted eigenvalues; a chain
    whose couplings vary adds an assumed check instead."""
    eigs, blocks = [], []
    for c, g in zip(chs, gains):
        if c.constant:
            Ac = _chain_matrix([float(a) for a in c.couplings])
            M = Ac - np.outer(g, np.eye(len(g))[0])
            ev = np.linalg.eigvals(M)
            if np.max(ev.real) >= 0:
                raise PreconditionError(f"{caller}: L0 = {g} does not make A_c - K0 C0 Hurwitz for the chain of "
                                        f"{system.outputs[c.output]}: eigenvalue {complex(ev[np.argmax(ev.real)]):.4g}; choose other gains")
            eigs.append(ev[np.lexsort((ev.imag, ev.real))])
            blocks.append(M)
        else:
            checks.append(Check.assumed(f"coupling(s) of the chain of {system.outputs[c.output]} bounded away from 0 with a "
                                        f"fixed sign ({cite('002')} extension)",
                                        "depends on the trajectory: " + ", ".join(str(a) for a in c.couplings if a.free_symbols)))
    return eigs, blocks


def _chain_gains(chs: Sequence[Chain], L0: Any, poles: Any, caller: str) -> list[np.ndarray]:
    """The normalised gain of each chain: `L0` as given, or from the requested poles (default all at -1: binomial)."""
    sizes = [len(c.states) for c in chs]
    if L0 is not None:
        return _per_chain(L0, sizes, "L0", caller)
    want = [np.full(m, -1.0 + 0j) for m in sizes] if poles is None else \
        _per_chain(poles, sizes, "poles", caller, complex_ok=True)
    for k, p in enumerate(want):
        if np.any(p.real >= 0):
            raise PreconditionError(f"{caller}: the requested pole {complex(p[p.real >= 0][0]):.4g} (chain {k}) is not in the "
                                    "open left half-plane; choose poles with negative real part")
        cp = p[np.abs(p.imag) > 0]
        if not np.allclose(np.sort_complex(cp), np.sort_complex(cp.conj())):
            raise PreconditionError(f"{caller}: complex poles must come in conjugate pairs; chain {k} got {p}")
    return [chain_gain([float(a) for a in c.couplings], p) for c, p in zip(chs, want)]


def _lipschitz_bound(blocks: Sequence[np.ndarray], th: float, lipschitz: Any, checks: list[Check], caller: str) -> dict[str, Any]:
    """θ > θ* = max(1, 2√n γ λmax(P0)) with P0 the Lyapunov matrix of the scaled error (Besançon (2010), high-gain
    observer); appends the checks and returns the certificate values (P0, θ*, γ, guaranteed rate)."""
    import scipy.linalg  # deferred: keeps `import nlobs` fast

    gam = float(lipschitz)
    if not (np.isfinite(gam) and gam >= 0):
        raise PreconditionError(f"{caller}: `lipschitz` must be a non-negative number, got {lipschitz}")
    Abar = scipy.linalg.block_diag(*blocks)
    n = Abar.shape[0]
    P0 = scipy.linalg.solve_continuous_lyapunov(Abar.T, -np.eye(n))
    lmax = float(np.linalg.eigvalsh((P0 + P0.T) / 2).max())
    theta_min = max(1.0, 2.0 * np.sqrt(n) * gam * lmax)
    if th <= theta_min:
        raise PreconditionError(f"{caller}: theta = {th:.4g} is not above the sufficient bound theta* = max(1, 2√n γ "
                                f"λmax(P0)) = {theta_min:.4g} (γ = {gam:g}, λmax(P0) = {lmax:.4g}); increase theta")
    rate = (th - 2.0 * np.sqrt(n) * gam * lmax) / (2.0 * lmax)
    checks.append(Check("theta > theta* (Lyapunov bound in scaled coordinates)", True, f"{th:.4g} > {theta_min:.4g}",
                        "floating point (Lyapunov equation), with the γ given"))
    checks.append(Check.assumed(f"the nonlinearity is globally Lipschitz with the γ = {gam:g} given",
                                "stated by the user (`lipschitz`); not verified"))
    return {"P0": P0, "theta_min": theta_min, "lipschitz": gam, "guaranteed_rate": float(rate)}


def _derivative_symbols(system: System) -> tuple[dict[str, sp.Symbol], dict[str, sp.Basic], dict[sp.Symbol, sp.Basic]]:
    """The symbols D{i}_{output} of the output derivatives, every name Ψ may use, and the parameters' values."""
    dsyms = {f"D{i}_{yk}": symbol(f"D{i}_{yk}") for yk in system.outputs for i in range(32)}
    allowed: dict[str, sp.Basic] = {k: symbol(k) for k in (*system.inputs, *system.outputs, *system.params)}
    allowed["t"] = TIME
    allowed.update(dsyms)
    return dsyms, allowed, {symbol(k): exact(v) for k, v in system.params.items()}


def _psi_entries(system: System, psi: Any, caller: str) -> list[Any]:
    """Ψ's expressions in state order, from a mapping state -> expression or a sequence of n expressions."""
    if isinstance(psi, Mapping):
        unknown = [k for k in psi if k not in system.states]
        missing = [k for k in system.states if k not in psi]
        if unknown or missing:
            raise ShapeError(f"{caller}: `psi` must give one expression per state ({', '.join(system.states)}); "
                             + (f"unknown {unknown[0]!r}" if unknown else f"missing {', '.join(missing)}"))
        return [psi[s_] for s_ in system.states]
    entries = list(psi)
    if len(entries) != system.n_states:
        raise ShapeError(f"{caller}: `psi` must have {system.n_states} expressions (one per state), got {len(entries)}")
    return entries


def _psi_recovers_state(system: System, psi: Sequence[sp.Expr], psi_in: Sequence[Any], subs: Mapping[sp.Basic, sp.Expr],
                        caller: str) -> list[Any]:
    """Decide Ψ(L_f^i h) = x exactly, state by state (Schwartz-Zippel identity test); refuse naming the residual."""
    verdicts = []
    for j, e in enumerate(psi):
        v = decide_identity(e.xreplace(subs), system.x[j], seed=j)
        if v.fails:
            res = sp.simplify(e.xreplace(subs) - system.x[j])
            raise PreconditionError(f"{caller}: psi[{system.states[j]}] = {psi_in[j]} does not recover {system.states[j]} from the "
                                    f"output derivatives: with D{{i}}_y = L_f^i h it leaves {res}{v.where()} (inputs held "
                                    "constant). Check Ψ against the model.")
        verdicts.append(v)
    return verdicts


def _lie_derivatives(system: System, k: int, count: int) -> list[sp.Expr]:
    """y_k, ẏ_k, ..., along f with the inputs held constant (explicit t included)."""
    f, h = system.substituted()
    x = sp.Matrix(system.x)
    out = [h[k]]
    for _ in range(count - 1):
        prev = out[-1]
        out.append(sp.expand((sp.Matrix([prev]).jacobian(x) * f)[0] + sp.diff(prev, TIME)))
    return out


@kind('high_gain_derivatives', summary='high-gain observer of the output derivatives (Khalil-Esfandiari), x̂ computed from them',
      references=(work("004", "Table I (HGO with linear dynamics)"),), tune=tune_high_gain_derivatives)
@renamed(xhat="psi")
def design_high_gain_derivatives(system: System, *, psi: Mapping[str, ExprLike] | Sequence[ExprLike],
                                 r: float | None = None, theta: float | None = None,
                                 orders: Mapping[str, int] | Sequence[int] | None = None, alpha: Any = None,
                                 nominal: Mapping[str, ExprLike] | None = None,
                                 saturation: Mapping[str, float] | None = None, xhat0: Any = None) -> ObserverDesign:
    r"""Khalil-Esfandiari high-gain observer of the output derivatives, with x̂ computed from them.

    For each output :math:`y_k`, a chain :math:`\xi_{k,0}, \dots, \xi_{k,\rho_k-1}` estimates
    :math:`y_k, \dot y_k, \dots, y_k^{(\rho_k-1)}`:

    .. math::

        \dot\xi_{k,i} = \xi_{k,i+1} + \frac{\alpha_{k,i+1}}{r^{i+1}}(y_k - \xi_{k,0}), \qquad
        \dot\xi_{k,\rho-1} = \varphi_{0,k} + \frac{\alpha_{k,\rho}}{r^{\rho}}(y_k - \xi_{k,0}),

    and :math:`\hat x = \Psi(\xi, u, y, t)`, the user's map from output derivatives to the state
    (Yi, Ortega & Zhang (2019), Table I: :math:`\hat x = ((C_2\xi_2 - uy_2)/(1-u), -L_3\xi_4 - uy_1)`). The error
    dynamics of each chain are linear with eigenvalues :math:`r^{-1}` times the roots of
    :math:`s^\rho + \alpha_1 s^{\rho-1} + \dots + \alpha_\rho`; the unknown
    :math:`y^{(\rho)} - \varphi_0` enters as a disturbance attenuated like :math:`r^{\rho-i}`
    on :math:`\xi_i`.

    Before building, Ψ is checked symbolically: with :math:`\xi_{k,i}` replaced by the Lie
    derivatives :math:`L_f^i h_k(x)` (inputs held constant) it must give back x.

    Parameters
    ----------
    system : System
    psi : mapping of state name to expression, or a sequence in state order
        Ψ, in the inputs, outputs, parameters, ``t`` and the symbols ``D{i}_{output}`` for the
        i-th derivative estimate of an output (``D0_y1`` estimates y1, ``D1_y1`` its derivative).
    r : float, optional
        The small parameter (Yi, Ortega & Zhang (2019): r ∈ (0, 1]); give r or `theta` = 1/r.
    theta : float, optional
    orders : mapping of output name to int, or sequence, optional
        ρ_k, the number of derivatives estimated (including y itself). Default: one more than
        the highest derivative Ψ and `nominal` use (at least 1).
    alpha : array_like, optional
        α per chain (flat in output order or nested); the polynomial
        :math:`s^\rho + \alpha_1 s^{\rho-1} + \dots` must be Hurwitz. Default: binomial
        (all roots at -1): (2, 1) for ρ = 2, as in Yi, Ortega & Zhang (2019), Table I.

    Other Parameters
    ----------------
    nominal : mapping of output name to expression, optional
        φ0_k, a model of :math:`y_k^{(\rho_k)}` in the same symbols as `psi` (default 0).
    saturation : mapping of ``D{i}_{output}`` name to bound, optional
        Clip the derivative estimates where they enter Ψ and φ0 (Khalil's saturation).
    xhat0 : array_like of shape (n,), optional
        The chains start at the output derivatives of `xhat0` with u = 0, t = 0 (zeros by default,
        as in Yi, Ortega & Zhang (2019), §V-C: "all initial values of the dynamic extensions are 0").

    Returns
    -------
    ObserverDesign
        Certificate values: ``r``, ``alpha``, per-chain ``eigenvalues`` and ``decay_rate``.

    Raises
    ------
    PreconditionError
        If Ψ does not recover the state (naming the state and the residual), α is not Hurwitz,
        or r/θ are invalid.

    References
    ----------
    Yi, Ortega & Zhang (2019), §V-C, Table I "HGO (linear dynamics)" with r2 = 0.005,
    α1 = α3 = 2, α2 = α4 = 1. (The table prints r1 inside the formula of this observer but lists
    r2 as its parameter; the text assigns r2 = 0.005 to it.)
    """
    xhat = psi  # Ψ: the state as a function of the output derivatives
    require_system(system, "design_high_gain_derivatives")
    caller = "design_high_gain_derivatives"
    th = _theta(theta, r, caller)
    n, p = system.n_states, system.n_outputs
    dsyms, allowed, params = _derivative_symbols(system)
    psi_in = _psi_entries(system, xhat, caller)
    psi = [to_expr(e, allowed, where=f"psi[{system.states[j]}]").xreplace(params) for j, e in enumerate(psi_in)]
    nominal = dict(nominal or {})
    bad = [k for k in nominal if k not in system.outputs]
    if bad:
        raise ShapeError(f"{caller}: `nominal` names {bad[0]!r}, which is not an output ({', '.join(system.outputs)})")
    phi0 = {k: to_expr(v, allowed, where=f"nominal[{k}]").xreplace(params) for k, v in nominal.items()}
    used = set().union(*(e.free_symbols for e in (*psi, *phi0.values())))
    rho = []
    for yk in system.outputs:
        hi = max([i for i in range(32) if dsyms[f"D{i}_{yk}"] in used], default=-1)
        rho.append(max(1, hi + 1))
    if orders is not None:
        given = [int(orders[yk]) for yk in system.outputs] if isinstance(orders, Mapping) else [int(v) for v in orders]
        if len(given) != p:
            raise ShapeError(f"{caller}: `orders` needs one entry per output ({', '.join(system.outputs)})")
        for yk, g, need in zip(system.outputs, given, rho):
            if g < need:
                raise PreconditionError(f"{caller}: orders[{yk}] = {g}, but Ψ or the nominal model uses derivative {need - 1}")
        rho = given
    alphas = _per_chain(alpha, rho, "alpha", caller) if alpha is not None else \
        [np.array([float(sp.binomial(m, i + 1)) for i in range(m)]) for m in rho]
    eigs = []
    for yk, a in zip(system.outputs, alphas):
        roots = np.roots(np.concatenate([[1.0], a])) * th
        if np.max(roots.real) >= 0:
            raise PreconditionError(f"{caller}: α = {a} for {yk} does not give a Hurwitz polynomial s^ρ + α1 s^(ρ-1) + ...: root "
                                    f"{complex(roots[np.argmax(roots.real)] / th):.4g}; choose α with all roots in Re < 0")
        eigs.append(np.sort_complex(roots))
    # Ψ must recover x from the true output derivatives (inputs held constant).
    lie = {k: _lie_derivatives(system, k, rho[k]) for k in range(p)}
    _, h = system.substituted()
    subs = {dsyms[f"D{i}_{yk}"]: lie[k][i] for k, yk in enumerate(system.outputs) for i in range(rho[k])}
    subs.update({symbol(yk): h[k] for k, yk in enumerate(system.outputs)})
    verdicts = _psi_recovers_state(system, psi, psi_in, subs, caller)
    checks = [identity_check("Ψ(y, ẏ, ...) recovers x from the Lie derivatives of h (inputs held constant)", verdicts,
                             [f"state {s_}" for s_ in system.states]),
              Check("α gives Hurwitz injection polynomials", True,
                    "; ".join(f"{yk}: max Re eig = {e.real.max():.4g}" for yk, e in zip(system.outputs, eigs)))]
    names = [f"D{i}_{yk}" for k, yk in enumerate(system.outputs) for i in range(rho[k])]
    nz = len(names)
    s = Symbols.make(system, nz)
    sat = None
    if saturation is not None:
        sat = saturation_bounds(saturation, names, caller)
    xi = s.z if sat is None else saturate(s.z, sat)
    leaves = leaves_of(system, s)
    leaves.update({dsyms[nm]: xi[i] for i, nm in enumerate(names)})
    dz, off = [], 0
    for k, yk in enumerate(system.outputs):
        innov = s.y[k] - s.z[off]
        for i in range(rho[k]):
            nxt = s.z[off + i + 1] if i + 1 < rho[k] else (to_sx([phi0[yk]], leaves) if yk in phi0 else ca.SX(0))
            dz.append(nxt + float(alphas[k][i]) * th ** (i + 1) * innov)
        off += rho[k]
    xh = to_sx(psi, leaves)
    x0 = ca.SX.sym("xhat0", n)
    lx = {sym: x0[i] for i, sym in enumerate(system.x)}
    lx.update({sym: 0.0 for sym in system.u})
    lx[TIME] = 0.0
    z0 = to_sx([e for k in range(p) for e in lie[k]], lx)
    values: dict[str, Any] = {"r": 1.0 / th, "theta": th, "orders": dict(zip(system.outputs, rho)), "alpha": alphas,
                              "eigenvalues": eigs, "decay_rate": float(min(-e.real.max() for e in eigs)),
                              "xhat": {nm: str(e) for nm, e in zip(system.states, psi)}}
    if phi0:
        values["nominal"] = {k: str(v) for k, v in phi0.items()}
    if sat is not None:
        values["saturation"] = sat
    cert = Certificate(f"High-gain observer of the output derivatives (Khalil-Esfandiari, r = {1 / th:g})", REF_KE,
                       tuple(checks), values)
    return ObserverDesign.build("high_gain_derivatives", system, s, z_names=names, flow=ca.vertcat(*dz), xhat=xh,
                                xhat0_sym=x0, z0=z0, xhat0=np.zeros(n) if xhat0 is None else xhat0, certificate=cert)
