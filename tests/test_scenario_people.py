"""People in scenario files: the YAML entry builds the same person as the Python API."""

import numpy as np
import pytest

from twinsense.scenario import ScenarioError, scenario_from_dict
from twinsense.scene import Scene
from twinsense.scene.human import Reach, Walk, add_person

PERSON = {"name": "alice", "height": 1.7, "position": [0.0, -2.0],
          "walk": {"speed": 1.3, "path": [[0.0, 2.0], [3.0, 2.0]], "start_time": 0.5},
          "reach": {"target": [3.4, 2.2, 1.1], "start_time": 6.0, "side": "left"}}


def test_people_entry_builds_the_python_api_person():
    sc = scenario_from_dict({"duration": 1.0, "people": [PERSON]})
    ref = Scene()
    add_person(ref, "alice", 1.7, (0.0, -2.0), walk=Walk(1.3, ((0.0, 2.0), (3.0, 2.0)), start_time=0.5),
               reach=Reach((3.4, 2.2, 1.1), start_time=6.0, side="left"))
    assert [o.name for o in sc.scene.objects] == [o.name for o in ref.objects]
    for t in (0.0, 1.3, 4.2, 7.0):
        for name in ("alice/head", "alice/left_foot", "alice/right_hand"):
            a, b = sc.scene.object(name).state_at(t), ref.object(name).state_at(t)
            np.testing.assert_array_equal(a.pose.position, b.pose.position)
            np.testing.assert_array_equal(a.linear_velocity, b.linear_velocity)


@pytest.mark.parametrize(("entry", "field"), [
    ({"height": -1.0}, "people[0].height"),
    ({"walk": {"speed": 1.0}}, "people[0].walk.path"),
    ({"walk": {"speed": 1.0, "heading_deg": 0.0, "body": "float"}}, "people[0].walk.body"),
    ({"reach": {"target": [1, 2]}}, "people[0].reach.target"),
    ({"clothing": "velvet"}, "people[0].clothing"),
    ({"position": [1.0]}, "people[0].position"),
    ({"walk": {"speed": 2.9, "heading_deg": 0.0}}, "people[0].walk.speed"),
    ({"name": "a/b"}, "people[0].name"),
])
def test_bad_people_entries_name_the_field(entry, field):
    with pytest.raises(ScenarioError, match=field.replace(".", r"\.").replace("[", r"\[").replace("]", r"\]")):
        scenario_from_dict({"people": [{**PERSON, "walk": None, "reach": None, **entry}]})


def test_people_example_loads():
    from pathlib import Path

    from twinsense.scenario import load_scenario

    sc = load_scenario(Path(__file__).resolve().parents[1] / "examples" / "people_radar.yaml")
    names = {o.name for o in sc.scene.objects}
    assert {"alice/head", "bob/right_hand", "bob/thorax_clothing"} <= names
    # Bob's hand reaches the shelf point and stays (hold: .inf); to rounding (1e-9 m).
    st = sc.scene.object("bob/right_hand").state_at(1.5)
    hand = st.pose.apply([0.0, 0.0, -0.5 * 0.108 * 1.85])
    np.testing.assert_allclose(hand, (3.3, -1.1, 1.5), rtol=0, atol=1e-9)


@pytest.mark.parametrize(("entry", "field"), [
    ({"height": float("nan")}, "people[0].height"),
    ({"sway": float("nan")}, "people[0].sway"),
    ({"walk": {"speed": float("nan"), "heading_deg": 0.0}}, "people[0].walk.speed"),
    ({"reach": {"target": [1, 1, 1], "duration": float("inf")}}, "people[0].reach.duration"),
])
def test_nan_and_inf_are_refused_as_not_finite(entry, field):
    # Not "Input should be greater than 0": the number is refused for what it is.
    with pytest.raises(ScenarioError, match=field.replace(".", r"\.").replace("[", r"\[").replace("]", r"\]")
                       + r" = (nan|inf): a finite number"):
        scenario_from_dict({"people": [{**PERSON, "walk": None, "reach": None, **entry}]})
