"""Moving-horizon estimation: the "corrected trajectory-based" observer of Besançon (2010), solved as a compiled NLP.

At each sample the estimator solves, over the states at the N + 1 sample times of a window
(multiple shooting, one RK4-discretised interval between neighbours, process noise as free
variables), a weighted least-squares fit of the window's outputs with an arrival cost on the
window's first state; the arrival cost is updated EKF-style as the window slides. The NLP is
solved by an SQP method (exact Hessian, CasADi's sqpmethod with its qrqp QP solver) generated as
C and compiled with the system compiler (cached on disk); IPOPT, on compiled NLP functions, is
the fallback and may be chosen outright. The window and the solution live in the observer's
state z, so MHE fits the observer contract (z⁺ = J(t, z⁻, u, y, m)); J is a Python callback
around the compiled solver so that a failure stops the run with a :class:`~nlobs.SolverError`
naming the window and the solver status.

References: Besançon (2010), "About methods", approach I (the window problem);
Rao, Rawlings & Mayne (2003) (MHE with an arrival cost, EKF covariance as its approximation);
Kühl et al. (2011) (arrival cost updated by an EKF step linearised at the MHE solution).
"""

from __future__ import annotations

import hashlib
import itertools
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import casadi as ca
import numpy as np
import sympy as sp

from ...engine import compile_c, compile_system, compiled_nlpsol, defer_error, find_compiler, rk4_step
from ...engine._codegen import COSTS, built_path, choose_backend, code_size, signature_of
from ...engine._nlp import nlp_built, nlp_signature
from ...engine._budget import check_time
from ...errors import EngineError, PreconditionError, SolverError, TimeBudgetError
from ...model import System
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign, check_vector
from .._bounds import bounds_check, check_start, clip, clip_const, parse_bounds
from .._checks import check_matrix
from .._common import require_system
from .._kind import Tuning, kind
from .._tune import domain_bounds, square

__all__ = ["design_mhe"]

_APPROACH = 'I. "Corrected trajectory-based" approach'
REF = (f"{cite('002', _APPROACH)}: min over z_(t-T) of "
       "∫_(t-T)^t ‖h(χ_u(τ, z_(t-T))) - y(τ)‖² dτ, discretised on the window's samples with multiple shooting and "
       f"process noise; arrival cost of {cite('rao2003')}, updated by an EKF step linearised at the MHE solution "
       f"({cite('kuhl2011')})")

_NAMES = itertools.count()
_CACHE: dict[tuple[Any, ...], _Solvers] = {}


@dataclass
class _Solvers:
    """The pieces shared by every design of one structure (weights, bounds and parameters are inputs).

    The fast path is compiled on first use (a few seconds, once per machine: the shared object is cached on disk).
    """

    graph: ca.Function  # (t, z, u, y, m, c) -> (z+, [primal infeasibility, relative stationarity]), SQP inside
    compiled: bool  # whether the fast path is (to be) compiled: a C compiler exists
    pre: ca.Function  # (t, z, u, y, m, c) -> (w0, par, lbx, ubx, lam_g0, carry)
    post: ca.Function  # (carry, w, lam_g, lam_x, par, lbx, ubx) -> (z+, status)
    nlp: dict[str, Any]
    ipopt_opts: dict[str, Any]
    tag: str
    ipopt: ca.Function | None = None
    ipopt_compiled: bool = False
    _fast: ca.Function | None = None

    vm_spent: float = 0.0   # seconds the SQP path has run on the virtual machine in this process
    _sig: str | None = None
    _size: int | None = None

    def fast(self) -> ca.Function:
        """The SQP path: compiled C when it is built (cached on disk), or once the time it has spent on the virtual
        machine in this process reaches the time its compile is predicted to take (so a short run, such as the
        advisor's screening of a window or two, never waits for the compiler: :func:`nlobs.engine.choose_backend`'s
        rule, solve by solve); without a compiler, or when compiling fails, the virtual machine."""
        if self._fast is not None:
            return self._fast
        if not self.compiled:
            self._fast = self.graph
            return self._fast
        if self._sig is None:
            self._sig = signature_of(self.graph)
        path = built_path("mhe", self._sig, "")
        COSTS.spent[self._sig] = self.vm_spent
        if self._size is None:
            self._size = code_size(self.graph)
        if choose_backend("auto", ready=path is not None and path.exists(), n_instr=self._size, vm_instr=0.0,
                          signature=self._sig) == "vm":
            return self.graph
        try:
            self._fast = compile_c(self.graph, sig=self._sig, tag="mhe")
        except EngineError:
            self.compiled = False
            self._fast = self.graph
        return self._fast

    ipopt_spent: float = 0.0   # seconds IPOPT has run with its functions on the virtual machine in this process
    _nlp_sig: str | None = None

    def ipopt_solver(self) -> ca.Function:
        """IPOPT (the fallback when the SQP does not converge) with its functions compiled when they are built (cached
        on disk), or once its time on the virtual machine in this process reaches their predicted compile time (the
        derivatives of the window's Lagrangian: several times the NLP's own size); before that, on the VM."""
        if self.ipopt_compiled:
            return self.ipopt
        name = f"{self.tag}_ipopt"
        if self.compiled and self._nlp_sig is None:
            self._nlp_sig = nlp_signature(self.nlp)
        worth = self.compiled and (nlp_built(name, self._nlp_sig, "ipopt") or
                                   self.ipopt_spent >= COSTS.compile_seconds(4 * code_size(self.graph)))
        if worth:
            try:
                self.ipopt, self.ipopt_compiled = compiled_nlpsol(name, "ipopt", self.nlp, self.ipopt_opts, sig=self._nlp_sig)
                return self.ipopt
            except EngineError:
                self.compiled = False
        if self.ipopt is None:
            self.ipopt = ca.nlpsol(name, "ipopt", self.nlp, self.ipopt_opts)
        return self.ipopt


