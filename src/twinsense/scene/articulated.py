"""Articulated bodies: kinematic trees of links and joints, and joint trajectories.

A :class:`KinematicTree` holds rigid links connected by revolute, prismatic or
fixed joints (URDF conventions). A joint's ``origin`` maps the joint frame into
the parent link frame at q = 0; the child link frame *is* the joint frame,
turned by q [rad] about ``axis`` (revolute) or shifted by q [m] along it
(prismatic), the axis given in the joint frame.

:meth:`KinematicTree.forward` gives every link's pose (link -> world) and the
linear velocity of the link origin and angular velocity (world frame),
propagated analytically down the tree::

    w_child = w_parent + a qd                      (revolute)
    v_child = v_parent + w_parent x r + a qd       (prismatic adds a qd)

with a = R_child axis the joint axis in the world and r the offset of the child
origin from the parent origin. Sensors (radar Doppler, ToF motion artefacts)
read these exact velocities, never finite differences.

An :class:`ArticulatedBody` puts a tree in a scene, driven by a joint motion
(``q(t)``, ``qd(t)`` of the movable joints, with exact derivatives): one
:class:`~twinsense.scene.scene.SceneObject` per link with geometry, named
``"body/link"``, whose frame is the link frame, and one mount frame per link
without geometry. All links share one forward-kinematics evaluation per time.
"""

from __future__ import annotations

import bisect
import math
import warnings
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from twinsense import validation as V
from twinsense.compiled import jit
from twinsense.errors import ConfigError
from twinsense.forksafe import ForkSafeLock
from twinsense.scene.geometry import Geometry, TriangleMesh
from twinsense.scene.materials import Material, get_material
from twinsense.scene.motion import Motion, MotionState, Static, check_time
from twinsense.scene.pose import Pose
from twinsense.scene.scene import SENSOR_KINDS, Frame, Scene, SceneObject

JOINT_KINDS = ("revolute", "prismatic", "fixed")
#: Accepted on input and stored as a revolute joint without limits (URDF "continuous").
CONTINUOUS = "continuous"
_KIND_CODE = {"revolute": 0, "prismatic": 1, "fixed": 2}
_ORIGIN = np.zeros(3)
_ORIGIN.setflags(write=False)
_EYE = np.eye(3)
_EYE.setflags(write=False)
#: Forward-kinematics results kept per body (the sensors of one frame ask a few times).
FK_CACHE_SIZE = 64


def _name(field_name: str, value) -> str:
    if not isinstance(value, str) or not value:
        raise ConfigError(field_name, value, "a non-empty string")
    return value


def _limit(field_name: str, value, default: float) -> float:
    """A joint limit: a number or +-inf (no limit); NaN and text are refused."""
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ConfigError(field_name, value, "a number or +-inf [rad or m]")
    v = float(value)
    if math.isnan(v):
        raise ConfigError(field_name, value, "a number or +-inf [rad or m]")
    return v


@dataclass(frozen=True)
class Mimic:
    """A joint that follows another: q = multiplier * q_joint + offset, qd = multiplier * qd_joint
    (URDF's ``<mimic>``: a gripper's second finger, a coupled linkage).

    ``joint`` names the driving joint (a movable joint of the same tree, itself possibly a
    mimic one); ``offset`` [rad or m].
    """

    joint: str
    multiplier: float = 1.0
    offset: float = 0.0

    def __post_init__(self) -> None:
        _name("mimic.joint", self.joint)
        for f in ("multiplier", "offset"):
            v = getattr(self, f)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) \
                    or not math.isfinite(v):
                raise ConfigError(f"mimic.{f}", v, "a finite number")
            object.__setattr__(self, f, float(v))


@dataclass(frozen=True, eq=False)
class Joint:
    """A joint between two links.

    Parameters
    ----------
    name : str
    kind : str
        "revolute", "prismatic" or "fixed"; "continuous" is taken as a
        revolute joint with infinite limits.
    parent, child : str
        Link names.
    origin : Pose
        Joint frame -> parent link frame at q = 0.
    axis : (3,) float
        Joint axis in the joint frame (normalised here).
    lower, upper : float
        Limits [rad] (revolute) or [m] (prismatic); +-inf means none.
    mimic : Mimic, optional
        A revolute or prismatic joint driven by another one (not a column of q; its own
        limits are not checked, as ROS computes a mimic joint from its master alone).
    """

    name: str
    kind: str
    parent: str
    child: str
    origin: Pose = field(default_factory=Pose)
    axis: tuple = (0.0, 0.0, 1.0)
    lower: float = -math.inf
    upper: float = math.inf
    mimic: Mimic | None = None

    def __post_init__(self) -> None:
        n = _name("joint.name", self.name)
        kind = self.kind
        if kind == CONTINUOUS:
            kind = "revolute"
            object.__setattr__(self, "lower", -math.inf)
            object.__setattr__(self, "upper", math.inf)
        if not isinstance(kind, str) or kind not in JOINT_KINDS:
            raise ConfigError(f"joints[{n}].kind", self.kind, "one of: " + ", ".join((*JOINT_KINDS, CONTINUOUS)))
        object.__setattr__(self, "kind", kind)
        _name(f"joints[{n}].parent", self.parent)
        _name(f"joints[{n}].child", self.child)
        if self.parent == self.child:
            raise ConfigError(f"joints[{n}].child", self.child, "a link other than the parent")
        if not isinstance(self.origin, Pose):
            raise ConfigError(f"joints[{n}].origin", self.origin, "a twinsense Pose (joint frame -> parent link)")
        a = V.vector(f"joints[{n}].axis", self.axis, 3)
        norm = V._norm(a)
        if kind == "fixed" and norm == 0.0:
            # A fixed joint never turns: URDF writers often give it axis="0 0 0".
            a, norm = np.array([0.0, 0.0, 1.0]), 1.0
        if not norm > 0 or not math.isfinite(norm):
            raise ConfigError(f"joints[{n}].axis", self.axis,
                              "a finite direction (3,), non-zero for a revolute or prismatic joint")
        a = a / norm
        a.setflags(write=False)
        object.__setattr__(self, "axis", a)
        lo = _limit(f"joints[{n}].lower", self.lower, -math.inf)
        hi = _limit(f"joints[{n}].upper", self.upper, math.inf)
        if lo > hi:
            raise ConfigError(f"joints[{n}].lower", lo, f"a limit <= upper ({hi:g})")
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", hi)
        if self.mimic is not None:
            if not isinstance(self.mimic, Mimic):
                raise ConfigError(f"joints[{n}].mimic", self.mimic, "a twinsense Mimic or None")
            if kind == "fixed":
                raise ConfigError(f"joints[{n}].mimic", self.mimic, "None for a fixed joint")
            if self.mimic.joint == n:
                raise ConfigError(f"joints[{n}].mimic.joint", n, "another joint than itself")

    @property
    def movable(self) -> bool:
        return self.kind != "fixed"

    @property
    def driven(self) -> bool:
        """A column of q: movable and not a mimic joint."""
        return self.kind != "fixed" and self.mimic is None

    @property
    def unit(self) -> str:
        return "m" if self.kind == "prismatic" else "rad"


@dataclass(frozen=True, eq=False)
class Link:
    """A rigid link: optional geometry and the material it is made of.

    Parameters
    ----------
    name : str
    geometry : Geometry or None
        Shape in the geometry frame [m]; None for a frame-only link (a mount point).
    material : Material or str
    origin : Pose
        Geometry frame -> link frame.
    layers : iterable of str or None
        Sensor kinds that see the link (None: all).
    """

    name: str
    geometry: Geometry | None = None
    material: Material | str = "aluminium"
    origin: Pose = field(default_factory=Pose)
    layers: frozenset | None = None

    def __post_init__(self) -> None:
        n = _name("link.name", self.name)
        if self.geometry is not None and not isinstance(self.geometry, Geometry):
            raise ConfigError(f"links[{n}].geometry", self.geometry, "a twinsense geometry or None")
        object.__setattr__(self, "material", get_material(self.material))
        if not isinstance(self.origin, Pose):
            raise ConfigError(f"links[{n}].origin", self.origin, "a twinsense Pose (geometry frame -> link)")
        if self.layers is not None:
            layers = frozenset([self.layers] if isinstance(self.layers, str) else self.layers)
            bad = layers - set(SENSOR_KINDS)
            if bad:
                raise ConfigError(f"links[{n}].layers", sorted(bad), "sensor kinds among: " + ", ".join(SENSOR_KINDS))
            object.__setattr__(self, "layers", layers)

    def link_frame_geometry(self) -> Geometry | None:
        """The geometry expressed in the link frame (a mesh when ``origin`` is not the identity)."""
        g = self.geometry
        if g is None or self.origin == Pose():
            return g
        m = g.mesh
        return TriangleMesh(self.origin.apply(np.asarray(m.vertices)), np.asarray(m.faces), name=self.name)


