"""ZeroMQ live stream: a real publisher and real subscribers over loopback TCP.

Every frame a subscriber receives is compared with the frame the simulation
captured (the arrays a capturing sink kept on the simulation thread) and
with the HDF5 recording of the same run; a late joiner and a subscriber
that never reads must not disturb the run.
"""

from __future__ import annotations

import sys
import threading
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import yaml
import zmq

from twinsense.errors import ConfigError
from twinsense.io.recording import open_recording
from twinsense.scenario import scenario_from_dict
from twinsense.stream import FrameSink, Subscriber, ZmqSink, frame_arrays, serve
from twinsense.stream.zeromq import decode, frame_topic

ROOT = Path(__file__).resolve().parents[2]
LOOK = {"look_at": {"eye": [0.0, 0.0, 1.0], "target": [4.0, 0.0, 1.0]}}


def scenario(duration: float, sensors: list[dict] | None = None, camera: dict | None = None):
    d = yaml.safe_load((ROOT / "examples" / "office_depth.yaml").read_text())
    d["duration"] = duration
    if camera:
        d["sensors"][0].update(camera)
    d["sensors"] += sensors or []
    return scenario_from_dict(d, base_dir=ROOT / "examples")


class Keep:
    """A sink that keeps what the simulation thread hands over (the reference for the transports)."""

    name = "keep"

    def __init__(self, on_send=None, store: bool = True):
        self.store = store
        self.dropped: dict[str, int] = {}
        self.frames: dict[tuple[str, int], tuple[float, dict]] = {}
        self._k: dict[str, int] = {}
        self.on_send = on_send

    def open(self, scene, sensors):
        self.dropped = {s.name: 0 for s in sensors}

    def send(self, sensor, t, frame):
        k = self._k.get(sensor.name, 0)
        self._k[sensor.name] = k + 1
        if self.store:
            self.frames[sensor.name, k] = (t, frame_arrays(frame))
        if self.on_send is not None:
            self.on_send(sum(self._k.values()))

    def close(self):
        pass


def test_sinks_follow_the_protocol():
    assert isinstance(ZmqSink("tcp://127.0.0.1:*"), FrameSink) and isinstance(Keep(), FrameSink)


def test_every_frame_arrives_with_its_values(tmp_path):
    sc = scenario(0.4, [{"name": "lidar", "kind": "lidar", "preset": "velodyne_vlp16", "frame_rate": 10,
                         "overrides": {"columns": 90}, "mount": {"pose": LOOK}},
                        {"name": "radar", "kind": "radar", "preset": "paper_bgt60tr13c", "frame_rate": 5,
                         "mount": {"pose": LOOK}}])
    # nodrop: a frame the subscriber could not take would be refused and counted, never lost silently.
    sink, keep = ZmqSink("tcp://127.0.0.1:*", hwm=1000, nodrop=True), Keep()
    got, subs = [], []

    def on_open(sinks):
        subs.append(Subscriber(sink.endpoint, timeout=10.0))
        assert sink.wait_for_subscribers(1, timeout=10.0) == 1

    def receive():
        while not subs:
            threading.Event().wait(0.01)
        got.extend(subs[0])

    th = threading.Thread(target=receive)
    th.start()
    res = serve(sc.scene, sc.sensors, sc.duration, [keep, sink], rate=0, out=tmp_path / "r.h5", seed=sc.seed,
                on_open=on_open)
    th.join()
    sub = subs[0]
    sub.close()
    assert res.result.frame_counts == {"depth": 4, "lidar": 4, "radar": 2}
    assert res.dropped["zmq"] == {"depth": 0, "lidar": 0, "radar": 0} and sub.ended
    assert sub.stats == {"sent": {"depth": 4, "lidar": 4, "radar": 2}, "dropped": res.dropped["zmq"], "t": 0.3}
    assert sorted((f.sensor, f.index) for f in got) == sorted(keep.frames)
    assert sub.missed == {"depth": 0, "lidar": 0, "radar": 0}
    with open_recording(tmp_path / "r.h5") as rec:
        for f in got:
            t, arrays = keep.frames[f.sensor, f.index]
            assert f.t == t == rec[f.sensor].timestamps[f.index] and f.kind == rec[f.sensor].kind
            assert list(f.arrays) == list(arrays) and f.header["streams"][0]["name"] == next(iter(arrays))
            for name, a in arrays.items():
                # Raw buffers with their dtype and shape: equal bit for bit (tolerance 0), NaN included.
                assert f.arrays[name].dtype == a.dtype and f.arrays[name].shape == a.shape
                np.testing.assert_array_equal(f.arrays[name], a)
                if not name.startswith("detections."):
                    np.testing.assert_array_equal(f.arrays[name], rec[f.sensor][name][f.index])
    radar = [f for f in got if f.sensor == "radar"]
    assert all(len(f.arrays["detections.range"]) > 0 for f in radar)
    # Detection points lie at their ranges: |p| = r (double rounding only).
    for f in radar:
        np.testing.assert_allclose(np.linalg.norm(f.arrays["detections.points"], axis=1),
                                   f.arrays["detections.range"], rtol=1e-12, atol=0)


