"""Sensor selection on a navigation model (issue 44 item 2): the 16-state strapdown INS of benchmarks/models/car_nav.toml
(IMU inputs) with nine candidates of a car (GNSS x, y, z at 2 Hz, wheel speed at 50 Hz, a three-axis magnetometer, a
barometer and a vertical-speed aid at 10 Hz), on the first 20 s of its drive. The bounds of every observable set must
be finite, the pool's log det finite and at least every subset's (information only adds: F_S ⪯ F_pool), each
candidate sampled at its own period. The log dets are recomputed here with NumPy from the candidates' matrices."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from nlobs.analysis import select_sensors
from nlobs.model import loads_model

ROOT = Path(__file__).resolve().parents[2]
PERIODS = {"gnss_x": 0.5, "gnss_y": 0.5, "gnss_z": 0.5, "wheel": 0.02, "mag_x": 0.1, "mag_y": 0.1, "mag_z": 0.1,
           "baro": 0.1, "vspeed": 0.1}
EXPRS = {"gnss_x": ("px", 1.0), "gnss_y": ("py", 1.0), "gnss_z": ("pz", 2.0), "wheel": ("ks*(r11*vx + r21*vy + r31*vz)", 0.05),
         "mag_x": ("r11*mE + r21*mN + r31*mU", 0.005), "mag_y": ("r12*mE + r22*mN + r32*mU", 0.005),
         "mag_z": ("r13*mE + r23*mN + r33*mU", 0.005), "baro": ("pz", 0.5), "vspeed": ("vz", 0.1)}


def nav_text(t_final: float) -> str:
    """car_nav.toml over [0, t_final] with the nine candidates as [sensors] tables (benchmarks/bench_sensors.py runs
    it over the whole 120 s). Every minimal set holds gnss_x, gnss_y and wheel (the only candidates that see the sink
    components {px}, {py}, {ks}) and gnss_z or baro (the two that see {pz})."""
    text = (ROOT / "benchmarks" / "models" / "car_nav.toml").read_text(encoding="utf-8")
    assert "\nt_final = 120.0\n" in text
    text = text.replace("\nt_final = 120.0\n", f"\nt_final = {float(t_final)!r}\n")
    for name, (expr, noise) in EXPRS.items():
        text += f'\n[sensors.{name}]\nexpr = "{expr}"\nnoise = {noise}\nperiod = {PERIODS[name]}\n'
    return text


@pytest.fixture(scope="module")
def nav():
    return select_sensors(loads_model(nav_text(20.0), path="car_nav_sensors.toml"))


def test_every_observable_set_of_the_navigation_pool_has_finite_bounds(nav):
    assert nav.run["periods"] == pytest.approx(PERIODS)
    assert {tuple(sorted(m)) for m in nav.minimal_sets} == {("gnss_x", "gnss_y", "gnss_z", "wheel"),
                                                            ("baro", "gnss_x", "gnss_y", "wheel")}, nav.minimal_sets
    for s in nav.sets:
        if s.observable:
            assert all(math.isfinite(v) and v > 0 for v in s.crb.values()), (s.sensors, s.crb)
            assert math.isfinite(s.log_det) and math.isfinite(s.unobservability_index), s


def test_the_pool_scores_at_least_every_subset(nav):
    F = nav.fisher.information
    names = list(nav.fisher.names)
    pool = next(s for s in nav.sets if "pool" in s.roles)
    sign, full = np.linalg.slogdet(F.sum(axis=0))
    assert sign > 0 and math.isfinite(full) and pool.log_det == pytest.approx(full, rel=1e-9)
    worst = -np.inf
    for r in range(1, len(names)):
        for S in itertools.combinations(range(len(names)), r):
            sg, ld = np.linalg.slogdet(F[list(S)].sum(axis=0))
            if sg > 0:
                worst = max(worst, ld)
    assert worst <= full + 1e-9 * abs(full), (worst, full)
    for s in nav.sets:
        assert s.log_det <= pool.log_det + 1e-9 * abs(pool.log_det), s
