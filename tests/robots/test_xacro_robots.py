"""Robots written in xacro: expanded in memory by the ``xacro`` package, then read as URDF.

The reference is an independent expansion: the same robot written out by hand as plain URDF
(the numbers xacro computes, ``${pi/2}`` and the arguments, typed in here from Python's own
``math.pi / 2`` and the argument values). The two files load to trees with the same joints,
limits and link poses; every error names the file and what is allowed.
"""

import importlib.util
import math
import sys
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.robots import load_robot, load_urdf, urdf_tree
from twinsense.robots.paths import example_robot_data_share
from twinsense.robots.xacro_files import expand_xacro
from twinsense.scenario import ScenarioError, scenario_from_dict

MACROS = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="segment" params="name parent offset length axis lower:=${-pi} upper:=${pi} rpy:='0 0 0'">
    <link name="${name}_link">
      <visual><origin xyz="0 0 ${length / 2}"/>
        <geometry><cylinder radius="${link_radius}" length="${length}"/></geometry></visual>
    </link>
    <joint name="${name}_joint" type="revolute">
      <parent link="${parent}"/><child link="${name}_link"/>
      <origin xyz="0 0 ${offset}" rpy="${rpy}"/><axis xyz="${axis}"/>
      <limit lower="${lower}" upper="${upper}" effort="10" velocity="1"/>
    </joint>
  </xacro:macro>
</robot>
"""

ARM = """<?xml version="1.0"?>
<robot name="my_arm" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="upper_length" default="0.4"/>
  <xacro:arg name="with_tool" default="true"/>
  <xacro:property name="link_radius" value="0.05"/>
  <xacro:property name="base_height" value="0.1"/>
  <xacro:property name="upper_length" value="$(arg upper_length)"/>
  <xacro:include filename="$(find my_arm_description)/urdf/macros.xacro"/>
  <link name="base_link">
    <visual><geometry>
      <mesh filename="package://my_arm_description/meshes/part.stl" scale="0.001 0.001 0.001"/>
    </geometry></visual>
  </link>
  <xacro:segment name="shoulder" parent="base_link" offset="${base_height}" length="0.3" axis="0 0 1"/>
  <xacro:segment name="elbow" parent="shoulder_link" offset="0.3" length="${upper_length}" axis="0 1 0"
                 rpy="${pi/2} 0 0" lower="${-pi/2}" upper="${pi/2}"/>
  <xacro:segment name="wrist" parent="elbow_link" offset="${upper_length}" length="0.1" axis="1 0 0"/>
  <xacro:if value="$(arg with_tool)">
    <link name="tool"/>
    <joint name="flange" type="fixed"><parent link="wrist_link"/><child link="tool"/>
      <origin xyz="0 0 0.1"/></joint>
  </xacro:if>
</robot>
"""


def _segment(name, parent, offset, length, axis, lower=-math.pi, upper=math.pi, rpy="0 0 0"):
    return f"""  <link name="{name}_link"><visual><origin xyz="0 0 {length / 2!r}"/>
    <geometry><cylinder radius="0.05" length="{length!r}"/></geometry></visual></link>
  <joint name="{name}_joint" type="revolute"><parent link="{parent}"/><child link="{name}_link"/>
    <origin xyz="0 0 {offset!r}" rpy="{rpy}"/><axis xyz="{axis}"/>
    <limit lower="{lower!r}" upper="{upper!r}" effort="10" velocity="1"/></joint>
"""


def hand_expanded(upper_length=0.4, with_tool=True) -> str:
    """The robot of ARM + MACROS written out as plain URDF, its numbers from Python's math."""
    tool = ("""  <link name="tool"/><joint name="flange" type="fixed"><parent link="wrist_link"/><child link="tool"/>
    <origin xyz="0 0 0.1"/></joint>\n""" if with_tool else "")
    return f"""<robot name="my_arm">
  <link name="base_link"><visual><geometry>
    <mesh filename="package://my_arm_description/meshes/part.stl" scale="0.001 0.001 0.001"/></geometry></visual></link>
{_segment("shoulder", "base_link", 0.1, 0.3, "0 0 1")}\
{_segment("elbow", "shoulder_link", 0.3, upper_length, "0 1 0", -math.pi / 2, math.pi / 2, f"{math.pi / 2!r} 0 0")}\
{_segment("wrist", "elbow_link", upper_length, 0.1, "1 0 0")}{tool}</robot>
"""


