"""Hostile and malformed inputs for nlobs (issue 10, "Done when"): model files, CSVs, CLI flags, API calls.

Every case must end in a **correct result** (``"ok"``, checked where a value is known) or a **clean
error**: for the API an nlobs error (or a ValueError/TypeError raised by nlobs itself) whose
message is at most ``MAX_MESSAGE`` characters; for the CLI a non-zero exit whose last stderr line
is ``nlobs: error: ...`` (or argparse's usage error) and no traceback. Anything else — another
exception type, a traceback, a longer message, a time or memory budget exceeded, a file created by
the input (code executed) — is ``"bad"``.

The cases run in a separate worker process (``python hostile_cases.py --worker``) with a memory cap
(RLIMIT_AS) and a per-case time budget (SIGALRM inside the worker, and a kill from the parent if
the worker stops answering); the parent restarts the worker after a kill. :func:`run_cases`
returns one record per case; ``python tests/properties/hostile_cases.py`` prints the counts.

Cases whose fix belongs to another engineer's branch are marked ``pending=OWNER``; the test
suite lists them (they may fail until that branch is merged).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

MAX_MESSAGE = 800            #: longest acceptable error message (characters)
MEMORY_CAP = 4 * 1024**3     #: address-space cap of the worker (bytes)
DEFAULT_BUDGET = 30.0        #: seconds per case

PENDULUM = """\
name = "pendulum"
states = ["x1", "x2"]
inputs = ["u"]
outputs = ["y"]
[parameters]
a1 = 9.81
a2 = 0.5
b = 1.0
[dynamics]
x1 = "x2"
x2 = "-a1*sin(x1) - a2*x2 + b*u"
[output]
y = "x1"
[simulation]
t_final = 1.0
dt = 1e-3
x0 = [1.0, 0.0]
inputs = { u = "sin(t)" }
[observers.ekf]
kind = "ekf"
Q = [[0.001, 0.0], [0.0, 0.01]]
R = [[0.0001]]
xhat0 = [0.0, 0.0]
[observers.injection]
kind = "output_injection"
poles = [-2.0, -3.0]
"""


def _model(*, name: str = '"m"', states: str = '["x1", "x2"]', dyn: str = 'x1 = "x2"\nx2 = "-x1"', out: str = 'y = "x1"',
           extra: str = "", params: str = "", inputs: str = "") -> str:
    return (f"name = {name}\nstates = {states}\n{inputs}outputs = [\"y\"]\n" + (f"[parameters]\n{params}\n" if params else "")
            + f"[dynamics]\n{dyn}\n[output]\n{out}\n{extra}")


def _csv(rows: int = 50, dt: float = 0.01, header: str = "t,u,y", f: Callable[[float], str] | None = None) -> str:
    import math

    lines = [header]
    for k in range(rows):
        t = k * dt
        lines.append(f(t) if f else f"{t!r},{math.sin(t)!r},{math.cos(t)!r}")
    return "\n".join(lines) + "\n"


@dataclass
class Case:
    """One hostile input: `kind` is toml | cli | api; `expect` is ok | error | either."""

    id: str
    kind: str
    payload: Any
    expect: str = "error"
    pending: str = ""          #: the engineer/branch whose fix the case waits for ("model", "data", "speed")
    budget: float = DEFAULT_BUDGET
    files: dict[str, Any] = field(default_factory=dict)   #: extra files (name -> str or bytes) in the case's folder
    note: str = ""
    slow: bool = False         #: run by benchmarks/hostile_slow.py, not by the test suite
    names: str = ""            #: an error message must contain this (e.g. the file it is about)
    env: dict[str, str] = field(default_factory=dict)  #: environment variables set for this case only


CASES: list[Case] = []
#: cases that take seconds (long runs, big inputs, time gaps): benchmarks/hostile_slow.py runs them
SLOW = {"csv-gap", "csv-gap-vm", "csv-gap-max-step", "toml-blowup-analyze", "toml-toml-big", "toml-many-states", "csv-long-line",
        "csv-many-columns", "cli-analyze-inputs-huge", "cli-sim-plot-bad-dir", "cli-sim-plot-bad-ext", "cli-sim-valid",
        "cli-sim-json", "cli-export-valid", "toml-name-long"}


def case(*args: Any, **kwargs: Any) -> None:
    c = Case(*args, **kwargs)
    c.slow = c.slow or c.id in SLOW
    if any(o.id == c.id for o in CASES):
        raise ValueError(f"duplicate hostile case id {c.id}")
    CASES.append(c)


# ---------------------------------------------------------------------------------------------
# A. model files: expressions that try to run code, or break the parser / SymPy
# ---------------------------------------------------------------------------------------------
_CODE = [
    "__import__('os').system('touch PWNED')", "open('PWNED', 'w')", "eval('1')", "exec('x = 1')", "compile('1', 'f', 'eval')",
    "x1.__class__", "().__class__.__bases__[0].__subclasses__()", "lambda: 1", "[x for x in ()]", "'text'", "b'bytes'",
    "x1 if x1 else x2", "x1 < x2", "x1 and x2", "not x1", "x1 @ x2", "x1 // x2", "x1 % x2", "~x1", "x1[0]", "f'{x1}'",
    "(y := 2)", "*x1", "{x1}", "{}", "[]", "()", "x1; x2", "import os", "x1 = 2", "sin", "sin()", "sin(x1, x2)", "atan2(x1)",
    "unknown(x1)", "zz + 1", "x1.real", "getattr(x1, 'x')", "globals()", "__builtins__", "x1(2)", "2(x1)", "sin(x=1)",
    "...", "None", "True", "1j", "x1 is x2", "x1 in x2", "await x1", "yield x1", "print(1)", "__debug__",
]
for k, expr in enumerate(_CODE):
    case(f"toml-code-{k:02d}", "toml", _model(dyn=f'x1 = "x2"\nx2 = {json.dumps(expr)}'), note=expr)

_NUMERIC = [  # (expression, expect, pending)
    ("1e400", "error", ""), ("9**9**9", "error", ""), ("x1**65", "error", ""), ("x1**(-65)", "error", ""),
    ("((x1**64)**64)**64", "error", ""), ("x1**(64**150)", "error", ""), ("2**100000", "error", ""),
    ("x1**0.5**0.5", "either", ""), ("1/0", "error", ""), ("0/0", "error", ""), ("x1/0", "error", ""),
    ("log(0)", "error", ""), ("sqrt(-1)", "error", ""), ("exp(exp(exp(1000)))", "error", ""), ("1e-400", "either", ""),
    ("0x10", "either", ""), ("1_000*x1", "either", ""), ("pi**64", "either", ""), ("sqrt(x1**2)", "ok", ""),
    ("x1**64", "ok", ""), ("-x1 + 1e-300", "ok", ""), ("sin(x1)**2 + cos(x1)**2 - 1 - x1", "ok", ""),
    ("(" * 300 + "x1" + ")" * 300, "error", ""), ("(" * 50 + "x1" + ")" * 50, "ok", ""), ("-" * 500 + "x1", "error", ""),
    ("+".join(["x1"] * 3000), "either", ""), ("+".join(["x1"] * 4000), "ok", ""), ("x1" + "*x1" * 63, "ok", ""), ("", "error", ""), ("   ", "error", ""),
    ("x1 +", "error", ""), ("x1 + ẋ", "error", ""), ("x1\u202e + x2", "error", ""), ("x1\n+ x2", "error", ""),
    ("x1 \\\n+ x2", "either", ""), ("x1\x00", "error", ""), ("x1 # comment", "either", ""),
]
for k, (expr, exp, pend) in enumerate(_NUMERIC):
    case(f"toml-num-{k:02d}", "toml", _model(dyn=f'x1 = "x2"\nx2 = {json.dumps(expr)}'), expect=exp, pending=pend, note=expr[:60])
case("toml-blowup-analyze", "toml", _model(dyn='x1 = "x2"\nx2 = "((x1 + x2 + 1)**64)**64"'), expect="either", budget=60,
     note="symbolic expansion budget (analyze)")

_STRUCTURE = [  # (id, text, expect, pending)
    ("no-states", 'name = "m"\noutputs = ["y"]\n[dynamics]\nx1 = "0"\n[output]\ny = "x1"\n', "error", ""),
    ("states-string", _model(states='"x1"'), "error", ""),
    ("states-int", _model(states="3"), "error", ""),
    ("states-dup", _model(states='["x1", "x1"]'), "error", ""),
    ("state-t", _model(states='["t", "x2"]', dyn='t = "x2"\nx2 = "0"', out='y = "x2"'), "error", ""),
    ("state-sin", _model(states='["sin", "x2"]', dyn='sin = "x2"\nx2 = "0"', out='y = "x2"'), "error", ""),
    ("state-dunder", _model(states='["__class__", "x2"]', dyn='__class__ = "x2"\nx2 = "0"', out='y = "x2"'), "error", ""),
    ("state-keyword", _model(states='["lambda", "x2"]', dyn='lambda = "x2"\nx2 = "0"', out='y = "x2"'), "error", ""),
    ("state-newline", _model(states='["x1\\n", "x2"]'), "error", ""),
    ("state-space", _model(states='["x 1", "x2"]'), "error", ""),
    ("state-unicode", _model(states='["ẋ", "x2"]', dyn='"ẋ" = "x2"\nx2 = "0"', out='y = "x2"'), "either", ""),
    ("state-long", _model(states=json.dumps(["x" * 5000, "x2"])), "error", ""),
    ("name-comment-injection", _model(name=json.dumps("m */ int main(void){return 1;} /*")), "either", ""),
    ("name-terminal-escape", _model(name=json.dumps("m\x1b[2J\x1b[31mred")), "either", ""),
    ("name-two-spaces", _model(name='"my  model"'), "either", ""),
    ("name-long", _model(name=json.dumps("n" * 100_000)), "either", ""),
    ("name-int", _model(name="5"), "either", ""),
    ("missing-dynamics", _model(dyn='x1 = "x2"'), "error", ""),
    ("extra-dynamics", _model(dyn='x1 = "x2"\nx2 = "0"\nx3 = "1"'), "error", ""),
    ("dynamics-number", _model(dyn='x1 = 1\nx2 = "0"'), "either", ""),
    ("dynamics-list", _model(dyn='x1 = ["x2"]\nx2 = "0"'), "error", ""),
    ("output-missing", _model(out=""), "error", ""),
    ("output-unknown-symbol", _model(out='y = "q"'), "error", ""),
    ("param-string", _model(params='k = "1"'), "error", ""),
    ("param-inf", _model(params="k = inf"), "error", ""),
    ("param-nan", _model(params="k = nan"), "error", ""),
    ("param-huge", _model(params="k = 1e308", dyn='x1 = "k*x2"\nx2 = "0"'), "either", ""),
    ("param-array", _model(params="k = [1, 2]"), "error", ""),
    ("param-bigint", _model(params="k = " + "9" * 5000), "error", ""),
    ("param-shadows-state", _model(params="x1 = 1.0"), "error", ""),
    ("observer-no-kind", _model(extra='[observers.o]\npoles = [-1, -2]\n'), "error", ""),
    ("simulation-x0-length", _model(extra="[simulation]\nx0 = [1.0]\n"), "error", ""),
    ("simulation-t-final-negative", _model(extra="[simulation]\nt_final = -1.0\n"), "error", ""),
    ("simulation-dt-zero", _model(extra="[simulation]\ndt = 0.0\n"), "error", ""),
    ("simulation-noise-negative", _model(extra="[simulation]\nnoise = { y = -1.0 }\n"), "error", ""),
    ("simulation-input-state", _model(inputs='inputs = ["u"]\n', extra='[simulation]\ninputs = { u = "x1" }\n'), "error", ""),
    ("toml-syntax", "name = \n", "error", ""),
    ("toml-deep-arrays", "name = " + "[" * 5000 + "]" * 5000 + "\n", "error", ""),
    ("toml-deep-tables", "x = " + "{a = " * 2000 + "1" + "}" * 2000 + "\n", "error", ""),
    ("toml-unknown-key", _model(extra="colour = 'blue'\n"), "either", ""),
    ("toml-big", _model(extra="# " + "x" * 2_000_000 + "\n"), "either", ""),
    ("many-states", _model(states=json.dumps([f"x{i}" for i in range(300)]),
                           dyn="\n".join(f'x{i} = "x{i + 1}"' for i in range(299)) + '\nx299 = "-x0"', out='y = "x0"'), "ok", ""),
]
for sid, text, exp, pend in _STRUCTURE:
    case(f"toml-{sid}", "toml", text, expect=exp, pending=pend)
case("toml-bom", "toml", "\ufeff" + PENDULUM, expect="ok", note="UTF-8 BOM")
case("toml-valid-pendulum", "toml", PENDULUM, expect="ok")

# ---------------------------------------------------------------------------------------------
# B. recorded data through `nlobs estimate` (CSV)
# ---------------------------------------------------------------------------------------------
_EST = ["estimate", "{dir}/model.toml", "{dir}/data.csv", "--observer", "ekf", "--engine", "vm"]
_CSVS: list[tuple[str, Any, str, str, list[str]]] = [  # (id, content, expect, pending, extra flags)
    ("valid", _csv(), "ok", "", []),
    ("crlf", _csv().replace("\n", "\r\n"), "ok", "", []),
    ("columns-permuted", _csv(header="y,u,t", f=lambda t: f"{__import__('math').cos(t)!r},0.0,{t!r}"), "ok", "", []),
    ("extra-column", _csv(header="t,u,y,junk", f=lambda t: f"{t!r},0,1,5"), "ok", "", []),
    ("header-only", "t,u,y\n", "error", "", []),
    ("empty", "", "error", "", []),
    ("one-row", _csv(rows=1), "either", "", []),
    ("missing-y", _csv(header="t,u", f=lambda t: f"{t!r},0"), "error", "", []),
    ("missing-u", _csv(header="t,y", f=lambda t: f"{t!r},0"), "error", "", []),
    ("missing-t", _csv(header="u,y", f=lambda t: "0,1"), "error", "", []),
    ("duplicate-y", _csv(header="t,u,y,y", f=lambda t: f"{t!r},0,1,2"), "error", "", []),
    ("bom", "\ufeff" + _csv(), "ok", "", []),
    ("latin1", _csv(header="t,u,y,caf\xe9", f=lambda t: f"{t!r},0,1,2").encode("latin-1"), "either", "", []),
    ("nan-y", _csv(f=lambda t: f"{t!r},0,{'nan' if t > 0.2 else '1'}"), "error", "", []),
    ("nan-y-skip", _csv(f=lambda t: f"{t!r},0,{'nan' if 0.2 < t < 0.3 else '1'}"), "ok", "", ["--skip-missing"]),
    ("empty-y-skip", _csv(f=lambda t: f"{t!r},0,{'' if 0.2 < t < 0.3 else '1'}"), "ok", "", ["--skip-missing"]),
    ("inf-y", _csv(f=lambda t: f"{t!r},0,{'inf' if t > 0.2 else '1'}"), "error", "", []),
    ("huge-y", _csv(f=lambda t: f"{t!r},0,{'1e308' if 0.2 < t < 0.22 else '1'}"), "error", "", []),
    ("nan-u", _csv(f=lambda t: f"{t!r},{'nan' if t > 0.2 else '0'},1"), "error", "", []),
    ("nan-t", _csv(f=lambda t: f"{'nan' if 0.2 < t < 0.22 else repr(t)},0,1"), "error", "", []),
    ("t-decreasing", _csv(f=lambda t: f"{-t!r},0,1"), "error", "", []),
    ("t-duplicate", _csv(f=lambda t: f"{round(t, 1)!r},0,1"), "error", "", []),
    ("t0-huge-negative", _csv(f=lambda t: f"{(-1e300 if t == 0 else t)!r},0,1"), "error", "", []),
    # a 10⁶ s gap: about 7e6 RK4 sub-steps of the EKF (its covariance's rate is about 7 per second), a legitimate
    # result. With the default engine they are compiled (about 4 s in all); on the virtual machine the user forced,
    # 7e6 sub-steps of 284 instructions at CasADi's ~6 ns per instruction cost at least 12 s: a budget of 30 s there
    ("gap", _csv(f=lambda t: f"{(t if t < 0.25 else t + 1e6)!r},0,1"), "either", "", ["--engine", "default"]),
    ("gap-vm", _csv(f=lambda t: f"{(t if t < 0.25 else t + 1e6)!r},0,1"), "either", "", []),
    ("gap-max-step", _csv(f=lambda t: f"{(t if t < 0.25 else t + 1e6)!r},0,1"), "either", "", ["--max-step", "1", "--engine", "default"]),
    ("text-cell", _csv(f=lambda t: f"{t!r},0,{'abc' if 0.2 < t < 0.22 else '1'}"), "error", "", []),
    ("quoted", _csv(f=lambda t: f'"{t!r}","0","1"'), "either", "", []),
    ("semicolons", _csv(header="t;u;y", f=lambda t: f"{t!r};0;1"), "error", "", []),
    ("trailing-comma", _csv(f=lambda t: f"{t!r},0,1,"), "either", "", []),
    ("ragged", _csv(f=lambda t: f"{t!r},0" if 0.2 < t < 0.22 else f"{t!r},0,1"), "error", "", []),
    ("spaces-header", _csv(header=" t , u , y ", f=lambda t: f"{t!r},0,1"), "either", "", []),
    ("denormal", _csv(f=lambda t: f"{t!r},5e-324,1"), "ok", "", []),
    ("binary", bytes(range(256)) * 4, "error", "", []),
    ("nul-bytes", "t,u,y\n0,0,1\x00\n0.1,0,1\n", "error", "", []),
    ("long-line", "t,u,y\n0," + "1" * 200_000 + ",1\n0.1,0,1\n", "either", "", []),
    ("many-columns", "t,u,y," + ",".join(f"c{i}" for i in range(5000)) + "\n" + "0,0,1," + ",".join("0" * 5000) + "\n",
     "either", "", []),
]
for cid, content, exp, pend, flags in _CSVS:
    default = flags[-2:] == ["--engine", "default"]  # the engine a user gets without --engine (not the suite's vm)
    case(f"csv-{cid}", "cli", (_EST[:-2] + flags[:-2]) if default else _EST + flags, expect=exp, pending=pend,
         files={"model.toml": PENDULUM, "data.csv": content}, names="data.csv" if exp != "ok" else "",
         budget=30.0 if cid == "gap-vm" else 10.0 if "gap" in cid else DEFAULT_BUDGET,
         env={"NLOBS_ENGINE": "auto"} if default else {})

# ---------------------------------------------------------------------------------------------
# C. command-line flags
# ---------------------------------------------------------------------------------------------
_SIM = ["simulate", "{dir}/model.toml", "--engine", "vm", "--observer", "injection"]
_FLAGS: list[tuple[str, list[str], str, str]] = [
    ("sim-valid", _SIM + ["--t-final", "0.5"], "ok", ""),
    ("sim-json", _SIM + ["--t-final", "0.5", "--json"], "ok", ""),
    ("sim-t-final-zero", _SIM + ["--t-final", "0"], "error", ""),
    ("sim-t-final-negative", _SIM + ["--t-final", "-1"], "error", ""),
    ("sim-t-final-nan", _SIM + ["--t-final", "nan"], "error", ""),
    ("sim-t-final-inf", _SIM + ["--t-final", "inf"], "error", ""),
    ("sim-t-final-huge", _SIM + ["--t-final", "1e12"], "error", ""),
    ("sim-t-final-text", _SIM + ["--t-final", "ten"], "error", ""),
    ("sim-dt-zero", _SIM + ["--dt", "0"], "error", ""),
    ("sim-dt-negative", _SIM + ["--dt", "-0.001"], "error", ""),
    ("sim-dt-nan", _SIM + ["--dt", "nan"], "error", ""),
    ("sim-dt-tiny", _SIM + ["--dt", "1e-12"], "error", ""),
    ("sim-dt-larger-than-horizon", _SIM + ["--dt", "5", "--t-final", "1"], "error", ""),
    ("sim-tol-negative", _SIM + ["--tol", "-1"], "error", ""),
    ("sim-tol-nan", _SIM + ["--tol", "nan"], "error", ""),
    ("sim-seed-negative", _SIM + ["--seed", "-1"], "either", ""),
    ("sim-seed-float", _SIM + ["--seed", "1.5"], "error", ""),
    ("sim-observer-unknown", ["simulate", "{dir}/model.toml", "--observer", "nope"], "error", ""),
    ("sim-observer-twice", _SIM + ["--observer", "injection", "--t-final", "0.5"], "either", ""),
    ("sim-engine-unknown", ["simulate", "{dir}/model.toml", "--engine", "gpu"], "error", ""),
    ("sim-plot-bad-dir", _SIM + ["--t-final", "0.5", "--plot", "/nonexistent/dir/x.png"], "error", ""),
    ("sim-plot-bad-ext", _SIM + ["--t-final", "0.5", "--plot", "{dir}/x.docx"], "error", ""),
    ("sim-model-missing", ["simulate", "{dir}/nope.toml"], "error", ""),
    ("sim-model-directory", ["simulate", "{dir}"], "error", ""),
    ("sim-model-binary", ["simulate", "{dir}/binary.toml"], "error", ""),
    ("analyze-valid", ["analyze", "{dir}/model.toml"], "ok", ""),
    ("analyze-json", ["analyze", "{dir}/model.toml", "--json"], "ok", ""),
    ("analyze-inputs-bad", ["analyze", "{dir}/model.toml", "--inputs", "foo"], "error", ""),
    ("analyze-inputs-zero", ["analyze", "{dir}/model.toml", "--inputs", "0"], "either", ""),
    ("analyze-inputs-negative", ["analyze", "{dir}/model.toml", "--inputs", "-3"], "error", ""),
    ("analyze-inputs-huge", ["analyze", "{dir}/model.toml", "--inputs", "100000"], "either", ""),
    ("analyze-params-all", ["analyze", "{dir}/model.toml", "--params", "all"], "ok", ""),
    ("analyze-params-unknown", ["analyze", "{dir}/model.toml", "--params", "zz"], "error", ""),
    ("analyze-function-ok", ["analyze", "{dir}/model.toml", "--function", "x1**2 + x2"], "ok", ""),
    ("analyze-function-code", ["analyze", "{dir}/model.toml", "--function", "__import__('os').system('touch PWNED')"],
     "error", ""),
    ("analyze-function-syntax", ["analyze", "{dir}/model.toml", "--function", "x1 +"], "error", ""),
    ("analyze-function-unknown", ["analyze", "{dir}/model.toml", "--function", "x9"], "error", ""),
    ("estimate-hold-bad", _EST + ["--hold", "cubic"], "error", ""),
    ("estimate-max-step-zero", _EST + ["--max-step", "0"], "error", ""),
    ("estimate-max-step-negative", _EST + ["--max-step", "-1"], "error", ""),
    ("estimate-max-step-nan", _EST + ["--max-step", "nan"], "error", ""),
    ("estimate-no-observer", ["estimate", "{dir}/model.toml", "{dir}/data.csv"], "error", ""),
    ("estimate-output-bad-dir", _EST + ["--output", "/nonexistent/dir/out.csv"], "error", ""),
    ("estimate-data-missing", ["estimate", "{dir}/model.toml", "{dir}/nope.csv", "--observer", "ekf"], "error", ""),
    ("export-valid", ["export", "{dir}/model.toml", "--observer", "ekf", "--c", "{dir}/c"], "ok", ""),
    ("export-name-space", ["export", "{dir}/model.toml", "--observer", "ekf", "--c", "{dir}/c", "--name", "a b"], "error", ""),
    ("export-name-comment", ["export", "{dir}/model.toml", "--observer", "ekf", "--c", "{dir}/c", "--name", "*/x"], "error", ""),
    ("export-name-keyword", ["export", "{dir}/model.toml", "--observer", "ekf", "--c", "{dir}/c", "--name", "int"], "error", ""),
    ("export-name-long", ["export", "{dir}/model.toml", "--observer", "ekf", "--c", "{dir}/c", "--name", "a" * 500], "error", ""),
    ("export-dir-is-file", ["export", "{dir}/model.toml", "--observer", "ekf", "--c", "{dir}/model.toml"], "error", ""),
    ("export-max-step-zero", ["export", "{dir}/model.toml", "--observer", "ekf", "--c", "{dir}/c", "--max-step", "0"], "error", ""),
    ("export-observer-unknown", ["export", "{dir}/model.toml", "--observer", "nope", "--c", "{dir}/c"], "error", ""),
    ("demo-only-unknown", ["demo", "--only", "nope", "--out", "{dir}/r"], "error", ""),
    ("demo-list", ["demo", "--list"], "ok", ""),
    ("no-command", [], "error", ""),
    ("unknown-command", ["fly"], "error", ""),
    ("unknown-flag", ["analyze", "{dir}/model.toml", "--frobnicate"], "error", ""),
]
for fid, argv, exp, pend in _FLAGS:
    case(f"cli-{fid}", "cli", argv, expect=exp, pending=pend,
         files={"model.toml": PENDULUM, "data.csv": _csv(), "binary.toml": bytes(range(256))})
for oid, table, pend in (("unknown-kind", 'kind = "magic"', ""), ("bad-option", 'kind = "ekf"\nQ = "big"\nR = [[1.0]]', ""),
                         ("no-kind", "poles = [-1.0, -2.0]", ""),
                         ("perturbation-string", 'kind = "banks"\nP = [[-2.0], [1.0]]\nperturbation = "x2"', "")):
    case(f"cli-observer-{oid}", "cli", ["simulate", "{dir}/model.toml", "--engine", "vm", "--observer", "o", "--t-final", "0.1"],
         pending=pend, files={"model.toml": _model(extra=f"[simulation]\nx0 = [1.0, 0.0]\n[observers.o]\n{table}\n")})
for nid, name in (("two-spaces", "my  model"), ("terminal-escape", "m\x1b[2J\x1b[31mred"), ("comment", "m */ x /*"),
                  ("newline", "m\nnlobs: error: fake")):
    case(f"cli-name-{nid}-simulate", "cli", ["simulate", "{dir}/model.toml", "--engine", "vm", "--observer", "injection", "--t-final",
                                             "0.1"], expect="ok" if nid == "two-spaces" else "either",
         files={"model.toml": PENDULUM.replace('name = "pendulum"', f"name = {json.dumps(name)}")})
case("cli-export-hostile-name-model", "cli", ["export", "{dir}/model.toml", "--observer", "injection", "--c", "{dir}/c"],
     expect="either", files={"model.toml": PENDULUM.replace('name = "pendulum"',
                                                            'name = "p */ static int pwn = 1; /* ??/"')})

# ---------------------------------------------------------------------------------------------
# D. API calls
# ---------------------------------------------------------------------------------------------
API: dict[str, Callable[[Path], Any]] = {}


def api(expect: str = "error", pending: str = "", budget: float = DEFAULT_BUDGET) -> Callable[[Callable[[Path], Any]], Callable]:
    def deco(fn: Callable[[Path], Any]) -> Callable[[Path], Any]:
        API[fn.__name__] = fn
        case(f"api-{fn.__name__}", "api", fn.__name__, expect=expect, pending=pending, budget=budget)
        return fn
    return deco


def _pend():
    import nlobs

    return nlobs.System(states=["x1", "x2"], f=["x2", "-9.81*sin(x1) - 0.5*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"])


@api()
def design_ekf_string(d):
    import nlobs
    return nlobs.design_ekf("pend", Q=[[1, 0], [0, 1]], R=[[1]])


@api()
def design_ekf_nan_q(d):
    import nlobs
    return nlobs.design_ekf(_pend(), Q=[[float("nan"), 0], [0, 1]], R=[[1]])


@api()
def design_ekf_q_shape(d):
    import nlobs
    return nlobs.design_ekf(_pend(), Q=[[1, 0, 0]], R=[[1]])


@api()
def design_ekf_q_asymmetric(d):
    import nlobs
    return nlobs.design_ekf(_pend(), Q=[[1, 2], [0, 1]], R=[[1]])


@api()
def design_ekf_r_negative(d):
    import nlobs
    return nlobs.design_ekf(_pend(), Q=[[1, 0], [0, 1]], R=[[-1]])


@api()
def design_ekf_q_strings(d):
    import nlobs
    return nlobs.design_ekf(_pend(), Q="big", R=[[1]])


@api()
def design_luenberger_nonlinear(d):
    import nlobs
    return nlobs.design_luenberger(_pend(), poles=[-1, -2])


@api()
def design_injection_unstable_poles(d):
    import nlobs
    return nlobs.design_output_injection(_pend(), poles=[1, -2])


@api()
def design_injection_wrong_pole_count(d):
    import nlobs
    return nlobs.design_output_injection(_pend(), poles=[-1])


@api()
def design_injection_nan_pole(d):
    import nlobs
    return nlobs.design_output_injection(_pend(), poles=[float("nan"), -2])


@api()
def design_high_gain_negative_theta(d):
    import nlobs
    return nlobs.design_high_gain(_pend(), theta=-1.0)


@api()
def design_from_config_unknown(d):
    from nlobs.design import design_from_config
    return design_from_config(_pend(), "magic", {})


@api()
def design_from_config_bad_option(d):
    from nlobs.design import design_from_config
    return design_from_config(_pend(), "ekf", {"Q": [[1, 0], [0, 1]], "R": [[1]], "colour": "blue"})


@api()
def design_pebo_tiny_residual(d):
    import nlobs
    s = nlobs.System(states=["x1", "x2"], f=["x2", "-x1 + u - 1e-10*x2"], outputs=["y"], h=["x1"], inputs=["u"])
    return nlobs.design_pebo(s, phi=["x2"], left_inverse=["y", "xi1"], B=["-y + u"])


@api()
def design_kkl_code_in_phi(d):
    import nlobs
    s = nlobs.System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1"])
    return nlobs.design_kkl(s, phi=["__import__('os').system('touch PWNED')", "x2"], left_inverse=["y", "xi2"], B=["y", "y"],
                            Lambda=[-1, -2])


@api()
def system_states_string(d):
    import nlobs
    return nlobs.System(states="x1", f=["0"], outputs=["y"], h=["x1"])


@api()
def system_f_length(d):
    import nlobs
    return nlobs.System(states=["x1", "x2"], f=["0"], outputs=["y"], h=["x1"])


@api()
def system_unknown_symbol(d):
    import nlobs
    return nlobs.System(states=["x1"], f=["q"], outputs=["y"], h=["x1"])


@api()
def system_code_expression(d):
    import nlobs
    return nlobs.System(states=["x1"], f=["__import__('os').system('touch PWNED')"], outputs=["y"], h=["x1"])


@api()
def system_name_newline(d):
    import nlobs
    return nlobs.System(states=["x1\n"], f=["0"], outputs=["y"], h=["1"])


@api()
def system_param_nan(d):
    import nlobs
    return nlobs.System(states=["x1"], f=["k*x1"], outputs=["y"], h=["x1"], params={"k": float("nan")})


@api()
def system_param_string(d):
    import nlobs
    return nlobs.System(states=["x1"], f=["k*x1"], outputs=["y"], h=["x1"], params={"k": "1; rm -rf /"})


@api(expect="ok")
def system_numpy_param(d):
    import numpy as np
    import nlobs
    return nlobs.System(states=["x1"], f=["k*x1"], outputs=["y"], h=["x1"], params={"k": np.float32(2.0)}).params["k"] == 2.0


def _sim(**kw):
    import nlobs
    s = _pend()
    obs = {"inj": nlobs.design_output_injection(s, poles=[-2, -3])}
    args = dict(t_final=0.5, dt=1e-3, x0=[1, 0], inputs={"u": "sin(t)"}, engine="vm")
    args.update(kw)
    return nlobs.simulate(s, obs, **args)


_SIM_ERRORS = {  # simulate(...) with one bad argument: each must be refused with a clean error
    "simulate_t_final_negative": lambda: dict(t_final=-1),
    "simulate_t_final_nan": lambda: dict(t_final=float("nan")),
    "simulate_dt_zero": lambda: dict(dt=0),
    "simulate_dt_negative": lambda: dict(dt=-1e-3),
    "simulate_dt_huge_steps": lambda: dict(t_final=1e9, dt=1e-3),
    "simulate_x0_length": lambda: dict(x0=[1]),
    "simulate_x0_nan": lambda: dict(x0=[float("nan"), 0]),
    "simulate_x0_string": lambda: dict(x0="one"),
    "simulate_input_unknown": lambda: dict(inputs={"zz": 1}),
    "simulate_input_code": lambda: dict(inputs={"u": "__import__('os').system('touch PWNED')"}),
    "simulate_input_state": lambda: dict(inputs={"u": "x1"}),
    "simulate_input_array_length": lambda: dict(inputs={"u": [1.0, 2.0, 3.0]}),
    "simulate_noise_negative": lambda: dict(noise=__import__("nlobs").Noise.gaussian(-1.0)),
    "simulate_sampling_zero": lambda: dict(sampling=__import__("nlobs").Sampling(0.0)),
    "simulate_sampling_nan": lambda: dict(sampling=__import__("nlobs").Sampling(float("nan"))),
    "simulate_xhat0_nan": lambda: dict(xhat0=[float("nan"), 0]),
    "simulate_unknown_engine": lambda: dict(engine="gpu"),
}


def _sim_case(kwargs_of: Callable[[], dict]) -> Callable[[Path], Any]:
    return lambda d: _sim(**kwargs_of())


for _name, _kw in _SIM_ERRORS.items():
    API[_name] = _sim_case(_kw)
    case(f"api-{_name}", "api", _name)


@api()
def simulate_blowup(d):
    import nlobs
    s = nlobs.System(states=["x1"], f=["x1**2"], outputs=["y"], h=["x1"])
    return nlobs.simulate(s, {}, t_final=2.0, dt=1e-3, x0=[2.0], engine="vm")


@api(expect="ok")
def simulate_float32_dt(d):
    import numpy as np
    run = _sim(dt=np.float32(1e-3))
    return bool(np.all(np.isfinite(run.x)))


@api(expect="ok")
def simulate_valid(d):
    import numpy as np
    run = _sim()
    return bool(np.all(np.isfinite(run.observers["inj"].xhat)))


def _online():
    import nlobs
    s = _pend()
    ekf = nlobs.design_ekf(s, Q=[[1e-3, 0], [0, 1e-2]], R=[[1e-4]])
    return nlobs.Observer(ekf).start(xhat0=[0, 0])


@api()
def online_time_backwards(d):
    o = _online()
    o.update(t=0.1, y=[1.0], u=[0.0])
    return o.update(t=0.05, y=[1.0], u=[0.0])


@api()
def online_same_time_twice(d):
    o = _online()
    o.update(t=0.1, y=[1.0], u=[0.0])
    return o.update(t=0.1, y=[1.0], u=[0.0])


@api()
def online_y_length(d):
    return _online().update(t=0.1, y=[1.0, 2.0], u=[0.0])


@api()
def online_y_inf(d):
    return _online().update(t=0.1, y=[float("inf")], u=[0.0])


@api()
def online_t_nan(d):
    return _online().update(t=float("nan"), y=[1.0], u=[0.0])


@api()
def online_u_string(d):
    return _online().update(t=0.1, y=[1.0], u=["zero"])


@api()
def online_xhat0_length(d):
    import nlobs
    ekf = nlobs.design_ekf(_pend(), Q=[[1e-3, 0], [0, 1e-2]], R=[[1e-4]])
    return nlobs.Observer(ekf).start(xhat0=[0, 0, 0])


@api()
def recording_lengths(d):
    import nlobs
    return nlobs.Recording.from_arrays(_pend(), t=[0, 0.1, 0.2], u=[[0], [0]], y=[[1], [1], [1]])


@api()
def recording_from_missing_csv(d):
    import nlobs
    return nlobs.Recording.from_csv(str(d / "nope.csv"), _pend())


@api()
def estimate_bad_on_missing(d):
    import nlobs
    s = _pend()
    (d / "data.csv").write_text(_csv())
    rec = nlobs.Recording.from_csv(str(d / "data.csv"), s)
    return nlobs.estimate({"ekf": nlobs.design_ekf(s, Q=[[1e-3, 0], [0, 1e-2]], R=[[1e-4]])}, rec, on_missing="bogus")


@api()
def estimate_observer_not_design(d):
    import nlobs
    s = _pend()
    (d / "data.csv").write_text(_csv())
    rec = nlobs.Recording.from_csv(str(d / "data.csv"), s)
    return nlobs.estimate({"ekf": "ekf"}, rec)


@api()
def montecarlo_x0_shape(d):
    import numpy as np
    import nlobs
    s = _pend()
    return nlobs.montecarlo(s, {"inj": nlobs.design_output_injection(s, poles=[-2, -3])}, t_final=0.1, dt=1e-3,
                            x0=np.zeros((3, 5)), inputs={"u": "0"}, engine="vm")


@api()
def analyze_not_a_system(d):
    import nlobs
    return nlobs.analyze("pendulum")


@api()
def analyze_function_code(d):
    from nlobs.analysis import observable_function
    return observable_function(_pend(), "__import__('os').system('touch PWNED')")


@api(expect="ok")
def analyze_valid(d):
    import nlobs
    return nlobs.analyze(_pend()).observable


@api()
def export_name_injection(d):
    import nlobs
    ekf = nlobs.design_ekf(_pend(), Q=[[1e-3, 0], [0, 1e-2]], R=[[1e-4]])
    return nlobs.export_c(ekf, d / "c", name="x */ int y; /*")


@api()
def export_max_step_nan(d):
    import nlobs
    ekf = nlobs.design_ekf(_pend(), Q=[[1e-3, 0], [0, 1e-2]], R=[[1e-4]])
    return nlobs.export_c(ekf, d / "c", max_step=float("nan"))


@api()
def decide_identity_text(d):
    from nlobs.analysis import decide_identity
    return decide_identity("__import__('os')", 0)


@api(expect="ok")
def decide_identity_huge_degree(d):
    import sympy as sp
    from nlobs.analysis import decide_identity
    x = sp.Symbol("x", real=True)
    return decide_identity(x ** (10**9), x ** (10**9) + 1).status in ("fails", "undecided")


@api()
def banks_region_nan(d):
    from nlobs.analysis import banks_condition
    return banks_condition(["-x1"], ["x1"], [[-1.0]], ["x1"], [[float("nan"), 1.0]])


@api()
def lipschitz_box_inverted(d):
    from nlobs.analysis import lipschitz_bound
    return lipschitz_bound(["sin(x1)"], ["x1"], [[1.0, -1.0]])


@api()
def load_model_missing(d):
    import nlobs
    return nlobs.load_model(str(d / "nope.toml"))


@api()
def loads_model_not_text(d):
    import nlobs
    return nlobs.loads_model(b"name = 1")


@api()
def loads_model_none(d):
    import nlobs
    return nlobs.loads_model(None)


# -- issue 20's audit: one case per item ----------------------------------------------------------
@api(expect="ok")
def online_gap_100s(d):
    """An online update after a 100 s gap: integrated (was |x̂| = 9e5 from one RK4 step over the gap)."""
    import numpy as np

    import nlobs
    o = nlobs.Observer(nlobs.design_ekf(_pend(), Q=[[1e-4, 0], [0, 1e-2]], R=[[1e-4]], xhat0=[0.5, 0.0])).start()
    o.update(0.0, u=[0.0], y=[1.0])
    x = o.update(100.0, u=[0.0], y=[1.0])
    assert np.all(np.abs(x) < 2), x
    return x



@api()
def online_gap_1e6s(d):
    """After a 10⁶ s gap: a DataError that says to restart (was 4.3e22, no error)."""
    import nlobs
    o = nlobs.Observer(nlobs.design_ekf(_pend(), Q=[[1e-4, 0], [0, 1e-2]], R=[[1e-4]], xhat0=[0.5, 0.0])).start()
    o.update(0.0, u=[0.0], y=[1.0])
    return o.update(1e6, u=[0.0], y=[1.0])


@api(expect="ok")
def input_as_array_on_the_grid(d):
    import numpy as np

    import nlobs
    t = np.arange(1001) * 1e-3
    return nlobs.simulate(_pend(), None, t_final=1.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": np.sin(t)})


@api()
def input_array_wrong_length(d):
    import numpy as np

    import nlobs
    return nlobs.simulate(_pend(), None, t_final=1.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": np.zeros(10)})


@api(expect="ok")
def online_covariance_and_predict(d):
    import nlobs
    o = nlobs.Observer(nlobs.design_ekf(_pend(), Q=[[1e-4, 0], [0, 1e-2]], R=[[1e-4]], xhat0=[0.5, 0.0])).start()
    o.update(0.0, u=[0.0], y=[1.0])
    o.predict(0.01)
    assert o.P.shape == (2, 2)
    return o.update(0.01, u=[0.0], y=[1.0])


@api()
def poles_malformed_strings(d):
    import nlobs
    lin = nlobs.System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1"])
    return nlobs.design_luenberger(lin, poles=["a", "b"])


case("toml-integer-4301-digits", "toml", _model(dyn='x1 = "x2"\nx2 = "' + "9" * 4301 + '*x1"'))
case("toml-unary-chain-100k", "toml", _model(dyn='x1 = "x2"\nx2 = "' + "-(" * 50_000 + "x1" + ")" * 50_000 + '"'))
case("toml-expression-100k-ok", "toml", _model(dyn='x1 = "x2"\nx2 = "' + " + ".join(["0.0001*x1"] * 8000) + '"'),
     expect="ok")
for fid, argv, exp in (("sim-no-observers", ["simulate", "{dir}/plain.toml", "--engine", "vm", "--t-final", "0.5"], "ok"),
                       ("sim-observer-kind", ["simulate", "{dir}/plain.toml", "--engine", "vm", "--t-final", "0.5",
                                              "--observer", "ekf"], "ok"),
                       ("max-expression-zero", ["--max-expression", "0", "analyze", "{dir}/plain.toml"], "error")):
    case(f"cli-{fid}", "cli", argv, expect=exp,
         files={"plain.toml": _model(extra="[simulation]\nx0 = [1.0, 0.0]\nt_final = 1.0\n")})


# ---------------------------------------------------------------------------------------------
# The worker and the runner
# ---------------------------------------------------------------------------------------------
_ACTIONABLE = ("required", "`", "--", ".toml", ".csv", "'", '"', "usage", "must", "expected", "give ", "choose", "use ", "not ")


def actionable(message: str) -> bool:
    """A crude test that an error names what to change: a name in quotes or backticks, a flag, a file, a
    location prefix (``simulate: ...``) or a word such as "must"/"expected"; bare Python texts such as
    "cannot convert float infinity to integer" fail it."""
    m = message.removeprefix("nlobs: error: ").strip()
    head = m.split(" ", 1)[0]
    return head.endswith(":") or any(k in m for k in _ACTIONABLE)


def _first_line(text: str) -> str:
    return (text.strip().splitlines() or [""])[-1]


def _run_one(c: Case, folder: Path) -> dict[str, Any]:
    for name, content in c.files.items():
        p = folder / name
        (p.write_bytes if isinstance(content, bytes) else p.write_text)(content)
    t0 = time.perf_counter()
    rec: dict[str, Any] = {"id": c.id}
    try:
        if c.kind == "toml":
            import nlobs
            mf = nlobs.loads_model(c.payload)
            if c.id == "toml-blowup-analyze":
                nlobs.analyze(mf.system)
            rec.update(outcome="ok", message="")
        elif c.kind == "api":
            value = API[c.payload](folder)
            ok = value is not False
            rec.update(outcome="ok" if ok else "bad", message="" if ok else "returned a wrong result")
        else:
            from nlobs.cli import main
            argv = [a.replace("{dir}", str(folder)) for a in c.payload]
            out, err = io.StringIO(), io.StringIO()
            saved = {k: os.environ.get(k) for k in c.env}
            os.environ.update(c.env)
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                try:
                    code = main(argv)
                except SystemExit as e:
                    code = e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
                finally:
                    for k, v in saved.items():
                        if v is None:
                            os.environ.pop(k, None)
                        else:
                            os.environ[k] = v
            text = err.getvalue()
            line = _first_line(text)
            if "\x1b" in text or "\x1b" in out.getvalue():
                rec.update(outcome="bad", message="a terminal control sequence (ESC) was printed")
            elif code == 0:
                rec.update(outcome="ok", message="")
            elif "Traceback" in text:
                rec.update(outcome="bad", message="traceback: " + line[:MAX_MESSAGE])
            elif (line.startswith("nlobs: error:") or "error:" in line or line.startswith('{"error"')) and len(line) <= MAX_MESSAGE + 20:
                rec.update(outcome="error", message=line)
            else:
                rec.update(outcome="bad", message=f"exit {code}, stderr: {line[:MAX_MESSAGE]} ({len(line)} chars)")
    except BaseException as e:  # noqa: BLE001 - classifying every way a case can end is the point
        if isinstance(e, (KeyboardInterrupt, _Timeout)):
            raise
        msg = str(e)
        tb = traceback.extract_tb(e.__traceback__)
        from_nlobs = bool(tb) and "/nlobs/" in tb[-1].filename.replace("\\", "/")
        try:
            from nlobs.errors import NlobsError
        except ImportError:  # pragma: no cover
            NlobsError = ()  # type: ignore[assignment]
        clean = (isinstance(e, NlobsError) or (isinstance(e, (ValueError, TypeError)) and from_nlobs)) and 0 < len(msg) <= MAX_MESSAGE
        rec.update(outcome="error" if clean else "bad", type=type(e).__name__,
                   message=(msg[:MAX_MESSAGE] + (f"... ({len(msg)} chars)" if len(msg) > MAX_MESSAGE else "")))
    rec["seconds"] = round(time.perf_counter() - t0, 3)
    rec["executed"] = (folder / "PWNED").exists()
    if rec["executed"]:
        rec["outcome"] = "bad"
        rec["message"] = "CODE EXECUTED: " + rec.get("message", "")
    return rec


class _Timeout(BaseException):
    """Raised by SIGALRM; a BaseException so that no `except Exception` in nlobs (the CLI's) swallows it."""


def worker() -> None:
    """Run the case ids read from stdin (one JSON list), one JSON line per case on stdout."""
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))
    sys.setrecursionlimit(3000)
    ids = json.loads(sys.stdin.read())
    by_id = {c.id: c for c in CASES}
    real_stdout = sys.stdout

    def on_alarm(signum: int, frame: Any) -> None:
        raise _Timeout()

    signal.signal(signal.SIGALRM, on_alarm)
    for cid in ids:
        c = by_id[cid]
        print(json.dumps({"start": cid}), file=real_stdout, flush=True)
        with tempfile.TemporaryDirectory(prefix="nlobs-hostile-") as tmp:
            cwd = os.getcwd()
            os.chdir(tmp)
            signal.setitimer(signal.ITIMER_REAL, c.budget)
            try:
                rec = _run_one(c, Path(tmp))
            except _Timeout:
                rec = {"id": cid, "outcome": "bad", "message": f"time budget of {c.budget:g} s exceeded", "seconds": c.budget,
                       "executed": False}
            except MemoryError:
                rec = {"id": cid, "outcome": "bad", "message": "memory cap exceeded", "seconds": 0, "executed": False}
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
                os.chdir(cwd)
        print(json.dumps(rec), file=real_stdout, flush=True)


