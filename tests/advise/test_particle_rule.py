"""The advisor's rule for the particle filter: an output symmetric under a sign flip of a state (h(x) = h(σx) at
generic points) makes the posterior multimodal, and the particle filter is marked as the choice."""

import pytest

import nlobs
from nlobs.design.kalman._pf import output_symmetries

BIMODAL = """
name = "bimodal"
states = ["x1", "x2"]
outputs = ["y"]
[dynamics]
x1 = "x2"
x2 = "-x1 + 0.6"
[output]
y = "{h}"
[simulation]
t_final = 10.0
dt = 0.01
x0 = [1.5, 0.0]
noise = {{ y = 0.05 }}
sample_period = 0.05
"""


def _sys(*h):
    return nlobs.System(states=["x1", "x2"], f=["x2", "-x1"], outputs=[f"y{i}" for i in range(len(h))], h=list(h))


@pytest.mark.parametrize("h, flips", [
    (["x1**2"], [("x1",)]),
    (["x1"], []),
    (["x1*x2"], [("x1", "x2")]),                        # only the joint flip
    (["sqrt(x1**2 + x2**2)"], [("x1",), ("x2",), ("x1", "x2")]),   # a range
    (["cos(x1) + x2"], [("x1",)]),
    (["x1**2", "x1 + x2"], []),                          # a second output breaks it
])
def test_output_symmetries(h, flips):
    assert output_symmetries(_sys(*h)) == flips


def test_symmetric_output_marks_the_particle_filter_as_the_choice(tmp_path):
    path = tmp_path / "bimodal.toml"
    path.write_text(BIMODAL.format(h="x1**2"))
    adv = nlobs.advise(nlobs.load_model(path), kinds=["ekf", "pf"])
    assert adv.choice is not None and adv.choice[0] == "pf"
    pf = adv.candidate("pf")
    assert pf.applies and "symmetric" in pf.why and "x1 → −x1" in pf.why and "the choice here" in pf.why
    assert "choice: pf" in str(adv) and adv.to_dict()["choice"]["kind"] == "pf"


def test_no_choice_without_a_symmetry(tmp_path):
    path = tmp_path / "plain.toml"
    path.write_text(BIMODAL.format(h="x1"))
    adv = nlobs.advise(nlobs.load_model(path), kinds=["ekf", "pf"])
    assert adv.choice is None and adv.candidate("pf").applies and "no sign symmetry" in adv.candidate("pf").why


def test_a_tiny_R_marks_the_square_root_ukf_as_the_choice(tmp_path):
    path = tmp_path / "accurate.toml"
    path.write_text(BIMODAL.format(h="x1").replace("y = 0.05", "y = 1e-5"))  # R = σ² = 1e-10
    adv = nlobs.advise(nlobs.load_model(path), kinds=["ukf", "srukf", "srekf"])
    assert adv.choice is not None and adv.choice[0] == "srukf" and "loses definiteness" in adv.choice[1]
    assert "the square-root form is the choice here" in adv.candidate("srekf").why
    path.write_text(BIMODAL.format(h="x1"))  # σ = 0.05: no choice made
    assert nlobs.advise(nlobs.load_model(path), kinds=["ukf", "srukf"]).choice is None
