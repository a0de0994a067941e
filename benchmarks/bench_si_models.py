"""Benchmark (not a test): nlobs on StructuralIdentifiability.jl's benchmark models, against SI.jl's published times.

Usage::

    python benchmarks/bench_si_models.py [--models k1,k2] [--timeout 120] [--what global,functions]
                                         [--json benchmarks/results/si_models.json] [--fresh]
    python benchmarks/bench_si_models.py fields [--models k1,k2] [--timeout 300]
    python benchmarks/bench_si_models.py report [--json benchmarks/results/si_models.json]

The models are ``benchmarks/si_models.py`` (transcribed from SI.jl's ``benchmarking/benchmarks.jl``; keys as
there). For every model and every part of ``--what``, one child process (its own session, so that on the
time limit the whole process group goes, msolve/Singular included) runs, one at a time:

- ``global``: ``nlobs.analysis.global_identifiability(system, unknown_params="all")``;
- ``functions``: ``nlobs.analysis.find_identifiable_functions(system, with_states=True, reparametrize_model=False)``
  (SI.jl's published benchmark is ``find_identifiable_functions`` with states).

Measured in the child around the call only, after a warm-up call of the same part on a two-state model that is
not a benchmark model (the lazy imports and caches; SI.jl's published times are after a warm-up too): wall seconds, CPU seconds of the process and its
finished children (``getrusage`` RUSAGE_SELF + RUSAGE_CHILDREN, user + system: the Gröbner engines run as
subprocesses), and peak RSS (``ru_maxrss`` of the process and of its largest child, MB; of the whole process,
imports included; a child's figure includes the Python pages it had when forked, before exec). Also the verdicts, the route (``method``), notes and refusals. The parent records "timeout"
when the wall-clock limit is hit and "error: <message>" (with the traceback's last lines) when the child fails.
At the limit, before the kill, it records where the time went (``at_limit``: every process of the child's tree, the
nlobs frames of each Python one read with ``py-spy dump`` when py-spy is installed beside the interpreter, the
``route`` argument, and the engine processes with their age) and says it in words (``stage``: route and step, e.g.
"SIAN: Gröbner basis and normal forms (msolve running for 540 s)"); the report prints it for every stopped row, with
what SI.jl's own dated runs say of the model (``SI_OWN_RUNS``).

Records go to the JSON (``{"machine": ..., "rows": [...]}``, via ``_common.write`` when the file is in
``benchmarks/results``), one row per (model, part), rewritten after every row; rows of models not run this time
are kept unless ``--fresh``. ``report`` writes ``si_models.md`` next to the JSON. SI.jl's times are the published
ones (not rerun here). The machine is shared: compare CPU seconds; start the run under ``nice``.

``fields`` compares every finished ``functions`` row with SI.jl's published generators (``si_published.py``):
do both generate the same field? The check is the tests' independent one (``_same_field`` of
``tests/analysis/test_global.py``: SymPy over QQ, each generator constant on the fibre of the other set through
a rational point), not nlobs's; ``--timeout`` bounds it per model. The answer goes into the row
(``same_field``: True, False, or why it was not checked) and into the report's column.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import signal
import subprocess
import sys
import time
import traceback
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
HERE = ROOT / "benchmarks"
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(HERE))

import si_models
import si_published
from _common import RESULTS, machine, write

PARTS = ("global", "functions")
HEADER = ("| model | size | SI.jl functions s | nlobs global wall s (CPU s) | nlobs functions wall s (CPU s) "
          "| ratio functions CPU / SI.jl | route | status | same field as SI.jl's | machine: reference call CPU ms |")
DEFAULT_JSON = RESULTS / "si_models.json"
#: SI.jl's own runs of the models its published table leaves out: quoted from the dated result files beside that
#: table (``benchmarking/IdentifiableFunctions/benchmark_result_<date>.md``, same commit), not rerun here. "-" in
#: those files is a run that did not finish within the file's timeout.
_SI_600 = ("SI.jl's own runs did not finish it within 600 s in any strategy (`benchmark_result_01-09-23.md`, "
           "`07-09-23`, `13-09-23-I`)")
_SI_LATER = "not in any of SI.jl's dated result files (added to benchmarks.jl after them): no SI.jl time exists"
SI_OWN_RUNS = {
    "qwwc": _SI_600 + "; with a 6000 s limit: with states 1,323-1,361 s, parameters only 764-824 s "
                      "(`08-08-23`, `08-08-23-x2`)",
    "tumor_hu": _SI_600 + ", nor within 6000 s (`08-08-23`, `08-08-23-x2`)",
    "tumor_pillis": _SI_600 + ", nor within 6000 s (`08-08-23`, `08-08-23-x2`)",
    "leukaemia_leon2021": _SI_600,
    "clv1_1o": _SI_600,
    "ovarian_follicle": _SI_LATER,
    "chemotherapy": _SI_LATER,
    "covid2": _SI_LATER,
    "eaihrd": _SI_LATER,
}
#: From SI.jl's benchmarking/IdentifiableFunctions/benchmark_result.md (quoted, not measured here).
SI_RUN = ("2023-09-15 (`benchmark_result.md` of SciML/StructuralIdentifiability.jl, "
          "`find_identifiable_functions` with states, `(:normalforms, 2)`, column \"Runtime\"), Intel Xeon "
          "Processor (Icelake), 15 GiB RAM, Julia 1.9.3, Groebner 0.4.3, 7 workers, 600 s timeout")


# ---------------------------------------------------------------------------------------------- child
def _usage() -> tuple[float, float, float]:
    """(CPU seconds of this process and its waited-for children, peak RSS MB of this process, of its largest child)."""
    import resource

    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime, s.ru_maxrss / 1024, c.ru_maxrss / 1024


def _route(method: str) -> str:
    if method.startswith("input-output"):
        return "io"
    if method.startswith("SIAN"):
        return "sian"
    return method[:40]


def _warm_up(part: str) -> tuple[float, float]:
    """One call of the same part on a two-state model that is not a benchmark model: the lazy imports (scipy.sparse
    alone takes 0.3 s on this VM), SymPy's caches and the engine lookup are paid before the timed call, as
    StructuralIdentifiability.jl's published times are taken after a warm-up (Julia's compilation excluded).
    Returns its wall seconds (what a first call costs more) and the CPU seconds of the reference call (the smaller of
    two more identical calls): the same work in every row, whose spread shows how fast the shared machine ran then."""
    from nlobs import System
    from nlobs.analysis import find_identifiable_functions, global_identifiability

    def call() -> None:
        warm = System(states=["x1", "x2"], f=["-(a + b)*x1 + c*x2", "b*x1 - c*x2"], outputs=["y"], h=["x1"],
                      params={"a": 1.0, "b": 1.0, "c": 1.0}, name="warm_up")
        if part == "global":
            global_identifiability(warm, unknown_params="all")
        else:
            find_identifiable_functions(warm, with_states=True, reparametrize_model=False)

    t0 = time.perf_counter()
    call()
    wall = time.perf_counter() - t0
    ref = []
    for _ in range(2):  # the smaller of two: one call alone varies by 1.5x from second to second
        c0, _, _ = _usage()
        call()
        ref.append(_usage()[0] - c0)
    return wall, min(ref)


def child(key: str, part: str) -> dict[str, Any]:
    t_import = time.perf_counter()
    from nlobs.analysis import find_identifiable_functions, global_identifiability

    sys_ = si_models.system(key)
    out: dict[str, Any] = {"import_seconds": time.perf_counter() - t_import}
    out["warm_up_seconds"], out["reference_cpu"] = _warm_up(part)
    c0, _, _ = _usage()
    t0 = time.perf_counter()
    if part == "global":
        res = global_identifiability(sys_, unknown_params="all")
    else:
        res = find_identifiable_functions(sys_, with_states=True, reparametrize_model=False)
    wall = time.perf_counter() - t0
    c1, rss_self, rss_child = _usage()
    out.update(wall=wall, cpu=c1 - c0, rss_mb=rss_self, rss_child_mb=rss_child,
               engine_seconds=getattr(res, "engine_seconds", None), refused=res.refused, notes=list(res.notes))
    if part == "global":
        out.update(method=res.method, route=_route(res.method), engine=res.engine, globally=list(res.globally),
                   locally_only=[(lo.name, lo.solutions) for lo in res.locally_only],
                   non_identifiable=list(res.non_identifiable), undecided=[list(u) for u in res.undecided],
                   rewriting=list(res.rewriting), n_equations=res.n_equations, n_variables=res.n_variables)
    else:
        out.update(method=getattr(res, "method", ""), functions=list(res.functions), complete=res.complete,
                   local_checks=list(res.local_checks))
    return out


# ---------------------------------------------------------------------------------------------- parent
def run_one(key: str, part: str, timeout: float) -> dict[str, Any]:
    m = si_models.MODELS[key]
    row: dict[str, Any] = {"model": key, "name": m["name"], "what": part, "size": _size(m),
                           "si_functions_seconds": m["si_functions_seconds"], "timeout_s": timeout,
                           "date": time.strftime("%Y-%m-%d %H:%M:%S"), "load_1min": os.getloadavg()[0]}
    row["commit"] = _commit()
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, __file__, "child", "--models", key, "--what", part],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        row["process_wall"] = time.perf_counter() - t0
        at_limit = _at_limit(proc.pid)       # where the time went: the processes and Python stacks, before the kill
        for pid in [proc.pid, *[p["pid"] for p in at_limit]]:
            try:   # the child's group, and the groups of the routes it forked (each leads its own: module _budget)
                os.killpg(pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
        proc.communicate()
        row.update(status="timeout", at_limit=at_limit, stage=_stage(at_limit))
        return row
    row["process_wall"] = time.perf_counter() - t0
    lines = [x for x in stdout.splitlines() if x.startswith("RESULT ")]
    if lines:
        row.update(json.loads(lines[-1][len("RESULT "):]))
        row.setdefault("status", "ok")
    else:
        tail = [x for x in stderr.strip().splitlines() if x.strip()]
        row["status"] = "error: " + (tail[-1] if tail else f"exit code {proc.returncode}, no output")
        row["traceback_tail"] = tail[-12:]
    return row


def _descendants(root: int) -> list[tuple[int, int, str, float]]:
    """(pid, parent pid, command line, seconds since start) of every process below `root` (Linux /proc)."""
    hz, up = os.sysconf("SC_CLK_TCK"), float(Path("/proc/uptime").read_text().split()[0])
    procs: dict[int, tuple[int, str, float]] = {}
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
            cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        procs[int(d.name)] = (int(fields[1]), cmd, up - int(fields[19]) / hz)
    out, todo = [], [root]
    while todo:
        parent = todo.pop()
        for pid, (ppid, cmd, age) in sorted(procs.items()):
            if ppid == parent:
                out.append((pid, ppid, cmd, age))
                todo.append(pid)
    return out


def _at_limit(root: int) -> list[dict[str, Any]]:
    """At the time limit: every process of the child's tree, with the Python stack of each Python one (py-spy, when
    installed beside this interpreter; the frames of nlobs only, outermost first, and the `route` argument of the
    innermost frame that has one). The engine subprocesses (msolve, Singular) show as processes with their age."""
    spy = Path(sys.executable).with_name("py-spy")
    out = []
    for pid, ppid, cmd, age in [(root, os.getpid(), "benchmark child", 0.0), *_descendants(root)]:
        p: dict[str, Any] = {"pid": pid, "ppid": ppid, "cmd": cmd[:200], "age_s": round(age, 1)}
        if pid == root or Path(cmd.split(" ")[0]).name.startswith("python"):
            p["python"] = True
            if spy.exists():
                try:
                    dump = subprocess.run([str(spy), "dump", "--pid", str(pid), "--json", "--locals"],
                                          capture_output=True, text=True, timeout=30)
                    frames = json.loads(dump.stdout)[0]["frames"] if dump.returncode == 0 else []
                except (subprocess.TimeoutExpired, ValueError, IndexError, KeyError):
                    frames = []
                mine = [f for f in reversed(frames) if "nlobs" in f["filename"]]
                p["stack"] = [f'{f["name"]} ({f["filename"].split("src/")[-1]}:{f["line"]})' for f in mine]
                routes = [v["repr"].strip('"\'') for f in mine for v in (f.get("locals") or []) if v["name"] == "route"]
                if routes:
                    p["route"] = routes[-1]
        out.append(p)
    return out


#: What the innermost nlobs function of a stack is doing, in words (the first match from the innermost frame on).
STAGES = {
    "_det": "a resultant's determinant (eliminating a state)",
    "_factors": "factoring a resultant",
    "_without_parameter_factor": "dividing a resultant by its factors in the parameters",
    "io_equations": "eliminating the states",
    "wronskian_corank": "the Wronskian of the equations' monomials",
    "state_generators": "the outputs' Lie derivatives (with states)",
    "fibre": "the fibre of the route's generators",
    "_complete": "the completeness check (counting fibre points)",
    "_completed_on_the_route": "the completeness check on the route's generators",
    "_verified": "verifying candidate functions at fresh points",
    "_select": "selecting generators among the candidates",
    "_Search": "the search for identifiable functions (candidates at random points)",
    "_decide_rewritten": "Gröbner bases and normal forms on the rewritten model",
    "_decide": "Gröbner basis and normal forms",
    "_sian_at_a_random_point": "SIAN's output jets at a random point",
    "_prepare": "SIAN's output jets",
    "_local_of": "the local analysis (ranks of the output jets)",
}


def _names(p: dict[str, Any]) -> list[str]:
    return [s.split(" (")[0] for s in p.get("stack", [])]


def _route_of(p: dict[str, Any], others: list[dict[str, Any]]) -> str:
    """The `route` argument py-spy read; for rows taken without locals, the input-output route when its elimination is
    on the stack, SIAN when another process of the same race is on that route."""
    if p.get("route"):
        return p["route"]
    if any(n in ("_prepare_io", "io_equations") for n in _names(p)):
        return "io"
    # race_routes writes `race(lambda: <io route>,` on its call's first line and `lambda: <SIAN>` on the next
    lines = {s.split(" (")[0]: int(s.rsplit(":", 1)[1].rstrip(")")) for s in p.get("stack", [])}
    if "race_routes" in lines and "race_routes.<locals>.<lambda>" in lines:
        return {0: "io", 1: "sian"}.get(lines["race_routes.<locals>.<lambda>"] - lines["race_routes"], "")
    racing = [q for q in others if q is not p and "race_routes" in _names(q) and _working(q)]
    return "sian" if any(_route_of(q, []) == "io" for q in racing) else ""


def _working(p: dict[str, Any]) -> bool:
    names = _names(p)
    return bool(names) and "guard_group" not in names[-1:] and names[-1:] != ["race"]  # watchers; a parent waiting


def _phrase(p: dict[str, Any], engines: list[dict[str, Any]], others: list[dict[str, Any]]) -> str:
    names = _names(p)
    if not _working(p):
        return ""
    what = next((w for n in reversed(names) for k, w in STAGES.items() if n == k or n.startswith(k + ".")),
                names[-1])
    route = {"io": "input-output route", "sian": "SIAN"}.get(_route_of(p, others), "")
    run = ", ".join(f'{Path(e["cmd"].split(" ")[0]).name} running for {e["age_s"]:.0f} s' for e in engines)
    return f"{route + ': ' if route else ''}{what}" + (f" ({run})" if run else "")


def _stage(at_limit: list[dict[str, Any]]) -> str:
    """One line: what each working Python process was doing at the time limit (route and stage, from its stack),
    with the engine processes it was waiting on and their age."""
    def python(p: dict[str, Any]) -> bool:
        return p["cmd"] == "benchmark child" or Path(p["cmd"].split(" ")[0]).name.startswith("python")

    parts = []
    for p in at_limit:
        if python(p):
            engines = [e for e in at_limit if e["ppid"] == p["pid"] and not python(e) and "py-spy" not in e["cmd"]]
            ph = _phrase(p, engines, at_limit)
            if ph:
                parts.append(ph)
    return "; ".join(dict.fromkeys(parts)) or "not recorded"


@functools.lru_cache(maxsize=1)
def _commit() -> str:
    """The commit of the tree this benchmark file is in (the code measured, with ``PYTHONPATH`` at its ``src``), and
    "+changes" when that tree has uncommitted changes."""
    def git(*a: str) -> str:
        return subprocess.run(["git", "-C", str(ROOT), *a], capture_output=True, text=True, check=False).stdout.strip()

    head = git("rev-parse", "--short", "HEAD") or "unknown"
    return head + ("+changes" if git("status", "--porcelain", "--untracked-files=no", "src") else "")


def _size(m: dict[str, Any]) -> str:
    return f'{len(m["states"])}x{len(m["params"])}x{len(m["outputs"])}x{len(m["inputs"])}'


@functools.lru_cache(maxsize=1)
def _host() -> dict[str, Any]:
    """What _common.machine() leaves out: platform, CPU count, niceness, the Gröbner engines found."""
    info: dict[str, Any] = {"platform": platform.platform(), "cpus": os.cpu_count(), "python": sys.version.split()[0],
                            "nice": os.nice(0)}
    try:
        from nlobs.algebra._groebner import GroebnerEngine, available_engines

        info["engines"] = {n: GroebnerEngine(n, p).version() for n, p in available_engines().items()}
    except Exception as e:  # noqa: BLE001 - informational only
        info["engines"] = f"unknown ({e})"
    return info


def _save(path: Path, rows: list[dict[str, Any]], extra: dict[str, Any]) -> None:
    if path.parent.resolve() == RESULTS.resolve() and path.suffix == ".json":
        write(path.stem, rows, extra)
    else:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"machine": machine(), "rows": rows, **extra}, indent=2, default=str))


def _field_checker() -> Any:
    import importlib.util

    spec = importlib.util.spec_from_file_location("nlobs_test_global", ROOT / "tests" / "analysis" / "test_global.py")
    mod = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(ROOT / "tests" / "analysis"))
    spec.loader.exec_module(mod)
    return mod._same_field


def fields(keys: list[str], timeout: float, path: Path) -> None:
    """The ``fields`` mode (module docstring): same field as SI.jl's published generators, per finished row."""
    data = json.loads(path.read_text())
    same_field = _field_checker()

    def stop(*_: Any) -> None:
        raise TimeoutError

    signal.signal(signal.SIGALRM, stop)
    for r in data["rows"]:
        k = r["model"]
        if r["what"] != "functions" or k not in keys:
            continue
        m = si_models.MODELS[k]
        if r.get("status") != "ok" or r.get("refused") or r.get("complete") is not True:
            r["same_field"] = "-"
        elif k not in si_published.PUBLISHED:
            r["same_field"] = "not published"
        elif "2023 model file" in m["note"]:
            r["same_field"] = "published for another model"
        else:
            names = [*m["states"], *m["params"], *m["inputs"]]
            t0 = time.perf_counter()
            signal.alarm(int(timeout))
            try:
                r["same_field"] = bool(same_field(r["functions"], si_published.PUBLISHED[k], names))
            except TimeoutError:
                r["same_field"] = f"not checked (SymPy took over {timeout:g} s)"
            finally:
                signal.alarm(0)
            print(f"{k:22s} same field: {r['same_field']} ({time.perf_counter() - t0:.1f} s)", flush=True)
    _save(path, data["rows"], {x: v for x, v in data.items() if x not in ("machine", "rows")})
    print(f"written {path}")


