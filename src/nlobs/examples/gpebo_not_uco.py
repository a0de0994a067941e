"""M8 #7 (Wang, Ortega & Bobtsov (2021)): the 2G+D observer converges on a system that is observable but not UCO.

ẋ = [[0, u(t)], [0, 0]]x, y = x1, u(t) = e^{-t}: the input vanishes, so the observability
Gramian over a window [t0, t0 + T] decays like e^{-2 t0} (not uniformly completely observable),
while W(0, T) has full rank (observable). Wang, Ortega & Bobtsov (2021), Proposition 1 says observability suffices for the
2G+D observer; a Kalman-like observer (Besançon (2010)), whose convergence rests on UCO, stalls.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..analysis import ltv_gramian, state_affine_ltv, uco_test
from ..design import ObserverDesign, design_gpebo_2gd, design_kalman_like, excitation_report
from ..errors import FiniteEscapeError
from ..model import StateAffine
from ..simulate import Noise, Sampling, simulate
from ._base import Claim, ExampleResult, register, rows_from_run
from ..references import cite

__all__ = ["run", "model", "kalman_like", "KL_DELTA", "KL_V"]

REF = f"{cite('000')} Proposition 1, Lemmas 1-2, eqs. (3)-(4), (12)-(17); {cite('002')} Kalman-like observer"
GAMMA_G, GAMMA = 5.0, 50.0          # the tuning (000 gives none)
X0 = (1.0, -1.0)                     # not in the paper: any x(0) with x2(0) != 0 shows the effect
T_FINAL, DT = 20.0, 1e-3
UCO_WINDOW = 5.0
KL_DELTA, KL_V = 1.0, 0.01          # Kalman-like tuning (002 gives none): forgetting δ and state-noise weight V = 0.01·I


def kalman_like(sa: StateAffine, *, delta: float = KL_DELTA, V: float = KL_V) -> ObserverDesign:
    """The Kalman-like observer of Besançon (2010), (nlobs.design.design_kalman_like) with V = `V`·I, forgetting δ."""
    return design_kalman_like(sa, delta=delta, Q=V * np.eye(sa.n_states))


def model() -> StateAffine:
    """ẋ = [[0, u], [0, 0]]x, y = x1 (Wang, Ortega & Bobtsov (2021), eq. 1 with A = [[0, u], [0, 0]], b = 0, C = e1)."""
    return StateAffine([[0, "u"], [0, 0]], [0, 0], [[1], [0]], inputs=["u"], outputs=["y"], name="ltv_vanishing_input")


@register("2gd-not-uco", f"{cite('000')}: 2G+D converges where the system is observable but not UCO", 70, aliases=("000-2gd-not-uco",))
def run() -> ExampleResult:
    sa = model()
    system = sa.to_system()
    gd = design_gpebo_2gd(sa, gamma_g=GAMMA_G, gamma=GAMMA)
    kl = kalman_like(sa)
    designs = {"2G+D": gd, "Kalman-like": kl}
    u = {"u": "exp(-t)"}
    clean = simulate(system, designs, t_final=T_FINAL, dt=DT, x0=X0, inputs=u)
    noisy = simulate(system, designs, t_final=T_FINAL, dt=DT, x0=X0, inputs=u, noise=Noise.gaussian(0.01),
                     sampling=Sampling(0.01), seed=7)
    try:  # without V, the Kalman-like design needs δ > 2 sup‖A‖ = 2 (002); then M grows where u no longer excites
        simulate(system, {"kl": design_kalman_like(sa, delta=2.5, region={"u": (0.0, 1.0)})}, t_final=T_FINAL, dt=DT, x0=X0,
                 inputs=u)
        escape = "did not blow up"
    except FiniteEscapeError as e:
        escape = f"its M blew up (|M| > 1e12) at t = {e.t:.3g}"

    e_gd, e_kl = clean.error_norm("2G+D"), clean.error_norm("Kalman-like")
    k10 = int(round(10 / DT))
    rep = excitation_report(gd, clean.t, clean.observers["2G+D"].z, clean.u, clean.y)
    grid = slice(None, None, 10)                               # the analysis layer on a 0.01 s grid of the run
    A_t, C_t = state_affine_ltv(sa, clean.t[grid], u=clean.u[grid])
    gram = ltv_gramian(A_t, C_t, clean.t[grid])
    uco = uco_test(A_t, C_t, clean.t[grid], UCO_WINDOW, stride=50)
    order = gd.n_z
    claims = [
        Claim(f"observable on [0, 20]: the Gramian W(0, 20) ({cite('000')} eq. 3) has full rank ({cite('000')} Prop. 1 hypothesis)",
              gram.observable, str(gram)),
        Claim(f"not UCO: λmin W(t0, t0 + {UCO_WINDOW:g}) → 0 ({cite('000')} eq. 4 fails)", not uco.uniform, str(uco)),
        Claim(f"the regression of the 2G+D observer is interval exciting with the Gramian's level ({cite('000')} Prop. 2: ∫ψψᵀ = W(0, t))",
              abs(rep.ie_level[-1] - gram.eigenvalues[0]) < 1e-3 * gram.eigenvalues[0],
              f"λmin ∫ψψᵀ = {rep.ie_level[-1]:.5g}, λmin W(0, 20) = {gram.eigenvalues[0]:.5g}"),
        Claim(f"2G+D order n_χ = (3 + 2n)n = 14 ({cite('000')} §6)", order == 14, f"{order} internal states"),
        Claim(f"G+D mixed regressor Δ becomes non-zero ({cite('000')} Lemma 2)", rep.delta_time is not None,
              f"|Δ| > 1e-6 from t = {rep.delta_time}, final Δ = {rep.delta[-1]:.4g}"),
        Claim("2G+D error < 1e-12 by t = 20 (γ_g = 5, γ = 50, noise-free; round-off level)", e_gd[-1] < 1e-12,
              f"|x̂ - x|(20) = {e_gd[-1]:.3g}"),
        Claim("Kalman-like error stalls at a non-zero value", e_kl[-1] > 0.1 and abs(e_kl[-1] - e_kl[k10]) < 0.01 * e_kl[k10],
              f"|x̂ - x|(10) = {e_kl[k10]:.4g}, |x̂ - x|(20) = {e_kl[-1]:.4g}"),
        Claim(f"2G+D error stays bounded under measurement noise ({cite('000')} §6, BIBS robustness)",
              bool(np.all(np.isfinite(noisy.error_norm("2G+D")))) and noisy.metrics("2G+D").rms_error < 0.2,
              f"RMS error over the last 20 % = {noisy.metrics('2G+D').rms_error:.3g} (σ = 0.01, sampled every 0.01 s)"),
    ]
    fig = Figure(figsize=(8, 6.5), layout="constrained")
    ax1, ax2, ax3 = fig.subplots(3, 1)
    ax1.semilogy(clean.t, np.maximum(e_gd, 1e-16), label="2G+D")
    ax1.semilogy(clean.t, np.maximum(e_kl, 1e-16), label=f"Kalman-like (δ = {KL_DELTA:g}, V = {KL_V:g}·I)")
    ax1.set_ylabel("‖x̂ − x‖")
    ax1.legend(fontsize="small")
    ax2.plot(clean.t, rep.delta, label="Δ = det(I − Ω) (G+D)")
    ax2.set_ylabel("Δ")
    above = uco.delta > 1e-13                              # below: round-off of the Gramian difference
    ax3.semilogy(uco.starts[above], uco.delta[above], label=f"λmin W(t0, t0 + {UCO_WINDOW:g}) (shown down to 1e-13)")
    ax3.set_xlabel("t, t0")
    ax3.set_ylabel("UCO level")
    for ax in (ax1, ax2, ax3):
        ax.grid(alpha=0.3, which="both")
    ax2.legend(fontsize="small")
    ax3.legend(fontsize="small")
    fig.suptitle(f"{cite('000')}: observable, not UCO — 2G+D vs Kalman-like")
    table = rows_from_run("noise-free", clean) + rows_from_run("noise σ = 0.01", noisy)
    notes = [
        f"x(0) = {X0}, x̂(0) = (0, 0), t in [0, {T_FINAL:g}], RK4 with dt = {DT:g}: {cite('000')} gives no initial state or step.",
        f"G+D starts at θ̂_g(0) = 0, Ω(0) = I, θ̂(0) = 0 and ξ(0) = x̂(0), Φ_A(0) = I ({cite('000')} eq. 13b).",
        f"The Kalman-like observer is nlobs.design.design_kalman_like ({cite('002')}) with δ = {KL_DELTA:g}, V = {KL_V:g}·I, W = 1, "
        f"M(0) = I ({cite('002')} gives no tuning).",
        f"With V = 0 the Kalman-like design requires δ > 2 sup‖A‖ = 2 ({cite('002')}); with δ = 2.5 {escape}: the forgetting "
        "inflates M in the direction the vanishing input no longer excites.",
        "Observability and the UCO level come from nlobs.analysis (ltv_gramian, uco_test) on the model frozen along the "
        "input (state_affine_ltv), on a 0.01 s grid; the 2G+D regressor's excitation integral equals the Gramian, as the "
        f"proof of {cite('000')} Prop. 2 says.",
    ]
    return ExampleResult(
        systems={"ẋ = [[0, u], [0, 0]]x, y = x1": model().to_system()},
        key="2gd-not-uco", title=f"{cite('000')}: 2G+D on an observable, non-UCO LTV system", reference=REF,
        summary=(f"With u(t) = e^(-t) the system ẋ = [[0, u], [0, 0]]x, y = x1 is observable on [0, T] but not UCO. The 2G+D "
                 f"observer (order 14) reaches |x̂ - x| = {e_gd[-1]:.2g} at t = 20; the Kalman-like observer stalls at "
                 f"{e_kl[-1]:.3g}."),
        model=str(system), evidence=[str(gram), str(uco), str(gd), str(kl), str(rep)], runs={"noise-free": clean, "noisy": noisy},
        table=table, claims=claims, figures={"error norms, Δ and the UCO level": fig}, notes=notes)

