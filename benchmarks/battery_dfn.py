"""State of charge of a Li-ion cell simulated by a model nlobs did not write (issue 21 §4).

1. **Data from PyBaMM's DFN** (Doyle–Fuller–Newman, Chen2020 parameters, 5 Ah): a C/50 discharge and charge, a
   1C pulse with relaxation, and one hour of a drive-cycle-like current (benchmarks/dfn_recording.py). PyBaMM pins
   its own CasADi, so it runs in a virtual environment of its own (benchmarks/.venv-pybamm, made on first use
   with ``pip install pybamm==26.10.1.1``) unless the running Python already has it.
2. **An equivalent circuit identified from that data only**: OCV(SOC) as a lookup table (the mean of the C/50
   discharge and charge curves, 101 points, cubic); R0 and two RC pairs first from a 10-minute 1C pulse and the
   hour of relaxation after it (SciPy ``curve_fit``), then refined by least squares on a *training* hour of another
   drive profile (SciPy ``least_squares``; the test profile is never used): SOC' = −i/(3600 Q),
   v_k' = −v_k/(R_k C_k) + i/C_k, v = OCV(SOC) − v1 − v2 − R0 i.
3. **The estimate through the command line**: the drive cycle's voltage with 5 mV Gaussian sensor noise,
   ``nlobs estimate ecm.toml drive.csv --observer ekf``, an EKF started at SOC 0.5 while the cell is at 0.8
   (30 % of the capacity off). Target: SOC error below 2 % RMS after the first 10 minutes.

Run: ``PYTHONPATH=src python benchmarks/battery_dfn.py``; writes results/battery_dfn.json, results/battery_dfn.png
and results/battery_dfn.toml (the identified model).
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
import venv
from pathlib import Path

import numpy as np
from scipy.optimize import curve_fit

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
DATA = HERE / "results" / "dfn_data"
PYBAMM = "pybamm==26.10.1.1"
CAPACITY_AH = 5.0
SOC0_TRUE, SOC0_GUESS = 0.8, 0.5
NOISE_V = 0.005


def _read(path: Path) -> dict[str, np.ndarray]:
    with open(path, encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    return {k: np.array([float(r[j]) for r in rows[1:]]) for j, k in enumerate(rows[0])}


def make_data() -> None:
    """The DFN recordings, from PyBaMM in this Python or in benchmarks/.venv-pybamm."""
    try:
        import pybamm  # noqa: F401
        python = sys.executable
    except ImportError:
        env = HERE / ".venv-pybamm"
        python = str(env / "bin" / "python")
        if not Path(python).exists():
            print(f"making {env} with {PYBAMM} (once)")
            venv.create(env, with_pip=True)
            subprocess.run([python, "-m", "pip", "install", "--quiet", PYBAMM], check=True)
    subprocess.run([python, str(HERE / "dfn_recording.py"), str(DATA)], check=True)


def identify() -> dict[str, float]:
    """R0 from the voltage step at the start of the pulse; two RC pairs (a fast one for charge transfer, a slow one
    for diffusion) from a least-squares fit of the hour of relaxation after it."""
    p = _read(DATA / "pulse.csv")
    t, i, v = p["t"], p["i"], p["v"]
    on = int(np.flatnonzero(i > 0)[0])
    off = int(np.flatnonzero((t > t[on]) & (i == 0))[0])
    current = float(i[on])
    r0 = float((v[on - 1] - v[on]) / current)
    # after the pulse (the ohmic drop R0·I already back): v(s) = v_inf - R1·I·e^(-s/τ1) - R2·I·e^(-s/τ2)
    tr, vr = t[off + 1:] - t[off + 1], v[off + 1:]

    def relax(s: np.ndarray, v_inf: float, a1: float, tau1: float, a2: float, tau2: float) -> np.ndarray:
        return v_inf - a1 * np.exp(-s / tau1) - a2 * np.exp(-s / tau2)

    drop = vr[-1] - vr[0]
    (v_inf, a1, tau1, a2, tau2), _ = curve_fit(relax, tr, vr, p0=(vr[-1], drop / 2, 30.0, drop / 2, 600.0), maxfev=20000)
    if tau1 > tau2:
        a1, tau1, a2, tau2 = a2, tau2, a1, tau1
    r1, r2 = float(a1 / current), float(a2 / current)
    return {"R0": r0, "R1": r1, "C1": float(tau1 / r1), "R2": r2, "C2": float(tau2 / r2), "tau1": float(tau1),
            "tau2": float(tau2), "fit_rms_v": float(np.sqrt(np.mean((relax(tr, v_inf, a1, tau1, a2, tau2) - vr) ** 2)))}


def fit_on_training(start: dict[str, float]) -> dict[str, float]:
    """R0, R1, C1, R2, C2 by least squares on the training hour (a profile the estimator never sees), from the
    pulse values; the circuit is simulated exactly between samples (zero-order hold of the current) with the
    simulator's SOC, so only the circuit's voltage drop is fitted, not the state."""
    from scipy.interpolate import CubicSpline
    from scipy.optimize import least_squares

    d, o = _read(DATA / "training.csv"), _read(DATA / "ocv.csv")
    ocv = CubicSpline(o["soc"], o["ocv"])(d["soc"])
    i, v, dt = d["i"], d["v"], float(np.diff(d["t"])[0])

    def predicted(q: np.ndarray) -> np.ndarray:
        r0, r1, tau1, r2, tau2 = np.exp(q)
        out, v1, v2 = np.empty_like(v), 0.0, 0.0
        a1, a2 = np.exp(-dt / tau1), np.exp(-dt / tau2)
        for k in range(v.size):
            out[k] = ocv[k] - v1 - v2 - r0 * i[k]
            v1, v2 = a1 * v1 + r1 * (1 - a1) * i[k], a2 * v2 + r2 * (1 - a2) * i[k]
        return out

    q0 = np.log([start["R0"], start["R1"], start["tau1"], start["R2"], start["tau2"]])
    sol = least_squares(lambda q: predicted(q) - v, q0, x_scale=1.0)
    r0, r1, tau1, r2, tau2 = np.exp(sol.x)
    return {"R0": float(r0), "R1": float(r1), "C1": float(tau1 / r1), "R2": float(r2), "C2": float(tau2 / r2),
            "tau1": float(tau1), "tau2": float(tau2), "fit_rms_v": float(np.sqrt(np.mean(sol.fun ** 2))),
            "pulse": start}


def write_model(params: dict[str, float], path: Path) -> None:
    o = _read(DATA / "ocv.csv")
    soc, ocv = o["soc"], o["ocv"]
    fmt = ", ".join
    path.write_text(f'''# An equivalent circuit identified from PyBaMM's DFN (benchmarks/battery_dfn.py); OCV from C/50 curves
name = "cell_ecm"
states = ["soc", "v1", "v2"]
inputs = ["i"]
outputs = ["v"]

[parameters]
Q = {CAPACITY_AH}
R0 = {params["R0"]!r}
R1 = {params["R1"]!r}
C1 = {params["C1"]!r}
R2 = {params["R2"]!r}
C2 = {params["C2"]!r}

[tables.ocv]
x = [{fmt(repr(float(s)) for s in soc)}]
y = [{fmt(repr(float(v)) for v in ocv)}]
method = "cubic"

[dynamics]
soc = "-i/(3600*Q)"
v1 = "-v1/(R1*C1) + i/C1"
v2 = "-v2/(R2*C2) + i/C2"

[output]
v = "ocv(soc) - v1 - v2 - R0*i"

[units]
soc = "1"
v1 = "V"
v2 = "V"
i = "A"
v = "V"

[observers.ekf]
kind = "ekf"
xhat0 = [{SOC0_GUESS}, 0.0, 0.0]
P0 = [[0.1, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]]
Q = [[1e-9, 0.0, 0.0], [0.0, 1e-6, 0.0], [0.0, 0.0, 1e-6]]
R = [[4e-4]]
''', encoding="utf-8")


def main() -> dict[str, object]:
    if not (DATA / "training.csv").exists():
        make_data()
    params = fit_on_training(identify())
    model = RESULTS / "battery_dfn.toml"
    write_model(params, model)
    d = _read(DATA / "drive.csv")
    rng = np.random.default_rng(1)
    noisy = RESULTS / "battery_dfn_drive.csv"
    with open(noisy, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["t", "i", "v"])
        w.writerows(zip(d["t"].tolist(), d["i"].tolist(), (d["v"] + NOISE_V * rng.standard_normal(d["t"].size)).tolist()))
    est_csv = RESULTS / "battery_dfn_estimate.csv"
    cmd = [sys.executable, "-m", "nlobs.cli", "estimate", str(model), str(noisy), "--observer", "ekf", "--json",
           "--output", str(est_csv)]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True)
    summary = json.loads(out.stdout)
    e = _read(est_csv)
    err = e["ekf.soc"] - d["soc"]
    after = d["t"] >= 600.0
    # the same with the circuit from the pulse alone (no training hour): what the refinement buys
    pulse_model = RESULTS / "battery_dfn_estimate_pulse.toml"
    write_model(params["pulse"], pulse_model)
    subprocess.run([*cmd[:4], str(pulse_model), *cmd[5:-1], str(est_csv) + ".pulse"], check=True, capture_output=True)
    err_pulse = _read(Path(str(est_csv) + ".pulse"))["ekf.soc"] - d["soc"]
    pulse_model.unlink()
    result = {
        "pybamm": PYBAMM, "parameters": params, "soc0_true": SOC0_TRUE, "soc0_guess": SOC0_GUESS, "noise_v": NOISE_V,
        "soc_rms_after_600s": float(np.sqrt(np.mean(err[after] ** 2))),
        "soc_max_after_600s": float(np.max(np.abs(err[after]))),
        "soc_final_error": float(err[-1]), "soc_range": [float(d["soc"].min()), float(d["soc"].max())],
        "soc_rms_after_600s_pulse_only": float(np.sqrt(np.mean(err_pulse[after] ** 2))),
        "innovations": summary["observers"]["ekf"].get("innovations"), "command": " ".join(cmd[2:]),
    }
    (RESULTS / "battery_dfn.json").write_text(json.dumps(result, indent=2), encoding="utf-8")
    _plot(d, e, result)
    print(json.dumps({k: result[k] for k in ("parameters", "soc_rms_after_600s", "soc_max_after_600s", "soc_final_error",
                                             "soc_rms_after_600s_pulse_only")},
                     indent=2))
    print("target: SOC RMS error < 0.02 after 600 s:", "met" if result["soc_rms_after_600s"] < 0.02 else "NOT met")
    return result


def _plot(d: dict[str, np.ndarray], e: dict[str, np.ndarray], result: dict[str, object]) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 6), layout="constrained")
    a1, a2, a3 = fig.subplots(3, 1, sharex=True)
    t = d["t"] / 60
    a1.plot(t, d["soc"], "k", lw=1.6, label="DFN (PyBaMM)")
    a1.plot(t, e["ekf.soc"], "C1", lw=1.2, label="EKF on the identified ECM (nlobs estimate)")
    a1.set_ylabel("SOC [1]")
    a1.legend(fontsize="small")
    a2.plot(t, 100 * (e["ekf.soc"] - d["soc"]), "C1", lw=1)
    a2.axvline(10, color="0.5", ls=":", lw=1)
    a2.axhspan(-2, 2, color="C2", alpha=0.15, lw=0)
    a2.set_ylim(-10, 10)
    a2.set_ylabel("SOC error [%]")
    a2.set_title(f"RMS after 10 min: {100 * result['soc_rms_after_600s']:.2f} % (target < 2 %)", fontsize="small")
    a3.plot(t, d["i"], "C0", lw=0.8)
    a3.set_ylabel("i [A]")
    a3.set_xlabel("t [min]")
    fig.suptitle("SOC of a DFN cell (PyBaMM, Chen2020) from its voltage: EKF started 30 % off")
    fig.savefig(RESULTS / "battery_dfn.png", dpi=110)


if __name__ == "__main__":
    main()
