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

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from body_distance import person_to_mesh
from tf_matrix import tf_matrix
from twinsense.cli import app
from twinsense.errors import ConfigError
from twinsense.io.recording import open_recording
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
    ("joint_names inside keyframes",
     _data([_ur5(joints={"keyframes": {"times": [0, 1], "values": [[0.0], [0.1]], "joint_names": ["elbow_joint"]}})]),
     "robots[0].joints.keyframes.joint_names", "beside"),
    ("times not increasing", _data([_ur5(joints={"keyframes": {"times": [0, 1, 1], "values": [HOME6] * 3}})]),
     "robots[0].joints.keyframes.times", "increasing"),
    ("NaN keyframe", _data([_ur5(joints={"keyframes": {"times": [0, 1], "values": [HOME6, [math.nan] * 6]}})]),
     "robots[0].joints.keyframes.values[1][0]", "finite"),  # the first NaN, named as in the file
    ("NaN velocity", _data([_ur5(joints={"constant_velocity": {"q0": HOME6, "qd": [math.nan, 0, 0, 0, 0, 0]}})]),
     "robots[0].joints.constant_velocity.qd[0]", "finite"),
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
    ("fixed outside limits", _data([_ur5(joints={"fixed": [0, 0, 4.0, 0, 0, 0]})]), "robots[0].joints.fixed[2]",
     "elbow_joint"),
    ("fixed NaN", _data([_ur5(joints={"fixed": [0.0, math.nan, 0, 0, 0, 0]})]), "robots[0].joints.fixed[1]", "finite"),
    ("fixed true", _data([_ur5(joints={"fixed": [True] * 6})]), "robots[0].joints.fixed[0]", "finite"),
    ("fixed unknown joint", _data([_ur5(joints={"fixed": {"elbowjoint": 0.1}})]), "robots[0].joints.fixed.elbowjoint",
     "elbow_joint"),
    ("fixed mapping outside limits", _data([_ur5(joints={"fixed": {"wrist_1_joint": 0.1, "elbow_joint": -4.0}})]),
     "robots[0].joints.fixed.elbow_joint", "3.14159"),
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
    ("person named like an object", _data([], objects=[TABLE], people=[{"name": "table"}]), "people[0].name",
     "object"),
    # Names that differ only where ROS 2 topic names have no room: both would publish /my_arm/joint_states.
    ("robot names one topic", _data([{**UR5, "name": "my-arm"}, {**UR5, "name": "my_arm"}]), "robots[1].name",
     "my-arm"),
    ("person and robot one topic", _data([{**UR5, "name": "my-arm"}], people=[{"name": "my_arm"}]),
     "people[0].name", "my-arm"),
    ("sensor names one topic", _data([UR5], [{**CAM, "name": "cam-1"}, {**CAM, "name": "cam_1"}]),
     "sensors[1].name", "cam-1"),
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
        assert f in str(problems[0][1]) and "\n" not in problems[0][2]  # MuJoCo's parser message spans lines


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

    # The Panda's collision geoms have 14,316 triangles, its display meshes 126,598: equal counts per link
    # mean shapes= chose the collision geoms.
    collision = faces(load_robot("panda-mjcf", shapes="collision"))
    assert collision == faces(load_robot("panda-mjcf", geoms="collision")) and sum(collision) == 14316
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


def test_command_line_reports_a_missing_mjcf_mesh_on_one_line_per_problem(tmp_path):
    # Exit status 2; the file, then the problem on one line (MuJoCo's compiler message is multi-line).
    _panda_without_a_mesh(tmp_path / "panda")
    p = _write(tmp_path, _data([{"name": "p", "description": "panda/robot.xml"}], recording="rec.h5"))
    res = CliRunner().invoke(app, ["run", str(p), "-o", str(tmp_path / "out"), "--no-progress"])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert lines[0].startswith("error: ") and lines[0].endswith("1 problem") and len(lines) == 2
    assert "robots[0].description" in lines[1] and "link3.stl" in lines[1]
    assert not (tmp_path / "out").exists()


# --- a two-robot cell through the command line: HDF5 and MCAP against independent kinematics ---------

