"""The simulation loop: every sensor sampled at its own frame times on one clock."""

from __future__ import annotations

import heapq
import math
import multiprocessing
import os
import pickle
import queue
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import Future
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError, TwinsenseError, UnknownNameError
from twinsense.io.recording import RecordingWriter, check_sensor_name
from twinsense.render.parallel import default_workers
from twinsense.scene.articulated import LinkMotion
from twinsense.scene.scene import Scene


@dataclass
class SimulationResult:
    """What a run produced.

    Attributes
    ----------
    path : Path or None
        The recording (None when ``out`` was None).
    frame_counts : dict
        Frames captured per sensor name.
    frames : dict
        Frames kept in memory per sensor name (only when ``keep_frames``).
    removed : list of Path
        Files of earlier runs this run removed: the ``<name>.partial.h5`` that
        its complete recording supersedes.
    stale : list of Path
        Temporary files of killed earlier runs into the same recording name,
        kept for ``twinsense recover``.
    """

    path: Path | None
    frame_counts: dict[str, int]
    frames: dict[str, list] = field(default_factory=dict)
    removed: list[Path] = field(default_factory=list)
    stale: list[Path] = field(default_factory=list)


@dataclass(frozen=True)
class RunLimits:
    """What one run may ask for before anything is allocated.

    A scenario inside every per-field range can still ask for more than a
    machine has (``duration: 1e9``, a 100000 x 100000 camera); these limits
    turn that into an error before the run starts.

    Attributes
    ----------
    max_frames : int
        Frames of all sensors together in one run (10 million: a day at
        ~115 frames/s).
    max_frame_bytes : int
        [B] Estimated working memory of one capture (4 GiB, a sixth of a
        24 GiB machine).
    """

    max_frames: int = 10_000_000
    max_frame_bytes: int = 4 * 2**30

    def __post_init__(self):
        V.integer("RunLimits.max_frames", self.max_frames, lo=1)
        V.integer("RunLimits.max_frame_bytes", self.max_frame_bytes, lo=1)


# Peak working memory of one capture per rendered pixel [B], measured with
# tracemalloc on the presets (depth camera 320x240 and 640x480: 133-162 B; ToF
# 224x171: 452-476 B over 5-9 raw frames, i.e. <= 53 B per pixel and raw frame;
# radar render 256x128 and larger: 125-148 B) and rounded up.
_BYTES_PER_PIXEL = {"camera": 170, "tof_raw": 60, "radar": 160}
# Radar cube: complex128 IF samples plus the range/Doppler working copies.
_BYTES_PER_CUBE_SAMPLE = 64


def frame_memory_estimate(sensor) -> tuple[int, str]:
    """Estimated peak memory [B] of one ``sensor.capture`` and how it was reckoned.

    Known kinds are estimated from their image and cube sizes; a sensor of
    another kind (capacitive, user-defined) is estimated at 0 (not limited).
    """
    cfg = getattr(sensor, "config", None)
    kind = getattr(sensor, "kind", "")
    if kind == "camera" and hasattr(cfg, "camera"):
        w, h = int(cfg.camera.width), int(cfg.camera.height)
        return w * h * _BYTES_PER_PIXEL["camera"], f"{w} x {h} pixels x ~{_BYTES_PER_PIXEL['camera']} B"
    if kind == "tof" and hasattr(cfg, "raw_frame_times"):
        w, h, n = int(cfg.width), int(cfg.height), len(cfg.raw_frame_times(0.0))
        return (w * h * n * _BYTES_PER_PIXEL["tof_raw"],
                f"{w} x {h} pixels x {n} raw frames x ~{_BYTES_PER_PIXEL['tof_raw']} B")
    if kind == "radar" and hasattr(cfg, "cube_shape"):
        w, h = int(cfg.render_width), int(cfg.render_height)
        cube = math.prod(int(x) for x in cfg.cube_shape)
        return (w * h * _BYTES_PER_PIXEL["radar"] + cube * _BYTES_PER_CUBE_SAMPLE,
                f"{w} x {h} render pixels x ~{_BYTES_PER_PIXEL['radar']} B + {cube} cube samples x "
                f"{_BYTES_PER_CUBE_SAMPLE} B")
    return 0, "not estimated"


def frame_count(frame_rate: float, duration: float) -> int:
    """Frames of a sensor at ``frame_rate`` [Hz] over ``duration`` [s] (at least one).

    The same count as :func:`twinsense.sensors.frame_times`, without the array.
    """
    x = duration * frame_rate + 1e-9
    # Absurd products (1e300 Hz x 1e300 s) are counted as 2**62 frames, over any limit, not an overflow.
    return max(math.floor(x), 1) if x < 2.0**62 else 2**62


def _clock(frame_rate: float, n: int, t0: float, index: int) -> Iterator[tuple[float, int]]:
    # (t0 + k / rate, sensor index), as frame_times computes the times: sensors
    # at related rates line up exactly.
    return ((t0 + k / frame_rate, index) for k in range(n))


def run_size_problems(sensors, duration: float, limits: RunLimits | None = None,
                      fields: Sequence[str] | None = None) -> list[tuple[str, Any, str]]:
    """Problems ``(field, value, what is allowed)`` of a run too big for ``limits``; empty when it fits.

    ``fields`` names each sensor in messages (default ``sensors[i]``).
    """
    limits = limits or RunLimits()
    fields = list(fields) if fields is not None else [f"sensors[{i}]" for i in range(len(sensors))]
    problems = []
    counts = [frame_count(float(s.frame_rate), float(duration)) for s in sensors]
    total = sum(counts)
    if total > limits.max_frames:
        detail = ", ".join(f"{f} {s.name!r} at {float(s.frame_rate):g} Hz: {n:.3g}"
                           for f, s, n in zip(fields, sensors, counts))
        problems.append(("duration", duration,
                         f"a run of at most {limits.max_frames:,} frames (RunLimits.max_frames, "
                         f"--max-frames); estimated {total:.3g} frames ({detail}); shorten the duration "
                         "or lower the frame_rate"))
    for f, s in zip(fields, sensors):
        nbytes, how = frame_memory_estimate(s)
        if nbytes > limits.max_frame_bytes:
            problems.append((f, s.name,
                             f"a frame of at most {limits.max_frame_bytes / 2**30:.3g} GiB working memory "
                             f"(RunLimits.max_frame_bytes, --max-frame-bytes); estimated {nbytes / 2**30:.3g} "
                             f"GiB ({how}); use a smaller image"))
    return problems


