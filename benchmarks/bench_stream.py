"""Live streams: what publishing costs the simulation thread, and ZeroMQ throughput over loopback.

Two frame sizes: small (an inductive switch update, five 1-element streams)
and large (a 640 x 480 depth camera: range and depth float32 + object id
int32 = 3.7 MB).

- send cost on the simulation thread: ``ZmqSink.send`` (header, zero-copy
  non-blocking send) and ``FoxgloveSink.send`` (a bounded queue put; the
  conversion runs on the sink's own thread), best and median over up to 200
  calls with one subscriber reading;
- the Foxglove sender thread's work per frame (conversion to the built-in
  message types and ``log``, no client connected), best and median;
- throughput: frames/s a ``Subscriber`` receives from a ``ZmqSink`` over
  TCP loopback, each frame decoded into numpy arrays, against the anchor: a
  bare pyzmq PUB/SUB pair sending the same buffers zero-copy (no header, no
  decoding), best of 3 runs in the same process.

Run:  .venv/bin/python benchmarks/bench_stream.py
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np
import zmq
from _timing import print_load_at_end, print_machine

from twinsense.depthcam import DepthCamera, DepthFrame
from twinsense.stream import FoxgloveSink, Subscriber, ZmqSink


@dataclass(frozen=True)
class _Frame:
    t: float
    arrays: dict

    def streams(self):
        return self.arrays


@dataclass(frozen=True)
class _Sensor:
    name: str = "s"
    kind: str = "inductive"
    frame_rate: float = 1000.0

    def config_dict(self):
        return {}


def sensor(kind: str):
    return _Sensor() if kind == "small" else DepthCamera.preset("vga", name="s")


def frames(kind: str, n: int, rng: np.random.Generator) -> list[_Frame]:
    if kind == "small":
        return [_Frame(k / 1000, {"output": np.array([k % 2], np.uint8), "quality": rng.random(1),
                                  "delta_r": rng.random(1), "delta_l": rng.random(1), "frequency": rng.random(1)})
                for k in range(n)]
    d = rng.random((480, 640), dtype=np.float32)
    ids = np.zeros((480, 640), np.int32)
    return [DepthFrame(k / 30, d, d, ids) for k in range(n)]


def anchor(data: list[_Frame]) -> float:
    """Frames/s of a bare pyzmq PUB -> SUB pair over TCP loopback (zero-copy, no header, no decoding)."""
    ctx = zmq.Context()
    pub, sub = ctx.socket(zmq.PUB), ctx.socket(zmq.SUB)
    pub.setsockopt(zmq.SNDHWM, 0)
    port = pub.bind_to_random_port("tcp://127.0.0.1")
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(f"tcp://127.0.0.1:{port}")
    time.sleep(0.3)  # the slow-joiner handshake, outside the timing
    got = []
    th = threading.Thread(target=lambda: got.extend(sub.recv_multipart(copy=False) for _ in data))
    t0 = time.perf_counter()
    th.start()
    for f in data:
        pub.send_multipart([b"s", *f.streams().values()], copy=False)
    th.join()
    dt = time.perf_counter() - t0
    pub.close(0)
    sub.close(0)
    ctx.term()
    return len(got) / dt


def twinsense_rate(data: list, sen) -> float:
    """Frames/s a Subscriber receives (decoded) from a ZmqSink over TCP loopback."""
    sink = ZmqSink("tcp://127.0.0.1:*", hwm=len(data) + 10, nodrop=True)
    sink.open(None, [sen])
    sub = Subscriber(sink.endpoint, timeout=30.0, hwm=len(data) + 10)
    sink.wait_for_subscribers(1, 10.0)
    got = []

    def receive():
        for f in sub:
            got.append(f)
            if len(got) == len(data):
                return

    th = threading.Thread(target=receive)
    t0 = time.perf_counter()
    th.start()
    for f in data:
        sink.send(sen, f.t, f)
    th.join()
    dt = time.perf_counter() - t0
    assert not any(sink.dropped.values()), sink.dropped
    sink.close()
    sub.close()
    return len(got) / dt


def send_cost(send, sen, data: list) -> tuple[float, float]:
    """(best, median) seconds of one ``send(sensor, t, frame)`` on the calling thread."""
    times = []
    for f in data:
        t0 = time.perf_counter()
        send(sen, f.t, f)
        times.append(time.perf_counter() - t0)
    return min(times), float(np.median(times))


def main() -> None:
    print_machine()
    rng = np.random.default_rng(0)
    for kind, n in (("small", 2000), ("large", 60)):
        data, sen = frames(kind, n, rng), sensor(kind)
        size = sum(a.nbytes for a in data[0].streams().values())
        print(f"{kind} frames: {size:,} B each, {n} frames")
        ref = max(anchor(data) for _ in range(3))
        rate = max(twinsense_rate(data, sen) for _ in range(3))
        print(f"  {'anchor: bare pyzmq PUB/SUB, zero-copy':<46s} {ref:10.0f} frames/s ({ref * size / 1e6:8.1f} MB/s)")
        print(f"  {'ZmqSink -> Subscriber (header, decode)':<46s} {rate:10.0f} frames/s ({rate * size / 1e6:8.1f} MB/s)"
              f"  {rate / ref:.2f} x anchor")

        z = ZmqSink("tcp://127.0.0.1:*", hwm=8)
        z.open(None, [sen])
        sub = Subscriber(z.endpoint, timeout=1.0)
        z.wait_for_subscribers(1, 10.0)
        reader = threading.Thread(target=lambda sub=sub: list(sub))
        reader.start()
        best, med = send_cost(z.send, sen, data[:200])
        z.close()
        reader.join()
        sub.close()
        print(f"  {'ZmqSink.send on the simulation thread':<46s} best {best * 1e6:8.1f} us, median {med * 1e6:8.1f} us")
        f = FoxgloveSink(port=0, queue_size=16)
        f.open(_EmptyScene(), [sen])
        best, med = send_cost(f.send, sen, data[:200])
        f.close()
        assert f.error is None, f.error
        print(f"  {'FoxgloveSink.send on the simulation thread':<46s} best {best * 1e6:8.1f} us, "
              f"median {med * 1e6:8.1f} us")
        f = FoxgloveSink(port=0)
        f.scene, f.sensors = _EmptyScene(), [sen]
        f._start()  # the transport alone: the sender thread's work is timed on this thread
        best, med = send_cost(lambda s, t, fr, f=f: f._publish(s, t, (fr, [])), sen, data[:200])
        f._stop()
        print(f"  {'Foxglove conversion + log per frame':<46s} best {best * 1e3:8.3f} ms, median {med * 1e3:8.3f} ms")
    print_load_at_end()


class _EmptyScene:
    def __iter__(self):
        return iter(())


if __name__ == "__main__":
    main()
