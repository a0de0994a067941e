"""The report's building blocks, the demo report, and how results show themselves (terminal, notebook)."""

from __future__ import annotations

import io
import json
import re

import numpy as np
import pytest

import nlobs
from nlobs._progress import ProgressBar, as_progress
from nlobs.examples import Claim, ExampleResult, find_example
from nlobs.references import full_citation
from nlobs.report import bibliography, equations, example_section, expr, maths, plain, prose, run_demo, table

FILE_NAME = re.compile(r"\d{3}_[0-9a-f]{16}\.txt")


@pytest.fixture(scope="module")
def run():
    pend = nlobs.System(states=["x1", "x2"], f=["x2", "-9.81*sin(x1) - 0.5*x2 + u"], inputs=["u"], outputs=["y"],
                        h=["x1"], name="pendulum")
    oi = nlobs.design_output_injection(pend, poles=[-2, -3])
    return nlobs.simulate(pend, {"oi": oi}, t_final=3, dt=1e-3, x0=[1, 0], inputs={"u": "sin(t)"})


# -- maths ------------------------------------------------------------------------------------

def test_maths_is_mathml_with_superscripts_and_matrices():
    m = maths(r"e^{-(\varepsilon - K)t}")
    assert m.startswith("<math") and "<msup>" in m and "^" not in m
    J = expr([[-3 * nlobs.model.symbol("x1") ** 2 - 1, 0], [0, 1]])
    assert "<mtable>" in J and "**" not in J


def test_prose_renders_dollar_maths_and_escapes_the_rest():
    html = prose(r"a <b> & $x_1^2$ end")
    assert "&lt;b&gt; &amp; " in html and "<msubsup>" in html and "$" not in html


def test_plain_turns_maths_into_readable_unicode():
    assert plain(r"below $\|e(0)\| e^{-(\varepsilon - K)t}$") == "below ‖e(0)‖ e^(-(ε - K)t)"
    assert plain(r"$\hat{x}_2 \to x_2$, $\lambda_{\min}$") == "x̂₂ → x₂, λmin"


def test_equations_put_the_dot_on_the_letter_and_list_parameters():
    pend = nlobs.System(states=["x1", "x2"], f=["x2", "-a*sin(x1)"], outputs=["y"], h=["x1"], params={"a": 9.81})
    html = equations(pend)
    assert html.count("<mtr>") == 3 and "<mover>" in html and "9.81" in html and "sin" in html


def test_table_left_aligns_text_and_renders_dashes():
    html = table([{"run": "noisy σ=0.01", "t": None, "e": 1.23456}], [("run", "run"), ("t", "t"), ("e", "e")])
    assert "<td class=l>noisy σ=0.01</td>" in html and "<td>—</td>" in html and "<td>1.23</td>" in html


def test_bibliography_gives_authors_title_venue_year_with_anchors():
    html = bibliography("as shown by Yi, Ortega & Zhang (2019), eq. 5")
    assert "id='ref-004'" in html and "On state observers for nonlinear systems" in html and "2019" in html
    assert "doi.org/10.1109/TAC.2018.2839526" in html
    assert bibliography("no citation here") == ""


def test_example_section_has_no_internal_notes_and_renders_maths(run):
    r = ExampleResult(key="k", title="A $\\dot x = -x$ example", reference="Banks (1980), §3", summary="s",
                      model="m", runs={"noise-free": run}, table=[{"run": "noise-free", "observer": "oi",
                      "convergence_time": None, "rms_error": 1e-3, "final_error": 2e-3}],
                      claims=[Claim("holds $e^{-t}$", True, "d")], systems={"the model": nlobs.System(
                          states=["x"], f=["-x"], outputs=["y"], h=["x"])})
    html = example_section(r)
    assert "<math" in html and "$" not in html and "href='#ref-003'" in html
    assert re.search(r'<img alt="k noise-free" width="\d+" height="\d+"', html)
    assert example_section(r, plots=False).count("<img") == 0


def test_the_demo_report_names_every_paper_and_no_internal_file(tmp_path):
    out = io.StringIO()
    outcome = run_demo(tmp_path, only=["002-pendulum"], progress=False, stream=out)  # a former key still works
    html = outcome.report.read_text(encoding="utf-8")
    assert full_citation("002").split(",")[0] in html and "On observability &amp; observer forms" in html
    assert "id='references'" in html
    for internal in ("conversion", "papers README", "garbled", ".txt"):
        assert internal not in html, internal
    assert not FILE_NAME.search(html)
    text = out.getvalue()
    assert "wall time" in text and "never" not in text.replace("never leaves", "")
    assert max(len(line) for line in text.splitlines() if not line.startswith("report:")) <= 90


def test_example_keys_are_short_and_former_keys_still_select():
    from nlobs.examples import ALIASES, EXAMPLES

    assert all(len(k) <= 12 for k in EXAMPLES)
    assert find_example("004-cuk").key == "cuk" and set(ALIASES.values()) <= set(EXAMPLES)
    with pytest.raises(KeyError, match="available: aug-toy"):
        find_example("nope")


