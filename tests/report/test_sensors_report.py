"""The sensor-selection section of the model report and its figure (issue 37)."""

from __future__ import annotations

import html
import re

import pytest

from nlobs.analysis import select_sensors
from nlobs.cli import main
from nlobs.model import loads_model
from nlobs.report._sensors import plotted_sets, sensors_figure, sensors_section

MODEL = """
name = "chain3"
states = ["a", "b", "c"]
outputs = ["y"]
[parameters]
r = { value = 0.5, unknown = true }
[dynamics]
a = "1 - a"
b = "a - r*b"
c = "b*b - c"
[output]
y = "c"
[simulation]
t_final = 5.0
dt = 0.01
x0 = [0.0, 0.3, 0.1]
sample_period = 0.25
[sensors.A]
expr = "a"
noise = 0.01
[sensors.B]
expr = "b"
noise = 0.01
cost = 2
[sensors.C]
expr = "c"
noise = 0.02
"""


@pytest.fixture(scope="module")
def sel():
    return select_sensors(loads_model(MODEL, path="chain3.toml"))


def test_section_lists_the_sets_their_bounds_and_the_figure(sel):
    text = sensors_section(sel)
    plain = html.unescape(re.sub(r"<[^>]+>", " ", text))
    assert "What to measure" in plain and "Minimal sets" in plain and "{C}" in plain
    assert "σ r(0)" in plain and text.count("<img") == 1 and "Liu, Slotine & Barabási (2013)" in plain
    assert "Sedoglavic (2002)" in plain


def test_figure_draws_one_bar_per_unknown_and_set(sel):
    fig = sensors_figure(sel)
    ax = fig.axes[0]
    sets = plotted_sets(sel)
    bars = [p for p in ax.patches]
    assert len(bars) == len(sets) * len(sel.unknowns)
    assert ax.get_yscale() == "log" and [t.get_text() for t in ax.get_xticklabels()] == list(sel.unknowns)


def test_report_command_adds_the_section_for_a_file_with_sensors(tmp_path, capsys):
    p = tmp_path / "chain3.toml"
    p.write_text(MODEL, encoding="utf-8")
    out = tmp_path / "rep"
    assert main(["report", str(p), "--kind", "ekf", "--no-run", "--out", str(out)]) == 0
    page = (out / "index.html").read_text(encoding="utf-8")
    assert "id='sensors'" in page and "href='#sensors'" in page and "Krener, K. Ide" in page
