"""Convergence time: a property of the observer that agrees with the error curve, whatever the run length."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import Noise, Sampling, System, design_ekf, design_output_injection, simulate
from nlobs.simulate import CONVERGENCE_RULE, convergence_band, convergence_time, error_metrics

# the README's pendulum: injection and EKF, noise σ = 0.01 sampled at 100 Hz
PEND = System(states=["x1", "x2"], f=["x2", "-a1*sin(x1) - a2*x2 + b*u"], inputs=["u"], outputs=["y"], h=["x1"],
              params={"a1": 9.81, "a2": 0.5, "b": 1.0}, name="pendulum")
DESIGNS = {"injection": design_output_injection(PEND, poles=[-2, -3]),
           "ekf": design_ekf(PEND, Q=[[1e-3, 0], [0, 1e-2]], R=[[1e-4]])}


def _run(t_final: float):
    return simulate(PEND, DESIGNS, t_final=t_final, dt=1e-3, x0=[1, 0], inputs={"u": "sin(t)"}, noise=Noise.gaussian(0.01),
                    sampling=Sampling(0.01), seed=1)


@pytest.fixture(scope="module")
def runs():
    return {T: _run(T) for T in (20.0, 200.0)}


def test_the_readme_pendulum_converges_where_its_error_curve_settles_for_any_run_length(runs):
    """Before: the EKF reported 19.8 s for t_final = 20 and 199 s for t_final = 200 (2 % of the initial error lies
    below its noise floor). Its error is corrected by the first samples: within 0.3 s it is in its noise floor."""
    short, long_ = runs[20.0].metrics("ekf"), runs[200.0].metrics("ekf")
    for m in (short, long_):
        assert m.convergence_time is not None and m.convergence_time < 0.3
        assert m.tol_basis == "steady" and m.initial_error == pytest.approx(1.0)  # ‖x̂(0⁻) − x(0)‖ = |0 − 1|
    assert abs(short.convergence_time - long_.convergence_time) < 0.1
    # the old criterion is below the floor: the noise alone crosses 2 % of the initial error late in the run
    e = runs[200.0].error_norm("ekf")
    assert e[runs[200.0].t > 150].max() > 0.02
    # the output-injection observer converges in about 2.5-3 s (poles -2, -3: the slow mode e^{-2t} from 1 to ~0.03)
    a, b = runs[20.0].metrics("injection"), runs[200.0].metrics("injection")
    assert 2.0 < a.convergence_time < 3.5 and 2.0 < b.convergence_time < 3.5
    assert abs(a.convergence_time - b.convergence_time) < 0.3


def test_the_convergence_time_agrees_with_the_error_curve(runs):
    run = runs[20.0]
    for name in run.observers:
        m = run.metrics(name)
        e, t = run.error_norm(name), run.t
        after = t >= m.convergence_time
        assert np.all(e[after] <= m.tol)  # stays within the band from then on
        if m.convergence_time > t[0]:
            assert e[np.flatnonzero(after)[0] - 1] > m.tol  # and was outside just before
        # the band sits above the steady-state floor (twice its largest value over the last 20 %)...
        tail = e[t >= 0.8 * t[-1]]
        assert m.tol >= min(2 * tail.max(), 0.2 * m.initial_error) - 1e-15
        # ... and well below where the observer started
        assert m.tol <= 0.2 * m.initial_error


def test_known_signals():
    """Decaying exponentials with and without a floor, where the answer follows from the definition by hand."""
    for T in (10.0, 100.0):
        t = np.linspace(0, T, int(T * 1000) + 1)
        # noise-free: the classical 2 % settling time ln(50)/r, whatever T
        m = error_metrics(t, 3.0 * np.exp(-2.0 * t))
        assert m.tol == pytest.approx(0.06) and m.tol_basis == "initial" and m.steady_error is None
        assert m.convergence_time == pytest.approx(np.log(50) / 2, abs=1e-3)
        # a floor of peak 0.05 (5 % of e0 = 1; plus e^{-8} = 3e-4 in the tail of the short run): band ~0.1;
        # e(t) <= 0.1 once e^{-t} <= 0.05 (t = ln 20 = 3.00) at the latest, and not while e^{-t} > 0.1 (t < ln 10)
        e = np.exp(-t) + 0.05 * np.abs(np.sin(37.0 * t))
        m = error_metrics(t, e)
        assert m.steady_error == pytest.approx(0.05, rel=1e-2) and m.tol == pytest.approx(0.1, rel=1e-2)
        assert np.log(10) <= m.convergence_time <= np.log(20) + 0.01
        # an observer that stalls at half its initial error never converges (the band is capped at 20 %)
        stall = error_metrics(t, 0.5 + 0.5 * np.exp(-t))
        assert stall.convergence_time is None and stall.tol_basis == "cap" and stall.tol == pytest.approx(0.2)
    # e(0⁻), the error before the first update, sets the relative band even when the update removes most of it
    t = np.linspace(0, 10, 10001)
    m = error_metrics(t, 0.001 * np.exp(-t) + 0.01 * np.exp(-0.5 * t), e0=1.0)
    assert m.tol == pytest.approx(0.02) and m.convergence_time == 0.0


def test_the_steady_state_needs_a_settled_tail():
    """An error still decaying at the end of the run has no noise floor yet: only the relative band applies."""
    t = np.linspace(0, 10, 10001)
    e = np.exp(-0.3 * t)  # e(8) = 0.09, still decreasing
    band = convergence_band(t, e)
    assert band.steady_error is None and band.basis == "initial" and band.tol == pytest.approx(0.02)
    assert error_metrics(t, e).convergence_time is None


def test_an_absolute_tolerance_replaces_the_rule():
    t = np.linspace(0, 10, 1001)
    e = np.exp(-t)
    m = error_metrics(t, e, tol=0.05)
    assert m.tol == 0.05 and m.tol_basis == "tol" and m.convergence_time == pytest.approx(np.log(20), abs=0.01)
    assert convergence_time(t, np.ones_like(t), 0.5) is None
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="`tol` must be a positive number"):
            error_metrics(t, e, tol=bad)


def test_the_definition_travels_with_the_results(runs):
    run = runs[20.0]
    d = run.summary_dict()
    assert d["convergence_rule"] == CONVERGENCE_RULE and "before the first update" in CONVERGENCE_RULE
    entry = d["observers"]["ekf"]
    assert {"convergence_time", "tol", "tol_basis", "initial_error", "steady_error"} <= set(entry)
    assert entry["tol_basis"] == "steady"
    text = str(run.summary())
    assert "band" in text and "2 × steady-state error" in text
    assert "stays within `tol`" in run.summary_dict(tol=0.1)["convergence_rule"]


def test_the_convergence_time_is_counted_from_the_start_of_a_recording():
    t = np.linspace(0, 10, 1001)
    e = np.exp(-t)
    assert error_metrics(t + 1000.0, e).convergence_time == pytest.approx(error_metrics(t, e).convergence_time, abs=1e-9)
    assert convergence_time(t + 1000.0, e, 0.02) == pytest.approx(1000.0 + np.log(50), abs=0.01)  # the time itself
