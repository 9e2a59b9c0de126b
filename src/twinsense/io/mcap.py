"""ROS 2 recordings: a twinsense HDF5 recording converted to an MCAP file.

Messages are ROS 2 messages (``ros2msg`` schemas, CDR encoding) written with
the ``mcap`` and ``mcap-ros2-support`` libraries (the ``ros2`` extra). The
converter reads only the recording: each sensor's streams and its
``config`` JSON, and, for the poses of the scene's objects and mount frames
on ``/tf``, their geometry on ``/scene_markers``, the joint states of its robots and people, and radar
detections (derived from the recorded ADC codes), the scene and
sensors the caller rebuilds from the recording's scenario (``twinsense
convert`` does this). One builder per sensor kind makes its messages
(:data:`KIND_MESSAGES`, :func:`register_messages` for a new kind). Topics,
frames and message layouts are described in docs/ros2-mcap.md.
"""

from __future__ import annotations

import array
import functools
import json
import os
import re
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
POINT_FIELD_TYPES = {"i1": 1, "u1": 2, "i2": 3, "u2": 4, "i4": 5, "u4": 6, "f4": 7, "f8": 8}

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
    "sensor_msgs/msg/MagneticField": _with_deps(
        "std_msgs/Header header\ngeometry_msgs/Vector3 magnetic_field\nfloat64[9] magnetic_field_covariance\n",
        *_HEADER_DEPS, ("geometry_msgs/Vector3", _VEC)),
    "sensor_msgs/msg/JointState": _with_deps(
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n",
        *_HEADER_DEPS),
    "visualization_msgs/msg/MarkerArray": _with_deps(
        "visualization_msgs/Marker[] markers\n",
        ("visualization_msgs/Marker",
         "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\nint32 LINE_LIST=5\n"
         "int32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\nint32 TEXT_VIEW_FACING=9\nint32 MESH_RESOURCE=10\n"
         "int32 TRIANGLE_LIST=11\nint32 ADD=0\nint32 MODIFY=0\nint32 DELETE=2\nint32 DELETEALL=3\n"
         "std_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\ngeometry_msgs/Pose pose\n"
         "geometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\nbuiltin_interfaces/Duration lifetime\n"
         "bool frame_locked\ngeometry_msgs/Point[] points\nstd_msgs/ColorRGBA[] colors\nstring texture_resource\n"
         "sensor_msgs/CompressedImage texture\nvisualization_msgs/UVCoordinate[] uv_coordinates\nstring text\n"
         "string mesh_resource\nvisualization_msgs/MeshFile mesh_file\nbool mesh_use_embedded_materials\n"),
        *_HEADER_DEPS,
        ("geometry_msgs/Pose", "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n"),
        ("geometry_msgs/Point", _VEC), ("geometry_msgs/Quaternion", _QUAT), ("geometry_msgs/Vector3", _VEC),
        ("std_msgs/ColorRGBA", "float32 r\nfloat32 g\nfloat32 b\nfloat32 a\n"),
        ("builtin_interfaces/Duration", _TIME),
        ("sensor_msgs/CompressedImage", "std_msgs/Header header\nstring format\nuint8[] data\n"),
        ("visualization_msgs/UVCoordinate", "float32 u\nfloat32 v\n"),
        ("visualization_msgs/MeshFile", "string filename\nuint8[] data\n")),
}

_RADAR_CUBE = ("std_msgs/Header header\nuint32 n_rx\nuint32 n_chirps\nuint32 n_samples\n"
               "float32[] real\nfloat32[] imag\n")
_RANGE_DOPPLER = "std_msgs/Header header\nuint32 n_doppler\nuint32 n_range\nfloat32[] power\n"
_CAPACITIVE = ("std_msgs/Header header\nstring[] channels\nfloat64[] channel_values\nfloat64[] readout\n"
               "float64[] delta\nfloat64[] self_capacitance\nuint32 n_terminals\nfloat64[] maxwell\n")
