"""A walker's start and stop: the gait played slower, never faster than it walks.

The walk's gait time phi(t) ramps its rate from 0 to 1 over START_BLEND = 0.6 s after the walk's
start and back to 0 over the last 0.6 s (docs/people.md, "Paths, starts and stops"). References
written out here, not taken from the code: the closed form of the ramp (rate 3 x^2 - 2 x^3,
x = tau / 0.6 s; its integral 0.6 (x^3 - x^4 / 2) s), an independent steady walker (an endless
walk that started long before, whose pelvis moves at the steady gait's speeds), Boulic's stride
1.346 sqrt(RV) H_t, and central differences of the positions. Before, the start and stop blended
standing and walking positions while the walk's schedule ran on at full speed: the pelvis caught up
at 1.5-1.8 v in the start and ran at 1.85-2.0 m/s (1.2 m/s walk) in the stop.
"""

import math

import numpy as np
import pytest

from twinsense.scene.human import Walk, foot_sole_points, person_body

H = 1.75
HT = 0.530 * H  # hip-joint height (Winter 2009, fig. 4.1)
B = 0.6  # [s] the ramps' duration (docs/people.md)


def _ramp(x):
    """Rate 3 x^2 - 2 x^3 and gait time covered 0.6 (x^3 - x^4 / 2) [s] at x in [0, 1] of a ramp."""
    return x * x * (3 - 2 * x), B * (x ** 3 - 0.5 * x ** 4)


def _speed(body, t):
    return float(np.hypot(*body.base.state(t).linear_velocity[:2]))


@pytest.fixture(scope="module", params=[("planted", 1.2), ("smooth", 1.2), ("planted", 1.6)],
                ids=["planted-1.2", "smooth-1.2", "planted-1.6"])
def pair(request):
    """A walker along +x over a 4 m path from 0.5 s, and the same walker walking on endlessly since -20 s."""
    body, v = request.param
    walk = person_body("p", H, (0.0, 0.0), 0.0, walk=Walk(v, path=((4.0, 0.0),), start_time=0.5, body=body))
    steady = person_body("s", H, (0.0, 0.0), 0.0, walk=Walk(v, heading_deg=0.0, start_time=-20.0, body=body))
    return v, walk, steady


def test_the_pelvis_never_outruns_the_steady_gait(pair):
    v, walk, steady = pair
    person = walk.joint_motion.person
    dc = person.cycle.timing.cycle_duration
    # The steady gait's own pelvis speed over a cycle: v plus the published forward sway (Boulic:
    # +-(13-22) % of v). 2 ms samples: the peak between samples is missed by at most a dt^2 / 8 with
    # a < 40 m/s^2 (planted weight transfer), < 2e-5 m/s.
    ref = [_speed(steady, t) for t in np.arange(0.0, dc, 0.002)]
    top = max(ref)
    assert 1.1 * v < top < 1.25 * v
    # The whole walk, ramps included: never faster than that (+0.2 % for the fades' lateral term, at
    # most 1.5 / 0.6 s x 3 cm = 0.075 m/s across the path at half speed: sqrt(0.6^2 + 0.075^2) - 0.6
    # < 5 mm/s). Measured: the ramps peak below the steady peak; before, 1.5-1.8 v.
    speeds = np.array([_speed(walk, t) for t in np.arange(0.4, person.stop_time + 0.2, 0.002)])
    assert speeds.max() <= top * 1.002
    # Standing before and after: exactly still (no sway).
    assert _speed(walk, 0.5) == 0.0 and _speed(walk, person.stop_time + 0.1) == 0.0