@dataclass(frozen=True, eq=False)
class TreeState:
    """Every link's pose and velocities at one configuration.

    Attributes
    ----------
    link_names : tuple of str
        Order of the rows below (the tree's ``link_names``).
    positions : (n_links, 3) float
        Link origins in the world [m].
    rotations : (n_links, 3, 3) float
        Link -> world rotations.
    linear_velocities : (n_links, 3) float
        Velocity of each link origin, world frame [m/s].
    angular_velocities : (n_links, 3) float
        Angular velocity of each link, world frame [rad/s].
    """

    link_names: tuple
    positions: np.ndarray
    rotations: np.ndarray
    linear_velocities: np.ndarray
    angular_velocities: np.ndarray
    _index: dict = field(repr=False, default_factory=dict)
    # Every link's pose and state (pose, read-only velocities, as a static object's), built all at once at the
    # first ask: a state is cached per time and every sensor asks for every moving link at each capture (the
    # caster for all of them). One entry, (poses, states); threads that race build the same one, the first
    # appended is kept.
    _built: list = field(repr=False, default_factory=list)

    def index(self, link: str | int) -> int:
        if isinstance(link, (int, np.integer)) and not isinstance(link, bool):
            if not 0 <= link < len(self.link_names):
                raise ConfigError("link", link, f"an index in 0..{len(self.link_names) - 1}")
            return int(link)
        i = self._index.get(link)
        if i is None:
            from twinsense.errors import UnknownNameError

            raise UnknownNameError("link", link, list(self.link_names))
        return i

    def _links(self) -> tuple[list, list]:
        """(poses, states) of every link, built at the first call.

        The kernel's rotations are products of proper rotations: the checks of Pose(...) are skipped,
        its re-orthonormalisation kept (the same bits), for every link at once: NumPy's stacked SVD and
        matmul run LAPACK and BLAS per matrix as for one, so the same bits as Pose._trusted per link. The
        positions and velocities are copied once, read-only, each link's a row of them (a robot cell's
        frame asks for 27 links: per-link copies, checks and look-ups were ~30 us a link).
        """
        if not self._built:
            u, _, vt = np.linalg.svd(self.rotations)
            rots = u @ vt
            pos, lin, ang = (np.array(a, dtype=float) for a in (self.positions, self.linear_velocities,
                                                                  self.angular_velocities))
            for a in (rots, pos, lin, ang):
                a.setflags(write=False)
            poses = [Pose._trusted(pos[i], rots[i], normalised=True, copy=False) for i in range(len(pos))]
            states = [MotionState(p, lin[i], ang[i]) for i, p in enumerate(poses)]
            self._built.append((poses, states))
        return self._built[0]

    def pose(self, link: str | int) -> Pose:
        """Link -> world."""
        return self._links()[0][self.index(link)]

    def state(self, link: str | int) -> MotionState:
        """Link ``link``'s pose and velocities (read-only (3,) arrays [m/s], [rad/s]); one object per link
        and time, shared by every caller."""
        return self._links()[1][self.index(link)]

    def point_velocity(self, link: str | int, points_world) -> np.ndarray:
        """Velocity (n, 3) [m/s] of points (n, 3) fixed to ``link``, given in world coordinates: v + w x r."""
        i = self.index(link)
        p = np.asarray(points_world, dtype=float)
        return self.linear_velocities[i] + np.cross(self.angular_velocities[i], p - self.positions[i])


@jit
def _fk_kernel(q, qd, jint, jdat, root, base, out):  # pragma: no cover - compiled
    """Forward kinematics with velocities, joints in parent-before-child order (see KinematicTree.forward).

    jint (m, 5) int: per joint q index (-1: none), kind code, parent link, child link, mimic (1: the
    joint value is multiplier q + offset, its velocity multiplier qd, of that q index).
    jdat (m, 17): origin rotation (row-major 9), origin position (3), axis (3), multiplier, offset.
    base (18,): root position, rotation (row-major 9), linear and angular velocity.
    out (n_links, 18): position, rotation (row-major 9), linear and angular velocity per link.
    Per joint k (joint frame = child frame):
    R_c = R_p R_o,k J_k(q), p_c = p_p + R_p (o_k + R_o,k a_k q) (prismatic),
    a = R_c a_k, w_c = w_p + a qd (revolute), v_c = v_p + w_p x (p_c - p_p) + a qd (prismatic).
    (Few arguments on purpose: numba's dispatch costs ~0.3 us per argument.)
    """
    for i in range(18):
        out[root, i] = base[i]
    jr = np.empty((3, 3))
    rel = np.empty((3, 3))
    for k in range(jint.shape[0]):
        p = jint[k, 2]
        c = jint[k, 3]
        kind = jint[k, 1]
        ax, ay, az = jdat[k, 12], jdat[k, 13], jdat[k, 14]
        qk = 0.0
        qdk = 0.0
        if jint[k, 0] >= 0:
            qk = q[jint[k, 0]]
            qdk = qd[jint[k, 0]]
            if jint[k, 4] != 0:
                qk = jdat[k, 15] * qk + jdat[k, 16]
                qdk = jdat[k, 15] * qdk
        # Joint rotation J in the joint frame: Rodrigues for a revolute joint, identity otherwise.
        if kind == 0:
            cs = math.cos(qk)
            sn = math.sin(qk)
            t = 1.0 - cs
            jr[0, 0] = cs + t * ax * ax
            jr[0, 1] = t * ax * ay - sn * az
            jr[0, 2] = t * ax * az + sn * ay
            jr[1, 0] = t * ay * ax + sn * az
            jr[1, 1] = cs + t * ay * ay
            jr[1, 2] = t * ay * az - sn * ax
            jr[2, 0] = t * az * ax - sn * ay
            jr[2, 1] = t * az * ay + sn * ax
            jr[2, 2] = cs + t * az * az
        else:
            for i in range(3):
                for j in range(3):
                    jr[i, j] = 1.0 if i == j else 0.0
        shift = qk if kind == 1 else 0.0
        for i in range(3):
            for j in range(3):
                rel[i, j] = (jdat[k, 3 * i] * jr[0, j] + jdat[k, 3 * i + 1] * jr[1, j]
                             + jdat[k, 3 * i + 2] * jr[2, j])
        # Child origin in the parent frame: the joint origin plus the prismatic shift along the axis.
        lp0 = jdat[k, 9] + (jdat[k, 0] * ax + jdat[k, 1] * ay + jdat[k, 2] * az) * shift
        lp1 = jdat[k, 10] + (jdat[k, 3] * ax + jdat[k, 4] * ay + jdat[k, 5] * az) * shift
        lp2 = jdat[k, 11] + (jdat[k, 6] * ax + jdat[k, 7] * ay + jdat[k, 8] * az) * shift
        for i in range(3):
            rp0, rp1, rp2 = out[p, 3 + 3 * i], out[p, 4 + 3 * i], out[p, 5 + 3 * i]
            out[c, i] = out[p, i] + rp0 * lp0 + rp1 * lp1 + rp2 * lp2
            for j in range(3):
                out[c, 3 + 3 * i + j] = rp0 * rel[0, j] + rp1 * rel[1, j] + rp2 * rel[2, j]
        aw0 = out[c, 3] * ax + out[c, 4] * ay + out[c, 5] * az
        aw1 = out[c, 6] * ax + out[c, 7] * ay + out[c, 8] * az
        aw2 = out[c, 9] * ax + out[c, 10] * ay + out[c, 11] * az
        r0 = out[c, 0] - out[p, 0]
        r1 = out[c, 1] - out[p, 1]
        r2 = out[c, 2] - out[p, 2]
        wp0, wp1, wp2 = out[p, 15], out[p, 16], out[p, 17]
        out[c, 12] = out[p, 12] + wp1 * r2 - wp2 * r1
        out[c, 13] = out[p, 13] + wp2 * r0 - wp0 * r2
        out[c, 14] = out[p, 14] + wp0 * r1 - wp1 * r0
        out[c, 15] = wp0
        out[c, 16] = wp1
        out[c, 17] = wp2
        if kind == 0:
            out[c, 15] += aw0 * qdk
            out[c, 16] += aw1 * qdk
            out[c, 17] += aw2 * qdk
        elif kind == 1:
            out[c, 12] += aw0 * qdk
            out[c, 13] += aw1 * qdk
            out[c, 14] += aw2 * qdk


