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
"""

from .forms import LinearObservability as LinearObservability
from .forms import PBHResult as PBHResult
from .forms import kalman_rank as kalman_rank
from .forms import observability_matrix as observability_matrix
from .forms import pbh_test as pbh_test
from .structural import InputClass as InputClass
from .structural import analyze as analyze
from .structural import observable_function as observable_function
from .structural import GlobalResult as GlobalResult
from .structural import LocallyOnly as LocallyOnly
from .structural import MultiExperiment as MultiExperiment
from .structural import NotRational as NotRational
from .structural import global_identifiability as global_identifiability
from .structural import multi_experiment as multi_experiment
from .structural import replicate as replicate
from ..algebra._groebner import available_engines as available_engines
from .structural import IdentifiableFunctions as IdentifiableFunctions
from .structural import find_identifiable_functions as find_identifiable_functions
from .structural import Regime as Regime
from .structural import visited_regimes as visited_regimes
from .structural import Reparametrization as Reparametrization
from .structural import reparametrize as reparametrize
from ._reports import FunctionCheck as FunctionCheck
from ._reports import ObservabilityReport as ObservabilityReport
from ._reports import Symmetry as Symmetry
from .trajectory import EmpiricalGramian as EmpiricalGramian
from .trajectory import GramianResult as GramianResult
from .trajectory import Indistinguishability as Indistinguishability
from .trajectory import UCOResult as UCOResult
from .trajectory import empirical_gramian as empirical_gramian
from .trajectory import indistinguishable as indistinguishable
from .trajectory import ltv_gramian as ltv_gramian
from .trajectory import state_affine_ltv as state_affine_ltv
from .trajectory import uco_test as uco_test
from .forms import KalmanDecomposition as KalmanDecomposition
from .forms import kalman_decomposition as kalman_decomposition
from .trajectory import ExcitationResult as ExcitationResult
from .trajectory import IdentifiabilityResult as IdentifiabilityResult
from .trajectory import LocalRegularity as LocalRegularity
from .trajectory import identifiability_rank as identifiability_rank
from .trajectory import interval_excitation as interval_excitation
from .trajectory import local_regularity as local_regularity
from .trajectory import persistent_excitation as persistent_excitation
from .trajectory import regular_persistence as regular_persistence
from .forms import FormCheck as FormCheck
from .forms import FormsReport as FormsReport
from .forms import lipschitz_constant as lipschitz_constant
from .forms import recognise_forms as recognise_forms
from .forms import state_affine_form as state_affine_form
from .forms import triangular_form as triangular_form
from .forms import with_params_as_states as with_params_as_states
from ..algebra._identity import ExactRank as ExactRank
from ..algebra._identity import Identity as Identity
from ..algebra._identity import decide_identity as decide_identity
from ..algebra._identity import exact_generic_rank as exact_generic_rank
from .forms import BanksCheck as BanksCheck
from .forms import LipschitzEstimate as LipschitzEstimate
from .forms import SlopeResult as SlopeResult
from .forms import banks_condition as banks_condition
from .forms import lipschitz_bound as lipschitz_bound
from .forms import matrix_measure as matrix_measure
from .forms import max_slope as max_slope
from .forms import Augmentation as Augmentation
from .forms import AugmentedObservability as AugmentedObservability
from .forms import InjectivityCheck as InjectivityCheck
from .forms import LeftInverseBounds as LeftInverseBounds
from .forms import MimickingCheck as MimickingCheck
from .forms import augmented_observability as augmented_observability
from .forms import check_mimicking as check_mimicking
from .forms import injectivity as injectivity
from .forms import left_inverse_bounds as left_inverse_bounds
from .forms import propose_augmentation as propose_augmentation
from .sensors import Candidate as Candidate
from .sensors import SensorSelection as SensorSelection
from .sensors import SensorSet as SensorSet
from .sensors import select_sensors as select_sensors
from .sensors import sensor_pool as sensor_pool
