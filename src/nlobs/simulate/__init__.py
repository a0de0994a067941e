"""Simulate: run plants and observers on the same measurements; Monte Carlo; results and metrics. Observers on
recorded data are a layer above, :mod:`nlobs.estimation`."""

from ._metrics import CONVERGENCE_RULE as CONVERGENCE_RULE
from ._metrics import PER_STATE_RULE as PER_STATE_RULE
from ._metrics import Metrics as Metrics
from ._metrics import convergence_band as convergence_band
from ._metrics import steady_state_error as steady_state_error
from ._metrics import convergence_time as convergence_time
from ._metrics import error_metrics as error_metrics
from ._options import Adaptive as Adaptive
from ._options import Noise as Noise
from ._options import ProcessNoise as ProcessNoise
from ._options import Sampling as Sampling
from ._results import ObserverFailure as ObserverFailure
from ._results import ObserverTrace as ObserverTrace
from ._results import Run as Run
from ._whiteness import Whiteness as Whiteness
from ._whiteness import ljung_box as ljung_box
from ._run import Simulation as Simulation
from ._run import simulate as simulate
from ._montecarlo import MonteCarloResult as MonteCarloResult
from ._montecarlo import montecarlo as montecarlo
