"""Sensor fusion at real rates (issue 36): the bundled fusion models run as a user runs them, whole processes timed.

Models: ``quadrotor`` (12 states + the unknown drag kd; gyros and accelerometers 100 Hz, GPS 1 Hz 0.2 s late,
barometer 10 Hz, magnetometer 50 Hz; 2 ms grid, 60 s), ``ins16`` (16-state strapdown INS, IMU inputs at 200 Hz, GPS
5 Hz 0.15 s late, barometer 25 Hz, magnetometer 50 Hz; 5 ms grid, 60 s) and ``ins24`` (PX4 EKF2's 24 states, GPS
position and velocity 5 Hz 0.11 s late, barometer, magnetometer, airspeed 0.1 s late; 5 ms grid, 60 s).

Every command is the one a user types, in a fresh process (``python -m nlobs.cli ...``, the package at this
checkout's ``src``): wall time from start to exit, import, analysis, C generation and compiling included, with the
process's CPU time (user + system, its compiler subprocesses included) and its peak resident memory (the largest
process among it and those it waited for, as the kernel accounts them). Rows (``results/bench_fusion.json``,
the format of ``_common.py``; the peer of a budget row is the issue's budget, the ratio nlobs/budget):

F1  ``nlobs design MODEL --run --json``, cold: an empty compiled-code cache (a fresh ``NLOBS_CACHE_DIR`` per run).
    Target: <= 60 s for a model of 12-16 states.
F2  The same command again, warm: a second process on the cache the cold run filled. Target: <= 20 s (12-16 states).
F3  ``nlobs simulate MODEL --observer ekf --json`` with the file's measurement delays against the same command on a
    temporary copy of the file without its ``delay`` line, both warm (the cache filled by a first run of each,
    reported as "first run"). Target: ratio delayed / undelayed <= 2. The engine is the default ('auto'), as a user
    runs it; since 'auto' may choose CasADi's virtual machine over compiling (and then never compiles, so no later
    process is warm), the undelayed copy is also run with ``--engine c`` (in a cache of its own), reported in the note.
F4  The delayed run of F3 on its own. Target: <= 5 s for 16 states at 12,000 grid points (``ins16``).
F5  The compiled EKF step, in this process: ``nlobs.estimate({"ekf": design}, recording, engine="c")`` on the
    model's 60 s run (the plant alone, simulated with the file's noise, every grid point a row, each output
    present at its own clock's instants), with the automatic EKF design of ``nlobs design``; the first call
    (which compiles) apart, then the best and median of the next calls, per grid interval (the prediction over one
    interval plus the update with whatever is measured then). F5b: the same with every output measured at every
    grid point (a full update each interval). Target: <= 50 us for 16 states.
Peak resident memory of the simulate processes: in the F3/F4 rows (``peak_rss_mb``) and in ``rss``.

Every process gets a timeout (``--timeout``, default 600 s): one that exceeds it is killed and recorded as
"timed out", its time the timeout (a lower bound); a variant that timed out is not repeated.

Run:  .venv/bin/python benchmarks/bench_fusion.py [--quick] [--repeat N] [--models quadrotor,ins16] [--timeout S]
      --quick: one repetition, the smallest model (quadrotor) and the 16-state EKF step.
Results: benchmarks/results/bench_fusion.json (rows of the models measured replace earlier rows of the same
models) and bench_fusion.md (a summary table of the file).
"""

from __future__ import annotations

import argparse
import atexit
import json
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT / "src"))
import _common as cm  # noqa: E402

MODELS = ("quadrotor", "ins16", "ins24")
QUICK = ("quadrotor",)
DESIGN_COLD, DESIGN_WARM, SIM_DELAY, SIM_STEP = 60.0, 20.0, 5.0, 50e-6
DELAY_RATIO = 2.0
WHOLE = "target, whole process on 2 cores"
TMP = Path(tempfile.mkdtemp(prefix="nlobs-bench-fusion-"))
# removed at exit too: registered before nlobs saves its cost model (atexit, into the cache of F5), so it runs after
atexit.register(shutil.rmtree, TMP, ignore_errors=True)


