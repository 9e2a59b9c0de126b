"""URDF robots checked from outside: meshes against trimesh's own load and COLLADA units and corners against
pycollada, kinematics against a URDF reader written here from the XML and scipy's rotations, bad files (and a
xacro include, a link material) through the loader and a scenario file, and the named human's axes.

The references share no code with the loader's path through yourdfpy: the mesh reference reads each file with
trimesh, applies the declared ``scale`` and ``<origin>`` as one 4 x 4 matrix (``Trimesh.apply_transform``,
which also reverses the triangles of a mirroring transform), and a COLLADA file's unit through pycollada; the
kinematics reference parses ``<origin>``, ``<axis>`` and ``<mimic>`` from the XML text and composes scipy's
``Rotation.from_euler("xyz", rpy)`` (URDF's fixed-axis roll, pitch, yaw) and ``Rotation.from_rotvec``.
"""

import math
import re
import warnings
import xml.etree.ElementTree as ET

import collada
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from twinsense.errors import ConfigError
from twinsense.robots import load_robot, load_urdf
from twinsense.robots.meshes import read_mesh
from twinsense.robots.paths import example_robot_data_share
from twinsense.robots.urdf import urdf_tree
from twinsense.scenario import ScenarioError, scenario_from_dict
from twinsense.scene import Pose

SHARE = example_robot_data_share()
ROBOTS = SHARE / "robots"
EPS = np.finfo(float).eps


# ---------------------------------------------------------------------------------------------------------------
# Meshes: units, scale (mirroring ones too) and origin against trimesh's own load of the same file
# ---------------------------------------------------------------------------------------------------------------

def _origin_matrix(el) -> np.ndarray:
    """The 4 x 4 of an ``<origin>`` element (identity if None), from the XML text and scipy."""
    m = np.eye(4)
    if el is not None:
        m[:3, :3] = Rotation.from_euler("xyz", np.array(el.get("rpy", "0 0 0").split(), float)).as_matrix()
        m[:3, 3] = np.array(el.get("xyz", "0 0 0").split(), float)
    return m


def _reference_link_mesh(urdf, link, source):
    """(vertices, faces) of a link's mesh elements read by trimesh with scale, unit and origin applied, in the
    file's order (the loader merges them in that order); None if the link has a primitive shape or no shape."""
    parts = []
    for el in link.findall(source):
        mesh = el.find("geometry").find("mesh")
        if mesh is None:
            return None
        name = mesh.get("filename")
        assert name.startswith("package://example-robot-data/"), name
        path = SHARE / name[len("package://example-robot-data/"):]
        tm = trimesh.load(str(path), force="mesh", process=False)
        scale = np.broadcast_to(np.array(mesh.get("scale", "1").split(), float), (3,))
        if path.suffix.lower() == ".dae":
            scale = scale * (collada.Collada(str(path), ignore=[collada.common.DaeUnsupportedError,
                                                                collada.common.DaeBrokenRefError])
                             .assetInfo.unitmeter or 1.0)
        tm.apply_transform(_origin_matrix(el.find("origin")) @ np.diag([*scale, 1.0]))
        parts.append(tm)
    if not parts:
        return None
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts])
    return (np.vstack([p.vertices for p in parts]),
            np.vstack([p.faces + o for p, o in zip(parts, offsets[:-1], strict=True)]))


# DAE, OBJ, STL in mm scaled by 0.001, mirrored STL ("1 -1 1", "0.001 -0.001 0.001", "1 1 -1", "-1 -1 -1"),
# several meshes per link, ~4 s on the shared test machine. (The 2,318 mesh elements of every link drawn by meshes
# only in the 67 loadable files, visual and collision, agree the same way: <= 1.4e-16 of the largest coordinate.)
MESH_CASES = [
    ("ur_description/urdf/ur10_robot.urdf", "visual"),
    ("laikago_description/urdf/laikago.urdf", "visual"),  # OBJ
    ("so_arm_description/urdf/so101.urdf", "visual"),
    ("talos_data/robots/talos_reduced.urdf", "collision"),
    ("centauro_description/urdf/centauro.urdf", "visual"),
    ("tiago_description/robots/tiago_dual.urdf", "collision"),
]