def test_topic_filter_late_joiner_and_vanished_client():
    # A paced run (rate 1: 20 frames over 1 s); a subscriber to "depth" only joins after the 5th frame,
    # another one takes two frames and leaves.
    sc = scenario(1.0, [{"name": "depth2", "kind": "camera", "preset": "generic", "frame_rate": 5,
                         "overrides": {"width": 16, "height": 12}, "mount": {"pose": LOOK}}],
                  camera={"frame_rate": 20})
    joined, at_join = threading.Event(), {}

    def join(n):
        if n == 5:  # five frames of both sensors handed over; the 5th has yet to go to the ZeroMQ sink
            at_join.update(keep._k)
            joined.set()

    keep = Keep(on_send=join)
    sink = ZmqSink("tcp://127.0.0.1:*")
    got = []

    def late():
        joined.wait(30)
        with Subscriber(sink.endpoint, topics=["depth"], timeout=10.0) as sub:
            got.extend(sub)
            got.append(sub)

    vanished = []

    def leave_early(sinks):
        def run():
            with Subscriber(sink.endpoint, timeout=10.0) as sub:
                vanished.extend([sub.recv(), sub.recv()])

        threading.Thread(target=run).start()

    th = threading.Thread(target=late)
    th.start()
    res = serve(sc.scene, sc.sensors, sc.duration, [keep, sink], rate=1.0, seed=sc.seed, on_open=leave_early)
    th.join()
    assert len(vanished) == 2 and all(f is not None for f in vanished)
    sub, frames = got[-1], got[:-1]
    assert res.result.frame_counts == {"depth": 20, "depth2": 5} and sub.ended
    # Only "depth" (not "depth2", whose topic starts alike); none of the frames published before it joined,
    # no gap after the first one received.
    assert {f.sensor for f in frames} == {"depth"} and len(frames) >= 5
    idx = [f.index for f in frames]
    assert idx[0] >= at_join["depth"] - 1 >= 3 and idx == list(range(idx[0], 20)) and sub.missed == {"depth": 0}
    for f in frames:
        np.testing.assert_array_equal(f.arrays["depth"], keep.frames["depth", f.index][1]["depth"])


