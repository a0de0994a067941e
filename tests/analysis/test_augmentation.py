"""State augmentation (001): mimicking, injectivity, left inverses, the augmented system along a
trajectory, and the automatic augmentation (001 §V future work) on §IV-A, §IV-B and §IV-C.

The matrices of (16), (19) and (21) are re-derived by hand from the paper's T (the PDF text of
(16) and (19) is garbled) and written out here, independently of the automatic augmentation.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from nlobs import FormError, ShapeError, System
from nlobs.analysis import (augmented_observability, check_mimicking, injectivity, kalman_rank, left_inverse_bounds,
                            propose_augmentation)
from nlobs.analysis.forms._augment import _as_augmentation
from nlobs.model import symbol

RICH_VEL = {"u1": "0.5*sin(t)", "u2": "0.5*cos(0.7*t)", "u3": "0.3*sin(1.3*t)"}
RICH_ACC = {"u1": "sin(t)", "u2": "cos(0.7*t)", "u3": "sin(1.3*t)"}


def dot(a, b):
    return " + ".join(f"{a}{i}*{b}{i}" for i in (1, 2, 3))


def toy(c=0.5):
    """001 eq. (20): x1' = x2², x2' = c, y = x1."""
    return System(states=["x1", "x2"], f=["x2**2", "c"], outputs=["y"], h=["x1"], params={"c": c}, name="toy")


def range_velocity():
    """001 eq. (15): x1' = x2 + u, x2' = 0, y = ‖x1‖ (x1 = p, x2 = v)."""
    return System(states=["p1", "p2", "p3", "v1", "v2", "v3"], f=["v1 + u1", "v2 + u2", "v3 + u3", "0", "0", "0"],
                  outputs=["y"], h=["sqrt(p1**2 + p2**2 + p3**2)"], inputs=["u1", "u2", "u3"], name="range_velocity")


def range_acceleration():
    """001 eq. (17): x1' = -x2, x2' = x3 + u, x3' = 0, y = ‖x1‖ (x1 = a, x2 = b, x3 = g)."""
    return System(states=["a1", "a2", "a3", "b1", "b2", "b3", "g1", "g2", "g3"],
                  f=["-b1", "-b2", "-b3", "g1 + u1", "g2 + u2", "g3 + u3", "0", "0", "0"],
                  outputs=["y"], h=["sqrt(a1**2 + a2**2 + a3**2)"], inputs=["u1", "u2", "u3"], name="range_acceleration")


def paper_16():
    """(16) re-derived: w = [p, v, ‖p‖, p·v, v·v]; d‖p‖/dt = (uᵀp + p·v)/y, d(p·v)/dt = uᵀv + v·v."""
    T = ["p1", "p2", "p3", "v1", "v2", "v3", "sqrt(p1**2 + p2**2 + p3**2)", dot("p", "v"), dot("v", "v")]
    A = [[0] * 9 for _ in range(9)]
    for i in range(3):
        A[i][3 + i] = 1
        A[6][i] = f"u{i + 1}/y"
        A[7][3 + i] = f"u{i + 1}"
    A[6][7] = "1/y"
    A[7][8] = 1
    B = [[1 if (r == c) else 0 for c in range(3)] for r in range(9)]
    C = [[0, 0, 0, 0, 0, 0, 1, 0, 0]]
    return T, A, B, C


def paper_19():
    """(19) re-derived: w = [x1, x2, x3, ‖x1‖, x1·x2, x1·x3, -x2·x2, x2·x3, x3·x3] (15 scalars)."""
    T = ["a1", "a2", "a3", "b1", "b2", "b3", "g1", "g2", "g3", "sqrt(a1**2 + a2**2 + a3**2)", dot("a", "b"),
         dot("a", "g"), f"-({dot('b', 'b')})", dot("b", "g"), dot("g", "g")]
    A = [[0] * 15 for _ in range(15)]
    for i in range(3):
        A[i][3 + i] = -1
        A[3 + i][6 + i] = 1
        A[10][i] = f"u{i + 1}"
        A[12][3 + i] = f"-2*u{i + 1}"
        A[13][6 + i] = f"u{i + 1}"
    A[9][10] = "-1/y"
    A[10][11] = A[10][12] = 1  # d(x1·x2)/dt = w6 + w7 + uᵀx1: only the sum of blocks 6 and 7 enters
    A[11][13] = -1
    A[12][13] = -2
    A[13][14] = 1
    B = [[1 if r == 3 + c else 0 for c in range(3)] for r in range(15)]
    C = [[0] * 9 + [1] + [0] * 5]
    return T, A, B, C


def same_functions(got, want):
    # compare as plain SymPy expressions of the printed forms (the model uses real symbols)
    return len(got) == len(want) and all(sp.simplify(sp.sympify(str(a)) - sp.sympify(str(b))) == 0 for a, b in zip(got, want))


