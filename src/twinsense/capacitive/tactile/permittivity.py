"""Pressure-dependent permittivity of a porous (foamed) dielectric.

A foam is a solid matrix (relative permittivity ``eps_solid``) with an air
volume fraction ``porosity``. The matrix is nearly incompressible, so a
volume change of the foam is a change of its pore volume: with the
volumetric strain ``e = V / V0 - 1`` (negative under compression) the
porosity becomes ``(porosity0 + e) / (1 + e)`` (clipped at 0: fully closed
pores). The foam's permittivity follows the Looyenga mixture rule
``eps^(1/3) = (1 - phi) eps_solid^(1/3) + phi`` (Looyenga, Physica 31, 1965),
exact to first order in the contrast and within a few percent of measured
foams over the whole porosity range. Compressing the layer therefore raises
both ``1/d`` and ``eps``: a porous dielectric is more sensitive than a solid
one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from twinsense import validation as v

__all__ = ["PorousPermittivity"]


@dataclass(frozen=True)
class PorousPermittivity:
    """Looyenga mixture of a solid matrix and air whose pores close under compression.

    Attributes
    ----------
    eps_solid : float, relative permittivity of the matrix (silicone ~2.8).
    porosity : float, air volume fraction of the unloaded foam, in [0, 1).
    """

    eps_solid: float = 2.8
    porosity: float = 0.5

    def __post_init__(self) -> None:
        v.number("PorousPermittivity.eps_solid", self.eps_solid, lo=1.0)
        v.number("PorousPermittivity.porosity", self.porosity, lo=0.0, hi=1.0, hi_open=True)

    def porosity_at(self, volumetric_strain) -> np.ndarray:
        """Air fraction at a volumetric strain ``V / V0 - 1`` (> -1)."""
        e = np.asarray(volumetric_strain, float)
        return np.clip((self.porosity + e) / (1.0 + e), 0.0, 1.0)

    def permittivity(self, volumetric_strain=0.0) -> np.ndarray:
        """Relative permittivity at a volumetric strain ``V / V0 - 1``."""
        phi = self.porosity_at(volumetric_strain)
        root = (1.0 - phi) * self.eps_solid ** (1.0 / 3.0) + phi
        return root**3
