"""Engine: SymPy -> CasADi translation, VM and compiled-C paths, the on-disk cache, the no-compiler fallback."""

from __future__ import annotations

import os
import time

import casadi as ca
import numpy as np
import pytest
import sympy as sp

from nlobs import ConvergenceWarning, System
from nlobs.engine import StepRunner, cache_dir, compile_system, find_compiler, resolve_backend, rk4_step

MODEL = System(
    states=["x1", "x2", "x3"],
    f=["x2*cos(x1) + atan2(x3, 1 + x1**2)", "-k*sqrt(1 + x2**2) + exp(-x3**2)*u + sin(t)", "tanh(x1 - x3) + abs(x2)**1.5 + log(2 + x1**2)"],
    outputs=["y1", "y2"], h=["x1/(1 + x2**2)", "sign(x3)*x3**2 + sinh(x1)*cosh(x2) + tan(x3/10)"],
    inputs=["u"], params={"k": 0.7}, name="zoo")


def test_casadi_matches_sympy_values_and_jacobians():
    comp = compile_system(MODEL)
    rng = np.random.default_rng(0)
    syms = [*MODEL.x, *MODEL.u, *MODEL.p, MODEL.t]
    f_sym = sp.Matrix(MODEL.f)
    J_sym = f_sym.jacobian(sp.Matrix(MODEL.x))
    H_sym = sp.Matrix(MODEL.h).jacobian(sp.Matrix(MODEL.x))
    for _ in range(5):
        x = rng.normal(size=3)
        u, t = rng.normal(), rng.uniform(0, 5)
        vals = dict(zip(syms, [*x, u, 0.7, t]))
        f_ref = np.array(f_sym.evalf(subs=vals), dtype=float).ravel()
        J_ref = np.array(J_sym.evalf(subs=vals), dtype=float)
        H_ref = np.array(H_sym.evalf(subs=vals), dtype=float)
        assert np.allclose(np.array(comp.f(t, x, u, 0.7)).ravel(), f_ref, rtol=1e-12, atol=1e-12)
        assert np.allclose(np.array(comp.f_x(t, x, u, 0.7)), J_ref, rtol=1e-10, atol=1e-12)
        assert np.allclose(np.array(comp.h_x(t, x, u, 0.7)), H_ref, rtol=1e-10, atol=1e-12)


def test_compile_is_cached_per_structure():
    a = compile_system(MODEL)
    b = compile_system(MODEL.with_params(k=2.0))
    assert a.f is b.f and b.system.params["k"] == 2.0


def _vdp_step():
    s, a, c = ca.SX.sym("s", 2), ca.SX.sym("a", 1), ca.SX.sym("c", 1)

    def rhs(t, x, _k):
        return ca.vertcat(x[1], c[0] * (1 - x[0] ** 2) * x[1] - x[0])

    return ca.Function("vdp_step", [s, a, c], [rk4_step(rhs, 0, s, a[0])])


def _reference_rk4(x0, dt, n, mu):
    def f(x):
        return np.array([x[1], mu * (1 - x[0] ** 2) * x[1] - x[0]])

    x, out = np.array(x0, float), []
    for _ in range(n):
        k1 = f(x); k2 = f(x + dt / 2 * k1); k3 = f(x + dt / 2 * k2); k4 = f(x + dt * k3)  # noqa: E702
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(x)
    return np.array(out)


@pytest.mark.skipif(find_compiler() is None, reason="the compiled path needs a C compiler (gcc/cc); the VM path is tested below")
def test_vm_and_compiled_c_agree_with_a_plain_python_rk4():
    step = _vdp_step()
    A = np.full((2500, 1), 1e-2)
    ref = _reference_rk4([2.0, 0.0], 1e-2, 2500, 1.5)
    vm = StepRunner(step, backend="vm", chunk=1000).run([2.0, 0.0], A, [1.5])[0]
    c = StepRunner(step, backend="c", chunk=1000).run([2.0, 0.0], A, [1.5])[0]
    assert np.max(np.abs(vm - ref)) < 1e-11
    assert np.max(np.abs(c - ref)) < 1e-11


def test_vm_path_alone():
    step = _vdp_step()
    out = StepRunner(step, backend="vm", chunk=64).run([2.0, 0.0], np.full((200, 1), 1e-2), [1.5])[0]
    assert np.max(np.abs(out - _reference_rk4([2.0, 0.0], 1e-2, 200, 1.5))) < 1e-12


