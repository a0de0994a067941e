"""nlobs: nonlinear observability analysis and state-observer design.

The data flow, one way: ``model`` (System, forms, model files) -> ``engine`` (CasADi
compilation, integrators, C) -> ``algebra`` -> ``analysis`` -> ``design`` (one function per method,
returning an ObserverDesign with its evidence) -> ``observer`` (the runnable contract) ->
``simulate`` (plant + observers, noise, sampling, recorded data) -> ``report`` -> ``cli``.
"""

from . import analysis as analysis
from . import design as design
from . import engine as engine
from . import model as model
from . import observer as observer
from .design import Certificate as Certificate
from .design import ObserverDesign as ObserverDesign
from .errors import ConvergenceWarning as ConvergenceWarning
from .errors import DataError as DataError
from .errors import FiniteEscapeError as FiniteEscapeError
from .errors import SolverError as SolverError
from .errors import TimeBudgetError as TimeBudgetError
from .errors import FormError as FormError
from .errors import ModelError as ModelError
from .errors import ModelFileError as ModelFileError
from .errors import NlobsError as NlobsError
from .errors import PreconditionError as PreconditionError
from .errors import ShapeError as ShapeError
from .model import LTI as LTI
from .model import StateAffine as StateAffine
from .model import System as System
from .model import load_model as load_model
from .model import loads_model as loads_model
from .observer import CompiledObserver as CompiledObserver
from .observer import Observer as Observer
from .observer import OnlineObserver as OnlineObserver
from .simulate import Adaptive as Adaptive
from .simulate import MonteCarloResult as MonteCarloResult
from .simulate import Noise as Noise
from .simulate import ProcessNoise as ProcessNoise
from .simulate import Recording as Recording
from .simulate import Run as Run
from .simulate import Sampling as Sampling
from .simulate import Simulation as Simulation
from .simulate import estimate as estimate
from .simulate import fit_parameters as fit_parameters
from .simulate import LikelihoodFit as LikelihoodFit
from .simulate import fit_likelihood as fit_likelihood
from .simulate import log_likelihood as log_likelihood
from .simulate import montecarlo as montecarlo
from .simulate import simulate as simulate
from .design import DREM as DREM
from .design import GD as GD
from .design import Gradient as Gradient
from .design import LeastSquares as LeastSquares
from .design import LinearRegression as LinearRegression
from .design import WindowedNLS as WindowedNLS
from .design import excitation_report as excitation_report
from .design import KINDS as KINDS
from .design import DESIGN_FUNCTIONS as _DESIGN_FUNCTIONS

# one public function per observer kind, read from the registry (nlobs.design_ekf is nlobs.design.KINDS["ekf"].design)
globals().update(_DESIGN_FUNCTIONS)

from ._version import __version__ as __version__
from .analysis import analyze as analyze  # noqa: E402
from .observer import CExport as CExport  # noqa: E402
from .observer import export_c as export_c  # noqa: E402
from . import interop as interop  # noqa: E402
from .interop import from_control as from_control  # noqa: E402
from .interop import to_control as to_control  # noqa: E402
from . import advise as _advise_pkg  # noqa: E402
from .advise import Advice as Advice  # noqa: E402
from .advise import advise as advise  # noqa: E402


def __getattr__(name: str):  # PEP 562: renamed functions keep their old name for one release, with a DeprecationWarning
    if name in design.RENAMED:
        return getattr(design, name)
    raise AttributeError(f"module 'nlobs' has no attribute {name!r}")
