"""Are the ±2σ of estimated parameters honest? Coverage of the true value over many noise seeds.

A draining tank h' = u − k·sqrt(max(h, 0)), y = h + noise (σ = 0.01, sampled every 0.1 s), with
k unknown (file value 0.3 = initial guess, true 0.5), estimated jointly by the EKF and the UKF
of the model file below. For each seed, the run reports k̂ and its standard deviation σ from
the filter's covariance (``Run.parameters``); a consistent filter has |k̂ − k| < 2σ in about 95 %
of the runs. Two tunings: Q matching the (noise-free) plant, and a Q with process noise on h and k
(a conservative filter: coverage above 95 %, intervals wider than needed).

Run: ``python benchmarks/parameter_coverage.py [RUNS]`` (default 200). Measured (200 seeds):
matched Q: EKF 0.950, UKF 0.950; inflated Q: 1.000, 1.000 (about 14 s per tuning).
"""

from __future__ import annotations

import sys
import time

import nlobs

MODEL = '''
name = "tank"
states = ["h"]
inputs = ["u"]
outputs = ["y"]
[parameters]
k = { value = 0.3, unknown = true }
[dynamics]
h = "u - k*sqrt(max(h, 0))"
[output]
y = "h"
[simulation]
t_final = 40.0
dt = 0.01
x0 = [1.0]
inputs = { u = "0.5 + 0.3*sin(0.5*t)" }
noise = { y = 0.01 }
sample_period = 0.1
true_parameters = { k = 0.5 }
[observers.ekf]
kind = "ekf"
Q = QQ
R = [[1e-4]]
P0 = [[0.1, 0], [0, 0.1]]
xhat0 = [0.8]
[observers.ukf]
kind = "ukf"
Q = QQ
R = [[1e-4]]
P0 = [[0.1, 0], [0, 0.1]]
xhat0 = [0.8]
'''

TUNINGS = {"Q matched (1e-8, 0)": "[[1e-8, 0], [0, 0]]", "Q inflated (1e-4, 1e-5)": "[[1e-4, 0], [0, 1e-5]]"}


def main(runs: int = 200) -> None:
    for label, q in TUNINGS.items():
        mf = nlobs.loads_model(MODEL.replace("QQ", q), path="tank")
        designs = nlobs.design.designs_from_file(mf)
        hits = dict.fromkeys(designs, 0)
        t0 = time.perf_counter()
        for seed in range(runs):
            run = nlobs.simulate(mf, designs, seed=seed)
            for name in designs:
                p = run.parameters(name)["k"]
                hits[name] += abs(p["estimate"] - p["true"]) < 2 * p["std"]
        shares = ", ".join(f"{n} {h / runs:.3f}" for n, h in hits.items())
        print(f"{label}: |k̂ − k| < 2σ in {shares} of {runs} runs ({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200)
