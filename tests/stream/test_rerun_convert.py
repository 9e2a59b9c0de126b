"""Rerun .rrd files from recordings, read back with Rerun's own reader (rerun.chunk.RrdReader)
and checked against the HDF5 recording of the same run, the scene's closed-form motions and
the camera intrinsics."""

from __future__ import annotations

import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
import yaml
from rerun.chunk import RrdReader
from typer.testing import CliRunner

from twinsense.cli import app
from twinsense.errors import ConfigError, RecordingError
from twinsense.io.recording import RecordingWriter, open_recording
from twinsense.scenario import scenario_from_dict
from twinsense.scene.scene import Mount
from twinsense.stream import rerun as R

ROOT = Path(__file__).resolve().parents[2]
LOOK = {"look_at": {"eye": [0.0, 0.0, 1.2], "target": [4.0, 0.0, 0.8]}}


def scenario() -> dict:
    """The corridor example with one sensor of every kind except capacitive (its FEM takes seconds;
    the capacitive mapping is checked on a recording written directly below)."""
    d = yaml.safe_load((ROOT / "examples" / "office_depth.yaml").read_text())
    d["duration"] = 0.2  # two frames per sensor at 10 Hz
    d["sensors"] += [
        {"name": "tof", "kind": "tof", "preset": "generic", "frame_rate": 10,
         "overrides": {"width": 32, "height": 24}, "mount": {"pose": LOOK}},
        {"name": "radar", "kind": "radar", "preset": "paper_bgt60tr13c", "frame_rate": 10,
         "overrides": {"render_width": 250, "render_height": 86},  # a coarser scatterer render: faster
         "mount": {"pose": {"look_at": {"eye": [0.0, 0.0, 1.0], "target": [4.0, 0.0, 1.0]}}}},
        {"name": "lidar", "kind": "lidar", "preset": "livox_mid40", "frame_rate": 10,
         "mount": {"pose": {"look_at": {"eye": [0.0, 0.0, 1.0], "target": [4.0, 0.0, 1.0]}}}},
        {"name": "hall", "kind": "magnetic", "preset": "tle493d", "frame_rate": 10,
         "mount": {"pose": {"position": [1.0, 0.0, 0.5]}}},
        {"name": "prox", "kind": "inductive", "preset": "m18_flush", "frame_rate": 10,
         "mount": {"pose": {"position": [2.0, 0.0, 0.8]}}},
        {"name": "us", "kind": "ultrasonic", "preset": "open_40khz", "frame_rate": 10, "mount": {"pose": LOOK}},
        {"name": "rider", "kind": "magnetic", "preset": "tle493d", "frame_rate": 10,
         "mount": {"parent": "ball", "pose": {"position": [0.0, 0.0, 0.25]}}},
    ]
    return d


def read_rrd(path) -> dict[str, list[tuple[int | None, dict]]]:
    """entity path -> [(sim_time [ns] or None when static, {component: value})], in time order."""
    out: dict[str, list] = {}
    with warnings.catch_warnings():
        # A file saved by a gRPC server has no footer; Rerun reads it by a whole-file scan and says so.
        warnings.filterwarnings("ignore", message="RRD file has no footer")
        chunks = RrdReader(path).stream().to_chunks()
    for chunk in chunks:
        b = chunk.to_record_batch()
        names = [n for n in b.schema.names if ":" in n]
        times = (b.column("sim_time").cast(pa.int64()).to_pylist() if "sim_time" in b.schema.names
                 else [None] * b.num_rows)
        for i in range(b.num_rows):
            row = {n: b.column(n)[i].as_py() for n in names if b.column(n)[i].is_valid}
            out.setdefault(chunk.entity_path, []).append((times[i], row))
    for rows in out.values():
        rows.sort(key=lambda r: -1 if r[0] is None else r[0])
    return out


def timed(rows, component):
    return [(t, r[component]) for t, r in rows if t is not None and component in r]


def image(value, fmt, dtype) -> np.ndarray:
    return np.frombuffer(bytes(value[0]), dtype=dtype).reshape(fmt[0]["height"], fmt[0]["width"])


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("rrd")
    sc = scenario_from_dict(scenario(), base_dir=ROOT / "examples")
    res = sc.run(out, progress=False)
    rrd = R.convert(res.path, out / "run.rrd", lambda d: scenario_from_dict(d).scene)
    return {"h5": res.path, "rrd": rrd, "ents": read_rrd(rrd), "scene": sc.scene}


def ns(t: float) -> int:
    return round(t * 1e9)