# -- results in the terminal and in a notebook ------------------------------------------------

def test_summary_prints_as_before_shows_as_html_and_converts_to_pandas(run):
    s = run.summary()
    text = str(s)
    assert text.splitlines()[0].startswith("pendulum: t in [0, 3]") and "oi" in text and "conv. time" in text
    html = s._repr_html_()
    assert "<table>" in html and "<th>RMS (last 20%)</th>" in html
    df = s.to_pandas()
    m = run.metrics("oi")
    assert df.loc[0, "observer"] == "oi" and df.loc[0, "rms_error"] == m.rms_error
    assert "&lt;" not in html.split("<table>")[0] or True


def test_reprs_are_compact_and_every_result_has_an_html_form(run):
    assert len(repr(run)) < 300 and "array(" not in repr(run) and "samples=3001" in repr(run)
    assert run._repr_html_().count("<table>") == 1
    cert = next(iter([nlobs.design_output_injection(
        nlobs.System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1"]), poles=[-1, -2]).certificate]))
    assert repr(cert).startswith("Certificate(") and "holds" in repr(cert) and len(repr(cert)) < 400
    assert "<pre" in cert._repr_html_()
    rep = nlobs.analyze(nlobs.System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1"]))
    assert repr(rep).startswith("ObservabilityReport(") and "observable=True" in repr(rep)
    assert "<pre" in rep._repr_html_()


def test_montecarlo_result_repr_and_summary():
    sys_ = nlobs.System(states=["x"], f=["-x"], outputs=["y"], h=["x"], name="decay")
    oi = nlobs.design_luenberger(sys_, poles=[-3])
    mc = nlobs.montecarlo(sys_, {"l": oi}, t_final=1, dt=1e-2, x0=np.linspace(1, 2, 5)[:, None], engine="vm")
    assert repr(mc).startswith("MonteCarloResult(") and "runs=5" in repr(mc) and len(repr(mc)) < 300
    assert "<table>" in mc._repr_html_() and "unsettled" in str(mc.summary())
    assert list(mc.summary().to_pandas()["runs"]) == [5]


# -- progress ---------------------------------------------------------------------------------

class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_draws_nothing_when_not_a_terminal_and_ends_its_line_on_a_terminal():
    quiet = io.StringIO()
    bar = ProgressBar("work", stream=quiet)
    for f in (0.1, 0.5, 1.0):
        bar(f)
    assert quiet.getvalue() == ""
    tty = _Tty()
    bar = ProgressBar("work", stream=tty)
    for f in (0.1, 0.5, 1.0):
        bar(f)
    assert "100%" in tty.getvalue() and tty.getvalue().endswith("\n")
    assert as_progress(False, "x") is None and as_progress(print, "x") is print


# -- nlobs kinds ------------------------------------------------------------------------------

def test_kinds_lists_every_kind_and_one_kind_its_options_and_references(capsys):
    from nlobs.cli import main
    from nlobs.design import KINDS

    assert main(["kinds"]) == 0
    listing = capsys.readouterr().out
    assert all(re.search(rf"^{re.escape(k)} ", listing, flags=re.M) for k in KINDS)
    assert main(["kinds", "ekf", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    opts = {o["name"]: o for o in info["options"]}
    assert opts["Q"]["required"] and opts["mode"]["default"] == "continuous-discrete"
    assert "Process-noise intensity" in opts["Q"]["description"]
    assert [r["cite"] for r in info["references"]][:1] == ["Jazwinski (1970)"]
    assert main(["kinds", "nope"]) == 1
    assert "no observer kind 'nope'" in capsys.readouterr().err


def test_help_texts_cite_no_paper_numbers():
    from nlobs.cli import _parser

    p = _parser()
    sub = next(a for a in p._actions if a.__class__.__name__ == "_SubParsersAction")
    texts = [a.help or "" for a in sub._choices_actions]
    for parser in sub.choices.values():
        texts += [parser.description or ""] + [a.help or "" for a in parser._actions]
    bad = [t for t in texts if re.search(r"(?<![\w.])00[0-4](?![\w-])", t) or FILE_NAME.search(t)]
    assert not bad, bad


def test_plots_label_units_when_the_model_declares_them_and_keep_fonts_readable(run):
    import dataclasses

    from nlobs.simulate._plot import FONT

    fig = dataclasses.replace(run, info={**run.info, "units": {"x1": "rad", "t": "s"}}).plot(width=5.1, title="T")
    axes = fig.get_axes()
    assert axes[0].get_ylabel() == "x1 [rad]" and axes[1].get_ylabel() == "x2" and axes[-1].get_xlabel() == "t [s]"
    assert min(FONT.values()) >= 9 and axes[0].yaxis.get_ticklabels()[0].get_fontsize() >= 9
    assert run.plot().get_axes()[0].get_ylabel() == "x1"  # no units declared: names only
    styles = {line.get_linestyle() for line in fig.get_axes()[0].get_lines()[1:]}
    assert styles  # estimates are drawn dashed/dotted over the grey truth
