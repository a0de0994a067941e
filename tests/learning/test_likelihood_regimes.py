"""The likelihood on piecewise models (issue 39): censored saturating outputs, smoothed switches, known truths.

References are independent of the code under test: SciPy's ``log_ndtr`` and ``norm.logcdf``; a NumPy Kalman filter
with the exact discretisation (matrix exponential) of a linear model whose sensor saturates; the smoothing formulas
written out here in NumPy; plants simulated here by RK4 with Euler-Maruyama noise increments.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.linalg import expm
from scipy.special import log_ndtr as scipy_log_ndtr
from scipy.stats import norm

import nlobs
from nlobs.learning import fit_likelihood, log_likelihood
from nlobs.estimation import Recording
from nlobs.learning._regimes import filter_model, log_ndtr


def test_log_ndtr_matches_scipy_in_both_tails():
    z = ca.SX.sym("z")
    fn = ca.Function("f", [z], [log_ndtr(z), ca.gradient(log_ndtr(z), z)])
    zs = np.r_[np.linspace(-40.0, 8.0, 1201), -3 - 1e-9, -3 + 1e-9]
    val = np.array([float(fn(v)[0]) for v in zs])
    grad = np.array([float(fn(v)[1]) for v in zs])
    assert np.max(np.abs(val - scipy_log_ndtr(zs)) / np.maximum(1.0, np.abs(scipy_log_ndtr(zs)))) < 1e-13
    mills = np.exp(norm.logpdf(zs) - scipy_log_ndtr(zs))  # d/dz log Φ = φ/Φ
    assert np.max(np.abs(grad - mills) / np.maximum(1.0, mills)) < 1e-11


SWITCHES = nlobs.System(states=["x", "z"], inputs=["u"], outputs=["y", "w"],
                        f=["-max(x, 0) + u*sign(z - 1)", "-abs(z) + min(x, 2*u)"],
                        h=["sat(x, 0, ymax)", "min(z, x)"], params={"ymax": 3.0, "k": 1.0})


def test_censored_outputs_and_smoothed_switches_as_written_in_numpy():
    N = 101
    t = np.linspace(0, 10, N)
    xs, zs = np.linspace(-1, 4, N), np.linspace(0, 2, N)
    xs[60:] += 1.0   # one fast move of x between two samples
    run = {"x": np.c_[xs, zs], "u": np.full((N, 1), 0.5), "t": t}
    fm = filter_model(SWITCHES, ["k"], run, smoothing=1.0)
    cy, cw = fm.censored
    assert (cy.output, cy.lower, cy.upper, str(cy.branch)) == ("y", 0.0, 3.0, "x") and cw is None  # min(z, x): no limit
    # widths: 1 % of the range each switch's argument spans along the run
    spans = {"max(0, x)": 6.0, "sign(z - 1)": 2.0, "abs(z)": 2.0, "min(2*u, x)": 6.0, "min(x, z)": np.ptp(xs - zs)}
    got = {s.text: s.width for s in fm.smoothed}
    assert set(got) == set(spans), got
    for k, span in spans.items():
        assert got[k] == pytest.approx(0.01 * span, rel=1e-12), k
    # x moves by 1.05 between two samples (x − z by 1.03): with widths 0.06 and 0.04, ceil(1.03 / 0.08) = 13 sub-steps
    # move every argument by at most two widths each
    assert fm.substeps == int(np.ceil(1.03 / (2 * 0.04))) == 13
    e = {k: got[k] for k in spans}
    cs = nlobs.engine.compile_system(fm.system)
    x, z, u = 0.3, 0.9, 0.7

    def plus(g, eps):   # max(g, 0) convolved with the density 3 eps^4 / (4 (s^2 + eps^2)^(5/2)), by quadrature
        s = np.linspace(-400 * eps, 400 * eps, 800001)
        w = 3 * eps**4 / (4 * (s**2 + eps**2) ** 2.5)
        return np.trapezoid(np.maximum(g - s, 0) * w, s)

    def smax(a, b, eps):
        return b + plus(a - b, eps)

    def smin(a, b, eps):
        return a - plus(a - b, eps)

    for g in (-1.0, 0.0, 1.0):   # the error: eps/4 at the switch, eps^4/(4 r (r + |g|)^2) away from it
        r = np.hypot(g, 0.1)
        assert plus(g, 0.1) - max(g, 0.0) == pytest.approx(0.1 / 4 if g == 0 else 0.1**4 / (4 * r * (r + 1) ** 2), rel=1e-4)
    f_ref = [-smax(0, x, e["max(0, x)"]) + u * np.tanh((z - 1) / e["sign(z - 1)"]),
             -(plus(z, e["abs(z)"]) + plus(-z, e["abs(z)"])) + smin(2 * u, x, e["min(2*u, x)"])]
    h_ref = [x, smin(z, x, e["min(x, z)"])]   # y: the unsaturated branch (censored output)
    p = np.asarray(fm.system.param_values)
    assert np.allclose(np.asarray(cs.f(0, [x, z], [u], p)).ravel(), f_ref, rtol=1e-8, atol=1e-10)   # quadrature
    assert np.allclose(np.asarray(cs.h(0, [x, z], [u], p)).ravel(), h_ref, rtol=1e-8, atol=1e-10)
    codes, limits = fm.censoring(np.array([[3.0, 0.0], [2.9, 1.0], [0.0, 1.0], [np.nan, 1.0]]),
                                 np.array([[1, 1], [1, 1], [1, 1], [0, 1]]))
    assert codes[:, 0].tolist() == [1, 0, -1, 0] and limits[:, 0].tolist() == [3.0, 0.0, 0.0, 0.0]
    assert not codes[:, 1].any()
    # a limit that depends on a fitted parameter is not known: the output is then an ordinary switch
    assert filter_model(SWITCHES, ["ymax"], run, smoothing=1.0).censored[0] is None


# a first-order lag read by a sensor saturating at C: y = min(x + v, C)
LAG = nlobs.System(states=["x"], inputs=["u"], outputs=["y"], f=["-a*x + b*u"], h=["min(x, c)"],
                   params={"a": 0.5, "b": 1.0, "c": 1.5})


def _numpy_censored_loglik(t, u, y, a, b, c, q, r, x0, p0):
    """Kalman filter with the exact discretisation of x' = -a x + b u + w (zero-order hold); a sample at the limit c
    contributes log Φ((x̂⁻ − c)/√S) and no update (as a missing sample); the others the Gaussian term."""
    x, P, total = x0, p0, 0.0
    for k in range(t.size):
        if k:
            h = t[k] - t[k - 1]
            M = expm(np.array([[-a, b * u[k - 1], 1.0, 0.0], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]]) * h)
            x = M[0, 0] * x + M[0, 1]   # e^{-ah} x + (1 − e^{-ah}) b u / a
            P = np.exp(-2 * a * h) * P + q * (1 - np.exp(-2 * a * h)) / (2 * a)
        S = P + r
        if y[k] >= c:
            total += norm.logcdf((x - c) / np.sqrt(S))
            continue
        total += -0.5 * (np.log(2 * np.pi * S) + (y[k] - x) ** 2 / S)
        K = P / S
        x, P = x + K * (y[k] - x), (1 - K) * P
    return total


def test_censored_likelihood_matches_a_numpy_filter():
    rng = np.random.default_rng(3)
    t = np.arange(200) * 0.05
    u = 1.2 + np.sign(np.sin(0.8 * t))
    x, xs = 0.2, []
    for k in range(t.size):
        xs.append(x)
        x = x + 0.05 * (-0.5 * x + u[k]) + 0.05 * rng.standard_normal()
    y = np.minimum(np.array(xs) + 0.05 * rng.standard_normal(t.size), 1.5)
    assert 20 < np.sum(y >= 1.5) < 150
    rec = Recording.from_arrays(LAG, t, y, u)
    d = nlobs.design_ekf(LAG, Q=[[0.04]], R=[[0.0025]], P0=[[0.1]], xhat0=[0.2])
    for a_, qs, rs in ((0.5, 1.0, 1.0), (0.7, 2.0, 0.5)):
        ll, g = log_likelihood(d, rec, params=["a"], learn_noise=True, max_step=0.005,
                               values={"a": a_, "log_Q_scale": np.log(qs), "log_R_scale": np.log(rs)})
        ref = _numpy_censored_loglik(t, u, y, a_, 1.0, 1.5, 0.04 * qs, 0.0025 * rs, 0.2, 0.1)
        assert abs(ll - ref) < 1e-8 * abs(ref), (ll, ref)
        eps = 1e-6   # and the gradient against central differences of the NumPy filter (here only)
        fd = (_numpy_censored_loglik(t, u, y, a_ + eps, 1.0, 1.5, 0.04 * qs, 0.0025 * rs, 0.2, 0.1)
              - _numpy_censored_loglik(t, u, y, a_ - eps, 1.0, 1.5, 0.04 * qs, 0.0025 * rs, 0.2, 0.1)) / (2 * eps)
        assert abs(g[0] - fd) < 1e-5 * max(1.0, abs(fd)), (g[0], fd)
    # without censoring the filter linearises min(x, 1.5): another number (the EKF's on the saturated branch)
    plain, _ = log_likelihood(d, rec, censor=False, max_step=0.005)
    assert abs(plain - _numpy_censored_loglik(t, u, y, 0.5, 1.0, 1.5, 0.04, 0.0025, 0.2, 0.1)) > 1.0


# two tanks, the lower one read by a sensor saturating at 10: the truth, and the model a user writes
TA, TB, TK, SW, SV, YMAX = 0.5, 0.4, 0.3, 0.03, 0.05, 10.0
TANKS = nlobs.System(states=["x1", "x2"], inputs=["u"], outputs=["y"],
                     f=["-a*sqrt(max(x1, 0)) + k*u", "a*sqrt(max(x1, 0)) - b*sqrt(max(x2, 0))"],
                     h=["min(x2, ymax)"], params={"a": TA, "b": TB, "k": TK, "ymax": YMAX})


def _tanks(seed: int, N: int = 800, dt: float = 0.5, sub: int = 20, after: bool = False):
    """The plant by RK4 + Euler-Maruyama; its sensor clips its noisy value at YMAX (Tobit), or with `after` its noise
    is added after the limit (y = min(x2, YMAX) + v, as nlobs.simulate draws a saturating output's noise)."""
    rng = np.random.default_rng(seed)
    t = np.arange(N) * dt
    u = 3.7 + 0.8 * np.sin(0.03 * t) + 0.3 * np.sin(0.11 * t)

    def f(x, uk):
        q1 = TA * np.sqrt(max(x[0], 0))
        return np.array([-q1 + TK * uk, q1 - TB * np.sqrt(max(x[1], 0))])

    x, X, h = np.array([5.0, 8.0]), np.empty((N, 2)), dt / sub
    for k in range(N):
        X[k] = x
        for _ in range(sub):
            k1 = f(x, u[k])
            k2 = f(x + h / 2 * k1, u[k])
            k3 = f(x + h / 2 * k2, u[k])
            k4 = f(x + h * k3, u[k])
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4) + SW * np.sqrt(h) * rng.standard_normal(2)
    v = SV * rng.standard_normal(N)
    return t, u, (np.minimum(X[:, 1], YMAX) + v if after else np.minimum(X[:, 1] + v, YMAX))


