"""ToF camera throughput: the full pmd_pico_flexx chain on a >= 50k-triangle office.

Measures depth frames per second of ``ToFCamera.capture`` (rendering
included) for the pmd_pico_flexx preset (224 x 171 px, 2 x 2 supersampling,
dual frequency, every effect but multipath: flying pixels, cross-talk, noise,
ADC, saturation, unwrapping, filters) with the walking person, in one
process, for the fixed office camera (static-scene phasors kept) and for a
camera that moves every frame (everything traced again). Then the
motion-artefact mode (one rendering per raw frame) and the multipath mode.
In the same process it times the stages: the shared caster's cold cast, its
cast with kept static hits, the ToF phasors and the signal chain.

Run:  .venv/bin/python benchmarks/bench_tof.py
"""

from __future__ import annotations

import itertools

import numpy as np
from _timing import best_and_median, embree_anchor, print_anchor, print_load_at_end, print_machine

from twinsense.demos.office import SENSOR_EYE, SENSOR_TARGET, build_office_scene, sensor_pose, triangle_count
from twinsense.linalg import rotate_rows
from twinsense.render import Rays, caster_for
from twinsense.scene.pose import Pose
from twinsense.scene.scene import Mount
from twinsense.tof import ToFCamera
from twinsense.tof.pipeline import finish_geometry, run_chain
from twinsense.tof.rendering import DIRECT_FIELDS
from twinsense.tof.signal import pixel_phasors

PERIOD_FRAMES = 270  # the person walks 1.5 m at 0.5 m/s and back: 6 s at 45 fps


timed = best_and_median


def report(label: str, best: float, median: float) -> None:
    print(f"  {label:<52s} {best * 1e3:7.1f} ms best {median * 1e3:7.1f} ms median "
          f"-> {1 / median:6.1f} fps (median)")