def _check_sensors(sensors) -> list:
    if not isinstance(sensors, Sequence) or isinstance(sensors, str):
        sensors = [sensors]
    names = set()
    for i, s in enumerate(sensors):
        for attr in ("name", "kind", "frame_rate", "capture"):
            if not hasattr(s, attr):
                raise ConfigError(f"sensors[{i}]", s, f"a twinsense sensor (missing {attr!r})")
        check_sensor_name(f"sensors[{i}].name", s.name)
        if s.name in names:
            raise ConfigError(f"sensors[{i}].name", s.name, "a name not used by another sensor")
        names.add(s.name)
        V.positive(f"sensors[{i}].frame_rate", s.frame_rate, "Hz")
    return list(sensors)


def check_processes(processes) -> int:
    """``processes`` of :func:`simulate` checked: an int in 1..64, above 1 only where processes can fork."""
    V.integer("processes", processes, lo=1, hi=64)
    if processes > 1 and not fork_available():
        raise ConfigError("processes", processes, "1 on a platform without the fork start method "
                          "(capture processes inherit the scene and sensors by forking)")
    if processes > 1 and multiprocessing.current_process().daemon:
        # multiprocessing refuses children of a daemonic process (a multiprocessing.Pool worker) with an
        # AssertionError from deep inside; said here instead.
        raise ConfigError("processes", processes, "1 inside a daemonic process (a multiprocessing.Pool worker), "
                          "which may not start capture processes")
    return processes


