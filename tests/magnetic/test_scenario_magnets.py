"""Magnets in scenario files: built like the Python API, bad values named with their path."""

import numpy as np
import pytest

from twinsense.magnetic import MagneticSensor
from twinsense.scenario import ScenarioError, scenario_from_dict
from twinsense.scene import Magnet


def scenario(magnet):
    return {"duration": 0.01,
            "objects": [{"name": "tool", "geometry": {"type": "box", "size": [0.02, 0.02, 0.02]},
                         "motion": {"type": "constant_velocity", "velocity": [0.1, 0, 0]}, "magnet": magnet}],
            "sensors": [{"name": "hall", "kind": "magnetic", "preset": "a1324",
                         "mount": {"pose": {"position": [0, 0, -0.01]}}}]}


def test_magnet_block_builds_the_same_magnet():
    sc = scenario_from_dict(scenario({"shape": "ring", "size": [0.01, 0.004, 0.003], "remanence": 1.1,
                                      "direction": [0, 0, 2], "pose": {"position": [0, 0, 0.005]}}))
    m = sc.scene.object("tool").magnet
    assert m.shape == "ring" and m.size == (0.01, 0.004, 0.003) and m.remanence == 1.1
    assert m.direction == (0.0, 0.0, 1.0)  # normalised
    np.testing.assert_array_equal(m.pose.position, [0, 0, 0.005])
    assert isinstance(sc.sensors[0], MagneticSensor)
    # The scene's dictionary (stored with recordings) carries the magnet.
    assert sc.scene.to_dict()["objects"][0]["magnet"] == Magnet("ring", (0.01, 0.004, 0.003), 1.1, (0, 0, 1),
                                                                m.pose).to_dict()


@pytest.mark.parametrize("magnet, path, words", [
    ({"shape": "cylinder", "size": [0.01], "remanence": 1.0}, "objects[0].magnet.size", "2 finite numbers"),
    ({"shape": "cylinder", "size": [0.01, 0.005], "remanence": 2.5}, "objects[0].magnet.remanence", "<= 2"),
    ({"shape": "ring", "size": [0.01, 0.012, 0.003], "remanence": 1.0}, "objects[0].magnet.size[1]",
     "inner diameter"),
    ({"shape": "block", "size": [0.01, 0.01, 0.01], "remanence": 1.0, "direction": [0, 0, 0]},
     "objects[0].magnet.direction", "non-zero"),
    ({"shape": "sphere", "size": [0.01], "remanence": 1.0}, "objects[0].magnet.shape", "cylinder"),
    ({"shape": "cylinder", "size": [0.01, 0.005], "remanence": 1.0, "strength": 3}, "objects[0].magnet.strength",
     ""),
])
def test_bad_magnet_blocks_name_the_field(magnet, path, words):
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict(scenario(magnet))
    text = str(err.value)
    assert path in text and words in text
