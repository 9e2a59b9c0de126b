"""A replayed real radar streams like a simulated one: a real ZeroMQ publisher and subscriber over loopback."""

from __future__ import annotations

import threading

import numpy as np

from twinsense import Scene
from twinsense.data import bgt60_radar_npy
from twinsense.radar import make_radar
from twinsense.radar.replay import ReplayRadar
from twinsense.stream import Subscriber, ZmqSink, serve


def test_replay_and_simulation_stream_side_by_side(tmp_path):
    real = ReplayRadar("bgt60tr13c_napas", name="real")
    sim = make_radar("infineon_bgt60tr13c", name="sim")
    sink = ZmqSink("tcp://127.0.0.1:*", hwm=1000, nodrop=True)
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
    res = serve(Scene(), [real, sim], 3 / real.frame_rate, [sink], rate=0, out=tmp_path / "r.h5", seed=0,
                on_open=on_open)
    th.join()
    subs[0].close()
    recorded = np.load(bgt60_radar_npy())
    frames = sorted((f for f in got if f.sensor == "real"), key=lambda f: f.index)
    assert [f.index for f in frames] == [0, 1, 2] and res.dropped["zmq"]["real"] == 0
    for f in frames:
        # The recorded codes arrive bit for bit, at the shared clock's times.
        np.testing.assert_array_equal(f.arrays["adc"], recorded[f.index])
        assert f.t == f.index / real.frame_rate and f.kind == "radar"
    assert any(f.sensor == "sim" for f in got)
