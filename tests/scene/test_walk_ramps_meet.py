"""A walk shorter than one ramp of gait: its start and stop ramps meet at start_time + 0.6 s.

docs/people.md ("Paths, starts and stops"): a path shorter than 0.6 s of gait peaks at that fraction
of v and takes 1.2 s. Its gait time rises as start + r 0.6 F(x) and falls back from the end, F(x) =
x^3 - x^4 / 2, with no steady part: at the meeting time t_m = start_time + 0.6 s both ramps give
the gait time gait0 + r 0.3 s and the rate r = G / 0.6 s < 1. At exactly t_m the walk used to take the
steady branch (gait0 + 0.3 s, rate 1): every link jumped (0.88 m for a 0.1 m walk at 1.2 m/s) for that
one instant, which a frame clock hits (t_m = 0.6 = 18 / 30 s for a walk from t = 0).

References written out here: continuity of every link's position (a state 1 ns earlier), central
differences of the positions, the closed-form peak rate.
"""

import math

import numpy as np
import pytest

from twinsense.scene.human import Walk, person_body

B = 0.6  # [s] the ramps' duration (docs/people.md)
H_FD = 1e-6  # [s] central-difference step


@pytest.mark.parametrize(("height", "speed", "length", "start"), [
    (1.75, 1.2, 0.1, 0.0), (1.6, 0.8, 0.3, 1.0), (1.95, 2.0, 0.5, 0.0), (1.5, 1.2, 0.4, 0.2)])
def test_the_ramps_meet_without_a_jump(height, speed, length, start):
    body = person_body("p", height, (0.0, 0.0), 0.0, walk=Walk(speed, path=((length, 0.0),), start_time=start))
    person = body.joint_motion.person
    assert person.arrival_time == pytest.approx(start + 2 * B, rel=0, abs=1e-12)  # a walk shorter than a ramp
    for t_m in (start + B, person.arrival_time - B, 18 / 30 if start == 0.0 else start + B):
        s, before = body.state(t_m), body.state(t_m - 1e-9)
        # Positions: links move at most a few m/s (a swinging toe: 4.5 v), so 1 ns earlier they are at
        # most 1e-8 m away (+ rounding 1e-15 m); before the fix, 0.13-0.88 m.
        assert np.max(np.linalg.norm(s.positions - before.positions, axis=1)) < 1e-8
        # Velocities: central differences over 1e-6 s. The motion is C2 here except for the ramps'
        # rate, whose second derivative jumps by r 12 / 0.6^2 /s^2 at t_m (and a heel-toe roll):
        # h |jump of the acceleration| / 4 < 1e-6 x 80 m/s^2 / 4 = 2e-5 m/s (test_people_review's
        # bound). Before the fix the velocity at t_m was the gait at rate 1 instead of r: 0.1-2 m/s off.
        fd = (body.state(t_m + H_FD).positions - body.state(t_m - H_FD).positions) / (2 * H_FD)
        assert np.max(np.abs(fd - s.linear_velocities)) < 2e-5
    # The pelvis's forward speed at the meeting: the rate r = G / 0.6 s times the gait's own forward speed
    # there, so at most r x the steady gait's peak (1.25 v, the published forward sway) with G the gait
    # time of the walk, L / v give or take the sway's lead 2 a_a H_t / v (a_a = 0.021, H_t = 0.53 H).
    g_max = length / speed + 2 * 0.021 * 0.53 * height / speed
    vx = body.base.state(start + B).linear_velocity[0]
    assert 0.0 < vx < g_max / B * 1.25 * speed
    # And the walk still ends on its waypoint, standing.
    np.testing.assert_allclose(body.base.state(person.stop_time).pose.position[:2], (length, 0.0),
                               rtol=0, atol=1e-6)
    assert math.isfinite(person.arrival_time)
