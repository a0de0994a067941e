"""The disk cache of compiled code (issue 36 §2): a second process on the same model starts warm (builds nothing),
a changed model recompiles, and a step is compiled per observer (another combination reuses it)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from nlobs.engine import find_compiler

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")

MODEL = """
name = "cart"
states = ["p", "v", "b"]
inputs = ["a"]
outputs = ["gps", "wheel"]
[parameters]
c = 0.1
[dynamics]
p = "v"
v = "a - c*v"
b = "0"
[output]
gps = "p"
wheel = "v + b"
[simulation]
t_final = 4.0
dt = 0.01
x0 = [0.0, 1.0, 0.3]
inputs = { a = "sin(0.5*t)" }
noise = { gps = 0.5, wheel = 0.1 }
sample_period = { gps = 0.25, wheel = 0.1 }
seed = 3
[observers.ekf]
kind = "ekf"
xhat0 = [5.0, 0.0, 0.0]
R = [[0.25, 0.0], [0.0, 0.01]]
Q = [[1e-4, 0.0, 0.0], [0.0, 1e-3, 0.0], [0.0, 0.0, 1e-6]]
[observers.slow]
kind = "ekf"
xhat0 = [-3.0, 2.0, 0.1]
R = [[1.0, 0.0], [0.0, 0.04]]
Q = [[1e-3, 0.0, 0.0], [0.0, 1e-2, 0.0], [0.0, 0.0, 1e-5]]
"""


def _nlobs(model, cache, *args):
    env = {**os.environ, "NLOBS_CACHE_DIR": str(cache)}
    out = subprocess.run([sys.executable, "-m", "nlobs.cli", "simulate", str(model), "--engine", "c", "--json", *args],
                         env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def _builds(cache):
    return {p.name: p.stat().st_mtime_ns for p in cache.glob("*.so")}


@pytest.mark.parametrize("delay", [False, True])
def test_a_second_process_is_warm_and_a_changed_model_recompiles(tmp_path, delay):
    model, cache = tmp_path / "cart.toml", tmp_path / "cache"
    text = MODEL
    if delay:
        text = text.replace("seed = 3\n", "seed = 3\ndelay = { gps = 0.15 }\n")
    model.write_text(text, encoding="utf-8")
    first = _nlobs(model, cache)
    built = _builds(cache)
    assert len(built) >= 2                              # one compiled step per observer (and the plant's own)
    second = _nlobs(model, cache)
    assert _builds(cache) == built                      # warm: nothing built again, not even replaced
    assert second["observers"]["ekf"]["final_estimate"] == first["observers"]["ekf"]["final_estimate"]
    _nlobs(model, cache, "--observer", "ekf")           # another combination: the ekf's step is reused
    assert _builds(cache) == built
    model.write_text(text.replace('v = "a - c*v"', 'v = "a - c*v - 0.01*v**3"'), encoding="utf-8")
    _nlobs(model, cache)
    changed = _builds(cache)
    assert set(built) < set(changed)                    # a changed model recompiles (and keeps the old builds)
