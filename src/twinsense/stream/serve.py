"""A live run: the simulation paced to wall time, every frame handed to every sink."""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.simulate import SimulationResult, simulate
from twinsense.stream.sinks import FrameSink

#: [s] Longest sleep of the pacing loop between checks of ``stop`` (how fast a stop request is seen).
STOP_POLL = 0.05


@dataclass
class ServeResult:
    """What a live run did.

    Attributes
    ----------
    result : SimulationResult or None
        The simulation's result (None when the run was stopped).
    sent, dropped : dict[str, dict[str, int]]
        Frames delivered / dropped per sink name and sensor name.
    wall_time : float
        [s] From the first frame's start to the last sink closed.
    late : int
        Frames captured after their wall-clock time (the simulation was
        slower than ``rate`` there).
    stopped : BaseException or None
        What stopped the run early (a stop request, an error).
    errors : dict[str, str]
        Per sink name, the error that stopped a sink's transport during the
        run (its later frames are counted as dropped; the run went on).
    """

    result: SimulationResult | None
    sent: dict[str, dict[str, int]] = field(default_factory=dict)
    dropped: dict[str, dict[str, int]] = field(default_factory=dict)
    wall_time: float = 0.0
    late: int = 0
    stopped: BaseException | None = None
    errors: dict[str, str] = field(default_factory=dict)

    def summary(self) -> str:
        """One line per sink: frames sent and dropped per sensor."""
        lines = []
        for sink, sent in self.sent.items():
            drops = self.dropped.get(sink, {})
            per = ", ".join(f"{s}: {n} sent, {drops.get(s, 0)} dropped" for s, n in sent.items())
            err = f" (transport failed: {self.errors[sink]})" if sink in self.errors else ""
            lines.append(f"{sink}: {per or 'no sensors'}{err}")
        return "\n".join(lines)


def _sink_name(sink: Any, i: int, taken: set[str]) -> str:
    base = str(getattr(sink, "name", None) or type(sink).__name__)
    name = base if base not in taken else f"{base}{i}"
    taken.add(name)
    return name


def serve(scene, sensors, duration: float, sinks: Sequence[FrameSink], *, rate: float = 1.0, out=None,
          seed: int = 0, scenario: dict | None = None, stop: Callable[[], BaseException | None] | None = None,
          limits=None, on_open: Callable[[list], None] | None = None,
          clock: Callable[[], float] = time.monotonic) -> ServeResult:
    """Run ``sensors`` in ``scene`` for ``duration`` [s], publishing every frame to ``sinks`` as it is made.

    ``rate`` is simulation seconds per wall second: a frame of time ``t`` is
    handed to the sinks no earlier than ``t / rate`` after the run started
    (``rate = 0``: as fast as possible). A run slower than that is never
    held back; it runs late. ``out`` also writes the HDF5 recording (a
    stopped run keeps its frames in ``<name>.partial.h5``). ``stop``: as in
    :func:`twinsense.simulate.simulate`, also polled while waiting for the
    wall clock. ``limits``: see ``simulate``. ``on_open(sinks)`` is called
    once every sink is open (to announce ports). Every sink is closed on
    return, however the run ended;
    an exception stopping the run is raised after that, with the
    :class:`ServeResult` as its ``serve_result`` attribute.
    """
    rate = V.non_negative("rate", rate)
    sinks = list(sinks)
    for i, s in enumerate(sinks):
        if not all(callable(getattr(s, m, None)) for m in ("open", "send", "close")) or not hasattr(s, "dropped"):
            raise ConfigError(f"sinks[{i}]", s, "a FrameSink (open, send, close, dropped)")
    sensors = list(sensors) if isinstance(sensors, Sequence) else [sensors]
    taken: set[str] = set()
    names = [_sink_name(s, i, taken) for i, s in enumerate(sinks)]
    res = ServeResult(None)
    opened: list[FrameSink] = []
    start = clock()

    def poll_stop() -> BaseException | None:
        return None if stop is None else stop()

    def on_frame(sensor, frame) -> None:
        t = float(frame.t)
        if rate > 0:
            due = start + t / rate
            if clock() > due + STOP_POLL:
                res.late += 1
            while (left := due - clock()) > 0:
                if (reason := poll_stop()) is not None:
                    raise reason
                time.sleep(min(left, STOP_POLL))
        for s in opened:
            s.send(sensor, t, frame)

    try:
        for s in sinks:
            s.open(scene, sensors)
            opened.append(s)
        if on_open is not None:
            on_open(opened)
        start = clock()
        res.result = simulate(scene, sensors, duration, out=out, seed=seed, scenario=scenario, keep_frames=False,
                              on_frame=on_frame, stop=poll_stop, limits=limits)
    except BaseException as exc:
        res.stopped = exc
        exc.serve_result = res
        raise
    finally:
        for s in opened:
            try:
                s.close()
            except Exception as err:  # one broken sink must not keep the others open
                res.stopped = res.stopped or err
        for name, s in zip(names, sinks):
            res.dropped[name] = dict(s.dropped)
            res.sent[name] = dict(getattr(s, "sent", {}) or {s2: 0 for s2 in s.dropped})
            if getattr(s, "error", None) is not None:
                res.errors[name] = f"{type(s.error).__name__}: {s.error}"
        res.wall_time = clock() - start
    return res


def serve_scenario(sc, sinks: Sequence[FrameSink], *, rate: float = 1.0, out_dir=None,
                   stop: Callable[[], BaseException | None] | None = None,
                   on_open: Callable[[list], None] | None = None) -> ServeResult:
    """:func:`serve` a loaded :class:`~twinsense.scenario.Scenario`; ``out_dir`` also records it there.

    A served run captures in this one process: its sinks hold server threads
    and sockets that forked capture processes must not inherit, so a
    scenario's ``processes`` key (for ``twinsense run``) is not used here and
    a warning says so.
    """
    if getattr(sc, "processes", 1) != 1:
        warnings.warn(f"processes: {sc.processes} is not used by serve: a served run captures in one process",
                      UserWarning, stacklevel=2)
    out = sc.recording_path(out_dir) if out_dir is not None else None
    return serve(sc.scene, sc.sensors, sc.duration, sinks, rate=rate, out=out, seed=sc.seed, scenario=sc.raw,
                 stop=stop, limits=sc.limits, on_open=on_open)