def test_the_ramps_play_the_steady_gait_at_the_closed_form_gait_time(pair):
    # Start ramp: at tau = t - 0.5 s the walker is at gait time phi(tau) = 0.6 (x^3 - x^4 / 2) s past its
    # first pose, and moves rate(tau) times as fast. The steady walker passes the same gait times 0.3 s
    # (half a ramp) after its start plus whole cycles: at t_s = -20 + 0.3 + phi(tau) + n D_c, its path
    # progress counted from t_s(0). Both share the gait, so forward positions agree to rounding (1e-9 m),
    # and forward speeds too.
    _, walk, steady = pair
    person = walk.joint_motion.person
    dc = person.cycle.timing.cycle_duration
    t_s = -20.0 + 0.3 + math.ceil(10.0 / dc) * dc  # 10 s into the steady walk, at the walker's first pose
    x_s0 = steady.base.state(t_s).pose.position[0]
    x_w0 = walk.base.state(0.5).pose.position[0]
    for x in np.linspace(0.05, 1.0, 12):
        rate, phi = _ramp(x)
        a, b = walk.base.state(0.5 + B * x), steady.base.state(t_s + phi)
        assert a.pose.position[0] - x_w0 == pytest.approx(b.pose.position[0] - x_s0, rel=0, abs=1e-9)
        assert a.linear_velocity[0] == pytest.approx(rate * b.linear_velocity[0], rel=0, abs=1e-9)
    # Monotonic: the rate rises 0 -> 1 (and falls 1 -> 0 in the stop) with the closed form; every forward
    # speed lies between rate x (the steady gait's slowest, fastest) forward speed, an envelope that rises
    # monotonically from 0 to [0.78, 1.22] v.
    ref = np.array([steady.base.state(t).linear_velocity[0] for t in np.arange(0.0, dc, 0.002)])
    lo, hi = ref.min() * (1 - 1e-3), ref.max() * (1 + 1e-3)
    for t0, sign in ((0.5, 1.0), (person.arrival_time, -1.0)):
        for x in np.linspace(0.0, 1.0, 31):
            rate = _ramp(x)[0]
            vx = walk.base.state(t0 + sign * B * x).linear_velocity[0]
            assert rate * lo - 1e-12 <= vx <= rate * hi + 1e-12


def test_steady_gait_arrival_and_the_path_end(pair):
    v, walk, _ = pair
    person = walk.joint_motion.person
    dc = person.cycle.timing.cycle_duration
    # Between the ramps: one cycle later the pelvis is one Boulic stride further, 1.346 sqrt(v / H_t) H_t
    # (rounding, 1e-9 m), so stride, cadence and mean speed are the model's.
    p0 = walk.base.state(1.5).pose.position
    p1 = walk.base.state(1.5 + dc).pose.position
    assert p1[0] - p0[0] == pytest.approx(1.346 * math.sqrt(v / HT) * HT, rel=1e-9, abs=0)
    # Arrival: start + L / v + 0.6 s (each ramp covers half of what full speed would), +- the forward
    # sway's lead at either end, 2 a_a H_t / v (a_a = 0.021: 0.027 s at 1.2 m/s).
    assert person.arrival_time == pytest.approx(0.5 + 4.0 / v + B, rel=0, abs=2 * 0.021 * HT / v)
    # At the arrival the pelvis has come the path's length (the position spline's 1e-6 m), beside the path
    # by the gait's lateral sway (Boulic: a_l = 0.032 RV H_t peak-to-peak around the path, < 4 cm here).
    at = walk.base.state(person.arrival_time).pose.position
    assert at[0] == pytest.approx(4.0, rel=0, abs=1e-6) and abs(at[1]) < 0.04
    # The two closing steps take 2 x 0.4 s; then standing on the path's end, still.
    assert person.stop_time == pytest.approx(person.arrival_time + 0.8, rel=0, abs=1e-12)
    for t in (person.stop_time, person.stop_time + 1.0):
        st = walk.base.state(t)
        np.testing.assert_allclose(st.pose.position[:2], (4.0, 0.0), rtol=0, atol=1e-6)
        assert np.all(st.linear_velocity == 0.0)
    # The speed falls to 0 continuously: 10 ms before the arrival (x = 1/60 of the ramp) the gait's rate
    # is 3 x^2 - 2 x^3 < 8.3e-4, times the steady gait's peak 1.25 v: < 2 mm/s.
    assert _speed(walk, person.arrival_time - 0.01) < 8.3e-4 * 1.25 * v


def _right_contact_speed(body, t, sole):
    """Horizontal speed [m/s] of the right foot's lowest sole point and that point (3,) [m] at ``t``."""
    st = body.state(t)
    p = st.pose("right_foot").apply(sole)
    low = int(np.argmin(p[:, 2]))
    return float(np.hypot(*st.point_velocity("right_foot", p[low][None])[0][:2])), p[low], low