def simulate(scene: Scene, sensors, duration: float, out=None, *, seed: int = 0, t0: float = 0.0,
             progress: bool = False, keep_frames: bool | None = None,
             scenario: Mapping[str, Any] | None = None,
             on_frame: Callable[[Any, Any], None] | None = None,
             limits: RunLimits | None = None,
             stop: Callable[[], BaseException | None] | None = None,
             workers: int | None = None, processes: int | None = None,
             process_timeout: float | None = None, scenario_dir=None) -> SimulationResult:
    """Run ``sensors`` over ``[t0, t0 + duration)`` on one shared clock.

    Parameters
    ----------
    scene : Scene
    sensors : sensor or sequence of sensors
        Each needs ``name``, ``kind``, ``frame_rate`` [Hz] and ``capture``.
        A sensor that also has ``capture_frames(scene, times, rng) -> frames``
        gets each run of its consecutive frames (no other sensor's frame in
        between, at most 1024) in one call; it must give the frames and
        random draws that ``capture`` would one time after another.
    duration : float
        [s], > 0.
    out : path-like, optional
        HDF5 recording to write (a directory gets ``recording.h5`` inside).
        Frames are written as they are produced.
    seed : int
        Seeds one independent random stream per sensor (by position), so a
        sensor's noise does not change when another sensor is added.
    progress : bool
        Show a progress bar on the terminal.
    keep_frames : bool, optional
        Keep frames in memory (default: only when ``out`` is None).
    on_frame : callable, optional
        ``on_frame(sensor, frame)`` after each capture (live plots, streams).
    stop : callable, optional
        Called before each frame; when it returns an exception the run stops
        with it after the last whole frame (the recording is kept as
        ``<name>.partial.h5`` marked with it). The command line stops on
        SIGTERM/SIGHUP/Ctrl-C this way, never in the middle of a frame.
    limits : RunLimits, optional
        Frames per run and memory per frame allowed (checked before anything
        is allocated; ConfigError naming the field and the estimate).
    workers : int, optional
        Threads that capture different sensors' frames at once (default: the
        shared thread setting, ``TWINSENSE_THREADS`` or the cores up to 4,
        at most one per sensor; 1: one frame after another on this thread).
        A free thread takes the lane with the most work left (frames left x
        its measured cost per frame), and the sensors' ``prepare`` run on
        these threads beside the first captures.
        A sensor's own frames are always captured one after another, in
        clock order, with its own random stream, and frames reach the
        recording, ``keep_frames`` and ``on_frame`` in clock order on the
        calling thread: the run gives the same bytes whatever ``workers``.
        Sensors may capture frames up to a few frames ahead of the one being
        written; a stop or an error discards those. Use 1 when sensors share
        unguarded state, or when the scene's motion follows what ``on_frame``
        has seen (a controller fed from the frames).
    processes : int, optional
        Capture processes (default 1: none, the captures run in this process as ``workers`` says). With
        N > 1 the sensors' lanes are shared among N processes: this one, which keeps the group whose
        frames weigh most (:func:`home_group`) on a capture thread of its own, and N - 1 forked when the
        run starts (the scene, the sensors and their caches inherited, not pickled), each capturing its
        sensors' frames in clock order with ``TWINSENSE_THREADS`` = cores / N inner threads; their
        frames come back over pipes and reach the recording, ``keep_frames`` and ``on_frame`` here in
        clock order: the same bytes as one after another. The BLAS/OpenMP pools of each forked process
        are limited to the same share (threadpoolctl). The groups prepare their sensors before the
        recording is opened: a prepare that fails raises its own error and leaves no file, as one after
        another. Lanes go to processes by frame_rate x a per-kind cost (see :func:`lane_groups`);
        ``workers`` is then unused. The forked sensors' state after the run (a skin's last frame,
        caches built meanwhile) is not copied back. A process that dies or hangs (see
        ``process_timeout``) raises :class:`CaptureProcessError` naming its sensors and the frame.
        Needs the fork start method (Linux, macOS); elsewhere N > 1 is a ConfigError.
    process_timeout : float, optional
        [s] With ``processes`` > 1: the longest the run waits for one frame from a capture process (a
        block of n frames: n times it); past it the processes are ended and a
        :class:`CaptureProcessError` names the sensor, the scene time and the wait. Default None:
        max(60 s, 50 x the slowest frame handed back so far), and max(300 s, that) for each sensor's
        first frame and for the prepares (kernels compiled, caches filled); see
        :func:`process_wait`. A process that is alive but hangs is then found, not waited on forever.
    scenario_dir : path-like, optional
        The scenario file's folder, kept in the recording (``scenario_dir``) so that ``twinsense
        convert`` takes the stored scenario's relative paths from it.
    """
    if not isinstance(scene, Scene):
        raise ConfigError("scene", scene, "a twinsense.Scene")
    sensors = _check_sensors(sensors)
    V.positive("duration", duration, "s")
    V.integer("seed", seed, lo=0)
    if limits is not None and not isinstance(limits, RunLimits):
        raise ConfigError("limits", limits, "a twinsense.simulate.RunLimits")
    if workers is not None:
        V.integer("workers", workers, lo=1, hi=64)
    if processes is not None:
        check_processes(processes)
    if process_timeout is not None:
        V.positive("process_timeout", process_timeout, "s")
    t0 = V.time("t0", t0)
    for i, s in enumerate(sensors):
        # A mount on a frame the scene does not have: its error before any file is written (the first
        # capture would raise it with the recording open, leaving a partial file of no frames).
        parent = getattr(getattr(s, "mount", None), "parent", None)
        if parent is not None:
            try:
                scene.mount_target(parent)
            except UnknownNameError as exc:
                raise UnknownNameError(f"sensors[{i}].mount.parent", parent, exc.valid) from None
    problems = run_size_problems(sensors, duration, limits)
    if problems:
        raise ConfigError(*problems[0])
    keep = (out is None) if keep_frames is None else keep_frames
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(len(sensors))]
    # Merge the sensors' frame times into one ordered clock, lazily: a long
    # run never holds its frame times in memory.
    n_frames = [frame_count(s.frame_rate, duration) for s in sensors]
    blockable = [callable(getattr(s, "capture_frames", None)) for s in sensors]

    def make_runs() -> Iterator[tuple[int, list[float]]]:
        events = heapq.merge(*[_clock(s.frame_rate, n, t0, i) for i, (s, n) in enumerate(zip(sensors, n_frames))])
        return _runs(events, blockable)


    def prepare(i: int) -> None:
        # A sensor that meshes the scene (capacitive) resolves the objects where they are at its frame
        # times (the same t0 + k / rate values as the clock's).
        s = sensors[i]
        if callable(getattr(s, "prepare", None)):
            s.prepare(scene, t0 + np.arange(n_frames[i]) / s.frame_rate)

    n_procs = min(processes or 1, len(sensors))
    n_workers = min(default_workers() if workers is None else workers, len(sensors))
    source: Any
    if n_procs > 1:
        # Forked before the recording is opened (no HDF5 file is shared with a child) and before the
        # progress bar's refresh thread starts. Each process prepares its own sensors; the recording is
        # opened once all are prepared, so a prepare that fails leaves no file (as one after another).
        source = _Processes(scene, sensors, rngs, make_runs, n_procs, prepare, process_timeout, stop)
    elif n_workers > 1:
        # The prepares run on the capture threads beside the first captures; the recording is opened once
        # all are done, so a prepare that fails leaves no file (as one after another).
        source = _Ahead(scene, sensors, rngs, make_runs(), n_workers, prepare, n_frames)
        try:
            source.wait_prepared()
        except BaseException:
            source.close()
            raise
    else:
        for i in range(len(sensors)):
            prepare(i)
        source = ((i, times, lambda i=i, times=times: _capture(scene, sensors[i], times, rngs[i]))
                  for i, times in make_runs())
    closable = isinstance(source, (_Ahead, _Processes))
    writer = None
    path = None
    if out is not None:
        path = Path(out)
        if path.suffix not in (".h5", ".hdf5"):
            path = path / "recording.h5"
        try:
            writer = RecordingWriter(path, scenario=scenario, scenario_dir=scenario_dir)
        except BaseException:
            if closable:
                source.close()
            raise
        try:
            for s in sensors:
                cfg = s.config_dict() if hasattr(s, "config_dict") else {}
                writer.add_sensor(s.name, s.kind, s.frame_rate, cfg)
        except BaseException:
            writer.discard()  # no frame yet: leave nothing behind
            if closable:
                source.close()
            raise
    counts = {s.name: 0 for s in sensors}
    frames: dict[str, list] = {s.name: [] for s in sensors} if keep else {}
    bar = _progress(sum(n_frames)) if progress else None
    try:
        for i, times, get in source:
            s = sensors[i]
            if stop is not None and (reason := stop()) is not None:
                raise reason
            block = get()
            # A block goes to the recording in writes of whole runs of frames (one HDF5 write per stream),
            # at the latest _WRITE_AFTER after the last write and before an error or stop leaves the loop.
            # With on_frame (live sinks, a run paced to wall time) the callback may block, so each frame
            # is written before it is handed on, which keeps the recovery bound.
            pending: list = []
            since = time.monotonic()
            try:
                for k, (t, frame) in enumerate(zip(times, block)):
                    if k and stop is not None and (reason := stop()) is not None:
                        raise reason
                    if writer is not None:
                        if len(block) == 1 or on_frame is not None:
                            writer.append(s.name, t, frame.streams())
                        else:
                            pending.append((t, frame.streams()))
                    if keep:
                        frames[s.name].append(frame)
                    if on_frame is not None:
                        on_frame(s, frame)
                    counts[s.name] += 1
                    if bar is not None:
                        bar.advance()
                    if pending and time.monotonic() - since > _WRITE_AFTER:
                        _write(writer, s.name, pending)
                        since = time.monotonic()
            finally:
                if pending:
                    _write(writer, s.name, pending)
    except BaseException as exc:
        if closable:
            source.close()  # the captures still running end before the recording is closed
        if bar is not None:
            bar.stop()
        if writer is not None:
            writer.close(exc)
        raise
    if isinstance(source, _Ahead):
        source.close()
    elif isinstance(source, _Processes):
        source.close(finished=True)
    if bar is not None:
        bar.stop()
    removed: list[Path] = []
    stale: list[Path] = []
    if writer is not None:
        path = writer.close()
        removed, stale = writer.removed, writer.stale
    return SimulationResult(path, counts, frames, removed, stale)


