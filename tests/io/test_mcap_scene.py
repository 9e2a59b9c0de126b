"""The scene's geometry in ROS 2 MCAP files: ``/scene_markers`` (visualization_msgs/MarkerArray).

Read back with two independent readers: mcap_ros2's decoder (from the
schema embedded in the file) and rosbags' own ROS 2 Humble typestore (which
ignores the embedded text, so a layout that differs from Humble's Marker
would not decode). The triangles' corners are compared with the scene's
meshes value for value: float64 copied into float64 fields, tolerance 0.
"""

from __future__ import annotations

import copy
import re
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.typesys import Stores, get_typestore

from scene_dicts import FLANGE_HALL, OBJECTS
from twinsense.io import mcap as M
from twinsense.io.recording import open_recording
from twinsense.scenario import scenario_from_dict
from twinsense.scene import Box, Pose, Scene, Sphere
from twinsense.simulate import simulate

ROOT = Path(__file__).resolve().parents[2]


def _scenario() -> dict:
    """A floor, a wooden crate, a metal ball rolling along x and a UR5 (links with meshes and frames
    without), seen by one magnetic sensor at 10 Hz over 0.2 s (frame times 0 and 0.1 s)."""
    return {
        "name": "scene_markers", "duration": 0.2, "seed": 3,
        "objects": copy.deepcopy(OBJECTS),
        "robots": [{"name": "ur5", "description": "ur5", "base": {"position": [0.0, 0.0, 0.8]}}],
        "sensors": copy.deepcopy(FLANGE_HALL),
    }


def _mcap_ros2_messages(path) -> dict[str, list]:
    """topic -> [(log time [ns], decoded message)] through mcap_ros2 (the embedded ros2msg schemas)."""
    out: dict[str, list] = {}
    with open(path, "rb") as f:
        for _, ch, msg, dec in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            out.setdefault(ch.topic, []).append((msg.log_time, dec))
    return out


def _raw(path, topic) -> list[tuple[int, bytes, str, str]]:
    """[(log time, CDR bytes, schema name, schema text)] of ``topic``, read with the plain mcap reader."""
    with open(path, "rb") as f:
        return [(m.log_time, m.data, s.name, s.data.decode()) for s, ch, m in make_reader(f).iter_messages()
                if ch.topic == topic]


def _check_markers(markers, scene: Scene, stamp_ns: int) -> None:
    assert len(markers) == len(scene.objects)
    for i, (mk, obj) in enumerate(zip(markers, scene.objects, strict=True)):
        assert (mk.ns, mk.id, mk.type, mk.action, mk.frame_locked) == (M.SCENE_MARKER_NS, i, 11, 0, True)
        assert mk.header.frame_id == obj.name
        assert mk.header.stamp.sec * 10**9 + mk.header.stamp.nanosec == stamp_ns
        assert (mk.lifetime.sec, mk.lifetime.nanosec) == (0, 0)
        assert [mk.scale.x, mk.scale.y, mk.scale.z] == [1.0, 1.0, 1.0]
        p, q = mk.pose.position, mk.pose.orientation
        assert [p.x, p.y, p.z, q.x, q.y, q.z, q.w] == [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
        # Colour: the palette's values through float32 fields (exact after rounding to float32).
        want = np.float32(M.MATERIAL_COLORS[obj.material.name])
        np.testing.assert_array_equal(np.float32([mk.color.r, mk.color.g, mk.color.b, mk.color.a]), want)
        mesh = obj.geometry.mesh
        pts = np.array([[pt.x, pt.y, pt.z] for pt in mk.points])
        # Triangle after triangle, in the object's frame: float64 values copied, tolerance 0.
        assert pts.shape == (3 * len(mesh.faces), 3) and len(mk.colors) == 0
        np.testing.assert_array_equal(pts, np.asarray(mesh.vertices)[np.asarray(mesh.faces).ravel()])


def test_scene_markers_read_back_by_mcap_ros2_and_rosbags(tmp_path):
    sc = scenario_from_dict(_scenario(), base_dir=ROOT / "examples")
    res = simulate(sc.scene, sc.sensors, sc.duration, out=tmp_path / "r.h5", seed=sc.seed, scenario=sc.raw)
    path = M.convert(res.path, tmp_path / "r.mcap", lambda d: scenario_from_dict(d, base_dir=ROOT / "examples"))
    scene = sc.scene
    assert {"floor", "crate", "ball", "ur5/base_link", "ur5/wrist_3_link"} <= {o.name for o in scene.objects}

    msgs = _mcap_ros2_messages(path)
    (log_ns, arr), = msgs["/scene_markers"]  # once, at the first frame time
    assert log_ns == 0
    _check_markers(arr.markers, scene, 0)

    # Every marker's frame is a frame the file's transforms publish (the object's own /tf frame).
    children = {tr.child_frame_id for topic in ("/tf", "/tf_static") for _, m in msgs[topic] for tr in m.transforms}
    assert {mk.header.frame_id for mk in arr.markers} <= children

    # rosbags, with its own ROS 2 Humble definition of the message (not the file's text).
    (raw_ns, raw, name, text), = _raw(path, "/scene_markers")
    assert name == "visualization_msgs/msg/MarkerArray" and raw_ns == 0
    ts = get_typestore(Stores.ROS2_HUMBLE)
    _check_markers(ts.deserialize_cdr(raw, name).markers, scene, 0)
    # The embedded schema is Humble's text (rosbags writes the Quaternion without the .msg's defaults).
    humble, _ = ts.generate_msgdef(name, ros_version=2)
    assert re.sub(r"(?m)^(float64 [xyzw]) [01]$", r"\1", text) == humble


def test_a_scene_without_objects_writes_no_markers(tmp_path):
    # Geometry-free scene (only a frame): no /scene_markers topic; a scene with one box has exactly one marker.
    from twinsense.depthcam import DepthCamera

    cam = DepthCamera.preset("generic", name="cam", width=4, height=3)
    empty = Scene()
    res = simulate(empty, [cam], 0.1, out=tmp_path / "a.h5")
    with open_recording(res.path) as rec:
        path = M.write_mcap(rec, tmp_path / "a.mcap", empty)
    assert _raw(path, "/scene_markers") == []

    scene = Scene()
    scene.add_object("crate", Box((0.2, 0.2, 0.2)), material="plastic", pose=Pose(position=(0.0, 0.0, 1.0)))
    scene.add_object("ball", Sphere(0.05), material="glass", pose=Pose(position=(0.0, 0.3, 1.0)))
    res = simulate(scene, [cam], 0.1, out=tmp_path / "b.h5")
    with open_recording(res.path) as rec:
        path = M.write_mcap(rec, tmp_path / "b.mcap", scene)
    (_, arr), = _mcap_ros2_messages(path)["/scene_markers"]
    _check_markers(arr.markers, scene, 0)
    assert arr.markers[1].color.a < 1  # glass is translucent