KEYFRAMES = {"times": [0.0, 0.5, 1.0], "values": [HOME6, [0.3, -1.30, 1.45, -1.72, -1.57, 0.2], HOME6]}
PANDA_Q0 = [0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.7]
PANDA_QD = [0.5, 0.2, 0.0, 0.0, 0.0, 0.0, 0.0]
UR5_BASE = {"position": [0.0, 0.0, 0.8], "rpy_deg": [0, 0, 30]}
PANDA_BASE = {"position": [1.5, 0.5, 0.0], "rpy_deg": [0, 0, 180]}
PANDA2_BASE = {"position": [1.5, -0.8, 0.0], "rpy_deg": [0, 0, 0]}


def _cell() -> dict:
    """UR5 (URDF, named), a Panda MJCF by name and one by file path, a walking person; five kinds of sensor
    on robot links. 0.1 s: two frames of the 20 Hz sensors, one of the 10 Hz LiDAR and ultrasonic sensor."""
    mount = {"wrist_tof": ("ur5/tool0", {"position": [0, 0, 0.02]}),
             "link_radar": ("panda/link2", {"position": [0, 0.1, 0]}),
             "lidar": ("panda2/link0", {"position": [0, 0, 1.2], "rpy_deg": [0, 90, 0]}),
             "sonar": ("ur5/tool0", {"position": [0, 0, 0]}),
             "skin": ("ur5/forearm_link", {"position": [0.0, -0.062, 0.2], "rpy_deg": [90, -90, 0]})}
    kinds = {"wrist_tof": ("tof", "generic", {}), "link_radar": ("radar", "paper_bgt60tr13c", {
        "num_samples": 64, "num_chirps": 16, "render_width": 32, "render_height": 16}),
             "lidar": ("lidar", "livox_mid40", {}), "sonar": ("ultrasonic", "parking_40khz", {}),
             "skin": ("capacitive", "pad-grid", {})}
    sensors = []
    for name, (kind, preset, over) in kinds.items():
        s = {"name": name, "kind": kind, "preset": preset, "overrides": over,
             "mount": {"parent": mount[name][0], "pose": mount[name][1]}}
        s["frame_rate"] = 20 if kind in ("tof", "radar", "capacitive") else 10
        sensors.append(s)
    return _data(
        [{**UR5, "base": UR5_BASE, "joints": {"keyframes": KEYFRAMES}},
         {"name": "panda", "description": "panda-mjcf", "shapes": "collision", "base": PANDA_BASE,
          "joints": {"constant_velocity": {"q0": PANDA_Q0, "qd": PANDA_QD}}},
         {"name": "panda2", "description": str(PANDA_XML), "shapes": "collision", "base": PANDA2_BASE,
          "joints": {"fixed": {"joint2": 0.3, "joint4": -1.5}}}],
        sensors, objects=[{"name": "floor", "geometry": {"type": "plane", "size": [6, 6]}, "material": "concrete"},
                          {**TABLE, "material": "wood", "pose": {"position": [0.6, 0, 0.375]}}],
        people=[{"name": "person", "position": [2.5, -2.0], "walk": {"speed": 1.2, "path": [[1.0, -1.0]]}}],
        recording="rec.h5")


def _matrix(pose: dict) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    m = np.eye(4)
    m[:3, :3] = Rotation.from_euler("xyz", pose.get("rpy_deg", [0, 0, 0]), degrees=True).as_matrix()
    m[:3, 3] = pose["position"]
    return m


