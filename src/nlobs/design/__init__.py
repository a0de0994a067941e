"""Design: how? One function per method; each checks its preconditions and returns an ObserverDesign."""

from ._augmented import design_augmented as design_augmented
from ._base import Certificate as Certificate
from ._base import Check as Check
from ._base import ObserverDesign as ObserverDesign
from ._base import Symbols as Symbols
from ._checks import check_matrix as check_matrix
from ._custom import design_custom as design_custom
from ._checks import observer_gain as observer_gain
from ._ekf import design_ekf as design_ekf
from ._linear import design_luenberger as design_luenberger
from ._linear import design_output_injection as design_output_injection
from ._registry import DESIGNS as DESIGNS
from ._registry import design_from_config as design_from_config
from ._registry import register_design as register_design
from ._high_gain import design_high_gain as design_high_gain
from ._high_gain import design_high_gain_derivatives as design_high_gain_derivatives
from ._lipschitz import design_lipschitz as design_lipschitz
from ._kalman import design_high_gain_kalman as design_high_gain_kalman
from ._kalman import design_kalman_bucy as design_kalman_bucy
from ._kalman import design_kalman_like as design_kalman_like
from ._banks import design_banks as design_banks
from ._ukf import design_ukf as design_ukf
from ._mhe import design_mhe as design_mhe
