"""KKL observer with a learned left inverse (beyond 004 Proposition 1; Andrieu-Praly dimensions)."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import PreconditionError, ShapeError, System, design_kkl_learned, simulate

VDP = System(states=["x1", "x2"], f=["x2", "(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], name="vdp")


def test_learned_map_fits_held_out_data_and_the_observer_converges():
    d = design_kkl_learned(VDP, region=[(-3, 3), (-3, 3)], degree=3, n_trajectories=40, t_final=24.0, dt=0.01, seed=1)
    v = d.certificate.values
    assert v["n_xi"] == 3 and v["held_out_rms"] < 5e-3
    run = simulate(VDP, {"kkl": d}, t_final=25.0, dt=1e-2, x0=[1.5, 0.5])
    e = run.error_norm("kkl")
    assert e[0] > 0.5 and e[-200:].max() < 1e-2           # from a large error to the fit accuracy on the limit cycle


def test_same_seed_same_observer():
    kw = dict(region=[(-2, 2), (-2, 2)], degree=2, n_trajectories=8, t_final=20.0, dt=0.02)
    a, b = design_kkl_learned(VDP, **kw, seed=4), design_kkl_learned(VDP, **kw, seed=4)
    z = np.array([0.1, -0.2, 0.3])
    assert np.array_equal(np.asarray(a.output(0.0, z, [], [0.5])), np.asarray(b.output(0.0, z, [], [0.5])))


@pytest.mark.parametrize("kw, err, match", [
    (dict(region=[(-1, 1)]), ShapeError, "region"),
    (dict(region=[(-1, 1), (1, -1)]), ShapeError, "low < high"),
    (dict(region=[(-1, 1), (-1, 1)], eigenvalues=[-1, -2, 1]), PreconditionError, "distinct and negative"),
    (dict(region=[(-1, 1), (-1, 1)], eigenvalues=[-1, -2]), ShapeError, "n \\+ 1 = 3"),
    (dict(region=[(-1, 1), (-1, 1)], burn_in=50.0), PreconditionError, "burn_in"),
    (dict(region=[(-1, 1), (-1, 1)], held_out=1.0), PreconditionError, "held_out"),
])
def test_bad_options(kw, err, match):
    with pytest.raises(err, match=match):
        design_kkl_learned(VDP, **kw)


def test_inputs_must_be_fixed_for_training():
    s = System(states=["x1", "x2"], f=["x2", "-x1 + u"], outputs=["y"], h=["x1"], inputs=["u"])
    with pytest.raises(PreconditionError, match="one constant per input"):
        design_kkl_learned(s, region=[(-1, 1), (-1, 1)])
    d = design_kkl_learned(s, region=[(-1, 1), (-1, 1)], inputs={"u": 0.0}, eigenvalues=[-2, -3, -4], degree=1,
                           n_trajectories=8, t_final=14.0, dt=0.02)
    assert d.certificate.values["held_out_rms"] < 1e-6      # linear system: φ is linear, degree 1 is exact