def carry_field_check(old: list[dict[str, Any]], row: dict[str, Any]) -> None:
    """Keep the `fields` verdict of the model's previous functions row when the new row has the same generators: the
    check's only input is the generator list (and SI.jl's published one), so its answer is the same. Marked with
    the date of the row it came from."""
    if row.get("what") != "functions" or row.get("status") != "ok":
        return
    for prev in old:
        if (prev.get("model"), prev.get("what")) == (row["model"], "functions") and "same_field" in prev \
                and prev.get("functions") == row.get("functions"):
            row["same_field"] = prev["same_field"]
            row["same_field_from"] = prev.get("same_field_from", prev.get("date"))


def run(keys: list[str], parts: list[str], timeout: float, path: Path, fresh: bool) -> None:
    old: list[dict[str, Any]] = []
    if path.exists() and not fresh:
        old = json.loads(path.read_text()).get("rows", [])
    todo = {(k, p) for k in keys for p in parts}
    rows = [r for r in old if (r.get("model"), r.get("what")) not in todo]
    extra = {"source": si_models.SOURCE, "si_run": SI_RUN, "args": " ".join(sys.argv[1:]), "host": _host()}
    for k in keys:
        for p in parts:
            r = run_one(k, p, timeout)
            carry_field_check(old, r)
            rows.append(r)
            _save(path, rows, extra)
            shown = (f'{r["wall"]:.2f} s wall, {r["cpu"]:.2f} s CPU, {r.get("rss_mb", 0):.0f} MB'
                     if r["status"] == "ok" else r["status"][:150])
            print(f'{k:22s} {p:9s} {shown}  {r.get("route", "")} {("REFUSED: " + r["refused"][:80]) if r.get("refused") else ""}',
                  flush=True)
    print(f"written {path}")


