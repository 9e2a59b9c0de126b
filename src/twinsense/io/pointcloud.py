"""Point clouds to files: PCD (PCL's format, v0.7, ASCII or binary) and PLY (binary little endian).

A cloud is a mapping ``{field name: (n,) array}`` with at least ``x``,
``y``, ``z`` [m]; every other field (``intensity``, ``range``, ``ring``,
...) is written with its own type. :func:`recording_points` takes the
cloud of one frame of a recorded ToF camera or LiDAR.

PCD header (PCL file format v0.7): ``VERSION``, ``FIELDS``, ``SIZE`` (bytes),
``TYPE`` (F float, I signed, U unsigned), ``COUNT``, ``WIDTH``, ``HEIGHT``,
``VIEWPOINT``, ``POINTS``, ``DATA`` (ascii or binary); binary data is the
points one after the other, each with its fields packed in header order,
little endian. PLY: one ``vertex`` element with one property per field.
Files are written under a temporary name and renamed when complete.
"""

from __future__ import annotations

import io
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.io.recording import SensorRecording

#: numpy dtype -> (PCD TYPE letter, SIZE in bytes).
_PCD_TYPES = {np.dtype(t): (t[0].upper(), np.dtype(t).itemsize)
              for t in ("int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64")}
_PCD_TYPES |= {np.dtype("float32"): ("F", 4), np.dtype("float64"): ("F", 8)}
#: numpy dtype -> PLY property type (PLY has no 64-bit integers).
_PLY_TYPES = {np.dtype("int8"): "char", np.dtype("uint8"): "uchar", np.dtype("int16"): "short",
              np.dtype("uint16"): "ushort", np.dtype("int32"): "int", np.dtype("uint32"): "uint",
              np.dtype("float32"): "float", np.dtype("float64"): "double"}
# ASCII formats that read back to the same value: 9 significant digits for float32, 17 for float64.
_ASCII_FORMAT = {4: "%.9g", 8: "%.17g"}
#: Sensor kinds whose frames hold a point cloud.
POINT_KINDS = ("tof", "lidar")


def _cloud(field: str, fields: Mapping[str, np.ndarray], types: Mapping[np.dtype, object]) -> dict[str, np.ndarray]:
    if not isinstance(fields, Mapping) or not {"x", "y", "z"} <= set(fields):
        raise ConfigError(field, fields if not isinstance(fields, Mapping) else sorted(fields),
                          "a mapping of field name -> (n,) array with at least 'x', 'y' and 'z'")
    out: dict[str, np.ndarray] = {}
    n = None
    for name, value in fields.items():
        if not isinstance(name, str) or not name.isidentifier():
            raise ConfigError(f"{field}[{name!r}]", name, "a field name of letters, digits and '_'")
        a = np.asarray(value)
        if a.dtype == bool:
            a = a.astype(np.uint8)
        if a.ndim != 1:
            raise ConfigError(f"{field}[{name!r}]", f"array of shape {a.shape}", "a (n,) array")
        if a.dtype.newbyteorder("=") not in types:
            raise ConfigError(f"{field}[{name!r}]", str(a.dtype),
                              "one of the types " + ", ".join(sorted(str(t) for t in types)))
        if n is not None and len(a) != n:
            raise ConfigError(f"{field}[{name!r}]", f"{len(a)} values", f"{n} values, as the other fields")
        n = len(a)
        out[name] = a.astype(a.dtype.newbyteorder("<"), copy=False)
    return out


def _records(cloud: Mapping[str, np.ndarray]) -> np.ndarray:
    """The cloud as packed little-endian records, one per point, fields in order."""
    dt = np.dtype([(k, v.dtype.newbyteorder("<")) for k, v in cloud.items()])
    rec = np.empty(len(next(iter(cloud.values()))), dtype=dt)
    for k, v in cloud.items():
        rec[k] = v
    return rec


