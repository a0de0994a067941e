"""Monte Carlo over noise seeds for the Ćuk comparison of 004 §V-C (nlobs.examples.cuk_converter).

Prints, per seed, the noise-induced RMS error (x̂ with noise minus x̂ without) of i1 and v4 for the
six observers, and whether the paper's noise claims hold for that seed. Not part of the test run:
    .venv/bin/python benchmarks/cuk_noise_seeds.py [n_seeds]
"""

from __future__ import annotations

import sys

import nlobs
from nlobs import simulate
from nlobs.examples import cuk_converter as ex
from nlobs.model import Sampled


def main(n_seeds: int = 10) -> None:
    system = ex.model()
    ds = ex.designs(system)
    x0 = ex.equilibrium(ex.SETPOINTS[0], system.params)
    vd = Sampled.piecewise([0.2 * k for k in range(len(ex.SETPOINTS))], ex.SETPOINTS)
    loop = simulate(ex.closed_loop(system), {}, t_final=ex.T_FINAL, dt=ex.DT, x0=x0, inputs={"Vd": vd})
    duty = Sampled(loop.t, loop.y_true[:, 0], "linear")
    clean = simulate(system, ds, t_final=ex.T_FINAL, dt=ex.DT, x0=x0, inputs={"u": duty})
    e_clean = ex._errors(clean)
    noise = nlobs.Noise.uniform(ex.NOISE, hold=ex.NOISE_PERIOD)
    names = list(ds)
    print("seed  " + "  ".join(f"{n[:10]:>21}" for n in names) + "   KKLO best v4  KKLO best i1")
    for seed in range(1, n_seeds + 1):
        noisy = simulate(system, ds, t_final=ex.T_FINAL, dt=ex.DT, x0=x0, inputs={"u": duty}, noise=noise, seed=seed)
        rows = {r.label: r for r in ex._rows(clean, noisy, ds, e_clean, ex._errors(noisy))}
        best = [rows["KKLO"].noise_rms[j] <= 1.01 * min(r.noise_rms[j] for r in rows.values()) for j in (1, 0)]
        cells = "  ".join(f"{rows[n].noise_rms[0]:9.2e} {rows[n].noise_rms[1]:9.2e}  " for n in names)
        print(f"{seed:>4}  {cells}   {best[0]!s:>12}  {best[1]!s:>12}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10)