_ARRAY = "std_msgs/Header header\nstring stream\nuint32[] shape\nfloat64[] data\n"
_ULTRASONIC = ("std_msgs/Header header\nuint32 n_transducers\nuint32 n_samples\nfloat64 sample_rate\n"
               "float32[] ascan\nfloat32[] envelope\nfloat32[] first_echo_distance\nfloat64[] fire_time\n")
_MAGNETIC = ("std_msgs/Header header\nuint32 n_elements\nuint32 n_axes\nfloat64[] field_true\nfloat64[] field\n"
             "float64[] raw\n")
_INDUCTIVE = ("std_msgs/Header header\nbool output\nfloat64 quality\nfloat64 delta_r\nfloat64 delta_l\n"
              "float64 frequency\n")

#: The package's own messages: name -> definition (the field lines of docs/msg/<Name>.msg).
TWINSENSE_MSGS: dict[str, str] = {
    "twinsense_msgs/msg/RadarCube": _RADAR_CUBE,
    "twinsense_msgs/msg/RangeDoppler": _RANGE_DOPPLER,
    "twinsense_msgs/msg/CapacitiveFrame": _CAPACITIVE,
    "twinsense_msgs/msg/ArrayStream": _ARRAY,
    "twinsense_msgs/msg/UltrasonicFrame": _ULTRASONIC,
    "twinsense_msgs/msg/MagneticFrame": _MAGNETIC,
    "twinsense_msgs/msg/InductiveFrame": _INDUCTIVE,
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


def _f4(a) -> array.array:
    """A float32[] field: the writer takes an ``array.array`` as is (no per-element Python objects)."""
    return array.array("f", np.ascontiguousarray(a, dtype="<f4").ravel().tobytes())


def _f8(a) -> array.array:
    """A float64[] field (see :func:`_f4`)."""
    return array.array("d", np.ascontiguousarray(a, dtype="<f8").ravel().tobytes())


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


def scene_transforms(scene: Scene) -> tuple[list[tuple[str, str, Pose]], list]:
    """Every scene object and mount frame as a child of ``world``: (static transforms, moving items).

    Static items come as (``world``, name, pose item -> world); moving ones
    (objects and frames whose motion is not static: robot links, flanges,
    sites, people) as the items themselves, to be posed at each frame time
    with ``item.pose_at(t)``. Mount frames are what links without geometry
    become (a flange such as ``ur5/tool0``, a geomless MJCF body, a co-simulation's site): sensors hang from
    them, so they are published like the objects.
    """
    static: list[tuple[str, str, Pose]] = []
    moving: list = []
    eye = np.eye(4)
    for item in (*scene.objects, *scene.frames):
        if item.name == WORLD_FRAME:
            # MuJoCo's world body (its geoms) is the world frame itself: world -> world would be a loop.
            if item.motion.is_static and np.array_equal(item.pose_at(0.0).matrix, eye):
                continue
            raise ConfigError(f"scene[{item.name!r}].name", item.name,
                              f"a name other than {WORLD_FRAME!r} (the root frame of /tf) for an item "
                              "that is not at the world origin")
        if item.motion.is_static:
            static.append((WORLD_FRAME, item.name, item.pose_at(0.0)))
        else:
            moving.append(item)
    return static, moving


#: Colour (r, g, b, a in 0..1) of a scene object's geometry by its material's name, on the Foxglove
#: ``/scene`` topic and the MCAP ``/scene_markers`` topic (docs/streaming.md lists them). Metals are greys
#: (aluminium lightest), copper and brass their own hues, glass translucent; a material not listed (a
#: user's) is :data:`OTHER_COLOR`.
MATERIAL_COLORS: dict[str, tuple[float, float, float, float]] = {
    "metal": (0.50, 0.52, 0.55, 1.0), "mild_steel": (0.50, 0.52, 0.55, 1.0),
    "floating_metal": (0.45, 0.47, 0.62, 1.0), "stainless_steel": (0.66, 0.68, 0.70, 1.0),
    "aluminium": (0.78, 0.80, 0.83, 1.0), "brass": (0.78, 0.64, 0.28, 1.0), "copper": (0.72, 0.44, 0.20, 1.0),
    "wood": (0.60, 0.42, 0.24, 1.0), "drywall": (0.92, 0.91, 0.87, 1.0), "concrete": (0.58, 0.58, 0.56, 1.0),
    "plastic": (0.25, 0.45, 0.80, 1.0), "glass": (0.70, 0.85, 0.95, 0.35), "fabric": (0.55, 0.30, 0.45, 1.0),
    "human_skin": (0.90, 0.72, 0.60, 1.0), "human": (0.90, 0.72, 0.60, 1.0),
    "ir_reflector": (0.95, 0.90, 0.30, 1.0), "corner_reflector": (0.85, 0.20, 0.20, 1.0),
    "radar_corner_reflector": (0.85, 0.20, 0.20, 1.0), "silicone": (0.85, 0.85, 0.80, 1.0),
    "air": (1.0, 1.0, 1.0, 0.1),
}
#: Colour of a material :data:`MATERIAL_COLORS` does not list.
OTHER_COLOR = (0.70, 0.70, 0.70, 1.0)


def material_color(material) -> tuple[float, float, float, float]:
    """(r, g, b, a) in 0..1 of a material (a ``Material`` or its name): :data:`MATERIAL_COLORS`."""
    return MATERIAL_COLORS.get(getattr(material, "name", material), OTHER_COLOR)


def scene_triangles(obj) -> np.ndarray:
    """(3 m, 3) float64 [m]: the corners of each of an object's m mesh triangles, in the object's frame.

    Triangle after triangle (faces' vertices in order), as ``TRIANGLE_LIST`` markers list them: the same
    mesh the sensors see (``obj.geometry.mesh``), vertex values copied as they are.
    """
    mesh = obj.geometry.mesh
    return np.asarray(mesh.vertices, dtype=np.float64)[np.asarray(mesh.faces).ravel()]


#: ``ns`` of the scene's markers.
SCENE_MARKER_NS = "twinsense/scene"


def scene_markers(scene: Scene, ns: int) -> dict:
    """A ``visualization_msgs/MarkerArray`` of every scene object's geometry, stamped ``ns``.

    One ``TRIANGLE_LIST`` marker per object (``id`` its index in ``scene.objects``, ``ns``
    :data:`SCENE_MARKER_NS`), in the object's own frame (``frame_id`` = its name, the child frame
    ``/tf`` and ``/tf_static`` publish) at the identity pose, ``frame_locked`` so that it follows that
    frame; ``points`` the triangles' corners (:func:`scene_triangles`), ``scale`` 1, ``color`` the
    material's (:data:`MATERIAL_COLORS`), ``lifetime`` 0 (for ever).
    """
    zero = {"x": 0.0, "y": 0.0, "z": 0.0}
    empty_header = _header(0, "")
    markers = []
    for i, o in enumerate(scene.objects):
        r, g, b, a = material_color(o.material)
        markers.append({
            "header": _header(ns, o.name), "ns": SCENE_MARKER_NS, "id": i, "type": 11, "action": 0,
            "pose": {"position": zero, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
            "scale": {"x": 1.0, "y": 1.0, "z": 1.0}, "color": {"r": r, "g": g, "b": b, "a": a},
            "lifetime": {"sec": 0, "nanosec": 0}, "frame_locked": True,
            "points": [{"x": x, "y": y, "z": z} for x, y, z in scene_triangles(o).tolist()], "colors": [],
            "texture_resource": "", "texture": {"header": empty_header, "format": "", "data": b""},
            "uv_coordinates": [], "text": "", "mesh_resource": "", "mesh_file": {"filename": "", "data": b""},
            "mesh_use_embedded_materials": False})
    return {"markers": markers}


def body_frame(body) -> str:
    """The frame id of an articulated body's joint states: its root link, ``<body>/<root link>``."""
    return f"{body.name}/{body.tree.root}"


def joint_state(body, ns: int) -> dict:
    """A ``sensor_msgs/JointState`` of an articulated body at stamp ``ns``.

    ``name``: the driven joints (``tree.joint_names``); ``position`` [rad or m]
    and ``velocity`` [rad/s or m/s] as the body evaluates them at t = ns 1e-9 s
    (``body.joint_state``: joints the motion does not drive held at home);
    ``effort`` empty (the kinematic model has no forces). The header's
    frame is the body's root link (the message is not placed in space;
    ROS tools ignore it).
    """
    q, qd = body.joint_state(ns * 1e-9)
    return {"header": _header(ns, body_frame(body)), "name": list(body.tree.joint_names),
            "position": _f8(q), "velocity": _f8(qd), "effort": _f8(np.empty(0))}


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


def pack_columns(columns: list[tuple[str, np.ndarray]]) -> tuple[np.ndarray, list[tuple[str, int, str]]]:
    """Named (m,) columns packed as little-endian records: (structured array, [(name, offset, "f4"...)]).

    The type codes are numpy kind + size (``"f4"``, ``"u1"``, ...), one of
    :data:`POINT_FIELD_TYPES`; the record size is ``array.dtype.itemsize``.
    """
    dtype = np.dtype([(n, np.asarray(a).dtype.newbyteorder("<")) for n, a in columns])
    pts = np.empty(len(columns[0][1]) if columns else 0, dtype=dtype)
    layout = []
    for n, a in columns:
        pts[n] = a
        dt, off = dtype.fields[n]
        code = f"{dt.kind}{dt.itemsize}"
        if code not in POINT_FIELD_TYPES:
            raise ConfigError(f"point_cloud.{n}", str(dt), "int8..int32, uint8..uint32, float32 or float64")
        layout.append((n, off, code))
    return pts, layout


def point_cloud(columns: list[tuple[str, np.ndarray]], ns: int, frame_id: str,
                shape: tuple[int, int] | None = None) -> dict:
    """A PointCloud2 of named per-point columns, packed in the given order.

    ``columns``: (field name, (m,) array); each keeps its dtype (little-endian;
    int8..float64 map to the PointField datatypes). ``shape``: (height, width)
    of an organised cloud (default one row of m points). ``is_dense`` is false
    when an x, y or z value is not finite.
    """
    pts, layout = pack_columns(columns)
    h, w = shape if shape is not None else (1, len(pts))
    fields = [{"name": n, "offset": off, "datatype": POINT_FIELD_TYPES[code], "count": 1} for n, off, code in layout]
    dense = all(bool(np.isfinite(pts[n]).all()) for n in "xyz" if n in pts.dtype.names)
    step = pts.dtype.itemsize
    return {"header": _header(ns, frame_id), "height": h, "width": w, "fields": fields, "is_bigendian": False,
            "point_step": step, "row_step": step * w, "data": pts.tobytes(), "is_dense": dense}


def point_cloud_xyzi(xyz: np.ndarray, intensity: np.ndarray, ns: int, frame_id: str) -> dict:
    """An organised (H, W) cloud of float32 x, y, z [m], intensity; NaN marks a pixel without a point."""
    h, w = xyz.shape[:2]
    xyz = np.asarray(xyz, dtype=np.float32).reshape(-1, 3)
    return point_cloud([("x", xyz[:, 0]), ("y", xyz[:, 1]), ("z", xyz[:, 2]),
                        ("intensity", np.asarray(intensity, dtype=np.float32).ravel())], ns, frame_id, (h, w))


def radar_detection_columns(det) -> list[tuple[str, np.ndarray]]:
    """PointCloud2 columns of radar detections (a ``RadarPointCloud``), in the REP 103 link frame.

    x forward, y left, z up [m] (the optical sensor-frame points rotated by
    :data:`R_LINK_OPTICAL`), range [m], radial_velocity [m/s] (positive
    away), snr [dB]; all float32.
    """
    p = np.asarray(det.points_sensor, dtype=np.float64).reshape(-1, 3) @ R_LINK_OPTICAL.T
    f4 = np.float32
    return [("x", p[:, 0].astype(f4)), ("y", p[:, 1].astype(f4)), ("z", p[:, 2].astype(f4)),
            ("range", np.asarray(det.range, dtype=f4)), ("radial_velocity", np.asarray(det.velocity, dtype=f4)),
            ("snr", np.asarray(det.snr_db, dtype=f4))]


def lidar_columns(xyz: np.ndarray, intensity: np.ndarray, ring: np.ndarray, time: np.ndarray,
                  rng: np.ndarray, t: float) -> list[tuple[str, np.ndarray]]:
    """PointCloud2 columns of one LiDAR frame's echoes (empty slots left out), in firing order.

    ``xyz`` (n, E, 3), ``intensity`` / ``rng`` (n, E), ``ring`` / ``time``
    (n,) as in :class:`~twinsense.lidar.frame.LidarFrame`. Columns: x, y, z
    [m] float32 (sensor frame), intensity uint8 (the device's 0-255 scale),
    ring uint16, time float32 [s] after the frame stamp ``t`` (the per-point
    offset drivers publish; float32 keeps 10 ns over a 0.1 s revolution).
    """
    row, echo = np.nonzero(np.isfinite(rng))
    p = np.asarray(xyz, dtype=np.float32)[row, echo]
    return [("x", p[:, 0]), ("y", p[:, 1]), ("z", p[:, 2]),
            ("intensity", np.asarray(intensity, dtype=np.uint8)[row, echo]),
            ("ring", np.asarray(ring)[row].astype(np.uint16)),
            ("time", (np.asarray(time, dtype=np.float64)[row] - t).astype(np.float32))]


#: One message of the topic list: (topic, message type, message).
Message = tuple[str, str, dict]
#: ``builder(name, sensor_recording, k, ns, frame_id, sensor) -> [Message]``: frame ``k`` of one sensor.
#: ``sensor`` is the sensor rebuilt from the recording's scenario, or None.
MessageBuilder = Callable[[str, SensorRecording, int, int, str, Any], list[Message]]


def _camera_messages(name, s, k, ns, frame_id, sensor) -> list[Message]:
    return [(f"/{name}/depth", "sensor_msgs/msg/Image", image_32fc1(s["depth"][k], ns, frame_id)),
            (f"/{name}/range", "sensor_msgs/msg/Image", image_32fc1(s["range"][k], ns, frame_id))]


def _tof_messages(name, s, k, ns, frame_id, sensor) -> list[Message]:
    amp = s["amplitude"][k]
    return [(f"/{name}/depth", "sensor_msgs/msg/Image", image_32fc1(s["depth"][k], ns, frame_id)),
            (f"/{name}/amplitude", "sensor_msgs/msg/Image", image_32fc1(amp, ns, frame_id)),
            (f"/{name}/confidence", "sensor_msgs/msg/Image", image_mono8(s["confidence"][k], ns, frame_id)),
            (f"/{name}/points", "sensor_msgs/msg/PointCloud2",
             point_cloud_xyzi(s["points_sensor"][k], amp, ns, frame_id))]


def _radar_messages(name, s, k, ns, frame_id, sensor) -> list[Message]:
    out: list[Message] = []
    adc = np.asarray(s["adc"][k])
    if adc.ndim != 3:
        raise TwinsenseError(f"{s!r}: radar 'adc' frames have shape {adc.shape}; expected (rx, chirp, sample)")
    imag = adc.imag.ravel() if np.iscomplexobj(adc) else np.empty(0)
    out.append((f"/{name}/cube", "twinsense_msgs/msg/RadarCube",
                {"header": _header(ns, frame_id), "n_rx": adc.shape[0], "n_chirps": adc.shape[1],
                 "n_samples": adc.shape[2], "real": _f4(adc.real),
                 "imag": _f4(imag)}))
    if "range_doppler_power" in s.stream_names:
        p = np.asarray(s["range_doppler_power"][k], dtype=np.float32)
        out.append((f"/{name}/range_doppler", "twinsense_msgs/msg/RangeDoppler",
                    {"header": _header(ns, frame_id), "n_doppler": p.shape[0], "n_range": p.shape[1],
                     "power": _f4(p)}))
    if sensor is not None and getattr(sensor, "process", False):
        # The recording keeps the ADC codes, not the detections: the radar rebuilt from the scenario runs
        # its processing chain on the recorded codes, the same deterministic chain as in the run.
        from twinsense.radar.effects import codes_to_voltage

        det = sensor.process_cube(codes_to_voltage(adc, sensor.config.if_chain)).detections
        out.append((f"/{name}/detections", "sensor_msgs/msg/PointCloud2",
                    point_cloud(radar_detection_columns(det), ns, f"{name}_link")))
    return out


def _capacitive_messages(name, s, k, ns, frame_id, sensor) -> list[Message]:
    m = np.asarray(s["maxwell"][k], dtype=np.float64)
    return [(f"/{name}/frame", "twinsense_msgs/msg/CapacitiveFrame",
             {"header": _header(ns, frame_id), "channels": list(s.config.get("channels", [])),
              "channel_values": _f8(s["channels"][k]), "readout": _f8(s["readout"][k]),
              "delta": _f8(s["delta"][k]), "self_capacitance": _f8(s["self_capacitance"][k]),
              "n_terminals": m.shape[0], "maxwell": _f8(m)})]


def _lidar_messages(name, s, k, ns, frame_id, sensor) -> list[Message]:
    cols = lidar_columns(s["xyz"][k], s["intensity"][k], s["ring"][k], s["time"][k], s["range"][k],
                         float(s.timestamps[k]))
    return [(f"/{name}/points", "sensor_msgs/msg/PointCloud2", point_cloud(cols, ns, frame_id))]


def _ultrasonic_messages(name, s, k, ns, frame_id, sensor) -> list[Message]:
    ascan = np.asarray(s["ascan"][k], dtype=np.float32)
    return [(f"/{name}/frame", "twinsense_msgs/msg/UltrasonicFrame",
             {"header": _header(ns, frame_id), "n_transducers": ascan.shape[0], "n_samples": ascan.shape[1],
              "sample_rate": float(s.config.get("config", {}).get("sample_rate", 0.0)),
              "ascan": _f4(ascan), "envelope": _f4(s["envelope"][k]),
              "first_echo_distance": _f4(s["first_echo_distance"][k]),
              "fire_time": _f8(s["fire_time"][k])})]


def _magnetic_messages(name, s, k, ns, frame_id, sensor) -> list[Message]:
    field = np.asarray(s["field"][k], dtype=np.float64)
    out: list[Message] = [(f"/{name}/frame", "twinsense_msgs/msg/MagneticFrame",
                           {"header": _header(ns, frame_id), "n_elements": field.shape[0],
                            "n_axes": field.shape[1],
                            "field_true": _f8(s["field_true"][k]),
                            "field": _f8(field), "raw": _f8(s["raw"][k])})]
    if field.shape == (1, 3):
        # A single 3-axis element is what sensor_msgs/MagneticField describes; the covariance is left
        # all zero ("unknown" in ROS).
        x, y, z = (float(v) for v in field[0])
        out.append((f"/{name}/magnetic_field", "sensor_msgs/msg/MagneticField",
                    {"header": _header(ns, frame_id), "magnetic_field": {"x": x, "y": y, "z": z},
                     "magnetic_field_covariance": [0.0] * 9}))
    return out


def _inductive_messages(name, s, k, ns, frame_id, sensor) -> list[Message]:
    v = {st: np.asarray(s[st][k]).ravel()[0] for st in ("output", "quality", "delta_r", "delta_l", "frequency")}
    return [(f"/{name}/frame", "twinsense_msgs/msg/InductiveFrame",
             {"header": _header(ns, frame_id), "output": bool(v["output"]),
              **{st: float(v[st]) for st in ("quality", "delta_r", "delta_l", "frequency")}})]


def array_stream_messages(name, s, k, ns, frame_id, sensor) -> list[Message]:
    """One ``ArrayStream`` per recorded stream: the fallback of a kind without its own builder."""
    out: list[Message] = []
    for stream in s.stream_names:
        a = np.asarray(s[stream][k])
        out.append((f"/{name}/{stream}", "twinsense_msgs/msg/ArrayStream",
                    {"header": _header(ns, frame_id), "stream": stream, "shape": list(a.shape),
                     "data": _f8(a)}))
    return out


#: Sensor kind -> message builder. A kind not listed (a user-defined sensor) is written with
#: :func:`array_stream_messages`; :func:`register_messages` adds a kind (e.g. tactile arrays).
KIND_MESSAGES: dict[str, MessageBuilder] = {
    "camera": _camera_messages, "tof": _tof_messages, "radar": _radar_messages,
    "capacitive": _capacitive_messages, "lidar": _lidar_messages, "ultrasonic": _ultrasonic_messages,
    "magnetic": _magnetic_messages, "inductive": _inductive_messages,
}


def register_messages(kind: str, builder: MessageBuilder, msgdefs: dict[str, str] | None = None) -> None:
    """Write frames of sensor ``kind`` with ``builder`` (replacing any earlier one).

    ``msgdefs``: message type -> ROS 2 ``.msg`` definition for the types the
    builder emits that are not already in :data:`MSGDEFS`: the field lines
    (as in docs/msg/), to which the ``std_msgs/Header`` and
    ``builtin_interfaces/Time`` definitions are appended, or a complete
    definition with its dependencies after ``====`` separators.
    """
    if not isinstance(kind, str) or not kind:
        raise ConfigError("kind", kind, "a sensor kind name (non-empty str)")
    if not callable(builder):
        raise ConfigError("builder", builder, "a callable (name, recording, k, ns, frame_id, sensor) -> messages")
    for msgtype, text in (msgdefs or {}).items():
        if not isinstance(text, str) or msgtype.count("/") != 2:
            raise ConfigError(f"msgdefs[{msgtype!r}]", text, "'package/msg/Name': a .msg definition (str)")
        MSGDEFS[msgtype] = text if "\nMSG: " in text else _with_deps(text, *_HEADER_DEPS)
    KIND_MESSAGES[kind] = builder


def _sensor_messages(name: str, s: SensorRecording, k: int, ns: int, sensor: Any = None) -> list[Message]:
    """(topic, message type, message) of frame ``k`` of one sensor."""
    kind, frame_id = s.kind, sensor_frame(name, s.kind)
    out: list[Message] = []
    info = camera_info(kind, s.config)
    if info is not None:
        out.append((f"/{name}/camera_info", "sensor_msgs/msg/CameraInfo",
                    {"header": _header(ns, frame_id), **info, "binning_x": 0, "binning_y": 0,
                     "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False}}))
    out += KIND_MESSAGES.get(kind, array_stream_messages)(name, s, k, ns, frame_id, sensor)
    return out


_TOPIC_CHARS = re.compile(r"[^A-Za-z0-9_/]")


@functools.lru_cache(maxsize=1024)
def ros_topic(topic: str) -> str:
    """``topic`` as a valid ROS 2 topic name: a character other than a letter, digit, ``_`` or
    ``/`` becomes ``_``, a name token starting with a digit gets a leading ``_``, and empty
    tokens go ("/my-robot/joint_states" -> "/my_robot/joint_states"; a sensor or robot name
    may hold what ROS 2 refuses in a topic, and ROS 2 tools refuse such a file's topics)."""
    tokens = [t for t in _TOPIC_CHARS.sub("_", topic).split("/") if t]
    return "/" + "/".join("_" + t if t[0].isdigit() else t for t in tokens)


def write_mcap(rec: Recording, out, scene: Scene | None = None, sensors: dict[str, Any] | None = None) -> Path:
    """Write the messages of an open recording to ``out`` (an ``.mcap`` path); returns the path.

    ``scene`` (rebuilt from the recording's scenario) adds every object's
    and mount frame's transform (robot links without geometry, sites) to
    ``/tf`` (moving ones at each frame time) and ``/tf_static`` (static
    ones), and one ``/<body>/joint_states`` per articulated body (robots,
    people) at each frame time (a body at rest too); without it only the
    sensors' frames are published. With a scene of objects, ``/scene_markers`` carries their geometry
    once, at the first frame time (:func:`scene_markers`).
    ``sensors`` (name -> sensor, rebuilt from the same scenario) lets a
    builder derive what the recording does not store: radar detections.
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
            _write(writer_cls(f), rec, scene, sensors or {})
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return out


def _write(writer, rec: Recording, scene: Scene | None, sensors: dict[str, Any]) -> None:
    schemas: dict[str, Any] = {}

    def emit(topic: str, msgtype: str, msg: dict, ns: int) -> None:
        if msgtype not in schemas:
            schemas[msgtype] = writer.register_msgdef(msgtype, MSGDEFS[msgtype])
        writer.write_message(ros_topic(topic), schemas[msgtype], msg, log_time=ns, publish_time=ns)

    # Frame times of every sensor, on the shared clock.
    events = sorted((stamp_ns(t), name, k) for name, s in rec.sensors.items() for k, t in enumerate(s.timestamps))
    t_first = events[0][0] if events else 0

    static = [tr for name, s in rec.sensors.items() for tr in static_sensor_transforms(name, s.kind, s.config)]
    moving: list = []
    bodies: tuple = ()
    if scene is not None:
        items, moving = scene_transforms(scene)
        static += items
        bodies = scene.articulated_bodies
    emit("/tf_static", "tf2_msgs/msg/TFMessage",
         {"transforms": [_transform(t_first, p, c, pose) for p, c, pose in static]}, t_first)
    if scene is not None and len(scene):
        # The geometry once, at the start: each marker is frame-locked to its object's /tf frame.
        emit("/scene_markers", "visualization_msgs/msg/MarkerArray", scene_markers(scene, t_first), t_first)

    last_ns = None
    for ns, name, k in events:
        if ns != last_ns:
            emit("/clock", "rosgraph_msgs/msg/Clock", {"clock": _time(ns)}, ns)
            if moving:
                t = ns * 1e-9
                emit("/tf", "tf2_msgs/msg/TFMessage",
                     {"transforms": [_transform(ns, WORLD_FRAME, o.name, o.pose_at(t)) for o in moving]}, ns)
            for body in bodies:
                emit(f"/{body.name}/joint_states", "sensor_msgs/msg/JointState", joint_state(body, ns), ns)
            last_ns = ns
        for topic, msgtype, msg in _sensor_messages(name, rec[name], k, ns, sensors.get(name)):
            emit(topic, msgtype, msg, ns)
    writer.finish()


def convert(recording, out, scene_from_scenario: Callable[[dict], Any] | None = None,
            allow_incomplete: bool = False) -> Path:
    """Convert the HDF5 recording at ``recording`` into the MCAP file ``out``.

    ``scene_from_scenario`` builds, from the recording's scenario (a dict),
    the scene (for the objects' frames on ``/tf``) or a whole scenario (an
    object with ``.scene`` and ``.sensors``, e.g.
    :func:`twinsense.scenario.scenario_from_dict`): its sensors then add
    what is derived from the recorded streams (radar detections). It is not
    called when the recording has no scenario (a run from the Python API).
    """
    _require_mcap()
    with open_recording(recording, allow_incomplete=allow_incomplete) as rec:
        scenario = rec.scenario
        if isinstance(scenario, str):
            scenario = json.loads(scenario)
        built = scene_from_scenario(scenario) if scenario and scene_from_scenario is not None else None
        scene, sensors = built, None
        if built is not None and not isinstance(built, Scene):
            scene, sensors = built.scene, {s.name: s for s in built.sensors}
        return write_mcap(rec, out, scene, sensors)
