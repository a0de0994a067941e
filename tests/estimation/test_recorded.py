"""Observers on recorded data: CSV, missing samples, irregular times, holds."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import DataError, ModelError, Noise, Recording, Sampling, ShapeError, System, design_ekf, design_output_injection, estimate, simulate

PEND = System(states=["x1", "x2"], f=["x2", "-9.81*sin(x1) - 0.5*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"], name="pend")


@pytest.fixture(scope="module")
def recorded():
    run = simulate(PEND, t_final=5.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": "sin(t)"}, noise=Noise.gaussian(0.005),
                   sampling=Sampling(0.01), seed=2)
    return run, Recording.from_run(run, every=10)


def test_csv_round_trip_with_states(tmp_path, recorded):
    run, rec = recorded
    path = tmp_path / "data.csv"
    header = "t,u,y,x1,x2"
    np.savetxt(path, np.column_stack([rec.t, rec.u, rec.y, rec.x]), delimiter=",", header=header, comments="")
    back = Recording.from_csv(path, PEND)
    assert np.allclose(back.y, rec.y) and np.allclose(back.x, rec.x) and back.source == str(path)
    res = estimate(design_output_injection(PEND, poles=[-4, -5]), back)
    assert res.metrics().final_error < 0.05


def test_csv_errors_name_line_and_column(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("t,u\n0,1\n")
    with pytest.raises(DataError, match="lacks column\\(s\\) y"):
        Recording.from_csv(p, PEND)
    p.write_text("t,u,y\n0,1,2\n0.1,abc,2\n")
    with pytest.raises(DataError, match="line 3, column 'u': 'abc' is not a number"):
        Recording.from_csv(p, PEND)
    p.write_text("t,u,y\n0,1,2\n0.1,1\n")
    with pytest.raises(DataError, match="line 3: 2 field"):
        Recording.from_csv(p, PEND)
    with pytest.raises(DataError, match="cannot read"):
        Recording.from_csv(tmp_path / "missing.csv", PEND)


def test_nan_is_rejected_with_row_and_column_or_skipped(recorded):
    run, rec = recorded
    y = rec.y.copy()
    y[[40, 41, 200], 0] = np.nan
    holey = Recording.from_arrays(PEND, rec.t, y, rec.u, rec.x)
    d = design_ekf(PEND, Q=np.eye(2) * 1e-3, R=[[2.5e-5]])
    with pytest.raises(DataError, match=r"output 'y' is missing \(NaN\) at row 40 \(t = 0.4\), 3 missing value\(s\)"):
        estimate(d, holey)
    full = estimate(d, rec)
    skipped = estimate(d, holey, on_missing="skip")
    # up to the first gap the runs are identical; after it the estimate stays close
    assert np.array_equal(skipped.observers["ekf"].xhat[:40], full.observers["ekf"].xhat[:40])
    assert not np.allclose(skipped.observers["ekf"].xhat[41], full.observers["ekf"].xhat[41])
    assert skipped.metrics().rms_error < 0.02
    u = rec.u.copy()
    u[5] = np.inf
    with pytest.raises(DataError, match="input/state 'u' is inf at row 5"):
        estimate(d, Recording.from_arrays(PEND, rec.t, rec.y, u))


def test_skipped_sample_predicts_without_correction(recorded):
    _, rec = recorded
    y = rec.y.copy()
    y[10, 0] = np.nan
    d = design_ekf(PEND, Q=np.eye(2) * 1e-3, R=[[2.5e-5]])
    res = estimate(d, Recording.from_arrays(PEND, rec.t, y, rec.u), on_missing="skip")
    from nlobs import Observer

    obs = Observer(d)
    z9 = res.observers["ekf"].z[9]
    predicted = obs.step(rec.t[9], z9, rec.t[10] - rec.t[9], rec.u[9], y[9])
    assert np.allclose(res.observers["ekf"].z[10], predicted, atol=1e-12)


def test_irregular_times_and_time_checks(recorded):
    run, rec = recorded
    keep = np.sort(np.random.default_rng(0).choice(rec.t.size, 300, replace=False))
    keep[0] = 0
    irregular = Recording.from_arrays(PEND, rec.t[keep], rec.y[keep], rec.u[keep], rec.x[keep])
    res = estimate(design_output_injection(PEND, poles=[-4, -5]), irregular, max_step=1e-3)
    assert res.metrics().final_error < 0.05 and res.info["substeps"] >= 10
    with pytest.raises(DataError, match="time does not increase at row 2"):
        Recording.from_arrays(PEND, [0, 1, 1, 2], [0, 0, 0, 0], [0, 0, 0, 0])
    with pytest.raises(ShapeError, match="pass `u`"):
        Recording.from_arrays(PEND, [0, 1], [0, 0])


def test_linear_hold_beats_zero_order_hold_on_a_fast_output():
    sys = System(states=["x1", "x2"], f=["x2**2", "c"], outputs=["y"], h=["x1"], params={"c": 0.5}, name="toy")
    from nlobs import design_augmented

    d = design_augmented(sys, T=["x1", "x2", "x2**2"], A=[[0, 0, 1], [0, 0, 0], [0, "2*c", 0]], b=[0, "c", 0],
                         C=[[1, 0, 0]], left_inverse=["w1", "w2"], poles=[-1, -1.5, -2])
    run = simulate(sys, t_final=12.0, dt=1e-3, x0=[2.0, -2.0])
    rec = Recording.from_run(run, every=20)
    zoh = estimate(d, rec, max_step=1e-3).metrics().final_error
    lin = estimate(d, rec, max_step=1e-3, hold="linear").metrics().final_error
    assert lin < zoh / 50


def test_estimate_argument_checks(recorded):
    _, rec = recorded
    other = System(states=["a", "b"], f=["b", "-a"], outputs=["z"], h=["a"])
    with pytest.raises(ModelError, match="expects outputs \\['z'\\]"):
        estimate(design_output_injection(other, poles=[-1, -2]), rec)
    with pytest.raises(ValueError, match="`hold` must be"):
        estimate(design_output_injection(PEND, poles=[-1, -2]), rec, hold="cubic")  # type: ignore[arg-type]
    with pytest.raises(ModelError, match="at least one observer"):
        estimate({}, rec)


def test_multi_rate_outputs_from_a_csv(tmp_path):
    """Two outputs sampled at different rates: the slow one is empty between its samples."""
    two = System(states=["p", "v"], f=["v", "-p - 0.3*v + u"], inputs=["u"], outputs=["yp", "yv"], h=["p", "v"], name="two")
    run = simulate(two, t_final=6.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": "cos(t)"}, noise=Noise.gaussian([0.01, 0.05]),
                   sampling=Sampling(0.01), seed=4)
    rec = Recording.from_run(run, every=10)
    path = tmp_path / "multi.csv"
    with path.open("w") as fh:
        fh.write("t,u,yp,yv,p,v\n")
        for k, (t, u, y, x) in enumerate(zip(rec.t, rec.u, rec.y, rec.x)):
            yv = repr(float(y[1])) if k % 5 == 0 else ""  # velocity sensor at 20 Hz, position at 100 Hz
            fh.write(f"{float(t)!r},{float(u[0])!r},{float(y[0])!r},{yv},{float(x[0])!r},{float(x[1])!r}\n")
    multi = Recording.from_csv(path, two)
    assert np.isnan(multi.y[1:5, 1]).all() and np.isfinite(multi.y[:, 0]).all()
    d = design_ekf(two, Q=np.eye(2) * 1e-3, R=np.diag([1e-4, 2.5e-3]))
    res = estimate(d, multi, on_missing="skip")
    # the same observer fed sample by sample online agrees (the masks follow the NaNs)
    from nlobs import Observer

    online = Observer(d).start()
    xs = np.array([online.update(t, u=u, y=y) for t, y, u in zip(multi.t, multi.y, multi.u)])
    assert np.max(np.abs(xs - res.observers["ekf"].xhat)) < 1e-12
    assert res.metrics().rms_error < 0.02


def test_noise_gain(recorded):
    run, _ = recorded
    d = design_output_injection(PEND, poles=[-2, -3])
    noisy = simulate(PEND, {"oi": d}, t_final=5.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": "sin(t)"}, noise=Noise.gaussian(0.01), seed=1)
    sel = noisy.t >= 4.0
    expected = np.sqrt(np.mean(noisy.error_norm("oi")[sel] ** 2)) / np.sqrt(np.mean((noisy.y - noisy.y_true)[sel] ** 2))
    assert noisy.noise_gain("oi") == pytest.approx(expected)
    assert "noise_gain" in noisy.summary_dict()["observers"]["oi"]
    with pytest.raises(ValueError, match="no measurement noise"):
        simulate(PEND, {"oi": d}, t_final=1.0, dt=1e-3, x0=[1.0, 0.0]).noise_gain("oi")


def test_linear_hold_interpolates_the_input_too():
    """A pure integrator x' = u observed exactly through an 'observer' that integrates u: with a linear
    hold the offline estimate integrates the piecewise-linear input exactly (trapezoid)."""
    integ = System(states=["x"], f=["u"], inputs=["u"], outputs=["y"], h=["x"], name="integrator")
    from nlobs import design_custom

    d = design_custom(integ, states=["xi"], flow=["u"])  # open-loop copy of the model
    t = np.linspace(0.0, 1.0, 11)
    u = t**2
    rec = Recording.from_arrays(integ, t, np.zeros_like(t), u)
    lin = estimate(d, rec, hold="linear").observers["custom"].xhat[:, 0]
    zoh = estimate(d, rec, hold="zoh").observers["custom"].xhat[:, 0]
    trapezoid = np.r_[0.0, np.cumsum((u[1:] + u[:-1]) / 2 * np.diff(t))]
    left = np.r_[0.0, np.cumsum(u[:-1] * np.diff(t))]
    assert np.allclose(lin, trapezoid, atol=1e-14) and np.allclose(zoh, left, atol=1e-14)


# -- hostile and real-world files: every case ends in a result or an error naming the cause -----------------


def _write(path, header, rows):
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(header + "\n")
        for r in rows:
            fh.write(",".join(repr(float(v)) for v in r) + "\n")


def test_csv_encodings_duplicates_and_column_mapping(tmp_path, recorded):
    _, rec = recorded
    rows = np.column_stack([rec.t, rec.u, rec.y])
    plain = tmp_path / "plain.csv"
    _write(plain, "t,u,y", rows)
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())  # Excel's "CSV UTF-8"
    back = Recording.from_csv(bom, PEND)
    assert np.array_equal(back.y, rec.y) and np.array_equal(back.u, rec.u)
    latin = tmp_path / "latin.csv"
    latin.write_bytes(plain.read_bytes().replace(b"t,u,y", "t,u,y,température".encode("latin-1"), 1).replace(b"\n", b",1\n"))
    with pytest.raises(DataError, match=r"latin\.csv: not a UTF-8 text file \(byte 0xe9 at offset"):
        Recording.from_csv(latin, PEND)
    dup = tmp_path / "dup.csv"
    _write(dup, "t,y,u,y", np.column_stack([rec.t, rec.y, rec.u, rec.y + 1]))
    with pytest.raises(DataError, match=r"column 'y' appears twice in the header \(columns 2 and 4\)"):
        Recording.from_csv(dup, PEND)
    named = tmp_path / "named.csv"
    _write(named, "time,level,u", np.column_stack([rec.t, rec.y, rec.u]))
    with pytest.raises(DataError, match=r"lacks column\(s\) t, y.*--column CSV=MODEL"):
        Recording.from_csv(named, PEND)
    mapped = Recording.from_csv(named, PEND, columns={"time": "t", "level": "y"})
    assert np.array_equal(mapped.y, rec.y) and np.array_equal(mapped.t, rec.t)
    with pytest.raises(DataError, match="the column mapping names 'tim', which is not in the header"):
        Recording.from_csv(named, PEND, columns={"tim": "t"})
    with pytest.raises(DataError, match="sends 'level' to 'z', which is not t, an output, an input or a state"):
        Recording.from_csv(named, PEND, columns={"level": "z"})
    with pytest.raises(DataError, match=r"appears twice in the header after the column mapping"):
        Recording.from_csv(plain, PEND, columns={"u": "y"})
    # a text column the model does not use is ignored; a long bad cell is cut in the message
    extra = tmp_path / "extra.csv"
    extra.write_text("t,u,y,note\n0,0,1,start\n0.1,0,0.9,x\n")
    assert Recording.from_csv(extra, PEND).t.size == 2
    extra.write_text("t,u,y\n0,0,1\n0.1,0," + "9" * 500 + "z\n")
    with pytest.raises(DataError, match=r"is not a number") as info:
        Recording.from_csv(extra, PEND)
    assert len(str(info.value)) < 300


def test_huge_values_and_times_stop_with_the_sample_instead_of_nan_estimates(recorded):
    _, rec = recorded
    d = design_ekf(PEND, Q=np.eye(2) * 1e-3, R=[[2.5e-5]])
    y = rec.y.copy()
    y[100] = 1e308
    from nlobs import FiniteEscapeError

    with pytest.raises(FiniteEscapeError, match=r"observer 'ekf' .* from the sample at t = 1 \(row 100; y = 1e\+308"):
        estimate(d, Recording.from_arrays(PEND, rec.t, y, rec.u))
    t = rec.t.copy()
    t[0] = -1e300
    with pytest.raises(DataError, match=r"^recording \(t0 file\): observer .* from t = -1e\+300 to 0\.01 \(length 1e\+300\) "
                                        r"would need 3e\+300 RK4 steps"):   # the recording is named (issue 10)
        estimate(design_output_injection(PEND, poles=[-2, -3]), Recording.from_arrays(PEND, t, rec.y, rec.u, source="t0 file"))
    with pytest.raises(DataError, match="overflows"):
        Recording.from_arrays(PEND, [-1.7e308, 1.7e308], [0, 0], [0, 0])


def test_estimate_options_are_checked(recorded):
    _, rec = recorded
    d = design_output_injection(PEND, poles=[-2, -3])
    for bad in (0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="`max_step` must be a positive number"):
            estimate(d, rec, max_step=bad)
    assert estimate(d, rec, max_step=np.float32(0.005)).info["substeps"] >= 2  # NumPy numbers are numbers
    with pytest.raises(TypeError, match="`recording` must be an nlobs.Recording"):
        estimate(d, {"t": rec.t})  # type: ignore[arg-type]
    y = rec.y.copy()
    y[3] = np.nan
    with pytest.raises(DataError, match=r"on_missing='skip' \(command line: --skip-missing\)"):
        estimate(d, Recording.from_arrays(PEND, rec.t, y, rec.u))


def test_one_row_and_overlong_field_errors_name_the_file(tmp_path):
    # issue 10: every CSV error names the file (and, where it can, the line) and what to change
    one = tmp_path / "one.csv"
    one.write_text("t,u,y\n0,0,1\n")
    with pytest.raises(ShapeError, match=r"^recording \(.*one\.csv\): a recording needs at least 2 samples \(rows of data\), got 1"):
        Recording.from_csv(one, PEND)
    long = tmp_path / "long.csv"
    long.write_text("t,u,y\n0," + "1" * 200_000 + ",1\n0.1,0,1\n")
    with pytest.raises(DataError, match=r"long\.csv, line 2: a field is longer than 131072 characters.*delimiter") as e:
        Recording.from_csv(long, PEND)
    assert len(str(e.value)) < 300
