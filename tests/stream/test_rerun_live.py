"""The live Rerun sink: frames of a running simulation to an .rrd file and to a real Rerun gRPC
server (the rerun command-line server over loopback), checked against the HDF5 recording of
the same run; frames it cannot take are dropped and counted, never waited for."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from test_rerun_convert import LOOK, ROOT, image, ns, read_rrd, timed

from twinsense.errors import ConfigError
from twinsense.io.recording import open_recording
from twinsense.scenario import scenario_from_dict
from twinsense.simulate import simulate
from twinsense.stream.rerun import RerunSink
from twinsense.stream.sinks import FrameSink


def _scenario(radar: bool = True) -> dict:
    import yaml

    d = yaml.safe_load((ROOT / "examples" / "office_depth.yaml").read_text())
    d["duration"] = 0.2
    if radar:
        d["sensors"] += [{"name": "radar", "kind": "radar", "preset": "paper_bgt60tr13c", "frame_rate": 10,
                          "overrides": {"render_width": 250, "render_height": 86},  # coarser render: faster
                          "mount": {"pose": {"look_at": {"eye": [0.0, 0.0, 1.0], "target": [4.0, 0.0, 1.0]}}}},
                         {"name": "tof", "kind": "tof", "preset": "generic", "frame_rate": 10,
                          "overrides": {"width": 32, "height": 24}, "mount": {"pose": LOOK}}]
    return d


def _run_live(sink: RerunSink, out: Path, radar: bool = True):
    sc = scenario_from_dict(_scenario(radar), base_dir=ROOT / "examples")
    sink.open(sc.scene, sc.sensors)
    try:
        res = simulate(sc.scene, sc.sensors, 0.2, out=out, keep_frames=True,
                       on_frame=lambda s, f: sink.send(s, f.t, f))
    finally:
        sink.close()
    return res


def test_file_sink_holds_the_run(tmp_path):
    sink = RerunSink(tmp_path / "live.rrd", queue_size=256)
    assert isinstance(sink, FrameSink)
    res = _run_live(sink, tmp_path / "run.h5")
    assert sink.dropped == {"depth": 0, "radar": 0, "tof": 0} and sink.error is None
    assert sink.sent == res.frame_counts
    ents = read_rrd(tmp_path / "live.rrd")
    with open_recording(res.path) as rec:
        for name in ("depth", "tof"):
            s = rec[name]
            rows = [(t, r) for t, r in ents[f"/world/sensors/{name}/image/depth"] if t is not None]
            assert [t for t, _ in rows] == [ns(t) for t in s.timestamps]
            for k, (_, r) in enumerate(rows):
                np.testing.assert_array_equal(image(r["DepthImage:buffer"], r["DepthImage:format"], np.float32),
                                              s["depth"][k])
    # Radar detections (live only: the recording keeps the range-Doppler map, not the detections),
    # in the sensor frame, one point per detection of each frame.
    det = timed(ents["/world/sensors/radar/detections"], "Points3D:positions")
    frames = res.frames["radar"]
    assert [t for t, _ in det] == [ns(f.t) for f in frames]
    for (_, pts), f in zip(det, frames):
        np.testing.assert_allclose(np.array(pts).reshape(-1, 3), f.detections.points_sensor,
                                   rtol=0, atol=1e-6)  # float32 storage of points within ~10 m: < 1e-6 m
    assert not list(tmp_path.glob(".*.tmp"))


class _Gauge:
    """A user-defined sensor kind whose frames can be held up in ``streams()`` (a slow consumer)."""

    kind = "gauge"
    frame_rate = 10.0

    def __init__(self):
        self.name = "gauge"
        self.started = threading.Event()
        self.release = threading.Event()

    def config_dict(self) -> dict:
        return {}


class _GaugeFrame:
    def __init__(self, sensor: _Gauge, t: float):
        self.sensor, self.t = sensor, t

    def streams(self) -> dict:
        self.sensor.started.set()
        self.sensor.release.wait()
        return {"value": np.array([self.t])}


def test_send_drops_and_counts_when_behind(tmp_path):
    g = _Gauge()
    sink = RerunSink(tmp_path / "g.rrd", queue_size=2)
    sink.open(None, [g])
    sink.send(g, 0.0, _GaugeFrame(g, 0.0))
    assert g.started.wait(10)  # the logging thread holds frame 0; the queue is empty again
    for k in range(1, 10):
        sink.send(g, k / 10, _GaugeFrame(g, k / 10))  # returns at once: 2 queued, 7 dropped
    assert sink.dropped == {"gauge": 7}
    g.release.set()
    sink.close()
    assert sink.sent == {"gauge": 3}
    got = timed(read_rrd(tmp_path / "g.rrd")["/signals/gauge/value"], "Scalars:scalars")
    assert [t for t, _ in got] == [0, 100_000_000, 200_000_000]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_grpc_client_to_a_real_rerun_server(tmp_path):
    port = _free_port()
    saved = tmp_path / "server.rrd"
    exe = Path(sys.executable).with_name("rerun")
    server = subprocess.Popen([str(exe), "--serve-grpc", "--bind", "127.0.0.1", "--port", str(port),
                               "--save", str(saved)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        for _ in range(300):  # wait until the server accepts connections (a readiness poll, not a timing check)
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            time.sleep(0.05)
        sink = RerunSink(connect=f"rerun+http://127.0.0.1:{port}/proxy")
        res = _run_live(sink, tmp_path / "run.h5", radar=False)
        assert sink.dropped == {"depth": 0} and sink.error is None
    finally:
        server.send_signal(signal.SIGINT)  # the server finishes its .rrd on SIGINT
        try:
            server.wait(30)
        except subprocess.TimeoutExpired:
            os.kill(server.pid, signal.SIGKILL)
            server.wait()
    ents = read_rrd(saved)
    with open_recording(res.path) as rec:
        s = rec["depth"]
        rows = [(t, r) for t, r in ents["/world/sensors/depth/image/depth"] if t is not None]
        assert [t for t, _ in rows] == [ns(t) for t in s.timestamps]
        for k, (_, r) in enumerate(rows):
            np.testing.assert_array_equal(image(r["DepthImage:buffer"], r["DepthImage:format"], np.float32),
                                          s["depth"][k])
    assert "/world/objects/cart" in ents


@pytest.mark.parametrize("kwargs, field", [
    ({}, "RerunSink"),
    ({"serve": True, "grpc_port": 0}, "RerunSink.grpc_port"),
    ({"web_viewer": True, "web_port": "80"}, "RerunSink.web_port"),
    ({"connect": "http://localhost:9876"}, "RerunSink.connect"),
    ({"path": "x.mcap"}, "out"),
    ({"path": "x.rrd", "queue_size": 0}, "RerunSink.queue_size"),
])
def test_bad_options_name_the_field(kwargs, field, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError) as err:
        RerunSink(**kwargs)
    assert err.value.field == field


def _depth_rows(path: Path) -> list:
    """Timed depth rows saved so far by a client that is still writing (a partial file may not parse yet)."""
    try:
        ents = read_rrd(path)
    except Exception:  # the client is half-way through a message: read again later
        return []
    return [(t, r) for t, r in ents.get("/world/sensors/depth/image/depth", []) if t is not None]


def test_grpc_server_keeps_the_run_for_a_late_viewer(tmp_path):
    # serve=True hosts the gRPC server in-process; a viewer connecting after the run still gets
    # every frame (the server keeps them). The viewer here is the rerun command-line client saving
    # what it receives.
    port = _free_port()
    sink = RerunSink(serve=True, grpc_port=port)
    sc = scenario_from_dict(_scenario(radar=False), base_dir=ROOT / "examples")
    sink.open(sc.scene, sc.sensors)
    saved = tmp_path / "client.rrd"
    try:
        res = simulate(sc.scene, sc.sensors, 0.2, out=tmp_path / "run.h5", on_frame=lambda s, f: sink.send(s, f.t, f))
        client = subprocess.Popen([str(Path(sys.executable).with_name("rerun")), sink.url, "--save", str(saved)],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            rows = []
            for _ in range(600):  # until the client has saved both frames (a readiness poll)
                rows = _depth_rows(saved) if saved.exists() else []
                if len(rows) == 2:
                    break
                time.sleep(0.1)
        finally:
            client.send_signal(signal.SIGINT)
            try:
                client.wait(30)
            except subprocess.TimeoutExpired:
                os.kill(client.pid, signal.SIGKILL)
                client.wait()
    finally:
        sink.close()
    with open_recording(res.path) as rec:
        s = rec["depth"]
        assert [t for t, _ in rows] == [ns(t) for t in s.timestamps]
        for k, (_, r) in enumerate(rows):
            np.testing.assert_array_equal(image(r["DepthImage:buffer"], r["DepthImage:format"], np.float32),
                                          s["depth"][k])
