"""The Foxglove stream of a robot run: every frame of /tf chains to world (the flange a sensor hangs
from included) and /<body>/joint_states carries the body's joint values; read by a real WebSocket
client over loopback, as in test_foxglove_stream."""

from __future__ import annotations

import json
import struct
import threading
from pathlib import Path

import numpy as np
from test_foxglove_stream import _decoder, resubscribe_if_unknown, serve_with_client
from websockets.sync.client import connect

from twinsense.scenario import scenario_from_dict
from twinsense.stream import FoxgloveSink

ROOT = Path(__file__).resolve().parents[2]
WANTED = ("/tf", "/ur5/joint_states")


def _scenario():
    return scenario_from_dict({
        "name": "fox_tf", "duration": 10.0, "seed": 1,
        "robots": [{"name": "ur5", "description": "ur5", "base": {"position": [0.0, 0.0, 0.8]},
                    "joints": {"keyframes": {"times": [0.0, 10.0],
                                             "values": [[0.0, -1.57, 1.57, -1.57, -1.57, 0.0],
                                                        [0.5, -1.30, 1.45, -1.72, -1.57, 0.3]]}}}],
        "sensors": [{"name": "hall", "kind": "magnetic", "preset": "tle493d", "frame_rate": 10,
                     "mount": {"parent": "ur5/tool0", "pose": {"position": [0.0, 0.0, 0.02]}}}],
    }, base_dir=ROOT / "examples")


def _client(port: int, got: dict, ready: threading.Event) -> None:
    subs = {}
    with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"], open_timeout=10) as ws:
        ready.set()
        while not all(t in got for t in WANTED):
            msg = ws.recv(timeout=10)
            if isinstance(msg, str):
                m = json.loads(msg)
                resubscribe_if_unknown(ws, m, subs)
                if m["op"] == "advertise":
                    for ch in m["channels"]:
                        if ch["topic"] in WANTED:
                            subs[len(subs) + 1] = ch
                            ws.send(json.dumps({"op": "subscribe",
                                                "subscriptions": [{"id": len(subs), "channelId": ch["id"]}]}))
                continue
            op, sid, log_ns = struct.unpack_from("<BIQ", msg)  # message data: opcode, subscription, log time
            assert op == 1
            ch = subs[sid]
            body = json.loads(msg[13:]) if ch["encoding"] == "json" else _decoder(ch).FromString(msg[13:])
            got.setdefault(ch["topic"], (log_ns, ch, body))


def test_flange_frame_and_joint_states_on_the_stream():
    sc = _scenario()
    got, ready = {}, threading.Event()
    sink = FoxgloveSink(port=0)
    _, stopped = serve_with_client(sc, [sink], sink, _client, (got, ready), WANTED)
    assert stopped
    assert set(got) == set(WANTED)
    body = sc.scene.articulated_bodies[0]

    log_ns, ch, tf = got["/tf"]
    assert ch["schemaName"] == "foxglove.FrameTransforms"
    parent = {x.child_frame_id: x.parent_frame_id for x in tf.transforms}
    for frame in parent:  # every frame of the message chains to world within it
        seen = set()
        while frame != "world":
            assert frame not in seen and frame in parent, frame
            seen.add(frame)
            frame = parent[frame]
    assert parent["hall"] == "ur5/tool0" and parent["ur5/tool0"] == "world"
    t = round(log_ns / 1e8) / 10  # the frame time k / 10 s the run used (10 Hz)
    tool0 = next(x for x in tf.transforms if x.child_frame_id == "ur5/tool0")
    want = sc.scene.mount_target("ur5/tool0").pose_at(t)
    # float64 values copied into double fields: equal (tolerance 0).
    np.testing.assert_array_equal([tool0.translation.x, tool0.translation.y, tool0.translation.z], want.position)
    q = tool0.rotation
    np.testing.assert_array_equal([q.x, q.y, q.z, q.w], want.quat_xyzw)

    log_ns, ch, js = got["/ur5/joint_states"]
    assert ch["encoding"] == "json"
    stamp = js["header"]["stamp"]
    assert stamp["sec"] * 10**9 + stamp["nanosec"] == log_ns and js["header"]["frame_id"] == "ur5/world"
    q, qd = body.joint_state(round(log_ns / 1e8) / 10)
    assert js["name"] == list(body.tree.joint_names) and js["effort"] == []
    # JSON writes a double's shortest round-trip form: read back bit for bit (tolerance 0).
    np.testing.assert_array_equal(js["position"], q)
    np.testing.assert_array_equal(js["velocity"], qd)
    assert np.any(np.asarray(qd) != 0)  # mid-move: the velocities are the keyframe spline's, not zeros
