"""Motions: analytic velocities against central finite differences."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from twinsense import ConfigError, ConstantVelocity, Keyframes, Oscillation, Pose, Waypoints
from twinsense.scene.motion import Static

H = 1e-6  # finite-difference step [s]
# Central differences have O(h^2) truncation (~1e-12 here) and O(eps/h)
# rounding (~1e-10 for O(1) positions): 1e-6 relative leaves wide margin.
TOL = 1e-6


def fd_velocity(motion, t):
    p1, p0 = motion.pose(t + H), motion.pose(t - H)
    v = (p1.position - p0.position) / (2 * H)
    dr = Rotation.from_matrix(p1.rotation @ p0.rotation.T).as_rotvec() / (2 * H)
    return v, dr


MOTIONS = [
    ConstantVelocity(Pose.from_euler_deg((1, 2, 3), (10, 0, 5)), (0.3, -0.2, 0.1), (0.1, 0.5, -0.3)),
    Waypoints([[0, 0, 0], [1, 0, 0], [1, 2, 0], [0, 2, 1]], speed=0.7, mode="loop"),
    Waypoints([[0, 0, 0], [1, 0, 0], [1, 2, 0]], speed=0.7, mode="back_and_forth"),
    Keyframes([0.0, 1.0, 2.5], (Pose.from_euler_deg((0, 0, 0), (0, 0, 0)),
                                Pose.from_euler_deg((1, 0, 0), (0, 0, 90)),
                                Pose.from_euler_deg((1, 1, 1), (30, 20, 90)))),
    Oscillation(Pose((0, 0, 1)), (0.01, 0.0, 0.005), 0.25, 30.0, (0.0, 0.0, 0.2)),
]


@pytest.mark.parametrize("motion", MOTIONS, ids=lambda m: type(m).__name__ + getattr(m, "mode", ""))
@pytest.mark.parametrize("t", [0.3, 1.7, 2.2, 4.9])
def test_velocity_matches_finite_difference(motion, t):
    st = motion.state(t)
    v, w = fd_velocity(motion, t)
    np.testing.assert_allclose(st.linear_velocity, v, atol=TOL)
    np.testing.assert_allclose(st.angular_velocity, w, atol=TOL)


@pytest.mark.parametrize("motion", MOTIONS[:1] + MOTIONS[3:], ids=["cv", "kf", "osc"])
def test_surface_point_velocity(motion):
    # A body-fixed point's velocity v + w x r against finite differences.
    t = 0.6
    local = np.array([[0.3, -0.2, 0.5], [1.0, 1.0, 1.0]])
    st = motion.state(t)
    pw = st.pose.apply(local)
    fd = (motion.pose(t + H).apply(local) - motion.pose(t - H).apply(local)) / (2 * H)
    np.testing.assert_allclose(st.point_velocity(pw), fd, atol=TOL)


def test_waypoints_positions_and_modes():
    w = Waypoints([[0, 0, 0], [2, 0, 0]], speed=1.0, mode="once")
    np.testing.assert_allclose(w.pose(1.0).position, [1, 0, 0])
    np.testing.assert_allclose(w.pose(5.0).position, [2, 0, 0])
    assert np.all(w.state(5.0).linear_velocity == 0)
    b = Waypoints([[0, 0, 0], [2, 0, 0]], speed=1.0, mode="back_and_forth")
    np.testing.assert_allclose(b.pose(3.0).position, [1, 0, 0])
    np.testing.assert_allclose(b.state(3.0).linear_velocity, [-1, 0, 0])
    lp = Waypoints([[0, 0, 0], [2, 0, 0]], speed=1.0, mode="loop")
    np.testing.assert_allclose(lp.pose(5.0).position, [1, 0, 0])  # 4 m per loop, 1 m into the next
    assert Static().state(3.0).pose.isclose(Pose())


def test_keyframes_hit_the_keys():
    k = MOTIONS[3]
    for t, p in zip(k.times, k.poses):
        assert k.pose(t).isclose(p, atol=1e-9)


@pytest.mark.parametrize("make, match", [
    (lambda: Waypoints([[0, 0, 0]], speed=1), "motion.points"),
    (lambda: Waypoints([[0, 0, 0], [1, 0, 0]], speed=-1), r"motion.speed = -1 .*> 0"),
    (lambda: Waypoints([[0, 0, 0], [1, 0, 0]], speed=1, mode="pingpong"), "motion.mode"),
    (lambda: Oscillation(frequency=float("nan")), "motion.frequency"),
    (lambda: Keyframes([0.0, 0.0], (Pose(), Pose())), "motion.times"),
    (lambda: ConstantVelocity(velocity=(1, 2)), "motion.velocity"),
])
def test_bad_motion(make, match):
    with pytest.raises(ConfigError, match=match):
        make()


@pytest.mark.parametrize("motion", [
    Static(Pose()),
    ConstantVelocity(Pose(), (1, 0, 0)),
    Waypoints([[0, 0, 0], [1, 0, 0]], 1.0),
    Keyframes([0.0, 1.0], (Pose(), Pose((1, 0, 0)))),
    Oscillation(Pose(), (0, 0, 0.1), 1.0),
])
@pytest.mark.parametrize("t", [float("nan"), float("inf"), -1.1e10, "0.5", None])
def test_state_refuses_times_that_are_not_finite_numbers(motion, t):
    # A NaN time used to return the start pose (Waypoints, Static) or NaN poses.
    with pytest.raises(ConfigError, match=r"^t = .* expected a finite number >= -1e\+10 and <= 1e\+10 \[s\]"):
        motion.state(t)


def test_speed_limits_are_the_speed_of_light():
    # Keyframes imply the speed |dp| / dt: 1 m in 1 ns is 1e9 m/s > c = 2.998e8 m/s (refused),
    # 0.25 m in 1 ns is 2.5e8 m/s (allowed; the state reports that speed exactly).
    with pytest.raises(ConfigError, match=r"motion.times\[1\] = 1e-09 .* speed stays <= 2.99792e\+08 m/s"):
        Keyframes([0.0, 1e-9], (Pose(), Pose((1, 0, 0))))
    k = Keyframes([0.0, 1e-9], (Pose(), Pose((0.25, 0, 0))))
    assert k.state(0.5e-9).linear_velocity[0] == pytest.approx(2.5e8, rel=1e-12, abs=0)
    # An oscillation's peak speed is |a| 2 pi f: 1 m at 1e6 Hz is 6.3e6 m/s (allowed),
    # 100 m at 1e6 Hz is 6.3e8 m/s (refused).
    Oscillation(Pose(), (0, 0, 1.0), 1e6)
    with pytest.raises(ConfigError, match="motion.amplitude"):
        Oscillation(Pose(), (0, 0, 100.0), 1e6)
    with pytest.raises(ConfigError, match="motion.velocity"):
        ConstantVelocity(Pose(), (3e8, 0, 1))


def test_waypoint_path_length_without_overflow():
    # Squares of 1e200 overflow; the scaled norm gives sqrt(2) * 1e200 to float precision
    # (a few ulp: rel 1e-15), and the motion runs along it.
    w = Waypoints([[0, 0, 0], [1e200, 1e200, 0]], 1.0)
    assert w.length == pytest.approx(np.sqrt(2) * 1e200, rel=1e-15, abs=0)
    s = w.state(2.0)
    np.testing.assert_allclose(s.pose.position, [np.sqrt(2), np.sqrt(2), 0], rtol=1e-15, atol=0)
