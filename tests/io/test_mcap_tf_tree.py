"""The transform tree and joint states of ROS 2 MCAP files of robots, people and a MuJoCo co-simulation.

Read back with rosbags (an independent reader and its own typestore: tf2_msgs,
sensor_msgs/JointState of ROS 2 Humble) and checked as a property: every frame
a message is stamped in, and every transform's parent, is published (on
/tf_static, or on /tf at that very stamp) and chains to ``world``. Joint
states are checked against the bodies' own joint motions and the link poses
on /tf against the tree's forward kinematics of those joint states.
"""

from __future__ import annotations

import re
from pathlib import Path

import mujoco
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from twinsense.depthcam import DepthCamera
from twinsense.errors import ConfigError
from twinsense.io import mcap as M
from twinsense.robots import MujocoCosim
from twinsense.scenario import scenario_from_dict
from twinsense.scene import Box, Mount, Pose, Scene
from twinsense.scene.scene import Frame
from twinsense.simulate import simulate

ROOT = Path(__file__).resolve().parents[2]
# float64 poses through a quaternion and back, and a few 4 x 4 products: ~1e-15 per entry at metre
# scale; 1e-12 leaves a thousandfold margin and still catches any wrong frame or time (mm, mrad).
POSE_TOL = 1e-12


def robot_and_person() -> dict:
    """A UR5 with a small ToF on its flange frame ``ur5/tool0`` (no geometry), a walking person with a
    sensor on her head, at 10 and 20 Hz over 0.2 s (frame times 0, 0.05, ..., 0.15 s)."""
    return {
        "name": "tf_tree", "duration": 0.2, "seed": 1,
        "objects": [{"name": "floor", "geometry": {"type": "plane", "size": [6.0, 6.0]}, "material": "concrete"}],
        "robots": [{"name": "ur5", "description": "ur5", "base": {"position": [0.0, 0.0, 0.8]},
                    "joints": {"keyframes": {"times": [0.0, 1.0],
                                             "values": [[0.0, -1.57, 1.57, -1.57, -1.57, 0.0],
                                                        [0.5, -1.30, 1.45, -1.72, -1.57, 0.3]]}}}],
        "people": [{"name": "alice", "height": 1.7, "position": [2.0, 0.0],
                    "walk": {"speed": 1.2, "path": [[2.0, 2.0]]}}],
        "sensors": [
            {"name": "wrist", "kind": "tof", "preset": "generic", "frame_rate": 10,
             "overrides": {"width": 16, "height": 12},
             "mount": {"parent": "ur5/tool0", "pose": {"position": [0.0, 0.0, 0.02]}}},
            {"name": "badge", "kind": "magnetic", "preset": "tle493d", "frame_rate": 20,
             "mount": {"parent": "alice/head", "pose": {"position": [0.1, 0.0, 0.0]}}},
        ],
    }


def typestore():
    ts = get_typestore(Stores.ROS2_HUMBLE)  # tf2_msgs, sensor_msgs (JointState), rosgraph_msgs of ROS 2 Humble
    types = {}
    for f in sorted((ROOT / "docs" / "msg").glob("*.msg")):
        types.update(get_types_from_msg(f.read_text(), f"twinsense_msgs/msg/{f.stem}"))
    ts.register(types)
    return ts


def read(path) -> tuple[dict, dict]:
    """(topic -> message type, topic -> [(log time [ns], message)]) in log-time order."""
    msgs: dict[str, list] = {}
    with AnyReader([Path(path)], default_typestore=typestore()) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        for c, log_ns, raw in reader.messages():
            msgs.setdefault(c.topic, []).append((log_ns, reader.deserialize(raw, c.msgtype)))
    return types, msgs


def stamp(header) -> int:
    return header.stamp.sec * 10**9 + header.stamp.nanosec


