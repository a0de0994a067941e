"""Observer forms (002) and Banks' conditions (003)."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import DataError, ShapeError, System, load_model
from nlobs.analysis import (banks_condition, lipschitz_bound, lipschitz_constant, matrix_measure, max_slope,
                            recognise_forms, state_affine_form, triangular_form)

MODELS = __import__("pathlib").Path(__file__).resolve().parents[2] / "src" / "nlobs" / "models"
KOU_F1 = ["x1", "x1 - 2*x2 + exp(-x2)"]  # 003 example 3.1 (Kou et al.): y = x1 + x2
EX32_F1 = ["-x1 - x1**3 + x1*x2", "-x2 - x2**5 - 4*x1*x2"]  # 003 example 3.2: y = x1 x2


class TestForms:
    def test_002_pendulum_forms(self):
        # 002 robot arm: output-injection form in (x1, x2); with unknown b, state-affine
        # ẋe = Ae(u)xe + Be(y) but no longer output injection (b u multiplies an unmeasured state)
        pend = load_model(MODELS / "pendulum.toml").system
        rep = recognise_forms(pend)
        assert rep.holds("output injection") and rep.holds("state-affine") and rep.holds("triangular")
        rep_b = recognise_forms(pend, unknown_params=["b"])
        assert not rep_b.holds("output injection") and rep_b.holds("state-affine")
        assert "[0, 0, 1]" in str(rep_b)

    def test_002_van_der_pol_state_affine_coordinates(self):
        # 002 Van der Pol with unknown γ, ω²: in z = (x, ẋ - γ(x - x³/3), γ, ω²) the model is
        # ż = A(y) z with A(y) = [[0, 1, y - y³/3, 0], [0, 0, 0, -y], 0, 0] (re-derived)
        z = System(states=["z1", "z2", "g", "w"], f=["z2 + (z1 - z1**3/3)*g", "-z1*w", "0", "0"], outputs=["y"], h=["z1"])
        chk = state_affine_form(z)
        assert chk.holds
        y = z.y[0]
        assert (chk.details["A"][0, 2] - (y - y**3 / 3)).simplify() == 0 and chk.details["A"][1, 3] == -y
        tri = triangular_form(z)
        assert not tri.holds and "depends on g" in tri.reason

    def test_not_state_affine_names_the_entry(self):
        s = System(states=["x1", "x2"], f=["x2", "-x2**2"], outputs=["y"], h=["x1"])
        chk = state_affine_form(s)
        assert not chk.holds and "x2'" in chk.reason

    def test_lipschitz_constant_of_the_pendulum(self):
        # φ = f - A x with A the Jacobian at 0: ∂φ2/∂x1 = a1 (1 - cos x1), largest at |x1| = 3 on the box
        pend = load_model(MODELS / "pendulum.toml").system
        est = lipschitz_constant(pend, [[-3, 3], [-5, 5]])
        assert est.gamma == pytest.approx(9.81 * (1 - np.cos(3.0)), rel=1e-9)
        assert abs(est.worst_point[0]) == pytest.approx(3.0)


class TestBanks:
    def test_matrix_measure_example_31(self):
        # 003 example 3.1: λ([[-1, -2], [2, -1]]) = λ(diag(-1, -1)) = -1 (A + P·C with P = (-2, 1)ᵀ)
        A, C, P = np.array([[1.0, 0.0], [1.0, -2.0]]), np.array([[1.0, 1.0]]), np.array([[-2.0], [1.0]])
        assert matrix_measure(A + P @ C) == pytest.approx(-1.0)
        assert max_slope(["0", "exp(-x2)"], ["x1", "x2"], [[-4, 4], [-4, 4]]).dissipative  # f1 of Lemma 2.3

    def test_example_31_theorem_26(self):
        chk = banks_condition(KOU_F1, ["x1 + x2"], [[-2], [1]], ["x1", "x2"], [[-5, 5], [-5, 5]], epsilon=1.0)
        assert chk.holds and chk.lam_max == pytest.approx(-1.0, abs=1e-9)

    def test_example_32_gains(self):
        # 003 example 3.2 with gains (-1, 4): Df1 + P DB = diag(-1 - 3x1², -1 - 5x2⁴) (the text prints
        # -1 - 2x1² and -1 - 5x2²; re-derived), so λ ≤ -1 with equality on the axes (worst point on them)
        chk = banks_condition(EX32_F1, ["x1*x2"], [-1, 4], ["x1", "x2"], [[-2, 2], [-2, 2]], epsilon=1.0)
        assert chk.holds and chk.lam_max == pytest.approx(-1.0, abs=1e-9)
        assert min(abs(chk.worst_point)) < 1e-6
        bad = banks_condition(EX32_F1, ["x1*x2"], [0, 0], ["x1", "x2"], [[-2, 2], [-2, 2]])
        assert not bad.holds and bad.lam_max > 0 and "FAILS" in str(bad)

    def test_perturbation_slope_and_lipschitz(self):
        # f(x) = 0.5 sin x: slope and Lipschitz constant 0.5 (at x = 0), both < ε = 1 of example 3.1
        assert max_slope(["0.5*sin(x)"], ["x"], [[-1, 1]]).mu == pytest.approx(0.5)
        assert lipschitz_bound(["0.5*sin(x)"], ["x"], [[-1, 1]]).gamma == pytest.approx(0.5)

    def test_bad_regions(self):
        with pytest.raises(DataError, match="NaN or infinite"):
            banks_condition(KOU_F1, ["x1 + x2"], [-2, 1], ["x1", "x2"], [[-1, np.nan], [-1, 1]])
        with pytest.raises(DataError, match="low > high"):
            max_slope(["x"], ["x"], [[1, -1]])
        with pytest.raises(ShapeError, match="`P`"):
            banks_condition(KOU_F1, ["x1 + x2"], [-2, 1, 3], ["x1", "x2"], [[-1, 1], [-1, 1]])
        with pytest.raises(ShapeError, match="square"):
            matrix_measure([[1, 2, 3]])


class TestBanksReports:
    """What Banks' checks tell a user: the function and argument at fault, the verdict, the worst point, the evidence."""

    @pytest.mark.parametrize("call, where", [
        (lambda: max_slope(["x1 +"], ["x1"], [[0, 1]]), r"^max_slope: `exprs`\[0\]"),
        (lambda: max_slope(["x1"], ["x1"], [[0, 1], [0, 1]]), r"^max_slope: `region`"),
        (lambda: max_slope(["x1", "1"], ["x1"], [[0, 1]]), r"^max_slope: N must map R\^1 to itself: 2 components"),
        (lambda: banks_condition(["x1 +"], ["x1"], [[-1]], ["x1"], [[0, 1]]), r"^banks_condition: `f1`\[0\]"),
        (lambda: banks_condition(["-x1"], ["q"], [[-1]], ["x1"], [[0, 1]]), r"^banks_condition: `B`\[0\]"),
        (lambda: banks_condition(["-x1"], ["x1"], [[-1]], ["x1"], [[0, 1], [0, 1]]), r"^banks_condition: `region`"),
        (lambda: banks_condition(["-x1", "0"], ["x1"], [[-1]], ["x1"], [[0, 1]]), r"^banks_condition: `f1` must have 1"),
        (lambda: banks_condition(["-x1"], ["x1"], [[np.inf]], ["x1"], [[0, 1]]), r"^banks_condition: `P` has non-finite"),
        (lambda: lipschitz_bound(["x1"], ["x1"], [[0, 1], [0, 1]]), r"^lipschitz_bound: `region`"),
        (lambda: matrix_measure([[np.nan]]), r"^matrix_measure: `A` has non-finite"),
    ])
    def test_errors_name_the_function_and_the_argument(self, call, where):
        with pytest.raises(ValueError, match=where):
            call()

    def test_reports_give_verdict_point_and_evidence(self):
        ok = max_slope(["-x - x**3"], ["x"], [[-1, 1]])
        assert ok.dissipative and ok.mu == pytest.approx(-1.0, abs=1e-6) and ok.worst_point == pytest.approx([0.0], abs=1e-4)
        text = str(ok)
        assert "dissipative (Lemma 2.3)" in text and "(x=0)" in text and "Banks (1980)" in text and "lower bound" in text
        bad = max_slope(["x**3"], ["x"], [[-1, 2]])
        assert not bad.dissipative and bad.mu == pytest.approx(12.0) and "NOT dissipative" in str(bad)
        assert bad.evidence == "witness point" and abs(bad.worst_point[0]) == pytest.approx(2.0)
        chk = banks_condition(KOU_F1, ["x1 + x2"], [[-2], [1]], ["x1", "x2"], [[-5, 5], [-5, 5]], epsilon=0.5)
        assert chk.holds and "≤ -ε = -0.5" in str(chk) and "Thm 2.6" in str(chk) and "K < 1" in str(chk)
        assert chk.margin == pytest.approx(1.0, abs=1e-9) and chk.P.shape == (2, 1)
        free = banks_condition(KOU_F1, ["x1 + x2"], [[-2], [1]], ["x1", "x2"], [[-5, 5], [-5, 5]])
        assert free.holds and "< 0" in str(free) and free.epsilon == 0.0
        assert "FAILS" in str(banks_condition(KOU_F1, ["x1 + x2"], [[-2], [1]], ["x1", "x2"], [[-5, 5], [-5, 5]], epsilon=2.0))

    def test_defaults_are_reproducible_and_documented(self):
        # samples = 2000 and seed = 0 by default: the same numbers as asking for them explicitly
        a = lipschitz_bound(["sin(3*x)*y"], ["x", "y"], [[-1, 1], [0, 2]])
        b = lipschitz_bound(["sin(3*x)*y"], ["x", "y"], [[-1, 1], [0, 2]], samples=2000, seed=0)
        assert a.gamma == b.gamma and a.samples == 2000 and np.array_equal(a.worst_point, b.worst_point)
        s1, s2 = max_slope(["sin(3*x)"], ["x"], [[-1, 1]]), max_slope(["sin(3*x)"], ["x"], [[-1, 1]], samples=2000, seed=0)
        assert s1.mu == s2.mu and s1.tol == 1e-9 and s1.samples == 2000
        # a slope at the tolerance counts as dissipative (μ <= tol)
        assert max_slope(["0*x"], ["x"], [[-1, 1]]).dissipative


