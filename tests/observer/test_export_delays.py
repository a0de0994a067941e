"""C export with known measurement delays: the fusion filter, compiled with the system compiler, against Python.

References are computed by other code than the C writer: ``nlobs.estimate(..., delay=...)`` (exact re-processing of
a recording stamped at arrival) and, for the definition itself, plain ``nlobs.estimate`` on only the samples that have
arrived by t, each at the time it was taken.

RK4 steps: every export and every reference here gets the same ``max_step`` (2 ms against rows 10 ms apart and flow
rates of the cart EKF below 1 per second, so h·ρ <= 0.002): ``estimate``'s rule h·ρ <= 1 adds no sub-step and both
sides take n = ceil(gap / max_step) equal steps per gap between knots, as the exported C does.
"""

from __future__ import annotations

import ctypes
import re
import shutil
import subprocess

import numpy as np
import pytest

import nlobs
from nlobs import System
from nlobs.errors import ModelError
from nlobs.observer import export_c
from nlobs.simulate import Noise, Sampling

CC = shutil.which("gcc") or shutil.which("cc")
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler (gcc/cc) on PATH: the exported C cannot be compiled here")

MAX_STEP = 2e-3

# the cart of tests/simulate/test_delays.py: GPS every 0.25 s, a wheel speed every 0.1 s
CART = System(states=["p", "v", "b"], inputs=["a"], outputs=["gps", "wheel"], f=["v", "a - 0.1*v", "0"],
              h=["p", "v + b"], name="cart")
KW = dict(dt=0.01, x0=[0.0, 1.0, 0.3], inputs={"a": "sin(0.5*t)"}, noise=Noise.per_output({"gps": 0.5, "wheel": 0.1}),
          sampling=Sampling({"gps": 0.25, "wheel": 0.1}), seed=3)
# the cart with a wheel sensor that feels the input (so the update at a taken time depends on which row's input it
# uses), and with a third output read at every row without delay (a tachometer)
CARTU = System(states=["p", "v", "b"], inputs=["a"], outputs=["gps", "wheel"], f=["v", "a - 0.1*v", "0"],
               h=["p", "v + b + 0.5*a"], name="cartu")
CART3 = System(states=["p", "v", "b"], inputs=["a"], outputs=["gps", "wheel", "tacho"], f=["v", "a - 0.1*v", "0"],
               h=["p", "v + b + 0.5*a", "v"], name="cart3")


def _ekf(system=CART, R=None):
    R = np.diag([0.25, 0.01, 0.04][: system.n_outputs]) if R is None else R
    return nlobs.design_ekf(system, R=R, Q=np.diag([1e-4, 1e-3, 1e-6]), xhat0=[5.0, 0.0, 0.0])


# correlated noise of the three outputs: samples taken at the same time are one joint update, not two in a row (which
# gives another estimate), so the definition test below sees whether samples whose taken times t - d differ from a
# row's time by rounding only are applied with that row's samples
R_CORRELATED = np.array([[0.25, 0.0, 0.03], [0.0, 0.01, 0.012], [0.03, 0.012, 0.04]])


def _csv(t, u, y) -> str:
    rows = np.column_stack([t, u, y])
    return "".join(",".join("" if np.isnan(v) else repr(float(v)) for v in r) + "\n" for r in rows)


