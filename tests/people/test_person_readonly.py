"""A person's motion is read-only: a change after a first capture cannot leave a cache stale.

Every cache that serves a person keys on the motion's identity and the time:
the motion's own state at the last time asked (links ask in turn), the
arm's inverse kinematics solved once per reach, the body's forward
kinematics (keyed on the time and the joint motion's version, always 0 for a
person), a capacitive sensor's prepare (the motion's identity). Before the
attributes were read-only, ``person.sway = 0.05`` after a capture left the
pelvis where it was at that capture's time (0 m instead of the fresh
person's 0.0499 m to the side) and moved it at any other time; a changed
``walk`` or ``height`` also left the path, gait and leg derived from the old
one. Now an assignment is refused with the attribute's name, and a new
person is the way to a new motion.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import pickle

import numpy as np
import pytest

from twinsense.scene import Scene
from twinsense.scene.human import SWAY_FREQUENCY, PersonJoints, PersonMotion, Reach, Walk, add_person

T = 1.3  # [s]


def _person(**kw):
    scene = Scene()
    body = add_person(scene, "p", **kw)
    return scene, body, body.joint_motion.person


def _poses(scene, t: float) -> np.ndarray:
    """(links, 3, 4) every link's pose at ``t`` [m]."""
    return np.array([np.column_stack([o.pose_at(t).rotation, o.pose_at(t).position]) for o in scene.objects])


@pytest.mark.parametrize("name, value", [
    ("sway", 0.05), ("reach", Reach((0.4, -0.2, 1.2), 0.5)), ("walk", Walk(1.0, heading_deg=0.0)),
    ("turn", None), ("height", 1.6), ("heading", 1.0), ("floor", 0.1), ("start_xy", np.ones(2)),
    ("stop_time", 2.0), ("tree", None), ("cycle", None), ("path", None), ("leg", None),
])
def test_assigning_an_attribute_after_a_capture_is_refused_and_the_captures_stay_a_fresh_persons(name, value):
    scene, _, person = _person(sway=0.0)
    before = _poses(scene, T)
    with pytest.raises(dataclasses.FrozenInstanceError, match=rf"PersonMotion\.{name}\b.*read-only"):
        setattr(person, name, value)
    with pytest.raises(dataclasses.FrozenInstanceError, match=rf"PersonMotion\.{name}\b"):
        delattr(person, name)
    # The same time again (the caches' hit) and a fresh person's: the same bits.
    fresh, _, _ = _person(sway=0.0)
    assert np.array_equal(_poses(scene, T), before) and np.array_equal(_poses(fresh, T), before)


def test_a_new_person_is_the_way_to_a_new_motion():
    # Sway: the pelvis moves sideways by sway * sin(2 pi f t) along the normal of the heading (0 deg:
    # +y); exact in the model (the heading does not change), compared to 1e-12 m of rounding.
    scene, _, _ = _person(sway=0.0)
    swaying, _, _ = _person(sway=0.05)
    y = 0.05 * math.sin(2 * math.pi * SWAY_FREQUENCY * T)
    assert swaying.objects[0].name == "p/pelvis"
    assert swaying.objects[0].pose_at(T).position[1] == pytest.approx(y, rel=0, abs=1e-12)
    assert scene.objects[0].pose_at(T).position[1] == pytest.approx(0.0, rel=0, abs=1e-12)


def test_the_start_point_cannot_be_changed_in_place():
    _, _, person = _person(position=(1.0, 2.0))
    with pytest.raises(ValueError, match="read-only"):
        person.start_xy[0] = 5.0
    assert person.start_xy.tolist() == [1.0, 2.0]


def test_the_joint_motion_keeps_its_person():
    _, body, person = _person()
    with pytest.raises(dataclasses.FrozenInstanceError, match=r"PersonJoints\.person\b"):
        body.joint_motion.person = PersonMotion(person.tree, person.height)
    assert isinstance(body.joint_motion, PersonJoints) and body.joint_motion.person is person


def test_the_caches_still_serve_and_copies_are_as_read_only():
    scene, _, person = _person(sway=0.02, reach=Reach((0.45, -0.2, 1.1), 0.5, 0.5, math.inf))
    first = _poses(scene, T)
    cached = person._last
    _poses(scene, T)
    assert person._last is cached  # the last time's state, reused
    assert person._reach_q is not None  # solved once for the reach
    for other in (pickle.loads(pickle.dumps(person)), copy.deepcopy(person)):
        # The same motion to the bit (the same arithmetic on the same values).
        assert np.array_equal(other.q(T), person.q(T)) and np.array_equal(other.qd(T), person.qd(T))
        with pytest.raises(dataclasses.FrozenInstanceError):
            other.sway = 0.0
        with pytest.raises(ValueError, match="read-only"):
            other.start_xy[0] = 1.0
    assert np.array_equal(_poses(scene, T), first)
