"""An NLP estimator too large for a screening is not built for one, and the advice says so (issue 43, large models:
a moving-horizon estimator of the 24-state INS took 0.9 GB and 8 s to build before the screening's budget could stop
it, for no verdict)."""

import importlib

import nlobs
from nlobs.advise import _advise

SMALL = """
name = "small"
states = ["x1", "x2"]
outputs = ["y"]
[dynamics]
x1 = "x2"
x2 = "-x1 - 0.3*x2"
[output]
y = "x1"
[simulation]
t_final = 4.0
dt = 0.01
x0 = [1.0, 0.0]
noise = { y = 1e-2 }
sample_period = 0.05
"""


def test_an_nlp_window_above_the_limit_is_not_screened_and_says_why(tmp_path, monkeypatch):
    rank = importlib.import_module("nlobs.advise._rank")
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    model = nlobs.load_model(path)
    screened = []
    real = rank._without_diverging
    monkeypatch.setattr(rank, "_without_diverging", lambda ctx, designs, *a: (screened.append(set(designs)),
                                                                           real(ctx, designs, *a))[1])
    adv = nlobs.advise(model, kinds=["mhe"])
    mhe = next(c for c in adv.candidates if c.kind == "mhe")
    assert mhe.applies and "not screened: its window" not in mhe.why and screened == [{"mhe"}]   # 2 states: screened
    window = int(mhe.design.certificate.values["horizon (intervals)"])
    monkeypatch.setattr(rank, "SCREEN_NLP_SIZE", 2 * window - 1)
    screened.clear()
    adv = nlobs.advise(model, kinds=["mhe"])
    mhe = next(c for c in adv.candidates if c.kind == "mhe")
    assert mhe.applies and screened == []
    assert (f"its start was not screened: its window of {window} samples of 2 states ({2 * window} unknowns) is more "
            f"than a screening builds ({2 * window - 1})") in mhe.why
    assert _advise.screen is rank.screen