# Longest block of consecutive frames captured at once: bounds the memory a block holds (a 64-element
# 3-axis magnetic array: 1024 x 64 x 3 x 8 B x 3 streams = 4.7 MB).
_BLOCK = 1024


# [s] Longest a captured frame of a block waits before it is written (a fraction of the recording's
# 0.5 s flush interval, so a hard kill loses no more than with one write per frame plus this).
_WRITE_AFTER = 0.1


def _capture(scene: Scene, sensor, times: list[float], rng) -> list:
    """The frames of ``sensor`` at ``times`` (one run of the clock), in order.

    A run of consecutive frames of one sensor is captured in one block when the sensor offers
    ``capture_frames`` (the same frames and random draws as one capture after another).
    """
    if len(times) > 1:
        frames = sensor.capture_frames(scene, times, rng)
        if len(frames) != len(times):  # the writer pairs frames with times: a short block would lose frames
            raise ConfigError(f"{sensor.name}.capture_frames", f"{len(frames)} frames",
                              f"one frame per time ({len(times)} times)")
        return frames
    return [sensor.capture(scene, times[0], rng)]


def _articulated_bodies(scene: Scene) -> list:
    """The articulated bodies (robots, people) whose links move objects or mount frames of ``scene``."""
    bodies: dict[int, Any] = {}
    for item in (*scene.objects, *(scene.mount_target(n) for n in scene.frame_names)):
        motion = getattr(item, "motion", None)
        if isinstance(motion, LinkMotion) and not motion.body.is_static:
            bodies.setdefault(id(motion.body), motion.body)
    return list(bodies.values())


class _Ahead:
    """The clock's runs captured ahead of the writer on a few threads, handed out in clock order.

    Each sensor is a lane: its runs are captured one after another in clock order (its random stream
    and its own caches are only ever used by one thread at a time), lanes run side by side on
    ``workers`` threads. A thread that is free takes the lane with the most work left: its frames
    still to capture x its cost per frame (measured: the wall time of its recent captures; before its
    first, the kind's expected cost, ``_KIND_COST``). The costliest lane (the skin with a hand on it)
    so keeps a thread for as long as it has a run queued, instead of queueing behind the other lanes
    after each frame; the others share the remaining threads. At most ``depth`` runs are ahead of the
    one being handed out: a bound on the frames held in memory and on how far the lanes drift apart.

    ``prepare(i)`` of each sensor that has one is the first task of its lane: the prepares run at once,
    beside the other lanes' first captures (:meth:`wait_prepared` waits for them and raises the first
    failing sensor's error, in sensor order).

    The articulated bodies' forward kinematics of each run's time is computed here, on the calling
    thread, before the run is queued: every sensor of that time then reads it from the body's cache
    instead of several threads computing the same time at once.

    Iterating gives ``(sensor index, times, get)``; ``get()`` waits for that run's frames (or raises its
    capture's error). :meth:`close` drops the runs not started and waits for those running.
    """

    def __init__(self, scene: Scene, sensors: list, rngs: list, runs: Iterator, workers: int,
                 prepare: Callable[[int], None] | None = None, frames: Sequence[int] | None = None):
        self._scene, self._sensors, self._rngs, self._runs = scene, sensors, rngs, runs
        self._prepare = prepare
        self._bodies = _articulated_bodies(scene)
        # Enough runs ahead for every sensor to have one queued behind the one being captured.
        self._depth = 2 * len(sensors)
        self._wake = threading.Condition()
        self._lanes: list[deque] = [deque() for _ in sensors]
        self._busy = [False] * len(sensors)
        self._dropped = [False] * len(sensors)  # lanes whose prepare failed
        self._order: deque = deque()  # (sensor index, times, future) in clock order
        self._closed = False
        # [s] per frame: the kind's expected cost until the lane's first capture, then measured.
        self._cost = [_KIND_COST.get(getattr(s, "kind", ""), _OTHER_KIND_COST) * 1e-3 for s in sensors]
        self._measured = [False] * len(sensors)
        self._left = list(frames) if frames is not None else [1] * len(sensors)
        self._prepares: list[tuple[int, Future]] = []
        if prepare is not None:
            for i, s in enumerate(sensors):
                if callable(getattr(s, "prepare", None)):
                    fut: Future = Future()
                    self._lanes[i].append((None, fut))
                    self._prepares.append((i, fut))
        self._fill()  # the first runs are captured beside the prepares
        self._threads = [threading.Thread(target=self._work, daemon=True, name=f"twinsense-capture-{k}")
                         for k in range(workers)]
        for t in self._threads:
            t.start()

    def wait_prepared(self) -> None:
        """Wait for every prepare; raise the first failing sensor's error (in sensor order)."""
        failed = {i: exc for i, fut in self._prepares if (exc := fut.exception()) is not None}
        if failed:
            raise failed[min(failed)]

    def __iter__(self):
        self._fill()
        while self._order:
            i, times, fut = self._order.popleft()
            self._fill()
            yield i, times, fut.result

    def _fill(self) -> None:
        while len(self._order) < self._depth:
            run = next(self._runs, None)
            if run is None:
                return
            i, times = run
            if len(times) == 1:
                for body in self._bodies:
                    try:
                        body.state(times[0])
                    except Exception:  # the capture at this time raises it, in clock order
                        pass
            fut: Future = Future()
            self._order.append((i, times, fut))
            with self._wake:
                self._lanes[i].append((times, fut))
                self._wake.notify()

    def _pick(self) -> int | None:
        """The lane a free thread takes (the lock held): a queued prepare first, else the most work left."""
        best, key = None, None
        for i, lane in enumerate(self._lanes):
            if lane and not self._busy[i] and not self._dropped[i]:
                k = (lane[0][0] is None, self._cost[i] * self._left[i], -i)
                if key is None or k > key:
                    best, key = i, k
        return best

    def _work(self) -> None:
        while True:
            with self._wake:
                while not self._closed and (i := self._pick()) is None:
                    self._wake.wait()
                if self._closed:
                    return
                self._busy[i] = True
                times, fut = self._lanes[i].popleft()
            seconds = 0.0
            if fut.set_running_or_notify_cancel():
                start = time.perf_counter()
                try:
                    if times is None:
                        self._prepare(i)  # type: ignore[misc]
                        block = None
                    else:
                        block = _capture(self._scene, self._sensors[i], times, self._rngs[i])
                except BaseException as exc:  # handed to the writer's thread, raised there at this run
                    if times is None:
                        # A sensor that could not be prepared is never captured (the run ends with this error
                        # at wait_prepared, as one after another): its lane is no longer picked.
                        self._dropped[i] = True
                    fut.set_exception(exc)
                else:
                    fut.set_result(block)
                seconds = time.perf_counter() - start
            with self._wake:
                self._busy[i] = False
                if times is not None:
                    n = len(times)
                    self._left[i] = max(self._left[i] - n, 0)
                    # The recent frames weigh most: a lane's cost changes during a run (a hand on the skin).
                    per = seconds / n
                    self._cost[i] = 0.5 * (self._cost[i] + per) if self._measured[i] else per
                    self._measured[i] = True
                self._wake.notify_all()

    def close(self) -> None:
        """Drop the runs not started; wait for the captures running (a capture cannot be interrupted)."""
        with self._wake:
            self._closed = True
            for lane in self._lanes:
                for _, fut in lane:
                    fut.cancel()
                lane.clear()
            self._wake.notify_all()
        for t in self._threads:
            t.join()


