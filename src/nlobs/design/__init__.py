"""Design: how? One function per method; each checks its preconditions and returns an ObserverDesign."""

from ._augmented import design_augmented as design_augmented
from ._base import Certificate as Certificate
from ._base import Check as Check
from ._base import ObserverDesign as ObserverDesign
from ._base import Symbols as Symbols
from ._checks import check_matrix as check_matrix
from ._checks import check_positive as check_positive
from ._custom import design_custom as design_custom
from ._checks import observer_gain as observer_gain
from ._ekf import design_ekf as design_ekf
from ._linear import design_luenberger as design_luenberger
from ._linear import design_output_injection as design_output_injection
from ._registry import DESIGNS as DESIGNS
from ._registry import check_identifiable as check_identifiable
from ._registry import design_from_config as design_from_config
from ._registry import designs_from_file as designs_from_file
from ._registry import requires_model as requires_model
from ._registry import register_design as register_design
from ._high_gain import design_high_gain as design_high_gain
from ._high_gain import design_high_gain_derivatives as design_high_gain_derivatives
from ._lipschitz import design_lipschitz as design_lipschitz
from ._kalman import design_high_gain_kalman as design_high_gain_kalman
from ._kalman import design_kalman_bucy as design_kalman_bucy
from ._kalman import design_kalman_like as design_kalman_like
from ._banks import design_banks as design_banks
from ._ukf import design_ukf as design_ukf
from ._srukf import design_srukf as design_srukf
from ._srekf import design_srekf as design_srekf
from ._iekf import design_iekf as design_iekf
from ._pf import ParticleDesign as ParticleDesign
from ._pf import design_pf as design_pf
from ._mhe import design_mhe as design_mhe
from ._cascade import design_kkl_pebo_cascade as design_kkl_pebo_cascade
from ._gpebo import design_2gd as design_2gd
from ._gpebo import design_gpebo as design_gpebo
from ._iandi import design_iandi as design_iandi
from ._kkl import design_kkl_learned as design_kkl_learned
from ._pebo import WindowedNLS as WindowedNLS
from ._pebo import design_kkl as design_kkl
from ._pebo import design_kkl_pebo as design_kkl_pebo
from ._pebo import design_pebo as design_pebo
from ._regression import DREM as DREM
from ._regression import GD as GD
from ._regression import AbstractEstimator as AbstractEstimator
from ._regression import ExcitationReport as ExcitationReport
from ._regression import Gradient as Gradient
from ._regression import LeastSquares as LeastSquares
from ._regression import LinearRegression as LinearRegression
from ._regression import StateStack as StateStack
from ._regression import derivative_filter as derivative_filter
from ._regression import design_drem as design_drem
from ._regression import design_gd as design_gd
from ._regression import design_gradient as design_gradient
from ._regression import design_least_squares as design_least_squares
from ._regression import excitation_report as excitation_report
from ._regression import lowpass as lowpass

# Every public design function checks its model argument (one clear TypeError instead of an
# AttributeError deep inside) and runs its symbolic work within the budget: wrapped once, here,
# so nlobs.design and nlobs export the same checked functions.
for _name in [_n for _n in dir() if _n.startswith("design_") and _n != "design_from_config"]:
    globals()[_name] = requires_model(globals()[_name])
del _name
