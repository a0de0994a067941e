"""The advisor's best on a 16-state INS against the best EKF over Q scaled by powers of ten (issue 42's target: within
1.5x, and ``design --run`` at most 120 s cold).

Model: the bundled ``ins16`` (quaternion, position, velocity, gyro and accelerometer biases; IMU inputs, late GNSS,
barometer, magnetometer). Every filter is scored by the advisor's own metric (``advise._rank._score``: RMS over the
last 20 % of the run, each state over its scale) on the advisor's run (same scenario, seed and x̂(0)). The scan takes
the advisor's EKF and multiplies its whole Q by 10^k, k = -6 .. 2. Whole commands are timed with a cold cache
(NLOBS_CACHE_DIR in a fresh folder). Writes results/bench_ins_qscale.{json,md}.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE.parent / "src"))


def design_run_cold() -> dict:
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NLOBS_CACHE_DIR": cache}
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-m", "nlobs.cli", "design", "ins16", "--run", "--json"], env=env,
                             capture_output=True, text=True, timeout=900)
        wall = time.perf_counter() - t0
    d = json.loads(out.stdout)
    ranked = [s for s in d.get("scores") or [] if s.get("status") == "ok"]
    best = d.get("best")
    return {"wall_s": wall, "best": best, "scores": ranked, "rc": out.returncode}


def q_scan() -> list[dict]:
    import nlobs
    from nlobs.advise import _rank
    from nlobs.advise._context import build_context, file_true_parameters, file_unknown_params

    mf = nlobs.load_model("ins16")
    adv = nlobs.advise(mf, kinds=["ekf"], run=False, progress=False)
    base = adv.candidate("ekf")
    ctx = build_context(mf.system, model_file=mf, unknown_params=file_unknown_params(mf),
                        true_parameters=file_true_parameters(mf.simulation))
    sc = ctx.scenario
    opts = dict(base.options)
    rows = []
    for k in range(-6, 3):
        d = nlobs.design_ekf(ctx.system, **{**opts, "Q": np.asarray(opts["Q"], dtype=float) * 10.0 ** k})
        try:
            run = nlobs.simulate(ctx.system, {"ekf": d}, t_final=sc.t_final, dt=sc.dt, x0=sc.x0, inputs=sc.inputs,
                                 noise=sc.noise, process_noise=sc.process_noise, sampling=sc.sampling, seed=sc.seed,
                                 delay=sc.delay, progress=False, xhat0=np.asarray(ctx.xhat0, dtype=float))
            s = _rank._score(run, "ekf", ctx)
            rows.append({"k": k, "normalised_rms": s.normalised_rms, "status": s.status})
        except nlobs.NlobsError as e:
            rows.append({"k": k, "normalised_rms": None, "status": f"failed: {str(e)[:80]}"})
    return rows


def main() -> None:
    cold = design_run_cold()
    scan = q_scan()
    ok = [r for r in scan if r["normalised_rms"] is not None and r["status"] == "ok"]
    best_scan = min(ok, key=lambda r: r["normalised_rms"]) if ok else None
    best_adv = min((s["normalised_rms"] for s in cold["scores"] if s.get("normalised_rms") is not None), default=None)
    ratio = best_adv / best_scan["normalised_rms"] if best_adv and best_scan else None
    meta = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "commit": subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                     cwd=HERE).stdout.strip(), "cores": os.cpu_count()}
    res = {"meta": meta, "design_run": cold, "q_scan": scan, "best_scan": best_scan, "advisor_best": best_adv,
           "ratio": ratio}
    (HERE / "results" / "bench_ins_qscale.json").write_text(json.dumps(res, indent=1, default=str))
    lines = [f"# bench_ins_qscale: ins16, the advisor's best against the best Q-scaled EKF", "",
             f"{meta['date']}, commit {meta['commit']}, {meta['cores']} cores (shared).", "",
             "`nlobs design ins16 --run`, cold cache: %.0f s wall (target ≤ 120 s); best: %s, normalised RMS %s."
             % (cold["wall_s"], cold["best"], "—" if best_adv is None else "%.4g" % best_adv), "",
             "| Q × 10^k | normalised RMS | status |", "|---|---|---|"]
    lines += ["| {} | {} | {} |".format(r["k"], "—" if r["normalised_rms"] is None else "%.4g" % r["normalised_rms"],
                                        r["status"]) for r in scan]
    lines += ["", "Advisor's best / best scanned EKF: %s (target ≤ 1.5×)." % ("—" if ratio is None else "%.2f×" % ratio)]
    (HERE / "results" / "bench_ins_qscale.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