@pytest.fixture
def pkg(tmp_path):
    """``<tmp>/ws/src/my_arm_description``: a ROS description package (urdf/, meshes/, package.xml)."""
    root = tmp_path / "ws" / "src" / "my_arm_description"
    (root / "urdf").mkdir(parents=True)
    (root / "meshes").mkdir()
    (root / "package.xml").write_text("<package format='3'><name>my_arm_description</name></package>\n")
    (root / "urdf" / "macros.xacro").write_text(MACROS)
    (root / "urdf" / "arm.urdf.xacro").write_text(ARM)
    # A 120 x 120 x 60 mm base plate in millimetres (the mesh's scale takes it to metres).
    trimesh.creation.box((120.0, 120.0, 60.0)).export(root / "meshes" / "part.stl")
    return root


def _hand(pkg, **kw):
    path = pkg / "urdf" / "arm.urdf"
    path.write_text(hand_expanded(**kw))
    return urdf_tree(path)


def _same_tree(a, b, rng):
    """Same joints (names, kinds, limits, axes, parents) and link poses at random q, to 1e-12."""
    assert [lk.name for lk in a.links] == [lk.name for lk in b.links]
    assert a.joint_names == b.joint_names
    for ja, jb in zip(a.joints, b.joints):
        assert (ja.name, ja.kind, ja.parent, ja.child) == (jb.name, jb.kind, jb.parent, jb.child)
        # Both sides parse the same decimal text (xacro prints repr(float), as does the hand file): equal to the
        # bit; 1e-12 rad or m leaves room for one rounding of a ~1 value and no more.
        np.testing.assert_allclose([ja.lower, ja.upper], [jb.lower, jb.upper], rtol=0, atol=1e-12)
        np.testing.assert_allclose(ja.axis, jb.axis, rtol=0, atol=1e-12)
    for _ in range(5):
        q = rng.uniform(-1.5, 1.5, a.n_joints)  # inside every limit (the elbow's are +-pi/2)
        sa, sb = a.forward(q), b.forward(q)
        # Link poses: the same chain of 4 joints on the same parsed numbers; 1e-12 m is ~5000 ulps of 1 m.
        np.testing.assert_allclose(sa.positions, sb.positions, rtol=0, atol=1e-12)
        np.testing.assert_allclose(sa.rotations, sb.rotations, rtol=0, atol=1e-12)
    for la, lb in zip(a.links, b.links):
        if la.geometry is None:
            assert lb.geometry is None
        else:  # the same primitives and the same STL, merged the same way
            np.testing.assert_allclose(la.geometry.vertices, lb.geometry.vertices, rtol=0, atol=1e-12)


def test_xacro_loads_to_the_tree_of_its_hand_expansion(pkg):
    rng = np.random.default_rng(7)
    tree = urdf_tree(pkg / "urdf" / "arm.urdf.xacro")
    assert tree.name == "my_arm"
    assert tree.joint_names == ("shoulder_joint", "elbow_joint", "wrist_joint")
    _same_tree(tree, _hand(pkg), rng)
    # ${pi/2}: the elbow's limits and its frame turned +90 deg about x.
    elbow = tree.joint("elbow_joint")
    assert (elbow.lower, elbow.upper) == (-math.pi / 2, math.pi / 2)
    # The package:// mesh resolved to the package folder above the file: the 0.12 x 0.12 x 0.06 m plate
    # (millimetres times the 0.001 scale; STL stores float32, so the size is exact to 1e-6 m).
    base = tree.link("base_link").geometry
    np.testing.assert_allclose(np.ptp(base.vertices, axis=0), [0.12, 0.12, 0.06], rtol=0, atol=1e-6)


