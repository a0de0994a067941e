"""nlobs: nonlinear observability analysis and state-observer design.

The data flow, one way: ``model`` (System, forms, model files) -> ``engine`` (CasADi
compilation, integrators, C) -> ``algebra`` -> ``analysis`` -> ``design`` (one function per method,
returning an ObserverDesign with its evidence) -> ``observer`` (the runnable contract) ->
``simulate`` (plant + observers, noise, sampling, Monte Carlo) -> ``estimation`` (observers and smoothers on
recorded data) -> ``learning`` (parameters and noise fitted to recordings) -> ``advise`` -> ``report`` -> ``cli``.

Every public name below is loaded when it is first used (PEP 562): ``import nlobs`` itself imports
nothing heavy (SymPy, CasADi, SciPy and matplotlib load with the first model, run or plot), so
that every ``nlobs`` command starts in a fraction of a second.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import Any

from ._version import __version__ as __version__

#: Public name -> (module, attribute); attribute None: the module itself.
_LAZY: dict[str, tuple[str, str | None]] = {
    **{name: (f".{name}", None) for name in ("analysis", "design", "engine", "model", "observer", "interop", "errors",
                                             "references", "algebra", "estimation", "learning")},
    **{name: (".design", name) for name in ("Certificate", "ObserverDesign", "DREM", "GD", "Gradient", "LeastSquares",
                                            "LinearRegression", "WindowedNLS", "excitation_report", "KINDS")},
    **{name: (".errors", name) for name in ("ConvergenceWarning", "DataError", "FiniteEscapeError", "SolverError",
                                            "TimeBudgetError", "FormError", "ModelError", "ModelFileError", "NlobsError",
                                            "PreconditionError", "ShapeError", "EngineError")},
    **{name: (".model", name) for name in ("LTI", "StateAffine", "System", "load_model", "loads_model")},
    **{name: (".observer", name) for name in ("CompiledObserver", "Observer", "OnlineObserver", "CExport", "export_c")},
    **{name: (".simulate", name) for name in ("Adaptive", "MonteCarloResult", "Noise", "ProcessNoise", "Run", "Sampling",
                                              "Simulation", "montecarlo", "simulate")},
    **{name: (".estimation", name) for name in ("Recording", "estimate")},
    **{name: (".learning", name) for name in ("fit_parameters", "LikelihoodFit", "fit_likelihood", "log_likelihood",
                                              "TuneResult")},
    "analyze": (".analysis", "analyze"),
    "select_sensors": (".analysis", "select_sensors"),
    "from_control": (".interop", "from_control"),
    "to_control": (".interop", "to_control"),
    "Advice": (".advise", "Advice"),
    "advise": (".advise", "advise"),
    "tune": (".advise", "tune"),
}

#: Functions whose name is also a subpackage's: the attribute stays the function when the subpackage is imported.
_SHADOWED = frozenset(("simulate", "advise"))


def _load(name: str) -> Any:
    module, attr = _LAZY[name]
    mod = importlib.import_module(module, __name__)
    value = mod if attr is None else getattr(mod, attr)
    globals()[name] = value
    return value


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return _load(name)
    if name.startswith("design_"):   # one public function per observer kind, read from the registry
        design = importlib.import_module(".design", __name__)
        if name in design.DESIGN_FUNCTIONS:
            globals()[name] = design.DESIGN_FUNCTIONS[name]
            return globals()[name]
        if name in design.RENAMED:   # renamed functions keep their old name for one release, with a DeprecationWarning
            return getattr(design, name)
    raise AttributeError(f"module 'nlobs' has no attribute {name!r}")


def __dir__() -> list[str]:
    from .design import DESIGN_FUNCTIONS

    return sorted({*globals(), *_LAZY, *DESIGN_FUNCTIONS})


class _Package(types.ModuleType):
    """Importing the subpackage ``nlobs.simulate`` (or ``nlobs.advise``) sets the attribute of that name on the
    package; here it stays the function of that name, as ``from nlobs import simulate`` has always given."""

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _SHADOWED and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
