"""A reach by a person who moves meanwhile: the hand must be on the world target when it arrives.

Reference: the target is built from the same person *without* a reach at the arrival time
(start_time + duration), a point the three arm joints reach in the thorax frame then (0.4 m in
front, 0.1 m to the side of the left shoulder, well inside the 0.676 m arm of a 1.75 m person and
within every joint limit). The arm is a rigid chain on the thorax, so with the arm solved for the
thorax pose at arrival the hand centre is on the target to rounding: 1e-9 m (the IK is closed
form; measured < 1e-15 m). Solved at the reach's start, the hand missed by the thorax's motion
over the duration: 0.28 m walking, 0.36 m turning, 1.8 cm swaying, the last without a warning.
"""

import math
import warnings

import numpy as np
import pytest

from twinsense.scene.human import Reach, Turn, Walk, person_body

H = 1.75
HAND_CENTRE = np.array([0.0, 0.0, -0.5 * 0.108 * H])  # half of Winter's hand length 0.108 H below the wrist
LOCAL = np.array([0.4, 0.1, 0.0])  # thorax frame: forward, left, up from the left shoulder [m]


@pytest.mark.parametrize(("kwargs", "start", "duration"), [
    ({"walk": Walk(1.2, heading_deg=30.0)}, 2.0, 0.6),          # steady walking, 0.72 m during the reach
    ({"turn": Turn(90.0, 0.0, 2.0)}, 0.5, 1.0),                  # turning on the spot
    ({"sway": 0.05}, 0.5, 1.0),                                 # standing with a 5 cm sway
    ({"walk": Walk(1.0, path=((2.0, 1.0), (2.0, 3.0)), start_time=0.5)}, 2.2, 0.8),  # through a corner
])
def test_the_hand_is_on_the_target_when_it_arrives(kwargs, start, duration):
    arrive = start + duration
    ref = person_body("p", H, (0.0, 0.0, 0.3), 30.0, **kwargs).state(arrive)  # on a 0.3 m platform
    target = ref.pose("left_shoulder").position + ref.pose("thorax").rotation @ LOCAL
    body = person_body("p", H, (0.0, 0.0, 0.3), 30.0, reach=Reach(tuple(target), start, duration, 0.5, "left"),
                       **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # reachable: no short-reach warning
        hand = body.state(arrive).pose("left_hand").apply(HAND_CENTRE[None])[0]
    np.testing.assert_allclose(hand, target, rtol=0, atol=1e-9)
    lo, hi = body.tree.limits.T
    q = body.joint_motion.q(arrive)
    assert np.all(q >= lo - 1e-12) and np.all(q <= hi + 1e-12)


def test_a_standing_reach_is_unchanged_and_an_unreachable_one_still_warns():
    # A still person: the thorax is the same at start and arrival, so the solution is the one at the
    # start (hit to 1e-9 m); behind the back (flexion limit -60 deg) the hand falls short and warns.
    stand = person_body("p", H, (1.0, -1.0), 135.0).state(0.0)
    sh, rot = stand.pose("left_shoulder").position, stand.pose("thorax").rotation
    target = sh + rot @ LOCAL
    body = person_body("p", H, (1.0, -1.0), 135.0, reach=Reach(tuple(target), 0.2, 0.5, math.inf, "left"))
    hand = body.state(3.0).pose("left_hand").apply(HAND_CENTRE[None])[0]
    np.testing.assert_allclose(hand, target, rtol=0, atol=1e-9)
    behind = sh + rot @ np.array([-0.5, 0.0, 0.0])
    body = person_body("p", H, (1.0, -1.0), 135.0, reach=Reach(tuple(behind), 0.2, 0.5, math.inf, "left"))
    with pytest.warns(UserWarning, match=r"reach\.target = .*the left hand stops 0\.\d+ m from it"):
        body.state(1.0)