def test_arguments_override_their_defaults(pkg):
    rng = np.random.default_rng(8)
    longer = urdf_tree(pkg / "urdf" / "arm.urdf.xacro", xacro_args={"upper_length": 0.6})
    _same_tree(longer, _hand(pkg, upper_length=0.6), rng)
    default = urdf_tree(pkg / "urdf" / "arm.urdf.xacro")
    # The wrist sits 0.6 m instead of 0.4 m along the elbow link: its origin, the elbow's cylinder.
    assert longer.joint("wrist_joint").origin.position[2] == 0.6
    assert default.joint("wrist_joint").origin.position[2] == 0.4
    # A bool argument turns the <xacro:if> off: no tool link, no flange joint.
    bare = urdf_tree(pkg / "urdf" / "arm.urdf.xacro", xacro_args={"with_tool": False})
    _same_tree(bare, _hand(pkg, with_tool=False), rng)
    assert "tool" not in [lk.name for lk in bare.links]


def test_load_robot_and_load_urdf_take_xacro(pkg):
    path = pkg / "urdf" / "arm.urdf.xacro"
    body = load_robot(path, name="arm", xacro_args={"upper_length": "0.5"})
    assert body.tree.joint("wrist_joint").origin.position[2] == 0.5
    # NumPy scalars are numbers and bools like Python's.
    tree = urdf_tree(path, xacro_args={"upper_length": np.float32(0.25), "with_tool": np.bool_(False)})
    assert tree.joint("wrist_joint").origin.position[2] == 0.25 and "tool" not in [lk.name for lk in tree.links]
    assert urdf_tree(path, xacro_args={"upper_length": np.int64(1)}).joint("wrist_joint").origin.position[2] == 1.0
    assert load_urdf(str(path)).tree.name == "my_arm"
    # A plain .xacro suffix is xacro too.
    plain = pkg / "urdf" / "arm.xacro"
    plain.write_text(ARM)
    assert load_robot(plain).tree.joint_names == ("shoulder_joint", "elbow_joint", "wrist_joint")
    with pytest.raises(UnknownNameError, match=r"<path>.xacro"):
        load_robot(pkg / "urdf" / "arm.sdf")


def test_packages_argument_wins_over_the_folders_above(pkg, tmp_path):
    # A second copy of the package elsewhere, its mesh twice the size: packages= takes $(find) and package:// there.
    other = tmp_path / "elsewhere"
    (other / "urdf").mkdir(parents=True)
    (other / "meshes").mkdir()
    (other / "urdf" / "macros.xacro").write_text(MACROS.replace("${link_radius}", "0.07"))
    trimesh.creation.box((240.0, 240.0, 120.0)).export(other / "meshes" / "part.stl")
    tree = urdf_tree(pkg / "urdf" / "arm.urdf.xacro", packages={"my_arm_description": other})
    np.testing.assert_allclose(np.ptp(tree.link("base_link").geometry.vertices, axis=0), [0.24, 0.24, 0.12],
                               rtol=0, atol=1e-6)
    # The cylinder of the other macros file: radius 0.07 m (0.14 m across, to the mesh's float rounding).
    shoulder = tree.link("shoulder_link").geometry.vertices
    assert abs(np.ptp(shoulder[:, 0]) - 0.14) < 1e-9


def test_a_ros_workspace_sibling_package_is_found(pkg):
    # $(find other_pkg) for a package beside this one in the workspace's src/ folder.
    (pkg.parent / "other_pkg" / "urdf").mkdir(parents=True)
    (pkg.parent / "other_pkg" / "urdf" / "macros.xacro").write_text(MACROS)
    f = pkg / "urdf" / "sibling.urdf.xacro"
    f.write_text(ARM.replace("$(find my_arm_description)", "$(find other_pkg)"))
    assert urdf_tree(f).joint_names == ("shoulder_joint", "elbow_joint", "wrist_joint")