class KinematicTree:
    """Links connected by joints into one tree (one root link, no cycles).

    Parameters
    ----------
    name : str
    links : sequence of Link
    joints : sequence of Joint
        Every link except the root is the child of exactly one joint.
    home : (n_joints,) float, optional
        The rest configuration of the driven joints [rad or m], within the limits (an MJCF
        model's "home" keyframe or qpos0); default 0 clipped into each joint's limits.
        A body without a joint motion rests there, and joints a motion does not drive
        hold it.
    """

    def __init__(self, name: str, links: Sequence[Link], joints: Sequence[Joint], home=None):
        self.name = _name("tree.name", name)
        if isinstance(links, (str, bytes)) or not isinstance(links, Sequence) or not links:
            raise ConfigError(f"{name}.links", links, "a non-empty sequence of Link")
        if isinstance(joints, (str, bytes)) or not isinstance(joints, Sequence):
            raise ConfigError(f"{name}.joints", joints, "a sequence of Joint")
        for i, lk in enumerate(links):
            if not isinstance(lk, Link):
                raise ConfigError(f"{name}.links[{i}]", lk, "a twinsense Link")
        for i, j in enumerate(joints):
            if not isinstance(j, Joint):
                raise ConfigError(f"{name}.joints[{i}]", j, "a twinsense Joint")
        self.links = tuple(links)
        self.joints = tuple(joints)
        self.link_names = tuple(lk.name for lk in self.links)
        index = {}
        for i, n in enumerate(self.link_names):
            if n in index:
                raise ConfigError(f"{name}.links[{i}].name", n, "a name not used by another link")
            index[n] = i
        self._link_index = index
        seen = set()
        parent_joint: dict[str, Joint] = {}
        for i, j in enumerate(self.joints):
            if j.name in seen:
                raise ConfigError(f"{name}.joints[{i}].name", j.name, "a name not used by another joint")
            seen.add(j.name)
            for role in ("parent", "child"):
                ln = getattr(j, role)
                if ln not in index:
                    raise ConfigError(f"{name}.joints[{j.name}].{role}", ln,
                                      "one of the links: " + ", ".join(self.link_names))
            if j.child in parent_joint:
                raise ConfigError(f"{name}.joints[{j.name}].child", j.child,
                                  "a link without another parent joint (already child of "
                                  f"{parent_joint[j.child].name!r})")
            parent_joint[j.child] = j
        roots = [n for n in self.link_names if n not in parent_joint]
        if len(roots) != 1:
            raise ConfigError(f"{name}.joints", f"root links {roots}",
                              "a tree with exactly one root link (a link that is no joint's child); "
                              + ("a cycle leaves none" if not roots else "join the others to it"))
        self.root = roots[0]
        # Breadth-first from the root: joints in an order where a parent is placed before its child.
        children: dict[str, list[Joint]] = {n: [] for n in self.link_names}
        for j in self.joints:
            children[j.parent].append(j)
        order: list[Joint] = []
        frontier = [self.root]
        reached = {self.root}
        while frontier:
            nxt = []
            for ln in frontier:
                for j in children[ln]:
                    order.append(j)
                    reached.add(j.child)
                    nxt.append(j.child)
            frontier = nxt
        if len(reached) != len(self.link_names):
            lost = [n for n in self.link_names if n not in reached]
            raise ConfigError(f"{name}.joints", f"links {lost}", "a tree: these links form a cycle, unreachable "
                              f"from the root {self.root!r}")
        self._parent_joint = parent_joint
        movable = [j for j in self.joints if j.driven]
        self.joint_names = tuple(j.name for j in movable)
        self._joint_index = {n: i for i, n in enumerate(self.joint_names)}
        lim = np.array([[j.lower, j.upper] for j in movable], dtype=float).reshape(-1, 2)
        lim.setflags(write=False)
        self.limits = lim
        self._lower, self._upper = lim[:, 0].copy(), lim[:, 1].copy()
        self._zeros = np.zeros(len(movable))
        self._shape = (len(movable),)
        self._base0 = np.zeros(18)  # the root at the origin, at rest: position, rotation (identity), velocities
        self._base0[3:12] = np.eye(3).ravel()
        self._mimics = self._resolve_mimics()
        self._compile(order)
        rest = np.clip(0.0, self._lower, self._upper)
        if home is not None:
            rest = self._vector(f"{self.name}.home", home).copy()
            self.check_limits(rest, f"{self.name}.home")
        rest.setflags(write=False)
        self._home = rest

    def _resolve_mimics(self) -> dict[str, tuple[int, float, float]]:
        """{mimic joint: (q column, multiplier, offset)}, a chain of mimics composed down to its driven joint."""
        by_name = {j.name: j for j in self.joints}
        out: dict[str, tuple[int, float, float]] = {}
        for j in self.joints:
            if j.mimic is None:
                continue
            mult, off, seen, cur = 1.0, 0.0, [j.name], j
            while cur.mimic is not None:
                m = cur.mimic
                master = by_name.get(m.joint)
                if master is None or not master.movable:
                    raise ConfigError(f"{self.name}.joints[{cur.name}].mimic.joint", m.joint,
                                      "a revolute or prismatic joint of the tree: "
                                      + ", ".join(x.name for x in self.joints if x.movable and x is not cur))
                if master.name in seen:
                    raise ConfigError(f"{self.name}.joints[{j.name}].mimic", " -> ".join([*seen, master.name]),
                                      "a chain of mimic joints ending at a driven joint (not a cycle)")
                # cur = m.multiplier * master + m.offset, and j = mult * cur + off.
                mult, off = mult * m.multiplier, mult * m.offset + off
                seen.append(master.name)
                cur = master
            out[j.name] = (self._joint_index[cur.name], mult, off)
        return out

    # ---------------------------------------------------------------- precomputation
    def _compile(self, order: list[Joint]) -> None:
        m = len(order)
        self._order_parent = np.array([self._link_index[j.parent] for j in order], dtype=np.intp)
        self._order_child = np.array([self._link_index[j.child] for j in order], dtype=np.intp)
        mim = self._mimics
        self._order_qi = np.array([mim[j.name][0] if j.name in mim else self._joint_index.get(j.name, -1)
                                   if j.movable else -1 for j in order], dtype=np.intp)
        kinds = np.array([_KIND_CODE[j.kind] for j in order], dtype=np.intp)
        is_mimic = np.array([j.name in mim for j in order], dtype=np.intp)
        self._jint = np.ascontiguousarray(np.column_stack(
            [self._order_qi, kinds, self._order_parent, self._order_child, is_mimic]).reshape(m, 5).astype(np.intp))
        self._jdat = np.ascontiguousarray(np.column_stack(
            [np.array([j.origin.rotation.ravel() for j in order]).reshape(m, 9),
             np.array([j.origin.position for j in order]).reshape(m, 3),
             np.array([j.axis for j in order]).reshape(m, 3),
             np.array([mim[j.name][1:] if j.name in mim else (1.0, 0.0) for j in order]).reshape(m, 2)]))
        self._root_index = self._link_index[self.root]

    # ---------------------------------------------------------------- queries
    @property
    def home(self) -> np.ndarray:
        """(n_joints,) the rest configuration [rad or m] (``home``; default 0 clipped into each joint's limits)."""
        return self._home.copy()

    @property
    def n_joints(self) -> int:
        """Number of driven joints (the length of q: movable joints that are not mimic joints)."""
        return len(self.joint_names)

    def link(self, name: str) -> Link:
        i = self._link_index.get(name)
        if i is None:
            from twinsense.errors import UnknownNameError

            raise UnknownNameError(f"{self.name}.link", name, list(self.link_names))
        return self.links[i]

    def joint(self, name: str) -> Joint:
        for j in self.joints:
            if j.name == name:
                return j
        from twinsense.errors import UnknownNameError

        raise UnknownNameError(f"{self.name}.joint", name, [j.name for j in self.joints])

    @property
    def mimic_joints(self) -> tuple:
        """Names of the joints that follow another (:class:`Mimic`; not columns of q)."""
        return tuple(self._mimics)

    def joint_index(self, name: str) -> int:
        """Column of driven joint ``name`` in q (a mimic joint has none)."""
        i = self._joint_index.get(name)
        if i is None:
            from twinsense.errors import UnknownNameError

            raise UnknownNameError(f"{self.name}.joint", name, list(self.joint_names))
        return i

    def parent_joint(self, link: str) -> Joint | None:
        """The joint whose child is ``link`` (None for the root)."""
        self.link(link)
        return self._parent_joint.get(link)

    def check_limits(self, q, field_name: str | None = None, when: str = "") -> None:
        """ConfigError naming the first joint whose value lies outside its limits."""
        q = np.asarray(q, dtype=float)
        # NaN fails both comparisons, so it is refused here too.
        ok = (q >= self._lower) & (q <= self._upper)
        if not ok.all():
            bad = ~ok
            i = int(np.argmax(bad))
            j = self.joint(self.joint_names[i])
            raise ConfigError(field_name or f"{self.name}.joints[{j.name}]", float(q[i]),
                              f"a value within the limits [{j.lower:g}, {j.upper:g}] {j.unit} of joint "
                              f"{j.name!r}{when}")

    def _vector(self, field_name: str, value) -> np.ndarray:
        if (type(value) is np.ndarray and value.dtype == np.float64 and value.shape == self._shape
                and value.flags.c_contiguous and np.isfinite(value).all()):
            return value  # the fast path of forward kinematics in a loop
        try:
            v = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(field_name, value, f"{self.n_joints} finite numbers, one per joint "
                              f"{list(self.joint_names)}") from None
        if v.shape != (self.n_joints,) or not np.all(np.isfinite(v)):
            raise ConfigError(field_name, value, f"{self.n_joints} finite numbers, one per joint "
                              f"{list(self.joint_names)}")
        return v

    # ---------------------------------------------------------------- kinematics
    def forward(self, q, qd=None, base: MotionState | Pose | None = None) -> TreeState:
        """Pose and velocities of every link.

        Parameters
        ----------
        q : (n_joints,) float
            Joint positions [rad or m], in ``joint_names`` order, within ``limits``.
        qd : (n_joints,) float, optional
            Joint velocities [rad/s or m/s] (default zero).
        base : MotionState or Pose, optional
            State of the root link in the world (default: identity, at rest).
        """
        q = self._vector(f"{self.name}.q", q)
        qd = self._zeros if qd is None else self._vector(f"{self.name}.qd", qd)
        if not ((q >= self._lower) & (q <= self._upper)).all():  # NaN fails too
            self.check_limits(q)
        if base is None:
            return self._run(q, qd, self._base0)
        if isinstance(base, Pose):
            bp, br, bv, bw = base.position, base.rotation, _ORIGIN, _ORIGIN
        elif isinstance(base, MotionState):
            bp, br = base.pose.position, base.pose.rotation
            bv = V.vector(f"{self.name}.base.linear_velocity", base.linear_velocity, 3, "m/s")
            bw = V.vector(f"{self.name}.base.angular_velocity", base.angular_velocity, 3, "rad/s")
        else:
            raise ConfigError(f"{self.name}.base", base, "a MotionState, a Pose or None")
        return self._forward(q, qd, bp, br, bv, bw)

    def _forward(self, q, qd, bp, br, bv, bw) -> TreeState:
        base = np.empty(18)
        base[:3], base[3:12], base[12:15], base[15:] = bp, np.ravel(br), bv, bw
        return self._run(q, qd, base)

    def _run(self, q, qd, base) -> TreeState:
        n = len(self.link_names)
        out = np.empty((n, 18))
        _fk_kernel(q, qd, self._jint, self._jdat, self._root_index, base, out)
        out.setflags(write=False)  # the views below are read-only too
        return TreeState(self.link_names, out[:, :3], out[:, 3:12].reshape(n, 3, 3), out[:, 12:15], out[:, 15:],
                         self._link_index)

    def __repr__(self) -> str:
        return f"KinematicTree({self.name!r}, {len(self.links)} links, joints={list(self.joint_names)})"