# Expected CPU of one frame per kind [ms], for sharing the lanes among capture processes: the robot
# cell's sensors each alone on one thread, as in a capture process, over its costliest second (the
# person's hand at the skin, 3.2-4.2 s; docs/moving-sensors.md): ToF 224 x 171 with 2 x 2 rays 19-45 ms
# (the wall camera's static hits kept, the wrist camera moving), radar 96 x 48 rays with a 64 x 64 cube
# 24 ms, the forearm skin 33-45 ms (2 ms away from the person); a VLP-16 revolution 84 ms and an
# ultrasonic ring's cycle 34 ms (BENCHMARKS.md), rounded. A kind not listed counts as a depth camera's.
# On the robot cell this gives {skin} and {wall ToF, radar, wrist ToF}: both ToF cameras in one
# process also share one caster (warmed, and its pages copied from the parent, once). In turn with
# {wall ToF, skin}, {radar, wrist ToF}, 3 rounds per 1-s window at load 2.5: from 0.9 s 1.12-1.14 against
# 1.30-1.62 s of CPU; over the reach 1.82-2.15 against 1.87-2.28 s (within the load's spread).
_KIND_COST = {"tof": 38.0, "radar": 24.0, "capacitive": 40.0, "camera": 20.0, "lidar": 84.0, "ultrasonic": 34.0}
_OTHER_KIND_COST = 20.0


def fork_available() -> bool:
    """Whether capture processes can run here (``simulate(processes=N > 1)`` needs the fork start method)."""
    return "fork" in multiprocessing.get_all_start_methods()


def lane_groups(sensors: Sequence, processes: int) -> list[list[int]]:
    """Sensor indices per capture process: each lane's frame_rate x kind cost, largest first, to the least
    loaded process (ties to the lowest process). Deterministic; every process gets at least one lane."""
    n = min(processes, len(sensors))
    cost = [float(s.frame_rate) * _KIND_COST.get(getattr(s, "kind", ""), _OTHER_KIND_COST) for s in sensors]
    groups: list[list[int]] = [[] for _ in range(n)]
    load = [0.0] * n
    for i in sorted(range(len(sensors)), key=lambda i: (-cost[i], i)):
        k = min(range(n), key=lambda k: (load[k], k))
        groups[k].append(i)
        load[k] += cost[i]
    return [sorted(g) for g in groups]


def home_group(sensors: Sequence, groups: list[list[int]]) -> int:
    """The group of :func:`lane_groups` that ``simulate(processes=N)`` captures in the calling process.

    The one whose frames weigh most (frame_rate x :func:`frame_memory_estimate`): its frames then cross
    no pipe and its caches (casters, static hits) are not copied into a child. Ties (sensors of kinds
    not estimated) go to the last group, the one of least expected CPU, since this process also writes
    the recording and calls ``on_frame``. On the robot cell the ToF cameras and the radar stay here and
    the skin is forked: 1.61 against 1.87 s of CPU per scene second over the reach, 1.12 against 1.27-1.30
    from 0.9 s (6 and 4 runs each, in turn; the skin kept here instead: 1.99 against 1.91-1.93).
    """
    weight = [sum(float(sensors[i].frame_rate) * frame_memory_estimate(sensors[i])[0] for i in g) for g in groups]
    return max(range(len(groups)), key=lambda k: (weight[k], k))


class CaptureProcessError(TwinsenseError, RuntimeError):
    """A capture process ended without handing back a frame the run needs (killed, crashed)."""


def _pickled(message) -> tuple[bytes, list]:
    """``message`` pickled with protocol 5: the pickle and its arrays' buffers (out of band, uncopied)."""
    buffers: list = []
    data = pickle.dumps(message, protocol=5, buffer_callback=buffers.append)
    return data, [b.raw() for b in buffers]


def _send_pickled(conn, pickled: tuple[bytes, list]) -> None:
    data, raws = pickled
    conn.send_bytes(pickle.dumps([r.nbytes for r in raws]))
    conn.send_bytes(data)
    for r in raws:
        conn.send_bytes(r)


def _send(conn, message) -> None:
    """``message`` over ``conn``: pickle protocol 5 with the arrays' buffers sent out of band, uncopied."""
    _send_pickled(conn, _pickled(message))


def _receive(conn):
    """The message of :func:`_send`; the arrays land in fresh writable buffers (one copy, from the socket)."""
    sizes = pickle.loads(conn.recv_bytes())
    data = conn.recv_bytes()
    buffers = []
    for n in sizes:
        b = bytearray(n)
        if n:
            conn.recv_bytes_into(b)
        else:
            conn.recv_bytes()
        buffers.append(b)
    return pickle.loads(data, buffers=buffers)


# [s] The default floor of the wait for one frame from a capture process, and of the wait for a sensor's
# first frame in its process and for the prepares, which may compile kernels (numba, when the disk cache
# is cold: tens of seconds on a busy 2-core machine) and fill caches (a skin's mesh).
PROCESS_TIMEOUT_FLOOR = 60.0
PROCESS_TIMEOUT_FIRST = 300.0
# The default wait is this many times the slowest frame handed back so far: a frame that slow is
# far outside anything a load swing gives; a process past it is taken as hung.
PROCESS_TIMEOUT_FACTOR = 50.0


