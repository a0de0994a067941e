"""Exact identity decisions (Schwartz-Zippel), and the designs that use them.

The reference values are independent: witness points are re-evaluated here with SymPy's own exact
arithmetic, identities are textbook ones (sin² + cos² = 1, tanh through exp), and the false ones
differ by a known non-zero term.
"""

from __future__ import annotations

import pytest
import sympy as sp

from nlobs import PreconditionError, System, WindowedNLS, design_pebo
from nlobs.analysis import decide_identity, exact_generic_rank
from nlobs.algebra._identity import TARGET_ERROR
from nlobs.model import symbol

x1, x2, x3 = (symbol(f"x{i}") for i in (1, 2, 3))


def _value_at(e: sp.Expr, witness) -> sp.Expr:
    return sp.nsimplify(e.xreplace({symbol(k): sp.Rational(v) for k, v in witness.items()}))


@pytest.mark.parametrize("lhs, rhs", [
    (x1**2 - x2**2, (x1 - x2) * (x1 + x2)),
    (sp.expand((x1 + x2 + x3) ** 12), (x1 + x2 + x3) ** 12),
    (1 / (x1 - 1) - 1 / (x1 + 1), 2 / (x1**2 - 1)),
])
def test_rational_identities_hold_with_a_stated_error_bound(lhs, rhs):
    v = decide_identity(lhs, rhs)
    assert v.holds and v.error_bound <= TARGET_ERROR and "Schwartz-Zippel" in v.evidence


def test_a_tiny_residual_is_not_zero():
    # the case that a floating test at 12 points with a relative tolerance accepted: -1e-10·x2
    v = decide_identity(x1 - sp.Rational(1, 10**10) * x2, x1)
    assert v.fails and not v.holds and v.error_bound == 0
    assert _value_at(-sp.Rational(1, 10**10) * x2, v.witness) == sp.Rational(v.value)   # the witness is right
    assert decide_identity(x1 + 1e-10 * x2, x1).fails                                   # floats are exact too


@pytest.mark.parametrize("lhs, rhs", [
    (sp.sin(x1) ** 2 + sp.cos(x1) ** 2, 1),
    (sp.sin(2 * x1), 2 * sp.sin(x1) * sp.cos(x1)),
    (sp.sin(x1 - x2), sp.sin(x1) * sp.cos(x2) - sp.cos(x1) * sp.sin(x2)),
    (sp.exp(x1 + 2 * x2), sp.exp(x1) * (sp.cosh(x2) + sp.sinh(x2)) ** 2),
    (sp.tanh(x1), (sp.exp(2 * x1) - 1) / (sp.exp(2 * x1) + 1)),
    (sp.sqrt(x1**2 + x1 * x2) ** 3, (x1**2 + x1 * x2) * sp.sqrt(x1 * (x1 + x2))),
])
def test_transcendental_identities_hold(lhs, rhs):
    assert sp.sympify(lhs) - sp.sympify(rhs) != 0              # not zero as written: the test has work to do
    v = decide_identity(lhs, rhs, simplify=False)
    assert v.holds, v


@pytest.mark.parametrize("lhs, rhs", [
    (sp.sin(x1) + sp.Rational(1, 10**30) * sp.cos(x2), sp.sin(x1)),   # 1e-30 is not 0
    (sp.exp(x1), 1 + x1 + x1**2 / 2),
    (sp.sin(x1) ** 2, sp.sin(x1)),
])
def test_transcendental_non_identities_fail_with_a_point(lhs, rhs):
    v = decide_identity(lhs, rhs)
    assert v.fails and v.witness
    val = complex(sp.N((lhs - rhs).xreplace({symbol(k): sp.Rational(p) for k, p in v.witness.items()}), 40))
    assert abs(val) > 0


def test_what_cannot_be_proved_is_undecided_never_holds():
    v = decide_identity(sp.atan(x1) + sp.atan(1 / x1), sp.pi / 2, simplify=False)   # true for x1 > 0 only
    assert v.status == "undecided" and not v.holds and "not proved" in v.method


def test_exact_generic_rank():
    full = exact_generic_rank(sp.Matrix([[x1, x2], [x1**2, x2]]))
    assert full.rank == 2 and full.error_bound == 0
    low = exact_generic_rank(sp.Matrix([[x1, x2], [x1**2, x1 * x2]]))          # row 2 = x1 · row 1
    assert low.rank == 1 and 0 < low.error_bound < 1e-20
    num = exact_generic_rank(sp.Matrix([[sp.sin(x1), x2], [x1, 1]]))
    assert num.rank == 2 and "floating point" in num.evidence


def test_text_is_never_parsed():
    with pytest.raises(TypeError):
        decide_identity("x1", 0)


# the designs: a PDE that is off by 1e-10·x2 is refused (it was accepted with "[ok] ... checked symbolically")
PEB = System(states=["x1", "x2"], f=["x2", "-x1 + u - 1e-10*x2"], outputs=["y"], h=["x1"], inputs=["u"])


def test_pebo_with_a_tiny_pde_residual_is_refused():
    with pytest.raises(PreconditionError, match=r"PDE .* fails for component 1.*at x2 = \d+"):
        design_pebo(PEB, phi=["x2"], left_inverse=["y", "xi1"], B=["-y + u"])
    with pytest.raises(PreconditionError, match="not a left inverse"):
        design_pebo(System(states=["x1", "x2"], f=["x2", "-x1 + u"], outputs=["y"], h=["x1"], inputs=["u"]),
                    phi=["x2"], left_inverse=["y", "xi1 + 1e-12*y"], B=["-y + u"])


def test_pebo_certificate_states_its_evidence():
    ok = System(states=["x1", "x2"], f=["x2", "-x1 + u"], outputs=["y"], h=["x1"], inputs=["u"])
    d = design_pebo(ok, phi=["x2"], left_inverse=["y", "xi1"], B=["-y + u"])
    by = {c.condition.split(" (")[0]: c for c in d.certificate.checks}
    pde = next(c for k, c in by.items() if "PDE" in k)
    assert pde.holds and pde.evidence and "checked symbolically" not in str(d.certificate)
    assert any(c.status == "assumed" and "exciting" in c.condition for c in d.certificate.checks)
    assert not any(str(c).startswith("[ok]") for c in d.certificate.checks if c.status == "assumed")


def test_an_undecided_identity_makes_the_check_assumed():
    # sqrt(xi1²) = |x2| equals x2 only for x2 > 0: the design cannot decide it, so its certificate must not claim it
    ok = System(states=["x1", "x2"], f=["x2", "-x1 + u"], outputs=["y"], h=["x1"], inputs=["u"])
    d = design_pebo(ok, phi=["x2"], left_inverse=["y", "sqrt(xi1**2)"], B=["-y + u"], estimator=WindowedNLS(window=1.0))
    left = next(c for c in d.certificate.checks if c.condition.startswith("φ^L"))
    assert left.status == "assumed" and "state x2" in left.detail and str(left).startswith("[assumed]")
