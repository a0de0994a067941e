"""Particle filter, continuous-discrete or on a map: bootstrap (Gordon, Salmond & Smith (1993)) and auxiliary (Pitt &
Shephard (1999)).

The design checks the options and builds the two model functions the particle loop calls (one RK4 step of the
model, or one step of a map, and the output map); :mod:`nlobs.observer._particles` runs them in a compiled C loop.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import casadi as ca
import numpy as np

from ...engine import compile_system, rk4_step
from ...errors import PreconditionError
from ...model import System
from ...references import cite, work
from .._base import Certificate, Check, check_vector
from .._common import require_system
from .._kind import Tuning, kind
from ._sqrt import covariance_inputs, sqrt_psd
from .._tune import square

__all__ = ["ParticleDesign", "design_pf"]

REF = (f"Bootstrap particle filter ({cite('gordon1993')}); auxiliary particle filter ({cite('pitt1999')}); "
       f"systematic resampling ({cite('kitagawa1996')}); effective sample size ({cite('kong1994')})")

Scheme = Literal["bootstrap", "auxiliary"]


@dataclass(frozen=True, eq=False)
class ParticleDesign:
    """A designed particle filter: its options, model functions and certificate.

    It is not an ODE observer (its state is a random cloud of particles), so it has no ``flow``; it runs
    on sampled measurements only, through :func:`nlobs.observer.compiled_observer` (or
    :func:`nlobs.simulate`, which runs it on the recorded samples after the plant).

    Attributes
    ----------
    method : str
        ``"pf"``.
    system : System
    xhat0 : numpy.ndarray
        Mean of the initial particles.
    P0, Q, R : numpy.ndarray
        Initial covariance, process-noise intensity (on a map: covariance per step), measurement covariance.
    particles : int
    scheme : {"bootstrap", "auxiliary"}
        Bootstrap (propagate, weight, resample below the threshold) or auxiliary (first-stage weights
        on the noise-free moves, resampling at every sample).
    threshold : float
        Resample when ESS < threshold · particles (bootstrap); the auxiliary filter resamples at every sample.
    seed : int
        Seed of the filter's random numbers: the same seed gives the same estimates.
    max_step : float or None
        Largest RK4 step between samples (None: one step per interval).
    engine : {"c", "jax"}
        Where :func:`nlobs.observer.particle_runner` runs it.
    z_names : tuple of str
        The columns of the filter's trace: x̂, P (column-major), ESS, resampled (0/1), log-likelihood.
    covariance : casadi.Function
        ``(z) -> P`` from a row of the trace.
    prop : casadi.Function
        ``(x, t, h, u) -> x(t + h)``, one RK4 step of the model; on a map ``f(t, x, u)``, the next state (h unused).
    meas : casadi.Function
        ``(x, t, u) -> y``.
    certificate : Certificate
    """

    method: str
    system: System
    xhat0: np.ndarray
    P0: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    particles: int
    scheme: str
    threshold: float
    seed: int
    max_step: float | None
    prop: ca.Function
    meas: ca.Function
    certificate: Certificate
    z_names: tuple[str, ...] = field(default=())
    covariance: ca.Function | None = None
    engine: str = "c"

    sampled: ClassVar[bool] = True
    needs_mx: ClassVar[bool] = False

    @property
    def n_z(self) -> int:
        return len(self.z_names)

    def __str__(self) -> str:
        return f"pf observer for {self.system.name!r} ({self.scheme}, {self.particles} particles)\n" + str(self.certificate)


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def output_symmetries(system: Any, *, samples: int = 4, seed: int = 0) -> list[tuple[str, ...]]:
    """Sign flips of states that leave every output unchanged at generic points: h(x) = h(σx).

    Each state the outputs depend on is flipped alone, then all of them together; a flip counts when
    h(σx) − h(x) expands to zero (SymPy), or, when that is not decided quickly, when it vanishes at
    `samples` random points (the inputs and t random too) to 1e-9 relative.
    """
    import sympy as sp

    _, h = system.substituted()
    xs = list(system.x)
    used = [i for i, x in enumerate(xs) if any(x in e.free_symbols for e in h)]
    flips = [(i,) for i in used] + ([tuple(used)] if len(used) > 1 else [])
    rng = np.random.default_rng(seed)
    _, h_num = compile_system(system).bind()  # CasADi, at generic points (no evaluation of model strings)
    n, nu = system.n_states, system.n_inputs
    found = []
    for flip in flips:
        sign = np.ones(n)
        sign[list(flip)] = -1
        sub = {xs[i]: -xs[i] for i in flip}
        if all(sp.expand(e.xreplace(sub) - e) == 0 for e in h):
            found.append(tuple(system.states[i] for i in flip))
            continue
        ok = True
        for _ in range(samples):
            x = rng.uniform(0.3, 1.7, n) * rng.choice([-1.0, 1.0], n)
            t, u = float(rng.uniform(0.3, 1.7)), rng.uniform(0.3, 1.7, nu)
            a = np.asarray(h_num(t, x, u), dtype=float).ravel()
            b = np.asarray(h_num(t, sign * x, u), dtype=float).ravel()
            if not (np.all(np.isfinite(a)) and np.allclose(a, b, rtol=1e-9, atol=1e-12)):
                ok = False
                break
        if ok:
            found.append(tuple(system.states[i] for i in flip))
    return found


#: The most particle-state updates (particles × samples × states) `--run` gives a particle filter: about 3 s in C.
PF_WORK_BUDGET = 2e8


def tune_pf(ctx: Any) -> Tuning:
    n = ctx.system.n_states
    particles = int(min(20000, 1000 * max(2, n)))
    sc = ctx.scenario
    work = particles * sc.samples * n if sc is not None else 0   # particle-state updates of the comparison run
    runnable = work <= PF_WORK_BUDGET
    note = "" if runnable else (f"left out of --run: {particles} particles over {sc.samples} samples of a {n}-state model "
                                f"({work:.2g} particle-state updates, budget {PF_WORK_BUDGET:.0e}: tens of seconds); run it "
                                "with `nlobs simulate --observer pf`")
    opts: dict[str, Any] = {"Q": square(ctx.Q), "R": square(ctx.R), "P0": square(4 * np.asarray(ctx.P0)), "particles": particles, "seed": 0}
    sym = output_symmetries(ctx.system)
    if sym:
        flips = "; ".join(("−" + ", −".join(f)) if len(f) > 1 else f"{f[0]} → −{f[0]}" for f in sym)
        why = (f"the output is symmetric in the state: h(x) = h(σx) for the sign flip {flips} at generic points (decided "
               "symbolically, or at random points), so the posterior of x̂ can have two modes that the measurements alone "
               "cannot tell apart; a Gaussian filter (EKF, UKF and their square-root and iterated forms) commits to one mode and "
               "can converge to the mirror state; the particle filter carries both until the dynamics separate them — the "
               "choice here")
        choice = f"output symmetric under {flips}: multimodal posterior, the particle filter (kind 'pf') is the choice"
    else:
        choice = ""
        why = ("no sign symmetry of the output found: a Gaussian filter (EKF/UKF) is cheaper here; the particle filter fits "
               "multimodal or non-Gaussian posteriors")
    return Tuning.tuned(opts, f"{ctx.noise_note}; {particles} particles, systematic resampling when ESS < N/2, P(0) = 4·diag(σ₀²) "
                        f"(a wide cloud), seed 0; {why}", choice=choice, choice_reason=why if choice else "", choice_rank=2,
                        runnable=runnable, extra=note)


@kind('pf', likelihood='ekf', summary='particle filter (continuous-discrete, or on a map): bootstrap or auxiliary, systematic resampling, seeded',
      references=(work("gordon1993"), work("pitt1999", "auxiliary")), time_base="both", tune=tune_pf)
def design_pf(system: System, *, Q: Any, R: Any, P0: Any = None, xhat0: Any = None, particles: int = 1000,
              scheme: Scheme = "bootstrap", threshold: float = 0.5, seed: int = 0,
              max_step: float | None = None, engine: str = "c") -> ParticleDesign:
    r"""Particle filter (continuous-discrete, or on a map): bootstrap or auxiliary, systematic resampling, seeded.

    The particles start from :math:`\mathcal N(\hat x_0, P_0)`. Between samples each particle follows
    the model in RK4 steps of length h (one per interval, or enough that h ≤ `max_step`), with
    :math:`\sqrt h\,Q^{1/2}\xi`, ξ ~ N(0, I), added after each step (process noise of intensity Q).
    On a discrete-time model (a map x[k+1] = f(x[k], u[k], t[k]) + w[k]) each particle steps once per sample,
    :math:`x_i \leftarrow f(x_i, u_{k-1}, t_{k-1}) + Q^{1/2}\xi` with Q the covariance of w per step, as the
    bootstrap filters of filterpy, LowLevelParticleFilters.jl and ``particles`` are written; the first sample
    weights the initial particles (the prior of x[0]), as the map EKF and UKF start.
    At a sample the weights are multiplied by the Gaussian likelihood
    :math:`\mathcal N(y; h(x_i), R)` of the measured outputs and normalised; the estimate is the weighted mean
    (and covariance), and the effective sample size :math:`\mathrm{ESS} = 1/\sum_i w_i^2` (Kong, Liu & Wong
    (1994)) is reported for every sample.

    - ``scheme="bootstrap"`` (Gordon, Salmond & Smith (1993)): propagate with the model, weight by the
      likelihood, resample (systematic, Kitagawa (1996)) when ESS < `threshold` · `particles`.
    - ``scheme="auxiliary"`` (Pitt & Shephard (1999)): first-stage weights :math:`w_i\,p(y\mid\mu_i)` with
      :math:`\mu_i` the particle moved without noise; ancestors drawn by systematic resampling with them;
      the chosen particles moved with noise and weighted by :math:`p(y\mid x_i)/p(y\mid\mu_{a_i})`. It
      resamples at every sample; `threshold` is not used.

    The run is a compiled C loop (model functions generated by CasADi, the filter in C with a xoshiro256**
    generator seeded by `seed`): the same seed gives the same estimates, bit for bit. The log-likelihood
    estimate of each sample, :math:`\log\hat p(y_k\mid y_{1:k-1})`, is reported as well.

    Parameters
    ----------
    system : System
    Q : array_like of shape (n, n)
        Process-noise intensity, positive semidefinite (on a map: the covariance of w[k] per step).
    R : array_like of shape (p, p)
        Covariance of one measurement sample, positive definite (Gaussian likelihood).
    P0 : array_like of shape (n, n), optional
        Covariance of the initial particles (identity), positive definite.
    particles : int
        Number of particles (≥ 2).
    scheme : {"bootstrap", "auxiliary"}
    threshold : float
        Resampling threshold on ESS / particles, in [0, 1] (0: never, 1: every sample).
    seed : int
        Seed of the random numbers (a non-negative integer).
    max_step : float, optional
        Largest RK4 step between samples (continuous-time models only: a map steps once per sample).
    engine : {"c", "jax"}
        Where the filter runs: the compiled C loop, or (the optional ``nlobs[jax]`` extra) the same loop as one
        XLA program, on a GPU when JAX has one: for 10⁵–10⁶ particles. The bootstrap scheme only; its random
        numbers come from JAX's generator, so the two engines' runs differ by their draws (given the same draws
        they agree to rounding).

    Other Parameters
    ----------------
    xhat0 : array_like of shape (n,), optional

    Raises
    ------
    PreconditionError, ShapeError
        For matrices of the wrong shape or definiteness, or options out of range.
    """
    require_system(system, "design_pf")
    caller = "design_pf"
    n, p = system.n_states, system.n_outputs
    Qm, Rm, P0m, checks = covariance_inputs(Q, R, P0, n, p, caller)
    if isinstance(particles, bool) or not isinstance(particles, (int, np.integer)) or particles < 2:
        raise PreconditionError(f"{caller}: `particles` must be an integer ≥ 2, got {particles!r}")
    if scheme not in ("bootstrap", "auxiliary"):
        raise PreconditionError(f"{caller}: `scheme` must be 'bootstrap' or 'auxiliary', got {scheme!r}")
    if not (isinstance(threshold, (int, float)) and 0 <= threshold <= 1):
        raise PreconditionError(f"{caller}: `threshold` (of ESS / particles) must be in [0, 1], got {threshold!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**63:
        raise PreconditionError(f"{caller}: `seed` must be a non-negative integer, got {seed!r}")
    if engine not in ("c", "jax"):
        raise PreconditionError(f"{caller}: `engine` must be 'c' or 'jax', got {engine!r}")
    if engine == "jax" and scheme != "bootstrap":
        raise PreconditionError(f"{caller}: engine='jax' runs the bootstrap scheme only; use engine='c' for the {scheme} filter")
    if max_step is not None and system.is_discrete:
        raise PreconditionError(f"{caller}: `max_step` does not apply to a discrete-time model ({system.name!r} steps once "
                                f"per sample, sample_time = {system.sample_time:g} s): leave it out")
    if max_step is not None and not (np.isfinite(max_step) and max_step > 0):
        raise PreconditionError(f"{caller}: `max_step` must be a positive number, got {max_step!r}")
    x0v = check_vector(np.zeros(n) if xhat0 is None else xhat0, n, "xhat0", caller)
    f, h = compile_system(system).bind()
    x, t, hh, u = ca.SX.sym("x", n), ca.SX.sym("t"), ca.SX.sym("h"), ca.SX.sym("u", system.n_inputs)
    step = f(t, x, u) if system.is_discrete else rk4_step(lambda tt, xx, _k: f(tt, xx, u), t, x, hh)
    prop = ca.Function("pf_prop", [x, t, hh, u], [step])
    meas = ca.Function("pf_meas", [x, t, u], [h(t, x, u)])
    checks.append(Check("particles and resampling", True,
                        f"{int(particles)} particles, {scheme}, systematic resampling"
                        + (f" when ESS < {threshold:g}·N" if scheme == "bootstrap" else " at every sample")))
    noise = "Gaussian with covariance Q per step" if system.is_discrete else "white with intensity Q"
    checks.append(Check.assumed(f"the measurement noise is Gaussian with covariance R and the process noise {noise}",
                                "the likelihood and the particles' noise are built on it"))
    values: dict[str, Any] = {"Q": Qm, "R": Rm, "P0": P0m, "particles": int(particles), "scheme": scheme,
                              "threshold": float(threshold), "seed": int(seed),
                              "max_step": ("one step of the map per sample" if system.is_discrete else "one RK4 step per interval"
                                           if max_step is None else float(max_step)),
                              "random numbers": "xoshiro256** seeded by splitmix64; normals by the ziggurat of Marsaglia & Tsang (2000)"}
    time = f"discrete time, sample_time = {system.sample_time:g} s" if system.is_discrete else "continuous-discrete"
    cert = Certificate(f"Particle filter ({scheme}, {time})", REF, tuple(checks), values)
    names = ([f"xhat_{v}" for v in system.states] + [f"P_{i}_{j}" for j in range(n) for i in range(n)]
             + ["ess", "resampled", "loglik"])
    zs = ca.SX.sym("z", len(names))
    cov = ca.Function("pf_covariance", [zs], [ca.reshape(zs[n:n + n * n], n, n)], ["z"], ["P"])
    return ParticleDesign("pf", system, x0v, P0m, Qm, Rm, int(particles), scheme, float(threshold), int(seed),
                          None if max_step is None else float(max_step), prop, meas, cert, tuple(names), cov, engine)


def square_roots(d: ParticleDesign) -> tuple[np.ndarray, np.ndarray]:
    """L0, Lq with L0 L0ᵀ = P0 and Lq Lqᵀ = Q."""
    return np.linalg.cholesky(d.P0), sqrt_psd(d.Q)
