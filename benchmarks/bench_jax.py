"""The JAX engine (``engine="jax"``), the GPU path: Monte Carlo and the particle filter at the sizes it is for.

G1  Monte Carlo of the P2 problem at scale: Van der Pol (mu = 1, y = x1) with the observer of bench_core.py (L = 5,
    xh(0) = 0), RK4, dt = 1e-3, t in [0, 10] (10,000 steps), M initial states uniform in [-3, 3]^2, final states.
    - hand-written JAX, the reference: jax.vmap over the initial states of a lax.fori_loop of RK4 steps of the plant
      and the observer together (float64, jit);
    - nlobs.montecarlo(engine="jax"): nlobs's compiled step (plant, observer, escape check) translated to JAX;
    - nlobs.montecarlo(engine="c") on every core, for scale.
    Target: on a GPU, nlobs within 2x of the hand-written JAX. Both must agree (final states) to 1e-12.
G1n The same with measurement noise y + N(0, 0.05^2) at every step, nlobs only (the reference has none): drawn on the
    host, per run, as the C engine draws it (same seeds, same numbers), then sent to the device; and with
    draws="device", drawn by JAX inside the runs (other numbers, the same distribution).
G2  The bootstrap particle filter (design_pf) on 20 s of the same plant sampled at 20 Hz (y = x1 + N(0, 0.05^2)),
    P particles, engine="jax" against engine="c" (the C loop, one core).

First calls (JIT, compile) are reported apart; the timed calls are warm (interleaved, min and median).
Without a GPU, JAX runs on its CPU backend and the sizes default to small ones: the figures then say what the engine
costs on a CPU, not what a GPU gives; the device is printed and recorded with every row.

Run:  python benchmarks/bench_jax.py [--sizes 16000 160000 1000000] [--particles 100000 1000000] [--rounds 3]
      [--noise-max 160000] (the largest M with host-drawn noise; above it only draws='device' is run)
Needs JAX (pip install 'nlobs[jax]'; jax[cuda12] for an NVIDIA GPU). Results: benchmarks/results/bench_jax.json
(only from a machine with a GPU, unless --write: the CPU figures are not the GPU rows' figures).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import _common as cm  # noqa: E402

import nlobs  # noqa: E402
from nlobs.engine import usable_cores  # noqa: E402

MU, L, DT, T_FINAL, SEED = 1.0, 5.0, 1e-3, 10.0, 20240501
N = int(round(T_FINAL / DT))
VDP = nlobs.System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], params={"mu": MU})
OBS = nlobs.design_custom(VDP, states=["xh1", "xh2"], params={"L": L},
                          flow=["xh2 + 2*L*(y - xh1)", "mu*(1 - xh1**2)*xh2 - xh1 + L**2*(y - xh1)"])


def hand_written(jax):
    """The reference: plant and observer stepped together by RK4, vmapped over initial states (no noise)."""
    jnp, lax = jax.numpy, jax.lax

    def rhs(s):
        x1, x2, h1, h2 = s[0], s[1], s[2], s[3]
        return jnp.stack([x2, MU * (1 - x1 * x1) * x2 - x1, h2 + 2 * L * (x1 - h1),
                          MU * (1 - h1 * h1) * h2 - h1 + L * L * (x1 - h1)])

    def step(_, s):
        k1 = rhs(s)
        k2 = rhs(s + DT / 2 * k1)
        k3 = rhs(s + DT / 2 * k2)
        k4 = rhs(s + DT * k3)
        return s + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    one = lambda x0: lax.fori_loop(0, N, step, jnp.concatenate([x0, jnp.zeros(2)]))  # noqa: E731
    run = jax.jit(jax.vmap(one))
    return lambda X0: np.asarray(run(jnp.asarray(X0)).block_until_ready())


def nlobs_mc(engine: str, noise: bool, draws: str = "host"):
    def run(X0):
        mc = nlobs.montecarlo(VDP, {"obs": OBS}, t_final=T_FINAL, dt=DT, x0=X0, save_every=N, engine=engine,
                              noise=nlobs.Noise.gaussian(0.05) if noise else None, seed=SEED, draws=draws)
        return np.column_stack([mc.x[:, -1], mc.observers["obs"].xhat[:, -1]])
    return run


def monte_carlo(jax, sizes: list[int], rounds: int, device: str, noise_max: int | None,
                save) -> list[dict]:
    rows = []
    ref = hand_written(jax)
    for M in sizes:
        X0 = np.random.default_rng(SEED).uniform(-3, 3, (M, 2))
        fns = {"hand-written JAX": lambda X0=X0: ref(X0), "nlobs jax": lambda X0=X0: nlobs_mc("jax", False)(X0),
               "nlobs c": lambda X0=X0: nlobs_mc("c", False)(X0),
               "nlobs jax, noise": lambda X0=X0: nlobs_mc("jax", True)(X0),
               "nlobs jax, noise on device": lambda X0=X0: nlobs_mc("jax", True, "device")(X0),
               "nlobs c, noise": lambda X0=X0: nlobs_mc("c", True)(X0)}
        host = noise_max is None or M <= noise_max   # host-drawn noise: M x N numbers drawn, and sent to the device
        if not host:
            del fns["nlobs jax, noise"], fns["nlobs c, noise"]
        first = {k: cm.first_call(fn) for k, fn in fns.items()}
        timed = cm.interleaved(fns, rounds)
        print(f"\nG1: M = {M:,} runs of {N:,} RK4 steps (plant + observer), final states; JAX on {device}, C on "
              f"{usable_cores()} core(s)")
        for k, (mn, med, out) in timed.items():
            if "device" in k:   # other draws: the estimate's error, beside that of the host's draws
                rms = [float(np.sqrt(np.mean((v[:, 2:] - v[:, :2]) ** 2)))
                       for v in (out, *([timed["nlobs c, noise"][2]] if host else []))]
                dev = f"RMS x̂ - x {rms[0]:.2e}" + (f" (host draws {rms[1]:.2e})" if host else "")
            else:
                base = timed["hand-written JAX"][2] if "noise" not in k else timed["nlobs c, noise"][2]
                dev = f"max |dev| {np.max(np.abs(out - base)):.1e} (against {'the reference' if 'noise' not in k else 'nlobs c'})"
            print(f"  {k:<27} first {first[k]:7.2f} s   min {mn:8.3f} s   median {med:8.3f} s   {dev}")
        dev = float(np.max(np.abs(timed["nlobs jax"][2] - timed["hand-written JAX"][2])))
        rows.append(cm.row("G1", f"Monte Carlo, {M:,} runs x {N:,} steps, final states ({device})",
                           nlobs="nlobs.montecarlo(engine='jax')", t_nlobs=timed["nlobs jax"][:2],
                           err_nlobs=f"max |dev| {dev:.1e}", peer=f"hand-written JAX (vmap, fori_loop; {device})",
                           t_peer=timed["hand-written JAX"][:2], err_peer="reference", kind="nlobs/peer",
                           target="<= 2x (GPU)", threshold=2.0 if device.startswith("gpu") else None,
                           note=f"engine='c' on {usable_cores()} core(s): {timed['nlobs c'][0]:.3f} s min; with noise: "
                                + (f"jax {timed['nlobs jax, noise'][0]:.3f} s (drawn on the host), " if host else "")
                                + f"{timed['nlobs jax, noise on device'][0]:.3f} s (draws='device')"
                                + (f", c {timed['nlobs c, noise'][0]:.3f} s min" if host else
                                   f" (host draws not run above M = {noise_max:,}: --noise-max)")
                                + f"; first calls jax {first['nlobs jax']:.1f} s, hand-written {first['hand-written JAX']:.1f} s"))
        cm.print_row(rows[-1])
        save(rows)
    return rows


def particle_filter(particles: list[int], rounds: int, device: str, save, done: list[dict]) -> list[dict]:
    rows = []
    run = nlobs.simulate(VDP, {}, t_final=20.0, dt=1e-3, x0=[2.0, 0.0], noise=nlobs.Noise.gaussian(0.05),
                         sampling=nlobs.Sampling(0.05), seed=0)
    rec = nlobs.Recording.from_run(run, every=50)
    for P in particles:
        fns, first = {}, {}
        for engine in ("jax", "c"):
            d = nlobs.design_pf(VDP, Q=np.eye(2) * 1e-2, R=np.eye(1) * 0.05 ** 2, P0=np.eye(2), xhat0=[0.0, 0.0],
                                particles=P, seed=1, engine=engine)
            fns[engine] = lambda d=d: nlobs.estimate(d, rec).observers["pf"].xhat
            first[engine] = cm.first_call(fns[engine])
        timed = cm.interleaved(fns, rounds)
        err = {k: float(np.sqrt(np.mean(np.sum((v[2][100:] - rec.x[100:]) ** 2, axis=1)))) for k, v in timed.items()}
        print(f"\nG2: bootstrap particle filter, {P:,} particles, {rec.t.size} samples; JAX on {device}")
        for k, (mn, med, _) in timed.items():
            print(f"  {k:<4} first {first[k]:7.2f} s   min {mn:8.3f} s   median {med:8.3f} s   RMS error {err[k]:.4f}")
        rows.append(cm.row("G2", f"bootstrap PF, {P:,} particles, {rec.t.size} samples ({device})",
                           nlobs="design_pf(engine='jax')", t_nlobs=timed["jax"][:2], err_nlobs=f"RMS {err['jax']:.4f}",
                           peer="design_pf(engine='c'), the C loop", t_peer=timed["c"][:2], err_peer=f"RMS {err['c']:.4f}",
                           kind="peer/nlobs", target="(report)", threshold=None))
        cm.print_row(rows[-1])
        save(done + rows)
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="*", help="Monte Carlo runs (default: 16,000 160,000 1,000,000 on a "
                    "GPU; 1,000 4,000 on a CPU)")
    ap.add_argument("--particles", type=int, nargs="*", help="particles (default: 100,000 1,000,000 on a GPU; 10,000 "
                    "on a CPU)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--write", action="store_true", help="write the results file from a machine without a GPU too")
    ap.add_argument("--noise-max", type=int, default=160_000,
                    help="the largest M run with noise drawn on the host (M x 10,000 numbers drawn and sent; default "
                         "160,000); larger M run with draws='device' only")
    args = ap.parse_args()
    try:
        import jax
    except ImportError:
        print("JAX is not installed (pip install 'nlobs[jax]'): nothing to run")
        return 0
    jax.config.update("jax_enable_x64", True)
    gpu = jax.default_backend() == "gpu"
    device = f"{jax.default_backend()}: {jax.devices()[0].device_kind}"
    sizes = args.sizes if args.sizes is not None else ([16_000, 160_000, 1_000_000] if gpu else [1_000, 4_000])
    particles = args.particles if args.particles is not None else ([100_000, 1_000_000] if gpu else [10_000])
    t0 = time.perf_counter()

    def save(rows: list[dict], final: bool = False) -> None:   # after every row: a run cut short keeps what it did
        if gpu or args.write:
            path = cm.write("bench_jax", rows, {"device": device, "complete": final})
            if final:
                print(f"wrote {path}")

    mc = monte_carlo(jax, sizes, args.rounds, device, args.noise_max, save)
    rows = mc + particle_filter(particles, args.rounds, device, save, mc)
    print(f"\n{time.perf_counter() - t0:.0f} s in all")
    save(rows, final=True)
    if not (gpu or args.write):
        print("no GPU: the results file is left as it is (--write to record these CPU figures)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
