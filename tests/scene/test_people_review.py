"""People through the public API, against an independent reading of the formulas.

The references here are written out from the papers and the documentation
(docs/people.md), not taken from twinsense.scene.gait or .human: the Boulic
(1990) gait timing, the pelvis and foot motion a walker must show, the exact
velocities a sensor sees (central finite differences of the poses), the
reach's two-link arm and the errors of bad inputs.
"""

import functools
import math
import warnings

import numpy as np
import pytest

from twinsense.errors import ConfigError
from twinsense.scenario import ScenarioError, scenario_from_dict
from twinsense.scene import Scene
from twinsense.scene.human import Reach, Turn, Walk, add_person, person_body

HIP = 0.530  # hip-joint height / body height (Winter 2009, fig. 4.1)
ARM = (0.186, 0.146, 0.108)  # upper arm, forearm, hand / body height (same table)
HEEL, FOOT, ANKLE = 0.25 * 0.152, 0.152, 0.039  # sole: heel behind the ankle, length, ankle height (/ H)

# Central differences over h = 1e-6 s. Where the motion is C2 the truncation is h^2 |x'''| / 6
# < 1e-9 m/s (|x'''| < 1e3 m/s^3 for the fastest link, a toe) and the rounding 1e-16 m / 1e-6 s
# ~ 1e-10 m/s. The motion is C1 only at a few instants (a blend's or a ramp's start and end,
# the stance contact rolling from heel to toe): there the central difference is off by at most
# h |jump of the acceleration| / 4, < 1e-6 * 80 / 4 = 2e-5 m/s for jumps below 80 m/s^2 (8 g;
# the largest error measured in these scenes is 3.7e-6 m/s; 4.3e-6 m/s when the start was a
# position blend). Rotations: the same bound in rad/s (measured 9e-6 rad/s: the half-turn start's
# yaw fade, pi rad under a weight whose second derivative jumps by 6 / 0.6^2 /s^2 at its ends).
FD_H = 1e-6
FD_TOL = 2e-5


def _fd_errors(body, times):
    """Largest |API velocity - central difference| over links and times: linear [m/s], angular [rad/s]."""
    lin = ang = 0.0
    for t in times:
        s0, s1, s = body.state(t - FD_H), body.state(t + FD_H), body.state(t)
        lin = max(lin, float(np.max(np.abs((s1.positions - s0.positions) / (2 * FD_H) - s.linear_velocities))))
        # R' R^T = [w]x, R' by the same central difference.
        dr = np.einsum("nij,nkj->nik", (s1.rotations - s0.rotations) / (2 * FD_H), s.rotations)
        w = np.stack([dr[:, 2, 1], dr[:, 0, 2], dr[:, 1, 0]], axis=1)
        ang = max(ang, float(np.max(np.abs(w - s.angular_velocities))))
    return lin, ang


def _largest_step(body, times):
    """Largest link displacement between neighbouring times [m] and the bound a continuous motion
    allows: the fastest link speed seen times the time step (plus 1 % for the speed between samples)."""
    states = [body.state(t) for t in times]
    pos = np.array([st.positions for st in states])
    speed = max(float(np.max(np.linalg.norm(st.linear_velocities, axis=1))) for st in states)
    step = float(np.max(np.linalg.norm(np.diff(pos, axis=0), axis=2)))
    return step, 1.01 * speed * float(np.max(np.diff(times)))


