"""People through the public API, against an independent reading of the formulas.

The references here are written out from the papers and the documentation
(docs/people.md), not taken from twinsense.scene.gait or .human: the Boulic
(1990) gait timing, the pelvis and foot motion a walker must show, the exact
velocities a sensor sees (central finite differences of the poses), the
reach's two-link arm and the errors of bad inputs.
"""


import numpy as np
import pytest

from twinsense.errors import ConfigError
from twinsense.scene import Scene
from twinsense.scene.human import Turn, Walk, add_person, person_body

HIP = 0.530  # hip-joint height / body height (Winter 2009, fig. 4.1)
ARM = (0.186, 0.146, 0.108)  # upper arm, forearm, hand / body height (same table)
HEEL, FOOT, ANKLE = 0.25 * 0.152, 0.152, 0.039  # sole: heel behind the ankle, length, ankle height (/ H)

# Central differences over h = 1e-6 s. Where the motion is C2 the truncation is h^2 |x'''| / 6
# < 1e-9 m/s (|x'''| < 1e3 m/s^3 for the fastest link, a toe) and the rounding 1e-16 m / 1e-6 s
# ~ 1e-10 m/s. The motion is C1 only at a few instants (a blend's or a ramp's start and end,
# the stance contact rolling from heel to toe): there the central difference is off by at most
# h |jump of the acceleration| / 4, < 1e-6 * 80 / 4 = 2e-5 m/s for jumps below 80 m/s^2 (8 g;
# the largest error measured in these scenes is 4.3e-6 m/s, a jump of ~17 m/s^2 at the end of
# a start blend). Rotations: the same bound in rad/s (measured 4e-6 rad/s).
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
    pos = np.array([body.state(t).positions for t in times])
    speed = max(float(np.max(np.linalg.norm(body.state(t).linear_velocities, axis=1))) for t in times)
    step = float(np.max(np.linalg.norm(np.diff(pos, axis=0), axis=2)))
    return step, 1.01 * speed * float(np.max(np.diff(times)))


# ---------------------------------------------------------------- continuity and exact velocities
def test_turn_on_the_spot_then_walk_has_no_jump():
    # Turn to 120 deg over 0.5-1.5 s, then walk that way from 2 s: the person must not snap back to
    # its first heading when the walk starts (it did: the pelvis yawed 120 deg in one instant and
    # the hands jumped 0.47 m). Fine grid of 2 ms over the start: no link moves further between
    # two samples than its speed allows.
    body = person_body("p", 1.75, (0.0, 0.0), 0.0, turn=Turn(120.0, 0.5, 1.0),
                       walk=Walk(1.2, heading_deg=120.0, start_time=2.0))
    step, bound = _largest_step(body, np.linspace(1.4, 2.8, 701))
    assert step <= bound
    lin, ang = _fd_errors(body, np.linspace(1.9, 2.7, 33))
    assert lin < FD_TOL and ang < FD_TOL


def test_turn_still_under_way_when_the_walk_starts_blends_out():
    # A turn that has not ended when the walk starts (0.5-2.5 s, walk from 1 s) fades out over the
    # start blend: positions continuous and velocities exact throughout.
    body = person_body("p", 1.75, (0.0, 0.0), 0.0, turn=Turn(90.0, 0.5, 2.0),
                       walk=Walk(1.2, heading_deg=0.0, start_time=1.0))
    step, bound = _largest_step(body, np.linspace(0.8, 1.8, 501))
    assert step <= bound
    lin, ang = _fd_errors(body, np.linspace(0.9, 1.7, 33))
    assert lin < FD_TOL and ang < FD_TOL


def test_sway_into_the_walk_has_exact_velocities():
    # A swaying person (3 cm) who starts walking: the standing sway keeps going while the gait
    # blends in. The API reported the sway's velocity for a standing pose it held still (2.4e-3
    # m/s off at the start).
    body = person_body("p", 1.75, (0.0, 0.0), 0.0, sway=0.03, walk=Walk(1.2, heading_deg=0.0, start_time=1.3))
    lin, ang = _fd_errors(body, np.linspace(1.2, 2.0, 41))
    assert lin < FD_TOL and ang < FD_TOL


def test_velocities_are_exact_around_a_tight_corner():
    # 2 m out and back to (0.2, 0.3) (a 170 deg turn, the fillet shortened to half the segment): the
    # heading changes fast, and the position spline between its 1 cm nodes bends away from the
    # exact tangent; the velocity must be the derivative of the positions the API gives
    # (was 2.7e-4 m/s off).
    body = person_body("p", 1.75, (0.0, 0.0), 0.0, walk=Walk(1.0, path=((2.0, 0.0), (0.2, 0.3))))
    stop = body.joint_motion.person.stop_time
    lin, ang = _fd_errors(body, np.linspace(0.0, stop + 0.5, 161))
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
