"""People in the scene: an articulated human that stands, turns, walks and reaches.

:func:`human_tree` builds the body as a :class:`~twinsense.scene.articulated.KinematicTree`
of capsules and boxes sized by segment-length ratios of the body height H.
The ratios are Drillis and Contini's (1966) as tabulated by D. A. Winter,
*Biomechanics and Motor Control of Human Movement*, 4th ed., Wiley 2009,
fig. 4.1: hip joint 0.530 H above the floor, thigh 0.245 H, shank 0.246 H,
ankle 0.039 H, foot 0.152 H long and 0.055 H wide, shoulder 0.818 H, chin
0.870 H, upper arm 0.186 H, forearm 0.146 H, hand 0.108 H, shoulder width
0.259 H, hip width 0.191 H. Segment radii are not in that table; they are
chosen so that widths and depths match an average adult (chest 0.22 H wide,
0.13 H deep; waist and belly 0.19 H wide, 0.12 H deep; head 0.11 H wide, chin
to crown). Between its horizontal rolls the trunk is filled (a box and two
upright capsules) so that its front and sides are continuous surfaces.

The motion (:class:`PersonMotion`) gives both the root (pelvis) motion and
the joint trajectory, each with exact time derivatives:

- walking: the Boulic-Magnenat-Thalmann-Thalmann model of
  :mod:`twinsense.scene.gait` along a straight heading or a waypoint path
  whose heading turns smoothly (a C1 ramp of the heading over ``turn_length``
  around each waypoint, so the yaw rate is continuous);
- starting and stopping: the gait played at a gait time whose rate ramps
  smoothly from 0 to 1 (1 to 0) over START_BLEND, so the body never moves
  faster than its steady gait; the standing pose fades out over the start
  (the walk starts at the right foot's mid-stance, where standing puts that
  foot, and the left foot rises from its place into the gait's swing along
  a world-space blend, by closed-form leg inverse kinematics); at a path's
  end the gait comes to rest wherever in its cycle it is, and two closing
  steps (one foot, then the other, lifted and set down
  on the standing footholds by closed-form leg inverse kinematics while the
  other foot stays put) bring the person into the standing pose;
- standing: legs straight, arms hanging, optional sway of the pelvis;
- turning on the spot: the heading ramps to a new value;
- reaching: analytic two-link inverse kinematics of shoulder (flexion,
  abduction) and elbow towards a world point, blended in and out with a C1
  ramp; a point beyond the arm's reach is not an error: the arm points at
  it fully stretched (the distance is clamped into the arm's range), and
  every angle is clamped into its joint limits.

:class:`Walker` and :func:`add_person` put a person in a scene.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import FrozenInstanceError, dataclass

import numpy as np
from scipy.interpolate import CubicHermiteSpline, make_interp_spline

from twinsense import validation as V
from twinsense.errors import ConfigError, UnknownNameError
from twinsense.scene.articulated import ArticulatedBody, Joint, JointMotion, KinematicTree, Link
from twinsense.scene.gait import BODY_MODES, GaitTiming, LegGeometry, WalkCycle, smoothstep
from twinsense.scene.geometry import Box, Capsule
from twinsense.scene.materials import Material, material_names
from twinsense.scene.motion import Motion, MotionState, check_time
from twinsense.scene.pose import Pose

# ---------------------------------------------------------------- anthropometry (Winter 2009, fig. 4.1)
HIP_HEIGHT = 0.530
THIGH = 0.245
SHANK = 0.246
ANKLE_HEIGHT = 0.039
FOOT_LENGTH = 0.152
FOOT_WIDTH = 0.055
SHOULDER_HEIGHT = 0.818
CHIN_HEIGHT = 0.870
UPPER_ARM = 0.186
FOREARM = 0.146
HAND = 0.108
SHOULDER_WIDTH = 0.259
HIP_WIDTH = 0.191
# Ours (not in the table): the hip joint centres sit about a quarter of the hip
# width either side of the mid-line, the ankle a quarter of the foot length
# in front of the heel, the shoulder joints 0.02 H below and inside the acromion.
HIP_JOINT_HALF_WIDTH = HIP_WIDTH / 4
HEEL_BEHIND_ANKLE = 0.25 * FOOT_LENGTH
SHOULDER_JOINT_DROP = 0.02
SHOULDER_JOINT_HALF_WIDTH = SHOULDER_WIDTH / 2 - 0.02
# Ours: the trunk between the pelvis and chest rolls (waist and belly) is 0.19 H wide and 0.12 H deep.
TRUNK_WIDTH = 0.19
TRUNK_DEPTH = 0.12

HEIGHT_RANGE = (0.5, 2.5)  # [m] body heights accepted
WALK_BODIES = ("auto", *BODY_MODES)  # Walk.body: "auto" takes "planted" where it can walk, else "smooth"
SKIN = "human_skin"
CLOTHING_LAYERS = ("tof", "camera", "lidar", "ultrasonic")
SIDES = (("right", -1.0), ("left", 1.0))
_DEG = math.pi / 180
# Joint limits [deg]: typical active ranges of motion of adults (AAOS, Greene & Heckman 1994).
LIMITS_DEG = {
    "torso_rotation": (-45, 45), "torso_tilt": (-30, 90), "neck_flexion": (-60, 70), "neck_rotation": (-80, 80),
    "shoulder_flexion": (-60, 180), "shoulder_abduction": (-30, 180), "elbow": (0, 150),
    "hip_flexion": (-30, 120), "hip_abduction": (-30, 45), "hip_rotation": (-45, 45), "knee": (-5, 140),
    "ankle": (-50, 30),
}
ARM_REST_ABDUCTION = 8 * _DEG  # arms hang clear of the chest
ELBOW_REST = 8 * _DEG
REACH_MISS = 0.01  # [m] a reach whose hand stops further than this from its target warns


def _limits(kind: str) -> tuple[float, float]:
    lo, hi = LIMITS_DEG[kind]
    return lo * _DEG, hi * _DEG


def _capsule_down(length: float, radius: float) -> tuple[Capsule, Pose]:
    """A capsule from the link origin down to -z ``length`` [m] (end to end)."""
    radius = min(radius, 0.45 * length)
    return Capsule(radius=radius, height=length - 2 * radius), Pose((0.0, 0.0, -0.5 * length))


def _capsule_across(width: float, radius: float, z: float) -> tuple[Capsule, Pose]:
    """A capsule along y, ``width`` end to end, centred at height ``z`` [m]."""
    rot = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # local z -> y
    return Capsule(radius=radius, height=width - 2 * radius), Pose((0.0, 0.0, z), rot)


def check_height(height) -> float:
    return V.number("person.height", height, lo=HEIGHT_RANGE[0], hi=HEIGHT_RANGE[1], unit="m")


def leg_geometry(height: float = 1.75) -> LegGeometry:
    """The sagittal leg of :func:`human_tree` (the walk's body translation is fitted to it)."""
    h = check_height(height)
    return LegGeometry(THIGH * h, SHANK * h, ANKLE_HEIGHT * h, HEEL_BEHIND_ANKLE * h,
                       (FOOT_LENGTH - HEEL_BEHIND_ANKLE) * h, HIP_JOINT_HALF_WIDTH * h)


def human_tree(height: float = 1.75, *, clothing: str | Material | None = None, clothing_thickness: float = 0.004,
               name: str = "human") -> KinematicTree:
    """An articulated human of ``height`` [m] standing at q = 0.

    The root link "pelvis" has its origin at the midpoint of the hip joints,
    x forward, y left, z up; at q = 0 the soles lie 0.530 H below it. All
    links are ``human_skin``. ``clothing`` (a material name such as
    "fabric", or a :class:`~twinsense.scene.materials.Material`) adds a layer
    ``clothing_thickness`` [m] over the trunk, arms and legs, seen only by
    ToF, camera, LiDAR and ultrasonic sensors (fabric is nearly transparent
    to mm-wave radar, and capacitive and inductive sensors respond to the
    body beneath).

    Joints (revolute, angles > 0): torso_rotation (left), torso_tilt
    (forward lean), neck_flexion (chin down), neck_rotation (left), and per
    side (``right_``, ``left_``): shoulder_flexion (arm forward),
    shoulder_abduction (arm out), elbow (flexion), hip_flexion (thigh
    forward), hip_abduction (leg out), hip_rotation (about the pelvis z,
    left > 0), knee (flexion), ankle (dorsiflexion, toes up); the hands are
    fixed to the forearms.
    """
    H = check_height(height)
    if clothing is not None and not isinstance(clothing, (str, Material)):
        raise ConfigError("person.clothing", clothing, "a material name (e.g. 'fabric'), a Material or None")
    if isinstance(clothing, str) and clothing not in material_names():
        raise UnknownNameError("person.clothing", clothing, material_names())
    V.number("person.clothing_thickness", clothing_thickness, lo=0.0005, hi=0.05, unit="m")
    links: list[Link] = []
    joints: list[Joint] = []

    def link(lname, geom_pose, clothed=False):
        geom, origin = geom_pose
        links.append(Link(lname, geom, SKIN, origin))
        if clothing is not None and clothed:
            c = clothing_thickness
            if isinstance(geom, Capsule):
                outer = Capsule(radius=geom.radius + c, height=geom.height)
            else:
                outer = Box(tuple(np.asarray(geom.size) + 2 * c))
            links.append(Link(f"{lname}_clothing", outer, clothing, origin, layers=CLOTHING_LAYERS))
            joints.append(Joint(f"{lname}_clothing", "fixed", lname, f"{lname}_clothing"))

    def joint(jname, kind, parent, child, xyz, axis):
        lo, hi = _limits(kind)
        joints.append(Joint(jname, "revolute", parent, child, Pose(np.asarray(xyz, float) * H), axis, lo, hi))

    def fill(parent, z_lo, z_hi):
        """The trunk between two rolls' axes at heights ``z_lo``, ``z_hi`` [H] of ``parent``'s frame:
        the rectangle of the rolls' straight parts swept by a sphere of the rolls' radius (a box
        and two upright capsules). With the rolls it makes one rounded slab, TRUNK_DEPTH deep and
        TRUNK_WIDTH wide, so the trunk's front and sides have no grooves between the rolls."""
        r, c = 0.5 * TRUNK_DEPTH * H, (TRUNK_WIDTH - TRUNK_DEPTH) * H  # the abdomen roll's radius, straight part
        dz, zc = (z_hi - z_lo) * H, 0.5 * (z_lo + z_hi) * H
        link(f"{parent}_fill", (Box((2 * r, c, dz)), Pose((0.0, 0.0, zc))), True)
        joints.append(Joint(f"{parent}_fill", "fixed", parent, f"{parent}_fill"))
        for side, s in SIDES:
            link(f"{parent}_fill_{side}", (Capsule(radius=r, height=dz), Pose((0.0, s * 0.5 * c, zc))), True)
            joints.append(Joint(f"{parent}_fill_{side}", "fixed", parent, f"{parent}_fill_{side}"))

    trunk = SHOULDER_HEIGHT - HIP_HEIGHT  # 0.288 H from the hip joints to the shoulders
    link("pelvis", _capsule_across(0.20 * H, 0.06 * H, 0.03 * H), True)
    joint("torso_rotation", "torso_rotation", "pelvis", "abdomen", (0, 0, 0.07), (0, 0, 1))
    link("abdomen", _capsule_across(TRUNK_WIDTH * H, 0.5 * TRUNK_DEPTH * H, 0.03 * H), True)
    fill("abdomen", -0.04, 0.03)  # pelvis roll axis (0.56 H) to the abdomen's (0.63 H)
    joint("torso_tilt", "torso_tilt", "abdomen", "thorax", (0, 0, 0.06), (0, -1, 0))
    chest_z = trunk - 0.13 - 0.065  # 0.093 H above the thorax joint (0.753 H above the floor)
    link("thorax", (Capsule(radius=0.065 * H, height=0.09 * H),
                    Pose((0, 0, chest_z * H), _capsule_across(1, 0.1, 0)[1].rotation)), True)
    fill("thorax", -0.03, chest_z)  # abdomen roll axis (0.63 H) to the chest's (0.753 H)
    joint("neck_flexion", "neck_flexion", "thorax", "neck", (0, 0, trunk - 0.13), (0, -1, 0))
    link("neck", (Capsule(radius=0.03 * H, height=0.0), Pose((0, 0, 0.026 * H))))
    joint("neck_rotation", "neck_rotation", "neck", "head", (0, 0, CHIN_HEIGHT - SHOULDER_HEIGHT), (0, 0, 1))
    # Chin (0.870 H) to crown (1.000 H): 0.13 H end to end, centred 0.065 H above the chin.
    link("head", (Capsule(radius=0.055 * H, height=0.02 * H), Pose((0.01 * H, 0, 0.065 * H))))
    shoulder_z = trunk - 0.13 - SHOULDER_JOINT_DROP
    for side, s in SIDES:
        p = f"{side}_"
        joint(p + "shoulder_flexion", "shoulder_flexion", "thorax", p + "shoulder",
              (0, s * SHOULDER_JOINT_HALF_WIDTH, shoulder_z), (0, -1, 0))
        link(p + "shoulder", (Capsule(radius=0.028 * H, height=0.0), Pose()))
        joint(p + "shoulder_abduction", "shoulder_abduction", p + "shoulder", p + "upper_arm", (0, 0, 0), (s, 0, 0))
        link(p + "upper_arm", _capsule_down(UPPER_ARM * H, 0.026 * H), True)
        joint(p + "elbow", "elbow", p + "upper_arm", p + "forearm", (0, 0, -UPPER_ARM), (0, -1, 0))
        link(p + "forearm", _capsule_down(FOREARM * H, 0.021 * H), True)
        joints.append(Joint(p + "wrist", "fixed", p + "forearm", p + "hand", Pose((0, 0, -FOREARM * H))))
        links.append(Link(p + "hand", Box((0.025 * H, 0.05 * H, HAND * H)), SKIN, Pose((0, 0, -0.5 * HAND * H))))
        # Hip rotation (inward > 0 for the right leg's z), flexion, abduction: frames between the axes.
        joint(p + "hip_rotation", "hip_rotation", "pelvis", p + "hip_turn", (0, s * HIP_JOINT_HALF_WIDTH, 0), (0, 0, 1))
        links.append(Link(p + "hip_turn"))
        joint(p + "hip_flexion", "hip_flexion", p + "hip_turn", p + "hip", (0, 0, 0), (0, -1, 0))
        links.append(Link(p + "hip"))
        joint(p + "hip_abduction", "hip_abduction", p + "hip", p + "thigh", (0, 0, 0), (s, 0, 0))
        link(p + "thigh", _capsule_down(THIGH * H, 0.045 * H), True)
        joint(p + "knee", "knee", p + "thigh", p + "shank", (0, 0, -THIGH), (0, 1, 0))
        link(p + "shank", _capsule_down(SHANK * H, 0.032 * H), True)
        joint(p + "ankle", "ankle", p + "shank", p + "foot", (0, 0, -SHANK), (0, -1, 0))
        heel = HEEL_BEHIND_ANKLE
        link(p + "foot", (Box((FOOT_LENGTH * H, FOOT_WIDTH * H, ANKLE_HEIGHT * H)),
                          Pose(((0.5 * FOOT_LENGTH - heel) * H, 0, -0.5 * ANKLE_HEIGHT * H))))
    return KinematicTree(name, links, joints)


def foot_sole_points(height: float) -> np.ndarray:
    """(2, 3) heel and toe points of a sole (on the mid-line) in the foot link frame [m]."""
    h = check_height(height)
    return np.array([[-HEEL_BEHIND_ANKLE * h, 0, -ANKLE_HEIGHT * h],
                     [(FOOT_LENGTH - HEEL_BEHIND_ANKLE) * h, 0, -ANKLE_HEIGHT * h]])


# ---------------------------------------------------------------- paths
def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def _tangent_distance(turn: float) -> float:
    """Distance [per metre of ramp] from a corner to where a heading ramp turning by ``turn`` [rad]
    leaves the incoming line (and, by symmetry, joins the outgoing one)."""
    if abs(turn) < 1e-9:
        return 0.5
    gx, gw = np.polynomial.legendre.leggauss(24)
    w, _ = smoothstep(0.5 * (gx + 1.0))
    dx, dy = 0.5 * float(gw @ np.cos(turn * w)), 0.5 * float(gw @ np.sin(turn * w))
    # The ramp ends at (dx, dy) heading along `turn`; that line meets the incoming x axis at the corner.
    return dx - dy / math.tan(turn)


class HeadingPath:
    """A floor path whose heading turns smoothly: position and heading by arc length.

    ``points`` (n >= 2, 2 or 3) [m] are waypoints on the floor (z ignored).
    Each inner waypoint is a corner rounded by a fillet: the heading ramps
    (C1, 3 s^2 - 2 s^3 in arc length, so the heading rate is continuous) from
    the incoming to the outgoing direction over ``turn_length`` [m] of path,
    leaving the incoming segment and joining the outgoing one at the same
    distance from the waypoint; the path therefore runs along every segment
    and ends exactly at the last waypoint. ``points`` of one row plus
    ``heading`` [rad] give an endless straight line.
    """

    NODE_SPACING = 0.01  # [m] between the nodes of the position spline

    def __init__(self, points, heading: float | None = None, turn_length: float = 1.0):
        p = np.asarray(points, float) if not isinstance(points, str) else points
        if not isinstance(p, np.ndarray) or p.ndim != 2 or p.shape[1] not in (2, 3) or len(p) < 1 \
                or not np.all(np.isfinite(p)) or np.any(np.abs(p) > V.LENGTH_MAX):
            raise ConfigError("walk.path", points, "waypoints (n, 2) or (n, 3) [m], finite, within 10 km")
        self.turn_length = V.number("walk.turn_length", turn_length, lo=0.05, hi=100.0, unit="m")
        self.start = p[0, :2].copy()
        if len(p) == 1:
            if heading is None:
                raise ConfigError("walk.heading_deg", heading, "a heading [deg] for a walk without a path")
            self.headings = np.array([V.number("walk.heading", heading, unit="rad")])
            self.length = math.inf
            self._spline = None
            return
        seg = np.diff(p[:, :2], axis=0)
        lens = np.linalg.norm(seg, axis=1)
        if np.any(lens < 1e-3):
            raise ConfigError("walk.path", points, "waypoints at least 1 mm apart on the floor")
        self.headings = np.arctan2(seg[:, 1], seg[:, 0])
        turns = _wrap(np.diff(self.headings))
        if np.any(np.abs(turns) > np.radians(175)):
            raise ConfigError("walk.path", points, "turns of less than 175 deg at each waypoint")
        # Each corner is a fillet: the heading ramp leaves the incoming segment and joins the
        # outgoing one at the same distance d from the waypoint (symmetric ramp), d = ell d1(turn);
        # ell = turn_length unless d would pass half of either neighbouring segment.
        d1 = np.array([_tangent_distance(float(tn)) for tn in turns])
        ell = np.minimum(self.turn_length, 0.5 * np.minimum(lens[:-1], lens[1:]) / d1)
        d = ell * d1
        starts, s_arc, before = [], 0.0, 0.0
        for i in range(len(turns)):
            s_arc += lens[i] - before - d[i]
            starts.append(s_arc)
            s_arc += ell[i]
            before = d[i]
        self._starts, self._ells, self._turns = np.array(starts), ell, turns
        self.length = float(s_arc + lens[-1] - before)
        n = max(math.ceil(self.length / self.NODE_SPACING), 2)
        s = np.linspace(0.0, self.length, n + 1)
        # Node positions: 5-point Gauss-Legendre on each interval of the unit tangent.
        gx, gw = np.polynomial.legendre.leggauss(5)
        h = np.diff(s)
        mid = 0.5 * (s[:-1] + s[1:])
        q = mid[:, None] + 0.5 * h[:, None] * gx[None, :]
        psi_q = self._psi(q.ravel())[0].reshape(q.shape)
        dx = 0.5 * h * (np.cos(psi_q) @ gw)
        dy = 0.5 * h * (np.sin(psi_q) @ gw)
        xy = self.start + np.column_stack([np.concatenate([[0], np.cumsum(dx)]), np.concatenate([[0], np.cumsum(dy)])])
        psi = self._psi(s)[0]
        self._spline = CubicHermiteSpline(s, xy, np.column_stack([np.cos(psi), np.sin(psi)]), axis=0)
        self._rate = self._spline.derivative()

    def _psi(self, s):
        """Heading [rad] and d heading / ds [rad/m] at arc lengths ``s``."""
        s = np.asarray(s, float)
        psi = np.full(s.shape, self.headings[0])
        dpsi = np.zeros(s.shape)
        if len(self.headings) == 1:
            return psi, dpsi
        for a, ell, turn in zip(self._starts, self._ells, self._turns, strict=True):
            w, wd = smoothstep((s - a) / ell)
            psi = psi + turn * w
            dpsi = dpsi + turn * wd / ell
        return psi, dpsi

    def at(self, s) -> tuple[np.ndarray, np.ndarray, float, float]:
        """Floor point (2,) [m], unit tangent (2,), heading [rad], d heading/ds [rad/m] at arc length ``s``."""
        s = float(s)
        psi, dpsi = self._psi(s)
        psi, dpsi = float(psi), float(dpsi)
        tangent = np.array([math.cos(psi), math.sin(psi)])
        if self._spline is None:
            return self.start + s * tangent, tangent, psi, dpsi
        if s <= 0:
            return self.start + s * tangent, tangent, psi, dpsi
        if s >= self.length:
            end = self._spline(self.length)
            return end + (s - self.length) * tangent, tangent, psi, dpsi
        return self._spline(s), tangent, psi, dpsi

    def rate(self, s) -> np.ndarray:
        """d(floor point)/ds (2,) at arc length ``s``: the derivative of the positions :meth:`at` gives.

        The unit tangent at the spline's nodes; between them the cubic's own slope, which differs
        from the exact tangent by O(h^3) (up to ~3e-4 in a 170 deg corner) but is what makes a
        walker's velocity the time derivative of its positions.
        """
        s = float(s)
        if self._spline is None or s <= 0 or s >= self.length:
            return self.at(s)[1]
        return self._rate(s)


# ---------------------------------------------------------------- what a person does
@dataclass(frozen=True)
class Walk:
    """Walk at ``speed`` [m/s] from ``start_time`` [s] along ``path`` (waypoints (n, 2|3) [m],
    starting at the first) or, without a path, endlessly along ``heading_deg`` [deg, from +x
    towards +y]. ``turn_length`` [m]: path length over which a corner's heading change ramps.
    ``body``: "planted" (the standing foot stays put and the pelvis moves as published, by a
    time-warp of the stance leg's curves), "smooth" (the published timing; the standing foot
    rocks about its place; see :class:`~twinsense.scene.gait.WalkCycle`) or "auto" (the
    default: planted where the planted body can walk at this speed, else smooth; the person's
    ``cycle.body`` says which)."""

    speed: float = 1.3
    path: tuple | None = None
    heading_deg: float | None = None
    start_time: float = 0.0
    turn_length: float = 1.0
    body: str = "auto"

    def __post_init__(self):
        V.positive("walk.speed", self.speed, "m/s")
        V.choice("walk.body", self.body, WALK_BODIES)
        V.time("walk.start_time", self.start_time)
        V.number("walk.turn_length", self.turn_length, lo=0.05, hi=100.0, unit="m")
        if self.path is None and self.heading_deg is None:
            raise ConfigError("walk.path", None, "a path (waypoints) or a heading_deg")
        if self.path is not None:
            try:
                pts = None if isinstance(self.path, (str, bytes, dict)) else np.asarray(self.path, float)
            except (TypeError, ValueError):
                pts = None
            if pts is None or pts.ndim != 2 or pts.shape[1] not in (2, 3) or len(pts) < 1 \
                    or not np.all(np.isfinite(pts)) or np.any(np.abs(pts) > V.LENGTH_MAX):
                raise ConfigError("walk.path", self.path, "waypoints (n, 2) or (n, 3) [m], n >= 1, finite, "
                                  "within 10 km (the walk starts where the person stands)")
        if self.heading_deg is not None:
            V.number("walk.heading_deg", self.heading_deg, unit="deg")
            if self.path is not None:
                raise ConfigError("walk.heading_deg", self.heading_deg,
                                  "none with a path (its waypoints set the heading), or a heading without a path")


@dataclass(frozen=True)
class Reach:
    """Move the ``side`` hand ("right"/"left") to world point ``target`` (3,) [m].

    The arm moves over ``duration`` [s] from ``start_time`` [s], holds for
    ``hold`` [s], and returns over ``duration`` (``hold`` = inf keeps it there).
    The arm pose is solved for the thorax at ``start_time + duration``, when
    the hand arrives.
    """

    target: tuple = (0.5, 0.0, 1.2)
    start_time: float = 0.0
    duration: float = 1.0
    hold: float = 1.0
    side: str = "right"

    def __post_init__(self):
        V.vector("reach.target", self.target, 3, "m")
        V.time("reach.start_time", self.start_time)
        V.number("reach.duration", self.duration, lo=0.05, hi=60.0, unit="s")
        if not (isinstance(self.hold, (int, float)) and not isinstance(self.hold, bool)
                and (self.hold == math.inf or 0 <= self.hold <= V.TIME_MAX)):
            raise ConfigError("reach.hold", self.hold, "a time >= 0 [s] or inf")
        V.choice("reach.side", self.side, ("right", "left"))


@dataclass(frozen=True)
class Turn:
    """Turn on the spot (while standing) to ``heading_deg`` [deg] over ``duration`` [s] from ``start_time`` [s]."""

    heading_deg: float = 0.0
    start_time: float = 0.0
    duration: float = 1.0

    def __post_init__(self):
        V.number("turn.heading_deg", self.heading_deg, unit="deg")
        V.time("turn.start_time", self.start_time)
        V.number("turn.duration", self.duration, lo=0.05, hi=60.0, unit="s")


# [s] the walk's gait rate ramps from 0 to 1 over this after its start (and from 1 to 0 over this
# before a path's end) while the standing pose fades out (in); the walk arrives START_BLEND later
# than start_time + L / v (each ramp covers half of what full speed would).
START_BLEND = 0.6
# [s] each of the two steps that close the stance after a path's end (the walk stops at an arbitrary
# phase of its cycle: one foot steps beside where the standing pose puts it, then the other).
CLOSE_STEP = 0.4
# A closing step lifts the foot straight up by CLOSE_LIFT H (4.4 cm at 1.75 m), carries it over an apex
# that high above the higher of its two places and sets it straight down (STEP_KNOTS).
CLOSE_LIFT = 0.025
STEP_KNOTS = (0.0, 0.2, 0.5, 0.8, 1.0)  # a closing step: its start, lifted, apex, lifted over the foothold, on it
START_SWING = "left"  # the leg that swings as the walk starts (the reference right foot is in mid-stance)
START_KNOTS = 13  # closed-form poses of the swinging leg over the start ramp (both ends: the plan's own)
START_LIFT_ONLY = 0.15  # share of the start ramp over which the swinging foot only rises
PLANTED_KNOTS = 9  # closed-form leg poses along the pelvis's path over a standing foot
LIMIT_MARGIN = 0.05  # [rad] closed-form leg poses stay this far inside the joint limits; a spline past it is squeezed
PELVIS_DIP = 0.01  # [H] the pelvis's pause between the closing steps: this far below its lower end height
LEG_JOINTS = ("hip_rotation", "hip_flexion", "hip_abduction", "knee", "ankle")
CONTACT_HEIGHT = 0.005  # [m] a sole point this far above the floor is off it
SWAY_FREQUENCY = 0.2  # [Hz] of a standing person's lateral sway


def _pair(vd) -> tuple[float, float]:
    """(value, rate) of a curve at one time as floats."""
    return float(np.ravel(vd[0])[0]), float(np.ravel(vd[1])[0])


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _joint_spline(knots, values, lift: bool = False) -> CubicHermiteSpline:
    """C1 spline through joint vectors ``values`` at ``knots`` (increasing, from 0 to 1), at rest at both
    ends. Inner slopes: Catmull-Rom; with ``lift`` (a step's start, lifted start, ..., lifted end, end)
    the second and second-last take the slopes of the first and last chords, so that those pieces run along
    their chords (the foot goes straight up and straight down, as nearly as a straight line in joint
    space does over a few centimetres) and the middle one arcs over."""
    x, y = np.asarray(knots, float), np.asarray(values, float)
    dy = np.zeros_like(y)
    dy[1:-1] = (y[2:] - y[:-2]) / (x[2:] - x[:-2])[:, None]
    if lift:
        dy[1] = (y[1] - y[0]) / (x[1] - x[0])
        dy[-2] = (y[-1] - y[-2]) / (x[-1] - x[-2])
    return CubicHermiteSpline(x, y, dy, axis=0)


@dataclass
class _Plan:
    """Base position/velocity, yaw, roll (and rates), and q, qd at one time."""

    p: np.ndarray
    v: np.ndarray
    yaw: float
    yaw_d: float
    roll: float
    roll_d: float
    q: np.ndarray
    qd: np.ndarray

    def fade(self, stand: _Plan, ref: _Plan, k: float, kd: float, dyaw: float) -> _Plan:
        """self + k (stand - ref): the difference between a standing plan and a fixed pose of the gait
        ``ref`` (its rates ignored), weighted by ``k`` (rate ``kd`` [1/s]), added to this plan.
        ``dyaw`` [rad] is stand.yaw - ref.yaw on the branch the caller chose (a difference wrapped
        to +-pi at each instant would flip with the pelvis torsion in a turn of about half round).

        The gait runs on under it (its forward progress is not faded: the reference pose is where
        the gait is at the start or end of the walk), so the fade moves the pelvis only by the
        small lateral and vertical offsets of that pose and the joints from the standing angles.
        """
        def mix(a, s_, r, ad, sd):
            return a + k * (s_ - r), ad + k * sd + kd * (s_ - r)
        p, v = mix(self.p, stand.p, ref.p, self.v, stand.v)
        yaw, yaw_d = self.yaw + k * dyaw, self.yaw_d + k * stand.yaw_d + kd * dyaw
        roll, roll_d = mix(self.roll, stand.roll, ref.roll, self.roll_d, stand.roll_d)
        q, qd = mix(self.q, stand.q, ref.q, self.qd, stand.qd)
        return _Plan(p, v, yaw, yaw_d, roll, roll_d, q, qd)


def _refuse(owner: object, name: str, value, verb: str = "assign") -> FrozenInstanceError:
    """The error of a change to a read-only person: names the attribute, the value and the way out."""
    cls = type(owner).__name__
    what = f" = {value!r}" if verb == "assign" else ""
    return FrozenInstanceError(
        f"cannot {verb} {cls}.{name}{what}: a person's motion is read-only once built (the caches of its "
        "states, of its body's forward kinematics and of the sensors' prepares key on it); build a new "
        "person instead (person_body, add_person, Walker)")


class _ReadOnly:
    """Attributes set in ``__init__`` only: later assignments and deletions raise FrozenInstanceError,
    except the names in ``_CACHES`` (what the object memoises about itself)."""

    _CACHES: frozenset = frozenset()

    def _seal(self) -> None:
        object.__setattr__(self, "_sealed", True)

    def __setattr__(self, name: str, value) -> None:
        if name not in self._CACHES and self.__dict__.get("_sealed", False):
            raise _refuse(self, name, value)
        object.__setattr__(self, name, value)

    def __delattr__(self, name: str) -> None:
        if name not in self._CACHES and self.__dict__.get("_sealed", False):
            raise _refuse(self, name, None, "delete")
        object.__delattr__(self, name)

    def __setstate__(self, state: dict) -> None:
        # A copy (pickle, deepcopy) is as read-only as its original: its arrays come back writable.
        self.__dict__.update(state)
        for name, value in state.items():
            if isinstance(value, np.ndarray) and name not in self._CACHES:
                value.setflags(write=False)


class PersonMotion(_ReadOnly):
    """Everything one person does, as exact functions of time.

    Read-only once built: an assignment to any attribute (``sway``,
    ``walk``, ``reach``, ...) raises ``dataclasses.FrozenInstanceError``,
    as a frozen dataclass does, and ``start_xy`` is a read-only array. The
    states are cached by time (here, in the body's forward kinematics and
    in a capacitive sensor's prepare), so a changed motion would be served
    stale; a new person (:func:`person_body`, :func:`add_person`) is the
    way to another motion.

    Parameters
    ----------
    tree : KinematicTree
        From :func:`human_tree` (its height is ``height``).
    height : float
        Body height [m].
    position : (2,) or (3,) float
        Where the person stands at first (floor point; z is the floor height) [m].
    heading_deg : float
        Where the person faces at first [deg, from +x towards +y].
    walk : Walk, optional
    turn : Turn, optional
        A turn on the spot while standing (before the walk starts).
    reach : Reach, optional
    sway : float
        Lateral sway amplitude of a standing person [m] (0.2 Hz).

    ``arrival_time`` [s] is when a walk along a path arrives, its gait at rest (start_time + L / v +
    START_BLEND, give or take the forward sway; inf without a path); ``stop_time`` [s] = arrival_time
    + 2 CLOSE_STEP is when the two steps that close the stance end and the person stands on the path's
    end; :attr:`gait_origin` where the steady gait's phases count from.
    """

    def __init__(self, tree: KinematicTree, height: float, position=(0.0, 0.0), heading_deg: float = 0.0,
                 walk: Walk | None = None, turn: Turn | None = None, reach: Reach | None = None,
                 sway: float = 0.0):
        self.tree = tree
        self.height = H = check_height(height)
        pos = V.array("person.position", position, (None,), "m")
        if pos.shape not in ((2,), (3,)):
            raise ConfigError("person.position", position, "a floor point (x, y) or (x, y, z) [m]")
        self.floor = float(pos[2]) if len(pos) == 3 else 0.0
        self.heading = math.radians(V.number("person.heading_deg", heading_deg, unit="deg"))
        for name, obj, cls in (("walk", walk, Walk), ("turn", turn, Turn), ("reach", reach, Reach)):
            if obj is not None and not isinstance(obj, cls):
                raise ConfigError(f"person.{name}", obj, f"a {cls.__name__} or None")
        self.walk, self.turn, self.reach = walk, turn, reach
        if walk is not None and turn is not None and turn.start_time >= walk.start_time:
            # A turn on the spot happens while standing; once the walk is under way the path sets the heading.
            raise ConfigError("turn.start_time", turn.start_time,
                              f"a time before the walk's start_time {walk.start_time:g} s (a turn on the spot "
                              "happens while standing; a path's waypoints turn a walker)")
        self.sway = V.number("person.sway", sway, lo=0.0, hi=0.1, unit="m")
        self.leg = leg_geometry(H)
        self._col = {n: i for i, n in enumerate(tree.joint_names)}
        q_rest = np.zeros(tree.n_joints)
        for side, _ in SIDES:
            q_rest[self._col[f"{side}_shoulder_abduction"]] = ARM_REST_ABDUCTION
            q_rest[self._col[f"{side}_elbow"]] = ELBOW_REST
        self._q_rest = q_rest
        self.cycle = None
        self.path = None
        self.stop_time = self.arrival_time = math.inf
        self.start_xy = start_xy = pos[:2].copy()
        if walk is not None:
            if walk.path is not None:
                # The walk starts where the person stands and then passes the waypoints.
                pts = np.asarray(walk.path, float)  # checked by Walk
                try:
                    self.path = HeadingPath(np.vstack([start_xy, pts[:, :2]]), None, walk.turn_length)
                except ConfigError as e:  # name the waypoints as given, not with the start prepended
                    raise ConfigError(e.field, walk.path if e.field == "walk.path" else e.value, e.allowed) from None
            else:
                self.path = HeadingPath(start_xy[None], math.radians(walk.heading_deg), walk.turn_length)
        self._reach_q = None
        self._last = None
        self._start_turn = 0.0
        self._gait0 = self._gait_end = self._x0 = 0.0
        self._rate = 1.0
        self._close = None
        self._start_swing = None
        if walk is not None:
            # "auto": the planted body where it can walk (its leg sweeps the stance under the pelvis and
            # its swing keeps the joints within their limits), else the smooth one.
            bodies = ("planted", "smooth") if walk.body == "auto" else (walk.body,)
            timing = GaitTiming(walk.speed, self.leg.leg_length)
            for k, body in enumerate(bodies):
                try:
                    self.cycle = WalkCycle(timing, self.leg, body)
                    self._schedule()
                    # The start's turn from the standing heading to the path's [rad], chosen once.
                    t0 = walk.start_time
                    self._start_turn = float(_wrap(self._walking(self._gait0, 0.0).yaw
                                                   - self._standing(t0, start_xy, self.heading).yaw))
                    self._check_gait_limits()
                    break
                except ConfigError:
                    if k == len(bodies) - 1:
                        raise
            # The gait's first and last poses, which the standing poses fade from and into.
            self._ref0 = self._walking(self._gait0, 0.0)
            self._stand0_yaw = self._standing(walk.start_time, start_xy, self.heading).yaw
            if math.isfinite(self.stop_time):
                self._ref_end = self._walking(self._gait_end, 0.0)
                self._close = self._closing_steps()
            self._start_swing = self._starting_step()
            self._last = None  # states cached while the start's step was solved lack it
        self.start_xy.setflags(write=False)
        self._q_rest.setflags(write=False)
        self._seal()

    _CACHES = frozenset({"_last", "_reach_q"})  # the state at the last time; the reach's arm angles

    def _check_gait_limits(self) -> None:
        """Refuse, at set-up, a walk whose joint curves would leave the joint limits (the swing
        lift of a slow planted walk can), rather than fail in the middle of a run."""
        lo, hi = self.tree.limits.T
        dc = self.cycle.timing.cycle_duration
        for t in self._gait0 + np.linspace(0.0, dc, 97):
            q = self._walking(float(t), 1.0).q
            bad = np.nonzero((q < lo) | (q > hi))[0]
            if len(bad):
                j = self.tree.joint_names[bad[0]]
                raise ConfigError("walk.speed", self.walk.speed,
                                  f"a speed whose gait keeps every joint within its limits (joint {j!r} reaches "
                                  f"{math.degrees(q[bad[0]]):.1f} deg, limits [{math.degrees(lo[bad[0]]):.0f}, "
                                  f"{math.degrees(hi[bad[0]]):.0f}] deg; body={self.cycle.body!r})")

    def _schedule(self) -> None:
        """The walk's gait times, its peak rate and ``stop_time``.

        The gait starts at the reference (right) foot's mid-stance, at the gait time ``_gait0``
        where that foot's sole centre is as far ahead of the pelvis as a standing person's (the
        other foot swings beside it): the standing pose is then closest to the gait's, and the
        fade between them hardly moves the standing foot. It ends at ``_gait_end``, where the
        pelvis has come the path's length (root of the forward body translation). The gait time
        phi(t) (:meth:`_phase`) ramps its rate smoothly from 0 to 1 over START_BLEND, and back to
        0 over the last START_BLEND; a walk too short for that peaks at rate G / START_BLEND < 1
        (G = _gait_end - _gait0).
        """
        from scipy.optimize import brentq

        wc, walk = self.cycle, self.walk
        dc = wc.timing.cycle_duration
        centre = 0.5 * (FOOT_LENGTH - 2 * HEEL_BEHIND_ANKLE) * self.height  # standing: sole centre ahead
        tg = np.linspace(0.0, wc.timing.relative_support * dc, 257)

        def ahead(t):
            x = wc.sole_points(t)[0]
            return 0.5 * (x[0] + x[1]) - centre

        gap = ahead(tg)
        k = np.nonzero((gap[:-1] > 0) & (gap[1:] <= 0))[0]
        if len(k):
            self._gait0 = float(brentq(lambda t: float(ahead(t)[0]), tg[k[0]], tg[k[0] + 1], xtol=1e-12))
        else:  # not reached (no stance crosses it): the nearest
            self._gait0 = float(tg[np.argmin(np.abs(gap))])
        self._x0 = float(wc.body_translation(self._gait0)[0][0, 0])
        length, v = self.path.length, walk.speed
        if not math.isfinite(length):
            self._gait_end, self._rate = math.inf, 1.0
            self.arrival_time = self.stop_time = math.inf
            return

        def short(t):
            return float(wc.body_translation(t)[0][0, 0]) - self._x0 - length

        # The pelvis never moves backwards, and its forward translation stays within a fraction of
        # a step of v t: the root lies within half a cycle of L / v.
        lo, hi = self._gait0 + max(0.0, length / v - 0.5 * dc), self._gait0 + length / v + 0.5 * dc
        self._gait_end = float(brentq(short, lo, hi, xtol=1e-13, rtol=4 * np.finfo(float).eps))
        g = self._gait_end - self._gait0
        self._rate = min(1.0, g / START_BLEND)
        self.arrival_time = walk.start_time + START_BLEND + max(g, START_BLEND)
        self.stop_time = self.arrival_time + 2 * CLOSE_STEP

    @property
    def gait_origin(self) -> float:
        """Wall time [s] from which the steady walk's gait phases count: between the start and stop
        ramps the reference (right) heel strikes at ``gait_origin + n D_c`` (inf without a walk).
        The walk starts at the reference foot's mid-stance and its rate ramps up over START_BLEND,
        so this is ``walk.start_time + START_BLEND / 2 - _gait0``."""
        if self.walk is None:
            return math.inf
        return self.walk.start_time + 0.5 * START_BLEND - self._gait0

    def _phase(self, t: float) -> tuple[float, float]:
        """Gait time phi [s] and its rate d phi / dt at ``t`` [s] of a walk under way.

        With B = START_BLEND, r the peak rate, F(x) = x^3 - x^4 / 2 (the integral of the ramp
        3 x^2 - 2 x^3): phi = gait0 + r B F(tau / B) over the start (tau = t - start_time), then
        gait0 + tau - B / 2, and gait_end - r B F((stop_time - t) / B) over the stop. The rate is
        r (3 x^2 - 2 x^3): it rises from 0 and falls to 0 monotonically with a continuous
        derivative (0 at both ends of each ramp), so positions and velocities are continuous.
        """
        B, r = START_BLEND, self._rate
        tau = t - self.walk.start_time
        left = self.arrival_time - t
        # A walk shorter than B of gait (r < 1) has no steady part: its two ramps meet at
        # start_time + B, where tau = left = B (give or take rounding), and the time belongs to
        # whichever ramp is nearer. The steady branch there would put the gait at gait0 + B / 2
        # instead of gait0 + r B / 2 (a jump of up to 0.3 s of gait, 0.4 m of pelvis at 1.2 m/s).
        if left < B or (r < 1.0 and left <= tau):
            x = min(max(left, 0.0), B) / B
            return self._gait_end - r * B * (x ** 3 - 0.5 * x ** 4), r * x * x * (3 - 2 * x)
        if tau < B or r < 1.0:
            x = min(max(tau, 0.0), B) / B
            return self._gait0 + r * B * (x ** 3 - 0.5 * x ** 4), r * x * x * (3 - 2 * x)
        return self._gait0 + tau - 0.5 * B, 1.0

    # ------------------------------------------------------------ pieces
    def _standing(self, t: float, xy, heading: float, turning: bool = True, sway: bool = True) -> _Plan:
        """Standing at ``xy`` facing ``heading`` at ``t``, swaying (if ``sway``); the turn on the spot if
        ``turning``."""
        yaw, yaw_d = heading, 0.0
        if self.turn is not None and turning:
            w, wd = smoothstep((t - self.turn.start_time) / self.turn.duration)
            dturn = float(_wrap(math.radians(self.turn.heading_deg) - heading))
            yaw, yaw_d = heading + dturn * float(w), dturn * float(wd) / self.turn.duration
        q, qd = self._q_rest.copy(), np.zeros(self.tree.n_joints)
        d, dd = 0.0, 0.0
        if self.sway > 0 and sway:
            arg = 2 * math.pi * SWAY_FREQUENCY * t
            d, dd = self.sway * math.sin(arg), self.sway * 2 * math.pi * SWAY_FREQUENCY * math.cos(arg)
        self._hip_abduction(q, qd, d, dd, 0.0, 0.0)
        n = np.array([-math.sin(yaw), math.cos(yaw)])
        p = np.array([xy[0] + d * n[0], xy[1] + d * n[1], self.floor + self.leg.leg_length])
        v = np.array([dd * n[0] - d * math.cos(yaw) * yaw_d, dd * n[1] - d * math.sin(yaw) * yaw_d, 0.0])
        return _Plan(p, v, yaw, yaw_d, 0.0, 0.0, q, qd)

    def _hip_abduction(self, q, qd, d, dd, roll, roll_d) -> None:
        """Legs that stay in their lanes under a lateral pelvis offset d [m] and a list (roll) [rad]."""
        ht = self.leg.leg_length
        a = math.atan(d / ht)
        ad = dd / ht / (1 + (d / ht) ** 2)
        for side, s in SIDES:
            c = self._col[f"{side}_hip_abduction"]
            q[c] = -s * (a + roll)
            qd[c] = -s * (ad + roll_d)

    def _walking(self, tg: float, rate: float) -> _Plan:
        """The gait's pose at gait time ``tg`` [s] (see :meth:`_phase`), its rates multiplied by
        ``rate`` (d tg / dt): the walk played ``rate`` times as fast, the same poses."""
        wc, path = self.cycle, self.path
        (p,), (v,) = wc.body_translation(tg)
        s, sd = float(p[0]) - self._x0, float(v[0])
        xy, tangent, psi, dpsi = path.at(s)
        psi_d = dpsi * sd
        normal = np.array([-tangent[1], tangent[0]])
        lat, lat_d = float(p[1]), float(v[1])
        pos = np.array([*(xy + lat * normal), self.floor + p[2]])
        vel = np.array([*(sd * path.rate(s) + lat_d * normal - lat * psi_d * tangent), v[2]])
        g = wc.gait
        tors, tors_d = _pair(g.curve("pelvis_torsion", tg))
        lst, lst_d = _pair(g.curve("pelvis_list", tg))
        roll, roll_d = -lst, -lst_d
        q, qd = self._q_rest.copy(), np.zeros(self.tree.n_joints)
        col = self._col
        for side, off in (("right", 0.0), ("left", 0.5)):
            for joint, curve in (("hip_flexion", "hip_flexion"), ("knee", "knee_flexion"), ("ankle", "ankle_flexion"),
                                 ("shoulder_flexion", "shoulder_flexion"), ("elbow", "elbow_flexion")):
                q[col[f"{side}_{joint}"]], qd[col[f"{side}_{joint}"]] = _pair(wc.joint_curve(curve, tg, off))
        self._hip_abduction(q, qd, lat, lat_d, roll, roll_d)
        # The legs turn against the pelvis torsion and keep swinging along the path.
        for side, _ in SIDES:
            q[col[f"{side}_hip_rotation"]], qd[col[f"{side}_hip_rotation"]] = -tors, -tors_d
        thor, thor_d = _pair(g.curve("thorax_torsion", tg))
        tilt, tilt_d = _pair(g.curve("pelvis_tilt", tg))
        # The thorax turns against the pelvis (-thor in the world), the head keeps facing the path.
        for name, val, der in (("torso_rotation", -thor - tors, -thor_d - tors_d), ("torso_tilt", tilt, tilt_d),
                               ("neck_flexion", -tilt, -tilt_d), ("neck_rotation", thor, thor_d)):
            q[col[name]], qd[col[name]] = val, der
        return _Plan(pos, vel * rate, psi + tors, (psi_d + tors_d) * rate, roll, roll_d * rate, q, qd * rate)

    def _plan(self, t: float, reach: bool = True) -> _Plan:
        walk = self.walk
        if walk is None or t <= walk.start_time:
            plan = self._standing(t, self.start_xy, self.heading)
        elif t >= self.stop_time:
            end_xy, _, end_psi, _ = self.path.at(self.path.length)
            plan = self._standing(t, end_xy, end_psi, turning=False)
        elif t >= self.arrival_time:
            plan = self._closing(t)
        else:
            plan = self._walking(*self._phase(t))
            tau = t - walk.start_time
            if tau < START_BLEND:
                # The standing pose's difference from the gait's first pose fades out (the standing
                # motion, a sway or a turn still under way, goes on under it), so nothing jumps.
                w, wd = smoothstep(tau / START_BLEND)
                stand = self._standing(t, self.start_xy, self.heading)
                dyaw = stand.yaw - self._stand0_yaw - self._start_turn
                plan = plan.fade(stand, self._ref0, 1.0 - float(w), -float(wd) / START_BLEND, dyaw)
                if self._start_swing is not None:
                    self._set_leg(plan, START_SWING, self._start_swing(tau), self._start_swing(tau, nu=1))
        if reach and self.reach is not None:
            self._apply_reach(t, plan)
        return plan

    # ------------------------------------------------------------ closing the stance after a path's end
    def _foot_poses(self, plan: _Plan) -> dict:
        """World pose of each foot link ({"right": Pose, "left": Pose}) in ``plan``."""
        base = Pose._trusted(plan.p, _rot_z(plan.yaw) @ _rot_x(plan.roll))
        st = self.tree.forward(plan.q, None, base)
        return {side: st.pose(f"{side}_foot") for side, _ in SIDES}

    def _leg_columns(self, side: str) -> np.ndarray:
        return np.array([self._col[f"{side}_{j}"] for j in LEG_JOINTS])

    def _leg_ik(self, pelvis: tuple, side: str, foot: Pose) -> np.ndarray:
        """(5,) angles of ``side``'s LEG_JOINTS [rad] that put its foot link (origin at the ankle joint)
        at ``foot`` (world) with the pelvis at ``pelvis`` = (position (3,) [m], yaw, roll [rad]).

        Closed form: the knee from the hip-ankle distance (clamped into the leg's reach), the leg's
        plane through the hip, the ankle and the foot's forward axis (the foot's roll follows that
        plane: the leg has no joint to set it), the hip's Z-Y-X angles from the thigh's rotation,
        and the ankle from the foot's forward axis in the shank's frame.
        """
        pos, yaw, roll = pelvis
        H, s = self.height, (1.0 if side == "left" else -1.0)
        T, S = THIGH * H, SHANK * H
        rb = _rot_z(yaw) @ _rot_x(roll)
        d = rb.T @ (foot.position - np.asarray(pos, float)) - np.array([0.0, s * HIP_JOINT_HALF_WIDTH * H, 0.0])
        fx = rb.T @ foot.rotation[:, 0]
        r = float(np.linalg.norm(d))
        r_c = min(max(r, abs(T - S) + 1e-9), (T + S) * (1.0 - 1e-12))
        knee = math.acos(max(-1.0, min(1.0, (r_c * r_c - T * T - S * S) / (2 * T * S))))
        leg = np.array([-S * math.sin(knee), 0.0, -T - S * math.cos(knee)])
        e1, e2 = leg / np.linalg.norm(leg), np.array([0.0, 1.0, 0.0])
        f1 = d / r
        n = np.cross(fx, f1)
        # The leg plane's normal is the thigh's (and foot's) lateral axis: on the side of the foot's own
        # lateral axis. fx x f1 alone flips for a foot pointing behind the hip-ankle line (knee past
        # about 90 deg, ankle plantarflexed), which was solved in the mirrored plane.
        f2 = n / (np.linalg.norm(n) * (1.0 if n @ (rb.T @ foot.rotation[:, 1]) >= 0.0 else -1.0))
        rot = np.column_stack([f1, f2, np.cross(f1, f2)]) @ np.column_stack([e1, e2, np.cross(e1, e2)]).T
        lo, hi = self.tree.limits[self._leg_columns(side)].T
        theta = math.asin(max(-1.0, min(1.0, -rot[2, 0])))
        turn, chi = math.atan2(rot[1, 0], rot[0, 0]), math.atan2(rot[2, 1], rot[2, 2])
        c = (rot @ _rot_y(knee)).T @ fx
        ankle = math.atan2(c[2], c[0])
        # Z-Y-X angles have two branches, (turn, theta, chi) and (turn + pi, pi - theta, chi + pi): the
        # one within the limits (a hip flexed past 90 deg, theta < -90 deg, is on the second).
        out = min((np.array([turn, -theta, s * chi, knee, ankle]),
                   np.array([_wrap(turn + math.pi), -_wrap(math.pi - theta), s * _wrap(chi + math.pi), knee, ankle])),
                  key=lambda x: float(np.sum(np.maximum(lo - x, 0.0) + np.maximum(x - hi, 0.0))))
        # Into the joint limits, LIMIT_MARGIN inside them: the splines through these poses may overshoot
        # a little between them (a foot on its foothold then tilts by the clipped angle).
        return np.clip(out, lo + LIMIT_MARGIN, hi - LIMIT_MARGIN)

    def _closing_steps(self) -> tuple:
        """The closing steps after the walk's arrival (see :meth:`_closing`): (first side, second side,
        the pelvis's (position (3,), yaw, roll) where the gait stopped, between the steps and standing,
        per step the stepping leg's joint spline over the step (u in [0, 1]) and the standing leg's
        over the pelvis's fade weight, and per side the standing sway's lever [m] over both steps)."""
        ref = self._ref_end
        end_xy, _, end_psi, _ = self.path.at(self.path.length)
        still = self._standing(0.0, end_xy, end_psi, turning=False, sway=False)
        at_end, standing = self._foot_poses(ref), self._foot_poses(still)
        sole = foot_sole_points(self.height)
        low = {side: float(at_end[side].apply(sole)[:, 2].min()) for side, _ in SIDES}
        forward = np.array([math.cos(end_psi), math.sin(end_psi), 0.0])
        if abs(low["right"] - low["left"]) > CONTACT_HEIGHT:
            # One foot in its swing: it is the free one and steps first.
            first = "right" if low["right"] > low["left"] else "left"
        else:  # both on the floor: the one behind (in its push-off) steps first
            first = min(("right", "left"), key=lambda side: float(at_end[side].position @ forward))
        second = "left" if first == "right" else "right"
        # Between the steps the pelvis pauses halfway, PELVIS_DIP below the lower of its two heights: the
        # first foot's foothold (under the standing hip) is then within the leg's reach with the knee bent,
        # also when the gait stopped with the pelvis higher than standing (on the stance foot's toe).
        dyaw = float(_wrap(still.yaw - ref.yaw))
        mid = 0.5 * (ref.p + still.p)
        mid[2] = min(ref.p[2], still.p[2]) - PELVIS_DIP * self.height
        poses = ((ref.p, ref.yaw, ref.roll), (mid, ref.yaw + 0.5 * dyaw, 0.5 * (ref.roll + still.roll)),
                 (still.p, ref.yaw + dyaw, still.roll))
        lift = np.array([0.0, 0.0, CLOSE_LIFT * self.height])

        def pelvis(k, w):
            (pa, ya, ra), (pb, yb, rb) = poses[k], poses[k + 1]
            return pa + w * (pb - pa), ya + w * (yb - ya), ra + w * (rb - ra)

        def step(k, side, start_q, end_q):
            """Joint spline of step k (0, 1) of ``side`` from its angles ``start_q`` to its standing
            foothold: straight up by the lift, over an apex halfway, straight down."""
            a, b = at_end[side], standing[side]
            top = max(a.position[2], b.position[2]) + lift[2]
            apex = 0.5 * (a.position + b.position)
            apex[2] = top
            at = [float(smoothstep(u)[0]) for u in STEP_KNOTS]
            keys = [start_q,
                    self._leg_ik(pelvis(k, at[1]), side, Pose._trusted(a.position + lift, a.rotation)),
                    self._leg_ik(pelvis(k, at[2]), side, Pose._trusted(apex, b.rotation)),
                    self._leg_ik(pelvis(k, at[3]), side, Pose._trusted(b.position + lift, b.rotation)),
                    self._leg_ik(pelvis(k, 1.0), side, b) if end_q is None else end_q]
            return _joint_spline(STEP_KNOTS, keys, lift=True)

        def planted(k, side, foot, start_q, end_q):
            """Joint spline over the fade weight w of step k of ``side`` standing on ``foot``."""
            ws = np.linspace(0.0, 1.0, PLANTED_KNOTS)
            inner = [self._leg_ik(pelvis(k, w), side, foot) for w in ws[1:-1]]
            return _joint_spline(ws, [start_q, *inner, self._leg_ik(pelvis(k, 1.0), side, foot)
                                      if end_q is None else end_q])

        cf, cs = self._leg_columns(first), self._leg_columns(second)
        first_step = step(0, first, ref.q[cf], None)
        second_stands = planted(0, second, at_end[second], ref.q[cs], None)
        first_stands = planted(1, first, standing[first], first_step(1.0), still.q[cf])
        # The second step ends at the standing angles themselves (the pelvis there is the standing one).
        second_step = step(1, second, second_stands(1.0), still.q[cs])
        # The standing sway's lever per leg (see :meth:`_closing`): at the standing knots, the sole centre's
        # sideways motion per radian of hip abduction (times the side's sign), s d(sole . n) / d q_abd, with
        # n the sway's direction; the leg's hip height above its sole when straight. A C1 spline in the time
        # since the arrival through the knots where the leg stands, ending at the standing leg's lever.
        n = np.array([-math.sin(still.yaw), math.cos(still.yaw), 0.0])
        centre = sole.mean(axis=0)
        ws = np.linspace(0.0, 1.0, PLANTED_KNOTS)
        us = 0.5 - np.sin(np.arcsin(1.0 - 2.0 * ws) / 3.0)  # smoothstep(us) = ws
        T = CLOSE_STEP

        def lever(k, side, spline, w):
            pos, yaw, roll = pelvis(k, w)
            base = Pose._trusted(pos, _rot_z(yaw) @ _rot_x(roll))
            c, sign = self._col[f"{side}_hip_abduction"], (1.0 if side == "left" else -1.0)
            q = ref.q.copy()
            q[self._leg_columns(side)] = spline(w)
            lat = []
            for e in (1e-6, -1e-6):
                q[c] += e
                lat.append(float(self.tree.forward(q, None, base).pose(f"{side}_foot").apply(centre[None])[0] @ n))
                q[c] -= e
            return sign * (lat[0] - lat[1]) / 2e-6

        ht = self.leg.leg_length
        levers = {
            second: _joint_spline(np.r_[T * us, 2 * T] / (2 * T),
                                  np.r_[[lever(0, second, second_stands, w) for w in ws], ht][:, None]),
            first: _joint_spline(np.r_[0.0, T + T * us] / (2 * T),
                                 np.r_[lever(1, first, first_stands, 0.0), [lever(1, first, first_stands, w)
                                                                            for w in ws[:-1]], ht][:, None]),
        }
        return first, second, poses, ((first_step, second_stands), (second_step, first_stands)), levers

    def _set_leg(self, plan: _Plan, side: str, q: np.ndarray, qd: np.ndarray) -> None:
        """Put ``side``'s LEG_JOINTS angles ``q`` (5,) [rad] and rates ``qd`` (5,) [rad/s] into ``plan``,
        never past a joint limit. A spline through poses LIMIT_MARGIN inside the limits may overshoot
        them between its knots: past lo + m or hi - m (m = LIMIT_MARGIN) the angle is squeezed into the
        last m before the limit, hi - m + m tanh((q - hi + m) / m) (lower limit alike), and its rate
        multiplied by the squeeze's slope. The tanh joins the identity with its slope and curvature, so
        angles, rates and accelerations stay continuous (clipped at the limit with the rate set to 0,
        the rate jumped by up to 12 rad/s where the spline crossed it). The squeeze leaves every angle
        of the gait and the standing pose alone (0.14 rad or more inside the limits)."""
        c = self._leg_columns(side)
        lo, hi = self.tree.limits[c].T
        m = LIMIT_MARGIN
        over = np.maximum(q - (hi - m), 0.0) - np.maximum((lo + m) - q, 0.0)  # signed excess over the band
        th = np.tanh(over / m)
        plan.q[c] = q - over + m * th
        plan.qd[c] = np.where(over != 0.0, 1.0 - th * th, 1.0) * qd

    def _starting_step(self):
        """The swinging (left) leg's angles over the start ramp, a quintic spline in tau = t - start_time.

        The gait starts at the right foot's mid-stance with the left foot swinging beside it; fading
        the left leg's angles from standing into that swing put its foot up to 5.4 cm into the floor,
        sliding at up to 2.8 m/s. Instead its foot follows, in the world, the blend (1 - w) S + w G(t)
        of its standing foothold S and the gait's own foot G(t) (w the fade weight, both on or above
        the floor) at its toe, lifted by CLOSE_LIFT H sin^2(pi tau / B), its forward axis blended
        likewise (the foot rolls about its toe as its pitch changes), the weight held at 0 over the
        first START_LIFT_ONLY of the ramp (the foot rises straight up first). The angles are a
        quintic spline through the closed form (:meth:`_leg_ik`) at START_KNOTS times, with the
        pelvis of the start's own plan there, and through the plan's own angles, rates and
        accelerations at both ends.
        """
        walk, B = self.walk, START_BLEND
        c = self._leg_columns(START_SWING)
        taus = np.linspace(0.0, B, START_KNOTS)
        keys, slopes, accels = [], [], []
        lift = CLOSE_LIFT * self.height
        sole = foot_sole_points(self.height)
        for k, tau in enumerate(taus):
            t = walk.start_time + float(tau)
            plan = self._plan(t, reach=False)
            if k in (0, len(taus) - 1):
                keys.append(plan.q[c].copy())
                slopes.append(plan.qd[c].copy())
                # The plan's angular accelerations there (central differences of its exact rates), so
                # that the spline joins it C2.
                h = 1e-6
                accels.append((self._plan(t + h, reach=False).qd[c] - self._plan(t - h, reach=False).qd[c]) / (2 * h))
                continue
            stand = self._standing(t, self.start_xy, self.heading)
            s_foot = self._foot_poses(stand)[START_SWING]
            g_foot = self._foot_poses(self._walking(*self._phase(t)))[START_SWING]
            # The foot first rises (the blend waits START_LIFT_ONLY of the ramp: it would move the toe
            # along the floor), then blends; the weight ends at 1 at rest, so the foot joins G C1.
            w = float(smoothstep((tau / B - START_LIFT_ONLY) / (1.0 - START_LIFT_ONLY))[0])
            # The toe's blend (the foot rolls about it as its pitch changes, rather than about the ankle,
            # which would push the toe into the floor), and the ankle where that puts it.
            toe = (1.0 - w) * s_foot.apply(sole[1:])[0] + w * g_foot.apply(sole[1:])[0]
            toe[2] += lift * math.sin(math.pi * tau / B) ** 2
            fx = (1.0 - w) * s_foot.rotation[:, 0] + w * g_foot.rotation[:, 0]
            fx /= np.linalg.norm(fx)
            fy = np.cross(np.array([0.0, 0.0, 1.0]), fx)
            fy /= np.linalg.norm(fy)
            rot = np.column_stack([fx, fy, np.cross(fx, fy)])
            target = Pose._trusted(toe - rot @ sole[1], rot)
            keys.append(self._leg_ik((plan.p, plan.yaw, plan.roll), START_SWING, target))
        # Quintic, C2 into the plan's own rates and accelerations at both ends: no jump of the
        # acceleration anywhere (a C1 join put 100 rad/s^2 jumps into the foot at the ramp's ends).
        return make_interp_spline(taus, np.array(keys), k=5, axis=0,
                                  bc_type=([(1, slopes[0]), (2, accels[0])], [(1, slopes[1]), (2, accels[1])]))

    def _closing(self, t: float) -> _Plan:
        """The pose at ``t`` between the arrival and ``stop_time``: the stance closes in two steps.

        The gait stops (its rate ramps to 0) wherever in its cycle the path ends, with the feet
        apart. In each of two steps of CLOSE_STEP one foot steps to where the standing pose puts it,
        straight up by CLOSE_LIFT H, over an apex halfway and straight down (its leg's angles a C1
        spline through the closed-form angles of :meth:`_leg_ik` at those poses), while the other
        stands (its leg's angles through the closed form at PLANTED_KNOTS points of the pelvis's path) and
        the pelvis moves, C1, from where the gait stopped to a pause halfway and on into the
        standing pose. The free foot (or, in double support, the one behind) steps first. The arms,
        trunk and head fade into standing over both steps.
        """
        first, second, poses, steps, levers = self._close
        T = CLOSE_STEP
        ref = self._ref_end
        end_xy, _, end_psi, _ = self.path.at(self.path.length)
        stand = self._standing(t, end_xy, end_psi, turning=False)
        tau = t - self.arrival_time
        k, kd = (float(x) for x in smoothstep(tau / (2 * T)))
        kd /= 2 * T
        # The upper body over both steps (the legs and pelvis below); the standing sway (pelvis offset
        # and hip abduction) weighted in with the same weight.
        q = ref.q + k * (stand.q - ref.q)
        qd = k * stand.qd + kd * (stand.q - ref.q)
        i = 0 if tau < T else 1
        u = min(max(tau / T - i, 0.0), 1.0)
        w, wd = (float(x) for x in smoothstep(u))
        wd /= T
        (pa, ya, ra), (pb, yb, rb) = poses[i], poses[i + 1]
        sway_p = stand.p - np.array([*end_xy, self.floor + self.leg.leg_length])
        p = pa + w * (pb - pa) + k * sway_p
        v = wd * (pb - pa) + k * stand.v + kd * sway_p
        yaw, yaw_d = ya + w * (yb - ya), wd * (yb - ya)
        roll, roll_d = ra + w * (rb - ra), wd * (rb - ra)
        stepping, standing = (first, second) if i == 0 else (second, first)
        step, stands = steps[i]
        # The standing sway (pelvis k d sideways, d = sway sin(2 pi f t)) is held off the feet by the hip
        # abductions: -s atan(k d / lambda), lambda the leg's lever at this time (the sole centre's sideways
        # motion per radian of abduction; standing straight, the hip's height above the sole, where this is
        # the standing pose's own -s atan(d / h_t)). With h_t on a bent standing leg instead, its sole
        # centre moved 2.6-3.7 mm sideways with the pelvis at 5-10 cm of sway.
        d = dd = 0.0
        if self.sway > 0:
            arg = 2 * math.pi * SWAY_FREQUENCY * t
            d, dd = self.sway * math.sin(arg), self.sway * 2 * math.pi * SWAY_FREQUENCY * math.cos(arg)
        plan = _Plan(p, v, yaw, yaw_d, roll, roll_d, q, qd)
        x = tau / (2 * T)
        for side, q_side, qd_side in ((stepping, step(u), step(u, 1) / T), (standing, stands(w), stands(w, 1) * wd)):
            c = self._leg_columns(side)
            lam, lam_d = float(levers[side](x)[0]), float(levers[side](x, 1)[0]) / (2 * T)
            r = k * d / lam
            r_d = (kd * d + k * dd) / lam - k * d * lam_d / (lam * lam)
            sign = 1.0 if side == "left" else -1.0
            comp, comp_d = np.zeros(len(c)), np.zeros(len(c))
            comp[2], comp_d[2] = -sign * math.atan(r), -sign * r_d / (1.0 + r * r)  # LEG_JOINTS[2]: hip_abduction
            self._set_leg(plan, side, q_side + comp, qd_side + comp_d)
        return plan

    # ------------------------------------------------------------ reaching
    def _warn_short_reach(self, q0, qd0, base) -> None:
        """Warn once when the solved arm leaves the hand centre more than REACH_MISS from the target at the
        hand's arrival, start_time + duration (a target beyond the arm, across the body, or beside the
        shoulder where the arm has no humeral rotation): the best effort is documented, but should not
        pass unnoticed."""
        rc = self.reach
        q = np.array(q0, float)
        for k, joint in enumerate(("shoulder_flexion", "shoulder_abduction", "elbow")):
            q[self._col[f"{rc.side}_{joint}"]] = self._reach_q[k]
        hand = self.tree.forward(q, qd0, base).pose(f"{rc.side}_hand").apply(
            np.array([[0.0, 0.0, -0.5 * HAND * self.height]]))[0]
        miss = float(np.linalg.norm(hand - np.asarray(rc.target, float)))
        if miss > REACH_MISS:
            warnings.warn(f"reach.target = {tuple(float(v) for v in rc.target)}: the {rc.side} hand stops "
                          f"{miss:.3f} m from it (beyond the arm, or where its three joints cannot turn; "
                          "docs/people.md, 'Standing, turning, reaching')", UserWarning, stacklevel=2)

    def _arm_ik(self, target_thorax: np.ndarray, side: str) -> np.ndarray:
        """(shoulder_flexion, shoulder_abduction, elbow) [rad] putting the hand centre at a thorax-frame point.

        Upper arm a along -z from the shoulder, forearm + half hand b; the
        elbow flexes in the arm's sagittal plane. With h0 = (b sin e, 0,
        -a - b cos e) the hand at zero shoulder angles, the abduction solves
        the lateral component and the flexion turns the rest in the x-z
        plane. The distance is clamped into [|a - b|, a + b] (1 mm inside)
        and every angle into its joint limits.
        """
        H = self.height
        s = 1.0 if side == "left" else -1.0
        shoulder = self.tree.joint(f"{side}_shoulder_flexion").origin.position
        a, b = UPPER_ARM * H, (FOREARM + 0.5 * HAND) * H
        d = np.asarray(target_thorax, float) - shoulder
        r = float(np.linalg.norm(d))
        r_c = min(max(r, abs(a - b) + 1e-3), a + b - 1e-3)
        d = d * (r_c / r) if r > 0 else np.array([0.0, 0.0, -r_c])
        cos_inner = (a * a + b * b - r_c * r_c) / (2 * a * b)
        elbow = math.pi - math.acos(max(-1.0, min(1.0, cos_inner)))
        px, qz = b * math.sin(elbow), -a - b * math.cos(elbow)
        gamma = math.asin(max(-1.0, min(1.0, -d[1] / qz)))  # rotation about +x
        phi = math.atan2(d[2], d[0]) - math.atan2(qz * math.cos(gamma), px)
        phi = float(_wrap(phi))
        out = np.array([phi, s * gamma, elbow])
        for i, kind in enumerate(("shoulder_flexion", "shoulder_abduction", "elbow")):
            lo, hi = _limits(kind)
            out[i] = min(max(out[i], lo), hi)
        return out

    def _apply_reach(self, t: float, plan: _Plan) -> None:
        rc = self.reach
        t1 = rc.start_time + rc.duration
        t2 = t1 + rc.hold
        if t <= rc.start_time or t >= t2 + rc.duration:
            return
        if self._reach_q is None:
            # Solved once, in the thorax frame at the hand's arrival (start_time + duration, where
            # the blend weight reaches 1): the hand is on the target then also for a person who
            # sways, turns or walks meanwhile (solved at the reach's start, the thorax's motion over
            # the duration was the hand's miss: 0.28 m for a 0.6 s reach at 1.2 m/s, 0.36 m in a
            # 90 deg turn, 1.8 cm in a 5 cm sway, and only a geometric miss was warned of).
            q0, qd0, base = self._at(t1, reach=False)
            thorax = self.tree.forward(q0, qd0, base).pose("thorax")
            self._reach_q = self._arm_ik(thorax.inverse().apply(np.asarray(rc.target, float)), rc.side)
            self._warn_short_reach(q0, qd0, base)
        if t < t1:
            w, wd = smoothstep((t - rc.start_time) / rc.duration)
        elif t <= t2:
            w, wd = 1.0, 0.0
        else:
            w, wd = smoothstep((t - t2) / rc.duration)
            w, wd = 1.0 - w, -wd
        w, wd = float(w), float(wd) / rc.duration
        for k, joint in enumerate(("shoulder_flexion", "shoulder_abduction", "elbow")):
            c = self._col[f"{rc.side}_{joint}"]
            a, ad = plan.q[c], plan.qd[c]
            plan.q[c] = (1 - w) * a + w * self._reach_q[k]
            plan.qd[c] = (1 - w) * ad + wd * (self._reach_q[k] - a)

    # ------------------------------------------------------------ outputs
    def _at(self, t: float, reach: bool = True):
        """(q, qd, base MotionState) at t (the last time is cached: links ask in turn).

        The cache entry is one tuple, replaced whole, so threads that ask at
        different times never see a mixed state.
        """
        t = check_time(t)
        key = (t, reach)
        last = self._last  # read once: another thread may replace it between the test and the read
        if last is not None and last[0] == key:
            return last[1]
        plan = self._plan(t, reach)
        rz = _rot_z(plan.yaw)
        rot = rz @ _rot_x(plan.roll)
        omega = np.array([0.0, 0.0, plan.yaw_d]) + rz[:, 0] * plan.roll_d
        # A product of two proper rotations and a finite floor point (finite t): the checks of
        # Pose(...) skipped (~0.25 ms, most of a new time's cost of the person), the same bits.
        # The state is kept (self._last) and handed to every caller at this time: its velocities are
        # read-only, as a link's (TreeState.state), so no caller can change what another one reads.
        plan.v.setflags(write=False)
        omega.setflags(write=False)
        base = MotionState(Pose._trusted(plan.p, rot), plan.v, omega)
        out = (plan.q, plan.qd, base)
        self._last = (key, out)
        return out

    def q(self, t: float) -> np.ndarray:
        return self._at(t)[0].copy()

    def qd(self, t: float) -> np.ndarray:
        return self._at(t)[1].copy()

    def base_state(self, t: float) -> MotionState:
        return self._at(t)[2]

    def to_dict(self) -> dict:
        def spec(o):
            return None if o is None else {k: (list(v) if isinstance(v, tuple) else v) for k, v in vars(o).items()}
        return {"type": "person", "height": self.height, "position": [*self.start_xy.tolist(), self.floor],
                "heading_deg": math.degrees(self.heading), "walk": spec(self.walk), "turn": spec(self.turn),
                "reach": spec(self.reach), "sway": self.sway}


class PersonJoints(_ReadOnly, JointMotion):
    """The joint trajectory of a :class:`PersonMotion` (every joint of its tree); its ``person`` is
    read-only (its ``version`` stays 0: nothing is pushed to a person)."""

    def __init__(self, person: PersonMotion):
        if not isinstance(person, PersonMotion):
            raise ConfigError("person.joints", person, "a PersonMotion")
        self.person = person
        self._seal()

    @property
    def n_columns(self) -> int:
        return self.person.tree.n_joints

    def q(self, t):
        return self.person.q(t)

    def qd(self, t):
        return self.person.qd(t)

    def q_qd(self, t):
        q, qd, _ = self.person._at(t)
        return q.copy(), qd.copy()

    def to_dict(self):
        return self.person.to_dict()


@dataclass(frozen=True, eq=False)
class PersonBase(Motion):
    """The pelvis (root link) motion of a :class:`PersonMotion`."""

    person: PersonMotion

    def __post_init__(self):
        if not isinstance(self.person, PersonMotion):
            raise ConfigError("person.base", self.person, "a PersonMotion")

    def state(self, t):
        return self.person.base_state(t)

    def to_dict(self):
        return self.person.to_dict()


def Walker(name: str = "person", height: float = 1.75, speed: float = 1.3, start=(0.0, 0.0),
           heading_deg: float | None = 0.0, path=None, start_time: float = 0.0, *,
           reach: Reach | None = None, clothing: str | Material | None = None,
           turn_length: float = 1.0) -> ArticulatedBody:
    """A walking person as an :class:`ArticulatedBody` (add it with ``body.add_to(scene)``).

    Walks at ``speed`` [m/s] from ``start`` (floor point [m]) from
    ``start_time`` [s], through the waypoints ``path`` (then stops), or
    without a path endlessly along ``heading_deg``.
    """
    pts = None if path is None else tuple(tuple(float(c) for c in row) for row in np.atleast_2d(
        V._floats("walk.path", path, "waypoints (n, 2) or (n, 3) [m]")))
    try:
        walk = Walk(speed, pts, heading_deg if path is None else None, start_time, turn_length)
    except ConfigError as e:
        if e.field != "walk.path":
            raise
        # Name the path as given: the tuple built above shows [] as ((),) and NaN as np.float64(nan).
        raise ConfigError("walk.path", path, e.allowed) from None
    return person_body(name, height, start, heading_deg if heading_deg is not None else 0.0, walk=walk,
                       reach=reach, clothing=clothing)


def person_body(name: str, height: float = 1.75, position=(0.0, 0.0), heading_deg: float = 0.0, *,
                walk: Walk | None = None, turn: Turn | None = None, reach: Reach | None = None,
                sway: float = 0.0, clothing: str | Material | None = None) -> ArticulatedBody:
    """A person (standing, turning, walking, reaching) as an :class:`ArticulatedBody`."""
    if not isinstance(name, str) or not name or "/" in name:
        raise ConfigError("person.name", name, "a non-empty name without '/' (it separates person and link names)")
    tree = human_tree(height, clothing=clothing, name=name)
    motion = PersonMotion(tree, height, position, heading_deg, walk=walk, turn=turn, reach=reach, sway=sway)
    return ArticulatedBody(name, tree, PersonJoints(motion), PersonBase(motion))


def add_person(scene, name: str = "person", height: float = 1.75, position=(0.0, 0.0), heading_deg: float = 0.0,
               *, walk: Walk | None = None, turn: Turn | None = None, reach: Reach | None = None,
               sway: float = 0.0, clothing: str | Material | None = None) -> ArticulatedBody:
    """Build a person (see :func:`person_body`) and add its links to ``scene`` as ``f"{name}/{link}"``."""
    body = person_body(name, height, position, heading_deg, walk=walk, turn=turn, reach=reach, sway=sway,
                       clothing=clothing)
    try:
        body.add_to(scene)
    except ConfigError as e:
        if e.field != f"{name}.name":
            raise
        # The body's check speaks of a robot; here it is the person's name that is taken.
        raise ConfigError("person.name", name, e.allowed.replace("a robot name", "a person name")) from None
    return body
