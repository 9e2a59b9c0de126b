"""Scenarios with robots (a URDF and an MJCF file) and people, checked from outside.

Bad values in a robot's joint entry or a person's entry are reported at the field as written in the file
(``robots[0].joints.keyframes.values[1][2]``), once, and nothing is written. A run is read back with
independent readers (the mcap package and rosbags' typestore) and checked against independent
kinematics: yourdfpy's forward kinematics of the URDF, MuJoCo's of the MJCF, the closed forms of the
joint motions (q0 + qd t; scipy's clamped cubic spline for keyframes). The same scenario run twice, and
with two capture processes, gives the same datasets.
"""

from __future__ import annotations

import copy
import math
import subprocess
import sys
from pathlib import Path

import h5py
import mujoco
import numpy as np
import pytest
import yaml
import yourdfpy
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from twinsense.io.mcap import convert
from twinsense.scenario import ScenarioError, scenario_from_dict

URDF = """<robot name="arm">
  <link name="base"><visual><geometry><box size="0.2 0.2 0.1"/></geometry></visual></link>
  <link name="upper"><visual><origin xyz="0 0 0.25"/><geometry><cylinder radius="0.04" length="0.5"/></geometry>
  </visual></link>
  <link name="fore"><visual><origin xyz="0.2 0 0"/><geometry><box size="0.4 0.05 0.05"/></geometry></visual></link>
  <link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.05" rpy="0 0 0.3"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0 0 0.5" rpy="0.1 0.2 0"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j3" type="prismatic"><parent link="fore"/><child link="tip"/><origin xyz="0.4 0 0"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.2" effort="1" velocity="1"/></joint>
</robot>
"""

MJCF = """<mujoco model="marm">
  <compiler angle="radian"/>
  <worldbody>
    <body name="link0">
      <geom type="box" size="0.1 0.1 0.05"/>
      <body name="link1" pos="0 0 0.1">
        <joint name="a" type="hinge" axis="0 0 1" range="-2 2" limited="true"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.4" size="0.04"/>
        <body name="link2" pos="0 0 0.4" euler="0.2 0 0">
          <joint name="b" type="hinge" axis="1 0 0" range="-1.5 1.5" limited="true"/>
          <geom type="box" size="0.03 0.03 0.15" pos="0 0 0.15"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

ARM_BASE = {"position": [1.5, 0.5, 0.0], "quat_xyzw": [0.0, 0.0, 0.3826834323650898, 0.9238795325112867]}
ARM_KEYS = {"times": [0.0, 0.3, 0.6], "values": [[0.1, 0.2, 0.05], [0.4, -0.1, 0.1], [0.2, 0.0, 0.02]]}
MARM_BASE = {"position": [-1.0, 1.0, 0.2], "rpy_deg": [5.0, 0.0, -20.0]}
MARM_Q0, MARM_QD = [0.1, -0.5], [0.4, 0.7]  # columns (b, a): joint_names reorders them


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("bodies")
    (d / "arm.urdf").write_text(URDF)
    (d / "arm.xml").write_text(MJCF)
    return d


def scenario() -> dict:
    """A URDF arm on keyframes, an MJCF arm at constant velocity, a walking and a turning, reaching person;
    sensors on a robot link, an MJCF body and a person's head (0.6 s, frame times 0 .. 0.5 s)."""
    return {
        "name": "outside", "duration": 0.6, "seed": 11,
        "objects": [{"name": "floor", "geometry": {"type": "plane", "size": [8, 8]}, "material": "concrete"}],
        "robots": [
            {"name": "arm", "description": "arm.urdf", "base": ARM_BASE, "joints": {"keyframes": ARM_KEYS}},
            {"name": "marm", "description": "arm.xml", "base": MARM_BASE,
             "joints": {"joint_names": ["b", "a"], "constant_velocity": {"q0": MARM_Q0, "qd": MARM_QD}}},
        ],
        "people": [
            {"name": "alice", "height": 1.7, "position": [2.0, -1.0], "heading_deg": 63.4,
             "walk": {"speed": 1.2, "path": [[2.5, 0.0], [2.5, 1.5]], "start_time": 0.1}},
            {"name": "bob", "height": 1.85, "position": [-2.0, -1.0], "heading_deg": 45, "sway": 0.02,
             "clothing": "fabric", "turn": {"heading_deg": 90, "start_time": 0.1, "duration": 0.4},
             "reach": {"target": [-2.0, -0.55, 1.3], "start_time": 0.2, "duration": 0.3}},
        ],
        "sensors": [
            {"name": "tip_mag", "kind": "magnetic", "preset": "tle493d", "frame_rate": 10,
             "mount": {"parent": "arm/tip"}},
            {"name": "link_cam", "kind": "camera", "preset": "generic", "frame_rate": 5,
             "overrides": {"width": 8, "height": 6}, "mount": {"parent": "marm/link2",
                                                                "pose": {"position": [0, 0, 0.3]}}},
            {"name": "head_cam", "kind": "camera", "preset": "generic", "frame_rate": 10,
             "overrides": {"width": 8, "height": 6}, "mount": {"parent": "alice/head",
                                                                "pose": {"position": [0.1, 0, 0]}}},
        ],
        "outputs": {"recording": "recording.h5", "plots": False},
    }