# ==================================================================== joint motions
class JointMotion:
    """Base class of joint trajectories: ``q(t)`` and ``qd(t)`` of some joints.

    ``joint_names`` lists the joints the columns belong to (None: every movable
    joint of the tree, in its order); joints not listed stay at their home
    value (0 clipped into the joint's limits).
    """

    joint_names: tuple | None = None

    def q(self, t: float) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def qd(self, t: float) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def q_qd(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        return self.q(t), self.qd(t)

    @property
    def n_columns(self) -> int:  # pragma: no cover - abstract
        raise NotImplementedError

    @property
    def is_static(self) -> bool:
        return False

    @property
    def version(self) -> int:
        """Changes when values are pushed from outside (FK caches key on it)."""
        return 0

    def check(self, tree: KinematicTree, columns: np.ndarray, field_name: str) -> None:
        """Raise ConfigError if the trajectory is known, at load, to leave the joint limits.

        ``columns``: the tree's q column of each of this motion's columns; -1 for a column the
        body does not use (a mimic joint's, which follows its master), which is not checked.
        """

    def _narrow_limits(self, tree: KinematicTree, columns) -> None:
        """Narrow ``self._lo``, ``self._hi`` (per column) to the limits of ``tree``'s joints at ``columns``
        (-1: unused): the bounds a motion that drives several bodies keeps its values within."""
        cols = np.asarray(columns)
        used = cols >= 0
        self._lo[used] = np.maximum(self._lo[used], tree.limits[cols[used], 0])
        self._hi[used] = np.minimum(self._hi[used], tree.limits[cols[used], 1])

    def to_dict(self) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError


def _joint_names(field_name: str, names) -> tuple | None:
    if names is None:
        return None
    if isinstance(names, str) or not isinstance(names, Sequence) or not all(isinstance(n, str) for n in names):
        raise ConfigError(field_name, names, "a list of joint names or None")
    if len(set(names)) != len(names):
        raise ConfigError(field_name, list(names), "joint names without repeats")
    return tuple(names)


def _check_speeds(field_name: str, t: np.ndarray, q: np.ndarray) -> None:
    """ConfigError naming the first row whose step from the previous one is faster than
    ``ANGULAR_SPEED_MAX`` (1e6 rad/s or m/s, the bound of a constant joint velocity): a cubic through
    such rows would overflow (values near 1e308 give NaN coefficients) or claim absurd joint speeds."""
    with np.errstate(over="ignore", invalid="ignore"):
        speed = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]
    bad = np.argwhere(~(speed <= V.ANGULAR_SPEED_MAX))
    if bad.size:
        i, k = (int(x) for x in bad[0])
        raise ConfigError(f"{field_name}[{i + 1}][{k}]", float(q[i + 1, k]),
                          f"a joint value within {V.ANGULAR_SPEED_MAX:g} rad/s or m/s times "
                          f"{t[i + 1] - t[i]:.6g} s of the previous one ({q[i, k]:.6g} at t = {t[i]:.6g} s): "
                          f"joint speeds <= {V.ANGULAR_SPEED_MAX:g}")


def _limits_text(tree: KinematicTree, col: int) -> str:
    j = tree.joint(tree.joint_names[col])
    return f"within the limits [{j.lower:g}, {j.upper:g}] {j.unit} of joint {j.name!r}"


