"""Lookup tables (issue 21): declared in a file, evaluated by CasADi's interpolant (exact derivatives), checked with
one-line errors, treated as generic smooth functions by the analysis, and a run that leaves them says so."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.interpolate as si

import nlobs
from nlobs.errors import ModelFileError
from nlobs.model._tables import table_calls

X = [0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 1.0]
Y = [3.0, 3.3, 3.45, 3.55, 3.61, 3.65, 3.69, 3.75, 3.83, 3.93, 4.04, 4.1, 4.2]

CELL = f"""
name = "cell"
states = ["SOC", "v1"]
inputs = ["i"]
outputs = ["v"]
[parameters]
Q = 7200.0
R0 = 0.05
R1 = 0.03
C1 = 1500.0
[tables.ocv]
x = {X}
y = {Y}
method = "cubic"
[dynamics]
SOC = "-i/Q"
v1 = "-v1/(R1*C1) + i/C1"
[output]
v = "ocv(SOC) - v1 - R0*i"
[simulation]
t_final = 2400
dt = 0.1
x0 = [0.9, 0.0]
inputs = {{ i = "1.5 + 1.0*sin(0.01*t) + max(0, 2*sin(0.05*t))" }}
noise = {{ v = 0.005 }}
sample_period = 1.0
seed = 3
[observers.ekf]
kind = "ekf"
Q = [[1e-10, 0.0], [0.0, 1e-6]]
R = [[2.5e-5]]
P0 = [[0.09, 0.0], [0.0, 0.01]]
xhat0 = [0.6, 0.0]
"""


def _table(mf):
    return table_calls(list(mf.system.h))[0].table


def test_cubic_is_the_not_a_knot_spline_and_linear_is_np_interp():
    mf = nlobs.loads_model(CELL)
    s = np.linspace(0, 1, 401)
    np.testing.assert_allclose(_table(mf)(s), si.make_interp_spline(X, Y, k=3)(s), atol=1e-12)
    lin = _table(nlobs.loads_model(CELL.replace('method = "cubic"', 'method = "linear"')))
    np.testing.assert_allclose(lin(s), np.interp(s, X, Y), atol=1e-14)


def test_outside_the_breakpoints_hold_or_extrapolate():
    hold = _table(nlobs.loads_model(CELL.replace('method = "cubic"', 'method = "linear"')))
    np.testing.assert_allclose(hold(np.array([-0.5, 1.5])), [3.0, 4.2])
    ext = _table(nlobs.loads_model(CELL.replace('method = "cubic"', 'method = "linear"\noutside = "extrapolate"')))
    np.testing.assert_allclose(ext(np.array([-0.05, 1.05])), [3.0 - 0.3, 4.2 + 0.1], atol=1e-12)   # end slopes 6 and 2


def test_the_model_differentiates_through_the_table_exactly():
    mf = nlobs.loads_model(CELL)
    f, h = nlobs.engine.compile_system(mf.system).bind()
    import casadi as ca

    x = ca.SX.sym("x", 2)
    H = ca.Function("H", [x], [ca.jacobian(h(0.0, x, ca.DM([1.0])), x)])
    for soc in (0.13, 0.5, 0.77):
        slope = si.make_interp_spline(X, Y, k=3).derivative()(soc)
        np.testing.assert_allclose(np.asarray(H([soc, 0.0])).ravel(), [slope, -1.0], atol=1e-10)


def test_an_ekf_started_30_percent_off_finds_the_soc():
    run = nlobs.simulate(nlobs.loads_model(CELL))
    e = run.observers["ekf"].xhat[:, 0] - run.x[:, 0]
    assert np.sqrt(np.mean(e[run.t >= 600] ** 2)) < 0.02 and "notes" not in run.info


def test_analysis_treats_the_table_as_a_generic_function_and_refuses_the_global_check():
    mf = nlobs.loads_model(CELL)
    r = nlobs.analyze(mf.system, global_check=True)
    assert r.observable and any("generic smooth function" in n for n in r.notes)
    assert any("global check" in n and "lookup tables" in n for n in r.notes) and r.global_check is None
    flat = nlobs.loads_model(CELL.replace(f"y = {Y}", f"y = {[3.7] * len(Y)}"))   # a flat table: still generic (say so)
    assert any("derivatives are non-zero" in n for n in nlobs.analyze(flat.system).notes)


def test_a_run_that_leaves_the_table_says_so():
    run = nlobs.simulate(nlobs.loads_model(CELL.replace("t_final = 2400", "t_final = 6000")))
    assert any("leaves the table `ocv`'s range [0, 1]" in n and "below 0" in n for n in run.info["notes"])
    assert "note: the run leaves the table" in str(run.summary())


@pytest.mark.parametrize("table, message", [
    ("x = [0.0, 0.5, 0.4, 1.0]\ny = [1, 2, 3, 4]", "`x` must be strictly increasing; x[2] = 0.4 follows 0.5"),
    ("x = [0.0, 1.0]\ny = [1.0, nan]", "`y` has a value that is not finite at index (1,)"),
    ("x = [0.0, 0.5, 1.0]\ny = [1, 2]", "`y` must have shape (3,)"),
    ("x = [0.0]\ny = [1]", "`x` needs at least 2 breakpoints"),
    ("x = [0.0, 1.0]\ny = [1, 2]\nmethod = \"quadratic\"", '`method` must be "linear" or "cubic"'),
    ("x = [0.0, 1.0]\ny = [1, 2]\nmethod = \"cubic\"", "a cubic table needs at least 4 breakpoints"),
    ("x = [0.0, 1.0]\ny = [1, 2]\nslope = 3", "unknown key `slope`"),
    ("x = [0.0, 1.0]\nz = [0.0, 1.0]\ny = [1, 2]", "`y` must have shape (2, 2)"),
])
def test_bad_tables_are_one_line_errors_naming_the_table(table, message):
    text = CELL.replace(f'[tables.ocv]\nx = {X}\ny = {Y}\nmethod = "cubic"', f"[tables.ocv]\n{table}")
    with pytest.raises(ModelFileError) as e:
        nlobs.loads_model(text)
    assert "key `tables.ocv`" in str(e.value) and message in str(e.value) and "\n" not in str(e.value)


def test_a_table_too_large_and_a_name_clash_are_refused():
    big = list(range(nlobs.model.MAX_TABLE_POINTS + 1))
    with pytest.raises(ModelFileError, match="limit of 100,000"):
        nlobs.loads_model(CELL.replace(f"x = {X}\ny = {Y}", f"x = {big}\ny = {big}"))
    with pytest.raises(ModelFileError, match="already a state"):
        nlobs.loads_model(CELL.replace("[tables.ocv]", "[tables.SOC]"))


def test_a_2d_table():
    text = CELL.replace(f'[tables.ocv]\nx = {X}\ny = {Y}\nmethod = "cubic"',
                        "[tables.ocv]\nx = [0.0, 1.0]\nz = [0.0, 10.0]\ny = [[3.0, 3.1], [4.0, 4.3]]").replace(
        "ocv(SOC)", "ocv(SOC, i)")
    tb = _table(nlobs.loads_model(text))
    # bilinear: at (0.5, 5): mean of the four corners
    assert tb(np.array(0.5), np.array(5.0)) == pytest.approx((3.0 + 3.1 + 4.0 + 4.3) / 4)
    with pytest.raises(ModelFileError, match="takes 2 positional argument"):
        nlobs.loads_model(text.replace("ocv(SOC, i)", "ocv(SOC)"))


def test_the_model_report_plots_each_table_against_its_argument(tmp_path):
    import base64
    import io
    import re

    from PIL import Image

    from nlobs.advise import advise
    from nlobs.report import write_model_report

    mf = nlobs.loads_model(CELL.replace("[simulation]", '[units]\nSOC = "1"\nv = "V"\n[simulation]'))
    path = write_model_report(advise(mf, kinds=["ekf"], run=False), tmp_path / "r")
    page = path.read_text(encoding="utf-8")
    assert "<h3 id='tables'>Lookup tables</h3>" in page
    assert "ocv: 1-D, 13 values on [0, 1], cubic" in page and "hold outside the breakpoints" in page
    png = re.search(r'alt="lookup table ocv"[^>]*src="data:image/png;base64,([^"]+)"', page).group(1)
    assert Image.open(io.BytesIO(base64.b64decode(png))).size[0] > 300
