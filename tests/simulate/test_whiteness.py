"""Innovations on recorded data and their whiteness (Ljung–Box)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from nlobs import Noise, Observer, Recording, Sampling, System, design_ekf, design_output_injection, estimate, simulate
from nlobs.engine import compile_system
from nlobs.simulate import ljung_box

PEND = System(states=["x1", "x2"], f=["x2", "-a*sin(x1) - 0.5*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"],
              params={"a": 9.81}, name="pend")


def _q_by_hand(r: np.ndarray, h: int) -> float:
    """Ljung & Box (1978): Q = n(n+2) Σ_{k=1..h} r_k² / (n − k), r_k = Σ_t (e_t − ē)(e_{t−k} − ē) / Σ_t (e_t − ē)²."""
    n = len(r)
    m = sum(r) / n
    den = sum((v - m) ** 2 for v in r)
    q = 0.0
    for k in range(1, h + 1):
        rk = sum((r[i] - m) * (r[i - k] - m) for i in range(k, n)) / den
        q += rk * rk / (n - k)
    return n * (n + 2) * q


def test_statistic_and_p_value_by_hand():
    r = np.random.default_rng(3).standard_normal(60)
    w = ljung_box(r, lags=5)
    assert w.q == pytest.approx(_q_by_hand(r.tolist(), 5), rel=1e-12)
    assert w.p_value == pytest.approx(stats.chi2.sf(w.q, 5), rel=1e-12)
    assert w.lags == 5 and w.n == 60 and w.rms == pytest.approx(np.sqrt(np.mean(r**2)))
    assert ljung_box(r).lags == 10  # default min(10, n // 5)
    short = ljung_box(r[:8])
    assert short.q is None and short.white is None and "too few samples" in str(short)
    with pytest.raises(ValueError, match="`lags` must be between 1 and"):
        ljung_box(r, lags=0)


def test_white_noise_is_accepted_at_the_level_and_correlated_noise_is_rejected():
    rng = np.random.default_rng(0)
    white = [ljung_box(rng.standard_normal(400)).white for _ in range(400)]
    rejected = 400 - sum(white)
    # the false rejection rate is the level, 5 % (binomial 400 x 0.05 = 20, 3σ = 13)
    assert 7 <= rejected <= 33
    e = rng.standard_normal(400)
    ar = np.empty(400)
    ar[0] = e[0]
    for k in range(1, 400):
        ar[k] = 0.5 * ar[k - 1] + e[k]
    assert ljung_box(ar).white is False and ljung_box(ar).p_value < 1e-6


@pytest.fixture(scope="module")
def recording():
    run = simulate(PEND, t_final=20.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": "sin(t)"}, noise=Noise.gaussian(0.01),
                   sampling=Sampling(0.02), seed=5)
    return Recording.from_run(run, every=20)


def test_innovations_are_the_prior_prediction_errors(recording):
    rec = Recording(recording.t, recording.u, recording.y, recording.input_names, recording.output_names, source="no states")
    d = design_ekf(PEND, Q=np.diag([1e-6, 1e-4]), R=[[1e-4]])
    res = estimate(d, rec)
    assert res.x is None
    inn = res.innovations()
    # independently: one step of the observer from the previous posterior, then y_k − h(x̂_k⁻)
    obs, (_, h) = Observer(d), compile_system(PEND).bind()
    z = res.observers["ekf"].z
    for k in (1, 50, 400, len(rec.t) - 1):
        zp = obs.step(rec.t[k - 1], z[k - 1], rec.t[k] - rec.t[k - 1], rec.u[k - 1], rec.y[k - 1])
        xp = obs.estimate(rec.t[k], zp, rec.u[k], rec.y[k - 1])
        assert inn[k, 0] == pytest.approx(rec.y[k, 0] - float(h(rec.t[k], xp, rec.u[k])), abs=1e-12)
    assert inn[0, 0] == pytest.approx(rec.y[0, 0] - 0.0)  # against the initial estimate x̂0 = 0
    # a well-tuned filter on its own model leaves white innovations of the noise's size
    w = res.whiteness()["y"]
    assert w.white and 0.009 < w.rms < 0.02
    # the same filter on a model with the wrong gravity leaves correlated innovations
    wrong = design_ekf(PEND.with_params(a=8.0), Q=np.diag([1e-6, 1e-4]), R=[[1e-4]])
    assert estimate(wrong, rec).whiteness()["y"].white is False
    # the summary of a recording without states is the innovations table, not an empty one
    text = str(res.summary())
    assert "Ljung-Box" in text and "ekf" in text and "(no true state)" not in text
    j = res.summary_dict()["observers"]["ekf"]
    assert j["innovations"]["y"]["white"] is True and set(j["estimate"]) == {"x1", "x2"}


def test_missing_samples_have_no_innovation(recording):
    y = recording.y.copy()
    y[[10, 11]] = np.nan
    rec = Recording.from_arrays(PEND, recording.t, y, recording.u)
    res = estimate(design_output_injection(PEND, poles=[-2, -3]), rec, on_missing="skip")
    inn = res.innovations()
    assert np.isnan(inn[[10, 11], 0]).all() and np.isfinite(np.delete(inn[:, 0], [10, 11])).all()
    assert res.whiteness(burn_in=0)["y"].n == len(rec.t) - 2 and res.whiteness()["y"].n == len(rec.t) - 101  # the gap is in the burn-in
    with pytest.raises(ValueError, match="innovations are recorded by nlobs.estimate"):
        simulate(PEND, {"o": design_output_injection(PEND, poles=[-2, -3])}, t_final=1.0, dt=0.01, x0=[1, 0]).innovations()