def test_depth_images_and_timestamps_equal_the_recording(run):
    ents = run["ents"]
    with open_recording(run["h5"]) as rec:
        for name in ("depth", "tof"):
            s = rec[name]
            rows = [r for t, r in ents[f"/world/sensors/{name}/image/depth"] if t is not None]
            times = [t for t, _ in ents[f"/world/sensors/{name}/image/depth"]]
            # Rerun stores durations as integer ns; the recording's float seconds round to the same ns.
            assert times == [ns(t) for t in s.timestamps]
            for k, r in enumerate(rows):
                d = image(r["DepthImage:buffer"], r["DepthImage:format"], np.float32)
                np.testing.assert_array_equal(d, s["depth"][k])  # float32 logged as is: bit-equal
                assert r["DepthImage:meter"] == [1.0]


def test_tof_amplitude_and_world_points(run):
    ents = run["ents"]
    with open_recording(run["h5"]) as rec:
        s = rec["tof"]
        amp = [r for t, r in ents["/world/sensors/tof/image/amplitude"] if t is not None]
        pts = timed(ents["/world/points/tof"], "Points3D:positions")
        assert [t for t, _ in pts] == [ns(t) for t in s.timestamps]
        for k in range(len(s)):
            np.testing.assert_array_equal(image(amp[k]["Image:buffer"], amp[k]["Image:format"], np.float32),
                                          s["amplitude"][k])
            valid = (s["invalid"][k] == 0) & np.isfinite(s["points_world"][k]).all(axis=-1)
            got = np.array(pts[k][1], dtype=np.float32).reshape(-1, 3)
            assert len(got) == valid.sum() > 0
            np.testing.assert_array_equal(got, s["points_world"][k][valid])


def test_lidar_points_are_the_valid_echoes(run):
    with open_recording(run["h5"]) as rec:
        s = rec["lidar"]
        pts = timed(run["ents"]["/world/points/lidar"], "Points3D:positions")
        assert [t for t, _ in pts] == [ns(t) for t in s.timestamps]
        for k in range(len(s)):
            valid = np.isfinite(s["range"][k])
            got = np.array(pts[k][1], dtype=np.float32).reshape(-1, 3)
            assert len(got) == valid.sum() > 0
            np.testing.assert_array_equal(got, s["xyz_world"][k][valid])


def test_pinhole_is_the_camera_intrinsics(run):
    with open_recording(run["h5"]) as rec:
        cam = rec["depth"].config["config"]["camera"]
    (_, row), = run["ents"]["/world/sensors/depth/image"]
    # Rerun stores the 3 x 3 matrix column-major.
    k = np.array(row["Pinhole:image_from_camera"], dtype=np.float64).reshape(3, 3).T
    np.testing.assert_allclose(k, [[cam["fx"], 0, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1]],
                               rtol=1e-6)  # float32 storage: 6e-8 relative
    assert row["Pinhole:resolution"] == [[cam["width"], cam["height"]]]  # one pinhole, (w, h) [px]


def test_radar_range_doppler_in_db(run):
    with open_recording(run["h5"]) as rec:
        s = rec["radar"]
        rows = timed(run["ents"]["/signals/radar/range_doppler_db"], "Tensor:data")
        assert [t for t, _ in rows] == [ns(t) for t in s.timestamps]
        for k, (_, (tensor,)) in enumerate(rows):
            assert tensor["names"] == ["doppler", "range"]
            got = np.array(tensor["buffer"], dtype=np.float32).reshape(tensor["shape"])
            want = (10 * np.log10(np.maximum(s["range_doppler_power"][k].astype(np.float64), 1e-30)))
            np.testing.assert_array_equal(got, want.astype(np.float32))


def test_scalars_of_magnetic_and_inductive(run):
    with open_recording(run["h5"]) as rec:
        for name, stream in (("hall", "field"), ("prox", "quality"), ("prox", "output"), ("us", "first_echo_distance")):
            s = rec[name]
            rows = timed(run["ents"][f"/signals/{name}/{stream}"], "Scalars:scalars")
            assert [t for t, _ in rows] == [ns(t) for t in s.timestamps]
            for k, (_, v) in enumerate(rows):
                np.testing.assert_array_equal(v, np.asarray(s[stream][k], dtype=np.float64).ravel())


def test_moving_object_follows_its_closed_form_motion(run):
    # ball: p(t) = (3, 0.8, 1.0) + (0, 0, 0.1) sin(2 pi t) (oscillation at 1 Hz, examples/office_depth.yaml)
    rows = timed(run["ents"]["/world/objects/ball"], "Transform3D:translation")
    with open_recording(run["h5"]) as rec:
        times = sorted({ns(t) for s in rec.sensors.values() for t in s.timestamps})
    assert [t for t, _ in rows] == times
    for t, p in rows:
        want = [3.0, 0.8, 1.0 + 0.1 * math.sin(2 * math.pi * t * 1e-9)]
        # Rerun stores translations as float32: half an ulp at 3 m is 1.2e-7 m.
        np.testing.assert_allclose(p[0], want, rtol=0, atol=2.5e-7)


