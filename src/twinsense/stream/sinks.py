"""The sink protocol live transports implement, and a queued base for transports whose send may block.

A sink receives every frame of a running simulation. ``send`` is called on
the simulation thread, so it must never block: a sink that cannot keep up
drops the frame and counts it in ``dropped[sensor name]``. The simulation
never waits for a viewer, a network client or a disk.
"""

from __future__ import annotations

import queue
import threading
from typing import Any, Protocol, runtime_checkable

from twinsense import validation as V

#: Frames a queued sink holds while its sender thread catches up (per sink, all sensors together).
QUEUE_SIZE = 16
#: [s] How long ``close`` waits for a queued sink's sender thread to hand over what is queued.
CLOSE_TIMEOUT = 2.0


@runtime_checkable
class FrameSink(Protocol):
    """Where the frames of a live run go (a viewer, a network transport, a file).

    Attributes
    ----------
    dropped : dict[str, int]
        Frames not delivered, per sensor name (the sink was behind).
    """

    dropped: dict[str, int]

    def open(self, scene, sensors) -> None:
        """Start the transport for ``scene`` (a ``Scene``) and ``sensors`` (the run's sensors, in order)."""
        ...

    def send(self, sensor, t: float, frame) -> None:
        """Hand over ``frame`` of ``sensor`` captured at ``t`` [s]; never blocks (drop and count when behind)."""
        ...

    def close(self) -> None:
        """Stop the transport and release its sockets and threads; safe to call twice."""
        ...


class QueuedSink:
    """A sink whose frames go through a bounded queue to one sender thread.

    Subclasses implement :meth:`_publish` (runs on the sender thread, may
    take its time or block) and optionally :meth:`_start` / :meth:`_stop`.
    ``send`` only puts the frame on the queue; when the queue is full the
    frame is dropped and counted, so memory stays bounded by ``queue_size``
    frames whatever the clients do.
    """

    name = "queued"

    def __init__(self, queue_size: int = QUEUE_SIZE):
        self.queue_size = V.integer(f"{type(self).__name__}.queue_size", queue_size, lo=1)
        self.dropped: dict[str, int] = {}
        self.sent: dict[str, int] = {}
        self.error: BaseException | None = None
        self._queue: queue.Queue = queue.Queue(maxsize=self.queue_size)
        self._thread: threading.Thread | None = None
        self._closed = False

    # --- FrameSink -------------------------------------------------------------
    def open(self, scene, sensors) -> None:
        self.scene, self.sensors = scene, list(sensors)
        for s in self.sensors:
            self.dropped.setdefault(s.name, 0)
            self.sent.setdefault(s.name, 0)
        self._start()
        self._thread = threading.Thread(target=self._run, name=f"twinsense-{self.name}-sender", daemon=True)
        self._thread.start()

    def send(self, sensor, t: float, frame) -> bool:
        """Queue the frame for the sender thread; False (and counted) when it was dropped."""
        if self._closed or self.error is not None:
            self.dropped[sensor.name] = self.dropped.get(sensor.name, 0) + 1
            return False
        try:
            self._queue.put_nowait((sensor, float(t), frame))
        except queue.Full:
            self.dropped[sensor.name] = self.dropped.get(sensor.name, 0) + 1
            return False
        return True

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self._thread is not None and self._thread.is_alive():
            try:
                # The sender drains what is queued, then stops; a stuck transport is given up on
                # (the thread is a daemon) rather than holding the shutdown.
                self._queue.put(None, timeout=CLOSE_TIMEOUT)
            except queue.Full:
                pass
            self._thread.join(CLOSE_TIMEOUT)
        # Whatever is still queued (a stuck or broken transport) was never delivered.
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                break
            if item is not None:
                self.dropped[item[0].name] = self.dropped.get(item[0].name, 0) + 1
        self._stop()

    @property
    def queued(self) -> int:
        """Frames waiting for the sender thread (at most ``queue_size``)."""
        return self._queue.qsize()

    # --- for subclasses --------------------------------------------------------
    def _start(self) -> None:
        """Open the transport (called by ``open`` before the sender thread starts)."""

    def _stop(self) -> None:
        """Close the transport (called by ``close`` after the sender thread ended)."""

    def _publish(self, sensor, t: float, frame) -> None:
        raise NotImplementedError

    def _run(self) -> None:
        while True:
            item: Any = self._queue.get()
            if item is None:
                return
            sensor, t, frame = item
            try:
                self._publish(sensor, t, frame)
                self.sent[sensor.name] = self.sent.get(sensor.name, 0) + 1
            except Exception as exc:  # a broken transport stops this sink, never the run
                self.error = exc
                self.dropped[sensor.name] = self.dropped.get(sensor.name, 0) + 1
                return
