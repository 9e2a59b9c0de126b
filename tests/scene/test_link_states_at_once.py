"""Every link's state built at once per time, and the newest state returned again without its checks.

``TreeState`` builds every link's pose and state at the first ask (one stacked SVD, one read-only copy of
the positions and velocities); ``ArticulatedBody.state`` returns its newest state again when asked at the
same time (each link of a body asks in turn). Compared bit for bit with the checked constructor and the
kernel's rows; a bad time is still refused and a new joint setpoint still gives a new state.
"""

import numpy as np
import pytest

from twinsense import Pose
from twinsense.errors import ConfigError
from twinsense.robots import load_robot
from twinsense.scene import JointKeyframes, JointSetpoints, Scene
from twinsense.scene.human import Walk, add_person


def test_link_states_are_rows_of_the_kernel_output_read_only():
    ur5 = load_robot("ur5", joints=JointKeyframes((0.0, 2.0), ((0.0,) * 6, (0.5, -1.2, 1.4, -0.7, 1.1, 0.3))))
    st = ur5.state(0.7)
    for i in range(len(st.link_names)):
        ms = st.state(i)
        assert ms.pose.position.tobytes() == Pose(st.positions[i], st.rotations[i]).position.tobytes()
        assert ms.pose.rotation.tobytes() == Pose(st.positions[i], st.rotations[i]).rotation.tobytes()
        assert ms.linear_velocity.tobytes() == st.linear_velocities[i].tobytes()
        assert ms.angular_velocity.tobytes() == st.angular_velocities[i].tobytes()
        for a in (ms.pose.position, ms.pose.rotation, ms.linear_velocity, ms.angular_velocity):
            assert not a.flags.writeable
            with pytest.raises(ValueError):
                a[...] = 0.0
        # The kernel's arrays stay the caller's (writable, not views of the states' copies).
        assert not np.shares_memory(ms.pose.position, st.positions)
        assert not np.shares_memory(ms.linear_velocity, st.linear_velocities)


def test_the_same_time_returns_the_newest_state_and_bad_times_are_still_refused():
    s = Scene()
    add_person(s, "p", 1.75, (1.0, -2.0), walk=Walk(1.2, path=((0.5, 0.0),)))
    person = s.object("p/thorax").motion.body
    a = person.state(0.5)
    assert person.state(0.5) is a
    assert person.state(np.float64(0.5)) is a  # a float subclass equal to the time
    zero = person.state(0)  # an int: checked as before, another time, another state
    assert zero is not a and person.state(0.0) is zero
    for bad in (float("nan"), float("inf"), "0.5", None):
        with pytest.raises(ConfigError):
            person.state(bad)
    b = person.state(0.75)
    assert b is not a and person.state(0.5) is a  # older times from the cache


def test_a_new_setpoint_at_the_same_time_gives_a_new_state():
    ur5 = load_robot("ur5", joints=JointSetpoints(np.zeros(6)))
    first = ur5.state(1.0)
    assert ur5.state(1.0) is first
    ur5.joint_motion.set(1.0, np.full(6, 0.3))
    second = ur5.state(1.0)
    assert second is not first
    assert not np.array_equal(second.positions, first.positions)
