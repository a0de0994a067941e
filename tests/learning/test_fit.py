"""Batch parameter estimation by simulation-error least squares: recovery, standard errors, identifiability."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from nlobs import DataError, ModelError, Recording, System, fit_parameters

# first-order lag x' = -a x + b u, y = x: the data come from SciPy's integrator with a held square-wave input
LAG = System(states=["x"], f=["-a*x + b*u"], inputs=["u"], outputs=["y"], h=["x"], params={"a": 1.0, "b": 1.0}, name="lag")
A, B, X0, SIGMA = 2.0, 3.0, 0.5, 0.02
T = np.round(np.arange(0, 12.0001, 0.1), 10)
U = np.sign(np.sin(0.9 * T) + 1e-9)


def _truth() -> np.ndarray:
    x, out = np.array([X0]), [X0]
    for k in range(T.size - 1):
        x = solve_ivp(lambda _t, z: -A * z + B * U[k], (T[k], T[k + 1]), x, rtol=1e-12, atol=1e-14).y[:, -1]
        out.append(x[0])
    return np.array(out)


CLEAN = _truth()


def _recording(seed: int) -> Recording:
    y = CLEAN + SIGMA * np.random.default_rng(seed).standard_normal(T.size)
    return Recording.from_arrays(LAG, T, y, U)


def test_noise_free_data_give_the_true_parameters():
    rec = Recording.from_arrays(LAG, T, CLEAN, U)
    res = fit_parameters(LAG, rec, ["a", "b"], x0=[X0], max_step=0.01)
    assert res.success and np.allclose(res.estimate, [A, B], rtol=1e-6)  # RK4 error with h = 0.01, ~1e-9
    assert res.system.params["a"] == pytest.approx(A, rel=1e-6) and res.integration_change < 1e-8
    assert max(res.rmse.values()) < 1e-7


def test_standard_errors_match_the_spread_over_noise_draws():
    """The Jacobian's standard errors against the empirical spread of the estimates over 40 noise seeds."""
    fits = [fit_parameters(LAG, _recording(s), ["a", "b"], x0=[X0], max_step=0.05) for s in range(40)]
    est = np.array([f.estimate for f in fits])
    std = np.array([f.std for f in fits])
    spread = est.std(axis=0, ddof=1)
    assert np.all(np.abs(est.mean(axis=0) - [A, B]) < 3 * spread / np.sqrt(40) + 1e-3)  # unbiased
    # the std of a sample std over 40 draws is ~11 %: agree within 35 %
    assert np.all(np.abs(std.mean(axis=0) / spread - 1) < 0.35), (std.mean(axis=0), spread)
    one = fits[0]
    assert one.covariance.shape == (2, 2) and np.allclose(np.sqrt(np.diag(one.covariance)), one.std)
    assert one.rmse["y"] == pytest.approx(SIGMA, rel=0.2)
    d = one.to_dict()
    assert set(d["parameters"]) == {"a", "b"} and d["parameters"]["a"]["std"] == pytest.approx(one.std[0])


def test_unknown_initial_state_and_bounds():
    rec = _recording(1)
    res = fit_parameters(LAG, rec, ["a"], x0=[0.0], fit_x0=["x"], initial={"a": 0.5})
    assert res.names == ("a", "x(t0)") and res.initial.tolist() == [0.5, 0.0]
    assert abs(res.estimate[1] - X0) < 4 * res.std[1] and abs(res.x0[0] - res.estimate[1]) == 0
    # a bound that excludes the truth holds the estimate on the bound
    capped = fit_parameters(LAG, rec, ["a", "b"], x0=[X0], bounds={"a": (None, 1.5)}, initial={"a": 1.0})
    assert capped.estimate[0] == pytest.approx(1.5, abs=1e-6)
    text = capped.summary()
    assert "a " in text and "output RMS error" in text and "halving the step" in text


def test_a_product_of_parameters_is_not_identifiable():
    prod = System(states=["x"], f=["-a*c*x + b*u"], inputs=["u"], outputs=["y"], h=["x"], params={"a": 1.0, "b": 1.0, "c": 1.0})
    res = fit_parameters(prod, Recording.from_arrays(prod, T, CLEAN, U), ["a", "b", "c"], x0=[X0], max_step=0.02)
    assert res.unidentifiable and np.all(np.isnan(res.std))
    assert "changing (a, c) in proportion to (+0.71, -0.71)" in res.unidentifiable[0] or \
        "changing (c, a) in proportion to (+0.71, -0.71)" in res.unidentifiable[0]
    assert res.estimate[0] * res.estimate[2] == pytest.approx(A, rel=1e-5)  # the product is determined
    assert "NOT identifiable" in res.summary()


def test_bad_arguments():
    rec = _recording(2)
    with pytest.raises(ModelError, match="'k' is not a parameter of 'lag'; its parameters: a, b"):
        fit_parameters(LAG, rec, ["k"], x0=[X0])
    with pytest.raises(ModelError, match="nothing to fit"):
        fit_parameters(LAG, rec, [], x0=[X0])
    with pytest.raises(ModelError, match="give `x0`"):
        fit_parameters(LAG, rec, ["a"])
    with pytest.raises(ModelError, match="not inside its bounds"):
        fit_parameters(LAG, rec, ["a"], x0=[X0], bounds={"a": (2.5, None)})
    with pytest.raises(ModelError, match="`initial` names 'z'"):
        fit_parameters(LAG, rec, ["a"], x0=[X0], initial={"z": 1})
    with pytest.raises(ValueError, match="`max_step` must be a positive number"):
        fit_parameters(LAG, rec, ["a"], x0=[X0], max_step=0)
    empty = Recording.from_arrays(LAG, T, np.full(T.size, np.nan), U)
    with pytest.raises(DataError, match="no measured output sample"):
        fit_parameters(LAG, empty, ["a"], x0=[X0])
    blow = System(states=["x"], f=["a*x**2"], inputs=["u"], outputs=["y"], h=["x"], params={"a": 1.0})
    with pytest.raises(DataError, match="the simulation from the initial guess .* is not finite"):
        fit_parameters(blow, Recording.from_arrays(blow, T, CLEAN, U), ["a"], x0=[5.0])
