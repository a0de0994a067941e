"""Structured forms: LTI, state-affine (000 eq. 1), output injection (002)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from nlobs import LTI, FormError, ShapeError, StateAffine, System
from nlobs.model import OutputInjectionForm, symbol


def test_lti_round_trip():
    A = [[0, 1], [-2, -3]]
    lti = LTI(A, [0, 1], [[1, 0]], states=["p", "v"], inputs=["F"], outputs=["y"])
    sys = lti.to_system()
    assert sys.states == ("p", "v") and sys.inputs == ("F",)
    back = LTI.from_system(sys)
    assert np.array_equal(back.A, np.array(A, float)) and np.array_equal(back.B, [[0], [1]])
    assert np.array_equal(back.C, [[1, 0]]) and np.array_equal(back.D, [[0]])


def test_lti_shapes_checked():
    with pytest.raises(ShapeError, match="`A` must be square"):
        LTI([[0, 1]], None, [[1, 0]])
    with pytest.raises(ShapeError, match="incompatible dimensions of `C`: expected \\(\\*, 2\\), found \\(1, 3\\)"):
        LTI(np.eye(2), None, [[1, 0, 0]])
    with pytest.raises(ShapeError, match="`C` is required"):
        LTI(np.eye(2))


def test_lti_from_nonlinear_names_the_entry():
    s = System(states=["x1", "x2"], f=["x2", "-sin(x1)"], outputs=["y"], h=["x1"])
    with pytest.raises(FormError, match=r"f\[x2\] = -sin\(x1\) is not linear"):
        LTI.from_system(s)
    s2 = System(states=["x"], f=["-x + 1"], outputs=["y"], h=["x"])
    with pytest.raises(FormError, match="has the term 1"):
        LTI.from_system(s2)


def test_lti_with_parameters_uses_their_values():
    s = System(states=["x"], f=["-k*x + u"], inputs=["u"], outputs=["y"], h=["2*x"], params={"k": 3.0})
    lti = LTI.from_system(s)
    assert lti.A[0, 0] == -3.0 and lti.C[0, 0] == 2.0


def test_state_affine_substitutes_y_into_A_and_b():
    # a y-dependent entry of A: v' = -y*w2 becomes -x*w2 once y = Cᵀz = x is substituted
    sa = StateAffine([[0, 1, 0, 0], [0, 0, 0, "-y"], [0, 0, 0, 0], [0, 0, 0, 0]],
                     b=[0, 0, 0, 0], C=[[1], [0], [0], [0]], states=["x", "v", "g", "w2"], outputs=["y"])
    sys = sa.to_system()
    x, w2 = symbol("x"), symbol("w2")
    assert sys.f[1] == -x * w2 and sys.h == (x,)


def test_state_affine_000_example():
    # 000: x' = [[0, u], [0, 0]] x, y = x1 (002's example with u(t) = exp(-t))
    sa = StateAffine([[0, "u"], [0, 0]], [0, 0], [[1], [0]], inputs=["u"])
    sys = sa.to_system()
    assert sys.f[0] == symbol("u") * symbol("x2")


def test_state_affine_rejects_states_inside_A_and_bad_shapes():
    with pytest.raises(Exception, match="unknown name `x1`"):
        StateAffine([["x1", 0], [0, 0]], [0, 0], [[1], [0]])
    with pytest.raises(ShapeError, match="expected \\(2, 1\\)"):
        StateAffine([[0, 1], [0, 0]], [0, 0, 0], [[1], [0]])


def test_state_affine_strings_never_reach_sympify(monkeypatch):
    # every route from a string to SymPy (sympify, Matrix(...), S(...)) ends in parse_expr
    import sympy.parsing.sympy_parser as parser

    def forbidden(text, *args, **kwargs):
        raise AssertionError(f"SymPy parsed user text {text!r}")

    monkeypatch.setattr(parser, "parse_expr", forbidden)
    sa = StateAffine([[0, "u"], [0, 0]], [0, 0], [[1], [0]], inputs=["u"])
    assert sa.A[0, 1] == symbol("u")


def test_output_injection_form_of_the_pendulum():
    s = System(states=["x1", "x2"], f=["x2", "-a1*sin(x1) - a2*x2 + b*u"], outputs=["y"], h=["x1"], inputs=["u"],
               params={"a1": 9.81, "a2": 0.5, "b": 2.0})
    form = OutputInjectionForm.from_system(s)
    assert np.allclose(form.A, [[0, 1], [0, -0.5]]) and np.allclose(form.C, [[1, 0]])
    y, u = symbol("y"), symbol("u")
    assert form.B[0] == 0
    assert sp.simplify(form.B[1] - (-sp.Rational(981, 100) * sp.sin(y) + 2 * u)) == 0
    # the decomposition reproduces f: A x + B(u, Cx) == f
    x = sp.Matrix(s.x)
    f, _ = s.substituted()
    rebuilt = sp.Matrix(form.A) * x + sp.Matrix(form.B).xreplace({y: s.x[0]})
    assert all(sp.simplify(e) == 0 for e in (rebuilt - f))


def test_output_injection_refusals_name_the_obstruction():
    vdp = System(states=["x1", "x2"], f=["x2", "(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"])
    with pytest.raises(FormError, match="depends on the unmeasured direction \\[0, 1\\] through x1"):
        OutputInjectionForm.from_system(vdp)
    quad = System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1**2"])
    with pytest.raises(FormError, match="not linear in x"):
        OutputInjectionForm.from_system(quad)
