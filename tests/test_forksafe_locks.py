"""Every long-lived lock outside the render layer is a ForkSafeLock: a child forked while another
thread holds one (a capture thread mid-frame when ``simulate(processes=N)`` forks) computes as the
parent instead of hanging on it. Each case holds the lock in another thread, forks, and runs in the
child the call that takes it; the result must equal the parent's (the guard of ``in_forked_child``
kills a hung child after 120 s and fails the test).
"""

import sys
from pathlib import Path

import numpy as np

from twinsense.forksafe import ForkSafeLock
from twinsense.radar import spreader
from twinsense.robots import xacro_files
from twinsense.scene import ArticulatedBody, Joint, JointKeyframes, KinematicTree, Link, Pose

sys.path.insert(0, str(Path(__file__).parent / "render"))
from test_forksafe import held_by_another_thread, in_forked_child


def _arm() -> ArticulatedBody:
    tree = KinematicTree("arm", [Link("base"), Link("upper")],
                         [Joint("j", "revolute", "base", "upper", Pose((0, 0, 0.4)), axis=(0, 1, 0))])
    return ArticulatedBody("arm", tree, JointKeyframes([0, 1], [[0.0], [1.0]]))


def test_the_locks_are_fork_safe():
    body = _arm()
    for lock in (body._lock, spreader._KERNELS_LOCK, xacro_files._LOCK):
        assert isinstance(lock, ForkSafeLock)


def test_an_articulated_bodys_states_in_a_child_forked_while_another_thread_holds_its_lock():
    body = _arm()
    with held_by_another_thread(body._lock):
        # A time the parent has not asked for: the child's state() takes the lock for the cache.
        got = in_forked_child(lambda: body.state(0.37).pose("upper").matrix)
    np.testing.assert_array_equal(got, body.state(0.37).pose("upper").matrix)


def test_the_radar_spreaders_kernel_in_a_child_forked_while_another_thread_holds_its_lock():
    want = spreader.kernel_for(513, 1e-6).coef
    with held_by_another_thread(spreader._KERNELS_LOCK):
        got = in_forked_child(lambda: spreader.kernel_for(515, 1e-6).coef)  # a new size: takes the lock
    assert got.shape[1] == want.shape[1]
