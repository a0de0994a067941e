"""Benchmark (not a test): the advisor's time against the number of states (issue 20, SPEC M15).

Usage::

    python benchmarks/bench_advise_scale.py [--sizes 8,20,40] [--repeat 2] [--json FILE]

Model: Lorenz-96 with n sites, x_i' = (x_{i+1} - x_{i-2}) x_{i-1} - x_i + F (F = 8), every other site measured,
written to a model file per n (with a [simulation]: 5 s, dt = 1e-3, samples every 0.02 s, σ = 0.05). For each n,
in a fresh process each time (what a user types): ``nlobs design FILE`` and ``nlobs design FILE --run``, wall and CPU
seconds (min and median over the repeats; cold compiled-code cache), how many kinds apply, the best-ranked one.
The growth exponent is the slope of log(time) against log(n) between the smallest and largest n.
Targets (M15): ``design`` within 30 s and ``design --run`` within 120 s for models up to 20 states, on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def lorenz96(n: int) -> str:
    dyn = "\n".join(f'x{i} = "(x{(i + 1) % n} - x{(i - 2) % n})*x{(i - 1) % n} - x{i} + F"' for i in range(n))
    outs = [f"y{i}" for i in range(0, n, 2)]
    out = "\n".join(f'y{i} = "x{i}"' for i in range(0, n, 2))
    x0 = [8.01] + [8.0] * (n - 1)
    noise = ", ".join(f"{o} = 0.05" for o in outs)
    return (f'name = "lorenz96_{n}"\ndescription = "Lorenz-96, {n} sites, every other site measured"\n'
            f"states = {[f'x{i}' for i in range(n)]}\noutputs = {outs}\n[parameters]\nF = 8.0\n[dynamics]\n{dyn}\n"
            f"[output]\n{out}\n[simulation]\nt_final = 5.0\ndt = 1e-3\nx0 = {x0}\nnoise = {{ {noise} }}\n"
            "sample_period = 0.02\nseed = 1\n")


def _child_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def run_once(path: str, run: bool, timeout: float) -> dict:
    cache = tempfile.mkdtemp(prefix="nlobs-bench-advise-")
    env = dict(os.environ, NLOBS_CACHE_DIR=cache, PYTHONPATH=str(ROOT / "src"))
    args = [sys.executable, "-m", "nlobs.cli", "design", path, "--json"] + (["--run"] if run else [])
    cpu0 = _child_cpu()
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(args, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"wall": timeout, "cpu": None, "error": f"no answer within {timeout:g} s"}
    wall = time.perf_counter() - t0
    cpu = _child_cpu() - cpu0
    if proc.returncode not in (0,):
        return {"wall": wall, "cpu": cpu, "error": (proc.stderr.strip().splitlines() or ["?"])[-1][:200]}
    out = json.loads(proc.stdout)
    return {"wall": wall, "cpu": cpu, "applies": sum(c["applies"] for c in out["candidates"]),
            "best": (out.get("ranking") or ["—"])[0] if run else None}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="8,20,40")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "bench_advise_scale.json"))
    a = ap.parse_args()
    sizes = [int(s) for s in a.sizes.split(",")]
    work = Path(tempfile.mkdtemp(prefix="nlobs-l96-"))
    paths = {}
    for n in sizes:
        paths[n] = str(work / f"lorenz96_{n}.toml")
        Path(paths[n]).write_text(lorenz96(n))
    rows: dict[tuple[int, bool], list[dict]] = {(n, r): [] for n in sizes for r in (False, True)}
    for _ in range(a.repeat):               # interleaved: a burst of load spreads over every size
        for n in sizes:
            for r in (False, True):
                res = run_once(paths[n], r, a.timeout)
                rows[(n, r)].append(res)
                print(f"n = {n:3d} {'design --run' if r else 'design      '}: {res['wall']:7.1f} s wall"
                      + (f", {res['cpu']:.1f} s CPU" if res.get("cpu") is not None else "")
                      + (f"  ERROR {res['error']}" if "error" in res else f"  applies {res['applies']}"
                         + (f", best {res['best']}" if r else "")), flush=True)
    out = {"measured": time.strftime("%Y-%m-%d %H:%M"), "load": os.getloadavg()[0], "model": "Lorenz-96, every other site measured",
           "rows": []}
    for (n, r), rs in rows.items():
        walls = [x["wall"] for x in rs]
        cpus = [x["cpu"] for x in rs if x.get("cpu") is not None]
        out["rows"].append({"n": n, "run": r, "wall_min": min(walls), "wall_median": statistics.median(walls),
                            "cpu_min": min(cpus) if cpus else None, "errors": [x["error"] for x in rs if "error" in x],
                            "applies": rs[-1].get("applies"), "best": rs[-1].get("best")})
    for r in (False, True):
        pts = [(row["n"], row["wall_min"]) for row in out["rows"] if row["run"] == r and not row["errors"]]
        if len(pts) >= 2:
            (n0, t0), (n1, t1) = pts[0], pts[-1]
            out[f"exponent_{'run' if r else 'design'}"] = math.log(t1 / t0) / math.log(n1 / n0)
    print(json.dumps({k: v for k, v in out.items() if k.startswith("exponent")}))
    Path(a.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
