"""Rerun output: a live frame sink (file, gRPC, viewer) and a recording converter.

Both write the same entities on one timeline, ``sim_time`` (a duration in
seconds of simulation time; Rerun stores integer nanoseconds):

``world``                              view coordinates right-handed, z up (static)
``world/objects/<object>``             the object's mesh (static) and pose
                                       (static, or per frame time when it moves);
                                       robot links ``<robot>/<link>`` nest under ``<robot>``;
                                       mount frames (links without geometry, sites)
                                       likewise, a pose only (axes where a sensor
                                       hangs from one)
``world/sensors/<sensor>``             sensor -> world transform (static when fixed)
``world/sensors/<sensor>/image``       pinhole of a camera or ToF sensor (static)
``world/sensors/<sensor>/image/depth`` depth image [m] (``DepthImage``, meter = 1)
``world/sensors/<sensor>/image/amplitude``  ToF amplitude [DN] (``Image``)
``world/sensors/<sensor>/detections``  radar detections, sensor frame (live sink only)
``world/points/<sensor>``              ToF / LiDAR points in the world frame [m]
``signals/<sensor>/<stream>``          scalars (capacitive channels, magnetic
                                       field, inductive and ultrasonic values)
                                       and tensors (radar range-Doppler power
                                       [dB], ultrasonic envelopes)

The optical sensor frame (x right, y down, z forward) is Rerun's default
pinhole frame (RDF), so a depth image under the pinhole back-projects to
the right place in the viewer. Everything goes to a dedicated
``rerun.RecordingStream``, never the process-wide global one.

rerun-sdk is an optional dependency (``pip install 'twinsense[rerun]'``).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twinsense.errors import ConfigError, RecordingError
from twinsense.io.mcap import camera_info
from twinsense.io.recording import Recording, open_recording
from twinsense.scene.pose import Pose
from twinsense.scene.scene import Mount, Scene
from twinsense.stream.sinks import QueuedSink

TIMELINE = "sim_time"
APPLICATION_ID = "twinsense"
#: Frames the live sink holds while its logging thread catches up; beyond this it drops (a few
#: seconds of a 30 Hz camera: Rerun's own batching absorbs short stalls behind it).
QUEUE_SIZE = 64
#: Streams of at most this many values are logged as scalars (one series each); larger ones as tensors.
MAX_SCALARS = 64
#: Object colours (RGBA), cycled by object index: distinct at a glance, none close to the point colours.
PALETTE = ((166, 206, 227, 255), (178, 223, 138, 255), (251, 154, 153, 255), (253, 191, 111, 255),
           (202, 178, 214, 255), (255, 255, 153, 255), (190, 190, 190, 255))
# The power floor of the dB maps: 10 log10 of zero would be -inf.
_DB_FLOOR = 1e-30
#: [m] Axis length of the triad drawn at a mount frame a sensor hangs from (a robot flange's size).
FRAME_AXIS_LENGTH = 0.05


def require_rerun():
    """The ``rerun`` module, or ConfigError naming the extra that installs it."""
    try:
        import rerun
    except ImportError:
        raise ConfigError("rerun", "rerun-sdk is not installed",
                          "the optional extra: pip install 'twinsense[rerun]'") from None
    return rerun


def _plain(obj: Any) -> Any:
    """A config as the recording stores it (JSON types), so live and converted runs log alike."""
    def default(o):
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, (np.integer, np.floating, np.bool_)):
            return o.item()
        if hasattr(o, "to_dict"):
            return o.to_dict()
        return repr(o)

    return json.loads(json.dumps(obj, default=default))


def _mount_of(cfg: Mapping) -> Mount:
    m = cfg.get("mount") or {}
    p = m.get("pose") or {}
    pose = Pose.from_quat(p.get("position", (0.0, 0.0, 0.0)), p.get("quat_xyzw", (0.0, 0.0, 0.0, 1.0)))
    return Mount(pose, m.get("parent"))


@dataclass(frozen=True)
class SensorInfo:
    """What the logger needs of one sensor: name, kind, config (recorded JSON form), mount."""

    name: str
    kind: str
    config: dict
    mount: Mount

    @classmethod
    def from_sensor(cls, sensor) -> SensorInfo:
        cfg = _plain(sensor.config_dict()) if hasattr(sensor, "config_dict") else {}
        mount = getattr(sensor, "mount", None)
        return cls(sensor.name, sensor.kind, cfg, mount if isinstance(mount, Mount) else _mount_of(cfg))


def entity(*parts: str) -> str:
    """An entity path from raw names (each part escaped, so any object name is one path part)."""
    rr = require_rerun()
    return "/".join(rr.escape_entity_path_part(p) for p in parts)


def object_path(name: str) -> str:
    """Entity of a scene object: ``world/objects/<name>``; a robot link ``robot/link`` nests as
    ``world/objects/robot/link`` (the group entity has no transform, so the link's pose is its world pose)."""
    return entity("world", "objects", *name.split("/"))


def _transform(rr, pose: Pose):
    return rr.Transform3D(translation=np.asarray(pose.position, dtype=np.float64),
                          quaternion=rr.Quaternion(xyzw=np.asarray(pose.quat_xyzw, dtype=np.float64)))


def _gray(values: np.ndarray) -> np.ndarray:
    """(n,) values -> (n, 3) uint8 gray levels, scaled to the 99th percentile (a few hot pixels do not
    darken the rest)."""
    v = np.nan_to_num(np.asarray(values, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    top = np.percentile(v, 99) if v.size else 1.0
    g = np.clip(v / top, 0.0, 1.0) if top > 0 else np.zeros_like(v)
    return np.repeat((40 + 215 * g).astype(np.uint8)[:, None], 3, axis=1)


class RerunLogger:
    """Writes a scene and sensor frames to one Rerun recording stream.

    Parameters
    ----------
    rec : rerun.RecordingStream
    scene : Scene or None
        Its objects become meshes; moving ones get a pose at every frame time.
    sensors : iterable of SensorInfo
    """

    def __init__(self, rec, scene: Scene | None, sensors: Iterable[SensorInfo]):
        self.rr = require_rerun()
        self.rec = rec
        self.scene = scene
        self.sensors = {s.name: s for s in sensors}
        self._last_t: float | None = None
        self._moving = [] if scene is None else [o for o in scene if not o.is_static]
        # Mount frames (links without geometry, sites) get a pose like the objects: the frames sensors hang
        # from are then in the entity tree (the sensors' own entities carry their world poses).
        self._frames = () if scene is None else scene.frames
        self._moving += [f for f in self._frames if not f.motion.is_static]

    def log_static(self) -> None:
        """World axes, every object's mesh, fixed sensor poses and pinholes, series names."""
        rr, rec = self.rr, self.rec
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        if self.scene is not None:
            for i, obj in enumerate(self.scene):
                mesh = obj.geometry.mesh
                path = object_path(obj.name)
                rec.log(path, rr.Mesh3D(vertex_positions=np.asarray(mesh.vertices, dtype=np.float32),
                                        triangle_indices=np.asarray(mesh.faces, dtype=np.uint32),
                                        vertex_normals=np.asarray(mesh.vertex_normals, dtype=np.float32),
                                        albedo_factor=PALETTE[i % len(PALETTE)]), static=True)
                if obj.is_static:
                    rec.log(path, _transform(rr, obj.pose_at(0.0)), static=True)
            hung = {s.mount.parent for s in self.sensors.values()}
            for frame in self._frames:
                path = object_path(frame.name)
                if frame.name in hung:
                    rec.log(path, rr.TransformAxes3D(FRAME_AXIS_LENGTH), static=True)
                if frame.motion.is_static:
                    rec.log(path, _transform(rr, frame.pose_at(0.0)), static=True)
        for s in self.sensors.values():
            base = entity("world", "sensors", s.name)
            if s.mount.parent is None:
                rec.log(base, _transform(rr, s.mount.pose), static=True)
            info = camera_info(s.kind, s.config)
            if info is not None:
                k = np.array(info["k"], dtype=np.float64).reshape(3, 3)
                rec.log(f"{base}/image", rr.Pinhole(image_from_camera=k, resolution=[info["width"], info["height"]],
                                                    camera_xyz=rr.ViewCoordinates.RDF), static=True)
            if s.kind == "capacitive":
                names = list(s.config.get("channels", []))
                if names:
                    for stream in ("channels", "delta"):
                        rec.log(entity("signals", s.name, stream), rr.SeriesLines(names=names), static=True)

    def _set_time(self, t: float) -> None:
        self.rec.set_time(TIMELINE, duration=float(t))
        if t != self._last_t:
            # Moving objects and frames once per distinct frame time, on the same timeline as the frames.
            for obj in self._moving:
                self.rec.log(object_path(obj.name), _transform(self.rr, obj.pose_at(float(t))))
            self._last_t = t

    def log_frame(self, name: str, t: float, streams: Mapping[str, np.ndarray], detections=None) -> None:
        """Log one frame of sensor ``name`` at ``t`` [s] from its ``streams()`` arrays.

        ``detections`` (a radar frame's :class:`RadarPointCloud`) adds the detected points.
        """
        rr, rec = self.rr, self.rec
        s = self.sensors[name]
        self._set_time(t)
        base = entity("world", "sensors", name)
        # A fixed mount's pose is logged once, static (Rerun lets static data shadow timed data of the
        # same component, so a fixed sensor gets no per-frame pose at all).
        if s.mount.parent is not None:
            if "pose" in streams:  # the sensor -> world pose the frame was captured at (ToF)
                pose = Pose.from_matrix(np.asarray(streams["pose"], dtype=np.float64))
            else:
                pose = s.mount.pose_at(self.scene, t) if self.scene is not None else s.mount.pose
            rec.log(base, _transform(rr, pose))
        kind = s.kind
        if kind in ("camera", "tof"):
            rec.log(f"{base}/image/depth", rr.DepthImage(np.asarray(streams["depth"], dtype=np.float32), meter=1.0))
        if kind == "tof":
            amp = np.asarray(streams["amplitude"], dtype=np.float32)
            rec.log(f"{base}/image/amplitude", rr.Image(amp))
            pts = np.asarray(streams["points_world"], dtype=np.float32).reshape(-1, 3)
            valid = (np.asarray(streams["invalid"]).ravel() == 0) & np.isfinite(pts).all(axis=1)
            rec.log(entity("world", "points", name), rr.Points3D(pts[valid], colors=_gray(amp.ravel()[valid])))
        elif kind == "lidar":
            rng = np.asarray(streams["range"])
            valid = np.isfinite(rng)
            pts = np.asarray(streams["xyz_world"], dtype=np.float32)[valid]
            rec.log(entity("world", "points", name),
                    rr.Points3D(pts, colors=_gray(np.asarray(streams["intensity"])[valid])))
        elif kind == "radar":
            if "range_doppler_power" in streams:
                p = np.asarray(streams["range_doppler_power"], dtype=np.float64)
                db = (10.0 * np.log10(np.maximum(p, _DB_FLOOR))).astype(np.float32)
                rec.log(entity("signals", name, "range_doppler_db"), rr.Tensor(db, dim_names=["doppler", "range"]))
            if detections is not None:
                rec.log(f"{base}/detections", rr.Points3D(np.asarray(detections.points_sensor, dtype=np.float32)))
        elif kind == "capacitive":
            for stream in ("channels", "delta"):
                rec.log(entity("signals", name, stream), rr.Scalars(np.asarray(streams[stream], dtype=np.float64)))
        elif kind == "camera":
            pass
        else:
            # Magnetic, inductive, ultrasonic and sensor kinds defined elsewhere: small streams as
            # scalars, larger ones as tensors.
            for stream, value in streams.items():
                a = np.asarray(value)
                if a.dtype.kind not in "biuf" or a.size == 0:
                    continue
                path = entity("signals", name, stream)
                if a.size <= MAX_SCALARS:
                    rec.log(path, rr.Scalars(a.astype(np.float64).ravel()))
                elif a.ndim >= 2:
                    rec.log(path, rr.Tensor(a.astype(np.float32)))


def _new_stream(application_id: str):
    rr = require_rerun()
    rec = rr.RecordingStream(application_id)
    # Only simulation time: the wall clock of logging says nothing about the run.
    rec.set_log_time_enabled(False)
    rec.set_log_tick_enabled(False)
    return rr, rec


def _check_out(out) -> Path:
    out = Path(out)
    if out.suffix != ".rrd":
        raise ConfigError("out", str(out), "a file name ending in .rrd")
    if not out.parent.is_dir():
        raise ConfigError("out", str(out), "a path in an existing folder")
    return out


def _tmp(out: Path) -> Path:
    return out.with_name(f".{out.name}.{os.getpid()}.tmp")


def write_rrd(recording, out, scene: Scene | None = None, *, allow_incomplete: bool = False) -> Path:
    """Convert a twinsense HDF5 recording into a Rerun ``.rrd`` file; returns its path.

    Parameters
    ----------
    recording : path-like or Recording
        The HDF5 recording (or one already open).
    out : path-like
        The ``.rrd`` file, written under a temporary name and renamed when complete.
    scene : Scene, optional
        The run's scene (``twinsense convert`` rebuilds it from the recording's
        scenario): adds the object meshes and their poses.
    """
    require_rerun()
    out = _check_out(out)
    if isinstance(recording, Recording):
        return _write(recording, out, scene)
    with open_recording(recording, allow_incomplete=allow_incomplete) as rec:
        return _write(rec, out, scene)


class _FrameStreams(Mapping):
    """Frame ``k`` of a recorded sensor as a read-only mapping that reads a stream only when it is
    looked up (a converted frame logs a few of its streams; the rest stay on disk)."""

    def __init__(self, sensor, k: int):
        self._s, self._k, self._names = sensor, k, sensor.stream_names

    def __getitem__(self, key: str) -> np.ndarray:
        if key not in self._names:
            raise KeyError(key)
        return self._s[key][self._k]

    def __contains__(self, key) -> bool:  # without reading the stream (Mapping's default would)
        return key in self._names

    def __iter__(self):
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)


def _write(recording: Recording, out: Path, scene: Scene | None) -> Path:
    rr, rec = _new_stream(APPLICATION_ID)
    tmp = _tmp(out)
    try:
        rec.set_sinks(rr.FileSink(str(tmp)))
        infos = [SensorInfo(n, s.kind, s.config, _mount_of(s.config)) for n, s in recording.sensors.items()]
        logger = RerunLogger(rec, scene, infos)
        logger.log_static()
        # Every sensor's frames merged in time order on the shared clock.
        events = sorted((float(t), n, k) for n, s in recording.sensors.items() for k, t in enumerate(s.timestamps))
        for t, n, k in events:
            logger.log_frame(n, t, _FrameStreams(recording[n], k))
        rec.flush()
        rec.disconnect()
        os.replace(tmp, out)
    except KeyError as exc:
        # A recording whose sensor lacks a stream or config entry its kind has (written by other tools).
        raise RecordingError(f"{str(recording.path)!r}: cannot convert to Rerun: missing {exc}") from None
    finally:
        rec.disconnect()  # no sink writes into the temporary file after it is removed
        tmp.unlink(missing_ok=True)
    return out


def convert(recording, out, scene_from_scenario: Callable[[dict], Scene] | None = None,
            allow_incomplete: bool = False) -> Path:
    """Convert the HDF5 recording at ``recording`` into the Rerun file ``out`` (``.rrd``).

    ``scene_from_scenario`` rebuilds the scene from the recording's scenario
    (a dict) for the object meshes; it is not called when the recording has
    no scenario (a run from the Python API).
    """
    require_rerun()
    out = _check_out(out)
    with open_recording(recording, allow_incomplete=allow_incomplete) as rec:
        scenario = rec.scenario
        scene = scene_from_scenario(scenario) if scenario and scene_from_scenario is not None else None
        return _write(rec, out, scene)


class RerunSink(QueuedSink):
    """A live sink: frames of a running simulation to a Rerun file, gRPC server or viewer.

    ``send`` never blocks the simulation: frames go to a bounded queue that a
    logging thread empties (:class:`~twinsense.stream.sinks.QueuedSink`); when
    the queue is full the frame is dropped and counted in ``dropped[sensor
    name]``. A logging failure stops the sink (``error``), never the run; its
    ``.rrd`` file is then removed rather than left half-written.

    Parameters
    ----------
    path : path-like, optional
        Also write an ``.rrd`` file (written under a temporary name, renamed into place by ``close``).
    serve : bool
        Host a gRPC server that viewers connect to (:attr:`url`).
    grpc_port : int
        Port of that server (default 9876, Rerun's).
    bind : str
        Address the server and the web viewer listen on (default loopback only).
    web_viewer : bool
        Also host Rerun's web viewer on ``web_port`` (HTTP), connected to the server (implies ``serve``).
    web_port : int
        Port of the web viewer (default 9090, Rerun's).
    connect : str, optional
        Stream to an existing Rerun gRPC server or viewer at this URL
        (``rerun+http://127.0.0.1:9876/proxy``).
    spawn : bool
        Start a native Rerun viewer process and stream to it.
    queue_size : int
        Frames held while the logging thread catches up.
    """

    name = "rerun"

    def __init__(self, path=None, *, serve: bool = False, grpc_port: int = 9876, bind: str = "127.0.0.1",
                 web_viewer: bool = False, web_port: int = 9090, connect: str | None = None, spawn: bool = False,
                 queue_size: int = QUEUE_SIZE, application_id: str = APPLICATION_ID):
        super().__init__(queue_size)
        self.path = None if path is None else _check_out(path)
        for field, port in (("grpc_port", grpc_port), ("web_port", web_port)):
            if isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535:
                raise ConfigError(f"RerunSink.{field}", port, "a TCP port 1..65535")
        if connect is not None and (not isinstance(connect, str) or not connect.startswith(("rerun://", "rerun+http"))):
            raise ConfigError("RerunSink.connect", connect,
                              "a Rerun gRPC URL such as 'rerun+http://127.0.0.1:9876/proxy'")
        if not (path is not None or serve or web_viewer or connect or spawn):
            raise ConfigError("RerunSink", "no output", "a path, serve=True, web_viewer=True, connect=URL or "
                                                          "spawn=True")
        require_rerun()
        self.serve = bool(serve or web_viewer)
        self.grpc_port, self.bind, self.web_viewer, self.web_port = grpc_port, bind, bool(web_viewer), web_port
        self.connect, self.spawn, self.application_id = connect, bool(spawn), application_id
        self._rec = None
        self._tmp: Path | None = None

    @property
    def url(self) -> str | None:
        """The gRPC URL viewers connect to when serving, else None."""
        return f"rerun+http://{self.bind}:{self.grpc_port}/proxy" if self.serve else None

    @property
    def web_url(self) -> str | None:
        """The web viewer page, opened on the served recording, else None."""
        if not self.web_viewer:
            return None
        from urllib.parse import quote

        return f"http://{self.bind}:{self.web_port}/?url={quote(self.url, safe='')}"

    def _start(self) -> None:
        rr, rec = _new_stream(self.application_id)
        sinks = []
        if self.path is not None:
            self._tmp = _tmp(self.path)
            sinks.append(rr.FileSink(str(self._tmp)))
        if self.serve:
            sinks.append(rr.GrpcServerSink(self.bind, self.grpc_port))
        if self.connect:
            sinks.append(rr.GrpcSink(self.connect))
        if self.spawn:
            rr.spawn(connect=False)
            sinks.append(rr.GrpcSink())  # the spawned viewer listens on Rerun's default URL
        rec.set_sinks(*sinks)
        if self.web_viewer:
            rr.serve_web_viewer(web_port=self.web_port, open_browser=False, connect_to=self.url)
        self._rec = rec
        self._logger = RerunLogger(rec, self.scene, [SensorInfo.from_sensor(s) for s in self.sensors])
        self._logger.log_static()

    def close(self) -> None:
        """Log what is queued, flush, and finish the file (renamed into place); safe to call twice.

        With a file output every queued frame is logged first, however long that takes (the
        base class gives a stuck network transport a bounded time instead).
        """
        while (self.path is not None and not self._closed and self.error is None and self._thread is not None
               and self._thread.is_alive() and self._queue.qsize()):
            time.sleep(0.01)
        super().close()

    def _publish(self, sensor, t: float, frame) -> None:
        self._logger.log_frame(sensor.name, t, frame.streams(), getattr(frame, "detections", None))

    def _stop(self) -> None:
        if self._rec is None:
            return
        self._rec.flush()
        self._rec.disconnect()
        self._rec = None
        if self._tmp is not None:
            if self.error is None:
                os.replace(self._tmp, self.path)
            else:
                self._tmp.unlink(missing_ok=True)
