"""The scene's geometry on the Foxglove stream (``/scene``, foxglove.SceneUpdate), read by real WebSocket
clients over loopback (the protocol client of test_foxglove_stream, decoding the protobuf schema the
server advertises).

Checked against the scene itself: one entity per object, in the frame /tf publishes for it, the mesh's
vertices and faces value for value (float64 copied into double fields, tolerance 0), boxes as cubes of
their edge lengths; a client joining late gets the scene too, and an added object is sent again.
"""

from __future__ import annotations

import base64
import copy
import json
import struct
import threading
from pathlib import Path

import numpy as np
import trimesh
from test_foxglove_stream import _decoder, handle_text, serve_with_client, subscribing_client
from websockets.sync.client import connect

from scene_dicts import FLANGE_HALL, OBJECTS
from twinsense.io.mcap import MATERIAL_COLORS, OTHER_COLOR
from twinsense.scenario import scenario_from_dict
from twinsense.scene import Box, Cylinder, Pose, Scene, SceneObject, Sphere, TriangleMesh
from twinsense.scene.materials import Material
from twinsense.stream import FoxgloveSink
from twinsense.stream.foxglove_ws import SCENE_MESSAGE_BYTES, pack_scene

ROOT = Path(__file__).resolve().parents[2]


def _scenario():
    """A floor, a crate (box), a rolling ball and a UR5 whose joints move, a magnetic sensor on its flange."""
    return scenario_from_dict({
        "name": "fox_scene", "duration": 10.0, "seed": 2,
        "objects": copy.deepcopy(OBJECTS),
        "robots": [{"name": "ur5", "description": "ur5", "base": {"position": [0.0, 0.0, 0.8]},
                    "joints": {"keyframes": {"times": [0.0, 10.0],
                                             "values": [[0.0, -1.57, 1.57, -1.57, -1.57, 0.0],
                                                        [0.5, -1.30, 1.45, -1.72, -1.57, 0.3]]}}}],
        "sensors": copy.deepcopy(FLANGE_HALL),
    }, base_dir=ROOT / "examples")