@pytest.fixture(scope="module")
def cell_run(tmp_path_factory):
    """The cell run as a user runs it: python -m twinsense run cell.yaml -o out --format mcap."""
    d = tmp_path_factory.mktemp("cell")
    r = subprocess.run([sys.executable, "-m", "twinsense", "run", str(_write(d, _cell())), "-o", str(d / "out"),
                        "--format", "mcap", "--no-progress"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return d / "out", r.stdout


def _read_mcap(path: Path):
    """(static {child: (parent, 4x4)}, moving {stamp: {child: (parent, 4x4)}}, [(topic, frame_id, stamp)],
    {body: {stamp: (names, positions)}}) read with mcap + mcap_ros2; /tf also decoded by rosbags' own CDR
    reader and compared."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    static, moving, headers, joints = {}, {}, [], {}
    with path.open("rb") as f:
        for _, channel, msg, dec in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            if channel.topic in ("/tf", "/tf_static"):
                other = store.deserialize_cdr(msg.data, "tf2_msgs/msg/TFMessage")
                for tf, tf2 in zip(dec.transforms, other.transforms, strict=True):
                    assert (tf.child_frame_id, tf.header.frame_id) == (tf2.child_frame_id, tf2.header.frame_id)
                    np.testing.assert_array_equal(tf_matrix(tf), tf_matrix(tf2))
                    into = static if channel.topic == "/tf_static" else moving.setdefault(msg.log_time, {})
                    into[tf.child_frame_id] = (tf.header.frame_id, tf_matrix(tf))
                    headers.append((channel.topic, tf.header.frame_id, msg.log_time))
            elif hasattr(dec, "header"):
                headers.append((channel.topic, dec.header.frame_id, msg.log_time))
                if channel.topic.endswith("/joint_states"):
                    joints.setdefault(channel.topic.split("/")[1], {})[msg.log_time] = (list(dec.name),
                                                                                       np.array(dec.position))
    return static, moving, headers, joints


def _world(frame: str, stamp: int, static, moving) -> np.ndarray:
    """The frame's pose in world at ``stamp`` [ns] from the published transforms (KeyError: not chained)."""
    m = np.eye(4)
    for _ in range(64):
        if frame == "world":
            return m
        parent, x = moving.get(stamp, {}).get(frame) or static[frame]
        m, frame = x @ m, parent
    raise AssertionError(f"{frame}: a cycle in /tf")


def test_cell_outputs_open_with_independent_readers_and_follow_the_kinematics(cell_run, mj_model):
    import h5py
    import mujoco
    import yourdfpy
    from scipy.interpolate import CubicSpline

    out, stdout = cell_run
    assert "wrote" in stdout and (out / "rec.h5").is_file() and (out / "rec.mcap").is_file()
    assert sorted(p.name for p in out.iterdir()) == ["rec.h5", "rec.mcap"]  # nothing half-written beside them
    with h5py.File(out / "rec.h5") as f:
        stamps = {n: f[n]["timestamps"][:] for n in ("wrist_tof", "link_radar", "lidar", "sonar", "skin")}
        tof_pose = f["wrist_tof/pose"][:]
    assert {n: len(t) for n, t in stamps.items()} == {"wrist_tof": 2, "link_radar": 2, "lidar": 1, "sonar": 1,
                                                        "skin": 2}
    static, moving, headers, joints = _read_mcap(out / "rec.mcap")
    # Every frame id of every message and every transform's parent chains to world at the message's stamp.
    for topic, frame, stamp in headers:
        assert frame, topic
        _world(frame, stamp, static, moving)
    assert len(moving) == 2 and all(n in joints for n in ("ur5", "panda", "panda2", "person"))

    # Independent kinematics: yourdfpy for the UR5 URDF, MuJoCo for the Panda MJCF, at the joint values
    # each stamp's /joint_states gives; those against the motions in closed form (scipy's clamped spline
    # through the keyframes, q0 + qd t, the fixed values). Sensor frames: base @ link @ mount.
    ur5 = yourdfpy.URDF.load(str(robot_path("ur5")), build_scene_graph=True, load_meshes=False,
                             build_collision_scene_graph=False, load_collision_meshes=False)
    model = mj_model("panda-mjcf")
    data = mujoco.MjData(model)
    spline = CubicSpline(KEYFRAMES["times"], KEYFRAMES["values"], bc_type="clamped")

    def ur5_link(link, stamp):
        names, q = joints["ur5"][stamp]
        # Float64 spline evaluations by two implementations: a few ulp of ~2 rad.
        np.testing.assert_allclose(q, spline(stamp * 1e-9), rtol=0, atol=1e-12)
        ur5.update_cfg(dict(zip(names, q, strict=True)))
        return _matrix(UR5_BASE) @ ur5.get_transform(frame_to=link, frame_from=ur5.base_link)

    def panda_link(body, link, stamp):
        names, q = joints[body][stamp]
        assert names == [model.joint(i).name for i in range(model.njnt)]  # MuJoCo's qpos order
        if body == "panda":  # q0 + qd t: one rounding each
            np.testing.assert_allclose(q, np.array(PANDA_Q0) + np.array(PANDA_QD) * stamp * 1e-9, rtol=0, atol=1e-12)
        else:
            assert (q[1], q[3]) == (0.3, -1.5)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = data.body(link).xmat.reshape(3, 3), data.body(link).xpos
        return _matrix(PANDA_BASE if body == "panda" else PANDA2_BASE) @ m

    cell = _cell()
    mounts = {s["name"]: s["mount"] for s in cell["sensors"]}
    frames = {"wrist_tof": "wrist_tof_optical_frame", "link_radar": "link_radar_optical_frame", "lidar": "lidar",
              "sonar": "sonar", "skin": "skin"}
    worst = 0.0
    for name, times in stamps.items():
        body, link = mounts[name]["parent"].split("/")
        for k, t in enumerate(times):
            stamp = round(t * 1e9)
            assert stamp in joints[body]
            parent = ur5_link(link, stamp) if body == "ur5" else panda_link(body, link, stamp)
            want = parent @ _matrix({"position": [0, 0, 0], **mounts[name]["pose"]})
            got = _world(frames[name], stamp, static, moving)
            worst = max(worst, float(np.abs(got - want).max()))
            if name == "wrist_tof":
                worst = max(worst, float(np.abs(tof_pose[k] - want).max()))
    # Float64 chains of ~10 transforms on both sides, quaternions in the messages: 1e-9 m and 1e-9 in each
    # rotation entry (a few 1e-16 seen).
    assert worst < 1e-9


# --- a link's Doppler against the analytic twist ---------------------------------------------------

SPINNER = """<robot name="spinner">
  <link name="base"/>
  <link name="paddle"><visual><origin xyz="{r} 0 0"/><geometry><sphere radius="{a}"/></geometry></visual></link>
  <joint name="spin" type="revolute"><parent link="base"/><child link="paddle"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="5"/></joint>
</robot>"""


def test_a_link_turning_at_constant_joint_velocity_has_the_doppler_of_its_twist(tmp_path):
    # One revolute joint about world z through (0, 0, 1) turning at OMEGA; its link carries a sphere of
    # radius A whose centre is R from the axis. A radar 1.2 m in front (-y) looks at the sphere's start.
    omega, r, a, axis = 3.0, 0.4, 0.1, np.array([0.0, 0.0, 1.0])
    (tmp_path / "spinner.urdf").write_text(SPINNER.format(r=r, a=a))
    radar = {"name": "radar", "kind": "radar", "preset": "paper_bgt60tr13c", "frame_rate": 10,
             "overrides": {"num_samples": 64, "num_chirps": 64, "chirp_repetition_time": 1e-4,
                           "ramp_end_time": 4e-5, "render_width": 96, "render_height": 48},
             "mount": {"pose": {"look_at": {"eye": [r, -1.2, 1.0], "target": [r, 0.0, 1.0]}}}}
    sc = scenario_from_dict(_data([{"name": "sp", "description": "spinner.urdf", "base": {"position": axis.tolist()},
                                    "materials": {"paddle": "corner_reflector"},
                                    "joints": {"constant_velocity": {"q0": [0.0], "qd": [omega]}}}], [radar],
                                  duration=0.5), base_dir=tmp_path)
    sensor = sc.sensors[0]
    pose = sensor.mount.state_at(sc.scene, 0.0).pose  # the radar stands still
    w = np.array([0.0, 0.0, omega])
    cfg = sensor.config
    for t in (0.0, 0.1, 0.3):
        frame = sensor.capture(sc.scene, t, np.random.default_rng(4))
        # Ground truth: every scatterer on the link moves at omega x (p - axis) (world), seen in the radar
        # frame through R^T; float64 pose products of ~1 m and ~1 m/s: 1e-9.
        s = frame.scatterers
        assert len(s) > 5
        p_world = pose.apply(s.points)
        np.testing.assert_allclose(s.velocities, np.cross(w, p_world - axis) @ pose.rotation, rtol=0, atol=1e-9)
        # The detection: the sphere's front point c - a u moves radially as its centre does
        # (u . (w x u) = 0), u . (w x (c - axis)), c the centre turned by omega t.
        c = axis + r * np.array([math.cos(omega * t), math.sin(omega * t), 0.0])
        u = (c - pose.position) / np.linalg.norm(c - pose.position)
        v_radial = float(u @ np.cross(w, c - axis))  # 1.20, 1.15, 0.84 m/s: 2-3 Doppler bins
        det = frame.detections
        i = int(np.argmax(det.snr_db))
        # Range within one range bin (0.20 m), radial velocity within one Doppler bin (0.41 m/s; the
        # centripetal acceleration changes it by 0.02 m/s over the 6.4 ms of chirps). Seen: 0.05 m/s.
        assert abs(det.range[i] - (np.linalg.norm(c - pose.position) - a)) <= cfg.chirp.range_resolution
        assert abs(det.velocity[i] - v_radial) <= cfg.velocity_resolution, (t, det.velocity[i], v_radial)


# --- the robot-cell demo's separation against trimesh's exact closest points ----------------------

def test_demo_separation_matches_exact_closest_points_on_the_link_meshes():
    # The demo's true human-robot distance (SeparationMonitor: link meshes subdivided to 10 mm edges, as
    # vertices, against the person's exact capsules and boxes) at three times of its cycle: walking in,
    # the hand's closest approach to the forearm (29 mm, docs/robots.md) and walking out. Reference:
    # trimesh's exact point-to-triangle closest points from points on the body segments (2 mm spacing).
    # The monitor is never below the truth and at most 10 / sqrt(3) = 5.8 mm above it; the reference is
    # never below the truth and at most the sampling bound (1 mm on an axis, 1.4 mm on a box face) above.
    import trimesh
    from scipy.spatial import cKDTree

    from twinsense.demos.robot_cell import PERSON, ROBOT, build_arm_cell_scene
    from twinsense.safety import SeparationMonitor

    scene = build_arm_cell_scene()
    monitor = SeparationMonitor(scene, ROBOT, PERSON)
    links = [o for o in scene.objects if o.name.startswith(f"{ROBOT}/")]
    bound = monitor.spacing / math.sqrt(3.0)
    # Only as a filter: the vertices of the meshes subdivided to 10 mm lie within 5.8 mm of every mesh point,
    # so a body point whose mesh distance could reach the monitor's value is within that of one of them.
    fine = [trimesh.remesh.subdivide_to_size(np.asarray(o.geometry.mesh.vertices), np.asarray(o.geometry.mesh.faces),
                                             max_edge=monitor.spacing, max_iter=30)[0] for o in links]
    seen = {}
    for t in (1.5, 3.55, 4.3):
        got = monitor.at(t).distance
        poses = [o.pose_at(t) for o in links]
        robot = trimesh.util.concatenate([trimesh.Trimesh(p.apply(np.asarray(o.geometry.mesh.vertices)),
                                                          np.asarray(o.geometry.mesh.faces), process=False)
                                          for o, p in zip(links, poses, strict=True)])
        near = cKDTree(np.concatenate([p.apply(f) for f, p in zip(fine, poses, strict=True)]))
        ref, err = person_to_mesh(monitor.person, t, robot, near, got + 1.01 * bound)
        assert -err - 1e-9 <= got - ref <= bound + 1e-9, (t, got, ref)
        seen[t] = ref
    # The hand's closest approach to a link, as docs/robots.md gives it (29 mm), within the bounds above.
    assert abs(seen[3.55] - 0.029) < 0.006


def test_run_with_mcap_resolves_a_relative_description_from_the_scenario_folder(tmp_path, monkeypatch):
    # run --format mcap rebuilds the scene for /tf from the stored scenario: a description path relative to
    # the scenario file must resolve from that file's folder, not from where the command runs.
    (tmp_path / "cell").mkdir()
    (tmp_path / "cell" / "spinner.urdf").write_text(SPINNER.format(r=0.4, a=0.1))
    sonar = {"name": "sonar", "kind": "ultrasonic", "preset": "open_40khz", "mount": {"parent": "sp/paddle"}}
    p = _write(tmp_path / "cell", _data([{"name": "sp", "description": "spinner.urdf", "base": {"position": [0, 0, 1]},
                                          "joints": {"constant_velocity": {"q0": [0.0], "qd": [1.0]}}}], [sonar],
                                        recording="rec.h5"))
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, ["run", str(p), "-o", "out", "--format", "mcap", "--no-progress"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "out" / "rec.mcap").is_file()


def test_robot_links_take_the_scenario_own_materials(tmp_path):
    # A scenario's materials: entries are for its robots' links as for its objects.
    data = _data([_ur5(materials={"base_link": "dark_paint", "forearm_link": "mild_steel"})])
    data["materials"] = [{"name": "dark_paint", "base": "aluminium", "nir_reflectance": 0.05}]
    sc = scenario_from_dict(data, base_dir=tmp_path)
    paint = sc.scene.object("ur5/base_link").material
    assert (paint.name, paint.nir_reflectance) == ("dark_paint", 0.05)
    assert sc.scene.object("ur5/forearm_link").material.name == "mild_steel"
    data["robots"][0]["materials"]["base_link"] = "dark_pain"
    problems = _problems(data, tmp_path)
    assert [p[0] for p in problems] == ["robots[0].materials.base_link"] and "dark_paint" in problems[0][2]


def test_demo_output_folder_that_is_a_file_is_a_clear_error(tmp_path):
    (tmp_path / "afile").write_text("x")
    res = CliRunner().invoke(app, ["demo", "robot-cell", "-o", str(tmp_path / "afile"), "--no-progress"])
    assert res.exit_code == 2, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit)
    assert "--out" in res.output and "afile" in res.output and "Traceback" not in res.output


def test_sweep_output_folder_that_is_a_file_is_a_clear_error(tmp_path):
    (tmp_path / "afile").write_text("x")
    p = _write(tmp_path, _data([UR5]))
    res = CliRunner().invoke(app, ["sweep", str(p), "-p", "seed=0,1", "--backend", "serial", "-o",
                                   str(tmp_path / "afile")])
    assert res.exit_code == 2, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit)
    assert "--out" in res.output and "afile" in res.output


