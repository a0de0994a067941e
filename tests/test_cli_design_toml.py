"""`nlobs design --toml` pastes back (issue 38, item 3b): for every bundled model and every kind that applies, the tables
printed, pasted into the model file, load and design the same observer (the same equations, evaluated at the observer's
start and after an update, to 1e-9 relative; a particle filter's settings; an NLP estimator's certificate values). Also
a discrete-time heat-pump model with a COP table and an unknown resistance whose MHE has a one-sided bound, the case of
the issue."""

from __future__ import annotations

import re
import tomllib

import numpy as np
import pytest

from nlobs.advise import advise
from nlobs.cli import main
from nlobs.cli._design import to_toml
from nlobs.design import ObserverDesign, ParticleDesign
from nlobs.design import designs_from_file
from nlobs.model import load_model
from nlobs.model._library import bundled_names, bundled_path

#: The sensor-fusion models (13-24 states, multi-rate, delayed): the advisor's screening of every kind takes 15-45 s
#: there, so their round trip covers the Kalman family (the kinds that apply to them) with a few of them.
FUSION = {"quadrotor": ["ekf", "iekf", "srekf"], "ins16": ["ekf", "iekf"], "ins24": ["ekf", "iekf"]}

NUMBER = re.compile(r"-?\d+\.\d+(?:e[-+]?\d+)?")


def noisy(text):
    """The numbers written with 16-17 significant digits of which a run of 8 zeros or nines leaves one or two at the
    end: a short number with the rounding noise of a computation, as the issue saw them (0.010000000000000002,
    2.2499999999999996e-08; written 0.01 and 2.25e-08 now)."""
    out = []
    for m in NUMBER.finditer(text):
        digits = m.group().split("e")[0].replace("-", "").replace(".", "").lstrip("0")
        if len(digits) >= 16 and re.search(r"(0{8,}|9{8,})\d{1,2}$", digits):
            out.append(m.group())
    return out

HEAT_PUMP = '''
name = "heat_pump"
description = "A house heated by an air-to-water heat pump, one step every 5 minutes; COP from a table; resistance unknown"
time = "discrete"
sample_time = 300.0
states = ["Ti", "Tw"]
inputs = ["P", "To"]
outputs = ["yi", "yw"]
[parameters]
Ci = 4.0e6
Cw = 1.5e6
Rw = 0.002
Rinf = { value = 0.006, unknown = true }
Ts = 300.0
[tables.cop]
x = [10.0, 20.0, 30.0, 40.0, 50.0, 60.0]
y = [6.2, 4.7, 3.7, 3.0, 2.5, 2.1]
method = "cubic"
[dynamics]
Ti = "Ti + Ts*((Tw - Ti)/Rw - (Ti - To)/Rinf)/Ci"
Tw = "Tw + Ts*(cop(Tw - To)*P - (Tw - Ti)/Rw)/Cw"
[output]
yi = "Ti"
yw = "Tw"
[simulation]
t_final = 172800.0
x0 = [19.0, 30.0]
inputs = { P = "1800 + 900*sin(2*pi*t/86400 + 1)", To = "2 + 5*sin(2*pi*t/86400 - 2)" }
noise = { yi = 0.05, yw = 0.1 }
process_noise = { Ti = 0.005, Tw = 0.01 }
true_parameters = { Rinf = 0.0045 }
seed = 3
'''


def _close(a, b, what, atol=1e-14):
    a, b = np.asarray(a), np.asarray(b)
    if np.iscomplexobj(a) or np.iscomplexobj(b):
        _close(np.real(a), np.real(b), what, atol)
        a, b = np.imag(a), np.imag(b)
    a, b = a.astype(float), b.astype(float)
    assert a.shape == b.shape, what
    scale = np.maximum(np.abs(a), 1e-300)
    bad = ~((np.abs(a - b) <= 1e-9 * scale + atol) | (np.isnan(a) & np.isnan(b)))
    assert not bad.any(), f"{what}: {a[bad][:3]} against {b[bad][:3]}"


def _same_value(a, b, what):
    """Numbers (arrays, nested mappings and lists of them) to 1e-9 relative; anything else as text."""
    if isinstance(a, dict) and isinstance(b, dict):
        assert a.keys() == b.keys(), what
        for k in a:
            _same_value(a[k], b[k], f"{what}[{k}]")
        return
    try:
        x, z = np.asarray(a), np.asarray(b)
        numeric = x.dtype.kind in "biufc" and z.dtype.kind in "biufc"
    except (TypeError, ValueError):
        numeric = False
    if numeric:
        _close(x, z, what)
    else:
        assert str(a) == str(b), what


