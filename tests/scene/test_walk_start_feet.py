"""The feet through a walker's start, over heights and speeds the start/stop tests do not use.

docs/people.md (limits): through the 0.6 s start ramp the standing (right) foot stays put when the
path leaves along the standing heading (planted body: slip below the single-support 0.03 m/s of
test_human, measured 0.011-0.023 m/s at 0.8-2.0 m/s, 1.5-1.95 m); a path leaving at an angle makes
the start turn the body over the ramp and the standing foot slides (about 1 m/s for 90 deg at
1.2 m/s), which a Turn on the spot ending by the walk's start avoids; the swinging (left) foot rises straight up
from its standing place and follows the blend of that place and the gait's own swing, never into the
floor (before: up to 5.4 cm into it).
"""


import numpy as np
import pytest

from twinsense.scene.human import Turn, Walk, foot_sole_points, person_body

B = 0.6  # [s] the start ramp (docs/people.md)
SLIP = 0.03  # [m/s] the planted body's single-support slip bound (test_human, docs/people.md)


def _standing_foot_slip(body, height):
    """Largest horizontal speed [m/s] of the right foot's lowest sole point from the walk's start until the
    left heel strikes (gait_origin + D_c / 2) or the ramp ends, and its largest |height| [m]."""
    person = body.joint_motion.person
    sole = foot_sole_points(height)
    t0 = person.walk.start_time
    end = min(person.gait_origin + 0.5 * person.cycle.timing.cycle_duration, t0 + B)
    slip = lift = 0.0
    for t in np.linspace(t0, end - 0.01, 30):
        st = body.state(t)
        p = st.pose("right_foot").apply(sole)
        k = int(np.argmin(p[:, 2]))
        slip = max(slip, float(np.hypot(*st.point_velocity("right_foot", p[k][None])[0][:2])))
        lift = max(lift, abs(float(p[k, 2])))
    return slip, lift


@pytest.mark.parametrize(("height", "speed"), [(1.5, 0.8), (1.5, 2.0), (1.95, 0.8), (1.95, 2.0)])
def test_the_standing_foot_stays_put_through_a_straight_start(height, speed):
    body = person_body("p", height, (0.0, 0.0), 0.0,
                       walk=Walk(speed, path=((3.0, 0.0),), start_time=0.5, body="planted"))
    slip, lift = _standing_foot_slip(body, height)
    # Measured 0.011-0.023 m/s; the foot's lowest point within 5 mm of the floor (measured 1-2 mm).
    assert slip < SLIP and lift < 0.005


def test_a_turn_before_the_walk_keeps_the_standing_foot_put():
    # A path leaving at 90 deg to the standing heading: the start turns the body over the ramp while the
    # gait carries it along the path, and the standing foot slides (documented: 0.99 m/s at 1.2 m/s; the
    # pelvis speed times 2 sin(90 deg / 2) ~ 1.4 x the ramp's speed at mid-turn, so well above SLIP). A
    # Turn on the spot to the path's heading that ends by the walk's start leaves a straight start.
    walk = Walk(1.2, path=((0.0, 3.0),), start_time=0.5, body="planted")
    turned = person_body("p", 1.75, (0.0, 0.0), 0.0, walk=walk)
    assert _standing_foot_slip(turned, 1.75)[0] > 0.5
    facing = person_body("q", 1.75, (0.0, 0.0), 0.0, walk=walk, turn=Turn(90.0, 0.0, 0.5))
    slip, lift = _standing_foot_slip(facing, 1.75)
    assert slip < SLIP and lift < 0.005
    # The walk is the same one: it arrives on its waypoint at the same time.
    assert facing.joint_motion.person.stop_time == turned.joint_motion.person.stop_time
    stop = facing.joint_motion.person.stop_time
    np.testing.assert_allclose(facing.base.state(stop).pose.position[:2], (0.0, 3.0), rtol=0, atol=1e-6)


@pytest.mark.parametrize(("height", "speed", "body"), [(1.95, 0.8, "planted"), (1.75, 1.2, "planted"),
                                                    (1.5, 2.0, "planted"), (1.89, 0.53, "smooth")])
def test_the_swinging_foot_rises_from_the_floor_and_never_goes_into_it(height, speed, body):
    # The left foot lifts off from its standing place into the gait's swing, following the blend of the
    # two in the world (docs/people.md, "Paths, starts and stops"). Before, the leg's angles were faded
    # from standing into the swing: the foot went 0.7-5.4 cm into the floor (deepest in slow walks of
    # tall people) and slid there at 0.8-2.8 m/s. Sampled every 2 ms: near its lowest point the sole's
    # vertical speed is ~0, so a sample misses at most a dt^2 / 8 with a < 50 m/s^2: 0.025 mm. The
    # closed-form poses are exact at their knots, a quintic spline between them: measured -0.06 mm over
    # 58 random walks. Bound 0.5 mm.
    body = person_body("p", height, (0.0, 0.0), 0.0, walk=Walk(speed, path=((3.0, 0.0),), start_time=0.5,
                                                              body=body))
    sole = foot_sole_points(height)
    low = min(float(body.state(t).pose("left_foot").apply(sole)[:, 2].min()) for t in np.arange(0.5, 0.5 + B, 0.002))
    assert low > -0.0005
    # Over the first 15 % of the ramp it only rises (straight up): its sole moves across the floor at most
    # 0.1 m/s (measured 0.071 m/s over 58 random walks; the pelvis moves under the fade meanwhile).
    for t in np.arange(0.5, 0.5 + 0.15 * B, 0.002):
        st = body.state(t)
        p = st.pose("left_foot").apply(sole)
        v = st.point_velocity("left_foot", p)
        assert np.max(np.hypot(v[:, 0], v[:, 1])) < 0.1
