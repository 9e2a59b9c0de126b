"""Live frames to Foxglove: a WebSocket server (foxglove-sdk, the ``stream`` extra).

Topics use Foxglove's built-in message types, so the app shows them
without set-up (frames and layouts as in docs/streaming.md):

==============================  ====================  ==========================================
topic                           type                  content
==============================  ====================  ==========================================
``/tf``                         FrameTransforms       sensor frames (REP 103, as in the MCAP
                                                      output), scene objects and mount frames
                                                      (robot flanges, sites) at each frame time
``/scene``                      SceneUpdate           the scene's geometry: one entity per object in
                                                      its own /tf frame (frame-locked), latched: sent
                                                      as a client subscribes (sends at least
                                                      SCENE_RESEND_INTERVAL apart), again when
                                                      objects are added; in messages of at most
                                                      SCENE_MESSAGE_BYTES (entities packed in order)
``/<body>/joint_states``        JSON                  robots, people: sensor_msgs/JointState's
                                                      fields (header, name, position, velocity,
                                                      effort) at each frame time
``/<s>/depth``                  RawImage ``32FC1``    camera, ToF: depth [m]
``/<s>/amplitude``              RawImage ``32FC1``    ToF: amplitude [DN]
``/<s>/camera_info``            CameraCalibration     camera, ToF
``/<s>/points``                 PointCloud            ToF (x, y, z, intensity), LiDAR (x, y, z,
                                                      intensity, ring, time)
``/<s>/detections``             PointCloud            radar: x, y, z (``<s>_link``, REP 103),
                                                      range, radial_velocity, snr [dB]
``/<s>/range_doppler``          RawImage ``32FC1``    radar: power [dB], rows Doppler, columns range
``/<s>/maxwell``                RawImage ``32FC1``    capacitive: Maxwell matrix [F]
``/<s>/frame``                  JSON                  capacitive channels; ultrasonic, magnetic,
                                                      inductive and other kinds: their streams
``/twinsense/stats``            JSON                  frames sent and dropped per sensor
==============================  ====================  ==========================================

Stamps and log times are the simulation time (ns from 0). The server
keeps a bounded backlog per client (the oldest message goes first when a
client is slow); in front of it, frames wait in this sink's bounded
queue for the sender thread that converts them, and are dropped and
counted when it is full.
"""

from __future__ import annotations

import json
import threading
import time
from typing import Any

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.io.mcap import (
    WORLD_FRAME,
    body_frame,
    camera_info,
    lidar_columns,
    material_color,
    pack_columns,
    radar_detection_columns,
    scene_transforms,
    sensor_frame,
    stamp_ns,
    static_sensor_transforms,
)
from twinsense.scene.geometry import Box
from twinsense.stream.sinks import QUEUE_SIZE, QueuedSink

#: Messages the server holds per client before it drops the oldest.
BACKLOG = 256
#: Streams of at most this many values go into a kind's JSON ``/<s>/frame`` message.
MAX_JSON_VALUES = 16384
#: [s] Wall time between ``/twinsense/stats`` messages.
STATS_INTERVAL = 1.0
#: [s] How long closing waits, when a client is subscribed, for the server to hand over the last messages
#: (stopping the server discards what its client queues still hold).
LINGER = 0.25
# dB maps: 10 log10 of zero would be -inf.
_DB_FLOOR = 1e-30
#: The topic of the scene's geometry (``foxglove.SceneUpdate``).
SCENE_TOPIC = "/scene"
#: [s] Shortest time between two sends of the scene for subscribing clients: those subscribing sooner are
#: served together at its end, so clients subscribing in a burst (or one resubscribing in a loop) cannot
#: fill the others' backlogs with copies of a multi-megabyte message.
SCENE_RESEND_INTERVAL = 0.5
#: [bytes] Most a /scene message holds: entities are packed into SceneUpdates of at most this size (an entity
#: larger than it goes alone), so that clients with a frame limit of 1 MiB (2**20 bytes, e.g. Python's
#: ``websockets`` by default) take them; 1,000,000 leaves 48,576 bytes for the 13-byte message header.
SCENE_MESSAGE_BYTES = 1_000_000


def require_foxglove():
    """The ``foxglove`` module, or an ImportError naming the extra that installs it."""
    try:
        import foxglove
        import foxglove.messages
    except ImportError as err:
        raise ImportError("the Foxglove server needs the optional 'stream' extra: "
                          "pip install 'twinsense[stream]' (foxglove-sdk, pyzmq)") from err
    return foxglove