class TestToy:
    def test_001_eq21(self):
        # 001 §IV-C: T = (x1, x2, x2²), A = [[0,0,1],[0,0,0],[0,2c,0]], B = (0,1,0), v = c
        s = toy()
        chk = check_mimicking(s, ["x1", "x2", "x2**2"], [[0, 0, 1], [0, 0, 0], [0, "2*c", 0]], [[1, 0, 0]], b=[0, "c", 0])
        assert chk.holds
        aug = propose_augmentation(s)
        assert same_functions(aug.T, ["x1", "x2", "x2**2"])
        c = symbol("c")
        assert aug.A == sp.Matrix([[0, 0, 1], [0, 0, 0], [0, 2 * c, 0]]) and list(aug.b) == [0, c, 0]
        assert injectivity(s, aug).injective is True
        b = left_inverse_bounds(["w1", "w2"], 3)
        assert b.upper == pytest.approx(1.0) and b.lemma1 and not b.lemma2  # 001: [I 0] meets Lemma 1, not Lemma 2
        # the augmented LTI pair is observable iff c != 0 (001: O = [[1,0,0],[0,0,1],[0,2c,0]])
        for cv, obs in ((0.5, True), (0.0, False)):
            A = np.array(aug.A.xreplace({c: cv}), dtype=float)
            assert kalman_rank(A, np.array(aug.C, dtype=float)).observable is obs

    def test_wrong_mimicking_names_the_row(self):
        chk = check_mimicking(toy(), ["x1", "x2", "x2**2"], [[0, 0, 1], [0, 0, 0], [0, "c", 0]], [[1, 0, 0]], b=[0, "c", 0])
        assert not chk.holds and "row 3" in chk.reason


class TestRangeVelocity:
    def test_001_eq16_mimics_and_is_found_automatically(self):
        T, A, B, C = paper_16()
        assert check_mimicking(range_velocity(), T, A, C, B=B).holds
        # the garbled text of (16) drops the 1 in the p·v row; that A does not mimic (15)
        A_bad = [row[:] for row in A]
        A_bad[7][8] = 0
        bad = check_mimicking(range_velocity(), T, A_bad, C, B=B)
        assert not bad.holds and "row 8" in bad.reason
        aug = propose_augmentation(range_velocity())
        assert same_functions(aug.T, T)
        assert check_mimicking(range_velocity(), aug).holds

    def test_001_rich_vs_straight_line(self):
        # 001 §IV-A: observable iff t, t², u^[1], t u^[1] are linearly independent: true for a rich
        # velocity, false for a constant one (a straight line: u^[1] = u t)
        s = range_velocity()
        T, A, B, C = paper_16()
        aug = _as_augmentation(s, T, A, C, B=B)
        x0 = [5, 3, 2, 0.1, -0.2, 0.1]
        rich = augmented_observability(s, aug, x0, t_final=20, dt=0.01, inputs=RICH_VEL)
        assert rich.observable
        line = augmented_observability(s, aug, x0, t_final=20, dt=0.01, inputs={"u1": 0.2, "u2": -0.1, "u3": 0.3})
        assert not line.observable and line.gramian.rank <= 6


class TestRangeAcceleration:
    def test_001_eq18_found_and_observable(self):
        # 001 §IV-B: the 14-state augmentation (18) is observable for a rich input
        s = range_acceleration()
        aug = propose_augmentation(s)
        want = ["a1", "a2", "a3", "b1", "b2", "b3", "g1", "g2", "g3", "sqrt(a1**2 + a2**2 + a3**2)", dot("a", "b"),
                f"{dot('a', 'g')} - ({dot('b', 'b')})", dot("b", "g"), dot("g", "g")]
        assert same_functions(aug.T, want)
        x0 = [5, 3, 2, 0.1, -0.2, 0.1, 0.05, 0.02, -0.03]
        assert augmented_observability(s, aug, x0, t_final=20, dt=0.01, inputs=RICH_ACC).observable

    def test_001_eq19_only_the_sum_w6_plus_w7_is_seen(self):
        # 001 §IV-B: (19) mimics (17) but is not observable: the states for x1·x3 and -x2·x2
        # (scalars 12 and 13) are indistinguishable; only their sum is seen
        s = range_acceleration()
        T, A, B, C = paper_19()
        assert check_mimicking(s, T, A, C, B=B).holds
        aug = _as_augmentation(s, T, A, C, B=B)
        x0 = [5, 3, 2, 0.1, -0.2, 0.1, 0.05, 0.02, -0.03]
        res = augmented_observability(s, aug, x0, t_final=20, dt=0.01, inputs=RICH_ACC)
        assert res.gramian.rank == 14
        v = res.gramian.unobservable_directions[0]
        want = np.zeros(15)
        want[11], want[12] = 1 / np.sqrt(2), -1 / np.sqrt(2)
        assert min(np.linalg.norm(v - want), np.linalg.norm(v + want)) < 1e-6
        assert "w12" in str(res) and "w13" in str(res)


def test_errors():
    with pytest.raises(FormError, match="not polynomial"):
        propose_augmentation(System(states=["x"], f=["sin(x)"], outputs=["y"], h=["x"]))
    with pytest.raises(ShapeError, match="6 finite numbers"):
        T, A, B, C = paper_16()
        augmented_observability(range_velocity(), _as_augmentation(range_velocity(), T, A, C, B=B), [1, 2], t_final=1)
    with pytest.raises(ShapeError, match="incompatible dimensions of `A`"):
        check_mimicking(toy(), ["x1", "x2"], [[0, 1, 0]], [[1, 0]])
