"""The particle filter moved to :mod:`nlobs.design.kalman._pf` (the Kalman family's sub-package); this name is kept for
code that imports ``ParticleDesign`` from here."""

from .kalman._pf import ParticleDesign, design_pf, output_symmetries, square_roots

__all__ = ["ParticleDesign", "design_pf", "output_symmetries", "square_roots"]
