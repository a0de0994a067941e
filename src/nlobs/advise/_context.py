r"""What every candidate observer is tuned from: the model, the run it will be compared on, the
observability verdict, the time scales, the region the state visits and the declared noise.

Automatic tuning rules (each one reported with the candidate that uses it):

* **What the run resolves.** For every state and unknown parameter, δ_i is the smallest offset of x_i(0) that the run
  resolves when all initial values are unknown together: :math:`\delta_i = \sqrt{(M^{-1})_{ii}}`,
  :math:`M = \mathrm{mean}_t\, S(t)^\top C(t)^\top \Sigma^{-1} C(t) S(t)` the information per sample of the model
  linearised along the nominal run (S = ∂x(t)/∂x(0), C = ∂h/∂x, Σ the output noise; :func:`_resolvable`). Alone, a state
  would resolve to :math:`1/\sqrt{M_{ii}}` (its effect on the outputs one noise σ in RMS over the run); together, a
  tilt and an accelerometer bias that the outputs nearly confuse each resolve far less well (at most
  :data:`JOINT_CAP` times worse; ∞ when the outputs do not depend on the state). δ_i is √N times the Cramér–Rao bound
  from N samples: a filter ends well below it, but a prior, a range or a random walk below it is invisible to the
  sensors. It is the floor of every size below: a state that does not move on the run (a height on a flat road, a
  vertical speed, a bias, a constant) has a range of zero, or of the rounding of the integration, and that range says
  nothing about what a filter is uncertain about. (Before this floor, a flat road's vertical speed, its range 1e-10,
  made ‖D⁻¹∂f/∂x D‖ — and with it ω_p, Q and P(0) — a million times off.)
* **Time scale.** :math:`\omega_p` is the largest spectral radius of :math:`\partial f/\partial x`
  along the nominal (noise-free) run of the file's ``[simulation]``, at least :math:`0.2\|D^{-1}\partial f/\partial x\,D\|_2`
  with D = diag(s_i) the states' scales below (a nilpotent coupling still has a time scale; in the states' own units,
  each at least δ_i, so a state the run does not move cannot make the plant look fast) and :math:`3/t_{final}`.
  Observer error dynamics are placed at :math:`\omega_o = 3\omega_p`, capped so that the explicit RK4 step and
  the sample-and-hold of the measurements stay well inside their stability limits
  (:math:`\omega_o\,dt \le 0.5`, :math:`\omega_o T_s \le 0.5`).
* **Region.** The box the nominal run visits (states, inputs, outputs), widened by 10 % of each range (not by δ_i: the
  region is where designs bound their model's terms, and a square root's domain ends where it ends).
* **Local scale.** A state's scale s_i is its range on the run (half its size when it moves by less than 5 % of it), at
  least δ_i; its local scale ℓ_i is that range, at most the distance its fastest rate on the run covers in 2/ω_p, at
  least δ_i (:math:`\ell_i = \max(\delta_i, \min(s_i, 2\max_t|\dot x_i|/\omega_p))`): for a state oscillating at the
  plant's own rate the two agree; a position that travels a kilometre, or an angle that winds five turns, has a range
  that says nothing of what a filter is uncertain about over one time scale. A state that moves on the run by less than
  δ_i is *quiet* (a height on a flat road): its scale is δ_i, x̂(0) is moved from x(0) by ℓ_i/2 (never clipped into a
  box it hardly leaves), and the sigma points' spread is not sized on its box.
* **Noise.** A Gaussian output noise of standard deviation σ gives the sample covariance
  :math:`R = \sigma^2` (continuous-discrete filters) and the intensity :math:`R\,T_s` (continuous-time
  filters); a uniform bound b gives :math:`\sigma^2 = b^2/3`. Without declared noise, σ is 0.1 % of the
  output's range (said so in the tuning). Declared process noise σ_w (``[simulation] process_noise``, of a state or of
  an unknown parameter: its random walk, in the plant and in the filters) gives :math:`Q = \sigma_w^2`; otherwise
  :math:`Q = (0.01\,\ell_i)^2\omega_p` for a moving state, a small model-error allowance (1 % of the state's local change
  per time scale), and for a constant (a state the run leaves where it starts, an unknown parameter) the random walk
  :math:`Q = (0.1\,\min(\delta_i, \sigma_{0,i}))^2/t_{final}` (× T_s on a map): over the whole run it wanders by a
  tenth of what the run resolves and of its initial uncertainty, so the filter keeps learning it without losing it.
  (The plant's fastest rate says nothing about how a bias drifts: ω_p-scaled, it gave accelerometer biases a Q of 3.)
* **Initial estimate.** x̂(0) is x(0) moved by half of each state's local scale ℓ_i (no more than max(|x_i(0)|,
  s_i/10) for a state that travels far from where it starts), with alternating signs (a state that keeps its sign
  on the run keeps it: ×1.5 or ×0.5 where the move would flip it), inside the box the run visits; unknown parameters
  start at the file's value (the initial guess) when ``[simulation] true_parameters`` gives the plant other values;
  without it the file's value is also the truth, and they start 30 % off it (by σ₀ with ``initial_std``).
  P(0) = diag(σ₀²), σ₀ = max(min(offset, ℓ_i), ℓ_i/10, δ_i): the offset is a one-σ error, and P(0) is never smaller
  than what the model and sensors can resolve (the file's ``initial_std`` is taken as written).
* **States that do not move on the run** (a sensor bias, a constant: ẋ = 0 along it, so the box the run visits is a
  single point and clipping into it would start the estimate *at the true value*): x̂(0) = x(0) ± σ₀ (away from 0
  for a nonzero state, never clipped onto the point) and P(0) = max(σ₀, δ_i)², with σ₀

  (a) the file's ``[simulation] initial_std`` for it (which also sets σ₀, offset and P(0), of any moving state or
      unknown parameter it names; a parameter keeps its guess);
  (b) else, with ``process_noise`` σ_w declared for it, :math:`\sigma_w\sqrt{t_{final}}`: the spread its own random
      walk reaches over the run, the uncertainty the model itself gives it;
  (c) else |x(0)|/2, its magnitude;
  (d) else (x(0) = 0) δ_i, the smallest offset the run resolves. It is well above the error such a run leaves (about
      that value over the square root of the number of samples), so the run shows whether the state converges; 1
      (said so) when the outputs do not depend on the state along the run at all.

  A constant's scale and local scale are max(σ₀, δ_i) (as an unknown parameter's are its uncertainty, at least δ_i).
  When the run cannot settle a constant from its offset, the ranking says so (:func:`nlobs.advise._rank._unsettled`)
  and does not call that candidate best.
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
from ..estimation import Recording
from ..simulate import Noise, ProcessNoise, Run, Sampling, simulate
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
    initial_std: Mapping[str, float] | None = None  # [simulation] initial_std: σ of the initial error by state/parameter

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
        if self.periods:   # each output at its own period, not all at the fastest
            by: dict[float, list[str]] = {}
            for k, v in self.periods.items():
                by.setdefault(float(v), []).append(k)
            bits.append("measurements " + "; ".join(f"{', '.join(ks)} every {v:g}" for v, ks in by.items()))
        elif self.sample_period:
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
    choice_notes: dict[str, str] = field(default_factory=dict)  # kind -> the note in `notes` that names it as the choice
    local_scale: np.ndarray | None = None  # ℓ per state: its range, at most the distance its fastest rate covers in 2/ω_p
    constant: tuple[int, ...] = ()         # the states the nominal run leaves where they start (biases, constants)
    resolvable: np.ndarray | None = None   # δ per state: the smallest offset of x(0) the run resolves (inf: not seen)
    quiet: tuple[int, ...] = ()            # states that move on the run by less than δ (a height on a flat road)
    rate_unit: str = "s⁻¹"                 # a rate in the model's time unit (rate_unit)
    cramer_rao: np.ndarray | None = None   # per state: the Cramér–Rao bound of x(0) from the run's samples (cramer_rao)

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
                         f"{lim:.3g} {self.rate_unit} (a continuous-time filter cannot be faster than the samples)")
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


def _scenario(mf: ModelFile | None, simulation: Any, system: System, unknown: Sequence[str] = ()) -> Scenario | None:
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
        names = [*system.states, *unknown]
        bad = [k for k in cfg.process_noise if k not in names]
        if bad:
            what = ("a parameter this analysis does not estimate (add it to the unknown parameters, --params)"
                    if bad[0] in system.params else "neither a state nor an unknown parameter")
            raise ModelError(f"advise: [simulation] process_noise names {bad[0]!r}, {what} of {system.name!r}; states: "
                             f"{', '.join(system.states)}" + (f"; unknown parameters: {', '.join(unknown)}" if unknown else ""))
        pstd = np.array([float(cfg.process_noise.get(k, 0.0)) for k in names])
    periods = dict(cfg.sample_period) if isinstance(cfg.sample_period, Mapping) else None
    fastest = min(periods.values()) if periods else (float(cfg.sample_period) if cfg.sample_period else None)
    if not system.is_discrete and cfg.sample_period:  # at once, before any trial run, with the file and the key
        from ..model._toml import period_multiple_problem

        for key, period in ({f"sample_period.{k}": v for k, v in periods.items()} if periods
                            else {"sample_period": cfg.sample_period}).items():
            why = period_multiple_problem(period, dt)
            if why:
                where = f"{mf.path}, key `simulation.{key}`" if mf is not None else f"[simulation] {key}"
                raise ModelError(f"{where}: {why}" + ("" if cfg.dt else " ([simulation] dt is not set: the default 1e-3)"))
    return Scenario(t_final, dt, np.asarray(cfg.x0, dtype=float), dict(cfg.inputs), noise, std, pstd, fastest, cfg.seed,
                    periods, dict(getattr(cfg, "delay", None) or {}) or None,
                    dict(getattr(cfg, "initial_std", None) or {}) or None)


def _jacobians(system: System, s: Mapping[str, np.ndarray]) -> np.ndarray:
    from ..design._constructions import jacobians_at

    return jacobians_at(system, s["t"], s["x"], s["u"])[0]


def rate_unit(model_file: ModelFile | None) -> str:
    """How a rate is written in the model's time unit (``[units] t``): ``s⁻¹`` by default, ``h⁻¹`` for a model in hours."""
    unit = str((model_file.units if model_file is not None else {}).get("t", "s")).strip() or "s"
    return f"{unit}⁻¹" if unit.isalpha() else f"1/({unit})"


