"""The report's table of observer kinds (issue 38, item 3c): kinds that fail for one shared reason are one row naming
them; the kinds that apply, and those with a reason of their own, keep a row each."""

from __future__ import annotations

import nlobs
from nlobs.advise import advise
from nlobs.report import write_model_report
from nlobs.report._model_report import kind_rows

RICKER = nlobs.System(states=["N"], f=["N*exp(r*(1 - N/K)) - u"], inputs=["u"], outputs=["y"], h=["N"],
                      params={"r": 1.2, "K": 10.0}, time="discrete", sample_time=1.0, name="ricker")


def test_a_map_lists_the_continuous_time_kinds_on_one_row(tmp_path):
    from nlobs.model import SimulationConfig

    adv = advise(RICKER, simulation=SimulationConfig(t_final=40.0, x0=(3.0,), inputs={"u": "0.5"}), progress=False)
    rows = kind_rows(adv)
    continuous = [c.kind for c in adv.candidates if c.why == "continuous-time only (the model is discrete-time)"]
    assert len(continuous) >= 20
    shared = [r for r in rows if r["why"] == "continuous-time only (the model is discrete-time)"]
    assert len(shared) == 1 and shared[0]["kind"] == f"{len(continuous)} kinds: " + ", ".join(continuous)
    # every other kind keeps its own row, in the registry's order; the shared row comes after them
    alone = [r["kind"] for r in rows[:-1]]
    assert alone == [c.kind for c in adv.candidates if c.kind not in continuous] and len(rows) == len(alone) + 1
    assert {"ekf", "ukf", "srukf", "srekf", "iekf", "pf"} <= set(alone)
    html = write_model_report(adv, tmp_path / "r").read_text()
    assert html.count("continuous-time only (the model is discrete-time)") == 1 and ">pf<" in html


def test_an_unobservable_state_blocks_the_kinds_in_one_row():
    # y = x1 with x2 moving alone: x2 never reaches the output, every full-state observer is blocked for that reason
    blind = nlobs.System(states=["x1", "x2"], f=["-x1", "-2*x2"], outputs=["y"], h=["x1"], name="blind")
    adv = advise(blind, progress=False)
    rows = kind_rows(adv)
    reasons = [c.why for c in adv.candidates]
    top = max(set(reasons), key=reasons.count)
    assert reasons.count(top) > 5 and sum(r["why"] == top for r in rows) == 1
    assert len(rows) == len(set((c.status, c.why) for c in adv.candidates if c.status != "applies")) + \
        sum(c.status == "applies" for c in adv.candidates)
