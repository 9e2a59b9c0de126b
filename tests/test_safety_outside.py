"""twinsense.safety on robots, people and scenes its other tests do not use, against independent references.

- SeparationMonitor's distance against an exact mesh-to-primitive distance written here (trimesh's closest
  points for the primitives' end points and corners, Ericson's segment-segment distance for the mesh edges
  against the capsule axes and box edges; exact for disjoint shapes): a Panda posed by yourdfpy's forward
  kinematics with a person reaching past it, and MuJoCo's Panda co-simulated (posed by MuJoCo's own xpos /
  xmat) with a person in front of it. The documented bound: never below the truth, at most
  spacing / sqrt(3) above.
- robot_speed (the closest point's speed towards the person) against central differences of the distance;
  approach_speed (the fastest approach of any robot point) for a bar sliding past a sphere, in closed form.
- Bad inputs named by field: a scene that is not a Scene, the person as the robot, a robot without geometry,
  unknown object names.
"""

import math

import numpy as np
import pytest
import trimesh

from twinsense.errors import ConfigError
from twinsense.safety import SeparationMonitor, SeparationParameters, protective_separation_distance
from twinsense.scene import Box, JointConstantVelocity, JointKeyframes, Pose, Scene, Sphere
from twinsense.scene.articulated import ArticulatedBody, Joint, KinematicTree, Link
from twinsense.scene.human import Reach, add_person

mujoco = pytest.importorskip("mujoco")
yourdfpy = pytest.importorskip("yourdfpy")

from twinsense.robots import MujocoCosim, load_robot, robot_path  # noqa: E402

SPACING = 0.02
BOUND = SPACING / math.sqrt(3.0)  # a triangle point is at most edge / sqrt(3) from its nearest vertex


# ---- the exact reference ---------------------------------------------------------------------------------

def _seg_seg(p1, q1, p2, q2):
    """Distances (n,) between segments p1-q1 and p2-q2 (each (n, 3), non-degenerate): Ericson, Real-Time
    Collision Detection, 5.1.9 (the clamped closest parameters of the two lines)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e = np.einsum("ij,ij->i", d1, d1), np.einsum("ij,ij->i", d2, d2)
    b, c, f = np.einsum("ij,ij->i", d1, d2), np.einsum("ij,ij->i", d1, r), np.einsum("ij,ij->i", d2, r)
    den = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(den > 1e-14 * a * e, np.clip((b * f - c * e) / den, 0.0, 1.0), 0.0)
        t = (b * s + f) / e
        s = np.where(t < 0, np.clip(-c / a, 0, 1), np.where(t > 1, np.clip((b - c) / a, 0, 1), s))
        t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(p1 + s[:, None] * d1 - p2 - t[:, None] * d2, axis=1)


def _point_seg(p, a, b):
    ab = b - a
    s = np.clip((p - a) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
    return np.linalg.norm(p - (a + s[:, None] * ab), axis=1)


def _prim(geometry, pose):
    """('capsule', (a, b, radius)) or ('box', (pose, size)) of a person's segment in the world."""
    if isinstance(geometry, Box):
        return "box", (pose, np.asarray(geometry.size, dtype=float))
    h = 0.0 if isinstance(geometry, Sphere) else 0.5 * geometry.height
    a, b = pose.apply(np.array([[0.0, 0.0, -h], [0.0, 0.0, h]]))
    return "capsule", (a, b, geometry.radius)


def _vertex_distances(v, kind, data):
    if kind == "capsule":
        a, b, r = data
        return _point_seg(v, a, b) - r
    pose, size = data
    return np.linalg.norm(np.maximum(np.abs((v - pose.position) @ pose.rotation) - 0.5 * size, 0.0), axis=1)


def _mesh_prim(mesh, kind, data, best):
    """Exact distance from a world mesh to a disjoint capsule or box, if below ``best`` (else ``best``).

    Two disjoint convex sets (a triangle, a box or a capsule's axis) are closest at a vertex of one and a
    point of the other, or at two edges: the mesh's vertices to the primitive, the primitive's end points or
    corners to the mesh (trimesh's closest points), the mesh's edges to the axis or the box's 12 edges.
    Edges are skipped when both ends are farther than best + their length (1-Lipschitz)."""
    v = np.asarray(mesh.vertices)
    edges = np.asarray(mesh.edges_unique)
    dv = _vertex_distances(v, kind, data)
    length = np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1)
    if dv.min() - length.max() >= best:
        return best
    if kind == "capsule":
        a, b, _ = data
        ends, pairs = np.array([a, b]), [(a, b)]
    else:
        pose, size = data
        corner = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * 0.5 * size
        ends = pose.apply(corner)
        pairs = [(ends[i], ends[j]) for i in range(8) for j in range(i + 1, 8)
                 if np.sum(corner[i] != corner[j]) == 1]
    off = 0.0 if kind == "box" else data[2]
    _, de, _ = trimesh.proximity.closest_point(mesh, ends)
    best = min(best, float(dv.min()), float(de.min()) - off)
    near = np.flatnonzero(np.minimum(dv[edges[:, 0]], dv[edges[:, 1]]) - length < best)
    for p, q in pairs:
        if len(near) and not np.allclose(p, q):
            n = len(near)
            dd = _seg_seg(v[edges[near, 0]], v[edges[near, 1]], np.tile(p, (n, 1)), np.tile(q, (n, 1)))
            best = min(best, float(dd.min()) - off)
    return best