def problems(data: dict, base_dir: Path) -> list:
    with pytest.raises(ScenarioError) as e:
        scenario_from_dict(data, source="cell.yaml", base_dir=base_dir)
    return e.value.problems


def _set(data: dict, path: tuple, value) -> dict:
    d = copy.deepcopy(data)
    node = d
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return d


ARM = ("robots", 0, "joints")


@pytest.mark.parametrize(("path", "value", "field"), [
    # true/false among numbers was read as 1/0: a joint moved to 1 rad without a word
    ((*ARM, "keyframes", "values", 1, 1), True, "robots[0].joints.keyframes.values[1][1]"),
    ((*ARM, "keyframes", "times", 0), False, "robots[0].joints.keyframes.times[0]"),
    # NaN, inf and text named only the whole array ('array with NaN or inf')
    ((*ARM, "keyframes", "values", 2, 0), math.nan, "robots[0].joints.keyframes.values[2][0]"),
    ((*ARM, "keyframes", "values", 1, 2), "x", "robots[0].joints.keyframes.values[1][2]"),
    ((*ARM, "keyframes", "times", 1), math.inf, "robots[0].joints.keyframes.times[1]"),
])
def test_keyframe_numbers_named(files, path, value, field):
    probs = problems(_set(scenario(), path, value), files)
    assert len(probs) == 1 and probs[0][0] == field
    got = probs[0][1]
    if value != value:  # NaN
        assert isinstance(got, float) and math.isnan(got)
    else:
        assert got == value and type(got) is type(value)
    assert "finite" in probs[0][2]


@pytest.mark.parametrize(("joints", "field", "value"), [
    ({"constant_velocity": {"q0": [0.1, True, 0.0], "qd": [0, 0, 0]}}, "robots[0].joints.constant_velocity.q0[1]",
     True),
    ({"constant_velocity": {"q0": [0.1, 0.0, 0.0], "qd": [0, math.inf, 0]}},
     "robots[0].joints.constant_velocity.qd[1]", math.inf),
    ({"constant_velocity": {"q0": [0.1, 0.0, 0.0], "qd": [0, 0, "fast"]}},
     "robots[0].joints.constant_velocity.qd[2]", "fast"),
    ({"setpoints": [0.0, True, 0.0]}, "robots[0].joints.setpoints[1]", True),
    ({"setpoints": [0.0, 0.0, "x"]}, "robots[0].joints.setpoints[2]", "x"),
])
def test_joint_numbers_named(files, joints, field, value):
    probs = problems(_set(scenario(), ARM, joints), files)
    assert [(p[0], p[1]) for p in probs] == [(field, value)]


