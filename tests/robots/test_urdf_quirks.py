"""What real robot descriptions write and a loader must take: fixed joints with a zero axis,
``package:///`` mesh paths, COLLADA files with broken material bindings, xacro stubs; and
every named robot (``robot_names()``) loading with its joints.

Each quirk is taken from a file example-robot-data installs (Kinova, TIAGo, iCub, Talos
and Go2 write ``axis="0 0 0"`` on fixed joints; Talos writes ``package:///``; ANYmal's
Blender-exported feet bind a missing texture; ``ur3.urdf`` is an empty xacro stub), and
reproduced in a small file of its own so the cause is tested apart from the rest.
"""

from pathlib import Path

import numpy as np
import pytest

from twinsense.errors import ConfigError
from twinsense.robots import load_robot, load_urdf, robot_names
from twinsense.robots.meshes import read_mesh
from twinsense.robots.paths import example_robot_data_share, resolve_uri
from twinsense.scene import Joint, Pose

#: Movable joints of every named robot (the descriptions' own counts).
JOINTS = {"ur3": 6, "ur5": 6, "ur10": 6, "panda": 8, "kinova": 6, "xarm7": 7, "z1": 7, "human": 36,
          "panda-mjcf": 7, "ur5e": 6, "ur5e-mjcf": 6, "iiwa-mjcf": 7, "jaco-mjcf": 7, "kinova3-mjcf": 7,
          "sawyer-mjcf": 7, "xarm7-mjcf": 7}

# One triangle pair in millimetres (unit meter="0.001"), under a node that doubles it and
# shifts it by 10 mm in x, whose material binding names a material the file lacks.
_DAE = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="millimetre" meter="0.001"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries><geometry id="tri-mesh" name="tri"><mesh>
    <source id="tri-pos">
      <float_array id="tri-pos-array" count="12">0 0 0 100 0 0 0 200 0 0 0 300</float_array>
      <technique_common><accessor source="#tri-pos-array" count="4" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common>
    </source>
    <vertices id="tri-verts"><input semantic="POSITION" source="#tri-pos"/></vertices>
    <triangles material="paint" count="2">
      <input semantic="VERTEX" source="#tri-verts" offset="0"/><p>0 1 2 0 1 3</p>
    </triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="Scene" name="Scene">
    <node id="part" name="part" type="NODE">
      <matrix sid="transform">2 0 0 10 0 2 0 0 0 0 2 0 0 0 0 1</matrix>
      <instance_geometry url="#tri-mesh" name="tri">{binding}</instance_geometry>
    </node>
  </visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#Scene"/></scene>
