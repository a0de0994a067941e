"""Run every speed benchmark (each in its own process, one after another) and print the docs' speed table (docs/benchmarks.rst).

Runs bench_core.py (P1, P3, P3b), bench_batch.py (P2) and every other ``bench_*.py`` in this folder
(P4 analysis, P6 MHE and whatever the team adds), then ``speed_table.py``. Timings on a shared
machine are noisy: each script interleaves its implementations and reports min and median; run
this on a quiet machine for the docs' speed table.

Run:  .venv/bin/pip install -e '.[bench]'   then   .venv/bin/python benchmarks/run_all.py [--rounds N]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).parent
ROUNDS = {"bench_core.py", "bench_batch.py"}  # the scripts that take --rounds


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, help="interleaved rounds for the scripts that take them")
    args = ap.parse_args()
    scripts = ["bench_core.py", "bench_batch.py"] + sorted(p.name for p in HERE.glob("bench_*.py")
                                                           if p.name not in ("bench_core.py", "bench_batch.py"))
    failed = []
    for name in scripts:
        cmd = [sys.executable, str(HERE / name)] + (["--rounds", str(args.rounds)] if args.rounds and name in ROUNDS else [])
        print(f"\n=== {name} ===", flush=True)
        if subprocess.run(cmd).returncode != 0:
            failed.append(name)
    print("\n=== the speed table of docs/benchmarks.rst ===", flush=True)
    subprocess.run([sys.executable, str(HERE / "speed_table.py")])
    if failed:
        print(f"failed: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