def test_the_standing_foot_stays_put_through_the_start(pair):
    # The gait starts at the right foot's mid-stance (its sole centre where standing puts it), so the
    # fade from the standing pose leaves it where it stood: through the start ramp, until the left heel
    # strikes, its lowest sole point stays on the floor (5 mm) and slides no faster than in the steady
    # walk's single support: the planted body's documented < 0.03 m/s (test_human; the 3-D tree's pelvis
    # list; measured 0.012-0.014 m/s here), the smooth body's own rocking (docs/people.md: 0.2-0.4 m/s
    # rms), its peak measured here on the steady walker over the same single support (0.5 cycle).
    _, walk, steady = pair
    person = walk.joint_motion.person
    cyc = person.cycle
    dc = cyc.timing.cycle_duration
    sole = foot_sole_points(H)
    if cyc.body == "planted":
        slip = 0.03
    else:
        t0 = steady.joint_motion.person.gait_origin + math.ceil(10.0 / dc) * dc
        slip = max(_right_contact_speed(steady, t0 + u * dc, sole)[0] for u in np.linspace(0.0, 0.49, 50))
    first = walk.state(0.5).pose("right_foot").apply(sole)
    # The left heel strikes at gait time dc / 2 past the reference heel strike: at gait_origin + dc / 2.
    end = min(person.gait_origin + 0.5 * dc, 0.5 + B)
    for t in np.linspace(0.5, end - 0.01, 25):
        speed, point, low = _right_contact_speed(walk, t, sole)
        assert abs(point[2]) < 0.005
        assert speed < slip
    # And the sole point it stands on (the heel lifts as the foot rolls onto its toe) has hardly moved:
    # less than the slip bound over 0.6 s (1.8 cm planted; measured 2.7 mm at 1.2 m/s, smooth 2.4 cm).
    assert np.max(np.abs(point[:2] - first[low, :2])) < slip * B


def _fd_errors(body, times, h=1e-6):
    """Largest |API linear velocity - central difference| over links and times [m/s]."""
    err = 0.0
    for t in times:
        s0, s1, s = body.state(t - h), body.state(t + h), body.state(t)
        err = max(err, float(np.max(np.abs((s1.positions - s0.positions) / (2 * h) - s.linear_velocities))))
    return err


@pytest.mark.parametrize("length", [0.4, 3.0])
def test_ramps_have_exact_velocities_and_a_short_walk_peaks_below_v(length):
    # A 0.4 m walk at 1.2 m/s covers less gait time (~0.33 s) than two half ramps (0.6 s): its rate
    # peaks at that / 0.6 s < 1 and it lasts 2 x 0.6 s. Velocities of every link equal central
    # differences of the positions over h = 1e-6 s (truncation h^2 |x'''| / 6 < 1e-9 m/s, rounding
    # 1e-10 m/s; at a heel-toe roll or a ramp's end the acceleration may jump: h |jump| / 4 < 2e-5 m/s
    # for jumps below 80 m/s^2, as in test_people_review).
    v = 1.2
    body = person_body("p", H, (0.0, 0.0), 0.0, walk=Walk(v, path=((length, 0.0),), start_time=0.2))
    person = body.joint_motion.person
    times = np.concatenate([np.linspace(0.2, 0.2 + B, 9), np.linspace(person.arrival_time - B, person.arrival_time, 9)])
    assert _fd_errors(body, times) < 2e-5
    if length < v * B:
        assert person.arrival_time == pytest.approx(0.2 + 2 * B, rel=0, abs=1e-12)
        peak = max(_speed(body, t) for t in np.linspace(0.2, person.arrival_time, 121))
        # Rate length / (v 0.6 s) (+- the forward sway's 2 a_a H_t / v over 0.6 s) times <= 1.25 v.
        assert peak < (length / (v * B) + 2 * 0.021 * HT / (v * B)) * 1.25 * v
    np.testing.assert_allclose(body.base.state(person.stop_time).pose.position[:2], (length, 0.0), rtol=0, atol=1e-6)