@pytest.mark.parametrize(("rel", "source"), MESH_CASES)
def test_link_meshes_equal_trimesh_with_the_declared_scale_and_origin(rel, source):
    tree = urdf_tree(ROBOTS / rel, shapes=source)
    root = ET.parse(ROBOTS / rel).getroot()
    checked = mirrored = 0
    for link in root.findall("link"):
        ref = _reference_link_mesh(root, link, source)
        if ref is None:
            continue
        geom = tree.links[tree.link_names.index(link.get("name"))].geometry
        # R (s * v) + t against (T @ S) v: each coordinate is a 3-term dot product on either side, ~3 roundings of
        # the largest coordinate each; 16 eps of max(1 m, |coordinate|) covers them (seen: <= 1 eps).
        extent = max(1.0, float(np.abs(ref[0]).max()))
        np.testing.assert_allclose(geom.vertices, ref[0], rtol=0, atol=16 * EPS * extent)
        # trimesh reverses the corners of a mirrored part: the triangles face out in both, corner for corner.
        np.testing.assert_array_equal(geom.faces, ref[1])
        checked += 1
        mirrored += any(np.prod(np.array(m.get("scale", "1").split(), float)) < 0
                        for el in link.findall(source) for m in el.iter("mesh"))
    assert checked >= 5
    if "talos" in rel or "centauro" in rel or "tiago" in rel:
        assert mirrored >= 5, mirrored


def test_a_mirrored_closed_part_stays_a_volume_facing_out(tmp_path):
    # A closed, asymmetric part (a tetrahedron off its origin) drawn mirrored and squashed: scale "0.5 -2 1".
    v = np.array([[0.1, 0.0, 0.0], [0.3, 0.0, 0.0], [0.1, 0.2, 0.0], [0.1, 0.0, 0.4]])
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    part = trimesh.Trimesh(v, f, process=False)
    assert part.is_volume and part.volume > 0  # outward as written
    part.export(tmp_path / "tet.stl")
    (tmp_path / "m.urdf").write_text(
        '<robot name="m"><link name="a"><collision><origin xyz="0.1 -0.2 0.3" rpy="0.3 -0.2 0.1"/>'
        '<geometry><mesh filename="tet.stl" scale="0.5 -2 1"/></geometry></collision></link></robot>')
    geom = load_urdf(tmp_path / "m.urdf", shapes="collision").tree.links[0].geometry
    ref = trimesh.load(tmp_path / "tet.stl", process=False)
    origin = ET.fromstring('<origin xyz="0.1 -0.2 0.3" rpy="0.3 -0.2 0.1"/>')
    ref.apply_transform(_origin_matrix(origin) @ np.diag([0.5, -2.0, 1.0, 1.0]))
    # Coordinates < 1 m, a 3-term dot product per coordinate on either side: 16 eps as above.
    np.testing.assert_allclose(geom.vertices, ref.vertices, rtol=0, atol=16 * EPS)
    np.testing.assert_array_equal(geom.faces, ref.faces)
    # Closed form: |det S| = 0.5 * 2 * 1 = 1, so the volume is the tetrahedron's as the STL stores it (float32
    # corners), det[b - a, c - a, d - a] / 6, and positive (the loader's mesh was inside out before: volume -V,
    # so no volume to the soft-iron bodies). Either side sums triple products of coordinates < 1 m: 1e-15 m^3
    # is ~100 roundings of the 2.7e-3 m^3.
    v32 = v.astype(np.float32).astype(float)
    exact = np.linalg.det(v32[1:] - v32[0]) / 6.0
    assert geom.mesh.is_volume
    assert geom.mesh.volume == pytest.approx(exact, rel=0, abs=1e-15)
    assert geom.mesh.volume == pytest.approx(ref.volume, rel=0, abs=1e-15)
    # Every face normal points away from the part's centroid (the tetrahedron is convex).
    centroid = geom.mesh.vertices.mean(axis=0)
    assert np.all(np.einsum("ij,ij->i", geom.mesh.triangles_center - centroid, geom.mesh.face_normals) > 0)


