"""The slow hostile-input cases (long runs, big inputs, time gaps): the same harness and rules as
tests/properties/test_hostile.py, with the cases marked slow in tests/properties/hostile_cases.py.

Run:  .venv/bin/python benchmarks/hostile_slow.py [--all]
Prints the counts and records them in benchmarks/results/hostile_slow.json (--all: every case).
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "properties"))
import hostile_cases as H  # noqa: E402

if __name__ == "__main__":
    chosen = H.CASES if "--all" in sys.argv else [c for c in H.CASES if c.slow]
    s = H.report(chosen, "hostile_slow.json" if "--all" not in sys.argv else "hostile_all.json")
    sys.exit(1 if s["failing"] else 0)
