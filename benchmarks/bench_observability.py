"""Benchmark (not a test): nlobs' generic-rank observability vs StrikePy, in one process.

Usage::

    python benchmarks/bench_observability.py [--timeout 60] [--models HIV,phos] [--no-strikepy] [--repeat 3]

It installs nothing. When ``StrikePy`` (PyPI ``strikepy==1.0``, GPLv3, the Python port of
STRIKE-GOLDD's FISPO) is importable, each of its 23 shipped models is analysed by both tools in
this process: StrikePy through ``strike_goldd(options_module)`` with an options module injected
into ``sys.modules`` (its shipped options where they exist; otherwise generic known inputs,
nnzDerU = inf, and unknown inputs of degree 1, nnzDerW = 1, since its default nnzDerW = inf never
terminates), stopped after ``--timeout`` seconds by SIGALRM. nlobs reads the same model module
(symbols, f, h, p, u, w) and runs :func:`nlobs.analysis.analyze` with every parameter unknown and
the same input classes. The table gives both times, the ratio, both verdicts, and whether the
verdicts agree (per state, parameter and unknown input). Then the targets of issue 6 / SPEC P4:
every model in < 1 s with nlobs, a 50-state nonlinear chain in < 2 s.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import math
import re
import signal
import statistics
import sys
import time
import types
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

import sympy as sp  # noqa: E402

from nlobs import System  # noqa: E402
from nlobs.analysis import InputClass, analyze  # noqa: E402
from nlobs.model._system import RESERVED  # noqa: E402

MODELS = ["1A_integral", "1B_prop_integral", "1C_nonlinear", "1D_BIG", "Arabidopsis", "BIG_known_input", "Bolie", "C2M",
          "C2M_2outputs", "C2M_unknown_input_known_b", "C2M_unknown_input_known_b_k1e", "CR", "HIV", "HIV_1", "JAKSTAT",
          "MAPK", "PK", "SIWR", "TS_unknown_inputs_reparameterized", "p53", "phos", "sirs", "tumor"]


def _flat(v) -> list:
    out = []
    for e in v or []:
        if isinstance(e, (list, tuple)):
            out.extend(_flat(e))
        else:
            out.append(e)
    return out


def _safe(name: str) -> str:
    return name + "_" if name in RESERVED or not re.match(r"^[A-Za-z][A-Za-z0-9_]*$", name) else name


def _options(name: str):
    """StrikePy's shipped options for `name`, or the defaults described in the module docstring."""
    try:
        opt = importlib.import_module(f"StrikePy.custom_options.options_{name}")
        return list(getattr(opt, "nnzDerU", [])), list(getattr(opt, "nnzDerW", [])), list(getattr(opt, "prev_ident_pars", [])), True
    except ModuleNotFoundError:
        return None, None, [], False


def to_system(name: str):
    """The StrikePy model module as an nlobs System plus the analysis options (same input classes)."""
    mod = importlib.import_module(f"StrikePy.models.{name}")
    # (dict.fromkeys: StrikePy's MAPK declares KK1, KK2 = symbols('n1 n2'), so n1 and n2 are listed twice)
    xs, ps, us, ws = (list(dict.fromkeys(_flat(getattr(mod, k, [])))) for k in ("x", "p", "u", "w"))
    f, h = _flat(mod.f), _flat(mod.h)
    nnzU, nnzW, prev, _ = _options(name)
    if nnzU is None:
        nnzU, nnzW = [math.inf] * len(us), [1] * len(ws)
    nnzW = (nnzW or []) + [1] * (len(ws) - len(nnzW or []))
    nnzW = [1 if (w is None or w == math.inf) else int(w) for w in nnzW]  # inf never terminates in StrikePy
    declared = {*xs, *ps, *us, *ws}
    extra = sorted({s for e in (*f, *h) for s in sp.sympify(e).free_symbols} - declared, key=str)
    ren = {s: sp.Symbol(_safe(s.name)) for s in (*declared, *extra)}
    params = {ren[s].name: 1.0 for s in ps}
    # symbols that are neither states, parameters nor inputs are known constants: a generic value
    params.update({ren[s].name: 0.5 + 0.137 * i for i, s in enumerate(extra)})
    system = System(states=[ren[s].name for s in xs], f=[sp.sympify(e).xreplace(ren) for e in f],
                    outputs=[f"y{i + 1}" for i in range(len(h))], h=[sp.sympify(e).xreplace(ren) for e in h],
                    inputs=[ren[s].name for s in (*us, *ws)], params=params, name=name)
    known = {str(s) for s in prev}
    unknown = [ren[s].name for s in ps if str(s) not in known]
    classes = {ren[s].name: (InputClass.generic() if d == math.inf else InputClass.polynomial(int(d)))
               for s, d in zip(us, nnzU or [math.inf] * len(us))}
    return system, dict(unknown_params=unknown, inputs=classes, unknown_inputs={ren[s].name: d for s, d in zip(ws, nnzW)}), \
        {ren[s].name: s.name for s in declared}


