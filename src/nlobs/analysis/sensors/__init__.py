"""Sensor selection: which candidate sensors make the model observable (exact generic rank of each set, pruned by the
influence graph) and which set estimates best for its cost (Cramér–Rao bounds of x(0) from the Fisher information on the
``[simulation]`` run). :func:`select_sensors` -> :class:`SensorSelection`; the pool: :func:`sensor_pool`."""

from ._pool import DEFAULT_RELATIVE_NOISE as DEFAULT_RELATIVE_NOISE
from ._pool import Candidate as Candidate
from ._pool import sensor_pool as sensor_pool
from ._select import SensorSelection as SensorSelection
from ._select import SensorSet as SensorSet
from ._select import select_sensors as select_sensors
