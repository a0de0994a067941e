r"""What every candidate observer is tuned from: the model, the run it will be compared on, the
observability verdict, the time scales, the region the state visits and the declared noise.

Automatic tuning rules (each one reported with the candidate that uses it):

* **Time scale.** :math:`\omega_p` is the largest spectral radius of :math:`\partial f/\partial x`
  along the nominal (noise-free) run of the file's ``[simulation]``, at least :math:`0.2\|\partial f/
  \partial x\|_2` (a nilpotent coupling still has a time scale) and :math:`3/t_{final}`. Observer
  error dynamics are placed at :math:`\omega_o = 3\omega_p`, capped so that the explicit RK4 step and
  the sample-and-hold of the measurements stay well inside their stability limits
  (:math:`\omega_o\,dt \le 0.5`, :math:`\omega_o T_s \le 0.5`).
* **Region.** The box the nominal run visits (states, inputs, outputs), widened by 10 % of each range.
* **Noise.** A Gaussian output noise of standard deviation σ gives the sample covariance
  :math:`R = \sigma^2` (continuous-discrete filters) and the intensity :math:`R\,T_s` (continuous-time
  filters); a uniform bound b gives :math:`\sigma^2 = b^2/3`. Without declared noise, σ is 0.1 % of the
  output's range (said so in the tuning). Declared process noise σ_w gives :math:`Q = \sigma_w^2`;
  otherwise :math:`Q = (0.01\,s_i)^2\omega_p` per state (s_i its scale, below), a small model-error allowance.
* **Initial estimate.** x̂(0) is x(0) moved by half of each state's scale s_i (its range on the run; half its
  largest magnitude for a state that moves less than 5 % of it; no more than max(|x_i(0)|, s_i/10) for a state that
  travels far from where it starts), with alternating signs (a state that keeps its
  sign on the run keeps it: ×1.5 or ×0.5 where the move would flip it); unknown parameters start at the file's
  value (the initial guess). P(0) = diag(max(s_i, |x̂_i(0) − x_i(0)|)²).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from ..analysis import ObservabilityReport, analyze, matrix_measure, pbh_test
from ..errors import FiniteEscapeError, FormError, ModelError
from ..model import LTI, ModelFile, System
from ..simulate import Noise, ProcessNoise, Recording, Run, Sampling, simulate
from ._forms import recognise

__all__ = ["Scenario", "Context", "build_context", "file_unknown_params", "file_true_parameters"]


# -- the contracts of the "model" engineer (unknown parameters in model files), in one place ------------------
def file_unknown_params(mf: ModelFile) -> tuple[str, ...]:
    """The parameters a model file declares unknown (``k = { value = 0.3, unknown = true }``)."""
    return tuple(getattr(mf, "unknown_params", ()) or ())


def file_true_parameters(cfg: Any) -> dict[str, float]:
    """``[simulation] true_parameters``: the values a simulation uses for the unknown parameters."""
    return {str(k): float(v) for k, v in dict(getattr(cfg, "true_parameters", None) or {}).items()}


@dataclass(frozen=True)
class Scenario:
    """The run candidates are compared on: the file's ``[simulation]``, or a recording."""

    t_final: float
    dt: float
    x0: np.ndarray | None
    inputs: Mapping[str, Any]
    noise: Noise | None
    noise_std: np.ndarray | None          # per output, the declared σ (uniform b -> b/√3); None: no noise declared
    process_std: np.ndarray | None
    sample_period: float | None           # the fastest clock (per-output periods: the shortest)
    seed: int | None
    periods: Mapping[str, float] | None = None   # one period per output (multi-rate sensors), or None
    delay: Mapping[str, float] | None = None     # known measurement delays by output, or None

    @property
    def sampling(self) -> Sampling | None:
        if self.periods:
            return Sampling(dict(self.periods))
        return Sampling(self.sample_period) if self.sample_period else None

    @property
    def process_noise(self) -> ProcessNoise | None:
        return ProcessNoise(self.process_std) if self.process_std is not None else None

    @property
    def samples(self) -> int:
        """Measurement updates over the run (the step count when measurements are continuous)."""
        return int(round(self.t_final / (self.sample_period or self.dt)))

    def describe(self) -> str:
        bits = [f"t in [0, {self.t_final:g}], dt = {self.dt:g}"]
        if self.sample_period:
            bits.append(f"measurements every {self.sample_period:g}")
        if self.noise_std is not None:
            bits.append("noise σ = " + ", ".join(f"{v:.3g}" for v in self.noise_std))
        return ", ".join(bits)