def test_without_a_compiler_c_falls_back_to_the_vm_with_a_warning(monkeypatch):
    monkeypatch.setenv("NLOBS_CC", "none")
    assert find_compiler() is None
    with pytest.warns(ConvergenceWarning, match="no C compiler found"):
        assert resolve_backend("c", work=10) == "vm"
    assert resolve_backend("auto", work=10**9) == "vm"  # auto falls back silently
    step = _vdp_step()
    with pytest.warns(ConvergenceWarning):
        out = StepRunner(step, backend="c").run([2.0, 0.0], np.full((100, 1), 1e-2), [1.5])[0]
    assert np.max(np.abs(out - _reference_rk4([2.0, 0.0], 1e-2, 100, 1.5))) < 1e-12


def test_auto_compiles_only_long_runs(monkeypatch):
    monkeypatch.delenv("NLOBS_ENGINE", raising=False)
    if find_compiler() is None:
        pytest.skip("no C compiler on this machine: auto always uses the VM (tested above)")
    assert resolve_backend("auto", work=100) == "vm"
    assert resolve_backend("auto", work=10**7) == "c"
    monkeypatch.setenv("NLOBS_ENGINE", "vm")
    assert resolve_backend("auto", work=10**7) == "vm"
    with pytest.raises(ValueError, match="must be 'auto', 'vm' or 'c'"):
        resolve_backend("gpu", work=1)  # type: ignore[arg-type]


@pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")
def test_compiled_models_are_cached_on_disk(tmp_path, monkeypatch):
    monkeypatch.setenv("NLOBS_CACHE_DIR", str(tmp_path))
    from nlobs.engine._codegen import CompiledLoop

    s, a, c = ca.SX.sym("s", 1), ca.SX.sym("a", 1), ca.SX.sym("c", 1)
    step = ca.Function("decay", [s, a, c], [s * (1 - a[0] * c[0])])
    CompiledLoop(step)
    built = list(tmp_path.glob("loop-*.so"))
    assert len(built) == 1 and cache_dir() == tmp_path
    mtime = built[0].stat().st_mtime_ns
    time.sleep(0.01)
    loop = CompiledLoop(step)  # same code: reuses the build
    assert built[0].stat().st_mtime_ns == mtime and len(list(tmp_path.glob("loop-*.so"))) == 1
    out = np.empty((3, 1))
    assert loop(np.array([1.0]), np.full((3, 1), 0.5), np.array([1.0]), out) == 3
    assert np.allclose(out.ravel(), [0.5, 0.25, 0.125])
    assert not os.listdir(tmp_path) == []


def test_auto_chooses_by_measured_cost(monkeypatch):
    """Compile once the VM time spent on a function (plus this call's) reaches the measured compile time;
    at once when the build is already cached; never for "vm"; $NLOBS_ENGINE overrides."""
    from nlobs.engine._codegen import COSTS, choose_backend

    monkeypatch.delenv("NLOBS_ENGINE", raising=False)
    if find_compiler() is None:
        pytest.skip("no C compiler on this machine: auto always uses the VM (tested above)")
    monkeypatch.setattr(COSTS, "_data", {"compile_a": 0.5, "compile_b": 0.0, "vm_per_instr": 1e-9})
    monkeypatch.setattr(COSTS, "spent", {})
    kw = dict(n_instr=100, signature="sig")
    assert choose_backend("auto", ready=False, vm_instr=1e8, **kw) == "vm"   # 0.1 s < 0.5 s
    assert choose_backend("auto", ready=False, vm_instr=6e8, **kw) == "c"    # 0.6 s >= 0.5 s
    COSTS.spent["sig"] = 0.45
    assert choose_backend("auto", ready=False, vm_instr=1e8, **kw) == "c"    # 0.45 s spent + 0.1 s
    assert choose_backend("auto", ready=True, vm_instr=1.0, signature="other", n_instr=100) == "c"
    assert choose_backend("vm", ready=True, vm_instr=1e12, **kw) == "vm"
    monkeypatch.setenv("NLOBS_ENGINE", "vm")
    assert choose_backend("auto", ready=True, vm_instr=1e12, **kw) == "vm"


def test_a_cached_build_is_found_by_signature_without_generating_code(monkeypatch, tmp_path):
    import nlobs.engine._codegen as cg

    monkeypatch.setenv("NLOBS_CACHE_DIR", str(tmp_path))
    step = _vdp_step()
    loop = cg.CompiledLoop(step) if find_compiler() is not None else None
    if loop is None:
        pytest.skip("needs a C compiler")
    monkeypatch.setattr(cg, "_generate", lambda *fns: (_ for _ in ()).throw(AssertionError("generated again")))
    again = cg.CompiledLoop(step)  # found on disk by the step's signature: no code generation, no compile
    assert again.path == loop.path