def _time_scales(system: System, s: Mapping[str, np.ndarray], t_final: float, scale: np.ndarray,
                 where: str = "on the run", per: str = "s⁻¹") -> tuple[float, str]:
    J = _jacobians(system, s)
    J = J[np.all(np.isfinite(J), axis=(1, 2))]
    if not J.size:
        return 3.0 / t_final, "the Jacobian is not finite along the run"
    if system.is_discrete:   # a map: the rate of its fastest mode, |ln|λ||/T_s, λ the eigenvalues of ∂f/∂x
        Ts = system.sample_time
        lam = np.abs(np.linalg.eigvals(J)).ravel()
        rates = np.abs(np.log(np.clip(lam, 1e-3, None))) / Ts
        omega = float(max(np.max(rates, initial=0.0), 3.0 / t_final))
        return omega, (f"ω_p = {omega:.3g} {per} (fastest |ln|eig ∂f/∂x||/T_s of the map {where}, floor 3/t_final = "
                       f"{3.0 / t_final:.3g})")
    rho = float(np.max(np.abs(np.linalg.eigvals(J)), initial=0.0))
    Js = J * scale[None, None, :] / scale[None, :, None]         # D⁻¹JD, D = diag(scale): in the states' own units
    norm = float(np.max(np.linalg.norm(Js, 2, axis=(1, 2)), initial=0.0))
    omega = max(rho, 0.2 * norm, 3.0 / t_final)
    why = (f"ω_p = {omega:.3g} {per} (largest |eig ∂f/∂x| {where} {rho:.3g}, ‖D⁻¹ ∂f/∂x D‖₂ up to {norm:.3g} with D the "
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


#: A state whose range on the nominal run is at most this fraction of its size (at least 1) is constant on the run.
STILL = 1e-12


def _still(span: np.ndarray, mag: np.ndarray) -> np.ndarray:
    """Which states the nominal run leaves where they start (a sensor bias, a constant: ẋ = 0 on the run)."""
    return span <= STILL * np.maximum(mag, 1.0)


#: The joint offset the run resolves (:func:`_resolvable` with ``joint=True``) is at most this many times the offset of
#: the state alone: a direction the run barely excites (a symmetry, a nearly singular input) gets a large, finite prior,
#: not the 1e8 of a numerically singular information matrix.
JOINT_CAP = 1e3


def _resolvable(system: System, run: Run, idx: Sequence[int], sig: np.ndarray, count: int = 1001,
                joint: bool = False) -> np.ndarray:
    """See :func:`_resolvable_both`: the offsets of the states alone, or (`joint`) together."""
    return _resolvable_both(system, run, idx, sig, count, joint)[1 if joint else 0]


def _inverse_diagonal(M: np.ndarray, cap: np.ndarray) -> np.ndarray:
    """√diag(M⁻¹) of a symmetric positive semidefinite M (inverted in its correlation form, eigenvalues clipped at 1e-12
    of the largest), at most `cap` each."""
    d = np.sqrt(np.diag(M))
    lam, V = np.linalg.eigh(M / np.outer(d, d))          # the correlation form: well scaled whatever the units
    lam = np.maximum(lam, 1e-12 * max(float(lam.max()), 1e-300))
    inv_diag = np.einsum("ij,j,ij->i", V, 1.0 / lam, V) / d ** 2
    return np.minimum(np.sqrt(np.maximum(inv_diag, 0.0)), cap)


def cramer_rao(system: System, run: Run, sig: np.ndarray, counts: np.ndarray, count: int = 1001) -> np.ndarray:
    r"""The Cramér–Rao bound of each state and unknown parameter's initial value from the run's samples:
    :math:`\sqrt{(F^{-1})_{ii}}`, :math:`F = \sum_k N_k\,\mathrm{mean}_t (\partial y_k/\partial x(0))^	op
    (\partial y_k/\partial x(0))/\sigma_k^2` with N_k the samples of output k over the run (the linearised sensitivities
    of :func:`_resolvable_both`). A constant's error at the end of the run is its initial value's: no unbiased estimator
    ends below this."""
    return _resolvable_both(system, run, list(range(system.n_states)), sig, count, True, counts)[2]


def _resolvable_both(system: System, run: Run, idx: Sequence[int], sig: np.ndarray, count: int = 1001,
                     joint: bool = True, counts: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""For each state in `idx`: the initial offset δ whose effect on the outputs along the run is, in RMS over the run,
    one noise standard deviation:
    :math:`\delta_i = 1/\sqrt{\operatorname{mean}_t \sum_k (\partial y_k(t)/\partial x_i(0))^2/\sigma_k^2}`.

    The sensitivities are those of the model linearised along the nominal run: :math:`\dot S = A(t) S`, S(0) = the unit
    vectors of `idx`, :math:`\partial y/\partial x(0) = C(t)S(t)`, with A = ∂f/∂x and C = ∂h/∂x at (up to) `count` points
    of the run (S stepped by exp of the trapezoidal mean of A over each interval; a map multiplies its Jacobians step by
    step). An offset smaller than δ_i moves the outputs less than their noise: a run cannot show it being estimated.
    inf where the outputs do not depend on the state along the run.

    With `joint`, the offset of each state when all of `idx` are unknown together:
    :math:`\delta_i = \sqrt{(M^{-1})_{ii}}` with :math:`M = \operatorname{mean}_t \sum_k S_k^\top S_k/\sigma_k^2` (the
    information per sample; √N times the Cramér–Rao bound of x(0) from N samples). A tilt and an accelerometer bias that
    the outputs nearly confuse each resolve far less well together than alone. At most :data:`JOINT_CAP` times the
    state's own δ."""
    import scipy.linalg

    from ..design._constructions import jacobians_at

    m = len(idx)
    if m == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    N = run.t.size
    if system.is_discrete:
        k = np.arange(min(N, 5000))
    else:
        k = np.unique(np.linspace(0, N - 1, min(N, count)).astype(int))
    t = run.t[k]
    F, H = jacobians_at(system, t, run.x[k], run.u[k])
    S = np.zeros((system.n_states, m))
    S[list(idx), np.arange(m)] = 1.0
    acc = np.zeros(m)
    gram = np.zeros((m, m))
    fisher = np.zeros((m, m))
    w = None if counts is None else np.asarray(counts, dtype=float)
    used = 0
    with np.errstate(all="ignore"):
        for j in range(k.size):
            Y = H[j] @ S / sig[:, None]
            if not (np.all(np.isfinite(Y)) and np.all(np.isfinite(F[j]))):
                break
            acc += np.sum(Y ** 2, axis=0)
            if joint:
                gram += Y.T @ Y
            if w is not None:
                fisher += (Y * w[:, None]).T @ Y
            used += 1
            if j + 1 < k.size:
                S = F[j] @ S if system.is_discrete else scipy.linalg.expm(0.5 * (F[j] + F[j + 1]) * (t[j + 1] - t[j])) @ S
                if not np.all(np.isfinite(S)) or np.abs(S).max() > 1e150:
                    break
    mean = acc / max(used, 1)
    with np.errstate(divide="ignore"):
        alone = np.where(mean > 0, 1.0 / np.sqrt(mean), np.inf)
    seen = np.flatnonzero(mean > 0)
    crlb = np.full(m, np.inf)
    if w is not None and seen.size:
        crlb[seen] = _inverse_diagonal(fisher[np.ix_(seen, seen)] / max(used, 1), np.inf)
    if not joint or seen.size < 2:
        return alone, alone, crlb
    out = alone.copy()
    out[seen] = _inverse_diagonal(gram[np.ix_(seen, seen)] / max(used, 1), JOINT_CAP * alone[seen])
    return alone, np.maximum(out, alone), crlb


def _sample_counts(system: System, sc: Scenario) -> np.ndarray:
    """The samples of each output over the run (its own period, the common one, or every step)."""
    step = system.sample_time if system.is_discrete else sc.dt
    periods = [float((sc.periods or {}).get(k, sc.sample_period or step)) for k in system.outputs]
    return np.array([max(1.0, np.floor(sc.t_final / p + 1e-9)) for p in periods])


def _initial_std(model: System, system: System, sc: Scenario, nominal: Run | None, still: np.ndarray,
                 sig: np.ndarray, delta: np.ndarray | None = None) -> tuple[dict[int, float], str]:
    """σ₀ of the initial error for each state the rule fixes (the file's ``initial_std``, and every state constant on the
    run), by state index, with the sentence that says how (see the module docstring)."""
    given = dict(sc.initial_std or {})
    names = list(system.states)
    # a parameter the file declares unknown but this analysis does not estimate (--params): nothing to start
    given = {k: v for k, v in given.items() if k in names or k not in model.params}
    bad = [k for k in given if k not in names]
    if bad:
        raise ModelError(f"advise: [simulation] initial_std names {bad[0]!r}, which is not a state or an unknown parameter of "
                         f"{model.name!r}; states and unknown parameters: {', '.join(names)}")
    for k, v in given.items():
        if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
            raise ModelError(f"advise: [simulation] initial_std.{k} must be a positive finite number (the standard deviation of "
                             f"the initial estimation error of {k}), got {v!r}")
    out = {names.index(k): float(v) for k, v in given.items()}
    const = [i for i in range(model.n_states) if still[i] and i not in out]
    if not const:
        why = (f"x̂(0) and P(0) of {', '.join(given)} from [simulation] initial_std (σ₀ = "
               + ", ".join(f"{v:.3g}" for v in given.values()) + ")") if given else ""
        return out, why
    x0 = sc.x0
    if delta is None:
        at_zero = [i for i in const if x0[i] == 0]
        found = _resolvable(system, nominal, at_zero, sig) if nominal is not None else [np.inf] * len(at_zero)
        floor = dict(zip(at_zero, found))
    else:
        floor = {i: float(delta[i]) for i in const}
    pstd = sc.process_std
    parts = []
    for j, i in enumerate(const):
        fl = float(floor.get(i, np.inf))
        fl_ok = np.isfinite(fl) and fl > 0
        if pstd is not None and pstd[i] > 0:     # (b) the spread its own random walk reaches over the run
            base, how = float(pstd[i] * np.sqrt(sc.t_final)), "σ_w·√t_final"
        elif x0[i] != 0:                           # (c) its magnitude
            base, how = 0.5 * abs(float(x0[i])), "|x(0)|/2"
        elif fl_ok:                                # (d) at 0: the smallest offset the run resolves
            base, how = fl, "x(0) = 0: the smallest offset the run resolves, all initial values unknown together"
        else:
            base, how = 0.0, ""
        if not base > 0:                            # x(0) = 0 and the run does not show the state in the outputs at all
            base, how = 1.0, "1 (x(0) = 0 and the outputs do not depend on it along the run: give initial_std)"
        out[i] = base
        parts.append(f"{names[i]}: {base:.3g} ({how})")
    why = ("states constant on the run (" + ", ".join(names[i] for i in const) + ") start off their true value by σ₀ = "
           + "; ".join(parts) + ", P(0) = σ₀²")
    if given:
        why += "; " + ", ".join(given) + " from [simulation] initial_std"
    return out, why


def _xhat0(x0: np.ndarray, run: Run | None, scale: np.ndarray, estimated: Sequence[int], guesses: Sequence[float],
           fixed: Mapping[int, float] | None = None, local: np.ndarray | None = None) -> np.ndarray:
    """x̂(0): x(0) moved by half each state's local scale (alternating signs), inside the box the run visits (so inside
    every region a design assumes from that box: a state of charge stays below 1, a concentration positive).

    A state in `fixed` (σ₀ by index: the file's ``initial_std`` and the states constant on the run) is moved by σ₀
    itself: towards the box the run visits where that box has room, never clipped onto it (a constant's box is a
    single point: clipping would start it at its true value, and bias estimation would look solved when it was never
    tested); a nonzero state keeps its sign. Unknown parameters (`estimated`) start at their `guesses`."""
    out = np.array(x0, dtype=float)
    fixed = dict(fixed or {})
    local = scale if local is None else local
    sign = 1.0
    for i in range(out.size):
        if i in estimated:
            continue
        keeps = run is not None and (np.all(run.x[:, i] > 0) or np.all(run.x[:, i] < 0))
        lo, hi = (float(np.min(run.x[:, i])), float(np.max(run.x[:, i]))) if run is not None else (-np.inf, np.inf)
        if i in fixed:
            d = fixed[i]
            tries = [x0[i] + d * sign, x0[i] - d * sign]
            if x0[i] != 0:   # keep the sign: of the two directions, away from 0 when the other would cross it
                tries = [v for v in tries if v * x0[i] > 0] or [x0[i] + d * np.sign(x0[i])]
            # the direction that stays nearest the visited box (inside it when it has room)
            out[i] = min(tries, key=lambda v: max(lo - v, v - hi, 0.0))
            sign = -sign
            continue
        # half the state's local scale, but no more than its initial size (or a tenth of its range) for a state that
        # grows far from where it starts
        s0 = min(local[i], max(abs(x0[i]), 0.1 * scale[i]))
        tries = [x0[i] + 0.5 * s0 * sign, x0[i] - 0.5 * s0 * sign]
        if keeps:  # a state that keeps its sign on the run (a level, a concentration) keeps it
            tries = [v if v * x0[i] > 0 else x0[i] * (1.5 if v > x0[i] else 0.5) for v in tries]
        inside = [v for v in tries if lo <= v <= hi]
        out[i] = inside[0] if inside else float(np.clip(tries[0], lo, hi))
        sign = -sign
    for i, g in zip(estimated, guesses):
        out[i] = g
    return out


#: An unknown parameter whose guess is its true value starts this fraction of it off (without an initial_std).
PARAM_OFFSET = 0.3


def _off_truth(xh0: np.ndarray, unknown: Sequence[str], first: int, guesses: Sequence[float], truth: Mapping[str, float],
               sigma0: Mapping[int, float], local: np.ndarray) -> str:
    """Move the unknown parameters whose guess is their true value (no ``true_parameters`` in the file: the file's
    value is both) off it, in place: by their σ₀ from ``initial_std``, else by 30 % (a zero one by its local scale),
    alternating up and down, keeping the sign. A run started at the true value would show a parameter "estimated"
    that was never tested. Returns the note saying so ("" when none moved)."""
    moved, sign = [], 1.0
    for j, (k, g) in enumerate(zip(unknown, guesses)):
        i = first + j
        if g != truth[k]:
            continue
        d = float(sigma0[i]) if i in sigma0 else (PARAM_OFFSET * abs(g) if g != 0 else float(local[i]))
        v = g + sign * d
        if g != 0 and v * g <= 0:          # keep the sign of a rate, a gain, a mass
            v = g + np.sign(g) * d
        xh0[i] = v
        moved.append(f"{k} = {v:.4g}")
        sign = -sign
    if not moved:
        return ""
    return (f"x̂(0) of the unknown parameters {', '.join(moved)}: the file's value is both the plant's and the guess, "
            f"and an estimate started at the true value tests nothing, so it starts {int(PARAM_OFFSET * 100)} % off "
            "(by σ₀ where [simulation] initial_std names it); give [simulation] true_parameters (the plant's values) "
            "to start from the file's guess")


def _blockers(ctx: Context, model: System, unknown: Sequence[str], rep: Any, rep_sig: Any, nominal: Run | None,
              recording: Recording | None) -> None:
    """What stops every observer (an unobservable state, a non-identifiable parameter) or the run (an input that does
    not excite it), and the notes on local-only observability: into `ctx`."""
    system = ctx.system
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
    scen = _scenario(model_file, simulation, model, unknown)
    notes: list[str] = []
    nominal = None
    if scen is not None:
        if scen.x0.size != model.n_states:
            raise ModelError(f"advise: [simulation] x0 has {scen.x0.size} entries but {model.name!r} has {model.n_states} "
                             f"states ({', '.join(model.states)})")
        x0_plant = np.concatenate([scen.x0, [truth[k] for k in unknown]])
        scen = Scenario(scen.t_final, scen.dt, x0_plant, scen.inputs, scen.noise, scen.noise_std,
                        scen.process_std,   # per state and unknown parameter (a parameter's: its random walk)
                        scen.sample_period,
                        seed if scen.seed is None else scen.seed,   # a ranking that is the same at every call
                        scen.periods, scen.delay, scen.initial_std)
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
    sc = scen
    # output noise -> R (σ per output; the constant states' offsets below are measured against it)
    p = system.n_outputs
    if sc is not None and sc.noise_std is not None and np.all(sc.noise_std > 0):
        sig = sc.noise_std
        noise_note = "R = σ² from the declared output noise"
    else:
        yspan = (nominal.y.max(axis=0) - nominal.y.min(axis=0)) if nominal is not None else np.ones(p)
        sig = np.maximum(1e-3 * yspan, 1e-6)
        if sc is not None and sc.noise_std is not None:
            sig = np.where(sc.noise_std > 0, sc.noise_std, sig)
        noise_note = ("no (or zero) output noise declared: R from σ = 0.1 % of each output's range on the run"
                      if nominal is not None else "no output noise declared and no run: R from σ = 1e-3")
    sigma0: dict[int, float] = {}
    initial_note = ""
    if nominal is not None:
        s = {"t": nominal.t, "x": nominal.x, "u": nominal.u}
        k = np.unique(np.linspace(0, nominal.t.size - 1, 200).astype(int))
        span = nominal.x.max(axis=0) - nominal.x.min(axis=0)
        mag = np.abs(nominal.x).max(axis=0)
        still = _still(span, mag)
        still[model.n_states:] = False              # unknown parameters: their own rule below
        # the smallest offset of each state and unknown parameter that the run resolves (one noise σ in RMS on the
        # outputs): no scale, local scale or P(0) below it (see the module docstring)
        counts = _sample_counts(system, sc)
        _, delta, crlb = _resolvable_both(system, nominal, list(range(system.n_states)), sig, counts=counts)
        seen = np.isfinite(delta) & (delta > 0)
        moving = ~still
        moving[model.n_states:] = False
        quiet = moving & seen & (span < delta)     # moves on the run, by less than the run can resolve
        # a state's scale: its range on the run; for a state that barely moves (< 5 % of its size), half its size; at
        # least the offset the run resolves
        scale = np.where(span > 0.05 * mag, span, 0.5 * mag)
        scale = np.where(moving & seen, np.maximum(scale, delta), scale)
        scale = np.maximum(scale, 1e-6)
        for j, k_ in enumerate(unknown):  # a constant parameter: its uncertainty, not its (zero) range
            i = model.n_states + j
            scale[i] = max(0.5 * abs(float(model.params[k_])), abs(truth[k_] - float(model.params[k_])), 1e-3,
                           float(delta[i]) if seen[i] else 0.0)
        sigma0, initial_note = _initial_std(model, system, sc, nominal, still, sig, delta)
        for i, v in sigma0.items():     # a constant state: its uncertainty (at least δ), not its (zero) range
            if still[i]:
                scale[i] = max(v, float(delta[i])) if seen[i] else v
        region = _region(system, nominal, model.inputs)
        omega_p, scale_note = _time_scales(system, {key: v[k] for key, v in s.items()}, t_final, scale,
                                             per=rate_unit(model_file))
        # the local scale: the distance a state covers at its fastest rate in 2/ω_p, at most its range (a position that
        # travels a kilometre, an angle that winds five turns: their range is no measure of the uncertainty a filter
        # carries over one time scale), at least the offset the run resolves; a constant's is its uncertainty
        local = scale.copy()
        if not system.is_discrete:
            rate = (np.max(np.abs(np.gradient(nominal.x, nominal.t, axis=0)), axis=0) if nominal.t.size > 1
                    else np.zeros(system.n_states))
            local[moving] = np.minimum(scale[moving], np.maximum(2.0 * rate[moving] / omega_p, 1e-6))
            local = np.where(moving & seen, np.maximum(local, delta), local)
    else:
        pts = {"t": np.zeros(1), "x": np.zeros((1, system.n_states)), "u": np.zeros((1, system.n_inputs))}
        scale = np.ones(system.n_states)
        local = scale
        omega_p, scale_note = _time_scales(system, pts, t_final, scale, "at x = 0, u = 0",
                                             per=rate_unit(model_file))
        region = {}
        delta = crlb = np.full(system.n_states, np.inf)
        still = quiet = np.zeros(system.n_states, dtype=bool)
    limit = np.inf
    if sc is not None:
        limit = 0.5 / sc.dt
        if sc.sample_period:
            limit = min(limit, 0.5 / sc.sample_period)
    omega_o = float(min(3.0 * omega_p, limit))
    notes.append(f"time scale: {scale_note}; observer rate ω_o = {omega_o:.3g} {rate_unit(model_file)} (3 ω_p"
                 + (f", capped at {limit:.3g} by the step/sample period" if 3.0 * omega_p > limit else "") + ")")
    period = (sc.sample_period or sc.dt) if sc is not None else 1e-2
    R = np.diag(sig ** 2)
    R_rate = R * period
    if xhat0 is not None:
        xh0 = np.asarray(xhat0, dtype=float).reshape(-1)
        if xh0.size != system.n_states:
            raise ModelError(f"advise: `xhat0` must have {system.n_states} entries ({', '.join(system.states)}), got {xh0.size}")
    elif sc is not None and sc.x0 is not None:
        est = list(range(model.n_states, system.n_states))
        guesses = [float(model.params[k]) for k in unknown]
        # a state that moves by less than the run resolves is moved like a constant (by half its local scale, never
        # clipped into the box the run visits, which is about a single point for it)
        moved_by = {**{int(i): 0.5 * float(local[i]) for i in np.flatnonzero(quiet)}, **sigma0}
        xh0 = _xhat0(sc.x0, nominal, scale, est, guesses, moved_by, local)
        # on a recording the plant is the real one: its parameters are unknown, and the file's value is only a guess
        moved = _off_truth(xh0, unknown, model.n_states, guesses, truth, sigma0, local) if recording is None else ""
        if moved:
            notes.append(moved)
    else:
        xh0 = np.array([0.0] * model.n_states + [float(model.params[k]) for k in unknown])
    P0, q, noise_note = _p0_and_q(model, system, sc, xh0, xhat0, local, sigma0, delta, still, omega_p, t_final, noise_note)
    Q = np.diag(q)
    if initial_note:
        notes.append(initial_note)
    ctx = Context(model, system, unknown, truth, sc, nominal, rep, rep_sig, omega_p, omega_o, scale, region, xh0, R, R_rate, Q,
                  P0, noise_note, notes=notes, recording=recording, local_scale=np.asarray(local, dtype=float),
                  constant=tuple(int(i) for i in np.flatnonzero(still)) if nominal is not None else (),
                  resolvable=np.asarray(delta, dtype=float), quiet=tuple(int(i) for i in np.flatnonzero(quiet)),
                  cramer_rao=np.asarray(crlb, dtype=float), rate_unit=rate_unit(model_file))
    _blockers(ctx, model, unknown, rep, rep_sig, nominal, recording)
    return ctx


def _p0_and_q(model: System, system: System, sc: Any, xh0: np.ndarray, xhat0: Any, local: np.ndarray,
              sigma0: Mapping[int, float], delta: np.ndarray, still: np.ndarray, omega_p: float, t_final: float,
              noise_note: str) -> tuple[np.ndarray, np.ndarray, str]:
    """P(0), diag Q and the tuning's text (the rules of the module docstring)."""
    # P(0): the initial uncertainty, i.e. the offset of x̂(0) from x(0) chosen above, at least a tenth of the state's
    # local scale; never the whole range squared (1e4 m² on a position that covers 100 m puts sigma points and
    # EKF corrections far outside anything the model has seen). A state with a σ₀ of its own (initial_std, a constant on
    # the run) has P(0) = σ₀²: its offset is σ₀, a one-σ error.
    offset = np.abs(xh0 - sc.x0) if sc is not None and sc.x0 is not None else local
    sd0 = np.maximum(np.minimum(offset, local), 0.1 * local)
    given = {system.states.index(k) for k in (sc.initial_std or {})} if sc is not None else set()
    for i, v in sigma0.items():   # with an x̂(0) of the caller's, a constant's P(0) covers that offset too
        sd0[i] = v if xhat0 is None or i in given else max(v, float(offset[i]))
    for i in range(system.n_states):   # never below the offset the run resolves (the file's initial_std is kept)
        if np.isfinite(delta[i]) and delta[i] > 0 and i not in given:
            sd0[i] = max(float(sd0[i]), float(delta[i]))
    P0 = np.diag(sd0 ** 2)
    # Q: the declared process noise σ_w², else a small model-error allowance for a moving state, and for a constant (a
    # state the run leaves where it starts, an unknown parameter) a random walk the run cannot resolve
    per_step = system.is_discrete   # a map's Q is the covariance of the noise of one step, not an intensity
    allowance = (0.01 * local) ** 2 * (1.0 if per_step else omega_p)
    fixed = np.zeros(system.n_states, dtype=bool)
    fixed[list(np.flatnonzero(still))] = True
    fixed[model.n_states:] = True
    off0 = np.array([sigma0.get(i, sd0[i]) for i in range(system.n_states)])   # the initial offset (σ₀) of each
    drift = np.where(np.isfinite(delta) & (delta > 0), np.minimum(delta, off0), off0)
    walk = (0.1 * drift) ** 2 / t_final * (system.sample_time if per_step else 1.0)
    allowance = np.where(fixed, walk, allowance)
    declared = sc is not None and sc.process_std is not None and np.any(sc.process_std > 0)
    q = np.where(sc.process_std > 0, sc.process_std ** 2, allowance) if declared else allowance
    parts = []
    if declared:
        parts.append("Q = σ_w² from the declared process noise" + (" (where declared)" if np.any(sc.process_std == 0) else ""))
    if not declared or np.any(sc.process_std[~fixed] == 0):
        parts.append("Q = (0.01·range)² per step for a moving state" if per_step else
                     "Q = (0.01·ℓ)²·ω_p for a moving state, ℓ its local scale (its range, at most the distance its fastest "
                     "rate covers in 2/ω_p, at least the offset the run resolves)")
    if np.any(fixed & (q == walk)):
        parts.append("a constant (a state the run leaves where it starts, an unknown parameter) gets the random walk "
                     "(0.1 δ)²/t_final" + (" per unit time (× T_s per step)" if per_step else "")
                     + ", δ the smaller of its initial offset σ₀ and the smallest offset the run resolves: over the run it "
                     "wanders by a tenth of what the run can see, so the filter keeps learning it without losing it")
    noise_note += "; " + "; ".join(parts)
    return P0, q, noise_note
