"""The model file's [sensors.NAME] tables (issue 37): what they hold, and one-line errors that name the table."""

from __future__ import annotations

import pytest

from nlobs.errors import ModelFileError
from nlobs.model import load_model, loads_model, symbol

BASE = """
states = ["x", "v"]
outputs = ["y"]
[parameters]
k = 2.0
[definitions]
e = "x*v"
[dynamics]
x = "v"
v = "-k*x"
[output]
y = "x"
"""

GOOD = BASE + """
[sensors.A]
expr = "x + e"
noise = 0.1
[sensors.B]
expr = "k*v"
noise = 0.2
cost = 3
"""


def test_sensor_tables_are_read_in_order_with_definitions_expanded():
    mf = loads_model(GOOD, path="m.toml")
    assert list(mf.sensors) == ["A", "B"]
    a, b = mf.sensors["A"], mf.sensors["B"]
    x, v, k = symbol("x"), symbol("v"), symbol("k")
    assert a.expr == x + x * v and a.noise == 0.1 and a.cost == 1.0 and a.text == "x + e"
    assert b.expr == k * v and b.cost == 3.0
    assert loads_model(BASE, path="m.toml").sensors == {}


@pytest.mark.parametrize("text, key, message", [
    (GOOD.replace('"x + e"', '"x + w"'), "sensors.A.expr", "unknown name `w`"),                   # unknown name
    (GOOD.replace("noise = 0.2", "noise = 0"), "sensors.B.noise", "must be positive"),            # non-positive noise
    (GOOD.replace("noise = 0.2", "noise = -1"), "sensors.B.noise", "must be positive"),
    (GOOD + '[sensors.A]\nexpr = "v"\nnoise = 1\n', "sensors.A", "declared twice"),            # duplicate name
    (BASE + '[sensors]\nA = { expr = "x", noise = 1 }\nA = { expr = "v", noise = 2 }\n', "sensors.A", "declared twice"),
    (BASE + "[sensors]\n", "sensors", "declares no candidate sensor"),                            # empty pool
    (GOOD.replace("noise = 0.1\n", ""), "sensors.A", "`noise` is required"),
    (GOOD.replace('expr = "k*v"\n', ""), "sensors.B", "`expr` is required"),
    (GOOD.replace("cost = 3", "cost = -3"), "sensors.B.cost", "must be non-negative"),
    (GOOD.replace("cost = 3", "gain = 3"), "sensors.B.gain", "unknown key `gain`"),
    (BASE + "[sensors]\nA = 3\n", "sensors.A", "must be a table with `expr` and `noise`"),
    (GOOD.replace("noise = 0.1", 'noise = "small"'), "sensors.A.noise", "finite number"),
])
def test_bad_sensor_tables_get_one_line_errors_naming_the_table(text, key, message):
    with pytest.raises(ModelFileError) as e:
        loads_model(text, path="m.toml")
    assert e.value.key == key and message in str(e.value)
    assert "\n" not in str(e.value) and f"key `{key}`" in str(e.value)


def test_a_file_on_disk_with_sensors(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text(GOOD, encoding="utf-8")
    assert set(load_model(p).sensors) == {"A", "B"}
