"""A LiDAR frame: every firing of one revolution (or scan period) with its echoes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class LidarFrame:
    """One frame: n firings (rows, in firing order) x E echo slots.

    Slots hold the reported echoes of a firing in range order (slot 0 the
    nearest); an empty slot has NaN range and points, 0 intensity and power.

    Attributes
    ----------
    t : float
        Frame start [s].
    time : (n,) float64
        Firing time of each row [s] (absolute; per-point timestamps).
    azimuth, elevation : (n,) float32
        Beam centre angles in the sensor frame [rad] (azimuth positive right,
        elevation positive up).
    ring : (n,) int16
        Beam index within the column (0 = the preset's first, lowest beam).
    range : (n, E) float32
        Measured range from the beam origin [m].
    intensity : (n, E) uint8
        Calibrated reflectivity as the device reports it: 0-100 diffuse
        (100 x rho cos theta), 101-255 retro-reflectors, 255 saturated.
    power : (n, E) float32
        Received peak power [W] (clipped at saturation).
    xyz : (n, E, 3) float32
        Points in the sensor frame at the firing instant [m] (x right, y down, z forward).
    xyz_world : (n, E, 3) float32
        Points in the world frame [m], each with the sensor pose of its own firing.
    object_id : (n, E) int32
        Ground truth: scene object that dominates each echo (-1 for none).
    """

    t: float
    time: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray
    ring: np.ndarray
    range: np.ndarray
    intensity: np.ndarray
    power: np.ndarray
    xyz: np.ndarray
    xyz_world: np.ndarray
    object_id: np.ndarray

    def streams(self) -> dict[str, np.ndarray]:
        """Fixed-shape arrays per frame, as the recorder stores them."""
        return {"time": self.time, "azimuth": self.azimuth, "elevation": self.elevation, "ring": self.ring,
                "range": self.range, "intensity": self.intensity, "power": self.power, "xyz": self.xyz,
                "xyz_world": self.xyz_world, "object_id": self.object_id}

    @property
    def valid(self) -> np.ndarray:
        """(n, E) bool: the slot holds an echo."""
        return np.isfinite(self.range)

    @property
    def n_points(self) -> int:
        return int(self.valid.sum())

    def point_cloud(self, world: bool = False) -> dict[str, np.ndarray]:
        """The echoes as a flat point cloud (m points).

        Keys: x, y, z [m] (sensor frame, or world with ``world=True``), range
        [m], intensity (uint8), power [W], ring, echo (slot index), time [s],
        azimuth, elevation [rad], object_id.
        """
        row, echo = np.nonzero(self.valid)
        p = (self.xyz_world if world else self.xyz)[row, echo]
        return {"x": p[:, 0], "y": p[:, 1], "z": p[:, 2], "range": self.range[row, echo],
                "intensity": self.intensity[row, echo], "power": self.power[row, echo], "ring": self.ring[row],
                "echo": echo.astype(np.int16), "time": self.time[row], "azimuth": self.azimuth[row],
                "elevation": self.elevation[row], "object_id": self.object_id[row, echo]}
