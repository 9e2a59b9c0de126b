"""A named robot and the same description given by the path of its file are one robot."""

import os

import numpy as np

from twinsense.robots import load_robot
from twinsense.robots.descriptions import ROBOTS


def test_the_named_human_by_its_file_path_is_the_named_one():
    by_name = load_robot("human")
    path = ROBOTS["human"].path()
    for given in (str(path), os.path.relpath(path)):
        by_path = load_robot(given, name="human")
        a, b = (dict((o.name, o.material.name) for o in x.scene_items()[0]) for x in (by_name, by_path))
        assert a == b and set(a.values()) == {"human_skin"}
        np.testing.assert_array_equal(by_name.state(0.0).positions, by_path.state(0.0).positions)
    # The caller's materials still go over the description's.
    mixed = load_robot(str(path), name="human", materials={"middle_head": "plastic"})
    assert {o.name: o.material.name for o in mixed.scene_items()[0]}["human/middle_head"] == "plastic"


def test_a_scenario_robot_by_name_and_by_path_moves_its_mounted_sensor_alike():
    from twinsense.scenario import scenario_from_dict

    def scenario(description):
        return scenario_from_dict({
            "name": "s", "duration": 1.0, "seed": 1,
            "robots": [{"name": "arm", "description": description,
                        "base": {"position": [0, 0, 0.5], "rpy_deg": [0, 0, 30]},
                        "joints": {"keyframes": {"times": [0, 1], "values": [[0, -1.2, 1.0, -1.0, -1.5, 0.3],
                                                                             [0.4, -1.0, 1.2, -1.3, -1.5, 0.0]]}}}],
            "sensors": [{"name": "d", "kind": "camera", "preset": "vga",
                         "mount": {"parent": "arm/tool0", "pose": {"position": [0, 0, 0.02]}}}],
            "outputs": {}})

    a, b = scenario("ur10"), scenario(str(ROBOTS["ur10"].path()))
    assert [(o.name, o.material.name) for o in a.scene.objects] == [(o.name, o.material.name) for o in b.scene.objects]
    for t in (0.0, 0.37, 1.0):
        sa, sb = (s.sensors[0].mount.state_at(s.scene, t) for s in (a, b))
        assert sa.pose.position.tobytes() == sb.pose.position.tobytes()
        assert sa.linear_velocity.tobytes() == sb.linear_velocity.tobytes()
