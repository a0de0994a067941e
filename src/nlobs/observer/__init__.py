"""Observer: the runnable contract z' = F(t, z, u, y), x̂ = H(t, z, u, y) (+ sample-time update)."""

from ._base import AbstractObserver as AbstractObserver
from ._base import Observer as Observer
from ._base import OnlineObserver as OnlineObserver
from ._convert import as_observer as as_observer
from ._compiled import CompiledObserver as CompiledObserver
from ._compiled import ObserverTrajectory as ObserverTrajectory
from ._compiled import compiled_observer as compiled_observer
from ._export import CExport as CExport
from ._export import export_c as export_c
from ._particles import ParticleObserver as ParticleObserver
from ._particles import ParticleRun as ParticleRun
from ._particles import ParticleRunner as ParticleRunner
from ._particles import particle_runner as particle_runner
