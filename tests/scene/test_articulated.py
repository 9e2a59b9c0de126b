"""Kinematic trees: forward kinematics against closed forms, velocities against finite differences."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from twinsense import ConfigError
from twinsense.errors import UnknownNameError
from twinsense.scene import Box, Mount, Oscillation, Pose, Scene
from twinsense.scene.articulated import (
    ArticulatedBody,
    Joint,
    JointConstantVelocity,
    JointKeyframes,
    JointSetpoints,
    KinematicTree,
    Link,
)

L1, L2 = 0.5, 0.3


def planar_arm(limits=(-math.inf, math.inf)) -> KinematicTree:
    """Two links in the xy-plane, both joints about +z; a frame-only tool point at the end."""
    links = [Link("base"), Link("l1", Box((L1, 0.05, 0.05)), origin=Pose((L1 / 2, 0, 0))),
             Link("l2", Box((L2, 0.05, 0.05)), origin=Pose((L2 / 2, 0, 0))), Link("tip")]
    joints = [Joint("j1", "revolute", "base", "l1", lower=limits[0], upper=limits[1]),
              Joint("j2", "revolute", "l1", "l2", Pose((L1, 0, 0)), lower=limits[0], upper=limits[1]),
              Joint("jt", "fixed", "l2", "tip", Pose((L2, 0, 0)))]
    return KinematicTree("arm", links, joints)


def spatial_tree() -> KinematicTree:
    """A branched 3-D tree: revolute joints on skew axes, a prismatic joint, a fixed joint, two branches."""
    o = Pose.from_euler_deg
    links = [Link(n) for n in ("root", "a", "b", "c", "d", "e")]
    joints = [
        Joint("ja", "revolute", "root", "a", o((0.1, 0.2, 0.3), (10, 20, 30)), axis=(1, 2, 3)),
        Joint("jb", "prismatic", "a", "b", o((0.0, 0.4, 0.1), (-30, 5, 60)), axis=(0, 1, 1), lower=-1, upper=1),
        Joint("jc", "revolute", "b", "c", o((0.3, 0.0, -0.2), (90, 0, 0)), axis=(0, 0, 1)),
        Joint("jd", "fixed", "c", "d", o((0.0, 0.0, 0.25), (0, 45, 0))),
        Joint("je", "continuous", "a", "e", o((-0.2, 0.1, 0.0), (0, 0, -70)), axis=(1, 0, 0)),
    ]
    return KinematicTree("tree", links, joints)


def test_planar_two_link_forward_kinematics_closed_form():
    tree = planar_arm()
    rng = np.random.default_rng(1)
    for _ in range(5):
        q, qd = rng.uniform(-3, 3, 2), rng.uniform(-2, 2, 2)
        st = tree.forward(q, qd)
        s1, c1 = math.sin(q[0]), math.cos(q[0])
        s12, c12 = math.sin(q[0] + q[1]), math.cos(q[0] + q[1])
        tip = [L1 * c1 + L2 * c12, L1 * s1 + L2 * s12, 0.0]
        # Tip velocity J qd of the planar arm.
        v_tip = [-(L1 * s1 + L2 * s12) * qd[0] - L2 * s12 * qd[1], (L1 * c1 + L2 * c12) * qd[0] + L2 * c12 * qd[1], 0]
        # Closed forms in double precision: a few ulp of O(1) values; 1e-12 is ~1e4 ulp.
        np.testing.assert_allclose(st.positions[3], tip, atol=1e-12)
        np.testing.assert_allclose(st.positions[2], [L1 * c1, L1 * s1, 0], atol=1e-12)
        np.testing.assert_allclose(st.rotations[3], Rotation.from_euler("z", q.sum()).as_matrix(), atol=1e-12)
        np.testing.assert_allclose(st.linear_velocities[3], v_tip, atol=1e-12)
        np.testing.assert_allclose(st.angular_velocities[3], [0, 0, qd.sum()], atol=1e-12)
        np.testing.assert_allclose(st.angular_velocities[1], [0, 0, qd[0]], atol=1e-12)
    assert tree.joint_names == ("j1", "j2")
    assert tree.limits.shape == (2, 2)


H = 1e-5  # finite-difference step [s]
# Central differences err by h^2/6 |x'''| (x''' <~ 1e2 m/s^3 or rad/s^3 for these trajectories: ~2e-9)
# plus rounding eps |x| / h (~2e-11 for O(1) positions): 1e-7 leaves a margin of ~50.
FD_TOL = 1e-7


def _fd(body: ArticulatedBody, t: float, link: str):
    p1, p0 = body.state(t + H).pose(link), body.state(t - H).pose(link)
    v = (p1.position - p0.position) / (2 * H)
    w = Rotation.from_matrix(p1.rotation @ p0.rotation.T).as_rotvec() / (2 * H)
    return v, w


def _spatial_body():
    tree = spatial_tree()
    kf = JointKeyframes([0.0, 0.7, 1.5, 2.0], [[0.0, 0.0, 0.0, 0.0], [0.8, 0.3, -1.0, 2.0],
                                              [-0.4, -0.2, 1.2, 4.0], [0.1, 0.1, 0.0, 5.0]])
    base = Oscillation(Pose.from_euler_deg((1, 0, 0.5), (0, 0, 20)), (0.05, 0.02, 0.0), 0.8, 10.0, (0.0, 0.1, 0.2))
    return ArticulatedBody("bot", tree, kf, base)


@pytest.mark.parametrize("t", [0.31, 0.95, 1.77])
def test_link_velocities_match_finite_differences(t):
    body = _spatial_body()
    st = body.state(t)
    for link in body.tree.link_names:
        v, w = _fd(body, t, link)
        np.testing.assert_allclose(st.state(link).linear_velocity, v, atol=FD_TOL)
        np.testing.assert_allclose(st.state(link).angular_velocity, w, atol=FD_TOL)


def test_point_on_link_velocity_is_v_plus_w_cross_r():
    body = _spatial_body()
    t = 1.1
    local = np.array([[0.2, -0.1, 0.4], [-0.3, 0.5, 0.05]])
    for link in ("c", "d", "e"):
        pw = body.state(t).pose(link).apply(local)
        fd = (body.state(t + H).pose(link).apply(local) - body.state(t - H).pose(link).apply(local)) / (2 * H)
        np.testing.assert_allclose(body.state(t).point_velocity(link, pw), fd, atol=FD_TOL)
        # The same through the scene: the link is an object or a mount frame and a Mount reads it.
        scene = Scene()
        scene.add_articulated(body)
        ms = Mount(Pose(local[0]), f"bot/{link}").state_at(scene, t)
        np.testing.assert_allclose(ms.linear_velocity, fd[0], atol=FD_TOL)


def test_scene_objects_and_mount_frames():
    body = ArticulatedBody("arm", planar_arm(), JointConstantVelocity([0.2, 0.4], [0.5, 0.0]),
                           Pose((0, 0, 1)))
    scene = Scene()
    objs = scene.add_articulated(body)
    assert [o.name for o in objs] == ["arm/l1", "arm/l2"]
    assert scene.frame_names == ("arm/base", "arm/tip")
    # The object frame is the link frame: the box was moved by its origin into the link frame.
    st = scene.object("arm/l2").state_at(0.0)
    np.testing.assert_allclose(st.pose.position, [L1 * math.cos(0.2), L1 * math.sin(0.2), 1.0], atol=1e-12)
    lo, hi = scene.object("arm/l2").geometry.bounds
    np.testing.assert_allclose([lo[0], hi[0]], [0.0, L2], atol=1e-12)
    with pytest.raises(ConfigError, match="arm/l1"):
        scene.add_articulated(body)  # the names are taken
    with pytest.raises(UnknownNameError, match="arm/base"):
        Mount(Pose(), "arm/nope").state_at(scene, 0.0)


def test_tree_validation_errors():
    a, b, c = Link("a"), Link("b"), Link("c")
    with pytest.raises(ConfigError, match="parent.*nope"):
        KinematicTree("t", [a, b], [Joint("j", "revolute", "nope", "b")])
    with pytest.raises(ConfigError, match="exactly one root"):
        KinematicTree("t", [a, b, c], [Joint("j", "revolute", "a", "b")])
    with pytest.raises(ConfigError, match="cycle"):  # a -> b, and c <-> d apart from the root
        KinematicTree("t", [a, b, c, Link("d")], [Joint("j1", "revolute", "a", "b"), Joint("j2", "revolute", "c", "d"),
                                                  Joint("j3", "revolute", "d", "c")])
    with pytest.raises(ConfigError, match="already child"):
        KinematicTree("t", [a, b], [Joint("j1", "revolute", "a", "b"), Joint("j2", "revolute", "a", "b")])
    with pytest.raises(ConfigError, match="kind"):
        Joint("j", "ball", "a", "b")
    with pytest.raises(ConfigError, match="axis"):
        Joint("j", "revolute", "a", "b", axis=(0, 0, 0))
    with pytest.raises(ConfigError, match="lower"):
        Joint("j", "revolute", "a", "b", lower=1.0, upper=0.0)
    with pytest.raises(ConfigError, match="lower"):
        Joint("j", "revolute", "a", "b", lower=float("nan"))
    with pytest.raises(ConfigError, match="arm.q"):
        planar_arm().forward([0.0])


def test_cycle_without_root_is_refused():
    a, b = Link("a"), Link("b")
    with pytest.raises(ConfigError, match="root"):
        KinematicTree("t", [a, b], [Joint("j1", "revolute", "a", "b"), Joint("j2", "revolute", "b", "a")])


def test_joint_limit_errors_name_joint_value_and_limits():
    tree = planar_arm(limits=(-1.0, 1.0))
    with pytest.raises(ConfigError, match=r"j2.*\[-1, 1\]"):
        tree.forward([0.0, 1.5])
    with pytest.raises(ConfigError, match=r"values\[1\]\[0\].*j1"):
        ArticulatedBody("arm", tree, JointKeyframes([0, 1], [[0, 0], [1.2, 0]]))
    # Keyframes inside the limits whose spline overshoots them: 0 -> 0.99 -> 0.99 -> 0 swings above 0.99
    # only if the middle interval bulges; a fast reversal 0.99 -> -0.99 -> 0.99 overshoots past +-1.
    with pytest.raises(ConfigError, match="overshoots"):
        ArticulatedBody("arm", tree, JointKeyframes([0, 0.1, 0.2, 0.3], [[0, 0], [0.99, 0], [-0.99, 0], [0.99, 0]]))
    body = ArticulatedBody("arm", tree, JointConstantVelocity([0.0, 0.5], [0.0, 0.25]))
    body.state(1.9)  # q2 = 0.975: inside
    # q2 = 0.5 + 0.25 t reaches 1 at t = 2 s exactly.
    with pytest.raises(ConfigError, match=r"j2.*t = 2 s"):
        body.state(2.1)
    with pytest.raises(UnknownNameError, match="j1, j2"):
        ArticulatedBody("arm", tree, JointConstantVelocity([0.0], [0.0], joint_names=["j9"]))
    with pytest.raises(ConfigError, match="one column per movable joint"):
        ArticulatedBody("arm", tree, JointConstantVelocity([0.0], [0.0]))


def test_keyframes_c1_and_hold():
    times = [0.0, 0.4, 1.0, 1.3]
    vals = [[0.0, 1.0], [0.5, -0.2], [0.1, 0.3], [-0.3, 0.0]]
    kf = JointKeyframes(times, vals)
    np.testing.assert_allclose([kf.q(t) for t in times], vals, atol=1e-12)
    h = 1e-6
    # Spline derivative against central differences: truncation h^2/6 |q'''| (|q'''| < 1e3 rad/s^3 here:
    # ~2e-10) plus rounding eps/h ~ 2e-10; 1e-7 covers both.
    for t in (0.1, 0.4, 0.77, 1.0, 1.2):
        np.testing.assert_allclose(kf.qd(t), (kf.q(t + h) - kf.q(t - h)) / (2 * h), atol=1e-7)
        # C1 at the keyframes: the velocity just left and right of a knot agrees to O(h q'') (< 1e-4).
        np.testing.assert_allclose(kf.qd(t - h), kf.qd(t + h), atol=1e-4)
    # Held before and after, with zero velocity (the clamped ends make that continuous).
    np.testing.assert_array_equal(kf.q(-5.0), vals[0])
    np.testing.assert_array_equal(kf.q(9.0), vals[-1])
    np.testing.assert_array_equal(kf.qd(9.0), [0.0, 0.0])
    np.testing.assert_allclose(kf.qd(1.3 - 1e-9), [0.0, 0.0], atol=1e-6)
    with pytest.raises(ConfigError, match="times"):
        JointKeyframes([0.0, 0.0], [[0], [1]])
    with pytest.raises(ConfigError, match="values"):
        JointKeyframes([0.0, 1.0], [[0], [float("nan")]])


def test_setpoints_follow_pushed_values():
    tree = planar_arm()
    sp = JointSetpoints([0.0, 0.0])
    body = ArticulatedBody("arm", tree, sp)
    sp.set(0.0, [0.1, 0.2], [1.0, 0.0])
    np.testing.assert_allclose(body.state(0.0).positions[2][:2], [L1 * math.cos(0.1), L1 * math.sin(0.1)],
                               atol=1e-12)
    # Between pushes the last setpoint moves on by its velocity: q1 = 0.1 + 1.0 * 0.05.
    np.testing.assert_allclose(sp.q(0.05), [0.15, 0.2], atol=1e-12)
    sp.set(0.0, [0.3, 0.2])  # same time again: replaced, and the FK cache sees the change
    np.testing.assert_allclose(body.state(0.0).positions[2][:2], [L1 * math.cos(0.3), L1 * math.sin(0.3)],
                               atol=1e-12)
    with pytest.raises(ConfigError, match="setpoints.t"):
        sp.set(-1.0, [0.0, 0.0])
    short = JointSetpoints([0.0], history=2)
    for t in (0.0, 1.0, 2.0):
        short.set(t, [t])
    assert short.q(1.5)[0] == 1.0  # the setpoint at 1 s, held (no velocity given)
    with pytest.raises(ConfigError, match="oldest kept setpoint"):
        short.q(0.5)  # the 0 s setpoint is gone: refused rather than answered from q0