class _TimeState(list):
    """The moving items' transforms at one time, [(parent, child, pose)], and the articulated bodies'
    joint states then, ``joints``: [(body name, root frame, joint names, q, qd)]; both taken on the
    simulation thread."""

    joints: list
    #: (objects, static transforms) when the scene's objects changed since the last time state, else None.
    scene: tuple | None = None


def _scene_listener(sink: FoxgloveSink):
    """A foxglove-sdk server listener that hands the scene to each client subscribing to ``/scene``.

    foxglove-sdk keeps no last message per channel, and its Python ``Client`` has no sink id to aim a
    message at one client: the scene goes to every client subscribed to ``/scene``; those that had it
    already get the same entities again, which replace themselves (same ids) without a visible change.
    """
    from foxglove.websocket import ServerListener

    class Listener(ServerListener):
        def on_subscribe(self, client, channel) -> None:
            if channel.topic == SCENE_TOPIC:
                sink._scene_subscribed()

    return Listener()


def _plain(obj: Any) -> Any:
    """``obj`` with JSON types only (numpy arrays and scalars converted), as a recording stores a config."""
    def default(o):
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, np.generic):
            return o.item()
        return repr(o)

    return json.loads(json.dumps(obj, default=default))


class FoxgloveSink(QueuedSink):
    """A Foxglove WebSocket server publishing every frame (a :class:`~twinsense.stream.sinks.FrameSink`).

    Parameters
    ----------
    port : int
        TCP port (0 picks a free one; ``port`` holds the real one after ``open``).
    host : str
        Address to listen on (default loopback only).
    queue_size : int
        Frames waiting for the sender thread before new ones are dropped.
    backlog : int
        Messages the server holds per client.
    """

    name = "foxglove"

    def __init__(self, port: int = 8765, host: str = "127.0.0.1", *, queue_size: int = QUEUE_SIZE,
                 backlog: int = BACKLOG, stats_interval: float = STATS_INTERVAL):
        super().__init__(queue_size)
        self.port = V.integer("FoxgloveSink.port", port, lo=0, hi=65535)
        if not isinstance(host, str) or not host:
            raise ConfigError("FoxgloveSink.host", host, "a host name or IP address to listen on")
        self.host = host
        self.backlog = V.integer("FoxgloveSink.backlog", backlog, lo=1)
        self.stats_interval = V.positive("FoxgloveSink.stats_interval", stats_interval, "s")
        self.server = None
        self._channels: dict[str, Any] = {}
        self._channel_names: dict[str, list] = {}
        self._camera_info: dict[str, dict | None] = {}
        self._posed_t: float | None = None
        # The latched scene: its encoded SceneUpdate (the only copy kept), its entity ids, the scene
        # version it shows, and the simulation time [ns] of the last frame published (its log time).
        self._scene_bytes: tuple[bytes, ...] = ()
        self._scene_ids: tuple[str, ...] = ()
        self._scene_version: int | None = None
        self._scene_lock = threading.Lock()
        self._scene_sent_at = -np.inf
        self._scene_timer: threading.Timer | None = None
        self._last_ns = 0

    # --- transport ---------------------------------------------------------------
    def _start(self) -> None:
        fg = require_foxglove()
        self._fg, self._m = fg, fg.messages
        self._ctx = fg.Context()  # its own channels, never the process-wide default context
        self._sensor_static = []
        self._static = []
        self._moving = []
        self._bodies = ()
        for s in self.sensors:
            cfg = _plain(s.config_dict()) if hasattr(s, "config_dict") else {}
            self._sensor_static += static_sensor_transforms(s.name, s.kind, cfg)
        self._static = list(self._sensor_static)
        listener = None
        if self.scene is not None:
            # Objects and mount frames (flanges, frame-only links, sites), as in the MCAP output.
            static, self._moving = scene_transforms(self.scene)
            self._static += static
            self._bodies = self.scene.articulated_bodies
            # The geometry is encoded once, before any client can subscribe; the channel is made now,
            # so that it is advertised to every client as it connects.
            self._scene_version = self.scene.version
            self._set_scene(self.scene.objects, 0)
            self._channels[SCENE_TOPIC] = self._fg.Channel(SCENE_TOPIC, schema=self._m.SceneUpdate.get_schema(),
                                                           message_encoding="protobuf", context=self._ctx)
            listener = _scene_listener(self)
        try:
            self.server = fg.start_server(name="twinsense", host=self.host, port=self.port, context=self._ctx,
                                          message_backlog_size=self.backlog, server_listener=listener)
        except Exception as err:
            raise ConfigError("foxglove_port", self.port, f"a free TCP port on {self.host} ({err})") from None
        self.port = int(self.server.port)
        self._next_stats = time.monotonic() + self.stats_interval

    def _stop(self) -> None:
        with self._scene_lock:
            if self._scene_timer is not None:
                self._scene_timer.cancel()
                self._scene_timer = None
        if self.server is not None:
            self._log_stats()
            if self.subscribed > 0:
                time.sleep(LINGER)
            self.server.stop()
            self.server = None

    @property
    def subscribed(self) -> int:
        """Channels (topics) at least one client is subscribed to, as the server has them now.

        Channels are advertised with their first message, and a subscription
        takes effect when the server has processed it: messages logged before
        that do not reach the client.
        """
        return sum(1 for ch in list(self._channels.values()) if ch.has_sinks())

    def stats(self) -> dict:
        """Frames sent and dropped per sensor, the frames queued now and the clients' subscriptions."""
        return {"sent": dict(self.sent), "dropped": dict(self.dropped), "queued": self.queued,
                "subscribed_channels": self.subscribed}

    # --- messages ----------------------------------------------------------------
    def _channel(self, topic: str, cls_name: str | None):
        ch = self._channels.get(topic)
        if ch is None:
            if cls_name is None:
                ch = self._fg.Channel(topic, schema={"type": "object"}, context=self._ctx)
            else:
                import foxglove.channels as channels

                ch = getattr(channels, f"{cls_name}Channel")(topic, context=self._ctx)
            self._channels[topic] = ch
        return ch

    def _log(self, topic: str, cls_name: str | None, msg, ns: int) -> None:
        self._channel(topic, cls_name).log(msg, log_time=ns)

    def _log_stats(self) -> None:
        self._log("/twinsense/stats", None, self.stats(), time.time_ns())

    def _stamp(self, ns: int):
        return self._fg.messages.Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)

    # --- the scene's geometry ------------------------------------------------------
    def _entity(self, obj, ns: int):
        """One object as a frame-locked SceneEntity in its own /tf frame (id and frame id: its name).

        A box is a CubePrimitive of its edge lengths (exactly the box the sensors see); any other
        geometry a TriangleListPrimitive of its mesh (the one the sensors ray-cast): the mesh's vertices
        [m] in the object's frame and its faces as indices. Colour: the material's (MATERIAL_COLORS).
        """
        m = self._m
        r, g, b, a = material_color(obj.material)
        color = m.Color(r=r, g=g, b=b, a=a)
        ident = m.Pose(position=m.Vector3(x=0.0, y=0.0, z=0.0), orientation=m.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))
        geom = obj.geometry
        if isinstance(geom, Box):
            sx, sy, sz = geom.size
            shape = {"cubes": [m.CubePrimitive(pose=ident, size=m.Vector3(x=sx, y=sy, z=sz), color=color)]}
        else:
            mesh = geom.mesh
            pts = [m.Point3(x=x, y=y, z=z) for x, y, z in np.asarray(mesh.vertices, dtype=np.float64).tolist()]
            shape = {"triangles": [m.TriangleListPrimitive(pose=ident, points=pts, color=color,
                                                           indices=np.asarray(mesh.faces).ravel().tolist())]}
        return m.SceneEntity(timestamp=self._stamp(ns), frame_id=obj.name, id=obj.name,
                             lifetime=m.Duration(sec=0, nsec=0), frame_locked=True,
                             metadata=[m.KeyValuePair(key="material", value=obj.material.name),
                                       m.KeyValuePair(key="geometry", value=geom.kind)], **shape)

    def _set_scene(self, objects, ns: int) -> list[str]:
        """Encode ``objects`` as the latched SceneUpdates (entities stamped ``ns``); the ids that went."""
        ids = tuple(o.name for o in objects)
        data = pack_scene([self._m.SceneUpdate(entities=[self._entity(o, ns)]).encode() for o in objects])
        with self._scene_lock:
            kept = set(ids)
            gone = [i for i in self._scene_ids if i not in kept]
            self._scene_bytes, self._scene_ids = data, ids
        return gone

    def _send_scene(self) -> None:
        """Log the latched scene on ``/scene`` to the clients subscribed to it (a no-op without objects)."""
        with self._scene_lock:
            for data in self._scene_bytes:
                self._channels[SCENE_TOPIC].log(data, log_time=self._last_ns)
            self._scene_sent_at = time.monotonic()

    def _scene_subscribed(self) -> None:
        """A client subscribed to ``/scene`` (the server's thread): send the scene now, or, within
        :data:`SCENE_RESEND_INTERVAL` of the last send, once at the end of it for all who subscribed."""
        with self._scene_lock:
            wait = self._scene_sent_at + SCENE_RESEND_INTERVAL - time.monotonic()
            if wait > 0:
                if self._scene_timer is None:
                    self._scene_timer = threading.Timer(wait, self._scene_deferred)
                    self._scene_timer.daemon = True
                    self._scene_timer.start()
                return
        self._send_scene()

    def _scene_deferred(self) -> None:
        with self._scene_lock:
            self._scene_timer = None
            if self.server is None:
                return
        self._send_scene()

    def _image(self, a: np.ndarray, ns: int, frame_id: str):
        a = np.ascontiguousarray(a, dtype="<f4")
        h, w = a.shape
        return self._m.RawImage(timestamp=self._stamp(ns), frame_id=frame_id, width=w, height=h,
                                encoding="32FC1", step=4 * w, data=a.tobytes())

    def _cloud(self, columns: list[tuple[str, np.ndarray]], ns: int, frame_id: str):
        m = self._m
        nt = m.PackedElementFieldNumericType
        types = {"u1": nt.Uint8, "i1": nt.Int8, "u2": nt.Uint16, "i2": nt.Int16, "u4": nt.Uint32, "i4": nt.Int32,
                 "f4": nt.Float32, "f8": nt.Float64}
        pts, layout = pack_columns(columns)
        fields = [m.PackedElementField(name=n, offset=off, type=types[code]) for n, off, code in layout]
        pose = m.Pose(position=m.Vector3(x=0.0, y=0.0, z=0.0), orientation=m.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))
        return m.PointCloud(timestamp=self._stamp(ns), frame_id=frame_id, pose=pose,
                            point_stride=pts.dtype.itemsize, fields=fields, data=pts.tobytes())

    def send(self, sensor, t: float, frame) -> bool:
        # The moving objects' poses are taken here, on the simulation thread: the sender thread never
        # reads the scene (a motion may keep per-time state that is not safe to share between threads).
        # An added object (the scene's version changes) is seen here too: its transforms join the lists
        # and its geometry rides, with this time's poses, to the sender thread, which re-sends the scene.
        t = float(t)
        poses = None
        scene = getattr(self, "scene", None)
        changed = scene is not None and scene.version != self._scene_version
        if t != self._posed_t or changed:
            if changed:
                static, self._moving = scene_transforms(scene)
                self._bodies = scene.articulated_bodies
                self._scene_version = scene.version
            poses = _TimeState((WORLD_FRAME, o.name, o.pose_at(t)) for o in getattr(self, "_moving", ()))
            poses.joints = [(b.name, body_frame(b), b.tree.joint_names, *b.joint_state(t))
                            for b in getattr(self, "_bodies", ())]
            if changed:
                poses.scene = (scene.objects, static)
            self._posed_t = t
        queued = super().send(sensor, t, (frame, poses))
        if not queued and poses is not None:
            # The frame that carried this time's transforms was dropped: the next frame at this time carries them
            # (and the scene's change, if it carried one).
            self._posed_t = None
            if poses.scene is not None:
                self._scene_version = None
        return queued

    def _transforms(self, poses: list, ns: int):
        m = self._m
        out = []
        for parent, child, pose in self._static + poses:
            x, y, z = (float(v) for v in pose.position)
            qx, qy, qz, qw = (float(v) for v in pose.quat_xyzw)
            out.append(m.FrameTransform(timestamp=self._stamp(ns), parent_frame_id=parent, child_frame_id=child,
                                        translation=m.Vector3(x=x, y=y, z=z),
                                        rotation=m.Quaternion(x=qx, y=qy, z=qz, w=qw)))
        return m.FrameTransforms(transforms=out)

    def _publish(self, sensor, t: float, item) -> None:
        frame, poses = item
        ns = stamp_ns(t)
        name, kind = sensor.name, sensor.kind
        fid = sensor_frame(name, kind)
        self._last_ns = ns
        change = getattr(poses, "scene", None)
        if change is not None:
            objects, static = change
            self._static = self._sensor_static + static
            gone = self._set_scene(objects, ns)
            if gone:
                m = self._m
                self._channels[SCENE_TOPIC].log(m.SceneUpdate(deletions=[
                    m.SceneEntityDeletion(timestamp=self._stamp(ns), type=m.SceneEntityDeletionType.MatchingId, id=i)
                    for i in gone]).encode(), log_time=ns)
            self._send_scene()
        if poses is not None:
            # Every transform at every new frame time: a client that joins late has them at once.
            self._log("/tf", "FrameTransforms", self._transforms(poses, ns), ns)
            for body, root, names, q, qd in getattr(poses, "joints", ()):
                # JSON with sensor_msgs/JointState's fields (Foxglove has no joint-state schema of its own).
                self._log(f"/{body}/joint_states", None,
                          {"header": {"stamp": {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000},
                                      "frame_id": root},
                           "name": list(names), "position": q.tolist(), "velocity": qd.tolist(), "effort": []}, ns)
        if kind in ("camera", "tof"):
            if name not in self._camera_info:
                self._camera_info[name] = camera_info(kind, _plain(sensor.config_dict()))
            info = self._camera_info[name]
            if info is not None:
                self._log(f"/{name}/camera_info", "CameraCalibration",
                          self._m.CameraCalibration(timestamp=self._stamp(ns), frame_id=fid, width=info["width"],
                                                    height=info["height"], distortion_model=info["distortion_model"],
                                                    D=info["d"], K=info["k"], R=info["r"], P=info["p"]), ns)
            self._log(f"/{name}/depth", "RawImage", self._image(frame.depth, ns, fid), ns)
        if kind == "tof":
            self._log(f"/{name}/amplitude", "RawImage", self._image(frame.amplitude, ns, fid), ns)
            xyz = np.asarray(frame.points_sensor, dtype=np.float32).reshape(-1, 3)
            amp = np.asarray(frame.amplitude, dtype=np.float32).ravel()
            ok = np.isfinite(xyz).all(axis=1)
            self._log(f"/{name}/points", "PointCloud",
                      self._cloud([("x", xyz[ok, 0]), ("y", xyz[ok, 1]), ("z", xyz[ok, 2]), ("intensity", amp[ok])],
                                  ns, fid), ns)
        elif kind == "radar":
            proc = getattr(frame, "processed", None)
            if proc is not None:
                db = 10.0 * np.log10(np.maximum(np.asarray(proc.power, dtype=float), _DB_FLOOR))
                self._log(f"/{name}/range_doppler", "RawImage", self._image(db, ns, fid), ns)
                self._log(f"/{name}/detections", "PointCloud",
                          self._cloud(radar_detection_columns(proc.detections), ns, f"{name}_link"), ns)
        elif kind == "lidar":
            cols = lidar_columns(frame.xyz, frame.intensity, frame.ring, frame.time, frame.range, float(frame.t))
            self._log(f"/{name}/points", "PointCloud", self._cloud(cols, ns, fid), ns)
        elif kind == "capacitive":
            st = frame.streams()
            self._log(f"/{name}/maxwell", "RawImage", self._image(st["maxwell"], ns, fid), ns)
            names = self._channel_names.setdefault(name, list(_plain(sensor.config_dict()).get("channels", [])))
            self._log(f"/{name}/frame", None, {"t": t, "channel_names": names,
                                               **{k: _json_values(st[k]) for k in
                                                  ("channels", "readout", "delta", "self_capacitance") if k in st}},
                      ns)
        elif kind != "camera":
            st = frame.streams()
            self._log(f"/{name}/frame", None,
                      {"t": t, **{k: _json_values(v) for k, v in st.items() if np.size(v) <= MAX_JSON_VALUES}}, ns)
        if time.monotonic() >= self._next_stats:
            self._log_stats()
            self._next_stats = time.monotonic() + self.stats_interval


def pack_scene(updates: list[bytes], limit: int = SCENE_MESSAGE_BYTES) -> tuple[bytes, ...]:
    """Encoded one-entity SceneUpdates packed, in order, into messages of at most ``limit`` bytes.

    Concatenated protobuf messages parse as one whose repeated fields hold all the parts' entries
    (protobuf's merge rule), so a message is its parts joined: a SceneUpdate with their entities. An
    update longer than ``limit`` is a message of its own. No updates: no messages.
    """
    out: list[bytes] = []
    part: list[bytes] = []
    size = 0
    for u in updates:
        if part and size + len(u) > limit:
            out.append(b"".join(part))
            part, size = [], 0
        part.append(u)
        size += len(u)
    if part:
        out.append(b"".join(part))
    return tuple(out)


def _json_values(a) -> Any:
    """An array as nested lists for JSON; NaN and inf become None (JSON has neither)."""
    a = np.asarray(a)
    if a.dtype.kind in "fc":
        a = np.real(a).astype(float)
        return np.where(np.isfinite(a), a, None).tolist() if not np.isfinite(a).all() else a.tolist()
    return a.tolist()

