"""ROS 2 MCAP output, read back with an independent reader (rosbags) and checked
against the HDF5 recording of the same run and against closed forms of the scene."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from typer.testing import CliRunner

from twinsense.cli import app
from twinsense.errors import TwinsenseError
from twinsense.io import mcap as M
from twinsense.io.recording import open_recording
from twinsense.scenario import scenario_from_dict
from twinsense.simulate import simulate

ROOT = Path(__file__).resolve().parents[2]
MSG_DIR = ROOT / "docs" / "msg"
EYE, TARGET = np.array([0.0, 0.0, 1.2]), np.array([4.0, 0.0, 0.8])


def _scenario() -> dict:
    d = yaml.safe_load((ROOT / "examples" / "office_depth.yaml").read_text())
    d["duration"] = 0.2  # two frames per sensor at 10 Hz
    look = {"look_at": {"eye": EYE.tolist(), "target": TARGET.tolist()}}
    d["sensors"] += [
        {"name": "tof", "kind": "tof", "preset": "generic", "frame_rate": 10,
         "overrides": {"width": 32, "height": 24}, "mount": {"pose": look}},
        {"name": "radar", "kind": "radar", "preset": "paper_bgt60tr13c", "frame_rate": 10,
         "mount": {"pose": {"look_at": {"eye": [0.0, 0.0, 1.0], "target": [4.0, 0.0, 1.0]}}}},
        {"name": "cap", "kind": "capacitive", "preset": "pad-grid", "frame_rate": 10,
         "mount": {"pose": {"position": [2.0, 0.0, 1.6]}}},
        {"name": "hall", "kind": "magnetic", "preset": "tle493d", "frame_rate": 10,
         "mount": {"pose": {"position": [1.0, 0.0, 0.5]}}},
        {"name": "lidar", "kind": "lidar", "preset": "velodyne_vlp16", "frame_rate": 10,
         "overrides": {"columns": 90}, "mount": {"pose": {"look_at": {"eye": [0.0, 0.0, 1.0],
                                                                       "target": [4.0, 0.0, 1.0]}}}},
        {"name": "sonar", "kind": "ultrasonic", "preset": "open_40khz", "frame_rate": 10,
         "mount": {"pose": {"look_at": {"eye": [0.0, 0.0, 0.5], "target": [4.0, 0.0, 0.5]}}}},
        {"name": "prox", "kind": "inductive", "preset": "m12_flush", "frame_rate": 10,
         "mount": {"pose": {"position": [2.0, -1.0, 0.1]}}},
    ]
    return d


def _typestore():
    # The package's messages from their documented .msg files, not from the writer's tables.
    ts = get_typestore(Stores.ROS2_HUMBLE)
    types = {}
    for f in sorted(MSG_DIR.glob("*.msg")):
        types.update(get_types_from_msg(f.read_text(), f"twinsense_msgs/msg/{f.stem}"))
    ts.register(types)
    return ts


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("mcap")
    sc = scenario_from_dict(_scenario(), base_dir=ROOT / "examples")
    detections = []  # the radar's detections as captured in the run (the recording keeps the cube only)

    def keep(sensor, frame):
        if sensor.kind == "radar":
            detections.append(frame.detections)

    res = simulate(sc.scene, sc.sensors, sc.duration, out=sc.recording_path(out), seed=sc.seed,
                   scenario=sc.raw, on_frame=keep)
    # The converter rebuilds the scenario (scene and sensors) from the recording, as `twinsense convert` does.
    mcap_path = M.convert(res.path, out / "run.mcap", lambda d: scenario_from_dict(d))
    msgs: dict[str, list] = {}
    with AnyReader([mcap_path], default_typestore=_typestore()) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        for c, log_ns, raw in reader.messages():
            msgs.setdefault(c.topic, []).append((log_ns, reader.deserialize(raw, c.msgtype)))
    return {"h5": res.path, "mcap": mcap_path, "msgs": msgs, "types": types, "scene": sc.scene,
            "detections": detections}


def _ns(t: float) -> int:
    return round(t * 1e9)


def test_docs_msg_files_are_the_embedded_definitions():
    # Field lines of docs/msg/<Name>.msg (comments dropped) are the schema the writer embeds.
    for name, text in M.TWINSENSE_MSGS.items():
        doc = (MSG_DIR / f"{name.rsplit('/', 1)[1]}.msg").read_text()
        fields = "".join(line + "\n" for line in doc.splitlines() if line and not line.startswith("#"))
        assert fields == text, name


def test_every_topic_and_type(run):
    assert run["types"] == {
        "/tf_static": "tf2_msgs/msg/TFMessage", "/tf": "tf2_msgs/msg/TFMessage", "/clock": "rosgraph_msgs/msg/Clock",
        "/depth/camera_info": "sensor_msgs/msg/CameraInfo", "/depth/depth": "sensor_msgs/msg/Image",
        "/depth/range": "sensor_msgs/msg/Image",
        "/tof/camera_info": "sensor_msgs/msg/CameraInfo", "/tof/depth": "sensor_msgs/msg/Image",
        "/tof/amplitude": "sensor_msgs/msg/Image", "/tof/confidence": "sensor_msgs/msg/Image",
        "/tof/points": "sensor_msgs/msg/PointCloud2",
        "/radar/cube": "twinsense_msgs/msg/RadarCube", "/radar/range_doppler": "twinsense_msgs/msg/RangeDoppler",
        "/cap/frame": "twinsense_msgs/msg/CapacitiveFrame",
        "/radar/detections": "sensor_msgs/msg/PointCloud2",
        "/hall/frame": "twinsense_msgs/msg/MagneticFrame", "/hall/magnetic_field": "sensor_msgs/msg/MagneticField",
        "/lidar/points": "sensor_msgs/msg/PointCloud2", "/sonar/frame": "twinsense_msgs/msg/UltrasonicFrame",
        "/prox/frame": "twinsense_msgs/msg/InductiveFrame",
        "/scene_markers": "visualization_msgs/msg/MarkerArray",
    }
    # Two frames per sensor; one static tf message and the scene's geometry once.
    assert {k: len(v) for k, v in run["msgs"].items()} == {
        k: 1 if k in ("/tf_static", "/scene_markers") else 2 for k in run["types"]}


def test_clock_and_stamps_are_the_recording_times(run):
    with open_recording(run["h5"]) as rec:
        times = sorted({_ns(t) for s in rec.sensors.values() for t in s.timestamps})
        depth_t = rec["depth"].timestamps
    clock = [(m.clock.sec * 10**9 + m.clock.nanosec, log) for log, m in run["msgs"]["/clock"]]
    assert [c for c, _ in clock] == times == [log for _, log in clock]
    for k, (log, m) in enumerate(run["msgs"]["/depth/depth"]):
        assert (m.header.stamp.sec, m.header.stamp.nanosec) == divmod(_ns(depth_t[k]), 10**9)
        assert m.header.frame_id == "depth_optical_frame" and log == _ns(depth_t[k])


def _image(m) -> np.ndarray:
    dtype = {"32FC1": "<f4", "mono8": "u1"}[m.encoding]
    a = np.frombuffer(m.data.tobytes(), dtype=dtype)
    assert m.step == m.width * a.itemsize and m.is_bigendian == 0
    return a.reshape(m.height, m.width)


def test_images_are_the_recorded_pixels(run):
    # float32 and uint8 pixels are copied, never computed: equal bit for bit (tolerance 0).
    with open_recording(run["h5"]) as rec:
        for topic, sensor, stream in [("/depth/depth", "depth", "depth"), ("/depth/range", "depth", "range"),
                                      ("/tof/depth", "tof", "depth"), ("/tof/amplitude", "tof", "amplitude"),
                                      ("/tof/confidence", "tof", "confidence")]:
            for k, (_, m) in enumerate(run["msgs"][topic]):
                np.testing.assert_array_equal(_image(m), rec[sensor][stream][k], err_msg=topic)


def test_camera_info(run):
    (_, depth), (_, tof) = run["msgs"]["/depth/camera_info"][0], run["msgs"]["/tof/camera_info"][0]
    with open_recording(run["h5"]) as rec:
        cam = rec["depth"].config["config"]["camera"]
    k = np.array(depth.k).reshape(3, 3)
    np.testing.assert_array_equal(k, [[cam["fx"], 0, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1]])
    assert (depth.width, depth.height, depth.distortion_model) == (64, 48, "plumb_bob")
    np.testing.assert_array_equal(depth.d, [0.0] * 5)
    np.testing.assert_array_equal(np.array(depth.p).reshape(3, 4)[:, :3], k)
    np.testing.assert_array_equal(np.array(depth.r).reshape(3, 3), np.eye(3))
    # The generic ToF preset: 62 x 45 deg on 32 x 24 px, fx = (W / 2) / tan(hfov / 2) and the
    # principal point at the image centre with pixel centres on integers ((W - 1) / 2).
    fx, fy = 16 / math.tan(math.radians(31.0)), 12 / math.tan(math.radians(22.5))
    np.testing.assert_allclose(np.array(tof.k).reshape(3, 3), [[fx, 0, 15.5], [0, fy, 11.5], [0, 0, 1]],
                               rtol=1e-15, atol=0)  # the same double arithmetic, a few ulp at most


def test_tof_point_cloud(run):
    _, m = run["msgs"]["/tof/points"][1]
    assert [(f.name, f.offset, f.datatype, f.count) for f in m.fields] == [
        ("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("intensity", 12, 7, 1)]
    assert (m.height, m.width, m.point_step, m.row_step, m.is_bigendian) == (24, 32, 16, 16 * 32, False)
    pts = np.frombuffer(m.data.tobytes(), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("i", "<f4")])
    pts = pts.reshape(24, 32)
    with open_recording(run["h5"]) as rec:
        xyz, amp = rec["tof"]["points_sensor"][1], rec["tof"]["amplitude"][1]
    got = np.stack([pts["x"], pts["y"], pts["z"]], axis=-1)
    np.testing.assert_array_equal(got, xyz)
    np.testing.assert_array_equal(pts["i"], amp)
    assert m.is_dense == bool(np.isfinite(xyz).all())


def _tf(msgs, parent, child):
    return next(tr for tr in msgs if tr.header.frame_id == parent and tr.child_frame_id == child)


def _rot(q) -> np.ndarray:
    x, y, z, w = q.x, q.y, q.z, q.w
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_sensor_frames_follow_rep_103(run):
    static = run["msgs"]["/tf_static"][0][1].transforms
    link = _tf(static, "world", "depth_link")
    opt = _tf(static, "depth_link", "depth_optical_frame")
    r_link, r_opt = _rot(link.transform.rotation), _rot(opt.transform.rotation)
    # Optical frame: z forward, x right, y down; in the x-forward link frame z_opt = x_link, x_opt = -y_link.
    np.testing.assert_allclose(r_opt, [[0, 0, 1], [-1, 0, 0], [0, -1, 0]], atol=1e-15)
    # The camera looks from EYE at TARGET: the optical z axis in the world is the unit view direction,
    # the link's x axis too; rounding of a unit quaternion is ~1e-16 per entry.
    view = (TARGET - EYE) / np.linalg.norm(TARGET - EYE)
    np.testing.assert_allclose((r_link @ r_opt)[:, 2], view, atol=1e-12)
    np.testing.assert_allclose(r_link[:, 0], view, atol=1e-12)
    # look_at keeps the optical x axis horizontal (up = +z): the link's y axis has no z component.
    assert abs(r_link[2, 1]) < 1e-12
    t = link.transform.translation
    np.testing.assert_array_equal([t.x, t.y, t.z], EYE)
    # Non-optical kinds: one frame at the mount, no rotation here.
    cap = _tf(static, "world", "cap").transform
    assert [cap.translation.x, cap.translation.y, cap.translation.z] == [2.0, 0.0, 1.6]
    assert cap.rotation.w == 1.0


def test_object_frames(run):
    static = run["msgs"]["/tf_static"][0][1].transforms
    wall = _tf(static, "world", "back_wall").transform.translation
    assert [wall.x, wall.y, wall.z] == [4.0, 0.0, 1.5]
    for log, m in run["msgs"]["/tf"]:
        t = log * 1e-9
        cart = _tf(m.transforms, "world", "cart").transform
        # Waypoints (2, -1, 0.25) -> (2, 1, 0.25) at 0.5 m/s: y = -1 + 0.5 t for t < 4 s (closed form);
        # the time is the stamp (exact to 1 ns, i.e. 5e-10 m), the rest is double rounding.
        np.testing.assert_allclose([cart.translation.x, cart.translation.y, cart.translation.z],
                                   [2.0, -1.0 + 0.5 * t, 0.25], rtol=0, atol=1e-9)
        # Yaw 15 deg about z: q = (0, 0, sin 7.5 deg, cos 7.5 deg).
        q = cart.rotation
        np.testing.assert_allclose([q.x, q.y, q.z, abs(q.w)], [0, 0, math.copysign(math.sin(math.radians(7.5)), q.w),
                                                                 math.cos(math.radians(7.5))], rtol=0, atol=1e-12)
        ball = _tf(m.transforms, "world", "ball").transform.translation
        expected = run["scene"].object("ball").pose_at(t).position
        np.testing.assert_allclose([ball.x, ball.y, ball.z], expected, rtol=0, atol=1e-12)


def test_radar_capacitive_and_array_messages(run):
    with open_recording(run["h5"]) as rec:
        radar, cap, hall = rec["radar"], rec["cap"], rec["hall"]
        for k, (_, m) in enumerate(run["msgs"]["/radar/cube"]):
            adc = radar["adc"][k]
            assert (m.n_rx, m.n_chirps, m.n_samples) == adc.shape and len(m.imag) == 0
            # uint16 ADC codes are exact in float32 (24-bit mantissa).
            np.testing.assert_array_equal(m.real.reshape(adc.shape), adc)
            _, rd = run["msgs"]["/radar/range_doppler"][k]
            np.testing.assert_array_equal(rd.power.reshape(rd.n_doppler, rd.n_range), radar["range_doppler_power"][k])
        for k, (_, m) in enumerate(run["msgs"]["/cap/frame"]):
            assert list(m.channels) == cap.config["channels"]
            for field, stream in [("channel_values", "channels"), ("readout", "readout"), ("delta", "delta"),
                                  ("self_capacitance", "self_capacitance")]:
                np.testing.assert_array_equal(getattr(m, field), cap[stream][k])
            np.testing.assert_array_equal(m.maxwell.reshape(m.n_terminals, m.n_terminals), cap["maxwell"][k])
            assert m.header.frame_id == "cap"
        for k, (_, m) in enumerate(run["msgs"]["/hall/frame"]):
            # float64 copies of float64 fields and of int32 codes: exact (tolerance 0).
            n, a = m.n_elements, m.n_axes
            assert (n, a) == hall["field"][k].shape and m.header.frame_id == "hall"
            np.testing.assert_array_equal(m.field_true.reshape(n, 3), hall["field_true"][k])
            np.testing.assert_array_equal(m.field.reshape(n, a), hall["field"][k])
            np.testing.assert_array_equal(m.raw.reshape(n, a), hall["raw"][k].astype(np.float64))
            _, mf = run["msgs"]["/hall/magnetic_field"][k]
            b = mf.magnetic_field
            np.testing.assert_array_equal([b.x, b.y, b.z], hall["field"][k][0])
            assert list(mf.magnetic_field_covariance) == [0.0] * 9


def test_cli_convert_and_errors(run, tmp_path):
    runner = CliRunner()
    res = runner.invoke(app, ["convert", str(run["h5"]), str(tmp_path / "cli.mcap")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "cli.mcap").stat().st_size > 0
    res = runner.invoke(app, ["convert", str(tmp_path / "missing.h5"), str(tmp_path / "x.mcap")])
    assert res.exit_code == 2 and "missing.h5" in res.output
    bad = tmp_path / "bad.h5"
    bad.write_text("not a recording")
    with pytest.raises(TwinsenseError, match="bad.h5"):
        M.convert(bad, tmp_path / "x.mcap")
    with pytest.raises(TwinsenseError, match="out.*.mcap"):
        M.convert(run["h5"], tmp_path / "x.bag")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.h5", "cli.mcap"]


def test_failed_write_leaves_no_file(run, tmp_path, monkeypatch):
    def boom(*args):
        raise RuntimeError("disk full")

    monkeypatch.setattr(M, "_sensor_messages", boom)
    with pytest.raises(RuntimeError, match="disk full"):
        M.convert(run["h5"], tmp_path / "x.mcap")
    assert list(tmp_path.iterdir()) == []


def test_missing_extra_names_it(monkeypatch, tmp_path):
    import sys

    monkeypatch.setitem(sys.modules, "mcap_ros2.writer", None)
    with pytest.raises(ImportError, match=r"'ros2' extra"):
        M.convert(tmp_path / "r.h5", tmp_path / "x.mcap")


def test_negative_time_is_refused():
    with pytest.raises(TwinsenseError, match="timestamp"):
        M.stamp_ns(-0.1)
    assert M.stamp_ns(1.5) == 1_500_000_000


def _cloud(m) -> np.ndarray:
    """A PointCloud2 decoded from its own field table (names, offsets, datatypes), not the writer's."""
    types = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
    dt = np.dtype({"names": [f.name for f in m.fields], "formats": ["<" + types[f.datatype] for f in m.fields],
                   "offsets": [f.offset for f in m.fields], "itemsize": m.point_step})
    assert m.row_step == m.point_step * m.width and not m.is_bigendian
    return np.frombuffer(m.data.tobytes(), dtype=dt).reshape(m.height, m.width)


