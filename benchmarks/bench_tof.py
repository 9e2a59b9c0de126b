"""ToF camera throughput: the full pmd_pico_flexx chain on a >= 50k-triangle office.

Measures depth frames per second of ``ToFCamera.capture`` (rendering
included) for the pmd_pico_flexx preset (224 x 171 px, 2 x 2 supersampling,
dual frequency, every effect but multipath: flying pixels, cross-talk, noise,
ADC, saturation, unwrapping, filters), then the motion-artefact mode (one
rendering per raw frame) and the multipath mode. In the same process it times
the bare Embree call for the same rays and the shared ``twinsense.render.cast``
so the ratios hold on a busy machine.

Run:  .venv/bin/python benchmarks/bench_tof.py
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

from twinsense.demos.office import build_office_scene, sensor_pose, triangle_count
from twinsense.render import cast
from twinsense.tof import ToFCamera
from twinsense.tof.raycast import caster_for


def timed(fn, repeats: int) -> tuple[float, float]:
    """(best, median) seconds of ``fn()`` over ``repeats`` calls after one warm-up."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times), float(np.median(times))


def report(label: str, best: float, median: float) -> None:
    print(f"  {label:<44s} {best * 1e3:7.1f} ms best {median * 1e3:7.1f} ms median "
          f"-> {1 / median:6.1f} fps (median)")


def main() -> None:
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}, numpy {np.__version__}")
    scene = build_office_scene(detail=6, person=True)
    print(f"scene: office, {len(scene)} objects, {triangle_count(scene)} triangles (walking person)")
    rng = np.random.default_rng(0)
    cam = ToFCamera.preset("pmd_pico_flexx", mount=sensor_pose())
    cfg = cam.config
    n_rays = cfg.width * cfg.height * cfg.supersample ** 2
    print(f"camera: pmd_pico_flexx {cfg.width} x {cfg.height}, {cfg.supersample} x {cfg.supersample} "
          f"supersampling = {n_rays} rays, {cfg.n_raw_frames} raw frames")
    t = iter(np.arange(100_000) / 45.0)

    best, med = timed(lambda: cam.capture(scene, next(t), rng), 60)
    report("full chain, 1 process", best, med)
    par = ToFCamera.preset("pmd_pico_flexx", mount=sensor_pose(), render_workers=1)
    best, med = timed(lambda: par.capture(scene, next(t), rng), 60)
    report("full chain, render_workers=1 (2 processes)", best, med)
    default_fps = 1 / med

    caster = caster_for(scene)
    pose = sensor_pose()
    dirs = cam._renderer.world_directions(pose.rotation, (0, cfg.height))
    o32 = np.zeros((n_rays, 3), np.float32) + pose.position.astype(np.float32)
    bare = caster._static_scene[0]
    b_best, b_med = timed(lambda: bare.run(o32, dirs, output=1), 30)
    report("  of which: bare Embree, static objects", b_best, b_med)
    f_best, f_med = timed(lambda: caster.cast(pose.position, dirs, 0.3), 30)
    report("  of which: ToF caster (static + person)", f_best, f_med)
    samples = cam.render(scene, 0.3)
    from twinsense.tof.pipeline import finish_geometry, run_chain
    from twinsense.tof.signal import pixel_phasors

    def chain():
        out = run_chain(pixel_phasors(samples, cam.radiometry), cfg, rng)
        finish_geometry(out, cam._pixel_dirs, cfg)

    c_best, c_med = timed(chain, 60)
    report("  of which: signal chain after rendering", c_best, c_med)

    rays = cam.pinhole.rays(pose, cfg.supersample)
    s_best, s_med = timed(lambda: cast(scene, rays, 0.3), 10)
    report("reference: twinsense.render.cast, same rays", s_best, s_med)
    print(f"  ToF caster / shared cast speed-up: {s_med / f_med:.1f}x")

    motion = ToFCamera(cfg.replaced(motion_artifacts=True), sensor_pose())
    best, med = timed(lambda: motion.capture(scene, next(t), rng), 10)
    report(f"motion artefacts ({cfg.n_raw_frames} renderings per frame)", best, med)

    mp = ToFCamera(cfg.replaced(multipath=True), sensor_pose())
    best, med = timed(lambda: mp.capture(scene, next(t), rng), 5)
    report(f"multipath ({cfg.multipath_vpl_grid[0]}x{cfg.multipath_vpl_grid[1]} VPLs, stride "
           f"{cfg.multipath_stride}, shadow rays)", best, med)
    mp_open = ToFCamera(cfg.replaced(multipath=True, multipath_visibility=False), sensor_pose())
    best, med = timed(lambda: mp_open.capture(scene, next(t), rng), 5)
    report("multipath without shadow rays", best, med)
    print(f"\ntarget >= 60 fps for the full chain on 2 cores: {'met' if default_fps >= 60 else 'NOT met'} "
          f"({default_fps:.1f} fps median with render_workers=1)")


if __name__ == "__main__":
    main()
