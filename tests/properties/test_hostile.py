"""The hostile-input suite (issue 10): every case ends in a correct result or a short, clean error,
within a time and memory budget, and never executes code. The cases and the harness are in
hostile_cases.py; they run in a worker process with a memory cap (see there). The slow cases run in
benchmarks/hostile_slow.py.

Cases whose fix is another engineer's (``pending``: "model", "data", "speed") are listed in the
terminal summary and reported as expected failures until their branch is merged; one that passes
is reported as fixed, so the pending list can be trimmed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import hostile_cases as H  # noqa: E402

FAST = [c for c in H.CASES if not c.slow]
RESULTS: dict[str, dict] = {}


@pytest.fixture(scope="module")
def records():
    recs = {r["id"]: r for r in H.run_cases(FAST)}
    RESULTS.update(recs)
    return recs


def test_there_are_at_least_200_cases_of_each_promised_kind():
    kinds = {k: sum(c.kind == k for c in H.CASES) for k in ("toml", "cli", "api")}
    assert len(H.CASES) >= 200 and len(FAST) >= 200, kinds
    assert all(v >= 40 for v in kinds.values()), kinds
    assert sum(c.id.startswith("csv-") for c in H.CASES) >= 30


@pytest.mark.parametrize("case", FAST, ids=[c.id for c in FAST])
def test_hostile_case(case, records):
    rec = records.get(case.id)
    assert rec is not None, "the harness lost this case"
    assert not rec.get("executed"), f"CODE EXECUTED by {case.id}"
    ok = H.verdict(case, rec)
    if not ok and case.pending:
        pytest.xfail(f"pending ({case.pending}'s branch): {rec['outcome']}: {rec.get('message', '')[:200]}")
    assert ok, f"{rec['outcome']} (expected {case.expect}): {rec.get('message', '')}"