@dataclass(eq=False)
class Context:
    """Everything the per-kind trials share (built once by :func:`build_context`)."""

    model: System                       # the model as written (parameters at their file values)
    system: System                      # what the observers estimate: the model with unknown parameters as states
    unknown: tuple[str, ...]
    truth: dict[str, float]             # values the simulation uses for the unknown parameters
    scenario: Scenario | None
    nominal: Run | None                 # the plant alone over the scenario, noise-free (None without x0)
    report: ObservabilityReport
    report_signal: ObservabilityReport | None
    omega_p: float
    omega_o: float
    scale: np.ndarray
    region: dict[str, tuple[float, float]]
    xhat0: np.ndarray
    R: np.ndarray                       # sample covariance
    R_rate: np.ndarray                  # intensity (continuous-time filters)
    Q: np.ndarray
    P0: np.ndarray
    noise_note: str
    blockers: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    detectability: dict[str, Any] = field(default_factory=dict)
    uco: Any = None
    forms: Any = None                   # FormsReport of the system (computed once; the trials reuse its verdicts)
    recording: Recording | None = None  # recorded data to compare on (the tuning still comes from [simulation])
    run_blockers: list[str] = field(default_factory=list)   # why the comparison run cannot show what it should
    configs: dict[str, tuple[str, Mapping[str, Any]]] = field(default_factory=dict)  # kind -> the file's [observers.NAME]
    choice: tuple[str, str] | None = None  # (kind, why) when a rule marks one kind as the choice (e.g. pf for a symmetric output)
    choice_rank: int = 0                   # the weight of that rule (Tuning.choice_rank): a stronger rule replaces a weaker one

    @property
    def n(self) -> int:
        return self.system.n_states

    @property
    def p(self) -> int:
        return self.system.n_outputs

    def step_limit(self) -> float:
        """The largest rate an observer may have on this run: ω·dt ≤ 0.5 and ω·Ts ≤ 0.5."""
        if self.scenario is None:
            return np.inf
        lim = 0.5 / self.scenario.dt
        if self.scenario.sample_period:
            lim = min(lim, 0.5 / self.scenario.sample_period)
        return lim

    def riccati_weights(self, W: np.ndarray, M0: np.ndarray, Q: np.ndarray, C: np.ndarray | None = None,
                        CA: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, str]:
        """W and M(0) of a continuous-time Riccati observer that the run can integrate.

        With explicit RK4 on held samples, every rate of the filter must stay below the step limit ω_lim:

        - the steady gain, about √(q/W)‖C‖: W ≥ max(q)‖C‖²/ω_lim²;
        - the gain on the unmeasured states, which reach the output through A: about √(λmax(CA M CAᵀ)/W), so W ≥
          max λmax(CA M0 CAᵀ)/ω_lim² over `CA`, the matrices C A(u, y, t) at points of the run, shape (k, p, n) (in
          the states' own scales: a large coupling to a state whose prior is small does not count as a fast gain);
        - the first correction, λmax(C M0 Cᵀ W⁻¹): met by shrinking M(0) along the measured directions only (the
          first samples fix those anyway), keeping the prior of the unmeasured ones.

        W starts from the noise intensity σ²T_s and is raised only as far as these need.
        """
        lim = self.step_limit()
        W2 = np.array(W, dtype=float)
        M = np.array(M0, dtype=float)
        if not np.isfinite(lim):
            return W2, M, ""
        notes = []
        c2 = self.output_gain ** 2
        cam = 0.0
        if CA is not None and len(CA):
            cam = float(np.max(np.linalg.eigvalsh(np.einsum("kpi,ij,kqj->kpq", CA, M, CA))))
        floor = max(float(np.max(np.diag(Q))) * c2, cam) / lim ** 2
        if np.any(np.diag(W2) < floor):
            W2[np.diag_indices_from(W2)] = np.maximum(np.diag(W2), floor)
            notes.append(f"W raised from σ²T_s to {floor:.3g} so that the filter's gains stay below the step limit "
                         f"{lim:.3g} s⁻¹ (a continuous-time filter cannot be faster than the samples)")
        if C is not None and C.size:
            rate = float(np.max(np.linalg.eigvals(C @ M @ C.T @ np.linalg.inv(W2)).real))
            if rate > 0.5 * lim:
                _, sv, Vt = np.linalg.svd(C)
                Vm = Vt[: int(np.sum(sv > 1e-12))].T                   # measured directions (row space of C)
                Pm = Vm @ Vm.T
                Pu = np.eye(M.shape[0]) - Pm
                shrink = 0.5 * lim / rate
                M = Pu @ M @ Pu + shrink * (Pm @ M @ Pm)
                M = (M + M.T) / 2 + 1e-9 * float(np.abs(M).max()) * np.eye(M.shape[0])
                notes.append(f"M(0) shrunk ×{shrink:.2g} along the measured direction(s) so that the first correction stays "
                             "below the step limit (the unmeasured prior is kept)")
        return W2, M, "; ".join(notes)

    @property
    def output_gain(self) -> float:
        """max ‖∂h/∂x‖₂ on the run (1 without a run)."""
        from ..design._constructions import jacobians_at

        if self.nominal is None:
            return 1.0
        pts = self.samples(50)
        H = jacobians_at(self.system, pts["t"], pts["x"], pts["u"])[1]
        H = H[np.all(np.isfinite(H), axis=(1, 2))]
        return float(np.max(np.linalg.norm(H, 2, axis=(1, 2)), initial=1e-12)) if H.size else 1.0

    def samples(self, count: int = 200) -> dict[str, np.ndarray]:
        """Points of the nominal run (t, x, u, y), at most `count`, evenly spaced (x includes estimated parameters)."""
        if self.nominal is None:
            return {}
        run = self.nominal
        k = np.unique(np.linspace(0, run.t.size - 1, min(count, run.t.size)).astype(int))
        return {"t": run.t[k], "x": run.x[k], "u": run.u[k], "y": run.y[k]}

    def jacobians(self, count: int = 300) -> np.ndarray:
        """∂f/∂x at (up to) `count` points of the nominal run, shape (k, n, n); empty without a run."""
        if self.nominal is None:
            return np.zeros((0, self.n, self.n))
        return _jacobians(self.system, self.samples(count))

    def box(self, names: Sequence[str]) -> dict[str, tuple[float, float]]:
        return {k: self.region[k] for k in names if k in self.region}

    def form(self, prefix: str) -> tuple[bool, str]:
        """Whether the system is in the form whose name starts with `prefix`, and the reason (from the form recognition)."""
        for c in self.forms.checks:
            if c.form.startswith(prefix):
                return c.holds, c.reason
        raise KeyError(prefix)