# ---------------------------------------------------------------------------------------------- report
def _cell(r: dict[str, Any] | None) -> str:
    if r is None:
        return "-"
    if r["status"] == "ok":
        return f'{r["wall"]:.2f} ({r["cpu"]:.2f})' + (" refused" if r.get("refused") else "")
    if r["status"] == "timeout":
        return f'> {r["timeout_s"]:g} (timeout)'
    return "error"


def _machine(r: dict[str, Any] | None) -> str:
    """CPU ms of the functions row's reference call (the same work in every row: how fast the machine ran then)."""
    if not r or not r.get("reference_cpu"):
        return "-"
    return f'{1000 * r["reference_cpu"]:.0f}'


def _commits(rows: list[dict[str, Any]]) -> str:
    counts: dict[str, int] = {}
    for r in rows:
        counts[r.get("commit", "not recorded")] = counts.get(r.get("commit", "not recorded"), 0) + 1
    return ", ".join(f"{c} ({n} rows)" for c, n in sorted(counts.items(), key=lambda kv: -kv[1]))


def _spread(rows: list[dict[str, Any]]) -> str:
    refs = sorted(1000 * r["reference_cpu"] for r in rows if r.get("reference_cpu") and r.get("what") == "functions")
    if not refs:
        return "not measured in this file's rows"
    return (f"{refs[0]:.0f}-{refs[-1]:.0f} ms over the {len(refs)} functions rows that have it, median "
            f"{refs[len(refs) // 2]:.0f}")