def nlobs_verdict(rep, back) -> dict[str, bool]:
    out = {back.get(s, s): s in rep.observable_states for s in rep.states}
    out.update({back.get(p, p): p in rep.identifiable_params for p in rep.unknown_params})
    for w in {c.rsplit("_", 1)[0] for c in rep.unknown_input_coefficients}:
        out[back.get(w, w)] = f"{w}_0" in rep.extra["observable_unknowns"]
    return out


class _Timeout(Exception):
    pass


def run_strikepy(name: str, timeout: float) -> tuple[float | None, dict[str, bool] | None, str]:
    from StrikePy.strike_goldd import strike_goldd

    nnzU, nnzW, prev, shipped = _options(name)
    mod = importlib.import_module(f"StrikePy.models.{name}")
    if not shipped:
        nnzU = [math.inf] * len(_flat(getattr(mod, "u", [])))
        nnzW = [1] * len(_flat(getattr(mod, "w", [])))
    opt = types.ModuleType(f"StrikePy.custom_options.options_bench_{name}")
    opt.modelname, opt.checkObser, opt.maxLietime = name, 1, math.inf
    opt.nnzDerU = nnzU
    opt.nnzDerW = [1 if w == math.inf else w for w in (nnzW or [])] or [1]
    opt.prev_ident_pars = prev
    sys.modules[opt.__name__] = opt

    def alarm(*_):
        raise _Timeout

    old = signal.signal(signal.SIGALRM, alarm)
    buf = io.StringIO()
    t0 = time.perf_counter()
    try:
        signal.setitimer(signal.ITIMER_REAL, timeout)
        with contextlib.redirect_stdout(buf):
            strike_goldd(f"options_bench_{name}")
        dt = time.perf_counter() - t0
    except _Timeout:
        return None, None, f"> {timeout:g} s"
    except Exception as e:  # noqa: BLE001 - report StrikePy's own failures in the table
        return None, None, f"error: {type(e).__name__}: {str(e)[:60]}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    return dt, parse_strikepy(buf.getvalue(), mod), ""


def parse_strikepy(text: str, mod) -> dict[str, bool]:
    """Per-variable verdicts from StrikePy's printed summary."""
    names = [str(s) for s in (*_flat(mod.x), *_flat(getattr(mod, "p", [])), *_flat(getattr(mod, "w", [])))]
    summary = text.split("RESULTS SUMMARY", 1)[-1]
    if "Fully Input-State-Parameter Observable" in summary:
        return {n: True for n in names}
    out: dict[str, bool] = {}

    def grab(header: str, value: bool) -> None:
        m = re.search(re.escape(header) + r":\s*\n\s*(.*)", summary)
        if m:
            for tok in re.findall(r"[A-Za-z_][A-Za-z0-9_]*", m.group(1)):
                out[tok] = value

    grab("These parameters are identifiable", True)
    grab("These parameters are unidentifiable", False)
    grab("These states are observable (and their initial conditions, if unknown, are identifiable)", True)
    grab("These states are unobservable (and their initial conditions, if unknown, are unidentifiable)", False)
    grab("These states are directly measured", True)
    grab("These unmeasured inputs are observable", True)
    grab("These unmeasured inputs are unobservable", False)
    if "All its parameters are structurally identifiable" in summary:
        out.update({str(s): True for s in _flat(getattr(mod, "p", []))})
    return {n: out[n] for n in names if n in out}


