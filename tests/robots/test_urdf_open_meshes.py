"""URDF links of several parts, some of them open display shells, checked from outside: a point is inside the
link only where it is inside one of its parts (primitives by their closed forms, closed meshes by trimesh's own
inside test, open shells by the convex hull of the shells they touch), never in the air between parts."""

import pickle
import xml.etree.ElementTree as ET

import numpy as np
import trimesh
from scipy.spatial import ConvexHull, Delaunay

import twinsense as ts
from twinsense.robots import load_urdf
from twinsense.robots.urdf import urdf_tree
from twinsense.scene.pose import Pose


def _open_box(path, extents) -> None:
    """An STL box of ``extents`` [m] about its centre with its first face (two triangles) removed: a display
    shell that is not watertight, and whose convex hull is the box."""
    box = trimesh.creation.box(extents=extents)
    shell = trimesh.Trimesh(box.vertices, box.faces[2:], process=False)
    assert not shell.is_watertight
    shell.export(path)


def _closed_box(path, extents) -> None:
    trimesh.creation.box(extents=extents).export(path)


def _urdf(tmp_path, visuals: str, name: str = "cell.urdf"):
    """A one-link robot whose link "shell" has the given visual elements."""
    path = tmp_path / name
    path.write_text(f'<robot name="r"><link name="shell">{visuals}</link></robot>')
    return path


def _mesh(filename: str, xyz=(0, 0, 0), rpy=(0, 0, 0)) -> str:
    return (f'<visual><origin xyz="{" ".join(map(str, xyz))}" rpy="{" ".join(map(str, rpy))}"/>'
            f'<geometry><mesh filename="{filename}"/></geometry></visual>')


def _in_box(p, centre, half) -> np.ndarray:
    return np.all(np.abs(p - centre) <= half, axis=1)


# Two open boxes 0.1 m wide, 0.2 m apart (centres at x = -+0.15): the whole link's hull filled the 0.2 m gap.
HALF = np.array([0.05, 0.08, 0.06])
CENTRES = np.array([[-0.15, 0.0, 0.0], [0.15, 0.0, 0.0]])


def test_two_separate_open_boxes_are_not_inside_between_them(tmp_path):
    # Reference: the closed forms of the two boxes (an open box's hull is the box). Before, the link's
    # inside test was the hull of both: the slab |x| < 0.1 between them was inside (e.g. the origin).
    # Exact: random points lie within rounding (1e-12 m of the 1e-12 hull margin) of a face with
    # probability ~1e-7 here.
    _open_box(tmp_path / "open.stl", 2 * HALF)
    tree = urdf_tree(_urdf(tmp_path, _mesh("open.stl", CENTRES[0]) + _mesh("open.stl", CENTRES[1])))
    geom = tree.link("shell").geometry
    p = np.random.default_rng(3).uniform([-0.25, -0.1, -0.08], [0.25, 0.1, 0.08], (20000, 3))
    truth = _in_box(p, CENTRES[0], HALF) | _in_box(p, CENTRES[1], HALF)
    between = np.abs(p[:, 0]) < 0.1
    assert truth.sum() > 1000 and between.sum() > 1000
    np.testing.assert_array_equal(geom.contains(p), truth)
    assert not geom.contains([[0.0, 0.0, 0.0]])[0]
    # A scene is copied by pickle (capture processes): the copy keeps the parts' test.
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(geom)).contains(p), truth)


def test_open_shell_beside_a_closed_concave_part_keeps_its_winding_number(tmp_path):
    # A closed torus (concave: its hole is air) and an open box beside it in one link. Before, the open box
    # made the whole link "open" and its hull filled the torus' hole and the air to the box. Reference:
    # trimesh's contains (ray parity) on the torus itself, and the box's closed form; points are kept 1e-6 m
    # away from the torus' surface (trimesh's signed distance), where the two inside tests could differ by
    # rounding only.
    torus = trimesh.creation.torus(major_radius=0.1, minor_radius=0.03, major_sections=48, minor_sections=24)
    assert torus.is_watertight
    torus.export(tmp_path / "torus.stl")
    _open_box(tmp_path / "open.stl", 2 * HALF)
    tree = urdf_tree(_urdf(tmp_path, _mesh("torus.stl") + _mesh("open.stl", (0.3, 0, 0))))
    geom = tree.link("shell").geometry
    rng = np.random.default_rng(5)
    p = rng.uniform([-0.15, -0.15, -0.05], [0.4, 0.15, 0.05], (6000, 3))
    far = np.abs(trimesh.proximity.signed_distance(torus, p)) > 1e-6
    p = p[far]
    truth = np.asarray(torus.contains(p), bool) | _in_box(p, [0.3, 0, 0], HALF)
    hole = np.linalg.norm(p[:, :2], axis=1) < 0.06
    assert hole.sum() > 100 and truth.sum() > 500
    np.testing.assert_array_equal(geom.contains(p), truth)