def _scenario(mf: ModelFile | None, simulation: Any, system: System) -> Scenario | None:
    cfg = simulation if simulation is not None else (mf.simulation if mf is not None else None)
    if cfg is None or getattr(cfg, "x0", None) is None:
        return None
    t_final = float(cfg.t_final or 10.0)
    dt = float(system.sample_time) if system.is_discrete else float(cfg.dt or 1e-3)   # a map steps by its sample_time
    outs = system.outputs
    std = None
    noise = None
    if cfg.noise or cfg.noise_bound:
        noise = Noise.per_output(dict(cfg.noise), dict(cfg.noise_bound))
        std = np.array([float(cfg.noise.get(k, 0.0)) if k in cfg.noise else float(cfg.noise_bound.get(k, 0.0)) / np.sqrt(3.0)
                        for k in outs])
    pstd = None
    if cfg.process_noise:
        pstd = np.array([float(cfg.process_noise.get(k, 0.0)) for k in system.states])
    periods = dict(cfg.sample_period) if isinstance(cfg.sample_period, Mapping) else None
    fastest = min(periods.values()) if periods else (float(cfg.sample_period) if cfg.sample_period else None)
    return Scenario(t_final, dt, np.asarray(cfg.x0, dtype=float), dict(cfg.inputs), noise, std, pstd, fastest, cfg.seed,
                    periods, dict(getattr(cfg, "delay", None) or {}) or None)


