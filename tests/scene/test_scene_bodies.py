"""Scene.frames and Scene.articulated_bodies: what the writers of /tf and joint states walk."""

from __future__ import annotations

from twinsense.scene import Box, Pose, Scene
from twinsense.scene.articulated import ArticulatedBody, Joint, KinematicTree, Link
from twinsense.scene.human import add_person
from twinsense.scene.scene import Frame


def _arm(name: str) -> ArticulatedBody:
    tree = KinematicTree("arm", [Link("base", Box((0.2, 0.2, 0.2))), Link("flange", None)],
                         [Joint("j", "revolute", "base", "flange", origin=Pose(position=(0.0, 0.0, 1.0)))])
    return ArticulatedBody(name, tree)


def test_bodies_in_order_of_their_first_link_however_added():
    scene = Scene()
    scene.add_object("table", Box((1.0, 1.0, 0.1)))
    scene.add_frame(Frame("marker", Pose(position=(1.0, 0.0, 0.0))))
    a, b = _arm("a"), _arm("b")
    scene.add_articulated(a)
    b.add_to(scene)  # added by the body itself: found the same way
    assert scene.articulated_bodies == (a, b)
    # Frames in the order added: the plain one, then each body's frame-only link.
    assert scene.frames == (scene.mount_target("marker"), scene.mount_target("a/flange"),
                            scene.mount_target("b/flange"))
    assert [f.name for f in scene.frames] == list(scene.frame_names)


def test_a_person_is_a_body_and_a_plain_scene_has_none():
    assert Scene().articulated_bodies == () and Scene().frames == ()
    scene = Scene()
    scene.add_object("box", Box((1.0, 1.0, 1.0)))
    assert scene.articulated_bodies == ()
    person = add_person(scene, "p")
    assert scene.articulated_bodies == (person,) and len(person.tree.joint_names) > 0


def test_object_and_frame_names_are_valid_tf_frame_ids():
    # An object's or frame's name is its /tf frame id in MCAP files and the Foxglove stream; tf2 refuses
    # ids that start with '/', and '/' separates a body from its links, so empty segments are refused.
    import pytest

    from twinsense.errors import ConfigError
    from twinsense.scene import SceneObject

    for bad in ("/floor", "floor/", "ur5//tool0", "", 3):
        with pytest.raises(ConfigError, match="object.name.*tf frame id"):
            SceneObject(bad, Box((1.0, 1.0, 1.0)))
        with pytest.raises(ConfigError, match="frame.name.*tf frame id"):
            Frame(bad)
    for good in ("floor", "ur5/tool0", "person/left_hand", "ball body"):
        assert SceneObject(good, Box((1.0, 1.0, 1.0))).name == good
        assert Frame(good).name == good
