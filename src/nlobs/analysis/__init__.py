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
