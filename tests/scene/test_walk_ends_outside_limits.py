"""A walk's start and closing steps near the leg joints' limits: no joint rate jumps.

docs/people.md ("Paths, starts and stops"): the swinging leg of the start and the legs of the two
closing steps are splines through closed-form leg poses kept LIMIT_MARGIN inside the joint limits; a
spline may overshoot between its poses. Before, the overshoot past a limit was clipped there and its
rate set to 0 at once: where the spline crossed the limit the joint's rate jumped (a start that
turns 174 deg: the left hip rotation and ankle by 6-13 rad/s), and so did every link below it. Now
the overshoot is squeezed into the last LIMIT_MARGIN before the limit along a tanh, whose slope and
curvature join the spline's (rates and accelerations continuous), never reaching the limit.

References written out here: a finite difference of each joint's rate over a short step (a jump
shows as its full size, a continuous rate as at most its acceleration times the step), central
differences of the angles (the rate is the derivative of the angle also in the squeezed stretch),
and the joint limits themselves.
"""

import numpy as np
import pytest

from twinsense.scene.human import Walk, person_body

B = 0.6  # [s] the start ramp (docs/people.md)
CLOSE = 0.8  # [s] the two closing steps
DT = 2e-4  # [s] the scan's step
# (height [m], speed [m/s], path, body, heading [deg], start_time [s]) of walks whose splines pass a limit
# (found over random walks): a start that turns 174 deg (the left leg's hip rotation and ankle), and a tall
# fast walker whose closing step lifts the foot with the ankle at its dorsiflexion limit.
CASES = [(1.591, 1.804, ((1.848, 1.777),), "smooth", -130.36, -0.599),
         (1.95, 2.0, ((-1.157, -1.225), (-2.046, -0.453), (-1.004, 0.21)), "planted", -69.83, -0.831)]


def _leg_rates(person, times, cols):
    return np.array([person.qd(float(t))[cols] for t in times]), np.array([person.q(float(t))[cols] for t in times])


@pytest.mark.parametrize("case", CASES, ids=["174deg-start", "tall-fast-close"])
def test_leg_joint_rates_do_not_jump_at_the_limits(case):
    height, speed, path, body, heading, t0 = case
    walker = person_body("p", height, (0.0, 0.0), heading,
                         walk=Walk(speed, path=path, start_time=t0, body=body))
    person = walker.joint_motion.person
    tree = walker.tree
    cols = np.array([tree.joint_index(f"{s}_{j}") for s in ("left", "right")
                     for j in ("hip_rotation", "hip_flexion", "hip_abduction", "knee", "ankle")])
    lo, hi = tree.limits[cols].T
    for a, b in ((t0, t0 + B), (person.arrival_time, person.arrival_time + CLOSE)):
        times = np.arange(a, b, DT)
        qd, q = _leg_rates(person, times, cols)
        # Never past a limit.
        assert np.all(q >= lo) and np.all(q <= hi)
        # A continuous rate changes over DT by at most its largest acceleration times DT. The squeeze
        # f(q) = hi - m + m tanh((q - hi + m) / m) has |f''| <= 4 / (3 sqrt 3) / m = 15.4 / rad, so a rate
        # w entering it turns at most 15.4 w^2 + |q''| rad/s^2: with w <= 15 rad/s and |q''| <= 1000 rad/s^2
        # (the 174 deg start's spline, measured), 4500 rad/s^2, 0.9 rad/s over DT (measured 0.75 rad/s
        # there, 0.06 rad/s in the other case). Bound 1.5 rad/s; before, the rate jumped by 6-13 rad/s.
        jump = float(np.max(np.abs(np.diff(qd, axis=0))))
        assert jump < 1.5, f"a leg joint's rate changes by {jump:.2f} rad/s in {DT * 1e3:.1f} ms"
        # The rates are the derivatives of the angles, also where squeezed: central differences over
        # h = 1e-6 s agree to h^2 / 6 |q'''| + 2 eps |q| / h ~ 1e-12 x 1e6 + 1e-10 (a tanh stretch's q'''
        # ~ w^3 / m^2 = 1.4e5 rad/s^3); bound 1e-4 rad/s (before, 3-6 rad/s across a clip).
        h = 1e-6
        for t in times[::40]:
            fd = (person.q(float(t) + h)[cols] - person.q(float(t) - h)[cols]) / (2 * h)
            assert np.max(np.abs(fd - person.qd(float(t))[cols])) < 1e-4

