"""Fixed-interval smoothing of a continuous-discrete EKF or UKF run: Rauch-Tung-Striebel on the sample grid.

The filter gives, at each sample k, the filtered mean and covariance (x̂_k, P_k). Between samples it
integrated its flow by RK4 in n_k sub-steps, which maps x̂_k to the prediction x̂⁻_{k+1} and P_k to
P⁻_{k+1}. The backward pass (Rauch, Tung & Striebel (1965); unscented form: Särkkä (2008))

.. math::

    G_k = P_k A_k^\\top (P^-_{k+1})^{-1}, \\quad
    x^s_k = \\hat x_k + G_k (x^s_{k+1} - \\hat x^-_{k+1}), \\quad
    P^s_k = P_k + G_k (P^s_{k+1} - P^-_{k+1}) G_k^\\top ,

needs A_k, the linearisation of the transition from sample k to k + 1 (A_k P_k is the cross-covariance
of x_{k+1} and x_k):

- EKF: the Jacobian of the RK4 map the filter integrates, over its n_k sub-steps. It is computed by
  integrating Φ' = (∂f/∂x) Φ, Φ(t_k) = I, with the same RK4 stages as x (for explicit Runge-Kutta,
  the scheme applied to the variational equation gives exactly the Jacobian of the scheme's map).
- UKF: the statistical linearisation of the sigma-point flow, F̄ = Σᵢ Wᶜᵢ (f(𝒳ᵢ) − f̄)(𝒳ᵢ − m)ᵀ P⁻¹
  (for which the UKF's covariance flow is Ṗ = F̄P + PF̄ᵀ + Q), integrated the same way: the cross-covariance
  Φ P_k of x(t) and x_k then follows the extra differential equation of the continuous-discrete Gaussian
  smoother of Särkkä & Sarmavuori (2013), the continuous-discrete counterpart of the unscented RTS
  smoother of Särkkä (2008). For a linear model both smoothers are the exact Kalman smoother.

The predictions x̂⁻, P⁻ and A_k come from one compiled replay of the filter over the same intervals with
the same sub-step counts (so prediction and filter agree to rounding); the backward pass is a compiled
loop over the samples.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from ..design import ObserverDesign
from ..engine import Backend, compile_system, rows
from ..engine._integrate import rk4_step_rate
from ..engine._intervals import IntervalRunner
from ..errors import FiniteEscapeError, PreconditionError
from ..simulate._loop import Loop

__all__ = ["SMOOTHABLE", "rts_smooth", "check_smoothable", "INFLATION", "forget"]

#: The observer kinds a fixed-interval smoother exists for (continuous-discrete, without state bounds).
SMOOTHABLE = ("ekf", "ukf")
#: A smoothed variance above INFLATION × the filtered one (plus rounding of the column's largest filtered variance)
#: is a diverged backward pass: in exact arithmetic P^s_k <= P_k (Rauch, Tung & Striebel (1965)).
INFLATION = 10.0


def check_smoothable(design: ObserverDesign, name: str) -> None:
    """Refuse, in one line, an observer the smoother does not support."""
    ok = design.method in SMOOTHABLE and design.update is not None and design.covariance is not None
    if not ok:
        mode = " in continuous mode" if design.method == "ekf" else ""
        raise PreconditionError(f"smoothing: observer {name!r} is of kind {design.method!r}{mode}; smoothers exist for the "
                                f"continuous-discrete kinds {', '.join(SMOOTHABLE)} only")
    if "bounds" in design.certificate.values:
        raise PreconditionError(f"smoothing: observer {name!r} ({design.method}) has state bounds; the smoother supports "
                                f"{', '.join(SMOOTHABLE)} without bounds only")


def _linearisation(d: ObserverDesign, t: Any, z: Any, u: Any) -> Any:
    """A(t, z, u): the matrix whose flow Φ' = AΦ gives the transition's linearisation (see the module docstring)."""
    n = d.system.n_states
    f, _ = compile_system(d.system).bind()
    x = z[:n]
    if d.method == "ekf":
        return ca.jacobian(f(t, x, u), x)
    from ..design.kalman._ukf import unscented_weights

    v = d.certificate.values
    wm, wc, c = unscented_weights(n, float(v["alpha"]), float(v["beta"]), float(v["kappa"]))
    P = ca.reshape(z[n:n + n * n], n, n)
    P = (P + P.T) / 2
    Lc = ca.chol(P).T * np.sqrt(c)
    X = [x] + [x + Lc[:, i] for i in range(n)] + [x - Lc[:, i] for i in range(n)]
    F = [f(t, xi, u) for xi in X]
    fbar = sum((float(wm[i]) * F[i] for i in range(2 * n + 1)), ca.SX.zeros(n))
    C = sum((float(wc[i]) * (F[i] - fbar) @ (X[i] - x).T for i in range(2 * n + 1)), ca.SX.zeros(n, n))
    return ca.solve(P, C.T).T


class _Replay:
    """The filter replayed over the intervals with the transition's linearisation Φ integrated alongside;
    the per-sample output is (x̂⁻, P⁻, Φ) of the interval just ended."""

    def __init__(self, d: ObserverDesign, hold: str):
        s = d.system
        n, nu, ny, nz = s.n_states, s.n_inputs, s.n_outputs, d.n_z
        self.n, self.nz, self.ny = n, nz, ny
        _, h = compile_system(s).bind()
        ns = nz + ny + n * n
        S, a, th = ca.SX.sym("S", ns), ca.SX.sym("a", 2 + 2 * (nu + 2 * ny)), ca.SX.sym("th", 2)
        z, yh, Phi = rows(S, 0, nz), rows(S, nz, nz + ny), ca.reshape(rows(S, nz + ny, ns), n, n)
        t, dt = a[0], a[1]
        o1 = 2 + nu + 2 * ny
        u0, m0 = rows(a, 2, 2 + nu), rows(a, 2 + nu + ny, 2 + nu + 2 * ny)
        u1, y1, m1 = rows(a, o1, o1 + nu), rows(a, o1 + nu, o1 + nu + ny), rows(a, o1 + nu + ny, o1 + nu + 2 * ny)
        if hold == "linear":  # as the filter holds them (observer/_compiled.py)
            slope, u_slope = (m0 * m1) * (y1 - yh) / dt, (u1 - u0) / dt
        else:
            slope, u_slope = ca.SX.zeros(ny), ca.SX.zeros(nu)
        zz, tt, uu = ca.SX.sym("zz", nz), ca.SX.sym("tt"), ca.SX.sym("uu", nu)
        lin = ca.Function("lin", [tt, zz, uu], [_linearisation(d, tt, zz, uu)])

        def rhs(t_: Any, S_: Any, _k: int) -> Any:
            z_, yh_, Phi_ = rows(S_, 0, nz), rows(S_, nz, nz + ny), ca.reshape(rows(S_, nz + ny, ns), n, n)
            u_ = u0 + (t_ - t) * u_slope
            return ca.vertcat(d.flow(t_, z_, u_, yh_ + (t_ - t) * slope), ca.SX.zeros(ny), ca.vec(lin(t_, z_, u_) @ Phi_))

        S_next, _ = rk4_step_rate(rhs, th[0], S, th[1])
        self.sub = ca.Function(f"{d.method}_smooth_substep", [S, a, th], [ca.densify(S_next), ca.SX(0)])
        z_plus = d.update(t + dt, z, u1, y1, m1)
        yhat = h(t + dt, d.output(t + dt, z_plus, u1, yh), u1)
        yh_plus = m1 * y1 + (1 - m1) * yhat
        prior = ca.vertcat(z[:n], ca.vec(d.covariance(z)), ca.vec(Phi))
        self.jump = ca.Function(f"{d.method}_smooth_sample", [S, a],
                                [ca.densify(ca.vertcat(z_plus, yh_plus, ca.vec(ca.DM.eye(n)))), ca.densify(prior)])
        self.runners: dict[str, IntervalRunner] = {}

    def run(self, z0: np.ndarray, yh0: np.ndarray, A: np.ndarray, substeps: np.ndarray, engine: Backend) -> Any:
        r = self.runners.get(engine)
        if r is None:
            r = self.runners[engine] = IntervalRunner(self.sub, self.jump, backend=engine)
        s0 = np.concatenate([z0, yh0, np.eye(self.n).reshape(-1)])
        # exactly the filter's sub-step counts: no rate rule (target and rejection threshold infinite)
        return r.run(s0, A, np.asarray(substeps, dtype=float), rate0=0.0, target=np.inf, reject=np.inf)


class _Backward:
    """The RTS backward recursion, one step per sample, run backwards (compiled loop, or mapaccum on the VM)."""

    def __init__(self, n: int):
        self.n = n
        nn = n * n
        acc, a, c = ca.SX.sym("acc", n + nn), ca.SX.sym("a", 2 * (n + nn) + nn), ca.SX.sym("c", 1)
        xs, Ps = acc[:n], ca.reshape(acc[n:], n, n)
        xf, Pf = a[:n], ca.reshape(a[n:n + nn], n, n)
        o = n + nn
        xp, Pp = a[o:o + n], ca.reshape(a[o + n:o + n + nn], n, n)
        Phi = ca.reshape(a[o + n + nn:], n, n)
        Pf, Pp = (Pf + Pf.T) / 2, (Pp + Pp.T) / 2
        Gt = ca.solve(Pp, Phi @ Pf)  # Gᵀ = P⁻⁻¹ Φ P (P⁻ symmetric)
        G = Gt.T
        xs_new = xf + G @ (xs - xp)
        Ps_new = Pf + G @ (Ps - Pp) @ Gt
        self.step = ca.Function(f"rts_backward_{n}", [acc, a, c],
                                [ca.densify(ca.vertcat(xs_new, ca.vec((Ps_new + Ps_new.T) / 2)))])
        self.loop = Loop(self.step)

    def run(self, last: np.ndarray, data: np.ndarray, engine: Backend) -> np.ndarray:
        """`data` rows in backward order (k = N-2, ..., 0); returns the smoothed [x, vec P] rows in that order."""
        return self.loop(last, data, np.zeros(1), engine)


_CACHE: dict[tuple[int, str], tuple[ObserverDesign, _Replay]] = {}  # (id of design, hold)
_BACK: dict[int, _Backward] = {}


def forget(design: ObserverDesign) -> None:
    """Drop the compiled replays kept for `design`, and its prepared observers (a caller that smooths with a design it
    will not use again: each holds its CasADi functions, about 100 MB for a 17-state EKF)."""
    from ..observer._compiled import forget as forget_observer

    for key in [k for k, (d, _) in _CACHE.items() if d is design]:
        del _CACHE[key]
    forget_observer(design)


def rts_smooth(design: ObserverDesign, traj: Any, u: np.ndarray, y: np.ndarray, mask: np.ndarray, *,
               hold: str = "zoh", engine: Backend = "auto") -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Smoothed estimates (N, n) and covariances (N, n, n) of a filter run `traj` (an ObserverTrajectory) on the
    samples u, y (zero where missing), mask. The third result says how closely the replayed filter reproduced
    the run: its largest internal-state difference (rounding only)."""
    from ..observer._compiled import interval_table

    n, N = design.system.n_states, traj.t.size
    key = (id(design), hold)
    hit = _CACHE.get(key)
    if hit is None or hit[0] is not design:  # the cache keeps the design alive, so its id is not reused
        rep = _Replay(design, hold)
        _CACHE[key] = (design, rep)
        if len(_CACHE) > 64:
            _CACHE.pop(next(iter(_CACHE)))
    else:
        rep = hit[1]
    nn = n * n
    Pf = traj.z[:, n:n + nn]
    Pf = ((Pf.reshape(N, n, n) + Pf.reshape(N, n, n).transpose(0, 2, 1)) / 2).reshape(N, nn)
    if N == 1:
        return traj.xhat.copy(), Pf.reshape(1, n, n).transpose(0, 2, 1).copy(), {"replay_difference": 0.0}
    A = interval_table(traj.t, u, y, mask)
    res = rep.run(traj.z[0], traj.y_used[0], A, traj.substeps, engine)
    replay = float(np.max(np.abs(res.states[:, :design.n_z] - traj.z[1:]))) if N > 1 else 0.0
    prior = res.outputs  # rows k = 0..N-2: (x̂⁻_{k+1}, P⁻_{k+1}, Φ_k)
    data = np.hstack([traj.z[:-1, :n], Pf[:-1], prior])[::-1]
    back = _BACK.get(n)
    if back is None:
        back = _BACK[n] = _Backward(n)
    last = np.concatenate([traj.z[-1, :n], Pf[-1]])
    sm = back.run(last, data, engine)[::-1]
    out = np.vstack([sm, last])
    xs = out[:, :n].copy()
    Ps = out[:, n:].reshape(N, n, n).transpose(0, 2, 1).copy()  # column-major blocks
    _check_backward(design, traj, xs, Ps, Pf.reshape(N, n, n))
    return xs, Ps, {"replay_difference": replay}


