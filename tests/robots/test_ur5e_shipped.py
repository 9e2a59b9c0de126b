"""The UR5e shipped with twinsense (``load_robot("ur5e")``): robosuite's MJCF kinematics, UR's published DH
parameters, its meshes, and that it loads without robosuite."""

import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import trimesh

import twinsense
from twinsense.robots import load_mjcf, load_robot, robot_path
from twinsense.robots.paths import robosuite_robots_dir

# Universal Robots' published DH parameters of the UR5e [m, rad] (d, a, alpha per joint).
UR5E_D = (0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996)
UR5E_A = (0.0, -0.425, -0.3922, 0.0, 0.0, 0.0)
UR5E_ALPHA = (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)
JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint")


def _dh(q) -> np.ndarray:
    """Flange in the DH base frame (4, 4): the standard product A_i = Rz(q) Tz(d) Tx(a) Rx(alpha)."""
    t = np.eye(4)
    for qi, d, a, al in zip(q, UR5E_D, UR5E_A, UR5E_ALPHA, strict=True):
        c, s, ca, sa = np.cos(qi), np.sin(qi), np.cos(al), np.sin(al)
        t = t @ np.array([[c, -s * ca, s * sa, a * c], [s, c * ca, -c * sa, a * s], [0, sa, ca, d], [0, 0, 0, 1]])
    return t


def test_shipped_ur5e_lives_in_the_package_and_loads_without_robosuite(tmp_path):
    path = robot_path("ur5e")
    assert Path(twinsense.__file__).parent in path.parents
    # A fresh interpreter that cannot import robosuite (None in sys.modules blocks the import and find_spec).
    code = ("import sys; sys.modules['robosuite'] = None\n"
            "from twinsense.robots import load_robot\n"
            "b = load_robot('ur5e')\n"
            "print(b.tree.n_joints, sum(len(lk.geometry.faces) for lk in b.tree.links if lk.geometry is not None))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, check=True)
    assert out.stdout.split() == ["6", "7558"]


def test_shipped_ur5e_has_robosuites_kinematics_and_flange():
    # Bit for bit: the same bodies, joints and numbers; tool0 is robosuite's "right_hand".
    ours = load_robot("ur5e").tree
    theirs = load_mjcf(robosuite_robots_dir() / "ur5e" / "robot.xml", geoms="collision").tree
    assert ours.joint_names == theirs.joint_names == JOINTS
    rng = np.random.default_rng(5)
    for _ in range(5):
        q, qd = rng.uniform(-3.0, 3.0, 6), rng.uniform(-2.0, 2.0, 6)
        a, b = ours.forward(q, qd), theirs.forward(q, qd)
        for mine, other in [(n, n) for n in ("shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
                                             "wrist_2_link", "wrist_3_link")] + [("tool0", "right_hand")]:
            i, j = a.index(mine), b.index(other)
            for field in ("positions", "rotations", "linear_velocities", "angular_velocities"):
                np.testing.assert_array_equal(getattr(a, field)[i], getattr(b, field)[j], err_msg=(mine, field))


def test_shipped_ur5e_flange_against_published_dh():
    # robosuite's model gives UR's lengths to the millimetre: d1 0.163 (0.1625), d4 0.138 - 0.131 + 0.127 =
    # 0.134 (0.1333), a3 0.392 (0.3922), d5 0.1 (0.0997), d6 0.098 (0.0996). Each length error moves the
    # flange by at most itself: 0.5 + 0.7 + 0.2 + 0.3 + 1.6 = 3.3 mm. The frames are exact: its base is
    # UR's DH base turned by pi about z (as in UR's URDF, base_link), its flange the DH flange frame.
    tree = load_robot("ur5e").tree
    turn = np.diag([-1.0, -1.0, 1.0, 1.0])
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(20):
        q = rng.uniform(-3.0, 3.0, 6)
        st = tree.forward(q)
        rel = (st.pose("base").inverse() @ st.pose("tool0")).matrix
        ref = turn @ _dh(q)
        np.testing.assert_allclose(rel[:3, :3], ref[:3, :3], rtol=0, atol=1e-12)
        worst = max(worst, float(np.linalg.norm(rel[:3, 3] - ref[:3, 3])))
    assert worst <= 3.3e-3 + 1e-9
    assert worst > 5e-4  # the rounding is real: a tolerance far above it would hide a wrong length


def test_shipped_ur5e_matches_mujoco_and_its_meshes_are_robosuites():
    path = robot_path("ur5e")
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    tree = load_robot("ur5e").tree
    rng = np.random.default_rng(9)
    for _ in range(3):
        data.qpos[:] = rng.uniform(-3.0, 3.0, 6)
        mujoco.mj_kinematics(model, data)
        st = tree.forward(np.array(data.qpos))
        for name in ("forearm_link", "tool0"):
            b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
            np.testing.assert_allclose(st.positions[st.index(name)], data.xpos[b], rtol=0, atol=1e-12)
            np.testing.assert_allclose(st.rotations[st.index(name)], data.xmat[b].reshape(3, 3), rtol=0, atol=1e-12)
    # The collision meshes are robosuite's files, byte for byte, and closed.
    for stl in sorted((path.parent / "meshes").glob("*.stl")):
        assert stl.read_bytes() == (robosuite_robots_dir() / "ur5e" / "meshes" / stl.name).read_bytes()
        assert trimesh.load(stl).is_watertight, stl.name
    assert (path.parent / "LICENSE-robosuite.txt").read_text().startswith("MIT License")
