"""Magnetic sensing throughput: 8 Hall sensors (one TLE493D array object) and 4 moving magnets.

Measures updates per second (every sensor read once, 8 x 3 field components,
noise and 12-bit quantisation) two ways:

- ``capture`` one update at a time (what ``simulate`` calls per frame);
- ``capture_many`` over a block of 1000 update times (poses of the 4 moving
  magnets from their motions' closed forms, the fields of all
  times x magnets x sensors in one vectorised kernel call);
- ``simulate`` over 0.5 s at 10 kHz (5000 updates), the path a user's run
  takes: frames in memory, and frames to an HDF5 recording. The run loop
  hands each run of consecutive frames of the sensor to ``capture_frames``
  in blocks (byte-identical to one capture after another) and writes each
  block with ``RecordingWriter.append_many`` (one HDF5 write per stream).
  Anchor of the recording's cost: bench_recording.py's plain h5py block
  writes of the same 5000 frames (same chunk layout, no flush), against
  the to-HDF5 run minus the in-memory run.

The magnets: two axial cylinders (oscillating), one diametric disc
(turning) and one block (constant velocity), all moving. Same-run anchor:
the bare Derby-Olbert kernel (``cylinder_axial``, the cel iteration) on the
same number of points (8 sensors x 4 magnets per update), and the ratio.

Run:  .venv/bin/python benchmarks/bench_magnetic.py
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from _timing import best_and_median, print_load_at_end, print_machine
from bench_recording import anchor_blocks

from twinsense import simulate
from twinsense.magnetic import MagneticSensor
from twinsense.magnetic.fields import cylinder_axial
from twinsense.scene import Box, ConstantVelocity, Magnet, Mount, Oscillation, Pose, Scene

BLOCK = 1000  # update times per capture_many call


def build() -> tuple[Scene, MagneticSensor]:
    s = Scene(name="bench_magnetic")
    body = Box((0.01, 0.01, 0.01))
    s.add_object("tool_a", body, motion=Oscillation(Pose((0.01, 0.0, 0.01)), (0.02, 0, 0), 2.0),
                 magnet=Magnet("cylinder", (0.006, 0.003), 1.2, (0, 0, 1)))
    s.add_object("tool_b", body, motion=Oscillation(Pose((0.05, 0.005, 0.012)), (0, 0.01, 0.003), 1.3),
                 magnet=Magnet("cylinder", (0.008, 0.004), 1.3, (0, 0, -1)))
    s.add_object("disc", body, motion=ConstantVelocity(Pose((0.03, 0, 0.008)), angular_velocity=(0, 0, 6.0)),
                 magnet=Magnet("cylinder", (0.006, 0.0025), 1.2, (1, 0, 0)))
    s.add_object("slider", body, motion=ConstantVelocity(Pose((0.0, -0.01, 0.01)), velocity=(0.05, 0, 0)),
                 magnet=Magnet("block", (0.005, 0.005, 0.002), 1.2, (0, 0, 1)))
    return s, MagneticSensor.preset("hall_array8", mount=Mount(Pose()), frame_rate=10_000.0)


def main() -> None:
    print_machine()
    scene, sensor = build()
    n, m = sensor.config.n_elements, 4
    print(f"scene: {m} moving magnets (2 axial cylinders, 1 diametric disc, 1 block); sensor: hall_array8, "
          f"{n} x 3-axis TLE493D, 12 bit, noise; target 10 kHz updates")
    rng = np.random.default_rng(0)
    times = iter(np.arange(10 ** 6) / 1e4)
    best1, med1 = best_and_median(lambda: sensor.capture(scene, next(times), rng), repeats=200)
    print(f"  capture, one update                   {best1 * 1e6:8.1f} us best {med1 * 1e6:8.1f} us median"
          f"  -> {1 / med1:8.0f} updates/s")
    block = np.arange(BLOCK) / 1e4
    bestb, medb = best_and_median(lambda: sensor.capture_many(scene, block, rng), repeats=7)
    print(f"  capture_many, {BLOCK} updates           {bestb * 1e3:8.2f} ms best {medb * 1e3:8.2f} ms median"
          f"  -> {BLOCK / medb:8.0f} updates/s")
    duration = 0.5
    n_sim = round(duration * sensor.frame_rate)
    bests, meds = best_and_median(lambda: simulate(scene, [sensor], duration, None, keep_frames=False), repeats=3)
    print(f"  simulate, {n_sim} updates, in memory     {bests * 1e3:8.1f} ms best {meds * 1e3:8.1f} ms median"
          f"  -> {n_sim / meds:8.0f} updates/s")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run.h5"
        bestr, medr = best_and_median(lambda: simulate(scene, [sensor], duration, out), repeats=3)
    print(f"  simulate, {n_sim} updates, to HDF5       {bestr * 1e3:8.1f} ms best {medr * 1e3:8.1f} ms median"
          f"  -> {n_sim / medr:8.0f} updates/s")
    kept = simulate(scene, [sensor], duration, None).frames[sensor.name]
    data = [f.streams() for f in kept]
    stamps = np.array([f.t for f in kept])
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "anchor.h5"
        ah5 = best_and_median(lambda: anchor_blocks(out, data, stamps, 1024), repeats=3)[1]
    print(f"  anchor: plain h5py block writes of the same {len(data)} frames {ah5 * 1e3:8.1f} ms median;"
          f" (to HDF5 - in memory) / anchor = {(medr - meds) / ah5:5.2f}")
    # Anchor: the bare cel kernel on the same number of points (n sensors x m magnets per update).
    pts1 = np.random.default_rng(1).uniform(-0.02, 0.02, (n * m, 3))
    a1 = best_and_median(lambda: cylinder_axial(pts1, 0.003, 0.003, 1.2), repeats=200)[1]
    ptsb = np.random.default_rng(1).uniform(-0.02, 0.02, (BLOCK * n * m, 3))
    ab = best_and_median(lambda: cylinder_axial(ptsb, 0.003, 0.003, 1.2), repeats=7)[1]
    print(f"  anchor: bare Derby-Olbert kernel, {n * m} points          {a1 * 1e6:8.1f} us median;"
          f" capture / anchor = {med1 / a1:5.1f}")
    print(f"  anchor: bare Derby-Olbert kernel, {BLOCK * n * m} points   {ab * 1e3:8.2f} ms median;"
          f" capture_many / anchor = {medb / ab:5.1f}")
    print_load_at_end()


if __name__ == "__main__":
    main()
