"""Robot scenarios end to end: a two-robot cell through the command line and its outputs read by
independent readers, a link's Doppler against the analytic twist, and bad robot entries.

Every bad entry is a ScenarioError naming the YAML path, the value and what is allowed; through the
command line it exits with 2, prints no traceback and writes nothing.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from twinsense.cli import app
from twinsense.errors import ConfigError
from twinsense.robots import load_robot, robot_path
from twinsense.scenario import ScenarioError, scenario_from_dict

PANDA_XML = robot_path("panda-mjcf")
UR5 = {"name": "ur5", "description": "ur5", "shapes": "collision"}
HOME6 = [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]


def _data(robots, sensors=(), objects=(), people=(), duration=0.1, recording=None):
    return {"name": "review", "duration": duration, "seed": 2, "objects": list(objects), "robots": list(robots),
            "people": list(people), "sensors": list(sensors), "outputs": {"recording": recording}}


def _problems(data, base_dir: Path) -> list[tuple[str, object, str]]:
    with pytest.raises(ScenarioError) as exc:
        scenario_from_dict(data, base_dir=base_dir)
    return exc.value.problems


# --- bad robot entries: each names its YAML path --------------------------------------------------

def _ur5(**entry):
    return {**UR5, **entry}


TABLE = {"name": "table", "geometry": {"type": "box", "size": [0.6, 1.0, 0.75]}}
CAM = {"name": "cam", "kind": "camera", "preset": "generic"}

# (id, scenario data, the problem's field, a text its value or what is allowed must hold)
BAD = [
    ("unknown robot", _data([{"name": "r", "description": "ur55"}]), "robots[0].description", "ur5"),
    ("missing urdf", _data([{"name": "r", "description": "gone.urdf"}]), "robots[0].description", "gone.urdf"),
    ("missing mjcf", _data([{"name": "r", "description": "sub/gone.xml"}]), "robots[0].description", "gone.xml"),
    ("unknown joint in keyframes",
     _data([_ur5(joints={"keyframes": {"times": [0, 1], "values": [[0.0], [0.1]]}, "joint_names": ["elbow"]})]),
     "robots[0].joints.joint_names", "elbow_joint"),
    ("value outside limits",
     _data([_ur5(joints={"keyframes": {"times": [0, 1], "values": [HOME6, [0, 0, 4.0, 0, 0, 0]]}})]),
     "robots[0].joints.keyframes.values[1][2]", "elbow_joint"),
    ("times not increasing", _data([_ur5(joints={"keyframes": {"times": [0, 1, 1], "values": [HOME6] * 3}})]),
     "robots[0].joints.keyframes.times", "increasing"),
    ("NaN keyframe", _data([_ur5(joints={"keyframes": {"times": [0, 1], "values": [HOME6, [math.nan] * 6]}})]),
     "robots[0].joints.keyframes.values", "finite"),
    ("NaN velocity", _data([_ur5(joints={"constant_velocity": {"q0": HOME6, "qd": [math.nan, 0, 0, 0, 0, 0]}})]),
     "robots[0].joints.constant_velocity", "finite"),
    ("short row", _data([_ur5(joints={"keyframes": {"times": [0, 1], "values": [HOME6, HOME6[:5]]}})]),
     "robots[0].joints.keyframes.values", "(n_times, n_joints)"),
    ("five columns", _data([_ur5(joints={"keyframes": {"times": [0, 1], "values": [HOME6[:5], HOME6[:5]]}})]),
     "robots[0].joints", "shoulder_pan_joint"),
    ("mount on unknown link", _data([UR5], [{**CAM, "mount": {"parent": "ur5/flange"}}]),
     "sensors[0].mount.parent", "ur5/tool0"),
    ("base position of 2", _data([_ur5(base={"position": [0, 0]})]), "robots[0].base.position[2]", "required"),
    ("base not a mapping", _data([_ur5(base=[0, 0, 0.8])]), "robots[0].base", "dictionary"),
    ("base zero quaternion", _data([_ur5(base={"quat_xyzw": [0, 0, 0, 0]})]), "robots[0].base.quat_xyzw",
     "non-zero"),
    ("base 3 x 3 matrix", _data([_ur5(base={"matrix": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]})]),
     "robots[0].base.matrix", "(4, 4)"),
    ("duplicate robot names", _data([UR5, UR5]), "robots", "repeated: ur5"),
    ("person named like a robot", _data([UR5], people=[{"name": "ur5"}]), "people[0].name", "robot"),
    # Fixed joints are their own entry: errors name it, not the constant velocity it is built as.
    ("fixed outside limits", _data([{"name": "p", "description": "panda-mjcf",
                                     "joints": {"fixed": [0, 0, 0, 0.5, 0, 0, 0]}}]),
     "robots[0].joints.fixed[3]", "joint4"),
    ("fixed NaN", _data([_ur5(joints={"fixed": [0.0, math.nan, 0, 0, 0, 0]})]), "robots[0].joints.fixed[1]", "finite"),
    ("fixed true", _data([_ur5(joints={"fixed": [True] * 6})]), "robots[0].joints.fixed[0]", "finite"),
    ("fixed unknown joint", _data([_ur5(joints={"fixed": {"elbowjoint": 0.1}})]), "robots[0].joints.fixed.elbowjoint",
     "elbow_joint"),
    ("fixed mapping outside limits", _data([{"name": "p", "description": "panda-mjcf",
                                             "joints": {"fixed": {"joint2": 0.1, "joint4": 0.5}}}]),
     "robots[0].joints.fixed.joint4", "joint4"),
    ("fixed mapping text", _data([_ur5(joints={"fixed": {"elbow_joint": "up"}})]),
     "robots[0].joints.fixed.elbow_joint", "finite"),
    # Materials: the link whose entry is wrong.
    ("material of an unknown link", _data([_ur5(materials={"gripper": "wood"})]), "robots[0].materials.gripper",
     "forearm_link"),
    ("unknown material", _data([_ur5(materials={"base_link": "unobtainium"})]), "robots[0].materials.base_link",
     "mild_steel"),
    # Names: a robot's links are "robot/link"; a robot named like an object would make both "table" and
    # "table/base_link" frames of unrelated things.
    ("robot named like an object", _data([{**UR5, "name": "table"}], objects=[TABLE]), "robots[0].name", "table"),
    # A constant velocity that leaves a joint's limits during the run is refused when the scenario is built,
    # not in the middle of the run (which would leave a partial recording).
    ("constant velocity leaves limits",
     _data([_ur5(joints={"constant_velocity": {"q0": [0, 0, 3.1, 0, 0, 0], "qd": [0, 0, 1.0, 0, 0, 0]}})],
           duration=0.2),
     "robots[0].joints.constant_velocity.qd[2]", "t = 0.04159"),
]


@pytest.mark.parametrize(("data", "field", "text"), [c[1:] for c in BAD], ids=[c[0] for c in BAD])
def test_bad_robot_entries_name_their_yaml_path(tmp_path, data, field, text):
    problems = _problems(data, tmp_path)
    hits = [p for p in problems if p[0] == field]
    assert hits, problems
    assert any(text in f"{v!r} {allowed}" for _, v, allowed in hits), hits


MISSING_MESH_URDF = """<robot name="arm">
  <link name="base"><visual><geometry><box size="0.2 0.2 0.2"/></geometry></visual></link>
  <link name="upper"><visual><geometry><mesh filename="meshes/upper.stl"/></geometry></visual></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"""


def _panda_without_a_mesh(folder: Path) -> Path:
    """robosuite's Panda MJCF copied with its meshes, link3.stl left out."""
    (folder / "meshes").mkdir(parents=True)
    for f in (PANDA_XML.parent / "meshes").iterdir():
        if f.name != "link3.stl":
            (folder / "meshes" / f.name).write_bytes(f.read_bytes())
    (folder / "robot.xml").write_text(PANDA_XML.read_text())
    return folder / "robot.xml"