def check_scene(update, scene: Scene) -> None:
    """``update`` (a decoded SceneUpdate) is ``scene``'s geometry, object for object."""
    assert len(update.deletions) == 0
    assert [e.id for e in update.entities] == [o.name for o in scene.objects]
    for e, obj in zip(update.entities, scene.objects, strict=True):
        assert e.frame_id == obj.name and e.frame_locked and (e.lifetime.seconds, e.lifetime.nanos) == (0, 0)
        assert {kv.key: kv.value for kv in e.metadata} == {"material": obj.material.name, "geometry": obj.geometry.kind}
        # The palette's values, through float64 fields: equal.
        (prim,) = list(e.cubes) + list(e.triangles)
        assert [prim.color.r, prim.color.g, prim.color.b, prim.color.a] == list(
            MATERIAL_COLORS.get(obj.material.name, OTHER_COLOR))
        p, q = prim.pose.position, prim.pose.orientation
        assert [p.x, p.y, p.z, q.x, q.y, q.z, q.w] == [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
        if isinstance(obj.geometry, Box):
            assert len(e.triangles) == 0 and [prim.size.x, prim.size.y, prim.size.z] == list(obj.geometry.size)
            continue
        mesh = obj.geometry.mesh
        pts = np.array([[v.x, v.y, v.z] for v in prim.points])
        # The mesh the sensors see, in the object's frame: vertices and faces equal (tolerance 0).
        assert pts.shape == mesh.vertices.shape and len(e.cubes) == 0 and len(prim.colors) == 0
        np.testing.assert_array_equal(pts, mesh.vertices)
        np.testing.assert_array_equal(np.asarray(prim.indices).reshape(-1, 3), mesh.faces)


def test_the_scene_reaches_a_client_in_the_frames_of_tf():
    sc = _scenario()
    wanted = ("/scene", "/tf")
    got, ready, seen = {}, threading.Event(), {}
    sink = FoxgloveSink(port=0)
    # The UR5 cell's scene is 2.5 MB: several messages, each within websockets' default 1 MiB frame limit.
    ids = [o.name for o in sc.scene.objects]
    _, stopped = serve_with_client(sc, [sink], sink, subscribing_client, (got, ready, seen, wanted, ids, 2**20),
                                   wanted)
    assert stopped, sorted(got)
    _, ch, update = got["/scene"]
    assert ch["schemaName"] == "foxglove.SceneUpdate" and ch["encoding"] == "protobuf"
    names = {o.name for o in sc.scene.objects}
    assert {"floor", "crate", "ball", "ur5/base_link", "ur5/wrist_3_link"} <= names
    check_scene(update, sc.scene)
    _, _, tf = got["/tf"]
    # Every entity's frame is a frame /tf publishes (static objects and moving links alike), a child of world.
    parents = {x.child_frame_id: x.parent_frame_id for x in tf.transforms}
    assert all(parents.get(e.frame_id) == "world" for e in update.entities)


class _Probe:
    """A sensor of a kind without its own topics: its frames go to /probe/frame as JSON."""

    name, kind = "probe", "probe"


class _Frame:
    def streams(self):
        return {"v": np.zeros(1)}


def collecting_client(port: int, topics, out: list, ready: threading.Event, stop: threading.Event) -> None:
    """Subscribes to ``topics`` and appends every decoded message to ``out`` as (topic, log ns, message)."""
    subs: dict = {}
    with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"], open_timeout=10, max_size=None) as ws:
        ready.set()
        while not stop.is_set():
            try:
                msg = ws.recv(timeout=0.05)
            except TimeoutError:
                continue
            if isinstance(msg, str):
                handle_text(ws, json.loads(msg), subs, topics)
                continue
            _, sid, log_ns = struct.unpack_from("<BIQ", msg)
            ch = subs[sid]
            body = json.loads(msg[13:]) if ch["encoding"] == "json" else _decoder(ch).FromString(msg[13:])
            out.append((ch["topic"], log_ns, body))


def _wait(pred, what: str, timeout: float = 10.0) -> None:
    ev = threading.Event()
    for _ in range(int(timeout / 0.02)):
        if pred():
            return
        ev.wait(0.02)
    raise AssertionError(f"timed out waiting for {what}")


def test_a_late_client_gets_the_scene_and_an_added_object_is_sent_again():
    scene = Scene()
    scene.add_object("floor", Box((4.0, 4.0, 0.01)), material="concrete", pose=Pose(position=(0.0, 0.0, -0.005)))
    scene.add_object("ball", Sphere(0.1), material="plastic", pose=Pose(position=(1.0, 0.0, 0.5)))
    sink = FoxgloveSink(port=0)
    sink.open(scene, [_Probe()])
    a_msgs, a_ready, a_stop = [], threading.Event(), threading.Event()
    a = threading.Thread(target=collecting_client, args=(sink.port, ("/scene", "/tf"), a_msgs, a_ready, a_stop))
    a.start()
    threads = [a]
    try:
        assert a_ready.wait(10)
        # Sent when the client subscribes, before any frame.
        _wait(lambda: any(t == "/scene" for t, _, _ in a_msgs), "the scene on subscription")
        # /tf is advertised with its first message: the client subscribes then, and gets the later ones.
        sink.send(_Probe(), 0.0, _Frame())
        _wait(lambda: sink.subscribed == 2, "the subscription to /tf")
        for k in (1, 2):
            sink.send(_Probe(), k * 0.1, _Frame())
        _wait(lambda: any(t == "/tf" and ns == round(0.2e9) for t, ns, _ in a_msgs), "/tf at 0.2 s")
        # Not again with the frames: only on subscription (and on a change).
        assert [t for t, _, _ in a_msgs].count("/scene") == 1

        lamp = scene.add_object("lamp", Cylinder(0.05, 0.3), material="brass", pose=Pose(position=(0.0, 1.0, 0.15)))
        sink.send(_Probe(), 0.3, _Frame())
        _wait(lambda: [t for t, _, _ in a_msgs].count("/scene") == 2, "the scene again after the change")
        scenes = [(ns, m) for t, ns, m in a_msgs if t == "/scene"]
        check_scene(scenes[0][1], Scene(scene.objects[:2]))
        assert scenes[1][0] == round(0.3e9)  # logged at the frame time of the change
        check_scene(scenes[1][1], scene)
        _wait(lambda: any(t == "/tf" and ns == round(0.3e9) for t, ns, _ in a_msgs), "/tf at 0.3 s")
        tf = next(m for t, ns, m in a_msgs if t == "/tf" and ns == round(0.3e9))
        assert "lamp" in {x.child_frame_id for x in tf.transforms}  # the new object's frame joins /tf
        assert lamp.name == scenes[1][1].entities[-1].frame_id

        # A client joining now gets the scene as it is (latched), not only frames from now on.
        got, ready = {}, threading.Event()
        b = threading.Thread(target=subscribing_client, args=(sink.port, got, ready, {}, ("/scene",),
                                                              [o.name for o in scene.objects], 2**20))
        b.start()
        threads.append(b)
        b.join(20)
        assert "/scene" in got
        check_scene(got["/scene"][2], scene)
    finally:
        a_stop.set()
        for th in threads:
            th.join(20)
        sink.close()
    assert sink.error is None


def test_clients_subscribing_together_all_get_the_scene():
    # Subscriptions within SCENE_RESEND_INTERVAL of a send are served together at its end: none is lost.
    scene = Scene()
    scene.add_object("ball", Sphere(0.1), material="copper", pose=Pose(position=(1.0, 0.0, 0.5)))
    # A user's material, not in the palette: OTHER_COLOR.
    paint = Material("my_paint", 0.3, 0.1, False, 0.05, 0.2, 3.0, "none")
    scene.add_object("post", Cylinder(0.02, 1.0), material=paint, pose=Pose(position=(0.0, 1.0, 0.5)))
    sink = FoxgloveSink(port=0)
    sink.open(scene, [])
    gots = [{} for _ in range(4)]
    threads = [threading.Thread(target=subscribing_client, args=(sink.port, g, threading.Event(), {}, ("/scene",)))
               for g in gots]
    try:
        for th in threads:
            th.start()
        for th in threads:
            th.join(20)
    finally:
        sink.close()
    for g in gots:
        check_scene(g["/scene"][2], scene)


def _ball(name: str, x: float, subdivisions: int) -> SceneObject:
    """An icosphere of radius 0.2 m (subdivisions 5: 20,480 triangles, a 0.55 MB entity)."""
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=0.2)
    return SceneObject(name, TriangleMesh(m.vertices, m.faces), "plastic", Pose(position=(x, 0.0, 0.5)))


