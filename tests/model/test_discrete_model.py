"""Discrete-time models (issue 21): the time base is declared, checked, and never read as an ODE."""

from __future__ import annotations

import numpy as np
import pytest

import nlobs
from nlobs.errors import ModelError, ModelFileError, PreconditionError, ShapeError

RICKER = """
name = "ricker"
time = "discrete"
sample_time = 0.5
states = ["N"]
inputs = ["u"]
outputs = ["y"]
[parameters]
r = { value = 1.2, unknown = true }
K = 10.0
[dynamics]
N = "N*exp(r*(1 - N/K)) - u"
[output]
y = "N"
[simulation]
t_final = 10
x0 = [3.0]
inputs = { u = "0.5" }
"""


def test_a_discrete_file_is_a_map_and_its_parameters_stay_constant():
    mf = nlobs.loads_model(RICKER)
    assert mf.system.is_discrete and mf.system.sample_time == 0.5
    aug = mf.observer_system
    assert aug.is_discrete and aug.states == ("N", "r") and str(aug.f[1]) == "r"     # r[k+1] = r, not r' = 0
    assert "N[k+1] = " in str(mf.system)
    assert not nlobs.loads_model(RICKER.replace('time = "discrete"\nsample_time = 0.5\n', "")).system.is_discrete


@pytest.mark.parametrize("edit, key, message", [
    (('time = "discrete"', 'time = "hybrid"'), "time", 'must be "continuous" or "discrete"'),
    (('time = "discrete"\n', ""), "sample_time", 'needs time = "discrete" as well'),
    (("sample_time = 0.5", "sample_time = -1"), "sample_time", "positive and finite"),
    (("sample_time = 0.5", 'sample_time = "fast"'), "sample_time", "a number of seconds per step"),
    (("t_final = 10", "t_final = 10.2"), "simulation.t_final", "whole number of steps"),
    (("t_final = 10", "t_final = 10\ndt = 0.01"), "simulation.dt", "steps by its `sample_time`"),
])
def test_time_base_mistakes_are_one_line_errors_naming_the_key(edit, key, message):
    with pytest.raises(ModelFileError) as e:
        nlobs.loads_model(RICKER.replace(*edit))
    assert f"key `{key}`" in str(e.value) and message in str(e.value) and "\n" not in str(e.value)


def test_python_api_and_pickling_keep_the_time_base():
    import pickle

    s = nlobs.System(states=["x"], f=["0.5*x + u"], inputs=["u"], outputs=["y"], h=["x"], time="discrete", sample_time=0.1)
    for other in (s.with_params(), s.with_name("other"), pickle.loads(pickle.dumps(s))):
        assert other.is_discrete and other.sample_time == 0.1
    c = nlobs.System(states=["x"], f=["0.5*x + u"], inputs=["u"], outputs=["y"], h=["x"])
    assert c != s and c.key != s.key
    with pytest.raises(ModelError, match="sample_time"):
        nlobs.System(states=["x"], f=["x"], outputs=["y"], h=["x"], sample_time=0.1)


def test_continuous_only_kinds_refuse_a_map_and_name_the_ones_that_run():
    s = nlobs.loads_model(RICKER).observer_system
    with pytest.raises(PreconditionError, match=r"continuous-time only.*discrete-time model.*ekf, .*ukf.*mhe"):
        nlobs.design_high_gain(s, theta=2.0)
    with pytest.raises(PreconditionError, match="continuous-time only"):
        nlobs.design_kalman_bucy(s)
    assert nlobs.design_mhe(s, horizon=5).system.is_discrete      # MHE runs on maps (issue 21)


def test_simulate_refuses_a_continuous_observer_on_a_map_and_a_dt():
    mf = nlobs.loads_model(RICKER)
    cont = nlobs.System(states=["N", "r"], f=["0", "0"], inputs=["u"], outputs=["y"], h=["N"], params={"K": 10.0})
    ekf_c = nlobs.design_ekf(cont, Q=np.eye(2), R=[[1.0]])
    with pytest.raises(ModelError, match="designed for a continuous-time model"):
        nlobs.simulate(mf.true_system, {"c": ekf_c}, t_final=1, x0=[1.0])
    with pytest.raises(ShapeError, match="`dt` = 0.01 does not apply"):
        nlobs.simulate(mf.system, t_final=1, dt=0.01, x0=[1.0])
    with pytest.raises(ShapeError, match="whole number of steps"):
        nlobs.simulate(mf.system, t_final=1.2, x0=[1.0])