def report(path: Path) -> Path:
    data = json.loads(path.read_text())
    rows = data["rows"]
    by = {(r["model"], r["what"]): r for r in rows}
    mach = {**data.get("machine", {}), **data.get("host", {})}
    dates = sorted(r.get("date", "") for r in rows) or [""]
    intro = (f"Models: `benchmarks/si_models.py`, transcribed from {data.get('source', si_models.SOURCE)} "
             f"`{si_models.FILE}`. **SI.jl's times are the published ones, not rerun here**: "
             f"{data.get('si_run', SI_RUN)}. SI.jl's runtime is the wall time of one call after a warm-up (Julia "
             "compilation excluded).")
    warmed = [r["warm_up_seconds"] for r in rows if r.get("warm_up_seconds") is not None]
    warm = (f"the timed call after a warm-up call of the same part on a two-state model in the same process "
            f"({len(warmed)} of {len(rows)} rows; the warm-up took {min(warmed):.2f}-{max(warmed):.2f} s wall, what a "
            "first call costs more)" if warmed else "no warm-up: the first call pays the lazy imports")
    how = (f"nlobs: run {dates[0]} to {dates[-1]} on a shared {mach.get('cpus', '?')}-CPU machine "
           f"({mach.get('platform', mach.get('machine', '?'))}, Python {mach.get('python', '?')}, engines: "
           f"{mach.get('engines', '?')}), one model at a time, each part in its own process, args "
           f"`{data.get('args', '')}`, {warm}; code: {_commits(rows)}. Wall s (CPU s): CPU is the process plus its Gröbner-engine subprocesses, user + "
           "system, the fair measure on a shared machine. Global: `global_identifiability(system, "
           "unknown_params=\"all\")`; functions: `find_identifiable_functions(system, with_states=True, "
           "reparametrize_model=False)`. Size: states x params x outputs x inputs. Ratio: nlobs functions CPU s / "
           "SI.jl's published runtime; above 3 in bold. Route: the global check's (io = input-output equations, "
           "sian = SIAN). Machine: the CPU time of the functions row's reference call (the warm-up model again, the "
           f"same work in every row; {_spread(rows)}). The VM's speed varies by up to 2x over a day (Modified LV, "
           "same code: 0.15 s CPU in one hour, 0.29 s in another): compare rows at similar reference times, and read "
           "a ratio measured at a slow hour with that in mind; the ratio itself is not corrected. Same field: the "
           "`fields` mode's independent SymPy check; a verdict is carried over from an earlier row of the model with "
           "the same generators (`same_field_from` in the JSON: the check's only input is the generator list).")
    L = ["# nlobs on StructuralIdentifiability.jl's benchmark models", "",
         f"Written by `python benchmarks/bench_si_models.py report` from `{path.name}`; do not edit by hand.", "",
         intro, "", how, "",
         HEADER,
         "|---|---|---|---|---|---|---|---|---|---|"]
    keys = [k for k in si_models.MODELS if any((k, p) in by for p in PARTS)]
    errors, timeouts, suspicious, refusals = [], [], [], []
    for k in keys:
        m = si_models.MODELS[k]
        g, f = by.get((k, "global")), by.get((k, "functions"))
        si = m["si_functions_seconds"]
        ratio = "-"
        if si and f and f["status"] == "ok" and not f.get("refused"):
            x = f["cpu"] / si
            ratio = f"**{x:.2f}**" if x > 3 else f"{x:.2f}"
        elif si and f and f["status"] == "timeout":
            x = f["timeout_s"] / si
            ratio = f"> {x:.2f}" if x <= 3 else f"**> {x:.2f}**"
        status = []
        for part, r in (("global", g), ("functions", f)):
            if r is None:
                continue
            s = r["status"]
            if s.startswith("error"):
                errors.append((k, part, r))
                s = "error"
            elif s == "timeout":
                if r.get("at_limit"):   # the words of this file's version, for rows taken before
                    r["stage"] = _stage(r["at_limit"])
                elif part == "functions" and g and g["status"] == "timeout" and g.get("at_limit") \
                        and g["timeout_s"] >= r["timeout_s"]:
                    r["stage"] = (f"no stacks taken (an older run); the functions begin with the global check's own "
                                  f"work (the same route, the same Gröbner basis), which did not finish in "
                                  f'{g["timeout_s"]:g} s: {_stage(g["at_limit"])}')
                timeouts.append((k, part, r))
                s = f'stopped at {r["timeout_s"]:g} s in {r["stage"]}' if r.get("stage") else "stopped (stage not recorded)"
            elif r.get("refused"):
                refusals.append((k, part, r))
                s = "refused"
            elif part == "functions" and r.get("complete") is not True:
                suspicious.append((k, r))
                s = f"complete={r.get('complete')}"
            elif part == "functions" and not all(r.get("local_checks", [])):
                suspicious.append((k, r))
                s = "local check failed"
            status.append(f"{part}: {s}")
        route = g.get("route", "") if g and g["status"] == "ok" else ""
        same = f.get("same_field", "-") if f else "-"
        same = {True: "yes", False: "**NO**"}.get(same, same) if isinstance(same, bool) else same
        L.append(f'| {k} ({m["name"]}) | {_size(m)} | {"-" if si is None else f"{si:g}"} | {_cell(g)} | {_cell(f)} | '
                 f'{ratio} | {route} | {"; ".join(status)} | {same} | {_machine(f)} |')
    ok_f = [(k, by[(k, "functions")]) for k in keys if (k, "functions") in by and by[(k, "functions")]["status"] == "ok"
            and not by[(k, "functions")].get("refused") and si_models.MODELS[k]["si_functions_seconds"]]
    L += ["", "## Summary", ""]
    n = {p: sum(1 for k in keys if (k, p) in by) for p in PARTS}
    n_ok = {p: sum(1 for k in keys if (k, p) in by and by[(k, p)]["status"] == "ok" and not by[(k, p)].get("refused"))
            for p in PARTS}
    L.append(f"- global: {n_ok['global']} of {n['global']} finished with verdicts; functions: {n_ok['functions']} of "
             f"{n['functions']} finished with generators.")
    if ok_f:
        rat = sorted(r["cpu"] / si_models.MODELS[k]["si_functions_seconds"] for k, r in ok_f)
        L.append(f"- functions CPU / SI.jl published runtime on the {len(rat)} models both have: median "
                 f"{rat[len(rat) // 2]:.2f}, range {rat[0]:.2f}-{rat[-1]:.2f}; above 3 on "
                 f"{sum(x > 3 for x in rat)}.")
    checked = [by[(k, "functions")].get("same_field") for k in keys if (k, "functions") in by]
    L.append(f"- same field as SI.jl's published generators: {sum(c is True for c in checked)} of "
             f"{sum(isinstance(c, bool) for c in checked)} compared; differ: "
             f"{[k for k in keys if (k, 'functions') in by and by[(k, 'functions')].get('same_field') is False] or 'none'}.")
    L += ["", "## Errors (inside nlobs)", ""]
    L += [f"- {k} {p}: `{r['status'][7:][:300]}`" + ("\n  ```\n  " + "\n  ".join(r.get("traceback_tail", [])[-6:]) + "\n  ```"
                                                   if r.get("traceback_tail") else "") for k, p, r in errors] or ["None."]
    L += ["", "## Timeouts", ""]
    L += ["Where the time went: the stacks of the child's processes at the limit (py-spy; `at_limit` in the JSON), "
          "and the engine processes they were waiting on.", ""] if timeouts else []
    L += [f"- {k} {p}: stopped after {r['timeout_s']:g} s (run {r.get('date', '?')}, code {r.get('commit', '?')}); "
          f"at the limit: {r.get('stage') or 'not recorded (a run before the stacks were taken)'}"
          + (f". {SI_OWN_RUNS[k]}" if k in SI_OWN_RUNS else "") for k, p, r in timeouts] or ["None."]
    L += ["", "## Refused", ""]
    L += [f"- {k} {p}: {r['refused']}" for k, p, r in refusals] or ["None."]
    L += ["", "## Identifiable functions to look at (complete not True, or a local check failed)", ""]
    L += [f"- {k}: complete={r.get('complete')}, local checks {r.get('local_checks')}, functions {r.get('functions')}"
          + (f"; notes: {'; '.join(r.get('notes', []))}" if r.get("notes") else "") for k, r in suspicious] or ["None."]
    diff = [(k, m["note"]) for k, m in si_models.MODELS.items() if "2023 model file" in m["note"] and k in keys]
    if diff:
        L += ["", "## Models whose published time was measured on a different 2023 version (see `si_models.py`)", ""]
        L += [f"- {k}: {note}" for k, note in diff]
    out = path.with_suffix(".md")
    out.write_text("\n".join(L) + "\n")
    print(f"written {out}")
    return out