class JointKeyframes(JointMotion):
    """Timed joint positions joined by a clamped cubic spline (C2, zero velocity at both ends).

    Before the first and after the last keyframe the joints hold still, so the
    velocity is continuous there too. The spline may swing past a keyframe
    between two keyframes; the check at load covers the whole curve (its
    extrema), not only the keyframes. A keyframe on a limit with the curve
    turning there rounds past it by an ulp or so: the check takes 1e-12 of the
    limit's size for rounding, and ``q(t)`` puts such values back on the limit
    (the velocity there is ~0), so a time near that keyframe does not fail.

    Parameters
    ----------
    times : (n_t,) float
        Strictly increasing [s], n_t >= 2.
    values : (n_t, n_j) float
        Joint positions [rad or m] at those times.
    joint_names : list of str, optional
        The joints of the columns (default: every movable joint, in tree order).
    """

    def __init__(self, times, values, joint_names=None):
        t = V.array("joints.keyframes.times", times, (None,), "s")
        if len(t) < 2 or np.any(np.diff(t) <= 0) or np.any(np.abs(t) > V.TIME_MAX):
            raise ConfigError("joints.keyframes.times", times,
                              f"at least 2 strictly increasing times within +-{V.TIME_MAX:g} [s]")
        vals = np.asarray(V._floats("joints.keyframes.values", values, "a finite array (n_times, n_joints)"))
        if vals.ndim == 1 and len(t) == len(vals):
            vals = vals[:, None]
        if vals.ndim != 2 or len(vals) != len(t) or vals.shape[1] == 0:
            raise ConfigError("joints.keyframes.values", f"array of shape {vals.shape}",
                              f"one row per keyframe time: shape ({len(t)}, n_joints)")
        if not np.all(np.isfinite(vals)):
            raise ConfigError("joints.keyframes.values", "array with NaN or inf", "finite joint positions")
        _check_speeds("joints.keyframes.values", t, vals)
        self.joint_names = _joint_names("joints.keyframes.joint_names", joint_names)
        if self.joint_names is not None and len(self.joint_names) != vals.shape[1]:
            raise ConfigError("joints.keyframes.joint_names", list(self.joint_names),
                              f"one name per column of values ({vals.shape[1]})")
        self.times = t
        self.values = vals
        self._spline = CubicSpline(t, vals, axis=0, bc_type="clamped")
        self._dspline = self._spline.derivative()
        # Clip bounds of q(t): the limits of the bodies it drives (set by check), +-inf until then.
        self._lo = np.full(vals.shape[1], -np.inf)
        self._hi = np.full(vals.shape[1], np.inf)
        self._clipping = False

    @property
    def n_columns(self) -> int:
        return self.values.shape[1]

    def _clip_time(self, t: float) -> tuple[float, bool]:
        t = check_time(t)
        if t <= self.times[0]:
            return float(self.times[0]), True
        if t >= self.times[-1]:
            return float(self.times[-1]), True
        return t, False

    def q(self, t):
        tc, held = self._clip_time(t)
        if held:  # the keyframe itself, not the spline's rounding of it
            return self.values[0 if tc == self.times[0] else -1].copy()
        q = np.asarray(self._spline(tc), dtype=float)
        if self._clipping:  # the spline's rounding past a limit the check let through, back on the limit
            np.clip(q, self._lo, self._hi, out=q)
        return q

    def qd(self, t):
        tc, held = self._clip_time(t)
        if held:
            return np.zeros(self.n_columns)
        return np.asarray(self._dspline(tc), dtype=float)

    def extrema(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(min, max, t_min, t_max) per column over the whole spline [rad or m, s].

        Per interval the derivative is a quadratic 3 c0 s^2 + 2 c1 s + c2; its
        real roots inside the interval and the interval ends are the candidates.
        """
        c = self._spline.c  # (4, n_intervals, n_cols): coefficients of s^3, s^2, s, 1
        h = np.diff(self.times)[:, None]
        a, b, cc = 3 * c[0], 2 * c[1], c[2]
        disc = b * b - 4 * a * cc
        sq = np.sqrt(np.maximum(disc, 0.0))
        cands = [np.zeros_like(h + a), np.broadcast_to(h, a.shape)]
        with np.errstate(divide="ignore", invalid="ignore"):
            for r in ((-b + sq) / (2 * a), (-b - sq) / (2 * a), -cc / b):
                ok = np.isfinite(r) & (r > 0) & (r < h) & (disc >= 0)
                cands.append(np.where(ok, r, 0.0))
        s = np.stack(cands)  # (n_cand, n_intervals, n_cols)
        val = ((c[0] * s + c[1]) * s + c[2]) * s + c[3]
        tt = self.times[:-1][None, :, None] + s
        flat_v = val.transpose(2, 0, 1).reshape(self.n_columns, -1)
        flat_t = tt.transpose(2, 0, 1).reshape(self.n_columns, -1)
        i_lo, i_hi = np.argmin(flat_v, axis=1), np.argmax(flat_v, axis=1)
        cols = np.arange(self.n_columns)
        return flat_v[cols, i_lo], flat_v[cols, i_hi], flat_t[cols, i_lo], flat_t[cols, i_hi]

    def check(self, tree, columns, field_name):
        for k, col in enumerate(columns):
            if col < 0:
                continue
            lo, hi = tree.limits[col]
            for i, v in enumerate(self.values[:, k]):
                if not lo <= v <= hi:
                    raise ConfigError(f"{field_name}.keyframes.values[{i}][{k}]", float(v),
                                      _limits_text(tree, col))
        vmin, vmax, tmin, tmax = self.extrema()
        near = False
        for k, col in enumerate(columns):
            if col < 0:
                continue
            lo, hi = tree.limits[col]
            # A spline passing through in-limit keyframes overshoots by far more than rounding when it
            # really leaves the limits; 1e-12 of the range absorbs the rounding of the extremum.
            tol = 1e-12 * max(1.0, abs(lo) if math.isfinite(lo) else 0.0, abs(hi) if math.isfinite(hi) else 0.0)
            for v, tv in ((vmin[k], tmin[k]), (vmax[k], tmax[k])):
                if not lo - tol <= v <= hi + tol:
                    raise ConfigError(f"{field_name}.keyframes", f"{float(v):.6g} at t = {float(tv):.6g} s",
                                      _limits_text(tree, col) + " along the whole spline between the keyframes "
                                      "(the cubic overshoots here: add a keyframe or move it away from the limit)")
            # Within that allowance of a limit the spline, evaluated at other times than its extremum, may
            # round past it: q(t) then clips onto the limits (of every body this motion drives).
            near = near or vmin[k] < lo + tol or vmax[k] > hi - tol
        self._narrow_limits(tree, columns)
        self._clipping = self._clipping or bool(near)

    def to_dict(self):
        return {"type": "keyframes", "times": self.times.tolist(), "values": self.values.tolist(),
                "joint_names": None if self.joint_names is None else list(self.joint_names)}


#: How far [rad or m] a recorded joint value may lie outside its joint's limits and still be accepted
#: (then clipped onto the limit): encoder noise and rounding put a joint parked at its limit a few
#: counts beyond it (a 17-bit encoder's count is 4.8e-5 rad; drivers report values rounded to ~1e-9).
SAMPLES_LIMIT_TOLERANCE = 1e-6


class JointSamples(JointMotion):
    """Densely sampled recorded joint positions (and velocities): a robot's ``/joint_states`` played back.

    With ``velocities``, a piecewise cubic Hermite through every (t_i, q_i, qd_i)
    (:class:`scipy.interpolate.CubicHermiteSpline`: C1, its derivative the recorded
    velocity at every sample; error <= h^4 max|q''''| / 384). Without, a not-a-knot
    cubic spline (C2; not the clamped one of :class:`JointKeyframes`: a recording
    neither starts nor ends at rest). At a sample time ``q`` and ``qd`` are the
    recorded values themselves (``qd`` the spline's slope without velocities).
    Before the first and after the last sample the joints hold the first / last
    sample with zero velocity (a step in velocity there: the recording says
    nothing about the robot outside its span).

    Repeated time stamps (real logs have them: a driver republishing the last
    state) are dropped when the whole row repeats (positions and velocities);
    a repeated stamp with other values, or a time going back, is a ConfigError
    naming the sample index.

    Limits, checked when a body is built (like :class:`JointKeyframes`: every
    sample and the interpolant's extrema between samples): a value more than
    :data:`SAMPLES_LIMIT_TOLERANCE` (1e-6 rad or m) outside a joint's limits is a
    ConfigError naming the joint and the time; a value within that tolerance
    outside (measurement noise at a limit) is clipped onto the limit by ``q(t)``.

    Parameters
    ----------
    times : (n_t,) float
        Sample times [s], non-decreasing, n_t >= 2 distinct.
    positions : (n_t, n_j) float
        Joint positions [rad or m].
    velocities : (n_t, n_j) float, optional
        Joint velocities [rad/s or m/s] at the same samples.
    joint_names : list of str, optional
        The joints of the columns (default: every driven joint, in tree order).
    """

    def __init__(self, times, positions, velocities=None, joint_names=None):
        f = "joints.samples"
        t = V.array(f"{f}.times", times, (None,), "s")
        if np.any(np.abs(t) > V.TIME_MAX):
            raise ConfigError(f"{f}.times", times, f"times within +-{V.TIME_MAX:g} [s]")
        q = self._table(f"{f}.positions", positions, len(t))
        qd = None if velocities is None else self._table(f"{f}.velocities", velocities, len(t))
        if qd is not None and qd.shape != q.shape:
            raise ConfigError(f"{f}.velocities", f"array of shape {qd.shape}",
                              f"one velocity per position: shape {q.shape}")
        dt = np.diff(t)
        back = np.flatnonzero(dt < 0)
        if back.size:
            i = int(back[0]) + 1
            raise ConfigError(f"{f}.times[{i}]", float(t[i]), f"a time >= the previous sample's ({t[i - 1]:.9g} s)")
        same = np.flatnonzero(dt == 0)
        for i in same + 1:
            if not (np.array_equal(q[i], q[i - 1]) and (qd is None or np.array_equal(qd[i], qd[i - 1]))):
                raise ConfigError(f"{f}.times[{i}]", float(t[i]),
                                  f"a time > the previous sample's ({t[i - 1]:.9g} s): a repeated time stamp is "
                                  "only dropped when its whole row repeats too")
        keep = np.ones(len(t), dtype=bool)
        keep[same + 1] = False
        t, q = t[keep], q[keep]
        qd = None if qd is None else qd[keep]
        if len(t) < 2:
            raise ConfigError(f"{f}.times", times, "at least 2 samples at distinct times [s]")
        self.joint_names = _joint_names(f"{f}.joint_names", joint_names)
        if self.joint_names is not None and len(self.joint_names) != q.shape[1]:
            raise ConfigError(f"{f}.joint_names", list(self.joint_names),
                              f"one name per column of positions ({q.shape[1]})")
        for a in (t, q) if qd is None else (t, q, qd):
            a.setflags(write=False)
        self.times, self.positions, self.velocities = t, q, qd
        if qd is None:
            self._spline = CubicSpline(t, q, axis=0, bc_type="not-a-knot")
        else:
            self._spline = CubicHermiteSpline(t, q, qd, axis=0)
        self._c = self._spline.c  # (4, n_t - 1, n_j): each piece's coefficients of s^3, s^2, s, 1
        self._tlist = t.tolist()
        # Clip bounds of q(t): the limits of the bodies it drives (set by check), +-inf until then.
        self._lo = np.full(q.shape[1], -np.inf)
        self._hi = np.full(q.shape[1], np.inf)
        self._clipping = False

    @staticmethod
    def _table(field_name: str, value, n_t: int) -> np.ndarray:
        a = np.array(V._floats(field_name, value, "a finite array (n_times, n_joints)"), dtype=float)
        if a.ndim == 1 and len(a) == n_t:
            a = a[:, None]
        if a.ndim != 2 or len(a) != n_t or a.shape[1] == 0:
            raise ConfigError(field_name, f"array of shape {a.shape}",
                              f"one row per sample time: shape ({n_t}, n_joints)")
        bad = np.argwhere(~np.isfinite(a))
        if bad.size:
            i, k = (int(x) for x in bad[0])
            raise ConfigError(f"{field_name}[{i}][{k}]", float(a[i, k]), "a finite number")
        return a

    @property
    def n_columns(self) -> int:
        return self.positions.shape[1]

    def q_qd(self, t):
        """(q, qd) at t [s], both from one interval search and one product with the piece's coefficients."""
        t = check_time(t)
        times = self._tlist
        if not times[0] <= t <= times[-1]:  # held: the first / last sample, at rest
            q = self.positions[0 if t < times[0] else -1]
            return self._clip(q.copy()), np.zeros(self.n_columns)
        # bisect on a list: a quarter of np.searchsorted's call overhead for one time.
        i = bisect.bisect_right(times, t) - 1
        if times[i] == t:  # at a sample: the recorded row itself, not the spline's rounding of it
            if self.velocities is not None:
                qd = self.velocities[i].copy()
            else:  # the spline's slope there (the last sample: the end of the last piece)
                j = min(i, len(times) - 2)
                h = t - times[j]
                qd = np.array((3 * h * h, 2 * h, 1.0, 0.0)) @ self._c[:, j]
            return self._clip(self.positions[i].copy()), qd
        h = t - times[i]
        # Rows: the cubic's powers of h and their derivatives; (2, 4) @ (4, n_j) -> q, qd.
        qqd = np.array(((h * h * h, h * h, h, 1.0), (3 * h * h, 2 * h, 1.0, 0.0))) @ self._c[:, i]
        return self._clip(qqd[0]), qqd[1]

    def _clip(self, q: np.ndarray) -> np.ndarray:
        """q clipped onto the limits in place, when a body's check found values within the tolerance outside."""
        if self._clipping:
            np.clip(q, self._lo, self._hi, out=q)
        return q

    def q(self, t):
        return self.q_qd(t)[0]

    def qd(self, t):
        return self.q_qd(t)[1]

    #: (min, max, t_min, t_max) per column over the whole interpolant: the cubic pieces' extrema,
    #: found as for the keyframes (the roots of each piece's quadratic derivative and its ends).
    extrema = JointKeyframes.extrema

    def check(self, tree, columns, field_name):
        tol = SAMPLES_LIMIT_TOLERANCE
        for k, col in enumerate(columns):
            if col < 0:
                continue
            lo, hi = tree.limits[col]
            out = np.flatnonzero((self.positions[:, k] < lo - tol) | (self.positions[:, k] > hi + tol))
            if out.size:
                i = int(out[0])
                raise ConfigError(f"{field_name}.samples.positions[{i}][{k}]",
                                  f"{self.positions[i, k]:.9g} at t = {self.times[i]:.9g} s",
                                  _limits_text(tree, col) + f" (+-{tol:g}: measurement noise at a limit)")
        vmin, vmax, tmin, tmax = self.extrema()
        for k, col in enumerate(columns):
            if col < 0:
                continue
            lo, hi = tree.limits[col]
            for v, tv in ((vmin[k], tmin[k]), (vmax[k], tmax[k])):
                if not lo - tol <= v <= hi + tol:
                    raise ConfigError(f"{field_name}.samples", f"{float(v):.9g} at t = {float(tv):.9g} s",
                                      _limits_text(tree, col) + f" (+-{tol:g}) along the whole interpolant between "
                                      "the samples (the cubic overshoots here, between two samples near the limit)")
        # Within the tolerance outside: q(t) clips onto the limits (of every body this motion drives).
        self._narrow_limits(tree, columns)
        self._clipping = self._clipping or bool(np.any(vmin < self._lo) or np.any(vmax > self._hi))

    def to_dict(self):
        return {"type": "samples", "times": self.times.tolist(), "positions": self.positions.tolist(),
                "velocities": None if self.velocities is None else self.velocities.tolist(),
                "joint_names": None if self.joint_names is None else list(self.joint_names)}


class JointConstantVelocity(JointMotion):
    """q(t) = q0 + qd t: constant joint velocities [rad/s or m/s] from q0 at t = 0.

    A joint that reaches its limit raises ConfigError at the first time asked beyond it.
    """

    def __init__(self, q0, qd, joint_names=None):
        q0 = np.asarray(V._floats("joints.constant_velocity.q0", q0, "finite joint positions"), dtype=float)
        qd = np.asarray(V._floats("joints.constant_velocity.qd", qd, "finite joint velocities"), dtype=float)
        if q0.ndim != 1:
            raise ConfigError("joints.constant_velocity.q0", q0.tolist(), "a list of joint positions [rad or m]")
        if qd.shape != q0.shape:
            raise ConfigError("joints.constant_velocity.qd", qd.tolist(), f"one velocity per joint ({len(q0)})")
        if not (np.all(np.isfinite(q0)) and np.all(np.isfinite(qd))):
            raise ConfigError("joints.constant_velocity", "NaN or inf", "finite joint positions and velocities")
        if np.any(np.abs(qd) > V.ANGULAR_SPEED_MAX):
            raise ConfigError("joints.constant_velocity.qd", qd.tolist(),
                              f"joint speeds <= {V.ANGULAR_SPEED_MAX:g} [rad/s or m/s]")
        self.joint_names = _joint_names("joints.constant_velocity.joint_names", joint_names)
        if self.joint_names is not None and len(self.joint_names) != len(q0):
            raise ConfigError("joints.constant_velocity.joint_names", list(self.joint_names),
                              f"one name per value ({len(q0)})")
        self.q0 = q0
        self.qdot = qd

    @property
    def n_columns(self):
        return len(self.q0)

    @property
    def is_static(self):
        return not np.any(self.qdot)

    def q(self, t):
        return self.q0 + self.qdot * check_time(t)

    def qd(self, t):
        check_time(t)
        return self.qdot.copy()

    def exit_time(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Per column, the first time t >= 0 [s] at which q leaves [lo, hi] (inf if never)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            t_hi = np.where(self.qdot > 0, (hi - self.q0) / self.qdot, np.inf)
            t_lo = np.where(self.qdot < 0, (lo - self.q0) / self.qdot, np.inf)
        return np.minimum(t_hi, t_lo)

    def entry_time(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Per column, the last time t <= 0 [s] before which q lies outside [lo, hi] (-inf if never):
        the exit time of the motion run backwards, for a time asked before t = 0."""
        with np.errstate(divide="ignore", invalid="ignore"):
            t_lo = np.where(self.qdot > 0, (lo - self.q0) / self.qdot, -np.inf)
            t_hi = np.where(self.qdot < 0, (hi - self.q0) / self.qdot, -np.inf)
        return np.maximum(t_lo, t_hi)

    def check(self, tree, columns, field_name):
        for k, col in enumerate(columns):
            if col < 0:
                continue
            lo, hi = tree.limits[col]
            if not lo <= self.q0[k] <= hi:
                raise ConfigError(f"{field_name}.constant_velocity.q0[{k}]", float(self.q0[k]),
                                  _limits_text(tree, col))

    def to_dict(self):
        return {"type": "constant_velocity", "q0": self.q0.tolist(), "qd": self.qdot.tolist(),
                "joint_names": None if self.joint_names is None else list(self.joint_names)}


class JointSetpoints(JointMotion):
    """Joint values pushed from outside at each step (a co-simulation, a robot driver).

    ``set(t, q, qd)`` records the state at time t; ``q(t')`` is the latest
    setpoint at or before t' moved on by its velocity (q_k + qd_k (t' - t_k)),
    ``q0`` before any. The last ``history`` setpoints are kept; a time before
    the oldest kept one raises ConfigError.

    Limits: ``q0`` and every setpoint already kept are checked when a body is
    built with this motion (a ConfigError naming the joint and its limits); a
    setpoint pushed later outside them raises when a time on or after it is
    asked (naming the joint, the value and the time). Moving a setpoint on by
    its velocity is this class's own guess between pushes, and a joint cannot
    run past its limit: the guess stops at the limit (the position held there,
    the velocity 0) instead of failing the run, for the limits of the bodies
    the motion drives (a robot driver's last push 1 mm before a limit at
    0.1 m/s would otherwise leave it 10 ms later).
    """

    def __init__(self, q0, joint_names=None, history: int = 256):
        q0 = np.asarray(V._floats("joints.setpoints.q0", q0, "finite joint positions"), dtype=float)
        if q0.ndim != 1 or len(q0) == 0 or not np.all(np.isfinite(q0)):
            raise ConfigError("joints.setpoints.q0", q0.tolist(), "a non-empty vector of finite joint positions")
        self.joint_names = _joint_names("joints.setpoints.joint_names", joint_names)
        if self.joint_names is not None and len(self.joint_names) != len(q0):
            raise ConfigError("joints.setpoints.joint_names", list(self.joint_names), f"one name per value ({len(q0)})")
        self._history = V.integer("joints.setpoints.history", history, lo=1)
        self._t = [-math.inf]
        self._q = [q0]
        self._qd = [np.zeros_like(q0)]
        self._version = 0
        self._lock = ForkSafeLock()
        # Where the guess between pushes stops: the limits of the bodies it drives (set by check).
        self._lo = np.full(len(q0), -np.inf)
        self._hi = np.full(len(q0), np.inf)

    @property
    def n_columns(self):
        return len(self._q[0])

    @property
    def version(self):
        return self._version

    def set(self, t: float, q, qd=None) -> None:
        """Record joint positions q [rad or m] and velocities qd at time t [s] (t not before the last)."""
        t = check_time(t)
        n = self.n_columns
        q = np.array(V._floats("setpoints.q", q, f"{n} finite joint positions"), dtype=float)
        qd = np.zeros(n) if qd is None else np.array(V._floats("setpoints.qd", qd, f"{n} finite velocities"),
                                                     dtype=float)
        # Each array is named on its own: a bad velocity is reported as setpoints.qd with its own values.
        for f, a, what in (("setpoints.q", q, "joint positions [rad or m]"), ("setpoints.qd", qd,
                                                                             "joint velocities [rad/s or m/s]")):
            if a.shape != (n,) or not np.all(np.isfinite(a)):
                raise ConfigError(f, a.tolist(), f"{n} finite {what}, one per column")
        with self._lock:
            if t < self._t[-1]:
                raise ConfigError("setpoints.t", t, f"a time >= the last setpoint's ({self._t[-1]:g} s)")
            if t == self._t[-1]:
                self._q[-1], self._qd[-1] = q, qd
            else:
                self._t.append(t)
                self._q.append(q)
                self._qd.append(qd)
                if len(self._t) > self._history:
                    del self._t[0], self._q[0], self._qd[0]
            self._version += 1

    def _at(self, t: float) -> int:
        i = bisect.bisect_right(self._t, t) - 1  # O(log n) on the list, no array conversion
        if i < 0:
            raise ConfigError("setpoints.t", t, f"a time at or after the oldest kept setpoint ({self._t[0]:.9g} s; "
                              f"the last {self._history} setpoints are kept)")
        return i

    def _state(self, t) -> tuple[np.ndarray, np.ndarray]:
        """(q, qd) at t: the latest setpoint moved on by its velocity, stopped at a limit it runs into."""
        t = check_time(t)
        # Read under the lock: a push from another thread may drop the oldest setpoint between the
        # search and the reads, which would pair one setpoint's time with another's values.
        with self._lock:
            i = self._at(t)
            t_i, q_i, qd_i = self._t[i], self._q[i], self._qd[i]
        if not math.isfinite(t_i):
            return q_i.copy(), qd_i.copy()
        q = q_i + qd_i * (t - t_i)
        # Past a limit the setpoint itself is within: the joint stops there. A setpoint already
        # outside keeps its value (and the body refuses it, naming the push's value).
        lo, hi = np.minimum(self._lo, q_i), np.maximum(self._hi, q_i)
        # At a limit and moving into it (a co-simulation's value held there) it stays, at rest, too.
        stopped = (q < lo) | (q > hi) | ((q <= lo) & (qd_i < 0)) | ((q >= hi) & (qd_i > 0))
        if not stopped.any():
            return q, qd_i.copy()
        return np.clip(q, lo, hi), np.where(stopped, 0.0, qd_i)

    def q(self, t):
        return self._state(t)[0]

    def qd(self, t):
        return self._state(t)[1]

    def check(self, tree, columns, field_name):
        with self._lock:
            kept = list(zip(self._t, self._q, strict=True))
        for t_i, q_i in kept:
            for k, col in enumerate(columns):
                if col < 0:
                    continue
                lo, hi = tree.limits[col]
                if not lo <= q_i[k] <= hi:  # NaN cannot be here: set() refuses it
                    if math.isfinite(t_i):
                        raise ConfigError(f"{field_name}.setpoints.q[{k}]", f"{q_i[k]:.9g} at t = {t_i:.9g} s",
                                          _limits_text(tree, col))
                    raise ConfigError(f"{field_name}.setpoints.q0[{k}]", float(q_i[k]), _limits_text(tree, col))
        with self._lock:
            self._narrow_limits(tree, columns)

    def to_dict(self):
        return {"type": "setpoints", "n_joints": self.n_columns,
                "joint_names": None if self.joint_names is None else list(self.joint_names)}


# ==================================================================== bodies in a scene
class ArticulatedBody:
    """A kinematic tree in a scene, driven by a joint motion, on a (possibly moving) base.

    Parameters
    ----------
    name : str
        Prefix of the scene objects: ``f"{name}/{link}"``.
    tree : KinematicTree
    joint_motion : JointMotion, or None (every joint held at its home value, ``tree.home``)
    base : Pose or Motion
        Root link -> world (a Motion for a mobile base).
    """

    def __init__(self, name: str, tree: KinematicTree, joint_motion: JointMotion | None = None,
                 base: Pose | Motion | None = None):
        self.name = _name("robot.name", name)
        if "/" in name:
            raise ConfigError("robot.name", name, "a name without '/' (it separates body and link names)")
        if not isinstance(tree, KinematicTree):
            raise ConfigError(f"{name}.tree", tree, "a KinematicTree")
        self.tree = tree
        # The forward kinematics are cached by time and the joint motion's version; a new
        # joint motion or base (the setters below) empties the cache.
        self._cache: OrderedDict = OrderedDict()
        self._last: tuple | None = None  # (t, motion version, state) of the newest state asked for
        self._lock = ForkSafeLock()
        self.joint_motion = joint_motion
        self.base = base

    @property
    def joint_motion(self) -> JointMotion:
        """The joint trajectory; may be replaced (checked against the tree, the kept states dropped)."""
        return self._joint_motion

    @joint_motion.setter
    def joint_motion(self, joint_motion: JointMotion | None) -> None:
        name, tree = self.name, self.tree
        if joint_motion is None:
            joint_motion = JointConstantVelocity(tree.home, np.zeros(tree.n_joints))
        if not isinstance(joint_motion, JointMotion):
            raise ConfigError(f"{name}.joints", joint_motion, "a JointMotion: JointKeyframes, JointSamples, "
                              "JointConstantVelocity or JointSetpoints (or None)")
        names = joint_motion.joint_names
        if names is None:
            if joint_motion.n_columns != tree.n_joints:
                raise ConfigError(f"{name}.joints", f"{joint_motion.n_columns} columns",
                                  f"one column per movable joint ({tree.n_joints}: {list(tree.joint_names)}), "
                                  "or joint_names naming the columns")
            cols = np.arange(tree.n_joints)
        else:
            cols = []
            for n in names:
                if n in tree.mimic_joints:
                    cols.append(-1)  # follows its master: the column is not used (as ROS does)
                    continue
                if n not in tree.joint_names:
                    from twinsense.errors import UnknownNameError

                    raise UnknownNameError(f"{name}.joints.joint_names", n, list(tree.joint_names))
                cols.append(tree.joint_index(n))
            cols = np.array(cols, dtype=np.intp)
        joint_motion.check(tree, cols, f"{name}.joints")
        keep = None
        if np.any(cols < 0):
            keep = np.flatnonzero(cols >= 0)
            dropped = [names[k] for k in np.flatnonzero(cols < 0)]
            warnings.warn(f"{name}: the joint motion's columns {dropped} are mimic joints, which follow their "
                          "masters; their values are not used", stacklevel=3)
            cols = cols[keep]
        with self._lock:
            self._joint_motion = joint_motion
            self._cols = cols
            self._keep = keep
            # Joints the motion does not drive stay at their home value.
            self._q_fixed = tree.home.copy()
            self._forget()

    @property
    def base(self) -> Motion:
        """Root link -> world; may be replaced by a Pose or a Motion (the kept states dropped)."""
        return self._base

    @base.setter
    def base(self, base: Pose | Motion | None) -> None:
        if base is None:
            base = Static(Pose())
        elif isinstance(base, Pose):
            base = Static(base)
        if not isinstance(base, Motion):
            raise ConfigError(f"{self.name}.base", base, "a Pose or a Motion (root link -> world)")
        with self._lock:
            self._base = base
            self._forget()

    def _forget(self) -> None:
        """Drop the kept states (under the lock): they belong to the replaced motion or base."""
        self._cache = OrderedDict()
        self._last = None

    def __getstate__(self) -> dict:
        # A copy (pickle, deepcopy) gets a lock and kept states of its own.
        state = self.__dict__.copy()
        del state["_lock"]
        state["_cache"], state["_last"] = OrderedDict(), None
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._lock = ForkSafeLock()

    @property
    def is_static(self) -> bool:
        return self.base.is_static and self.joint_motion.is_static

    def joint_state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(q, qd) of every movable joint at t, in ``tree.joint_names`` order; checked against the limits."""
        qm, qdm = self.joint_motion.q_qd(t)
        if self._keep is not None:  # columns of mimic joints: not used
            qm, qdm = qm[self._keep], qdm[self._keep]
        q = self._q_fixed.copy()
        qd = np.zeros(self.tree.n_joints)
        q[self._cols] = qm
        qd[self._cols] = qdm
        if not np.all((q >= self.tree.limits[:, 0]) & (q <= self.tree.limits[:, 1])):
            when = f" (reached at t = {t:.9g} s)"
            m = self.joint_motion
            if isinstance(m, JointConstantVelocity):
                lo = np.full(m.n_columns, -np.inf)
                hi = np.full(m.n_columns, np.inf)
                used = slice(None) if self._keep is None else self._keep
                lo[used], hi[used] = self.tree.limits[self._cols, 0], self.tree.limits[self._cols, 1]
                if t >= 0:
                    te = float(np.min(m.exit_time(lo, hi)))
                    when = f" (the constant velocity leaves them at t = {te:.9g} s; asked at t = {t:.9g} s)"
                else:  # before t = 0 q ran backwards from q0: it left them going back in time
                    te = float(np.max(m.entry_time(lo, hi)))
                    when = (f" (the constant velocity is within them only from t = {te:.9g} s on; asked at "
                            f"t = {t:.9g} s)")
            self.tree.check_limits(q, None, when)
        return q, qd

    def state(self, t: float) -> TreeState:
        """Every link's state at t [s]; one forward kinematics per time for all links (cached)."""
        last = self._last
        # Every link of the body asks at the same time in turn (the caster: 19 segments of a person): the
        # newest state is returned before the time's checks (a float equal to a checked time is one).
        if last is not None and isinstance(t, float) and t == last[0] and self.joint_motion.version == last[1]:
            return last[2]
        t = check_time(t)
        key = (t, self.joint_motion.version)
        with self._lock:
            hit = self._cache.get(key)
            if hit is not None:
                self._cache.move_to_end(key)
                self._last = (t, key[1], hit)
                return hit
            cache = self._cache
        q, qd = self.joint_state(t)
        st = self.tree.forward(q, qd, self.base.state(t))
        with self._lock:
            if self._cache is cache:  # not if the motion or base was replaced meanwhile
                cache[key] = st
                while len(cache) > FK_CACHE_SIZE:
                    cache.popitem(last=False)
                self._last = (t, key[1], st)
        return st

    def object_name(self, link: str) -> str:
        self.tree.link(link)
        return f"{self.name}/{link}"

    def link_motion(self, link: str) -> LinkMotion:
        return LinkMotion(self, self.tree.link_names.index(self.tree.link(link).name))

    def scene_items(self) -> tuple[list[SceneObject], list[Frame]]:
        """One SceneObject per link with geometry (frame = link frame), one Frame per link without."""
        objs, frames = [], []
        for i, lk in enumerate(self.tree.links):
            motion = LinkMotion(self, i)
            name = f"{self.name}/{lk.name}"
            geom = lk.link_frame_geometry()
            if geom is None:
                frames.append(Frame(name, motion))
            else:
                kw = {} if lk.layers is None else {"layers": lk.layers}
                objs.append(SceneObject(name, geom, lk.material, motion, **kw))
        return objs, frames

    def add_to(self, scene: Scene) -> list[SceneObject]:
        """Add the links to ``scene``: objects for links with geometry, mount frames for the others."""
        if not isinstance(scene, Scene):
            raise ConfigError("scene", scene, "a twinsense Scene")
        objs, frames = self.scene_items()
        taken = {o.name for o in scene.objects} | set(scene.frame_names)
        for item in (*objs, *frames):
            if item.name in taken:
                raise ConfigError(f"{self.name}.name", self.name,
                                  f"a robot name whose link names are free in the scene ({item.name!r} is taken)")
        for o in objs:
            scene.add(o)
        for f in frames:
            scene.add_frame(f)
        return objs

    def __repr__(self) -> str:
        return f"ArticulatedBody({self.name!r}, {self.tree!r})"


@dataclass(frozen=True, eq=False)
class LinkMotion(Motion):
    """The motion of one link of an articulated body (its frame = the link frame)."""

    body: ArticulatedBody
    link_index: int

    def state(self, t):
        return self.body.state(t).state(self.link_index)

    @property
    def is_static(self):
        return self.body.is_static

    def to_dict(self):
        return {"type": "link", "body": self.body.name, "link": self.body.tree.link_names[self.link_index]}