def _jacobians(system: System, s: Mapping[str, np.ndarray]) -> np.ndarray:
    from ..design._constructions import jacobians_at

    return jacobians_at(system, s["t"], s["x"], s["u"])[0]


def _time_scales(system: System, s: Mapping[str, np.ndarray], t_final: float, scale: np.ndarray,
                 where: str = "on the run") -> tuple[float, str]:
    J = _jacobians(system, s)
    J = J[np.all(np.isfinite(J), axis=(1, 2))]
    if not J.size:
        return 3.0 / t_final, "the Jacobian is not finite along the run"
    if system.is_discrete:   # a map: the rate of its fastest mode, |ln|λ||/T_s, λ the eigenvalues of ∂f/∂x
        Ts = system.sample_time
        lam = np.abs(np.linalg.eigvals(J)).ravel()
        rates = np.abs(np.log(np.clip(lam, 1e-3, None))) / Ts
        omega = float(max(np.max(rates, initial=0.0), 3.0 / t_final))
        return omega, (f"ω_p = {omega:.3g} s⁻¹ (fastest |ln|eig ∂f/∂x||/T_s of the map {where}, floor 3/t_final = "
                       f"{3.0 / t_final:.3g})")
    rho = float(np.max(np.abs(np.linalg.eigvals(J)), initial=0.0))
    Js = J * scale[None, None, :] / scale[None, :, None]         # D⁻¹JD, D = diag(scale): in the states' own units
    norm = float(np.max(np.linalg.norm(Js, 2, axis=(1, 2)), initial=0.0))
    omega = max(rho, 0.2 * norm, 3.0 / t_final)
    why = (f"ω_p = {omega:.3g} s⁻¹ (largest |eig ∂f/∂x| {where} {rho:.3g}, ‖D⁻¹ ∂f/∂x D‖₂ up to {norm:.3g} with D the "
           f"states' scales, floor 3/t_final = {3.0 / t_final:.3g})")
    return omega, why


def _unobservable(ctx_model: System, rep: ObservabilityReport, nominal: Run | None, unknown: Sequence[str]) -> tuple[list[str], dict[str, Any]]:
    """The blocking sentences for unobservable states, with their detectability."""
    bad = [s for s in ctx_model.states if s not in rep.observable_states]
    if not bad:
        return [], {}
    info: dict[str, Any] = {"unobservable": bad}
    dirs = "; ".join("[" + ", ".join(f"{v:.3g}" for v in row) + "]" for row in rep.unobservable_directions[:3])
    text = (f"{', '.join(bad)} {'is' if len(bad) == 1 else 'are'} not observable from {', '.join(ctx_model.outputs)} "
            f"(generic rank {rep.rank} < {len(rep.unknowns)}; unobservable direction(s) over ({', '.join(rep.unknowns)}): {dirs})")
    f, _ = ctx_model.substituted()
    xs = {s.name: s for s in ctx_model.x}
    obs = [s for s in ctx_model.states if s not in bad]
    never = [b for b in bad if not any(xs[b] in f[i].free_symbols for i, s in enumerate(ctx_model.states) if s != b)
             and not any(xs[b] in e.free_symbols for e in ctx_model.h)]
    if never:
        text += f": {', '.join(never)} never reaches the output (no other equation and no output uses it)"
    detect = _detectability(ctx_model, bad, obs, nominal)
    info["detectable"] = detect
    text += "; " + detect["text"]
    return [text], info


