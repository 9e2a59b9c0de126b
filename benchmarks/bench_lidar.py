"""LiDAR speed: Velodyne VLP-16 revolutions in the robot cell with the walking person.

One revolution = 28,800 firings x 3 x 3 sub-rays = 259,200 rays, the moving
person posed per 1 ms slice, waveform echoes, noise and points. Real time at
10 Hz needs one revolution in < 100 ms. Prints revolutions per second for a
fixed sensor (static hits kept by the caster from the second revolution on),
for the same sensor moving (every revolution cast afresh), the Livox-like
rosette (new rays every frame) and, as the same-run anchor, a bare
single-thread Embree cast of the same 259,200 rays.

Run:  .venv/bin/python benchmarks/bench_lidar.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from _timing import best_and_median, embree_anchor, print_anchor, print_load_at_end, print_machine

from twinsense.lidar import Lidar
from twinsense.lidar.scan import firings
from twinsense.scenario import load_scenario
from twinsense.scene import Mount, Pose
from twinsense.scene.motion import ConstantVelocity

CELL = Path(__file__).resolve().parents[1] / "examples" / "cylinder_cell.yaml"
EYE, TARGET = (-0.8, 0.0, 1.6), (2.0, 0.0, 1.0)


def main() -> None:
    print_machine()
    scene = load_scenario(CELL).scene
    fixed = Lidar.preset("velodyne_vlp16", mount=Mount(Pose.look_at(EYE, TARGET)))
    counter = iter(range(10**6))

    def rev(sensor):
        k = next(counter)
        return sensor.capture(scene, 0.1 * (k % 20), np.random.default_rng(k))

    n_rays = fixed.config.n_firings * fixed.config.subrays ** 2
    print(f"\nrobot cell: {len(scene)} objects; VLP-16, {fixed.config.n_firings} firings x "
          f"{fixed.config.subrays ** 2} sub-rays = {n_rays} rays per revolution")
    best, med = best_and_median(lambda: rev(fixed), repeats=9)
    print(f"  fixed VLP-16            : {best * 1e3:6.1f} ms best, {med * 1e3:6.1f} ms median per revolution "
          f"-> {1 / med:5.1f} rev/s (real time: >= 10)")
    fir = firings(fixed.config, 0.0)
    o, d, _ = fixed._world_rays(scene, fir)
    _, a_med = embree_anchor(scene, "lidar", 0.0, np.asarray(o[0]), np.asarray(d), repeats=5)
    print_anchor("bare single-thread Embree, same 259,200 rays", a_med, med)

    scene.add_object("cart", _tiny_box(), "metal", motion=ConstantVelocity(Pose((-0.8, 0.0, 1.6)), (0.5, 0, 0)),
                     layers=["tof"])
    moving = Lidar.preset("velodyne_vlp16", mount=Mount(Pose.look_at((0, 0, 0), (2.8, 0, -0.6)), parent="cart"))
    m_best, m_med = best_and_median(lambda: rev(moving), repeats=5)
    print(f"  VLP-16 on a moving cart : {m_best * 1e3:6.1f} ms best, {m_med * 1e3:6.1f} ms median "
          f"-> {1 / m_med:5.1f} rev/s")
    print_anchor("bare single-thread Embree, same 259,200 rays", a_med, m_med)
    mid = Lidar.preset("livox_mid40", mount=Mount(Pose.look_at(EYE, TARGET)))
    l_best, l_med = best_and_median(lambda: rev(mid), repeats=5)
    print(f"  Livox-like rosette      : {l_best * 1e3:6.1f} ms best, {l_med * 1e3:6.1f} ms median per 0.1 s frame "
          f"(10,000 points x 9 sub-rays)")
    print_load_at_end()


def _tiny_box():
    from twinsense import Box

    return Box((0.05, 0.05, 0.05))


if __name__ == "__main__":
    main()
