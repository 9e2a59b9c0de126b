"""A permanent magnet carried by a scene object (a description only; its field lives in twinsense.magnetic)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from twinsense import validation as V
from twinsense.constants import MU0
from twinsense.errors import ConfigError
from twinsense.scene.pose import Pose

MAGNET_SHAPES = ("cylinder", "block", "ring")
REMANENCE_MAX = 2.0  # [T] above the strongest NdFeB grades (N52: 1.48 T)


@dataclass(frozen=True, eq=False)
class Magnet:
    """A uniformly magnetised body fixed to a scene object.

    Parameters
    ----------
    shape : "cylinder", "block" or "ring"
    size : tuple [m]
        cylinder: (diameter, length); block: (x, y, z) edge lengths;
        ring: (outer diameter, inner diameter, length). Cylinder and ring
        axes lie along the magnet frame's z, the block's edges along its axes.
    remanence : float
        B_r [T] (NdFeB N35 ~1.2 T, N52 ~1.45 T, ferrite ~0.4 T).
    direction : (3,)
        Magnetisation direction in the magnet frame (normalised here):
        (0, 0, 1) axial, (1, 0, 0) diametric; any mix is allowed.
    pose : Pose
        Magnet frame -> object frame (default: the object's origin).
    """

    shape: str = "cylinder"
    size: tuple = (0.006, 0.003)
    remanence: float = 1.2
    direction: tuple = (0.0, 0.0, 1.0)
    pose: Pose = field(default_factory=Pose)

    def __post_init__(self):
        V.choice("magnet.shape", self.shape, MAGNET_SHAPES)
        n = {"cylinder": 2, "block": 3, "ring": 3}[self.shape]
        size = V.vector("magnet.size", self.size, n, "m")
        for i, s in enumerate(size):
            V.length(f"magnet.size[{i}]", float(s))
        if self.shape == "ring" and not size[1] < size[0]:
            raise ConfigError("magnet.size[1]", float(size[1]), f"an inner diameter < the outer {size[0]:g} m")
        object.__setattr__(self, "size", tuple(float(s) for s in size))
        object.__setattr__(self, "remanence", V.number("magnet.remanence", self.remanence, lo=0.0, lo_open=True,
                                                       hi=REMANENCE_MAX, unit="T"))
        d = V.vector("magnet.direction", self.direction, 3)
        norm = float(np.linalg.norm(d))
        if norm == 0.0:
            raise ConfigError("magnet.direction", self.direction, "a non-zero vector")
        object.__setattr__(self, "direction", tuple(float(v) for v in d / norm))
        if not isinstance(self.pose, Pose):
            raise ConfigError("magnet.pose", self.pose, "a Pose")

    @property
    def volume(self) -> float:
        """[m^3]"""
        s = self.size
        if self.shape == "cylinder":
            return float(np.pi * s[0] ** 2 / 4 * s[1])
        if self.shape == "block":
            return float(s[0] * s[1] * s[2])
        return float(np.pi * (s[0] ** 2 - s[1] ** 2) / 4 * s[2])

    @property
    def moment(self) -> np.ndarray:
        """Dipole moment (3,) [A m^2] in the magnet frame: B_r V / mu0 along the direction."""
        return self.remanence * self.volume / MU0 * np.asarray(self.direction)

    def to_dict(self) -> dict:
        return {"shape": self.shape, "size": list(self.size), "remanence": self.remanence,
                "direction": list(self.direction), "pose": self.pose.to_dict()}
