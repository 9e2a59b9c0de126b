"""HDF5 recordings of sensor time series.

Layout (documented in docs/recording-format.md)::

    /                      attrs: format = "twinsense-recording", format_version = 1,
                                  twinsense_version, created (ISO 8601 UTC),
                                  complete (bool), error (str, only if incomplete),
                                  scenario (JSON text, may be "{}"),
                                  scenario_dir (str, only with a scenario file)
    /<sensor name>/        attrs: kind, frame_rate [Hz], config (JSON text)
    /<sensor name>/timestamps     (n_frames,) float64 [s]
    /<sensor name>/<stream>       (n_frames, ...) one dataset per frame stream

Frames are appended as they are produced (datasets are chunked along the
frame axis and grow), so memory stays flat over long runs. The file is
written under a hidden temporary name next to the target and renamed only
when the run completes; a failed or interrupted run leaves the previous
output untouched and keeps what was written as ``<name>.partial.h5`` with
``complete = False`` and the error message.

Surviving a hard kill (SIGKILL, a crash of the interpreter): a background
thread flushes the file at most ``flush_interval`` seconds after a frame was
appended, and only between whole frames, so the temporary file on disk is a
consistent HDF5 file after every flush. The metadata cache is told not to
evict (write) dirty entries between flushes, and a compressed chunk holds
exactly one frame and is written once, so nothing the last flush left on
disk is overwritten before the next flush. :func:`recover` turns such a
left-over temporary file into a readable ``complete = False`` recording.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import re
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from twinsense._version import __version__
from twinsense.errors import ConfigError, RecordingError, UnknownNameError

FORMAT = "twinsense-recording"
FORMAT_VERSION = 1
#: Seconds between flushes of a recording being written (at most this long after a frame was appended).
FLUSH_INTERVAL = 0.5
#: Documented recovery bound [s]: after a hard kill every frame appended more than this long before the
#: kill is readable. It covers the flush interval, the flusher's polling step and the flush itself.
RECOVERY_BOUND = 1.0
#: Names every sink accepts as is: an HDF5 group, a ROS/MCAP topic segment and a file name.
SENSOR_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,63}")
SENSOR_NAME_RULE = "a letter, then up to 63 letters, digits, '_' or '-' (e.g. 'tof_front')"
#: Frames up to this size share a chunk (uncompressed, rewritten in place as it fills); larger frames
#: get a chunk of their own, LZF-compressed and written once.
SMALL_FRAME_BYTES = 4096
_TMP_NAME = re.compile(r"^\.(?P<target>.+)\.(?P<pid>\d+)\.tmp$")


def check_sensor_name(field: str, name: Any) -> str:
    """Return ``name`` if every sink accepts it, else raise ConfigError naming ``field``."""
    if not isinstance(name, str) or SENSOR_NAME.fullmatch(name) is None:
        raise ConfigError(field, name, SENSOR_NAME_RULE)
    return name


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


def temp_path(path: Path, pid: int | None = None) -> Path:
    """Hidden name a recording is written under until it completes: ``.<name>.<pid>.tmp``."""
    return path.with_name(f".{path.name}.{os.getpid() if pid is None else pid}.tmp")


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


def stale_temp_files(path: Path) -> list[Path]:
    """Temporary files of ``path`` left by writers that no longer run (killed runs)."""
    out = []
    for p in sorted(Path(path).parent.glob(f".{Path(path).name}.*.tmp")):
        m = _TMP_NAME.match(p.name)
        if m and not _pid_alive(int(m["pid"])):
            out.append(p)
    return out


def _hold_metadata(f: h5py.File) -> None:
    """Keep dirty metadata in memory until the next flush (no evictions in between).

    HDF5 otherwise writes metadata whenever its cache is full, which can leave
    the file on disk half-way between two states. With evictions off, the
    on-disk metadata changes only during an explicit flush. The adaptive
    resizing modes must be off for evictions to be switched off (HDF5 rule).
    """
    cfg = f.id.get_mdc_config()
    cfg.incr_mode = 0  # H5C_incr__off
    cfg.flash_incr_mode = 0  # H5C_flash_incr__off
    cfg.decr_mode = 0  # H5C_decr__off
    cfg.evictions_enabled = False
    f.id.set_mdc_config(cfg)


class RecordingWriter:
    """Append-only writer; use as a context manager.

    Parameters
    ----------
    path : path-like
        Final file name (``.h5``).
    scenario : mapping, optional
        Stored as JSON in the root attribute ``scenario``.
    compression : str or None
        h5py filter for streams whose frames are larger than
        ``SMALL_FRAME_BYTES`` ("lzf" is fast and lossless).
    flush_interval : float or None
        [s] A frame is on disk (readable after a hard kill) at most this long
        after it was appended; None flushes only when the file is closed.
    scenario_dir : path-like, optional
        The scenario file's folder, stored (absolute) in the root attribute
        ``scenario_dir``: where the scenario's relative paths are taken from.

    Attributes
    ----------
    removed : list of Path
        Files of earlier runs removed on success (a ``<name>.partial.h5`` that
        the complete recording supersedes).
    stale : list of Path
        Temporary files of killed earlier runs into the same file name; they
        are kept for :func:`recover`.
    """

    def __init__(self, path, scenario: Mapping | None = None, compression: str | None = "lzf",
                 flush_interval: float | None = FLUSH_INTERVAL, scenario_dir=None):
        self.path = Path(path)
        if self.path.suffix not in (".h5", ".hdf5"):
            self.path = self.path.with_suffix(".h5")
        if flush_interval is not None and not (isinstance(flush_interval, (int, float)) and flush_interval > 0):
            raise ConfigError("flush_interval", flush_interval, "a number of seconds > 0, or None")
        if scenario_dir is not None and not isinstance(scenario_dir, (str, os.PathLike)):
            raise ConfigError("scenario_dir", scenario_dir, "the scenario file's folder (a path), or None")
        # The folder the scenario's relative paths (meshes, robot descriptions, recordings) were taken
        # from, absolute: `twinsense convert` rebuilds the scenario from it wherever it is run.
        stored_dir = None if scenario_dir is None else str(Path(scenario_dir).resolve())
        if self.path.parent.exists() and not self.path.parent.is_dir():  # h5py would say only "errno = 20"
            raise RecordingError(f"cannot write {str(self.path)!r}: {str(self.path.parent)!r} is a file, not a folder")
        if not self.path.parent.exists():
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise RecordingError(f"cannot create output directory {str(self.path.parent)!r}: {exc}") from None
        self.tmp_path = temp_path(self.path)
        self.compression = compression
        self.removed: list[Path] = []
        self.stale: list[Path] = []
        try:
            self._f = h5py.File(self.tmp_path, "w")
        except OSError as exc:
            raise RecordingError(f"cannot write {str(self.path)!r}: {exc}") from None
        _hold_metadata(self._f)
        a = self._f.attrs
        a["format"] = FORMAT
        a["format_version"] = FORMAT_VERSION
        a["twinsense_version"] = __version__
        a["created"] = _dt.datetime.now(_dt.UTC).isoformat()
        a["complete"] = False
        a["scenario"] = _json(dict(scenario or {}))
        if stored_dir is not None:
            a["scenario_dir"] = stored_dir
        self._counts: dict[str, int] = {}
        self._datasets: dict[str, tuple[h5py.Dataset, dict[str, h5py.Dataset]]] = {}
        self._closed = False
        # One lock around every HDF5 call: the flusher thread flushes only
        # between whole frames, so each flush leaves every sensor's datasets
        # at the same length.
        self._lock = threading.Lock()
        self._dirty = True
        self._last_flush = time.monotonic()
        self._stop = threading.Event()
        self._flusher = None
        self.flush_interval = flush_interval
        self.flush()
        if flush_interval is not None:
            self._flusher = threading.Thread(target=self._flush_loop, name="twinsense-recording-flush", daemon=True)
            self._flusher.start()

    # ------------------------------------------------------------------
    def _flush_loop(self) -> None:
        step = min(0.1, self.flush_interval / 5)
        while not self._stop.wait(step):
            if self._dirty and time.monotonic() - self._last_flush >= self.flush_interval:
                with self._lock:
                    if not self._closed and self._dirty:
                        self._flush_locked()

    def _flush_locked(self) -> None:
        self._f.flush()
        self._dirty = False
        self._last_flush = time.monotonic()

    def add_sensor(self, name: str, kind: str, frame_rate: float, config: Mapping | None = None) -> None:
        check_sensor_name("sensor name", name)
        with self._lock:
            if name in self._f:
                raise RecordingError(f"sensor name {name!r} is used twice in one recording")
            g = self._f.create_group(name)
            g.attrs["kind"] = kind
            g.attrs["frame_rate"] = float(frame_rate)
            g.attrs["config"] = _json(dict(config or {}))
            ts = g.create_dataset("timestamps", shape=(0,), maxshape=(None,), dtype="f8", chunks=(1024,))
            self._counts[name] = 0
            # Dataset handles kept per sensor: looking them up in the group on
            # every append costs more than the write of a small frame.
            self._datasets[name] = (ts, {})
            self._dirty = True

    def append(self, name: str, t: float, streams: Mapping[str, np.ndarray]) -> None:
        """Append one frame of sensor ``name`` at time ``t`` [s]."""
        if name not in self._counts:
            raise UnknownNameError("recording sensor", name, list(self._counts))
        with self._lock:
            self._append_locked(name, t, streams)

    def append_many(self, name: str, times, streams_list) -> None:
        """Append consecutive frames of sensor ``name`` at ``times`` (T,) [s]: one write per stream.

        ``streams_list`` holds one ``{stream: array}`` mapping per time. The file
        holds the same datasets, bit for bit, as T calls of :meth:`append`; the
        block is written under one lock, so a flush sees all of it or none. Frames
        that do not stack (a stream missing, another shape or dtype) go one by one,
        so the error names the frame, as :meth:`append` does, after the frames before it.
        """
        if name not in self._counts:
            raise UnknownNameError("recording sensor", name, list(self._counts))
        frames = list(streams_list)
        ts_new = np.asarray(times, dtype=float).reshape(-1)
        if len(ts_new) != len(frames):
            raise ConfigError("append_many.times", f"{len(ts_new)} times",
                              f"one time per frame ({len(frames)} frames)")
        if not frames:
            return
        with self._lock:
            ts, dsets = self._datasets[name]
            first = 0
            if not dsets:  # the first frame creates the streams
                self._append_locked(name, float(ts_new[0]), frames[0])
                first = 1
                if len(frames) == 1:
                    return
            # No streams yet (a first frame without any): one by one, so a stream that appears is refused.
            stacked = self._stack(dsets, frames[first:]) if dsets else None
            if stacked is None:
                for t, streams in zip(ts_new[first:], frames[first:]):
                    self._append_locked(name, float(t), streams)
                return
            n = len(frames) - first
            k = self._counts[name]
            for key, arr in stacked.items():
                ds = dsets[key]
                ds.resize(k + n, axis=0)
                ds[k:k + n] = arr
            ts.resize(k + n, axis=0)
            ts[k:k + n] = ts_new[first:]
            self._counts[name] = k + n
            self._dirty = True

    @staticmethod
    def _stack(dsets: dict[str, h5py.Dataset], frames: list) -> dict[str, np.ndarray] | None:
        """Each stream of ``frames`` stacked (T, ...), or None when a frame differs from the datasets.

        Every frame must have exactly the datasets' streams, in their shape, all in one dtype per
        stream: h5py then converts the stack element by element as it would each frame.
        """
        out = {}
        for key, ds in dsets.items():
            shape = ds.shape[1:]
            arrays = []
            for streams in frames:
                if len(streams) != len(dsets) or key not in streams:
                    return None
                arr = np.asarray(streams[key])
                if arr.shape != shape:
                    return None
                arrays.append(arr)
            dtype = arrays[0].dtype
            if any(a.dtype != dtype for a in arrays):
                return None
            out[key] = np.stack(arrays)
        return out

    def _append_locked(self, name: str, t: float, streams: Mapping[str, np.ndarray]) -> None:
        ts, dsets = self._datasets[name]
        k = self._counts[name]
        arrays = {}
        for key, value in streams.items():
            arr = np.asarray(value)
            if key == "timestamps":
                raise RecordingError(f"{name}: 'timestamps' is reserved and cannot be a stream name")
            ds = dsets.get(key)
            if ds is None:
                if k:
                    raise RecordingError(f"{name}: stream {key!r} appeared after {k} frames without it")
                dsets[key] = self._create_stream(self._f[name], key, arr)
            elif ds.shape[1:] != arr.shape:
                raise RecordingError(f"{name}/{key}: frame shape {arr.shape} differs from earlier "
                                     f"{ds.shape[1:]}")
            arrays[key] = arr
        if len(arrays) != len(dsets):
            missing = sorted(set(dsets) - set(arrays))
            raise RecordingError(f"{name}: frame {k} lacks stream(s) {', '.join(map(repr, missing))}")
        for key, arr in arrays.items():
            ds = dsets[key]
            ds.resize(k + 1, axis=0)
            ds[k] = arr
        ts.resize(k + 1, axis=0)
        ts[k] = float(t)
        self._counts[name] = k + 1
        self._dirty = True

    def _create_stream(self, g: h5py.Group, key: str, arr: np.ndarray) -> h5py.Dataset:
        if arr.nbytes > SMALL_FRAME_BYTES:
            # One frame per chunk: a chunk is complete when written and never
            # rewritten, so compressing it cannot move data a flushed index points at.
            chunks, compression = (1, *arr.shape), self.compression
        else:
            # Small frames share an uncompressed chunk (~64 KiB), which keeps its
            # size and place on disk as it fills.
            chunks = (min(256, max(1, 65536 // max(1, arr.nbytes))), *arr.shape)
            compression = None
        return g.create_dataset(key, shape=(0, *arr.shape), maxshape=(None, *arr.shape), dtype=arr.dtype,
                                chunks=chunks, compression=compression)

    @property
    def frame_counts(self) -> dict[str, int]:
        """Frames appended so far per sensor."""
        return dict(self._counts)

    def flush(self) -> None:
        """Write everything appended so far to disk now."""
        with self._lock:
            self._flush_locked()

    def _stop_flusher(self) -> None:
        self._stop.set()
        if self._flusher is not None and self._flusher is not threading.current_thread():
            self._flusher.join()

    def _truncate_to_whole_frames(self) -> None:
        # An error (Ctrl-C, a signal) may arrive between the datasets of one
        # frame; keep only frames whose every dataset and timestamp was written.
        for name, n in self._counts.items():
            for ds in self._f[name].values():
                if ds.shape[0] != n:
                    ds.resize(n, axis=0)

    def close(self, error: BaseException | None = None) -> Path:
        """Finish: rename into place (success) or keep a marked partial file (error)."""
        if self._closed:
            return self.path
        self._stop_flusher()
        with self._lock:
            self._closed = True
            if error is None:
                self._f.attrs["complete"] = True
                self._f.close()
                os.replace(self.tmp_path, self.path)
                # A partial file of an earlier run into the same name is superseded
                # by this complete recording; temporary files of killed runs may
                # still hold frames and are only reported (see `recover`).
                part = partial_path(self.path)
                if part.exists():
                    part.unlink()
                    self.removed.append(part)
                self.stale = stale_temp_files(self.path)
                return self.path
            self._truncate_to_whole_frames()
            self._f.attrs["complete"] = False
            self._f.attrs["error"] = f"{type(error).__name__}: {error}"
            self._f.close()
            dest = partial_path(self.path)
            os.replace(self.tmp_path, dest)
            return dest

    def discard(self) -> None:
        """Close and delete the temporary file (nothing of value was written)."""
        if self._closed:
            return
        self._stop_flusher()
        with self._lock:
            self._closed = True
            self._f.close()
            self.tmp_path.unlink(missing_ok=True)

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(exc)


class StreamDataset:
    """One stream of one sensor, read lazily; a read error names file and dataset.

    Indexing (``ds[3]``, ``ds[()]``, ``ds[2:5, 0]``) reads from the file like
    an h5py dataset; ``shape``, ``dtype`` and ``len`` need no read.
    """

    def __init__(self, ds: h5py.Dataset, path: Path):
        self._ds = ds
        self._path = path
        self.name = ds.name.strip("/")

    @property
    def shape(self) -> tuple[int, ...]:
        return self._ds.shape

    @property
    def dtype(self) -> np.dtype:
        return self._ds.dtype

    @property
    def ndim(self) -> int:
        return self._ds.ndim

    def __len__(self) -> int:
        return self._ds.shape[0]

    def __getitem__(self, index):
        try:
            return self._ds[index]
        except OSError as exc:
            raise RecordingError(f"{str(self._path)!r}: cannot read dataset {self.name!r} "
                                 f"(damaged data?): {exc}") from None

    def __array__(self, dtype=None, copy=None):
        arr = self[()]
        return arr if dtype is None else arr.astype(dtype)

    def __repr__(self) -> str:
        return f"StreamDataset({self.name!r}, shape={self.shape}, dtype={self.dtype})"


def _attr(obj, key: str, path: Path, what: str):
    try:
        return obj.attrs[key]
    except KeyError:
        raise RecordingError(f"{str(path)!r}: attribute {key!r} of {what} is missing") from None


def _json_attr(obj, key: str, path: Path, what: str):
    text = _attr(obj, key, path, what)
    try:
        return json.loads(text)
    except (TypeError, ValueError) as exc:
        raise RecordingError(f"{str(path)!r}: attribute {key!r} of {what} is not JSON text: {exc}") from None


class SensorRecording:
    """One sensor's data in a recording (datasets are read lazily).

    Opening checks the group: attributes ``kind``, ``frame_rate`` and
    ``config`` (JSON), a 1-D ``timestamps`` dataset, and every stream as
    long as ``timestamps``.
    """

    def __init__(self, group: h5py.Group, path: Path):
        self._g = group
        self._path = Path(path)
        self.name = group.name.strip("/")
        what = f"sensor group {self.name!r}"
        self.kind = str(_attr(group, "kind", path, what))
        try:
            self.frame_rate = float(_attr(group, "frame_rate", path, what))
        except (TypeError, ValueError):
            raise RecordingError(f"{str(path)!r}: attribute 'frame_rate' of {what} is not a number") from None
        self.config = _json_attr(group, "config", path, what)
        ts = group.get("timestamps")
        if not isinstance(ts, h5py.Dataset) or ts.ndim != 1:
            raise RecordingError(f"{str(path)!r}: dataset '{self.name}/timestamps' is missing or not 1-D")
        n = ts.shape[0]
        for key, ds in group.items():
            if not isinstance(ds, h5py.Dataset):
                raise RecordingError(f"{str(path)!r}: '{self.name}/{key}' is a group, expected a stream dataset")
            if ds.ndim == 0 or ds.shape[0] != n:
                raise RecordingError(f"{str(path)!r}: dataset '{self.name}/{key}' holds "
                                     f"{ds.shape[0] if ds.ndim else 'no'} frames but '{self.name}/timestamps' "
                                     f"holds {n}: the recording is inconsistent")

    @property
    def timestamps(self) -> np.ndarray:
        return StreamDataset(self._g["timestamps"], self._path)[()]

    @property
    def stream_names(self) -> list[str]:
        return sorted(k for k in self._g if k != "timestamps")

    def __getitem__(self, key: str | int) -> StreamDataset | dict:
        """``rec["tof"]["depth"]``: a stream (read lazily); ``rec["tof"][10]``: frame 10 of every
        stream as ``{"timestamps": t [s], stream: array}`` (negative indices count from the end)."""
        if isinstance(key, (int, np.integer)) and not isinstance(key, (bool, np.bool_)):
            n = len(self)
            if not -n <= key < n:
                raise IndexError(f"{self.name}[{key}]: the sensor has {n} frames (indices {-n}..{n - 1})")
            i = int(key) % n
            return {name: StreamDataset(self._g[name], self._path)[i] for name in ["timestamps", *self.stream_names]}
        if not isinstance(key, str):
            raise TypeError(f"{self.name}[{key!r}]: a stream name (one of: timestamps, "
                            f"{', '.join(self.stream_names)}) or a frame index (int), not {type(key).__name__}")
        if key not in self._g:
            raise UnknownNameError(f"{self.name} stream", key, ["timestamps", *self.stream_names])
        return StreamDataset(self._g[key], self._path)

    def __len__(self) -> int:
        return int(self._g["timestamps"].shape[0])

    def to_xarray(self):
        """This sensor as an ``xarray.Dataset`` with named dimensions (needs the 'xarray' extra).

        See :mod:`twinsense.io.labelled` and docs/recording-format.md.
        """
        from twinsense.io.labelled import sensor_dataset

        return sensor_dataset(self)

    def __repr__(self) -> str:
        return f"SensorRecording({self.name!r}, kind={self.kind!r}, frames={len(self)}, streams={self.stream_names})"


class Recording:
    """A recording opened for reading (use as a context manager or call ``close``).

    Opening checks the structure (attributes, JSON texts, every stream as long
    as its ``timestamps``) and raises :class:`RecordingError` naming the file
    and the part that is wrong; a damaged chunk is reported when it is read.
    """

    def __init__(self, path, allow_incomplete: bool = False):
        self.path = Path(path)
        if not self.path.is_file():
            raise RecordingError(f"recording not found: {str(self.path)!r}")
        try:
            self._f = h5py.File(self.path, "r")
        except OSError as exc:
            raise RecordingError(f"{str(self.path)!r} is not a readable HDF5 recording: {exc}") from None
        try:
            self._open(allow_incomplete)
        except BaseException:
            self._f.close()
            raise

    def _open(self, allow_incomplete: bool) -> None:
        a = self._f.attrs
        if a.get("format") != FORMAT:
            raise RecordingError(f"{str(self.path)!r} is not a twinsense recording (format attribute missing)")
        self.complete = bool(_attr(self._f, "complete", self.path, "the file"))
        self.error = str(a.get("error", ""))
        if not self.complete and _TMP_NAME.match(self.path.name) and not self.error:
            self.error = "the writing process did not finish (temporary file)"
        if not self.complete and not allow_incomplete:
            raise RecordingError(f"{str(self.path)!r} is an incomplete recording ({self.error}); "
                                 "open it with allow_incomplete=True to read what was written")
        self.version = str(_attr(self._f, "twinsense_version", self.path, "the file"))
        self.created = str(_attr(self._f, "created", self.path, "the file"))
        self.scenario = _json_attr(self._f, "scenario", self.path, "the file")
        stored = a.get("scenario_dir")
        #: The folder the stored scenario's relative paths were taken from (None: not recorded, e.g. a
        #: Python-built run, or a recording from before this attribute).
        self.scenario_dir = Path(str(stored)) if stored else None
        self.sensors = {}
        for k, g in self._f.items():
            if not isinstance(g, h5py.Group):
                raise RecordingError(f"{str(self.path)!r}: '{k}' at the top level is not a sensor group")
            self.sensors[k] = SensorRecording(g, self.path)

    def __getitem__(self, name: str) -> SensorRecording:
        if name not in self.sensors:
            raise UnknownNameError("sensor", name, list(self.sensors))
        return self.sensors[name]

    def to_xarray(self) -> dict:
        """Every sensor as ``{name: xarray.Dataset}`` with named dimensions (needs the 'xarray' extra)."""
        from twinsense.io.labelled import recording_datasets

        return recording_datasets(self)

    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Recording({str(self.path)!r}, complete={self.complete}, sensors={list(self.sensors)})"


def open_recording(path, allow_incomplete: bool = False) -> Recording:
    """Open a twinsense HDF5 recording for reading.

    ``allow_incomplete=True`` also opens a ``.partial.h5`` file and the hidden
    temporary file a killed run left behind (everything up to its last flush).
    """
    return Recording(path, allow_incomplete=allow_incomplete)


def open_xarray(path, allow_incomplete: bool = False) -> dict:
    """Read a recording into ``{sensor name: xarray.Dataset}`` (needs the 'xarray' extra).

    Dimensions are named (``time``, ``row``, ``col``, ``rx``, ``chirp``,
    ``sample``, ``channel``, ...) and ``time`` holds the timestamps [s]; see
    docs/recording-format.md. The data is read into memory and the file closed.
    """
    from twinsense.io.labelled import require_xarray

    require_xarray()
    with Recording(path, allow_incomplete=allow_incomplete) as rec:
        return rec.to_xarray()


# ----------------------------------------------------------------------
def _readable_frames(ds: h5py.Dataset, n: int) -> int:
    """How many leading frames of ``ds`` (at most ``n``) read without error."""
    step = max(1, ds.chunks[0] if ds.chunks else 1)
    for start in range(0, n, step):
        stop = min(n, start + step)
        try:
            ds[start:stop]
        except OSError:
            for k in range(start, stop):
                try:
                    ds[k]
                except OSError:
                    return k
    return n


def recover(path) -> tuple[Path, dict[str, int]]:
    """Turn the temporary file of a killed run into a readable ``complete = False`` recording.

    Parameters
    ----------
    path : path-like
        A hidden ``.<name>.h5.<pid>.tmp`` file, or a directory (its only such
        file of a stopped writer).

    Returns
    -------
    (Path, dict)
        The recovered recording (``<name>.partial.h5`` beside the target, or
        ``<name>.<pid>.partial.h5`` when that name is taken) and the frames
        recovered per sensor. Every sensor keeps the leading frames that read
        back without error; the temporary file is removed afterwards.
    """
    path = Path(path)
    if path.is_dir():
        found = [p for p in sorted(path.glob(".*.tmp")) if _TMP_NAME.match(p.name)
                 and not _pid_alive(int(_TMP_NAME.match(p.name)["pid"]))]
        if len(found) != 1:
            raise RecordingError(f"{str(path)!r}: expected one temporary recording of a stopped run, found "
                                 f"{len(found)}" + (f": {', '.join(p.name for p in found)}" if found else ""))
        path = found[0]
    m = _TMP_NAME.match(path.name)
    if not path.is_file() or m is None:
        raise RecordingError(f"{str(path)!r} is not a temporary recording (expected an existing "
                             "'.<name>.h5.<pid>.tmp' file)")
    pid = int(m["pid"])
    if _pid_alive(pid):
        raise RecordingError(f"{str(path)!r} is still being written by process {pid}; stop that run first")
    target = path.with_name(m["target"])
    dest = partial_path(target)
    if dest.exists():
        dest = target.with_name(f"{target.stem}.{pid}.partial{target.suffix}")
    try:
        src = h5py.File(path, "r")
    except OSError as exc:
        raise RecordingError(f"{str(path)!r}: nothing recoverable (the run stopped before its first flush "
                             f"or the file is damaged): {exc}") from None
    work = dest.with_name(f".{dest.name}.{os.getpid()}.tmp")
    counts: dict[str, int] = {}
    try:
        with src, h5py.File(work, "w") as out:
            for k, v in src.attrs.items():
                out.attrs[k] = v
            if out.attrs.get("format") != FORMAT:
                raise RecordingError(f"{str(path)!r} is not a twinsense recording (format attribute missing)")
            out.attrs["complete"] = False
            out.attrs["error"] = (f"recovered from {path.name}: the writing process (pid {pid}) stopped before it "
                                  "finished; frames up to its last flush are kept")
            for name, g in src.items():
                if not isinstance(g, h5py.Group) or "timestamps" not in g:
                    continue
                datasets = {key: ds for key, ds in g.items() if isinstance(ds, h5py.Dataset) and ds.ndim}
                n = min(ds.shape[0] for ds in datasets.values())
                n = min(_readable_frames(ds, n) for ds in datasets.values())
                og = out.create_group(name)
                for ak, av in g.attrs.items():
                    og.attrs[ak] = av
                for key, ds in datasets.items():
                    od = og.create_dataset(key, shape=(n, *ds.shape[1:]), maxshape=ds.maxshape, dtype=ds.dtype,
                                           chunks=ds.chunks, compression=ds.compression)
                    step = ds.chunks[0] if ds.chunks else n
                    for start in range(0, n, max(1, step)):
                        od[start:start + step] = ds[start:min(n, start + step)]
                counts[name] = n
        os.replace(work, dest)
    except BaseException:
        work.unlink(missing_ok=True)
        raise
    path.unlink()
    return dest, counts
