"""A walker's stop at a path's end: the gait comes to rest, then two closing steps.

docs/people.md ("Paths, starts and stops"): the gait slows to rest at ``arrival_time`` wherever in
its cycle the path ends, the feet apart; then one foot steps to where the standing pose puts it
(the free one, or in double support the one behind) while the other stands, and then the other
steps, each over 0.4 s: the person stands on the last waypoint from ``stop_time`` = arrival_time +
0.8 s. Before, the legs faded from the gait's last pose into the standing pose while the gait slowed:
a foot on the floor slid at 0.4-1.4 m/s (up to 4 m/s for a swinging foot brought down onto the
floor) and a foot went up to 9 cm into the floor.

References written out here: a foot that stands must not slide (the planted single support's own
bound, 0.03 m/s, tests/scene/test_walk_start_feet.py), the standing pose at the end, central
differences of every link's pose, continuity at the phase boundaries.
"""

import math

import numpy as np
import pytest

from twinsense.scene.human import Walk, foot_sole_points, person_body

STEP = 0.4  # [s] each closing step (docs/people.md)
SLIP = 0.03  # [m/s] the planted body's single-support slip bound (test_human, test_walk_start_feet)
CONTACT = 0.005  # [m] a sole point this high or lower is on the floor

# (height [m], speed [m/s], path length [m], body, heading [deg]): tall and short people, slow and fast,
# a path shorter than a ramp of gait, both bodies, headings off the axes.
CASES = [(1.75, 1.2, 3.0, "planted", 0.0), (1.5, 2.0, 3.0, "planted", 40.0), (1.95, 0.8, 3.1, "planted", -90.0),
         (1.89, 0.53, 2.92, "smooth", 10.0), (1.6, 1.81, 2.17, "smooth", 0.0), (1.75, 1.2, 0.4, "planted", 0.0),
         (1.75, 1.4, 2.6, "auto", 135.0)]


def _walker(height, speed, length, body, heading, sway=0.0):
    a = math.radians(heading)
    return person_body("p", height, (0.0, 0.0), heading, sway=sway,
                       walk=Walk(speed, path=((length * math.cos(a), length * math.sin(a)),), start_time=0.5,
                                 body=body))


def _soles(body, t, side, sole):
    st = body.state(t)
    p = st.pose(f"{side}_foot").apply(sole)
    return p, st.point_velocity(f"{side}_foot", p)


@pytest.mark.parametrize("case", CASES, ids=[f"{c[0]}m-{c[1]}mps-{c[2]}m-{c[3]}" for c in CASES])
def test_each_foot_stands_still_or_steps_clear_of_the_floor(case):
    height = case[0]
    body = _walker(*case)
    person = body.joint_motion.person
    sole = foot_sole_points(height)
    ta = person.arrival_time
    assert person.stop_time == pytest.approx(ta + 2 * STEP, rel=0, abs=1e-12)
    # The floor the gait itself stood on at the arrival: the push-off toe may be up to 4.5 mm in
    # (docs/people.md, limits). The closing legs are exact closed-form poses at their knots and a spline
    # between them; the first piece blends the gait's own foot roll into the leg plane's (the leg has no
    # joint to hold the foot's roll about its long axis): 2.2 mm below that floor at most (measured, one
    # smooth slow walk; the others 0-0.9 mm). Bound 3 mm; before, 9 cm.
    floor = min(0.0, min(float(_soles(body, ta, s, sole)[0][:, 2].min()) for s in ("right", "left"))) - 0.003
    sole_paths = {}
    for k in (0, 1):
        t0 = ta + k * STEP
        for t in np.linspace(t0, t0 + STEP, 81):
            for side in ("right", "left"):
                p, v = _soles(body, t, side, sole)
                assert p[:, 2].min() >= floor
                sole_paths.setdefault((k, side), []).append((p, np.hypot(v[:, 0], v[:, 1])))
    # In each step one foot stays put and the other steps; the first to step is the other one in the
    # second. The standing foot's sole moves less than 2.5 mm (the foot's roll, above: up to 2 deg x the
    # 6.8-7.6 cm from the ankle to the sole; measured 0.7-2.2 mm) and where it is on the floor it slides
    # slower than planted single support (measured 0.010-0.022 m/s); a step carries its foot further
    # (measured >= 3.8 cm: it lifts 3.8-4.9 cm), and it leaves and meets the floor straight up and down:
    # within 5 mm of the floor at most 0.1 m/s (measured 0.033 m/s in its first 20 ms here, 0.081 m/s
    # over 86 random walks, docs/people.md). Before, a foot
    # on the floor slid at 0.4-1.4 m/s.
    for k in (0, 1):
        moved = {side: max(float(np.max(np.linalg.norm(p - path[0][0], axis=1))) for p, _ in path)
                 for (kk, side), path in sole_paths.items() if kk == k}
        stood = min(moved, key=moved.get)
        stepped = "left" if stood == "right" else "right"
        assert moved[stood] < 0.0025 < moved[stepped]
        for side, limit in ((stood, SLIP), (stepped, 0.1)):
            for p, speed in sole_paths[k, side]:
                assert np.all(speed[p[:, 2] < CONTACT] < limit)
        if k == 0:
            first_stood = stood
    assert stood != first_stood


