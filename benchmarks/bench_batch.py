"""Batch speed benchmark (SPEC M9 P2): 1,000 initial states of the Van der Pol + observer problem.

Plant Van der Pol (mu = 1, y = x1) with the observer of bench_core.py (L = 5, xh(0) = 0); RK4,
dt = 1e-3, t in [0, 10], 1,000 plant initial states uniform in [-3, 3]^2 (seed 20240501);
final states only. Compared in the same process with
  - a plain C loop over the initial states (one after another), gcc with nlobs' flags;
  - a C loop vectorised across initial states (structure of arrays, the compiler's SIMD);
Targets (issue 13): nlobs montecarlo at most 1.5x the SIMD C loop (and well under the plain loop).
nlobs is timed through ``nlobs.montecarlo`` on one thread (``workers=1``, like the C loops; parameters not varied:
compiled in as constants; no metric is computed unless read); bench_cores.py times it on every core.
Installs nothing. Results: benchmarks/results/bench_batch.json.
"""

from __future__ import annotations

import ctypes
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import _common as cm  # noqa: E402

import nlobs  # noqa: E402
from nlobs.engine import find_compiler  # noqa: E402
from nlobs.engine._codegen import CFLAGS  # noqa: E402

M, DT, T_FINAL, SEED = 1000, 1e-3, 10.0, 20240501
N = int(round(T_FINAL / DT))

C_SOURCE = r"""
static inline void rhs(const double *s, double *d) {
  const double mu = 1.0, L = 5.0;
  double x1 = s[0], x2 = s[1], h1 = s[2], h2 = s[3], y = x1;
  d[0] = x2; d[1] = mu * (1 - x1 * x1) * x2 - x1;
  d[2] = h2 + 2 * L * (y - h1); d[3] = mu * (1 - h1 * h1) * h2 - h1 + L * L * (y - h1);
}
/* one initial state after another */
void plain(const double *x0, long m, long n, double dt, double *out) {
  for (long j = 0; j < m; ++j) {
    double x[4] = {x0[2 * j], x0[2 * j + 1], 0, 0}, k1[4], k2[4], k3[4], k4[4], tmp[4];
    for (long k = 0; k < n; ++k) {
      rhs(x, k1); for (int i = 0; i < 4; ++i) tmp[i] = x[i] + dt / 2 * k1[i];
      rhs(tmp, k2); for (int i = 0; i < 4; ++i) tmp[i] = x[i] + dt / 2 * k2[i];
      rhs(tmp, k3); for (int i = 0; i < 4; ++i) tmp[i] = x[i] + dt * k3[i];
      rhs(tmp, k4); for (int i = 0; i < 4; ++i) x[i] += dt / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
    }
    for (int i = 0; i < 4; ++i) out[4 * j + i] = x[i];
  }
}
/* structure of arrays: every step for all initial states, inner loop vectorised by the compiler */
#define W 8
void soa(const double *x0, long m, long n, double dt, double *out) {
  const double mu = 1.0, L = 5.0;
  for (long j0 = 0; j0 < m; j0 += W) {
    double x1[W], x2[W], h1[W], h2[W];
    for (int l = 0; l < W; ++l) { long j = j0 + l < m ? j0 + l : m - 1; x1[l] = x0[2*j]; x2[l] = x0[2*j+1]; h1[l] = 0; h2[l] = 0; }
    for (long k = 0; k < n; ++k) {
      for (int l = 0; l < W; ++l) {
        double a = x1[l], b = x2[l], c = h1[l], d = h2[l];
#define F(a_, b_, c_, d_, o1, o2, o3, o4) \
        { double A_ = (a_), B_ = (b_), C_ = (c_), D_ = (d_); \
          o1 = B_; o2 = mu * (1 - A_ * A_) * B_ - A_; o3 = D_ + 2 * L * (A_ - C_); o4 = mu * (1 - C_ * C_) * D_ - C_ + L * L * (A_ - C_); }
        double k11, k12, k13, k14, k21, k22, k23, k24, k31, k32, k33, k34, k41, k42, k43, k44;
        F(a, b, c, d, k11, k12, k13, k14)
        F(a + dt/2*k11, b + dt/2*k12, c + dt/2*k13, d + dt/2*k14, k21, k22, k23, k24)
        F(a + dt/2*k21, b + dt/2*k22, c + dt/2*k23, d + dt/2*k24, k31, k32, k33, k34)
        F(a + dt*k31, b + dt*k32, c + dt*k33, d + dt*k34, k41, k42, k43, k44)
        x1[l] = a + dt/6*(k11 + 2*k21 + 2*k31 + k41); x2[l] = b + dt/6*(k12 + 2*k22 + 2*k32 + k42);
        h1[l] = c + dt/6*(k13 + 2*k23 + 2*k33 + k43); h2[l] = d + dt/6*(k14 + 2*k24 + 2*k34 + k44);
      }
    }
    for (int l = 0; l < W && j0 + l < m; ++l) { long j = j0 + l; out[4*j] = x1[l]; out[4*j+1] = x2[l]; out[4*j+2] = h1[l]; out[4*j+3] = h2[l]; }
  }
}
"""


