"""HDF5 recordings of sensor time series.

Layout (documented in docs/recording-format.md)::

    /                      attrs: format = "twinsense-recording", format_version = 1,
                                  twinsense_version, created (ISO 8601 UTC),
                                  complete (bool), error (str, only if incomplete),
                                  scenario (JSON text, may be "{}")
    /<sensor name>/        attrs: kind, frame_rate [Hz], config (JSON text)
    /<sensor name>/timestamps     (n_frames,) float64 [s]
    /<sensor name>/<stream>       (n_frames, ...) one dataset per frame stream

Frames are appended as they are produced (datasets are chunked along the
frame axis and grow), so memory stays flat over long runs. The file is
written under a temporary name next to the target and renamed only when the
run completes; a failed or interrupted run leaves the previous output
untouched and keeps what was written as ``<name>.partial.h5`` with
``complete = False`` and the error message.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from twinsense._version import __version__
from twinsense.errors import RecordingError

FORMAT = "twinsense-recording"
FORMAT_VERSION = 1


def _json(obj: Any) -> str:
    def default(o):
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, (np.integer, np.floating, np.bool_)):
            return o.item()
        if isinstance(o, Path):
            return str(o)
        if hasattr(o, "to_dict"):
            return o.to_dict()
        return repr(o)

    return json.dumps(obj, default=default, sort_keys=True)


def partial_path(path: Path) -> Path:
    return path.with_name(path.stem + ".partial" + path.suffix)


class RecordingWriter:
    """Append-only writer; use as a context manager.

    Parameters
    ----------
    path : path-like
        Final file name (``.h5``).
    scenario : mapping, optional
        Stored as JSON in the root attribute ``scenario``.
    compression : str or None
        h5py filter for the stream datasets ("lzf" is fast and lossless).
    """

    def __init__(self, path, scenario: Mapping | None = None, compression: str | None = "lzf"):
        self.path = Path(path)
        if self.path.suffix not in (".h5", ".hdf5"):
            self.path = self.path.with_suffix(".h5")
        if not self.path.parent.exists():
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise RecordingError(f"cannot create output directory {str(self.path.parent)!r}: {exc}") from None
        self.tmp_path = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        self.compression = compression
        try:
            self._f = h5py.File(self.tmp_path, "w")
        except OSError as exc:
            raise RecordingError(f"cannot write {str(self.path)!r}: {exc}") from None
        a = self._f.attrs
        a["format"] = FORMAT
        a["format_version"] = FORMAT_VERSION
        a["twinsense_version"] = __version__
        a["created"] = _dt.datetime.now(_dt.UTC).isoformat()
        a["complete"] = False
        a["scenario"] = _json(dict(scenario or {}))
        self._counts: dict[str, int] = {}
        self._closed = False

    # ------------------------------------------------------------------
    def add_sensor(self, name: str, kind: str, frame_rate: float, config: Mapping | None = None) -> None:
        if name in self._f:
            raise RecordingError(f"sensor name {name!r} is used twice in one recording")
        g = self._f.create_group(name)
        g.attrs["kind"] = kind
        g.attrs["frame_rate"] = float(frame_rate)
        g.attrs["config"] = _json(dict(config or {}))
        g.create_dataset("timestamps", shape=(0,), maxshape=(None,), dtype="f8", chunks=(1024,))
        self._counts[name] = 0

    def append(self, name: str, t: float, streams: Mapping[str, np.ndarray]) -> None:
        """Append one frame of sensor ``name`` at time ``t`` [s]."""
        g = self._f[name]
        k = self._counts[name]
        for key, value in streams.items():
            arr = np.asarray(value)
            if key == "timestamps":
                raise RecordingError(f"{name}: 'timestamps' is reserved and cannot be a stream name")
            if key not in g:
                chunk = (1, *arr.shape) if arr.nbytes > 4096 else (min(256, max(1, 65536 // max(1, arr.nbytes))),
                                                                   *arr.shape)
                g.create_dataset(key, shape=(0, *arr.shape), maxshape=(None, *arr.shape), dtype=arr.dtype,
                                 chunks=chunk, compression=self.compression if arr.nbytes > 256 else None)
                if k:
                    raise RecordingError(f"{name}: stream {key!r} appeared after {k} frames without it")
            ds = g[key]
            if ds.shape[1:] != arr.shape:
                raise RecordingError(f"{name}/{key}: frame shape {arr.shape} differs from earlier {ds.shape[1:]}")
            ds.resize(k + 1, axis=0)
            ds[k] = arr
        ts = g["timestamps"]
        ts.resize(k + 1, axis=0)
        ts[k] = float(t)
        self._counts[name] = k + 1

    def flush(self) -> None:
        self._f.flush()

    def close(self, error: BaseException | None = None) -> Path:
        """Finish: rename into place (success) or keep a marked partial file (error)."""
        if self._closed:
            return self.path
        self._closed = True
        if error is None:
            self._f.attrs["complete"] = True
            self._f.close()
            os.replace(self.tmp_path, self.path)
            return self.path
        self._f.attrs["complete"] = False
        self._f.attrs["error"] = f"{type(error).__name__}: {error}"
        self._f.close()
        dest = partial_path(self.path)
        os.replace(self.tmp_path, dest)
        return dest

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(exc)


class SensorRecording:
    """One sensor's data in a recording (datasets are read lazily)."""

    def __init__(self, group: h5py.Group):
        self._g = group
        self.name = group.name.strip("/")
        self.kind = str(group.attrs["kind"])
        self.frame_rate = float(group.attrs["frame_rate"])
        self.config = json.loads(group.attrs["config"])

    @property
    def timestamps(self) -> np.ndarray:
        return self._g["timestamps"][()]

    @property
    def stream_names(self) -> list[str]:
        return sorted(k for k in self._g if k != "timestamps")

    def __getitem__(self, stream: str) -> h5py.Dataset:
        if stream not in self._g:
            from twinsense.errors import UnknownNameError

            raise UnknownNameError(f"{self.name} stream", stream, ["timestamps", *self.stream_names])
        return self._g[stream]

    def __len__(self) -> int:
        return int(self._g["timestamps"].shape[0])

    def __repr__(self) -> str:
        return f"SensorRecording({self.name!r}, kind={self.kind!r}, frames={len(self)}, streams={self.stream_names})"


