"""Bad people inputs through the public API: errors name the field, the value as given and what is allowed."""

import math

import pytest

from twinsense.errors import ConfigError
from twinsense.scene import Scene
from twinsense.scene.human import Walker, add_person


@pytest.mark.parametrize("path", [[], [(math.nan, 1.0)], [(1.0, 2.0, 3.0, 4.0)]])
def test_walker_names_a_bad_path_as_given(path):
    # Walker converts the path to a tuple for Walk; the error shows the caller's value, not that
    # tuple (it showed [] as ((),) and NaN as np.float64(nan)).
    with pytest.raises(ConfigError) as e:
        Walker("w", path=path)
    assert e.value.field == "walk.path"
    assert e.value.value is path
    assert "np.float64" not in str(e.value) and "((),)" not in str(e.value)


def test_walker_path_still_walks_to_its_last_waypoint():
    import numpy as np

    body = Walker("w", 1.75, 1.2, (0.0, 0.0), None, [(2.0, 0.0), (2.0, 1.5)])
    person = body.joint_motion.person
    end = body.state(person.stop_time + 1.0).state("pelvis").pose.position
    np.testing.assert_allclose(end[:2], (2.0, 1.5), rtol=0, atol=1e-6)  # the path's end (root finding 1e-13 s)


def test_a_second_person_with_a_taken_name_is_refused_by_name():
    scene = Scene()
    add_person(scene, "alice", 1.6, (0.0, 0.0))
    with pytest.raises(ConfigError, match=r"person\.name = 'alice'.*a person name whose link names are free"):
        add_person(scene, "alice", 1.8, (2.0, 0.0))
    add_person(scene, "bob", 1.8, (2.0, 0.0))  # another name is fine
