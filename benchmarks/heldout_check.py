"""Held-out check (not a test): ``nlobs design MODEL --run --json`` on models that no test names, against what
an expert expects of each (written down below before looking at nlobs's answer).

Usage::

    python benchmarks/heldout_check.py [--models a,b] [--json FILE]

Each model in ``benchmarks/heldout/`` is run as a new user would run it (a fresh process, the CLI). The
expectations are facts an expert states from the equations alone: observable or not (and which states),
blocked before estimation, which kinds must apply and which must not, whether the run is refused, and which
observer should do well on the run. Prints one line per expectation (ok / WRONG) and the ranking; the
discussion of each verdict is in ``benchmarks/results/heldout.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HELDOUT = ROOT / "benchmarks" / "heldout"

#: What an expert expects, per model (see heldout.md for the reasoning).
EXPECT: dict[str, dict] = {
    "cart_position_only": {"observable": True, "apply": ["ekf", "ukf"],
                           "not_apply": ["luenberger", "output_injection", "high_gain", "kalman_like"]},
    "glucose_minimal": {"observable": True, "apply": ["ekf", "kalman_like", "kalman_bucy", "high_gain"],
                        "not_apply": ["luenberger", "output_injection"],
                        "good": ["ekf", "ukf", "kalman_bucy", "kalman_like"]},
    "heater_saturated": {"observable": True, "apply": ["output_injection", "kkl", "pebo", "ekf", "kalman_bucy"],
                         "not_apply": ["luenberger"]},
    "idle_gain": {"observable": True, "identifiable": ["b"], "run_refused": True},
    "mass_spring_chain": {"observable": False, "blocked": True, "detectable": True, "unobservable": ["x1", "x3", "v1", "v3"]},
    "michaelis_menten": {"observable": True, "identifiable": ["Vmax"], "apply": ["ekf", "ukf", "kalman_like", "gpebo_2gd"],
                         "not_apply": ["luenberger", "output_injection"], "good": ["ekf", "ukf"],
                         "recovers": {"Vmax": (1.0, 0.05)}},
    "parallel_tanks": {"observable": False, "blocked": True, "detectable": True},
    "product_params": {"blocked": True, "not_identifiable": ["a", "b"]},
    "spring_unknown_k": {"observable": True, "identifiable": ["k"], "apply": ["ekf", "ukf", "kalman_like"],
                         "not_apply": ["luenberger", "high_gain"], "good": ["ekf", "ukf"],
                         "recovers": {"k": (4.0, 0.1)}},
    "squared_sensor": {"observable": True, "symmetry": True, "apply": ["ekf", "ukf"],
                       "not_apply": ["luenberger", "kalman_like", "high_gain", "lipschitz"]},
    "thermal_rc": {"observable": True, "apply": ["luenberger", "output_injection", "kalman_bucy", "ekf", "kkl"]},
    "unicycle_one_beacon": {"observable": False, "blocked": True, "detectable": False},
}


def run(name: str) -> tuple[dict, float]:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "nlobs.cli", "design", str(HELDOUT / f"{name}.toml"), "--run", "--json"],
                          env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"{name}: nlobs design failed: {proc.stderr.strip()[-500:]}")
    return json.loads(proc.stdout), time.perf_counter() - t0


def check(name: str, out: dict, exp: dict) -> list[tuple[bool, str]]:
    obs = out["observability"]
    cand = {c["kind"]: c for c in out["candidates"]}
    res: list[tuple[bool, str]] = []

    def say(ok: bool, what: str) -> None:
        res.append((bool(ok), what))

    if "observable" in exp:
        say(obs["observable"] == exp["observable"] or (exp["observable"] and not obs["blockers"] and
                                                      set(out["states"]) - set(out["estimated_params"]) <= set(obs["observable_states"])),
            f"observable = {exp['observable']}")
    if "unobservable" in exp:
        got = obs.get("detectability", {}).get("unobservable", [])
        say(sorted(got) == sorted(exp["unobservable"]), f"unobservable states {exp['unobservable']} (got {got})")
    if "blocked" in exp:
        say(bool(obs["blockers"]) == exp["blocked"], f"blocked before estimation = {exp['blocked']}")
        if exp["blocked"]:
            say(not any(c["applies"] for c in out["candidates"]) and not out.get("ranking"), "nothing applies, nothing ran")
    if "detectable" in exp:
        det = obs.get("detectability", {}).get("detectable", {})
        say(det.get("detectable") == exp["detectable"], f"detectable = {exp['detectable']} (got {det.get('detectable')})")
    for k in exp.get("identifiable", []):
        say(k in obs.get("identifiable_params", []), f"{k} identifiable")
    for k in exp.get("not_identifiable", []):
        say(k not in obs.get("identifiable_params", []) and any("not identifiable" in b for b in obs["blockers"]),
            f"{k} reported not identifiable before estimation")
    if "run_refused" in exp:
        say(bool(out.get("run_refused")) == exp["run_refused"] and not out.get("ranking"), "run refused before estimation")
    if exp.get("symmetry"):
        say(any("mirror image" in n or "invariant under" in n for n in out["notes"]), "local-only observability noted")
    for k in exp.get("apply", []):
        say(cand[k]["applies"], f"{k} applies" + ("" if cand[k]["applies"] else f" (got: {cand[k]['why'][:120]})"))
    for k in exp.get("not_apply", []):
        say(not cand[k]["applies"], f"{k} does not apply")
    ranking = out.get("ranking") or []
    if exp.get("good") and ranking:
        say(ranking[0] in exp["good"], f"best on the run among {exp['good']} (got {ranking[0]})")
    for k, (true, tol) in exp.get("recovers", {}).items():
        best = next((s for s in out.get("scores", []) if s["status"] == "ok"), None)
        est = best["parameters"][k]["estimate"] if best else None
        say(est is not None and abs(est - true) < tol, f"{k} recovered to ±{tol} by the best observer (got {est})")
    return res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default="")
    ap.add_argument("--json", default="", metavar="FILE")
    args = ap.parse_args()
    names = [m for m in args.models.split(",") if m] or sorted(EXPECT)
    table, wrong = [], 0
    for name in names:
        out, sec = run(name)
        res = check(name, out, EXPECT[name])
        wrong += sum(not ok for ok, _ in res)
        print(f"{name} ({sec:.1f} s): ranking {', '.join(out.get('ranking') or []) or '—'}"
              + (f"; run refused: {out['run_refused'][:90]}..." if out.get("run_refused") else ""))
        for ok, what in res:
            print(f"   {'ok   ' if ok else 'WRONG'} {what}")
        table.append({"model": name, "seconds": sec, "ranking": out.get("ranking"),
                      "checks": [{"ok": ok, "expectation": w} for ok, w in res],
                      "scores": out.get("scores"), "applies": [c["kind"] for c in out["candidates"] if c["applies"]]})
    print(f"\n{sum(len(t['checks']) for t in table) - wrong} of {sum(len(t['checks']) for t in table)} expectations met")
    if args.json:
        Path(args.json).write_text(json.dumps(table, indent=1))
    return 1 if wrong else 0


if __name__ == "__main__":
    raise SystemExit(main())