def test_a_saturating_sensor_recovers_the_truth_within_two_sigma():
    t, u, y = _tanks(0)
    assert np.sum(y >= YMAX) > 100    # the sensor sits at its limit for a quarter of the record
    rec = Recording.from_arrays(TANKS, t, y, u)
    start = TANKS.with_params(a=0.8 * TA, b=1.2 * TB, k=0.8 * TK)
    d = nlobs.design_ekf(start, Q=np.diag([SW**2, SW**2]), R=[[SV**2]], xhat0=[5.0, 8.0], P0=np.diag([1.0, 0.1]))
    fit = fit_likelihood(d, rec, ["a", "b", "k"], learn_noise=True, engine="vm")
    assert fit.success, fit.message
    truth = np.array([TA, TB, TK, 0.0, 0.0])   # noise scalings: the design's Q and R are the true ones
    assert np.all(np.abs(fit.estimate - truth) < 2 * fit.std), (fit.estimate, fit.std)
    assert fit.info["censored_samples"] == int(np.sum(y >= YMAX))
    # the EKF of min(x2, 10) as written (no censoring) is far off: its saturated branch sees no error
    plain = fit_likelihood(d, rec, ["a", "b", "k"], learn_noise=True, censor=False, starts=1, engine="vm")
    assert not np.all(np.abs(plain.estimate[:3] - truth[:3]) < 2 * np.where(np.isfinite(plain.std[:3]), plain.std[:3], 0))