def test_meshes_static_and_whole(run):
    ents = run["ents"]
    for obj in run["scene"]:
        rows = ents[f"/world/objects/{obj.name}"]
        mesh = [r for t, r in rows if t is None and "Mesh3D:vertex_positions" in r]
        assert len(mesh) == 1
        assert len(mesh[0]["Mesh3D:vertex_positions"]) == len(obj.geometry.mesh.vertices)
        assert len(mesh[0]["Mesh3D:triangle_indices"]) == len(obj.geometry.mesh.faces)
        static_pose = [r for t, r in rows if t is None and "Transform3D:translation" in r]
        assert len(static_pose) == int(obj.is_static)
    # Every timed entity is on the one timeline and nothing logs wall-clock time.
    for chunk in RrdReader(run["rrd"]).stream().to_chunks():
        assert set(chunk.timeline_names) <= {"sim_time"}


def test_capacitive_channels_as_named_scalars(tmp_path):
    channels = ["a", "b", "c"]
    values = np.array([[1e-12, 2e-12, 3e-12], [1.5e-12, 2.5e-12, 3.5e-12]])
    with RecordingWriter(tmp_path / "cap.h5") as w:
        w.add_sensor("cap", "capacitive", 10.0, {"channels": channels, "mount": {"parent": None}})
        for k, t in enumerate((0.0, 0.1)):
            w.append("cap", t, {"channels": values[k], "delta": values[k] - values[0], "readout": values[k],
                                "self_capacitance": values[k], "maxwell": np.eye(3)})
    ents = read_rrd(R.write_rrd(tmp_path / "cap.h5", tmp_path / "cap.rrd"))
    (_, names), = [(t, r) for t, r in ents["/signals/cap/channels"] if t is None]
    assert names["SeriesLines:names"] == channels
    got = timed(ents["/signals/cap/channels"], "Scalars:scalars")
    assert [t for t, _ in got] == [0, 100_000_000]
    np.testing.assert_array_equal([v for _, v in got], values)


def test_bad_output_and_missing_recording(run, tmp_path):
    with pytest.raises(ConfigError, match="out.*\\.rrd"):
        R.write_rrd(run["h5"], tmp_path / "x.mcap")
    with pytest.raises(ConfigError, match="existing folder"):
        R.write_rrd(run["h5"], tmp_path / "nope" / "x.rrd")
    with pytest.raises(RecordingError, match="not found"):
        R.write_rrd(tmp_path / "missing.h5", tmp_path / "x.rrd")
    assert list(tmp_path.iterdir()) == []  # nothing half-written


def test_cli_convert_by_suffix(run, tmp_path):
    out = tmp_path / "cli.rrd"
    res = CliRunner().invoke(app, ["convert", str(run["h5"]), str(out)])
    assert res.exit_code == 0, res.output
    assert "Rerun" in res.output
    assert read_rrd(out).keys() == run["ents"].keys()


def test_cli_run_format_rrd(tmp_path):
    d = yaml.safe_load((ROOT / "examples" / "office_depth.yaml").read_text())
    d["duration"] = 0.1  # one depth frame
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(d))
    res = CliRunner().invoke(app, ["run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "o"), "--no-progress",
                                   "--format", "rrd"])
    assert res.exit_code == 0, res.output
    ents = read_rrd(tmp_path / "o" / "recording.rrd")
    with open_recording(tmp_path / "o" / "recording.h5") as rec:
        (t, r), = [(t, r) for t, r in ents["/world/sensors/depth/image/depth"] if t is not None]
        assert t == 0
        np.testing.assert_array_equal(image(r["DepthImage:buffer"], r["DepthImage:format"], np.float32),
                                      rec["depth"]["depth"][0])