def _build(exp, tmp_path) -> str:
    exe = tmp_path / f"{exp.name}_prog"
    proc = subprocess.run([CC, "-std=c99", "-O2", "-Wall", "-pedantic", "-Werror", "-o", str(exe), str(exp.source),
                           str(exp.example), "-lm"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return str(exe)


def _run(exe: str, csv: str) -> tuple[np.ndarray, str]:
    proc = subprocess.run([exe], input=csv, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("t,xhat_")
    return np.loadtxt(lines[1:], delimiter=",", ndmin=2), proc.stderr


def _arrived_recording(system, t, u, every, delays, drop=0.0, seed=0):
    """A recording stamped at arrival on the rows `t`: output j arrives at every every[j]-th row (0 = every row), its
    value h_j(x(s)) + noise of the cart's true path at the time it was taken, s = t - delays[j]; a fraction `drop` of
    the arrivals is lost (NaN)."""
    rng = np.random.default_rng(seed)
    fine = nlobs.simulate(system, None, t_final=np.ceil(t[-1] * 100) / 100 + 0.01, dt=1e-3, x0=[0.0, 1.0, 0.3],
                          inputs={"a": "sin(0.5*t)"})
    x = np.column_stack([np.interp(np.asarray(t), fine.t, fine.x[:, i]) for i in range(3)])
    y = np.full((t.size, system.n_outputs), np.nan)
    for j, name in enumerate(system.outputs):
        rows = np.arange(0, t.size, every[j] or 1)
        s = t[rows] - delays.get(name, 0.0)
        xs = np.column_stack([np.interp(s, fine.t, fine.x[:, i]) for i in range(3)])
        coupled = 0.5 * np.sin(0.5 * s) if system is not CART else 0.0
        true = [xs[:, 0], xs[:, 1] + xs[:, 2] + coupled, xs[:, 1]][j]
        vals = true + [0.5, 0.1, 0.2][j] * rng.standard_normal(rows.size)
        vals[rng.random(rows.size) < drop] = np.nan
        y[rows, j] = vals
    return nlobs.Recording.from_arrays(system, t, y, u, x=x)


def _jittered_rows(t_final, h, seed=1):
    rng = np.random.default_rng(seed)
    return np.concatenate([[0.0], np.cumsum(h * (1.0 + 0.5 * rng.random(int(t_final / h))))])   # spacing h .. 1.5 h


def _case(case):
    """(system, recording stamped at arrival, delays, min_interval) of the three equality cases."""
    if case == "cart":          # (a) the cart of test_delays.py, written by Run.to_csv (stamped at arrival)
        delays = {"gps": 0.15}
        run = nlobs.simulate(CART, {"ekf": _ekf()}, t_final=6.0, delay=delays, **KW)
        y = np.where(run.info["measured"], run.y, np.nan)
        k = 15                   # 0.15 s = 15 rows of 10 ms: the row where each GPS sample arrived
        y[k:, 0], y[:k, 0] = y[:-k, 0].copy(), np.nan
        y[3, 0] = 7.0            # a fix arriving at 0.03 s, taken at -0.12 s: before the first row, left out
        return CART, nlobs.Recording.from_arrays(CART, run.t, y, run.u, x=run.x), delays, 0.01
    if case == "between_rows":  # (b) irregular rows 10-15 ms apart, delays not multiples of the spacing
        t = _jittered_rows(6.0, 0.01)
        delays = {"gps": 0.137, "wheel": 0.0437}
        return CARTU, _arrived_recording(CARTU, t, np.sin(0.5 * t), [25, 10], delays, seed=2), delays, 0.01
    if case == "two_delays_and_none":   # (c) two delays, a zero-delay output at every row, lost samples everywhere
        t = np.round(np.arange(0.0, 6.0 + 1e-9, 0.01), 12)
        delays = {"gps": 0.2, "wheel": 0.05, "tacho": 0.0}
        rec = _arrived_recording(CART3, t, np.sin(0.5 * t), [25, 10, 0], delays, drop=0.15, seed=4)
        return CART3, rec, delays, 0.01
    raise AssertionError(case)


@needs_cc
@pytest.mark.parametrize("case", ["cart", "between_rows", "two_delays_and_none"])
def test_fusion_filter_equals_estimate_with_delays(case, tmp_path):
    system, rec, delays, h = _case(case)
    design = _ekf(system)
    exp = export_c(design, tmp_path, name="fus", max_step=MAX_STEP, delays=delays, min_interval=h)
    out, err = _run(_build(exp, tmp_path), "t,a," + ",".join(system.outputs) + "\n" + _csv(rec.t, rec.u, rec.y))
    late = nlobs.estimate({"ekf": design}, rec, delay=delays, on_missing="skip", max_step=MAX_STEP)
    ref = late.observers["ekf"].xhat
    assert out.shape == (rec.t.size, 4)
    np.testing.assert_array_equal(out[:, 0], rec.t)
    assert np.abs(out[:, 1:] - ref).max() <= 1e-12
    # a run where the delays matter: the same rows taken as current give other estimates, and the filter converged
    naive = nlobs.estimate({"ekf": design}, rec, on_missing="skip", max_step=MAX_STEP).observers["ekf"].xhat
    assert np.abs(naive - ref).max() > 1e-3
    assert np.abs(ref[-1, :2] - rec.x[-1, :2]).max() < 0.5 < np.abs(ref[0, :2] - rec.x[0, :2]).max()
    # samples taken before the first row (the cart's fix at 0.03 s; the first row's late samples): left out by both
    early = {"cart": 1, "between_rows": 2, "two_delays_and_none": 2}[case]
    assert late.info["notes"] == [f"{early} delayed sample(s) taken before the recording's first time were left out"]
    assert err == f"note: {early} delayed sample(s) taken before the first row were left out\n"


def _definition(system, rec, delays, k, design):
    """Plain estimate (no delays) on the samples arrived by t_k, each in a row at the time it was taken: the rows of
    the recording up to t_k and the taken times between them, the input of the row whose hold interval holds each."""
    t, tk = rec.t[: k + 1], rec.t[k]
    d = np.array([delays.get(o, 0.0) for o in system.outputs])
    rows, cols = np.nonzero(np.isfinite(rec.y[: k + 1]))
    taken, vals = t[rows] - d[cols], rec.y[rows, cols]
    keep = taken >= t[0] - 1e-12                                   # taken before the first row: left out
    taken, cols, vals = taken[keep], cols[keep], vals[keep]
    near = np.abs(taken[:, None] - t[None, :]) <= 1e-12              # a taken time within 1e-12 of a row: that row
    taken = np.where(near.any(axis=1), t[np.argmax(near, axis=1)], taken)
    times = np.unique(np.concatenate([t, taken]))
    y = np.full((times.size, system.n_outputs), np.nan)
    y[np.searchsorted(times, taken), cols] = vals
    u = rec.u[np.searchsorted(t, times, side="right") - 1]
    part = nlobs.Recording.from_arrays(system, times, y, u)
    return nlobs.estimate({"ekf": design}, part, on_missing="skip", max_step=MAX_STEP).observers["ekf"].xhat[-1]


@needs_cc
@pytest.mark.parametrize("case", ["between_rows", "two_delays_and_none"])
def test_the_estimate_at_t_is_the_plain_filter_on_the_samples_arrived_by_t(case, tmp_path):
    system, rec, delays, h = _case(case)
    design = _ekf(system, R_CORRELATED if system is CART3 else None)
    exp = export_c(design, tmp_path, name="fus", max_step=MAX_STEP, delays=delays, min_interval=h)
    out, _ = _run(_build(exp, tmp_path), _csv(rec.t, rec.u, rec.y))
    for k in (37, 212, 401, rec.t.size - 1):
        assert np.abs(out[k, 1:] - _definition(system, rec, delays, k, design)).max() <= 1e-10, k


# ---- the C interface itself, through ctypes ----------------------------------------------------------------------

def _library(exp, tmp_path):
    so = tmp_path / f"lib{exp.name}.so"
    proc = subprocess.run([CC, "-std=c99", "-O2", "-shared", "-fPIC", str(exp.source), "-o", str(so), "-lm"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    lib = ctypes.CDLL(str(so))
    P = ctypes.POINTER(ctypes.c_double)
    getattr(lib, f"{exp.name}_fusion_init").argtypes = [ctypes.c_void_p, P]
    getattr(lib, f"{exp.name}_fusion_step").argtypes = [ctypes.c_void_p, ctypes.c_double, P, P, P]
    return lib


def _ptr(a):
    return None if a is None else np.ascontiguousarray(a, dtype=float).ctypes.data_as(ctypes.POINTER(ctypes.c_double))


class _Fusion:
    """The caller-allocated filter state in a buffer larger than any NAME_fusion here (its size is a C sizeof)."""

    def __init__(self, lib, name):
        self.buf = ctypes.create_string_buffer(1 << 20)
        self.init = lambda xhat0=None: getattr(lib, f"{name}_fusion_init")(self.buf, _ptr(xhat0))
        self._step = getattr(lib, f"{name}_fusion_step")

    def step(self, t, u, y, xhat):
        return self._step(self.buf, t, _ptr(u), _ptr(y), xhat.ctypes.data_as(ctypes.POINTER(ctypes.c_double)))

    def snapshot(self) -> bytes:
        return self.buf.raw


def _header_value(exp, macro):
    return float(re.search(rf"#define {exp.name.upper()}_{macro} (\S+)", exp.header.read_text()).group(1))


@needs_cc
def test_history_sized_from_min_interval_holds_and_overflow_is_an_error_that_changes_nothing(tmp_path):
    delays = {"gps": 0.2, "wheel": 0.05}
    exp = export_c(_ekf(CART3), tmp_path, name="hist", max_step=MAX_STEP, delays=delays, min_interval=0.01)
    # (floor(0.2 / 0.01) + 2) rows x (1 + 2 delays) + 1 + 2 late outputs + 1
    assert exp.history == _header_value(exp, "HISTORY") == 22 * 3 + 4
    lib = _library(exp, tmp_path)
    f = _Fusion(lib, "hist")
    assert f.init() == 0
    xhat = np.zeros(3)
    # the worst case it was sized for: rows exactly min_interval apart, every output arriving at every row
    for k in range(400):
        assert f.step(0.01 * k, [0.1], [0.1, 1.0, 1.0], xhat) == 0, k
    assert np.all(np.isfinite(xhat))
    # rows closer than min_interval: the history fills; the error leaves the filter as it was, and says so
    rc, k = 0, 0
    while rc == 0 and k < 1000:
        before = f.snapshot()
        rc = f.step(4.0 + 0.003 * k, [0.1], [0.1, 1.0, 1.0], xhat)
        k += 1
    assert rc == 4 and f.snapshot() == before   # HIST_EHISTORY, nothing changed
    # the same row can then be given without its late samples (one knot), or a later row after a wider gap
    assert f.step(4.0 + 0.003 * (k - 1), [0.1], [np.nan, np.nan, 1.0], xhat) == 0
    # the example program names the remedy
    exe = _build(exp, tmp_path)
    t = np.arange(0.0, 1.0, 0.004)
    proc = subprocess.run([exe], input=_csv(t, np.zeros_like(t), np.ones((t.size, 3))), capture_output=True, text=True)
    assert proc.returncode == 1 and "history is full" in proc.stderr and "smaller min_interval" in proc.stderr


@needs_cc
def test_errors_of_the_fusion_step(tmp_path):
    exp = export_c(_ekf(), tmp_path, name="errs", max_step=MAX_STEP, delays={"gps": 0.15}, min_interval=0.01)
    lib = _library(exp, tmp_path)
    f = _Fusion(lib, "errs")
    xhat = np.zeros(3)
    assert f.step(0.0, [0.0], [1.0, 1.0], xhat) == 5          # not initialised: ERRS_ESTATE
    assert f.init([1.0, 2.0, 3.0]) == 0
    assert f.step(0.0, [0.0], [np.nan, np.nan], xhat) == 0     # nothing arrived: the prior
    np.testing.assert_array_equal(xhat, [1.0, 2.0, 3.0])
    assert f.step(0.01, [0.0], [np.nan, 1.0], xhat) == 0
    before = f.snapshot()
    for t, u, y in ((0.01, [0.0], [1.0, 1.0]), (0.005, [0.0], [1.0, 1.0]), (np.nan, [0.0], [1.0, 1.0]),
                    (0.02, [np.inf], [1.0, 1.0]), (0.02, [0.0], [np.inf, 1.0])):
        assert f.step(t, u, y, xhat) == 1, (t, u, y)            # ERRS_EINPUT
        assert f.snapshot() == before
    # a state that overflows in the flow: non-finite, then the filter stays stopped until init
    assert f.init([1.7e308, 1.7e308, 0.0]) == 0 and f.step(0.0, [0.0], [np.nan, np.nan], xhat) == 0
    assert f.step(1.0, [0.0], [np.nan, np.nan], xhat) == 2     # ERRS_ENONFINITE
    assert f.step(1.1, [0.0], [np.nan, 1.0], xhat) == 5
    assert f.init() == 0 and f.step(0.0, [0.0], [np.nan, 1.0], xhat) == 0


@needs_cc
def test_the_fusion_state_is_the_callers_and_a_copy_is_a_snapshot(tmp_path):
    # no global state: two filters interleaved give what each gives alone; a copied struct continues identically
    system, rec, delays, h = _case("two_delays_and_none")
    exp = export_c(_ekf(system), tmp_path, name="two", max_step=MAX_STEP, delays=delays, min_interval=h)
    lib = _library(exp, tmp_path)
    a, b = _Fusion(lib, "two"), _Fusion(lib, "two")
    a.init(), b.init([0.0, 1.0, 0.3])
    xa, xb, outs = np.zeros(3), np.zeros(3), []
    for k in range(200):
        assert a.step(rec.t[k], rec.u[k], rec.y[k], xa) == 0 and b.step(rec.t[k], rec.u[k], rec.y[k], xb) == 0
        outs.append(xa.copy())
    c = _Fusion(lib, "two")
    ctypes.memmove(c.buf, a.buf, len(a.buf))
    xc = np.zeros(3)
    for k in range(200, 300):
        assert a.step(rec.t[k], rec.u[k], rec.y[k], xa) == 0 and c.step(rec.t[k], rec.u[k], rec.y[k], xc) == 0
        np.testing.assert_array_equal(xa, xc)
        outs.append(xa.copy())
    ref = nlobs.estimate({"ekf": _ekf(system)}, nlobs.Recording.from_arrays(system, rec.t[:300], rec.y[:300], rec.u[:300]),
                         delay=delays, on_missing="skip", max_step=MAX_STEP).observers["ekf"].xhat
    assert np.abs(np.array(outs) - ref).max() <= 1e-12


@needs_cc
def test_generated_fusion_source_is_dependency_free_and_compiles_strictly(tmp_path):
    exp = export_c(_ekf(CART3), tmp_path, name="strict_fus", max_step=MAX_STEP, delays={"gps": 0.2, "wheel": 0.05},
                   min_interval=0.01)
    src = exp.source.read_text()
    assert re.findall(r"#include\s*[<\"]([^>\"]+)[>\"]", src) == ["strict_fus.h", "math.h"]
    assert re.findall(r"#include", exp.header.read_text()) == []
    for banned in ("malloc", "calloc", "realloc", "free(", "printf", "FILE"):
        assert banned not in src, banned
    mutable = [ln for ln in src.splitlines() if re.match(r"\s*static\b", ln) and "(" not in ln and " const " not in ln]
    assert not mutable, f"mutable static (global) state: {mutable}"
    proc = subprocess.run([CC, "-std=c99", "-Os", "-Wall", "-Wextra", "-Wno-unused-parameter", "-pedantic", "-Werror",
                           "-c", str(exp.source), "-o", str(tmp_path / "s.o")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    header = exp.header.read_text()
    assert "#define STRICT_FUS_MAX_DELAY 0.2" in header and "#define STRICT_FUS_MIN_INTERVAL 0.01" in header
    assert "the estimate at t" in header and "arrived by t" in header
    assert "gps 0.2 s, wheel 0.05 s" in str(exp)


def test_bad_delay_arguments_are_named(tmp_path):
    d = _ekf()
    with pytest.raises(ValueError, match="`delays` names 'z', which is not an output; the outputs are gps, wheel"):
        export_c(d, tmp_path, delays={"z": 0.1}, min_interval=0.01)
    with pytest.raises(ValueError, match="the delay of 'gps' must be a finite number of seconds >= 0, got -0.1"):
        export_c(d, tmp_path, delays={"gps": -0.1}, min_interval=0.01)
    with pytest.raises(ValueError, match="give `min_interval` .* or `history`"):
        export_c(d, tmp_path, delays={"gps": 0.1})
    with pytest.raises(ValueError, match="`min_interval` must be a positive number"):
        export_c(d, tmp_path, delays={"gps": 0.1}, min_interval=0.0)
    with pytest.raises(ValueError, match="`history` must be a whole number of knots >= 3"):
        export_c(d, tmp_path, delays={"gps": 0.1}, history=2)
    with pytest.raises(ValueError, match="written only with measurement `delays`"):
        export_c(d, tmp_path, min_interval=0.01)
    lue = nlobs.design_luenberger(System(states=["x"], outputs=["y"], f=["-x"], h=["x"]), poles=[-2.0])
    with pytest.raises(ModelError, match="takes the output continuously; measurement delays are handled by the "
                                         "continuous-discrete observers"):
        export_c(lue, tmp_path, delays={"y": 0.1}, min_interval=0.01)
    osc = nlobs.System(states=["x1"], outputs=["y"], f=["0.9*x1"], h=["x1"], time="discrete", sample_time=0.1)
    with pytest.raises(ModelError, match="discrete-time model"):
        export_c(nlobs.design_ekf(osc, Q=[[1e-3]], R=[[1e-2]]), tmp_path, delays={"y": 0.2}, history=10)
    assert not any(tmp_path.iterdir())   # nothing written


def test_history_given_directly(tmp_path):
    exp = export_c(_ekf(), tmp_path, name="h7", delays={"gps": 0.15}, history=7)
    assert exp.history == 7 and exp.min_interval is None
    header = exp.header.read_text()
    assert "#define H7_HISTORY 7" in header and "#define H7_MIN_INTERVAL 0.0" in header
