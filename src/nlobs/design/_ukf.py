"""The UKF moved to :mod:`nlobs.design.kalman._ukf` (the Kalman family's sub-package); this name is kept for code that
imports ``unscented_weights`` from here."""

from .kalman._ukf import design_ukf, unscented_weights

__all__ = ["design_ukf", "unscented_weights"]