def check_tree(msgs: dict) -> dict[int, dict[str, tuple[str, object]]]:
    """Assert the property; returns {stamp: {child: (parent, transform)}} of /tf (static ones under -1)."""
    static: dict[str, tuple[str, object]] = {}
    for _, m in msgs.get("/tf_static", []):
        for tr in m.transforms:
            assert tr.child_frame_id != tr.header.frame_id
            assert static.setdefault(tr.child_frame_id, (tr.header.frame_id, tr))[0] == tr.header.frame_id
    dynamic: dict[int, dict[str, tuple[str, object]]] = {}
    for log, m in msgs.get("/tf", []):
        for tr in m.transforms:
            assert stamp(tr.header) == log and tr.child_frame_id not in static  # one parent per frame
            dynamic.setdefault(log, {})[tr.child_frame_id] = (tr.header.frame_id, tr)

    def resolves(frame: str, ns: int) -> bool:
        seen = set()
        while frame != "world":
            if frame in seen:
                return False  # a loop never reaches world
            seen.add(frame)
            parent = static.get(frame) or dynamic.get(ns, {}).get(frame)
            if parent is None:
                return False
            frame = parent[0]
        return True

    checked = 0
    for topic, rows in msgs.items():
        for _, m in rows:
            headers = [tr.header for tr in m.transforms] if hasattr(m, "transforms") else [getattr(m, "header", None)]
            for h in headers:
                if h is None:
                    continue  # /clock
                ns = stamp(h) if topic != "/tf_static" else next(iter(dynamic), 0)
                assert h.frame_id and resolves(h.frame_id, ns), (topic, h.frame_id, ns)
                checked += 1
    assert checked > 0
    return {-1: static, **dynamic}


@pytest.fixture(scope="module")
def robot_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("tf_tree")
    sc = scenario_from_dict(robot_and_person(), base_dir=ROOT / "examples")
    res = simulate(sc.scene, sc.sensors, sc.duration, out=out / "r.h5", seed=sc.seed, scenario=sc.raw)
    path = M.convert(res.path, out / "r.mcap", lambda d: scenario_from_dict(d, base_dir=ROOT / "examples"))
    types, msgs = read(path)
    return {"h5": res.path, "mcap": path, "scene": sc.scene, "types": types, "msgs": msgs}


def test_every_frame_resolves_to_world_robot_and_person(robot_run):
    tree = check_tree(robot_run["msgs"])
    scene = robot_run["scene"]
    # The flange frame the wrist ToF hangs from is published at every /tf stamp, as are the other
    # frame-only links; and the sensor's own frames chain through it.
    assert "ur5/tool0" in scene.frame_names
    times = [log for log, _ in robot_run["msgs"]["/tf"]]
    assert times == [round(k * 0.05e9) for k in range(4)]
    for ns in times:
        assert set(scene.frame_names) | {o.name for o in scene.objects if not o.is_static} == set(tree[ns])
    assert tree[-1]["wrist_link"][0] == "ur5/tool0" and tree[-1]["badge"][0] == "alice/head"


def _matrix(tr) -> np.ndarray:
    t, q = tr.transform.translation, tr.transform.rotation
    return Pose.from_quat((t.x, t.y, t.z), (q.x, q.y, q.z, q.w)).matrix


def test_the_chain_to_the_wrist_tof_is_its_recorded_pose(robot_run):
    # world <- optical = (world <- tool0 on /tf) (tool0 <- wrist_link) (wrist_link <- optical), all from
    # the file, against the sensor -> world pose the ToF recorded at each frame.
    from twinsense.io.recording import open_recording

    tree = check_tree(robot_run["msgs"])
    with open_recording(robot_run["h5"]) as rec:
        s = rec["wrist"]
        for k, t in enumerate(s.timestamps):
            ns = M.stamp_ns(t)
            m = _matrix(tree[ns]["ur5/tool0"][1]) @ _matrix(tree[-1]["wrist_link"][1]) @ _matrix(
                tree[-1]["wrist_optical_frame"][1])
            np.testing.assert_allclose(m, s["pose"][k], rtol=0, atol=POSE_TOL)


def test_joint_states_are_the_bodies_values(robot_run):
    msgs, scene = robot_run["msgs"], robot_run["scene"]
    bodies = scene.articulated_bodies
    assert [b.name for b in bodies] == ["ur5", "alice"]
    times = [log for log, _ in msgs["/tf"]]
    for body in bodies:
        topic = f"/{body.name}/joint_states"
        assert robot_run["types"][topic] == "sensor_msgs/msg/JointState"
        rows = msgs[topic]
        assert [log for log, _ in rows] == times  # one message per body at each /tf time
        for log, m in rows:
            assert stamp(m.header) == log and m.header.frame_id == f"{body.name}/{body.tree.root}"
            assert list(m.name) == list(body.tree.joint_names)
            q, qd = body.joint_state(log * 1e-9)
            # float64 written and read back: bit for bit (tolerance 0).
            np.testing.assert_array_equal(m.position, q)
            np.testing.assert_array_equal(m.velocity, qd)
            assert len(m.effort) == 0
    # The robot moves between keyframes: its joint states are not all the same.
    ur5 = [m.position for _, m in msgs["/ur5/joint_states"]]
    assert not np.array_equal(ur5[0], ur5[-1])