# ---------------------------------------------------------------------------------------------- main
def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mode", nargs="?", default="run", choices=["run", "report", "child", "fields"])
    ap.add_argument("--models", default="", help="comma-separated keys of si_models.MODELS (default: all)")
    ap.add_argument("--timeout", type=float, default=120.0, help="wall-clock seconds per model and part")
    ap.add_argument("--what", default="global,functions", help="global, functions or both, comma-separated")
    ap.add_argument("--json", default=str(DEFAULT_JSON), help="results file")
    ap.add_argument("--fresh", action="store_true", help="drop the rows of models not run this time")
    args = ap.parse_args()
    path = Path(args.json)
    if not path.is_absolute():
        path = Path.cwd() / path
    if args.mode == "report":
        report(path)
        return 0
    keys = [k for k in args.models.split(",") if k] or list(si_models.MODELS)
    unknown = [k for k in keys if k not in si_models.MODELS]
    if unknown:
        ap.error(f"unknown models {unknown}; known: {', '.join(si_models.MODELS)}")
    parts = [p for p in args.what.split(",") if p]
    if any(p not in PARTS for p in parts):
        ap.error(f"--what takes {', '.join(PARTS)}")
    if args.mode == "fields":
        fields(keys, args.timeout, path)
        return 0
    if args.mode == "child":
        try:
            out = child(keys[0], parts[0])
        except Exception as e:  # noqa: BLE001 - an error inside nlobs is a result
            tb = traceback.format_exc().strip().splitlines()
            out = {"status": f"error: {type(e).__name__}: {e}"[:2000], "traceback_tail": tb[-12:]}
        print("RESULT " + json.dumps(out, default=str), flush=True)
        return 0
    run(keys, parts, args.timeout, path, args.fresh)
    return 0


if __name__ == "__main__":
    sys.exit(main())