def _commit() -> str:
    def git(*a: str) -> str:
        done = subprocess.run(["git", "-C", str(ROOT), *a], capture_output=True, text=True, check=False, timeout=60)
        return done.stdout.strip()

    head = git("rev-parse", "--short", "HEAD") or "unknown"
    return head + ("+changes" if git("status", "--porcelain", "--untracked-files=no", "src") else "")


def run_process(args: list[str], cache: Path, timeout: float) -> dict[str, Any]:
    """One ``python -m nlobs.cli ARGS`` in its own process group: wall, CPU and peak RSS of the finished child (its
    waited-for subprocesses included), its JSON output when it printed one; killed after `timeout` seconds."""
    env = dict(os.environ, NLOBS_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT / "src"))
    with tempfile.TemporaryFile(dir=TMP) as out, tempfile.TemporaryFile(dir=TMP) as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", "nlobs.cli", *args], stdin=subprocess.DEVNULL, stdout=out,
                                stderr=err, env=env, start_new_session=True)
        timed_out = False
        while True:
            pid, status, ru = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() - t0 > timeout:
                timed_out = True
                os.killpg(proc.pid, signal.SIGKILL)      # the group this call started, nothing else
                pid, status, ru = os.wait4(proc.pid, 0)
                break
            time.sleep(0.005)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)  # reaped here, not by Popen
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read().decode(errors="replace"), err.read().decode(errors="replace")
    rec: dict[str, Any] = {"args": args, "wall": wall, "cpu": ru.ru_utime + ru.ru_stime, "rss_mb": ru.ru_maxrss / 1024,
                           "rc": proc.returncode, "timed_out": timed_out}
    if timed_out:
        rec["error"] = f"timed out after {timeout:g} s (killed; the time is a lower bound)"
    elif proc.returncode != 0:
        rec["error"] = (stderr.strip().splitlines() or [f"exit status {proc.returncode}"])[-1][:300]
    else:
        try:
            rec["json"] = json.loads(stdout)
        except ValueError:
            rec["error"] = "no JSON on stdout"
    return rec


def undelayed_copy(name: str) -> Path:
    """The bundled model's file without its [simulation] `delay` line, as MODEL.toml in a temporary folder (same name,
    everything else the same: checked)."""
    from nlobs.model import bundled_path, load_model

    src = bundled_path(name)
    text = src.read_text()
    kept = [line for line in text.splitlines(keepends=True) if not re.match(r"\s*delay\s*=", line)]
    folder = TMP / f"nodelay-{name}"
    folder.mkdir(exist_ok=True)
    path = folder / f"{name}.toml"
    path.write_text("".join(kept))
    a, b = load_model(src), load_model(path)
    assert a.simulation.delay and not b.simulation.delay, f"{name}: expected delays in the file and none in the copy"
    assert a.system.f == b.system.f and a.system.h == b.system.h and a.simulation.x0 == b.simulation.x0
    return path


def model_info(name: str) -> dict[str, Any]:
    from nlobs.model import load_model

    mf = load_model(name)
    cfg = mf.simulation
    return {"states": mf.system.n_states, "unknown": len(mf.unknown_params), "n": mf.observer_system.n_states,
            "outputs": mf.system.n_outputs, "dt": cfg.dt, "t_final": cfg.t_final,
            "intervals": int(round(cfg.t_final / cfg.dt)), "delay": dict(cfg.delay)}


def _times(recs: list[dict[str, Any]]) -> tuple[float, float]:
    w = [r["wall"] for r in recs]
    return min(w), statistics.median(w)


def _error(recs: list[dict[str, Any]]) -> str | None:
    return next((r["error"] for r in recs if "error" in r), None)


def _cpu(recs: list[dict[str, Any]]) -> str:
    return f"CPU {min(r['cpu'] for r in recs):.1f} s min"


def _label(name: str, info: dict[str, Any]) -> str:
    unk = f" + {info['unknown']} unknown" if info["unknown"] else ""
    return (f"{name} ({info['states']} states{unk}, {info['outputs']} outputs, {info['intervals']:,} intervals of "
            f"{info['dt'] * 1e3:g} ms)")