class _Layout:
    """Where each part of the MHE state z lives."""

    def __init__(self, n: int, nu: int, p: int, N: int, r: int):
        self.dims = {"xhat": n, "T": N + 1, "U": nu * (N + 1), "Y": p * (N + 1), "M": p * (N + 1), "X": n * (N + 1),
                     "V": r * N, "LG": n * N, "xbar": n, "P": n * n, "count": 1, "fallbacks": 1}
        self.off: dict[str, slice] = {}
        k = 0
        for key, d in self.dims.items():
            self.off[key] = slice(k, k + d)
            k += d
        self.size = k

    def part(self, z: Any, key: str) -> Any:
        sl = self.off[key]
        return z[sl.start:sl.stop] if sl.stop > sl.start else type(z)(0, 1)


def _check_options(horizon: Any, substeps: Any, max_iter: Any, tol: Any, arrival: Any, solver: Any, caller: str) -> int:
    """The window length N after checking the solver options (one message per option, naming it)."""
    N = int(horizon) if isinstance(horizon, (int, np.integer)) else -1
    if N < 1:
        raise PreconditionError(f"{caller}: `horizon` must be a positive whole number of sample intervals, got {horizon!r}")
    if not isinstance(substeps, (int, np.integer)) or substeps < 1 or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise PreconditionError(f"{caller}: `substeps` and `max_iter` must be positive integers, got {substeps!r} and {max_iter!r}")
    if not (isinstance(tol, (int, float)) and 0 < tol < 1):
        raise PreconditionError(f"{caller}: `tol` must be a number in (0, 1), got {tol!r}")
    if arrival not in ("ekf", "fixed"):
        raise PreconditionError(f"{caller}: `arrival` must be 'ekf' or 'fixed', got {arrival!r}")
    if solver not in ("sqp", "ipopt"):
        raise PreconditionError(f"{caller}: `solver` must be 'sqp' or 'ipopt', got {solver!r}")
    return N


def _z_names(system: System, N: int, r: int) -> list[str]:
    """Names of the estimator's internal state: x̂, the window's t, u, y, mask, shooting states, noises, multipliers,
    the arrival cost's x̄ and P, and two counters (in the order of :class:`_Layout`)."""
    n, nu, p = system.n_states, system.n_inputs, system.n_outputs
    return ([f"xhat_{v}" for v in system.states] + [f"t_{i}" for i in range(N + 1)]
            + [f"u{j}_{i}" for i in range(N + 1) for j in range(nu)] + [f"y{j}_{i}" for i in range(N + 1) for j in range(p)]
            + [f"m{j}_{i}" for i in range(N + 1) for j in range(p)] + [f"X_{v}_{i}" for i in range(N + 1) for v in system.states]
            + [f"v{j}_{i}" for i in range(N) for j in range(r)] + [f"lam_{v}_{i}" for i in range(N) for v in system.states]
            + [f"xbar_{v}" for v in system.states] + [f"P_{i}_{j}" for j in range(n) for i in range(n)]
            + ["window_count", "solver_fallbacks"])


def _sqrt_psd(Q: np.ndarray) -> np.ndarray:
    """L with L Lᵀ = Q (Q positive semidefinite), keeping only the numerically nonzero directions (n x rank)."""
    w, U = np.linalg.eigh(Q)
    keep = w > 1e-12 * max(1.0, float(np.abs(w).max(initial=0.0)))
    return U[:, keep] * np.sqrt(w[keep])


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
#: The largest number of measurement updates `--run` gives a moving-horizon estimator (one NLP each).
MHE_SAMPLE_BUDGET = 200


def tune_mhe(ctx: Any) -> Tuning:
    sc = ctx.scenario
    Ts = (sc.sample_period or sc.dt) if sc is not None else 0.01
    horizon = int(np.clip(round(2.0 / (ctx.omega_p * Ts)), 10, 30))
    runnable = sc is not None and sc.samples <= MHE_SAMPLE_BUDGET
    note = "" if runnable or sc is None else (f"left out of --run: {sc.samples} measurement updates, each an NLP solve (budget "
                                              f"{MHE_SAMPLE_BUDGET}); run it with `nlobs simulate` on a sampled model")
    opts: dict[str, Any] = {"horizon": horizon, "R": square(ctx.R), "Q": square(ctx.Q), "P0": square(ctx.P0)}
    bounds = domain_bounds(ctx)
    if bounds:
        opts["bounds"] = bounds
    return Tuning.tuned(opts, f"window of {horizon} samples (≈ 2/ω_p); R = σ², Q and P(0) as for the EKF", runnable=runnable,
                    extra=note)


@kind('mhe', likelihood='ekf', summary='moving-horizon estimator over the last samples (multiple shooting, compiled NLP)',
      references=(work("002", "trajectory-based observers (moving horizon)"),), tune=tune_mhe, time_base="both")