def _detectability(model: System, bad: Sequence[str], obs: Sequence[str], nominal: Run | None) -> dict[str, Any]:
    """Is the unobservable part stable? LTI: PBH test. Otherwise: the unobservable states must not act on
    the observable ones, and their own Jacobian must be contracting (matrix measure < 0) along the run."""
    try:
        lti = LTI.from_system(model)
    except FormError:
        lti = None
    if lti is not None:
        pbh = pbh_test(lti.A, lti.C)
        ok = bool(pbh.detectable)
        return {"detectable": ok, "text": f"{'detectable' if ok else 'NOT detectable'} ({pbh})"
                + (": a reduced-order observer of the observable part converges; the unobservable modes decay on their own"
                   if ok else "")}
    f, _ = model.substituted()
    xs = {s.name: s for s in model.x}
    B = [xs[b] for b in bad]
    coupled = [s for i, s in enumerate(model.states) if s in obs and set(B) & f[i].free_symbols]
    if coupled:
        return {"detectable": None, "text": f"detectability not decided: {', '.join(coupled)} depend(s) on the unobservable "
                f"state(s) (the unobservable part is not a driven subsystem)"}
    idx = [model.states.index(b) for b in bad]
    G = sp.Matrix([f[i] for i in idx]).jacobian(sp.Matrix(B))
    if all(e == 0 for e in G):
        return {"detectable": False, "text": f"NOT detectable: {', '.join(bad)} {'has' if len(bad) == 1 else 'have'} no dynamics of "
                "its own (∂f/∂x = 0 on it: an initial error never decays). Measure it, eliminate it (e.g. through a "
                "conservation law), or drop it from the model"}
    if nominal is None or nominal.x is None:
        return {"detectable": None, "text": "detectability not checked (no [simulation] run to check the unobservable part's "
                "contraction on)"}
    from ..design._constructions import jacobians_at

    k = np.unique(np.linspace(0, nominal.t.size - 1, 300).astype(int))
    F, _ = jacobians_at(model, nominal.t[k], nominal.x[k, :model.n_states], nominal.u[k])
    Gk = F[:, idx][:, :, idx]                            # ∂f/∂x restricted to the unobservable states
    Gk = Gk[np.all(np.isfinite(Gk), axis=(1, 2))]
    mu = float(np.max(matrix_measure(Gk))) if len(Gk) else np.inf
    if mu < 0:
        return {"detectable": True, "rate": -mu,
                "text": (f"detectable along the run: the unobservable part is driven by the observable one and contracts "
                         f"(matrix measure of ∂f/∂({', '.join(bad)}) ≤ {mu:.3g} on the run). A reduced-order observer converges: "
                         f"estimate {', '.join(obs) or 'the observable states'} and integrate {', '.join(bad)}' open loop from "
                         f"the estimates (its error decays at rate ≥ {-mu:.3g}); with a known φ this is the KKL part of kkl_pebo")}
    return {"detectable": False, "rate": -mu,
            "text": (f"not shown detectable: the matrix measure of ∂f/∂({', '.join(bad)}) reaches {mu:.3g} ≥ 0 on the run, so "
                     "an error in the unobservable part need not decay")}


