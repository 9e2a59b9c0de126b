"""The Foxglove stream of a robot run: every frame of /tf chains to world (the flange a sensor hangs
from included) and /<body>/joint_states carries the body's joint values; read by a real WebSocket
client over loopback, as in test_foxglove_stream."""

from __future__ import annotations

import threading

import numpy as np
from test_foxglove_stream import serve_with_client, subscribing_client
from ur5_flange import ur5_flange_scenario

from twinsense.stream import FoxgloveSink

WANTED = ("/tf", "/ur5/joint_states")


def _scenario():
    return ur5_flange_scenario("fox_tf", 10.0, 10.0, seed=1)


def test_flange_frame_and_joint_states_on_the_stream():
    sc = _scenario()
    got, ready = {}, threading.Event()
    sink = FoxgloveSink(port=0)
    _, stopped = serve_with_client(sc, [sink], sink, subscribing_client, (got, ready, {}, WANTED), WANTED)
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
