"""ROS 2 recordings: a twinsense HDF5 recording converted to an MCAP file.

Messages are ROS 2 messages (``ros2msg`` schemas, CDR encoding) written with
the ``mcap`` and ``mcap-ros2-support`` libraries (the ``ros2`` extra). The
converter reads only the recording: each sensor's streams and its
``config`` JSON, and, for the poses of the scene's objects on ``/tf``, a
:class:`~twinsense.scene.scene.Scene` the caller rebuilds from the
recording's scenario (``twinsense convert`` does this). Topics, frames and
message layouts are described in docs/ros2-mcap.md.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from twinsense.errors import ConfigError, TwinsenseError
from twinsense.io.recording import Recording, SensorRecording, open_recording
from twinsense.scene.pose import Pose
from twinsense.scene.scene import Scene

WORLD_FRAME = "world"

#: Rotation of an optical frame (x right, y down, z forward) in its REP 103
#: body frame (x forward, y left, z up): the columns are the optical axes.
R_LINK_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])

#: Sensor kinds whose twinsense sensor frame is an optical frame (their
#: mounts use the camera convention of ``Pose.look_at``).
OPTICAL_KINDS = frozenset({"camera", "tof", "radar"})

# sensor_msgs/PointField datatypes.
FLOAT32 = 7

_TIME = "int32 sec\nuint32 nanosec\n"
_HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
_SEP = "=" * 80 + "\n"


def _with_deps(body: str, *deps: tuple[str, str]) -> str:
    return body + "".join(f"{_SEP}MSG: {name}\n{text}" for name, text in deps)


_HEADER_DEPS = (("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME))
_VEC = "float64 x\nfloat64 y\nfloat64 z\n"
_QUAT = "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
_ROI = "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n"
_POINT_FIELD = ("uint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\nuint8 INT32=5\nuint8 UINT32=6\n"
                "uint8 FLOAT32=7\nuint8 FLOAT64=8\nstring name\nuint32 offset\nuint8 datatype\nuint32 count\n")

#: Standard ROS 2 message definitions (fields as in ROS 2 Humble), with their dependencies.
ROS_MSGDEFS: dict[str, str] = {
    "sensor_msgs/msg/Image": _with_deps(
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\n"
        "uint32 step\nuint8[] data\n", *_HEADER_DEPS),
    "sensor_msgs/msg/CameraInfo": _with_deps(
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\n"
        "float64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\nRegionOfInterest roi\n",
        *_HEADER_DEPS, ("sensor_msgs/RegionOfInterest", _ROI)),
    "sensor_msgs/msg/PointCloud2": _with_deps(
        "std_msgs/Header header\nuint32 height\nuint32 width\nPointField[] fields\nbool is_bigendian\n"
        "uint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n",
        *_HEADER_DEPS, ("sensor_msgs/PointField", _POINT_FIELD)),
    "tf2_msgs/msg/TFMessage": _with_deps(
        "geometry_msgs/TransformStamped[] transforms\n",
        ("geometry_msgs/TransformStamped", "std_msgs/Header header\nstring child_frame_id\nTransform transform\n"),
        *_HEADER_DEPS,
        ("geometry_msgs/Transform", "Vector3 translation\nQuaternion rotation\n"),
        ("geometry_msgs/Vector3", _VEC), ("geometry_msgs/Quaternion", _QUAT)),
    "rosgraph_msgs/msg/Clock": _with_deps("builtin_interfaces/Time clock\n", ("builtin_interfaces/Time", _TIME)),
}

_RADAR_CUBE = ("std_msgs/Header header\nuint32 n_rx\nuint32 n_chirps\nuint32 n_samples\n"
               "float32[] real\nfloat32[] imag\n")
_RANGE_DOPPLER = "std_msgs/Header header\nuint32 n_doppler\nuint32 n_range\nfloat32[] power\n"
_CAPACITIVE = ("std_msgs/Header header\nstring[] channels\nfloat64[] channel_values\nfloat64[] readout\n"
               "float64[] delta\nfloat64[] self_capacitance\nuint32 n_terminals\nfloat64[] maxwell\n")
_ARRAY = "std_msgs/Header header\nstring stream\nuint32[] shape\nfloat64[] data\n"

#: The package's own messages: name -> definition (the field lines of docs/msg/<Name>.msg).
TWINSENSE_MSGS: dict[str, str] = {
    "twinsense_msgs/msg/RadarCube": _RADAR_CUBE,
    "twinsense_msgs/msg/RangeDoppler": _RANGE_DOPPLER,
    "twinsense_msgs/msg/CapacitiveFrame": _CAPACITIVE,
    "twinsense_msgs/msg/ArrayStream": _ARRAY,
}
MSGDEFS: dict[str, str] = {**ROS_MSGDEFS, **{k: _with_deps(v, *_HEADER_DEPS) for k, v in TWINSENSE_MSGS.items()}}


def _require_mcap():
    try:
        from mcap_ros2.writer import Writer
    except ImportError as err:
        raise ImportError("writing MCAP files needs the optional 'ros2' extra: "
                          "pip install 'twinsense[ros2]' (mcap, mcap-ros2-support)") from err
    return Writer


def stamp_ns(t: float) -> int:
    """Simulation time ``t`` [s] as integer nanoseconds (rounded to the nearest ns)."""
    if not np.isfinite(t) or t < 0:
        raise ConfigError("timestamp", t, "a finite time >= 0 s (ROS 2 stamps count from 0)")
    return round(float(t) * 1e9)


def _time(ns: int) -> dict:
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def _header(ns: int, frame_id: str) -> dict:
    return {"stamp": _time(ns), "frame_id": frame_id}


def _transform(ns: int, parent: str, child: str, pose: Pose) -> dict:
    x, y, z = (float(v) for v in pose.position)
    qx, qy, qz, qw = (float(v) for v in pose.quat_xyzw)
    return {"header": _header(ns, parent), "child_frame_id": child,
            "transform": {"translation": {"x": x, "y": y, "z": z},
                          "rotation": {"x": qx, "y": qy, "z": qz, "w": qw}}}


def sensor_frame(name: str, kind: str) -> str:
    """The frame id of a sensor's data: ``<name>_optical_frame`` for optical kinds, else ``<name>``."""
    return f"{name}_optical_frame" if kind in OPTICAL_KINDS else name


