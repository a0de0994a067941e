"""The practitioners' models of the docs' gallery (issue 38, item 3a): each runs, and each of its claims holds — the OCV
table against SciPy's not-a-knot spline, the map filters' recovery of a resistance, the value of applying a late GPS fix
when it was taken. A claim that fails here fails on its gallery page too."""

from __future__ import annotations

import pytest

from nlobs.examples import EXAMPLES, PRACTICE


@pytest.mark.parametrize("key", sorted(PRACTICE))
def test_each_practitioners_model_runs_and_its_claims_hold(key):
    result = PRACTICE[key].run()
    assert result.key == key and result.claims and result.runs and result.figures
    assert all(c.holds is True for c in result.claims), [str(c) for c in result.claims if c.holds is not True]
    assert "[simulation]" in result.model          # the model file the page shows, to copy


def test_they_are_not_part_of_the_papers_demo():
    assert {"battery", "building", "vehicle"} == set(PRACTICE) and not set(PRACTICE) & set(EXAMPLES)