def test_radar_detections_are_the_runs(run):
    # Detections recomputed from the recorded ADC codes by the rebuilt radar equal those of the run:
    # the same deterministic chain on the same codes; float32 storage of float64 values -> rel 2^-24.
    assert len(run["detections"]) == len(run["msgs"]["/radar/detections"]) == 2
    for det, (_, m) in zip(run["detections"], run["msgs"]["/radar/detections"]):
        assert m.header.frame_id == "radar_link" and m.height == 1 and m.width == len(det.range) > 0
        assert [f.name for f in m.fields] == ["x", "y", "z", "range", "radial_velocity", "snr"]
        c = _cloud(m)[0]
        # REP 103 link frame: x forward = optical z, y left = -optical x, z up = -optical y.
        p = det.points_sensor
        for got, want in [(c["x"], p[:, 2]), (c["y"], -p[:, 0]), (c["z"], -p[:, 1]), (c["range"], det.range),
                          (c["radial_velocity"], det.velocity), (c["snr"], det.snr_db)]:
            np.testing.assert_allclose(got, want, rtol=2**-24, atol=1e-30)
        # A point lies at its range: |p| = r (float32 rounding of 3 coordinates, ~1e-7 relative).
        np.testing.assert_allclose(np.sqrt(c["x"].astype(float) ** 2 + c["y"] ** 2 + c["z"] ** 2), c["range"],
                                   rtol=1e-6, atol=0)