class TestBoxSup:
    """The sampled supremum over a box (analysis.box_sup) that every Banks/Lipschitz estimate uses."""

    def test_sup_at_a_corner_of_a_box_away_from_the_origin(self):
        from nlobs.analysis.forms._conditions import box_sup
        box = np.array([[1.0, 2.0], [3.0, 5.0]])
        v, x = box_sup(lambda P: P[:, 0] + P[:, 1], box)
        assert v == 7.0 and np.array_equal(x, [2.0, 5.0])          # the corner (hi, hi), exactly, and inside the box
        v, x = box_sup(lambda P: -P[:, 0] - P[:, 1], box)
        assert v == -4.0 and np.array_equal(x, [1.0, 3.0])
        v, x = box_sup(lambda P: -((P[:, 0] - 1.5) ** 2) - (P[:, 1] - 4.0) ** 2, box)
        assert v == 0.0 and np.array_equal(x, [1.5, 4.0])          # the centre is sampled exactly
        # a corner that random samples and a local search from the best samples would miss: a narrow spike
        v, x = box_sup(lambda P: np.where((P[:, 0] > 1.999999) & (P[:, 1] < 3.000001), 10.0, 0.0), box)
        assert v == 10.0
        with pytest.raises(Exception, match=r"not finite at \(1, 3\)|not finite at \[1, 3\]|not finite at"):
            box_sup(lambda P: np.where(P[:, 0] == 1.0, np.inf, 0.0), box)

    def test_lipschitz_constant_on_a_shifted_box(self):
        # γ of x² on [1, 2] is 4, at x = 2 (samples must stay inside the box)
        est = lipschitz_bound(["x**2"], ["x"], [[1.0, 2.0]])
        assert est.gamma == pytest.approx(4.0, abs=1e-12) and est.worst_point == pytest.approx([2.0])

    def test_boxes_and_matrices_are_checked(self):
        assert max_slope("-x", ["x"], [-1, 1]).dissipative            # a single expression and a flat [lo, hi]
        assert max_slope(["-x"], ["x"], [[0.5, 0.5]]).mu == pytest.approx(-1.0)   # a degenerate box is a point
        with pytest.raises(ShapeError, match="one \\[low, high\\] pair per coordinate"):
            max_slope(["-x", "-y"], ["x", "y"], [-1, 1, -1, 1])
        with pytest.raises(DataError, match="row 1 has a NaN"):
            max_slope(["-x", "-y"], ["x", "y"], [[-1, 1], [np.nan, 1]])
        with pytest.raises(DataError, match=r"row 1 has low > high: \[2.0, 1.0\]"):
            max_slope(["-x", "-y"], ["x", "y"], [[-1, 1], [2, 1]])
        assert isinstance(matrix_measure([[1.0, 0.0], [0.0, -1.0]]), float)
        assert matrix_measure(np.zeros((4, 2, 2))).shape == (4,)
        with pytest.raises(ShapeError, match="square"):
            matrix_measure(np.zeros((4, 2, 3)))


