"""The large model, cold (issue 43 §5): ``nlobs design ins24 --run`` with an empty compiled-code cache.

The 24-state INS of PX4's EKF2 (``ins24``, 11 outputs, 12,000 intervals of 5 ms): the advisor tries every kind, and
runs the applicable ones (EKF, UKF, SR-UKF, SR-EKF, IEKF) side by side, each compiling its interval run. One fresh
process per row, a fresh ``NLOBS_CACHE_DIR``: wall time, CPU time (user + system, the compiler processes included:
the machine is shared, so the CPU seconds are the steadier figure) and peak resident memory (the largest process among
it and those it waited for), with the candidates ranked and those that did not finish. Targets (issue 43): <= 1 GB
and <= 60 s cold.

Each call appends its row to ``results/bench_large.json`` (date, commit and the source tree measured), so the rows
before and after a change sit side by side; ``--src`` measures another checkout's ``src`` (e.g. an exported commit).
Run:  python benchmarks/bench_large.py [--src PATH --label COMMIT] [--timeout S]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
import _common as cm  # noqa: E402
import bench_fusion as fusion  # noqa: E402

RESULT = cm.RESULTS / "bench_large.json"


def main() -> int:
    ap = argparse.ArgumentParser(description="ins24 design --run, cold")
    ap.add_argument("--src", default=None, help="the src folder to measure (default: this checkout's)")
    ap.add_argument("--label", default=None, help="the commit that src is (default: this checkout's HEAD)")
    ap.add_argument("--timeout", type=float, default=300.0)
    args = ap.parse_args()
    if args.src is not None:
        fusion.ROOT = Path(args.src).resolve().parent   # run_process puts ROOT/src first on the path
    with tempfile.TemporaryDirectory(prefix="nlobs-bench-large-") as cache:
        rec = fusion.run_process(["design", "ins24", "--run", "--json"], Path(cache), args.timeout)
    ranked, unfinished = [], []
    for s in (rec.get("json") or {}).get("scores", []):
        (unfinished if str(s.get("detail", "")).startswith("did not finish") else ranked).append(s.get("kind"))
    row = {"date": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "commit": args.label or fusion._commit(),
           "src": str(Path(args.src).resolve()) if args.src else "this checkout", "command": "nlobs design ins24 --run (cold)",
           "wall_s": round(rec["wall"], 1), "cpu_s": round(rec["cpu"], 1), "peak_rss_mb": round(rec["rss_mb"]),
           "ranked": ranked, "did_not_finish": unfinished, "error": rec.get("error"),
           "load_1min_at_start": cm.machine().get("load_1min_at_start")}
    rows = json.loads(RESULT.read_text())["rows"] if RESULT.exists() else []
    rows.append(row)
    cm.write("bench_large", rows, {"targets": {"peak_rss_mb": 1024, "wall_s": 60}})
    print(f"{row['commit']}: wall {row['wall_s']} s, CPU {row['cpu_s']} s, peak {row['peak_rss_mb']} MB; ranked "
          f"{', '.join(map(str, ranked)) or 'none'}; did not finish: {', '.join(map(str, unfinished)) or 'none'}"
          + (f"; error: {row['error']}" if row["error"] else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