# ---------------------------------------------------------------------------------------------------------------
# Kinematics: every link pose against a URDF reader written from the XML text
# ---------------------------------------------------------------------------------------------------------------

def _reference_poses(root, q: dict) -> dict:
    """{link: 4 x 4 world pose} of a URDF tree from its XML text, the joints at ``q`` (mimics from their
    masters: multiplier * q_master + offset, as ROS computes them)."""
    joints = {j.get("name"): j for j in root.findall("joint")}
    parent_joint = {j.find("child").get("link"): j for j in joints.values()}
    memo = {}

    def value(j):
        m = j.find("mimic")
        if m is not None and m.get("joint") in joints:
            return float(m.get("multiplier", "1")) * value(joints[m.get("joint")]) + float(m.get("offset", "0"))
        return q.get(j.get("name"), 0.0)

    def pose(link):
        if link not in memo:
            j = parent_joint.get(link)
            if j is None:
                memo[link] = np.eye(4)
            else:
                motion = np.eye(4)
                axis_el = j.find("axis")
                axis = np.array((axis_el.get("xyz", "1 0 0") if axis_el is not None else "1 0 0").split(), float)
                if j.get("type") in ("revolute", "continuous", "prismatic"):
                    axis = axis / np.linalg.norm(axis)  # KDL's (ROS) unit axis
                    if j.get("type") == "prismatic":
                        motion[:3, 3] = axis * value(j)
                    else:
                        motion[:3, :3] = Rotation.from_rotvec(axis * value(j)).as_matrix()
                memo[link] = pose(j.find("parent").get("link")) @ _origin_matrix(j.find("origin")) @ motion
        return memo[link]

    return {lk.get("name"): pose(lk.get("name")) for lk in root.findall("link")}


FK_CASES = [  # installed name or example-robot-data file
    "ur3", "ur10", "kinova", "xarm7", "z1", "human", "panda",
    "so_arm_description/urdf/so100.urdf", "so_arm_description/urdf/so101.urdf",
    "pr2_description/urdf/pr2.urdf", "tiago_description/robots/tiago.urdf",
]


@pytest.mark.parametrize("robot", FK_CASES)
def test_link_poses_equal_an_independent_urdf_reader(robot):
    if "/" in robot:
        path, body = ROBOTS / robot, load_urdf(ROBOTS / robot, shapes="collision")
    else:
        from twinsense.robots import robot_path

        path, body = robot_path(robot), load_robot(robot, shapes="collision")
    tree, root = body.tree, ET.parse(path).getroot()
    rng = np.random.default_rng(sum(map(ord, robot)))
    lo, hi = np.maximum(tree.limits[:, 0], -math.pi), np.minimum(tree.limits[:, 1], math.pi)
    for _ in range(4):
        q = rng.uniform(lo, hi)
        st = tree.forward(q)
        want = _reference_poses(root, dict(zip(tree.joint_names, q, strict=True)))
        length = max(1.0, max(float(np.abs(w[:3, 3]).max()) for w in want.values()))
        # Each joint adds a few roundings on either side (a 3 x 3 product, the joint rotation, a position sum):
        # <= ~10 eps of max(1 m, the largest coordinate) per joint; these chains have <= 21 joints (TIAGo),
        # so 300 eps bounds the difference (seen: <= 6 eps, 1.2e-15 m), far inside 1e-9 m / 1e-9 rad.
        for n in tree.link_names:
            got = st.pose(n).matrix
            np.testing.assert_allclose(got[:3, 3], want[n][:3, 3], rtol=0, atol=300 * EPS * length, err_msg=n)
            np.testing.assert_allclose(got[:3, :3], want[n][:3, :3], rtol=0, atol=300 * EPS, err_msg=n)


# ---------------------------------------------------------------------------------------------------------------
# Bad files: a ConfigError naming the element, the value and what is allowed
# ---------------------------------------------------------------------------------------------------------------

_UR5_BASE = "package://example-robot-data/robots/ur_description/meshes/ur5/collision/base.stl"
_LINKS = '<link name="a"/><link name="b"/>'
_JOINT = ('<joint name="j" type="revolute"><parent link="a"/><child link="b"/>{x}<axis xyz="0 0 1"/>'
          '<limit lower="-1" upper="1" effort="1" velocity="1"/>{m}</joint>')


