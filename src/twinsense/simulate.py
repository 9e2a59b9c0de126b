"""The simulation loop: every sensor sampled at its own frame times on one clock."""

from __future__ import annotations

import heapq
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.io.recording import RecordingWriter
from twinsense.scene.scene import Scene
from twinsense.sensors import frame_times


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
    """

    path: Path | None
    frame_counts: dict[str, int]
    frames: dict[str, list] = field(default_factory=dict)


def _check_sensors(sensors) -> list:
    if not isinstance(sensors, Sequence) or isinstance(sensors, str):
        sensors = [sensors]
    names = set()
    for i, s in enumerate(sensors):
        for attr in ("name", "kind", "frame_rate", "capture"):
            if not hasattr(s, attr):
                raise ConfigError(f"sensors[{i}]", s, f"a twinsense sensor (missing {attr!r})")
        if s.name in names:
            raise ConfigError(f"sensors[{i}].name", s.name, "a name not used by another sensor")
        names.add(s.name)
        V.positive(f"sensors[{i}].frame_rate", s.frame_rate, "Hz")
    return list(sensors)


def simulate(scene: Scene, sensors, duration: float, out=None, *, seed: int = 0, t0: float = 0.0,
             progress: bool = False, keep_frames: bool | None = None,
             scenario: Mapping[str, Any] | None = None,
             on_frame: Callable[[Any, Any], None] | None = None) -> SimulationResult:
    """Run ``sensors`` over ``[t0, t0 + duration)`` on one shared clock.

    Parameters
    ----------
    scene : Scene
    sensors : sensor or sequence of sensors
        Each needs ``name``, ``kind``, ``frame_rate`` [Hz] and ``capture``.
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
    """
    if not isinstance(scene, Scene):
        raise ConfigError("scene", scene, "a twinsense.Scene")
    sensors = _check_sensors(sensors)
    V.positive("duration", duration, "s")
    V.integer("seed", seed, lo=0)
    keep = (out is None) if keep_frames is None else keep_frames
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(len(sensors))]
    # Merge the sensors' frame times into one ordered clock.
    events = list(heapq.merge(*[[(float(t), i) for t in frame_times(s.frame_rate, duration, t0)]
                                for i, s in enumerate(sensors)]))
    writer = None
    path = None
    if out is not None:
        path = Path(out)
        if path.suffix not in (".h5", ".hdf5"):
            path = path / "recording.h5"
        writer = RecordingWriter(path, scenario=scenario)
        for s in sensors:
            cfg = s.config_dict() if hasattr(s, "config_dict") else {}
            writer.add_sensor(s.name, s.kind, s.frame_rate, cfg)
    counts = {s.name: 0 for s in sensors}
    frames: dict[str, list] = {s.name: [] for s in sensors} if keep else {}
    bar = _progress(len(events)) if progress else None
    try:
        for t, i in events:
            s = sensors[i]
            frame = s.capture(scene, t, rngs[i])
            if writer is not None:
                writer.append(s.name, t, frame.streams())
            if keep:
                frames[s.name].append(frame)
            if on_frame is not None:
                on_frame(s, frame)
            counts[s.name] += 1
            if bar is not None:
                bar.advance()
    except BaseException as exc:
        if bar is not None:
            bar.stop()
        if writer is not None:
            writer.close(exc)
        raise
    if bar is not None:
        bar.stop()
    if writer is not None:
        path = writer.close()
    return SimulationResult(path, counts, frames)


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
