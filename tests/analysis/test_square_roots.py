"""Square roots in the generic-rank test (algebra/_series.py): modulo p ≡ 3 (mod 4) only half the elements are
squares, so a random point had a root of k radicands with probability 2^-k, and a chain of twelve Torricelli tanks
(sqrt(h_i)) was refused as "undefined almost everywhere". And on the regime where max(x, 0) = 0, sqrt(max(x, 0)) is
the constant 0, not the root of a vanishing base (which has no derivative there)."""

from __future__ import annotations

import nlobs
from nlobs import System


def _tanks(n: int) -> System:
    """h1' = k u − a √h1, h_i' = a √h_{i−1} − a √h_i, y = h_n: a chain in triangular observable form (each level
    enters the next through a strictly increasing √, so y and its n − 1 derivatives determine h_n, ..., h_1 where all
    h_i > 0; Gauthier & Kupka's triangular form), and with u generic the rate a is identifiable as well."""
    h = [f"h{i}" for i in range(1, n + 1)]
    f = ["k*u - a*sqrt(max(h1, 0))"] + [f"a*sqrt(max(h{i - 1}, 0)) - a*sqrt(max(h{i}, 0))" for i in range(2, n + 1)]
    return System(states=h, inputs=["u"], outputs=["y"], f=f, h=[f"h{n}"], params={"a": 0.3, "k": 0.5})


def test_a_chain_of_twelve_square_roots_is_analysed():
    system = _tanks(12)
    for seed in range(3):
        rep = nlobs.analyze(system, unknown_params=["a"], seed=seed)
        assert rep.rank == 13 and rep.observable, rep


def test_a_root_of_a_branch_at_zero_is_zero():
    tanks = System(states=["x1", "x2"], inputs=["u"], outputs=["y"],
                   f=["k*u - a*sqrt(max(x1, 0))", "a*sqrt(max(x1, 0)) - b*sqrt(max(x2, 0))"], h=["x2"],
                   params={"a": 0.3, "b": 0.2, "k": 0.5})
    # the upper tank empty (max(x1, 0) = 0): x1 enters neither x2' nor y, so it is unobservable (rank 1)
    rep = nlobs.analyze(tanks, regime={"x1": -1.0, "x2": 1.0})
    assert rep.rank == 1 and not rep.observable
    assert rep.observable_states == ("x2",)
    # where it holds water, both levels are observable
    assert nlobs.analyze(tanks, regime={"x1": 2.0, "x2": 1.0}).rank == 2