def same_observer(a, b, what):
    assert type(a) is type(b) and a.method == b.method, what
    if isinstance(a, ParticleDesign):
        for field in ("xhat0", "P0", "Q", "R"):
            _close(getattr(a, field), getattr(b, field), f"{what}: {field}")
        assert (a.particles, a.scheme, a.threshold, a.seed, a.max_step) == (b.particles, b.scheme, b.threshold, b.seed,
                                                                              b.max_step), what
        return
    assert isinstance(a, ObserverDesign) and a.z_names == b.z_names, what
    _close(a.xhat0, b.xhat0, f"{what}: xhat0")
    z = np.asarray(a.initial(a.xhat0), dtype=float).ravel()
    _close(z, np.asarray(b.initial(b.xhat0), dtype=float).ravel(), f"{what}: z(0)")
    _same_value(dict(a.certificate.values), dict(b.certificate.values), f"{what}: certificate")
    if a.needs_mx:    # an NLP estimator: its equations embed a solver; the certificate and z(0) say it all
        return
    s = a.system
    t, u = 0.1 * s.sample_time if s.is_discrete else 0.1, np.full(s.n_inputs, 0.1)
    y, m = np.asarray(a.output(t, z, u, np.zeros(s.n_outputs)), dtype=float).ravel()[:0], np.ones(s.n_outputs)
    y = np.full(s.n_outputs, 0.05)
    for fn in ("flow", "output"):
        _close(getattr(a, fn)(t, z, u, y), getattr(b, fn)(t, z, u, y), f"{what}: {fn} at z(0)")
    if a.update is not None:
        za, zb = a.update(t, z, u, y, m), b.update(t, z, u, y, m)
        # the iterated EKF stops its Gauss-Newton steps below an absolute step of 1e-10 (design_iekf's tol): numbers
        # written short (within 4 ulps, cli._design.ULPS) can stop it one step apart, within that tolerance
        _close(za, zb, f"{what}: update at z(0)", atol=1e-10)
        _close(a.output(t, za, u, y), b.output(t, za, u, y), f"{what}: output after an update")


def _round_trip(adv, text_of_file, path, observers=()):
    pasted = to_toml(adv, existing=observers)
    tables = tomllib.loads(pasted).get("observers", {})
    path.write_text(text_of_file + "\n" + pasted + "\n", encoding="utf-8")
    mf = load_model(path)
    designs = designs_from_file(mf, list(tables))
    by_kind = {c.kind: c for c in adv.applicable}
    for name, table in tables.items():
        same_observer(by_kind[table["kind"]].design, designs[name], f"{adv.model}: [observers.{name}]")
    return pasted, tables


@pytest.mark.parametrize("name", bundled_names())
def test_design_toml_of_every_bundled_model_pastes_back(name, tmp_path):
    mf = load_model(name)
    adv = advise(mf, run=False, progress=False, kinds=FUSION.get(name))
    pasted, tables = _round_trip(adv, bundled_path(name).read_text(encoding="utf-8"), tmp_path / f"{name}.toml",
                                 mf.observers)
    own = [c for c in adv.applicable if c.why.startswith("designed from the file's")]
    assert len(tables) + len(own) == len(adv.applicable)   # every kind that applies: pasted, or the file's own table
    assert "None" not in pasted and not noisy(pasted), noisy(pasted)


def test_the_heat_pump_map_round_trips_through_the_command_line(tmp_path, capsys):
    path = tmp_path / "heat_pump.toml"
    path.write_text(HEAT_PUMP, encoding="utf-8")
    assert main(["design", str(path), "--toml"]) == 0
    printed = capsys.readouterr().out
    tables = tomllib.loads(printed)["observers"]
    # the three defects: a bound without an upper side, digits of rounding noise, an ODE mode for a map
    assert tables["mhe"]["bounds"]["Rinf"][1] == np.inf and "None" not in printed
    assert "R = [[0.0025, 0.0], [0.0, 0.01]]" in printed and not noisy(printed) and noisy("0.010000000000000002")
    assert "mode" not in tables["ekf"]
    assert {"ekf", "ukf", "srukf", "srekf", "iekf", "pf", "mhe"} <= set(tables)
    adv = advise(load_model(path), run=False, progress=False)
    _round_trip(adv, HEAT_PUMP, tmp_path / "pasted.toml")
    (tmp_path / "twice.toml").write_text(HEAT_PUMP + printed, encoding="utf-8")
    again = to_toml(adv, existing=load_model(tmp_path / "twice.toml").observers)   # the names are taken: new ones
    assert "[observers.ekf_design]" in again and tomllib.loads(HEAT_PUMP + printed + again)
