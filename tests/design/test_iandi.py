"""I&I observer with the pseudo-inverse (004_f1e237c45ff4719e.txt Proposition 4, eqs. 16-19, A4, R8)."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import PreconditionError, ShapeError, System, design_iandi, simulate

# x1' = x2, x2' = -x1 - x2 + u, y = x1. With β = χ + k y, φ = x2 (reduced-order observer), (18) gives
# χ' = -k x̂2 + (-y - x̂2 + u), and the off-the-manifold error d = x̂2 - x2 obeys d' = -(k + 1) d (derived by hand).
PLANT = System(states=["x1", "x2"], f=["x2", "-x1 - x2 + u"], outputs=["y"], h=["x1"], inputs=["u"], name="damped")
K = 3.0


@pytest.mark.parametrize("beta, n_chi", [([f"chi1 + {K}*y"], None),
                                         ([f"chi1 + chi2 + {K}*y"], 2)])   # n_χ > n_z: the pseudo-inverse (R8)
def test_error_obeys_the_derived_linear_law(beta, n_chi):
    d = design_iandi(PLANT, beta=beta, phi=["x2"], left_inverse=["y", "xi1"], n_chi=n_chi)
    x0 = np.array([0.4, -1.0])
    run = simulate(PLANT, {"ii": d}, t_final=4.0, dt=1e-3, x0=x0, inputs={"u": "sin(t)"})
    e = run.error("ii")
    e0 = K * x0[0] - x0[1]                               # χ(0) = 0: x̂2(0) = k y(0)
    assert np.allclose(e[:, 0], 0.0) and np.allclose(e[:, 1], e0 * np.exp(-(K + 1) * run.t), atol=1e-9)


def test_free_term_q_stays_in_the_kernel():
    # with n_χ = 2 and Q = (1, -1) (in the kernel of ∂β/∂χ = [1, 1]) the estimate is unchanged, χ drifts apart
    common = dict(beta=[f"chi1 + chi2 + {K}*y"], phi=["x2"], left_inverse=["y", "xi1"], n_chi=2)
    a = design_iandi(PLANT, **common)
    b = design_iandi(PLANT, **common, Q=["1", "-1"])
    run = simulate(PLANT, {"a": a, "b": b}, t_final=2.0, dt=1e-3, x0=[0.4, -1.0], inputs={"u": "sin(t)"})
    assert np.allclose(run.observers["a"].xhat, run.observers["b"].xhat, atol=1e-9)
    chi = run.observers["b"].z
    assert chi[-1, 0] - chi[-1, 1] == pytest.approx(2.0 * 2.0, abs=1e-9)    # (I - J†J)Q = (1, -1): drift 2 per second


def test_a4_and_the_maps_are_checked():
    with pytest.raises(PreconditionError, match=r"A4 fails.*rank 0 < n_z = 1"):
        design_iandi(PLANT, beta=["y"], phi=["x2"], left_inverse=["y", "xi1"])
    with pytest.raises(PreconditionError, match="not a left inverse"):
        design_iandi(PLANT, beta=["chi1"], phi=["x2"], left_inverse=["y", "2*xi1"])
    with pytest.raises(PreconditionError, match="n_chi = 1 < n_z = 2"):
        design_iandi(PLANT, beta=["chi1", "y"], phi=["x2", "x1"], left_inverse=["xi2", "xi1"], n_chi=1)
    with pytest.raises(ShapeError, match="`phi` has 2"):
        design_iandi(PLANT, beta=["chi1"], phi=["x2", "x1"], left_inverse=["y", "xi1"])
