"""Small helpers shared by the paper examples."""

from __future__ import annotations

from importlib import resources

import numpy as np
import scipy.linalg

from ..model import ModelFile, load_model

__all__ = ["bundled", "decay_rate", "linear_error_deviation"]


def bundled(name: str) -> ModelFile:
    """A model file shipped in ``nlobs/models``."""
    return load_model(resources.files("nlobs.models").joinpath(f"{name}.toml"))


def decay_rate(t: np.ndarray, e: np.ndarray, t1: float, t2: float) -> float:
    """Exponential decay rate between two times: ln(e(t1)/e(t2)) / (t2 - t1).

    Choosing t2 - t1 equal to a period of an oscillating mode cancels the oscillation.
    """
    i1, i2 = np.searchsorted(t, [t1, t2])
    return float(np.log(e[i1] / e[i2]) / (t[i2] - t[i1]))


def linear_error_deviation(t: np.ndarray, err: np.ndarray, M: np.ndarray) -> float:
    """max_t ‖err(t) - expm(M t) err(0)‖: how far an error trajectory is from the linear law e' = Me."""
    dev = 0.0
    for k in range(0, t.size, max(1, t.size // 200)):
        dev = max(dev, float(np.linalg.norm(err[k] - scipy.linalg.expm(M * t[k]) @ err[0])))
    return dev