def test_hector_quadrotor_of_example_robot_data(tmp_path):
    # The installed quadrotor_base.urdf.xacro only defines a macro (no robot name, no link): the error says so.
    hector = example_robot_data_share() / "robots" / "hector_description" / "robots"
    with pytest.raises(ConfigError, match=r"xacro.path.*quadrotor_base.urdf.xacro gives <robot> with 0 <link>"
                       r".*only defines the macros quadrotor_base_macro"), \
            pytest.warns(UserWarning, match=r"redefining global symbol: pi"):
        load_urdf(hector / "quadrotor_base.urdf.xacro")
    # Its own quadrotor_base.xacro includes that file from a folder that is not installed (urdf/, not robots/).
    with pytest.raises(ConfigError, match=r"included files that exist.*quadrotor_base.xacro includes "
                       r".*hector_description/urdf/quadrotor_base.urdf.xacro"):
        load_urdf(hector / "quadrotor_base.xacro")
    # Included as the macro file it is, with $(find example-robot-data): the quadrotor loads, its COLLADA mesh
    # read through package://example-robot-data (the rotors span ~0.6 m across).
    f = tmp_path / "hector.urdf.xacro"
    f.write_text('<robot name="hector" xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
                 '  <xacro:include filename="$(find example-robot-data)/robots/hector_description/robots/'
                 'quadrotor_base.urdf.xacro"/>\n  <xacro:quadrotor_base_macro/>\n</robot>\n')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tree = urdf_tree(f)
    # The file redefines xacro's own "pi": xacro's warning arrives as a Python warning naming the file.
    assert any("hector.urdf.xacro" in str(w.message) and "pi" in str(w.message) for w in caught)
    assert [lk.name for lk in tree.links] == ["base_link"]
    size = np.ptp(tree.link("base_link").geometry.vertices, axis=0)
    assert 0.4 < size.max() < 0.8, size


def test_franka_panda_xacro_against_its_packaged_urdf():
    # robosuite ships Franka's panda_description package with both the xacro sources and the URDF their authors
    # expanded with ROS xacro: an independent expansion of a real description (meshes by package:// into the
    # package folder above the file). The packaged URDF has panda_link8, which robosuite's copy of
    # panda_arm.xacro comments out; every other link and joint is the same.
    spec = importlib.util.find_spec("robosuite")
    urdf = Path(next(iter(spec.submodule_search_locations))) / "models/assets/bullet_data/panda_description/urdf"
    for name, extra in (("hand", set()), ("panda_arm", {"panda_link8"})):
        ours = urdf_tree(urdf / f"{name}.urdf.xacro", shapes="collision")
        ref = urdf_tree(urdf / f"{name}.urdf", shapes="collision")
        assert {lk.name for lk in ref.links} - {lk.name for lk in ours.links} == extra
        assert ours.joint_names == tuple(j for j in ref.joint_names if ref.joint(j).child not in extra)
        for j in ours.joints:
            r = ref.joint(j.name)
            assert (j.kind, j.parent, j.child, j.lower, j.upper) == (r.kind, r.parent, r.child, r.lower, r.upper)
            assert tuple(j.axis) == tuple(r.axis)
        rng = np.random.default_rng(3)
        lo = np.array([ours.joint(j).lower for j in ours.joint_names])
        hi = np.array([ours.joint(j).upper for j in ours.joint_names])
        for _ in range(5):
            q = rng.uniform(lo, hi)
            so, sr = ours.forward(q), ref.forward(q)
            for lk in ours.links:
                # The packaged URDF writes pi/2 as 1.57079632679 (4.9e-12 rad short); 6 such joints on the
                # 1.2 m arm move a link by <= 6 * 4.9e-12 * 1.2 = 3.5e-11 m and turn it by <= 3e-11 rad: 5e-11.
                np.testing.assert_allclose(so.pose(lk.name).matrix, sr.pose(lk.name).matrix, rtol=0, atol=5e-11)
    # The whole arm with its hand: the hand hangs on panda_link8, which the edited panda_arm.xacro lacks.
    with pytest.raises(ConfigError, match=r"joints\[panda_hand_joint\].parent = 'panda_link8'"):
        urdf_tree(urdf / "panda_arm_hand.urdf.xacro", shapes="collision")


