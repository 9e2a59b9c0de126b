"""Materials: optical (NIR), radar and electrical properties, and a named library.

Values are representative figures for the sensing bands twinsense models
(850-940 nm NIR, 60-80 GHz radar, kHz-MHz capacitive and inductive); users
override them with their own measured materials through :func:`register_material` or the
``materials`` section of a scenario.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from twinsense import validation as V
from twinsense.errors import ConfigError, UnknownNameError

CONDUCTOR_KINDS = ("none", "grounded", "floating")


@dataclass(frozen=True)
class Material:
    """Surface and bulk properties of an object.

    Attributes
    ----------
    name : str
    nir_reflectance : float
        Diffuse (Lambertian) NIR albedo, 0..1.
    nir_specular : float
        Share of reflected NIR light in the specular lobe, 0..1.
    nir_retroreflective : bool
        Retro-reflector (ir_reflector tape): light returns towards the source
        with a high gain, which saturates ToF pixels.
    radar_reflectivity : float
        Normalised radar cross-section per unit area (sigma0, linear), >= 0.
    radar_specular : float
        Share of the radar return in the specular lobe, 0..1.
    permittivity : float
        Relative permittivity (>= 1) at the capacitive sensing frequency.
    conductor : str
        "none" (dielectric), "grounded" (held at 0 V) or "floating"
        (isolated equipotential with zero net charge).
    sigma : float
        Electrical conductivity [S/m], >= 0 (0: not a metal; eddy currents
        for inductive sensing).
    mu_r : float
        Relative magnetic permeability (>= 1; the effective low-field value
        for ferromagnetic metals).
    """

    name: str
    nir_reflectance: float = 0.5
    nir_specular: float = 0.0
    nir_retroreflective: bool = False
    radar_reflectivity: float = 0.1
    radar_specular: float = 0.0
    permittivity: float = 1.0
    conductor: str = "none"
    sigma: float = 0.0
    mu_r: float = 1.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError("Material.name", self.name, "a non-empty string")
        p = f"Material[{self.name}]"
        V.number(f"{p}.nir_reflectance", self.nir_reflectance, lo=0, hi=1)
        V.number(f"{p}.nir_specular", self.nir_specular, lo=0, hi=1)
        V.number(f"{p}.radar_reflectivity", self.radar_reflectivity, lo=0)
        V.number(f"{p}.radar_specular", self.radar_specular, lo=0, hi=1)
        V.number(f"{p}.permittivity", self.permittivity, lo=1.0, unit="relative, vacuum = 1")
        V.number(f"{p}.sigma", self.sigma, lo=0.0, hi=1e9, unit="S/m")
        V.number(f"{p}.mu_r", self.mu_r, lo=1.0, hi=1e6, unit="relative, vacuum = 1")
        if not isinstance(self.nir_retroreflective, bool):
            raise ConfigError(f"{p}.nir_retroreflective", self.nir_retroreflective, "true or false")
        if self.conductor not in CONDUCTOR_KINDS:
            raise ConfigError(f"{p}.conductor", self.conductor, "one of: " + ", ".join(CONDUCTOR_KINDS))

    def to_dict(self) -> dict:
        return asdict(self)


_LIBRARY: dict[str, Material] = {}


def register_material(material: Material, *, overwrite: bool = False) -> Material:
    """Add a user material to the named library."""
    if not isinstance(material, Material):
        raise ConfigError("material", material, "a twinsense.Material")
    if material.name in _LIBRARY and not overwrite:
        raise ConfigError("material.name", material.name,
                          "a name not yet in the library (or overwrite=True)")
    _LIBRARY[material.name] = material
    return material


def get_material(name: str | Material) -> Material:
    """Look a material up by name (a Material passes through)."""
    if isinstance(name, Material):
        return name
    if not isinstance(name, str) or name not in _LIBRARY:
        raise UnknownNameError("material", name, list(_LIBRARY))
    return _LIBRARY[name]


def material_names() -> list[str]:
    return sorted(_LIBRARY)


# Conductivities at 20 deg C (ASM Metals Handbook resistivities): mild steel
# (low-carbon, AISI 1010, 0.143 uOhm m) 7.0e6 S/m; stainless steel 304
# (0.72 uOhm m) 1.39e6 S/m; aluminium (1xxx / 6063, ~0.029 uOhm m) 3.5e7 S/m;
# brass (C26000 cartridge brass, 28 % IACS) 1.5e7 S/m (1.6e7 by the IACS
# figure); copper 5.8e7 S/m (100 % IACS, the definition). Permeability of
# mild steel: the effective low-field (initial) value of low-carbon steel is
# ~100-200 (Bozorth, Ferromagnetism, 1951); 100 is taken. Annealed 304 is
# austenitic, mu_r ~1.0. "metal" (and "floating_metal") are taken as mild steel.
_MILD_STEEL = (7.0e6, 100.0)
# NIR albedo at 850 nm: Bulczak et al. 2018 and common ToF target charts;
# radar sigma0 at 60 GHz: order-of-magnitude values for smooth/rough surfaces;
# permittivities: handbook values at kHz-MHz.
for _m in (
    Material("metal", 0.55, 0.6, False, 1.0, 0.9, 1.0, "grounded", *_MILD_STEEL),
    Material("aluminium", 0.70, 0.7, False, 1.0, 0.9, 1.0, "grounded", 3.5e7, 1.0),
    Material("floating_metal", 0.55, 0.6, False, 1.0, 0.9, 1.0, "floating", *_MILD_STEEL),
    Material("mild_steel", 0.55, 0.6, False, 1.0, 0.9, 1.0, "grounded", *_MILD_STEEL),
    Material("stainless_steel", 0.60, 0.7, False, 1.0, 0.9, 1.0, "grounded", 1.39e6, 1.0),
    Material("brass", 0.65, 0.7, False, 1.0, 0.9, 1.0, "grounded", 1.5e7, 1.0),
    Material("copper", 0.65, 0.7, False, 1.0, 0.9, 1.0, "grounded", 5.8e7, 1.0),
    Material("wood", 0.45, 0.05, False, 0.08, 0.2, 2.5, "none"),
    Material("drywall", 0.80, 0.02, False, 0.05, 0.1, 2.8, "none"),
    Material("concrete", 0.35, 0.02, False, 0.15, 0.1, 5.0, "none"),
    Material("plastic", 0.60, 0.10, False, 0.03, 0.3, 3.0, "none"),
    Material("glass", 0.08, 0.9, False, 0.2, 0.8, 6.0, "none"),
    Material("fabric", 0.55, 0.0, False, 0.02, 0.0, 1.6, "none"),
    # Skin: radar_specular is the mirror's power reflectance (second bounces): Fresnel at normal
    # incidence for Gabriel et al.'s (Phys. Med. Biol. 41, 1996) dry skin, eps = 7.98 - 10.90j at
    # 60 GHz, |(1 - n) / (1 + n)|^2 = 0.378 (0.34 at 77 GHz); skin is smooth at 5 mm. NIR: 0.4-0.6
    # at 850-940 nm. A conductor to capacitive sensing (100-200 pF to ground: taken as grounded).
    Material("human_skin", 0.50, 0.05, False, 0.3, 0.38, 40.0, "grounded"),
    Material("ir_reflector", 0.95, 0.0, True, 0.05, 0.2, 3.0, "none"),
    Material("corner_reflector", 0.55, 0.6, False, 100.0, 1.0, 1.0, "grounded"),
    Material("silicone", 0.6, 0.05, False, 0.02, 0.1, 2.8, "none"),
    Material("air", 0.0, 0.0, False, 0.0, 0.0, 1.0, "none"),
):
    register_material(_m)
# Short aliases users reach for.
_LIBRARY["human"] = Material(**{**asdict(_LIBRARY["human_skin"]), "name": "human"})
_LIBRARY["radar_corner_reflector"] = Material(
    **{**asdict(_LIBRARY["corner_reflector"]), "name": "radar_corner_reflector"})