def chain(n: int) -> System:
    states = [f"x{i}" for i in range(1, n + 1)]
    f = [f"x{i + 1} - k{i}*x{i}**2" for i in range(1, n)] + [f"-x{n}*x1"]
    return System(states=states, f=f, outputs=["y"], h=["x1"], params={f"k{i}": 1 + i / 10 for i in range(1, n)}, name=f"chain{n}")


def timed(fn, repeat: int):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--timeout", type=float, default=60.0, help="StrikePy time limit per model, seconds")
    ap.add_argument("--models", default="", help="comma-separated subset of the 23 models")
    ap.add_argument("--no-strikepy", action="store_true", help="time nlobs only")
    ap.add_argument("--repeat", type=int, default=3, help="nlobs repeats (median)")
    args = ap.parse_args()
    try:
        import StrikePy  # noqa: F401
        have = not args.no_strikepy
        models = [m for m in MODELS if not args.models or m in args.models.split(",")]
    except ModuleNotFoundError:
        print("StrikePy is not importable (pip install strikepy==1.0 to compare); timing nlobs on the chain only.")
        have, models = False, []
    rows = []
    print(f"{'model':<34}{'unk':>4}{'rank':>6}{'nlobs s':>10}{'StrikePy s':>12}{'ratio':>9}  agree  nlobs: unobservable / unidentifiable")
    for name in models:
        system, opts, back = to_system(name)
        t_n, rep = timed(lambda: analyze(system, **opts), args.repeat)
        mine = nlobs_verdict(rep, back)
        bad = [k for k, v in mine.items() if not v]
        if have:
            t_s, theirs, note = run_strikepy(name, args.timeout)
        else:
            t_s, theirs, note = None, None, "not run"
        if theirs:
            common = [k for k in theirs if k in mine]
            agree = "yes" if all(theirs[k] == mine[k] for k in common) and common else "NO"
            if agree == "NO":
                note = "differs on " + ", ".join(k for k in common if theirs[k] != mine[k])
        else:
            agree = "-"
        ratio = f"{t_s / t_n:,.0f}x" if t_s else "-"
        ts = f"{t_s:.2f}" if t_s else note.split(":")[0]
        M = len(rep.unknowns)
        print(f"{name:<34}{M:>4}{rep.rank:>4}/{M:<2}{t_n:>9.4f}{ts:>12}{ratio:>9}  {agree:<5}  {', '.join(bad) or '-'}"
              + (f"   [{note}]" if note and theirs else ""))
        rows.append((name, t_n, t_s, agree))
    if rows:
        worst = max(rows, key=lambda r: r[1])
        done = [r for r in rows if r[2]]
        print(f"\nnlobs: slowest model {worst[0]} {worst[1]:.3f} s (target < 1 s: {'met' if worst[1] < 1 else 'MISSED'}); "
              f"StrikePy finished {len(done)}/{len(rows)} within {args.timeout:g} s; verdicts agree on "
              f"{sum(r[3] == 'yes' for r in done)}/{len(done)} of those")
        if done:
            print(f"speed-up on the models StrikePy finished: median {statistics.median(r[2] / r[1] for r in done):,.0f}x, "
                  f"min {min(r[2] / r[1] for r in done):,.0f}x")
    for n in (9, 25, 50):
        s = chain(n)
        t_c, rep = timed(lambda: analyze(s, unknown_params=["k1"]), args.repeat)
        print(f"chain n = {n:>2} (k1 unknown): rank {rep.rank}/{len(rep.unknowns)}, {t_c:.3f} s"
              + (f" (target < 2 s: {'met' if t_c < 2 else 'MISSED'})" if n == 50 else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
