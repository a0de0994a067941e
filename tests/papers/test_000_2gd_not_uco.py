"""Acceptance, M8 #7: 000_6cd8bea7ca1db43b.txt — observability suffices for the 2G+D observer.

ẋ = [[0, u], [0, 0]]x, y = x1, u = e^{-t}: observable on [0, T] (rank W(0, T) = 2, eq. 3) but not UCO
(eq. 4 fails); the 2G+D observer (Prop. 1, eqs. 12-17) with γ_g = 5, γ = 50 follows its closed-form error law and
reaches 1e-13 by t = 20, a Kalman-like observer (002) stalls.
"""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import design_gpebo_2gd, simulate
from nlobs.examples import gpebo_not_uco as ex


def test_gramian_closed_form_observable_not_uco():
    # independent of the observer: Φ(τ, t0) = [[1, e^{-t0} - e^{-τ}], [0, 1]], so with C = e1 the Gramian is
    # W(t0, t0 + T) = ∫ [1, s; s, s²] dτ with s = e^{-t0} - e^{-τ}; its λmin → 0 as t0 grows
    def lam_min(t0, T=5.0):
        tau = np.linspace(t0, t0 + T, 20001)
        s = np.exp(-t0) - np.exp(-tau)
        W = np.array([[np.trapezoid(np.ones_like(s), tau), np.trapezoid(s, tau)],
                      [np.trapezoid(s, tau), np.trapezoid(s * s, tau)]])
        return np.linalg.eigvalsh(W)[0]
    assert lam_min(0.0) > 0.1          # rank W(0, 5) = 2: observable
    assert lam_min(10.0) < 1e-9        # not UCO: no δ > 0 works for every t0


def _closed_form_error(t: np.ndarray, gamma_g: float, gamma: float) -> np.ndarray:
    """‖x̂ - x‖ of 2G+D from the paper's equations, integrated independently of nlobs.

    x̂ - x = Φ_A θ̃ (eq. 12 with eq. 8), Φ_A = [[1, 1 - e^{-t}], [0, 1]] (eq. 13b for A = [[0, e^{-t}], [0, 0]]),
    ψ = Φ_Aᵀ e1 (eq. 10), and the proof of Lemma 2: θ̃(t) = θ̃(0) exp(-γ ∫Δ²) with Δ = det(I - Ω),
    Ω' = -γ_g ψψᵀ Ω, Ω(0) = I (eqs. 16b, 17a-c); θ̃(0) = θ̂(0) - θ = -(x(0) - ξ(0)) = -x(0).
    """
    from scipy.integrate import solve_ivp

    def rhs(s, z):
        Om = z[:4].reshape(2, 2)
        psi = np.array([1.0, 1.0 - np.exp(-s)])
        return np.concatenate([(-gamma_g * np.outer(psi, psi) @ Om).ravel(), [np.linalg.det(np.eye(2) - Om) ** 2]])

    sol = solve_ivp(rhs, (t[0], t[-1]), np.concatenate([np.eye(2).ravel(), [0.0]]), t_eval=t, rtol=1e-12, atol=1e-15,
                    method="DOP853")
    x0 = np.asarray(ex.X0, dtype=float)
    phi_x0 = np.stack([x0[0] + (1 - np.exp(-t)) * x0[1], np.full_like(t, x0[1])], axis=1)
    return np.linalg.norm(phi_x0, axis=1) * np.exp(-gamma * sol.y[4])


def test_2gd_error_follows_the_paper_law_to_round_off():
    # both implementations (nlobs and the closed form above) agree to ~2e-12 and reach 1e-13 by t = 20
    sa = ex.model()
    d = design_gpebo_2gd(sa, gamma_g=5.0, gamma=50.0)
    assert d.n_z == (3 + 2 * 2) * 2
    run = simulate(sa.to_system(), {"2gd": d}, t_final=20.0, dt=1e-3, x0=ex.X0, inputs={"u": "exp(-t)"})
    e = run.error_norm("2gd")[::50]
    ref = _closed_form_error(run.t[::50], 5.0, 50.0)
    assert np.max(np.abs(e - ref)) < 1e-11
    assert np.all(np.abs(e - ref) <= 1e-8 * ref + 1e-11)
    assert e[-1] < 1e-13


def test_kalman_like_stalls():
    sa = ex.model()
    run = simulate(sa.to_system(), {"kl": ex.kalman_like(sa)}, t_final=20.0, dt=1e-3, x0=ex.X0,
                   inputs={"u": "exp(-t)"})
    e = run.error_norm("kl")
    assert e[-1] > 0.1 and e[-1] == pytest.approx(e[10000], rel=0.01)


def test_example_claims_hold():
    result = ex.run()
    assert all(c.holds is True for c in result.claims), [str(c) for c in result.claims if c.holds is not True]
    assert {r["observer"] for r in result.table} == {"2G+D", "Kalman-like"}