# ---------------------------------------------------------------- continuity and exact velocities
@pytest.mark.parametrize(("turn", "walk_heading", "walk_start"), [
    # Turn to 120 deg over 0.5-1.5 s, then walk that way from 2 s: the person must not snap back to
    # its first heading when the walk starts (it did: the pelvis yawed 120 deg in one instant and
    # the hands jumped 0.47 m).
    (Turn(120.0, 0.5, 1.0), 120.0, 2.0),
    # A turn that has not ended when the walk starts (0.5-2.5 s, walk from 1 s) fades out over the
    # start blend.
    (Turn(90.0, 0.5, 2.0), 0.0, 1.0),
])
def test_a_turn_on_the_spot_into_the_walk_has_no_jump(turn, walk_heading, walk_start):
    # A 2 ms grid around the start: no link moves further between two samples than its speed
    # allows; velocities exact throughout.
    body = person_body("p", 1.75, (0.0, 0.0), 0.0, turn=turn,
                       walk=Walk(1.2, heading_deg=walk_heading, start_time=walk_start))
    step, bound = _largest_step(body, np.linspace(walk_start - 0.1, walk_start + 0.3, 201))
    assert step <= bound
    lin, ang = _fd_errors(body, np.linspace(walk_start - 0.1, walk_start + 0.7, 17))
    assert lin < FD_TOL and ang < FD_TOL


def test_sway_into_the_walk_has_exact_velocities():
    # A swaying person (3 cm) who starts walking: the standing sway keeps going while the gait
    # blends in. The API reported the sway's velocity for a standing pose it held still (2.4e-3
    # m/s off at the start).
    body = person_body("p", 1.75, (0.0, 0.0), 0.0, sway=0.03, walk=Walk(1.2, heading_deg=0.0, start_time=1.3))
    lin, ang = _fd_errors(body, np.linspace(1.2, 2.0, 41))
    assert lin < FD_TOL and ang < FD_TOL


@pytest.mark.filterwarnings("ignore:reach.target")  # a target out of reach on purpose
def test_velocities_are_exact_while_reaching_walking_turning_and_swaying():
    # A reach while walking that runs into the stop blend, and a swaying person who turns on the
    # spot while reaching with the other hand: API velocities against central differences.
    walking = person_body("p", 1.7, (0.0, 0.0), 0.0, walk=Walk(1.1, path=((3.0, 0.0),), start_time=0.2),
                          reach=Reach((3.2, 0.6, 1.3), 1.6, 0.6, 0.3, "left"))
    standing = person_body("q", 1.7, (0.0, 0.0), 0.0, sway=0.02, turn=Turn(-70.0, 0.4, 1.0),
                           reach=Reach((0.4, -0.3, 1.1), 0.6, 0.5, 0.2, "right"))
    for body, times in ((walking, np.linspace(1.5, 3.6, 22)), (standing, np.linspace(0.3, 2.0, 18))):
        lin, ang = _fd_errors(body, times)
        assert lin < FD_TOL and ang < FD_TOL


@pytest.mark.parametrize("heading", [179.9])
def test_walking_off_opposite_to_where_the_person_faces_has_no_jump(heading):
    # Facing west and walking east: the start blend turns the person half round. The turn's
    # direction was re-chosen at every instant (the yaw difference wrapped to +-pi, and the pelvis
    # torsion tipped it from one side to the other), so the body flipped between turning left and
    # right: links jumped 0.55 m between 2 ms samples.
    body = person_body("p", 1.75, (0.0, 0.0), heading, walk=Walk(1.3, path=((3.0, 0.0), (3.0, 2.0)), start_time=0.2))
    step, bound = _largest_step(body, np.linspace(0.15, 0.85, 176))
    assert step <= bound
    lin, ang = _fd_errors(body, np.linspace(0.15, 0.85, 8))
    assert lin < FD_TOL and ang < FD_TOL


def test_velocities_are_exact_around_a_tight_corner():
    # 2 m out and back to (0.2, 0.3) (a 170 deg turn, the fillet shortened to half the segment): the
    # heading changes fast, and the position spline between its 1 cm nodes bends away from the
    # exact tangent; the velocity must be the derivative of the positions the API gives
    # (was 2.7e-4 m/s off).
    body = person_body("p", 1.75, (0.0, 0.0), 0.0, walk=Walk(1.0, path=((2.0, 0.0), (0.2, 0.3))))
    stop = body.joint_motion.person.stop_time
    lin, ang = _fd_errors(body, np.linspace(0.0, stop + 0.5, 49))
    assert lin < FD_TOL and ang < FD_TOL