def design_mhe(system: System, *, horizon: int = 20, R: Any = None, Q: Any = None, P0: Any = None,
               bounds: Mapping[str, Any] | None = None, arrival: Literal["ekf", "fixed"] = "ekf",
               solver: Literal["sqp", "ipopt"] = "sqp", substeps: int = 2, max_iter: int = 50, tol: float = 1e-8,
               xhat0: Any = None) -> ObserverDesign:
    r"""Moving-horizon estimator over the last `horizon` sample intervals (multiple shooting, compiled NLP).

    At sample :math:`t_k` the window holds the samples :math:`(t_i, u_i, y_i)`,
    :math:`i = k-N, \dots, k`, and the estimator solves

    .. math::

        \min_{x_{k-N..k},\, v} \; \|x_{k-N} - \bar x\|^2_{P^{-1}}
            + \sum_{i} \|m_i \odot (y_i - h(t_i, x_i, u_i))\|^2_{R^{-1}} + \sum_i \|v_i\|^2
        \quad\text{s.t.}\quad x_{i+1} = F(x_i, u_i; t_i, \Delta_i) + \sqrt{\Delta_i}\, L v_i,
        \quad x_i \in [\ell, \upsilon],

    Besançon (2010), "Some observer problem formulations - About methods", approach I;
    Rao, Rawlings & Mayne (2003); Kühl et al. (2011).

    Parameters
    ----------
    system : System
    horizon : int
        N, the number of sample intervals in the window (N + 1 samples), >= 1.
    R : array_like of shape (p, p), optional
        Covariance of one measurement sample, positive definite (identity).
    Q : array_like of shape (n, n), optional
        Process-noise intensity (continuous time, as for :func:`design_ekf`), positive
        semidefinite; the noise of an interval Δ has covariance QΔ. Default 0: the window's
        trajectory is an exact model trajectory. For a discrete-time model (a map), the covariance of
        the noise per step: the window's constraint is then :math:`x_{i+1} = f(x_i, u_i, t_i) + L v_i`.
    P0 : array_like of shape (n, n), optional
        Covariance of the initial estimate (the first arrival cost), positive definite (identity).
    bounds : mapping of state name to (lo, hi), optional
        Hard bounds on the window's states, e.g. ``{"x1": (0, None)}``; the model is evaluated at
        states clipped to them (see :mod:`nlobs.design` bounds policy).
    arrival : {"ekf", "fixed"}
        How the arrival cost follows the window.
    solver : {"sqp", "ipopt"}
        ``"sqp"``: compiled SQP (exact Hessian, qrqp), IPOPT as fallback when its solution fails
        the optimality check; ``"ipopt"``: IPOPT only.

    Other Parameters
    ----------------
    substeps : int
        RK4 steps per sample interval inside the window.
    max_iter : int
        Iteration limit per sample.
    tol : float
        Solver tolerance (primal infeasibility and stationarity); a solution is accepted when both
        are below max(tol, 1e-6) (stationarity relative to the objective's gradient).
    xhat0 : array_like of shape (n,), optional
        Initial estimate: the first arrival prior (zeros).

    Returns
    -------
    ObserverDesign
        Sampled (its ``update`` runs at sample instants); z holds the estimate, the window
        (t, u, y, mask), its solution (states, noise, multipliers), the arrival prior and
        covariance, the number of samples in the window and the number of IPOPT fallbacks.

    Raises
    ------
    PreconditionError, ShapeError
        For a bad horizon, weights of the wrong shape or definiteness, bad bounds (or a model whose
        Jacobian is infinite on a bound), an initial estimate outside the bounds.
    SolverError
        During a run, when the window's NLP cannot be solved (named with its time span and the
        solvers' status).

    Notes
    -----
    The solver is generated as C and compiled once per model structure and horizon (cached on
    disk); weights, bounds and parameter values are inputs of the compiled code. Without a C
    compiler the same solver runs on CasADi's virtual machine.

    References
    ----------
    Besançon (2010), "Some observer problem formulations - About methods", approach I;
    Rao, Rawlings & Mayne (2003); Kühl et al. (2011).
    """
    require_system(system, "design_mhe")
    caller = "design_mhe"
    n, p, nu = system.n_states, system.n_outputs, system.n_inputs
    N = _check_options(horizon, substeps, max_iter, tol, arrival, solver, caller)
    if p == 0:
        raise PreconditionError(f"{caller}: the model {system.name!r} has no outputs; MHE fits the outputs")
    Rm = np.eye(p) if R is None else check_matrix(R, p, p, "R", caller, definite="positive")
    Qm = np.zeros((n, n)) if Q is None else check_matrix(Q, n, n, "Q", caller, definite="semidefinite")
    P0m = np.eye(n) if P0 is None else check_matrix(P0, n, n, "P0", caller, definite="positive")
    x0v = check_vector(np.zeros(n) if xhat0 is None else xhat0, n, "xhat0", caller)
    box = parse_bounds(system, bounds, caller)
    evidence = check_start(system, box, np.array(x0v), caller)
    Lq = _sqrt_psd(Qm)
    r = Lq.shape[1]
    Ri = np.linalg.cholesky(np.linalg.inv(Rm)).T  # Riᵀ Ri = R⁻¹
    lo = np.full(n, -np.inf) if box is None else box.lo
    hi = np.full(n, np.inf) if box is None else box.hi
    consts = np.concatenate([Lq.reshape(-1, order="F"), Rm.reshape(-1, order="F"), Ri.reshape(-1, order="F"),
                             P0m.reshape(-1, order="F"), lo, hi, system.param_values, [1.0 if arrival == "ekf" else 0.0]])
    lay = _Layout(n, nu, p, N, r)
    if system.is_discrete:   # a map: one step per interval, and the per-step noise enters as sqrt(Ts)·(L/sqrt(Ts))·v
        substeps = 1
        consts[:n * r] = (Lq / np.sqrt(system.sample_time)).reshape(-1, order="F")
    solvers = _solvers(system, N, r, int(substeps), int(max_iter), float(tol), lay)
    name = f"mhe_update_{next(_NAMES)}"
    kink_fns = sorted({nm for e in (*system.f, *system.h) for fn, nm in ((sp.sign, "sign"), (sp.Abs, "abs")) if e.has(fn)})
    update = _MHEUpdate(name, lay, (n, nu, p, N), solvers, consts, solver, max(float(tol), 1e-6), kink_fns)

    # flow between samples: predict the estimate (model evaluated inside the bounds), keep the rest
    f, _ = compile_system(system).bind()
    t, z, u, y = ca.SX.sym("t"), ca.SX.sym("z", lay.size), ca.SX.sym("u", nu), ca.SX.sym("y", p)
    xh = z[:n]
    flow = (ca.SX.zeros(lay.size) if system.is_discrete   # a map's estimate changes at the samples only
            else ca.vertcat(f(t, clip_const(xh, box), u), ca.SX.zeros(lay.size - n)))
    x0 = ca.SX.sym("xhat0", n)
    z0 = ca.vertcat(x0, ca.SX.zeros(lay.dims["T"] + lay.dims["U"] + lay.dims["Y"] + lay.dims["M"]), ca.repmat(x0, N + 1, 1),
                    ca.SX.zeros(lay.dims["V"] + lay.dims["LG"]), x0, ca.DM(P0m.reshape(-1, order="F")), 0, 0)
    checks = [Check("R positive definite, Q positive semidefinite, P0 positive definite", True,
                    f"min eig R = {np.linalg.eigvalsh(Rm).min():.3g}, Q = {np.linalg.eigvalsh(Qm).min():.3g} "
                    f"(rank {r}), P0 = {np.linalg.eigvalsh(P0m).min():.3g}")]
    bc = bounds_check(box, evidence)
    if bc is not None:
        checks.append(bc)
    kinks = [f"{nm}()" for nm in kink_fns]
    if kinks:
        checks.append(Check("the model is differentiable (the SQP and IPOPT take Newton steps)", False,
                            f"it uses {', '.join(kinks)}: a window whose trajectory crosses such a switch is a nonsmooth NLP, "
                            "which may not converge (SolverError); a steep smooth step, e.g. (1 + tanh(s/w))/2 for "
                            "(1 + sign(s))/2, avoids it", "symbolic"))
    checks.append(Check.assumed("the model is observable over the window for the data",
                                "not checked at design time (it depends on the input and the trajectory): an unobservable "
                                "window leaves the arrival cost in charge"))
    values = {"horizon (intervals)": N, "R": Rm, "Q": Qm, "P0": P0m, "arrival": arrival, "solver": solver,
              "substeps": int(substeps), "max_iter": int(max_iter), "tol": float(tol),
              "bounds": "none" if box is None else box.describe(),
              "compiled": ("generated C (compiled on first use, cached on disk)" if solvers.compiled
                           else "no C compiler: CasADi virtual machine")}
    cert = Certificate(f"Moving-horizon estimator (window of {N} intervals, multiple shooting, "
                       f"{'SQP with IPOPT fallback' if solver == 'sqp' else 'IPOPT'})", REF, tuple(checks), values)
    z_names = _z_names(system, N, r)
    ins, names = [t, z, u, y], ["t", "z", "u", "y"]
    return ObserverDesign(
        "mhe", system, tuple(z_names),
        ca.Function("mhe_flow", ins, [flow], names, ["dz"]),
        ca.Function("mhe_output", ins, [xh], names, ["xhat"]),
        ca.Function("mhe_initial", [x0], [z0], ["xhat0"], ["z0"]),
        x0v, cert, update)