def run_cases(cases: list[Case] | None = None) -> list[dict[str, Any]]:
    """Run cases in worker processes; a worker that hangs or dies is killed and replaced."""
    todo = [c.id for c in (cases if cases is not None else CASES)]
    budget = {c.id: c.budget for c in CASES}
    results: dict[str, dict[str, Any]] = {}
    env = {**os.environ, "NLOBS_ENGINE": "vm", "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
    src = Path(__file__).resolve().parents[2] / "src"
    env["PYTHONPATH"] = str(src) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    spawns = 0
    while todo:
        spawns += 1
        t_spawn = time.monotonic()
        proc = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "--worker"], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env)
        assert proc.stdin is not None and proc.stdout is not None
        proc.stdin.write(json.dumps(todo))
        proc.stdin.close()
        current: str | None = None
        started = time.monotonic()
        import selectors

        sel = selectors.DefaultSelector()
        sel.register(proc.stdout, selectors.EVENT_READ)
        while True:
            limit = (budget.get(current, DEFAULT_BUDGET) if current else 120.0) + 5.0
            if not sel.select(timeout=max(0.1, limit - (time.monotonic() - started))):
                proc.kill()
                break
            line = proc.stdout.readline()
            if not line:
                break
            msg = json.loads(line)
            if "start" in msg:
                current, started = msg["start"], time.monotonic()
                continue
            results[msg["id"]] = msg
            todo.remove(msg["id"])
            current = None
        proc.wait()
        sel.close()
        proc.stdout.close()
        if os.environ.get("NLOBS_HOSTILE_DEBUG"):
            print(f"worker {spawns}: {time.monotonic() - t_spawn:.1f} s, exit {proc.returncode}, current {current}", file=sys.stderr)
        if current is not None and current in todo:   # the worker died or hung on this case
            results[current] = {"id": current, "outcome": "bad", "executed": False, "seconds": budget.get(current, 0),
                                "message": f"worker killed or crashed (exit {proc.returncode}): time or memory budget"}
            todo.remove(current)
        elif todo and current is None and proc.returncode not in (0, None):
            nxt = todo.pop(0)
            results[nxt] = {"id": nxt, "outcome": "bad", "executed": False, "seconds": 0,
                            "message": f"worker crashed before the case (exit {proc.returncode})"}
    return [results[c.id] for c in (cases if cases is not None else CASES) if c.id in results]


