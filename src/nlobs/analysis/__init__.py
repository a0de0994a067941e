"""Analysis: is it possible? Observability, excitation, forms, augmentation."""

from ._linear import LinearObservability as LinearObservability
from ._linear import PBHResult as PBHResult
from ._linear import kalman_rank as kalman_rank
from ._linear import observability_matrix as observability_matrix
from ._linear import pbh_test as pbh_test
from ._lie import InputClass as InputClass
from ._lie import analyze as analyze
from ._lie import observable_function as observable_function
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