def test_link_of_primitives_is_inside_exactly_where_a_primitive_is(tmp_path):
    # A box, a turned cylinder and a sphere: the link's inside test is theirs, exactly, not that of their
    # tessellation (a 32-sided cylinder's chords lie up to r (1 - cos(pi / 32)) = 0.0048 r inside the true
    # surface; an icosphere's triangles similarly). Reference: the closed forms, at points 0.2 % of each size
    # in or out of its surface, and random points. Exact: none of them lies within rounding of a surface.
    urdf = _urdf(tmp_path, """
      <visual><origin xyz="0 0 0"/><geometry><box size="0.2 0.1 0.06"/></geometry></visual>
      <visual><origin xyz="0.3 0 0" rpy="1.5707963267948966 0 0"/>
        <geometry><cylinder radius="0.05" length="0.2"/></geometry></visual>
      <visual><origin xyz="-0.3 0.05 0"/><geometry><sphere radius="0.07"/></geometry></visual>""")
    geom = urdf_tree(urdf).link("shell").geometry
    rng = np.random.default_rng(9)

    def truth(p):
        box = _in_box(p, [0, 0, 0], [0.1, 0.05, 0.03])
        # The cylinder's axis is the link's y after rpy = (pi/2, 0, 0); its length 0.2 m along it.
        q = p - [0.3, 0, 0]
        cyl = (np.hypot(q[:, 0], q[:, 2]) <= 0.05) & (np.abs(q[:, 1]) <= 0.1)
        sph = np.linalg.norm(p - [-0.3, 0.05, 0], axis=1) <= 0.07
        return box | cyl | sph

    u = rng.normal(size=(3000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    s = rng.choice([0.998, 1.002], (3000, 1))
    near_sphere = [-0.3, 0.05, 0] + 0.07 * s * u
    a = rng.uniform(0, 2 * np.pi, 3000)
    near_cyl = np.c_[0.3 + 0.05 * s[:, 0] * np.cos(a), rng.uniform(-0.099, 0.099, 3000), 0.05 * s[:, 0] * np.sin(a)]
    p = np.vstack([near_sphere, near_cyl, rng.uniform([-0.4, -0.15, -0.1], [0.4, 0.15, 0.1], (10000, 3))])
    np.testing.assert_array_equal(geom.contains(p), truth(p))


def test_kinova_hand_and_its_ring_are_inside_only_where_one_of_them_is(tmp_path):
    # example-robot-data's Kinova Jaco 2 (j2s6s200): link 6's visual is an open hand shell (hand_2finger.dae,
    # not watertight) and a closed ring (ring_small.dae). Before, the link was the hull of both. Reference:
    # the ring by trimesh's contains (ray parity) on the ring's own mesh, the hand by scipy's Delaunay
    # tessellation of the hand's hull vertices (find_simplex), each posed by the URDF's <origin> through
    # yourdfpy's own transforms; points are kept 1e-6 m off the ring's surface (its signed distance).
    import yourdfpy

    from twinsense.robots.descriptions import resolve

    path = resolve("kinova", "urdf")
    link = "j2s6s200_link_6"
    robot = yourdfpy.URDF.load(str(path), build_scene_graph=False, build_collision_scene_graph=False,
                               load_meshes=False, load_collision_meshes=False)
    parts = {}
    for v in robot.link_map[link].visuals:
        f = v.geometry.mesh.filename
        assert f.startswith("package://example-robot-data/")  # the package's share folder, 3 above the URDF's
        mesh = trimesh.load(path.parents[3] / f[len("package://example-robot-data/"):], force="mesh")
        mesh.merge_vertices()  # a COLLADA file's triangles come unshared: the ring closes once merged
        mesh.apply_transform(np.eye(4) if v.origin is None else v.origin)
        parts[f.rsplit("/", 1)[1]] = mesh
    hand, ring = parts["hand_2finger.dae"], parts["ring_small.dae"]
    assert not hand.is_watertight and ring.is_watertight
    # The link alone (its package:// meshes resolve from anywhere): the arm's other meshes take seconds to read.
    element = ET.tostring(next(lk for lk in ET.parse(path).getroot().iter("link") if lk.get("name") == link))
    (tmp_path / "link6.urdf").write_bytes(b'<robot name="k">' + element + b"</robot>")
    geom = urdf_tree(tmp_path / "link6.urdf").link(link).geometry
    hand_hull = Delaunay(hand.vertices[ConvexHull(hand.vertices).vertices])
    rng = np.random.default_rng(2)
    lo, hi = geom.bounds
    p = rng.uniform(lo, hi, (12000, 3))
    near = np.all((p >= ring.bounds[0] - 1e-5) & (p <= ring.bounds[1] + 1e-5), axis=1)  # others are far off it
    near[near] = np.abs(trimesh.proximity.signed_distance(ring, p[near])) <= 1e-6
    p = p[~near]
    truth = (hand_hull.find_simplex(p) >= 0) | np.asarray(ring.contains(p), bool)
    whole = Delaunay(np.vstack([hand.vertices, ring.vertices])[ConvexHull(np.vstack([hand.vertices,
                                                                                     ring.vertices])).vertices])
    between = (whole.find_simplex(p) >= 0) & ~truth  # inside the whole link's hull, in no part
    assert between.sum() > 300, between.sum()
    np.testing.assert_array_equal(geom.contains(p), truth)


def _pad_channels(urdf_path) -> tuple:
    """The pad-grid's channels [F] under a link "shell" whose boxes (half height 2 cm) sit 2 cm above the pad
    (the pad faces +z)."""
    scene = ts.Scene()
    scene.add_articulated(load_urdf(urdf_path, base=Pose((0.0, 0.0, 0.04))))  # the boxes' centres at 4 cm
    cap = ts.CapacitiveSensor.preset("pad-grid", name="cap", mount=ts.Mount(Pose()))
    return cap, cap.capture(scene, 0.0, np.random.default_rng(0)).channels


def test_capacitive_pad_under_the_gap_reads_as_with_closed_parts(tmp_path):
    # A proximity pad (pad-grid: 3 x 2 pads over x, y in +-0.06, +-0.045 m) 2 cm under a link of two
    # separated boxes (0.04 m wide, their inner faces 6 cm apart over the pad's middle). With open
    # shells the link was the hull of both: a slab of metal over the middle pads. The reference is the
    # same link made of the same two boxes closed (their inside test exact): the channels must agree
    # within the frame solver's contract, each capacitance within capacitance_atol of a direct solve, so
    # two solves within twice that.
    half = np.array([0.02, 0.06, 0.02])
    xs = (-0.05, 0.05)
    _open_box(tmp_path / "open.stl", 2 * half)
    _closed_box(tmp_path / "closed.stl", 2 * half)
    both = "".join(_mesh("open.stl", (x, 0, 0)) for x in xs)
    closed = "".join(_mesh("closed.stl", (x, 0, 0)) for x in xs)
    cap, opened = _pad_channels(_urdf(tmp_path, both, "open.urdf"))
    _, ref = _pad_channels(_urdf(tmp_path, closed, "closed.urdf"))
    np.testing.assert_allclose(opened, ref, rtol=0, atol=2 * cap.frame_solver_config.capacitance_atol)


def _l_halves():
    """A closed L-shaped prism (the square 0.2 m x 0.2 m less its 0.15 m x 0.15 m corner x, y > 0.05, 0.06 m
    high) cut into two open shells along x = 0.1 (faces by their centroid): each alone is open, the two
    close together, sharing the cut's vertices."""
    from shapely.geometry import Polygon

    prism = trimesh.creation.extrude_polygon(
        Polygon([(0, 0), (0.2, 0), (0.2, 0.05), (0.05, 0.05), (0.05, 0.2), (0, 0.2)]), 0.06)
    assert prism.is_watertight
    left = prism.triangles_center[:, 0] < 0.1
    halves = [trimesh.Trimesh(prism.vertices, prism.faces[k], process=False) for k in (left, ~left)]
    assert not any(h.is_watertight for h in halves)
    return halves


def _in_l(p) -> np.ndarray:
    return (_in_box(p, [0.1, 0.025, 0.03], [0.1, 0.025, 0.03]) | _in_box(p, [0.025, 0.1, 0.03], [0.025, 0.1, 0.03]))


def test_open_shells_that_close_together_keep_the_concave_corner_outside(tmp_path):
    # Display shells that close only together (a cover in two halves): their common hull would fill the
    # L's missing corner (0.15 m x 0.15 m of air); together they are a closed mesh, tested by its winding
    # number. Reference: the L's closed form. Exact, as above. The same rule for MuJoCo bodies.
    import mujoco

    from twinsense.robots import MujocoCosim

    halves = _l_halves()
    for k, h in enumerate(halves):
        h.export(tmp_path / f"half{k}.stl")
    geom = urdf_tree(_urdf(tmp_path, _mesh("half0.stl") + _mesh("half1.stl"))).link("shell").geometry
    p = np.random.default_rng(4).uniform([-0.02, -0.02, -0.01], [0.22, 0.22, 0.07], (20000, 3))
    truth = _in_l(p)
    corner = np.all(p[:, :2] > 0.06, axis=1) & (np.abs(p[:, 2] - 0.03) < 0.03)  # in the hull, not the L
    assert corner.sum() > 3000 and truth.sum() > 3000
    np.testing.assert_array_equal(geom.contains(p), truth)
    meshes = "".join(f'<mesh name="h{k}" vertex="{" ".join(f"{x:.17g}" for x in h.vertices.ravel())}" '
                     f'face="{" ".join(map(str, h.faces.ravel()))}"/>' for k, h in enumerate(halves))
    xml = (f'<mujoco><asset>{meshes}</asset><worldbody><body name="b"><freejoint/><geom type="mesh" mesh="h0"/>'
           '<geom type="mesh" mesh="h1"/></body></worldbody></mujoco>')
    body = MujocoCosim(mujoco.MjModel.from_xml_string(xml)).scene.object("b").geometry
    np.testing.assert_array_equal(body.contains(p), truth)
