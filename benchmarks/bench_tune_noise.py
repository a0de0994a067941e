"""Tuning Q and R from a recording (issue 42, item 1): wall time, iterations, convergence, and the tuned filter's error.

T1  A pendulum map at 100 Hz, 5,000 samples drawn here with known Q (per step) and R: `nlobs.tune` of an EKF and a UKF
    started from Q × 100 and R × 10. Reported: wall time, iterations, converged, the NIS check, and the RMS state error
    of the tuned EKF over that of the EKF with the true Q and R (target ≤ 1.2×; `nlobs tune` ≤ 60 s).
T2  ins16 (16 states, 7 outputs at three rates, GPS 0.15 s late): `nlobs simulate` a 30 s recording with its process
    noise, then the whole command `nlobs tune ins16.toml rec.csv --observer ekf --json` (the advisor's EKF as start).

Run: ``PYTHONPATH=src python benchmarks/bench_tune_noise.py [--quick]``; writes results/bench_tune_noise.json.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import nlobs
from nlobs.learning import tune
from nlobs.estimation import Recording

T = 0.01
PEND = nlobs.System(states=["th", "om"], f=[f"th + {T}*om", f"om + {T}*(-9.81*sin(th) - 0.2*om + u)"], inputs=["u"],
                    outputs=["y"], h=["th"], time="discrete", sample_time=T, name="pendulum_map")
Q_TRUE, R_TRUE = np.diag([1e-7, 4e-4]), np.array([[1e-3]])


def pendulum(N: int, seed: int = 0) -> tuple[Recording, np.ndarray]:
    rng = np.random.default_rng(seed)
    x, X, Y = np.array([0.5, 0.0]), [], []
    u = 0.5 * np.sin(0.7 * np.arange(N) * T)
    for k in range(N):
        X.append(x.copy())
        Y.append(x[0] + np.sqrt(R_TRUE[0, 0]) * rng.standard_normal())
        x = np.array([x[0] + T * x[1], x[1] + T * (-9.81 * np.sin(x[0]) - 0.2 * x[1] + u[k])])
        x = x + np.sqrt(np.diag(Q_TRUE)) * rng.standard_normal(2)
    return Recording.from_arrays(PEND, np.arange(N) * T, np.array(Y)[:, None], u[:, None]), np.array(X)


def rms(design: object, rec: Recording, X: np.ndarray) -> float:
    xhat = next(iter(nlobs.estimate(design, rec).observers.values())).xhat
    return float(np.sqrt(np.mean(((xhat - X) / X.std(axis=0)) ** 2)))


def t1(N: int) -> list[dict[str, object]]:
    rec, X = pendulum(N)
    out = []
    for kind in ("ekf", "ukf"):
        make = nlobs.design_ekf if kind == "ekf" else nlobs.design_ukf
        start = make(PEND, Q=100 * Q_TRUE, R=10 * R_TRUE, P0=np.diag([0.1, 0.1]), xhat0=[0.0, 0.0])
        t0 = time.perf_counter()
        res = tune(start, rec)
        wall = time.perf_counter() - t0
        ideal = make(PEND, Q=Q_TRUE, R=R_TRUE, P0=np.diag([0.1, 0.1]), xhat0=[0.0, 0.0])
        row = {"case": f"pendulum map {N} samples, {kind}", "seconds": round(wall, 2), "iterations": res.iterations,
               "evaluations": res.evaluations, "converged": res.converged, "nis_ok": res.nis_ok,
               "Q": np.diag(res.Q).tolist(), "R": np.diag(res.R).tolist(),
               "rms_ratio_tuned_over_true": round(rms(res.apply(), rec, X) / rms(ideal, rec, X), 4),
               "rms_ratio_start_over_true": round(rms(start, rec, X) / rms(ideal, rec, X), 4)}
        print(row, flush=True)
        out.append(row)
    return out


def t2(t_final: float) -> dict[str, object]:
    model = Path(nlobs.__file__).parent / "models" / "ins16.toml"
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "ins16.csv"
        py = [sys.executable, "-m", "nlobs.cli"]
        subprocess.run(py + ["simulate", str(model), "--t-final", str(t_final), "--output", str(data)], check=True,
                       capture_output=True)
        import resource

        t0, c0 = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
        p = subprocess.run(py + ["tune", str(model), str(data), "--observer", "ekf", "--json", "--skip-missing"],
                           capture_output=True, text=True)
        wall = time.perf_counter() - t0
        c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime)
    if p.returncode not in (0, 1):
        row = {"case": f"ins16 {t_final:g} s", "seconds": round(wall, 1), "cpu_seconds": round(cpu, 1), "error": p.stderr.strip()[-400:]}
    else:
        res = json.loads(p.stdout)
        row = {"case": f"ins16 {t_final:g} s", "seconds": round(wall, 1), "cpu_seconds": round(cpu, 1), "iterations": res["iterations"],
               "evaluations": res["evaluations"], "converged": res["converged"], "nis": res["nis"],
               "tune_seconds": round(res["seconds"], 1), "message": res["message"]}
    print(row, flush=True)
    return row


if __name__ == "__main__":
    quick = "--quick" in sys.argv
    rows = t1(2000 if quick else 5000)
    if "--no-ins" not in sys.argv:
        rows.append(t2(10.0 if quick else 30.0))
    out = Path(__file__).parent / "results" / "bench_tune_noise.json"
    out.write_text(json.dumps(rows, indent=1))