def _check_backward(design: ObserverDesign, traj: Any, xs: np.ndarray, Ps: np.ndarray, Pf: np.ndarray) -> None:
    """Refuse a backward pass that diverged: a non-finite smoothed row, or a smoothed variance above the filtered one
    by more than INFLATION (the smoothed covariance never exceeds the filtered one; rounding aside, a larger one means
    the recursion amplified its rounding errors, as G_k = P_k Φᵀ (Φ P_k Φᵀ + Q)⁻¹ = Φ⁻¹ does with Q = 0 on a
    contracting flow)."""
    names = design.system.states
    vs, vf = np.einsum("kii->ki", Ps), np.einsum("kii->ki", Pf)
    slack = 1e-9 * np.max(np.abs(vf), axis=0)
    finite = np.isfinite(xs).all(axis=1) & np.isfinite(vs).all(axis=1)
    bad = ~finite | (vs > INFLATION * np.abs(vf) + slack).any(axis=1)
    if not bad.any():
        return
    k = int(np.flatnonzero(bad)[-1])  # the backward pass goes from the end: its first bad row is the last one
    if not finite[k]:
        c = int(np.flatnonzero(~(np.isfinite(xs[k]) & np.isfinite(vs[k])))[0])
        what = f"its estimate or variance of {names[c]} is not finite"
    else:
        c = int(np.argmax(vs[k] / np.maximum(np.abs(vf[k]) + slack, 1e-300)))
        what = (f"its variance of {names[c]} is {vs[k, c]:.3g}, above the filter's {vf[k, c]:.3g} (a smoothed "
                "variance never exceeds the filtered one)")
    raise FiniteEscapeError("smoother", float(traj.t[k]), xs[k], names, np.inf,
                            message=f"the smoother diverged going backwards: at t = {traj.t[k]:.6g} (row {k}) {what}. "
                                    "With little or no process noise Q the backward gain inverts the model's flow and "
                                    "amplifies rounding; give the filter a small Q (e.g. 1e-10 × the squared scale of "
                                    "each state per unit time)")