def _solvers(system: System, N: int, r: int, substeps: int, max_iter: int, tol: float, lay: _Layout) -> _Solvers:
    key = (system.key, N, r, substeps, max_iter, tol, find_compiler() is not None)
    hit = _CACHE.get(key)
    if hit is None:
        hit = _CACHE[key] = _build(system, N, r, substeps, max_iter, tol, lay)
    return hit


def _arrival_core(tag: str, hx: ca.SX, xs: ca.SX, ys: ca.SX, ms: ca.SX, us: ca.SX, ts: ca.SX, ps: ca.SX, los: ca.SX,
                  his: ca.SX, r: int) -> ca.Function:
    """The arrival cost's EKF step (SX): measurement update of (x̄, P) at the leaving node, linearised at the MHE
    solution xl there (Joseph form; masked outputs left out), then the prediction x̄⁺ = F(xl) + A(x̄ − xl),
    P⁺ = APAᵀ + dt·LqLqᵀ with the interval map F and its Jacobian A given as inputs."""
    n, p = xs.shape[0], ys.shape[0]
    xbar, xl, Rs = ca.SX.sym("xbar", n), ca.SX.sym("xl", n), ca.SX.sym("R", p, p)
    P = ca.SX.sym("P", n, n)
    Al, Fl, dts, Lqs = ca.SX.sym("A", n, n), ca.SX.sym("Fl", n), ca.SX.sym("dt"), ca.SX.sym("Lq", n, r)
    Psym = (P + P.T) / 2
    H = ca.jacobian(hx, xs)
    hl, Hl = ca.substitute([hx, H], [xs], [xl])
    Md = ca.diag(ms)
    Hm = Md @ Hl
    Rmask = Md @ Rs @ Md + ca.diag(1 - ms)
    S = Hm @ Psym @ Hm.T + Rmask
    K = ca.solve((S + S.T) / 2, Hm @ Psym).T
    e = ms * (ys - hl - Hl @ (xbar - xl))
    xf = xbar + K @ e
    IKH = ca.DM.eye(n) - K @ Hm
    Pf = IKH @ Psym @ IKH.T + K @ Rmask @ K.T
    xn = clip(Fl + Al @ (xf - xl), los, his)
    Pn = Al @ Pf @ Al.T + dts * (Lqs @ Lqs.T)
    return ca.Function(f"{tag}_arrival_core", [xbar, P, xl, Fl, Al, ys, ms, us, ts, dts, Lqs, Rs, ps, los, his],
                       [xn, (Pn + Pn.T) / 2])


