"""How the demo words a claim of a paper that nlobs checked and found not true (a finding about the paper, with
why), apart from a claim of nlobs that fails (a broken install or a bug)."""

from __future__ import annotations

import io
from pathlib import Path

from nlobs.examples import Claim, ExampleResult
from nlobs.report import example_section
from nlobs.report._demo import _print_summary


def _result(*claims: Claim) -> ExampleResult:
    return ExampleResult(key="cuk", title="t", reference="Yi, Ortega & Zhang (2019)", summary="s", model="m",
                         claims=claims)


HOLDS = Claim("every observer converges", True)
PAPER_HOLDS = Claim("KKLO is the least sensitive to noise — v4", True, "KKLO 0.01, PEBO 0.2", paper=True, why="unused")
NOT_TRUE = Claim("KKLO is the least sensitive to noise — i1", False, "KKLO 0.02, HGO (linear) 0.01", paper=True,
                 why="HGO (linear) is less noise-sensitive than KKLO in i1 (the notes)")


def _printed(r: ExampleResult) -> str:
    out = io.StringIO()
    _print_summary([r], [], out, Path("index.html"), 1.0, 1.0)
    return out.getvalue()


def test_a_claim_of_the_paper_found_not_true_is_said_so_with_why_and_is_no_failure():
    r = _result(HOLDS, PAPER_HOLDS, NOT_TRUE)
    assert r.ok and r.tally == "claims 2/3 hold, 1 of the paper's checked and not true"
    assert NOT_TRUE.word == "not true" and str(NOT_TRUE).startswith("[not true] ") and "why: HGO (linear)" in str(NOT_TRUE)
    text = _printed(r)
    assert "FAIL" not in text and "see the report" not in text
    flat = " ".join(text.split())
    assert ("NOT TRUE, checked: the paper's claim \"KKLO is the least sensitive to noise — i1\" "
            "(KKLO 0.02, HGO (linear) 0.01). Why: HGO (linear) is less noise-sensitive than KKLO in i1 (the notes)") in flat
    assert "noise — v4" not in flat                           # a claim that holds is not listed (the path printed may hold "v4")
    html = example_section(r, plots=False)
    assert "FAILS" not in html and "<span class='warn'>not true</span> — paper: KKLO" in html
    assert "Why: HGO (linear) is less noise-sensitive" in html and html.count("Why:") == 1


def test_a_claim_of_nlobs_that_does_not_hold_still_fails():
    broken = Claim("every observer converges", False, "KKLO: 3.1 A")
    r = _result(broken, NOT_TRUE)
    assert not r.ok and r.tally == "claims 0/2 hold, 1 of the paper's checked and not true"
    assert broken.word == "FAILS" and "FAILS: every observer converges (KKLO: 3.1 A)" in _printed(r)
    assert "<span class='fail'>FAILS</span>" in example_section(r, plots=False)


def test_the_convergence_note_states_the_rule_the_table_was_measured_by():
    # the examples' tables come from Run.metrics, which judges each state in its own units; the demo's note and each
    # example's section described the norm's band, a rule no longer used
    r = ExampleResult(key="cuk", title="t", reference="r", summary="s", model="m", claims=(HOLDS,),
                      table=[{"run": "a", "observer": "ekf", "convergence_time": 1.0, "rms_error": 0.1, "final_error": 0.1}])
    flat = " ".join(_printed(r).split())
    assert "every state's error" in flat and "‖x̂ − x‖ stays within a band" not in flat
    import html as html_lib

    html = " ".join(html_lib.unescape(example_section(r, plots=False)).split())
    assert "every state's error" in html and "‖x̂ − x‖ stays within a band" not in html