def main() -> None:
    print_machine()
    scene = build_office_scene(detail=6, person=True)
    print(f"scene: office, {len(scene)} objects, {triangle_count(scene)} triangles (walking person)")
    rng = np.random.default_rng(0)
    pose = sensor_pose()
    cam = ToFCamera.preset("pmd_pico_flexx", mount=pose)
    cfg = cam.config
    n_rays = cfg.width * cfg.height * cfg.supersample ** 2
    print(f"camera: pmd_pico_flexx {cfg.width} x {cfg.height}, {cfg.supersample} x {cfg.supersample} "
          f"supersampling = {n_rays} rays, {cfg.n_raw_frames} raw frames")
    # Every timing runs over the same frame times: 45 fps over the person's
    # 6 s walk there and back (the cost depends on how much of the image it covers).
    def times():
        return itertools.cycle(np.arange(PERIOD_FRAMES) / 45.0)

    # Same-run anchor: a bare single-thread Embree cast of the same supersampled
    # rays (closest-hit ids only) against the whole scene posed at one time.
    rays0 = cam._renderer.rays(pose.rotation, pose.position)
    _, anchor = embree_anchor(scene, "tof", 1.5, rays0.origins, rays0.directions, repeats=15)
    print(f"  anchor: bare embreex cast of the same {n_rays} rays, 1 thread: {anchor * 1e3:.1f} ms median")

    t = times()
    best, med = timed(lambda: cam.capture(scene, next(t), rng), PERIOD_FRAMES)
    report("full chain, fixed camera, 1 process", best, med)
    print_anchor("bare embreex cast, same rays", anchor, med)
    default_fps = 1 / med

    # A camera that turns a little every frame: no kept hits, every ray traced.
    step = iter(np.arange(100_000) * 1e-3)
    moving = ToFCamera.preset("pmd_pico_flexx", mount=pose)

    def moving_capture():
        moving.mount = Mount(Pose.look_at(SENSOR_EYE, np.add(SENSOR_TARGET, (0.0, next(step), 0.0))))
        moving.capture(scene, next(t), rng)

    t = times()
    best, med = timed(moving_capture, 90)
    report("full chain, camera moving (no kept hits), 1 process", best, med)
    print_anchor("bare embreex cast, same rays", anchor, med)

    caster = caster_for(scene, "tof")
    rays = cam._renderer.rays(pose.rotation, pose.position)
    writable = Rays(rays.origins.copy(), rays.directions.copy())  # writable: traced every time
    best, med = timed(lambda: caster.cast(writable, 0.3, DIRECT_FIELDS), 30)
    report("  stage: shared cast, all rays traced (cold)", best, med)
    t = times()
    best, med = timed(lambda: caster.cast(rays, next(t), DIRECT_FIELDS), PERIOD_FRAMES)
    report("  stage: shared cast, kept static hits", best, med)
    best, med = timed(lambda: caster.cast(writable, 0.3), 20)
    report("  stage: shared cast, cold, every field", best, med)
    r = cam._renderer
    t = times()
    best, med = timed(lambda: r.phasors(scene, pose.rotation, pose.position, next(t)), PERIOD_FRAMES)
    report("  stage: ToF phasors, kept static phasors + movers", best, med)
    samples = cam.render(scene, 1.5)
    best, med = timed(lambda: pixel_phasors(samples, cam.radiometry), 60)
    report("  stage: pixel phasors of a whole image", best, med)
    phasors = pixel_phasors(samples, cam.radiometry)

    def chain():
        out = run_chain(phasors, cfg, rng)
        finish_geometry(out, cam._pixel_dirs, cfg)

    best, med = timed(chain, 60)
    report("  stage: signal chain after the phasors", best, med)

    motion = ToFCamera(cfg.replaced(motion_artifacts=True), pose)
    t = itertools.cycle(np.arange(0, PERIOD_FRAMES, 9) / 45.0)
    best, med = timed(lambda: motion.capture(scene, next(t), rng), 30)
    report(f"motion artefacts ({cfg.n_raw_frames} renderings per frame)", best, med)
    print_anchor("bare embreex cast, same rays", anchor, med)

    mp = ToFCamera(cfg.replaced(multipath=True), pose)
    best, med = timed(lambda: mp.capture(scene, next(t), rng), 5)
    report(f"multipath ({cfg.multipath_vpl_grid[0]}x{cfg.multipath_vpl_grid[1]} VPLs, stride "
           f"{cfg.multipath_stride}, shadow rays)", best, med)
    mp_open = ToFCamera(cfg.replaced(multipath=True, multipath_visibility=False), pose)
    best, med = timed(lambda: mp_open.capture(scene, next(t), rng), 5)
    report("multipath without shadow rays", best, med)
    print_anchor("bare embreex cast, same rays", anchor, med)
    # rotate_rows against the broadcast form it replaced, 342 000 rows (2 x 2
    # supersampled 224 x 171 image, twice), float64.
    v = np.random.default_rng(1).normal(size=(342_000, 3))
    m = pose.rotation

    def broadcast_form():
        out = v[..., 0:1] * m[0]
        out += v[..., 1:2] * m[1]
        out += v[..., 2:3] * m[2]
        return out

    assert np.array_equal(broadcast_form(), rotate_rows(v, m))
    b_best, b_med = timed(broadcast_form, 30)
    report("rotate_rows reference: broadcast (n, 1) x (3,) form", b_best, b_med)
    r_best, r_med = timed(lambda: rotate_rows(v, m), 30)
    report("rotate_rows: columns into a preallocated array", r_best, r_med)
    print(f"  rotate_rows speed-up: {b_med / r_med:.1f}x (identical results)")
    print(f"\ntarget >= 60 fps for the full chain on 2 cores, 1 process: "
          f"{'met' if default_fps >= 60 else 'NOT met'} ({default_fps:.1f} fps median, fixed camera)")
    print_load_at_end()


if __name__ == "__main__":
    main()