def _atomic_write(path: Path, data: bytes) -> Path:
    if not path.parent.is_dir():
        raise ConfigError("path", str(path), "a path in an existing folder")
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError as exc:  # a folder of that name, a read-only folder, a full disk: nothing is left behind
        raise ConfigError("path", str(path), f"a writable file path ({exc.strerror})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return path


def write_pcd(path, fields: Mapping[str, np.ndarray], *, binary: bool = True,
              viewpoint: tuple[float, ...] = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)) -> Path:
    """Write a PCD v0.7 file (``DATA binary`` or ``DATA ascii``); returns the path.

    Parameters
    ----------
    fields : mapping of str -> (n,) array
        ``x``, ``y``, ``z`` [m] and any other per-point values (int8..uint64, float32, float64).
    viewpoint : (7,) float
        PCD ``VIEWPOINT``: translation tx ty tz [m] and quaternion qw qx qy qz of the
        acquisition viewpoint (default: identity).
    """
    path = Path(path)
    if path.suffix != ".pcd":
        raise ConfigError("path", str(path), "a file name ending in .pcd")
    cloud = _cloud("fields", fields, _PCD_TYPES)
    vp = np.asarray(viewpoint, dtype=np.float64)
    if vp.shape != (7,) or not np.isfinite(vp).all():
        raise ConfigError("viewpoint", viewpoint, "7 finite numbers: tx ty tz qw qx qy qz")
    n = len(next(iter(cloud.values())))
    types = [_PCD_TYPES[v.dtype.newbyteorder("=")] for v in cloud.values()]
    header = ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
              f"FIELDS {' '.join(cloud)}\nSIZE {' '.join(str(s) for _, s in types)}\n"
              f"TYPE {' '.join(t for t, _ in types)}\nCOUNT {' '.join('1' for _ in cloud)}\n"
              f"WIDTH {n}\nHEIGHT 1\nVIEWPOINT {' '.join(f'{v:.17g}' for v in vp)}\nPOINTS {n}\n"
              f"DATA {'binary' if binary else 'ascii'}\n")
    if binary:
        body = _records(cloud).tobytes()
    else:
        buf = io.BytesIO()
        fmt = " ".join(_ASCII_FORMAT[v.dtype.itemsize] if v.dtype.kind == "f" else "%d" for v in cloud.values())
        if n:
            np.savetxt(buf, _records(cloud), fmt=fmt)
        body = buf.getvalue()
    return _atomic_write(path, header.encode("ascii") + body)