def design_rows(name: str, info: dict[str, Any], cold: list[dict], warm: list[dict]) -> list[dict[str, Any]]:
    rows = []
    in_range = 12 <= info["n"] <= 16
    for rid, recs, budget, what in (("F1", cold, DESIGN_COLD, "cold cache"), ("F2", warm, DESIGN_WARM, "warm cache")):
        if not recs:
            continue
        err = _error(recs)
        if err is None:
            out = recs[-1]["json"]
            applies = sum(bool(c.get("applies")) for c in out.get("candidates", []))
            best = (out.get("ranking") or ["none"])[0]
            score = next((s for s in out.get("scores", []) if s.get("kind") == best), {})
            rms = f", RMS error {score['rms_error']:.3g}" if isinstance(score.get("rms_error"), (int, float)) else ""
            err = f"{applies}/{len(out.get('candidates', []))} kinds apply, best {best}{rms}; {_cpu(recs)}"
        r = cm.row(rid, f"{_label(name, info)}: nlobs design --run, {what}", nlobs="nlobs design MODEL --run (whole process)",
                   t_nlobs=_times(recs), err_nlobs=err, peer="issue 36 budget", t_peer=(budget, budget), err_peer=WHOLE,
                   kind="nlobs/peer", target=f"<= {budget:g} s (12-16 states)" if in_range else "(report: not 12-16 states)",
                   threshold=1.0 if in_range else None, note=f"{len(recs)} run(s)")
        r["model"] = name
        rows.append(r)
    return rows


def sim_rows(name: str, info: dict[str, Any], delayed: list[dict], plain: list[dict], first: dict[str, dict],
             plain_c: list[dict]) -> list[dict]:
    rows = []
    if not delayed or not plain:
        return rows

    def err_of(recs: list[dict]) -> str:
        e = _error(recs)
        if e:
            return e
        o = recs[-1]["json"]["observers"].get("ekf", {})
        rss = max(r["rss_mb"] for r in recs)
        return f"EKF RMS error {o.get('rms_error', float('nan')):.3g}; {_cpu(recs)}; peak RSS {rss:.0f} MB"

    firsts = "; ".join(f"first run ({k}, fills the cache): {v['wall']:.1f} s" for k, v in first.items())
    compiled = ""
    if plain_c and not _error(plain_c):
        tc = _times(plain_c)
        rss = max(x["rss_mb"] for x in plain_c)
        compiled = (f"; the undelayed copy with --engine c (compiled; 'auto' may run the virtual machine instead): "
                    f"{tc[0]:.2f} s min, {rss:.0f} MB, delayed / that {_times(delayed)[0] / tc[0]:.2f}x")
    groups: dict[float, list[str]] = {}
    for o, d in info["delay"].items():
        groups.setdefault(d, []).append(o)
    delays = "; ".join(f"{', '.join(os_)} {d:g} s" for d, os_ in groups.items())
    r = cm.row("F3", f"{_label(name, info)}: nlobs simulate --observer ekf, delays ({delays}) vs none",
               nlobs="with the file's delays (whole process, warm)", t_nlobs=_times(delayed), err_nlobs=err_of(delayed),
               peer="the same file without `delay` (whole process, warm)", t_peer=_times(plain), err_peer=err_of(plain),
               kind="nlobs/peer", target=f"<= {DELAY_RATIO:g}x the undelayed run", threshold=DELAY_RATIO,
               note=f"{len(delayed)} run(s) each; {firsts}{compiled}")
    r.update(model=name, peak_rss_mb={"delayed": max(x["rss_mb"] for x in delayed), "undelayed": max(x["rss_mb"] for x in plain)})
    if plain_c and not _error(plain_c):
        r["undelayed_engine_c"] = {"min": _times(plain_c)[0], "median": _times(plain_c)[1],
                                   "peak_rss_mb": max(x["rss_mb"] for x in plain_c)}
    rows.append(r)
    target16 = info["n"] == 16 and info["intervals"] == 12000
    r = cm.row("F4", f"{_label(name, info)}: nlobs simulate --observer ekf with the delays",
               nlobs="nlobs simulate MODEL --observer ekf (whole process, warm)", t_nlobs=_times(delayed),
               err_nlobs=err_of(delayed), peer="issue 36 budget", t_peer=(SIM_DELAY, SIM_DELAY), err_peer=WHOLE,
               kind="nlobs/peer", target=f"<= {SIM_DELAY:g} s (16 states, 12,000 points)" if target16 else
               "(report: the 5 s budget is for 16 states at 12,000 points)", threshold=1.0 if target16 else None,
               note=f"{len(delayed)} run(s)")
    r.update(model=name, peak_rss_mb=max(x["rss_mb"] for x in delayed))
    rows.append(r)
    return rows


