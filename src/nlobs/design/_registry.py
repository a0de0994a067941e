"""Observer kinds by name, for model files (``[observers.NAME] kind = "..."``) and the CLI."""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from typing import Any

from ..errors import ModelError
from ..model import System
from ._augmented import design_augmented
from ._banks import design_banks
from ._base import ObserverDesign
from ._custom import design_custom
from ._ekf import design_ekf
from ._high_gain import design_high_gain, design_high_gain_derivatives
from ._kalman import design_high_gain_kalman, design_kalman_bucy, design_kalman_like
from ._linear import design_luenberger, design_output_injection
from ._lipschitz import design_lipschitz
from ._mhe import design_mhe
from ._ukf import design_ukf

__all__ = ["DESIGNS", "register_design", "design_from_config"]

#: Design functions by the ``kind`` used in model files.
DESIGNS: dict[str, Callable[..., ObserverDesign]] = {
    "luenberger": design_luenberger,
    "output_injection": design_output_injection,
    "ekf": design_ekf,
    "augmented": design_augmented,
    "custom": design_custom,
    "high_gain": design_high_gain,
    "high_gain_derivatives": design_high_gain_derivatives,
    "lipschitz": design_lipschitz,
    "kalman_bucy": design_kalman_bucy,
    "kalman_like": design_kalman_like,
    "high_gain_kalman": design_high_gain_kalman,
    "banks": design_banks,
    "ukf": design_ukf,
    "mhe": design_mhe,
}


def register_design(kind: str, fn: Callable[..., ObserverDesign]) -> None:
    """Make a design function `fn` available to model files under the name `kind`."""
    DESIGNS[kind] = fn


def options_of(fn: Callable[..., Any]) -> tuple[str, ...]:
    """The keyword-only tuning options a design function accepts."""
    return tuple(n for n, p in inspect.signature(fn).parameters.items() if p.kind is inspect.Parameter.KEYWORD_ONLY)


def design_from_config(system: System, kind: str, options: Mapping[str, Any], *, where: str = "") -> ObserverDesign:
    """Run the design `kind` on `system` with the `options` of a model file.

    Raises
    ------
    ModelError
        For an unknown kind or option (listing the allowed ones); the design's own errors
        (PreconditionError, ShapeError) pass through with `where` prepended.
    """
    prefix = f"{where}: " if where else ""
    if kind not in DESIGNS:
        raise ModelError(f"{prefix}unknown observer kind {kind!r}; available: {', '.join(sorted(DESIGNS))}")
    fn = DESIGNS[kind]
    allowed = options_of(fn)
    unknown = [k for k in options if k not in allowed]
    if unknown:
        raise ModelError(f"{prefix}unknown option `{unknown[0]}` for kind {kind!r}; {fn.__name__} accepts: {', '.join(allowed)}")
    try:
        return fn(system, **options)
    except (ValueError, TypeError) as e:
        raise type(e)(f"{prefix}{e}") from e

# Parameter-estimation based observers and estimators (000, 004)
from ._cascade import design_kkl_pebo_cascade  # noqa: E402
from ._gpebo import design_2gd, design_gpebo  # noqa: E402
from ._iandi import design_iandi  # noqa: E402
from ._kkl import design_kkl_learned  # noqa: E402
from ._pebo import design_kkl, design_kkl_pebo, design_pebo  # noqa: E402
from ._regression import design_drem, design_gd, design_gradient, design_least_squares  # noqa: E402

DESIGNS.update({
    "gradient": design_gradient,
    "least_squares": design_least_squares,
    "drem": design_drem,
    "gd": design_gd,
    "gpebo": design_gpebo,
    "gpebo_2gd": design_2gd,
    "kkl": design_kkl,
    "kkl_learned": design_kkl_learned,
    "pebo": design_pebo,
    "kkl_pebo": design_kkl_pebo,
    "kkl_pebo_cascade": design_kkl_pebo_cascade,
    "iandi": design_iandi,
})