# ---------------------------------------------------------------- bad inputs
@pytest.mark.parametrize(("path", "allowed"), [
    ([], "(n, 2)"), ((), "(n, 2)"), ("abc", "(n, 2)"), (((1.0, 2.0), (3.0,)), "(n, 2)"), ((1.0, 2.0), "(n, 2)"),
    (((1.0, float("nan")),), "finite"), (((1.0, 2.0, 0.0, 0.0),), "(n, 2)"),
])
def test_walk_refuses_a_malformed_path_when_built(path, allowed):
    # The Walk itself checks its waypoints (it did not: the error came later, from the person,
    # as "a finite array of shape (N, N)" about an array the user never wrote).
    with pytest.raises(ConfigError) as e:
        Walk(1.0, path=path)
    assert e.value.field == "walk.path" and e.value.value is path and allowed in str(e.value)


@pytest.mark.parametrize("turn_length", ["x", 0.0, -1.0, float("nan"), float("inf"), None])
def test_walk_refuses_a_bad_turn_length_when_built(turn_length):
    with pytest.raises(ConfigError) as e:
        Walk(1.0, path=((2.0, 0.0), (2.0, 2.0)), turn_length=turn_length)
    assert e.value.field == "walk.turn_length"


@pytest.mark.parametrize("path", [((2.0, 0.0), (2.0, 0.0), (2.0, 2.0)), ((0.0, 0.0),), [[1.0, 1.0], [1.0, 1.0]]])
def test_repeated_waypoints_name_the_path_as_given(path):
    # Repeated waypoints (or one on the start): the error shows the waypoints the user gave, not
    # the internal array with the start prepended.
    with pytest.raises(ConfigError) as e:
        add_person(Scene(), "p", 1.75, (0.0, 0.0), walk=Walk(1.0, path=path))
    assert e.value.field == "walk.path" and e.value.value is path and "1 mm apart" in str(e.value)


def test_a_walk_with_both_a_path_and_a_heading_is_refused():
    # The path's waypoints set the heading; a heading_deg given as well was silently ignored.
    with pytest.raises(ConfigError) as e:
        Walk(1.0, path=((2.0, 0.0),), heading_deg=90.0)
    assert e.value.field == "walk.heading_deg" and e.value.value == 90.0 and "path" in e.value.allowed
    with pytest.raises(ScenarioError, match=r"people\[0\]\.walk\.heading_deg"):
        scenario_from_dict({"people": [{"name": "a", "walk": {"speed": 1.0, "path": [[2.0, 0.0]], "heading_deg": 90}}]})


@pytest.mark.parametrize("name", ["", None, 5, "a/b"])
def test_person_name_errors_name_the_person(name):
    with pytest.raises(ConfigError) as e:
        add_person(Scene(), name)
    assert e.value.field == "person.name" and e.value.value == name


def test_a_turn_after_the_walk_starts_is_refused():
    # A turn on the spot happens while standing; one that would start once the walk is under way
    # was silently ignored.
    with pytest.raises(ConfigError) as e:
        person_body("p", 1.75, turn=Turn(90.0, 3.0, 1.0), walk=Walk(1.0, heading_deg=0.0, start_time=2.0))
    assert e.value.field == "turn.start_time" and e.value.value == 3.0 and "2" in e.value.allowed


# ---------------------------------------------------------------- Boulic (1990) timing and the walk it gives
def _boulic(height, speed):
    """Independent reading of Boulic et al. (1990): RV, D_c, stride, cadence, D_s."""
    ht = HIP * height
    rv = speed / ht
    dc = 1.346 / math.sqrt(rv)
    return {"rv": rv, "cycle": dc, "stride": 1.346 * math.sqrt(rv) * ht, "cadence": 120.0 / dc,
            "stance": 0.752 * dc - 0.143, "ht": ht}


@functools.cache
def _walker(height, speed, body="planted"):
    """A walker along +x from t = 0 (read-only: shared by the tests that ask for the same one)."""
    return person_body("p", height, (0.0, 0.0), 0.0, walk=Walk(speed, heading_deg=0.0, body=body))