# -- F5: the compiled EKF step, in this process ---------------------------------------------------------------------

def step_rows(name: str, rounds: int) -> list[dict[str, Any]]:
    import nlobs
    from nlobs.advise import advise

    mf = nlobs.load_model(name)
    cfg = mf.simulation
    info = model_info(name)
    t0 = time.perf_counter()
    adv = advise(mf, kinds=["ekf"], run=False, progress=False)
    design = next(c.design for c in adv.candidates if c.kind == "ekf" and c.applies)
    t_design = time.perf_counter() - t0
    run = nlobs.simulate(mf.true_system, None, t_final=cfg.t_final, dt=cfg.dt, x0=cfg.x0, inputs=dict(cfg.inputs),
                         noise=nlobs.Noise.per_output(dict(cfg.noise)),
                         process_noise=nlobs.ProcessNoise(dict(cfg.process_noise)) if cfg.process_noise else None,
                         seed=cfg.seed, engine="c")
    k = np.rint(run.t / cfg.dt).astype(np.int64)
    y = run.y.copy()
    for j, o in enumerate(mf.system.outputs):
        every = int(round(cfg.sample_period[o] / cfg.dt))
        y[k % every != 0, j] = np.nan
    truth = run.x if not mf.unknown_params else np.column_stack(
        [run.x, np.tile([mf.true_system.params[p] for p in mf.unknown_params], (run.t.size, 1))])
    late = run.t > 10.0
    rows = []
    for rid, yy, what in (("F5", y, "each output at its own clock"), ("F5b", run.y, "every output at every interval")):
        rec = nlobs.Recording.from_arrays(mf.system, run.t, yy, run.u, run.x)
        go = lambda rec=rec: nlobs.estimate({"ekf": design}, rec, engine="c", on_missing="skip")  # noqa: E731
        first = cm.first_call(go)
        res = cm.interleaved({"ekf": go}, rounds)["ekf"]
        n_int = run.t.size - 1
        xhat = res[2].observers["ekf"].xhat
        rms = float(np.sqrt(np.mean(np.sum((xhat[late] - truth[late]) ** 2, axis=1))))
        in_range = info["n"] == 16
        r = cm.row(rid, f"{_label(name, info)}: compiled EKF, one grid interval (prediction + update), {what}",
                   nlobs="nlobs.estimate(engine='c'), per grid interval", t_nlobs=(res[0] / n_int, res[1] / n_int),
                   err_nlobs=f"RMS ‖x̂ − x‖ after 10 s {rms:.3g}; whole run {res[0]:.3g} s; "
                             f"first call {first:.1f} s (builds; compiles unless cached)",
                   peer="issue 36 budget", t_peer=(SIM_STEP, SIM_STEP), err_peer="target (the step in the compiled loop)",
                   kind="nlobs/peer",
                   target="<= 50 us (16 states)" if in_range else "(report: the budget is for 16 states)",
                   threshold=1.0 if in_range else None,
                   note=f"{rounds} call(s) after the first; automatic EKF design of `nlobs design` ({t_design:.1f} s)")
        r.update(model=name, us_per_interval={"min": res[0] / n_int * 1e6, "median": res[1] / n_int * 1e6},
                 first_call_s=first)
        rows.append(r)
        cm.print_row(r)
    return rows


# -- the report ------------------------------------------------------------------------------------------------------

def _mark(r: dict[str, Any]) -> str:
    return {True: " ✔", False: " ✘", None: ""}[r.get("met")]