def test_a_client_that_never_reads_costs_frames_not_time_or_memory():
    # 100 frames of 160 x 120 (range, depth float32 and object_id int32: 230 kB each) as fast as possible
    # to a SUB socket that subscribes and never reads, with the smallest queues.
    sc = scenario(1.0, camera={"frame_rate": 100, "overrides": {"width": 160, "height": 120}})
    ctx = zmq.Context()
    stalled = ctx.socket(zmq.SUB)
    stalled.setsockopt(zmq.RCVHWM, 1)
    stalled.setsockopt(zmq.RCVBUF, 4096)
    stalled.setsockopt(zmq.SUBSCRIBE, b"")
    sink = ZmqSink("tcp://127.0.0.1:*", hwm=1, nodrop=True)
    base = []

    def after_warm_up(n):
        # From the 10th frame on (the first captures build the ray-casting caches), memory is measured.
        if n == 10:
            base.append(tracemalloc.get_traced_memory()[0])
            tracemalloc.reset_peak()

    def on_open(sinks):
        stalled.connect(sink.endpoint)
        assert sink.wait_for_subscribers(1, timeout=10.0) == 1

    tracemalloc.start()
    try:
        res = serve(sc.scene, sc.sensors, sc.duration, [Keep(after_warm_up, store=False), sink], rate=0, seed=sc.seed,
                    on_open=on_open)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
        stalled.close(0)
        ctx.term()
    assert res.result.frame_counts == {"depth": 100}
    assert res.sent["zmq"]["depth"] + res.dropped["zmq"]["depth"] == 100
    # The kernel's socket buffers take a few frames, then every frame is refused and counted.
    assert res.dropped["zmq"]["depth"] > 50
    # Held frames are bounded by the queues, not by the run. A queue without bound would grow by the 90
    # frames after the warm-up, 90 x 230 kB = 20.7 MB. The bound: one capture's working memory
    # (~170 B/pixel = 3.3 MB) plus a few frames in flight, 8 MB.
    assert peak - base[0] < 8e6 < 90 * 160 * 120 * 12, (peak, base)


def test_decode_rejects_a_short_message_and_bad_addresses():
    header = (b'{"sensor": "s", "kind": "k", "t": 0.0, "index": 0, '
              b'"streams": [{"name": "a", "dtype": "<f4", "shape": [2]}]}')
    f = decode([frame_topic("s"), header, np.array([1.0, 2.0], dtype="<f4").tobytes()])
    np.testing.assert_array_equal(f.arrays["a"], [1.0, 2.0])
    with pytest.raises(ConfigError, match="parts"):
        decode([frame_topic("s"), header])
    with pytest.raises(ConfigError, match="ZmqSink.address"):
        ZmqSink("127.0.0.1:5555")
    with pytest.raises(ConfigError, match="Subscriber.topics"):
        Subscriber("tcp://127.0.0.1:1", topics="depth")
    with pytest.raises(ConfigError, match="ZmqSink.hwm"):
        ZmqSink("tcp://127.0.0.1:*", hwm=0)
    # A port in use is refused with the endpoint named, before anything runs.
    a = ZmqSink("tcp://127.0.0.1:*")
    a.open(None, [])
    try:
        with pytest.raises(ConfigError, match="ZmqSink.address"):
            ZmqSink(a.endpoint).open(None, [])
    finally:
        a.close()
    # libzmq would take a port modulo 65536 (70000 -> 4464); it is refused instead.
    with pytest.raises(ConfigError, match="port 1..65535"):
        ZmqSink("tcp://127.0.0.1:70000")


def test_missing_extra_names_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "zmq", None)
    with pytest.raises(ImportError, match=r"twinsense\[stream\]"):
        Subscriber("tcp://127.0.0.1:5555")


def test_serve_warns_that_a_scenario_s_processes_are_not_used():
    # A served run captures in one process (its servers' threads and sockets must not be forked):
    # a scenario asking for 2 capture processes still runs, with a warning naming the key.
    from twinsense.stream import serve_scenario

    d = yaml.safe_load((ROOT / "examples" / "office_depth.yaml").read_text())
    d.update(duration=0.2, processes=2)
    sc = scenario_from_dict(d, base_dir=ROOT / "examples")
    assert sc.processes == 2
    keep = Keep()
    with pytest.warns(UserWarning, match="processes: 2 is not used by serve"):
        res = serve_scenario(sc, [keep], rate=0)
    assert res.result.frame_counts == {"depth": 2}
