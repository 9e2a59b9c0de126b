"""Mimic joints (URDF ``<mimic>``): a joint that follows another, q = m q_master + o, qd = m qd_master.

The reference is the same tree without the mimic relation, its follower set by hand: both run the
same compiled kernel, so the follower's value m q + o (one product and one sum in binary64) is the
only difference, and the poses agree to a few ulps. Velocities are also checked against central
differences of the poses (an independent route through the mimic's multiplier).
"""

import math

import numpy as np
import pytest

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.scene import ArticulatedBody, Joint, JointKeyframes, KinematicTree, Link, Mimic, Pose

EPS = np.finfo(float).eps


def _tree(mimic_b: Mimic | None, mimic_c: Mimic | None = None) -> KinematicTree:
    links = [Link(n) for n in ("base", "arm", "left", "right", "tip")]
    joints = [
        Joint("a", "revolute", "base", "arm", Pose.from_rotvec((0, 0, 0.4), (0.1, 0.2, 0.3)), axis=(0, 0.6, 0.8),
              lower=-2, upper=2),
        Joint("b", "prismatic", "arm", "left", Pose((0.5, 0, 0)), axis=(0, 1, 0), lower=0.0, upper=0.04,
              mimic=mimic_b),
        Joint("s", "prismatic", "arm", "right", Pose((0.5, 0, 0)), axis=(0, 1, 0), lower=-0.04, upper=0.0),
        Joint("c", "revolute", "right", "tip", Pose((0.1, 0, 0)), axis=(1, 0, 0), lower=-1, upper=1,
              mimic=mimic_c),
    ]
    return KinematicTree("grip", links, joints)


def test_a_mimic_joint_follows_its_master_exactly():
    tree = _tree(Mimic("s", -1.0, 0.002))
    plain = _tree(None)
    assert tree.joint_names == ("a", "s", "c") and tree.mimic_joints == ("b",)
    assert plain.joint_names == ("a", "b", "s", "c")
    rng = np.random.default_rng(7)
    for _ in range(5):
        qa, qs, qc = rng.uniform(-1.5, 1.5), rng.uniform(-0.04, 0.0), rng.uniform(-1, 1)
        qda, qds, qdc = rng.uniform(-1, 1, 3)
        st = tree.forward([qa, qs, qc], [qda, qds, qdc])
        ref = plain.forward([qa, -qs + 0.002, qs, qc], [qda, -qds, qds, qdc])
        # The same kernel on the same values: m q + o is computed as the reference's -qs + 0.002.
        np.testing.assert_array_equal(st.positions, ref.positions)
        np.testing.assert_array_equal(st.rotations, ref.rotations)
        np.testing.assert_array_equal(st.linear_velocities, ref.linear_velocities)
        np.testing.assert_array_equal(st.angular_velocities, ref.angular_velocities)


def test_mimic_velocities_match_central_differences():
    tree = _tree(Mimic("s", -2.5, 0.01), Mimic("b", 3.0, -0.1))  # c follows b follows s: c = 3 (-2.5 s + 0.01) - 0.1
    assert tree.mimic_joints == ("b", "c")
    q, qd, h = np.array([0.3, -0.02]), np.array([0.4, 0.7]), 1e-6
    st = tree.forward(q, qd)
    fwd, bwd = tree.forward(q + h * qd), tree.forward(q - h * qd)
    # Truncation h^2 / 6 |p'''| <= h^2 r w^3 / 6 with r < 2 m and w = |qd_a| + |m_c m_b qd_s| < 6: ~1e-10;
    # rounding ~eps / h ~ 2e-10. 1e-8 bounds both with room.
    np.testing.assert_allclose(st.linear_velocities, (fwd.positions - bwd.positions) / (2 * h), rtol=0, atol=1e-8)
    m = (fwd.rotations - bwd.rotations) / (2 * h) @ np.swapaxes(st.rotations, 1, 2)
    w = 0.5 * np.stack([m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]], axis=1)
    np.testing.assert_allclose(st.angular_velocities, w, rtol=0, atol=1e-8)
    # The chain composes: the tip turns by 3 (-2.5 q_s + 0.01) - 0.1 about x of the right finger.
    rel = st.pose("right").inverse() @ st.pose("tip")
    angle = 3.0 * (-2.5 * q[1] + 0.01) - 0.1
    np.testing.assert_allclose(rel.rotation, Pose.from_rotvec((0, 0, 0), (angle, 0, 0)).rotation, rtol=0,
                               atol=8 * EPS)