# RV = 3 /s is the top of the model's third range (gait.py, docs/people.md): 2.384 / 2.782 / 3.100 m/s.
EDGE = 3.0 * (1 - 1e-9)


@pytest.mark.parametrize("height", [1.5, 1.75, 1.95])
@pytest.mark.parametrize("speed", [0.3, 0.8, 1.3, 2.0, "edge"])
def test_boulic_timing_and_the_walk_it_gives(height, speed):
    speed = EDGE * HIP * height if speed == "edge" else speed
    ref = _boulic(height, speed)
    # The default (planted) body, or where it refuses the speed, the smooth one (the refusal names
    # the speed and points to it).
    try:
        body = _walker(height, speed)
    except ConfigError as e:
        assert e.field == "walk.speed" and e.value == speed and "smooth" in e.allowed
        body = _walker(height, speed, "smooth")
    timing = body.joint_motion.person.cycle.timing
    # Closed forms, rounding only (1e-12 relative).
    for name, attr in (("cycle", "cycle_duration"), ("stride", "stride_length"), ("cadence", "cadence"),
                       ("stance", "support_duration")):
        assert getattr(timing, attr) == pytest.approx(ref[name], rel=1e-12, abs=1e-12)
    assert timing.step_length == pytest.approx(0.5 * ref["stride"], rel=1e-12, abs=1e-12)
    dc = ref["cycle"]
    t0 = 2.0  # after the 0.6 s start blend
    for t in (t0, t0 + 0.37 * dc):
        a, b = body.state(t), body.state(t + dc)
        # One cycle later every joint angle repeats and every link is one stride further along x:
        # the mean speed over whole cycles is v and the stride the published one (rounding, 1e-9 m).
        np.testing.assert_allclose(body.joint_motion.q(t + dc), body.joint_motion.q(t), rtol=0, atol=1e-9)
        np.testing.assert_allclose(b.positions - a.positions, np.tile([ref["stride"], 0.0, 0.0], (len(a.positions), 1)),
                                   rtol=0, atol=1e-9)
    # Half a cycle later the legs have swapped (left and right hip angles exchange): cadence 2 / D_c.
    q = body.joint_motion.q
    names = body.tree.joint_names
    r, left = names.index("right_hip_flexion"), names.index("left_hip_flexion")
    assert q(t0 + 0.5 * dc)[left] == pytest.approx(q(t0)[r], rel=0, abs=1e-9)
    # Every joint within its limits through the start blend and a whole cycle.
    lo, hi = body.tree.limits.T
    for t in np.linspace(0.0, 0.6 + dc, 16):
        assert np.all((q(t) >= lo) & (q(t) <= hi))


def test_walks_beyond_the_model_range_are_refused():
    for height in (1.5, 1.75, 1.95):
        v = 3.0 * (1 + 1e-6) * HIP * height
        with pytest.raises(ConfigError) as e:
            _walker(height, v)
        assert e.value.field == "walk.speed" and e.value.value == v and "3" in e.value.allowed


def _sole(height):
    """Heel and toe of a sole in the foot link frame (bottom corners of the foot box, mid-line) [m]."""
    return np.array([[-HEEL * height, 0.0, -ANKLE * height], [(FOOT - HEEL) * height, 0.0, -ANKLE * height]])