class TestSamplingOptions:
    def test_spectral_norm_two_outputs_and_report_text(self):
        est = lipschitz_bound(["0.3*y", "0.4*x"], ["x", "y"], [[-1, 1], [-1, 1]])
        assert est.gamma == pytest.approx(0.4, abs=1e-12)                  # ‖[[0, 0.3], [0.4, 0]]‖₂ (Frobenius: 0.5)
        assert "x=" in str(est) and "‖DN‖₂" in str(est)
        # two outputs, P given flat (n·p numbers, row-major): P = [[-1, 0], [0, -1]]
        chk = banks_condition(["x1", "x2"], ["x1", "x2"], [-2, 0, 0, -2], ["x1", "x2"], [[-1, 1], [-1, 1]])
        assert chk.P.shape == (2, 2) and chk.lam_max == pytest.approx(-1.0, abs=1e-12)

    def test_seed_and_samples_are_used(self):
        # on a plateau every sample is a maximiser: the reported point is a sample, so it follows seed and samples
        def worst(**kw):
            return banks_condition(["-x1"], ["x1"], [[0.0]], ["x1"], [[0.0, 1.0]], **kw).worst_point[0]
        assert worst(seed=3) == worst(seed=3) != worst(seed=4)
        assert worst(samples=50, seed=3) != worst(samples=60, seed=3)
        s3, s4 = (max_slope(["0*x"], ["x"], [[0.0, 1.0]], seed=k).worst_point[0] for k in (3, 4))
        assert s3 != s4
        l3, l4 = (lipschitz_bound(["x"], ["x"], [[0.0, 1.0]], seed=k, samples=40).worst_point[0] for k in (3, 4))
        assert l3 != l4 and lipschitz_bound(["x"], ["x"], [[0.0, 1.0]], samples=40).samples == 40

    def test_tolerance_is_inclusive(self):
        assert max_slope(["0*x"], ["x"], [[-1, 1]], tol=0.0).dissipative           # μ = 0 <= tol = 0
        assert not max_slope(["1e-6*x"], ["x"], [[-1, 1]], tol=0.0).dissipative


