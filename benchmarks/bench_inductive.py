"""Inductive switch throughput: M18 flush, a steel plate passing the face, updates per second on one core.

Measures ``InductiveSensor.capture`` (pose, 24 rays through the render
stage against the metal-only scene, ring model lookup, tank, noise,
hysteresis) with the response table loaded, over a plate moving across
the face, and the real-time factor against the preset's switching frequency
(1 kHz). Same-run anchors: one bare scipy CubicSpline evaluation of the
same table (the interpolation a naive model would run per update), and one
sparse factorisation + solve of the FEM on a table grid (what a run without
tables would pay per update, at least). Also ``simulate`` over 1 s of the
same scene (1000 updates at the preset's 1 kHz, frames in memory, and to
an HDF5 recording): the path a user's run takes, where the run loop hands
the sensor's consecutive frames to ``capture_frames`` in blocks; and
``capture_frames`` alone over the same 400 update times.

Run:  .venv/bin/python benchmarks/bench_inductive.py
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from _timing import best_and_median, print_anchor, print_load_at_end, print_machine
from scipy.interpolate import CubicSpline

from twinsense import simulate
from twinsense.inductive import InductiveSensor
from twinsense.inductive.fem import build_grid, solve_on_grid
from twinsense.inductive.head import target_disc
from twinsense.inductive.table import load_or_compute
from twinsense.scene import Box, Mount, Pose, Scene
from twinsense.scene.motion import ConstantVelocity


def main() -> None:
    print_machine()
    sensor = InductiveSensor.preset("m18_flush", mount=Mount(Pose()))
    sensor.prepare()
    cfg = sensor.config
    scene = Scene()
    # A plate 3 mm in front of the face sliding across it at 0.5 m/s.
    scene.add_object("plate", Box((0.018, 0.018, 0.001)), "mild_steel",
                     motion=ConstantVelocity(Pose((-0.02, 0.0, 0.0035)), (0.5, 0.0, 0.0)))
    rng = np.random.default_rng(1)
    n = 400
    times = np.arange(n) / cfg.frame_rate * 0.1  # 80 us apart: the plate crosses the face in 80 ms

    def run():
        for t in times:
            sensor.capture(scene, float(t), rng)

    best, med = best_and_median(run, repeats=5)
    per = med / n
    rt = 1 / per / cfg.switching_frequency
    print(f"m18_flush capture: {per * 1e6:7.1f} us median per update ({best / n * 1e6:.1f} us best) -> "
          f"{1 / per:,.0f} updates/s; real time at {cfg.switching_frequency:g} Hz: x{rt:.1f}")

    bestb, medb = best_and_median(lambda: sensor.capture_frames(scene, times, rng), repeats=5)
    print(f"m18_flush capture_frames, {n} updates: {medb / n * 1e6:7.1f} us median per update "
          f"({bestb / n * 1e6:.1f} us best) -> {n / medb:,.0f} updates/s; real time x"
          f"{n / medb / cfg.switching_frequency:.1f}")

    # simulate: the same plate crossing the face at 0.04 m/s, over the face (|x| < 18 mm) for 0.9 of the 1 s.
    slow = Scene()
    slow.add_object("plate", Box((0.018, 0.018, 0.001)), "mild_steel",
                    motion=ConstantVelocity(Pose((-0.02, 0.0, 0.0035)), (0.04, 0.0, 0.0)))
    n_sim = round(cfg.frame_rate)
    bests, meds = best_and_median(lambda: simulate(slow, [sensor], 1.0, None, keep_frames=False), repeats=3)
    print(f"simulate, 1 s ({n_sim} updates), in memory: {meds / n_sim * 1e6:7.1f} us median per update "
          f"({bests / n_sim * 1e6:.1f} us best) -> {n_sim / meds:,.0f} updates/s; real time x{1.0 / meds:.1f}")

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run.h5"
        bestr, medr = best_and_median(lambda: simulate(slow, [sensor], 1.0, out), repeats=3)
    print(f"simulate, 1 s ({n_sim} updates), to HDF5: {medr / n_sim * 1e6:7.1f} us median per update "
          f"({bestr / n_sim * 1e6:.1f} us best) -> {n_sim / medr:,.0f} updates/s; real time x{1.0 / medr:.1f}")

    spec = cfg.table_spec()
    table, _ = load_or_compute(spec)
    spline = CubicSpline(np.asarray(spec.distances), table.real, axis=1)
    _, a_med = best_and_median(lambda: spline(0.004), repeats=200)
    print_anchor("one scipy CubicSpline eval of the table", a_med, per)

    head = cfg.head
    d = spec.distances[4]
    ghosts = tuple(target_disc(d, a, spec.thickness, 7e6, 100.0) for a in spec.radii)
    r, z = build_grid(head.coil(), head.regions() + ghosts, cfg.frequency, cfg.mesh)
    _, f_med = best_and_median(lambda: solve_on_grid(head.coil(), (*head.regions(), ghosts[1]),
                                                          cfg.frequency, r, z), repeats=3)
    print(f"  grid {len(r)} x {len(z)} nodes")
    print_anchor("one FEM assembly + sparse LU solve (table grid)", f_med, per)
    print_load_at_end()


if __name__ == "__main__":
    main()
