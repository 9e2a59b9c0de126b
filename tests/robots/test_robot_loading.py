"""Robots from URDF and MJCF: kinematics against published parameters and across formats, meshes, errors."""

import time

import numpy as np
import pytest

from twinsense import ConfigError
from twinsense.errors import UnknownNameError
from twinsense.robots import load_robot, load_urdf, mjcf_tree, robot_names
from twinsense.robots.deps import require
from twinsense.scene import Mount, Pose, Scene

# Universal Robots' published DH parameters of the UR5 [m, rad] (d, a, alpha per joint).
UR5_D = (0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823)
UR5_A = (0.0, -0.425, -0.39225, 0.0, 0.0, 0.0)
UR5_ALPHA = (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)


def _dh(q):
    """Flange in the base frame by the standard DH product A_i = Rz(q) Tz(d) Tx(a) Rx(alpha)."""
    t = np.eye(4)
    for qi, d, a, al in zip(q, UR5_D, UR5_A, UR5_ALPHA):
        c, s, ca, sa = np.cos(qi), np.sin(qi), np.cos(al), np.sin(al)
        t = t @ np.array([[c, -s * ca, s * sa, a * c], [s, c * ca, -c * sa, a * s], [0, sa, ca, d], [0, 0, 0, 1]])
    return t


@pytest.fixture(scope="module")
def ur5():
    t0 = time.perf_counter()
    body = load_robot("ur5")
    print(f"ur5 URDF load: {time.perf_counter() - t0:.2f} s")
    return body


def test_ur5_urdf_matches_published_dh(ur5):
    tree = ur5.tree
    assert tree.joint_names == ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                                "wrist_2_joint", "wrist_3_joint")
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-3.0, 3.0, 6)
        st = tree.forward(q)
        rel = (st.pose("base").inverse() @ st.pose("tool0")).matrix
        # The URDF writes pi/2 as 1.570796325 (error 2e-9 rad) and the DH lengths to 1e-6 m; over ~1 m
        # of arm that moves the flange by ~1e-9 m. 1e-8 covers it.
        np.testing.assert_allclose(rel, _dh(q), atol=1e-8)


def test_ur5_meshes_have_metres_and_sane_sizes(ur5):
    tree = ur5.tree
    faces = {lk.name: len(lk.geometry.faces) for lk in tree.links if lk.geometry is not None}
    assert set(faces) == {"base_link", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
                          "wrist_2_link", "wrist_3_link"}
    assert all(500 < n < 100_000 for n in faces.values()), faces
    # The upper arm spans the 0.425 m shoulder-elbow distance plus the two joint housings (~0.06 m each).
    ext = np.ptp(tree.link("upper_arm_link").geometry.bounds, axis=0)
    assert 0.45 < ext.max() < 0.6, ext
    assert {lk.material.name for lk in tree.links} == {"aluminium"}


def test_panda_urdf_and_mjcf_agree_up_to_a_fixed_flange_offset(mj_model):
    urdf = load_robot("panda", shapes="collision").tree  # the STL shapes load fastest; kinematics are the same
    mjcf = mjcf_tree(mj_model("panda-mjcf"))
    assert urdf.joint_names[:7] == tuple(f"panda_joint{i}" for i in range(1, 8))
    assert urdf.joint_names[7:] == ("panda_finger_joint1",)  # finger_joint2 mimics it
    assert urdf.mimic_joints == ("panda_finger_joint2",)
    assert mjcf.joint_names == tuple(f"joint{i}" for i in range(1, 8))
    # The offset, found once at the home pose: robosuite's right_hand against the URDF's panda_hand.
    home = mjcf.home
    offset = mjcf.forward(home).pose("right_hand").inverse() @ urdf.forward(np.r_[home, 0]).pose("panda_hand")
    # Stated in docs/robots.md: 0.5 mm along the flange z axis, 0.0282 deg about it (robosuite's quaternion
    # (0.924, 0, 0, -0.383) is -45 deg rounded to 3 digits); the bases coincide.
    np.testing.assert_allclose(offset.position, [0, 0, 0.0005], atol=1e-12)
    np.testing.assert_allclose(offset.euler_deg(), [0, 0, 0.0282253], atol=1e-6)
    rng = np.random.default_rng(11)
    for _ in range(10):
        q = rng.uniform(mjcf.limits[:, 0], mjcf.limits[:, 1])
        a = urdf.forward(np.r_[q, 0.02]).pose("panda_hand")
        b = mjcf.forward(q).pose("right_hand") @ offset
        # Both files hold the same link offsets; what remains is float rounding: 1e-6 m / 1e-6 rad as stated.
        np.testing.assert_allclose(a.position, b.position, atol=1e-6)
        np.testing.assert_allclose(a.rotation, b.rotation, atol=1e-6)
        np.testing.assert_allclose(urdf.forward(np.r_[q, 0]).pose("panda_link0").matrix, np.eye(4), atol=1e-12)


