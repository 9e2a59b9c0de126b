"""Ray-casting throughput: 1000 x 342 rays against a >= 50k-triangle scene.

Prints Mrays/s of ``twinsense.render.cast`` with every per-ray output
(distance, point, normal, incidence, object, material, triangle, velocity)
for a static scene and for the same scene with moving objects, next to a
bare embreex call (closest-hit ids only, single thread) measured in the same
process, so the ratio holds on a busy machine. Also: one thread against the
default workers, only the fields a radar needs, and a fixed sensor's repeated
cast of the same read-only rays (static hits kept, moving objects traced).

Run:  .venv/bin/python benchmarks/bench_render.py
"""

from __future__ import annotations

import numpy as np
from _timing import best_and_median, embree_anchor, print_load_at_end, print_machine

from twinsense.demos.office import build_office_scene, sensor_pose, triangle_count
from twinsense.render import PinholeCamera, Rays, cast, caster_for

best_of = best_and_median


LEAN = ("distance", "cos_incidence", "object_id", "material_id", "velocity")  # what a radar asks


def main() -> None:
    cam = PinholeCamera.from_fov(1000, 342, 90.0, 40.0)
    rays = cam.rays(sensor_pose())
    n = len(rays)
    print_machine()
    for label, person in (("static scene", False), ("with a walking person", True)):
        scene = build_office_scene(detail=6, person=person)
        print(f"\n{label}: {len(scene)} objects, {triangle_count(scene)} triangles, {n} rays")
        caster = caster_for(scene, "tof")
        best, med = best_of(lambda scene=scene: cast(scene, rays, 0.3))
        print(f"  twinsense cast, all outputs : {best * 1e3:6.1f} ms best, {med * 1e3:6.1f} ms median "
              f"-> {n / best / 1e6:5.1f} Mrays/s")
        # Same-run anchor: every object posed at t in one world-space BVH,
        # a bare single-thread embreex cast (closest-hit ids only).
        rb, rm = embree_anchor(scene, "tof", 0.3, rays.origins, rays.directions)
        print(f"  anchor: bare embreex, 1 thr : {rb * 1e3:6.1f} ms best, {rm * 1e3:6.1f} ms median "
              f"-> {n / rb / 1e6:5.1f} Mrays/s")
        print(f"  ratio twinsense / anchor    : {best / rb:5.2f} (best), {med / rm:5.2f} (median)")
        b1, _ = best_of(lambda scene=scene: cast(scene, rays, 0.3, workers=1))
        print(f"  the same on 1 thread        : {b1 * 1e3:6.1f} ms best "
              f"(workers / 1 thread: {best / b1:4.2f})")
        bl, _ = best_of(lambda scene=scene: cast(scene, rays, 0.3, fields=LEAN))
        print(f"  radar's fields only         : {bl * 1e3:6.1f} ms best")
        d = rays.directions.copy()
        d.setflags(write=False)
        origin = np.array(rays.origins[0])
        origin.setflags(write=False)
        fixed = Rays(origin, d)
        bw, _ = best_of(lambda scene=scene, fixed=fixed: cast(scene, fixed, 0.3, fields=LEAN))
        print(f"  fixed sensor, repeated cast : {bw * 1e3:6.1f} ms best (static hits kept)")
        static = caster.cast_static(fixed, ("distance",))
        bm, _ = best_of(lambda c=caster, fixed=fixed, static=static: c.cast_moving(fixed, 0.3,
                                                                                   static.distance))
        print(f"  cast_moving only            : {bm * 1e3:6.1f} ms best")
        h = cast(scene, rays, 0.3)
        print(f"  hit fraction {h.hit.mean():.3f}")
    print_load_at_end()


if __name__ == "__main__":
    main()
