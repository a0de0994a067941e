"""Benchmark (not a test): how long ``nlobs design NAME --run`` takes for every bundled model.

Usage::

    python benchmarks/bench_design.py [--repeat 2] [--models lorenz,cstr] [--warm] [--json FILE]

Each run is the command a user types, in a fresh process (``python -m nlobs.cli design NAME --run --json``):
the import, the observability analysis, every registered observer kind tried with its automatic tuning, the
comparison simulation (C code generated and compiled for it), and the ranking. By default every run gets an
empty compiled-code cache (``NLOBS_CACHE_DIR``), i.e. a cold start as on a fresh machine; ``--warm`` reuses one
cache across the repeats (the second ``nlobs design`` of the same model). Reported per model: the number of
states, wall time (min and median over the repeats), the CPU time of the child (user + system), how many kinds
apply and the best-ranked one. The target (issue 9): under 10 s for every bundled model with at most 10 states,
on 2 cores. Timings on a shared machine are noisy: the CPU column is the steadier one; runs are interleaved
across models (round-robin over the repeats) so that a burst of load spreads over all of them.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from nlobs.model import bundled_names, load_model  # noqa: E402

TARGET = 10.0


def _child_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def run_once(name: str, cache: str) -> dict:
    env = dict(os.environ, NLOBS_CACHE_DIR=cache, PYTHONPATH=str(ROOT / "src"))
    cpu0 = _child_cpu()
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "nlobs.cli", "design", name, "--run", "--json"], env=env,
                          capture_output=True, text=True)
    wall = time.perf_counter() - t0
    cpu = _child_cpu() - cpu0
    if proc.returncode != 0:
        return {"wall": wall, "cpu": cpu, "error": (proc.stderr.strip().splitlines() or ["?"])[-1]}
    out = json.loads(proc.stdout)
    return {"wall": wall, "cpu": cpu, "applies": sum(c["applies"] for c in out["candidates"]),
            "kinds": len(out["candidates"]), "best": (out.get("ranking") or ["—"])[0]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--models", default="", help="comma-separated names (default: every bundled model)")
    ap.add_argument("--warm", action="store_true", help="reuse one compiled-code cache per model across the repeats")
    ap.add_argument("--json", default="", metavar="FILE", help="also write the results as JSON")
    args = ap.parse_args()
    names = [m for m in args.models.split(",") if m] or list(bundled_names())
    sizes = {n: load_model(n).system.n_states for n in names}
    results: dict[str, list[dict]] = {n: [] for n in names}
    caches = {n: tempfile.mkdtemp(prefix=f"nlobs-bench-{n}-") for n in names}
    for r in range(args.repeat):            # interleaved: one run of every model per round
        for n in names:
            cache = caches[n] if args.warm else tempfile.mkdtemp(prefix=f"nlobs-bench-{n}-{r}-")
            results[n].append(run_once(n, cache))
            print(f"  round {r + 1}/{args.repeat} {n}: {results[n][-1]['wall']:.1f} s", file=sys.stderr, flush=True)
    print(f"nlobs design NAME --run ({'warm' if args.warm else 'cold'} compiled-code cache), {args.repeat} run(s) per model, "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")
    head = f"{'model':<22} {'n':>2} {'wall min':>9} {'wall med':>9} {'CPU min':>8} {'applies':>8}  best on the run"
    print(head + "\n" + "-" * len(head))
    table = []
    for n in names:
        rs = results[n]
        walls, cpus = [x["wall"] for x in rs], [x["cpu"] for x in rs]
        err = next((x["error"] for x in rs if "error" in x), None)
        ok = "" if min(walls) < TARGET or sizes[n] > 10 else "  <-- over the 10 s target"
        last = rs[-1]
        applies = "—" if err else f"{last['applies']}/{last['kinds']}"
        print(f"{n:<22} {sizes[n]:>2} {min(walls):>8.2f}s {statistics.median(walls):>8.2f}s {min(cpus):>7.2f}s {applies:>8}  "
              f"{err or last['best']}{ok}")
        table.append({"model": n, "n_states": sizes[n], "wall_min": min(walls), "wall_median": statistics.median(walls),
                      "cpu_min": min(cpus), **({"error": err} if err else {"applies": last["applies"], "best": last["best"]})})
    over = [t["model"] for t in table if t["wall_min"] >= TARGET and t["n_states"] <= 10]
    print(f"\nover the {TARGET:g} s target (models with ≤ 10 states): {', '.join(over) or 'none'}")
    if args.json:
        Path(args.json).write_text(json.dumps({"cold": not args.warm, "repeat": args.repeat, "results": table}, indent=1))
    return 1 if over else 0


if __name__ == "__main__":
    raise SystemExit(main())
