"""Rerun, point-cloud and labelled-array output: throughput against plain library calls.

Same-run anchors (the same data through the bare library, no twinsense code):

- recording -> .rrd (``write_rrd``) of a 640 x 480 depth camera and a
  28,800-firing LiDAR, 20 frames each, against a bare ``rerun.RecordingStream``
  logging the same depth images and point arrays (already in memory) to a file;
- the live sink: the cost of ``send`` on the simulation thread, and frames
  logged per second until ``close`` returns, against the same bare logging;
- PCD / PLY of 100,000 points with 8 fields, against ``ndarray.tofile`` of the
  same packed records;
- ``open_xarray`` of the recording, against h5py reading every dataset.

Run:  .venv/bin/python benchmarks/bench_rerun.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
from _timing import best_and_median, print_anchor, print_load_at_end, print_machine

from twinsense.io.pointcloud import write_pcd, write_ply
from twinsense.io.recording import RecordingWriter, open_xarray
from twinsense.stream.rerun import RerunSink, write_rrd

N_FRAMES = 20
W, H, N_FIRINGS = 640, 480, 28_800
CAMERA = {"config": {"camera": {"width": W, "height": H, "fx": 500.0, "fy": 500.0, "cx": 319.5, "cy": 239.5,
                                "distortion": [0.0] * 5}},
          "mount": {"pose": {"position": [0.0, 0.0, 1.0], "quat_xyzw": [0.0, 0.0, 0.0, 1.0]}, "parent": None}}


def frames(rng: np.random.Generator) -> tuple[list[dict], list[dict]]:
    yy, xx = np.mgrid[0:H, 0:W]
    depth = (2.0 + 0.001 * xx + 0.002 * yy).astype(np.float32)
    cams, lidars = [], []
    az = np.linspace(-np.pi, np.pi, N_FIRINGS, endpoint=False)
    for _ in range(N_FRAMES):
        d = depth + rng.normal(0, 0.005, depth.shape).astype(np.float32)
        cams.append({"depth": d, "range": d, "object_id": np.zeros((H, W), np.int32)})
        r = rng.uniform(1, 30, (N_FIRINGS, 1)).astype(np.float32)
        xyz = np.stack([r * np.cos(az)[:, None], r * np.sin(az)[:, None], np.zeros_like(r)], -1)
        lidars.append({"range": r, "xyz_world": xyz.astype(np.float32), "xyz": xyz.astype(np.float32),
                       "intensity": rng.integers(0, 255, (N_FIRINGS, 1)).astype(np.uint8)})
    return cams, lidars


class _Sensor:
    def __init__(self, name: str, kind: str, cfg: dict):
        self.name, self.kind, self._cfg = name, kind, cfg
        self.frame_rate = 10.0

    def config_dict(self) -> dict:
        return self._cfg


class _Frame:
    def __init__(self, t: float, streams: dict):
        self.t, self._s = t, streams

    def streams(self) -> dict:
        return self._s


def bare_rerun(path: Path, cams, lidars) -> None:
    import rerun as rr

    rec = rr.RecordingStream("anchor")
    rec.set_sinks(rr.FileSink(str(path)))
    for k, (c, li) in enumerate(zip(cams, lidars)):
        rec.set_time("sim_time", duration=k * 0.1)
        rec.log("cam/depth", rr.DepthImage(c["depth"], meter=1.0))
        ok = np.isfinite(li["range"])
        rec.log("lidar", rr.Points3D(li["xyz_world"][ok]))
    rec.flush()
    rec.disconnect()


def main() -> None:
    print_machine()
    rng = np.random.default_rng(0)
    cams, lidars = frames(rng)
    mb = sum(a.nbytes for f in cams + lidars for a in f.values()) / 1e6
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        h5 = tmp / "rec.h5"
        with RecordingWriter(h5) as w:
            w.add_sensor("depth", "camera", 10.0, CAMERA)
            w.add_sensor("lidar", "lidar", 10.0, {"mount": CAMERA["mount"]})
            for k, (c, li) in enumerate(zip(cams, lidars)):
                w.append("depth", k * 0.1, c)
                w.append("lidar", k * 0.1, li)
        n = 2 * N_FRAMES
        print(f"\nrecording -> .rrd: {N_FRAMES} depth {W}x{H} + {N_FRAMES} LiDAR {N_FIRINGS} frames ({mb:.0f} MB)")
        best, med = best_and_median(lambda: write_rrd(h5, tmp / "out.rrd"), repeats=3)
        print(f"  write_rrd: {med:.3f} s median ({n / med:.0f} frames/s, {mb / med:.0f} MB/s), best {best:.3f} s")
        _, a_med = best_and_median(lambda: bare_rerun(tmp / "anchor.rrd", cams, lidars), repeats=3)
        print_anchor("bare rerun logging of the same arrays", a_med, med)

        sensors = [_Sensor("depth", "camera", CAMERA), _Sensor("lidar", "lidar", {"mount": CAMERA["mount"]})]

        def live():
            sink = RerunSink(tmp / "live.rrd", queue_size=1000)
            sink.open(None, sensors)
            t0 = time.perf_counter()
            for k, (c, li) in enumerate(zip(cams, lidars)):
                sink.send(sensors[0], k * 0.1, _Frame(k * 0.1, c))
                sink.send(sensors[1], k * 0.1, _Frame(k * 0.1, li))
            t_send = time.perf_counter() - t0
            sink.close()
            assert sum(sink.dropped.values()) == 0
            live.send_us = t_send / n * 1e6
            return time.perf_counter() - t0

        live()
        totals, sends = [], []
        for _ in range(3):
            totals.append(live())
            sends.append(live.send_us)
        med = float(np.median(totals))
        print(f"\nlive RerunSink, file output: send() {np.median(sends):.1f} us per frame on the simulation thread; "
              f"{n / med:.0f} frames/s logged ({med:.3f} s until close returned)")
        print_anchor("bare rerun logging of the same arrays", a_med, med)

        m = 100_000
        cloud = {"x": rng.normal(size=m).astype(np.float32), "y": rng.normal(size=m).astype(np.float32),
                 "z": rng.normal(size=m).astype(np.float32), "intensity": rng.integers(0, 255, m).astype(np.uint8),
                 "range": rng.uniform(0, 30, m).astype(np.float32), "ring": rng.integers(0, 16, m).astype(np.uint16),
                 "echo": np.zeros(m, np.uint8), "time": rng.uniform(0, 0.1, m)}
        rec = np.empty(m, dtype=[(k, v.dtype) for k, v in cloud.items()])
        for k, v in cloud.items():
            rec[k] = v
        print(f"\npoint clouds: {m:,} points, 8 fields ({rec.nbytes / 1e6:.1f} MB)")
        _, a_med = best_and_median(lambda: rec.tofile(tmp / "anchor.bin"))
        for label, fn in (("PCD binary", lambda: write_pcd(tmp / "c.pcd", cloud)),
                          ("PLY binary", lambda: write_ply(tmp / "c.ply", cloud)),
                          ("PCD ascii", lambda: write_pcd(tmp / "a.pcd", cloud, binary=False))):
            _, med = best_and_median(fn, repeats=3)
            print(f"  {label}: {med * 1e3:.1f} ms median ({m / med / 1e6:.2f} M points/s)")
            print_anchor("ndarray.tofile of the packed records", a_med, med)

        import h5py

        def h5_all():
            with h5py.File(h5, "r") as f:
                return [ds[()] for g in f.values() for ds in g.values()]

        _, med = best_and_median(lambda: open_xarray(h5), repeats=3)
        _, a_med = best_and_median(h5_all, repeats=3)
        print(f"\nopen_xarray: {med:.3f} s median ({mb / med:.0f} MB/s)")
        print_anchor("h5py reading every dataset", a_med, med)
    print_load_at_end()


if __name__ == "__main__":
    main()