def test_missing_meshes_name_the_description_and_the_file(tmp_path):
    (tmp_path / "arm.urdf").write_text(MISSING_MESH_URDF)
    problems = _problems(_data([{"name": "arm", "description": "arm.urdf"}]), tmp_path)
    assert len(problems) == 1 and problems[0][0].startswith("robots[0].")
    assert "upper.stl" in str(problems[0][1]) and "'upper'" in problems[0][2]
    _panda_without_a_mesh(tmp_path / "panda")
    problems = _problems(_data([{"name": "p", "description": "panda/robot.xml"}]), tmp_path)
    assert [p[0] for p in problems] == ["robots[0].description"]
    assert "robot.xml" in str(problems[0][1]) and "link3.stl" in problems[0][2]


def test_broken_description_files_name_the_description(tmp_path):
    (tmp_path / "broken.urdf").write_text('<robot name="x"><link name="a"></robot>')
    (tmp_path / "broken.xml").write_text("<mujoco><worldbody><body name='a'></worldbody></mujoco>")
    for f in ("broken.urdf", "broken.xml"):
        problems = _problems(_data([{"name": "r", "description": f}]), tmp_path)
        assert [p[0] for p in problems] == ["robots[0].description"], problems
        assert f in str(problems[0][1])


def test_sensor_frames_must_not_take_an_object_name(tmp_path):
    # A non-camera sensor's ROS frame is its name, a camera's <name>_link and <name>_optical_frame: an
    # object of that name would give one tf frame two parents.
    sonar = {"name": "table", "kind": "ultrasonic", "preset": "open_40khz", "mount": {"pose": {"position": [0, 0, 2]}}}
    problems = _problems(_data([], [sonar], objects=[TABLE]), tmp_path)
    assert [p[0] for p in problems] == ["sensors[0].name"] and "table" in problems[0][2]
    cam = {**CAM, "name": "table"}
    obj = {**TABLE, "name": "table_optical_frame"}
    problems = _problems(_data([], [cam], objects=[obj]), tmp_path)
    assert [p[0] for p in problems] == ["sensors[0].name"]


