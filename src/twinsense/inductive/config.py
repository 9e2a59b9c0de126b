"""Configuration of an inductive proximity sensor."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.inductive.fem import MeshSpec
from twinsense.inductive.head import HeadGeometry
from twinsense.inductive.table import TableSpec

#: Reference metals of the response tables: (name, conductivity [S/m], relative permeability).
#: Values as in twinsense.scene.materials (sources cited there).
TABLE_MATERIALS: tuple[tuple[str, float, float], ...] = (
    ("mild_steel", 7.0e6, 100.0),
    ("stainless_steel", 1.39e6, 1.0),
    ("brass", 1.5e7, 1.0),
    ("aluminium", 3.5e7, 1.0),
    ("copper", 5.8e7, 1.0),
)

#: Table distances as multiples of s_n, and disc radii as multiples of the standard target's equal-area radius.
DISTANCE_FACTORS = (0.15, 0.3, 0.5, 0.7, 0.9, 1.1, 1.4, 2.0)
RADIUS_FACTORS = (0.5, 1.0, 1.6)


@dataclass(frozen=True)
class InductiveConfig:
    """An inductive proximity switch.

    Attributes
    ----------
    head : HeadGeometry — coil, ferrite core and housing.
    frequency : oscillator frequency [Hz] (100 kHz - 1 MHz).
    rated_distance : s_n [m], where the standard target switches at ``temperature_ref``.
    hysteresis : H, release at s_n (1 + H) (fraction, datasheets: typ. 5 %, <= 15 %).
    coil_q : quality factor Q0 of the coil in its core (winding and core losses).
    frame_rate : update rate [Hz] (default: the datasheet's switching frequency).
    switching_frequency : the datasheet's maximum switching frequency [Hz].
    repeatability : datasheet repeat accuracy as a fraction of s_n, taken as 3 sigma of the switching distance.
    temperature : ambient temperature [deg C].
    temperature_ref : calibration temperature [deg C].
    temperature_coefficient : relative drift of the switching distance per kelvin [1/K]; datasheets bound
        the drift by +-10 % over -25..70 deg C, i.e. |k_T| <= 0.1 / 47 K = 2.1e-3 / K.
    target_thickness : plate thickness [m] the tables assume (IEC 60947-5-2 standard target: 1 mm).
    sectors : rays per ring of the sensing-face ray pattern.
    mesh : FEM resolution of the response tables.
    """

    head: HeadGeometry
    frequency: float
    rated_distance: float
    hysteresis: float = 0.05
    coil_q: float = 80.0
    frame_rate: float = 1000.0
    switching_frequency: float = 1000.0
    repeatability: float = 0.02
    temperature: float = 23.0
    temperature_ref: float = 23.0
    temperature_coefficient: float = 1.0e-3
    target_thickness: float = 1e-3
    sectors: int = 8
    mesh: MeshSpec = field(default_factory=MeshSpec)

    def __post_init__(self):
        if not isinstance(self.head, HeadGeometry):
            raise ConfigError("InductiveConfig.head", self.head, "a HeadGeometry")
        V.number("InductiveConfig.frequency", self.frequency, lo=1e4, hi=2e6, unit="Hz (10 kHz - 2 MHz)")
        V.number("InductiveConfig.rated_distance", self.rated_distance, lo=1e-4, hi=0.2, unit="m")
        V.number("InductiveConfig.hysteresis", self.hysteresis, lo=0.0, hi=0.5, lo_open=True, unit="fraction of s_n")
        V.number("InductiveConfig.coil_q", self.coil_q, lo=2.0, hi=1000.0)
        V.positive("InductiveConfig.frame_rate", self.frame_rate, "Hz")
        V.positive("InductiveConfig.switching_frequency", self.switching_frequency, "Hz")
        V.number("InductiveConfig.repeatability", self.repeatability, lo=0.0, hi=0.5, unit="fraction of s_n")
        V.number("InductiveConfig.temperature", self.temperature, lo=-60.0, hi=150.0, unit="deg C")
        V.number("InductiveConfig.temperature_ref", self.temperature_ref, lo=-60.0, hi=150.0, unit="deg C")
        V.number("InductiveConfig.temperature_coefficient", self.temperature_coefficient, lo=-5e-3, hi=5e-3,
                 unit="1/K (datasheets: drift <= 10 % over 47 K)")
        V.number("InductiveConfig.target_thickness", self.target_thickness, lo=1e-5, hi=0.05, unit="m")
        if isinstance(self.sectors, bool) or not isinstance(self.sectors, int) or not 1 <= self.sectors <= 64:
            raise ConfigError("InductiveConfig.sectors", self.sectors, "an integer 1..64")
        if not isinstance(self.mesh, MeshSpec):
            raise ConfigError("InductiveConfig.mesh", self.mesh, "a MeshSpec")

    @property
    def standard_target_side(self) -> float:
        """Side [m] of the IEC 60947-5-2 standard target: the face diameter or 3 s_n, whichever is larger."""
        return max(2 * self.head.face_radius, 3 * self.rated_distance)

    @property
    def standard_radius(self) -> float:
        """Radius [m] of the disc with the standard target's area (the axisymmetric stand-in)."""
        return self.standard_target_side / np.sqrt(np.pi)

    def table_spec(self, materials=TABLE_MATERIALS) -> TableSpec:
        sn, a = self.rated_distance, self.standard_radius
        return TableSpec(self.head, float(self.frequency), tuple(float(f * sn) for f in DISTANCE_FACTORS),
                         tuple(float(f * a) for f in RADIUS_FACTORS), tuple(materials),
                         float(self.target_thickness), self.mesh)

    def with_overrides(self, **overrides) -> InductiveConfig:
        names = {f.name for f in fields(self)}
        bad = [k for k in overrides if k not in names]
        if bad:
            raise ConfigError("sensor.overrides", bad[0], "one of: " + ", ".join(sorted(names)))
        return replace(self, **overrides)

    def to_dict(self) -> dict:
        return asdict(self)