@pytest.mark.parametrize(("height", "speed"), [(1.5, 0.8), (1.5, 2.0), (1.75, 1.3), (1.95, 0.8), (1.95, 2.0)])
def test_planted_stance_foot_and_pelvis_speed(height, speed):
    ref = _boulic(height, speed)
    body = _walker(height, speed)
    dc, rs = ref["cycle"], ref["stance"] / ref["cycle"]
    n0 = math.ceil(2.0 / dc)
    sole = _sole(height)
    # Published single support of the right foot: from the end of double support (D_s/D_c - 1/2)
    # to the left heel strike (1/2). The lowest sole point must stay on the floor and not slide.
    # What the model can honestly meet: its sagittal fit is exact (rounding), but the 3-D tree's
    # pelvis list and the hip abduction that keeps the legs in their lanes are outside that fit;
    # they move the contact by up to 0.06 m/s at RV 2.5 (measured 0.060 at 1.5 m / 2.0 m/s,
    # 0.015 at 1.75 m / 1.3 m/s) and the smooth maximum that picks the foot holding the pelvis lets
    # a swinging foot a few mm above the floor lift it (measured up to 9 mm, 1.95 m / 0.8 m/s).
    slip, z = [], []
    for u in np.linspace(rs - 0.5, 0.5, 25)[1:-1]:
        st = body.state(body.joint_motion.person.gait_origin + (n0 + u) * dc)
        p = st.pose("right_foot").apply(sole)
        low = p[np.argmin(p[:, 2])]
        v = st.point_velocity("right_foot", low[None])[0]
        slip.append(math.hypot(v[0], v[1]))
        z.append(low[2])
    assert max(slip) < 0.07
    assert 0.0 <= min(z) and max(z) < 0.010
    # The pelvis moves forward as published: v plus the derivative of the forward sway
    # a_a H_t sin 2 pi (2u + 2 phi_a), a_a = 0.021, phi_a = 0.625 - D_s / D_c (Boulic appendix A).
    # The stance warp meets it up to its interpolation (docs: max 0.05 m/s): tolerance 0.06 m/s.
    amp = 0.021 * ref["ht"] * 4 * math.pi / dc
    errs, on_floor = [], 0
    for u in np.linspace(0.0, 1.0, 40, endpoint=False):
        st = body.state(body.joint_motion.person.gait_origin + (n0 + u) * dc)
        vx = st.state("pelvis").linear_velocity[0]
        errs.append(vx - (speed + amp * math.cos(2 * math.pi * (2 * u + 2 * (0.625 - rs)))))
        on_floor += float(np.min(st.pose("right_foot").apply(sole)[:, 2])) < 0.005
    assert max(abs(e) for e in errs) < 0.06
    # The foot is on the floor (lowest sole point within 5 mm) for less than the published stance
    # (docs/people.md: 0.46-0.55 of a cycle against D_s / D_c = 0.58-0.66; the landing foot reaches
    # the floor after the published heel strike). 40 samples: +-1/40 either side.
    assert 0.46 - 0.025 <= on_floor / 40 <= 0.55 + 0.025 < rs
    # That sway is +-(13-23) % of v here: the torso's speed varies as measured gait's does.
    assert 0.12 * speed < amp < 0.24 * speed


@pytest.mark.parametrize("height", [1.5, 1.95])
@pytest.mark.parametrize("speed", [0.8, 2.0])
def test_limb_peak_speeds_are_the_stated_ones(height, speed):
    # docs/people.md: the swinging toe peaks at 3.7-4.8 v (0.8-2.2 m/s, slower walks faster
    # relative to v); the hand swings at less than the toe and more than v. Measured here
    # 3.71-4.91 v; bounds 3.4-5.2 v (the stated range +-8 % for the other heights' proportions).
    body = _walker(height, speed)
    dc = _boulic(height, speed)["cycle"]
    toe = _sole(height)[1]
    hand_c = np.array([0.0, 0.0, -0.5 * ARM[2] * height])
    peak_toe = peak_hand = 0.0
    for t in 2.0 + np.linspace(0.0, dc, 48, endpoint=False):
        st = body.state(t)
        p = st.pose("right_foot").apply(toe)
        peak_toe = max(peak_toe, float(np.linalg.norm(st.point_velocity("right_foot", p[None])[0])))
        h = st.pose("right_hand").apply(hand_c)
        peak_hand = max(peak_hand, float(np.linalg.norm(st.point_velocity("right_hand", h[None])[0])))
    assert 3.4 * speed < peak_toe < 5.2 * speed
    assert speed < peak_hand < peak_toe


# ---------------------------------------------------------------- paths
def _yaw(rotation):
    return math.atan2(rotation[1, 0], rotation[0, 0])