def main() -> int:
    import argparse

    ap = argparse.ArgumentParser(description="P2 batch benchmark")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--vm", action="store_true", help="also time CasADi's virtual machine (slow: about a minute)")
    args = ap.parse_args()
    rounds, with_vm = args.rounds, args.vm
    X0 = np.random.default_rng(SEED).uniform(-3, 3, (M, 2))
    rows = []
    print(f"P2: {M} initial states of Van der Pol + observer, RK4, dt = {DT:g}, t in [0, {T_FINAL:g}], final states only")
    ref = None
    with tempfile.TemporaryDirectory() as tmp:
        cc = find_compiler()
        if cc is not None:
            src, so = Path(tmp) / "batch.c", Path(tmp) / "batch.so"
            src.write_text(C_SOURCE)
            subprocess.run([cc, *CFLAGS, str(src), "-o", str(so)], check=True)
            lib = ctypes.CDLL(str(so))
            dbl = ctypes.POINTER(ctypes.c_double)
            for fname in ("plain", "soa"):
                getattr(lib, fname).argtypes = [dbl, ctypes.c_long, ctypes.c_long, ctypes.c_double, dbl]

            def c_run(fname):
                def run():
                    out = np.empty((M, 4))
                    getattr(lib, fname)(X0.ctypes.data_as(dbl), M, N, DT, out.ctypes.data_as(dbl))
                    return out
                return run

            c_fns = {"plain": c_run("plain"), "soa": c_run("soa")}
        else:
            print("  no C compiler: C baselines skipped")
            c_fns = {}

        vdp = nlobs.System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], params={"mu": 1.0})
        obs = nlobs.design_custom(vdp, states=["xh1", "xh2"], params={"L": 5.0},
                                  flow=["xh2 + 2*L*(y - xh1)", "mu*(1 - xh1**2)*xh2 - xh1 + L**2*(y - xh1)"])

        def nl(engine, chunk):
            def run():
                mc = nlobs.montecarlo(vdp, {"obs": obs}, t_final=T_FINAL, dt=DT, x0=X0, save_every=N, engine=engine, chunk=chunk,
                                      workers=1)  # one core, as the C loops; bench_cores.py times the threads
                return np.column_stack([mc.x[:, -1], mc.observers["obs"].xhat[:, -1]])
            return run

        fns = dict(c_fns)
        first = {}
        for engine, chunk in ([("c", 1000), ("c", 64)] if cc is not None else []):
            fn = nl(engine, chunk)
            t0 = time.perf_counter()
            fn()
            first[(engine, chunk)] = time.perf_counter() - t0
            fns[(engine, chunk)] = fn
        timed = cm.interleaved(fns, rounds)
        plain_min = soa_min = None
        if "plain" in timed:
            plain_min, plain_med, ref = timed["plain"]
            rows.append(("plain C loop over the initial states", plain_min, plain_med, 0.0))
            soa_min, soa_med, soa_out = timed["soa"]
            rows.append(("C vectorised across initial states (SoA, SIMD)", soa_min, soa_med, float(np.max(np.abs(soa_out - ref)))))
        best = None
        for key, fn in fns.items():
            if key in ("plain", "soa"):
                continue
            mn, med, out = timed[key]
            dev = float(np.max(np.abs(out - ref))) if ref is not None else float("nan")
            rows.append((f"nlobs montecarlo (engine={key[0]}, chunk={key[1]}; first call {first[key]:.2f} s)", mn, med, dev))
            best = mn if best is None else min(best, mn)
        if with_vm:
            fn = nl("vm", 1000)
            mn, med, out = cm.interleaved({"vm": fn}, 1)["vm"]
            rows.append(("nlobs montecarlo (engine=vm, chunk=1000)", mn, med, float(np.max(np.abs(out - ref))) if ref is not None else float("nan")))
    print(f"  {'implementation':<66} {'min s':>8} {'median s':>9} {'max |dev|':>10}")
    for name, mn, med, dev in rows:
        print(f"  {name:<66} {mn:>8.3f} {med:>9.3f} {dev:>10.1e}")
    rows_json = []
    if plain_min and best:
        key = min((k for k in fns if k not in ("plain", "soa")), key=lambda k: timed[k][0])
        mn, med, out = timed[key]
        dev = float(np.max(np.abs(out - ref)))
        label = f"nlobs.montecarlo(engine='{key[0]}', chunk={key[1]})"
        for peer, kname, target, thr in (("soa", "C vectorised across states (SoA, SIMD, -O3 -march=native)", "<= 1.5x SIMD C", 1.5),
                                         ("plain", "plain C loop over the states", "(report)", None)):
            rows_json.append(cm.row("P2", f"{M} initial states, t in [0, {T_FINAL:g}], final states", nlobs=label, t_nlobs=(mn, med),
                                    err_nlobs=f"max |dev| from plain C {dev:.1e}", peer=kname, t_peer=timed[peer][:2],
                                    err_peer="reference" if peer == "plain" else f"max |dev| {float(np.max(np.abs(timed[peer][2] - ref))):.1e}",
                                    kind="nlobs/peer", target=target, threshold=thr))
            cm.print_row(rows_json[-1])
    path = cm.write("bench_batch", rows_json)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
