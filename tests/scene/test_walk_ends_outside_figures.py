"""The figures docs/people.md gives for a walk's start and closing steps, on the walks that set them.

docs/people.md ("Paths, starts and stops"), over 129 random walks (1.5-1.95 m, 0.5-2.0 m/s, 0.1-4 m
paths with corners, both bodies, a Turn before the walk or a start at an angle, starts before t = 0,
sway 0-5 cm): a foot that stands through a closing step slides at most 0.028 m/s and its sole moves
at most 2.2 mm, with a standing sway of 3-5 cm 0.035 m/s and 2.7 mm; no sole more than 1.5 mm (with
sway 1.9 mm) below the floor or the gait's own lowest sole at the arrival, whichever is lower; the
start's swinging foot stays above -0.065 mm and, until 5 mm up, moves across the floor at most
0.061 m/s (0.11 m/s with sway). Before, the page said 0.025 m/s, 2.1 mm, 1.3 mm below the arrival's
lowest sole (8 mm below it where that sole was 6 mm up) and 0.071 m/s, over walks without sway.

Reference written out here: the sole points' heights and velocities from the body's own link states,
sampled every 2.5 ms; the bounds are the documented figures with the sampling's margin (a sole point
moving at 0.1 m/s goes 0.25 mm between samples).
"""

import math

import numpy as np
import pytest

from twinsense.scene.human import Turn, Walk, foot_sole_points, person_body

CONTACT = 0.005  # [m] a sole point this high or lower is on the floor
# (height, speed, path, body, heading, start_time, turn, sway) of the walks that set the figures, and the
# figures: standing slip [m/s], standing sole travel [m], depth [m], start sole floor [m], start rise speed [m/s].
WALKS = {
    "sway-travel": ((1.543, 1.717, ((0.727, -2.99),), "auto", -91.62, 0.944, None, 0.0462),
                    (0.035, 0.0027, 0.0019, -0.065e-3, 0.11)),
    "sway-slip": ((1.95, 2.0, ((-0.11, 0.589), (-1.139, 1.71)), "smooth", 100.56, 0.746, None, 0.046),
                  (0.035, 0.0027, 0.0019, -0.065e-3, 0.11)),
    "turn-depth": ((1.599, 1.91, ((-0.31, -0.479), (-1.098, -0.248), (-1.674, -1.157)), "smooth", -186.08, -0.162,
                    Turn(-122.85, -1.662, 1.2), 0.0091), (0.035, 0.0027, 0.0019, -0.065e-3, 0.11)),
    "no-sway-slow": ((1.838, 0.5, ((-1.344, -0.259),), "auto", -169.07, 0.934, None, 0.0),
                     (0.028, 0.0022, 0.0015, -0.065e-3, 0.061)),
}


def _soles(body, t, side, sole):
    st = body.state(float(t))
    p = st.pose(f"{side}_foot").apply(sole)
    return p, st.point_velocity(f"{side}_foot", p)


@pytest.mark.parametrize("name", list(WALKS))
def test_the_documented_figures_hold(name):
    (height, speed, path, body_kind, heading, t0, turn, sway), figures = WALKS[name]
    slip_max, travel_max, depth_max, start_floor, rise_max = figures
    body = person_body("p", height, (0.0, 0.0), heading, sway=sway, turn=turn,
                       walk=Walk(speed, path=path, start_time=t0, body=body_kind))
    person = body.joint_motion.person
    sole = foot_sole_points(height)
    ta = person.arrival_time
    floor = min(0.0, min(float(_soles(body, ta, s, sole)[0][:, 2].min()) for s in ("right", "left")))
    for k in (0, 1):
        track = {"right": [], "left": []}
        for t in np.arange(ta + 0.4 * k, ta + 0.4 * (k + 1) + 1e-9, 0.0025):
            for side in track:
                p, v = _soles(body, t, side, sole)
                assert p[:, 2].min() >= floor - depth_max - 2e-4
                track[side].append((p, v))
        travel = {s: max(float(np.max(np.linalg.norm(p - tr[0][0], axis=1))) for p, _ in tr) for s, tr in track.items()}
        stood = min(travel, key=travel.get)
        assert travel[stood] <= travel_max + 2e-4
        slip = max(float(np.max(np.hypot(v[p[:, 2] < CONTACT, 0], v[p[:, 2] < CONTACT, 1]), initial=0.0))
                   for p, v in track[stood])
        assert slip <= slip_max + 1e-3
    # The start's swinging (left) foot: above the floor, and slow across it until it is 5 mm up.
    rising = True
    for t in np.arange(t0, t0 + 0.6, 0.0025):
        p, v = _soles(body, t, "left", sole)
        assert p[:, 2].min() >= start_floor - 1e-5
        if rising and p[:, 2].min() > CONTACT:
            rising = False
        if rising:
            on = p[:, 2] < CONTACT
            assert math.hypot(*v[on][np.argmax(np.hypot(v[on, 0], v[on, 1]))][:2]) <= rise_max + 5e-3
