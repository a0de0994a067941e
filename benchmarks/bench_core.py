"""Core speed benchmark (SPEC M9 P1 and P3), peers run in the same process; prints ratios.

P1  joint plant + observer simulation: Van der Pol (mu = 1, y = x1, x(0) = (2, 0)) with the observer
    xh1' = xh2 + 2L(y - xh1), xh2' = mu(1 - xh1^2)xh2 - xh1 + L^2(y - xh1), L = 5, xh(0) = 0;
    RK4, dt = 1e-3, t in [0, 100], all 100,001 x 4 states saved. Against a hand-written C RK4
    loop (same compiler and flags as nlobs' compiled engine) and python-control
    (nlsys + interconnect + input_output_response on the same time grid, its default solver).
    Targets: nlobs <= 2x C, and >= 1000x faster than python-control.
P3  EKF on recorded data: 20 s of the same plant sampled at 100 Hz (y = x1 + N(0, 0.1^2)), against
    filterpy's ExtendedKalmanFilter (Euler-discretised f and its Jacobian, one step per sample;
    nlobs integrates x and P with one RK4 step per sample). Target: >= 20x faster than filterpy.

Run:  .venv/bin/pip install 'nlobs[bench]'  then  .venv/bin/python benchmarks/bench_core.py
It installs nothing itself; a missing peer is reported and its row skipped.
"""

from __future__ import annotations

import ctypes
import json
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import nlobs
from nlobs.engine import find_compiler
from nlobs.engine._codegen import CFLAGS

MU, L, DT, T_FINAL = 1.0, 5.0, 1e-3, 100.0
N = int(round(T_FINAL / DT))

C_SOURCE = r"""
static void rhs(const double *s, double *d) {
  const double mu = 1.0, L = 5.0;
  double x1 = s[0], x2 = s[1], h1 = s[2], h2 = s[3], y = x1;
  d[0] = x2; d[1] = mu * (1 - x1 * x1) * x2 - x1;
  d[2] = h2 + 2 * L * (y - h1); d[3] = mu * (1 - h1 * h1) * h2 - h1 + L * L * (y - h1);
}
void run(double dt, long n, double *out) {
  double x[4] = {2, 0, 0, 0}, k1[4], k2[4], k3[4], k4[4], tmp[4];
  int i; long k;
  for (i = 0; i < 4; ++i) out[i] = x[i];
  for (k = 0; k < n; ++k) {
    rhs(x, k1); for (i = 0; i < 4; ++i) tmp[i] = x[i] + dt / 2 * k1[i];
    rhs(tmp, k2); for (i = 0; i < 4; ++i) tmp[i] = x[i] + dt / 2 * k2[i];
    rhs(tmp, k3); for (i = 0; i < 4; ++i) tmp[i] = x[i] + dt * k3[i];
    rhs(tmp, k4);
    for (i = 0; i < 4; ++i) { x[i] += dt / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]); out[4 * (k + 1) + i] = x[i]; }
  }
}
"""


def timeit(fn, repeat: int) -> tuple[float, float, object]:
    out, times = None, []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), statistics.median(times), out


def interleaved(fns: dict[str, object], rounds: int) -> dict[str, tuple[float, float, object]]:
    """Time several implementations round by round (A, B, C, A, B, C, ...), so machine noise hits
    them alike; return (min, median, last output) per implementation. On a shared virtual machine
    the min is the least-disturbed sample; both are reported."""
    times: dict[str, list[float]] = {k: [] for k in fns}
    outs: dict[str, object] = {}
    for _ in range(rounds):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            outs[k] = fn()  # type: ignore[operator]
            times[k].append(time.perf_counter() - t0)
    return {k: (min(v), statistics.median(v), outs[k]) for k, v in times.items()}


def c_baseline(tmp: Path):
    cc = find_compiler()
    if cc is None:
        return None
    src, so = tmp / "vdp.c", tmp / "vdp.so"
    src.write_text(C_SOURCE)
    subprocess.run([cc, *CFLAGS, str(src), "-o", str(so)], check=True)
    lib = ctypes.CDLL(str(so))
    lib.run.argtypes = [ctypes.c_double, ctypes.c_long, ctypes.POINTER(ctypes.c_double)]
    out = np.empty((N + 1, 4))

    def run():
        lib.run(DT, N, out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)))
        return out

    return run