def write_md(rows: list[dict[str, Any]], extra: dict[str, Any]) -> Path:
    lines = ["# Sensor fusion at real rates (issue 36): `bench_fusion.py`", "",
             f"Rows of the runs of `benchmarks/bench_fusion.py` (each row names its run and the code it measured; the last "
             f"run: `{extra.get('args', '') or '(all)'}` on {cm.machine()['date']}, {os.cpu_count()} CPUs, load average "
             f"{extra.get('load_at_start', float('nan')):.1f} at its start). Whole processes, wall time (min / median); "
             "the ratio is nlobs over the issue's budget (F3: over the undelayed run); ✔/✘ the min against the target.",
             "", "| row | what | nlobs (min / median) | vs | ratio (min / median) | target | details |",
             "|---|---|---|---|---|---|---|"]
    for r in sorted(rows, key=lambda r: (MODELS.index(r["model"]) if r.get("model") in MODELS else 9, r["id"])):
        t = (f"{r['nlobs_min'] * 1e6:.3g} µs / {r['nlobs_median'] * 1e6:.3g} µs" if r["id"].startswith("F5")
             else f"{cm.fmt_time(r['nlobs_min'])} / {cm.fmt_time(r['nlobs_median'])}")
        same = r["peer_min"] == r["peer_median"]
        peer = (f"{r['peer_min'] * 1e6:.3g} µs" if r["id"].startswith("F5") else
                cm.fmt_time(r["peer_min"]) + ("" if same else f" / {cm.fmt_time(r['peer_median'])}"))
        cells = [r["id"], r["what"], t, f"{r['peer']}: {peer}", f"{r['ratio_min']:.3g}× / {r['ratio_median']:.3g}×",
                 r["target"] + _mark(r),
                 r["nlobs_error"] + (f"; vs: {r['peer_error']}" if r["peer"] != "issue 36 budget" else "")
                 + (f" ({r['note']})" if r["note"] else "") + f" [{r.get('run', '?')}; {r.get('commit', '?')}]"]
        lines.append("| " + " | ".join(str(c).replace("|", "\\|") for c in cells) + " |")
    rss = [r for r in rows if r["id"] == "F3" and isinstance(r.get("peak_rss_mb"), dict)]
    if rss:
        lines += ["", "Peak resident memory of the `simulate --observer ekf` processes (MB, largest over the runs; the "
                  "process or one of the processes it waited for, e.g. the C compiler):", ""]
        for r in rss:
            v = {**r["peak_rss_mb"], **({"undelayed --engine c": r["undelayed_engine_c"]["peak_rss_mb"]}
                                         if "undelayed_engine_c" in r else {})}
            lines.append(f"- {r['model']}: " + ", ".join(f"{k} {x:.0f}" for k, x in v.items()))
    path = cm.RESULTS / "bench_fusion.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="one repetition, the smallest model, the 16-state EKF step")
    ap.add_argument("--repeat", type=int, default=3, help="repetitions of every process (min and median reported)")
    ap.add_argument("--models", default="", help=f"comma-separated, from {', '.join(MODELS)} (default: all)")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds after which a process is killed (default 600)")
    ap.add_argument("--rounds", type=int, default=5, help="timed estimate() calls of F5 after the first")
    ap.add_argument("--skip", default="", help="comma-separated parts to leave out: design, simulate, step")
    args = ap.parse_args()
    t_start = time.perf_counter()
    load0 = os.getloadavg()[0]
    models = [m for m in args.models.split(",") if m] or list(QUICK if args.quick else MODELS)
    step_models = [m for m in models if model_info(m)["n"] >= 16] or (["ins16"] if args.quick else [])
    repeat = 1 if args.quick else args.repeat
    rounds = 2 if args.quick else args.rounds
    skip = {s for s in args.skip.split(",") if s}
    info = {m: model_info(m) for m in models}
    runs: list[dict[str, Any]] = []
    design: dict[str, dict[str, list]] = {m: {"cold": [], "warm": []} for m in models}
    sim: dict[str, dict[str, list]] = {m: {"delayed": [], "undelayed": [], "undelayed_c": []} for m in models}
    first: dict[str, dict[str, dict]] = {m: {} for m in models}
    gave_up: set[tuple[str, str]] = set()

    def once(model: str, variant: str, cmd: list[str], cache: Path, store: list | None) -> dict[str, Any] | None:
        if (model, variant) in gave_up:
            return None
        rec = run_process(cmd, cache, args.timeout)
        rec.update(model=model, variant=variant)
        runs.append({k: v for k, v in rec.items() if k != "json"})
        print(f"  {model:<10} {variant:<22} {rec['wall']:8.2f} s wall  {rec['cpu']:8.2f} s CPU  {rec['rss_mb']:7.0f} MB"
              + (f"  [{rec['error']}]" if "error" in rec else ""), flush=True)
        if rec["timed_out"]:
            gave_up.add((model, variant))
        if store is not None:
            store.append(rec)
        return rec

    print(f"bench_fusion: models {', '.join(models)}, {repeat} repetition(s), timeout {args.timeout:g} s per process, "
          f"{os.cpu_count()} CPUs, load average {load0:.1f}", flush=True)
    nodelay = {m: undelayed_copy(m) for m in models}
    sim_cache = {m: TMP / f"sim-{m}" for m in models}
    sim_cache_c = {m: TMP / f"sim-c-{m}" for m in models}   # --engine c apart: 'auto' would then find its build
    try:
        for r in range(repeat):
            if "design" not in skip:
                for m in models:          # interleaved over the models: a burst of load spreads over all of them
                    cache = TMP / f"design-{m}-{r}"
                    once(m, "design cold", ["design", m, "--run", "--json"], cache, design[m]["cold"])
                    once(m, "design warm", ["design", m, "--run", "--json"], cache, design[m]["warm"])
                    shutil.rmtree(cache, ignore_errors=True)
            if "simulate" not in skip:
                for m in models:
                    cmd_d = ["simulate", m, "--observer", "ekf", "--json"]
                    cmd_u = ["simulate", str(nodelay[m]), "--observer", "ekf", "--json"]
                    cmd_c = [*cmd_u, "--engine", "c"]
                    variants = (("simulate delayed", cmd_d, sim_cache[m], "delayed"),
                                ("simulate undelayed", cmd_u, sim_cache[m], "undelayed"),
                                ("simulate undelayed -c", cmd_c, sim_cache_c[m], "undelayed_c"))
                    if r == 0:   # fill the caches: the first run of each compiles (reported apart)
                        for v, cmd, cache, key in variants:
                            rec = once(m, f"{v} (first)", cmd, cache, None)
                            if rec is not None:
                                first[m][key] = rec
                                if rec["timed_out"]:
                                    gave_up.add((m, v))
                    for v, cmd, cache, key in variants:
                        once(m, v, cmd, cache, sim[m][key])
        rows: list[dict[str, Any]] = []
        for m in models:
            rows += design_rows(m, info[m], design[m]["cold"], design[m]["warm"])
            d, u = sim[m]["delayed"], sim[m]["undelayed"]
            # a variant that timed out on its first run was not repeated: the first run is its measurement
            d = d or ([first[m]["delayed"]] if "delayed" in first[m] else [])
            u = u or ([first[m]["undelayed"]] if "undelayed" in first[m] else [])
            rows += sim_rows(m, info[m], d, u, first[m], sim[m]["undelayed_c"])
        for r in rows:
            cm.print_row(r)
        if "step" not in skip:
            os.environ["NLOBS_CACHE_DIR"] = str(TMP / "step")   # this process's compiled code: a cache of its own
            for m in step_models:
                print(f"  F5 {m}: compiled EKF step", flush=True)
                rows += step_rows(m, rounds)
    finally:
        shutil.rmtree(TMP, ignore_errors=True)
    commit = _commit()
    for r in rows:
        r["commit"] = commit
        r["run"] = f"{time.strftime('%Y-%m-%d %H:%M')} `bench_fusion.py {' '.join(sys.argv[1:])}`"
    measured = {(r["id"], r.get("model")) for r in rows}
    old = [r for r in cm.read("bench_fusion") if (r.get("id"), r.get("model")) not in measured]
    rss = {m: {k: max(x["rss_mb"] for x in v) for k, v in sim[m].items() if v} for m in models if any(sim[m].values())}
    extra = {"args": " ".join(sys.argv[1:]), "load_at_start": load0, "load_at_end": os.getloadavg()[0],
             "seconds": time.perf_counter() - t_start, "models": info, "rss": rss, "runs": runs}
    path = cm.write("bench_fusion", old + rows, extra)
    md = write_md(old + rows, extra)
    print(f"\nwrote {path} and {md} ({extra['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
