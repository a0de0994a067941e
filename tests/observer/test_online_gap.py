"""An online observer fed after a long gap integrates across it (issue 20 audit: one RK4 step over 100 s
returned |x̂| = 9·10⁵ with no error)."""

from __future__ import annotations

import numpy as np
import pytest

import nlobs
from nlobs import DataError, System

PEND = System(states=["x1", "x2"], inputs=["u"], outputs=["y"], f=["x2", "-9.81*sin(x1) - 0.5*x2 + u"], h=["x1"])


def _ekf():
    return nlobs.design_ekf(PEND, R=[[1e-4]], Q=np.diag([1e-4, 1e-2]), xhat0=[0.5, 0.0])


def _after(gap, **kw):
    o = nlobs.Observer(_ekf()).start(**kw)
    o.update(0.0, u=[0.0], y=[1.0])
    return o.update(gap, u=[0.0], y=[1.0])


def test_a_100_s_gap_is_integrated_not_stepped_over():
    # reference: the same interval with RK4 steps of 1 ms (the flow's rate is ~5/s: converged to ~1e-9)
    ref = _after(100.0, max_step=1e-3)
    got = _after(100.0)
    assert np.all(np.abs(got) < 2)                               # was 9.1e5
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-6)
    # and the online observer agrees with the recorded-data runner on the same two samples (same step rule)
    rec = nlobs.Recording.from_arrays(PEND, [0.0, 100.0], [[1.0], [1.0]], [[0.0], [0.0]])
    np.testing.assert_allclose(got, nlobs.estimate(_ekf(), rec).observers["ekf"].xhat[-1], rtol=0, atol=1e-9)


def test_a_gap_too_long_to_integrate_is_refused_by_name():
    with pytest.raises(DataError, match=r"the gap from t = 0 to t = 1e\+06 .* needs more than 1e\+06 RK4 steps .*"
                                        r"Start the observer again"):
        _after(1e6)


def test_short_intervals_keep_one_step_per_sample():
    # a slow filter (rate ≈ √9.81 ≈ 3.1/s) sampled at 100 Hz: h·ρ <= 1 already, so the result is one RK4 step, as before
    d = nlobs.design_ekf(PEND, R=[[1.0]], Q=np.diag([1e-4, 1e-2]), P0=1e-2 * np.eye(2), xhat0=[0.5, 0.0])
    obs = nlobs.Observer(d)
    z0 = obs.initial_state()
    one = obs.step(0.0, obs.update(0.0, z0, [0.0], [1.0]), 0.01, [0.0], [1.0])   # the sample update at 0, then the flow
    o = obs.start()
    o.update(0.0, u=[0.0], y=[1.0])
    o.update(0.01, u=[0.0], y=[1.0])
    np.testing.assert_array_equal(o.z, obs.update(0.01, one, [0.0], [1.0]))


def test_predict_then_update_is_update_and_P_is_the_filters_covariance():
    d = _ekf()
    a, b = nlobs.Observer(d).start(), nlobs.Observer(d).start()
    for o in (a, b):
        o.update(0.0, u=[0.0], y=[1.0])
    prior = a.predict(0.05)
    assert a.t == 0.05 and np.all(np.isfinite(prior))
    np.testing.assert_array_equal(a.update(0.05, u=[0.0], y=[0.9]), b.update(0.05, u=[0.0], y=[0.9]))
    # P read from z: the EKF's z = (x̂, P column-major), so the covariance is z[2:] reshaped
    np.testing.assert_array_equal(a.P, b.z[2:].reshape(2, 2, order="F"))
    assert np.allclose(a.P, a.P.T) and np.all(np.linalg.eigvalsh(a.P) > 0)
    with pytest.raises(DataError, match="after the last one"):
        a.predict(0.05)
    lue = nlobs.design_luenberger(nlobs.System(states=["x"], outputs=["y"], f=["-x"], h=["x"]), poles=[-2.0])
    assert nlobs.Observer(lue).start().P is None
