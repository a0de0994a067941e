"""Anything a user passes as an observer, made runnable: an observer, a design, or a model file's configuration.

Above both runtime families (:mod:`._base`, the ODE observers, and :mod:`._particles`, the particle loop
that builds on it), so that neither imports the other's caller.
"""

from __future__ import annotations

from typing import Any

from ..design import ObserverDesign, design_from_config
from ..model import ObserverConfig
from ._base import AbstractObserver, Observer
from ._particles import ParticleDesign, ParticleObserver

__all__ = ["as_observer"]


def as_observer(obj: Any, name: str | None = None) -> AbstractObserver:
    """An observer from an observer, a design, or a model file's observer configuration
    (:class:`nlobs.model.ObserverConfig`, designed here by :func:`nlobs.design.design_from_config`)."""
    if isinstance(obj, AbstractObserver):
        return obj
    if isinstance(obj, ObserverDesign):
        return Observer(obj, name)
    if isinstance(obj, ParticleDesign):
        return ParticleObserver(obj, name)
    if isinstance(obj, ObserverConfig):
        d = design_from_config(obj)
        return ParticleObserver(d, name or obj.name) if isinstance(d, ParticleDesign) else Observer(d, name or obj.name)
    raise TypeError(f"expected an observer or an ObserverDesign (from a design_* function), or a model file's "
                    f"ObserverConfig ([observers.NAME]), got {type(obj).__name__}")