def _mesh_link(attrs: str) -> str:
    return f'<link name="a"><collision><geometry><mesh {attrs}/></geometry></collision></link>'


BAD_URDFS = [
    # (name, robot body, field, value shown, words of the allowed)
    ("scale_two", _mesh_link(f'filename="{_UR5_BASE}" scale="1 2"'),
     r"links\[a\]\.collision\[0\]\.mesh\.scale", "'1 2'", "1 or 3 finite, non-zero"),
    ("scale_zero", _mesh_link(f'filename="{_UR5_BASE}" scale="0.001 0 0.001"'),
     r"links\[a\]\.collision\[0\]\.mesh\.scale", "'0.001 0 0.001'", "non-zero"),
    ("scale_text", _mesh_link(f'filename="{_UR5_BASE}" scale="mm"'),
     r"links\[a\]\.collision\[0\]\.mesh\.scale", "'mm'", "scale factors"),
    ("cylinder_length", '<link name="a"><visual><geometry><cylinder radius="0.1"/></geometry></visual></link>',
     r"links\[a\]\.visual\[0\]\.cylinder\.length", "None", "radius, length"),  # yourdfpy: KeyError 'length'
    ("no_filename", _mesh_link(""), r"links\[a\]\.collision\[0\]\.mesh\.filename", "None", "path or package://"),
    ("metres_as_microns",
     f'<link name="a"><visual><geometry><mesh filename="{_UR5_BASE}" scale="1e6 1e6 1e6"/></geometry></visual></link>',
     r"links\[a\]\.visual$", "'a'", "unit and scale"),
    ("no_geometry", '<link name="a"><collision><origin xyz="0 0 0"/></collision></link>',
     r"links\[a\]\.collision\[0\]\.geometry", "None", "<box>, <cylinder>, <sphere>, <mesh>"),
    ("capsule", '<link name="a"><collision><geometry><capsule radius="1" length="2"/></geometry></collision></link>',
     r"links\[a\]\.collision\[0\]\.geometry", "'capsule'", "<mesh>"),
    ("origin_nan", _LINKS + _JOINT.format(x='<origin xyz="0 0 nan"/>', m=""),
     r"joints\[j\]\.origin\.xyz", "'0 0 nan'", "3 finite numbers"),
    ("origin_two", _LINKS + _JOINT.format(x='<origin xyz="0 0.1"/>', m=""),
     r"joints\[j\]\.origin\.xyz", "'0 0.1'", "3 finite numbers"),
    ("origin_commas", _LINKS + _JOINT.format(x='<origin xyz="0,0,0.1"/>', m=""),  # yourdfpy: a ValueError
     r"joints\[j\]\.origin\.xyz", "'0,0,0.1'", "3 finite numbers separated by spaces"),
    ("rpy_inf", _LINKS + _JOINT.format(x='<origin rpy="0 inf 0"/>', m=""),
     r"joints\[j\]\.origin\.rpy", "'0 inf 0'", "[rad]"),
    ("visual_origin", '<link name="a"><visual><origin xyz="0 0 1e999"/><geometry><sphere radius="0.1"/>'
     '</geometry></visual></link>', r"links\[a\]\.visual\[0\]\.origin\.xyz", "'0 0 1e999'", "finite"),
    ("no_parent", _LINKS + '<joint name="j" type="fixed"><child link="b"/></joint>',
     r"joints\[j\]\.parent", "None", '<parent link="..."/>'),
    ("mimic_nan", _LINKS + '<link name="c"/>' + _JOINT.format(x="", m="")
     + '<joint name="k" type="prismatic"><parent link="b"/><child link="c"/><axis xyz="1 0 0"/>'
       '<limit lower="0" upper="1" effort="1" velocity="1"/><mimic joint="j" multiplier="nan"/></joint>',
     r"joints\[k\]\.mimic\.multiplier", "nan", "finite"),
    ("mimic_fixed", _LINKS + '<link name="c"/><joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint>'
     '<joint name="k" type="continuous"><parent link="b"/><child link="c"/><mimic joint="j"/></joint>',
     r"joints\[k\]\.mimic\.joint", "'j'", "a revolute, continuous or prismatic joint to follow ('j' is fixed)"),
]