def test_nan_constant_velocity_named(files):
    probs = problems(_set(scenario(), ARM, {"constant_velocity": {"q0": [0.1, math.nan, 0.0], "qd": [0, 0, 0]}}),
                     files)
    assert len(probs) == 1 and probs[0][0] == "robots[0].joints.constant_velocity.q0[1]"
    assert math.isnan(probs[0][1])


def test_failed_person_reported_once(files):
    """A person outside the model's heights is one problem: the sensor on her head is not also an unknown
    mount parent (the list of every link of the scenario, as it was before)."""
    probs = problems(_set(scenario(), ("people", 0, "height"), 3.0), files)
    assert [(p[0], p[1]) for p in probs] == [("people[0].height", 3.0)]


@pytest.mark.parametrize("who", ["robot", "person"])
def test_failed_own_material_reported_once(files, who):
    """A scenario material that fails (unknown base), named by a robot link or a person's clothing: the
    material's entry is the one problem. The robot's link was also called an unknown material (the list
    left the scenario's own name out) and the sensors on either body unknown mount parents."""
    data = scenario() | {"materials": [{"name": "paint", "base": "unobtainium"}]}
    if who == "robot":
        data["robots"][0]["materials"] = {"upper": "paint"}
        data["sensors"][0]["mount"] = {"parent": "arm/tip"}
    else:
        data["people"][0]["clothing"] = "paint"
    probs = problems(data, files)
    assert [(p[0], p[1]) for p in probs] == [("materials[0].base", "unobtainium")]


@pytest.mark.parametrize("hold", [math.nan, "nan"])
def test_reach_hold_nan_says_nan(files, hold):
    (p,) = problems(_set(scenario(), ("people", 1, "reach", "hold"), hold), files)
    assert p[0] == "people[1].reach.hold" and "NaN" in p[2]  # not "should be >= 0"


@pytest.mark.parametrize(("tag", "shapes"), [("collision", None), ("visual", "collision")])
def test_shapes_the_description_lacks(files, tag, shapes):
    """A URDF whose links carry only <collision> shapes, loaded with the default visual ones (or only <visual>,
    with shapes: collision), had no geometry at all: every sensor saw through the robot without a word."""
    text = URDF if tag == "visual" else URDF.replace("<visual>", "<collision>").replace("</visual>", "</collision>")
    (files / f"only_{tag}.urdf").write_text(text)
    entry = {"name": "arm", "description": f"only_{tag}.urdf"} | ({"shapes": shapes} if shapes else {})
    probs = problems({"duration": 0.1, "robots": [entry]}, files)
    wanted = "visual" if tag == "visual" else "collision"
    assert [(p[0], p[1]) for p in probs] == [("robots[0].shapes", shapes or "visual")]
    assert probs[0][2].startswith(f"{wanted}:")


def test_frames_only_description_allowed(files):
    """A description with no shapes in either set (frames to mount on) is built as frames."""
    (files / "frames.urdf").write_text('<robot name="f"><link name="a"/><link name="b"/><joint name="j" '
                                       'type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>'
                                       '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>')
    sc = scenario_from_dict({"duration": 0.1, "robots": [{"name": "f", "description": "frames.urdf"}]},
                            base_dir=files)
    assert len(sc.scene.objects) == 0 and set(sc.scene.frame_names) == {"f/a", "f/b"}


def test_bad_scenario_writes_nothing(files, tmp_path):
    """`twinsense run` on a file with two bad values: both named as in the file, exit 2, no output folder."""
    data = _set(_set(scenario(), (*ARM, "keyframes", "values", 1, 1), True), ("people", 0, "height"), 3.0)
    path = files / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "twinsense", "run", str(path), "-o", str(out)], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 2, r.stderr
    assert "2 problems" in r.stderr
    assert "robots[0].joints.keyframes.values[1][1] = True" in r.stderr
    assert "people[0].height = 3.0" in r.stderr
    assert not out.exists()


# --- a run read back -------------------------------------------------------------------------------------

