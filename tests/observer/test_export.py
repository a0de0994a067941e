"""C export: the generated step, compiled with the system compiler, reproduces the Python observer.

References are the Python paths the C must reproduce (``nlobs.estimate`` with zero-order hold,
``OnlineObserver.update`` one sample at a time), never the export code itself.
"""

from __future__ import annotations

import ctypes
import re
import shutil
import subprocess
from importlib import resources

import numpy as np
import pytest

import nlobs
from nlobs.design import design_ekf, design_from_config, design_output_injection
from nlobs.errors import PreconditionError
from nlobs.observer import Observer, export_c

CC = shutil.which("gcc") or shutil.which("cc")
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler (gcc/cc) on PATH: the exported C cannot be compiled here")

PEND = nlobs.load_model(str(resources.files("nlobs.models").joinpath("pendulum.toml")))
MAX_STEP = 2e-3


def _design(kind_name: str):
    cfg = PEND.observers[kind_name]
    return design_from_config(PEND.system, cfg.kind, cfg.options)


def _recording(t_final: float = 5.0, every: int = 10, seed: int = 3) -> nlobs.Recording:
    run = nlobs.simulate(PEND.system, t_final=t_final, dt=1e-3, x0=[1.0, 0.0], inputs={"u": "sin(t)"},
                         noise=nlobs.Noise.gaussian(0.01), seed=seed)
    return nlobs.Recording.from_run(run, every=every)


def _csv(t, u, y) -> str:
    rows = np.column_stack([t, u, y])
    cells = lambda r: ",".join("" if np.isnan(v) else repr(float(v)) for v in r)  # noqa: E731
    return "\n".join(cells(r) for r in rows) + "\n"


def _build_program(exp, tmp_path) -> str:
    exe = tmp_path / exp.name
    proc = subprocess.run([CC, "-std=c99", "-O2", "-Wall", "-pedantic", "-Werror", "-o", str(exe), str(exp.source),
                           str(exp.example), "-lm"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return str(exe)


def _run_program(exe: str, csv: str, *args: str) -> np.ndarray:
    proc = subprocess.run([exe, *args], input=csv, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("t,xhat_")
    return np.loadtxt(lines[1:], delimiter=",", ndmin=2)


def _design_or_ukf(observer: str):
    if observer == "ukf":
        return nlobs.design_ukf(PEND.system, Q=np.diag([1e-3, 1e-2]), R=[[1e-4]])
    return _design(observer)


@needs_cc
@pytest.mark.parametrize("observer", ["injection", "ekf", "ukf"])  # continuous, continuous-discrete (x2)
def test_compiled_program_matches_estimate_on_a_recording(observer, tmp_path):
    rec = _recording()
    exp = export_c(_design_or_ukf(observer), tmp_path, max_step=MAX_STEP)
    exe = _build_program(exp, tmp_path)
    out = _run_program(exe, "t,u,y\n" + _csv(rec.t, rec.u, rec.y))
    ref = nlobs.estimate({observer: _design_or_ukf(observer)}, rec, max_step=MAX_STEP, hold="zoh", engine="vm")
    assert out.shape == (rec.t.size, 3)
    np.testing.assert_array_equal(out[:, 0], rec.t)
    xhat = ref.observers[observer].xhat
    assert np.abs(out[:, 1:] - xhat).max() <= 1e-10 * max(1.0, np.abs(xhat).max())
    # a non-trivial run: the estimate moved from 0 to the state
    assert np.abs(xhat[-1] - rec.x[-1]).max() < 0.1 and np.abs(xhat[0] - xhat[-1]).max() > 0.1


@needs_cc
def test_initial_estimate_from_the_command_line_and_substeps(tmp_path):
    """xhat0 given to main.c; 4 RK4 steps per interval (dt = 0.01, max_step = 0.0025)."""
    rec = _recording(t_final=2.0)
    d = _design("ekf")
    exp = export_c(d, tmp_path, name="ekf4", max_step=0.0025)
    exe = _build_program(exp, tmp_path)
    out = _run_program(exe, _csv(rec.t, rec.u, rec.y), "0.5", "-0.25")  # no header line
    ref = nlobs.estimate(d, rec, xhat0=[0.5, -0.25], max_step=0.0025, engine="vm")
    xhat = next(iter(ref.observers.values())).xhat
    assert ref.info["substeps"] == 4
    assert np.abs(out[:, 1:] - xhat).max() <= 1e-10
    assert np.abs(out[0, 1:] - [0.5, -0.25]).max() > 1e-6  # the first sample already updated the EKF


@needs_cc
def test_time_varying_model_and_irregular_samples(tmp_path):
    """Explicit t in f (the flow must see the right time), irregular sample times, continuous EKF."""
    sys_ = nlobs.System(states=["p", "v"], f=["v", "-p - 0.2*v + cos(2*t)*u + sin(t)"], inputs=["u"], outputs=["y"],
                        h=["p + 0.1*sin(3*t)"], name="ltv")
    d = design_ekf(sys_, Q=np.diag([1e-3, 1e-2]), R=[[0.05]], mode="continuous", xhat0=[0.3, 0.0])
    rng = np.random.default_rng(7)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.005, 0.02, 300))])
    u = np.sin(0.7 * t)
    y = np.cos(t) + 0.1 * np.sin(3 * t) + 0.01 * rng.standard_normal(t.size)
    rec = nlobs.Recording.from_arrays(sys_, t, y, u)
    exp = export_c(d, tmp_path)
    out = _run_program(_build_program(exp, tmp_path), _csv(t, u, y))
    ref = nlobs.estimate(d, rec, engine="vm")  # no max_step: one RK4 step per interval, as in C
    xhat = next(iter(ref.observers.values())).xhat
    assert np.abs(out[:, 1:] - xhat).max() <= 1e-10
    # sensitivity: the same samples at shifted times give clearly other estimates, so the match above
    # needs the C step to use the right time in f and h
    shifted = nlobs.estimate(d, nlobs.Recording.from_arrays(sys_, t + 0.5, y, u), engine="vm")
    assert np.abs(next(iter(shifted.observers.values())).xhat - out[:, 1:]).max() > 1e-3