def test_lidar_points_are_the_recorded_echoes(run):
    with open_recording(run["h5"]) as rec:
        lid = rec["lidar"]
        for k, (_, m) in enumerate(run["msgs"]["/lidar/points"]):
            assert [(f.name, f.datatype) for f in m.fields] == [("x", 7), ("y", 7), ("z", 7), ("intensity", 2),
                                                                ("ring", 4), ("time", 7)]
            assert m.header.frame_id == "lidar" and m.is_dense
            c = _cloud(m)[0]
            valid = np.isfinite(lid["range"][k])
            row, echo = np.nonzero(valid)
            assert m.width == valid.sum() > 100
            xyz = lid["xyz"][k][row, echo]
            # float32 points, uint8 intensity and int16 rings are copied: exact.
            np.testing.assert_array_equal(np.stack([c["x"], c["y"], c["z"]], axis=-1), xyz)
            np.testing.assert_array_equal(c["intensity"], lid["intensity"][k][row, echo])
            np.testing.assert_array_equal(c["ring"], lid["ring"][k][row])
            # time: float32 offset from the stamp; offsets < 0.1 s round to <= 2^-24 * 0.1 s ~ 6e-9 s.
            t0 = lid.timestamps[k]
            np.testing.assert_allclose(c["time"] + t0, lid["time"][k][row], rtol=0, atol=1e-8)
            assert c["time"].min() >= 0 and c["time"].max() < 0.1