def process_wait(process_timeout: float | None, slowest: float, frames: int = 1, first: bool = False) -> float:
    """[s] The longest wait for ``frames`` frames (or prepares) of a capture process.

    ``process_timeout`` [s] per frame when given; else max(60 s, 50 x ``slowest``), the slowest frame
    handed back so far [s], with a floor of 300 s instead when ``first`` (a sensor's first frame in its
    process, the prepares).
    """
    if process_timeout is not None:
        per = float(process_timeout)
    else:
        per = max(PROCESS_TIMEOUT_FIRST if first else PROCESS_TIMEOUT_FLOOR, PROCESS_TIMEOUT_FACTOR * slowest)
    return per * max(int(frames), 1)


def _limit_threads(threads: int) -> None:
    """Limit this (forked) process's inner threads to ``threads``: twinsense's pools and BLAS/OpenMP.

    BLAS and OpenMP read their thread variables when they are loaded, which happened in the parent
    before the fork: the libraries already loaded are limited through threadpoolctl, and the variables
    are set for any loaded later in this process.
    """
    for var in ("TWINSENSE_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(threads)
    _thread_pools().limit(limits=threads)  # kept for the process's life (not used as a context)


# The native thread pools of this process (threadpoolctl's controller) and the number of modules loaded
# when they were found: finding them walks every loaded library (30-40 ms of CPU in the robot cell's
# process), which each capture process did again at every run. Found in the parent before the fork,
# they serve every child; found again once a module has been loaded since (it may bring a library).
_POOLS: list = []


def _thread_pools():
    """threadpoolctl's controller of the native thread pools loaded in this process (kept, see _POOLS)."""
    from threadpoolctl import ThreadpoolController

    n = len(sys.modules)
    if not _POOLS or _POOLS[0][0] != n:
        _POOLS[:] = [(n, ThreadpoolController())]
    return _POOLS[0][1]


def _send_error(conn, exc: BaseException, what: str = "error", where: Any = None) -> None:
    """``(what, (where, exc))`` over ``conn``; an exception that does not pickle, or does not unpickle (a
    class whose ``__init__`` takes other arguments than its message), goes as its type and text."""
    try:
        pickle.loads(pickle.dumps(exc, protocol=5))  # the parent must be able to make it again
        _send(conn, (what, (where, exc)))
    except Exception:
        _send(conn, (what, (where, RuntimeError(f"{type(exc).__name__}: {exc}"))))


def _lane_child(conn, scene: Scene, sensors: list, rngs: list, runs: Iterator, mine: frozenset,
                threads: int, prepare: Callable[[int], None]) -> None:
    """A capture process: ``prepare(i)`` of the sensors ``mine``, then their runs in clock order, each
    sent back as it is done.

    Messages: ``("prepared", None)`` once every prepare is done (``("prepare-error", (i, exc))`` in its
    place when sensor i's fails), then ``("frames", (seconds, frames))`` per run (the capture's wall
    time [s] and its frames), or ``("error", (None, exc))`` in place of the run whose capture failed.
    """
    # The parent alone decides when the run stops (its stop callback sees Ctrl-C); a child killed by the
    # parent needs no handler of the caller's inherited through the fork.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        # Inner threads per capture (render chunks, ToF bands, skin solves, BLAS): the cores shared by the
        # processes.
        _limit_threads(threads)
        for i in sorted(mine):
            try:
                prepare(i)
            except BaseException as exc:  # raised in the parent before the recording is opened
                _send_error(conn, exc, "prepare-error", i)
                return
        _send(conn, ("prepared", None))
        # The frames leave through a sender thread: the next capture starts while the parent still reads
        # the last frame from the pipe (the robot cell's ToF child spent 0.30-0.48 s per scene second
        # between captures, 0.02-0.23 s with it). A process that dies takes with it the frames it had
        # captured but not yet written.
        conn = _Sender(conn, 16 * len(sensors))
        for i, times in runs:
            if i not in mine:
                continue
            try:
                start = time.perf_counter()
                block = _capture(scene, sensors[i], times, rngs[i])
                seconds = time.perf_counter() - start
            except BaseException as exc:  # raised in the parent at this run, in clock order
                _send_error(conn, exc)
                return
            try:
                message = _pickled(("frames", (seconds, block)))
            except Exception as exc:  # pickling fails before anything is sent: the stream stays whole
                _send_error(conn, CaptureProcessError(
                    f"sensor {sensors[i].name!r}'s frame at t = {times[0]:.6g} s cannot be handed on from a "
                    f"capture process ({type(exc).__name__}: {exc}); use processes=1 for this sensor"))
                return
            _send_pickled(conn, message)
    except (BrokenPipeError, ConnectionResetError):  # the parent stopped reading: the run has ended
        return
    finally:
        conn.close()


class _Sender:
    """The sending end of a capture process's pipe, written by a thread of its own.

    ``send_bytes`` queues (at most ``chunks`` pieces waiting: a bound on the frames held) and returns; the
    thread writes the pieces in order. Once a write has failed (the parent stopped reading) every later
    ``send_bytes`` raises BrokenPipeError. ``close`` waits until every queued piece is written (or
    dropped after a failure) and closes the pipe.
    """

    def __init__(self, conn, chunks: int):
        self._conn = conn
        self._queue: queue.Queue = queue.Queue(chunks)
        self._broken = False
        self._failure: BaseException | None = None  # a write's error other than a closed pipe
        self._thread = threading.Thread(target=self._run, daemon=True, name="twinsense-capture-sender")
        self._thread.start()

    def _run(self) -> None:
        # A write to a pipe whose reader is gone raises SIGPIPE in the writing thread; Python ignores it,
        # but a host program (or a library) may have restored its default action, which ends the whole
        # process. Blocked in this thread, the write fails with EPIPE (an OSError, handled below) and the
        # pending signal ends with the thread.
        if hasattr(signal, "pthread_sigmask"):
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGPIPE})
        while (piece := self._queue.get()) is not None:
            if self._broken:
                continue  # drained, so that a put never blocks behind a failed write
            try:
                self._conn.send_bytes(piece)
            except OSError:
                self._broken = True
            except BaseException as exc:  # kept for send_bytes to raise; the thread goes on draining
                self._failure = exc
                self._broken = True

    def send_bytes(self, piece) -> None:
        if self._failure is not None:
            # Not a closed pipe: the capture process ends with this error (a non-zero exit code, which
            # the parent names), its message possibly cut short on the pipe.
            raise RuntimeError("the capture process's sender thread failed to write a frame") from self._failure
        if self._broken:
            raise BrokenPipeError("the run's process stopped reading")
        self._queue.put(piece)

    def close(self) -> None:
        self._queue.put(None)
        self._thread.join()
        self._conn.close()


