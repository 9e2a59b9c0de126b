"""Every URDF example-robot-data installs: twinsense's forward kinematics against yourdfpy's own.

yourdfpy builds a trimesh scene graph of the same file and multiplies its 4 x 4 joint
transforms (trimesh's axis-angle matrices) along the path root -> link; twinsense's compiled
kernel turns 3 x 3 Rodrigues rotations down its own tree order. The two share only the parsed
``<origin>`` matrices, so they agree to rounding only if joint kinds, axes, signs, limits,
the root, mimic joints and the tree order are all read the same way.

Each robot is loaded once per module (``shapes="collision"``: the kinematics do not depend on
the shapes, and the collision meshes of all 68 files load in ~9 s, the visual ones in ~31 s); the
whole file runs in 10-12 s on the shared 2-core test machine. A 1e-12 m change of one joint origin of
the UR5 moves its links by 8e-13 m against the pose tolerance of 6.7e-14 m: the check would see it.
"""

import functools
import math
import warnings
import zlib

import numpy as np
import pytest
import yourdfpy

from twinsense.errors import ConfigError
from twinsense.robots import load_urdf
from twinsense.robots.paths import example_robot_data_share
from twinsense.robots.urdf import urdf_tree

ROBOTS = example_robot_data_share() / "robots"
#: Not loadable on purpose: an empty xacro stub, and visual meshes at absolute paths of the authors' machine
#: (/usr/Romeo; its collision meshes are package paths, so its kinematics are checked below all the same).
STUB = "ur_description/urdf/ur3.urdf"
ABSOLUTE_MESHES = "romeo_description/urdf/romeo_laas_small.urdf"
FILES = sorted(str(p.relative_to(ROBOTS)) for p in ROBOTS.rglob("*.urdf") if str(p.relative_to(ROBOTS)) != STUB)

EPS = np.finfo(float).eps
# Pose tolerance [ulp of the largest coordinate]. Per joint each side rounds a 3 x 3 product (3 terms), the joint
# rotation (Rodrigues against trimesh's I cos + (1 - cos) a a^T + sin [a]x) and a position sum: <= ~10 eps of the
# largest coordinate (or of 1 for rotation entries). These files chain at most 21 joints (TIAGo: base to
# fingertip, 15 of them movable), so worst-case linear growth is ~210 ulps; 300 covers it. Seen: <= 7 ulps.
POSE_ULPS = 300
# Central-difference step along s in q + s qd [rad or m per (rad/s or m/s)]; see _velocity_tolerance.
H = 1e-6
CONFIGS = 3


@functools.cache
def _pair(rel: str):
    """(twinsense tree, yourdfpy URDF with its scene graph) of one file, parsed once per module."""
    path = ROBOTS / rel
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tree = urdf_tree(path, shapes="collision")
    # Only a mimic joint whose master the file lacks is warned about (see _orphans), and each is.
    named = {str(w.message).split("joint ")[1].split(" mimics")[0].strip("'") for w in caught}
    orphans = {j.name for j in tree.joints if j.name in tree.joint_names and j.mimic is None} & named
    assert all(issubclass(w.category, UserWarning) and "which the file does not have" in str(w.message)
               for w in caught), [str(w.message) for w in caught]
    assert orphans == named, (orphans, named)
    ref = yourdfpy.URDF.load(str(path), build_scene_graph=True, load_meshes=False,
                             build_collision_scene_graph=False, load_collision_meshes=False)
    return tree, ref


def _orphans(tree, ref) -> dict:
    """{twinsense q column: offset} of the mimic joints whose master the file lacks.

    Both follow a mimic joint's master (multiplier * q_master + offset: twinsense in its kinematics kernel,
    so a mimic joint is no column of q). A master the file lacks (alex_psyonic_hands.urdf's finger joints
    name "index_q1", ... while its joints are "Left_index_q1", ...) makes yourdfpy hold the joint at 0 +
    offset (with a logged warning) and twinsense drive it as a joint of its own (with a UserWarning): the
    test sets it to the offset.
    """
    return {tree.joint_index(j.name): float(j.mimic.offset or 0.0) for j in ref.robot.joints
            if j.mimic is not None and j.name in tree.joint_names}