@pytest.mark.parametrize(("name", "body", "field", "value", "allowed"), BAD_URDFS, ids=[c[0] for c in BAD_URDFS])
def test_bad_urdf_elements_name_the_element(tmp_path, name, body, field, value, allowed):
    path = tmp_path / f"{name}.urdf"
    path.write_text(f'<robot name="r">{body}</robot>')
    with pytest.raises(ConfigError) as exc:
        load_robot(path)
    assert exc.type is ConfigError  # not a GeometryError, ValueError, ... from the libraries
    msg = str(exc.value)
    assert exc.value.field.startswith(f"urdf[{name}.urdf].")
    assert re.search(field, exc.value.field), exc.value.field
    assert f"= {value} is invalid" in msg, msg
    assert allowed in msg, msg


@pytest.mark.parametrize("name", ["scale_two", "scale_zero", "metres_as_microns", "no_geometry", "origin_nan"])
def test_bad_urdf_in_a_scenario_is_a_scenario_problem(tmp_path, name):
    body = next(c[1] for c in BAD_URDFS if c[0] == name)
    (tmp_path / "arm.urdf").write_text(f'<robot name="r">{body}</robot>')
    data = {"name": "t", "duration": 0.1, "robots": [{"name": "arm", "description": "arm.urdf"}],
            "sensors": [], "outputs": {"recording": None}}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ScenarioError) as exc:
            scenario_from_dict(data, base_dir=tmp_path)
    assert len(exc.value.problems) == 1, exc.value.problems
    assert exc.value.problems[0][0].startswith("robots[0].urdf[arm.urdf]."), exc.value.problems


# ---------------------------------------------------------------------------------------------------------------
# COLLADA units: the document's own <asset><unit meter>, as pycollada reads it
# ---------------------------------------------------------------------------------------------------------------

_DAE = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  {head}<asset>{unit}<up_axis>Z_UP</up_axis></asset>
  <library_geometries><geometry id="g" name="g"><mesh>
    <source id="p"><float_array id="pa" count="12">0 0 0 100 0 0 0 200 0 0 0 300</float_array>
      <technique_common><accessor source="#pa" count="4" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common></source>
    <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
    <triangles count="2"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2 0 1 3</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s"><node id="n" name="n">{node_asset}
    <instance_geometry url="#g"/></node></visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""
DAE_CASES = {
    # Either quote is XML; an exporter's long comment before <asset>; a node's own <asset> is that node's only.
    "single_quotes": {"unit": "<unit name='millimetre' meter='0.001'/>"},
    "after_a_long_comment": {"head": "<!-- " + "licence text " * 800 + "-->\n  ",
                             "unit": '<unit name="centimetre" meter="0.01"/>'},
    "a_node_asset_only": {"node_asset": '<asset><unit meter="0.001"/></asset>'},
    "inches": {"unit": '<unit name="inch" meter="0.0254"/>'},
}


@pytest.mark.parametrize("case", sorted(DAE_CASES))
def test_collada_unit_is_the_documents_own_as_pycollada_reads_it(tmp_path, case):
    parts = {"head": "", "unit": "", "node_asset": "", **DAE_CASES[case]}
    path = tmp_path / f"{case}.dae"
    path.write_text(_DAE.format(**parts))
    (tmp_path / "r.urdf").write_text(f'<robot name="r"><link name="a"><visual><geometry><mesh filename="{path.name}"/>'
                                     '</geometry></visual></link></robot>')
    geom = load_urdf(tmp_path / "r.urdf").tree.links[0].geometry
    unit = collada.Collada(str(path)).assetInfo.unitmeter or 1.0
    raw = trimesh.load(str(path), force="mesh", process=False)
    # One product per coordinate on either side (coordinate * unit): equal to the bit.
    np.testing.assert_array_equal(geom.vertices, np.asarray(raw.vertices) * unit)
    # The span is 300 file units: 0.3 m to 7.62 m; one rounding each of the product and the difference.
    assert np.ptp(geom.vertices, axis=0).max() == pytest.approx(300 * unit, rel=4 * EPS, abs=0)


