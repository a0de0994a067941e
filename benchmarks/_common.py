"""Shared helpers of the speed benchmarks: interleaved timing, the result rows, the JSON they are written to.

Every benchmark script writes ``benchmarks/results/<script>.json`` as ``{"machine": {...}, "rows": [ROW, ...]}``
with one ROW per line of the speed table in docs/benchmarks.rst::

    {"id": "P1", "what": "...", "nlobs": "label", "nlobs_min": s, "nlobs_median": s, "nlobs_error": "...",
     "peer": "label", "peer_min": s, "peer_median": s, "peer_error": "...",
     "ratio_min": x, "ratio_median": x, "ratio_kind": "nlobs/peer" | "peer/nlobs",
     "target": "<= 1.3x C", "met": true/false/null, "note": "..."}

``speed_table.py`` turns all of them into the table. Scripts written by others (P4, P6) may write
the same format; ``run_all.py`` runs every ``bench_*.py``.
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

RESULTS = Path(__file__).with_name("results")


#: Seconds of untimed calls before each timed one with ``warm=True`` (see :func:`interleaved`).
WARM_S = 0.02


def interleaved(fns: Mapping[str, Callable[[], Any]], rounds: int, pause: float = 0.05,
                warm: bool = False) -> dict[str, tuple[float, float, Any]]:
    """Time implementations round by round (A, B, C, A, B, C, ...) so machine noise hits them alike;
    return (min, median, last output) per implementation.

    `warm`: each timed call follows untimed calls of the same implementation for at least WARM_S seconds (at least
    one), so that it runs with its own code and data in the caches and the core at the clock a loop of calls reaches,
    as a call in a loop does. After the pause another implementation's run has evicted the caches and the core has
    slowed down: one warm call leaves a call of a few hundred microseconds timed at the lower clock, which a call of
    milliseconds outlasts (measured on the 2-core machine: nlobs's P3 EKF 347 µs after one warm call, 292 µs after
    20 ms of them, no change beyond; dynamax's 3.16 ms and 3.09 ms)."""
    times: dict[str, list[float]] = {k: [] for k in fns}
    outs: dict[str, Any] = {}
    for _ in range(rounds):
        for k, fn in fns.items():
            time.sleep(pause)  # let another implementation's worker threads (JAX/XLA spin-waits) go idle first
            if warm:
                until = time.perf_counter() + WARM_S
                fn()
                while time.perf_counter() < until:
                    fn()
            t0 = time.perf_counter()
            outs[k] = fn()
            times[k].append(time.perf_counter() - t0)
    return {k: (min(v), statistics.median(v), outs[k]) for k, v in times.items()}


def first_call(fn: Callable[[], Any]) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def machine() -> dict[str, Any]:
    import casadi
    import numpy

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return {"python": platform.python_version(), "machine": platform.machine(), "numpy": numpy.__version__,
            "casadi": casadi.__version__, "load_1min_at_start": load, "date": time.strftime("%Y-%m-%d %H:%M")}


def row(id_: str, what: str, *, nlobs: str, t_nlobs: tuple[float, float], err_nlobs: str, peer: str,
        t_peer: tuple[float, float], err_peer: str, kind: str, target: str, threshold: float | None,
        note: str = "") -> dict[str, Any]:
    """One table row; the ratio is nlobs/peer (lower is better) or peer/nlobs (higher is better)."""
    if kind == "nlobs/peer":
        r = (t_nlobs[0] / t_peer[0], t_nlobs[1] / t_peer[1])
        met = None if threshold is None else r[0] <= threshold
    else:
        r = (t_peer[0] / t_nlobs[0], t_peer[1] / t_nlobs[1])
        met = None if threshold is None else r[0] >= threshold
    return {"id": id_, "what": what, "nlobs": nlobs, "nlobs_min": t_nlobs[0], "nlobs_median": t_nlobs[1],
            "nlobs_error": err_nlobs, "peer": peer, "peer_min": t_peer[0], "peer_median": t_peer[1], "peer_error": err_peer,
            "ratio_min": r[0], "ratio_median": r[1], "ratio_kind": kind, "target": target, "met": met, "note": note}


def fmt_time(s: float) -> str:
    return f"{s * 1e3:.3g} ms" if s < 1 else f"{s:.3g} s"


def print_row(r: Mapping[str, Any]) -> None:
    mark = {True: "MET", False: "MISSED", None: ""}[r["met"]]
    print(f"  {r['id']}: {r['nlobs']}: {fmt_time(r['nlobs_min'])} min / {fmt_time(r['nlobs_median'])} median  [{r['nlobs_error']}]")
    print(f"      vs {r['peer']}: {fmt_time(r['peer_min'])} / {fmt_time(r['peer_median'])}  [{r['peer_error']}]")
    print(f"      ratio {r['ratio_kind']} = {r['ratio_min']:.3g} (min) / {r['ratio_median']:.3g} (median); "
          f"target {r['target']} {mark}" + (f"  ({r['note']})" if r["note"] else ""))


def read(name: str) -> list[dict[str, Any]]:
    """The rows of the last run of a script (none when there is no result yet)."""
    try:
        return list(json.loads((RESULTS / f"{name}.json").read_text()).get("rows", []))
    except (OSError, ValueError, AttributeError):
        return []


def write(name: str, rows: list[dict[str, Any]], extra: Mapping[str, Any] | None = None) -> Path:
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / f"{name}.json"
    path.write_text(json.dumps({"machine": machine(), "rows": rows, **(extra or {})}, indent=2))
    return path