def test_path_corners_heading_speed_and_arrival():
    # A square's three sides, 4 m each, at 1.2 m/s from t = 0.5 s. The head faces the path: its
    # yaw is the path heading (the thorax turns against the pelvis torsion, the neck against the
    # thorax). Exactly on a segment's heading away from the fillets; up to 2e-3 rad from the pelvis
    # list tilting the head's axes (0.01 RV rad x a few deg of tilt).
    body = person_body("p", 1.8, (0.0, 0.0), 0.0, walk=Walk(1.2, path=((4.0, 0.0), (4.0, 4.0), (0.0, 4.0)),
                                                           start_time=0.5))
    person = body.joint_motion.person
    # The path is 12 m less what the two rounded corners cut (2 (2 d - l) for a 90 deg fillet
    # of ramp length l = 1 m leaving the segment at d from the corner); it is covered at the
    # mean speed, then the person stands on the last waypoint.
    for t, heading in ((0.5 + 1.5 / 1.2, 0.0), (0.5 + 6.0 / 1.2, math.pi / 2)):
        assert abs(math.remainder(_yaw(body.state(t).pose("head").rotation) - heading, 2 * math.pi)) < 2e-3
    end = person.arrival_time
    st = body.state(person.stop_time + 1.0)
    pelvis = st.pose("pelvis").position
    np.testing.assert_allclose(pelvis[:2], (0.0, 4.0), rtol=0, atol=1e-9)
    assert abs(math.remainder(_yaw(st.pose("pelvis").rotation) - math.pi, 2 * math.pi)) < 1e-9
    np.testing.assert_allclose(st.linear_velocities, 0.0, rtol=0, atol=1e-12)
    # The walk lasts path length / v plus 0.6 s (its rate ramps up over 0.6 s at the start and down
    # over 0.6 s at the end, each covering half of what full speed would), give or take the forward
    # sway's lead at either end (2 a_a H_t / v = 2 x 0.021 x 0.53 x 1.8 m / 1.2 m/s = 0.033 s):
    # between 12 m - 2 x 0.5 m and 12 m (each fillet cuts < 0.5 m).
    sway = 2 * 0.021 * HIP * 1.8 / 1.2
    assert (12.0 - 1.0) / 1.2 + 0.6 - sway < end - 0.5 < 12.0 / 1.2 + 0.6 + sway
    # Through both corners (their fillets span about 3.3-4.2 s and 6.5-7.3 s), the pelvis's horizontal speed
    # never jumps: no two 10 ms samples differ by more than the walk's own pelvis acceleration
    # allows (the forward sway's 2 (4 pi / D_c) a_a H_t (4 pi / D_c) ~ 4 m/s^2 at 1.2 m/s, plus
    # the weight transfer: measured 0.03 m/s per 10 ms; bound 0.06 m/s).
    for ts in (np.arange(3.0, 4.6, 0.01), np.arange(6.4, 8.0, 0.01)):
        sp = np.array([np.hypot(*body.state(t).state("pelvis").linear_velocity[:2]) for t in ts])
        assert np.max(np.abs(np.diff(sp))) < 0.06


# ---------------------------------------------------------------- reaching
def _arm_reaches(height, side, d):
    """Whether the documented three-joint arm (flexion about -y, abduction about the side's x,
    elbow about -y; upper arm a, forearm + half hand b) can put the hand centre on the
    shoulder-frame point d, by its own closed form: the elbow from the law of cosines, then
    |lateral| <= a + b cos(elbow) (no humeral rotation)."""
    a, b = ARM[0] * height, (ARM[1] + 0.5 * ARM[2]) * height
    r = float(np.linalg.norm(d))
    if not abs(a - b) + 1e-3 < r < a + b - 1e-3:
        return False
    elbow = math.pi - math.acos((a * a + b * b - r * r) / (2 * a * b))
    return abs(d[1]) < a + b * math.cos(elbow) - 1e-3 and elbow < math.radians(150)