def _exact(world_meshes, person, t):
    """The exact distance between the posed robot meshes [(name, mesh)] and the person's segments at t."""
    st = person.state(t)
    prims = [_prim(lk.geometry, st.pose(i) @ lk.origin) for i, lk in enumerate(person.tree.links)
             if lk.geometry is not None]
    best = math.inf
    for _, mesh in world_meshes:
        for kind, data in prims:
            best = _mesh_prim(mesh, kind, data, best)
    return best


def test_reference_segment_distance_against_brute_force():
    # The segment-segment formula against a dense sampling of both segments (2001 x 2001 points: the true
    # minimum is at most (L1 + L2) / 2000 / 2 below the sampled one, < 1 mm for these unit-size segments).
    rng = np.random.default_rng(5)
    p1, q1, p2, q2 = rng.uniform(-1, 1, (4, 6, 3))
    got = _seg_seg(p1, q1, p2, q2)
    s = np.linspace(0, 1, 2001)
    for k in range(6):
        x = p1[k] + s[:, None] * (q1[k] - p1[k])
        y = p2[k] + s[:, None] * (q2[k] - p2[k])
        brute = np.min(np.linalg.norm(x[:, None] - y[None], axis=2))
        assert got[k] <= brute + 1e-12
        assert got[k] >= brute - (np.linalg.norm(q1[k] - p1[k]) + np.linalg.norm(q2[k] - p2[k])) / 4000


# ---- a Panda (URDF) posed by yourdfpy ------------------------------------------------------------------

def test_panda_separation_against_exact_mesh_distances():
    robot = load_robot("panda")
    tree = robot.tree
    q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8, 0.02])
    q1 = np.array([0.9, 0.4, -0.3, -1.6, 0.5, 1.6, 0.0, 0.04])
    robot.joint_motion = JointKeyframes([0.0, 1.0], np.array([q0, q1]), joint_names=tree.joint_names)
    scene = Scene()
    robot.add_to(scene)
    # A 1.65 m person 0.7 m in front, facing the robot, reaching past link 6 with the right hand (11-24 cm).
    person = add_person(scene, "worker", 1.65, (0.7, -0.15), 180.0,
                        reach=Reach((0.45, -0.05, 0.85), 0.0, 0.8, 5.0))
    monitor = SeparationMonitor(scene, robot.name, "worker", spacing=SPACING)
    urdf = yourdfpy.URDF.load(str(robot_path("panda")), load_meshes=False, build_collision_scene_graph=False,
                              load_collision_meshes=False)
    for t in (0.0, 0.5, 1.0):
        q, _ = robot.joint_state(t)
        urdf.update_cfg(dict(zip(tree.joint_names, q)))
        meshes = []
        for lk in tree.links:
            g = lk.link_frame_geometry()
            if g is not None:
                m = g.mesh.copy()
                m.apply_transform(urdf.get_transform(lk.name, urdf.base_link))
                meshes.append((lk.name, m))
        true = _exact(meshes, person, t)
        s = monitor.at(t)
        assert true > 0.02  # disjoint, as the reference needs
        # Never below the truth (rounding: 1e-9 m), at most spacing / sqrt(3) above.
        assert true - 1e-9 <= s.distance <= true + BOUND, (t, s.distance, true)


# ---- MuJoCo's Panda, co-simulated ----------------------------------------------------------------------

@pytest.fixture(scope="module")
def cosim_cell():
    cosim = MujocoCosim(robot_path("panda-mjcf"))
    parts = [o.name for o in cosim.scene.objects if o.name != "world"]
    person = add_person(cosim.scene, "p", 1.7, (0.7, 0.0), 180.0)
    return cosim, parts, person