def test_a_scene_over_1_mib_reaches_a_client_with_the_default_frame_limit():
    # Three 0.55 MB meshes (1.6 MB): as one message, a client with websockets' default limit (2**20 bytes)
    # closed the connection (1009, message too big) and got no scene and no other topic; now each message
    # is at most SCENE_MESSAGE_BYTES and together they are the scene, entity for entity.
    scene = Scene([_ball(f"ball{i}", float(i), 5) for i in range(3)])
    sink = FoxgloveSink(port=0)
    sink.open(scene, [])
    got = {}
    client = threading.Thread(target=subscribing_client, args=(sink.port, got, threading.Event(), {}, ("/scene",),
                                                               [o.name for o in scene.objects], 2**20))
    try:
        client.start()
        client.join(20)
    finally:
        sink.close()
    assert "/scene" in got
    check_scene(got["/scene"][2], scene)


def test_scene_messages_pack_entities_up_to_the_limit():
    # Independent of the server: the packed messages parse, with protobuf's own decoder of foxglove's
    # schema, as SceneUpdates whose entities are the scene's in order; sizes within the limit except an
    # entity larger than it, alone.
    import foxglove
    import foxglove.messages as fm

    schema = fm.SceneUpdate.get_schema()
    decode = _decoder({"schema": base64.b64encode(schema.data).decode(), "schemaName": schema.name}).FromString
    scene = Scene([_ball("big", 0.0, 6), _ball("a", 1.0, 4), _ball("b", 2.0, 4), _ball("c", 3.0, 5)])
    sink = FoxgloveSink(port=0)
    sink._fg, sink._m = foxglove, fm
    parts = [fm.SceneUpdate(entities=[sink._entity(o, 0)]).encode() for o in scene.objects]
    sizes = [len(p) for p in parts]
    assert sizes[0] > SCENE_MESSAGE_BYTES > sizes[1] + sizes[2] + sizes[3] > sizes[3] > SCENE_MESSAGE_BYTES / 2
    msgs = pack_scene(parts)
    assert [len(m) for m in msgs] == [sizes[0], sizes[1] + sizes[2] + sizes[3]]
    merged = decode(msgs[0])
    merged.MergeFromString(msgs[1])
    assert [e.id for e in decode(msgs[1]).entities] == ["a", "b", "c"]
    check_scene(merged, scene)
    assert pack_scene([]) == ()
    small = pack_scene(parts[1:], limit=sizes[1] + sizes[2])
    assert [len(m) for m in small] == [sizes[1] + sizes[2], sizes[3]]


