"""Model files meet the API (issue 9 items 2 and 4): configs, unknown parameters, identifiability first,
covariances, parameter estimates with ±2σ."""

from __future__ import annotations

import sys
import textwrap

import numpy as np
import pytest

import nlobs
from nlobs import PreconditionError, loads_model
from nlobs.design import design_from_config, designs_from_file
from nlobs.design._registry import _converted

# x decays and is measured by y1; the unknown k is measured directly by y2: the filter's k-block is the
# Bayesian estimate of a constant from Gaussian samples, with a closed form to compare with.
DIRECT = textwrap.dedent('''
    name = "direct"
    states = ["x"]
    outputs = ["y1", "y2"]
    [parameters]
    k = { value = 0.0, unknown = true }
    [dynamics]
    x = "-x"
    [output]
    y1 = "x"
    y2 = "k"
    [simulation]
    t_final = 2.0
    dt = 0.01
    x0 = [1.0]
    noise = { y1 = 0.1, y2 = 0.2 }
    sample_period = 0.1
    true_parameters = { k = 1.5 }
    seed = 7
    [observers.ekf]
    kind = "ekf"
    Q = [[0.01, 0.0], [0.0, 0.0]]
    R = [[0.01, 0.0], [0.0, 0.04]]
    P0 = [[1.0, 0.0], [0.0, 4.0]]
''')

TANK = textwrap.dedent('''
    name = "tank"
    states = ["h"]
    inputs = ["u"]
    outputs = ["y"]
    [parameters]
    k = { value = 0.3, unknown = true }
    [dynamics]
    h = "u - k*sqrt(max(h, 0))"
    [output]
    y = "h"
    [simulation]
    t_final = 40.0
    dt = 0.01
    x0 = [1.0]
    inputs = { u = "0.5 + 0.3*sin(0.5*t)" }
    noise = { y = 0.01 }
    sample_period = 0.1
    true_parameters = { k = 0.5 }
    seed = 3
    [observers.ekf]
    kind = "ekf"
    Q = [[1e-4, 0], [0, 1e-6]]
    R = [[1e-4]]
    P0 = [[0.1, 0], [0, 0.1]]
    xhat0 = [0.8]
    [observers.ukf]
    kind = "ukf"
    Q = [[1e-4, 0], [0, 1e-6]]
    R = [[1e-4]]
    P0 = [[0.1, 0], [0, 0.1]]
''')


def test_the_parameter_estimate_and_its_std_are_the_bayesian_posterior():
    """Constant k, Gaussian samples y2 = k + n (σ = 0.2), prior N(0, 4): after N samples the posterior is
    mean = (Σ y / r) / (1/P0 + N/r), variance = 1 / (1/P0 + N/r) (conjugate Gaussian; independent of the filter)."""
    mf = loads_model(DIRECT)
    run = nlobs.simulate(mf)
    every = 10  # sample_period / dt
    samples = run.y[::every, 1]
    N, r, P0 = samples.size, 0.04, 4.0
    assert N == 21  # t = 0, 0.1, ..., 2.0: the filter updates at each
    var = 1.0 / (1.0 / P0 + N / r)
    mean = (samples.sum() / r) * var
    est = run.parameters("ekf")["k"]
    assert est["true"] == 1.5
    assert abs(est["estimate"] - mean) < 1e-12
    assert abs(est["std"] - np.sqrt(var)) < 1e-12
    js = run.summary_dict()["observers"]["ekf"]["parameters"]["k"]
    assert js == {"estimate": est["estimate"], "std": est["std"], "true": 1.5}
    text = str(run.summary())
    assert "k = " in text and "(2σ), true 1.5" in text


def test_default_xhat0_holds_the_initial_guesses():
    mf = loads_model(TANK)
    ekf = design_from_config(mf.observers["ekf"])
    ukf = design_from_config(mf.observers["ukf"])
    assert ekf.xhat0.tolist() == [0.8, 0.3]  # xhat0 for the state, guess appended
    assert ukf.xhat0.tolist() == [0.0, 0.3]  # none given: zeros for the states, then the guess
    full = design_from_config(mf.observer_system, "ekf", {**mf.observers["ekf"].options, "xhat0": [0.7, 0.9]})
    assert full.xhat0.tolist() == [0.7, 0.9]
    with pytest.raises(nlobs.ModelError, match="`xhat0` has 3 entries; give 1 .* or 2"):
        design_from_config(mf.observer_system, "ekf", {**mf.observers["ekf"].options, "xhat0": [1, 2, 3]})


def test_tank_recovers_k_within_two_sigma():
    run = nlobs.simulate(loads_model(TANK))
    for name in ("ekf", "ukf"):
        p = run.parameters(name)["k"]
        assert p["true"] == 0.5 and abs(p["estimate"] - 0.5) < 2 * p["std"] < 0.05
    assert run.state_names == ("h", "k") and run.estimated_params == ("k",)


def test_unidentifiable_parameter_is_refused_before_anything_runs(monkeypatch):
    text = TANK.replace('h = "u - k*sqrt(max(h, 0))"', 'h = "u - k*a*sqrt(max(h, 0))"').replace(
        "k = { value = 0.3, unknown = true }", "k = { value = 0.3, unknown = true }\na = { value = 1.0, unknown = true }")
    mf = loads_model(text, path="ka.toml")
    calls = []
    monkeypatch.setattr(sys.modules["nlobs.simulate._run"], "prepare", lambda *a, **k: calls.append(1))
    with pytest.raises(PreconditionError, match="ka.toml: the unknown parameters `k`, `a` are not identifiable from the "
                                                "output y .*rank 2 for 3 unknowns.*nothing was run"):
        designs_from_file(mf)
    with pytest.raises(PreconditionError, match="not identifiable"):
        nlobs.simulate(mf)
    with pytest.raises(PreconditionError, match="not identifiable"):
        design_from_config(mf.observers["ekf"])
    assert not calls


