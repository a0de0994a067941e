"""Analysis: is it possible? Observability, excitation, forms, augmentation.

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
Augmentation (Viegas, Batista, Oliveira & Silvestre (2015)): :func:`check_mimicking`, :func:`injectivity`, :func:`left_inverse_bounds`,
:func:`augmented_observability`, :func:`propose_augmentation`.
"""

from ._linear import LinearObservability as LinearObservability
from ._linear import PBHResult as PBHResult
from ._linear import kalman_rank as kalman_rank
from ._linear import observability_matrix as observability_matrix
from ._linear import pbh_test as pbh_test
from ._lie import InputClass as InputClass
from ._analyze import analyze as analyze
from ._lie import observable_function as observable_function
from ._global import GlobalResult as GlobalResult
from ._global import LocallyOnly as LocallyOnly
from ._global import MultiExperiment as MultiExperiment
from ._global import NotRational as NotRational
from ._global import global_identifiability as global_identifiability
from ._global import multi_experiment as multi_experiment
from ._global import replicate as replicate
from ._groebner import available_engines as available_engines
from ._identifiable import IdentifiableFunctions as IdentifiableFunctions
from ._identifiable import find_identifiable_functions as find_identifiable_functions
from ._regimes import Regime as Regime
from ._regimes import visited_regimes as visited_regimes
from ._reparam import Reparametrization as Reparametrization
from ._reparam import reparametrize as reparametrize
from ._reports import FunctionCheck as FunctionCheck
from ._reports import ObservabilityReport as ObservabilityReport
from ._reports import Symmetry as Symmetry
from ._gramian import EmpiricalGramian as EmpiricalGramian
from ._gramian import GramianResult as GramianResult
from ._gramian import Indistinguishability as Indistinguishability
from ._gramian import UCOResult as UCOResult
from ._gramian import empirical_gramian as empirical_gramian
from ._gramian import indistinguishable as indistinguishable
from ._gramian import ltv_gramian as ltv_gramian
from ._gramian import state_affine_ltv as state_affine_ltv
from ._gramian import uco_test as uco_test
from ._linear import KalmanDecomposition as KalmanDecomposition
from ._linear import kalman_decomposition as kalman_decomposition
from ._excitation import ExcitationResult as ExcitationResult
from ._excitation import IdentifiabilityResult as IdentifiabilityResult
from ._excitation import LocalRegularity as LocalRegularity
from ._excitation import identifiability_rank as identifiability_rank
from ._excitation import interval_excitation as interval_excitation
from ._excitation import local_regularity as local_regularity
from ._excitation import persistent_excitation as persistent_excitation
from ._excitation import regular_persistence as regular_persistence
from ._recognise import FormCheck as FormCheck
from ._recognise import FormsReport as FormsReport
from ._recognise import lipschitz_constant as lipschitz_constant
from ._recognise import recognise_forms as recognise_forms
from ._recognise import state_affine_form as state_affine_form
from ._recognise import triangular_form as triangular_form
from ._recognise import with_params_as_states as with_params_as_states
from ._identity import ExactRank as ExactRank
from ._identity import Identity as Identity
from ._identity import decide_identity as decide_identity
from ._identity import exact_generic_rank as exact_generic_rank
from ._conditions import BanksCheck as BanksCheck
from ._conditions import LipschitzEstimate as LipschitzEstimate
from ._conditions import SlopeResult as SlopeResult
from ._conditions import banks_condition as banks_condition
from ._conditions import lipschitz_bound as lipschitz_bound
from ._conditions import matrix_measure as matrix_measure
from ._conditions import max_slope as max_slope
from ._augment import Augmentation as Augmentation
from ._augment import AugmentedObservability as AugmentedObservability
from ._augment import InjectivityCheck as InjectivityCheck
from ._augment import LeftInverseBounds as LeftInverseBounds
from ._augment import MimickingCheck as MimickingCheck
from ._augment import augmented_observability as augmented_observability
from ._augment import check_mimicking as check_mimicking
from ._augment import injectivity as injectivity
from ._augment import left_inverse_bounds as left_inverse_bounds
from ._augment import propose_augmentation as propose_augmentation
