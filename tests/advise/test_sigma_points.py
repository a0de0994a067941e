"""The auto-tuned UKF and square-root UKF at moderate n (issue 36 part 4): sigma points at √3 σ (κ = 3 − n), a zero
central covariance weight, α not sized on the (single-point) box of a constant, bounds away from a 1/cos θ, and the
"tiny R" rule in the output's own units.

Reference values: the weights from their closed forms (Julier & Uhlmann (2004): W₀ = κ/(n + κ), Wᵢ = 1/(2(n + κ)));
the UKF update recomputed here in NumPy from those weights; the bound from arccos by hand.
"""

import numpy as np
import pytest

import nlobs
from nlobs.advise import advise
from nlobs.advise._context import build_context
from nlobs.design import design_ukf
from nlobs.design.kalman._srukf import design_srukf
from nlobs.design._tune import domain_bounds, prior_output_ratio, sigma_points
from nlobs.model import SimulationConfig
from nlobs.model._expr import parse_expression
from nlobs.model._system import symbol


def _sim(x0, inputs=None, **kw):
    ins = {k: parse_expression(v, {"t": symbol("t")}) for k, v in (inputs or {}).items()}
    return SimulationConfig(x0=tuple(x0), inputs=ins, seed=2, **kw)


# three undamped oscillators, one output each through a sine (n = 6)
OSC = nlobs.System(states=["a1", "v1", "a2", "v2", "a3", "v3"],
                   f=["v1", "-a1", "v2", "-2*a2", "v3", "-3*a3"], outputs=["y1", "y2", "y3"],
                   h=["sin(a1)", "sin(a2)", "a3 + 0.1*a3**2"], name="osc3")
SIM = _sim((0.5, 0.0, 0.4, 0.1, 0.3, 0.0), t_final=10.0, dt=0.01, noise={"y1": 0.01, "y2": 0.01, "y3": 0.01},
           sample_period=0.05)


def test_six_states_get_kappa_three_minus_n_and_a_zero_central_covariance_weight():
    ctx = build_context(OSC, simulation=SIM)
    opts, why = sigma_points(ctx)
    n = 6
    assert opts["kappa"] == 3 - n and "alpha" not in opts
    # closed forms at α = 1: W0m = κ/(n + κ), W0c = W0m + β must be 0 (so β = (n − 3)/3); Wi = 1/(2(n + κ)) = 1/6
    kappa = 3.0 - n
    w0m = kappa / (n + kappa)
    assert w0m + opts["beta"] == pytest.approx(0.0, abs=1e-15)
    assert "Julier & Uhlmann (2004)" in why and "√3 σ" in why


def test_up_to_three_states_keep_the_cubature_defaults():
    vdp = nlobs.System(states=["x1", "x2"], f=["x2", "(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"])
    sim = _sim((1.0, 0.0), t_final=10.0, dt=0.01, noise={"y": 0.05}, sample_period=0.05)
    opts, _ = sigma_points(build_context(vdp, simulation=sim))
    assert opts == {}                                                   # α = 1, β = 0, κ = 0: weights 1/(2n)


def test_a_constant_does_not_shrink_alpha():
    # b' = 0: its box on the run is the single value b(0), while its P(0) is σ₀² > 0; sizing α on that box gave 1e-3
    drift = nlobs.System(states=["x1", "b"], f=["b + u", "0"], inputs=["u"], outputs=["y"], h=["x1"])
    sim = _sim((0.5, 0.2), {"u": "sin(t)"}, t_final=20.0, dt=0.01, noise={"y": 0.05}, sample_period=0.05)
    ctx = build_context(drift, simulation=sim)
    assert ctx.P0[1, 1] > 0
    opts, _ = sigma_points(ctx)
    assert "alpha" not in opts


def _ukf_update(m, P, y, h, R, kappa, beta, alpha=1.0):
    """The UKF measurement update in NumPy (Wan & van der Merwe (2000), scaled sigma points), for reference."""
    n = m.size
    lam = alpha ** 2 * (n + kappa) - n
    c = n + lam
    wm = np.full(2 * n + 1, 1 / (2 * c))
    wm[0] = lam / c
    wc = wm.copy()
    wc[0] = lam / c + 1 - alpha ** 2 + beta
    L = np.linalg.cholesky(P) * np.sqrt(c)
    X = np.column_stack([m] + [m + L[:, i] for i in range(n)] + [m - L[:, i] for i in range(n)])
    Y = np.column_stack([h(X[:, i]) for i in range(2 * n + 1)])
    yhat = Y @ wm
    dY, dX = Y - yhat[:, None], X - m[:, None]
    S = (dY * wc) @ dY.T + R
    Cxy = (dX * wc) @ dY.T
    K = Cxy @ np.linalg.inv(S)
    return m + K @ (y - yhat), P - K @ S @ K.T


