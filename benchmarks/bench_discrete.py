"""Discrete-time EKF (issue 21): nlobs against filterpy's ExtendedKalmanFilter on the same map and data.

P12  10⁴ steps of a 2-state nonlinear map (a damped pendulum discretised by hand, two outputs y = (x1, x1·x2)),
     Q per step, R, P0; predict with u[k−1] from x[k−1|k−1], correct with y[k] (Joseph form) — filterpy's
     ``ExtendedKalmanFilter`` with ``predict_x`` set to the map and F = ∂f/∂x set before each ``predict``, and
     ``nlobs.estimate`` on the model file's discrete EKF. Same estimates to 1e-10 (checked, printed), ratio
     filterpy / nlobs (min and median over interleaved rounds). Target: ≥ 50×.

Run: ``PYTHONPATH=src python benchmarks/bench_discrete.py [--quick]``; writes results/bench_discrete.json.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _common import first_call, interleaved, print_row, row, write  # noqa: E402

import nlobs  # noqa: E402

T = 0.05
SYSTEM = nlobs.System(states=["x1", "x2"], f=[f"x1 + {T}*x2", f"x2 + {T}*(-sin(x1) - 0.3*x2 + u)"], inputs=["u"],
                      outputs=["y1", "y2"], h=["x1", "x1*x2"], time="discrete", sample_time=T, name="pendulum_map")
Q, R, P0, X0 = np.diag([1e-4, 1e-4]), np.diag([0.0025, 0.0025]), np.diag([0.5, 0.5]), np.array([0.5, 0.3])


def f(x: np.ndarray, u: float) -> np.ndarray:
    return np.array([x[0] + T * x[1], x[1] + T * (-np.sin(x[0]) - 0.3 * x[1] + u)])


def F(x: np.ndarray) -> np.ndarray:
    return np.array([[1.0, T], [-T * np.cos(x[0]), 1 - 0.3 * T]])


def h(x: np.ndarray) -> np.ndarray:
    return np.array([x[0], x[0] * x[1]])


def H(x: np.ndarray) -> np.ndarray:
    return np.array([[1.0, 0.0], [x[1], x[0]]])


def data(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = 0.5 * np.sin(0.1 * np.arange(n))
    x = np.zeros((n, 2))
    x[0] = [1.0, 0.0]
    for k in range(n - 1):
        x[k + 1] = f(x[k], u[k]) + 0.01 * rng.standard_normal(2)
    y = np.array([h(v) for v in x]) + 0.05 * rng.standard_normal((n, 2))
    return np.arange(n) * T, u, x, y


def filterpy_ekf(u: np.ndarray, y: np.ndarray) -> np.ndarray:
    from filterpy.kalman import ExtendedKalmanFilter

    ekf = ExtendedKalmanFilter(dim_x=2, dim_z=2, dim_u=1)
    ekf.x, ekf.P, ekf.Q, ekf.R = X0.copy(), P0.copy(), Q.copy(), R.copy()

    def predict_x(uk: float) -> None:   # the map (filterpy's default sets x = F x + B u)
        ekf.x = f(ekf.x, uk)

    ekf.predict_x = predict_x
    out = np.empty_like(y)
    for k in range(len(y)):
        if k:
            ekf.F = F(ekf.x)
            ekf.predict(u[k - 1])
        ekf.update(y[k], H, h)
        out[k] = ekf.x
    return out


def bench(n: int, rounds: int) -> dict:
    t, u, x, y = data(n)
    rec = nlobs.Recording.from_arrays(SYSTEM, t, y=y, u=u[:, None])
    design = nlobs.design_ekf(SYSTEM, Q=Q, R=R, P0=P0, xhat0=X0)
    build = first_call(lambda: nlobs.estimate(design, rec))
    res = interleaved({"nlobs": lambda: nlobs.estimate(design, rec).observers["ekf"].xhat,
                       "filterpy": lambda: filterpy_ekf(u, y)}, rounds)
    diff = float(np.max(np.abs(res["nlobs"][2] - res["filterpy"][2])))
    rms = float(np.sqrt(np.mean((res["nlobs"][2][n // 10:] - x[n // 10:]) ** 2)))
    r = row("P12", f"discrete-time EKF, {n:,} steps of a 2-state map, 2 outputs", nlobs="nlobs.estimate (discrete ekf)",
            t_nlobs=res["nlobs"][:2], err_nlobs=f"max |x̂ − filterpy| {diff:.1e}; RMS error {rms:.3g}",
            peer="filterpy ExtendedKalmanFilter", t_peer=res["filterpy"][:2], err_peer="same estimates",
            kind="peer/nlobs", target="≥ 50×", threshold=50.0,
            note=f"first call (design compiled, functions built) {build:.3g} s; same estimates to 1e-10: {diff <= 1e-10}")
    return r


def main() -> int:
    quick = "--quick" in sys.argv
    r = bench(10**4, 3 if quick else 9)
    print_row(r)
    write("bench_discrete", [r])
    return 0


if __name__ == "__main__":
    sys.exit(main())
