"""Learning from recordings: model parameters (and noise levels) fitted to measured data. This stage sits above
``estimation`` (whose recordings it reads) and ``simulate`` (whose compiled loop and delays it uses), and below
``advise``.

- :func:`fit_parameters`: simulation-error least squares (the model run open loop on the recorded input);
- :func:`log_likelihood`, :func:`fit_likelihood`: the innovations likelihood of an EKF or UKF, which accounts
  for process noise and can learn Q and R;
- :func:`tune`: the noise covariances of a Kalman-family filter fitted on a recording.
"""

from ._simulation_error import FitResult as FitResult
from ._simulation_error import fit_parameters as fit_parameters
from ._fit_likelihood import LikelihoodFit as LikelihoodFit
from ._fit_likelihood import fit_likelihood as fit_likelihood
from ._likelihood import log_likelihood as log_likelihood
from ._tune_noise import TuneResult as TuneResult
from ._tune_noise import tune as tune
