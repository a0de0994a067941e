"""Monte Carlo on every core (issue 43 §2): nlobs.montecarlo on 1..N threads, speed-up and efficiency.

The P2 problem (bench_batch.py): Van der Pol (mu = 1, y = x1) with the observer of bench_core.py (L = 5, xh(0) = 0),
RK4, dt = 1e-3, t in [0, 10], plant initial states uniform in [-3, 3]^2 (seed 20240501), final states only; here
M = 1,000 and 10,000 trajectories, and a second case with measurement noise (a seed per trajectory, so every chunk
also draws its noise inputs). Each is run with ``workers=1`` (the chunks one after another) and ``workers=w`` for
w = 2 .. N (N = the usable cores), interleaved round by round; the chunk size is montecarlo's default for each w.
Reported per case and w: min and median time, speed-up t(1)/t(w) and efficiency t(1)/(w t(w)) of the min times, the
process's CPU time over the wall time of the fastest round (how many cores it had), and whether the result is bit for
bit the serial one. Target (issue 43): speed-up >= 1.8 on 2 cores. Beside it, a projection for dedicated cores from
the CPU times alone (usable when the machine is shared): the serial run's CPU time over (the CPU time spent outside the
chunks + the busiest thread's CPU time in chunks), which is what the wall time would be if every thread had a core and
no chunk waited for Python's lock (an upper bound: a chunk's Python, e.g. drawing its noise, takes turns).

With --dask: the same Monte Carlo on a Dask LocalCluster of W = 1 .. N single-threaded worker processes (chunks sized
by montecarlo for the cluster), its time against the local serial run: efficiency t(serial) / (W t(W)).

First, the lock check: while one chunk runs in another thread (compiled C, then CasADi's VM), how often this thread
runs a Python loop strictly inside that call. A call that held Python's lock would leave it at zero.

On a shared machine the other processes take cores too: the load average at the start is written with the results.
Where the scheduler shares the CPU between sessions (Linux autogroups), a session's threads share its part: threads
then cannot show a speed-up however free of locks they are, and "CPU / wall" below says so.
Run:  python benchmarks/bench_cores.py [--rounds N] [--sizes 1000,10000] [--workers 1,2,4,8,16] [--noise-max M] [--dask]
(--workers: the thread and worker counts timed, default 1 .. N; --noise-max: the largest M of the noise case)
Results: benchmarks/results/bench_cores.json (rows "P2c" for the README's speed table, and the full table).
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import _common as cm  # noqa: E402

import nlobs  # noqa: E402
from nlobs.engine import usable_cores  # noqa: E402
from nlobs.simulate._montecarlo import _Spec  # noqa: E402

#: CPU seconds each thread spent in chunks during the current call (thread id -> seconds), see chunk_cpu
CHUNK_CPU: dict[int, float] = {}
_run_chunk = _Spec.run_chunk


def _timed_chunk(self, j0, j1, *args):
    c0 = time.thread_time()
    try:
        return _run_chunk(self, j0, j1, *args)
    finally:
        tid = threading.get_ident()
        CHUNK_CPU[tid] = CHUNK_CPU.get(tid, 0.0) + time.thread_time() - c0


_Spec.run_chunk = _timed_chunk

DT, T_FINAL, SEED = 1e-3, 10.0, 20240501
N = int(round(T_FINAL / DT))


def lock_check(vdp, obs, engine: str) -> dict:
    """Main-thread loop iterations strictly inside one montecarlo chunk run by another thread."""
    M, t_final = (2000, 10.0) if engine == "c" else (8, 4.0)
    X0 = np.random.default_rng(SEED).uniform(-3, 3, (M, 2))

    def go():
        return nlobs.montecarlo(vdp, {"obs": obs}, t_final=t_final, dt=DT, x0=X0, save_every=N, engine=engine, workers=1, chunk=M)

    go()
    stamps, ticks, done = [], [], threading.Event()

    def body():
        stamps.append(time.perf_counter())
        go()
        stamps.append(time.perf_counter())
        done.set()

    th = threading.Thread(target=body)
    th.start()
    while not done.is_set():
        ticks.append(time.perf_counter())
    th.join()
    t0, t1 = stamps
    inside = sum(1 for t in ticks if t0 + 0.02 < t < t1 - 0.02)
    return {"engine": engine, "call_s": t1 - t0, "iterations_inside": inside}


def on_dask(vdp, obs, sizes, counts, args) -> list[dict]:
    """montecarlo on LocalClusters of `counts` single-threaded worker processes against the local serial run."""
    from dask.distributed import Client, LocalCluster

    out = []
    for M in sizes:
        X0 = np.random.default_rng(SEED).uniform(-3, 3, (M, 2))
        kw = dict(t_final=T_FINAL, dt=DT, x0=X0, save_every=N, engine=args.engine, seed=SEED)
        ref = nlobs.montecarlo(vdp, {"obs": obs}, workers=1, **kw)
        t_serial = cm.interleaved({"s": lambda: nlobs.montecarlo(vdp, {"obs": obs}, workers=1, **kw)}, args.rounds)["s"][0]
        for W in counts:
            with LocalCluster(n_workers=W, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                    Client(cluster) as client:
                nlobs.montecarlo(vdp, {"obs": obs}, scheduler=client, **kw)  # each worker builds (or loads) the batch
                mn, med, mc = cm.interleaved({"d": lambda: nlobs.montecarlo(vdp, {"obs": obs}, scheduler=client, **kw)},
                                             args.rounds)["d"]
            same = bool(np.array_equal(mc.x, ref.x))
            out.append({"M": M, "workers": W, "chunk": mc.info["chunk"], "min_s": mn, "median_s": med, "serial_s": t_serial,
                        "speedup": t_serial / mn, "efficiency": t_serial / (W * mn), "identical_to_serial": same})
            print(f"  Dask, M = {M:,}, {W} worker processes (chunk {mc.info['chunk']}): min {cm.fmt_time(mn)}  median "
                  f"{cm.fmt_time(med)}  serial {cm.fmt_time(t_serial)}  efficiency {t_serial / (W * mn):4.2f}  "
                  f"{'identical' if same else 'DIFFERS'}")
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--sizes", default="1000,10000", help="numbers of trajectories, comma-separated")
    ap.add_argument("--engine", default="c", choices=("c", "vm", "auto"))
    ap.add_argument("--dask", action="store_true", help="also on a Dask LocalCluster of 1 .. N worker processes")
    ap.add_argument("--workers", default=None, help="thread and worker counts, comma-separated (default 1 .. N; 1 first)")
    ap.add_argument("--noise-max", type=int, default=None, help="the largest M of the noise case (default: every M)")
    args = ap.parse_args()
    cores = usable_cores()
    vdp = nlobs.System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], params={"mu": 1.0})
    obs = nlobs.design_custom(vdp, states=["xh1", "xh2"], params={"L": 5.0},
                              flow=["xh2 + 2*L*(y - xh1)", "mu*(1 - xh1**2)*xh2 - xh1 + L**2*(y - xh1)"])
    counts = sorted({1, *(int(v) for v in args.workers.split(","))}) if args.workers else list(range(1, cores + 1))

    def save(rows, table, dask):
        return cm.write("bench_cores", rows, {"cores": cores, "workers": counts, "engine": args.engine, "table": table,
                                              "lock_check": locks, "dask": dask,
                                              "load_at_end": os.getloadavg()[0] if hasattr(os, "getloadavg") else None})

    locks = [lock_check(vdp, obs, e) for e in ("c", "vm")]
    for r in locks:
        print(f"lock check, engine {r['engine']}: a {r['call_s']:.2f} s chunk in another thread; this thread's loop ran "
              f"{r['iterations_inside']:,} times inside it ({'released' if r['iterations_inside'] else 'HELD'})")
    print(f"montecarlo on {', '.join(map(str, counts))} threads: Van der Pol + observer, RK4, dt = {DT:g}, t in [0, {T_FINAL:g}], final states")
    table, rows = [], []
    for M in (int(s) for s in args.sizes.split(",")):
        X0 = np.random.default_rng(SEED).uniform(-3, 3, (M, 2))
        for noisy in (False, True):
            if noisy and args.noise_max is not None and M > args.noise_max:
                continue
            kw = dict(t_final=T_FINAL, dt=DT, x0=X0, save_every=N, engine=args.engine, seed=SEED,
                      noise=nlobs.Noise.gaussian(0.05) if noisy else None)

            cpu: dict[int, list[tuple[float, float]]] = {}

            def run(w, kw=kw):
                def go():
                    CHUNK_CPU.clear()
                    c0, t0 = time.process_time(), time.perf_counter()
                    mc = nlobs.montecarlo(vdp, {"obs": obs}, workers=w, **kw)
                    total = time.process_time() - c0
                    busiest = max(CHUNK_CPU.values(), default=0.0)
                    cpu.setdefault(w, []).append((time.perf_counter() - t0, total, total - sum(CHUNK_CPU.values()) + busiest))
                    return np.column_stack([mc.x[:, -1], mc.observers["obs"].xhat[:, -1]]), mc.info
                return go

            fns = {w: run(w) for w in counts}
            for fn in fns.values():
                fn()  # build once, warm the caches
            timed = cm.interleaved(fns, args.rounds)
            t1, ref = timed[1][0], timed[1][2][0]
            case = f"M = {M:,}" + (", measurement noise (a seed per run)" if noisy else "")
            for w in fns:
                mn, med, (out, info) = timed[w]
                same = bool(np.array_equal(out, ref))
                wall, used, _ = min(cpu[w])
                serial_cpu = min(c[1] for c in cpu[1])
                projected = serial_cpu / min(c[2] for c in cpu[w])
                entry = {"case": case, "M": M, "noise": noisy, "workers": w, "threads_used": info.get("workers"),
                         "chunk": info.get("chunk"), "min_s": mn, "median_s": med, "speedup": t1 / mn,
                         "efficiency": t1 / (w * mn), "cpu_over_wall": used / wall,
                         "projected_speedup_dedicated_cores": projected, "projected_efficiency": projected / w,
                         "identical_to_serial": same}
                table.append(entry)
                print(f"  {case:<45} workers {w:>2} (chunk {info.get('chunk')}): min {cm.fmt_time(mn):>9}  median "
                      f"{cm.fmt_time(med):>9}  speed-up {t1 / mn:5.2f}  efficiency {t1 / (w * mn):4.2f}  "
                      f"CPU / wall {used / wall:4.2f}  projected on dedicated cores {projected:4.2f} "
                      f"(efficiency {projected / w:4.2f})  {'identical' if same else 'DIFFERS'}")
            if max(counts) > 1:
                w = max(counts)
                rows.append(cm.row("P2c", f"{case}, t in [0, {T_FINAL:g}], final states, on {w} cores",
                                   nlobs=f"nlobs.montecarlo(workers={w}) (default: every core)", t_nlobs=timed[w][:2],
                                   err_nlobs="identical to serial" if np.array_equal(timed[w][2][0], ref) else "DIFFERS from serial",
                                   peer="nlobs.montecarlo(workers=1), the chunks one after another", t_peer=timed[1][:2],
                                   err_peer="reference", kind="peer/nlobs",
                                   target=">= 1.8x on 2 cores" if w == 2 else f"(report; efficiency {t1 / (w * timed[w][0]):.2f})",
                                   threshold=1.8 if w == 2 else None))
                cm.print_row(rows[-1])
            save(rows, table, [])   # after every case: a run cut short keeps what it did
    dask = on_dask(vdp, obs, [int(v) for v in args.sizes.split(",")], counts, args) if args.dask else []
    print(f"wrote {save(rows, table, dask)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
