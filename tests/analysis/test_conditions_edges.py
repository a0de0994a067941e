"""Banks' conditions at their edges (003_a2c72ccb4281ea3f.txt): exact inputs, boundary cases, the norm
of the Lipschitz constant, and evidence that reports the sampling actually done. Written against the
mutants the mutation run (benchmarks/mutation.py) found alive in analysis/forms/_conditions.py.

Reference values are computed by hand in the comments, not by the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from nlobs import ModelError, ShapeError
from nlobs.analysis.forms import _conditions as C
from nlobs.analysis import banks_condition, lipschitz_bound, matrix_measure, max_slope

KOU_F1 = ["x1", "x1 - 2*x2 + exp(-x2)"]  # 003 example 3.1 (Kou et al.): y = x1 + x2


def test_matrix_measure_of_an_exact_sympy_matrix():
    # 003 Lemma 2.3: λ(Q) = sup <Qx, x>/|x|² = max spec((Q + Qᵀ)/2). Q = [[1, 2], [0, 3]]:
    # (Q + Qᵀ)/2 = [[1, 1], [1, 3]], eigenvalues 2 ± √2, so λ = 2 + √2 (by hand)
    assert matrix_measure(sp.Matrix([[1, 2], [0, 3]])) == pytest.approx(2 + np.sqrt(2), abs=1e-14)
    assert matrix_measure([[1, 2], [0, 3]]) == pytest.approx(2 + np.sqrt(2), abs=1e-14)


def test_banks_example_3_1_with_an_exact_gain():
    # 003 example 3.1: P = (-2, 1)ᵀ, y = x1 + x2; Df1 + P·DB = [[1 - 2, -2], [1 + 1, -2 - e^{-x2} + 1]]
    # = [[-1, -2], [2, -1 - e^{-x2}]], symmetric part diag(-1, -1 - e^{-x2}): λ = -1 (sup as x2 → ∞)
    res = banks_condition(KOU_F1, ["x1 + x2"], sp.Matrix([[-2], [1]]), ["x1", "x2"], [[-1, 1], [0, 40]])
    assert res.lam_max == pytest.approx(-1.0, abs=1e-12)
    assert res.holds


def test_banks_gain_given_flat_with_two_outputs():
    # two outputs, P given as the flat list of its n·m = 4 entries (row by row). f1 = (x2, -x1), B = (x1, x2):
    # Df1 + P·DB = [[0, 1], [-1, 0]] + [[-1, 0.5], [0, -1]] = [[-1, 1.5], [-1, -1]];
    # symmetric part [[-1, 0.25], [0.25, -1]], eigenvalues -1 ± 0.25: λ = -0.75 (by hand)
    res = banks_condition(["x2", "-x1"], ["x1", "x2"], [-1, 0.5, 0, -1], ["x1", "x2"], [[-1, 1], [-1, 1]])
    assert res.lam_max == pytest.approx(-0.75, abs=1e-14)
    assert res.holds


def test_lipschitz_constant_is_the_spectral_norm_of_the_jacobian():
    # N = (x1²/2, x2) on x1 ∈ [0, 3]: DN = diag(x1, 1), ‖DN‖₂ = max(x1, 1) → γ = 3 at x1 = 3
    # (the Frobenius norm would give √10 ≈ 3.16: the Euclidean Lipschitz constant is the spectral norm,
    # the K of 003 Theorem 2.6)
    est = lipschitz_bound(["x1**2/2", "x2"], ["x1", "x2"], [[0, 3], [-1, 1]])
    assert est.gamma == pytest.approx(3.0, abs=1e-12)
    assert est.worst_point[0] == pytest.approx(3.0, abs=1e-9)
    assert est.variables == ("x1", "x2")
    text = str(est)
    assert text.startswith("Lipschitz constant of N over the box: γ ≈ 3 (largest ‖DN‖₂, at x1=3, x2=")
    assert text.endswith(f"; {est.evidence})") and "2000" in est.evidence


def test_maximum_slope_exactly_zero_is_dissipative():
    # 003 Lemma 2.3: f1 is dissipative iff <f1(x) - f1(z), x - z> ≤ 0, i.e. μ_N ≤ 0 (equality allowed).
    # N = -x1² on [0, 1]: N' = -2 x1 ≤ 0 with the maximum 0 reached at the corner x1 = 0.
    res = max_slope(["-x1**2"], ["x1"], [[0, 1]], tol=0.0)
    assert res.mu == 0.0
    assert res.dissipative


def test_a_box_of_zero_width_is_a_fixed_value():
    # low == high is a legitimate box (a coordinate held fixed); only low > high is refused
    b = C.check_box([[1.0, 1.0], [0.0, 2.0]], 2, "box", "caller")
    assert b.tolist() == [[1.0, 1.0], [0.0, 2.0]]
    # N = x1·x2 with x1 = 1: DN = (x2, x1), ‖DN‖₂ = √(x2² + 1), largest at x2 = 2: √5 (by hand)
    est = lipschitz_bound(["x1*x2"], ["x1", "x2"], [[1.0, 1.0], [0.0, 2.0]])
    assert est.gamma == pytest.approx(np.sqrt(5), abs=1e-12) and est.worst_point.tolist() == [1.0, 2.0]


@pytest.mark.parametrize("fn, args", [
    ("lipschitz_bound", (["x1"], ["x1"], [[0, 1]])),
    ("max_slope", (["-x1"], ["x1"], [[0, 1]])),
    ("banks_condition", (KOU_F1, ["x1 + x2"], [-2, 1], ["x1", "x2"], [[-1, 1], [0, 4]])),
])
def test_the_evidence_reports_the_sampling_actually_done(monkeypatch, fn, args):
    # the certificate says "n random points (seed s)": the sampler must receive exactly those
    seen = []
    real = C.box_sup

    def spy(fun, box, **kw):
        seen.append(kw)
        return real(fun, box, **kw)

    monkeypatch.setattr(C, "box_sup", spy)
    res = getattr(C, fn)(*args, samples=64, seed=5)
    assert seen[-1]["samples"] == 64 and seen[-1]["seed"] == 5 and res.samples == 64
    res = getattr(C, fn)(*args)
    assert seen[-1]["samples"] == 2000 and seen[-1]["seed"] == 0 and res.samples == 2000   # the documented defaults


def test_expression_errors_name_the_function_and_the_argument():
    with pytest.raises(ModelError, match=r"^lipschitz_bound: `exprs`\[1\]"):
        lipschitz_bound(["x1", "x1 +"], ["x1"], [[0, 1]])
    with pytest.raises(ModelError, match=r"^max_slope: `exprs`\[0\]: expected a string, number or SymPy expression"):
        max_slope([object()], ["x1"], [[0, 1]])
    with pytest.raises(ShapeError, match="banks_condition: incompatible dimensions of `P`"):
        banks_condition(KOU_F1, ["x1 + x2"], [[1, 2, 3]], ["x1", "x2"], [[-1, 1], [0, 4]])