@pytest.mark.parametrize("case", CASES[:5], ids=[f"{c[0]}m-{c[3]}" for c in CASES[:5]])
def test_the_person_ends_in_the_standing_pose_on_the_waypoint(case):
    height, _, length, _, heading = case
    body = _walker(*case)
    person = body.joint_motion.person
    a = math.radians(heading)
    still = person_body("s", height, (length * math.cos(a), length * math.sin(a)), heading)
    for t in (person.stop_time, person.stop_time + 2.0):
        end, ref = body.state(t), still.state(t)
        # Every link where a person standing on the waypoint has it (the position spline's 1e-6 m), still.
        np.testing.assert_allclose(end.positions, ref.positions, rtol=0, atol=1e-6)
        np.testing.assert_allclose(end.rotations, ref.rotations, rtol=0, atol=1e-6)
        assert np.all(end.linear_velocities == 0.0) and np.all(end.angular_velocities == 0.0)


@pytest.mark.parametrize("sway", [0.0, 0.02])
def test_velocities_through_the_closing_steps_are_the_derivatives_of_the_poses(sway):
    # Central differences over h = 1e-6 s at times off the splines' knots: truncation h^2 |x'''| / 6 with
    # |x'''| < 1e4 m/s^3 (a 0.5 m step's foot over 0.08 s pieces) is < 2e-9 m/s, rounding 3e-16 x 4 m / h
    # ~ 1e-9 m/s: 1e-8 m/s (and rad/s). Measured 4-9e-10.
    h = 1e-6
    for case in (CASES[0], CASES[4], CASES[5]):
        body = _walker(*case, sway=sway)
        person = body.joint_motion.person
        for t in np.linspace(person.arrival_time, person.stop_time, 41)[1:-1] + 1.234e-4:
            s0, s1, s = body.state(t - h), body.state(t + h), body.state(t)
            assert np.max(np.abs((s1.positions - s0.positions) / (2 * h) - s.linear_velocities)) < 1e-8
            d = np.einsum("nij,nkj->nik", s1.rotations, s0.rotations)  # R(t + h) R(t - h)^T
            w = 0.5 * np.stack([d[:, 2, 1] - d[:, 1, 2], d[:, 0, 2] - d[:, 2, 0], d[:, 1, 0] - d[:, 0, 1]], 1) / (2 * h)
            assert np.max(np.abs(w - s.angular_velocities)) < 1e-8


def test_no_jump_where_the_phases_meet():
    # Arrival, the second step's start and the stop: 1 ns apart, links move at most a few m/s (1e-8 m)
    # and their velocities by at most the acceleration (< 1e3 m/s^2) x 2 ns: 2e-6 m/s. Measured
    # 1e-9 m and 9e-8 m/s, 2e-7 rad/s.
    for case in (CASES[0], CASES[3]):
        body = _walker(*case, sway=0.02)
        person = body.joint_motion.person
        for t in (person.arrival_time, person.arrival_time + STEP, person.stop_time):
            a, b = body.state(t - 1e-9), body.state(t + 1e-9)
            assert np.max(np.abs(a.positions - b.positions)) < 1e-8
            assert np.max(np.abs(a.linear_velocities - b.linear_velocities)) < 2e-6
            assert np.max(np.abs(a.angular_velocities - b.angular_velocities)) < 2e-6