def _build(system: System, N: int, r: int, substeps: int, max_iter: int, tol: float, lay: _Layout) -> _Solvers:
    comp = compile_system(system)
    n, p, nu, npar = system.n_states, system.n_outputs, system.n_inputs, system.n_params
    tag = "mhe_" + hashlib.sha256(repr((system.key, N, r, substeps, max_iter, tol)).encode()).hexdigest()[:12]

    # -- building blocks: one RK4 step (SX), an interval of `substeps` of them (MX calls, so that code size and
    # derivatives do not grow with substeps), the output residual, the arrival EKF step
    xs, us, ts, hs = ca.SX.sym("x", n), ca.SX.sym("u", nu), ca.SX.sym("t"), ca.SX.sym("h")
    ps, los, his = ca.SX.sym("p", npar), ca.SX.sym("lo", n), ca.SX.sym("hi", n)
    if system.is_discrete:   # the interval is one step of the map x[k+1] = f(x[k], u[k], t[k]); none in an empty slot
        one = ca.Function(f"{tag}_map", [xs, ts, hs, us, ps, los, his],   # of a filling window (h = 0)
                          [ca.if_else(hs > 0, comp.f(ts, clip(xs, los, his), us, ps), xs)])
    else:
        one = ca.Function(f"{tag}_rk4", [xs, ts, hs, us, ps, los, his],
                          [rk4_step(lambda tt, xx, _k: comp.f(tt, clip(xx, los, his), us, ps), ts, xs, hs)])
    xm, um, tm, dtm = ca.MX.sym("x", n), ca.MX.sym("u", nu), ca.MX.sym("t"), ca.MX.sym("dt")
    pm, lom, him = ca.MX.sym("p", npar), ca.MX.sym("lo", n), ca.MX.sym("hi", n)
    xe = xm
    for i in range(substeps):
        xe = one(xe, tm + i * dtm / substeps, dtm / substeps, um, pm, lom, him)
    advance = ca.Function(f"{tag}_advance", [xm, tm, dtm, um, pm, lom, him], [xe])
    # the noise of an interval enters as sqrt(dt) L v; sqrt(dt) is a parameter of its own, so that no derivative
    # of sqrt at dt = 0 (the empty slots of a filling window) multiplies a zero seed into a NaN
    xbm, vm, Lqm, sdm = ca.MX.sym("xb", n), ca.MX.sym("v", r), ca.MX.sym("Lq", n, r), ca.MX.sym("sqrt_dt")
    defect = xbm - xe - (sdm * (Lqm @ vm) if r else 0)
    interval = ca.Function(f"{tag}_interval", [xm, xbm, vm, tm, dtm, sdm, um, Lqm, pm, lom, him], [defect])
    ys, ms, Ris = ca.SX.sym("y", p), ca.SX.sym("m", p), ca.SX.sym("Ri", p, p)
    hx = comp.h(ts, clip(xs, los, his), us, ps)
    residual = ca.Function(f"{tag}_residual", [xs, ts, us, ys, ms, Ris, ps, los, his], [Ris @ (ms * (ys - hx))])
    # arrival: EKF measurement update of (xbar, P) at the leaving node, then prediction to the next node,
    # both linearised at the MHE solution xl of the leaving node (Joseph form; masked outputs left out)
    ekf_core = _arrival_core(tag, hx, xs, ys, ms, us, ts, ps, los, his, r)
    # the interval map and its Jacobian at the leaving node (MX)
    xbar_m, P_m, xl_m, y_m, m_m, R_m = (ca.MX.sym(nm, *sh) for nm, sh in
                                        (("xbar", (n, 1)), ("P", (n, n)), ("xl", (n, 1)), ("y", (p, 1)), ("m", (p, 1)), ("R", (p, p))))
    Fl_m = advance(xl_m, tm, dtm, um, pm, lom, him)
    Al_m = ca.jacobian(Fl_m, xl_m)
    arrival_ekf = ca.Function(f"{tag}_arrival", [xbar_m, P_m, xl_m, y_m, m_m, um, tm, dtm, Lqm, R_m, pm, lom, him],
                              ekf_core(xbar_m, P_m, xl_m, Fl_m, Al_m, y_m, m_m, um, tm, dtm, Lqm, R_m, pm, lom, him))

    # -- the window NLP (MX, the interval and residual functions mapped over the window)
    X, V = ca.MX.sym("X", n, N + 1), ca.MX.sym("V", r, N)
    T, U, Y, M = ca.MX.sym("T", N + 1), ca.MX.sym("U", nu, N + 1), ca.MX.sym("Y", p, N + 1), ca.MX.sym("M", p, N + 1)
    SD = ca.MX.sym("SD", N)
    xb_, Pinv, Lq, Ri = ca.MX.sym("xbar", n), ca.MX.sym("Pinv", n, n), ca.MX.sym("Lq", n, r), ca.MX.sym("Ri", p, p)
    prm, lo, hi = ca.MX.sym("p", npar), ca.MX.sym("lo", n), ca.MX.sym("hi", n)
    dt = (T[1:] - T[:-1]).T
    D = interval.map(N)(X[:, :-1], X[:, 1:], V, T[:-1].T, dt, SD.T, U[:, :-1], Lq, prm, lo, hi)
    E = residual.map(N + 1)(X, T.T, U, Y, M, Ri, prm, lo, hi)
    d0 = X[:, 0] - xb_
    J = ca.bilin(Pinv, d0, d0) + ca.sumsqr(E) + ca.sumsqr(V)
    w = ca.vertcat(ca.vec(X), ca.vec(V))
    par = ca.vertcat(T, SD, ca.vec(U), ca.vec(Y), ca.vec(M), xb_, ca.vec(Pinv), ca.vec(Lq), ca.vec(Ri), prm, lo, hi)
    g = ca.vec(D)
    nlp = {"x": w, "p": par, "f": J, "g": g}
    nw, ng = w.shape[0], g.shape[0]
    lam_g, lam_x = ca.MX.sym("lam_g", ng), ca.MX.sym("lam_x", nw)
    lbx, ubx = ca.MX.sym("lbx", nw), ca.MX.sym("ubx", nw)
    grad = ca.gradient(J, w)
    stat = grad + ca.jtimes(g, w, lam_g, True) + lam_x
    viol = ca.vertcat(g, ca.fmax(lbx - w, 0), ca.fmax(w - ubx, 0))
    kkt = ca.Function(f"{tag}_kkt", [w, par, lam_g, lam_x, lbx, ubx],
                      [ca.vertcat(ca.norm_inf(viol), ca.norm_inf(stat) / ca.fmax(1, ca.norm_inf(grad)))])

    # -- pre: shift the window, update the arrival cost, warm start (MX; z and the constants c in)
    t, u, y, m = ca.MX.sym("t"), ca.MX.sym("u", nu), ca.MX.sym("y", p), ca.MX.sym("m", p)
    z = ca.MX.sym("z", lay.size)
    nc = n * r + 2 * p * p + n * n + 2 * n + npar + 1
    c = ca.MX.sym("c", nc)
    k = 0

    def take(rows_: int, cols: int) -> ca.MX:
        nonlocal k
        out = ca.reshape(c[k:k + rows_ * cols], rows_, cols) if rows_ * cols else ca.MX(rows_, cols)
        k += rows_ * cols
        return out

    cLq, cR, cRi, cP0 = take(n, r), take(p, p), take(p, p), take(n, n)
    clo, chi, cp, cekf = take(n, 1), take(n, 1), take(npar, 1), take(1, 1)
    zT = lay.part(z, "T")
    zU = ca.reshape(lay.part(z, "U"), nu, N + 1)
    zY, zM = ca.reshape(lay.part(z, "Y"), p, N + 1), ca.reshape(lay.part(z, "M"), p, N + 1)
    zX, zV = ca.reshape(lay.part(z, "X"), n, N + 1), ca.reshape(lay.part(z, "V"), r, N)
    zLG = ca.reshape(lay.part(z, "LG"), n, N)
    zxbar, zP = lay.part(z, "xbar"), ca.reshape(lay.part(z, "P"), n, n)
    count, fallbacks = lay.part(z, "count"), lay.part(z, "fallbacks")
    first, full = count < 0.5, count > N + 0.5
    T1 = ca.if_else(first, ca.repmat(t, N + 1, 1), ca.vertcat(zT[1:], t))
    U1 = ca.if_else(first, ca.repmat(u, 1, N + 1), ca.horzcat(zU[:, 1:], u)) if nu else ca.MX(0, N + 1)
    Y1 = ca.if_else(first, ca.repmat(y, 1, N + 1), ca.horzcat(zY[:, 1:], y))
    M1 = ca.if_else(first, ca.horzcat(ca.MX.zeros(p, N), m), ca.horzcat(zM[:, 1:], m))
    xe_, Pe_ = arrival_ekf(zxbar, zP, zX[:, 0], zY[:, 0], zM[:, 0], zU[:, 0], zT[0], zT[1] - zT[0], cLq, cR, cp, clo, chi)
    xbar1 = ca.if_else(full, ca.if_else(cekf, xe_, zX[:, 1]), zxbar)
    P1 = ca.if_else(full, ca.if_else(cekf, Pe_, cP0), zP)
    # with the fixed (smoothed) prior, the first node's measurement is already in the prior
    M1 = ca.horzcat(ca.if_else(ca.logic_and(full, cekf < 0.5), ca.MX.zeros(p, 1), M1[:, 0]), M1[:, 1:])
    pred = advance(zX[:, N], zT[N], t - zT[N], zU[:, N], cp, clo, chi)
    Xg = clip(ca.if_else(first, ca.repmat(zxbar, 1, N + 1), ca.horzcat(zX[:, 1:], pred)), clo, chi)
    Vg = ca.if_else(first, ca.MX.zeros(r, N), ca.horzcat(zV[:, 1:], ca.MX.zeros(r, 1))) if r else ca.MX(0, N)
    LGg = ca.if_else(first, ca.MX.zeros(n, N), ca.horzcat(zLG[:, 1:], ca.MX.zeros(n, 1)))
    Pinv1 = ca.solve(P1, ca.MX.eye(n))
    par1 = ca.vertcat(T1, ca.sqrt(ca.fmax(T1[1:] - T1[:-1], 0)), ca.vec(U1), ca.vec(Y1), ca.vec(M1), xbar1, ca.vec((Pinv1 + Pinv1.T) / 2), ca.vec(cLq), ca.vec(cRi),
                      cp, clo, chi)
    lbx1 = ca.vertcat(ca.repmat(clo, N + 1, 1), -np.inf * ca.DM.ones(r * N))
    ubx1 = ca.vertcat(ca.repmat(chi, N + 1, 1), np.inf * ca.DM.ones(r * N))
    carry = ca.vertcat(T1, ca.vec(U1), ca.vec(Y1), ca.vec(M1), xbar1, ca.vec(P1), ca.fmin(count + 1, N + 1), fallbacks)
    w0 = ca.vertcat(ca.vec(Xg), ca.vec(Vg))
    pre = ca.Function(f"{tag}_pre", [t, z, u, y, m, c], [w0, par1, lbx1, ubx1, ca.vec(LGg), carry],
                      ["t", "z", "u", "y", "m", "c"], ["x0", "p", "lbx", "ubx", "lam_g0", "carry"])

    # -- post: the solution into z+, and its optimality check
    cr = ca.MX.sym("carry", carry.shape[0])
    ws, lgs, lxs, ps_, lbs, ubs = (ca.MX.sym(nm, sz) for nm, sz in
                                   (("w", nw), ("lam_g", ng), ("lam_x", nw), ("p", par1.shape[0]), ("lbx", nw), ("ubx", nw)))
    Xs = ca.reshape(ws[:n * (N + 1)], n, N + 1)
    k2 = 0

    def cut(size: int) -> ca.MX:
        nonlocal k2
        out = cr[k2:k2 + size] if size else ca.MX(0, 1)
        k2 += size
        return out

    cT, cU, cY, cM, cxbar, cPv, ccount, cfb = (cut(sz) for sz in (N + 1, nu * (N + 1), p * (N + 1), p * (N + 1), n, n * n, 1, 1))
    lo_p = ps_[ps_.shape[0] - 2 * n:ps_.shape[0] - n]
    hi_p = ps_[ps_.shape[0] - n:]
    zplus = ca.vertcat(clip(Xs[:, N], lo_p, hi_p), cT, cU, cY, cM, ws, lgs, cxbar, cPv, ccount, cfb)
    post = ca.Function(f"{tag}_post", [cr, ws, lgs, lxs, ps_, lbs, ubs], [zplus, kkt(ws, ps_, lgs, lxs, lbs, ubs)],
                       ["carry", "x", "lam_g", "lam_x", "p", "lbx", "ubx"], ["z_plus", "status"])

    # -- the fast path: pre -> SQP -> post, one function, generated as C and compiled
    sqp_opts = {"qpsol": "qrqp", "qpsol_options": {"print_iter": False, "print_header": False, "error_on_fail": False},
                "print_time": False, "print_header": False, "print_iteration": False, "print_status": False,
                "tol_pr": tol, "tol_du": tol, "max_iter": max_iter, "min_step_size": 1e-14, "error_on_fail": False}
    sqp = ca.nlpsol(f"{tag}_sqp", "sqpmethod", nlp, sqp_opts)
    w0_, par_, lbx_, ubx_, lg0_, carry_ = pre(t, z, u, y, m, c)
    sol = sqp(x0=w0_, p=par_, lbx=lbx_, ubx=ubx_, lbg=0, ubg=0, lam_g0=lg0_)
    zp, st = post(carry_, sol["x"], sol["lam_g"], sol["lam_x"], par_, lbx_, ubx_)
    fast = ca.Function(f"{tag}_step", [t, z, u, y, m, c], [zp, st], ["t", "z", "u", "y", "m", "c"], ["z_plus", "status"])
    ipopt_opts = {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False, "ipopt.tol": tol, "ipopt.max_iter": max_iter,
                  "ipopt.bound_relax_factor": 0.0, "error_on_fail": False}
    return _Solvers(fast, find_compiler() is not None, pre, post, nlp, ipopt_opts, tag)


