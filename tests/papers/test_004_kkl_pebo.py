"""Acceptance, M8 #8: 004_f1e237c45ff4719e.txt §V-A, example (31), facts F3-F4, observer (32)-(37)."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import PreconditionError, design_kkl, design_pebo, simulate
from nlobs.examples import kkl_pebo_academic as ex


def test_kkl_check_points_at_the_x3_obstruction():
    # F3 proof: the x3 component has no decay (its ρ3 must vanish for λ ≠ 0); the check names it and λ = 0
    with pytest.raises(PreconditionError, match=r"component 2 \(φ_2 = x3.*depends on the state\(s\) x3.*λ = 0.*PEBO component"):
        design_kkl(ex.model(), phi=ex.PHI, left_inverse=ex.LEFT, B=ex.B, Lambda=[-1, -1])


def test_pebo_check_points_at_the_x2_obstruction():
    # F3 proof, PEBO half: -ρ2(x2)x2 cannot be matched by B2(x1, u); the check names x2 and λ = -1
    with pytest.raises(PreconditionError, match=r"component 1 \(φ_1 = x2.*depends on the state\(s\) x2.*λ = -1"):
        design_pebo(ex.model(), phi=ex.PHI, left_inverse=ex.LEFT, B=ex.B)


def test_kkl_pebo_is_the_papers_observer_and_converges():
    d = ex.observer()
    v = d.certificate.values
    # (37): Y = W[y] + F[y³] (a = -y³) and ψ = F[e^{ξ2}]
    assert v["regression Y"].endswith("a = [-y**3]") and v["regressor psi"] == "F[b_k], b = [[exp(xi2)]]"
    # (32)-(33): ξ1' = -ξ1 + y² + sin y, ξ2' = uy + 1/(y² + 1), evaluated at one point
    z = np.zeros(d.n_z)
    z[d.z_names.index("xi[0]")], z[d.z_names.index("xi[1]")] = 0.5, 0.2
    flow = np.asarray(d.flow(0.0, z, [0.3], [0.7])).ravel()
    assert flow[d.z_names.index("xi[0]")] == pytest.approx(-0.5 + 0.49 + np.sin(0.7))
    assert flow[d.z_names.index("xi[1]")] == pytest.approx(0.3 * 0.7 + 1 / (0.49 + 1))
    run = simulate(ex.model(), {"kp": d}, t_final=ex.T_FINAL, dt=ex.DT, x0=ex.X0, inputs={"u": ex.U})
    err = np.abs(run.error("kp"))
    assert err[-1, 1] < 1e-6 and err[-1, 2] < 1e-6        # F4: i = 2, 3


def test_example_claims_hold():
    result = ex.run()
    assert all(c.holds is True for c in result.claims), [str(c) for c in result.claims if c.holds is not True]


def test_example_31_is_detectable_but_not_observable():
    """x2 in 004 (31) never reaches y = x1 (x2' = -x2 + x1² + sin x1 is driven by x1 alone): the
    observation space misses x2, yet x2 is recovered asymptotically because its dynamics are stable."""
    from nlobs.analysis import analyze
    from nlobs.examples.kkl_pebo_academic import model

    report = analyze(model()).to_dict()
    assert not report["observable"] and report["rank"] == 2
    assert set(report["observable_states"]) == {"x1", "x3"}
    direction = np.abs(np.asarray(report["unobservable_directions"][0]))
    assert np.allclose(direction, [0, 1, 0], atol=1e-9)