def test_a_collada_unit_that_is_no_length_is_refused_naming_the_link(tmp_path):
    (tmp_path / "z.dae").write_text(_DAE.format(head="", unit='<unit meter="0"/>', node_asset=""))
    (tmp_path / "r.urdf").write_text('<robot name="r"><link name="a"><visual><geometry><mesh filename="z.dae"/>'
                                     '</geometry></visual></link></robot>')
    with pytest.raises(ConfigError, match=r"links\[a\]\.visual\[0\]\.mesh = .*z\.dae.*<unit meter='0'>"):
        load_urdf(tmp_path / "r.urdf")


def test_a_xacro_include_written_as_a_package_uri_names_the_find_form(tmp_path):
    # xacro (the ROS tool as well) reads <xacro:include filename> as a path relative to the including file, so a
    # package:// URI there is a missing file (example-robot-data's hector quadrotor_base.xacro writes one); the
    # error says how to write it.
    f = tmp_path / "arm.urdf.xacro"
    f.write_text('<robot name="arm" xmlns:xacro="http://www.ros.org/wiki/xacro">'
                 '<xacro:include filename="package://my_arm/urdf/parts.xacro"/><link name="a"/></robot>')
    with pytest.raises(ConfigError) as exc:
        load_robot(f)
    assert exc.value.field == "xacro.path"
    assert "includes " in exc.value.allowed and "(No such file or directory)" in exc.value.allowed
    assert "write 'package://my_arm/urdf/parts.xacro' as '$(find my_arm)/urdf/parts.xacro'" in exc.value.allowed


def test_an_unknown_link_material_names_the_link_it_was_given_for():
    with pytest.raises(ConfigError) as exc:
        load_robot("ur5", materials={"forearm_link": "unobtainium"}, shapes="collision")
    assert exc.value.field == "urdf[ur5_robot.urdf].materials.forearm_link"  # it was "material"
    assert exc.value.value == "unobtainium" and "aluminium" in exc.value.allowed and "mild_steel" in exc.value.allowed


def _pycollada_points(path) -> np.ndarray:
    """Every triangle corner of a COLLADA file's scene as pycollada binds it (node transforms applied), in
    metres (the document's unit)."""
    c = collada.Collada(str(path), ignore=[collada.common.DaeUnsupportedError, collada.common.DaeBrokenRefError])
    with warnings.catch_warnings():  # pycollada binds node transforms with numpy.matrix (pending deprecation)
        warnings.simplefilter("ignore", PendingDeprecationWarning)
        pts = [prim.vertex[np.asarray(prim.vertex_index).reshape(-1)]
               for geom in c.scene.objects("geometry") for prim in geom.primitives() if len(prim.vertex_index)]
    return np.vstack(pts) * (c.assetInfo.unitmeter or 1.0)


@pytest.mark.parametrize("folder", ["ur_description/meshes/ur10/visual", "panda_description/meshes/visual",
                                    "kinova_description/meshes"])
def test_collada_meshes_span_what_pycollada_binds(folder):
    # A second reader of the same files: pycollada's bound scene (its own node-transform products). 261 of the
    # 262 COLLADA files example-robot-data installs agree so, to 6e-8 of the largest coordinate (anymal_foot.dae
    # has nothing to compare: pycollada drops its geometry for the broken material binding).
    files = sorted((ROBOTS / folder).glob("*.dae"))
    assert len(files) >= 5, folder
    for path in files:
        v, f = read_mesh(path, "mesh", "link")
        used, ref = v[np.unique(f)], _pycollada_points(path)
        # The corners are float32 in the file; pycollada multiplies the node matrices in float32 too: a few
        # float32 roundings (2^-24 each) of the largest coordinate, 8 of them allowed.
        tol = 8 * 2.0**-24 * float(np.abs(ref).max())
        np.testing.assert_allclose(used.min(axis=0), ref.min(axis=0), rtol=0, atol=tol, err_msg=path.name)
        np.testing.assert_allclose(used.max(axis=0), ref.max(axis=0), rtol=0, atol=tol, err_msg=path.name)