def test_ultrasonic_and_inductive_frames(run):
    with open_recording(run["h5"]) as rec:
        son, prox = rec["sonar"], rec["prox"]
        for k, (_, m) in enumerate(run["msgs"]["/sonar/frame"]):
            a = son["ascan"][k]
            assert (m.n_transducers, m.n_samples) == a.shape and m.sample_rate == son.config["config"]["sample_rate"]
            # float32 and float64 arrays are copied: exact (NaN where no echo, compared as NaN).
            np.testing.assert_array_equal(m.ascan.reshape(a.shape), a)
            np.testing.assert_array_equal(m.envelope.reshape(a.shape), son["envelope"][k])
            np.testing.assert_array_equal(m.first_echo_distance, son["first_echo_distance"][k])
            np.testing.assert_array_equal(m.fire_time, son["fire_time"][k])
        for k, (_, m) in enumerate(run["msgs"]["/prox/frame"]):
            assert m.output == bool(prox["output"][k][0])
            for f in ("quality", "delta_r", "delta_l", "frequency"):
                assert getattr(m, f) == prox[f][k][0], f


def test_new_kind_through_the_extension_point(run, tmp_path, monkeypatch):
    # A kind without a builder falls back to one ArrayStream per stream; a registered builder (how a
    # tactile array will plug in) with its own message definition replaces the built-in one.
    monkeypatch.delitem(M.KIND_MESSAGES, "ultrasonic")
    monkeypatch.setitem(M.KIND_MESSAGES, "inductive", M.KIND_MESSAGES["inductive"])  # restored afterwards
    monkeypatch.setattr(M, "MSGDEFS", dict(M.MSGDEFS))
    text = "std_msgs/Header header\nfloat64 q\n"

    def quality(name, s, k, ns, frame_id, sensor):
        return [(f"/{name}/q", "demo_msgs/msg/Q", {"header": M._header(ns, frame_id), "q": float(s["quality"][k][0])})]

    M.register_messages("inductive", quality, {"demo_msgs/msg/Q": "# comment lines are fine\n" + text})
    with pytest.raises(TwinsenseError, match="kind"):
        M.register_messages("", quality)
    with pytest.raises(TwinsenseError, match="msgdefs"):
        M.register_messages("inductive", quality, {"Q": text})
    out = M.convert(run["h5"], tmp_path / "x.mcap")
    ts = _typestore()
    ts.register(get_types_from_msg(text, "demo_msgs/msg/Q"))
    with AnyReader([out], default_typestore=ts) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        got = {c.topic: reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()}
    assert types["/sonar/ascan"] == "twinsense_msgs/msg/ArrayStream" and "/sonar/frame" not in types
    assert types["/prox/q"] == "demo_msgs/msg/Q" and "/prox/frame" not in types
    with open_recording(run["h5"]) as rec:
        # The last message of each topic is frame 1; float64 copies: exact.
        assert got["/prox/q"].q == rec["prox"]["quality"][1][0]
        np.testing.assert_array_equal(got["/sonar/fire_time"].data, rec["sonar"]["fire_time"][1])