def test_noise_added_after_the_limit_is_not_read_as_censoring():
    """A recording whose saturated readings scatter around the limit (y = min(x2, 10) + v) is not a clipping sensor:
    censoring it took the readings just below 10 for unsaturated levels (a 12-tank model of ours, simulated by
    nlobs.simulate, fitted a rate 40 standard errors off). The output is then the switch as written, and said so."""
    t, u, y = _tanks(1, after=True)
    assert np.sum(y > YMAX) > 50 and np.sum(np.abs(y - YMAX) < 3 * SV) > 100
    rec = Recording.from_arrays(TANKS, t, y, u)
    start = TANKS.with_params(a=0.8 * TA, b=1.2 * TB, k=0.8 * TK)
    d = nlobs.design_ekf(start, Q=np.diag([SW**2, SW**2]), R=[[SV**2]], xhat0=[5.0, 8.0], P0=np.diag([1.0, 0.1]))
    fit = fit_likelihood(d, rec, ["a", "b", "k"], learn_noise=True, engine="vm")
    assert fit.success, fit.message
    assert fit.info["censored_samples"] == 0
    assert any("not censored: y = min(x2, ymax)" in n and "reading(s) lie above its limit 10" in n for n in fit.notes)
    truth = np.array([TA, TB, TK, 0.0, 0.0])
    assert np.all(np.abs(fit.estimate - truth) < 2.5 * fit.std), ((fit.estimate - truth) / fit.std)