def test_the_joint_states_replay_as_the_same_motion(robot_run):
    # The file's joint states read by twinsense's own recorded-trajectory reader (mcap-ros2-support's
    # decoder): a JointSamples exact at its samples (the stamps), velocities as published.
    from twinsense.robots.recordings import read_joint_states

    body = robot_run["scene"].articulated_bodies[0]
    samples = read_joint_states(robot_run["mcap"], "/ur5/joint_states")
    times = [log for log, _ in robot_run["msgs"]["/tf"]]
    for ns in times:
        q, qd = body.joint_state(ns * 1e-9)
        sq, sqd = samples.q_qd(ns * 1e-9)
        np.testing.assert_array_equal(sq, q)
        np.testing.assert_array_equal(sqd, qd)


def test_link_poses_are_forward_kinematics_of_the_joint_states(robot_run):
    # Consistency of the file with itself: each link on /tf (objects and frame-only links) is the tree's
    # forward kinematics of the published joint state at the body's base pose.
    msgs, scene = robot_run["msgs"], robot_run["scene"]
    tree = check_tree(msgs)
    for body in scene.articulated_bodies:
        for log, js in msgs[f"/{body.name}/joint_states"]:
            fk = body.tree.forward(np.array(js.position), base=body.base.state(log * 1e-9).pose)
            for link in body.tree.link_names:
                name = f"{body.name}/{link}"
                parent, tr = tree[log].get(name) or tree[-1][name]
                assert parent == "world"
                np.testing.assert_allclose(_matrix(tr), fk.pose(link).matrix, rtol=0, atol=POSE_TOL)


DT = 0.002
PENDULUM = f"""<mujoco model="pendulum">
  <option timestep="{DT}" gravity="0 0 -9.81"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="arm" pos="0 0 1.5"><joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.03"/>
      <body name="tip" pos="0.5 0 0"><site name="tool" pos="0.05 0 0"/></body></body>
  </worldbody>
</mujoco>"""


def test_mujoco_cosim_sites_and_geomless_bodies_resolve(tmp_path):
    # A swinging pendulum: its tip is a body without geoms and its tool a site (both mount frames), a
    # camera hangs from the site. The world body's floor is the object "world": the root, not re-published.
    cosim = MujocoCosim(mujoco.MjModel.from_xml_string(PENDULUM))
    scene = cosim.scene
    assert scene.frame_names == ("tip", "tool") and scene.objects[0].name == "world"
    cam = DepthCamera.preset("generic", name="cam", width=8, height=6, mount=Mount(Pose(), parent="tool"))
    res = simulate(scene, [cam], 0.1, out=tmp_path / "p.h5")
    from twinsense.io.recording import open_recording

    with open_recording(res.path) as rec:
        path = M.write_mcap(rec, tmp_path / "p.mcap", scene)
    _, msgs = read(path)
    tree = check_tree(msgs)
    assert "world" not in tree[-1] and all("world" not in v for v in tree.values())
    for log, _ in msgs["/tf"]:
        assert set(tree[log]) == {"arm", "tip", "tool"}
        np.testing.assert_allclose(_matrix(tree[log]["tool"][1]), scene.mount_target("tool").pose_at(log * 1e-9).matrix,
                                   rtol=0, atol=POSE_TOL)
    assert not any(t.endswith("joint_states") for t in msgs)  # no articulated body in a plain co-simulation


def test_an_item_called_world_away_from_the_origin_is_refused(tmp_path):
    scene = Scene()
    scene.add_object("world", Box((1.0, 1.0, 1.0)), pose=Pose(position=(1.0, 0.0, 0.0)))
    with pytest.raises(ConfigError, match="root frame"):
        M.scene_transforms(scene)
    scene = Scene()
    scene.add_frame(Frame("world"))  # at the origin: the world frame itself, left out
    scene.add_frame(Frame("flange", Pose(position=(0.0, 0.0, 1.0))))
    static, moving = M.scene_transforms(scene)
    assert [(p, c) for p, c, _ in static] == [("world", "flange")] and moving == []