def test_cli_run_format_mcap(tmp_path):
    # `twinsense run --format mcap` writes the recording and the .mcap beside it; the file decodes.
    d = {"name": "cli", "duration": 0.1, "objects": [
        {"name": "wall", "geometry": {"type": "box", "size": [0.2, 4.0, 3.0]}, "material": "concrete",
         "pose": {"position": [3.0, 0.0, 1.0]}}],
         "sensors": [{"name": "lidar", "kind": "lidar", "preset": "velodyne_vlp16", "frame_rate": 10,
                      "overrides": {"columns": 90}, "mount": {"pose": {"position": [0.0, 0.0, 1.0]}}},
                     {"name": "prox", "kind": "inductive", "preset": "m12_flush", "frame_rate": 10}],
         "outputs": {"recording": "rec.h5"}}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(d))
    res = CliRunner().invoke(app, ["run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "out"),
                                   "--no-progress", "--format", "mcap"])
    assert res.exit_code == 0, res.output
    path = tmp_path / "out" / "rec.mcap"
    assert f"wrote {path}" in res.output
    with AnyReader([path], default_typestore=_typestore()) as reader:
        got = {c.topic: reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()}
    assert set(got) == {"/tf_static", "/clock", "/lidar/points", "/prox/frame", "/scene_markers"}
    (wall,) = got["/scene_markers"].markers  # the wall's 12 triangles, in its own frame
    assert wall.header.frame_id == "wall" and len(wall.points) == 36
    assert got["/lidar/points"].width > 0 and got["/prox/frame"].quality > 0
