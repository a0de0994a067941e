"""The data side of benchmarks/battery_dfn.py: a Li-ion cell simulated by PyBaMM's Doyle–Fuller–Newman model.

Runs in an environment that has PyBaMM (battery_dfn.py makes one: PyBaMM pins its own CasADi). Writes, into the
folder given on the command line:

* ``ocv.csv``      — a C/50 discharge and a C/50 charge over the whole SOC range (SOC, voltage): their mean is
  the open-circuit voltage as a test bench would identify it;
* ``pulse.csv``    — a 1C discharge pulse of 10 min from SOC 0.6 followed by one hour of rest (t, current, voltage);
* ``drive.csv``    — one hour of a drive-cycle-like current (t, i, v, soc): piecewise-constant segments of
  5–40 s between −0.5C (regeneration) and 1.5C, from SOC 0.8; `soc` is the simulator's own
  (initial SOC − discharged charge / nominal capacity) and is used only to score the estimate;
* ``training.csv`` — another hour of the same kind of current (another seed, from SOC 0.9), for fitting the
  circuit's resistances and capacitances.

Parameter set Chen2020 (LG M50, 5 Ah), PyBaMM's default DFN options, IDAKLU solver; the upper cut-off is raised
to 4.4 V so that regeneration near full charge does not stop the run.

Run: ``python benchmarks/dfn_recording.py OUT_DIR`` (with PyBaMM importable).
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
import pybamm

CAPACITY_AH = 5.0


def _params() -> pybamm.ParameterValues:
    pv = pybamm.ParameterValues("Chen2020")
    pv["Upper voltage cut-off [V]"] = 4.4
    return pv


def _solve(t: np.ndarray, current: np.ndarray, initial_soc: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pv = _params()
    pv["Current function [A]"] = pybamm.Interpolant(t, current, pybamm.t, interpolator="linear")
    sim = pybamm.Simulation(pybamm.lithium_ion.DFN(), parameter_values=pv, solver=pybamm.IDAKLUSolver())
    sol = sim.solve(t_eval=[float(t[0]), float(t[-1])], t_interp=t, initial_soc=initial_soc)
    ts = sol["Time [s]"].entries
    return ts, sol["Terminal voltage [V]"].entries, sol["Discharge capacity [A.h]"].entries


def _write(path: Path, header: list[str], cols: list[np.ndarray]) -> None:
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        w.writerows(zip(*(c.tolist() for c in cols)))


def ocv_curve(out: Path) -> None:
    """C/50 discharge from SOC 1 and C/50 charge from SOC 0, on a common SOC grid; their mean."""
    rate = CAPACITY_AH / 50
    t = np.arange(0.0, 50.5 * 3600, 60.0)
    ts, vd, qd = _solve(t, np.full(t.size, rate), 1.0)
    soc_d = 1.0 - qd / CAPACITY_AH
    tc, vc, qc = _solve(t, np.full(t.size, -rate), 0.0)
    soc_c = 0.0 - qc / CAPACITY_AH
    grid = np.linspace(max(soc_d.min(), soc_c.min()) + 1e-3, min(soc_d.max(), soc_c.max()) - 1e-3, 101)
    vd_g = np.interp(grid, soc_d[::-1], vd[::-1])
    vc_g = np.interp(grid, soc_c, vc)
    _write(out / "ocv.csv", ["soc", "v_discharge", "v_charge", "ocv"], [grid, vd_g, vc_g, (vd_g + vc_g) / 2])


def pulse(out: Path) -> None:
    t = np.arange(0.0, 4261.0, 0.5)
    current = np.where((t >= 60) & (t < 660), CAPACITY_AH, 0.0)
    ts, v, _ = _solve(t, current, 0.6)
    _write(out / "pulse.csv", ["t", "i", "v"], [ts, np.interp(ts, t, current), v])


def drive(out: Path, seed: int = 0, name: str = "drive.csv", soc0: float = 0.8) -> None:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 3601.0, 1.0)
    current = np.zeros_like(t)
    k = 0
    while k < t.size:
        n = int(rng.integers(5, 40))
        current[k:k + n] = rng.choice([-0.5, 0.0, 0.3, 0.6, 1.0, 1.5], p=[0.1, 0.1, 0.2, 0.3, 0.2, 0.1]) * CAPACITY_AH
        k += n
    # a zero-order hold, as `nlobs estimate` holds a logged input: the current logged at t_k is applied over
    # [t_k, t_k + 1 s), each switch a 1 ms ramp just before the sample instant (PyBaMM's interpolant is linear)
    tt = np.sort(np.concatenate([t, t[1:] - 1e-3]))
    ii = np.interp(tt, t, current)
    ii[1::2] = current[:-1]
    ts, v, q = _solve(tt, ii, soc0)
    keep = np.isin(np.round(ts, 6), t)
    _write(out / name, ["t", "i", "v", "soc"], [ts[keep], np.interp(ts[keep], tt, ii), v[keep],
                                                soc0 - q[keep] / CAPACITY_AH])


if __name__ == "__main__":
    folder = Path(sys.argv[1])
    folder.mkdir(parents=True, exist_ok=True)
    ocv_curve(folder)
    pulse(folder)
    drive(folder)                                            # the test: seen by the estimator only
    drive(folder, seed=1, name="training.csv", soc0=0.9)     # another profile, for fitting the circuit
    print(f"DFN recordings written to {folder} (PyBaMM {pybamm.__version__})")