def _region(system: System, run: Run, names_u: Sequence[str]) -> dict[str, tuple[float, float]]:
    out: dict[str, tuple[float, float]] = {}

    def put(name: str, v: np.ndarray) -> None:
        lo, hi = float(np.min(v)), float(np.max(v))
        pad = 0.1 * (hi - lo) + 1e-3 * max(1.0, abs(lo), abs(hi))
        out[name] = (lo - pad, hi + pad)

    for i, s in enumerate(system.states):
        put(s, run.x[:, i])
    for i, s in enumerate(names_u):
        put(s, run.u[:, i])
    for i, s in enumerate(system.outputs):
        put(s, run.y[:, i])
    return out


def _xhat0(x0: np.ndarray, run: Run | None, scale: np.ndarray, estimated: Sequence[int], guesses: Sequence[float]) -> np.ndarray:
    """x̂(0): x(0) moved by half each state's scale (alternating signs), inside the box the run visits (so inside
    every region a design assumes from that box: a state of charge stays below 1, a concentration positive)."""
    out = np.array(x0, dtype=float)
    sign = 1.0
    for i in range(out.size):
        if i in estimated:
            continue
        keeps = run is not None and (np.all(run.x[:, i] > 0) or np.all(run.x[:, i] < 0))
        # half the state's scale, but no more than its initial size (or a tenth of its range) for a state that grows
        # far from where it starts
        s0 = min(scale[i], max(abs(x0[i]), 0.1 * scale[i]))
        lo, hi = (float(np.min(run.x[:, i])), float(np.max(run.x[:, i]))) if run is not None else (-np.inf, np.inf)
        tries = [x0[i] + 0.5 * s0 * sign, x0[i] - 0.5 * s0 * sign]
        if keeps:  # a state that keeps its sign on the run (a level, a concentration) keeps it
            tries = [v if v * x0[i] > 0 else x0[i] * (1.5 if v > x0[i] else 0.5) for v in tries]
        inside = [v for v in tries if lo <= v <= hi]
        out[i] = inside[0] if inside else float(np.clip(tries[0], lo, hi))
        sign = -sign
    for i, g in zip(estimated, guesses):
        out[i] = g
    return out