def _sample(tree, ref, rng, margin: float):
    """(q, qd, cfg): driven joint values within the limits ([-pi, pi] for unlimited ones) and velocities in
    [-1, 1] [rad/s or m/s] such that q +- margin qd stays within every limit, the orphaned mimic joints at their
    offsets; cfg is yourdfpy's configuration (its actuated joints). Mimic joints' own limits bind neither
    library (ROS computes a mimic joint from its master alone): the PR2's grippers open fully here."""
    lo, hi = tree.limits[:, 0], tree.limits[:, 1]
    orphans = _orphans(tree, ref)
    a, b = np.maximum(lo, -math.pi), np.minimum(hi, math.pi)
    free = b - a > 2.0 * margin
    q = np.where(free, rng.uniform(np.where(free, a + margin, 0.0), np.where(free, b - margin, 0.0)), 0.5 * (a + b))
    qd = np.where(free, rng.uniform(-1.0, 1.0, tree.n_joints), 0.0)  # a joint locked by its limits stays still
    for i, off in orphans.items():
        q[i], qd[i] = off, 0.0
    actuated = set(ref.actuated_joint_names)
    cfg = {n: q[i] for i, n in enumerate(tree.joint_names) if n in actuated}
    return q, qd, cfg


def _rng(rel: str, salt: int) -> np.random.Generator:
    # One stream per file and test, whatever the order pytest runs them in.
    return np.random.default_rng([zlib.crc32(rel.encode()), salt])


def test_the_installed_urdf_files_are_all_here():
    # The parametrisation below is read from disk: an install that lost files would shrink it silently.
    assert len(FILES) == 68, FILES
    with pytest.raises(ConfigError, match=r"urdf.path.*xacro"):
        urdf_tree(ROBOTS / STUB)
    with pytest.raises(ConfigError, match=r"/usr/Romeo"):
        load_urdf(ROBOTS / ABSOLUTE_MESHES)


@pytest.mark.parametrize("rel", FILES)
def test_link_poses_match_yourdfpy(rel):
    tree, ref = _pair(rel)
    assert tree.root == ref.base_link
    assert set(tree.link_names) == set(ref.link_map)
    movable = [j.name for j in ref.robot.joints if j.type in ("revolute", "continuous", "prismatic")]
    # Floating joints are fixed in twinsense (none in these files); mimic joints follow their masters.
    assert tree.joint_names == tuple(n for n in movable if n not in tree.mimic_joints)
    mimics = {j.name for j in ref.robot.joints if j.mimic is not None and j.name in movable}  # Talos: fixed ones
    assert set(tree.mimic_joints) == mimics - set(tree.joint_names)
    rng = _rng(rel, 1)
    for _ in range(CONFIGS):
        q, _, cfg = _sample(tree, ref, rng, 0.0)
        ref.update_cfg(cfg)
        st = tree.forward(q)
        want = np.array([ref.get_transform(frame_to=n, frame_from=ref.base_link) for n in tree.link_names])
        got = np.array([st.pose(n).matrix for n in tree.link_names])
        length = max(1.0, float(np.abs(want[:, :3, 3]).max()))  # [m]
        np.testing.assert_allclose(got[:, :3, 3], want[:, :3, 3], rtol=0, atol=POSE_ULPS * EPS * length)
        np.testing.assert_allclose(got[:, :3, :3], want[:, :3, :3], rtol=0, atol=POSE_ULPS * EPS)


def _velocity_tolerance(positions, qd) -> float:
    """Bound on |central difference - derivative| [m/s or rad/s] for step H along q + s qd.

    Truncation: H^2 / 6 |d3p/ds3|. A point at lever arm <= r from the joints' axes, moved by joints at rates
    summing to w = sum |qd|, has |d3p/ds3| <= r w^3 (each derivative brings one rate; prismatic rates in m/s
    count against r >= 1 m). r <= 2 max(1 m, max |p|): an axis point and a link origin each lie within max |p|
    of the root. Rounding: each pose is within the pose tolerance (POSE_ULPS eps r) of exact, the difference
    divided by 2 H: POSE_ULPS eps r / H. Rotations (entries <= 1, r = 1) give the smaller angular bound.
    """
    r = 2.0 * max(1.0, float(np.abs(positions).max()))
    w = float(np.abs(qd).sum())
    return r * w**3 * H**2 / 6.0 + POSE_ULPS * EPS * r / H