def test_a_person_and_mujoco_bodies_in_the_frames_of_tf():
    # Scenes the other tests do not use: a clothed person (skin and clothing segments, the clothing on
    # the optical sensors' layers only: drawn all the same, the user sees the scene), a MuJoCo model (its
    # world body's geoms and infinite plane as the object "world", the root of /tf; a free body named with
    # a space) and a plane. Entities: the meshes value for value; frames: those /tf publishes (or world).
    import mujoco

    from twinsense.robots.mujoco_cosim import MujocoCosim
    from twinsense.scene.human import add_person

    xml = """<mujoco><worldbody><geom type="plane" size="0 0 0.1"/>
             <geom type="cylinder" size="0.05 0.3" pos="1 0 0.3"/>
             <body name="ball body" pos="0 0 1"><freejoint/><geom type="sphere" size="0.1"/>
             <geom type="box" size="0.1 0.1 0.1" pos="0.2 0 0"/></body></worldbody></mujoco>"""
    cosim = MujocoCosim(mujoco.MjModel.from_xml_string(xml))
    scene = cosim.scene
    add_person(scene, "alice", position=(2.0, 0.0), clothing="fabric")
    names = [o.name for o in scene.objects]
    assert names[:2] == ["world", "ball body"] and "alice/thorax_clothing" in names
    assert "radar" not in scene.object("alice/thorax_clothing").layers
    sink = FoxgloveSink(port=0)
    sink.open(scene, [_Probe()])
    msgs, ready, stop = [], threading.Event(), threading.Event()
    client = threading.Thread(target=collecting_client, args=(sink.port, ("/scene", "/tf"), msgs, ready, stop))
    client.start()
    try:
        assert ready.wait(10)
        _wait(lambda: any(t == "/scene" for t, _, _ in msgs), "the scene")
        # /tf is advertised with its first message: new frame times until the client has one.
        for k in range(40):
            sink.send(_Probe(), 0.1 * k, _Frame())
            if any(t == "/tf" for t, _, _ in msgs):
                break
            threading.Event().wait(0.05)
        _wait(lambda: any(t == "/tf" for t, _, _ in msgs), "/tf")
    finally:
        stop.set()
        client.join(20)
        sink.close()
    # 2.0 MB (21 + 21 + 2 entities): three messages, each within the limit, together the scene.
    ups = [m for t, _, m in msgs if t == "/scene"]
    assert len(ups) == 3 and all(u.ByteSize() <= SCENE_MESSAGE_BYTES for u in ups)
    update = ups[0]
    for u in ups[1:]:
        update.MergeFromString(u.SerializeToString())
    check_scene(update, scene)
    tf = next(m for t, _, m in msgs if t == "/tf")
    parents = {x.child_frame_id: x.parent_frame_id for x in tf.transforms}
    assert "world" not in parents  # the root: no world -> world loop
    assert all(parents.get(e.frame_id) == "world" for e in update.entities if e.frame_id != "world")
