"""Start-up (issue 38 §4): whole processes, wall time, as a user meets them.

S1  ``python -c "import nlobs"``. Target <= 0.5 s.
S2  ``nlobs --help``. Target <= 0.3 s.
S3  ``nlobs analyze goodwin.toml --params all --global``: Goodwin's oscillator (StructuralIdentifiability.jl's
    benchmark, the model of ``si_models.py``), the global check through the command line, start-up included.
    Target <= 2.4 s on this VM (SI.jl's published time for the check alone: 0.13 s).

Each command runs in a fresh process, interleaved, `--repeat` times (default 5); min and median reported. The
peer of each row is the issue's budget (ratio nlobs/budget).

Run:  .venv/bin/python benchmarks/bench_startup.py [--repeat N]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
import _common as cm  # noqa: E402
from si_models import MODELS  # noqa: E402

NLOBS = [sys.executable, "-m", "nlobs.cli"]


def goodwin_file(folder: Path) -> Path:
    m = MODELS["goodwin"]
    lines = ['name = "goodwin"', f"states = {list(m['states'])!r}".replace("'", '"'),
             f"outputs = {list(m['outputs'])!r}".replace("'", '"'), "[parameters]"]
    lines += [f"{p} = 1.0" for p in m["params"]]
    lines += ["[dynamics]"] + [f'{k} = "{v}"' for k, v in m["states"].items()]
    lines += ["[output]"] + [f'{k} = "{v}"' for k, v in m["outputs"].items()]
    path = folder / "goodwin.toml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def timed(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {out.stderr[-500:]}")
    return time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        model = goodwin_file(Path(tmp))
        cmds = {"S1": [sys.executable, "-c", "import nlobs"], "S2": [*NLOBS, "--help"],
                "S3": [*NLOBS, "analyze", str(model), "--params", "all", "--global"]}
        timed(cmds["S3"])   # a first run: Python's bytecode caches, msolve's binary in the page cache
        times: dict[str, list[float]] = {k: [] for k in cmds}
        for _ in range(args.repeat):
            for k, c in cmds.items():
                times[k].append(timed(c))
    spec = {"S1": ("import nlobs (whole process)", "python -c 'import nlobs'", 0.5, "<= 0.5 s"),
            "S2": ("nlobs --help (whole process)", "nlobs --help", 0.3, "<= 0.3 s"),
            "S3": ("nlobs analyze goodwin.toml --params all --global (whole process)", "nlobs analyze --global", 2.4,
                   "<= 2.4 s")}
    rows = []
    for k, (what, label, budget, target) in spec.items():
        t = (min(times[k]), statistics.median(times[k]))
        r = cm.row(k, what, nlobs=label, t_nlobs=t, err_nlobs=f"{args.repeat} runs", peer="issue 38 budget",
                   t_peer=(budget, budget), err_peer="target, whole process", kind="nlobs/peer", target=target,
                   threshold=1.0)
        rows.append(r)
        cm.print_row(r)
    print("wrote", cm.write("bench_startup", rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
