"""External renders and real-sensor replay: throughput beside the ray-cast path.

Office scene (the demo's, with the walking person), one wide external render
(640 x 480 px, 110 x 90 deg, range + intensity + normals + velocity +
material ids, made by twinsense's own caster as a stand-in for a game
engine) from the sensor position. Timed:

- ``images_to_hits`` of the pico flexx's 448 x 342 sub-pixel rays from the
  render centre (one sample per ray) and from 5 cm beside it (marching and
  bisection through the render, then the fixed-point polish);
- a full ToF frame from the images against ``ToFCamera.capture`` (ray cast);
- a full radar frame (BGT60TR13C paper preset) from the images against
  ``FMCWRadar.capture``;
- ``ReplayRadar.capture`` of the real BGT60TR13C recording (frame look-up and
  the processing chain) against a simulated frame of the same config.

Same-run anchor: a bare single-thread Embree cast of the same 153k ToF rays.

Run:  .venv/bin/python benchmarks/bench_external.py
"""

from __future__ import annotations

import numpy as np
from _timing import best_and_median, embree_anchor, print_anchor, print_load_at_end, print_machine

from twinsense.demos.office import build_office_scene, sensor_pose
from twinsense.radar import FMCWRadar, make_radar
from twinsense.radar.external import capture_from_images as radar_from_images
from twinsense.radar.replay import ReplayRadar
from twinsense.render import PinholeCamera
from twinsense.render.external import images_from_scene, images_to_hits
from twinsense.scene import Mount, Pose
from twinsense.tof import ToFCamera
from twinsense.tof.external import capture_from_images as tof_from_images


def main() -> None:
    print_machine()
    scene = build_office_scene()
    pose = sensor_pose()
    t = 0.5
    wide = PinholeCamera.from_fov(640, 480, 110.0, 90.0)
    _best, med = best_and_median(lambda: images_from_scene(scene, wide, pose, t, "tof"), repeats=3)
    print(f"office scene; wide render {wide.width} x {wide.height} made by ray casting: {med * 1e3:7.1f} ms median")
    images = images_from_scene(scene, wide, pose, t, "tof")
    cam = ToFCamera.preset("pmd_pico_flexx", mount=Mount(pose))
    side = Pose(pose.position + 0.05 * pose.rotation[:, 0], pose.rotation)
    cam_side = ToFCamera.preset("pmd_pico_flexx", mount=Mount(side))
    rays = cam._renderer.rays(pose.rotation, pose.position)
    rays_side = cam_side._renderer.rays(side.rotation, side.position)
    n = len(rays)
    rng = np.random.default_rng(0)
    rows = [
        ("images_to_hits, from the render centre", lambda: images_to_hits(images, rays)),
        ("images_to_hits, 5 cm beside it", lambda: images_to_hits(images, rays_side)),
        ("ToF frame from the images (centre)",
         lambda: tof_from_images(cam, images, t, rng, materials=scene.materials)),
        ("ToF frame, ray cast (capture)", lambda: cam.capture(scene, t, rng)),
    ]
    print(f"pico flexx: {n} sub-pixel rays")
    timed = {}
    for label, fn in rows:
        b, m = best_and_median(fn, repeats=5)
        timed[label] = m
        print(f"  {label:<42s} {b * 1e3:8.1f} ms best {m * 1e3:8.1f} ms median")
    _a_best, a_med = embree_anchor(scene, "tof", t, rays.origins, rays.directions, repeats=5)
    print_anchor("bare Embree cast of the same rays, 1 thread", a_med, timed["images_to_hits, 5 cm beside it"])
    radar_images = images_from_scene(scene, PinholeCamera.from_fov(480, 320, 130.0, 80.0), pose, t, "radar")
    radar = make_radar("paper_bgt60tr13c", mount=Mount(pose))
    rb, rm = best_and_median(lambda: radar_from_images(radar, radar_images, t, rng, materials=scene.materials),
                             repeats=5)
    cb, cm = best_and_median(lambda: radar.capture(scene, t, rng), repeats=5)
    print(f"radar paper_bgt60tr13c, render {radar.config.render_width} x {radar.config.render_height}:")
    print(f"  {'radar frame from the images':<42s} {rb * 1e3:8.1f} ms best {rm * 1e3:8.1f} ms median")
    print(f"  {'radar frame, ray cast (capture)':<42s} {cb * 1e3:8.1f} ms best {cm * 1e3:8.1f} ms median")
    replay = ReplayRadar("bgt60tr13c_napas")
    sim = FMCWRadar(replay.config)
    k = iter(range(10 ** 6))
    pb, pm = best_and_median(lambda: replay.capture(None, (next(k) % 256) / replay.frame_rate), repeats=50)
    sb, sm = best_and_median(lambda: sim.capture(scene, 0.0, rng), repeats=10)
    print("replay of the real BGT60TR13C recording (3 rx x 8 chirps x 64 samples):")
    print(f"  {'ReplayRadar.capture (look-up + processing)':<42s} {pb * 1e3:8.2f} ms best {pm * 1e3:8.2f} ms median"
          f"  -> {1 / pm:7.0f} frames/s")
    print(f"  {'simulated frame, same config, office':<42s} {sb * 1e3:8.2f} ms best {sm * 1e3:8.2f} ms median")
    print_load_at_end()


if __name__ == "__main__":
    main()