def _matrix(position, rotation: Rotation) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = rotation.as_matrix()
    m[:3, 3] = position
    return m


def _read_mcap(path: Path):
    store = get_typestore(Stores.ROS2_HUMBLE)
    out = []
    with path.open("rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if schema.name not in store.types:
                store.register(get_types_from_msg(schema.data.decode().split("=" * 80)[0], schema.name))
            out.append((channel.topic, message.log_time, store.deserialize_cdr(message.data, schema.name)))
    return out


def _datasets(path: Path) -> dict:
    out = {}

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset):
            out[name] = (obj.dtype.str, obj.shape, obj[()].tobytes())
        out[name + "@"] = {k: np.asarray(v).tobytes() for k, v in obj.attrs.items() if k != "created"}

    with h5py.File(path) as f:
        f.visititems(visit)
    return out


@pytest.fixture(scope="module")
def run(files, tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    sc = scenario_from_dict(scenario(), source=str(files / "cell.yaml"), base_dir=files)
    result = sc.run(out / "a")
    mcap_path = convert(result.path, out / "a.mcap",
                        lambda raw: scenario_from_dict(raw, base_dir=files))
    return sc, result.path, _read_mcap(mcap_path)


def _tf(messages):
    """(static {child: (parent, T)}, {stamp ns: {child: (parent, T)}}) as published."""
    static, moving = {}, {}
    for topic, log_time, msg in messages:
        if topic not in ("/tf", "/tf_static"):
            continue
        for x in msg.transforms:
            stamp = x.header.stamp.sec * 10**9 + x.header.stamp.nanosec
            r, p = x.transform.rotation, x.transform.translation
            entry = (x.header.frame_id, _matrix([p.x, p.y, p.z], Rotation.from_quat([r.x, r.y, r.z, r.w])))
            if topic == "/tf_static":
                static[x.child_frame_id] = entry
            else:
                assert stamp == log_time
                moving.setdefault(stamp, {})[x.child_frame_id] = entry
    return static, moving


def _world(frame: str, static: dict, at: dict) -> np.ndarray:
    m = np.eye(4)
    while frame != "world":
        parent, t = at[frame] if frame in at else static[frame]
        m = t @ m
        frame = parent
    return m


# Poses through float64 quaternions and a few 4 x 4 products, at metre scale: ~1e-15 per entry each;
# 1e-9 (m, and per rotation-matrix entry) leaves a millionfold margin, far under any wrong frame or time.
TOL = 1e-9


def test_tf_against_independent_kinematics(run):
    """/tf composed to world at each stamp against yourdfpy (URDF) and MuJoCo (MJCF) forward kinematics of
    the closed-form joint motions, and against twinsense's own link poses (people)."""
    sc, _, messages = run
    static, moving = _tf(messages)
    assert sorted(moving) == [k * 100_000_000 for k in range(6)]  # frames at 0, 0.1, ..., 0.5 s
    spline = CubicSpline(ARM_KEYS["times"], np.array(ARM_KEYS["values"]), bc_type="clamped", axis=0)
    urdf = yourdfpy.URDF.load(str(Path(sc.base_dir) / "arm.urdf"))
    arm_base = _matrix(ARM_BASE["position"], Rotation.from_quat(ARM_BASE["quat_xyzw"]))
    model = mujoco.MjModel.from_xml_path(str(Path(sc.base_dir) / "arm.xml"))
    data = mujoco.MjData(model)
    marm_base = _matrix(MARM_BASE["position"], Rotation.from_euler("xyz", MARM_BASE["rpy_deg"], degrees=True))
    people = [b for b in sc.scene.articulated_bodies if b.name in ("alice", "bob")]
    for stamp, at in moving.items():
        t = stamp * 1e-9
        urdf.update_cfg(dict(zip(("j1", "j2", "j3"), spline(t), strict=True)))
        for link in ("base", "upper", "fore", "tip"):
            np.testing.assert_allclose(_world(f"arm/{link}", static, at), arm_base @ urdf.get_transform(link, "base"),
                                       rtol=0, atol=TOL)
        q_b, q_a = np.array(MARM_Q0) + np.array(MARM_QD) * t
        data.qpos[model.joint("a").qposadr[0]], data.qpos[model.joint("b").qposadr[0]] = q_a, q_b
        mujoco.mj_kinematics(model, data)
        for link in ("link0", "link1", "link2"):
            body = data.body(link)
            np.testing.assert_allclose(_world(f"marm/{link}", static, at),
                                       marm_base @ _matrix(body.xpos, Rotation.from_matrix(body.xmat.reshape(3, 3))),
                                       rtol=0, atol=TOL)
        for person in people:
            state = person.state(t)
            for link in person.tree.links:
                np.testing.assert_allclose(_world(f"{person.name}/{link.name}", static, at),
                                           state.pose(link.name).matrix, rtol=0, atol=TOL)
        for sensor in sc.sensors:  # the data frames: optical for cameras
            frame = f"{sensor.name}_optical_frame" if sensor.kind == "camera" else sensor.name
            np.testing.assert_allclose(_world(frame, static, at), sensor.mount.pose_at(sc.scene, t).matrix,
                                       rtol=0, atol=TOL)


def test_joint_states_closed_forms(run):
    sc, _, messages = run
    states = {}
    for topic, log_time, msg in messages:
        if topic.endswith("/joint_states"):
            assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == log_time
            states.setdefault(topic, []).append((log_time * 1e-9, list(msg.name), msg.position, msg.velocity))
    assert sorted(states) == ["/alice/joint_states", "/arm/joint_states", "/bob/joint_states", "/marm/joint_states"]
    spline = CubicSpline(ARM_KEYS["times"], np.array(ARM_KEYS["values"]), bc_type="clamped", axis=0)
    for t, names, q, qd in states["/arm/joint_states"]:
        assert names == ["j1", "j2", "j3"]
        # the spline's own evaluation against scipy's: the same coefficients, rounding only (~1e-16 rad)
        np.testing.assert_allclose(q, spline(t), rtol=0, atol=1e-12)
        np.testing.assert_allclose(qd, spline(t, 1), rtol=0, atol=1e-12)
    for t, names, q, qd in states["/marm/joint_states"]:
        assert names == ["a", "b"]  # the tree's order, whatever the columns' order in the file
        np.testing.assert_allclose(q, [MARM_Q0[1] + MARM_QD[1] * t, MARM_Q0[0] + MARM_QD[0] * t], rtol=0, atol=1e-12)
        np.testing.assert_allclose(qd, [MARM_QD[1], MARM_QD[0]], rtol=0, atol=0)
    for person in (b for b in sc.scene.articulated_bodies if b.name in ("alice", "bob")):
        for t, names, q, qd in states[f"/{person.name}/joint_states"]:
            q_ref, qd_ref = person.joint_state(t)
            assert names == list(person.tree.joint_names)
            np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-12)
            np.testing.assert_allclose(qd, qd_ref, rtol=0, atol=1e-12)


def test_every_frame_id_published_and_stamps_in_order(run):
    _, _, messages = run
    static, moving = _tf(messages)
    frames = {"world", *static, *(c for at in moving.values() for c in at)}
    last = {}
    for topic, log_time, msg in messages:
        assert log_time >= last.get(topic, 0), topic
        last[topic] = log_time
        header = getattr(msg, "header", None)
        if header is not None:
            assert header.frame_id in frames, (topic, header.frame_id)
        for marker in getattr(msg, "markers", ()):
            assert marker.header.frame_id in frames, marker.header.frame_id


def test_same_datasets_twice_and_with_two_processes(run, files, tmp_path):
    _, first, _ = run
    again = scenario_from_dict(scenario(), base_dir=files).run(tmp_path / "b").path
    forked = scenario_from_dict(scenario(), base_dir=files).run(tmp_path / "c", processes=2).path
    reference = _datasets(first)
    assert _datasets(again) == reference
    assert _datasets(forked) == reference
