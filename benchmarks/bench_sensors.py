"""Sensor selection at the issue's sizes (issue 37): ``nlobs sensors MODEL --json`` as a user runs it, whole processes.

Models (written by this script into a temporary folder; the same as the guide's and the tests'):

* ``enzyme``   5 states + the unknown rate k3, 7 candidates (the guide's example), budget 3;
* ``cascade6`` 6 states + the unknown rate k, 7 candidates (tests/analysis/test_sensors.py), budget 3;
* ``net20``    20 states in five strongly connected components, three of them sinks, 20 candidates (one per state),
               budget 6: the pool is over the exhaustive limit, so the minimum-size search and the greedy ranking run.

Every command is ``python -m nlobs.cli sensors MODEL --budget B --json`` in a fresh process (the package at this
checkout's ``src``): wall time from start to exit (imports, the jets, the run's sensitivities with their compiling when
the engine chooses C, every subset's score), with its CPU time and peak resident memory. Cold: an empty compiled-code
cache (a fresh ``NLOBS_CACHE_DIR``); warm: a second process on that cache. Each answer is checked (the minimal sets
of enzyme and cascade6 against the exhaustive SymPy check of the tests, net20's against one sensor per sink
component). Rows (``results/bench_sensors.json``, the format of ``_common.py``; the peer of a row is the issue's
budget, the ratio nlobs/budget):

S1  enzyme, cold and warm. Target: < 5 s (5-6 states, 7 candidates).
S2  cascade6, cold and warm. Target: < 5 s.
S3  net20, cold and warm. Target: < 30 s (20 states, 20 candidates).
S4  nav16, cold and warm (issue 44 item 2): benchmarks/models/car_nav.toml (16 states + ks, IMU inputs, 120 s at
    5 ms) with nine candidates at their own rates (tests/analysis/test_sensors_nav.py). Target: < 30 s and a peak
    RSS under 1 GB (before the VM chunk cap, the cold run's mapaccum over 10,000 steps peaked at 1.59 GB).

Run:  .venv/bin/python benchmarks/bench_sensors.py [--repeat N] [--timeout S]
Results: benchmarks/results/bench_sensors.json and bench_sensors.md.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT / "tests" / "analysis"))

from _common import RESULTS, print_row, row, write  # noqa: E402

TMP = Path(tempfile.mkdtemp(prefix="nlobs-bench-sensors-"))

ENZYME = (ROOT / "docs" / "guide" / "sensors.rst").read_text(encoding="utf-8").split("nlobs.loads_model('''")[1].split(
    "'''")[0].replace("\n   ", "\n")


def _models() -> dict[str, tuple[str, float, set[tuple[str, ...]]]]:
    """name -> (file text, budget, the expected minimal sets)."""
    from test_sensors import GROUPS, NL6, network_text
    from test_sensors_nav import nav_text

    net = {tuple(f"m{i}" for i in c) for c in itertools.product(GROUPS["C"], GROUPS["D"], GROUPS["E"])}
    return {"enzyme": (ENZYME, 3.0, {("P", "Q"), ("P", "total_product"), ("Q", "total_product")}),
            "cascade6": (NL6, 3.0, {("sDF",), ("sD", "sF"), ("sE", "sF"), ("sF", "sCE")}),
            "net20": (network_text(), 6.0, net),
            "nav16": (nav_text(120.0), 12.0, {("gnss_x", "gnss_y", "gnss_z", "wheel"), ("gnss_x", "gnss_y", "wheel", "baro")})}


def _commit() -> str:
    def git(*a: str) -> str:
        return subprocess.run(["git", "-C", str(ROOT), *a], capture_output=True, text=True, check=False).stdout.strip()

    return (git("rev-parse", "--short", "HEAD") or "unknown") + ("+changes" if git("status", "--porcelain",
                                                                                  "--untracked-files=no", "src") else "")


def run_process(args: list[str], cache: Path, timeout: float) -> dict[str, Any]:
    """One ``python -m nlobs.cli ARGS``: wall, CPU and peak RSS of the finished child, its JSON; killed at `timeout`."""
    env = dict(os.environ, NLOBS_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT / "src"))
    with tempfile.TemporaryFile(dir=TMP) as out, tempfile.TemporaryFile(dir=TMP) as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", "nlobs.cli", *args], stdin=subprocess.DEVNULL, stdout=out,
                                stderr=err, env=env, start_new_session=True)
        while True:
            pid, status, ru = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                timed_out = False
                break
            if time.perf_counter() - t0 > timeout:
                os.killpg(proc.pid, signal.SIGKILL)      # the group this call started, nothing else
                pid, status, ru = os.wait4(proc.pid, 0)
                timed_out = True
                break
            time.sleep(0.005)
        wall = time.perf_counter() - t0
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read().decode(errors="replace"), err.read().decode(errors="replace")
    rec: dict[str, Any] = {"wall": wall, "cpu": ru.ru_utime + ru.ru_stime, "rss_mb": ru.ru_maxrss / 1024}
    code = os.waitstatus_to_exitcode(status)
    if timed_out:
        rec["error"] = f"timed out after {timeout:g} s (the time is a lower bound)"
    elif code != 0:
        rec["error"] = (stderr.strip().splitlines() or [f"exit status {code}"])[-1][:300]
    else:
        rec["json"] = json.loads(stdout)
    return rec


def _check(name: str, rec: dict[str, Any], want: set[tuple[str, ...]]) -> str:
    if "error" in rec:
        return rec["error"]
    got = {tuple(sorted(s)) for s in rec["json"]["minimal_sets"]}
    if got != {tuple(sorted(s)) for s in want}:
        return f"WRONG minimal sets: {sorted(got)[:4]} ..."
    out = rec["json"]
    search = out["search"]
    return (f"{len(got)} minimal sets as expected ({'every minimal set' if search['complete'] else 'minimum size, proven' if search['proven_minimum'] else 'not proven'}), "
            f"{search['rank_checks']} ranks; best within {out['budget']:g}: {{{', '.join(out['best']['sensors'])}}}; "
            f"in-process {out['seconds']:.2f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="cold and warm processes per model (default 3)")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds per process (default 300)")
    ap.add_argument("--models", default="", help="comma-separated names to run (default: all); the rows of the others "
                                                  "are kept from the last results file")
    args = ap.parse_args()
    only = [m for m in args.models.split(",") if m]
    rows = []
    if only and (RESULTS / "bench_sensors.json").exists():
        keep = {"enzyme": "S1", "cascade6": "S2", "net20": "S3", "nav16": "S4"}
        ids_run = {keep[m] + s for m in only for s in ("", "w")}
        rows = [r for r in json.loads((RESULTS / "bench_sensors.json").read_text())["rows"] if r["id"] not in ids_run]
    budgets = {"enzyme": 5.0, "cascade6": 5.0, "net20": 30.0, "nav16": 30.0}
    ids = {"enzyme": "S1", "cascade6": "S2", "net20": "S3", "nav16": "S4"}
    for name, (text, budget, want) in _models().items():
        if only and name not in only:
            continue
        path = TMP / f"{name}.toml"
        path.write_text(text, encoding="utf-8")
        cold, warm = [], []
        for _ in range(args.repeat):
            cache = Path(tempfile.mkdtemp(dir=TMP, prefix="cache-"))
            cmd = ["sensors", str(path), "--budget", f"{budget:g}", "--json"]
            cold.append(run_process(cmd, cache, args.timeout))
            warm.append(run_process(cmd, cache, args.timeout))
            shutil.rmtree(cache, ignore_errors=True)
        for kind, recs in (("cold", cold), ("warm", warm)):
            walls = [r["wall"] for r in recs]
            t = (min(walls), statistics.median(walls))
            target = budgets[name]
            r = row(f"{ids[name]}{'' if kind == 'cold' else 'w'}",
                    f"nlobs sensors {name}.toml --budget {budget:g} --json, {kind} ({len(_models()[name][2])} minimal sets)",
                    nlobs=f"whole process, {kind}", t_nlobs=t,
                    err_nlobs=_check(name, recs[-1], want) + (f"; PEAK RSS {max(r['rss_mb'] for r in recs):.0f} MB "
                                                              "OVER 1 GB" if max(r["rss_mb"] for r in recs) > 1024 else ""),
                    peer="issue 37 budget", t_peer=(target, target), err_peer="", kind="nlobs/peer",
                    target=f"< {target:g} s", threshold=1.0,
                    note=f"CPU {statistics.median(r['cpu'] for r in recs):.2f} s, peak RSS "
                         f"{max(r['rss_mb'] for r in recs):.0f} MB, {args.repeat} runs, commit {_commit()}")
            print_row(r)
            rows.append(r)
    path = write("bench_sensors", rows)
    lines = ["| row | what | min | median | budget | met | check |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['id']} | {r['what']} | {r['nlobs_min']:.2f} s | {r['nlobs_median']:.2f} s | {r['target']} | "
                     f"{'yes' if r['met'] else 'NO'} | {r['nlobs_error']} |")
    (RESULTS / "bench_sensors.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"results: {path}")
    shutil.rmtree(TMP, ignore_errors=True)


if __name__ == "__main__":
    main()