def test_load_robot_takes_shapes_for_either_format_and_names_an_unknown_keyword():
    # shapes= (the scenario's word) works for MJCF too, as geoms=.
    def faces(body):
        return [len(lk.geometry.mesh.faces) for lk in body.tree.links if lk.geometry is not None]

    collision = faces(load_robot("panda-mjcf", shapes="collision"))
    assert collision == faces(load_robot("panda-mjcf", geoms="collision"))
    assert sum(collision) < sum(faces(load_robot("panda-mjcf")))  # not the visual meshes
    with pytest.raises(ConfigError, match="bogus") as exc:
        load_robot("ur5", bogus=1)
    assert "materials" in exc.value.allowed
    with pytest.raises(ConfigError, match="geoms"):
        load_robot("ur5", geoms="all")  # a URDF has no geoms


def _write(tmp_path: Path, data: dict) -> Path:
    p = tmp_path / "cell.yaml"
    p.write_text(yaml.safe_dump(data))
    return p


@pytest.mark.parametrize("case", ["unknown robot", "fixed outside limits", "robot named like an object",
                                  "constant velocity leaves limits", "mount on unknown link"])
def test_command_line_reports_bad_robot_entries_and_writes_nothing(tmp_path, case):
    data, field, _ = next(c[1:] for c in BAD if c[0] == case)
    data = {**data, "outputs": {"recording": "rec.h5"}}
    res = CliRunner().invoke(app, ["run", str(_write(tmp_path, data)), "-o", str(tmp_path / "out"), "--no-progress"])
    assert res.exit_code == 2, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit)
    assert "Traceback" not in res.output and f"{field} = " in res.output
    assert not (tmp_path / "out").exists()


def test_command_line_in_a_subprocess_reports_a_missing_mesh(tmp_path):
    # As a user runs it: python -m twinsense, exit status 2, the error on stderr, nothing written.
    _panda_without_a_mesh(tmp_path / "panda")
    p = _write(tmp_path, _data([{"name": "p", "description": "panda/robot.xml"}], recording="rec.h5"))
    r = subprocess.run([sys.executable, "-m", "twinsense", "run", str(p), "-o", str(tmp_path / "out")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2
    assert "robots[0].description" in r.stderr and "link3.stl" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "out").exists()