class TestRegionVocabulary:
    """One name for a box of variables: ``region``, a mapping by name or [low, high] pairs in order."""

    def test_a_mapping_is_the_same_box_as_the_pairs_in_order(self):
        by_pairs = lipschitz_bound(["sin(3*x)*y"], ["x", "y"], [[-1, 1], [0, 2]])
        by_name = lipschitz_bound(["sin(3*x)*y"], ["x", "y"], {"y": (0, 2), "x": (-1, 1)})  # any order of keys
        assert by_name.gamma == by_pairs.gamma
        pend = load_model(MODELS / "pendulum.toml").system
        est = lipschitz_constant(pend, {"x1": (-3, 3), "x2": (-5, 5)})
        assert est.gamma == pytest.approx(9.81 * (1 - np.cos(3.0)), rel=1e-9)  # as test_lipschitz_constant_of_the_pendulum

    def test_the_old_name_box_warns_and_still_works(self):
        with pytest.warns(DeprecationWarning, match="`box` is renamed `region`"):
            assert max_slope(["-x"], ["x"], box=[[-1, 1]]).dissipative
        with pytest.raises(TypeError, match="give `region` only"):
            max_slope(["-x"], ["x"], region=[[-1, 1]], box=[[-1, 1]])

    def test_a_mapping_must_name_each_variable_once(self):
        with pytest.raises(ShapeError, match=r"`region` names 'z', which is not one of x, y"):
            lipschitz_bound(["x*y"], ["x", "y"], {"x": (0, 1), "y": (0, 1), "z": (0, 1)})
        with pytest.raises(ShapeError, match=r"`region` has no bounds for y"):
            lipschitz_bound(["x*y"], ["x", "y"], {"x": (0, 1)})
