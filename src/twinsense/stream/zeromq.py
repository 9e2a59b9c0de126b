"""Live frames over ZeroMQ publish / subscribe (pyzmq, the ``stream`` extra).

One message per frame, multipart (docs/streaming.md has the full layout
and a MATLAB and a Python client sketch):

====  ==========================================================================
part  content
====  ==========================================================================
0     topic ``frame/<sensor>/`` (ASCII; the trailing slash lets a subscriber
      filter one sensor by prefix without matching ``<sensor>2``)
1     header, UTF-8 JSON: ``{"version": 1, "sensor", "kind", "t" [s], "index"
      (the sensor's frame number, counting dropped frames), "seq" (over all
      sensors), "streams": [{"name", "dtype" (numpy ``dtype.str``, e.g.
      ``"<f4"``), "shape"}, ...]}``
2...  one raw buffer per stream, in header order, C order, sent zero-copy
====  ==========================================================================

Control messages: ``ctrl/stats`` (every ``stats_interval`` seconds) and
``ctrl/end`` (the last message of a run), one JSON part each: ``{"sent":
{sensor: n}, "dropped": {sensor: n}, "t": last frame time [s]}``.

A publisher never waits for a subscriber. By default each subscriber has
its own queue of ``hwm`` messages in libzmq and a subscriber that falls
behind loses its own frames (it sees the gaps in ``index``; the
:class:`Subscriber` counts them in ``missed``). With ``nodrop=True`` the
publisher refuses a frame as long as any subscriber's queue is full and
counts it in ``dropped``: nobody gets the frame, everybody stays in step.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.stream.frames import frame_arrays

#: Layout version in every header.
VERSION = 1
#: Messages a subscriber's queue holds in the publisher before its frames are dropped (per subscriber).
HWM = 16
#: [s] Default period of the ``ctrl/stats`` message.
STATS_INTERVAL = 1.0
#: [ms] How long closing the publisher waits to hand over queued messages (the ``ctrl/end`` message).
LINGER_MS = 500


def require_zmq():
    """The ``zmq`` module, or an ImportError naming the extra that installs it."""
    try:
        import zmq
    except ImportError as err:
        raise ImportError("live streams need the optional 'stream' extra: "
                          "pip install 'twinsense[stream]' (pyzmq, foxglove-sdk)") from err
    return zmq


def frame_topic(sensor: str) -> bytes:
    """The topic of ``sensor``'s frames: ``b"frame/<sensor>/"``."""
    return f"frame/{sensor}/".encode()


def _address(field_name: str, address: Any) -> str:
    if not isinstance(address, str) or "://" not in address:
        raise ConfigError(field_name, address, "a ZeroMQ endpoint such as 'tcp://127.0.0.1:5555' "
                                               "(tcp://host:*  picks a free port), ipc://path or inproc://name")
    if address.startswith("tcp://"):
        # libzmq takes the port modulo 65536 (tcp://host:70000 binds port 4464): check it here.
        port = address.rpartition(":")[2]
        if port != "*" and not (port.isdigit() and 1 <= int(port) <= 65535):
            raise ConfigError(field_name, address, "a tcp:// endpoint with a port 1..65535 or * (a free port)")
    return address


