"""Issue 44, item 8b: an analysis that runs out of memory, or a model nested beyond Python's recursion depth, says
what ran out, where, and what to do (not a bare MemoryError or "maximum recursion depth exceeded")."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import nlobs
from nlobs import ModelFileError, loads_model


def _chain(depth: int) -> str:
    expr = "x1"
    for i in range(depth):
        expr = f"sin({expr})" if i % 3 else f"cos({expr} + x2)"
    return textwrap.dedent(f"""
        name = "nest"
        states = ["x1", "x2", "x3"]
        outputs = ["y"]
        [dynamics]
        x1 = "{expr}"
        x2 = "x1*x3"
        x3 = "-x2"
        [output]
        y = "x1"
        """)


def test_a_chain_nested_beyond_the_recursion_depth_is_named_with_its_key():
    with pytest.raises(ModelFileError) as err:
        loads_model(_chain(150), path="nest.toml")  # (beyond 200 levels the parser refuses it)
    msg = str(err.value)
    assert "key `dynamics.x1`" in msg and "nests 201 levels deep" in msg and "recursion depth" in msg
    assert "new state" in msg


def test_an_analysis_out_of_memory_says_what_ran_out_and_what_to_do(tmp_path):
    # a real exhaustion: the process's address space is capped below what it already maps, after the imports and a
    # first analysis (so only the analysis's own allocations meet the cap)
    model = tmp_path / "nest.toml"
    model.write_text(_chain(60), encoding="utf-8")
    script = tmp_path / "oom.py"
    script.write_text(textwrap.dedent(f"""
        import resource
        import nlobs
        from nlobs.model import load_model
        mf = load_model({str(model)!r})
        nlobs.analyze(nlobs.System(states=["a", "b"], f=["sin(b)", "-a*b"], outputs=["y"], h=["a"]))
        vm = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
        resource.setrlimit(resource.RLIMIT_AS, (vm - 64 * 2**20, resource.RLIM_INFINITY))
        try:
            nlobs.analyze(mf.system)
            print("finished")
        except MemoryError as e:
            print(type(e).__name__ + ": " + str(e))
        """), encoding="utf-8")
    src = str(Path(nlobs.__file__).resolve().parents[1])
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120,
                         env={"PYTHONPATH": src, "PATH": "/usr/bin:/bin"}).stdout
    assert out.startswith("ResourceError: ran out of memory during the local rank"), out
    assert "'nest'" in out and "run it with more memory" in out and "--params" in out