def test_the_update_with_a_negative_mean_weight_matches_numpy_and_stays_positive_definite():
    ctx = build_context(OSC, simulation=SIM)
    opts, _ = sigma_points(ctx)
    rng = np.random.default_rng(4)
    A = rng.normal(size=(6, 6))
    P = A @ A.T * 0.05 + 0.01 * np.eye(6)
    m = np.array([0.6, -0.2, 0.5, 0.3, 0.2, -0.1])
    y = np.array([0.55, 0.45, 0.3])
    R = np.diag([1e-4, 1e-4, 1e-4])
    h = lambda x: np.array([np.sin(x[0]), np.sin(x[2]), x[4] + 0.1 * x[4] ** 2])  # noqa: E731
    m_ref, P_ref = _ukf_update(m, P, y, h, R, opts["kappa"], opts["beta"])
    for design in (design_ukf, design_srukf):
        obs = nlobs.Observer(design(OSC, Q=np.zeros((6, 6)), R=R, P0=P, **opts))
        z = obs.update(0.0, obs.initial_state(m), None, y)
        np.testing.assert_allclose(obs.estimate(0.0, z), m_ref, rtol=0, atol=1e-12)
        P_plus = np.array(obs.design.covariance(z))
        np.testing.assert_allclose(P_plus, P_ref, rtol=0, atol=1e-12)
        assert np.linalg.eigvalsh(P_plus).min() > 0


def test_a_state_under_one_over_cos_is_kept_where_cos_keeps_half_its_size():
    # θ' = 1.45 cos t: θ = 1.45 sin t reaches ±1.45 rad; ψ' = r/cos θ. Sigma points beyond θ = π/2 see 1/cos θ → ∞.
    att = nlobs.System(states=["theta", "psi"], f=["w", "0.3/cos(theta)"], inputs=["w"], outputs=["yt", "yp"],
                       h=["theta", "psi"], name="att")
    sim = _sim((0.0, 0.0), {"w": "1.45*cos(t)"}, t_final=7.0, dt=0.001, noise={"yt": 0.01, "yp": 0.01},
               sample_period=0.01)
    ctx = build_context(att, simulation=sim)
    lo, hi = domain_bounds(ctx)["theta"]
    top = np.arccos(0.5 * np.cos(1.45))                                  # cos θ* = half the smallest cos θ on the run
    assert hi == pytest.approx(top, abs=2e-3) and hi <= top
    assert lo == pytest.approx(-top, abs=2e-3) and lo >= -top
    ukf = advise(att, simulation=sim, kinds=["ukf", "srukf"])
    for kind in ("ukf", "srukf"):
        c = ukf.candidate(kind)
        assert c.applies and c.options["bounds"]["theta"] == [lo, hi], c.why


def test_tiny_r_is_judged_against_the_prior_of_the_same_output():
    # a position known to ~8 m and a rate gyro with σ = 1e-4 rad/s: R_gyro / P0_position = 1e-8/65 mixes units;
    # against the gyro's own prior variance (P0 of the rate, 0.01) the ratio is 1e-6: no "tiny R"
    veh = nlobs.System(states=["p", "v", "w"], f=["v", "-0.1*v + u", "-w"], inputs=["u"], outputs=["gps", "gyro"],
                       h=["p", "w"], name="veh")
    sim = _sim((0.0, 5.0, 0.2), {"u": "sin(0.1*t)"}, t_final=100.0, dt=0.01, noise={"gps": 3.0, "gyro": 1e-4},
               sample_period=0.1)
    ctx = build_context(veh, simulation=sim)
    ratio, out = prior_output_ratio(ctx)
    expected = min(9.0 / ctx.P0[0, 0], 1e-8 / ctx.P0[2, 2])              # H picks p and w: (H P0 Hᵀ)_kk = P0 of each
    assert ratio == pytest.approx(expected, rel=1e-12)
    assert np.linalg.eigvalsh(ctx.R).min() / np.linalg.eigvalsh(ctx.P0).max() < 1e-8   # what the old rule read as tiny
    adv = advise(veh, simulation=sim, kinds=["ukf", "srukf"])
    assert adv.choice is None and not any("is the choice" in n for n in adv.notes)