def _mount(cfg: dict) -> tuple[Pose, str | None]:
    m = cfg.get("mount") or {}
    p = m.get("pose") or {}
    pose = Pose.from_quat(p.get("position", (0.0, 0.0, 0.0)), p.get("quat_xyzw", (0.0, 0.0, 0.0, 1.0)))
    return pose, m.get("parent")


def static_sensor_transforms(name: str, kind: str, cfg: dict) -> list[tuple[str, str, Pose]]:
    """(parent, child, pose child -> parent) of a sensor's fixed frames.

    A sensor's mount is fixed on its parent (an object's frame, or the
    world), so every sensor frame is static: optical kinds get
    ``<parent> -> <name>_link`` (REP 103, x forward) and ``<name>_link ->
    <name>_optical_frame``; other kinds ``<parent> -> <name>``.
    """
    pose, parent = _mount(cfg)
    parent = parent or WORLD_FRAME
    if kind not in OPTICAL_KINDS:
        return [(parent, name, pose)]
    link_optical = Pose.from_matrix(_h(R_LINK_OPTICAL))
    # world <- optical = (world <- link) (link <- optical)  =>  world <- link = pose @ optical^-1
    return [(parent, f"{name}_link", pose @ link_optical.inverse()),
            (f"{name}_link", f"{name}_optical_frame", link_optical)]


