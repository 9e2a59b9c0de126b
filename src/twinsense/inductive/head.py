"""Sensor head geometry: coil, ferrite pot core and housing as axisymmetric regions.

The sensing face is the plane z = 0 and the sensor body lies at z > 0; a
target plate of thickness ``c`` at distance ``d`` occupies ``-d - c <= z <= -d``.
Proportions of the pot core follow the usual cylindrical proximity-sensor
build (a ferrite cup with centre post, winding and, in a shielded sensor, an
outer wall up to the face; an unshielded sensor has no outer wall and its
metal sleeve ends behind the coil, so the field also spreads sideways):

- radii as fractions of the core radius ``Rc``: post 0..0.30, winding
  0.36..0.72 (unshielded: 0.36..0.85), outer wall 0.78..1.0 (shielded only);
- heights as fractions of the core height ``H = 0.7 Rc``: winding and wall
  from the core face to 0.7 H, back plate 0.7 H..H over the full core radius;
- the core face sits ``cap`` behind the sensing face (the plastic cap);
- the housing is a metal sleeve from ``housing_inner_radius`` to
  ``housing_outer_radius``, flush with the face (shielded) or set back by the
  core height plus 1 mm (unshielded).
"""

from __future__ import annotations

from dataclasses import dataclass

from twinsense import validation as V
from twinsense.inductive.fem import Coil, Region


@dataclass(frozen=True)
class HeadGeometry:
    """Dimensions [m] and materials of a sensor head.

    core_radius : ferrite cup outer radius [m]
    housing_inner_radius, housing_outer_radius : metal sleeve [m]
    shielded : flush (shielded) build with the core's outer wall, else non-flush
    turns : winding turns
    core_mu_r : ferrite relative permeability (MnZn power ferrite ~2000; sigma ~1 S/m is neglected:
        its skin depth at 1 MHz is ~1 cm, larger than the core)
    housing_sigma : sleeve conductivity [S/m] (nickel-plated brass, 1.5e7)
    cap : plastic cap thickness in front of the core [m]
    """

    core_radius: float
    housing_inner_radius: float
    housing_outer_radius: float
    shielded: bool = True
    turns: float = 100.0
    core_mu_r: float = 2000.0
    housing_sigma: float = 1.5e7
    cap: float = 0.5e-3

    def __post_init__(self):
        V.length("HeadGeometry.core_radius", self.core_radius)
        V.number("HeadGeometry.housing_inner_radius", self.housing_inner_radius, lo=self.core_radius,
                 lo_open=True, unit="m (> core_radius)")
        V.number("HeadGeometry.housing_outer_radius", self.housing_outer_radius, lo=self.housing_inner_radius,
                 lo_open=True, unit="m (> housing_inner_radius)")
        V.positive("HeadGeometry.turns", self.turns)
        V.number("HeadGeometry.core_mu_r", self.core_mu_r, lo=1.0, unit="relative")
        V.non_negative("HeadGeometry.housing_sigma", self.housing_sigma, "S/m")
        V.non_negative("HeadGeometry.cap", self.cap, "m")

    @property
    def core_height(self) -> float:
        return 0.7 * self.core_radius

    @property
    def face_radius(self) -> float:
        """Radius of the sensing face [m] (the housing's outer radius)."""
        return self.housing_outer_radius

    def coil(self) -> Coil:
        rc, h = self.core_radius, self.core_height
        r2 = 0.72 * rc if self.shielded else 0.85 * rc
        return Coil(0.36 * rc, r2, self.cap, self.cap + 0.7 * h, self.turns)

    def regions(self) -> tuple[Region, ...]:
        """Core and housing regions (the fixed parts of the sensor)."""
        rc, h, z0 = self.core_radius, self.core_height, self.cap
        mu = self.core_mu_r
        out = [Region(0.0, 0.30 * rc, z0, z0 + 0.7 * h, mu, 0.0),
               Region(0.0, rc, z0 + 0.7 * h, z0 + h, mu, 0.0)]
        if self.shielded:
            out.append(Region(0.78 * rc, rc, z0, z0 + 0.7 * h, mu, 0.0))
        front = 0.0 if self.shielded else z0 + h + 1e-3
        length = max(6 * rc, 20e-3)
        if self.housing_sigma > 0:
            out.append(Region(self.housing_inner_radius, self.housing_outer_radius, front, front + length, 1.0,
                              self.housing_sigma))
        return tuple(out)


def target_disc(distance: float, radius: float, thickness: float, sigma: float, mu_r: float) -> Region:
    """A target plate (disc of ``radius``) at ``distance`` in front of the face."""
    return Region(0.0, radius, -distance - thickness, -distance, mu_r, sigma)


def target_ring(distance: float, r_in: float, r_out: float, thickness: float, sigma: float, mu_r: float) -> Region:
    """A washer-shaped target (``r_in..r_out``) at ``distance`` in front of the face."""
    return Region(r_in, r_out, -distance - thickness, -distance, mu_r, sigma)
