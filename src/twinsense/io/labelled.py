"""A recording's sensors as labelled arrays (``xarray.Dataset``, one per sensor).

Every stream becomes a data variable with named dimensions: ``time`` (the
frame axis, coordinate = the sensor's timestamps [s]) followed by the
stream's own axes, named per sensor kind in :data:`DIMS` (``row``/``col``,
``rx``/``chirp``/``sample``, ``channel``, ...). Coordinates are added where
the recording defines them: ``range`` [m] of the radar range bins,
``channel`` and ``electrode`` names of a capacitive sensor, ``component`` (x, y, z) and
magnetic ``axis`` labels, ``sample_time`` [s] of ultrasonic A-scans.
A stream of a kind or shape not in the table gets dimensions
``<stream>_dim<i>``. LiDAR's per-firing ``time`` stream is named
``firing_time`` (``time`` is the frame dimension).

xarray is an optional dependency (``pip install 'twinsense[xarray]'``). The
arrays are read into memory.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from twinsense.errors import ConfigError

_IMAGE = ("row", "col")
#: (sensor kind, stream) -> names of the stream's axes after ``time``.
DIMS: dict[tuple[str, str], tuple[str, ...]] = {
    **{("tof", s): _IMAGE for s in ("gray", "amplitude", "distance", "depth", "noise", "confidence", "invalid")},
    ("tof", "raw"): ("frequency", "tap", "row", "col"),
    ("tof", "raw_times"): ("raw_frame",),
    ("tof", "points_sensor"): ("row", "col", "component"),
    ("tof", "points_world"): ("row", "col", "component"),
    ("tof", "pose"): ("pose_row", "pose_col"),
    **{("camera", s): _IMAGE for s in ("range", "depth", "object_id")},
    ("radar", "adc"): ("rx", "chirp", "sample"),
    ("radar", "range_doppler_power"): ("doppler", "range_bin"),
    ("capacitive", "maxwell"): ("terminal", "terminal_2"),
    ("capacitive", "self_capacitance"): ("electrode",),
    **{("capacitive", s): ("channel",) for s in ("channels", "readout", "delta")},
    **{("lidar", s): ("firing",) for s in ("azimuth", "elevation", "ring", "time")},
    **{("lidar", s): ("firing", "echo") for s in ("range", "intensity", "power", "object_id")},
    ("lidar", "xyz"): ("firing", "echo", "component"),
    ("lidar", "xyz_world"): ("firing", "echo", "component"),
    ("magnetic", "field_true"): ("element", "component"),
    ("magnetic", "field"): ("element", "axis"),
    ("magnetic", "raw"): ("element", "axis"),
    ("ultrasonic", "ascan"): ("transducer", "sample"),
    ("ultrasonic", "envelope"): ("transducer", "sample"),
    ("ultrasonic", "fire_time"): ("transducer",),
    ("ultrasonic", "first_echo_distance"): ("transducer",),
    **{("inductive", s): ("element",) for s in ("output", "quality", "delta_r", "delta_l", "frequency")},
}
#: Variables renamed because their stream name is a dimension name.
RENAMED = {("lidar", "time"): "firing_time"}
#: Units of streams whose unit does not depend on the device (attribute ``units``).
UNITS = {("tof", "depth"): "m", ("tof", "distance"): "m", ("tof", "noise"): "m", ("tof", "points_sensor"): "m",
         ("tof", "points_world"): "m", ("tof", "raw_times"): "s", ("camera", "range"): "m", ("camera", "depth"): "m",
         ("capacitive", "maxwell"): "F", ("capacitive", "self_capacitance"): "F", ("capacitive", "channels"): "F",
         ("capacitive", "readout"): "F", ("capacitive", "delta"): "F", ("lidar", "azimuth"): "rad",
         ("lidar", "elevation"): "rad", ("lidar", "time"): "s", ("lidar", "range"): "m", ("lidar", "power"): "W",
         ("lidar", "xyz"): "m", ("lidar", "xyz_world"): "m", ("magnetic", "field_true"): "T",
         ("ultrasonic", "ascan"): "Pa", ("ultrasonic", "envelope"): "Pa", ("ultrasonic", "fire_time"): "s",
         ("ultrasonic", "first_echo_distance"): "m", ("inductive", "frequency"): "Hz"}


def require_xarray():
    """The ``xarray`` module, or ConfigError naming the extra that installs it."""
    try:
        import xarray
    except ImportError:
        raise ConfigError("xarray", "xarray is not installed",
                          "the optional extra: pip install 'twinsense[xarray]'") from None
    return xarray


def _dims(kind: str, stream: str, shape: tuple[int, ...]) -> tuple[str, ...]:
    dims = DIMS.get((kind, stream))
    if dims is None or len(dims) != len(shape) - 1:
        dims = tuple(f"{stream}_dim{i}" for i in range(1, len(shape)))
    return ("time", *dims)


def _coords(kind: str, config: dict, sizes: dict[str, int]) -> dict[str, Any]:
    """Coordinates the sensor's config defines, for dimensions of matching length."""
    coords: dict[str, Any] = {}
    inner = config.get("config", config)
    for dim in ("component",):
        if sizes.get(dim) == 3:
            coords[dim] = ["x", "y", "z"]
    if kind == "magnetic" and "axis" in sizes and len(inner.get("axes", "")) == sizes["axis"]:
        coords["axis"] = list(inner["axes"])
    if kind == "capacitive":
        for dim, key in (("channel", "channels"), ("electrode", "electrodes")):
            names = config.get(key)
            if dim in sizes and isinstance(names, list) and len(names) == sizes[dim]:
                coords[dim] = names
    if kind == "ultrasonic" and "sample" in sizes and inner.get("sample_rate"):
        # Sample s is taken s / sample_rate after its transducer fired (UltrasonicFrame).
        coords["sample_time"] = ("sample", np.arange(sizes["sample"]) / float(inner["sample_rate"]),
                                 {"units": "s"})
    if kind == "radar" and "range_bin" in sizes:
        from twinsense.radar.processing.fft import range_axis

        chirp = config.get("chirp", {})
        complex_if = bool(config.get("if_chain", {}).get("complex_if", False))
        n = sizes["range_bin"]
        # The map keeps the positive-frequency half of a real IF's range FFT: n_fft = 2 n bins.
        n_fft = n if complex_if else 2 * n
        if chirp.get("sample_rate") and chirp.get("slope"):
            coords["range"] = ("range_bin", range_axis(n, sample_rate=float(chirp["sample_rate"]),
                                                       slope=float(chirp["slope"]), n_fft=n_fft), {"units": "m"})
    return coords


def sensor_dataset(sensor) -> Any:
    """One sensor of an open recording (a ``SensorRecording``) as an ``xarray.Dataset``."""
    xr = require_xarray()
    kind = sensor.kind
    variables = {}
    sizes: dict[str, int] = {}
    for stream in sensor.stream_names:
        data = sensor[stream][()]
        dims = _dims(kind, stream, data.shape)
        name = RENAMED.get((kind, stream), stream)
        attrs = {"units": UNITS[(kind, stream)]} if (kind, stream) in UNITS else {}
        variables[name] = xr.Variable(dims, data, attrs)
        sizes.update(zip(dims, data.shape))
    coords: dict[str, Any] = {"time": ("time", sensor.timestamps, {"units": "s"})}
    coords.update(_coords(kind, sensor.config, sizes))
    return xr.Dataset(variables, coords=coords,
                      attrs={"sensor": sensor.name, "kind": kind, "frame_rate": sensor.frame_rate})


def recording_datasets(recording) -> dict[str, Any]:
    """Every sensor of an open recording as ``{sensor name: xarray.Dataset}``."""
    require_xarray()
    return {name: sensor_dataset(s) for name, s in recording.sensors.items()}