@pytest.mark.parametrize("rel", FILES)
def test_link_velocities_match_central_differences(rel):
    tree, ref = _pair(rel)
    rng = _rng(rel, 2)
    for _ in range(2):
        q, qd, _ = _sample(tree, ref, rng, H)
        st = tree.forward(q, qd)
        fwd, bwd = tree.forward(q + H * qd), tree.forward(q - H * qd)
        tol = _velocity_tolerance(st.positions, qd)
        v = (fwd.positions - bwd.positions) / (2.0 * H)
        np.testing.assert_allclose(st.linear_velocities, v, rtol=0, atol=tol)
        # dR/ds = [w]x R: the skew part of (R(+H) - R(-H)) / 2H R(0)^T is [w]x.
        m = (fwd.rotations - bwd.rotations) / (2.0 * H) @ np.swapaxes(st.rotations, 1, 2)
        w = 0.5 * np.stack([m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]], axis=1)
        np.testing.assert_allclose(st.angular_velocities, w, rtol=0, atol=tol)


_JOINT_KINDS_URDF = """<robot name="kinds">
  <link name="world"/><link name="base"/><link name="arm"/><link name="finger_a"/><link name="finger_b"/>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.4" rpy="0 0.3 0"/><axis xyz="0 0.6 0.8"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="slide_a" type="prismatic"><parent link="arm"/><child link="finger_a"/>
    <origin xyz="0.5 0 0"/><axis xyz="1 0 0"/><limit lower="0" upper="0.05" effort="1" velocity="1"/></joint>
  <joint name="slide_b" type="prismatic"><parent link="arm"/><child link="finger_b"/>
    <origin xyz="0.5 0 0"/><axis xyz="0 1 0"/><limit lower="-0.1" upper="0.1" effort="1" velocity="1"/>
    <mimic joint="slide_a" multiplier="-2" offset="0.01"/></joint>
  <joint name="float" type="{base_kind}"><parent link="world"/><child link="base"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.2 -0.1 0.4"/></joint>
</robot>"""
# The floating joint comes last on purpose: yourdfpy 0.0.60 reads a mimic joint's master at the master's index
# among the actuated joints but indexes its dof vector with it, so a floating joint (several dofs there) declared
# before the master makes it read a dof of the floating joint (here 0) instead.


def test_floating_base_mimic_and_planar_joints(tmp_path):
    # A floating joint is taken as fixed at its origin (as yourdfpy's scene graph does), a mimic joint follows
    # its master (multiplier * q_master + offset, outside its own limits too), a planar joint is refused by name.
    path = tmp_path / "kinds.urdf"
    path.write_text(_JOINT_KINDS_URDF.format(base_kind="floating"))
    tree = load_urdf(path).tree
    ref = yourdfpy.URDF.load(str(path), build_scene_graph=True, load_meshes=False)
    assert tree.joint_names == ("shoulder", "slide_a") and tree.mimic_joints == ("slide_b",)
    rng = np.random.default_rng(4)
    for _ in range(CONFIGS):
        q, qd, cfg = _sample(tree, ref, rng, 0.0)
        ref.update_cfg(cfg)
        st = tree.forward(q, qd)
        # slide_b = -2 slide_a + 0.01 along y of the arm frame, its rate -2 qd_a: exact in binary64 up to the
        # rounding of the one product and sum (the finger's offset from finger_a's origin: 0.5 ulp each).
        rel = st.pose("arm").inverse() @ st.pose("finger_b")
        np.testing.assert_allclose(rel.position, [0.5, -2.0 * q[1] + 0.01, 0.0], rtol=0, atol=4 * EPS)
        vb = st.pose("arm").rotation.T @ (st.linear_velocities[st.index("finger_b")]
                                          - st.point_velocity("arm", st.positions[[st.index("finger_b")]])[0])
        np.testing.assert_allclose(vb, [0.0, -2.0 * qd[1], 0.0], rtol=0, atol=8 * EPS)
        for n in tree.link_names:
            # Three joints deep, coordinates < 1 m: the POSE_ULPS bound above holds with room.
            np.testing.assert_allclose(st.pose(n).matrix, ref.get_transform(frame_to=n, frame_from="world"),
                                       rtol=0, atol=POSE_ULPS * EPS)
    path.write_text(_JOINT_KINDS_URDF.format(base_kind="planar"))
    with pytest.raises(ConfigError, match=r"joints\[float\]\.type = 'planar'.*planar joints are not supported"):
        load_urdf(path)
