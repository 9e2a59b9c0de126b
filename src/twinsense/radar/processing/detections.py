"""Radar detections as a point cloud in the sensor and world frames.

Sensor frame (optical convention): x right, y down, z forward (boresight).
Azimuth ``az = atan2(x, z)`` is positive to the right, elevation
``el = atan2(-y, hypot(x, z))`` positive up, so a detection at range r is

    x = r cos(el) sin(az),   y = -r sin(el),   z = r cos(el) cos(az).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np


def polar_to_sensor(rng: np.ndarray, azimuth: np.ndarray, elevation: np.ndarray) -> np.ndarray:
    """Sensor-frame points (n, 3) [m] from range [m], azimuth and elevation [rad], each (n,)."""
    r = np.asarray(rng, dtype=float)
    az = np.asarray(azimuth, dtype=float)
    el = np.asarray(elevation, dtype=float)
    ce = np.cos(el)
    return np.stack([r * ce * np.sin(az), -r * np.sin(el), r * ce * np.cos(az)], axis=-1)


def sensor_to_polar(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(range, azimuth, elevation) of sensor-frame points (n, 3); see :func:`polar_to_sensor`."""
    p = np.asarray(points, dtype=float)
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    h = np.hypot(x, z)
    return np.linalg.norm(p, axis=-1), np.arctan2(x, z), np.arctan2(-y, h)


def _ro(a: Any, dtype=float) -> np.ndarray:
    arr = np.array(a, dtype=dtype)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class RadarPointCloud:
    """Detections of one radar frame; every per-detection array is (n,) or (n, 3).

    Attributes
    ----------
    range : (n,) float
        Radial distance [m].
    velocity : (n,) float
        Radial velocity [m/s], positive = moving away.
    azimuth, elevation : (n,) float
        Angles in the sensor frame [rad] (module docstring).
    snr_db : (n,) float
        Cell power over the CFAR noise estimate [dB].
    power : (n,) float
        Cell power (the processed map's linear unit, per channel).
    range_bin, doppler_bin : (n,) int
        Cell indices in the range-Doppler map.
    points_sensor : (n, 3) float
        Cartesian points in the sensor frame [m].
    points_world : (n, 3) float or None
        The same points in the world frame, when a sensor-to-world pose was given.
    max_range : float
        Unambiguous range [m] of the waveform.
    max_velocity : float
        Unambiguous radial velocity [m/s]; velocities are in [-max, max).
    range_resolution, velocity_resolution : float
        Rayleigh resolutions [m], [m/s].
    """

    range: np.ndarray
    velocity: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray
    snr_db: np.ndarray
    power: np.ndarray
    range_bin: np.ndarray
    doppler_bin: np.ndarray
    points_sensor: np.ndarray
    max_range: float
    max_velocity: float
    range_resolution: float
    velocity_resolution: float
    points_world: np.ndarray | None = field(default=None)

    @classmethod
    def from_polar(cls, *, range, velocity, azimuth, elevation, snr_db, power=None,
                   range_bin=None, doppler_bin=None, max_range: float, max_velocity: float,
                   range_resolution: float, velocity_resolution: float,
                   pose=None) -> RadarPointCloud:
        """Build from per-detection polar values; ``pose`` (sensor-to-world
        :class:`twinsense.scene.Pose`, or anything with ``apply``) adds world points."""
        r = _ro(range)
        n = len(r)
        cloud = cls(
            range=r, velocity=_ro(velocity), azimuth=_ro(azimuth), elevation=_ro(elevation),
            snr_db=_ro(snr_db), power=_ro(np.full(n, np.nan) if power is None else power),
            range_bin=_ro(np.full(n, -1) if range_bin is None else range_bin, int),
            doppler_bin=_ro(np.full(n, -1) if doppler_bin is None else doppler_bin, int),
            points_sensor=_ro(polar_to_sensor(r, azimuth, elevation).reshape(n, 3)),
            max_range=float(max_range), max_velocity=float(max_velocity),
            range_resolution=float(range_resolution),
            velocity_resolution=float(velocity_resolution),
        )
        return cloud if pose is None else cloud.in_world(pose)

    @classmethod
    def empty(cls, **limits: float) -> RadarPointCloud:
        """No detections, with the waveform limits given as keywords."""
        z = np.zeros(0)
        return cls.from_polar(range=z, velocity=z, azimuth=z, elevation=z, snr_db=z, **limits)

    def in_world(self, pose) -> RadarPointCloud:
        """A copy with ``points_world = pose.apply(points_sensor)`` (pose: sensor-to-world)."""
        pts = np.asarray(pose.apply(self.points_sensor), dtype=float).reshape(-1, 3)
        return replace(self, points_world=_ro(pts))

    def __len__(self) -> int:
        return len(self.range)

    def strongest(self, k: int) -> RadarPointCloud:
        """The ``k`` detections with the highest SNR (all if fewer)."""
        idx = np.argsort(-self.snr_db, kind="stable")[:k]
        return self.select(idx)

    def select(self, index: np.ndarray) -> RadarPointCloud:
        """A subset by boolean mask or integer index array."""
        per_det = ("range", "velocity", "azimuth", "elevation", "snr_db", "power",
                   "range_bin", "doppler_bin", "points_sensor")
        changes = {f: _ro(getattr(self, f)[index], getattr(self, f).dtype) for f in per_det}
        if self.points_world is not None:
            changes["points_world"] = _ro(self.points_world[index])
        return replace(self, **changes)


#: Alias: the detections of one frame are its point cloud.
Detections = RadarPointCloud