def verdict(c: Case, rec: dict[str, Any]) -> bool:
    """Whether the case ended as it must: ok/error as expected, never bad, never executed code."""
    if rec["outcome"] == "bad" or rec.get("executed"):
        return False
    if rec["outcome"] == "error" and (c.names and c.names not in rec.get("message", "")
                                      or not actionable(rec.get("message", ""))):
        return False
    return c.expect == "either" or rec["outcome"] == c.expect


def summary(records: list[dict[str, Any]]) -> dict[str, Any]:
    by_id = {c.id: c for c in CASES}
    out = {"total": len(records), "correct result": 0, "clean error": 0, "failing": [], "pending": [], "pending fixed": []}
    for r in records:
        c = by_id[r["id"]]
        good = verdict(c, r)
        if good:
            out["correct result" if r["outcome"] == "ok" else "clean error"] += 1
            if c.pending:
                out["pending fixed"].append(r["id"])
        elif c.pending:
            out["pending"].append(f"{r['id']} [{c.pending}]: {r['outcome']}: {r.get('message', '')[:160]}")
        else:
            out["failing"].append(f"{r['id']}: {r['outcome']} (expected {c.expect}): {r.get('message', '')[:200]}")
    return out


def report(cases: list[Case], out_name: str) -> dict[str, Any]:
    """Run `cases`, print the counts and the pending / failing ones, and record them in benchmarks/results."""
    t0 = time.time()
    recs = run_cases(cases)
    s = summary(recs)
    print(f"{s['total']} cases in {time.time() - t0:.0f} s: {s['correct result']} correct results, {s['clean error']} clean "
          f"errors, {len(s['pending'])} pending (another branch's fix), {len(s['failing'])} failing")
    for line in s["pending"]:
        print("  pending:", line)
    for line in s["failing"]:
        print("  FAILING:", line)
    out = Path(__file__).resolve().parents[2] / "benchmarks" / "results" / out_name
    out.write_text(json.dumps({"summary": s, "records": recs}, indent=1) + "\n")
    return s


if __name__ == "__main__":
    if "--worker" in sys.argv:
        worker()
    else:
        report(CASES if "--all" in sys.argv else [c for c in CASES if not c.slow], "hostile.json")