def test_a_mimic_joints_own_limits_are_not_checked():
    # b = -s + 0.002 leaves b's [0, 0.04] for s > 0.002: allowed (ROS computes a mimic joint from its master).
    tree = _tree(Mimic("s", -1.0, 0.002))
    st = tree.forward([0.0, -0.0, 0.0])
    assert np.isfinite(st.positions).all()
    with pytest.raises(ConfigError, match=r"joints\[s\].*limits"):
        tree.forward([0.0, 0.01, 0.0])  # the driven joint's own limits still hold


def test_mimic_errors_name_the_joint():
    with pytest.raises(ConfigError, match=r"grip\.joints\[b\]\.mimic\.joint = 'nope'.*a, s, c"):
        _tree(Mimic("nope"))
    with pytest.raises(ConfigError, match=r"joints\[b\]\.mimic.*b -> c -> b.*not a cycle"):
        _tree(Mimic("c"), Mimic("b"))
    with pytest.raises(ConfigError, match=r"joints\[b\]\.mimic\.joint = 'b'.*another joint"):
        _tree(Mimic("b"))
    with pytest.raises(ConfigError, match=r"mimic\.multiplier = nan.*finite"):
        Mimic("a", math.nan)
    with pytest.raises(ConfigError, match=r"joints\[f\]\.mimic.*None for a fixed joint"):
        Joint("f", "fixed", "x", "y", mimic=Mimic("a"))
    with pytest.raises(ConfigError, match=r"joints\[b\]\.mimic.*a twinsense Mimic"):
        Joint("b", "revolute", "x", "y", mimic="a")
    tree = _tree(Mimic("s", -1.0, 0.002))
    with pytest.raises(UnknownNameError):
        tree.joint_index("b")


def test_a_motions_mimic_columns_are_not_used():
    # A recorded /joint_states lists a gripper's mimic finger too: as ROS, the body warns and lets the
    # finger follow its master; that column's values (here outside b's own limits) are neither used nor
    # checked, the driven columns are checked as usual.
    tree = _tree(Mimic("s", -1.0, 0.002))
    motion = JointKeyframes([0, 1], [[0.5, -0.9, -0.01], [0.5, 0.9, -0.03]], joint_names=["b", "a", "s"])
    with pytest.warns(UserWarning, match=r"grip: the joint motion's columns \['b'\] are mimic joints"):
        body = ArticulatedBody("grip", tree, motion)
    q, qd = body.joint_state(0.5)
    want_q, want_qd = motion.q_qd(0.5)
    np.testing.assert_array_equal(q, [want_q[1], want_q[2], tree.home[2]])  # a, s driven; c at home
    np.testing.assert_array_equal(qd, [want_qd[1], want_qd[2], 0.0])
    st, ref = body.state(0.5), _tree(None).forward([q[0], -q[1] + 0.002, q[1], q[2]],
                                                   [qd[0], -qd[1], qd[1], qd[2]])
    np.testing.assert_array_equal(st.positions, ref.positions)
    bad = JointKeyframes([0, 1], [[0.5, 0.0, -0.01], [0.5, 0.0, 0.05]], joint_names=["b", "a", "s"])
    with pytest.raises(ConfigError, match=r"keyframes\.values\[1\]\[2\].*'s'"):
        ArticulatedBody("grip", tree, bad)  # s above its upper limit 0: still refused
