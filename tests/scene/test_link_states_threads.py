"""Link states asked from several threads at once, and a setpoint pushed at the time being read: every
state is the bits of one thread's forward kinematics at that time and joint values (real threads, a real
robot file)."""

import threading

import numpy as np

from twinsense.robots import load_robot
from twinsense.scene import JointKeyframes, JointSetpoints


def _bytes(st) -> list[bytes]:
    return [b for i in range(len(st.link_names)) for b in (st.state(i).pose.position.tobytes(),
                                                         st.state(i).pose.rotation.tobytes(),
                                                         st.state(i).linear_velocity.tobytes())]


def test_threads_asking_for_the_same_times_at_once_get_the_one_thread_bits():
    q1 = (0.5, -1.2, 1.4, -0.7, 1.1, 0.3)
    times = [0.01 * k for k in range(60)]
    ref = load_robot("ur5", joints=JointKeyframes((0.0, 2.0), ((0.0,) * 6, q1)))
    want = {t: _bytes(ref.state(t)) for t in times}
    body = load_robot("ur5", joints=JointKeyframes((0.0, 2.0), ((0.0,) * 6, q1)))
    barrier = threading.Barrier(4)
    bad: list = []

    def ask(order):
        barrier.wait()
        for t in order:
            for _ in range(3):  # the newest state's fast path, then the cache
                if _bytes(body.state(t)) != want[t]:
                    bad.append(t)

    rng = np.random.default_rng(0)
    orders = [times, times, list(rng.permutation(times)), list(reversed(times))]
    threads = [threading.Thread(target=ask, args=(o,)) for o in orders]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert bad == []


def test_a_setpoint_pushed_between_two_reads_at_the_same_time_is_seen():
    body = load_robot("ur5", joints=JointSetpoints(np.zeros(6)))
    for k in range(20):
        q = np.full(6, 0.01 * k)
        body.joint_motion.set(1.0, q)  # the same time, new values: the newest state must not be reused
        st = body.state(1.0)
        ref = load_robot("ur5", joints=JointSetpoints(q))
        assert _bytes(st) == _bytes(ref.state(1.0)), k