def nlobs_p1(engine: str):
    vdp = nlobs.System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], params={"mu": MU})
    obs = nlobs.design_custom(vdp, states=["xh1", "xh2"], params={"L": L},
                              flow=["xh2 + 2*L*(y - xh1)", "mu*(1 - xh1**2)*xh2 - xh1 + L**2*(y - xh1)"])

    def run():  # the result object itself; comparing with C happens outside the timed call
        return nlobs.simulate(vdp, {"obs": obs}, t_final=T_FINAL, dt=DT, x0=[2.0, 0.0], engine=engine)

    return run


def states_of(run) -> np.ndarray:
    return np.column_stack([run.x, run.observers["obs"].z])


def python_control_p1():
    try:
        import control as ct
    except ImportError:
        return None, None
    plant = ct.nlsys(lambda t, x, u, p: [x[1], MU * (1 - x[0] ** 2) * x[1] - x[0]], lambda t, x, u, p: x[:1],
                     states=2, inputs=0, outputs=["y"], name="plant")

    def obs_rhs(t, z, u, p):
        y = u[0]
        return [z[1] + 2 * L * (y - z[0]), MU * (1 - z[0] ** 2) * z[1] - z[0] + L**2 * (y - z[0])]

    observer = ct.nlsys(obs_rhs, lambda t, z, u, p: z, states=2, inputs=["y"], outputs=["xh1", "xh2"], name="observer")
    sys_ = ct.interconnect([plant, observer], inputs=[], outputs=["y", "xh1", "xh2"], name="joint")
    T = np.linspace(0, T_FINAL, N + 1)

    def run():
        resp = ct.input_output_response(sys_, T, 0, X0=[2.0, 0.0, 0.0, 0.0])
        return np.asarray(resp.states).T

    return run, ct.__version__


def ekf_data():
    vdp = nlobs.System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], params={"mu": MU})
    run = nlobs.simulate(vdp, t_final=20.0, dt=1e-3, x0=[2.0, 0.0], noise=nlobs.Noise.gaussian(0.1),
                         sampling=nlobs.Sampling(0.01), seed=0)
    return vdp, nlobs.Recording.from_run(run, every=10)


Q = np.diag([1e-4, 1e-3])
R = np.array([[0.01]])


def nlobs_p3(vdp, rec, engine):
    ekf = nlobs.design_ekf(vdp, Q=Q, R=R, P0=np.eye(2), xhat0=[0.0, 0.0])

    def run():
        return nlobs.estimate(ekf, rec, engine=engine).observers["ekf"].xhat

    return run


def filterpy_p3(rec):
    try:
        import filterpy
        from filterpy.kalman import ExtendedKalmanFilter
    except ImportError:
        return None, None
    dt = 0.01

    class VdpEKF(ExtendedKalmanFilter):
        def predict_x(self, u=0):
            x1, x2 = self.x[0, 0], self.x[1, 0]
            self.x = self.x + dt * np.array([[x2], [MU * (1 - x1**2) * x2 - x1]])

    def H_jac(x):
        return np.array([[1.0, 0.0]])

    def hx(x):
        return x[:1]

    def run():
        f = VdpEKF(dim_x=2, dim_z=1)
        f.x = np.zeros((2, 1))
        f.P = np.eye(2)
        f.R = R
        f.Q = Q * dt
        out = np.empty((rec.t.size, 2))
        for k, z in enumerate(rec.y):
            if k:
                x1, x2 = f.x[0, 0], f.x[1, 0]
                f.F = np.eye(2) + dt * np.array([[0.0, 1.0], [-2 * MU * x1 * x2 - 1, MU * (1 - x1**2)]])
                f.predict()
            f.update(z.reshape(1, 1), H_jac, hx)
            out[k] = f.x[:, 0]
        return out

    return run, filterpy.__version__