def read_pcd(path) -> dict[str, np.ndarray]:
    """Read a PCD file (v0.7, ``DATA ascii`` or ``binary``, COUNT 1 per field) into ``{field: (n,) array}``."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError("path", str(path), "an existing .pcd file")
    raw = path.read_bytes()
    header: dict[str, list[str]] = {}
    pos = 0
    while True:
        end = raw.find(b"\n", pos)
        if end < 0:
            raise ConfigError("path", str(path), "a PCD file (its header ends with a DATA line)")
        line = raw[pos:end].decode("ascii", "replace").strip()
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, *values = line.split()
        header[key.upper()] = values
        if key.upper() == "DATA":
            break
    try:
        names = header["FIELDS"]
        sizes = [int(s) for s in header["SIZE"]]
        kinds = header["TYPE"]
        counts = [int(c) for c in header.get("COUNT", ["1"] * len(names))]
        n = int(header["POINTS"][0])
        data = header["DATA"][0].lower()
    except (KeyError, IndexError, ValueError) as exc:
        raise ConfigError("path", str(path),
                          f"a PCD v0.7 header with FIELDS, SIZE, TYPE, POINTS and DATA ({exc})") from None
    if not (len(names) == len(sizes) == len(kinds) == len(counts)) or any(c != 1 for c in counts):
        raise ConfigError("path", str(path), "FIELDS, SIZE, TYPE and COUNT of equal length, every COUNT 1")
    letter = {"F": "f", "I": "i", "U": "u"}
    try:
        dt = np.dtype([(nm, f"<{letter[k.upper()]}{s}") for nm, k, s in zip(names, kinds, sizes)])
    except (KeyError, TypeError) as exc:
        raise ConfigError("path", str(path), f"field types F, I or U of 1, 2, 4 or 8 bytes ({exc})") from None
    if data == "binary":
        if len(raw) - pos < n * dt.itemsize:
            raise ConfigError("path", str(path), f"{n} binary points of {dt.itemsize} B (the file is short)")
        rec = np.frombuffer(raw, dtype=dt, count=n, offset=pos)
        return {nm: rec[nm].copy() for nm in names}
    if data == "ascii":
        rows = [r.split() for r in raw[pos:].decode("ascii").splitlines() if r.strip()]
        if len(rows) != n or any(len(r) != len(names) for r in rows):
            raise ConfigError("path", str(path), f"{n} ASCII rows of {len(names)} values")
        cols = list(zip(*rows)) if rows else [[] for _ in names]
        return {nm: np.array(c, dtype=dt[nm]) for nm, c in zip(names, cols)}
    raise UnknownNameError("PCD DATA", data, ["ascii", "binary"])


def write_ply(path, fields: Mapping[str, np.ndarray]) -> Path:
    """Write a binary little-endian PLY file with one ``vertex`` element; returns the path.

    ``fields`` as for :func:`write_pcd`; PLY has no 64-bit integers (int8..uint32, float32, float64).
    """
    path = Path(path)
    if path.suffix != ".ply":
        raise ConfigError("path", str(path), "a file name ending in .ply")
    cloud = _cloud("fields", fields, _PLY_TYPES)
    n = len(next(iter(cloud.values())))
    header = ("ply\nformat binary_little_endian 1.0\ncomment twinsense point cloud\n"
              f"element vertex {n}\n"
              + "".join(f"property {_PLY_TYPES[v.dtype.newbyteorder('=')]} {k}\n" for k, v in cloud.items())
              + "end_header\n")
    return _atomic_write(path, header.encode("ascii") + _records(cloud).tobytes())


def recording_points(sensor: SensorRecording, frame: int, coords: str = "world") -> dict[str, np.ndarray]:
    """The point cloud of frame ``frame`` of a recorded ToF camera or LiDAR.

    Parameters
    ----------
    coords : "world" or "sensor"
        Frame of x, y, z [m]: the world, or the sensor's own (optical for ToF).

    Returns
    -------
    dict of (n,) arrays
        ToF (valid pixels, row-major): x, y, z (float32), intensity (amplitude
        [DN], float32), confidence (uint8), row, col (uint16). LiDAR (every
        echo): x, y, z (float32), intensity (uint8), range [m] (float32), ring
        (uint16), echo (uint8), time [s] (float64, firing time).
    """
    if coords not in ("world", "sensor"):
        raise UnknownNameError("coords", coords, ["world", "sensor"])
    if sensor.kind not in POINT_KINDS:
        raise ConfigError("sensor", f"{sensor.name} (kind {sensor.kind!r})",
                          f"a sensor of a kind with point clouds: {', '.join(POINT_KINDS)}")
    n = len(sensor)
    if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)) or not 0 <= frame < n:
        raise ConfigError("frame", frame, f"a frame index 0..{n - 1}" if n else "a frame (the sensor has none)")
    if sensor.kind == "tof":
        xyz = sensor["points_world" if coords == "world" else "points_sensor"][frame]
        valid = (sensor["invalid"][frame] == 0) & np.isfinite(xyz).all(axis=-1)
        row, col = np.nonzero(valid)
        p = xyz[valid].astype(np.float32)
        return {"x": p[:, 0], "y": p[:, 1], "z": p[:, 2],
                "intensity": sensor["amplitude"][frame][valid].astype(np.float32),
                "confidence": sensor["confidence"][frame][valid].astype(np.uint8),
                "row": row.astype(np.uint16), "col": col.astype(np.uint16)}
    rng = sensor["range"][frame]
    fire, echo = np.nonzero(np.isfinite(rng))
    p = sensor["xyz_world" if coords == "world" else "xyz"][frame][fire, echo].astype(np.float32)
    return {"x": p[:, 0], "y": p[:, 1], "z": p[:, 2],
            "intensity": sensor["intensity"][frame][fire, echo].astype(np.uint8),
            "range": rng[fire, echo].astype(np.float32),
            "ring": sensor["ring"][frame][fire].astype(np.uint16),
            "echo": echo.astype(np.uint8),
            "time": sensor["time"][frame][fire].astype(np.float64)}


def export(sensor: SensorRecording, frame: int, out, coords: str = "world", binary: bool = True) -> Path:
    """Write frame ``frame`` of a recorded ToF camera or LiDAR to ``out`` (``.pcd`` or ``.ply``)."""
    out = Path(out)
    if out.suffix not in (".pcd", ".ply"):
        raise ConfigError("out", str(out), "a file name ending in .pcd or .ply")
    cloud = recording_points(sensor, frame, coords)
    return write_pcd(out, cloud, binary=binary) if out.suffix == ".pcd" else write_ply(out, cloud)
