"""Every link's velocities through a walk's start ramp and closing steps, in walks the other tests of
the start and stop do not use: a Turn on the spot before the walk with a standing sway, a start before
t = 0, a 0.3 m path whose ramps meet, a path with two corners, a start at 60 deg to the path.

docs/people.md ("Paths, starts and stops"): velocities are the derivatives of the splines (the start's
swinging leg, the closing steps' legs and pelvis) and of the gait played at the ramped gait time.

Reference written out here: central differences of each link's pose (position, and the rotation
R(t + h) R(t - h)^T's axial vector), and continuity at the phase boundaries.
"""

import numpy as np
import pytest

from twinsense.scene.human import Turn, Walk, person_body

H_FD = 1e-6  # [s]
CASES = {
    "turn-sway": dict(height=1.62, heading=-60.0, sway=0.03, turn=Turn(20.0, -2.0, 1.2),
                      walk=Walk(1.1, path=((1.8, 0.65), (2.6, 2.0)), start_time=-0.4, body="planted")),
    "short-tall-slow": dict(height=1.93, heading=200.0, sway=0.0, turn=None,
                            walk=Walk(0.7, path=((-0.28, -0.1),), start_time=-1.3, body="smooth")),
    "corners-fast": dict(height=1.52, heading=45.0, sway=0.01, turn=None,
                         walk=Walk(1.9, path=((1.0, 1.0), (1.0, 2.5), (-0.5, 2.6)), start_time=0.2, body="auto")),
    "angled-start": dict(height=1.78, heading=60.0, sway=0.0, turn=None,
                         walk=Walk(1.4, path=((2.5, 0.0),), start_time=0.0, body="planted")),
}


def _body(case):
    c = CASES[case]
    return person_body("p", c["height"], (0.0, 0.0), c["heading"], walk=c["walk"], turn=c["turn"], sway=c["sway"])


def _axial(d):
    return 0.5 * np.stack([d[:, 2, 1] - d[:, 1, 2], d[:, 0, 2] - d[:, 2, 0], d[:, 1, 0] - d[:, 0, 1]], 1)


@pytest.mark.parametrize("case", list(CASES))
def test_link_velocities_are_central_differences_of_the_poses(case):
    body = _body(case)
    person = body.joint_motion.person
    t0, ta = person.walk.start_time, person.arrival_time
    # Times off the splines' knots (the start's every 0.05 s, the closing steps' at 0.2 / 0.5 / 0.8 of each
    # 0.4 s step, where the C1 pieces' accelerations jump) by at least 1e-4 s >> H_FD.
    times = np.concatenate([t0 + np.linspace(0.0, 0.6, 25)[1:-1] + 1.234e-4,
                            ta + np.linspace(0.0, 0.8, 33)[1:-1] + 1.234e-4])
    worst_v = worst_w = 0.0
    for t in times:
        s0, s1, s = body.state(t - H_FD), body.state(t + H_FD), body.state(t)
        worst_v = max(worst_v, float(np.max(np.abs((s1.positions - s0.positions) / (2 * H_FD) - s.linear_velocities))))
        w = _axial(np.einsum("nij,nkj->nik", s1.rotations, s0.rotations)) / (2 * H_FD)
        worst_w = max(worst_w, float(np.max(np.abs(w - s.angular_velocities))))
    # Truncation h^2 |x'''| / 6: a foot's jerk in a 0.08 s lift of 5 cm or the gait's swing, < 1e4 m/s^3,
    # gives 2e-9; rounding 1.1e-16 x |x| (< 6 m) / h ~ 7e-10; the axial vector's own error (sin vs angle,
    # (w h)^3 / 6 over h for w < 20 rad/s) 1e-15. Bound 1e-8 m/s and rad/s (measured 0.4-3.4e-9).
    assert worst_v < 1e-8 and worst_w < 1e-8, (worst_v, worst_w)


@pytest.mark.parametrize("case", list(CASES))
def test_nothing_jumps_where_the_phases_meet(case):
    body = _body(case)
    person = body.joint_motion.person
    t0, ta = person.walk.start_time, person.arrival_time
    e = 1e-9
    for t in (t0, t0 + 0.6, ta - 0.6, ta, ta + 0.4, person.stop_time):
        a, b = body.state(t - e), body.state(t + e)
        # 2 ns apart: links move at most a few m/s (1e-8 m), velocities change by at most the acceleration
        # (< 1e3 m/s^2, rad/s^2) x 2 ns = 2e-6.
        assert np.max(np.abs(a.positions - b.positions)) < 1e-8
        assert np.max(np.abs(a.linear_velocities - b.linear_velocities)) < 2e-6
        assert np.max(np.abs(a.angular_velocities - b.angular_velocities)) < 2e-6
