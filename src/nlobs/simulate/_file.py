"""A model file's ``[simulation]`` table as the arguments of :func:`nlobs.simulate`.

``nlobs.simulate(model_file)`` simulates the file's plant (with ``true_parameters``) and its
observers on its ``[simulation]`` defaults; any keyword given overrides the file. The CLI uses
the same conversion (one place turns the table into Noise, ProcessNoise and Sampling objects).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..design import check_identifiable
from ..errors import ModelError
from ..model import ModelFile
from ._options import Noise, ProcessNoise, Sampling

__all__ = ["file_arguments", "observers_of"]


def file_arguments(mf: ModelFile, observers: Any = None, **given: Any) -> dict[str, Any]:
    """The keyword arguments of :func:`nlobs.simulate` for the model file `mf`.

    Parameters
    ----------
    mf : ModelFile
    observers : optional
        Observers as :func:`nlobs.simulate` takes them, or a list of names configured in the
        file; default: every observer of the file.
    **given
        Arguments of :func:`nlobs.simulate`; those given (not None) override the file.

    Raises
    ------
    ModelError
        When neither the file nor `given` sets the horizon or the initial state.
    PreconditionError
        When an unknown parameter is not identifiable with the file's input signals (checked
        before anything runs).
    """
    cfg = mf.simulation
    out = {k: v for k, v in given.items() if v is not None}
    if observers is None:
        observers = dict(mf.observers)
    elif isinstance(observers, str) or (isinstance(observers, (list, tuple)) and observers and all(isinstance(o, str) for o in observers)):
        names = [observers] if isinstance(observers, str) else list(observers)
        missing = [n for n in names if n not in mf.observers]
        if missing:
            raise ModelError(f"{mf.path}: no observer {missing[0]!r}; configured: {', '.join(mf.observers) or '(none)'}")
        observers = {n: mf.observers[n] for n in names}
    out["observers"] = observers
    out["plant"] = mf.true_system
    if "t_final" not in out:
        if cfg.t_final is None:
            raise ModelError(f"{mf.path}: no horizon: give t_final (--t-final) or set [simulation] t_final")
        out["t_final"] = cfg.t_final
    if mf.system.is_discrete:
        out.setdefault("dt", None)          # a map steps by its sample_time
    else:
        out.setdefault("dt", cfg.dt if cfg.dt is not None else 1e-3)
    if "x0" not in out:
        if cfg.x0 is None:
            raise ModelError(f"{mf.path}: no initial state: give x0 or set [simulation] x0 = [...] "
                             f"({mf.system.n_states} numbers: {', '.join(mf.system.states)})")
        out["x0"] = cfg.x0
    if "inputs" not in out:
        out["inputs"] = dict(cfg.inputs)
        if mf.unknown_params and observers:
            # the structural test again, on the input signals this simulation uses (u = 0 may not excite k)
            signals = {k: cfg.inputs.get(k, 0) for k in mf.system.inputs}
            check_identifiable(mf.observer_system, inputs=signals if signals else "generic",
                               where=f"{mf.path} [simulation]")
    if "noise" not in out and (cfg.noise or cfg.noise_bound):
        out["noise"] = Noise.per_output(dict(cfg.noise), dict(cfg.noise_bound))
    if "process_noise" not in out and cfg.process_noise:
        out["process_noise"] = ProcessNoise(dict(cfg.process_noise))
        drifting = [k for k in cfg.process_noise if k in mf.unknown_params]
        if drifting and "plant" not in given and len(out["x0"]) == mf.system.n_states:
            # a random walk on an unknown parameter: the plant carries the unknown parameters as states (as the observers
            # estimating them do), starting at their true values
            unknown = list(mf.unknown_params)
            out["plant"] = mf.true_system.augmented(unknown)
            out["x0"] = (*out["x0"], *(float(mf.true_system.params[k]) for k in unknown))
    if "delay" not in out and cfg.delay:
        out["delay"] = dict(cfg.delay)
    if "sampling" not in out and cfg.sample_period:
        out["sampling"] = Sampling(cfg.sample_period)
        if out.get("dt"):  # before anything runs: the file's periods against the step this run uses
            from ..model._toml import period_multiple_problem

            sp = cfg.sample_period
            for key, period in ({f"sample_period.{k}": v for k, v in sp.items()} if isinstance(sp, Mapping)
                                else {"sample_period": sp}).items():
                why = period_multiple_problem(period, float(out["dt"]))
                if why:
                    dt_from = (f"[simulation] dt = {cfg.dt:g}" if cfg.dt is not None and float(out["dt"]) == cfg.dt else
                               "the step given for this run" if cfg.dt is not None else
                               "[simulation] dt is not set: the default step 1e-3, or the step given for this run")
                    raise ModelError(f"{mf.path}, key `simulation.{key}`: {why} ({dt_from})")
    if "seed" not in out and cfg.seed is not None:
        out["seed"] = cfg.seed
    return out


def observers_of(observers: Any) -> Any:
    """A model file passed where observers are expected stands for its configured observers."""
    return dict(observers.observers) if isinstance(observers, ModelFile) else observers
