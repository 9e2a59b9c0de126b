"""Object motions with analytic velocities.

Every motion answers ``state(t) -> MotionState``: the pose at time t [s] and
the linear velocity of the frame origin and the angular velocity, both in the
world frame. Velocities are exact derivatives of the trajectory (radar Doppler
and ToF motion artefacts depend on them), never finite differences.

``state(t)`` accepts a finite time within +-1e10 s (``validation.TIME_MAX``);
speeds stay below the speed of light, angular speeds below 1e6 rad/s and
oscillation frequencies below 1 MHz (see :mod:`twinsense.validation`), so a
state is finite for every allowed time.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.scene.pose import Pose, _as_rotation_matrix, rotvec_matrix


@dataclass(frozen=True, eq=False)
class MotionState:
    """Pose and velocities of a rigid body at one time.

    Attributes
    ----------
    pose : Pose
        Body -> world.
    linear_velocity : (3,) float
        Velocity of the body-frame origin in the world frame [m/s].
    angular_velocity : (3,) float
        Angular velocity in the world frame [rad/s].
    """

    pose: Pose
    linear_velocity: np.ndarray
    angular_velocity: np.ndarray

    def point_velocity(self, points_world) -> np.ndarray:
        """Velocity (n, 3) [m/s] of body-fixed points given in world coordinates (n, 3)."""
        p = np.asarray(points_world, dtype=float)
        out = np.empty(p.shape)
        out[...] = self.linear_velocity
        w = self.angular_velocity
        if np.any(w):
            # w x (p - c), written per component (np.cross is slow on (n, 3)).
            r = p - self.pose.position
            out[..., 0] += w[1] * r[..., 2] - w[2] * r[..., 1]
            out[..., 1] += w[2] * r[..., 0] - w[0] * r[..., 2]
            out[..., 2] += w[0] * r[..., 1] - w[1] * r[..., 0]
        return out


class Motion:
    """Base class of all motions."""

    def state(self, t: float) -> MotionState:  # pragma: no cover - abstract
        raise NotImplementedError

    def pose(self, t: float) -> Pose:
        return self.state(t).pose

    @property
    def is_static(self) -> bool:
        return False

    def to_dict(self) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError


_ZERO = np.zeros(3)
_ZERO.setflags(write=False)


def check_time(t) -> float:
    """``t`` [s] as a float, or ConfigError if it is not a finite time within +-TIME_MAX."""
    return V.time("t", t)


def _check_pose(field_name: str, pose) -> None:
    if not isinstance(pose, Pose):
        raise ConfigError(field_name, pose, "a twinsense Pose")


@dataclass(frozen=True, eq=False)
class Static(Motion):
    """An object that does not move."""

    pose0: Pose = field(default_factory=Pose)

    def __post_init__(self):
        _check_pose("motion.pose0", self.pose0)

    def state(self, t):
        check_time(t)  # a static object still refuses t = NaN: the caller has a bug
        return MotionState(self.pose0, _ZERO, _ZERO)

    @property
    def is_static(self):
        return True

    def to_dict(self):
        return {"type": "static", "pose": self.pose0.to_dict()}


@dataclass(frozen=True, eq=False)
class ConstantVelocity(Motion):
    """Constant linear velocity [m/s] and angular velocity [rad/s] (world frame) from ``pose0`` at t=0."""

    pose0: Pose = field(default_factory=Pose)
    velocity: tuple = (0.0, 0.0, 0.0)
    angular_velocity: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        _check_pose("motion.pose0", self.pose0)
        object.__setattr__(self, "velocity", V.bounded_vector("motion.velocity", self.velocity, V.SPEED_MAX, "m/s"))
        object.__setattr__(self, "angular_velocity", V.bounded_vector(
            "motion.angular_velocity", self.angular_velocity, V.ANGULAR_SPEED_MAX, "rad/s"))
        # Without a turn every state has one rotation, I @ R0 re-orthonormalised: built once.
        fixed = None if np.any(self.angular_velocity) else Pose._trusted(_ZERO, np.eye(3) @ self.pose0.rotation)
        object.__setattr__(self, "_fixed", fixed)

    def state(self, t):
        t = check_time(t)
        # |velocity * t| <= c * TIME_MAX = 3e18 m: far below one ulp of any position near the
        # float limit, so the sum never overflows.
        pos = self.pose0.position + self.velocity * t
        if self._fixed is not None:
            return MotionState(Pose._trusted(pos, self._fixed.rotation, normalised=True), self.velocity,
                               self.angular_velocity)
        rot = rotvec_matrix("motion.angular_velocity * t", self.angular_velocity * t) @ self.pose0.rotation
        return MotionState(Pose._trusted(pos, rot), self.velocity, self.angular_velocity)

    def to_dict(self):
        return {"type": "constant_velocity", "pose": self.pose0.to_dict(),
                "velocity": self.velocity.tolist(), "angular_velocity": self.angular_velocity.tolist()}


WAYPOINT_MODES = ("once", "loop", "back_and_forth")


@dataclass(frozen=True, eq=False)
class Waypoints(Motion):
    """Straight segments through ``points`` (n, 3) [m] at constant ``speed`` [m/s].

    The orientation stays ``rotation`` (3, 3). ``mode``: "once" (stop at the
    last point), "loop" (travel back to the first point and
    repeat), or "back_and_forth" (reverse at each end). ``start_time`` [s]
    delays the start.
    """

    points: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    speed: float = 1.0
    mode: str = "once"
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    start_time: float = 0.0

    def __post_init__(self):
        p = V.array("motion.points", self.points, (None, 3), "m")
        if len(p) < 2:
            raise ConfigError("motion.points", self.points, "at least 2 waypoints (n, 3) [m]")
        V.number("motion.speed", self.speed, lo=0.0, lo_open=True, hi=V.SPEED_MAX, unit="m/s")
        V.time("motion.start_time", self.start_time)
        if not isinstance(self.mode, str) or self.mode not in WAYPOINT_MODES:
            raise ConfigError("motion.mode", self.mode, "one of: " + ", ".join(WAYPOINT_MODES))
        if self.mode == "loop":
            p = np.vstack([p, p[:1]])
        with np.errstate(over="ignore", invalid="ignore"):
            diff = np.diff(p, axis=0)
            # Row norms scaled by their largest entry: squares of 1e200 overflow.
            big = np.max(np.abs(diff), axis=1, keepdims=True)
            seg = big[:, 0] * np.linalg.norm(diff / np.where(big > 0, big, 1.0), axis=1)
            cum = np.concatenate([[0.0], np.cumsum(seg)])
        if not np.isfinite(cum[-1]):
            raise ConfigError("motion.points", self.points, "waypoints whose path length is a finite number [m]")
        if np.any(seg <= 0):
            raise ConfigError("motion.points", self.points, "consecutive waypoints that differ")
        object.__setattr__(self, "_path", p)
        object.__setattr__(self, "_cum", cum)
        object.__setattr__(self, "_rot", _as_rotation_matrix("motion.rotation", self.rotation))
        # The rotation of every state (re-orthonormalised once more, as a pose of it would be).
        object.__setattr__(self, "_fixed", Pose._trusted(_ZERO, self._rot))

    @property
    def length(self) -> float:
        """Path length of one pass [m]."""
        return float(self._cum[-1])

    def _arc(self, t):
        """Arc length s along the path and ds/dt sign at time t."""
        t = check_time(t)
        s = max(0.0, (t - self.start_time)) * self.speed
        L = self.length
        moving = t > self.start_time
        if self.mode == "once":
            if s >= L:
                return L, 0.0
            return s, 1.0 if moving else 0.0
        if self.mode == "loop":
            return s % L, 1.0 if moving else 0.0
        k, r = divmod(s, L)
        if int(k) % 2 == 0:
            return r, 1.0 if moving else 0.0
        return L - r, -1.0

    def state(self, t):
        s, sign = self._arc(t)
        i = int(np.clip(np.searchsorted(self._cum, s, side="right") - 1, 0, len(self._cum) - 2))
        a, b = self._path[i], self._path[i + 1]
        d = (b - a) / (self._cum[i + 1] - self._cum[i])
        pos = a + d * (s - self._cum[i])
        return MotionState(Pose._trusted(pos, self._fixed.rotation, normalised=True), sign * self.speed * d, _ZERO)

    def to_dict(self):
        return {"type": "waypoints", "points": np.asarray(self.points).tolist(), "speed": self.speed,
                "mode": self.mode, "start_time": self.start_time}


@dataclass(frozen=True, eq=False)
class Keyframes(Motion):
    """Timed poses: linear interpolation of position, slerp of rotation.

    Before the first and after the last keyframe the object holds still.
    """

    times: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0]))
    poses: tuple = ()

    def __post_init__(self):
        t = V.array("motion.times", self.times, (None,), "s")
        if len(t) < 2 or np.any(np.diff(t) <= 0) or np.any(np.abs(t) > V.TIME_MAX):
            raise ConfigError("motion.times", self.times,
                              f"at least 2 strictly increasing times within +-{V.TIME_MAX:g} [s]")
        if not isinstance(self.poses, (tuple, list)) or len(self.poses) != len(t):
            n = f"{len(self.poses)} poses" if isinstance(self.poses, (tuple, list)) else self.poses
            raise ConfigError("motion.poses", n, f"one Pose per keyframe time ({len(t)})")
        for i, p in enumerate(self.poses):
            if not isinstance(p, Pose):  # named on its own: the count is right, this entry is not
                raise ConfigError(f"motion.poses[{i}]", p, "a twinsense Pose")
        object.__setattr__(self, "times", t)
        pos = np.array([p.position for p in self.poses])
        rots = Rotation.from_matrix(np.array([p.rotation for p in self.poses]))
        # The segment velocities are those state(t) reports: keyframes too close
        # in time for their distance would claim faster-than-light motion.
        with np.errstate(over="ignore", invalid="ignore"):
            dt = np.diff(t)
            speed = np.linalg.norm(np.diff(pos, axis=0), axis=1) / dt
            spin = np.linalg.norm((rots[:-1].inv() * rots[1:]).as_rotvec(), axis=1) / dt
        if not np.all(speed <= V.SPEED_MAX):
            i = int(np.argmin(speed <= V.SPEED_MAX))
            raise ConfigError(f"motion.times[{i + 1}]", float(t[i + 1]),
                              f"keyframes far enough apart in time that the speed stays <= {V.SPEED_MAX:g} m/s "
                              f"(here {speed[i]:.3g} m/s)")
        if not np.all(spin <= V.ANGULAR_SPEED_MAX):
            i = int(np.argmin(spin <= V.ANGULAR_SPEED_MAX))
            raise ConfigError(f"motion.times[{i + 1}]", float(t[i + 1]),
                              f"keyframes far enough apart in time that the angular speed stays <= "
                              f"{V.ANGULAR_SPEED_MAX:g} rad/s (here {spin[i]:.3g} rad/s)")
        object.__setattr__(self, "_pos", pos)
        object.__setattr__(self, "_rots", rots)
        object.__setattr__(self, "_slerp", Slerp(t, rots))

    def state(self, t):
        t = check_time(t)
        ts = self.times
        if t <= ts[0] or t >= ts[-1]:
            p = self.poses[0] if t <= ts[0] else self.poses[-1]
            return MotionState(p, _ZERO, _ZERO)
        i = int(np.searchsorted(ts, t, side="right") - 1)
        dt = ts[i + 1] - ts[i]
        u = (t - ts[i]) / dt
        pos = (1 - u) * self._pos[i] + u * self._pos[i + 1]
        vel = (self._pos[i + 1] - self._pos[i]) / dt
        rot = self._slerp([t])[0].as_matrix()
        # Slerp turns at a constant rate about a fixed axis: omega = log(R_i^T R_i+1)/dt,
        # expressed in the world frame.
        rel = (self._rots[i].inv() * self._rots[i + 1]).as_rotvec()
        omega = self._rots[i].apply(rel) / dt
        return MotionState(Pose._trusted(pos, rot), vel, omega)

    def to_dict(self):
        return {"type": "keyframes", "times": self.times.tolist(), "poses": [p.to_dict() for p in self.poses]}


@dataclass(frozen=True, eq=False)
class Oscillation(Motion):
    """Sinusoidal translation about ``pose0``: p(t) = p0 + amplitude * sin(2 pi f t + phase).

    ``amplitude`` (3,) [m] sets the direction and size, ``frequency`` [Hz],
    ``phase_deg`` [deg]. Optional rotational oscillation ``angular_amplitude``
    (3,) [rad] (a rotation vector scaled by the same sine).
    """

    pose0: Pose = field(default_factory=Pose)
    amplitude: tuple = (0.0, 0.0, 0.0)
    frequency: float = 1.0
    phase_deg: float = 0.0
    angular_amplitude: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        _check_pose("motion.pose0", self.pose0)
        f = V.number("motion.frequency", self.frequency, lo=0.0, lo_open=True, hi=V.FREQUENCY_MAX, unit="Hz")
        w = 2 * np.pi * f
        # Peak speeds are amplitude * 2 pi f: bound them like every other motion's.
        object.__setattr__(self, "amplitude", V.bounded_vector(
            "motion.amplitude", self.amplitude, min(V.LENGTH_MAX, V.SPEED_MAX / w), "m"))
        object.__setattr__(self, "angular_amplitude", V.bounded_vector(
            "motion.angular_amplitude", self.angular_amplitude, V.ANGULAR_SPEED_MAX / w, "rad"))
        V.number("motion.phase_deg", self.phase_deg, unit="deg")

    def state(self, t):
        w = 2 * np.pi * self.frequency
        arg = w * check_time(t) + np.deg2rad(self.phase_deg)
        s, c = np.sin(arg), np.cos(arg)
        pos = self.pose0.position + self.amplitude * s  # |amplitude| <= 10 km: cannot overflow
        vel = self.amplitude * w * c
        # Rotation about a fixed axis n by angle theta(t) = |a| sin(arg):
        # omega = n * dtheta/dt (the axis does not change, so this is exact).
        rot = rotvec_matrix("motion.angular_amplitude", self.angular_amplitude * s) @ self.pose0.rotation
        omega = self.angular_amplitude * w * c
        return MotionState(Pose._trusted(pos, rot), vel, omega)

    def to_dict(self):
        return {"type": "oscillation", "pose": self.pose0.to_dict(), "amplitude": self.amplitude.tolist(),
                "frequency": self.frequency, "phase_deg": self.phase_deg,
                "angular_amplitude": self.angular_amplitude.tolist()}
