"""How a model shows itself in the report, the gallery and ``nlobs report``: a map as x[k+1] = f(x[k], ...), a lookup
table by the name the model file declares, and the links of an example's references."""

from __future__ import annotations

from nlobs.examples import ExampleResult
from nlobs.report import example_section


def test_the_references_of_an_example_link_to_the_page_asked_for():
    r = ExampleResult(key="k", title="t", reference="Banks (1980), §3", summary="s", model="m")
    assert "href='#ref-003'" in example_section(r, plots=False)                     # the demo report's own list
    assert "href='../references.html#ref-003'" in example_section(r, plots=False, references="../references.html")


def test_code_between_backticks_shows_as_code_not_as_markdown():
    from nlobs.report import maths, prose

    assert prose("Copy it: `nlobs design cell.toml --run` ranks the kinds; $x^2$ a < b") == (
        "Copy it: <code>nlobs design cell.toml --run</code> ranks the kinds; " + maths("x^2") + " a &lt; b")
    assert prose("a lone ` stays") == "a lone ` stays"
