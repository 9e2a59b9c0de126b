"""Configuration of a Hall / magnetoresistive sensor (or an array of identical ones)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError

OUTPUTS = ("analog", "digital", "switch")
SWITCH_MODES = ("unipolar", "omnipolar", "latch")
AXIS_SETS = ("x", "y", "z", "xy", "xyz")
B_LIMIT = 100.0  # [T] bound on any field figure of a config (far above any permanent magnet)

#: Ambient (Earth) field, world frame (x east, y north, z up): 50 uT at 64 deg inclination
#: (mid-European latitudes), pointing north and down.
EARTH_FIELD = (0.0, 50e-6 * float(np.cos(np.deg2rad(64.0))), -50e-6 * float(np.sin(np.deg2rad(64.0))))


@dataclass(frozen=True)
class HallSwitch:
    """Comparator with hysteresis on the field along the sensed axis.

    ``unipolar``: operates at B >= b_op, releases at B <= b_rp (0 <= b_rp < b_op);
    ``omnipolar``: the same on |B|; ``latch``: operates at B >= b_op, releases at
    B <= b_rp with b_rp < 0 < b_op. Between the two points the output holds.
    """

    b_op: float = 0.02
    b_rp: float = 0.015
    mode: str = "unipolar"

    def __post_init__(self):
        V.choice("switch.mode", self.mode, SWITCH_MODES)
        op = V.number("switch.b_op", self.b_op, lo=0.0, lo_open=True, hi=B_LIMIT, unit="T")
        rp = V.number("switch.b_rp", self.b_rp, lo=-B_LIMIT, hi=B_LIMIT, unit="T")
        if self.mode == "latch":
            if not rp < 0:
                raise ConfigError("switch.b_rp", self.b_rp, "a release point < 0 T for a latch")
        elif not 0 <= rp < op:
            raise ConfigError("switch.b_rp", self.b_rp, f"a release point in [0, b_op = {op:g}) T")
        object.__setattr__(self, "b_op", op)
        object.__setattr__(self, "b_rp", rp)

    @property
    def hysteresis(self) -> float:
        """b_op - b_rp [T]."""
        return self.b_op - self.b_rp


@dataclass(frozen=True)
class MagneticConfig:
    """A magnetic field sensor, or an array of identical ones read together.

    Parameters
    ----------
    positions : ((x, y, z), ...) [m]
        Sensing elements in the sensor frame (one row per element; an array
        of n elements is one sensor object, read in one vectorised call).
    axes : "x", "y", "z", "xy" or "xyz"
        Sensor-frame axes each element measures.
    output : "analog", "digital" or "switch"
        analog: volts quiescent_voltage + sensitivity B, clamped to
        [output_min, output_max]; digital: signed codes round(sensitivity B)
        of ``adc_bits`` bits; switch: a comparator with hysteresis (``switch``)
        on the first axis.
    sensitivity : float or per-axis tuple
        [V/T] (analog) or [LSB/T] (digital); unused for a switch.
    b_max : float [T]
        Linear range: the sensed field is clipped to +-b_max (front-end saturation).
    noise_rms : float [T]
        Input-referred white noise per axis and sample (independent per element, axis, sample).
    offset : (3,) [T]
        Input-referred offset per sensor-frame axis at the reference temperature.
    offset_tc : float [T/K]
        Offset drift (added on every axis) per kelvin away from the reference temperature.
    sensitivity_tc : float [1/K]
        Relative gain drift per kelvin; the device still reports with its nominal sensitivity.
    temperature, reference_temperature : float [degC]
        Operating temperature of the device, and the one its figures refer to.
    ambient_field : (3,) [T]
        Uniform background field at the site, world frame (default: the Earth's).
    soft_iron : bool
        Add the approximate field of permeable objects magnetised by the magnets and the
        ambient field (one induced dipole each, twinsense.magnetic.soft_iron).
    frame_rate : float [Hz]
    """

    positions: tuple = ((0.0, 0.0, 0.0),)
    axes: str = "xyz"
    output: str = "digital"
    sensitivity: float | tuple = 7.7e3
    b_max: float = 0.16
    noise_rms: float = 0.0
    offset: tuple = (0.0, 0.0, 0.0)
    offset_tc: float = 0.0
    sensitivity_tc: float = 0.0
    temperature: float = 25.0
    reference_temperature: float = 25.0
    adc_bits: int = 12
    quiescent_voltage: float = 2.5
    output_min: float = 0.0
    output_max: float = 5.0
    switch: HallSwitch | None = None
    ambient_field: tuple = EARTH_FIELD
    soft_iron: bool = False
    frame_rate: float = 1000.0

    def __post_init__(self):
        pos = V.array("MagneticConfig.positions", self.positions, (None, 3), "m")
        if len(pos) == 0 or np.abs(pos).max() > V.LENGTH_MAX:
            raise ConfigError("MagneticConfig.positions", self.positions, "one or more (x, y, z) rows within 10 km")
        object.__setattr__(self, "positions", tuple(tuple(float(v) for v in row) for row in pos))
        V.choice("MagneticConfig.axes", self.axes, AXIS_SETS)
        V.choice("MagneticConfig.output", self.output, OUTPUTS)
        na = len(self.axes)
        sens = np.atleast_1d(np.asarray(self.sensitivity, dtype=float)) if not isinstance(
            self.sensitivity, (str, bool)) else None
        if sens is None or sens.shape not in ((1,), (na,)) or not np.all(np.isfinite(sens)) or np.any(sens <= 0):
            raise ConfigError("MagneticConfig.sensitivity", self.sensitivity,
                              f"a positive number or {na} positive numbers (one per axis) [V/T or LSB/T]")
        object.__setattr__(self, "sensitivity", tuple(float(v) for v in np.broadcast_to(sens, (na,))))
        V.number("MagneticConfig.b_max", self.b_max, lo=0.0, lo_open=True, hi=B_LIMIT, unit="T")
        V.number("MagneticConfig.noise_rms", self.noise_rms, lo=0.0, hi=B_LIMIT, unit="T")
        object.__setattr__(self, "offset", tuple(float(v) for v in V.bounded_vector(
            "MagneticConfig.offset", self.offset, B_LIMIT, "T")))
        V.number("MagneticConfig.offset_tc", self.offset_tc, lo=-1.0, hi=1.0, unit="T/K")
        V.number("MagneticConfig.sensitivity_tc", self.sensitivity_tc, lo=-0.01, hi=0.01, unit="1/K")
        V.number("MagneticConfig.temperature", self.temperature, lo=-273.15, hi=1000.0, unit="degC")
        V.number("MagneticConfig.reference_temperature", self.reference_temperature, lo=-273.15, hi=1000.0,
                 unit="degC")
        V.integer("MagneticConfig.adc_bits", self.adc_bits, lo=2, hi=32)
        V.number("MagneticConfig.quiescent_voltage", self.quiescent_voltage, lo=-1e3, hi=1e3, unit="V")
        V.number("MagneticConfig.output_min", self.output_min, lo=-1e3, hi=1e3, unit="V")
        V.number("MagneticConfig.output_max", self.output_max, lo=-1e3, hi=1e3, unit="V")
        if not self.output_min < self.output_max:
            raise ConfigError("MagneticConfig.output_max", self.output_max, f"> output_min = {self.output_min:g} V")
        if self.output == "switch" and not isinstance(self.switch, HallSwitch):
            raise ConfigError("MagneticConfig.switch", self.switch, "a HallSwitch when output is 'switch'")
        if self.switch is not None and not isinstance(self.switch, HallSwitch):
            raise ConfigError("MagneticConfig.switch", self.switch, "a HallSwitch or None")
        object.__setattr__(self, "ambient_field", tuple(float(v) for v in V.bounded_vector(
            "MagneticConfig.ambient_field", self.ambient_field, B_LIMIT, "T")))
        if not isinstance(self.soft_iron, bool):
            raise ConfigError("MagneticConfig.soft_iron", self.soft_iron, "true or false")
        V.positive("MagneticConfig.frame_rate", self.frame_rate, "Hz")

    @property
    def n_elements(self) -> int:
        return len(self.positions)

    @property
    def axis_index(self) -> np.ndarray:
        """Sensor-frame axis index (0, 1, 2) of each measured axis."""
        return np.array(["xyz".index(a) for a in self.axes])

    def to_dict(self) -> dict:
        return asdict(self)
