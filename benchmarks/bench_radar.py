"""FMCW radar throughput: paper_bgt60tr13c on the office scene.

Prints per-stage times of one frame (16 chirps x 2 Rx x 512 samples, a
1000 x 342 render of the radar's 120 x 60 deg view) and the speed of the
fast IF synthesis against the exact reference. The exact reference is
O(scatterers x cube), so it is timed on a random subset of the frame's
scatterers and scaled linearly to the full count (it is exactly linear: a
sum over scatterers); the accuracy of the fast synthesis is measured on the
same subset.

    python benchmarks/bench_radar.py [--frames N]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from twinsense.demos.office import build_office_scene, sensor_pose
from twinsense.radar import (
    FMCWRadar,
    ScatterRenderer,
    effects,
    received_amplitude,
    synthesize,
    synthesize_exact,
)
from twinsense.scene import Mount


def _median_time(repeat, fn, *args, **kwargs):
    """Median wall time [s] of ``fn(*args, **kwargs)`` over ``repeat`` runs, and its result."""
    times = []
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn(*args, **kwargs)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


def _report(t, scene, radar, renderer, frames, exact_subset):
    cfg = radar.config
    state = radar.mount.state_at(scene, t)
    t_render, scat = _median_time(5, renderer.render, scene, state, t)
    n_moving = int(np.any(scat.velocities != 0, axis=1).sum())

    def weights():
        amp = received_amplitude(scat, cfg)
        return effects.filtered_weights(amp, scat.points, scat.velocities, cfg)

    t_weights, w = _median_time(5, weights)
    t_synth, cube = _median_time(5, synthesize, scat.points, scat.velocities, w, cfg,
                                 eps=radar.eps)
    t_synth2, _ = _median_time(5, synthesize, scat.points, scat.velocities, w, cfg,
                               eps=radar.eps, workers=2)
    t_proc, _ = _median_time(5, radar.process_cube, cube)
    t_full, _ = _median_time(frames, radar.capture, scene, t, np.random.default_rng(1))
    print(f"\nt = {t:.1f} s: {len(scat)} scatterers ({n_moving} moving)")
    print(f"  render + scatterers   {1e3 * t_render:7.1f} ms")
    print(f"  amplitudes + filters  {1e3 * t_weights:7.1f} ms")
    print(f"  IF synthesis (fast)   {1e3 * t_synth:7.1f} ms  (2 threads: {1e3 * t_synth2:.1f} ms)")
    print(f"  processing            {1e3 * t_proc:7.1f} ms  (range/Doppler FFT, CFAR, AoA)")
    print(f"  full capture          {1e3 * t_full:7.1f} ms  -> {1 / t_full:5.1f} frames/s")

    rng = np.random.default_rng(2)
    sub = rng.choice(len(scat), size=min(exact_subset, len(scat)), replace=False)
    p, v, ws = scat.points[sub], scat.velocities[sub], w[sub]
    t_exact_sub, ref = _median_time(1, synthesize_exact, p, v, ws, cfg)
    fast_sub = synthesize(p, v, ws, cfg, eps=radar.eps)
    err = np.linalg.norm(fast_sub - ref) / np.linalg.norm(ref)
    t_exact = t_exact_sub * len(scat) / len(sub)
    print(f"  exact reference       {t_exact:7.1f} s  (timed on {len(sub)} scatterers "
          f"in {t_exact_sub:.2f} s, scaled linearly)")
    print(f"  synthesis speed-up    {t_exact / t_synth:7.0f} x   fast vs exact rel. error "
          f"{err:.1e} (subset)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=15)
    ap.add_argument("--exact-subset", type=int, default=1500)
    args = ap.parse_args()

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}")
    scene = build_office_scene()
    radar = FMCWRadar.preset("paper_bgt60tr13c", mount=Mount(sensor_pose()))
    cfg = radar.config
    print(f"config: {cfg.cube_shape} cube (rx, chirp, sample), render "
          f"{cfg.render_width} x {cfg.render_height}")
    # Warm up (caster build, camera rays, FFT plans).
    radar.capture(scene, 0.0, np.random.default_rng(0))
    renderer = ScatterRenderer(cfg)
    # A frame with the person standing at a turning point (all static) and one walking.
    for t in (0.0, 1.0):
        _report(t, scene, radar, renderer, args.frames, args.exact_subset)


if __name__ == "__main__":
    main()
