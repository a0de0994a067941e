"""Observer forms: which structure a model has (recognition of the linear, output-injection, state-affine,
triangular and Lipschitz forms), the linear tests (Kalman rank, PBH, decomposition), Banks' conditions, and
augmentation into a system that mimics the model (``_augment``, built on the trajectory Gramian)."""

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
from ._conditions import BanksCheck as BanksCheck
from ._conditions import LipschitzEstimate as LipschitzEstimate
from ._conditions import SlopeResult as SlopeResult
from ._conditions import banks_condition as banks_condition
from ._conditions import lipschitz_bound as lipschitz_bound
from ._conditions import matrix_measure as matrix_measure
from ._conditions import max_slope as max_slope
from ._linear import KalmanDecomposition as KalmanDecomposition
from ._linear import LinearObservability as LinearObservability
from ._linear import PBHResult as PBHResult
from ._linear import kalman_decomposition as kalman_decomposition
from ._linear import kalman_rank as kalman_rank
from ._linear import observability_matrix as observability_matrix
from ._linear import pbh_test as pbh_test
from ._recognise import FormCheck as FormCheck
from ._recognise import FormsReport as FormsReport
from ._recognise import lipschitz_constant as lipschitz_constant
from ._recognise import recognise_forms as recognise_forms
from ._recognise import state_affine_form as state_affine_form
from ._recognise import triangular_form as triangular_form
from ._recognise import with_params_as_states as with_params_as_states
