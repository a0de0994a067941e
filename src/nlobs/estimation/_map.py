"""Observers of a discrete-time model on a recording: one row per step of its map, each observer on its own, and the
fixed-interval smoothers of :mod:`._smooth_map` (the map's runs, :mod:`nlobs.simulate._discrete`, are below)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..design import KINDS
from ..errors import ModelError, PreconditionError
from ..observer import AbstractObserver
from ..simulate._discrete import check_map_grid, observers_on
from ..simulate._results import ObserverTrace, Run

__all__ = ["estimate_map", "map_smoothable"]


def map_smoothable() -> tuple[str, ...]:
    """The kinds whose run on a map has a fixed-interval smoother (:mod:`._smooth_map`), as their declarations say
    (``@kind(..., map_smoother=...)``): the extended RTS smoother for the kinds that predict as the EKF does, the
    unscented one for the sigma-point filters."""
    return tuple(name for name, k in KINDS.items() if k.map_smoother)


def estimate_map(obs: Mapping[str, AbstractObserver], recording: Any, t: np.ndarray, u: np.ndarray, y0: np.ndarray,
                 mask: np.ndarray, xhat0: Any, smooth: bool) -> Run:
    """Observers of a discrete-time model on a recording on its grid (one row per step; NaN: not measured), each on
    its own; `smooth`: the fixed-interval smoother of each (see :func:`map_smoothable`)."""
    if not all(o.system.is_discrete for o in obs.values()):
        raise ModelError("estimate: a discrete-time model's observers run alone (no continuous-time observers beside "
                         "them)")
    if smooth:
        smoothable = map_smoothable()
        bad = [k for k, o in obs.items() if o.design.method not in smoothable or o.design.covariance is None]
        if bad:
            pf = " (a particle filter's smoother, by backward simulation, is not available)" \
                if obs[bad[0]].design.method == "pf" else ""
            raise PreconditionError(f"smoothing: observer {bad[0]!r} is of kind {obs[bad[0]].design.method!r}; smoothers of "
                                    f"a discrete-time model exist for its {', '.join(smoothable)}{pf}")
    for o in obs.values():
        check_map_grid(o.system, t, f"recording ({recording.source})")
    traces, failures, extra = observers_on(obs, t, u, y0, mask, xhat0, innovations=True)
    traces = {name: _smoothed(obs[name], tr, t, u) if smooth else tr for name, tr in traces.items()}
    system = next(iter(obs.values())).system
    info: dict[str, Any] = {"source": recording.source, "time": "discrete", "sample_time": system.sample_time}
    if extra:
        info["particles"] = extra
    return Run(system.name, t, system.states, recording.input_names, recording.output_names, u,
               np.where(mask > 0, recording.y, np.nan), traces, x=recording.x, info=info,
               estimated_params=system.estimated_params, failures=failures)


def _smoothed(o: AbstractObserver, tr: ObserverTrace, t: np.ndarray, u: np.ndarray) -> ObserverTrace:
    """The trace with the smoothed means (Rauch-Tung-Striebel on the map, unscented for the sigma-point filters), the
    filtered ones kept as `filtered`."""
    from dataclasses import replace

    from ..engine import evaluate_many
    from ._smooth_map import rts_smooth_map

    n = o.system.n_states
    P = evaluate_many(o.design.covariance, tr.z).reshape(-1, n, n, order="F")
    xs, Ps = rts_smooth_map(o.design, t, u, tr.xhat, P)
    return replace(tr, xhat=xs, filtered=tr.xhat, smoothed_covariance=Ps)
