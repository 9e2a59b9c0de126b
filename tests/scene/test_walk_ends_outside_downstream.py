"""What uses a walk's start and closing steps: a reach during the closing steps, a person built twice, and
two threads asking one person at different times.

References written out here: the hand target taken from the same person without the reach at the hand's
arrival (the arm is a rigid chain on the thorax, solved in the thorax frame then: on the target to
rounding, bound 1e-9 m), the bytes of a second build, and the states one thread computes alone.
"""

import threading
import warnings

import numpy as np
import pytest

from twinsense.scene.human import Reach, Walk, person_body

H = 1.75
HAND_CENTRE = np.array([0.0, 0.0, -0.5 * 0.108 * H])  # half of Winter's hand length 0.108 H below the wrist
LOCAL = np.array([0.4, 0.1, 0.0])  # thorax frame: forward, left, up from the left shoulder [m]
WALK = Walk(1.3, path=((2.0, 1.0), (2.5, 2.6)), start_time=-0.3)


@pytest.mark.parametrize(("after_arrival", "duration"), [(0.05, 0.3), (0.1, 0.5), (0.3, 1.0)])
def test_a_reach_that_starts_during_the_closing_steps_lands_on_its_target(after_arrival, duration):
    plain = person_body("p", H, (0.0, 0.0), 20.0, walk=WALK)
    start = plain.joint_motion.person.arrival_time + after_arrival
    arrive = start + duration  # in the first step, the second, after the stop
    ref = plain.state(arrive)
    target = ref.pose("left_shoulder").position + ref.pose("thorax").rotation @ LOCAL
    body = person_body("p", H, (0.0, 0.0), 20.0, walk=WALK, reach=Reach(tuple(target), start, duration, 0.5, "left"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # reachable: no short-reach warning
        hand = body.state(arrive).pose("left_hand").apply(HAND_CENTRE[None])[0]
    np.testing.assert_allclose(hand, target, rtol=0, atol=1e-9)  # measured < 1e-15 m


def _times(person):
    t0, ta = person.walk.start_time, person.arrival_time
    return np.concatenate([np.linspace(t0 - 0.05, t0 + 0.65, 71), np.linspace(ta - 0.05, person.stop_time + 0.05, 91)])


def _bytes(body, times):
    out = []
    for t in times:
        s = body.state(float(t))
        out += [s.positions.tobytes(), s.rotations.tobytes(), s.linear_velocities.tobytes(),
                s.angular_velocities.tobytes()]
    return b"".join(out)


def test_a_person_built_twice_is_the_same_bytes():
    a = person_body("p", 1.81, (0.3, -0.2), 30.0, sway=0.02, walk=WALK)
    b = person_body("p", 1.81, (0.3, -0.2), 30.0, sway=0.02, walk=WALK)
    times = _times(a.joint_motion.person)
    assert _bytes(a, times) == _bytes(b, times)


def test_two_threads_at_different_times_get_the_one_thread_states():
    one = person_body("p", 1.66, (0.0, 0.0), 0.0, sway=0.01, walk=WALK)
    person = one.joint_motion.person
    times = _times(person)
    ref = {float(t): (person.q(float(t)), person.qd(float(t)), person.base_state(float(t)).pose.position.copy(),
                      person.base_state(float(t)).linear_velocity.copy()) for t in times}
    shared = person_body("p", 1.66, (0.0, 0.0), 0.0, sway=0.01, walk=WALK).joint_motion.person
    bad = []

    def ask(sub):
        # Each thread asks its own times (interleaved through the start ramp and the closing steps), so the
        # person's one-state cache is replaced by the other thread between a test and a read.
        for _ in range(3):
            for t in sub:
                q, qd, base = shared._at(float(t))
                r = ref[float(t)]
                if not (np.array_equal(q, r[0]) and np.array_equal(qd, r[1])
                        and np.array_equal(base.pose.position, r[2]) and np.array_equal(base.linear_velocity, r[3])):
                    bad.append(float(t))

    threads = [threading.Thread(target=ask, args=(times[i::2],)) for i in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert bad == []