_STOP_POLL = 0.2  # [s] how often a wait for a capture process polls the run's stop


class _Processes:
    """The clock's runs captured by a few processes, each owning a fixed group of lanes: one group in
    this process, on a capture thread of its own, the others in forked processes.

    The processes are forked with the scene, the sensors (their caches, compiled kernels) and the
    run's random streams as they are now; each prepares its own sensors (a skin's mesh for the run's
    times), walks the same clock and captures its own sensors' runs in clock order, sending each back
    over a pipe. A reader thread per process receives them into a bounded queue (``depth`` runs: the
    frames held in memory and how far a process runs ahead). The group kept here (:func:`home_group`:
    the one whose frames weigh most) is captured the same way by a thread that queues its frames
    directly: its frames cross no pipe, its caches are the warm ones and no process is forked for it.
    Iterating hands the runs out in clock order like :class:`_Ahead`. The constructor returns once
    every group has prepared its sensors (or raises the first failing sensor's error, in sensor order,
    with the processes ended). Every wait for a group is bounded (:func:`process_wait`).
    """

    def __init__(self, scene: Scene, sensors: list, rngs: list, make_runs: Callable[[], Iterator],
                 processes: int, prepare: Callable[[int], None], timeout: float | None = None,
                 stop: Callable[[], BaseException | None] | None = None):
        ctx = multiprocessing.get_context("fork")
        self._stop = stop
        self._scene, self._sensors, self._rngs = scene, sensors, rngs
        self._groups = lane_groups(sensors, processes)
        self.home = home_group(sensors, self._groups)
        self._owner = {i: k for k, g in enumerate(self._groups) for i in g}
        self._runs = make_runs()
        self._closed = threading.Event()
        self._timeout = timeout
        self._slowest = 0.0  # [s] the slowest frame handed back so far
        self._seen: set[int] = set()  # sensors whose first frame was handed back
        self._hung = False  # this process's own lane passed its deadline: its thread cannot be ended
        threads = max(1, default_workers() // len(self._groups))
        _thread_pools()  # found here once, not in every child (see _POOLS)
        depth = 2 * len(sensors)
        self._procs: list = []
        self._queues: list[queue.Queue] = []
        self._readers: list[threading.Thread] = []
        self._conns: list = []
        try:
            for k, group in enumerate(self._groups):
                if k == self.home:
                    self._procs.append(None)
                    self._conns.append(None)
                    continue
                parent, child = ctx.Pipe(duplex=False)
                p = ctx.Process(target=_lane_child, name=f"twinsense-capture-{k}", daemon=True,
                                args=(child, scene, sensors, rngs, make_runs(), frozenset(group), threads,
                                      prepare))
                self._conns.append(parent)
                p.start()
                self._procs.append(p)
                child.close()  # the child alone holds the sending end: its exit is an end of file here
            # The readers and this process's own lane start after the last fork: no child is forked while
            # one of them runs.
            for k, conn in enumerate(self._conns):
                q: queue.Queue = queue.Queue(depth)
                if conn is None:
                    r = threading.Thread(target=self._home_lane, args=(q, self._groups[k], prepare, make_runs()),
                                         daemon=True, name="twinsense-capture-home")
                else:
                    r = threading.Thread(target=self._read, args=(conn, q), daemon=True,
                                         name=f"twinsense-capture-reader-{k}")
                r.start()
                self._queues.append(q)
                self._readers.append(r)
            self._wait_prepared(prepare)
        except BaseException:
            self.close()
            raise

    def _put(self, q: queue.Queue, msg) -> None:
        """``msg`` into ``q``, waiting while it is full, unless the run is closed meanwhile."""
        while not self._closed.is_set():
            try:
                q.put(msg, timeout=0.1)
                return
            except queue.Full:
                continue

    def _home_lane(self, q: queue.Queue, mine: list[int], prepare: Callable[[int], None], runs: Iterator) -> None:
        """This process's own group, on its capture thread: the messages of :func:`_lane_child`, queued."""
        for i in mine:
            try:
                prepare(i)
            except BaseException as exc:  # raised on the calling thread before the recording is opened
                self._put(q, ("prepare-error", (i, exc)))
                return
        self._put(q, ("prepared", None))
        for i, times in runs:
            if self._closed.is_set():
                return
            if i not in self._owner or self._owner[i] != self.home:
                continue
            try:
                start = time.perf_counter()
                block = _capture(self._scene, self._sensors[i], times, self._rngs[i])
                seconds = time.perf_counter() - start
            except BaseException as exc:  # raised on the calling thread at this run, in clock order
                self._put(q, ("error", (None, exc)))
                return
            self._put(q, ("frames", (seconds, block)))

    def _read(self, conn, q: queue.Queue) -> None:
        while not self._closed.is_set():
            try:
                msg = _receive(conn)
            except (EOFError, OSError):
                msg = ("ended", None)
            except BaseException as exc:  # a frame that does not unpickle
                msg = ("error", (None, exc))
            while not self._closed.is_set():
                try:
                    q.put(msg, timeout=0.1)
                    break
                except queue.Full:
                    continue
            if msg[0] not in ("frames", "prepared"):
                return

    def _rule(self) -> str:
        """The wait's rule, for messages."""
        if self._timeout is not None:
            return f"process_timeout = {self._timeout:g} s per frame"
        return (f"process_timeout None: max({PROCESS_TIMEOUT_FLOOR:g} s, {PROCESS_TIMEOUT_FACTOR:g} x the slowest "
                f"frame so far), {PROCESS_TIMEOUT_FIRST:g} s for a first frame or a prepare")

    def _names(self, k: int) -> str:
        return ", ".join(repr(self._sensors[j].name) for j in self._groups[k])

    def _who(self, k: int) -> str:
        """Group ``k`` named for messages."""
        if k == self.home:
            return f"this process's capture lane (sensors {self._names(k)})"
        return f"capture process {k} (sensors {self._names(k)})"

    def _ended(self, k: int) -> str:
        """How process ``k`` ended (it closed its pipe), once it has."""
        p = self._procs[k]
        p.join(timeout=5.0)
        code = p.exitcode
        return (f"killed by signal {-code} ({signal.Signals(-code).name})" if code is not None and code < 0
                else f"exit code {code}")

    def _wait_prepared(self, prepare) -> None:
        """Wait for every process's prepares; raise the first failing sensor's error (in sensor order)."""
        failed: dict[int, BaseException] = {}
        start = time.monotonic()
        for k, group in enumerate(self._groups):
            n = sum(callable(getattr(self._sensors[i], "prepare", None)) for i in group)
            wait = process_wait(self._timeout, 0.0, n, first=True)
            try:
                what, payload = self._take(k, max(start + wait - time.monotonic(), 0.0))
            except queue.Empty:
                self._hung = self._hung or k == self.home
                raise CaptureProcessError(
                    f"{self._who(k)} did not prepare its sensors within "
                    f"{wait:.3g} s ({self._rule()}); the capture processes were ended") from None
            if what == "prepare-error":
                failed[payload[0]] = payload[1]
            elif what != "prepared":
                raise CaptureProcessError(f"capture process {k} (sensors {self._names(k)}) ended "
                                          f"({self._ended(k)}) before its sensors were prepared")
        if failed:
            raise failed[min(failed)]

    def _take(self, k: int, wait: float):
        """Process ``k``'s next message within ``wait`` [s] (queue.Empty past it), polling the run's
        ``stop`` every _STOP_POLL seconds meanwhile: a stop (Ctrl-C through the command line) ends a
        run that waits on a slow or hung process as it ends one that captures."""
        end = time.monotonic() + wait
        while True:
            left = end - time.monotonic()
            try:
                return self._queues[k].get(timeout=max(min(left, _STOP_POLL), 0.0))
            except queue.Empty:
                if left <= _STOP_POLL:
                    raise
            if self._stop is not None and (reason := self._stop()) is not None:
                raise reason

    def __iter__(self):
        for i, times in self._runs:
            yield i, times, lambda i=i, times=times: self._get(i, times)

    def _get(self, i: int, times: list[float]) -> list:
        k = self._owner[i]
        wait = process_wait(self._timeout, self._slowest, len(times), first=i not in self._seen)
        try:
            what, payload = self._take(k, wait)
        except queue.Empty:
            # Alive but silent past the deadline (a capture stuck in a lock, a library that never
            # returns): the caller's error path ends the processes (a thread of this process cannot be
            # ended: it is left to finish or hang on its own).
            self._hung = self._hung or k == self.home
            raise CaptureProcessError(
                f"{self._who(k)} handed back no frame of sensor "
                f"{self._sensors[i].name!r} at t = {times[0]:.6g} s within {wait:.3g} s ({self._rule()}); "
                "the capture processes were ended") from None
        if what == "frames":
            seconds, block = payload
            self._seen.add(i)
            self._slowest = max(self._slowest, seconds / max(len(times), 1))
            return block
        if what == "error":
            raise payload[1]
        raise CaptureProcessError(
            f"capture process {k} (sensors {self._names(k)}) ended ({self._ended(k)}) before sensor "
            f"{self._sensors[i].name!r}'s frame at t = {times[0]:.6g} s")

    def close(self, finished: bool = False) -> None:
        """End the processes and the readers.

        ``finished``: every run was handed out, the processes end by themselves; otherwise (a stop, an
        error or a timeout) they are killed and the runs they captured ahead are dropped.
        """
        self._closed.set()
        procs = [p for p in self._procs if p is not None]
        for p in procs:
            if finished:
                p.join(timeout=10.0)
            if p.is_alive():
                p.kill()
        for p in procs:
            p.join()
        for k, r in enumerate(self._readers):
            # This process's own lane ends after its capture running (as a capture thread's): waited
            # for, unless it is the one that hung; after a stop or another group's error, for at most one
            # frame's wait (process_wait), since its capture may be the one hanging, not yet found.
            if k != self.home:
                r.join()
            elif not self._hung:
                r.join(None if finished else process_wait(self._timeout, self._slowest))
        for c in self._conns:
            if c is not None:
                c.close()
        for p in procs:
            p.close()


def _write(writer: RecordingWriter, name: str, pending: list) -> None:
    """Append the ``(t, streams)`` frames of ``pending`` in one block write and empty it."""
    times, streams = zip(*pending)
    pending.clear()
    writer.append_many(name, times, streams)


def _runs(events, blockable: list[bool]) -> Iterator[tuple[int, list[float]]]:
    """(sensor index, frame times) of the clock ``events``, consecutive frames of a blockable sensor grouped.

    A group holds frames of one sensor with no other sensor's frame between them (at most ``_BLOCK``);
    every other frame is a group of one. The order of frames is the clock's.
    """
    pending = None
    while True:
        event = pending if pending is not None else next(events, None)
        pending = None
        if event is None:
            return
        t, i = event
        times = [t]
        if blockable[i]:
            while len(times) < _BLOCK:
                nxt = next(events, None)
                if nxt is None or nxt[1] != i:
                    pending = nxt
                    break
                times.append(nxt[0])
        yield i, times


class _progress:
    """A small rich progress bar (frames done / total)."""

    def __init__(self, total: int):
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn

        self._p = Progress("[progress.description]{task.description}", BarColumn(), MofNCompleteColumn(),
                           TimeRemainingColumn(), transient=False)
        self._task = self._p.add_task("simulating", total=total)
        self._p.start()

    def advance(self) -> None:
        self._p.advance(self._task)

    def stop(self) -> None:
        self._p.stop()
