"""Link poses of a kinematic state: every link's rotation re-orthonormalised in one stacked SVD.

``TreeState.pose`` builds all links' rotations at the first ask with NumPy's stacked SVD and
matmul (LAPACK and BLAS per matrix, as for one matrix). The poses must be the bits of
``Pose._trusted`` (and so of ``Pose(...)``) link by link: compared with ``tobytes`` (no
tolerance: the same floating-point operations on the same numbers).
"""

import numpy as np

from twinsense import Pose
from twinsense.demos.robot_cell import PERSON, build_arm_cell_scene
from twinsense.robots import load_robot


def bits_equal(a: Pose, b: Pose) -> bool:
    return a.position.tobytes() == b.position.tobytes() and a.rotation.tobytes() == b.rotation.tobytes()


def test_ur5_link_poses_are_the_bits_of_one_pose_per_link():
    body = load_robot("ur5")
    tree = body.tree
    rng = np.random.default_rng(3)
    lo, hi = tree.limits[:, 0], tree.limits[:, 1]
    for _ in range(50):
        q = rng.uniform(np.maximum(lo, -6.0), np.minimum(hi, 6.0))
        base = Pose(rng.normal(size=3), Pose.from_euler_deg(rpy_deg=rng.uniform(-180, 180, 3)).rotation)
        st = tree.forward(q, rng.normal(size=tree.n_joints), base)
        # Asked in a shuffled order: the first ask builds every link's rotation.
        for i in rng.permutation(len(tree.link_names)):
            pose = st.pose(int(i))
            assert bits_equal(pose, Pose._trusted(st.positions[i], st.rotations[i]))
            assert bits_equal(pose, Pose(st.positions[i], st.rotations[i]))
            assert not pose.rotation.flags.writeable and not pose.position.flags.writeable
            assert st.pose(int(i)) is pose  # built once per link and state


def test_walking_person_segment_poses_are_the_bits_of_one_pose_per_segment():
    # The robot cell's person: standing, walking, turning and reaching over these times.
    person = build_arm_cell_scene().object(f"{PERSON}/thorax").motion.body
    for t in np.linspace(0.0, 4.0, 17):
        st = person.state(float(t))
        for i in range(len(st.link_names)):
            assert bits_equal(st.pose(i), Pose._trusted(st.positions[i], st.rotations[i]))