def main() -> int:
    results: dict[str, object] = {"python": platform.python_version(), "machine": platform.machine(), "nlobs": nlobs.__version__,
                                  "cflags": " ".join(CFLAGS)}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        c_run = c_baseline(Path(tmp))
        print("P1: Van der Pol + observer, RK4, dt = 1e-3, t in [0, 100], 100,001 x 4 states saved")
        ref = None
        fns: dict[str, object] = {}
        if c_run is None:
            print("  no C compiler: the C baseline and nlobs' compiled engine are skipped")
        else:
            fns["C"] = c_run
        engines = ["c", "vm"] if c_run is not None else ["vm"]
        first = {}
        for engine in engines:
            fn = nlobs_p1(engine)
            t0 = time.perf_counter()
            fn()
            first[engine] = time.perf_counter() - t0
            fns[engine] = fn
        timed = interleaved(fns, 15)
        c_min = c_med = None
        if "C" in timed:
            c_min, c_med, ref = timed["C"]
            ref = np.array(ref)
            rows.append(("hand-written C (gcc " + " ".join(CFLAGS[:2]) + ")", c_min, c_med, 0.0))
        nl = {}
        for engine in engines:
            mn, med, out = timed[engine]
            dev = float(np.max(np.abs(states_of(out) - ref))) if ref is not None else float("nan")
            rows.append((f"nlobs simulate (engine={engine}; first call {first[engine]:.3f} s)", mn, med, dev))
            nl[engine] = (mn, med)
        pc_run, pc_version = python_control_p1()
        pc_med = pc_min = None
        if pc_run is not None:
            pc_min, pc_med, out = timeit(pc_run, 3)
            mn = pc_min
            dev = float(np.max(np.abs(out - ref))) if ref is not None else float("nan")
            rows.append((f"python-control {pc_version} input_output_response (RK45 defaults)", mn, pc_med, dev))
        else:
            print("  python-control not installed (pip install 'nlobs[bench]'): skipped")
        print(f"  {'engine':<72} {'min s':>9} {'median s':>9} {'max |dev| vs C':>15}")
        for name, mn, med, dev in rows:
            print(f"  {name:<72} {mn:>9.4f} {med:>9.4f} {dev:>15.2e}")
        best_min, best_med = nl.get("c", nl.get("vm"))
        if c_med:
            r, rm = best_min / c_min, best_med / c_med
            results["P1_nlobs_over_C"] = {"min": r, "median": rm}
            print(f"  ratio nlobs / C = {r:.2f} (min) {rm:.2f} (median)  (target <= 2)  {'MET' if r <= 2 else 'MISSED'}")
        if pc_med:
            r, rm = pc_min / best_min, pc_med / best_med
            results["P1_python_control_over_nlobs"] = {"min": r, "median": rm}
            print(f"  ratio python-control / nlobs = {r:.0f} (min) {rm:.0f} (median)  (target >= 1000)  "
                  f"{'MET' if r >= 1000 else 'MISSED'}")

        print("\nP3: EKF on 20 s of recorded data at 100 Hz (2,001 samples)")
        vdp, rec = ekf_data()
        fp_run, fp_version = filterpy_p3(rec)
        p3 = []
        est = {}
        for engine in engines:
            fn = nlobs_p3(vdp, rec, engine)
            fn()
            mn, med, out = timeit(fn, 15)
            est[engine] = (med, out)
            err = float(np.sqrt(np.mean(np.sum((out[1000:] - rec.x[1000:]) ** 2, axis=1))))
            p3.append((f"nlobs estimate, continuous-discrete EKF (engine={engine})", mn, med, err))
        fp_med = None
        if fp_run is not None:
            mn, fp_med, out = timeit(fp_run, 5)
            err = float(np.sqrt(np.mean(np.sum((out[1000:] - rec.x[1000:]) ** 2, axis=1))))
            p3.append((f"filterpy {fp_version} ExtendedKalmanFilter", mn, fp_med, err))
        else:
            print("  filterpy not installed (pip install 'nlobs[bench]'): skipped")
        print(f"  {'implementation':<72} {'min s':>9} {'median s':>9} {'RMS err t>10':>15}")
        for name, mn, med, err in p3:
            print(f"  {name:<72} {mn:>9.4f} {med:>9.4f} {err:>15.4f}")
        if fp_med:
            best3 = min(m for m, _ in est.values())
            r = fp_med / best3
            results["P3_filterpy_over_nlobs"] = r
            print(f"  ratio filterpy / nlobs = {r:.1f}  (target >= 20)  {'MET' if r >= 20 else 'MISSED'}")
    out = Path(__file__).with_name("results")
    out.mkdir(exist_ok=True)
    (out / "bench_core.json").write_text(json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
