"""How a model shows itself in the report, the gallery and ``nlobs report``: a map as x[k+1] = f(x[k], ...), a lookup
table by the name the model file declares, and the links of an example's references."""

from __future__ import annotations

import re

import nlobs
from nlobs.examples import ExampleResult
from nlobs.model import Table
from nlobs.report import equations, example_section


def _rows(mathml: str) -> list[str]:
    return re.findall(r"<mtr>(.*?)</mtr>", mathml)


def test_a_map_shows_its_next_state_not_a_derivative():
    room = nlobs.System(states=["Ti"], f=["Ti + 0.1*(To - Ti)"], inputs=["To"], outputs=["y"], h=["Ti"],
                        time="discrete", sample_time=300.0)
    rows = _rows(equations(room))
    assert len(rows) == 2
    # Ti[k+1] on the left, as LaTeX writes it and latex2mathml converts it: T, i, then [k+1]; no accent (the dot)
    assert re.match(r"<mtd[^>]*><mi>T</mi><mi>i</mi><mo[^>]*>\[</mo><mi>k</mi><mo>&#x0002B;</mo><mn>1</mn><mo[^>]*>\]</mo>",
                    rows[0]), rows[0]
    assert "<mover>" not in rows[0] and "&#x002D9;" not in rows[0]
    flow = nlobs.System(states=["Ti"], f=["0.1*(To - Ti)"], inputs=["To"], outputs=["y"], h=["Ti"])
    first = _rows(equations(flow))[0]
    assert "<mover>" in first and "&#x002D9;" in first and "[" not in first     # a flow keeps its dot


def test_a_table_shows_by_its_declared_name():
    cop = Table("cop", [-10.0, 0.0, 10.0], [2.5, 3.2, 4.1])
    house = nlobs.System(states=["Tw"], f=["Tw + 300*(cop(To)*P - Tw)/1e6"], inputs=["To", "P"], outputs=["y"],
                         h=["Tw"], tables={"cop": cop}, time="discrete", sample_time=300.0)
    html = equations(house)
    assert "_table_" not in html and "digest" not in html
    assert re.search(r"<mo>cop</mo><mrow><mrow><mo[^>]*>&#x00028;</mo><mi>T</mi><mi>o</mi><mo[^>]*>&#x00029;</mo>", html), html
    # a derivative of the table (a filter's Jacobian) keeps the name, with its prime
    d = cop.function()(nlobs.model.symbol("To")).diff(nlobs.model.symbol("To"))
    assert nlobs.report.expr(d).count("cop") == 1 and "&#x02032;" in nlobs.report.expr(d)


def test_the_references_of_an_example_link_to_the_page_asked_for():
    r = ExampleResult(key="k", title="t", reference="Banks (1980), §3", summary="s", model="m")
    assert "href='#ref-003'" in example_section(r, plots=False)                     # the demo report's own list
    assert "href='../references.html#ref-003'" in example_section(r, plots=False, references="../references.html")


def test_code_between_backticks_shows_as_code_not_as_markdown():
    from nlobs.report import maths, prose

    assert prose("Copy it: `nlobs design cell.toml --run` ranks the kinds; $x^2$ a < b") == (
        "Copy it: <code>nlobs design cell.toml --run</code> ranks the kinds; " + maths("x^2") + " a &lt; b")
    assert prose("a lone ` stays") == "a lone ` stays"


def test_a_parameter_in_scientific_notation_shows_as_a_power_of_ten():
    # {v:g} gives "4e+06", which MathML shows as the letter e plus 06 (latex2mathml reads it as maths)
    wall = nlobs.System(states=["T"], f=["(To - T)/(C*R)"], inputs=["To"], outputs=["y"], h=["T"],
                        params={"C": 4.0e6, "R": 0.002, "k": 1.5e-7, "n": 3.0})
    note = re.search(r"<p class='note'>parameters: (.*)</p>", equations(wall)).group(1)
    assert "<mi>e</mi>" not in note and "&#x0002B;" not in note, note
    assert note.count("<msup><mn>10</mn>") == 2, note     # C = 4·10⁶, k = 1.5·10⁻⁷; R and n as they are
    assert "<mn>4</mn><mo>&#x000B7;</mo><msup><mn>10</mn><mrow><mn>6</mn></mrow></msup>" in note, note
    assert "<mn>0.002</mn>" in note and "<mn>3</mn>" in note, note
