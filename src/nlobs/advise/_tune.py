"""``nlobs.tune``: :func:`nlobs.learning.tune` from a model file (or its path) and a recording (or its CSV), starting,
when the file configures no observer of the kind, from the advisor's automatic tuning of that kind (as ``nlobs tune``
and ``nlobs estimate --observer KIND`` do)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import PreconditionError
from ..model import ModelFile, load_model
from ..estimation import Recording
from ..learning._tune_noise import TuneResult
from ..learning._tune_noise import tune as _tune

__all__ = ["tune"]


def tune(design_or_model: Any, recording: Any, *, observer: str = "ekf", **options: Any) -> TuneResult:
    """Tune the noise covariances of a Kalman-family filter on a recording; see :func:`nlobs.learning.tune`.

    Besides what :func:`nlobs.learning.tune` takes, `design_or_model` may be a model file's path and `recording` a CSV
    path; a model file that configures no observer named `observer` nor one of that kind starts from the advisor's
    automatic tuning of the kind `observer` (its Q, R, P0 and x̂0 are the start and the reference scales)."""
    if isinstance(design_or_model, (str, Path)):
        design_or_model = load_model(design_or_model)
    if isinstance(recording, (str, Path)):
        if not isinstance(design_or_model, ModelFile):
            raise TypeError("tune: a recording given as a path needs a model file (its outputs and inputs name the "
                            "columns); read it with nlobs.Recording.from_csv(path, system)")
        recording = Recording.from_csv(recording, design_or_model)
    if isinstance(design_or_model, ModelFile):
        mf = design_or_model
        configured = mf.observers
        if observer not in configured and sum(c.kind == observer for c in configured.values()) != 1:
            from ._advise import advise

            adv = advise(mf, kinds=[observer], run=False, progress=False)
            cand = next((c for c in adv.candidates if c.kind == observer), None)
            if cand is None or cand.design is None or not cand.applies:
                raise PreconditionError(f"tune: {mf.path} configures no observer {observer!r} and the advisor cannot "
                                        f"tune the kind {observer!r} for this model"
                                        + (f": {cand.why}" if cand is not None else ""))
            design_or_model = cand.design
    return _tune(design_or_model, recording, observer=observer, **options)

