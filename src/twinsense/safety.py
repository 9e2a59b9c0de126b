"""Speed and separation monitoring: the true human-robot distance and ISO/TS 15066's protective separation.

ISO/TS 15066:2016, clause 5.5.4.2.3, gives the protective separation
distance a robot must keep from a person at time t0::

    S_p = S_h + S_r + S_s + C + Z_d + Z_r

- ``S_h = v_h (T_r + T_s)``: the person's travel while the robot reacts and
  stops (v_h = 1.6 m/s, the walking speed of ISO 13855, unless a risk
  assessment gives another);
- ``S_r = v_r T_r``: the robot's travel during its reaction time (plus
  ``a T_r^2 / 2`` when the robot may speed up at ``robot_acceleration`` a
  meanwhile, which the TS asks to account for when v_r is the current speed);
- ``S_s``: the robot's stopping distance (here ``v_r' T_s / 2``, a constant
  deceleration from v_r' = v_r + a T_r to rest over T_s, unless a measured
  figure is given);
- ``C``: the intrusion distance (how far a body part reaches past the
  detection before it is detected, ISO 13855);
- ``Z_d``, ``Z_r``: the position uncertainties of the person (the sensing)
  and of the robot (its measurement system).

This is the TS's constant-speed form: v_h held over T_r + T_s, v_r over T_r
(or a constant acceleration), and a constant deceleration, in place of the
TS's integrals of v_h, v_r and the stopping speed v_s over those times. A
robot whose speed is not monitored takes its maximum speed as v_r (the TS).
Left to the caller: v_h other than 1.6 m/s (ISO 13855 takes 2.0 m/s
for a hand or arm approach where the distance it gives is at most 0.5 m:
``SeparationParameters(human_speed=2.0)``), C from the sensing's detection
capability d (ISO 13855: 8 (d - 14 mm) for d <= 40 mm, 0.208 m at 40 mm;
0.85 m for coarser detection), and a measured S_s (ISO 10218-1, Annex B:
``stopping_distance``).

v_r is "the directed speed of the robot in the direction of the operator". A
robot is not one point: a part a little farther from the person than the
closest one can approach it faster (a swinging wrist beside a slow elbow),
and S_p for the closest point's speed alone then falls short of what that
part needs. :class:`SeparationMonitor` gives both; ``approach_speed`` (the
largest speed towards the person of any robot surface point, each along the
line to its own nearest body point) is the conservative v_r: with it
``distance >= S_p`` implies ``d_i >= S_p(v_i)`` for every robot point i.

:class:`SeparationMonitor` gives the true minimum distance between a robot's
links and a person's body segments at any time: the person's capsules,
spheres and boxes are exact primitives, the robot's link meshes are taken as
their surface points (every vertex after subdividing each mesh until no edge
exceeds ``spacing``). A point of a triangle whose edges are all <= h is at
most h / sqrt(3) from its nearest vertex, so the distance returned exceeds
the true mesh-to-primitive distance by at most ``spacing / sqrt(3)`` (never
less than the true one). That is the unsafe side for ``distance >= S_p``: count
it in Z_r (``robot_uncertainty``). A robot link that is a primitive (sphere,
capsule, cylinder) is taken as its tessellation, which lies inside it by up
to 0.6 % of its radius (a capsule; a sphere or cylinder 0.12 %): the distance
exceeds the primitive's by that more.

The robot is an articulated body of the scene (by name) or a list of scene
objects, each a rigid part moved by its own motion (the bodies of a
:class:`~twinsense.robots.MujocoCosim`); the person is an articulated body
whose segments are capsules, spheres and boxes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from twinsense import validation as V
from twinsense.compiled import jit
from twinsense.errors import ConfigError
from twinsense.scene.articulated import ArticulatedBody
from twinsense.scene.geometry import Box, Capsule, Sphere
from twinsense.scene.motion import check_time
from twinsense.scene.scene import Scene

__all__ = ["SeparationMonitor", "SeparationParameters", "SeparationSample", "point_box_distance",
           "point_capsule_distance", "protective_separation_distance"]


#: The most robot surface points (estimated) a SeparationMonitor takes: each (n, 3) array of points,
#: velocities and gradients is 120 MB at 5 million, and the estimate runs up to 40 % low.
MAX_ROBOT_POINTS = 5_000_000


@dataclass(frozen=True)
class SeparationParameters:
    """The terms of ISO/TS 15066's S_p that do not come from the robot's motion (SI units).

    ``stopping_distance`` [m]: a measured S_s; None takes ``v_r' T_s / 2``.
    ``robot_acceleration`` [m/s^2]: the most the robot can speed up towards the person during T_r (the
    TS asks for it when S_p uses the robot's current speed): S_r = v_r T_r + a T_r^2 / 2 and the stop
    starts from v_r' = v_r + a T_r. 0 takes the speed as held.
    """

    human_speed: float = 1.6          # v_h [m/s], ISO 13855's walking speed
    reaction_time: float = 0.1        # T_r [s]: sensing, processing and the controller's reaction
    stopping_time: float = 0.3        # T_s [s]: from the stop command to rest
    intrusion_distance: float = 0.2   # C [m]: a hand reaching past its detection
    human_uncertainty: float = 0.05   # Z_d [m]: the sensing's position error
    robot_uncertainty: float = 0.01   # Z_r [m]: the robot's position error
    stopping_distance: float | None = None  # S_s [m]; None: v_r' T_s / 2
    robot_acceleration: float = 0.0   # a [m/s^2]: speeding up towards the person during T_r

    def __post_init__(self) -> None:
        V.non_negative("human_speed", self.human_speed, "m/s")
        for name in ("reaction_time", "stopping_time"):
            V.non_negative(name, getattr(self, name), "s")
        for name in ("intrusion_distance", "human_uncertainty", "robot_uncertainty"):
            V.non_negative(name, getattr(self, name), "m")
        if self.stopping_distance is not None:
            V.non_negative("stopping_distance", self.stopping_distance, "m")
        V.non_negative("robot_acceleration", self.robot_acceleration, "m/s^2")


def protective_separation_distance(robot_speed, params: SeparationParameters = SeparationParameters()):
    """S_p [m] for the robot's speed towards the person ``robot_speed`` [m/s] (scalar or array).

    Use the fastest approach of any robot point (``SeparationSample.approach_speed``), not only the
    closest point's: see the module docstring."""
    try:
        raw = np.asarray(robot_speed)
    except (TypeError, ValueError):
        raw = np.asarray(None)
    if raw.dtype.kind not in "iuf":  # True would be read as 1 m/s, a string or a ragged list as garbage
        raise ConfigError("robot_speed", robot_speed, "finite speeds >= 0 m/s (a number or an array)")
    v_r = raw.astype(float)
    if not np.all(np.isfinite(v_r)) or np.any(v_r < 0):
        raise ConfigError("robot_speed", robot_speed, "finite speeds >= 0 m/s")
    if not isinstance(params, SeparationParameters):
        raise ConfigError("params", params, "a twinsense.safety.SeparationParameters")
    p = params
    s_h = p.human_speed * (p.reaction_time + p.stopping_time)
    a, t_r = p.robot_acceleration, p.reaction_time
    s_r = v_r * t_r + 0.5 * a * t_r**2
    v_stop = v_r + a * t_r  # the speed when the stop begins
    s_s = v_stop * p.stopping_time / 2 if p.stopping_distance is None else np.full_like(v_r, p.stopping_distance)
    out = s_h + s_r + s_s + p.intrusion_distance + p.human_uncertainty + p.robot_uncertainty
    return float(out) if out.ndim == 0 else out


def point_capsule_distance(points, a, b, radius: float, gradient: bool = False):
    """Signed distance (n,) [m] from points (n, 3) to the capsule of axis a-b (3,) and ``radius`` (< 0 inside).

    ``gradient``: also the distance's gradient (n, 3) (unit vectors away from the capsule; zero on its axis).
    """
    p = np.asarray(points, dtype=float)
    a = np.asarray(a, dtype=float)
    ab = np.asarray(b, dtype=float) - a
    den = float(ab @ ab)
    s = np.zeros(len(p)) if den == 0.0 else np.clip((p - a) @ ab / den, 0.0, 1.0)
    off = p - (a + s[:, None] * ab)
    r = np.linalg.norm(off, axis=1)
    if not gradient:
        return r - radius
    return r - radius, off / np.maximum(r, 1e-300)[:, None]


def point_box_distance(points_local, size, gradient: bool = False):
    """Signed distance (n,) [m] from points (n, 3) in the box frame to a centred box of ``size`` (3,) (< 0 inside).

    ``gradient``: also the distance's gradient (n, 3) in the box frame (unit vectors; inside, the normal
    of the nearest face).
    """
    p = np.asarray(points_local, dtype=float)
    q = np.abs(p) - 0.5 * np.asarray(size, dtype=float)
    out = np.maximum(q, 0.0)
    outside = np.linalg.norm(out, axis=1)
    d = outside + np.minimum(q.max(axis=1), 0.0)
    if not gradient:
        return d
    g = out / np.maximum(outside, 1e-300)[:, None]
    inside = outside == 0.0
    g[inside] = 0.0
    g[inside, np.argmax(q[inside], axis=1)] = 1.0
    return d, g * np.where(p < 0.0, -1.0, 1.0)


@jit
def _nearest_segments(pts, kind, link, a, ab, den, radius, half, rot, best, which, grad):  # pragma: no cover
    """Per point (n, 3): the distance to the nearest segment [m] into ``best`` (n,), its link into ``which``
    (n,) and the distance's gradient into ``grad`` (n, 3); segments in order, the first of equals kept.

    Segment j: ``kind`` 0 a capsule (axis start ``a[j]``, axis ``ab[j]``, ``den[j]`` = |ab|^2, ``radius[j]``;
    a sphere has ab = 0), 1 a box (centre ``a[j]``, rotation ``rot[j]`` box -> world, half sizes ``half[j]``).
    The formulas of point_capsule_distance and point_box_distance, term by term."""
    n, m = pts.shape[0], kind.shape[0]
    for k in range(n):
        px, py, pz = pts[k, 0], pts[k, 1], pts[k, 2]
        bd, bw, g0, g1, g2 = np.inf, -1, 0.0, 0.0, 0.0
        for j in range(m):
            dx, dy, dz = px - a[j, 0], py - a[j, 1], pz - a[j, 2]
            if kind[j] == 0:
                s = 0.0
                if den[j] != 0.0:
                    s = min(max((dx * ab[j, 0] + dy * ab[j, 1] + dz * ab[j, 2]) / den[j], 0.0), 1.0)
                ox, oy, oz = dx - s * ab[j, 0], dy - s * ab[j, 1], dz - s * ab[j, 2]
                r = np.sqrt(ox * ox + oy * oy + oz * oz)
                d = r - radius[j]
                if d < bd:
                    inv = 1.0 / max(r, 1e-300)
                    bd, bw, g0, g1, g2 = d, link[j], ox * inv, oy * inv, oz * inv
            else:
                # The point in the box frame: (p - centre) R.
                lx = dx * rot[j, 0, 0] + dy * rot[j, 1, 0] + dz * rot[j, 2, 0]
                ly = dx * rot[j, 0, 1] + dy * rot[j, 1, 1] + dz * rot[j, 2, 1]
                lz = dx * rot[j, 0, 2] + dy * rot[j, 1, 2] + dz * rot[j, 2, 2]
                qx, qy, qz = abs(lx) - half[j, 0], abs(ly) - half[j, 1], abs(lz) - half[j, 2]
                ux, uy, uz = max(qx, 0.0), max(qy, 0.0), max(qz, 0.0)
                outside = np.sqrt(ux * ux + uy * uy + uz * uz)
                d = outside + min(max(qx, max(qy, qz)), 0.0)
                if d < bd:
                    if outside == 0.0:  # inside: the nearest face's normal (the first of equal q)
                        hx, hy, hz = 0.0, 0.0, 0.0
                        if qx >= qy and qx >= qz:
                            hx = 1.0
                        elif qy >= qz:
                            hy = 1.0
                        else:
                            hz = 1.0
                    else:
                        inv = 1.0 / max(outside, 1e-300)
                        hx, hy, hz = ux * inv, uy * inv, uz * inv
                    hx = -hx if lx < 0.0 else hx
                    hy = -hy if ly < 0.0 else hy
                    hz = -hz if lz < 0.0 else hz
                    # Back to the world: h R^T.
                    bd, bw = d, link[j]
                    g0 = hx * rot[j, 0, 0] + hy * rot[j, 0, 1] + hz * rot[j, 0, 2]
                    g1 = hx * rot[j, 1, 0] + hy * rot[j, 1, 1] + hz * rot[j, 1, 2]
                    g2 = hx * rot[j, 2, 0] + hy * rot[j, 2, 1] + hz * rot[j, 2, 2]
        best[k], which[k], grad[k, 0], grad[k, 1], grad[k, 2] = bd, bw, g0, g1, g2


@dataclass(frozen=True)
class SeparationSample:
    """The closest approach at time ``t`` [s].

    ``distance`` [m] (< 0: overlap); ``robot_point`` (3,) [m] the closest robot
    surface point; ``robot_link`` and ``human_link`` the scene object names;
    ``robot_speed`` [m/s] the speed of the robot's closest point towards the
    person (its velocity along the line to the person's nearest surface, >= 0);
    ``approach_speed`` [m/s] the largest such speed of any robot surface point
    (each along the line to its own nearest body point; >= ``robot_speed``):
    the v_r to give :func:`protective_separation_distance`.
    """

    t: float
    distance: float
    robot_point: np.ndarray
    robot_link: str
    human_link: str
    robot_speed: float
    approach_speed: float


def _bodies(scene) -> list:
    """The scene's articulated bodies (each once, in the order their first link was added)."""
    out = []
    for obj in scene.objects:
        # Only a LinkMotion's ``body`` is an ArticulatedBody (a MuJoCo co-simulation's object motions carry
        # the MuJoCo body index under that name).
        body = getattr(obj.motion, "body", None)
        if isinstance(body, ArticulatedBody) and all(b is not body for b in out):
            out.append(body)
    return out


def _body(scene, name: str, field: str):
    """The articulated body whose links are the scene objects ``name/...``."""
    bodies = _bodies(scene)
    for body in bodies:
        if body.name == name:
            return body
    names = sorted(b.name for b in bodies)
    if isinstance(name, str) and any(f.name.startswith(name + "/") for f in scene.frames):
        raise ConfigError(field, name, f"an articulated body with link geometry ({name!r} has frames only; "
                          "bodies with geometry: " + (", ".join(names) or "none") + ")")
    raise ConfigError(field, name, "an articulated body of the scene: " + (", ".join(names) or "none"))


def _objects(scene, names) -> list:
    """The scene objects ``names`` (a robot given as rigid objects, e.g. a MuJoCo co-simulation's bodies)."""
    names = list(names)
    if not names or not all(isinstance(n, str) for n in names):
        raise ConfigError("robot", names, "an articulated body's name or a non-empty list of scene object names")
    known = {o.name: o for o in scene.objects}
    for k, n in enumerate(names):
        if n not in known:
            raise ConfigError(f"robot[{k}]", n, "a scene object: " + ", ".join(sorted(known)))
    if len(set(names)) != len(names):
        raise ConfigError("robot", names, "each object once")
    return [known[n] for n in names]


class SeparationMonitor:
    """True minimum distance between the robot ``robot`` and the person ``person`` of ``scene``.

    ``robot``: the name of an articulated body of the scene (its links with geometry), or a list of
    scene object names, each a rigid part moved by its own motion (a :class:`~twinsense.robots.MujocoCosim`'s
    bodies: ``[o.name for o in cosim.scene.objects if o.name != "world"]``). ``person``: an articulated body
    whose segments are capsules, spheres or boxes (:func:`~twinsense.scene.human.add_person`).
    ``spacing`` [m]: the largest edge of the subdivided robot meshes (the distance is exact to
    ``spacing / sqrt(3)``, from above). Attributes ``robot`` (the ArticulatedBody; None for a list of
    objects) and ``person`` (the ArticulatedBody).
    """

    def __init__(self, scene, robot, person: str, spacing: float = 0.01):
        if not isinstance(scene, Scene):
            raise ConfigError("scene", scene, "a twinsense Scene holding the robot and the person")
        V.length("spacing", spacing)
        self.person = _body(scene, person, "person")
        if isinstance(robot, str):
            self.robot = _body(scene, robot, "robot")
            if self.robot is self.person:
                raise ConfigError("robot", robot, f"another body than the person ({person!r})")
            self._objects = None
            meshes = [(i, g.mesh) for i, lk in enumerate(self.robot.tree.links)
                      if (g := lk.link_frame_geometry()) is not None]
        elif isinstance(robot, (list, tuple)):
            self.robot = None
            self._objects = _objects(scene, robot)
            mine = {self.person.object_name(lk.name) for lk in self.person.tree.links}
            for k, o in enumerate(self._objects):
                if o.name in mine:
                    raise ConfigError(f"robot[{k}]", o.name, f"an object that is not a part of the person {person!r}")
            meshes = [(k, o.geometry.mesh) for k, o in enumerate(self._objects)]
        else:
            raise ConfigError("robot", robot, "an articulated body's name or a list of scene object names")
        self.spacing = float(spacing)
        # The subdivided meshes' vertex count, roughly (refused before it exhausts the memory): edges end
        # near spacing / 2 to spacing, a triangle of edges spacing / 2 covers sqrt(3) / 16 spacing^2 and a
        # closed mesh has half as many vertices as triangles (the UR5: 41,026 points at 10 mm for 33,900
        # estimated, 514,866 at 3 mm for 377,000).
        area = sum(float(m.area) for _, m in meshes)
        estimate = area / (np.sqrt(3.0) / 16.0 * self.spacing**2) / 2.0
        if estimate > MAX_ROBOT_POINTS:
            smallest = np.sqrt(area / (np.sqrt(3.0) / 16.0) / 2.0 / MAX_ROBOT_POINTS)
            raise ConfigError("spacing", spacing, f"a spacing >= {smallest:.2g} m for this robot (its "
                              f"{area:.3g} m^2 of link surface as at most {MAX_ROBOT_POINTS:,} points)")
        self._robot_points = []  # (link or object index, points (n, 3) in the link / object frame)
        for i, m in meshes:
            v, _ = trimesh.remesh.subdivide_to_size(np.asarray(m.vertices), np.asarray(m.faces),
                                                    max_edge=self.spacing, max_iter=30)
            self._robot_points.append((i, np.unique(v, axis=0)))
        self._prims = []  # (link index, geometry, origin pose)
        for i, lk in enumerate(self.person.tree.links):
            if lk.geometry is None:
                continue
            if not isinstance(lk.geometry, (Capsule, Sphere, Box)):
                raise ConfigError(f"person.links[{lk.name}].geometry", type(lk.geometry).__name__,
                                  "capsule, sphere or box (exact distances)")
            self._prims.append((i, lk.geometry, lk.origin))

    def robot_points(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(points (n, 3) [m], velocities (n, 3) [m/s], part index (n,)) of the robot's surface at t.

        The part index is the link's index in ``robot.tree.links`` (an articulated robot) or the object's
        in the ``robot`` list given.
        """
        pts, vel, idx = [], [], []
        if self._objects is None:
            st = self.robot.state(t)
            for i, local in self._robot_points:
                w = local @ st.rotations[i].T + st.positions[i]
                pts.append(w)
                vel.append(st.point_velocity(i, w))
                idx.append(np.full(len(w), i))
        else:
            t = check_time(t)
            for k, local in self._robot_points:
                ms = self._objects[k].motion.state(t)
                w = local @ ms.pose.rotation.T + ms.pose.position
                pts.append(w)
                vel.append(ms.point_velocity(w))
                idx.append(np.full(len(w), k))
        return np.concatenate(pts), np.concatenate(vel), np.concatenate(idx)

    def _robot_part_name(self, k: int) -> str:
        if self._objects is None:
            return self.robot.object_name(self.robot.tree.links[k].name)
        return self._objects[k].name

    def human_distances(self, points, t: float, gradient: bool = False):
        """(distance (n,) [m] from points (n, 3) to the nearest body segment, that segment's link index (n,)).

        ``gradient``: also the distance's gradient (n, 3) (unit vectors pointing away from the body: minus
        the direction from each point to its nearest body point), as a third item.

        One compiled pass over the points and segments (:func:`_nearest_segments`); the same formulas as
        :func:`point_capsule_distance` and :func:`point_box_distance` (``_human_distances_numpy``, the
        reference the tests compare it with), about 10x faster for a robot's ~10^5 surface points.
        """
        st = self.person.state(t)
        pts = np.ascontiguousarray(points, dtype=float).reshape(-1, 3)
        m = len(self._prims)
        kind, link = np.zeros(m, np.int64), np.zeros(m, np.int64)
        a, ab, den = np.zeros((m, 3)), np.zeros((m, 3)), np.zeros(m)
        radius, half, rot = np.zeros(m), np.zeros((m, 3)), np.zeros((m, 3, 3))
        for j, (i, g, origin) in enumerate(self._prims):
            pose = st.pose(i) @ origin
            link[j] = i
            if isinstance(g, Box):
                kind[j], a[j], rot[j], half[j] = 1, pose.position, pose.rotation, 0.5 * np.asarray(g.size, float)
            else:
                h = 0.0 if isinstance(g, Sphere) else 0.5 * g.height
                a[j] = pose.apply(np.array([[0.0, 0.0, -h]]))[0]
                ab[j] = pose.apply(np.array([[0.0, 0.0, h]]))[0] - a[j]
                den[j], radius[j] = float(ab[j] @ ab[j]), g.radius
        best, which, grad = np.empty(len(pts)), np.empty(len(pts), np.int64), np.empty((len(pts), 3))
        _nearest_segments(pts, kind, link, a, ab, den, radius, half, rot, best, which, grad)
        return (best, which, grad) if gradient else (best, which)

    def _human_distances_numpy(self, points, t: float, gradient: bool = False):
        """:meth:`human_distances` by the NumPy point-to-segment functions, segment by segment (the reference)."""
        st = self.person.state(t)
        pts = np.asarray(points, dtype=float)
        best = np.full(len(pts), np.inf)
        which = np.full(len(pts), -1)
        grad = np.zeros((len(pts), 3))
        for i, g, origin in self._prims:
            pose = st.pose(i) @ origin
            if isinstance(g, Box):
                d, gr = point_box_distance((pts - pose.position) @ pose.rotation, g.size, gradient=True)
                gr = gr @ pose.rotation.T
            else:
                h = 0.0 if isinstance(g, Sphere) else 0.5 * g.height
                a = pose.apply(np.array([[0.0, 0.0, -h]]))[0]
                b = pose.apply(np.array([[0.0, 0.0, h]]))[0]
                d, gr = point_capsule_distance(pts, a, b, g.radius, gradient=True)
            closer = d < best
            best[closer], which[closer], grad[closer] = d[closer], i, gr[closer]
        return (best, which, grad) if gradient else (best, which)

    def at(self, t: float) -> SeparationSample:
        """The closest approach between the robot and the person at ``t`` [s]."""
        pts, vel, idx = self.robot_points(t)
        d, seg, grad = self.human_distances(pts, t, gradient=True)
        # Each point's speed towards the person: its velocity along minus the exact distance field's gradient
        # (the line to its nearest body point).
        towards = np.maximum(-np.einsum("ij,ij->i", vel, grad), 0.0)
        k = int(np.argmin(d))
        return SeparationSample(float(t), float(d[k]), pts[k], self._robot_part_name(int(idx[k])),
                                self.person.object_name(self.person.tree.links[seg[k]].name),
                                float(towards[k]), float(towards.max()))