def test_convert_takes_the_scenario_folder_for_relative_descriptions(tmp_path, monkeypatch):
    # A recording of a robot given as a relative .urdf, converted from another folder: the recording keeps
    # the scenario file's folder (scenario_dir), so the stored scenario's relative paths resolve from any
    # working folder; once that folder is gone, --scenario-dir names where it went.
    (tmp_path / "cell").mkdir()
    (tmp_path / "cell" / "spinner.urdf").write_text(SPINNER.format(r=0.4, a=0.1))
    sonar = {"name": "sonar", "kind": "ultrasonic", "preset": "open_40khz", "mount": {"parent": "sp/paddle"}}
    p = _write(tmp_path / "cell", _data([{"name": "sp", "description": "spinner.urdf"}], [sonar], recording="r.h5"))
    monkeypatch.chdir(tmp_path / "cell")
    assert CliRunner().invoke(app, ["run", str(p), "-o", str(tmp_path / "out"), "--no-progress"]).exit_code == 0
    with open_recording(tmp_path / "out" / "r.h5") as rec:
        assert rec.scenario_dir == (tmp_path / "cell").resolve()
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, ["convert", "out/r.h5", "out/r.mcap"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "out" / "r.mcap").is_file()
    (tmp_path / "cell").rename(tmp_path / "moved")
    res = CliRunner().invoke(app, ["convert", "out/r.h5", "out/r2.mcap"])
    assert res.exit_code == 2 and "--scenario-dir" in res.output  # the error says where the way out is
    assert "working folder" in res.output
    res = CliRunner().invoke(app, ["convert", "out/r.h5", "out/r2.mcap", "--scenario-dir", "moved"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "out" / "r2.mcap").is_file()
