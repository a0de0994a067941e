"""Design: how? One function per method; each checks its preconditions and returns an ObserverDesign.

The observer kinds are declared next to their design functions (``@kind(...)``, :mod:`nlobs.design._kind`) and
collected in :data:`KINDS`; the ``design_<kind>`` functions exported here and from ``nlobs`` are read from it.
"""

import warnings as _warnings

# Importing a design module declares its kinds (the order here is the order of `nlobs kinds` and of the advisor).
# Each family is a sub-package: `linear`, `high_gain`, `lipschitz`, `banks`, `mhe`, `kalman` (the Kalman family,
# the Riccati observers and the particle filter) and `pebo` (regression estimators, PEBO, GPEBO, KKL, I&I); the
# modules shared by the families (`_base`, `_checks`, `_common`, `_kind`, `_tune`, ...) and the observer written by
# its equations (`_custom`) are at the top.
from .linear import _linear  # noqa: F401
from .kalman import _ekf  # noqa: F401
from .linear import _augmented  # noqa: F401
from . import _custom  # noqa: F401
from .high_gain import _high_gain  # noqa: F401
from .lipschitz import _lipschitz  # noqa: F401
from .kalman import _riccati  # noqa: F401
from .banks import _banks  # noqa: F401
from .kalman import _ukf  # noqa: F401
from .mhe import _mhe  # noqa: F401
from .kalman import _srukf, _srekf, _iekf, _pf  # noqa: F401
from .pebo import _regression, _gpebo, _pebo, _kkl, _cascade, _iandi  # noqa: F401
from ._base import Certificate as Certificate
from ._base import Check as Check
from ._base import ObserverDesign as ObserverDesign
from ._base import Symbols as Symbols
from ._checks import check_matrix as check_matrix
from ._checks import check_positive as check_positive
from ._checks import observer_gain as observer_gain
from ._kind import KINDS as KINDS
from ._kind import Kind as Kind
from ._kind import Tuning as Tuning
from ._kind import kind as kind
from ._kind import options_of as options_of
from ._kind import register_design as register_design
from ._kind import requires_model as requires_model
from .pebo._pebo import WindowedNLS as WindowedNLS
from .kalman._pf import ParticleDesign as ParticleDesign
from .pebo._regression import DREM as DREM
from .pebo._regression import GD as GD
from .pebo._regression import AbstractEstimator as AbstractEstimator
from .pebo._regression import ExcitationReport as ExcitationReport
from .pebo._regression import Gradient as Gradient
from .pebo._regression import LeastSquares as LeastSquares
from .pebo._regression import LinearRegression as LinearRegression
from .pebo._regression import StateStack as StateStack
from .pebo._regression import derivative_filter as derivative_filter
from .pebo._regression import excitation_report as excitation_report
from .pebo._regression import lowpass as lowpass
from ._registry import DESIGNS as DESIGNS
from ._registry import check_identifiable as check_identifiable
from ._registry import design_from_config as design_from_config
from ._registry import designs_from_file as designs_from_file

#: The public design functions, one per kind, read from the registry (``design_ekf`` is ``KINDS["ekf"].design``).
DESIGN_FUNCTIONS = {k.design.__name__: k.design for k in KINDS.values()}
globals().update(DESIGN_FUNCTIONS)

#: Names kept for one release: old name -> new name (a DeprecationWarning names the new one).
RENAMED = {"design_2gd": "design_gpebo_2gd"}


def __getattr__(name: str):  # PEP 562: the old names of renamed functions
    if name in RENAMED:
        _warnings.warn(f"nlobs.{name} is renamed {RENAMED[name]}; the old name goes in the next release",
                       DeprecationWarning, stacklevel=2)
        return globals()[RENAMED[name]]
    raise AttributeError(f"module 'nlobs.design' has no attribute {name!r}")


#: The family sub-packages are rooms of the package, not part of its public names (``kalman`` was listed before them).
_ROOMS = {"banks", "high_gain", "linear", "lipschitz", "pebo"}

__all__ = sorted({n for n in globals() if not n.startswith("_")} - {"annotations"} - _ROOMS)