def test_monitor_in_a_mujoco_cosim_scene(cosim_cell):
    # MujocoCosim's objects carry the MuJoCo body index as ``motion.body``: the monitor's look-up of the
    # articulated bodies raised AttributeError ('int' object has no attribute 'name') for any scene holding
    # them, and a co-simulated robot could not be monitored. Now its bodies are given by name; the
    # reference poses the same meshes by MuJoCo's own xpos / xmat (after mj_kinematics: after mj_step
    # they are one step stale) while the arm, uncontrolled, sags under gravity.
    cosim, parts, person = cosim_cell
    monitor = SeparationMonitor(cosim.scene, parts, "p", spacing=SPACING)
    for t in (0.0, 0.4):
        s = monitor.at(t)
        cosim.step_to(t)
        mujoco.mj_kinematics(cosim.model, cosim.data)
        meshes = []
        for name in parts:
            b = mujoco.mj_name2id(cosim.model, mujoco.mjtObj.mjOBJ_BODY, name)
            m = cosim.scene.object(name).geometry.mesh.copy()
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = cosim.data.xmat[b].reshape(3, 3), cosim.data.xpos[b]
            m.apply_transform(T)
            meshes.append((name, m))
        true = _exact(meshes, person, t)
        assert true > 0.02
        assert true - 1e-9 <= s.distance <= true + BOUND, (t, s.distance, true)
        assert s.robot_link in parts and s.human_link.startswith("p/")
        assert s.approach_speed >= s.robot_speed >= 0.0


def test_articulated_robot_beside_a_mujoco_cosim(cosim_cell):
    # The crash case itself: a URDF robot and a person in a scene that also holds co-simulated bodies.
    cosim, _, _ = cosim_cell
    scene = Scene()
    for o in cosim.scene.objects:
        scene.add(o)
    load_robot("ur10", base=Pose((0.0, -1.5, 0.0))).add_to(scene)
    monitor = SeparationMonitor(scene, "ur10", "p", spacing=0.05)
    assert monitor.at(0.0).robot_link.startswith("ur10/")


def test_robot_speed_is_minus_the_distance_rate(cosim_cell):
    # For a still person, the closest robot point's speed towards the person is -d(distance)/dt. Between
    # two physics steps the co-simulation moves each body on by its step's velocities (positions linear in
    # t), so a central difference over +-h inside one step (2 ms) differs from the derivative only where
    # the nearest vertex or body point changes (not at these times) and by rounding: 1e-9 m / h = 1e-5 m/s.
    cosim, parts, _ = cosim_cell
    monitor = SeparationMonitor(cosim.scene, parts, "p", spacing=SPACING)
    dt = cosim.model.opt.timestep
    h = dt / 8
    for t in (0.2 + dt / 2, 0.3 + dt / 2):
        s = monitor.at(t)
        rate = (monitor.at(t + h).distance - monitor.at(t - h).distance) / (2 * h)
        assert s.robot_speed > 0.05  # the arm falls towards the person: a real test of the rate
        assert s.robot_speed == pytest.approx(-rate, rel=0, abs=1e-9 / h)


# ---- bad inputs ----------------------------------------------------------------------------------------

def _frames_only(name):
    return ArticulatedBody(name, KinematicTree(name, [Link("base"), Link("tip")], [Joint("j", "fixed", "base", "tip")]))


@pytest.mark.parametrize("make, message", [
    (lambda sc, names: SeparationMonitor(None, "ur10", "p"), r"scene = None.*a twinsense Scene"),
    (lambda sc, names: SeparationMonitor(sc, "p", "p"), r"robot = 'p'.*another body than the person"),
    (lambda sc, names: SeparationMonitor(sc, "bare", "p"), r"robot = 'bare'.*link geometry.*frames only"),
    (lambda sc, names: SeparationMonitor(sc, [names[0], "elbow"], "p"), r"robot\[1\] = 'elbow'.*a scene object"),
    (lambda sc, names: SeparationMonitor(sc, [names[0], "p/head"], "p"),
     r"robot\[1\] = 'p/head'.*not a part of the person"),
    (lambda sc, names: SeparationMonitor(sc, [], "p"), r"robot = \[\].*non-empty list"),
    (lambda sc, names: SeparationMonitor(sc, 7, "p"), r"robot = 7.*name or a list"),
    (lambda sc, names: SeparationMonitor(sc, names, "nobody"), r"person = 'nobody'.*bare|person = 'nobody'.*: p"),
])
def test_bad_inputs_are_named(cosim_cell, make, message):
    cosim, parts, _ = cosim_cell
    scene = Scene()
    for o in cosim.scene.objects:
        scene.add(o)
    _frames_only("bare").add_to(scene)
    with pytest.raises(ConfigError, match=message):
        make(scene, parts)


# ---- approach_speed in closed form ---------------------------------------------------------------------