def build_context(model: System, *, model_file: ModelFile | None = None, unknown_params: Sequence[str] = (),
                  simulation: Any = None, recording: Recording | None = None, true_parameters: Mapping[str, float] | None = None,
                  xhat0: Sequence[float] | None = None, seed: int = 0) -> Context:
    """Analyse `model` and the run it will be compared on; see the module docstring for the rules."""
    unknown = tuple(unknown_params)
    bad = [k for k in unknown if k not in model.params]
    if bad:
        raise ModelError(f"advise: unknown parameter {bad[0]!r} is not a parameter of {model.name!r}; its parameters are: "
                         f"{', '.join(model.param_names) or '(none)'}")
    truth = {k: float(model.params[k]) for k in unknown}
    truth.update({k: float(v) for k, v in (true_parameters or {}).items() if k in unknown})
    system = model.augmented(list(unknown)) if unknown else model
    scen = _scenario(model_file, simulation, model)
    notes: list[str] = []
    nominal = None
    if scen is not None:
        if scen.x0.size != model.n_states:
            raise ModelError(f"advise: [simulation] x0 has {scen.x0.size} entries but {model.name!r} has {model.n_states} "
                             f"states ({', '.join(model.states)})")
        x0_plant = np.concatenate([scen.x0, [truth[k] for k in unknown]])
        scen = Scenario(scen.t_final, scen.dt, x0_plant, scen.inputs, scen.noise, scen.noise_std,
                        None if scen.process_std is None else np.concatenate([scen.process_std, np.zeros(len(unknown))]),
                        scen.sample_period, scen.seed, scen.periods, scen.delay)
        try:
            nominal = simulate(system, None, t_final=scen.t_final, dt=scen.dt, x0=scen.x0, inputs=scen.inputs)
        except FiniteEscapeError as e:
            raise ModelError(f"advise: the model's own simulation blows up ({e}); fix [simulation] (x0, inputs, t_final) first") from e
    elif scen is None:
        notes.append("no [simulation] x0: the tuning uses the Jacobian at x = 0, u = 0, region-based kinds cannot be tuned, "
                     "and --run has nothing to run on; add [simulation] x0 = [...] (and t_final, inputs, noise)")
    rep = analyze(model, unknown_params=list(unknown), seed=seed)
    rep_sig = None
    if scen is not None and model.inputs:
        try:
            sig = {k: (v if not isinstance(v, (int, float)) else float(v)) for k, v in scen.inputs.items()}
            sig.update({k: 0 for k in model.inputs if k not in sig})
            rep_sig = analyze(model, unknown_params=list(unknown), inputs=sig, symmetries=False, seed=seed)
        except (ModelError, ValueError, TypeError):
            rep_sig = None
    t_final = scen.t_final if scen is not None else 10.0
    if nominal is not None:
        s = {"t": nominal.t, "x": nominal.x, "u": nominal.u}
        k = np.unique(np.linspace(0, nominal.t.size - 1, 200).astype(int))
        span = nominal.x.max(axis=0) - nominal.x.min(axis=0)
        mag = np.abs(nominal.x).max(axis=0)
        # a state's scale: its range on the run; for a state that barely moves (< 5 % of its size), half its size
        scale = np.where(span > 0.05 * mag, span, 0.5 * mag)
        scale = np.maximum(scale, 1e-6)
        for j, k_ in enumerate(unknown):  # a constant parameter: its uncertainty, not its (zero) range
            i = model.n_states + j
            scale[i] = max(0.5 * abs(float(model.params[k_])), abs(truth[k_] - float(model.params[k_])), 1e-3)
        region = _region(system, nominal, model.inputs)
        omega_p, scale_note = _time_scales(system, {key: v[k] for key, v in s.items()}, t_final, scale)
    else:
        pts = {"t": np.zeros(1), "x": np.zeros((1, system.n_states)), "u": np.zeros((1, system.n_inputs))}
        scale = np.ones(system.n_states)
        omega_p, scale_note = _time_scales(system, pts, t_final, scale, "at x = 0, u = 0")
        region = {}
    sc = scen
    limit = np.inf
    if sc is not None:
        limit = 0.5 / sc.dt
        if sc.sample_period:
            limit = min(limit, 0.5 / sc.sample_period)
    omega_o = float(min(3.0 * omega_p, limit))
    notes.append(f"time scale: {scale_note}; observer rate ω_o = {omega_o:.3g} s⁻¹ (3 ω_p"
                 + (f", capped at {limit:.3g} by the step/sample period" if 3.0 * omega_p > limit else "") + ")")
    # noise -> R, Q
    p = system.n_outputs
    if sc is not None and sc.noise_std is not None and np.all(sc.noise_std > 0):
        sig = sc.noise_std
        noise_note = "R = σ² from the declared output noise"
    else:
        yspan = (nominal.y.max(axis=0) - nominal.y.min(axis=0)) if nominal is not None else np.ones(p)
        sig = np.maximum(1e-3 * yspan, 1e-6)
        if sc is not None and sc.noise_std is not None:
            sig = np.where(sc.noise_std > 0, sc.noise_std, sig)
        noise_note = ("no (or zero) output noise declared: R from σ = 0.1 % of each output's range on the run" if nominal is not None
                      else "no output noise declared and no run: R from σ = 1e-3")
    period = (sc.sample_period or sc.dt) if sc is not None else 1e-2
    R = np.diag(sig ** 2)
    R_rate = R * period
    per_step = system.is_discrete   # a map's Q is the covariance of the noise of one step, not an intensity
    allowance = (0.01 * scale) ** 2 * (1.0 if per_step else omega_p)
    if sc is not None and sc.process_std is not None and np.any(sc.process_std > 0):
        q = np.where(sc.process_std > 0, sc.process_std ** 2, allowance)
        noise_note += "; Q = σ_w² from the declared process noise"
    else:
        q = allowance
        noise_note += ("; Q = (0.01·range)² per step and state (no process noise declared)" if per_step else
                       "; Q = (0.01·range)²·ω_p per state (no process noise declared)")
    Q = np.diag(q)
    if xhat0 is not None:
        xh0 = np.asarray(xhat0, dtype=float).reshape(-1)
        if xh0.size != system.n_states:
            raise ModelError(f"advise: `xhat0` must have {system.n_states} entries ({', '.join(system.states)}), got {xh0.size}")
    elif sc is not None and sc.x0 is not None:
        est = list(range(model.n_states, system.n_states))
        xh0 = _xhat0(sc.x0, nominal, scale, est, [float(model.params[k]) for k in unknown])
    else:
        xh0 = np.array([0.0] * model.n_states + [float(model.params[k]) for k in unknown])
    # P(0): the initial uncertainty, i.e. the offset of x̂(0) from x(0) chosen above, at least a tenth of the state's
    # range on the run; never the whole range squared (1e4 m² on a position that covers 100 m puts sigma points and
    # EKF corrections far outside anything the model has seen)
    offset = np.abs(xh0 - sc.x0) if sc is not None and sc.x0 is not None else scale
    P0 = np.diag(np.maximum(np.minimum(offset, scale), 0.1 * scale) ** 2)
    ctx = Context(model, system, unknown, truth, sc, nominal, rep, rep_sig, omega_p, omega_o, scale, region, xh0, R, R_rate, Q,
                  P0, noise_note, notes=notes, recording=recording)
    blockers, info = _unobservable(model, rep, nominal, unknown)
    ctx.detectability = info
    ctx.forms = recognise(system)
    badp = [k for k in unknown if k not in rep.identifiable_params]
    if badp:
        blockers.append(f"the unknown parameter(s) {', '.join(badp)} {'is' if len(badp) == 1 else 'are'} not identifiable from "
                        f"{', '.join(model.outputs)} (generic rank {rep.rank} < {len(rep.unknowns)}): no observer can estimate "
                        f"{'it' if len(badp) == 1 else 'them'}; fix {'its' if len(badp) == 1 else 'their'} value(s) in the file or "
                        "estimate an identifiable combination (`nlobs analyze --params` shows the directions)")
    ctx.blockers = blockers
    if not badp and unknown and rep_sig is not None and recording is None:
        # identifiable for generic inputs, but the [simulation] inputs may not excite a parameter (k·u with u = 0): the
        # run would only show a parameter that never moves, so it is refused before anything is estimated
        badsig = [k for k in unknown if k not in rep_sig.identifiable_params]
        if badsig:
            one = len(badsig) == 1
            ctx.run_blockers.append(
                f"with the [simulation] inputs ({rep_sig.inputs}) the unknown parameter{'' if one else 's'} "
                f"{', '.join(badsig)} {'is' if one else 'are'} not identifiable (rank {rep_sig.rank} < {len(rep_sig.unknowns)}; "
                f"generic inputs would identify {'it' if one else 'them'}): a run would not show the estimation converge. "
                "Choose a richer [simulation] input (inputs = {...})")
    if rep_sig is not None and rep.observable and not rep_sig.observable:
        lost = [s for s in rep.unknowns if s not in rep_sig.extra.get("observable_unknowns", rep_sig.observable_states)]
        ctx.notes.append(f"with the simulation's input ({rep_sig.inputs}) {', '.join(lost)} {'is' if len(lost) == 1 else 'are'} "
                         "not observable (a singular input): the comparison run cannot show convergence in "
                         f"{'it' if len(lost) == 1 else 'them'}; choose a richer [simulation] input")
    if rep.symmetries and rep.observable:
        ctx.notes.append("only locally observable: the output is invariant under "
                         + "; ".join(str(s) for s in rep.symmetries) + "; estimates can converge to the mirror image")
    return ctx

