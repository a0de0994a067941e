"""A very large SX function is generated as a chain of parts (engine/_split.py): the same numbers, compiled apart."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import nlobs.engine._codegen as codegen
import nlobs.engine._split as split
from nlobs.engine import find_compiler


def _lorenz_rk4(steps: int) -> ca.Function:
    """`steps` RK4 steps of the Lorenz system (a straight line of a few thousand SX operations), with a sum and a
    constant among the outputs and a parameter vector that is read throughout."""
    s, a = ca.SX.sym("s", 3), ca.SX.sym("a", 4)

    def f(x):
        return ca.vertcat(a[0] * (x[1] - x[0]), x[0] * (a[1] - x[2]) - x[1], x[0] * x[1] - a[2] * x[2])
    x, h = s, a[3]
    for _ in range(steps):
        k1 = f(x)
        k2 = f(x + h / 2 * k1)
        k3 = f(x + h / 2 * k2)
        k4 = f(x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4) + ca.sin(x) * 1e-3
    return ca.Function("lorenz", [s, a], [x, ca.sumsqr(x) + ca.exp(-a[3]), ca.DM(2.5)], ["s", "a"], ["x", "n", "c"])


def test_the_parts_give_the_functions_numbers_bit_for_bit():
    f = _lorenz_rk4(60)
    g = split.split_large(f, above=500, part=400)
    calls = [h for h in g.find_functions() if h.name().startswith("lorenz_part")]
    ops = sum(1 for k in range(f.n_instructions()) if f.instruction_id(k) not in (ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST))
    # the parts of the arithmetic, and one that gathers the outputs (copies and constants only)
    assert g.is_a("MXFunction") and len(calls) == -(-ops // 400) + 1
    last = max(calls, key=lambda h: int(h.name().rsplit("part", 1)[1]))
    assert {last.instruction_id(k) for k in range(last.n_instructions())} <= {ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST}
    assert all(h.n_instructions() < 400 + 200 for h in calls)   # each part its share (plus reading and writing)
    rng = np.random.default_rng(3)
    for _ in range(5):
        s0, a0 = rng.normal(size=3), np.array([10.0, 28.0, 8 / 3, 0.01]) * rng.uniform(0.9, 1.1, 4)
        for p, q in zip(f(s0, a0), g(s0, a0)):
            assert np.array_equal(np.array(p), np.array(q))
    assert split.split_large(f, above=f.n_instructions()) is f   # below the threshold: unchanged


@pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")
def test_a_split_step_compiles_in_units_and_runs_as_the_vm(monkeypatch, tmp_path):
    """A compiled loop over a step above the threshold: its parts compiled in several units (gcc runs) and linked;
    the states equal CasADi's virtual machine to rounding."""
    monkeypatch.setenv("NLOBS_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(split, "ABOVE", 500)
    monkeypatch.setattr(split, "PART", 300)
    monkeypatch.setattr(split, "UNIT_LINES", 600)
    runs, commands = [], []
    real = codegen._run_compilers
    monkeypatch.setattr(codegen, "_run_compilers",
                        lambda cc, cmds, *a: (runs.append(len(cmds)), commands.append(cmds), real(cc, cmds, *a)))
    f = _lorenz_rk4(20)
    s, a, c = ca.SX.sym("s", 3), ca.SX.sym("a", 4), ca.SX.sym("c", 1)
    x, n, _ = f(s, a)
    step = ca.Function("step", [s, a, c], [x * c, n])
    loop = codegen.CompiledLoop(step)
    assert runs[0] >= 3 and runs[1:] == [1]   # three or more units compiled, then one link
    # gcc weighs fewer reload pseudos in each unit (a part is one long basic block); the link is not compiled again
    if codegen._is_gcc(find_compiler()):
        assert all(set(codegen.SPLIT_UNIT_GCC) <= set(cmd) for cmd in commands[0])
    A = np.tile([10.0, 28.0, 8 / 3, 0.002], (50, 1))
    out, obuf = np.empty((50, 3)), np.empty((50, 1))
    assert loop(np.array([1.0, 1.0, 1.0]), A, np.array([1.0]), out, obuf) == 50
    x_vm = np.array([1.0, 1.0, 1.0])
    for k in range(50):
        x_next, o = step(x_vm, A[k], 1.0)
        assert abs(float(o) - obuf[k, 0]) <= 1e-12 * abs(float(o))
        x_vm = np.array(x_next).ravel()
        np.testing.assert_allclose(out[k], x_vm, rtol=1e-12, atol=0)


def test_big_code_compiles_at_o1_with_gccs_faster_register_allocation(monkeypatch):
    """Above BIG_CODE lines: -O1, and with gcc the priority colouring in one region (register allocation is most of
    gcc's time on straight-line code); below it -O3 and nothing else; another compiler gets no gcc-only flag."""
    from nlobs.engine import _codegen as cg

    monkeypatch.setattr(cg, "find_compiler", lambda: "/usr/bin/gcc")
    monkeypatch.setattr(cg, "_is_gcc", lambda cc: True)
    small, big = cg.cflags(100), cg.cflags(cg.BIG_CODE + 1)
    assert "-O3" in small and not set(cg.BIG_CODE_GCC) & set(small)
    assert "-O1" in big and "-O3" not in big and set(cg.BIG_CODE_GCC) <= set(big)
    monkeypatch.setattr(cg, "_is_gcc", lambda cc: False)
    assert not set(cg.BIG_CODE_GCC) & set(cg.cflags(cg.BIG_CODE + 1))


def test_gcc_is_recognised_and_clang_is_not():
    import shutil

    from nlobs.engine import _codegen as cg

    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.skip("no gcc here (CI has it)")
    assert cg._is_gcc(gcc)
    assert not cg._is_gcc(None) and not cg._is_gcc("/nonexistent/cc")