def test_approach_speed_of_a_bar_sliding_past_a_sphere():
    # A bar along y (2L x 2w x 2w, L = 0.4 m, w = 0.02 m) slides along its own axis (+y) at v = 0.8 m/s past
    # a still sphere (radius 0.1 m) centred at (D, 0, 0), D = 0.3 m. The bar's face x = w is g = D - w from
    # the centre. Its point (w, y, 0) moves at (0, v, 0); the line to the sphere's nearest point runs along
    # (g, -y, 0), so its speed towards the person is f(y) = -v y / sqrt(g^2 + y^2): 0 at the closest point
    # (y = 0) and largest at the trailing end y = -L: v L / sqrt(g^2 + L^2) = 0.8 * 0.4 / 0.5 = 0.64 m/s
    # (points off z = 0, or on the other faces, are farther off the line and slower).
    L, w, v, D, R = 0.4, 0.02, 0.8, 0.3, 0.1
    g = D - w
    links = [Link("base"), Link("bar", Box((2 * w, 2 * L, 2 * w)))]
    joints = [Joint("slide", "prismatic", "base", "bar", axis=(0.0, 1.0, 0.0), lower=-5.0, upper=5.0)]
    scene = Scene()
    scene.add_articulated(ArticulatedBody("robot", KinematicTree("robot", links, joints),
                                          JointConstantVelocity([0.0], [v])))
    person = [Link("base"), Link("ball", Sphere(R))]
    scene.add_articulated(ArticulatedBody("person", KinematicTree("person", person,
                                                                  [Joint("j", "fixed", "base", "ball")]),
                                          None, Pose((D, 0.0, 0.0))))
    s = SeparationMonitor(scene, "robot", "person", spacing=0.01).at(0.0)
    # The bar's corners and edge midpoints are subdivided vertices (the trailing edge's point at z = 0
    # among them), so the sampled maximum is the closed form to rounding; the closest vertex is (w, 0, 0),
    # moving square to the line: 0. Distance: g - R on the face.
    assert s.approach_speed == pytest.approx(v * L / math.hypot(g, L), rel=0, abs=1e-9)
    assert s.robot_speed == pytest.approx(0.0, rel=0, abs=1e-12)
    assert s.distance == pytest.approx(g - R, rel=0, abs=1e-12)


@pytest.mark.parametrize("speed", [True, [True, False], "0.5", [0.1, [0.2]], 0.5j])
def test_protective_distance_refuses_non_numeric_speeds(speed):
    # A bool was read as 1 m/s (S_p 1.15 m for True); text, ragged lists and complex numbers are not speeds.
    with pytest.raises(ConfigError, match=r"robot_speed = .*finite speeds >= 0 m/s"):
        protective_separation_distance(speed)


def test_protective_distance_takes_integers_and_arrays():
    # The hand-worked S_p = 0.9 + 0.25 v_r [m] (defaults: 1.6 * 0.4 + 0.26; v_r (0.1 + 0.3 / 2)), for
    # integer and 2-D input alike: sums of a few decimals, 1e-12 m.
    np.testing.assert_allclose(protective_separation_distance(np.array([[0, 1], [2, 3]])),
                               0.9 + 0.25 * np.array([[0, 1], [2, 3]]), rtol=0, atol=1e-12)
    assert protective_separation_distance(1) == pytest.approx(1.15, rel=0, abs=1e-12)


def test_protective_distance_with_the_robot_speeding_up_during_its_reaction():
    # ISO/TS 15066: with the robot's current speed, S_p must allow for its acceleration capability during
    # T_r. At a = 2 m/s^2, v_r = 0.5 m/s, the defaults (v_h 1.6 m/s, T_r 0.1 s, T_s 0.3 s, C + Z_d + Z_r
    # 0.26 m): S_h = 0.64; S_r = 0.5 * 0.1 + 2 * 0.1^2 / 2 = 0.06; the stop starts from 0.5 + 2 * 0.1 =
    # 0.7 m/s: S_s = 0.7 * 0.3 / 2 = 0.105 -> S_p = 1.065 m (1.025 m at a = 0). A measured S_s of 0.1 m
    # replaces the 0.105: 1.06 m. Sums of a few decimals: 1e-12 m.
    p = SeparationParameters(robot_acceleration=2.0)
    assert protective_separation_distance(0.5, p) == pytest.approx(1.065, rel=0, abs=1e-12)
    assert protective_separation_distance(0.5) == pytest.approx(1.025, rel=0, abs=1e-12)
    p = SeparationParameters(robot_acceleration=2.0, stopping_distance=0.1)
    assert protective_separation_distance(0.5, p) == pytest.approx(1.06, rel=0, abs=1e-12)
    for bad in (-1.0, float("nan"), "2"):
        with pytest.raises(ConfigError, match=r"robot_acceleration = .*>= 0 \[m/s\^2\]"):
            SeparationParameters(robot_acceleration=bad)
