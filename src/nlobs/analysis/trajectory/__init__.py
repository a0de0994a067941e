"""Analysis along a trajectory: Gramians (LTV, empirical), uniform complete observability, indistinguishability, and
excitation of regressors (interval and persistent excitation, identifiability rank, regular persistence)."""

from ._excitation import ExcitationResult as ExcitationResult
from ._excitation import IdentifiabilityResult as IdentifiabilityResult
from ._excitation import LocalRegularity as LocalRegularity
from ._excitation import identifiability_rank as identifiability_rank
from ._excitation import interval_excitation as interval_excitation
from ._excitation import local_regularity as local_regularity
from ._excitation import persistent_excitation as persistent_excitation
from ._excitation import regular_persistence as regular_persistence
from ._gramian import EmpiricalGramian as EmpiricalGramian
from ._gramian import GramianResult as GramianResult
from ._gramian import Indistinguishability as Indistinguishability
from ._gramian import UCOResult as UCOResult
from ._gramian import empirical_gramian as empirical_gramian
from ._gramian import indistinguishable as indistinguishable
from ._gramian import ltv_gramian as ltv_gramian
from ._gramian import state_affine_ltv as state_affine_ltv
from ._gramian import uco_test as uco_test
