"""The planted walker's feet against the floor in 3-D (the full tree, not the sagittal fit).

Reference: the floor, z = 0, and the documented figures (docs/people.md, 'Feet on the floor').
The sagittal fit keeps every foot that holds the pelvis on the floor; the 3-D tree's pelvis list
(a roll of up to 0.02 RV rad, RV = v / H_t) drops the back leg's hip joint by up to
hw sin(0.02 RV) = 0.0478 H x 0.050 = 3.6 mm at 1.5 m / 2.0 m/s (RV 2.52), plus the hip-rotation
term r sin(torsion) sin(list) <= 0.4 H_t x 0.17 x 0.05 = 2.8 mm in the other direction or the same:
the push-off toe may go up to about 4.5 mm into the floor (measured 3.1-3.9 mm), never more;
a sole centimetres deep would be a broken fit.
"""

import numpy as np
import pytest

from twinsense.scene.human import Walk, person_body

HEEL, FOOT, ANKLE = 0.25 * 0.152, 0.152, 0.039  # sole: heel behind the ankle, length, ankle height (/ H)


@pytest.mark.parametrize("height", [1.5, 1.95])
def test_the_push_off_toe_stays_within_the_documented_depth(height):
    body = person_body("p", height, (0.0, 0.0, 0.25), 0.0, walk=Walk(2.0, heading_deg=0.0, body="planted"))
    person = body.joint_motion.person
    dc = person.cycle.timing.cycle_duration
    sole = np.array([[-HEEL * height, 0.0, -ANKLE * height], [(FOOT - HEEL) * height, 0.0, -ANKLE * height]])
    low = min(float(body.state(person.gait_origin + (3 + u) * dc).pose(f"{side}_foot").apply(sole)[:, 2].min())
              for u in np.linspace(0.0, 1.0, 120, endpoint=False) for side in ("right", "left"))
    # On a 0.25 m platform: the floor is z = 0.25 m.
    assert -0.0045 < low - 0.25 < 0.0