class Recording:
    """A recording opened for reading (use as a context manager or call ``close``)."""

    def __init__(self, path, allow_incomplete: bool = False):
        self.path = Path(path)
        if not self.path.is_file():
            raise RecordingError(f"recording not found: {str(self.path)!r}")
        try:
            self._f = h5py.File(self.path, "r")
        except OSError as exc:
            raise RecordingError(f"{str(self.path)!r} is not a readable HDF5 recording: {exc}") from None
        a = self._f.attrs
        if a.get("format") != FORMAT:
            self._f.close()
            raise RecordingError(f"{str(self.path)!r} is not a twinsense recording (format attribute missing)")
        self.complete = bool(a["complete"])
        self.error = str(a.get("error", ""))
        if not self.complete and not allow_incomplete:
            self._f.close()
            raise RecordingError(f"{str(self.path)!r} is an incomplete recording ({self.error}); "
                                 "open it with allow_incomplete=True to read what was written")
        self.version = str(a["twinsense_version"])
        self.created = str(a["created"])
        self.scenario = json.loads(a["scenario"])
        self.sensors = {k: SensorRecording(self._f[k]) for k in self._f}

    def __getitem__(self, name: str) -> SensorRecording:
        if name not in self.sensors:
            from twinsense.errors import UnknownNameError

            raise UnknownNameError("sensor", name, list(self.sensors))
        return self.sensors[name]

    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Recording({str(self.path)!r}, complete={self.complete}, sensors={list(self.sensors)})"


def open_recording(path, allow_incomplete: bool = False) -> Recording:
    """Open a twinsense HDF5 recording for reading."""
    return Recording(path, allow_incomplete=allow_incomplete)