def test_expansion_is_safe_from_threads(pkg):
    # xacro keeps its state in module globals: four threads, each its own argument, each gets its own robot.
    out = {}

    def run(k):
        out[k] = urdf_tree(pkg / "urdf" / "arm.urdf.xacro", xacro_args={"upper_length": 0.1 * (k + 1)})

    threads = [threading.Thread(target=run, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert [out[k].joint("wrist_joint").origin.position[2] for k in range(4)] == [0.1 * (k + 1) for k in range(4)]
    import xacro.substitution_args as sa

    assert sa._eval_find.__module__ == "xacro.substitution_args"  # the hook put back


# ---- errors: each names the file (or field) and what is allowed -------------------------------------------------


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match=r"xacro.path.*nope.urdf.xacro.*an existing xacro file"):
        urdf_tree(tmp_path / "nope.urdf.xacro")
    with pytest.raises(ConfigError, match=r"xacro.path.*an existing xacro file"):
        load_robot(tmp_path / "nope.xacro")


def test_syntax_and_evaluation_errors(pkg):
    bad = pkg / "urdf" / "broken.urdf.xacro"
    bad.write_text('<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro"><link name="a"></robot>')
    with pytest.raises(ConfigError, match=r"xacro.path.*well-formed XML in .*broken.urdf.xacro \(XML error: "
                       r"mismatched tag") as e:
        urdf_tree(bad)
    assert "Traceback" not in str(e.value)
    # A broken included file is named as the place of the error, with the file that includes it.
    (pkg / "urdf" / "macros.xacro").write_text(MACROS.replace("</robot>", "<robot>"))
    with pytest.raises(ConfigError, match=r"well-formed XML in .*macros.xacro \(included from .*arm.urdf.xacro\)"):
        urdf_tree(pkg / "urdf" / "arm.urdf.xacro")
    (pkg / "urdf" / "macros.xacro").write_text(MACROS)
    expr = pkg / "urdf" / "expr.urdf.xacro"
    expr.write_text('<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro"><link name="${1/0}"/></robot>')
    with pytest.raises(ConfigError, match=r"xacro.path.*expands without error \(xacro: division by zero when "
                       r"evaluating expression '1/0'; in .*expr.urdf.xacro\)"):
        urdf_tree(expr)
    undefined = pkg / "urdf" / "undef.urdf.xacro"
    undefined.write_text('<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:nosuch/></robot>')
    with pytest.raises(ConfigError, match=r"xacro: unknown macro name: xacro:nosuch"):
        urdf_tree(undefined)
    # A failing substitution: xacro's message once, with the kind of error.
    env = pkg / "urdf" / "env.urdf.xacro"
    env.write_text('<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro">'
                   '<link name="$(env TWINSENSE_TEST_UNSET_VARIABLE)"/></robot>')
    with pytest.raises(ConfigError, match=r"\(xacro: SubstitutionException: environment variable "
                       r"'TWINSENSE_TEST_UNSET_VARIABLE' is not set; in .*env.urdf.xacro\)$"):
        urdf_tree(env)


def test_unknown_package(pkg):
    f = pkg / "urdf" / "lost.urdf.xacro"
    f.write_text(ARM.replace("$(find my_arm_description)", "$(find ur_description)"))
    with pytest.raises(ConfigError, match=r"packages = 'ur_description'.*\$\(find ur_description\) in "
                       r".*lost.urdf.xacro: looked in packages= \(names: none given\), then a folder named "
                       r"'ur_description' at or inside .*my_arm_description/urdf or one of its parents; "
                       r"give it as packages=\{'ur_description': <its folder>\}"):
        urdf_tree(f)
    with pytest.raises(ConfigError, match=r"packages\[ur_description\].*an existing folder"):
        urdf_tree(f, packages={"ur_description": pkg / "missing"})
    with pytest.raises(ConfigError, match=r"packages.*a mapping"):
        urdf_tree(f, packages=["ur_description"])


def test_missing_and_unknown_arguments(pkg):
    f = pkg / "urdf" / "needs_arg.urdf.xacro"
    f.write_text('<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro">'
                 '<link name="$(arg prefix)base"/></robot>')
    with pytest.raises(ConfigError, match=r"xacro_args = 'prefix'.*needs_arg.urdf.xacro reads \$\(arg prefix\) "
                       r"and no <xacro:arg name='prefix' default=...> sets it; give xacro_args=\{'prefix': ...\}"):
        urdf_tree(f)
    assert [lk.name for lk in urdf_tree(f, xacro_args={"prefix": "left_"}).links] == ["left_base"]
    # A misspelt argument would change nothing: refused, naming the file's own arguments.
    with pytest.raises(ConfigError, match=r"xacro_args = 'upper_lenght'.*arm.urdf.xacro declares or reads: "
                       r"upper_length, with_tool"):
        urdf_tree(pkg / "urdf" / "arm.urdf.xacro", xacro_args={"upper_lenght": 0.5})
    for bad, match in (([1], r"xacro_args.*a mapping"), ({"a b": 1}, r"xacro_args = 'a b'.*without spaces"),
                       ({"upper_length": math.nan}, r"xacro_args\[upper_length\] = nan.*finite number"),
                       ({"upper_length": None}, r"xacro_args\[upper_length\] = None")):
        with pytest.raises(ConfigError, match=match):
            urdf_tree(pkg / "urdf" / "arm.urdf.xacro", xacro_args=bad)
    # A plain URDF takes no arguments.
    (pkg / "urdf" / "arm.urdf").write_text(hand_expanded())
    with pytest.raises(ConfigError, match=r"xacro_args.*only a .xacro file takes arguments"):
        urdf_tree(pkg / "urdf" / "arm.urdf", xacro_args={"upper_length": 0.5})


def test_result_that_is_not_a_robot(tmp_path):
    f = tmp_path / "world.xacro"
    f.write_text('<sdf xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:property name="a" value="1"/>'
                 '<model name="m"/></sdf>')
    with pytest.raises(ConfigError, match=r"xacro.path.*expands to a URDF robot.*world.xacro gives <sdf> with 0"):
        expand_xacro(f)


def test_without_xacro_installed_the_error_names_the_extra(pkg, monkeypatch):
    monkeypatch.setitem(sys.modules, "xacro", None)  # `import xacro` fails as on an install without it
    with pytest.raises(ConfigError, match=r"robots extra = 'xacro'.*pip install twinsense\[robots\]"):
        urdf_tree(pkg / "urdf" / "arm.urdf.xacro")


def test_nothing_is_written_next_to_the_file(pkg):
    before = sorted(p.name for p in pkg.rglob("*"))
    urdf_tree(pkg / "urdf" / "arm.urdf.xacro")
    assert sorted(p.name for p in pkg.rglob("*")) == before


# ---- scenario files ----------------------------------------------------------------------------------------------


def _scenario(robot):
    return {"name": "cell", "duration": 0.1, "sensors": [], "robots": [{"name": "arm", **robot}]}


def test_scenario_robot_from_xacro(pkg, tmp_path):
    scen = tmp_path / "ws" / "cell.yaml"
    other = tmp_path / "ws" / "copy"
    (other / "urdf").mkdir(parents=True)
    (other / "urdf" / "macros.xacro").write_text(MACROS)
    (other / "meshes").mkdir()
    trimesh.creation.box((120.0, 120.0, 60.0)).export(other / "meshes" / "part.stl")
    sc = scenario_from_dict(_scenario({"description": "src/my_arm_description/urdf/arm.urdf.xacro",
                                       "xacro_args": {"upper_length": 0.6, "with_tool": False},
                                       "packages": {"my_arm_description": "copy"}}), base_dir=scen.parent)
    names = {o.name for o in sc.scene.objects}
    assert {"arm/base_link", "arm/wrist_link"} <= names and "arm/tool" not in names
    # The wrist link sits 0.1 + 0.3 m up and 0.6 m along the elbow link, turned +90 deg about x: at y = -0.6 m.
    pose = sc.scene.object("arm/wrist_link").state_at(0.0).pose
    np.testing.assert_allclose(pose.position, [0.0, -0.6, 0.4], rtol=0, atol=1e-12)


def test_scenario_errors_name_the_field(pkg, tmp_path):
    scen = tmp_path / "ws" / "cell.yaml"
    desc = "src/my_arm_description/urdf/arm.urdf.xacro"
    cases = [({"description": desc, "xacro_args": {"upper_lenght": 1}}, r"robots\[0\].xacro_args"),
             ({"description": desc, "packages": {"my_arm_description": "nowhere"}},
              r"robots\[0\].packages\[my_arm_description\].*ws/nowhere.*an existing folder"),
             ({"description": "ur5", "xacro_args": {"a": 1}}, r"robots\[0\].xacro_args.*only a .xacro"),
             ({"description": desc.replace("arm.urdf", "lost.urdf")},
              r"robots\[0\].description.*an existing robot description file")]
    for robot, match in cases:
        with pytest.raises(ScenarioError, match=match):
            scenario_from_dict(_scenario(robot), base_dir=scen.parent)
