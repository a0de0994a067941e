"""The advisor on a discrete-time model: the kinds that run on maps (the Kalman family, the particle filter, MHE) are
tuned and run, the others are refused as continuous-time only, and a linear map gets poles inside the unit circle."""

from __future__ import annotations

import numpy as np

import nlobs

RICKER = """
name = "ricker"
time = "discrete"
sample_time = 1.0
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
t_final = 60
x0 = [3.0]
inputs = { u = "0.5 + 0.3*sin(0.2*t)" }
noise = { y = 0.05 }
true_parameters = { r = 1.4 }
seed = 1
"""


def test_a_map_is_advised_with_the_kinds_that_run_on_maps(tmp_path):
    path = tmp_path / "ricker.toml"
    path.write_text(RICKER)
    adv = nlobs.advise(nlobs.load_model(path), run=True)
    applies = {c.kind for c in adv.candidates if c.applies}
    assert applies == {"ekf", "ukf", "mhe", "srukf", "srekf", "iekf", "pf"}
    assert adv.candidate("high_gain").why == "continuous-time only (the model is discrete-time)"
    assert "mode" not in adv.candidate("ekf").options   # a map's EKF is the discrete-time filter
    assert "bounds" not in adv.candidate("srukf").options
    est = {s.kind: s for s in adv.scores}
    for k in applies:
        assert est[k].status == "ok" and est[k].convergence_time is not None, (k, est[k])
        r_hat = adv.run.observers[k].xhat[-1, 1]
        assert abs(r_hat - 1.4) < 0.05, (k, r_hat)     # the growth rate recovered (true 1.4, guess 1.2)
    assert adv.forms == ()                              # the ODE forms are not shown for a map


def test_a_linear_map_gets_poles_inside_the_unit_circle():
    lin = nlobs.System(states=["x1", "x2"], f=["0.9*x1 + 0.2*x2", "-0.1*x1 + 0.95*x2 + u"], inputs=["u"], outputs=["y"],
                       h=["x1"], time="discrete", sample_time=0.1)
    from nlobs.model import SimulationConfig

    adv = nlobs.advise(lin, simulation=SimulationConfig(t_final=5.0, x0=(1.0, -1.0)), kinds=["luenberger"])
    c = adv.candidate("luenberger")
    assert c.applies and all(0 < p < 1 for p in c.options["poles"])
    assert np.max(np.abs(c.design.certificate.values["eigenvalues"])) < 1