def test_robot_in_scene_and_mount_on_link(ur5):
    scene = Scene()
    scene.add_articulated(ur5)
    assert "ur5/wrist_3_link" in {o.name for o in scene.objects}
    assert "ur5/tool0" in scene.frame_names
    st = Mount(Pose((0, 0, 0.05)), "ur5/tool0").state_at(scene, 0.0)
    tool = ur5.tree.forward(ur5.tree.home).pose("tool0")
    np.testing.assert_allclose(st.pose.position, tool.apply([0, 0, 0.05]), atol=1e-12)


def test_material_overrides_and_defaults():
    body = load_robot("panda", materials={"panda_hand": "plastic", "panda_link3": "stainless_steel"},
                      shapes="collision")
    mats = {lk.name: lk.material.name for lk in body.tree.links}
    assert mats["panda_hand"] == "plastic" and mats["panda_link3"] == "stainless_steel"
    assert mats["panda_leftfinger"] == "plastic" and mats["panda_link1"] == "aluminium"
    with pytest.raises(UnknownNameError, match="panda_link0"):
        load_robot("panda", materials={"no_such_link": "plastic"})
    with pytest.raises(UnknownNameError, match="aluminium"):
        load_robot("panda", materials={"panda_hand": "unobtainium"})


def test_loader_errors(tmp_path):
    with pytest.raises(UnknownNameError, match="panda, panda-mjcf, sawyer-mjcf, ur10, ur3, ur5, ur5e, ur5e-mjcf"):
        load_robot("ur7")
    assert set(robot_names()) == {"ur3", "ur5", "ur10", "panda", "kinova", "xarm7", "z1", "human", "panda-mjcf",
                                  "ur5e", "ur5e-mjcf", "iiwa-mjcf", "jaco-mjcf", "kinova3-mjcf", "sawyer-mjcf",
                                  "xarm7-mjcf"}
    with pytest.raises(ConfigError, match="urdf.path"):
        load_urdf(tmp_path / "missing.urdf")
    urdf = tmp_path / "arm.urdf"
    urdf.write_text("""<robot name="arm">
      <link name="base"/>
      <link name="tool"><visual><geometry><mesh filename="meshes/tool.stl"/></geometry></visual></link>
      <joint name="j" type="revolute"><parent link="base"/><child link="tool"/>
        <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
    </robot>""")
    with pytest.raises(ConfigError, match=r"links\[tool\].*tool.stl.*'tool'"):
        load_urdf(urdf)
    # A package found nowhere: the message says where packages are looked up and how to give one.
    urdf.write_text(urdf.read_text().replace("meshes/tool.stl", "package://tool_pkg/meshes/tool.stl"))
    with pytest.raises(ConfigError, match=r"package 'tool_pkg' is looked up in packages=\{'tool_pkg': folder\}"):
        load_urdf(urdf)
    with pytest.raises(ConfigError, match=r"twinsense\[robots\]"):
        require("twinsense_no_such_module", "a test")


