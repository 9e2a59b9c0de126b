"""Named LiDAR configurations.

- ``velodyne_vlp16``: Velodyne VLP-16 (Puck) as its user manual describes
  it: 16 lasers at -15..+15 deg every 2 deg, fired one after another every
  2.304 us in the interleaved channel order (-15, 1, -13, 3, ..., -1, 15 deg
  for channels 0..15), 903 nm, 100 m. Points per laser per revolution as the
  manual's table: 18,000 / (revolutions per second), i.e. 1800 at 10 Hz
  (0.2 deg, 28,800 points per revolution). The manual's firing cycle is
  55.296 us, so a real unit fires ~1808 times in 0.1 s and its azimuth grid
  drifts from frame to frame; here a revolution holds exactly 1800 columns,
  spaced 1 / (10 Hz x 1800) = 55.56 us, and within a column the lasers keep
  their 2.304 us spacing (each laser points where the head is when it fires,
  the manual's azimuth interpolation). Frame rates 5-20 Hz give 3600-900
  columns. Beam divergence 3.0 x 1.5 mrad (H x V).
- ``ouster_os1_64``: Ouster OS1-64 with uniform beam spacing: 64 beams over a
  45 deg vertical field of view, elevations -22.5..+22.5 deg in 63 equal steps
  of 0.714 deg (ring 0 is the lowest beam; Ouster's own channel 0 is the
  highest), zero beam azimuth offsets (a unit's calibrated
  ``beam_azimuth_angles`` can be given as ``azimuth_offsets_deg``), the
  15.806 mm lidar-origin-to-beam-origin offset, all beams of a column fired
  together, 1024 columns at 10 Hz (``columns=512/2048``, ``frame_rate=20``
  for the other modes), 865 nm, 120 m.
- ``livox_mid40``: a Livox Mid-40-like two-prism rosette scanner: 38.4 deg
  circular field of view, 100,000 points/s, prisms at 7294 and -4664 rpm (an
  incommensurate pair; Livox does not publish the speeds), 905 nm, 260 m,
  divergence 0.03 x 0.28 deg. At 10 Hz a frame holds 10,000 points.

Radiometric figures that the makers do not publish (peak power, receiver
aperture, efficiency, noise, saturation, overlap, pulse width 5 ns) are
representative. The receiver noise of each preset is tied to its published
range: a Lambertian target of the stated reflectance facing the sensor at
the stated range is detected half of the time (VLP-16: 80 % at 120 m, so an
80 % target is seen to its 100 m gate and a 10 % one to ~42 m; OS1-64: 80 %
at 140 m, 10 % at ~50 m; Mid-40: 80 % at 260 m, 10 % at ~92 m, the data
sheet's 90 m). Saturation is set where a white (80 %) wall facing the sensor
saturates closer than 1 m, so a retro-reflector (gain 300) saturates to
~17 m, as the units do.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from twinsense import validation as V
from twinsense.errors import UnknownNameError
from twinsense.lidar.config import LidarConfig, RosetteScan, RotatingScan
from twinsense.lidar.radiometry import noise_power_for

#: VLP-16 channel elevations in firing order (user manual, table "laser ID vs vertical angle").
VLP16_CHANNEL_ELEVATIONS_DEG = (-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15)
VLP16_FIRING_INTERVAL = 2.304e-6  # [s] between two lasers of a firing sequence
VLP16_FIRING_CYCLE = 55.296e-6  # [s] 16 firings + recharge (the device's cycle; see the module notes)


def _radiometry(peak_power: float, aperture_area: float, eta: float, ref_range: float, ref_reflectance: float,
                detection_snr: float = 5.0) -> dict:
    """Receiver noise tied to the published range; saturation of an 80 % wall at 1 m."""
    k = peak_power * aperture_area * eta / np.pi
    return {"peak_power": peak_power, "aperture_area": aperture_area, "optics_efficiency": eta,
            "detection_snr": detection_snr,
            "noise_power": noise_power_for(ref_range, ref_reflectance, detection_snr, peak_power, aperture_area, eta),
            "saturation_power": k * 0.8 / 1.0 ** 2}


def _vlp16() -> LidarConfig:
    elev = tuple(float(e) for e in range(-15, 16, 2))
    channel = [VLP16_CHANNEL_ELEVATIONS_DEG.index(e) for e in elev]
    scan = RotatingScan(elev, 1800, tuple(c * VLP16_FIRING_INTERVAL for c in channel))
    return LidarConfig(scan, 10.0, wavelength=903e-9, divergence_deg=(0.172, 0.086), subrays=3, pulse_fwhm=5e-9,
                       blind_range=0.4, full_overlap_range=1.0, max_range=100.0, range_noise=0.015,
                       **_radiometry(30.0, 4.9e-4, 0.5, 120.0, 0.8))


def _os1_64() -> LidarConfig:
    scan = RotatingScan(tuple(np.linspace(-22.5, 22.5, 64)), 1024, beam_origin_radius=0.015806)
    return LidarConfig(scan, 10.0, wavelength=865e-9, divergence_deg=(0.18, 0.18), subrays=3, pulse_fwhm=5e-9,
                       blind_range=0.3, full_overlap_range=0.8, max_range=120.0, range_noise=0.015,
                       **_radiometry(20.0, 4.0e-4, 0.5, 140.0, 0.8))


def _mid40() -> LidarConfig:
    return LidarConfig(RosetteScan(38.4, 100_000.0, (7294.0, -4664.0)), 10.0, wavelength=905e-9,
                       divergence_deg=(0.03, 0.28), subrays=3, pulse_fwhm=5e-9, blind_range=1.0,
                       full_overlap_range=1.5, max_range=260.0, range_noise=0.02,
                       **_radiometry(40.0, 7.0e-4, 0.5, 260.0, 0.8))


def _vlp16_overrides(overrides: dict) -> dict:
    # The manual's points per laser per revolution follow the spin rate: 18,000 / rps.
    if "frame_rate" in overrides and "columns" not in overrides:
        f = V.number("LidarConfig.frame_rate", overrides["frame_rate"], lo=5.0, hi=20.0, unit="Hz (300-1200 rpm)")
        overrides = {**overrides, "columns": round(18000.0 / f)}
    return overrides


#: Named configurations: name -> (config builder, description).
LIDAR_PRESETS: dict[str, tuple[Callable[[], LidarConfig], str]] = {
    "velodyne_vlp16": (_vlp16, "Velodyne VLP-16: 16 beams -15..+15 deg, 0.2 deg x 1800 columns at 10 Hz, 903 nm, "
                               "100 m"),
    "ouster_os1_64": (_os1_64, "Ouster OS1-64: 64 beams over 45 deg (uniform), 1024 columns at 10 Hz, 865 nm, 120 m"),
    "livox_mid40": (_mid40, "Livox Mid-40-like rosette: 38.4 deg circular FOV, 100k points/s, 10 Hz frames, "
                            "905 nm, 260 m"),
}
_ADJUST = {"velodyne_vlp16": _vlp16_overrides}


def lidar_config(preset_name: str, **overrides) -> LidarConfig:
    """The configuration of a named preset with config or scan fields replaced."""
    if preset_name not in LIDAR_PRESETS:
        raise UnknownNameError("Lidar preset", preset_name, list(LIDAR_PRESETS))
    cfg = LIDAR_PRESETS[preset_name][0]()
    if overrides:
        adjust = _ADJUST.get(preset_name)
        cfg = cfg.with_overrides(**(adjust(overrides) if adjust else overrides))
    return cfg