def _h(r: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = r
    return m


def camera_info(kind: str, cfg: dict) -> dict | None:
    """CameraInfo fields (width, height, distortion_model, d, k, r, p) of a camera or ToF config, else None."""
    inner = cfg.get("config", {})
    if kind == "camera":
        cam = inner["camera"]
        w, h, fx, fy, cx, cy = (cam[k] for k in ("width", "height", "fx", "fy", "cx", "cy"))
        dist = cam.get("distortion", [0.0] * 5)
    elif kind == "tof":
        from twinsense.tof.config import ToFConfig

        tcfg = ToFConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in inner.items()})
        w, h = tcfg.width, tcfg.height
        fx, fy, cx, cy = tcfg.camera_intrinsics
        dist = tcfg.distortion
    else:
        return None
    # twinsense puts pixel centres at integer coordinates, as ROS and OpenCV do: K is used as is.
    # OpenCV's (k1, k2, p1, p2, k3) is ROS's plumb_bob D in the same order.
    return {"width": int(w), "height": int(h), "distortion_model": "plumb_bob",
            "d": [float(x) for x in dist],
            "k": [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
            "r": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            "p": [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]}


def image_32fc1(a: np.ndarray, ns: int, frame_id: str) -> dict:
    """A (H, W) array as a 32FC1 little-endian Image."""
    a = np.ascontiguousarray(a, dtype="<f4")
    h, w = a.shape
    return {"header": _header(ns, frame_id), "height": h, "width": w, "encoding": "32FC1",
            "is_bigendian": 0, "step": 4 * w, "data": a.tobytes()}


def image_mono8(a: np.ndarray, ns: int, frame_id: str) -> dict:
    a = np.ascontiguousarray(a, dtype=np.uint8)
    h, w = a.shape
    return {"header": _header(ns, frame_id), "height": h, "width": w, "encoding": "mono8",
            "is_bigendian": 0, "step": w, "data": a.tobytes()}


def point_cloud_xyzi(xyz: np.ndarray, intensity: np.ndarray, ns: int, frame_id: str) -> dict:
    """An organised (H, W) cloud of float32 x, y, z [m], intensity; NaN marks a pixel without a point."""
    h, w = xyz.shape[:2]
    pts = np.empty((h, w, 4), dtype="<f4")
    pts[..., :3] = xyz
    pts[..., 3] = intensity
    fields = [{"name": n, "offset": 4 * i, "datatype": FLOAT32, "count": 1} for i, n in enumerate("xyz")]
    fields.append({"name": "intensity", "offset": 12, "datatype": FLOAT32, "count": 1})
    return {"header": _header(ns, frame_id), "height": h, "width": w, "fields": fields, "is_bigendian": False,
            "point_step": 16, "row_step": 16 * w, "data": pts.tobytes(),
            "is_dense": bool(np.isfinite(pts[..., :3]).all())}


def _sensor_messages(name: str, s: SensorRecording, k: int, ns: int) -> list[tuple[str, str, dict]]:
    """(topic, message type, message) of frame ``k`` of one sensor."""
    kind, frame_id = s.kind, sensor_frame(name, s.kind)
    out: list[tuple[str, str, dict]] = []
    info = camera_info(kind, s.config)
    if info is not None:
        out.append((f"/{name}/camera_info", "sensor_msgs/msg/CameraInfo",
                    {"header": _header(ns, frame_id), **info, "binning_x": 0, "binning_y": 0,
                     "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False}}))
    if kind == "camera":
        out.append((f"/{name}/depth", "sensor_msgs/msg/Image", image_32fc1(s["depth"][k], ns, frame_id)))
        out.append((f"/{name}/range", "sensor_msgs/msg/Image", image_32fc1(s["range"][k], ns, frame_id)))
    elif kind == "tof":
        amp = s["amplitude"][k]
        out.append((f"/{name}/depth", "sensor_msgs/msg/Image", image_32fc1(s["depth"][k], ns, frame_id)))
        out.append((f"/{name}/amplitude", "sensor_msgs/msg/Image", image_32fc1(amp, ns, frame_id)))
        out.append((f"/{name}/confidence", "sensor_msgs/msg/Image", image_mono8(s["confidence"][k], ns, frame_id)))
        out.append((f"/{name}/points", "sensor_msgs/msg/PointCloud2",
                    point_cloud_xyzi(s["points_sensor"][k], amp, ns, frame_id)))
    elif kind == "radar":
        adc = np.asarray(s["adc"][k])
        if adc.ndim != 3:
            raise TwinsenseError(f"{s!r}: radar 'adc' frames have shape {adc.shape}; expected (rx, chirp, sample)")
        imag = adc.imag.ravel() if np.iscomplexobj(adc) else np.empty(0)
        out.append((f"/{name}/cube", "twinsense_msgs/msg/RadarCube",
                    {"header": _header(ns, frame_id), "n_rx": adc.shape[0], "n_chirps": adc.shape[1],
                     "n_samples": adc.shape[2], "real": adc.real.astype(np.float32).ravel().tolist(),
                     "imag": imag.astype(np.float32).tolist()}))
        if "range_doppler_power" in s.stream_names:
            p = np.asarray(s["range_doppler_power"][k], dtype=np.float32)
            out.append((f"/{name}/range_doppler", "twinsense_msgs/msg/RangeDoppler",
                        {"header": _header(ns, frame_id), "n_doppler": p.shape[0], "n_range": p.shape[1],
                         "power": p.ravel().tolist()}))
    elif kind == "capacitive":
        m = np.asarray(s["maxwell"][k], dtype=np.float64)
        out.append((f"/{name}/frame", "twinsense_msgs/msg/CapacitiveFrame",
                    {"header": _header(ns, frame_id), "channels": list(s.config.get("channels", [])),
                     "channel_values": np.asarray(s["channels"][k], dtype=np.float64).tolist(),
                     "readout": np.asarray(s["readout"][k], dtype=np.float64).tolist(),
                     "delta": np.asarray(s["delta"][k], dtype=np.float64).tolist(),
                     "self_capacitance": np.asarray(s["self_capacitance"][k], dtype=np.float64).tolist(),
                     "n_terminals": m.shape[0], "maxwell": m.ravel().tolist()}))
    else:
        for stream in s.stream_names:
            a = np.asarray(s[stream][k])
            out.append((f"/{name}/{stream}", "twinsense_msgs/msg/ArrayStream",
                        {"header": _header(ns, frame_id), "stream": stream, "shape": list(a.shape),
                         "data": a.astype(np.float64).ravel().tolist()}))
    return out


def write_mcap(rec: Recording, out, scene: Scene | None = None) -> Path:
    """Write the messages of an open recording to ``out`` (an ``.mcap`` path); returns the path.

    ``scene`` (rebuilt from the recording's scenario) adds every object's
    frame to ``/tf`` (moving objects at each frame time) and ``/tf_static``
    (static objects); without it only the sensors' frames are published.
    The file is written under a temporary name beside ``out`` and renamed
    into place when complete.
    """
    writer_cls = _require_mcap()
    out = Path(out)
    if out.suffix != ".mcap":
        raise ConfigError("out", str(out), "a file name ending in .mcap")
    if not out.parent.is_dir():
        raise ConfigError("out", str(out), "a path in an existing folder")
    tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as f:
            _write(writer_cls(f), rec, scene)
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return out


def _write(writer, rec: Recording, scene: Scene | None) -> None:
    schemas: dict[str, Any] = {}

    def emit(topic: str, msgtype: str, msg: dict, ns: int) -> None:
        if msgtype not in schemas:
            schemas[msgtype] = writer.register_msgdef(msgtype, MSGDEFS[msgtype])
        writer.write_message(topic, schemas[msgtype], msg, log_time=ns, publish_time=ns)

    # Frame times of every sensor, on the shared clock.
    events = sorted((stamp_ns(t), name, k) for name, s in rec.sensors.items() for k, t in enumerate(s.timestamps))
    t_first = events[0][0] if events else 0

    static = [tr for name, s in rec.sensors.items() for tr in static_sensor_transforms(name, s.kind, s.config)]
    moving = []
    if scene is not None:
        for obj in scene:
            if obj.is_static:
                static.append((WORLD_FRAME, obj.name, obj.pose_at(0.0)))
            else:
                moving.append(obj)
    emit("/tf_static", "tf2_msgs/msg/TFMessage",
         {"transforms": [_transform(t_first, p, c, pose) for p, c, pose in static]}, t_first)

    last_ns = None
    for ns, name, k in events:
        if ns != last_ns:
            emit("/clock", "rosgraph_msgs/msg/Clock", {"clock": _time(ns)}, ns)
            if moving:
                t = ns * 1e-9
                emit("/tf", "tf2_msgs/msg/TFMessage",
                     {"transforms": [_transform(ns, WORLD_FRAME, o.name, o.pose_at(t)) for o in moving]}, ns)
            last_ns = ns
        for topic, msgtype, msg in _sensor_messages(name, rec[name], k, ns):
            emit(topic, msgtype, msg, ns)
    writer.finish()


def convert(recording, out, scene_from_scenario: Callable[[dict], Scene] | None = None,
            allow_incomplete: bool = False) -> Path:
    """Convert the HDF5 recording at ``recording`` into the MCAP file ``out``.

    ``scene_from_scenario`` builds the scene from the recording's scenario
    (a dict) for the objects' frames on ``/tf``; it is not called when the
    recording has no scenario (a run from the Python API).
    """
    _require_mcap()
    with open_recording(recording, allow_incomplete=allow_incomplete) as rec:
        scenario = rec.scenario
        if isinstance(scenario, str):
            scenario = json.loads(scenario)
        scene = scene_from_scenario(scenario) if scenario and scene_from_scenario is not None else None
        return write_mcap(rec, out, scene)