</COLLADA>
"""
_BROKEN = ('<bind_material><technique_common><instance_material symbol="paint" target="#no-such-material"/>'
           '</technique_common></bind_material>')


@pytest.mark.parametrize("name", sorted(JOINTS))
def test_every_named_robot_loads_with_its_joints(name):
    assert set(robot_names()) == set(JOINTS)
    body = load_robot(name)
    assert body.tree.n_joints == JOINTS[name]
    shaped = [lk for lk in body.tree.links if lk.geometry is not None]
    assert shaped, name
    for lk in shaped:
        v = np.asarray(lk.geometry.mesh.vertices)
        assert len(lk.geometry.mesh.faces) > 0 and np.isfinite(v).all(), (name, lk.name)
        # Metres: a link of an arm or a person is between 1 mm and 2 m across.
        assert 1e-3 < np.ptp(v, axis=0).max() < 2.0, (name, lk.name)


def test_a_fixed_joint_takes_a_zero_axis_a_moving_one_does_not():
    j = Joint("mount", "fixed", "a", "b", Pose(), axis=(0.0, 0.0, 0.0))
    assert not j.movable and np.linalg.norm(j.axis) == 1.0
    for kind in ("revolute", "prismatic", "continuous"):
        with pytest.raises(ConfigError, match=r"joints\[j\]\.axis.*non-zero for a revolute or prismatic"):
            Joint("j", kind, "a", "b", Pose(), axis=(0.0, 0.0, 0.0))
    with pytest.raises(ConfigError, match=r"joints\[mount\]\.axis"):
        Joint("mount", "fixed", "a", "b", Pose(), axis=(np.nan, 0.0, 0.0))


def test_urdf_fixed_joint_axis_zero_and_the_real_kinova(tmp_path):
    urdf = tmp_path / "arm.urdf"
    urdf.write_text("""<robot name="arm">
      <link name="base"/><link name="plate"/><link name="upper"/>
      <joint name="mount" type="fixed"><parent link="base"/><child link="plate"/>
        <origin xyz="0 0 0.1"/><axis xyz="0 0 0"/></joint>
      <joint name="j1" type="revolute"><parent link="plate"/><child link="upper"/>
        <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
    </robot>""")
    tree = load_urdf(urdf).tree
    assert tree.joint_names == ("j1",)
    np.testing.assert_allclose(tree.forward([0.5]).pose("upper").position, [0.0, 0.0, 0.1], rtol=0, atol=1e-15)
    kinova = load_robot("kinova")  # fixed "jaco_mounting_block_to_j2s6s200_link_base" has axis 0 0 0
    assert kinova.tree.joint_names[0] == "j2s6s200_joint_1"
    bad = tmp_path / "bad.urdf"
    bad.write_text(urdf.read_text().replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>'))
    with pytest.raises(ConfigError, match=r"joints\[j1\]\.axis"):
        load_urdf(bad)


def test_package_uri_with_an_empty_authority():
    share = example_robot_data_share()
    rel = "robots/talos_data/meshes/torso/torso_2.STL"
    for uri in (f"package://example-robot-data/{rel}", f"package:///example-robot-data/{rel}"):
        assert resolve_uri(uri, Path("/nowhere")) == share / rel
    talos = load_urdf(share / "robots/talos_data/robots/talos_full_v2.urdf")  # writes package:///
    assert talos.tree.links[[lk.name for lk in talos.tree.links].index("torso_2_link")].geometry is not None


def test_collada_with_a_broken_material_binding_keeps_its_triangles(tmp_path):
    broken, plain = tmp_path / "broken.dae", tmp_path / "plain.dae"
    broken.write_text(_DAE.format(binding=_BROKEN))
    plain.write_text(_DAE.format(binding=""))
    v, f = read_mesh(broken, "mesh", "link")
    # The node's matrix (x2, +10 mm in x), then the unit (1 mm): exact in binary64 to rounding.
    expected = (2.0 * np.array([[0, 0, 0], [100, 0, 0], [0, 200, 0], [0, 0, 300]], float) + [10, 0, 0]) * 1e-3
    np.testing.assert_allclose(v, expected, rtol=1e-15, atol=1e-18)
    np.testing.assert_array_equal(f, [[0, 1, 2], [0, 1, 3]])
    v0, f0 = read_mesh(plain, "mesh", "link")
    np.testing.assert_array_equal(v, v0)
    np.testing.assert_array_equal(f, f0)
    # The real file: ANYmal's foot (a Blender export binding a texture it does not ship).
    foot = example_robot_data_share() / "robots/anymal_b_simple_description/meshes/foot/anymal_foot.dae"
    v, f = read_mesh(foot, "mesh", "LF_ADAPTER")
    assert len(f) == 4604 and 0.3 < np.ptp(v, axis=0).max() < 0.4  # the 0.32 m shank adapter, in metres


def test_an_empty_xacro_stub_is_named(tmp_path):
    stub = tmp_path / "ur3.urdf"
    stub.write_text('<?xml version="1.0"?>\n<robot xmlns:xacro="http://wiki.ros.org/xacro">\n</robot>\n')
    with pytest.raises(ConfigError, match=r"urdf.path.*named <robot> with at least one <link>.*xacro"):
        load_urdf(stub)
    other = tmp_path / "scene.urdf"
    other.write_text('<scene name="x"><link name="a"/></scene>')
    with pytest.raises(ConfigError, match=r"found <scene>"):
        load_urdf(other)