def test_parameter_not_excited_by_the_simulation_inputs_is_refused():
    """b u with u = 0: identifiable for generic inputs, not for the file's input (the structural test on the signal)."""
    text = TANK.replace('h = "u - k*sqrt(max(h, 0))"', 'h = "k*u - 0.2*h"').replace(
        'inputs = { u = "0.5 + 0.3*sin(0.5*t)" }', 'inputs = { u = "0" }')
    mf = loads_model(text, path="u0.toml")
    designs_from_file(mf)  # generic inputs excite k
    with pytest.raises(PreconditionError, match=r"u0.toml \[simulation\]: .*`k` is not identifiable .*with the inputs u = 0"):
        nlobs.simulate(mf)


def test_configs_go_straight_into_simulate_and_estimate():
    """Issue 9 item 4: a loaded file's observers are accepted where designs are (a TypeError before)."""
    mf = loads_model(TANK)
    cfg = mf.simulation
    run = nlobs.simulate(mf.true_system, mf.observers, t_final=cfg.t_final, dt=cfg.dt, x0=cfg.x0, inputs=dict(cfg.inputs),
                         noise=nlobs.Noise.gaussian(0.01), sampling=nlobs.Sampling(0.1), seed=3)
    assert set(run.observers) == {"ekf", "ukf"} and run.x.shape[1] == 2  # the augmented plant, true k appended
    assert abs(run.x[0, 1] - 0.5) == 0
    one = nlobs.simulate(mf, "ekf", t_final=4.0)
    assert list(one.observers) == ["ekf"] and one.t[-1] == 4.0
    rec = nlobs.Recording.from_arrays(mf.system, run.t[::10], run.y[::10], run.u[::10], x=run.x[::10, :1])
    est = nlobs.estimate(mf, rec, max_step=0.01)  # the UKF covariance ODE needs steps below the 0.1 s sampling
    assert set(est.observers) == {"ekf", "ukf"}
    assert est.error("ekf").shape == (rec.t.size, 1)  # the truth has the state only: errors over it
    p = est.parameters("ekf")["k"]
    assert p["true"] is None and abs(p["estimate"] - 0.5) < 0.05 and p["std"] > 0


def test_covariance_hook():
    s = nlobs.System(states=["x1", "x2"], f=["x2", "-x1 + u*x2"], inputs=["u"], outputs=["y"], h=["x1"])
    P0 = np.array([[2.0, 0.3], [0.3, 1.0]])
    for d in (nlobs.design_ekf(s, Q=np.eye(2), R=[[1.0]], P0=P0), nlobs.design_ukf(s, Q=np.eye(2), R=[[1.0]], P0=P0),
              nlobs.design_kalman_bucy(s, Q=np.eye(2), R=[[1.0]], P0=P0), nlobs.design_kalman_like(s, Q=np.eye(2), P0=P0)):
        z0 = nlobs.Observer(d).initial_state([0.1, 0.2])
        assert np.allclose(np.array(d.covariance(z0)), P0), d.method
    # forgetting δ > 0 inflates M: it is not a covariance, and no ±2σ is reported from it
    assert nlobs.design_kalman_like(s, Q=np.eye(2), delta=1.0).covariance is None
    assert nlobs.design_luenberger is not None and nlobs.design_output_injection(
        nlobs.System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1"]), poles=[-1, -2]).covariance is None


@pytest.mark.parametrize("option, value, expected", [
    ("perturbation", "x1", ["x1"]),  # Sequence[ExprLike] | None: one expression, not the characters 'x' and '1'
    ("P", "x1", "x1"),  # Any: left alone (the design says what it wants)
    ("perturbation", ["x1"], ["x1"]),
])
def test_a_string_where_a_list_is_expected_is_a_one_element_list(option, value, expected):
    assert _converted(nlobs.design.DESIGNS["banks"], {option: value})[option] == expected
    assert _converted(nlobs.design.DESIGNS["ekf"], {"mode": "continuous"})["mode"] == "continuous"  # Literal


def test_single_string_options_end_to_end():
    """A one-state custom observer written with strings, as a file writes a one-element list."""
    text = textwrap.dedent('''
        states = ["x"]
        outputs = ["y"]
        [dynamics]
        x = "-x"
        [output]
        y = "x"
        [observers.own]
        kind = "custom"
        states = "xh"
        flow = "-xh + 2*(y - xh)"
    ''')
    d = design_from_config(loads_model(text).observers["own"])
    assert d.z_names == ("xh",)


def test_unknown_option_and_kind_messages_are_short():
    mf = loads_model(TANK)
    with pytest.raises(nlobs.ModelError, match="unknown option `Qq` for kind 'ekf'"):
        design_from_config(mf.observer_system, "ekf", {"Qq": 1})
    with pytest.raises(nlobs.ModelError) as info:
        design_from_config(mf.observer_system, "x" * 100_000, {})
    assert len(str(info.value)) < 600
