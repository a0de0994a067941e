"""Analysis: is it possible? Observability, excitation, forms, augmentation.

Four rooms, one sub-package each: ``structural`` (from the equations: local rank, global identifiability,
identifiable functions, reparametrisation, regimes), ``trajectory`` (along a run: Gramians, excitation),
``forms`` (structure: form recognition, linear tests, Banks' conditions, augmentation) and ``sensors`` (which
candidate sensors to use: the structural and the trajectory rooms together); the report types they share
are in ``_reports``. The exact and modular tools they compute with live one layer below, in :mod:`nlobs.algebra`.
Every public name is re-exported here.

Structural (generic rank, Besançon (2010)): :func:`analyze` -> :class:`ObservabilityReport`, :func:`observable_function`;
piecewise models (abs, min, max, sat) one regime at a time: :func:`visited_regimes`.
Global (SIAN): :func:`global_identifiability` -> :class:`GlobalResult`; :func:`find_identifiable_functions`;
:func:`multi_experiment`; :func:`reparametrize`; Gröbner engines :func:`available_engines`.
Linear: :func:`kalman_rank`, :func:`pbh_test`, :func:`kalman_decomposition`.
LTV / state-affine along a trajectory (Wang, Ortega & Bobtsov (2021)): :func:`ltv_gramian`, :func:`uco_test`, :func:`state_affine_ltv`.
Nonlinear along a trajectory (Besançon (2010)): :func:`empirical_gramian`, :func:`indistinguishable`.
Excitation (Wang, Ortega & Bobtsov (2021), eq. 15, Besançon (2010)): :func:`interval_excitation`, :func:`persistent_excitation`,
:func:`identifiability_rank`, :func:`regular_persistence`, :func:`local_regularity`.
Observer forms (Besançon (2010)): :func:`recognise_forms`, :func:`state_affine_form`, :func:`triangular_form`,
:func:`lipschitz_constant`, :func:`with_params_as_states`.
Banks (1980): :func:`matrix_measure`, :func:`max_slope`, :func:`banks_condition`, :func:`lipschitz_bound`.
Identities (exact, Schwartz-Zippel): :func:`decide_identity`, :func:`exact_generic_rank`.
Sensor selection (Liu, Slotine & Barabási (2013); Krener & Ide (2009)): :func:`select_sensors` -> :class:`SensorSelection`.
Augmentation (Viegas, Batista, Oliveira & Silvestre (2015)): :func:`check_mimicking`, :func:`injectivity`, :func:`left_inverse_bounds`,
:func:`augmented_observability`, :func:`propose_augmentation`.

Every name loads its room when first used (PEP 562): a package that needs one test (a design's
``kalman_rank``) imports that room alone, and a Monte Carlo worker, which runs no analysis, none of them.
"""

from __future__ import annotations

import importlib
from typing import Any

#: Public name -> the module (relative to this package) that defines it.
_LAZY: dict[str, str] = {
    **dict.fromkeys((
        "LinearObservability", "PBHResult", "kalman_rank", "observability_matrix", "pbh_test",
        "KalmanDecomposition", "kalman_decomposition", "FormCheck", "FormsReport", "lipschitz_constant",
        "recognise_forms", "state_affine_form", "triangular_form", "with_params_as_states", "BanksCheck",
        "LipschitzEstimate", "SlopeResult", "banks_condition", "lipschitz_bound", "matrix_measure", "max_slope",
        "Augmentation", "AugmentedObservability", "InjectivityCheck", "LeftInverseBounds", "MimickingCheck",
        "augmented_observability", "check_mimicking", "injectivity", "left_inverse_bounds",
        "propose_augmentation",
    ), ".forms"),
    **dict.fromkeys((
        "InputClass", "analyze", "observable_function", "GlobalResult", "LocallyOnly", "MultiExperiment",
        "NotRational", "global_identifiability", "multi_experiment", "replicate", "IdentifiableFunctions",
        "find_identifiable_functions", "Regime", "visited_regimes", "Reparametrization", "reparametrize",
    ), ".structural"),
    **dict.fromkeys((
        "available_engines",
    ), "..algebra._groebner"),
    **dict.fromkeys((
        "FunctionCheck", "ObservabilityReport", "Symmetry",
    ), "._reports"),
    **dict.fromkeys((
        "EmpiricalGramian", "GramianResult", "Indistinguishability", "UCOResult", "empirical_gramian",
        "indistinguishable", "ltv_gramian", "state_affine_ltv", "uco_test", "ExcitationResult",
        "IdentifiabilityResult", "LocalRegularity", "identifiability_rank", "interval_excitation",
        "local_regularity", "persistent_excitation", "regular_persistence",
    ), ".trajectory"),
    **dict.fromkeys((
        "ExactRank", "Identity", "decide_identity", "exact_generic_rank",
    ), "..algebra._identity"),
    **dict.fromkeys((
        "Candidate", "SensorSelection", "SensorSet", "select_sensors", "sensor_pool",
    ), ".sensors"),
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_LAZY[name], __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