def test_a_collada_up_axis_is_not_applied_as_in_rviz(tmp_path):
    # RViz, Gazebo and hpp-fcl read a robot's COLLADA meshes through assimp and leave out the root node's turn
    # to Y_UP (their buildMesh: "Don't convert to y-up orientation"); a Y_UP file reads as written, like Z_UP.
    got = {}
    for axis in ("Z_UP", "Y_UP"):
        path = tmp_path / f"{axis}.dae"
        path.write_text(_DAE.format(head="", unit='<unit meter="0.001"/>', node_asset="").replace("Z_UP", axis))
        got[axis] = read_mesh(path, "mesh", "link")
    np.testing.assert_array_equal(got["Y_UP"][0], got["Z_UP"][0])
    np.testing.assert_array_equal(got["Y_UP"][0][3], [0.0, 0.0, 0.3])  # the file's (0, 0, 300) mm stays on z


def test_a_link_of_a_part_and_its_overlapping_mirror_image_is_solid_where_they_overlap(tmp_path):
    # A link drawn as a closed part and, overlapping it, the same file mirrored (scale "1 -1 1"), as a left and
    # right half of a housing can be. Inside tests count signed windings: with the mirrored part inside out, a
    # point inside both summed +1 - 1 = 0 and read as outside the link.
    trimesh.creation.box(extents=(0.2, 0.1, 0.1)).export(tmp_path / "half.stl")
    (tmp_path / "h.urdf").write_text(
        '<robot name="h"><link name="a">'
        '<visual><origin xyz="0 0.03 0"/><geometry><mesh filename="half.stl"/></geometry></visual>'
        '<visual><origin xyz="0 -0.03 0"/><geometry><mesh filename="half.stl" scale="1 -1 1"/></geometry></visual>'
        '</link></robot>')
    geom = load_urdf(tmp_path / "h.urdf").tree.links[0].geometry
    assert geom.mesh.is_watertight
    # Closed form: the boxes span y in [-0.02, 0.08] and [-0.08, 0.02], overlapping in |y| < 0.02 (|x| < 0.1,
    # |z| < 0.05); points 5 mm or more from every face, so no rounding decides them.
    inside = [[0.0, 0.0, 0.0], [0.05, 0.01, -0.02], [0.0, 0.05, 0.0], [0.0, -0.05, 0.0]]
    outside = [[0.0, 0.09, 0.0], [0.0, -0.09, 0.0], [0.11, 0.0, 0.0], [0.0, 0.0, 0.06]]
    np.testing.assert_array_equal(geom.contains(inside + outside), [True] * 4 + [False] * 4)


def test_the_named_human_stands_on_its_y_axis_as_its_isb_file_does():
    # human.urdf follows the ISB axes (Wu et al., J. Biomech. 2002/2005): x forward, y up, z to the body's right,
    # the pelvis at the origin. Turned +90 deg about x (y -> z, z -> -y) and lifted by 1.0555 m, as
    # docs/robots.md says, it stands on z = 0 facing +x with its left side at +y.
    standing = Pose((0.0, 0.0, 1.0555), Rotation.from_euler("x", 90, degrees=True).as_matrix())
    body = load_robot("human", base=standing)
    st = body.state(0.0)
    pts = {lk.name: st.pose(lk.name).apply(np.asarray(lk.geometry.vertices))
           for lk in body.tree.links if lk.geometry is not None}
    every = np.vstack(list(pts.values()))
    # The soles' lowest vertex is 1.0555184 m below the pelvis (float32 STL corners times the file's scale):
    # 0.1 mm covers the rounding of 1.0555 in the docs.
    assert abs(every[:, 2].min()) < 1e-4
    assert 1.78 < every[:, 2].max() < 1.80  # the head's top: a 1.79 m person
    assert pts["middle_head"][:, 2].mean() > 1.5
    assert pts["left_foot"][:, 1].mean() > 0.05 and pts["right_foot"][:, 1].mean() < -0.05
    # Toes ahead of the ankles: each foot mesh reaches further along +x than back along -x from its link.
    for foot in ("left_foot", "right_foot"):
        x = pts[foot][:, 0] - st.pose(foot).position[0]
        assert x.max() > 2 * -x.min(), foot