def test_joint_state_definition_is_the_official_one():
    # The embedded schema text equals the one rosbags generates from its own ROS 2 Humble
    # sensor_msgs/msg/JointState (with its Header and Time dependencies), character for character.
    text, _ = get_typestore(Stores.ROS2_HUMBLE).generate_msgdef("sensor_msgs/msg/JointState", ros_version=2)
    assert M.MSGDEFS["sensor_msgs/msg/JointState"] == text


def _flange_camera_run(tmp_path, body_name: str, cam_name: str, duration: float, lower=-np.inf, upper=np.inf):
    """(body, MCAP path): a one-joint arm without a joint motion, 1 m up at x = 1 m, whose flange (no
    geometry) carries an 8 x 6 depth camera at 10 Hz, run for ``duration`` [s] and written as MCAP."""
    from twinsense.io.recording import open_recording
    from twinsense.scene.articulated import ArticulatedBody, Joint, KinematicTree, Link

    tree = KinematicTree("arm", [Link("base", Box((0.2, 0.2, 0.2))), Link("flange", None)],
                         [Joint("j", "revolute", "base", "flange", origin=Pose(position=(0.0, 0.0, 1.0)),
                                lower=lower, upper=upper)])
    scene = Scene()
    body = ArticulatedBody(body_name, tree, base=Pose(position=(1.0, 0.0, 0.0)))
    body.add_to(scene)
    cam = DepthCamera.preset("generic", name=cam_name, width=8, height=6, frame_rate=10,
                             mount=Mount(Pose(), parent=f"{body_name}/flange"))
    res = simulate(scene, [cam], duration, out=tmp_path / "a.h5")
    with open_recording(res.path) as rec:
        return body, M.write_mcap(rec, tmp_path / "a.mcap", scene)


def test_a_body_at_rest_frames_static_joint_states_at_home(tmp_path):
    # A one-joint arm without a joint motion: its flange (no geometry) is on /tf_static, nothing on /tf,
    # and its joint states are still published at each frame time, at home (0 clipped into [0.2, 1]).
    body, path = _flange_camera_run(tmp_path, "arm", "cam", 0.2, lower=0.2, upper=1.0)
    _, msgs = read(path)
    tree_msgs = check_tree(msgs)
    assert "/tf" not in msgs and tree_msgs[-1]["cam_link"][0] == "arm/flange"
    np.testing.assert_allclose(_matrix(tree_msgs[-1]["arm/flange"][1]), body.state(0.0).pose("flange").matrix,
                               rtol=0, atol=POSE_TOL)
    rows = msgs["/arm/joint_states"]
    assert [log for log, _ in rows] == [0, 100_000_000]
    for _, m in rows:
        assert list(m.name) == ["j"] and list(m.position) == [0.2] and list(m.velocity) == [0.0]


# ROS 2's topic name rules (rcl's validation, as `ros2 topic` applies them to a bag's topics): tokens of
# letters, digits and underscores, none starting with a digit, joined by single slashes from a leading one.
_ROS2_TOPIC = re.compile(r"^(/[A-Za-z_][A-Za-z0-9_]*)+$")


@pytest.mark.parametrize(("name", "want"), [
    ("/tf", "/tf"), ("/ur5/joint_states", "/ur5/joint_states"), ("/my-arm/joint_states", "/my_arm/joint_states"),
    ("/2nd.cam/depth", "/_2nd_cam/depth"), ("/a//b/", "/a/b"), ("/wrist tof/points", "/wrist_tof/points")])
def test_topic_names_are_valid_ros2_names(name, want):
    assert M.ros_topic(name) == want and _ROS2_TOPIC.match(want)


def test_a_body_and_sensor_with_hyphens_give_valid_topics(tmp_path):
    # Names a scenario allows ("my-arm", "wrist-cam") but ROS 2 refuses in a topic: every topic of the
    # file is a valid ROS 2 name; the frame ids keep the names as they are (tf frames may hold '-').
    _, path = _flange_camera_run(tmp_path, "my-arm", "wrist-cam", 0.1)
    types, msgs = read(path)
    assert all(_ROS2_TOPIC.match(t) for t in types), sorted(types)
    assert {"/my_arm/joint_states", "/wrist_cam/depth", "/wrist_cam/camera_info"} <= set(types)
    assert msgs["/wrist_cam/depth"][0][1].header.frame_id == "wrist-cam_optical_frame"
    tree_msgs = check_tree(msgs)
    assert tree_msgs[-1]["wrist-cam_link"][0] == "my-arm/flange"
