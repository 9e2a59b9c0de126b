"""Recording throughput: the cost of the periodic flush that makes a killed run recoverable.

Writes the same frames three ways, in one process, into a temporary folder:

- anchor: plain h5py, the same datasets and chunk layout, resized and
  written frame by frame, closed once (no flush, no thread);
- RecordingWriter with ``flush_interval=None`` (flush only at close);
- RecordingWriter with the default ``flush_interval`` (0.5 s, the
  recoverable setting), and with 0.05 s (ten times as often) to show the
  trend.

Block appends (``append_many``, what ``simulate`` uses for a sensor's runs
of consecutive frames): small frames in blocks of 1000, against plain h5py
writing the same blocks (one resize and write per stream and block).

Two frame sizes: small (a capacitive-like frame, 64 float64 = 512 B,
frames share uncompressed chunks) and large (a 640 x 480 depth camera:
range and depth float32 + object id int32 = 3.7 MB, one LZF chunk per
stream and frame). Frames/s are the best of 3 runs; the ratio to the
anchor holds on a busy machine.

Run:  .venv/bin/python benchmarks/bench_recording.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
from _timing import print_load_at_end, print_machine

from twinsense.io.recording import FLUSH_INTERVAL, SMALL_FRAME_BYTES, RecordingWriter


def frames(kind: str, n: int, rng: np.random.Generator):
    if kind == "small":
        base = rng.normal(1e-12, 1e-14, 64)
        return [{"c": base + rng.normal(0, 1e-16, 64)} for _ in range(n)]
    yy, xx = np.mgrid[0:480, 0:640]
    depth = (2.0 + 0.001 * xx + 0.002 * yy).astype(np.float32)
    ids = (xx // 160 + 4 * (yy // 120)).astype(np.int32)
    out = []
    for _ in range(n):
        d = depth + rng.normal(0, 0.005, depth.shape).astype(np.float32)
        out.append({"range": d, "depth": d * np.float32(0.98), "object_id": ids})
    return out


def anchor(path: Path, data: list[dict]) -> None:
    with h5py.File(path, "w") as f:
        g = f.create_group("s")
        ts = g.create_dataset("timestamps", shape=(0,), maxshape=(None,), dtype="f8", chunks=(1024,))
        for k, streams in enumerate(data):
            for key, arr in streams.items():
                if key not in g:
                    big = arr.nbytes > SMALL_FRAME_BYTES
                    chunks = (1, *arr.shape) if big else (min(256, 65536 // arr.nbytes), *arr.shape)
                    g.create_dataset(key, shape=(0, *arr.shape), maxshape=(None, *arr.shape), dtype=arr.dtype,
                                     chunks=chunks, compression="lzf" if big else None)
                ds = g[key]
                ds.resize(k + 1, axis=0)
                ds[k] = arr
            ts.resize(k + 1, axis=0)
            ts[k] = k / 30


def anchor_blocks(path: Path, data: list[dict], times, block: int) -> None:
    """Plain h5py: the same datasets and chunk layout, one resize and write per stream and block."""
    with h5py.File(path, "w") as f:
        g = f.create_group("s")
        ts = g.create_dataset("timestamps", shape=(0,), maxshape=(None,), dtype="f8", chunks=(1024,))
        for lo in range(0, len(data), block):
            part = data[lo:lo + block]
            hi = lo + len(part)
            for key in part[0]:
                arr = np.stack([fr[key] for fr in part])
                if key not in g:
                    one = arr[0]
                    g.create_dataset(key, shape=(0, *one.shape), maxshape=(None, *one.shape), dtype=one.dtype,
                                     chunks=(min(256, 65536 // one.nbytes), *one.shape))
                ds = g[key]
                ds.resize(hi, axis=0)
                ds[lo:hi] = arr
            ts.resize(hi, axis=0)
            ts[lo:hi] = times[lo:hi]


def writer_blocks(path: Path, data: list[dict], times, block: int) -> None:
    with RecordingWriter(path) as w:
        w.add_sensor("s", "magnetic", 1e4)
        for lo in range(0, len(data), block):
            w.append_many("s", times[lo:lo + block], data[lo:lo + block])


def writer(path: Path, data: list[dict], flush_interval) -> None:
    with RecordingWriter(path, flush_interval=flush_interval) as w:
        w.add_sensor("s", "camera", 30.0)
        for k, streams in enumerate(data):
            w.append("s", k / 30, streams)


def best_rate(fn, n: int, folder: Path, repeats: int = 3) -> float:
    best = np.inf
    for r in range(repeats):
        p = folder / f"r{r}.h5"
        t0 = time.perf_counter()
        fn(p)
        best = min(best, time.perf_counter() - t0)
        p.unlink()
    return n / best


def main() -> None:
    print_machine()
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for kind, n in (("small", 5000), ("large", 40)):
            data = frames(kind, n, rng)
            size = sum(a.nbytes for a in data[0].values())
            print(f"{kind} frames: {size:,} B each, {n} frames")
            ref = best_rate(lambda p, data=data: anchor(p, data), n, folder)
            print(f"  {'anchor: plain h5py, no flush':<44s} {ref:10.0f} frames/s")
            for label, fi in (("RecordingWriter, flush only at close", None),
                              (f"RecordingWriter, flush every {FLUSH_INTERVAL} s", FLUSH_INTERVAL),
                              ("RecordingWriter, flush every 0.05 s", 0.05)):
                rate = best_rate(lambda p, fi=fi, data=data: writer(p, data, fi), n, folder)
                print(f"  {label:<44s} {rate:10.0f} frames/s  ({rate / ref:.2f} x anchor)")
        data = frames("small", 5000, rng)
        times = np.arange(5000) / 1e4
        print("small frames in blocks of 1000 (append_many, the default 0.5 s flush)")
        ref = best_rate(lambda p: anchor_blocks(p, data, times, 1000), 5000, folder)
        rate = best_rate(lambda p: writer_blocks(p, data, times, 1000), 5000, folder)
        print(f"  {'anchor: plain h5py, block writes, no flush':<44s} {ref:10.0f} frames/s")
        print(f"  {'RecordingWriter.append_many':<44s} {rate:10.0f} frames/s  ({rate / ref:.2f} x anchor)")
    print_load_at_end()


if __name__ == "__main__":
    main()