class ZmqSink:
    """A ZeroMQ PUB socket publishing every frame (a :class:`~twinsense.stream.sinks.FrameSink`).

    Parameters
    ----------
    address : str
        Endpoint to bind, e.g. ``"tcp://127.0.0.1:5555"``; ``tcp://127.0.0.1:*``
        binds a free port (``endpoint`` tells which, after ``open``).
    hwm : int
        Send high-water mark [messages] per subscriber.
    nodrop : bool
        Refuse (and count) a frame while a subscriber is ``hwm`` behind,
        instead of letting libzmq drop it for that subscriber alone.
    stats_interval : float
        [s] Wall time between ``ctrl/stats`` messages.
    """

    name = "zmq"

    def __init__(self, address: str = "tcp://127.0.0.1:5555", *, hwm: int = HWM, nodrop: bool = False,
                 stats_interval: float = STATS_INTERVAL):
        self.address = _address("ZmqSink.address", address)
        self.hwm = V.integer("ZmqSink.hwm", hwm, lo=1)
        self.nodrop = bool(nodrop)
        self.stats_interval = V.positive("ZmqSink.stats_interval", stats_interval, "s")
        self.endpoint: str | None = None
        #: Subscribers that joined (see :meth:`wait_for_subscribers`).
        self.subscribers = 0
        self.dropped: dict[str, int] = {}
        self.sent: dict[str, int] = {}
        self._index: dict[str, int] = {}
        self._seq = 0
        self._last_t = 0.0
        self._next_stats = 0.0
        self._ctx = self._sock = None

    def open(self, scene, sensors) -> None:
        zmq = require_zmq()
        self._zmq = zmq
        self._ctx = zmq.Context()
        # XPUB is PUB that also reports subscriptions (verbose: every subscriber's, so they can be counted).
        sock = self._ctx.socket(zmq.XPUB)
        sock.setsockopt(zmq.SNDHWM, self.hwm)
        sock.setsockopt(zmq.LINGER, LINGER_MS)
        sock.setsockopt(zmq.XPUB_VERBOSE, 1)
        if self.nodrop:
            sock.setsockopt(zmq.XPUB_NODROP, 1)
        try:
            sock.bind(self.address)
        except zmq.ZMQError as err:
            sock.close(0)
            self._ctx.term()
            self._ctx = None
            raise ConfigError("ZmqSink.address", self.address, f"an endpoint this process can bind ({err})") from None
        self._sock = sock
        self.endpoint = sock.getsockopt_string(zmq.LAST_ENDPOINT)
        for s in sensors:
            self.dropped.setdefault(s.name, 0)
            self.sent.setdefault(s.name, 0)
            self._index.setdefault(s.name, 0)
        self._next_stats = time.monotonic() + self.stats_interval

    def send(self, sensor, t: float, frame) -> None:
        name = sensor.name
        k = self._index.get(name, 0)
        self._index[name] = k + 1
        if self._sock is None:
            self.dropped[name] = self.dropped.get(name, 0) + 1
            return
        arrays = frame_arrays(frame)
        header = {"version": VERSION, "sensor": name, "kind": sensor.kind, "t": float(t), "index": k,
                  "seq": self._seq,
                  "streams": [{"name": n, "dtype": a.dtype.str, "shape": list(a.shape)} for n, a in arrays.items()]}
        self._seq += 1
        self._last_t = float(t)
        parts = [frame_topic(name), json.dumps(header).encode(), *arrays.values()]
        zmq = self._zmq
        try:
            self._sock.send_multipart(parts, flags=zmq.NOBLOCK, copy=False)
            self.sent[name] = self.sent.get(name, 0) + 1
        except zmq.Again:
            self.dropped[name] = self.dropped.get(name, 0) + 1
        self._drain_subscriptions()
        if time.monotonic() >= self._next_stats:
            self._control(b"ctrl/stats")
            self._next_stats = time.monotonic() + self.stats_interval

    def stats(self) -> dict:
        """The ``ctrl/stats`` content: frames sent and dropped per sensor, the last frame time [s]."""
        return {"sent": dict(self.sent), "dropped": dict(self.dropped), "t": self._last_t}

    def close(self) -> None:
        if self._sock is None:
            return
        self._control(b"ctrl/end")
        self._sock.close()  # waits up to LINGER_MS for queued messages, never longer
        self._ctx.term()
        self._sock = self._ctx = None

    def _control(self, topic: bytes) -> None:
        try:
            self._sock.send_multipart([topic, json.dumps(self.stats()).encode()], flags=self._zmq.NOBLOCK)
        except self._zmq.Again:
            pass  # a subscriber is full: it will see the next one

    def wait_for_subscribers(self, n: int = 1, timeout: float = 5.0) -> int:
        """Wait up to ``timeout`` [s] until ``n`` subscribers have joined; returns how many have.

        A subscriber counts once it subscribed to the control topic (every
        :class:`Subscriber` does) or to everything (an empty prefix). A
        publisher can hold its first frame this way: ZeroMQ subscriptions
        reach the publisher a moment after ``connect``, and frames before
        that are not delivered to the newcomer.
        """
        V.integer("n", n, lo=0)
        deadline = time.monotonic() + V.non_negative("timeout", timeout, "s")
        while self._sock is not None and self.subscribers < n:
            left = deadline - time.monotonic()
            if left <= 0 or not self._sock.poll(max(1, round(left * 1000))):
                break
            self._drain_subscriptions()
        return self.subscribers

    def _drain_subscriptions(self) -> None:
        # An XPUB socket queues every (un)subscription for the application; read them so they cannot pile up.
        zmq = self._zmq
        while self._sock.getsockopt(zmq.EVENTS) & zmq.POLLIN:
            msg = self._sock.recv()
            if msg[1:] in (b"ctrl/", b""):
                self.subscribers += 1 if msg[:1] == b"\x01" else -1


