"""Structural analysis, from the equations alone: local observability and identifiability (generic rank of the
output jets), global identifiability (SIAN), identifiable functions, reparametrisation, regimes of piecewise models.
:func:`analyze` (``_analyze``) sits above the local (``_lie``) and global (``_global``, ``_identifiable``) routes; the
parsers of their ``inputs=``, ``unknown_params=`` and ``functions`` arguments are in ``_inputs``, below them all."""

from ._analyze import analyze as analyze
from ._global import GlobalResult as GlobalResult
from ._global import LocallyOnly as LocallyOnly
from ._global import MultiExperiment as MultiExperiment
from ._global import NotRational as NotRational
from ._global import global_identifiability as global_identifiability
from ._global import multi_experiment as multi_experiment
from ._global import replicate as replicate
from ._identifiable import IdentifiableFunctions as IdentifiableFunctions
from ._identifiable import find_identifiable_functions as find_identifiable_functions
from ._inputs import InputClass as InputClass
from ._lie import observable_function as observable_function
from ._regimes import Regime as Regime
from ._regimes import visited_regimes as visited_regimes
from ._reparam import Reparametrization as Reparametrization
from ._reparam import reparametrize as reparametrize