def _window_text(T: np.ndarray, N: int) -> str:
    """The window a failing solve was given, in words: while the window fills (its first samples repeat the first
    time) "t in [0, 0]" would say nothing, so the samples it has are counted instead."""
    have = np.unique(T).size
    if have < T.size:
        return (f"the window at t = {T[-1]:g} (the first {have} sample{'s' if have > 1 else ''} of the run; the window "
                f"fills up to {N + 1} samples)" if have > 1 else f"the window at the first sample (t = {T[-1]:g})")
    return f"the window t in [{T[0]:g}, {T[-1]:g}] ({N} intervals)"


class _MHEUpdate(ca.Callback):
    """z⁺ = J(t, z, u, y, m): the compiled SQP (or IPOPT) on the shifted window; a failure is recorded
    (raised by the caller after the evaluation, see :mod:`nlobs.engine`) and NaN returned."""

    def __init__(self, name: str, lay: _Layout, dims: tuple[int, int, int, int], solvers: _Solvers, consts: np.ndarray,
                 solver: str, accept: float, kinks: list[str]):
        ca.Callback.__init__(self)
        self.lay, self.solvers, self.consts, self.solver, self.accept, self.kinks = lay, solvers, consts, solver, accept, kinks
        self.n, self.nu, self.p, self.N = dims
        self._lock = threading.Lock()
        # the fast function through a preallocated buffer (no per-call allocation of CasADi arguments), set up on first use
        self._args = [np.zeros(1), np.zeros(lay.size), np.zeros(self.nu), np.zeros(self.p), np.zeros(self.p), consts.copy()]
        self._res = [np.zeros(lay.size), np.zeros(2)]
        self._ev: Any = None
        self._ev_of: Any = None
        self.construct(name, {})

    def _evaluator(self) -> Any:
        fn = self.solvers.fast()
        if self._ev is None or fn is not self._ev_of:
            self._ev_of = fn
            buf, ev = fn.buffer()
            for i, a in enumerate(self._args):
                buf.set_arg(i, memoryview(a))
            for i, a in enumerate(self._res):
                buf.set_res(i, memoryview(a))
            self._buf, self._ev = buf, ev
        return self._ev

    def get_n_in(self) -> int:
        return 5

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return ("t", "z", "u", "y", "m")[i]

    def get_name_out(self, i: int) -> str:
        return "z_plus"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense((1, self.lay.size, self.nu, self.p, self.p)[i], 1)

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self.lay.size, 1)

    def has_eval_buffer(self) -> bool:
        return True

    def eval_buffer(self, arg: list[Any], res: list[Any]) -> int:
        """Evaluate on CasADi's buffers (no DM conversion: ~10 µs of overhead instead of ~100)."""
        t, z, u, y, m = (np.frombuffer(a, dtype=float) if a is not None else np.zeros(0) for a in arg)
        out = np.frombuffer(res[0], dtype=float)
        if not (np.all(np.isfinite(z)) and np.isfinite(t[0])):
            out[:] = np.nan  # after an earlier failure in the same evaluation
            return 0
        try:
            out[:] = self.solve(t, z, u, y, m)
        except (SolverError, TimeBudgetError) as e:
            defer_error(e)
            out[:] = np.nan
        return 0

    def eval(self, arg: list[ca.DM]) -> list[ca.DM]:  # symbolic/other callers; the VM uses eval_buffer
        out = np.zeros(self.lay.size)
        self.eval_buffer([memoryview(np.asarray(a, dtype=float).reshape(-1)) for a in arg], [memoryview(out)])
        return [ca.DM(out)]

    def _ok(self, zp: np.ndarray, status: np.ndarray) -> bool:
        return bool(np.all(np.isfinite(zp)) and np.all(np.isfinite(status)) and status[0] <= self.accept
                    and status[1] <= self.accept)

    def solve(self, t: np.ndarray, z: np.ndarray, u: np.ndarray, y: np.ndarray, m: np.ndarray) -> np.ndarray:
        check_time("solving its window NLPs")   # a time budget (nlobs design --run) ends the run between two windows
        sqp_status = ""
        if self.solver == "sqp":
            with self._lock:
                ev = self._evaluator()
                for dst, src in zip(self._args, (t, z, u, y, m)):
                    dst[:] = src
                t0 = time.perf_counter()
                ev()
                if self._ev_of is self.solvers.graph:   # on the VM: counts toward compiling it
                    self.solvers.vm_spent += time.perf_counter() - t0
                zp, status = self._res[0].copy(), self._res[1].copy()
            if self._ok(zp, status):
                return zp
            sqp_status = (f"SQP: not converged (primal infeasibility {status[0]:.3g}, relative stationarity {status[1]:.3g}; "
                          f"accepted below {self.accept:g})")
        s = self.solvers
        w0, par, lbx, ubx, lg0, carry = s.pre(t, z, u, y, m, self.consts)
        ipopt = s.ipopt_solver()
        t0 = time.perf_counter()
        sol = ipopt(x0=w0, p=par, lbx=lbx, ubx=ubx, lbg=0, ubg=0, lam_g0=lg0)
        if not s.ipopt_compiled:
            s.ipopt_spent += time.perf_counter() - t0
        stats = ipopt.stats()
        zp_dm, status_dm = s.post(carry, sol["x"], sol["lam_g"], sol["lam_x"], par, lbx, ubx)
        zp, status = np.asarray(zp_dm, dtype=float).reshape(-1), np.asarray(status_dm, dtype=float).reshape(-1)
        if stats.get("success", False) and np.all(np.isfinite(zp)):
            if self.solver == "sqp":
                zp[self.lay.off["fallbacks"].start] += 1
            return zp
        T1 = np.asarray(carry, dtype=float).reshape(-1)[:self.N + 1]
        ipopt_status = f"IPOPT: {stats.get('return_status', 'unknown')} after {stats.get('iter_count', '?')} iterations"
        status_text = "; ".join(s_ for s_ in (sqp_status, ipopt_status) if s_)
        hint = (f"the model uses {' and '.join(self.kinks)}, whose switches make the window problem nonsmooth: write them "
                "as steep smooth steps; otherwise " if self.kinks else "")
        raise SolverError(
            f"MHE: {_window_text(T1, self.N)} could not be solved: {status_text}. "
            f"Check the model and the data in that window (a NaN in the model, an output the window cannot explain); {hint}"
            "more process noise (Q), a larger R, bounds on the states, or a larger `max_iter` may help",
            window=(T1[0], T1[-1]), status=status_text)
