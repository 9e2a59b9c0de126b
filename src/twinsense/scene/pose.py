"""Rigid poses: position [m] and rotation, with composition and inverse.

A ``Pose`` maps points from its child frame into its parent frame:
``p_parent = R @ p_child + t``. ``a @ b`` is "b expressed in a's parent":
``(a @ b).apply(p) == a.apply(b.apply(p))``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.linalg import rotate_rows

#: How far from orthonormal a rotation given to a Pose may be: every entry of R R^T - I
#: within this (float32 input, a matrix printed to 7 digits); it is re-orthonormalised after.
POSE_ROTATION_TOL = 1e-6


def is_rotation(r: np.ndarray, tol: float) -> bool:
    """Whether ``r`` (3, 3) float is a proper rotation to ``tol``: every entry of R R^T - I
    within ``tol`` and det R > 0 (not a scaled or mirrored matrix). False for NaN or inf.

    One rule, two tolerances: a :class:`Pose` takes slightly noisy input
    (:data:`POSE_ROTATION_TOL`) and re-orthonormalises it; ``Rays.local``
    (:mod:`twinsense.render.rays`) keeps its rotation as given, and the bundle picker
    inverts it as R^T, so it asks for 1e-9 there.
    """
    # A rotation's entries lie in [-1, 1]: tested first, so that R R^T of a huge matrix
    # never overflows (NaN compares False throughout).
    return bool(np.abs(r).max() <= 1.0 + tol and np.abs(r @ r.T - np.eye(3)).max() <= tol
                and np.linalg.det(r) > 0.0)


def _as_rotation_matrix(field_name: str, value: Any) -> np.ndarray:
    r = V.array(field_name, value, (3, 3))
    if not is_rotation(r, POSE_ROTATION_TOL):
        raise ConfigError(field_name, r.tolist(),
                          f"a proper rotation (R R^T = I within {POSE_ROTATION_TOL:g}, det = +1)")
    # Re-orthonormalise so errors do not accumulate under composition.
    u, _, vt = np.linalg.svd(r)
    return u @ vt


def rotvec_matrix(field_name: str, rotvec: Any) -> np.ndarray:
    """(3, 3) rotation matrix of a rotation vector (axis * angle [rad]) of any finite size.

    The angle is reduced modulo 2 pi first: scipy's Rodrigues formula gives NaN
    for angles near 1e300 rad, though the rotation is well defined.
    """
    v = V.vector(field_name, rotvec, 3, "rad")
    m = float(np.max(np.abs(v)))
    if m == 0.0:
        return np.eye(3)
    axis = v / m
    n = float(np.linalg.norm(axis))
    angle = m * n  # <= sqrt(3) * max float: finite unless m is within 2x of the float limit
    if not np.isfinite(angle):
        raise ConfigError(field_name, rotvec, "a rotation vector whose length (angle) is a finite number [rad]")
    return Rotation.from_rotvec(axis / n * np.fmod(angle, 2 * np.pi)).as_matrix()


@dataclass(frozen=True, eq=False)
class Pose:
    """Rigid transform child -> parent.

    Attributes
    ----------
    position : (3,) float
        Origin of the child frame in the parent frame [m].
    rotation : (3, 3) float
        Rotation matrix whose columns are the child axes in the parent frame.
    """

    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))

    def __post_init__(self) -> None:
        pos = V.vector("Pose.position", self.position, 3, "m")
        rot = _as_rotation_matrix("Pose.rotation", self.rotation)
        pos.setflags(write=False)
        rot.setflags(write=False)
        object.__setattr__(self, "position", pos)
        object.__setattr__(self, "rotation", rot)

    @classmethod
    def _trusted(cls, position: np.ndarray, rotation: np.ndarray, *, normalised: bool = False,
                 copy: bool = True) -> Pose:
        """A pose from parts already known valid: a finite (3,) position [m] and a rotation (3, 3) built
        from proper rotations (a product of poses' rotations, a motion's rotation vector, slerp).

        Skips the checks of the public constructor (about 10x its cost) but keeps its
        re-orthonormalisation, so the pose is bit for bit the one ``Pose(position, rotation)`` gives.
        ``normalised=True``: ``rotation`` is already the ``rotation`` of such a pose (read-only), kept
        as is (a motion whose rotation does not change reuses it). ``copy=False``: ``position`` is
        already a read-only float (3,) array, kept as is (a row of a read-only array of many poses).
        Internal: user input goes through ``Pose(...)``.
        """
        pose = object.__new__(cls)
        pos = np.array(position, dtype=float) if copy else position
        if normalised:
            rot = rotation
        else:
            u, _, vt = np.linalg.svd(np.asarray(rotation, dtype=float))
            rot = u @ vt
            rot.setflags(write=False)
        if copy:
            pos.setflags(write=False)
        object.__setattr__(pose, "position", pos)
        object.__setattr__(pose, "rotation", rot)
        return pose

    # ------------------------------------------------------------ builders
    @classmethod
    def from_euler_deg(cls, position=(0.0, 0.0, 0.0), rpy_deg=(0.0, 0.0, 0.0),
                       order: str = "xyz") -> Pose:
        """Position [m] and extrinsic Euler angles [deg] (default roll-pitch-yaw about x, y, z)."""
        ang = V.vector("Pose.rpy_deg", rpy_deg, 3, "deg")
        if not isinstance(order, str) or len(order) != 3 or set(order.lower()) - set("xyz"):
            raise ConfigError("Pose.order", order, "three axis letters such as 'xyz' (extrinsic) or 'XYZ' (intrinsic)")
        return cls(position, Rotation.from_euler(order, ang, degrees=True).as_matrix())

    @classmethod
    def from_quat(cls, position=(0.0, 0.0, 0.0), quat_xyzw=(0.0, 0.0, 0.0, 1.0)) -> Pose:
        """Position [m] and unit quaternion in (x, y, z, w) order (scipy/ROS convention)."""
        q = V.vector("Pose.quat_xyzw", quat_xyzw, 4)
        # Scale by the largest entry before normalising: the norm of
        # (1e200, 1e200, 0, 0) overflows. A near-zero one is refused: its
        # direction is mostly rounding noise.
        m = np.max(np.abs(q))
        if m < 1e-9:
            raise ConfigError("Pose.quat_xyzw", quat_xyzw, "a non-zero quaternion (x, y, z, w)")
        q = q / m
        return cls(position, Rotation.from_quat(q / np.linalg.norm(q)).as_matrix())

    @classmethod
    def from_matrix(cls, matrix) -> Pose:
        """From a homogeneous (4, 4) transform."""
        m = V.array("Pose.matrix", matrix, (4, 4))
        if not np.allclose(m[3], [0, 0, 0, 1]):
            raise ConfigError("Pose.matrix", m[3].tolist(), "last row [0, 0, 0, 1]")
        return cls(m[:3, 3], m[:3, :3])

    @classmethod
    def from_rotvec(cls, position=(0.0, 0.0, 0.0), rotvec=(0.0, 0.0, 0.0)) -> Pose:
        """Position [m] and rotation vector (axis * angle [rad])."""
        return cls(position, rotvec_matrix("Pose.rotvec", rotvec))

    @classmethod
    def look_at(cls, eye, target, up=(0.0, 0.0, 1.0)) -> Pose:
        """Sensor pose at ``eye`` looking at ``target``, optical convention.

        The child frame has +z towards the target (boresight), +x to the right
        and +y down in the image, so ``up`` maps to -y.
        """
        e = V.vector("look_at.eye", eye, 3, "m")
        g = V.vector("look_at.target", target, 3, "m")
        u = V.vector("look_at.up", up, 3)
        with np.errstate(over="ignore"):
            z = g - e
        if not np.all(np.isfinite(z)):
            raise ConfigError("look_at.target", target, "a point whose offset from eye is finite (overflows here)")
        if np.linalg.norm(z) < 1e-12:
            raise ConfigError("look_at.target", target, "a point different from eye")
        z = z / np.linalg.norm(z)
        # Only the direction of up matters: scale it to a unit-size vector so a
        # huge or tiny up neither overflows nor looks parallel to z.
        if not np.any(u):
            raise ConfigError("look_at.up", up, "a non-zero direction")
        u = u / np.max(np.abs(u))
        x = np.cross(z, u)
        if np.linalg.norm(x) < 1e-9:
            raise ConfigError("look_at.up", up, "a direction not parallel to the viewing direction")
        x = x / np.linalg.norm(x)
        y = np.cross(z, x)
        return cls(e, np.column_stack([x, y, z]))

    # ------------------------------------------------------------ algebra
    def __matmul__(self, other: Pose) -> Pose:
        if not isinstance(other, Pose):
            return NotImplemented
        return Pose._trusted(self.rotation @ other.position + self.position, self.rotation @ other.rotation)

    def inverse(self) -> Pose:
        rt = self.rotation.T
        return Pose._trusted(-rt @ self.position, rt)

    def apply(self, points) -> np.ndarray:
        """Transform points (n, 3) or (3,) from the child into the parent frame."""
        p = np.asarray(points, dtype=float)
        if p.ndim == 2 and len(p) > 64:
            out = rotate_rows(p, self.rotation.T)
            out += self.position
            return out
        return p @ self.rotation.T + self.position

    def apply_vectors(self, vectors) -> np.ndarray:
        """Rotate direction vectors (n, 3) or (3,) (no translation)."""
        v = np.asarray(vectors, dtype=float)
        if v.ndim == 2 and len(v) > 64:
            return rotate_rows(v, self.rotation.T)
        return v @ self.rotation.T

    # ------------------------------------------------------------ views
    @property
    def matrix(self) -> np.ndarray:
        """Homogeneous (4, 4) transform."""
        m = np.eye(4)
        m[:3, :3] = self.rotation
        m[:3, 3] = self.position
        return m

    @property
    def quat_xyzw(self) -> np.ndarray:
        return Rotation.from_matrix(self.rotation).as_quat()

    def euler_deg(self, order: str = "xyz") -> np.ndarray:
        return Rotation.from_matrix(self.rotation).as_euler(order, degrees=True)

    def isclose(self, other: Pose, atol: float = 1e-9) -> bool:
        return bool(np.allclose(self.position, other.position, atol=atol)
                    and np.allclose(self.rotation, other.rotation, atol=atol))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Pose):
            return NotImplemented
        return bool(np.array_equal(self.position, other.position)
                    and np.array_equal(self.rotation, other.rotation))

    def __hash__(self) -> int:
        return hash((self.position.tobytes(), self.rotation.tobytes()))

    def __repr__(self) -> str:
        p = np.array2string(self.position, precision=4)
        e = np.array2string(self.euler_deg(), precision=2)
        return f"Pose(position={p}, rpy_deg={e})"

    def to_dict(self) -> dict:
        return {"position": self.position.tolist(), "quat_xyzw": self.quat_xyzw.tolist()}