def test_missing_rerun_names_the_extra(run, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rerun", None)  # as if not installed: import raises ImportError
    with pytest.raises(ConfigError, match=r"pip install 'twinsense\[rerun\]'"):
        R.write_rrd(run["h5"], tmp_path / "x.rrd")
    with pytest.raises(ConfigError, match=r"pip install 'twinsense\[rerun\]'"):
        R.RerunSink(tmp_path / "x.rrd")
    assert list(tmp_path.iterdir()) == []


def test_sensor_on_a_moving_object_follows_it(run):
    # rider sits 0.25 m above the ball's centre; the ball translates only, so the sensor is at
    # (3, 0.8, 1.25 + 0.1 sin(2 pi t)) with the identity rotation.
    rows = [(t, r) for t, r in run["ents"]["/world/sensors/rider"]]
    assert all(t is not None for t, _ in rows)  # no static pose for a sensor that moves
    with open_recording(run["h5"]) as rec:
        assert [t for t, _ in rows] == [ns(t) for t in rec["rider"].timestamps]
    for t, r in rows:
        want = [3.0, 0.8, 1.25 + 0.1 * math.sin(2 * math.pi * t * 1e-9)]
        np.testing.assert_allclose(r["Transform3D:translation"][0], want, rtol=0, atol=2.5e-7)  # float32
        np.testing.assert_allclose(r["Transform3D:quaternion"][0], [0, 0, 0, 1], rtol=0, atol=1e-7)


def test_fixed_sensor_pose_is_static_and_the_recorded_pose(run):
    from twinsense.scene.pose import Pose

    rows = run["ents"]["/world/sensors/tof"]
    assert [t for t, _ in rows] == [None]  # once, static: a fixed mount
    with open_recording(run["h5"]) as rec:
        poses = rec["tof"]["pose"][()]
    for m in poses:  # every frame's recorded sensor -> world pose
        want = Pose.from_matrix(m)
        np.testing.assert_allclose(rows[0][1]["Transform3D:translation"][0], want.position, rtol=0,
                                   atol=2.5e-7)  # float32 storage
        q = np.array(rows[0][1]["Transform3D:quaternion"][0])
        # q and -q are the same rotation; float32 storage: 1e-7 per component.
        assert min(np.abs(q - want.quat_xyzw).max(), np.abs(q + want.quat_xyzw).max()) < 1e-6


def test_robot_links_nest_and_follow_the_joint(tmp_path):
    # A one-joint arm: link "arm" turns about the world z axis at 1 rad/s on a joint 1 m above the
    # base, so its frame is at (0, 0, 1) with the quaternion (0, 0, sin(t/2), cos(t/2)).
    from twinsense.depthcam import DepthCamera
    from twinsense.scene import Pose, Scene
    from twinsense.scene.articulated import ArticulatedBody, Joint, JointConstantVelocity, KinematicTree, Link
    from twinsense.scene.geometry import Box
    from twinsense.simulate import simulate

    tree = KinematicTree("arm", [Link("base", Box((0.2, 0.2, 0.2))),
                                 Link("arm", Box((0.6, 0.1, 0.1)), origin=Pose(position=(0.3, 0.0, 0.0)))],
                         [Joint("j", "revolute", "base", "arm", origin=Pose(position=(0.0, 0.0, 1.0)))])
    scene = Scene()
    ArticulatedBody("bot", tree, JointConstantVelocity([0.0], [1.0])).add_to(scene)
    cam = DepthCamera.preset("generic", name="cam", width=16, height=12,
                             mount=Mount(Pose.look_at((3.0, 0.0, 1.0), (0.0, 0.0, 1.0))))
    res = simulate(scene, [cam], 0.1, out=tmp_path / "r.h5")
    ents = read_rrd(R.write_rrd(res.path, tmp_path / "r.rrd", scene=scene))
    rows = ents["/world/objects/bot/arm"]
    assert sum("Mesh3D:vertex_positions" in r for t, r in rows if t is None) == 1
    poses = [(t, r) for t, r in rows if t is not None]
    assert [t for t, _ in poses] == [ns(k / 30) for k in range(3)]  # the camera at 30 Hz over 0.1 s
    for t, r in poses:
        s = t * 1e-9
        np.testing.assert_allclose(r["Transform3D:translation"][0], [0, 0, 1], rtol=0, atol=2.5e-7)  # float32
        np.testing.assert_allclose(r["Transform3D:quaternion"][0], [0, 0, math.sin(s / 2), math.cos(s / 2)],
                                   rtol=0, atol=1e-7)  # float32 components of a unit quaternion


def test_recording_lacking_what_its_kind_needs(tmp_path):
    # A "camera" recording written by another tool: no intrinsics in its config, no depth stream.
    with RecordingWriter(tmp_path / "odd.h5") as w:
        w.add_sensor("cam", "camera", 10.0, {"mount": {"parent": None}})
        w.append("cam", 0.0, {"gray": np.zeros((4, 4))})
    with pytest.raises(RecordingError, match="cannot convert to Rerun: missing"):
        R.write_rrd(tmp_path / "odd.h5", tmp_path / "odd.rrd")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["odd.h5"]
