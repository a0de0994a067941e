"""Estimation on recordings: observers run on recorded data (filtering), fixed-interval smoothing, and the sensor
check of ``nlobs sensors --run``. This stage sits above ``simulate`` (whose compiled loops, delays and results it
uses) and below ``learning`` (which fits models to the same recordings).

- :class:`Recording`: recorded t, u, y (and, optionally, the true states), from arrays, a CSV or a run;
- :func:`estimate`: observers on a recording, filtered or (``smooth=True``) smoothed by Rauch-Tung-Striebel;
- :func:`sensor_errors`: the error a smoothed EKF achieves with each set of sensors, beside its Cramér–Rao bound.
"""

from ._recorded import Recording as Recording
from ._recorded import estimate as estimate
from ._sensors import SensorErrors as SensorErrors
from ._sensors import sensor_errors as sensor_errors