def test_urdf_primitives_with_scale_and_origin(tmp_path):
    urdf = tmp_path / "prim.urdf"
    urdf.write_text("""<robot name="prim">
      <link name="base"><visual><origin xyz="0 0 0.5"/><geometry><box size="0.2 0.4 1.0"/></geometry></visual></link>
      <link name="arm"><visual><origin xyz="0.3 0 0" rpy="0 1.5707963267948966 0"/>
        <geometry><cylinder radius="0.05" length="0.6"/></geometry></visual></link>
      <joint name="j" type="continuous"><parent link="base"/><child link="arm"/><origin xyz="0 0 1"/>
        <axis xyz="0 0 1"/></joint>
    </robot>""")
    tree = load_urdf(urdf).tree
    np.testing.assert_allclose(tree.link("base").geometry.bounds, [[-0.1, -0.2, 0], [0.1, 0.2, 1.0]], atol=1e-12)
    # The cylinder turned onto x by its origin: it spans x in [0, 0.6] in the link frame.
    b = tree.link("arm").geometry.bounds
    np.testing.assert_allclose([b[0, 0], b[1, 0]], [0.0, 0.6], atol=1e-9)
    assert tree.limits.tolist() == [[-np.inf, np.inf]]


def test_open_link_mesh_inside_test_uses_its_convex_hull():
    import trimesh

    from twinsense.robots.meshes import LinkMesh

    box = trimesh.creation.box(extents=(0.2, 0.4, 0.6))
    closed = LinkMesh(box.vertices, box.faces, name="closed")
    opened = LinkMesh(box.vertices, box.faces[2:], name="open")  # one side's two triangles removed
    assert closed.mesh.is_watertight and not opened.mesh.is_watertight
    rng = np.random.default_rng(5)
    pts = rng.uniform(-0.4, 0.4, (2000, 3))
    # A box is its own convex hull: both answer |x| <= 0.1, |y| <= 0.2, |z| <= 0.3 (points on the faces have
    # probability zero here).
    truth = np.all(np.abs(pts) <= [0.1, 0.2, 0.3], axis=1)
    np.testing.assert_array_equal(closed.contains(pts), truth)
    np.testing.assert_array_equal(opened.contains(pts), truth)


def test_format_loaders_take_installed_names():
    from twinsense.robots import load_mjcf

    assert load_urdf("ur3", shapes="collision").tree.n_joints == 6
    with pytest.raises(UnknownNameError, match="human, kinova, panda, ur10, ur3, ur5, xarm7, z1$"):
        load_urdf("panda-mjcf")  # an MJCF robot: load_mjcf or load_robot
    with pytest.raises(UnknownNameError, match="iiwa-mjcf, jaco-mjcf, kinova3-mjcf, panda-mjcf, sawyer-mjcf, "
                       "ur5e, ur5e-mjcf, xarm7-mjcf$"):
        load_mjcf("ur5")
    with pytest.raises(ConfigError, match=r"urdf.path = 123.*ur3"):
        load_urdf(123)  # neither a path nor a name


def test_ray_hits_on_a_moving_robot_link_carry_its_analytic_velocity():
    # The UR5 turning about its base (shoulder pan at 0.8 rad/s, others still): a ray straight down onto the
    # upper arm hits a point whose velocity is w x r with w = (0, 0, 0.8) about the base z axis.
    from twinsense.render import Rays, cast
    from twinsense.scene import JointConstantVelocity

    qd = np.array([0.8, 0, 0, 0, 0, 0])
    body = load_robot("ur5", shapes="collision", joints=JointConstantVelocity([0, -1.2, 0.3, 0, 0, 0], qd))
    scene = Scene()
    scene.add_articulated(body)
    t = 0.4
    arm = body.state(t).pose("upper_arm_link")
    target = arm.apply([0, 0, 0.2])  # on the upper arm's axis, 0.2 m from the shoulder
    rays = Rays(np.array([[*target[:2], 3.0]]), np.array([[0.0, 0.0, -1.0]]))
    hits = cast(scene, rays, t, kind="tof", fields=["velocity", "point"])
    assert scene.objects[hits.object_id[0]].name == "ur5/upper_arm_link"
    p = hits.point[0]
    # The base frame is at the origin and the pan axis is world z: v = w x p. The renderer's hit point is
    # float64 (re-intersected against the triangle's plane), so 1e-9 m/s covers rounding.
    np.testing.assert_allclose(hits.velocity[0], np.cross([0, 0, 0.8], p), atol=1e-9)
