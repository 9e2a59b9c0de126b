"""Linear-elastic materials of a soft tactile skin and the strain range where they hold.

Rubber-like solids are nearly incompressible (Poisson's ratio 0.499 and
above for unfilled silicones). The body is discretised with linear (P1)
tetrahedra, which lock as nu -> 0.5 (the element volume is constant, so the
incompressibility constraint over-stiffens the mesh); the presets therefore
cap nu at :data:`POISSON_MAX` = 0.49 (lambda / mu = 49). Plain P1 still
locks there (Hertz indentation force 25-35 % too stiff at 3-4.5 cells per
contact radius), which the body's default nodal volumetric average removes
(2-3 %, as for nu = 0.3; docs/tactile.md).

Linear range
------------
Linear elasticity is the small-strain limit of a hyperelastic law. For an
incompressible neo-Hookean solid (the first-order model of silicone rubber)
in uniaxial compression to stretch ``l = 1 - e`` the nominal stress is
``mu (l - l**-2)`` against ``3 mu e`` for the linear law: the true stress
exceeds the linear one by ``(l**-2 - l) / (3 e) - 1``, which is about ``e``
itself: 5.4 % at e = 0.05, 11.5 % at e = 0.10, 18.7 % at e = 0.15. The
neo-Hookean law follows rubber in compression closely (Treloar, "The Physics
of Rubber Elasticity", 3rd ed., 1975, ch. 5), so this is the error of the
linear model itself, and 10-20 % compression is where it reaches 10-20 %.
:data:`LINEAR_STRAIN_LIMIT` = 0.15 is the default bound on the largest
compressive principal strain an :class:`~twinsense.capacitive.mechanics.ElasticBody`
accepts (stress error below ~19 % there, smaller over most of the patch).
"""

from __future__ import annotations

from dataclasses import dataclass

from twinsense import validation as v
from twinsense.errors import ConfigError, UnknownNameError

__all__ = ["LINEAR_STRAIN_LIMIT", "MATERIALS", "POISSON_MAX", "ElasticMaterial", "elastic_material",
           "gent_young_from_shore_a"]

POISSON_MAX = 0.49
"""Largest Poisson's ratio of a P1 body (see the module notes on locking)."""

LINEAR_STRAIN_LIMIT = 0.15
"""Default largest compressive principal strain of the linear model (see the module notes)."""


@dataclass(frozen=True)
class ElasticMaterial:
    """An isotropic linear-elastic material.

    Attributes
    ----------
    name : str
    young : float
        Young's modulus E [Pa], > 0.
    poisson : float
        Poisson's ratio nu, in [0, POISSON_MAX] (see the module notes).
    """

    name: str
    young: float
    poisson: float

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError("ElasticMaterial.name", self.name, "a non-empty string")
        object.__setattr__(self, "young", v.positive(f"ElasticMaterial({self.name}).young", self.young, "Pa"))
        object.__setattr__(self, "poisson", v.number(f"ElasticMaterial({self.name}).poisson", self.poisson,
                                                     lo=0.0, hi=POISSON_MAX,
                                                     unit="1 (P1 tetrahedra lock as nu -> 0.5)"))

    @property
    def lame(self) -> tuple[float, float]:
        """Lame's parameters (lambda, mu) [Pa]."""
        e, nu = self.young, self.poisson
        return e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))

    @property
    def constrained_modulus(self) -> float:
        """P-wave (oedometric) modulus M = E (1 - nu) / ((1 + nu)(1 - 2 nu)) [Pa]."""
        lam, mu = self.lame
        return lam + 2 * mu

    @property
    def contact_modulus(self) -> float:
        """Plane-strain modulus E* = E / (1 - nu^2) against a rigid indenter [Pa]."""
        return self.young / (1 - self.poisson**2)


def gent_young_from_shore_a(shore_a: float) -> float:
    """Young's modulus [Pa] from a Shore A hardness by Gent's relation.

    ``E = 0.0981 (56 + 7.62336 S) / (0.137505 (254 - 2.54 S))`` MPa (A. N. Gent,
    "On the relation between indentation hardness and Young's modulus",
    Trans. Inst. Rubber Ind. 34, 46-57, 1958), for 40 < S < 95 or so.
    """
    s = v.number("shore_a", shore_a, lo=0.0, hi=100.0, hi_open=True)
    return 0.0981 * (56 + 7.62336 * s) / (0.137505 * (254 - 2.54 * s)) * 1e6


MATERIALS: dict[str, ElasticMaterial] = {
    # Smooth-On Ecoflex 00-30 technical bulletin: 100 % tensile modulus 10 psi
    # (69 kPa). Rubber is nearly incompressible; nu at the P1 cap.
    "ecoflex_0030": ElasticMaterial("ecoflex_0030", 69e3, POISSON_MAX),
    # Sylgard 184 (10:1) cured at 25 C: E = 1.32 MPa (Johnston et al.,
    # "Mechanical characterization of bulk Sylgard 184 for microfluidics and
    # microengineering", J. Micromech. Microeng. 24, 035017, 2014; 1.3-3 MPa
    # with the cure temperature).
    "pdms_sylgard184": ElasticMaterial("pdms_sylgard184", 1.32e6, POISSON_MAX),
    # Closed-cell silicone sponge, medium firmness: 8-24 psi compression force
    # deflection at 25 % (Rogers BISCO HT-800 data sheet); the 16 psi middle
    # gives a secant modulus 110 kPa / 0.25 = 0.44 MPa. Foams are compressible:
    # nu ~ 1/3 (Gibson and Ashby, "Cellular Solids", 2nd ed., 1997, ch. 5).
    "silicone_foam": ElasticMaterial("silicone_foam", 0.44e6, 1.0 / 3.0),
    # A Shore 85A thermoplastic polyurethane film: E from Gent's relation
    # (13.2 MPa); nu 0.45 for a slightly compressible polyurethane elastomer.
    "tpu_cover": ElasticMaterial("tpu_cover", gent_young_from_shore_a(85.0), 0.45),
}
"""Named materials: name -> ElasticMaterial (sources in the comments)."""


def elastic_material(name: str | ElasticMaterial) -> ElasticMaterial:
    """A material by preset name (or the material itself)."""
    if isinstance(name, ElasticMaterial):
        return name
    if not isinstance(name, str) or name not in MATERIALS:
        raise UnknownNameError("ElasticMaterial.name", name, list(MATERIALS))
    return MATERIALS[name]
