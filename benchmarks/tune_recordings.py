"""Three recordings with known process noise, drawn in plain NumPy outside nlobs (issue 42, Targets).

Each system is simulated here with its own integrator or map and its own noise (nothing of nlobs is imported), and
written as a recording nlobs reads (``t``, the inputs, the outputs; empty cells where a slower sensor had nothing),
with the model file that declares the output noise R (``[simulation] noise``) but not the process noise Q:

* ``tune_pendulum``   a pendulum map at 100 Hz (symplectic Euler step), angle measured, noise on both states;
* ``tune_ct``         a target in a coordinated turn whose turn rate wanders (a random walk), tracked by range and
                      bearing from a fixed radar at the origin, a map at 10 Hz;
* ``tune_unicycle``   a wheeled robot in continuous time, dx = f dt + G dW with random-walk speed and turn rate,
                      simulated by Euler-Maruyama at 1 kHz; GPS at 2 Hz, gyro at 50 Hz.

For each, two records with different seeds: ``NAME_data.csv`` (to tune on) and ``NAME_valid.csv`` (held out, to
score on), the true states of each (``NAME_data_truth.csv``, ``NAME_valid_truth.csv``) and the true Q and R
(``NAME_truth.json``; for the maps Q is the covariance of one step's noise, for the continuous model the intensity
of dW, as nlobs' continuous-discrete filters take it).

    python benchmarks/tune_recordings.py           # writes benchmarks/tune_data/
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

OUT = Path(__file__).with_name("tune_data")
SEEDS = {"data": 11, "valid": 12}

# ---------------------------------------------------------------- the systems and their true noise
PEND = dict(T=0.01, a=9.81, c=0.3, x0=[0.8, 0.0], t_final=60.0,
            q_std=[2e-4, 5e-3], r_std=[0.01])
CT = dict(T=0.1, x0=[8000.0, 1000.0, 20.0, 2.0, 0.03], t_final=300.0,
          q_std=[0.1, 0.1, 0.05, 1e-3, 1e-3], r_std=[10.0, 2e-3])
UNI = dict(dt=1e-3, x0=[0.0, 0.0, 0.5, 2.0, 0.1], t_final=120.0, gps_period=0.5, gyro_period=0.02,
           q_std=[0.0, 0.0, 0.0, 0.1, 0.05], r_std=[0.5, 0.5, 0.02])


def u_pend(t: np.ndarray) -> np.ndarray:
    return 2.0 * np.sin(0.7 * t)


def pendulum(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """x1[k+1] = x1 + T x2[k+1], x2[k+1] = x2 + T (-a sin x1 - c x2 + u) (symplectic Euler), plus w[k]; y = x1 + v."""
    rng = np.random.default_rng(seed)
    T, a, c = PEND["T"], PEND["a"], PEND["c"]
    N = int(round(PEND["t_final"] / T)) + 1
    t = T * np.arange(N)
    u = u_pend(t)
    x = np.zeros((N, 2))
    x[0] = PEND["x0"]
    w = rng.standard_normal((N, 2)) * PEND["q_std"]
    for k in range(N - 1):
        x1, x2 = x[k]
        x2n = x2 + T * (-a * np.sin(x1) - c * x2 + u[k])
        x[k + 1] = [x1 + T * x2n + w[k, 0], x2n + w[k, 1]]
    y = x[:, :1] + rng.standard_normal((N, 1)) * PEND["r_std"]
    return t, u[:, None], y, x


def coordinated_turn(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """px += T v cos(psi), py += T v sin(psi), v, psi += T omega, omega (random walk), each plus w[k];
    y = (range, bearing) from the origin."""
    rng = np.random.default_rng(seed)
    T = CT["T"]
    N = int(round(CT["t_final"] / T)) + 1
    t = T * np.arange(N)
    x = np.zeros((N, 5))
    x[0] = CT["x0"]
    w = rng.standard_normal((N, 5)) * CT["q_std"]
    for k in range(N - 1):
        px, py, v, psi, om = x[k]
        x[k + 1] = np.array([px + T * v * np.cos(psi), py + T * v * np.sin(psi), v, psi + T * om, om]) + w[k]
    rng_y = np.hypot(x[:, 0], x[:, 1])
    bearing = np.arctan2(x[:, 1], x[:, 0])
    assert np.all(x[:, 0] > 0), "the target crossed behind the radar: the bearing would wrap"
    y = np.column_stack([rng_y, bearing]) + rng.standard_normal((N, 2)) * CT["r_std"]
    return t, np.zeros((N, 0)), y, x


def unicycle(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """dx = v cos(th) dt, dy = v sin(th) dt, dth = om dt, dv = s_v dW, dom = s_om dW (Euler-Maruyama at 1 kHz);
    GPS (x, y) every 0.5 s, gyro (om) every 0.02 s, rows every 0.02 s (GPS empty in the others)."""
    rng = np.random.default_rng(seed)
    dt = UNI["dt"]
    n_fine = int(round(UNI["t_final"] / dt))
    q = np.asarray(UNI["q_std"])
    s = np.asarray(UNI["x0"], dtype=float)
    every = int(round(UNI["gyro_period"] / dt))
    gps_every = int(round(UNI["gps_period"] / UNI["gyro_period"]))
    rows_x = [s.copy()]
    dW = rng.standard_normal((n_fine, 5)) * np.sqrt(dt) * q
    for k in range(n_fine):
        x_, y_, th, v, om = s
        s = s + dt * np.array([v * np.cos(th), v * np.sin(th), om, 0.0, 0.0]) + dW[k]
        if (k + 1) % every == 0:
            rows_x.append(s.copy())
    x = np.array(rows_x)
    N = x.shape[0]
    t = UNI["gyro_period"] * np.arange(N)
    r = np.asarray(UNI["r_std"])
    y = x[:, [0, 1, 4]] + rng.standard_normal((N, 3)) * r
    gps_missing = np.arange(N) % gps_every != 0
    y[gps_missing, 0:2] = np.nan
    return t, np.zeros((N, 0)), y, x


# ---------------------------------------------------------------- the model files (R declared, Q not)
PEND_TOML = f'''# Pendulum map at 100 Hz (benchmarks/tune_recordings.py): symplectic Euler step of
# x1'' = -a sin(x1) - c x1' + u. Output noise declared; the process noise of the recordings is NOT declared.
name = "tune_pendulum"
description = "pendulum map at 100 Hz, angle measured; process noise unknown to the file"
time = "discrete"
sample_time = {PEND["T"]}
states = ["x1", "x2"]
inputs = ["u"]
outputs = ["y"]

[parameters]
a = {PEND["a"]}
c = {PEND["c"]}
T = {PEND["T"]}

[dynamics]
x1 = "x1 + T*(x2 + T*(-a*sin(x1) - c*x2 + u))"
x2 = "x2 + T*(-a*sin(x1) - c*x2 + u)"

[output]
y = "x1"

[simulation]
t_final = {PEND["t_final"]}
x0 = {PEND["x0"]}
inputs = {{ u = "2*sin(0.7*t)" }}
noise = {{ y = {PEND["r_std"][0]} }}
seed = 1
'''

CT_TOML = f'''# Coordinated turn of wandering turn rate, tracked by range and bearing from a radar at the origin, a map at
# 10 Hz (benchmarks/tune_recordings.py). Output noise declared; the process noise (the turn rate's random walk
# among it) is NOT declared.
name = "tune_ct"
description = "coordinated turn, range and bearing radar, map at 10 Hz; process noise unknown to the file"
time = "discrete"
sample_time = {CT["T"]}
states = ["px", "py", "v", "psi", "omega"]
outputs = ["range", "bearing"]

[parameters]
T = {CT["T"]}

[dynamics]
px = "px + T*v*cos(psi)"
py = "py + T*v*sin(psi)"
v = "v"
psi = "psi + T*omega"
omega = "omega"

[output]
range = "sqrt(px**2 + py**2)"
bearing = "atan2(py, px)"

[simulation]
t_final = {CT["t_final"]}
x0 = {CT["x0"]}
noise = {{ range = {CT["r_std"][0]}, bearing = {CT["r_std"][1]} }}
seed = 1
'''

UNI_TOML = f'''# Wheeled robot (unicycle) in continuous time with random-walk speed and turn rate (benchmarks/tune_recordings.py):
# the recordings are Euler-Maruyama at 1 kHz of dv = s_v dW, domega = s_w dW. GPS at 2 Hz, gyro at 50 Hz.
# Output noise declared; the process noise is NOT declared.
name = "tune_unicycle"
description = "unicycle, random-walk speed and turn rate, GPS 2 Hz and gyro 50 Hz; process noise unknown to the file"
states = ["x", "y", "theta", "v", "omega"]
outputs = ["gx", "gy", "gyro"]

[dynamics]
x = "v*cos(theta)"
y = "v*sin(theta)"
theta = "omega"
v = "0"
omega = "0"

[output]
gx = "x"
gy = "y"
gyro = "omega"

[simulation]
t_final = {UNI["t_final"]}
dt = {UNI["gyro_period"]}
x0 = {UNI["x0"]}
noise = {{ gx = {UNI["r_std"][0]}, gy = {UNI["r_std"][1]}, gyro = {UNI["r_std"][2]} }}
sample_period = {{ gx = {UNI["gps_period"]}, gy = {UNI["gps_period"]}, gyro = {UNI["gyro_period"]} }}
seed = 1
'''

SYSTEMS = {
    "tune_pendulum": dict(draw=pendulum, toml=PEND_TOML, states=["x1", "x2"], inputs=["u"], outputs=["y"],
                          kind="map", Q=np.diag(np.square(PEND["q_std"])), R=np.diag(np.square(PEND["r_std"]))),
    "tune_ct": dict(draw=coordinated_turn, toml=CT_TOML, states=["px", "py", "v", "psi", "omega"], inputs=[],
                    outputs=["range", "bearing"], kind="map", Q=np.diag(np.square(CT["q_std"])),
                    R=np.diag(np.square(CT["r_std"]))),
    "tune_unicycle": dict(draw=unicycle, toml=UNI_TOML, states=["x", "y", "theta", "v", "omega"], inputs=[],
                          outputs=["gx", "gy", "gyro"], kind="continuous", Q=np.diag(np.square(UNI["q_std"])),
                          R=np.diag(np.square(UNI["r_std"]))),
}


def _write_csv(path: Path, header: list[str], cols: np.ndarray) -> None:
    def cell(v: float) -> str:
        return "" if np.isnan(v) else f"{v:.10g}"
    with path.open("w") as fh:
        fh.write(",".join(header) + "\n")
        for r in cols:
            fh.write(",".join(cell(v) for v in r) + "\n")


def write_all(out: Path = OUT) -> dict[str, dict[str, str]]:
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, dict[str, str]] = {}
    for name, spec in SYSTEMS.items():
        (out / f"{name}.toml").write_text(spec["toml"])
        files[name] = {"model": str(out / f"{name}.toml")}
        for which, seed in SEEDS.items():
            t, u, y, x = spec["draw"](seed)
            _write_csv(out / f"{name}_{which}.csv", ["t", *spec["inputs"], *spec["outputs"]], np.column_stack([t, u, y]))
            _write_csv(out / f"{name}_{which}_truth.csv", ["t", *spec["states"]], np.column_stack([t, x]))
            files[name][which] = str(out / f"{name}_{which}.csv")
            files[name][which + "_truth"] = str(out / f"{name}_{which}_truth.csv")
        truth = {"Q": spec["Q"].tolist(), "R": spec["R"].tolist(), "states": spec["states"], "outputs": spec["outputs"],
                 "kind": spec["kind"], "seeds": SEEDS,
                 "Q_is": "covariance of one step's noise" if spec["kind"] == "map" else "intensity of dW (per second)"}
        (out / f"{name}_truth.json").write_text(json.dumps(truth, indent=1) + "\n")
        files[name]["truth"] = str(out / f"{name}_truth.json")
    return files


if __name__ == "__main__":
    for name, f in write_all().items():
        print(name, ", ".join(f"{k}: {Path(v).name}" for k, v in f.items()))
