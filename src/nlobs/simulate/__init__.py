"""Simulate: run plants and observers on the same measurements; recorded data; results and metrics."""

from ._metrics import Metrics as Metrics
from ._metrics import convergence_time as convergence_time
from ._metrics import error_metrics as error_metrics
from ._options import Adaptive as Adaptive
from ._options import Noise as Noise
from ._options import ProcessNoise as ProcessNoise
from ._options import Sampling as Sampling
from ._results import ObserverTrace as ObserverTrace
from ._results import Run as Run
from ._run import Simulation as Simulation
from ._run import simulate as simulate
from ._recorded import Recording as Recording
from ._recorded import estimate as estimate
from ._montecarlo import MonteCarloResult as MonteCarloResult
from ._montecarlo import montecarlo as montecarlo
