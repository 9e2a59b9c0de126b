"""LiDAR configuration: scan pattern, beam, pulse, radiometry, receiver, returns.

Two scan patterns:

- :class:`RotatingScan`: a spinning head with a column of beams (Velodyne,
  Ouster). A revolution is one frame; ``columns`` firing groups per
  revolution, evenly spaced in time (period ``1 / (frame_rate * columns)``),
  beam ``b`` of a column fires ``firing_offsets[b]`` after the column starts
  and points at the head's azimuth at that instant (plus a fixed
  per-beam azimuth offset).
- :class:`RosetteScan`: a single beam steered by two counter-rotating
  Risley prisms (Livox). The deflection is the sum of two rotating vectors of
  equal length, a rosette ``|delta| = theta_max |cos((w1 - w2) t / 2)|`` that
  does not repeat when w1 / w2 is irrational. Points at ``point_rate``;
  the pattern runs on the absolute clock, so successive frames cover new
  paths.

Angles: azimuth positive to the right, elevation positive up, in the sensor's
optical frame (x right, y down, z forward; the spin axis is -y, "up").
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from twinsense import validation as V
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError

RETURN_MODES = ("strongest", "first", "last", "dual", "multi")


def _angles(field_name: str, value, n: int | None = None, lo: float = -90.0, hi: float = 90.0) -> tuple:
    arr = V.array(field_name, value, (n,), "deg")
    if arr.size == 0:
        raise ConfigError(field_name, value, "at least one angle [deg]")
    if np.any(arr < lo) or np.any(arr > hi):
        raise ConfigError(field_name, value, f"angles in [{lo:g}, {hi:g}] deg")
    return tuple(float(a) for a in arr)


@dataclass(frozen=True)
class RotatingScan:
    """Spinning multi-beam head.

    Attributes
    ----------
    elevations_deg : (B,) float
        Beam elevations, positive up [deg]. Rows of a column follow this order
        (the presets give them ascending: ring 0 is the lowest beam).
    columns : int
        Firing groups (azimuth steps) per revolution.
    firing_offsets : (B,) float
        Firing time of each beam after its column starts [s], each below the
        column period.
    azimuth_offsets_deg : (B,) float
        Fixed azimuth offset of each beam [deg] (a unit's calibrated beam
        azimuths); zeros for none.
    beam_origin_radius : float
        Distance of the beams' origin from the spin axis [m], along the beam's
        azimuth (Ouster: 15.806 mm); ranges are measured from there.
    """

    elevations_deg: tuple = (0.0,)
    columns: int = 1024
    firing_offsets: tuple | None = None
    azimuth_offsets_deg: tuple | None = None
    beam_origin_radius: float = 0.0

    def __post_init__(self):
        el = _angles("RotatingScan.elevations_deg", self.elevations_deg)
        object.__setattr__(self, "elevations_deg", el)
        b = len(el)
        V.integer("RotatingScan.columns", self.columns, lo=1, hi=100_000)
        fo = (0.0,) * b if self.firing_offsets is None else self.firing_offsets
        fo = V.array("RotatingScan.firing_offsets", fo, (b,), "s")
        if np.any(fo < 0):
            raise ConfigError("RotatingScan.firing_offsets", self.firing_offsets, "times >= 0 [s]")
        object.__setattr__(self, "firing_offsets", tuple(float(x) for x in fo))
        ao = (0.0,) * b if self.azimuth_offsets_deg is None else self.azimuth_offsets_deg
        object.__setattr__(self, "azimuth_offsets_deg",
                           _angles("RotatingScan.azimuth_offsets_deg", ao, b, -180.0, 180.0))
        V.number("RotatingScan.beam_origin_radius", self.beam_origin_radius, lo=0, hi=1.0, unit="m")

    @property
    def beams(self) -> int:
        return len(self.elevations_deg)

    def firings(self, frame_rate: float) -> int:
        return self.columns * self.beams


@dataclass(frozen=True)
class RosetteScan:
    """Two-prism (Risley) non-repetitive scan.

    Attributes
    ----------
    fov_deg : float
        Full circular field of view [deg]; the deflection reaches fov / 2.
    point_rate : float
        Points per second [Hz].
    prism_rpm : (2,) float
        Rotation speeds of the two prisms [rev/min], opposite signs for the
        rosette (same signs give a spiral family).
    """

    fov_deg: float = 38.4
    point_rate: float = 100_000.0
    prism_rpm: tuple = (7294.0, -4664.0)

    def __post_init__(self):
        V.number("RosetteScan.fov_deg", self.fov_deg, lo=0, hi=180, lo_open=True, hi_open=True, unit="deg")
        V.number("RosetteScan.point_rate", self.point_rate, lo=1.0, hi=1e7, unit="Hz")
        rpm = V.vector("RosetteScan.prism_rpm", self.prism_rpm, 2, "rev/min")
        if rpm[0] == rpm[1]:
            raise ConfigError("RosetteScan.prism_rpm", self.prism_rpm, "two different speeds [rev/min]")
        object.__setattr__(self, "prism_rpm", (float(rpm[0]), float(rpm[1])))

    @property
    def beams(self) -> int:
        return 1

    def firings(self, frame_rate: float) -> int:
        return max(1, round(self.point_rate / frame_rate))


@dataclass(frozen=True)
class LidarConfig:
    """A pulsed time-of-flight LiDAR.

    Scan
    ----
    scan : RotatingScan or RosetteScan
    frame_rate : float
        Frames per second [Hz]; a rotating head makes one revolution per frame.

    Beam and pulse
    --------------
    wavelength : float
        Laser wavelength [m] (sets the fog extinction).
    divergence_deg : (2,) float
        Full beam divergence at half maximum (FWHM), horizontal and vertical [deg].
    subrays : int
        n: each beam is cast as n x n sub-rays at the Gauss-Hermite nodes of
        its Gaussian profile, weighted by the quadrature weights (1: one ray).
    pulse_fwhm : float
        Laser pulse duration at half maximum [s]; the pulse is Gaussian.

    Radiometry (LiDAR equation, Lambertian target filling the beam)
    ---------------------------------------------------------------
    peak_power : float
        Emitted peak power [W].
    aperture_area : float
        Receiver aperture A_r [m^2].
    optics_efficiency : float
        Transmit x receive optics efficiency eta, 0..1.
    blind_range, full_overlap_range : float
        Overlap of the laser and the receiver's field of view: 0 up to
        ``blind_range``, 1 from ``full_overlap_range`` [m], smooth in between.
    max_range : float
        Longest range the device reports [m].
    retroreflector_gain, specular_exponent : float
        Return of retro-reflectors relative to a white Lambertian surface, and
        the Phong exponent of materials with a specular share.
    fog_visibility : float
        Meteorological visibility [m] (inf: clear air); extinction by the
        Kim model at ``wavelength``.
    rain_rate : float
        Rain rate [mm/h]; extinction 1.076 R^0.67 dB/km (Carbonneau, ITU-R P.1814).

    Receiver
    --------
    noise_power : float
        Noise-equivalent power: standard deviation of the receiver noise
        referred to optical input power [W].
    detection_snr : float
        Detection threshold in units of the noise standard deviation.
    saturation_power : float
        Received power at which the receiver clips [W].
    range_walk : bool
        Saturated echoes are timed at the leading-edge crossing of the clip
        level (early by sigma_R sqrt(2 ln(P / P_sat))); else at the peak.
    range_noise : float
        Range noise floor, standard deviation [m].
    snr_range_noise : bool
        Add sigma_R / SNR in quadrature (weak echoes are noisier).

    Returns
    -------
    return_mode : str
        ``strongest``, ``first``, ``last``, ``dual`` (strongest and last, the
        second strongest if they coincide) or ``multi`` (the ``max_echoes``
        strongest, in range order).
    max_echoes : int
        Echo slots per firing in a frame (1 for strongest/first/last, 2 for dual).
    motion_slice : float
        Longest time span over which moving objects are posed once [s];
        a point on an object moving at v is off by at most v motion_slice / 2.
    """

    scan: RotatingScan | RosetteScan = field(default_factory=RotatingScan)
    frame_rate: float = 10.0
    wavelength: float = 905e-9
    divergence_deg: tuple = (0.18, 0.18)
    subrays: int = 3
    pulse_fwhm: float = 5e-9
    peak_power: float = 30.0
    aperture_area: float = 5e-4
    optics_efficiency: float = 0.5
    blind_range: float = 0.3
    full_overlap_range: float = 1.0
    max_range: float = 100.0
    retroreflector_gain: float = 300.0
    specular_exponent: float = 30.0
    fog_visibility: float = math.inf
    rain_rate: float = 0.0
    noise_power: float = 5e-9
    detection_snr: float = 5.0
    saturation_power: float = 1e-3
    range_walk: bool = True
    range_noise: float = 0.01
    snr_range_noise: bool = True
    return_mode: str = "strongest"
    max_echoes: int = 1
    motion_slice: float = 1e-3

    def __post_init__(self):
        p = "LidarConfig"
        if not isinstance(self.scan, (RotatingScan, RosetteScan)):
            raise ConfigError(f"{p}.scan", self.scan, "a RotatingScan or a RosetteScan")
        V.number(f"{p}.frame_rate", self.frame_rate, lo=0.1, hi=1000.0, unit="Hz")
        V.number(f"{p}.wavelength", self.wavelength, lo=200e-9, hi=20e-6, unit="m")
        div = V.vector(f"{p}.divergence_deg", self.divergence_deg, 2, "deg")
        if np.any(div < 0) or np.any(div > 10):
            raise ConfigError(f"{p}.divergence_deg", self.divergence_deg, "two FWHM angles in [0, 10] deg")
        object.__setattr__(self, "divergence_deg", (float(div[0]), float(div[1])))
        V.integer(f"{p}.subrays", self.subrays, lo=1, hi=7)
        V.number(f"{p}.pulse_fwhm", self.pulse_fwhm, lo=1e-11, hi=1e-6, unit="s")
        V.positive(f"{p}.peak_power", self.peak_power, "W")
        V.positive(f"{p}.aperture_area", self.aperture_area, "m^2")
        V.number(f"{p}.optics_efficiency", self.optics_efficiency, lo=0, hi=1, lo_open=True)
        V.non_negative(f"{p}.blind_range", self.blind_range, "m")
        V.number(f"{p}.full_overlap_range", self.full_overlap_range, lo=self.blind_range, unit="m, >= blind_range")
        V.number(f"{p}.max_range", self.max_range, lo=self.full_overlap_range, lo_open=True, hi=1e5,
                 unit="m, > full_overlap_range")
        V.number(f"{p}.retroreflector_gain", self.retroreflector_gain, lo=1, hi=1e6)
        V.number(f"{p}.specular_exponent", self.specular_exponent, lo=1, hi=10_000)
        if not (isinstance(self.fog_visibility, (int, float)) and not isinstance(self.fog_visibility, bool)
                and self.fog_visibility >= 50.0):
            raise ConfigError(f"{p}.fog_visibility", self.fog_visibility, "a number >= 50 [m] or inf (clear air)")
        V.number(f"{p}.rain_rate", self.rain_rate, lo=0, hi=500, unit="mm/h")
        V.positive(f"{p}.noise_power", self.noise_power, "W")
        V.number(f"{p}.detection_snr", self.detection_snr, lo=0.5, hi=100)
        V.positive(f"{p}.saturation_power", self.saturation_power, "W")
        if not isinstance(self.range_walk, bool):
            raise ConfigError(f"{p}.range_walk", self.range_walk, "true or false")
        if not isinstance(self.snr_range_noise, bool):
            raise ConfigError(f"{p}.snr_range_noise", self.snr_range_noise, "true or false")
        V.non_negative(f"{p}.range_noise", self.range_noise, "m")
        V.choice(f"{p}.return_mode", self.return_mode, RETURN_MODES)
        V.integer(f"{p}.max_echoes", self.max_echoes, lo=1, hi=8)
        need = {"strongest": 1, "first": 1, "last": 1, "dual": 2}.get(self.return_mode)
        if need is not None and self.max_echoes != need:
            raise ConfigError(f"{p}.max_echoes", self.max_echoes,
                              f"{need} for return_mode '{self.return_mode}' (any 1..8 for 'multi')")
        V.number(f"{p}.motion_slice", self.motion_slice, lo=1e-6, hi=0.1, unit="s")
        n = self.scan.firings(self.frame_rate)
        if n > 2_000_000:
            raise ConfigError(f"{p}.frame_rate", self.frame_rate, "a rate giving at most 2,000,000 firings per frame")
        if isinstance(self.scan, RotatingScan):
            period = 1.0 / (self.frame_rate * self.scan.columns)
            if max(self.scan.firing_offsets) >= period:
                raise ConfigError("RotatingScan.firing_offsets", self.scan.firing_offsets,
                                  f"offsets below the column period 1 / (frame_rate x columns) = {period:.4g} s")

    # --- derived quantities ----------------------------------------------------

    @property
    def n_firings(self) -> int:
        """Beam firings per frame (rows of a frame)."""
        return self.scan.firings(self.frame_rate)

    @property
    def pulse_sigma_range(self) -> float:
        """Standard deviation of the pulse's range profile [m]: c sigma_t / 2, sigma_t = FWHM / (2 sqrt(2 ln 2))."""
        return SPEED_OF_LIGHT * self.pulse_fwhm / (2.0 * math.sqrt(2.0 * math.log(2.0))) / 2.0

    @property
    def pulse_resolution(self) -> float:
        """Two equal echoes closer than this [m] merge into one (2 sigma_R: the sum of two equal
        Gaussians is bimodal only when their centres are more than two standard deviations apart)."""
        return 2.0 * self.pulse_sigma_range

    def to_dict(self) -> dict:
        d = asdict(self)
        d["scan"] = {"type": type(self.scan).__name__, **asdict(self.scan)}
        if math.isinf(self.fog_visibility):
            d["fog_visibility"] = "inf"
        return d

    def with_overrides(self, **overrides) -> LidarConfig:
        """A copy with config or scan fields replaced (scan fields by name, e.g. ``columns``)."""
        scan_fields = set(type(self.scan).__dataclass_fields__)
        scan_over = {k: overrides.pop(k) for k in list(overrides) if k in scan_fields}
        bad = [k for k in overrides if k not in LidarConfig.__dataclass_fields__]
        if bad:
            allowed = sorted((set(LidarConfig.__dataclass_fields__) - {"scan"}) | scan_fields)
            raise ConfigError("sensor.overrides", bad[0], "one of: " + ", ".join(allowed))
        scan = replace(self.scan, **scan_over) if scan_over else self.scan
        return replace(self, scan=scan, **overrides)