@dataclass(frozen=True, eq=False)
class StreamFrame:
    """One frame received from a stream.

    Attributes
    ----------
    sensor, kind : str
    t : float
        Capture time [s] (simulation time).
    index : int
        The sensor's frame number in the run.
    arrays : dict[str, np.ndarray]
        The frame's streams (read-only views of the received buffers), shapes
        and dtypes as sent.
    header : dict
        The decoded JSON header.
    """

    sensor: str
    kind: str
    t: float
    index: int
    arrays: dict[str, np.ndarray] = field(repr=False)
    header: dict = field(repr=False)


def decode(parts: Sequence) -> StreamFrame:
    """A :class:`StreamFrame` from the parts of one frame message (bytes or ``zmq.Frame``)."""
    def buf(p):
        return p.buffer if hasattr(p, "buffer") else p

    header = json.loads(bytes(buf(parts[1])))
    specs = header["streams"]
    if len(parts) != 2 + len(specs):
        raise ConfigError("message", f"{len(parts)} parts", f"2 + {len(specs)} parts (topic, header, streams)")
    arrays = {s["name"]: np.frombuffer(buf(p), dtype=np.dtype(s["dtype"])).reshape(s["shape"])
              for s, p in zip(specs, parts[2:])}
    return StreamFrame(header["sensor"], header["kind"], float(header["t"]), int(header["index"]), arrays, header)


class Subscriber:
    """Receives the frames of a :class:`ZmqSink` (a ZeroMQ SUB socket).

    Iterate to get :class:`StreamFrame` objects; the iteration ends with the
    publisher's ``ctrl/end`` message or after ``timeout`` seconds without a
    message.

    Parameters
    ----------
    address : str
        The publisher's endpoint, e.g. ``"tcp://127.0.0.1:5555"``.
    topics : sequence of str, optional
        Sensor names to receive (default: every sensor).
    timeout : float
        [s] Longest wait for one message.
    hwm : int
        Receive high-water mark [messages].

    Attributes
    ----------
    missed : dict[str, int]
        Frames of each sensor that did not arrive (gaps in ``index``).
    stats : dict or None
        The last ``ctrl/stats`` or ``ctrl/end`` content.
    ended : bool
        The publisher sent ``ctrl/end``.
    """

    def __init__(self, address: str, topics: Sequence[str] | None = None, timeout: float = 5.0, hwm: int = 1000):
        zmq = require_zmq()
        self._zmq = zmq
        address = _address("Subscriber.address", address)
        self.timeout = V.positive("Subscriber.timeout", timeout, "s")
        if isinstance(topics, str) or (topics is not None and not all(isinstance(t, str) for t in topics)):
            raise ConfigError("Subscriber.topics", topics, "a list of sensor names (str), or None for all")
        self.topics = None if topics is None else list(topics)
        self.missed: dict[str, int] = {}
        self.stats: dict | None = None
        self.ended = False
        self._next: dict[str, int] = {}
        self._ctx = zmq.Context()
        self._sock = self._ctx.socket(zmq.SUB)
        self._sock.setsockopt(zmq.RCVHWM, V.integer("Subscriber.hwm", hwm, lo=1))
        self._sock.setsockopt(zmq.LINGER, 0)
        for t in ([b"frame/"] if self.topics is None else [frame_topic(n) for n in self.topics]) + [b"ctrl/"]:
            self._sock.setsockopt(zmq.SUBSCRIBE, t)
        try:
            self._sock.connect(address)
        except zmq.ZMQError as err:
            self.close()
            raise ConfigError("Subscriber.address", address, f"an endpoint to connect to ({err})") from None

    def recv(self, timeout: float | None = None) -> StreamFrame | None:
        """The next frame, or None when ``timeout`` [s] (default ``self.timeout``) passes or the run ended."""
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        while not self.ended:
            wait_ms = max(0, round((deadline - time.monotonic()) * 1000))
            if not self._sock.poll(wait_ms):
                return None
            parts = self._sock.recv_multipart(copy=False)
            topic = bytes(parts[0].buffer)
            if topic.startswith(b"ctrl/"):
                self.stats = json.loads(bytes(parts[1].buffer))
                self.ended = topic == b"ctrl/end"
                continue
            frame = decode(parts)
            expected = self._next.get(frame.sensor)
            if expected is not None and frame.index > expected:
                self.missed[frame.sensor] = self.missed.get(frame.sensor, 0) + frame.index - expected
            self.missed.setdefault(frame.sensor, 0)
            self._next[frame.sensor] = frame.index + 1
            return frame
        return None

    def __iter__(self) -> Iterator[StreamFrame]:
        while (frame := self.recv()) is not None:
            yield frame

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close(0)
            self._ctx.term()
            self._sock = None

    def __enter__(self) -> Subscriber:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
