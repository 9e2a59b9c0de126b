"""An articulated body whose joint motion or base is replaced after states were asked for, and
copies of bodies and scenes (pickle).

The forward kinematics are cached by time (and the joint motion's version); a replaced motion
or base must never be served the old one's states. References: the closed form of the planar
arm's tip (x = L1 cos q1 + L2 cos(q1 + q2), y = L1 sin q1 + L2 sin(q1 + q2)) and a fresh body.
Poses are the same float64 operations in either body: compared to 1e-12 m (rounding of a few
products of unit vectors and lengths below 1 m is ~1e-16 m).
"""

from __future__ import annotations

import math
import pickle
import threading

import numpy as np
import pytest
from test_articulated import L1, L2, planar_arm

from twinsense import ConfigError
from twinsense.scene import Pose, Scene
from twinsense.scene.articulated import ArticulatedBody, JointConstantVelocity, JointSetpoints


def _tip(q1, q2):
    return np.array([L1 * math.cos(q1) + L2 * math.cos(q1 + q2), L1 * math.sin(q1) + L2 * math.sin(q1 + q2), 0.0])


def test_a_replaced_joint_motion_is_served_its_own_states():
    body = ArticulatedBody("arm", planar_arm(), JointSetpoints([0.3, -0.2]))
    t = 0.5
    np.testing.assert_allclose(body.state(t).pose("tip").position, _tip(0.3, -0.2), rtol=0, atol=1e-12)
    body.joint_motion = JointSetpoints([1.1, 0.4])  # the same version (0) as the old motion
    np.testing.assert_allclose(body.state(t).pose("tip").position, _tip(1.1, 0.4), rtol=0, atol=1e-12)
    fresh = ArticulatedBody("arm", planar_arm(), JointSetpoints([1.1, 0.4]))
    assert body.state(t).pose("tip").position.tobytes() == fresh.state(t).pose("tip").position.tobytes()


def test_a_replaced_base_is_served_its_own_states():
    body = ArticulatedBody("arm", planar_arm(), JointSetpoints([0.0, 0.0]))
    t = 0.25
    body.state(t)
    body.base = Pose((1.0, 2.0, 3.0))
    np.testing.assert_allclose(body.state(t).pose("tip").position, _tip(0.0, 0.0) + np.array([1.0, 2.0, 3.0]),
                               rtol=0, atol=1e-12)


def test_a_replacement_is_checked_as_at_construction_and_a_refused_one_changes_nothing():
    body = ArticulatedBody("arm", planar_arm(), JointSetpoints([0.5, 0.5]))
    before = body.state(0.0).pose("tip").position.copy()
    with pytest.raises(ConfigError) as err:
        body.joint_motion = JointSetpoints([0.5, 0.5, 0.5])  # three columns for two joints
    assert err.value.field == "arm.joints"
    with pytest.raises(ConfigError) as err:
        body.base = "origin"
    assert err.value.field == "arm.base"
    assert body.state(0.0).pose("tip").position.tobytes() == before.tobytes()


def test_a_state_made_while_the_motion_is_replaced_is_not_kept():
    # A thread computing with the old motion finishes after the replacement: its state is
    # returned to it but not kept for later askers.
    class Slow(JointConstantVelocity):
        def q_qd(self, t):
            started.set()
            go.wait(5.0)
            return super().q_qd(t)

    started, go = threading.Event(), threading.Event()
    body = ArticulatedBody("arm", planar_arm(), Slow([0.3, -0.2], [0.0, 0.0]))
    th = threading.Thread(target=body.state, args=(0.5,))
    th.start()
    assert started.wait(5.0)
    body.joint_motion = JointSetpoints([1.1, 0.4])
    go.set()
    th.join(5.0)
    np.testing.assert_allclose(body.state(0.5).pose("tip").position, _tip(1.1, 0.4), rtol=0, atol=1e-12)


def test_bodies_and_scenes_with_bodies_pickle_and_the_copy_moves_as_the_original():
    body = ArticulatedBody("arm", planar_arm(), JointConstantVelocity([0.1, 0.2], [0.5, -0.25]))
    scene = Scene()
    scene.add_articulated(body)
    for t in (0.0, 0.4):
        body.state(t)  # kept states are not part of the copy
    copy = pickle.loads(pickle.dumps(scene))
    for t in (0.0, 0.4, 1.3):
        for o, c in zip(scene.objects, copy.objects, strict=True):
            assert o.name == c.name
            a, b = o.state_at(t), c.state_at(t)
            assert a.pose.position.tobytes() == b.pose.position.tobytes()
            assert a.linear_velocity.tobytes() == b.linear_velocity.tobytes()
    q1, q2 = 0.1 + 0.5 * 1.3, 0.2 - 0.25 * 1.3
    tip = pickle.loads(pickle.dumps(body)).state(1.3).pose("tip").position
    np.testing.assert_allclose(tip, _tip(q1, q2), rtol=0, atol=1e-12)
