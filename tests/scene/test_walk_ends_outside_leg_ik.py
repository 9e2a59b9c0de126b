"""The closed-form leg inverse kinematics of a walk's start and closing steps (PersonMotion._leg_ik).

docs/people.md ("Paths, starts and stops"): the knee from the hip-ankle distance, the leg's plane through
the hip, the ankle and the foot's forward axis, the hip's Z-Y-X angles, the ankle from the foot's
pitch. Five joints set the foot's position and forward axis (five numbers); its roll about that axis
follows the leg's plane.

References written out here: the tree's own forward kinematics (a foot pose made by the leg's joints is
solved back to the same joints and pose), and scipy's least_squares on that forward kinematics (for a
foot pose the leg cannot take exactly, the closed form and the numerical solution agree, and both put
the foot's position and forward axis on the target). Before, two families of reachable poses came back
wrong: a foot pointing behind the hip-ankle line (knee bent past about 90 deg with the ankle
plantarflexed) was solved in the mirrored leg plane, and a hip flexed past 90 deg on the other branch
of the Z-Y-X angles (the foot 7-77 cm off).
"""

import numpy as np
import pytest
from scipy.optimize import least_squares

from twinsense.scene.human import LIMIT_MARGIN, PersonMotion, human_tree
from twinsense.scene.pose import Pose


def _person(height):
    return PersonMotion(human_tree(height), height)


def _fk(person, side, q_leg, pelvis):
    """World pose of ``side``'s foot link with the leg at ``q_leg`` and the pelvis at (p, yaw, roll)."""
    tree = person.tree
    q = np.zeros(tree.n_joints)
    q[person._leg_columns(side)] = q_leg
    p, yaw, roll = pelvis
    cz, sz, cx, sx = np.cos(yaw), np.sin(yaw), np.cos(roll), np.sin(roll)
    rot = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]]) @ np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx],
                                                                                   [0.0, sx, cx]])
    return tree.forward(q, None, Pose(p, rot)).pose(f"{side}_foot")


@pytest.mark.parametrize("height", [1.5, 1.95])
@pytest.mark.parametrize("side", ["left", "right"])
def test_a_foot_pose_of_the_leg_comes_back_to_its_joints(height, side):
    person = _person(height)
    lo, hi = person.tree.limits[person._leg_columns(side)].T
    rng = np.random.default_rng(11)
    for _ in range(300):
        # Every joint anywhere LIMIT_MARGIN inside its limits (the closed form's own range), the knee bent
        # (a straight or hyperextended knee has no leg plane: the mirror image is the same foot pose).
        q = rng.uniform(lo + LIMIT_MARGIN, hi - LIMIT_MARGIN)
        q[3] = rng.uniform(0.05, hi[3] - LIMIT_MARGIN)
        pelvis = (rng.uniform(-2.0, 2.0, 3), rng.uniform(-np.pi, np.pi), rng.uniform(-0.2, 0.2))
        foot = _fk(person, side, q, pelvis)
        back = person._leg_ik(pelvis, side, foot)
        # The joints themselves (a unique solution with the knee bent), and the pose: arcsin / arctan2 of
        # products of unit vectors, 1e-12 each; bound 1e-9 rad and 1e-9 m. Before, up to 2.2 rad and 1.7 m.
        assert np.max(np.abs(back - q)) < 1e-9, (np.degrees(q), np.degrees(back))
        again = _fk(person, side, back, pelvis)
        assert np.max(np.abs(again.position - foot.position)) < 1e-9
        assert np.max(np.abs(again.rotation - foot.rotation)) < 1e-9


def test_the_closed_form_is_the_least_squares_solution_for_a_foot_the_leg_cannot_roll():
    person = _person(1.75)
    side = "left"
    lo, hi = person.tree.limits[person._leg_columns(side)].T
    rng = np.random.default_rng(5)
    checked = 0
    for _ in range(60):
        # A walking leg's range (knee 5-80 deg, hip flexion up to 60 deg), the foot then rolled by up to
        # 0.3 rad about its forward axis and moved by 2 cm: five of its six numbers are reachable.
        q = rng.uniform(lo + LIMIT_MARGIN, hi - LIMIT_MARGIN)
        q[1], q[3] = rng.uniform(-0.4, 1.0), rng.uniform(0.1, 1.4)
        pelvis = (np.array([0.0, 0.0, 0.93]), rng.uniform(-np.pi, np.pi), rng.uniform(-0.1, 0.1))
        foot = _fk(person, side, q, pelvis)
        a = rng.uniform(-0.3, 0.3)
        roll = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])
        target = Pose(foot.position + rng.normal(0.0, 0.02, 3), foot.rotation @ roll)

        def residual(x, target=target, pelvis=pelvis):
            f = _fk(person, side, x, pelvis)
            return np.r_[f.position - target.position, f.rotation[:, 0] - target.rotation[:, 0]]

        sol = least_squares(residual, q, bounds=(lo + LIMIT_MARGIN, hi - LIMIT_MARGIN), xtol=1e-15, ftol=1e-15,
                            gtol=1e-15)
        if np.max(np.abs(sol.fun)) > 1e-10 or np.any(np.isclose(sol.x, lo + LIMIT_MARGIN) | np.isclose(
                sol.x, hi - LIMIT_MARGIN)):
            continue  # off the leg's reach or held at a limit: no exact solution to compare
        checked += 1
        closed = person._leg_ik(pelvis, side, target)
        # Both put the foot on the target's position and forward axis (least_squares to its 1e-10 stop,
        # the closed form to rounding); the same joints to within the least-squares stop over the
        # Jacobian's smallest singular value (>= 0.05 m / rad here): 1e-8 rad.
        assert np.max(np.abs(residual(closed))) < 1e-12
        assert np.max(np.abs(closed - sol.x)) < 1e-8
    assert checked >= 40


def test_beyond_the_leg_the_foot_stops_on_the_line_to_the_target():
    person = _person(1.75)
    thigh_shank = (0.245 + 0.246) * 1.75  # THIGH + SHANK [H] (Winter's table)
    pelvis = (np.zeros(3), 0.3, 0.0)
    hip = _fk(person, "right", np.zeros(5), pelvis).position - np.array([0.0, 0.0, -thigh_shank])
    for reach in (1.0, 1.2, 3.0):
        direction = np.array([0.2, -0.1, -1.0]) / np.linalg.norm([0.2, -0.1, -1.0])
        target = Pose(hip + reach * thigh_shank * direction, np.eye(3))
        q = person._leg_ik(pelvis, "right", target)
        foot = _fk(person, "right", q, pelvis).position
        # The leg straight along the line from the hip to the target: the foot at the leg's length on it
        # (the closed form clamps the distance to (1 - 1e-12) of it: 1e-12 m; bound 1e-9 m).
        np.testing.assert_allclose(foot, hip + thigh_shank * direction, rtol=0, atol=1e-9)
        lo, hi = person.tree.limits[person._leg_columns("right")].T
        assert np.all(q >= lo + LIMIT_MARGIN - 1e-12) and np.all(q <= hi - LIMIT_MARGIN + 1e-12)
