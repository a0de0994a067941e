"""Benchmark (not a test): how `nlobs.analyze` grows with the number of states (SPEC P4).

Usage::

    python benchmarks/bench_scale.py [--quick]

Each case runs in its own process (so peak memory is its own), timed with wall clock and
CPU time, and its peak resident memory read from ``getrusage``. The growth exponent is the
least-squares slope of log(time) against log(n) over the two largest sizes of each family.
Families:

- ``linear``: the chain x_i' = x_{i+1} - x_i, y = x1 (affine in the unknowns: the rows of the
  jets' Jacobian are C A^k, one sparse product per order; the rank costs O(n³));
- ``linear, k unknown``: the same chain with x_i' = x_{i+1} - k x_i and k unknown (not affine: the
  dual-number power series, with k·x a scalar product per order: O(n · nnz · n));
- ``polynomial``: x_i' = x_{i+1} - k_i x_i², k_1 unknown (squares of series: O(n⁴)).

Target (SPEC P4): a 1,000-state model in < 10 s and < 2 GB.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import textwrap
from pathlib import Path

SRC = str(Path(__file__).resolve().parents[1] / "src")
sys.path.insert(0, str(Path(__file__).parent))
from _common import row, write  # noqa: E402

CASE = textwrap.dedent("""
    import json, resource, sys, time
    sys.path.insert(0, {src!r})
    from nlobs import System, analyze
    kind, n = {kind!r}, {n}
    xs = [f"x{{i}}" for i in range(1, n + 1)]
    if kind == "linear":
        f = [f"x{{i + 1}} - x{{i}}" for i in range(1, n)] + [f"-x{{n}}"]
        params, unknown = {{}}, []
    elif kind == "linear, k unknown":
        f = [f"x{{i + 1}} - k*x{{i}}" for i in range(1, n)] + [f"-x{{n}}"]
        params, unknown = {{"k": 0.5}}, ["k"]
    else:
        f = [f"x{{i + 1}} - k{{i}}*x{{i}}**2" for i in range(1, n)] + [f"-x{{n}}*x1"]
        params, unknown = {{f"k{{i}}": 1 + i / 10 for i in range(1, n)}}, ["k1"]
    s = System(states=xs, f=f, outputs=["y"], h=["x1"], params=params)
    t0, c0 = time.perf_counter(), time.process_time()
    rep = analyze(s, unknown_params=unknown)
    print(json.dumps({{"rank": rep.rank, "unknowns": len(rep.unknowns), "wall": time.perf_counter() - t0,
                      "cpu": time.process_time() - c0,
                      "rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6}}))
""")


def run(kind: str, n: int) -> dict:
    out = subprocess.run([sys.executable, "-c", CASE.format(src=SRC, kind=kind, n=n)], capture_output=True, text=True)
    if out.returncode:
        return {"error": out.stderr.strip().splitlines()[-1] if out.stderr else f"exit {out.returncode}"}
    return json.loads(out.stdout)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller sizes only")
    args = ap.parse_args()
    families = {
        "linear": [125, 250, 500, 1000],
        "linear, k unknown": [125, 250, 500, 1000],
        "polynomial": [25, 50, 100, 200],
    }
    if args.quick:
        families = {k: v[:3] for k, v in families.items()}
    print(f"{'family':<20}{'n':>6}{'rank':>7}{'wall s':>9}{'cpu s':>8}{'peak GB':>9}")
    table = []
    for kind, sizes in families.items():
        rows = []
        for n in sizes:
            r = run(kind, n)
            if "error" in r:
                print(f"{kind:<20}{n:>6}  failed: {r['error']}")
                continue
            rows.append((n, r))
            print(f"{kind:<20}{n:>6}{r['rank']:>4}/{r['unknowns']:<4}{r['wall']:>7.2f}{r['cpu']:>8.2f}{r['rss_gb']:>9.2f}")
        if len(rows) >= 2:
            (n1, a), (n2, b) = rows[-2], rows[-1]
            e = math.log(b["cpu"] / a["cpu"]) / math.log(n2 / n1)
            em = math.log(b["rss_gb"] / a["rss_gb"]) / math.log(n2 / n1)
            print(f"{'':<20}growth exponent (cpu time, n = {n1} -> {n2}): {e:.2f}; memory: {em:.2f}")
            if kind != "polynomial":  # SPEC P4 is stated for chains of 1,000 states: a budget, not a peer
                table.append(row("P4", f"analyze, {kind} chain, {n2} states (CPU time; time exponent {e:.2f})",
                                 nlobs=f"nlobs.analyze (peak {b['rss_gb']:.2f} GB)", t_nlobs=(b["cpu"], b["cpu"]),
                                 err_nlobs=f"rank {b['rank']}/{b['unknowns']} (exact generic rank)",
                                 peer="SPEC P4 budget (10 s, 2 GB)", t_peer=(10.0, 10.0), err_peer="-",
                                 kind="nlobs/peer", target="<= 1 (within budget)" if kind == "linear" else "(report: P4 states the linear chain)",
                                 threshold=1.0 if kind == "linear" else None))
    if table and not args.quick:
        write("bench_scale", table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
