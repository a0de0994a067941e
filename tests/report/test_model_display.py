"""How a model shows itself in the report, the gallery and ``nlobs report``: a map as x[k+1] = f(x[k], ...), a lookup
table by the name the model file declares, and the links of an example's references."""

from __future__ import annotations

from nlobs.examples import ExampleResult
from nlobs.report import example_section


def test_the_references_of_an_example_link_to_the_page_asked_for():
    r = ExampleResult(key="k", title="t", reference="Banks (1980), §3", summary="s", model="m")
    assert "href='#ref-003'" in example_section(r, plots=False)                     # the demo report's own list
    assert "href='../references.html#ref-003'" in example_section(r, plots=False, references="../references.html")