@pytest.mark.parametrize("side", ["right", "left"])
def test_reach_hits_reachable_targets_on_both_sides_within_limits(side):
    s = 1.0 if side == "left" else -1.0
    height = 1.7
    hand_c = np.array([0.0, 0.0, -0.5 * ARM[2] * height])
    lo, hi = None, None
    # Targets in front of and beside the shoulder, high and low, for a person at (1, -2) facing
    # 135 deg: in the thorax frame (x forward, y left).
    for local in ((0.35, 0.05, 0.0), (0.3, 0.15, 0.25), (0.45, 0.1, -0.2), (0.25, 0.2, -0.35), (0.5, 0.0, 0.2)):
        d = np.array([local[0], s * local[1], local[2]])
        assert _arm_reaches(height, side, d)
        stand = person_body("p", height, (1.0, -2.0), 135.0)
        st0 = stand.state(0.0)
        shoulder = st0.pose(f"{side}_shoulder").position
        target = shoulder + st0.pose("thorax").rotation @ d
        body = person_body("p", height, (1.0, -2.0), 135.0, reach=Reach(tuple(target), 0.3, 0.6, 0.5, side))
        lo, hi = body.tree.limits.T
        # Hit to rounding (the docs: 1e-9 m), and no warning of a short reach.
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            hand = body.state(1.2).pose(f"{side}_hand").apply(hand_c)
        np.testing.assert_allclose(hand, target, rtol=0, atol=1e-9)
        # Every joint within its limits at every time of the reach (10 ms grid).
        for t in np.arange(0.0, 2.5, 0.01):
            q = body.joint_motion.q(t)
            assert np.all(q >= lo - 1e-12) and np.all(q <= hi + 1e-12)


def test_reach_beyond_the_arm_or_its_joints_is_the_documented_best_effort():
    # Not an error (docs/people.md): beyond the arm the hand stops at full stretch (1 mm short)
    # on the shoulder-target line; a point the three arm joints cannot reach (here straight out to
    # the side, closer than the stretched arm: no humeral rotation) leaves the hand short; the
    # joints stay within their limits in both.
    height = 1.75
    hand_c = np.array([0.0, 0.0, -0.5 * ARM[2] * height])
    stand = person_body("p", height, (0.0, 0.0), 0.0).state(0.0)
    shoulder = stand.pose("left_shoulder").position
    for d, beyond in (((1.5, 0.4, 0.3), True), ((-0.05, 0.5, 0.1), False)):
        d = np.asarray(d)
        assert not _arm_reaches(height, "left", d)
        target = shoulder + d
        body = person_body("p", height, (0.0, 0.0), 0.0, reach=Reach(tuple(target), 0.0, 0.5, math.inf, "left"))
        # Not silent: the first state of the reach warns with the distance left (> REACH_MISS = 1 cm).
        with pytest.warns(UserWarning, match=r"reach\.target = .*the left hand stops 0\.\d+ m from it"):
            st = body.state(1.0)
        hand = st.pose("left_hand").apply(hand_c)
        lo, hi = body.tree.limits.T
        q = body.joint_motion.q(1.0)
        assert np.all(q >= lo) and np.all(q <= hi)
        if beyond:
            reach = (ARM[0] + ARM[1] + 0.5 * ARM[2]) * height - 1e-3
            assert np.linalg.norm(hand - shoulder) == pytest.approx(reach, rel=0, abs=1e-9)
            np.testing.assert_allclose((hand - shoulder) / reach, d / np.linalg.norm(d), rtol=0, atol=1e-9)
        else:
            assert np.linalg.norm(hand - target) > 0.05


# ---------------------------------------------------------------- same input, same bytes
@pytest.mark.filterwarnings("ignore:reach.target")  # a target out of reach on purpose
def test_people_are_deterministic_and_independent_of_the_order_of_queries():
    # Nothing in a person is random; two builds give the same bytes, and a state does not depend
    # on which times were asked before (the per-time caches).
    def build():
        return person_body("p", 1.8, (0.5, 0.2), 10.0, sway=0.01, turn=Turn(40.0, 0.1, 0.5),
                           walk=Walk(1.1, path=((3.0, 1.0), (3.0, 4.0)), start_time=0.8),
                           reach=Reach((2.0, 1.0, 1.3), 1.5, 0.5, 0.5, "left"))
    a, b = build(), build()
    times = [0.0, 0.45, 1.0, 1.7, 2.9, 4.4]
    for t in times:
        sa = a.state(t)
        for _ in range(2):
            sb = b.state(t)
            assert sa.positions.tobytes() == sb.positions.tobytes()
            assert sa.linear_velocities.tobytes() == sb.linear_velocities.tobytes()
            assert sa.angular_velocities.tobytes() == sb.angular_velocities.tobytes()
    c = build()
    for t in reversed(times):
        assert a.state(t).positions.tobytes() == c.state(t).positions.tobytes()