MOTOR = nlobs.System(states=["w", "i"], inputs=["v"], outputs=["enc", "amp"],
                     f=["(Kt*i - b*w - Fc*sign(w))/J", "(v - R*i - Kt*w)/L"], h=["w", "sat(i, -2, 2)"],
                     params={"J": 0.01, "b": 0.02, "Fc": 0.05, "Kt": 0.1, "R": 1.0, "L": 0.05})


def test_coulomb_friction_that_chatters_as_written_is_fitted_on_its_smoothed_model():
    """sign(w) at rest: on the model as written the filter's run chatters where w crosses 0 (115 RK4 sub-steps in one
    10 ms interval: the fit refused the recording), while the smoothed model's own stiffness asks for fewer than 64. The plant: RK4 at 0.5 ms of the
    exact equations, 10 ms samples with noise added to the clipped current."""
    rng = np.random.default_rng(0)   # its noise draw makes the exact run chatter (93 sub-steps from t = 2.61)
    J, b, Fc, Kt, R, L = 0.01, 0.02, 0.05, 0.1, 1.0, 0.05

    def f(x, v):
        return np.array([(Kt * x[1] - b * x[0] - Fc * np.sign(x[0])) / J, (v - R * x[1] - Kt * x[0]) / L])

    t = np.arange(1001) * 0.01
    V = lambda s: 3 * np.sin(1.3 * s) + 1.5 * np.sin(5.1 * s)  # noqa: E731
    x, X, h = np.zeros(2), np.empty((t.size, 2)), 0.0005
    for k in range(t.size):
        X[k] = x
        for j in range(20):
            s = t[k] + j * h
            k1 = f(x, V(s))
            k2 = f(x + h / 2 * k1, V(s + h / 2))
            k3 = f(x + h / 2 * k2, V(s + h / 2))
            k4 = f(x + h * k3, V(s + h))
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    y = np.c_[X[:, 0] + 0.05 * rng.standard_normal(t.size), np.clip(X[:, 1], -2, 2) + 0.02 * rng.standard_normal(t.size)]
    rec = Recording.from_arrays(MOTOR, t, y, V(t)[:, None])
    d = nlobs.design_ekf(MOTOR.with_params(b=0.03, Fc=0.02), Q=np.diag([1.0, 0.01]), R=np.diag([0.05**2, 0.02**2]),
                         xhat0=[0.5, 0.0], P0=np.diag([1.0, 0.25]))
    fit = fit_likelihood(d, rec, ["b", "Fc"], learn_noise=True, engine="vm")
    assert fit.success, fit.message
    assert np.all(np.abs(fit.estimate[:2] - [b, Fc]) < 2.5 * fit.std[:2]), ((fit.estimate[:2] - [b, Fc]) / fit.std[:2])
    assert fit.substeps <= 64