def _online_reference(design, t, u, y, max_step):
    online = Observer(design).start()
    online.max_step = max_step
    return np.array([online.update(tk, y=yk, u=uk) for tk, uk, yk in zip(t, u, y)])


@needs_cc
@pytest.mark.parametrize("observer", ["injection", "ekf"])
def test_missing_samples_follow_the_online_observer(observer, tmp_path):
    """NaN outputs: left out of the update and replaced by the prediction, exactly as OnlineObserver.update."""
    rec = _recording(t_final=3.0)
    y = rec.y.copy()
    y[[5, 6, 7, 40, 120]] = np.nan
    d = _design(observer)
    exp = export_c(d, tmp_path, max_step=MAX_STEP)
    out = _run_program(_build_program(exp, tmp_path), _csv(rec.t, rec.u, y))
    ref = _online_reference(d, rec.t, rec.u, y, MAX_STEP)
    assert np.all(np.isfinite(out))
    assert np.abs(out[:, 1:] - ref).max() <= 1e-10
    # and the gap did change the estimate (the missing samples were not silently zero or dropped rows)
    full = _online_reference(d, rec.t, rec.u, rec.y, MAX_STEP)
    assert np.abs(full[8] - ref[8]).max() > 1e-8


@needs_cc
def test_generated_source_is_dependency_free_and_compiles_strictly(tmp_path):
    d = _design("ekf")
    exp = export_c(d, tmp_path, name="strict_ekf", max_step=MAX_STEP)
    src = exp.source.read_text()
    assert re.findall(r"#include\s*[<\"]([^>\"]+)[>\"]", src) == ["strict_ekf.h", "math.h"]
    assert re.findall(r"#include", exp.header.read_text()) == []
    for banned in ("malloc", "calloc", "realloc", "free(", "printf", "FILE"):
        assert banned not in src, banned
    mutable = [ln for ln in src.splitlines() if re.match(r"\s*static\b", ln) and "(" not in ln and " const " not in ln]
    assert not mutable, f"mutable static (global) state: {mutable}"
    obj = tmp_path / "strict.o"
    proc = subprocess.run([CC, "-std=c99", "-Os", "-Wall", "-Wextra", "-Wno-unused-parameter", "-pedantic", "-Werror",
                           "-c", str(exp.source), "-o", str(obj)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    header = exp.header.read_text()
    assert "#define STRICT_EKF_NZ 6" in header and "#define STRICT_EKF_MAX_STEP 0.002" in header


@needs_cc
def test_step_through_ctypes_in_place_first_sample_and_errors(tmp_path):
    """The C interface itself: init with NULL, the first sample (dt = 0), in-place stepping, error codes."""
    d = _design("ekf")
    exp = export_c(d, tmp_path, name="lib_ekf", max_step=MAX_STEP)
    so = tmp_path / "lib_ekf.so"
    proc = subprocess.run([CC, "-std=c99", "-O2", "-shared", "-fPIC", str(exp.source), "-o", str(so), "-lm"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    lib = ctypes.CDLL(str(so))
    P = ctypes.POINTER(ctypes.c_double)
    lib.lib_ekf_init.argtypes = [P, P]
    lib.lib_ekf_step.argtypes = [P, ctypes.c_double, ctypes.c_double, P, P, P, P, P, P, P]

    def arr(v):
        return np.ascontiguousarray(v, dtype=float)

    def ptr(a):
        return None if a is None else a.ctypes.data_as(P)

    z = np.zeros(6)
    assert lib.lib_ekf_init(None, ptr(z)) == 0
    online = Observer(d).start()
    online.max_step = MAX_STEP
    np.testing.assert_array_equal(z, online.z)
    xhat, y_held = np.zeros(2), np.zeros(1)
    samples = [(0.0, 0.3, 0.1), (0.01, 0.35, 0.2), (0.025, 0.31, 0.25), (0.1, 0.2, -0.1)]
    t_prev, u_prev = 0.0, np.zeros(1)
    for k, (t, y, u) in enumerate(samples):
        ua, ya = arr([u]), arr([y])
        rc = lib.lib_ekf_step(ptr(z), t, t - t_prev if k else 0.0, None if k == 0 else ptr(u_prev),
                              None if k == 0 else ptr(y_held), ptr(ua), ptr(ya), ptr(z), ptr(xhat), ptr(y_held))
        assert rc == 0
        ref = online.update(t, y=[y], u=[u])
        assert np.abs(xhat - ref).max() <= 1e-12 and np.abs(z - online.z).max() <= 1e-12
        t_prev, u_prev = t, ua
    z_before = z.copy()
    for dt, yv in ((-0.01, 0.1), (float("nan"), 0.1), (0.01, float("inf"))):
        rc = lib.lib_ekf_step(ptr(z), 0.2, dt, ptr(u_prev), ptr(y_held), ptr(arr([0.0])), ptr(arr([yv])), ptr(z), ptr(xhat), None)
        assert rc == 1, (dt, yv)  # LIB_EKF_EINPUT, and nothing written
    np.testing.assert_array_equal(z, z_before)
    z_bad = z.copy()
    z_bad[2:] = 1e308  # a covariance whose flow overflows
    rc = lib.lib_ekf_step(ptr(z_bad), 0.2, 0.1, ptr(u_prev), ptr(y_held), ptr(arr([0.0])), ptr(arr([0.1])), ptr(z_bad),
                          ptr(xhat), None)
    assert rc == 2  # LIB_EKF_ENONFINITE


def test_bad_arguments_are_named():
    d = design_output_injection(PEND.system, poles=[-2, -3])
    with pytest.raises(ValueError, match=r"`name` must be a C identifier.*'9lives'"):
        export_c(d, "/nonexistent-never-written", name="9lives")
    with pytest.raises(ValueError, match=r"`name` must be a C identifier.*'double'"):
        export_c(d, "/nonexistent-never-written", name="double")
    with pytest.raises(ValueError, match=r"`max_step` must be a positive number \(finite and > 0\), got -0.1"):
        export_c(d, "/nonexistent-never-written", max_step=-0.1)
    with pytest.raises(TypeError, match="expected an observer or an ObserverDesign"):
        export_c(PEND.system, "/nonexistent-never-written")


def test_an_embedded_solver_is_refused_by_name(tmp_path):
    with pytest.raises(PreconditionError, match=r"'mhe' observer cannot be exported as dependency-free C.*numerical solver"):
        export_c(nlobs.design_mhe(PEND.system, horizon=4), tmp_path / "out")
    assert not (tmp_path / "out").exists()  # nothing half-written


def test_default_name_and_summary(tmp_path):
    exp = export_c(design_output_injection(PEND.system, poles=[-2, -3]), tmp_path)
    assert exp.name == "pendulum_output_injection"
    assert {p.name for p in tmp_path.iterdir()} == {"pendulum_output_injection.c", "pendulum_output_injection.h", "main.c"}
    text = str(exp)
    assert "one RK4 step per sample interval" in text and "cc -std=c99 -O2" in text


# A model name that closes the comment it is copied into and defines a constructor that runs before main():
# unescaped, compiling and running the exported example (as the README says) would create the file PWNED.
HOSTILE = ('pend */ __attribute__((constructor)) static void pwn(void) { FILE *f = fopen("PWNED", "w"); if (f) fclose(f); } '
           '/* ??/\n */ #include <stdio.h>\n\u202e')


def _hostile_design():
    d = design_output_injection(PEND.system, poles=[-2.0, -3.0])
    object.__setattr__(d.system, "_name", HOSTILE)   # whatever the model layer accepts, the C writer must be safe
    return d


def test_hostile_model_name_cannot_inject_code(tmp_path):
    d = _hostile_design()
    exp = export_c(d, tmp_path / "out", name="safe_obs")
    for path in (exp.source, exp.header, exp.example):
        text = path.read_text()
        assert "*/ __attribute__" not in text and "??/" not in text and "\u202e" not in text
        # every comment opened is closed by nlobs' own text: the name adds no comment delimiter
        assert text.count("/*") == text.count("*/")
    if CC is None:
        pytest.skip("no C compiler: the generated text was checked, not compiled")
    exe = _build_program(exp, tmp_path)
    rec = _recording(t_final=0.5, every=10)
    proc = subprocess.run([exe], input=_csv(rec.t, rec.u, rec.y), capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert not (tmp_path / "PWNED").exists()
    assert proc.stdout.splitlines()[0] == "t,xhat_theta,xhat_omega" or proc.stdout.startswith("t,xhat_")


def test_c_text_helpers_escape_everything_that_could_end_a_comment_or_string():
    from nlobs.observer._export import _c_comment, _c_string

    nasty = 'a*/b/*c//d\\\ne??/f"g%s\u202eh\x00'
    out = _c_comment(nasty)
    assert not any(tok in out for tok in ("*/", "/*", "//", "\\", "?", "\n", "\x00", "\u202e"))
    assert len(_c_comment("x" * 10_000)) <= 160
    lit = _c_string(nasty)
    assert all(ch.isalnum() or ch in "_,\\" for ch in lit)      # only escapes and plain characters
    # the literal decodes back to the original bytes (C octal escapes are the same as Python's)
    assert lit.encode().decode("unicode_escape").encode("latin-1") == nasty.encode("utf-8")


@pytest.mark.parametrize("bad", ["abc\n", "a b", "*/x", "int", "a" * 41, "1abc", "é"])
def test_export_name_must_be_a_c_identifier_exactly(bad, tmp_path):
    with pytest.raises(ValueError, match="C identifier") as info:
        export_c(design_output_injection(PEND.system, poles=[-2.0, -3.0]), tmp_path, name=bad)
    assert len(str(info.value)) < 300
    assert not any(tmp_path.iterdir())


@needs_cc
@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_a_discrete_time_observer_exports_its_map_step(kind, tmp_path):
    # a map's observer has no flow between samples: the exported step is its predict-from-the-last-sample + correct
    osc = nlobs.System(states=["x1", "x2"], inputs=["u"], outputs=["y"], f=["x1 + 0.1*x2", "x2 + 0.1*(-sin(x1) - 0.2*x2 + u)"],
                       h=["x1"], time="discrete", sample_time=0.1, name="osc_map")
    design = getattr(nlobs, f"design_{kind}")(osc, Q=np.eye(2) * 1e-4, R=[[1e-2]], P0=np.eye(2), xhat0=[0.5, 0.0])
    run = nlobs.simulate(osc, None, t_final=20.0, x0=[1.0, 0.0], inputs={"u": "sin(0.5*t)"}, noise=nlobs.Noise.gaussian(0.1),
                         seed=4)
    rec = nlobs.Recording.from_run(run)
    exe = _build_program(export_c(design, tmp_path), tmp_path)
    out = _run_program(exe, "t,u,y\n" + _csv(rec.t, rec.u, rec.y))
    xhat = nlobs.estimate({kind: design}, rec).observers[kind].xhat
    assert np.abs(out[:, 1:] - xhat).max() <= 1e-12 * max(1.0, np.abs(xhat).max())
    assert np.abs(xhat[-1] - run.x[-1]).max() < 0.2 and np.abs(xhat[0] - xhat[-1]).max() > 0.1