_NAN, _INF = float("nan"), float("inf")


@pytest.mark.parametrize(("entry", "field"), [
    ({"hieght": 1.7}, "people[0].hieght"),
    ({"height": _NAN}, "people[0].height"),
    ({"height": _INF}, "people[0].height"),
    ({"height": -1.7}, "people[0].height"),
    ({"height": "tall"}, "people[0].height"),
    ({"height": 3.0}, "people[0].height"),
    ({"walk": {"speed": _NAN, "heading_deg": 0.0}}, "people[0].walk.speed"),
    ({"walk": {"speed": -1.0, "heading_deg": 0.0}}, "people[0].walk.speed"),
    ({"walk": {"speed": "fast", "heading_deg": 0.0}}, "people[0].walk.speed"),
    ({"walk": {"speed": 1.0, "heading_deg": 0.0, "sped": 1}}, "people[0].walk.sped"),
    ({"walk": {"speed": 1.0, "path": []}}, "people[0].walk.path"),
    ({"walk": {"speed": 1.0, "path": [[0.0, 0.0]]}}, "people[0].walk.path"),
    ({"walk": {"speed": 1.0, "path": [[1.0, 0.0], [1.0, 0.0]]}}, "people[0].walk.path"),
    ({"walk": {"speed": 1.0, "path": [[1.0, 0.0], [1.0]]}}, "people[0].walk.path"),
    ({"walk": {"speed": 1.0, "path": 3}}, "people[0].walk.path"),
    ({"reach": {"target": [1.0, 0.0, 1.0], "side": "up"}}, "people[0].reach.side"),
    ({"reach": {"target": [1.0, 0.0, 1.0], "arm": "left"}}, "people[0].reach.arm"),
    ({"sway": _INF}, "people[0].sway"),
    ({"walk": {"speed": 1.0, "heading_deg": 0.0, "start_time": 1.0}, "turn": {"heading_deg": 90.0, "start_time": 2.0}},
     "people[0].turn.start_time"),
])
def test_bad_scenario_people_entries_name_the_field(entry, field):
    base = {"name": "a", "height": 1.7, "position": [0.0, 0.0]}
    with pytest.raises(ScenarioError) as e:
        scenario_from_dict({"people": [{**base, **entry}]})
    assert field in str(e.value)
    assert "Traceback" not in str(e.value)


def test_stance_foot_at_the_top_of_the_model_range_is_the_documented_one():
    # RV = 3 /s (docs/people.md, "near the top of the range"): in the published single support the
    # standing foot may lift off the floor by up to 6 cm at the start (the back foot's push-off
    # holds the pelvis up) and slide up to 0.15 m/s; it never sinks into the floor. Bounds: the
    # documented values, 40 samples of the single support.
    height = 1.75
    speed = EDGE * HIP * height
    ref = _boulic(height, speed)
    body = _walker(height, speed)
    dc, rs = ref["cycle"], ref["stance"] / ref["cycle"]
    n0 = math.ceil(2.0 / dc)
    sole = _sole(height)
    for u in np.linspace(rs - 0.5, 0.5, 42)[1:-1]:
        st = body.state(body.joint_motion.person.gait_origin + (n0 + u) * dc)
        p = st.pose("right_foot").apply(sole)
        low = p[np.argmin(p[:, 2])]
        v = st.point_velocity("right_foot", low[None])[0]
        assert math.hypot(v[0], v[1]) < 0.15
        assert 0.0 <= low[2] < 0.06
