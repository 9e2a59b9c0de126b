"""Ultrasonic ring throughput: ring8_40khz (8 x 15 Hz = 120 firings/s) in the robot cell, person walking.

Measures firing cycles per second of ``UltrasonicSensor.capture`` (echo
geometry of every firing in the cycle plus the earlier firings whose late
echoes reach it, visibility rays through the render stage, A-scan synthesis,
noise, envelope, detection) over the person's walk, and the real-time factor
(the ring needs 15 cycles/s). Same-run anchor: a bare single-thread Embree
cast of the same number of rays (two visibility rays per candidate echo of
one cycle) against the same scene.

``--mesh-robot``: one ``open_40khz`` sensor on the UR5e's forearm in the robot cell with the
arm's visual meshes (122k facets, ~8,000 candidate echoes a cycle), where the
A-scan's echo count, not the rays, sets the cost; the same anchor.

Run:  .venv/bin/python benchmarks/bench_ultrasonic.py [--mesh-robot]
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np
from _timing import best_and_median, embree_anchor, print_anchor, print_load_at_end, print_machine

from twinsense.demos.ultrasonic import build_cell


def mesh_robot() -> None:
    from twinsense.demos.robot_cell import ROBOT, build_arm_cell_scene
    from twinsense.presets import make_sensor
    from twinsense.scene import Mount, Pose

    scene = build_arm_cell_scene(shapes="visual")
    sensor = make_sensor("ultrasonic", "open_40khz", name="forearm_sonar",
                         mount=Mount(Pose((0.3, 0.1, 0.4)), parent=f"{ROBOT}/forearm_link"))
    times = itertools.cycle(np.arange(10) * 0.4 + 0.5)
    rng = np.random.default_rng(0)
    sensor.capture(scene, 0.1, rng)  # the caster and the static elements once
    best, med = best_and_median(lambda: sensor.capture(scene, next(times), rng), repeats=10)
    n_echo = sum(len(d) for d, _ in sensor.echoes(scene, 2.1))
    print(f"  open_40khz on the UR5e forearm, visual meshes ({n_echo} echoes heard at 2.1 s): capture "
          f"{best * 1e3:7.1f} ms best {med * 1e3:7.1f} ms median")
    n_rays = max(2 * n_echo, 64)
    pose = sensor.transducer_poses(scene, 2.1)[0]
    d = np.random.default_rng(1).normal(size=(n_rays, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    _, anchor = embree_anchor(scene, "ultrasonic", 2.1, pose.position, d, repeats=10)
    print_anchor(f"bare Embree cast of {n_rays} rays", anchor, med)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh-robot", action="store_true", help="only the sensor on the visual-mesh arm")
    args = ap.parse_args()
    print_machine()
    if args.mesh_robot:
        mesh_robot()
        print_load_at_end()
        return
    scene, ring = build_cell()
    cfg = ring.config
    print(f"scene: robot cell + ring pillar, {len(scene)} objects; sensor: ring8_40khz, "
          f"{cfg.n_transducers} transducers x {cfg.frame_rate:g} Hz = {cfg.n_transducers * cfg.frame_rate:g} "
          f"firings/s, {cfg.n_samples} samples per A-scan at {cfg.sample_rate / 1e3:g} kHz")
    times = itertools.cycle(np.arange(75) / cfg.frame_rate)  # the person's 5 s walk
    rng = np.random.default_rng(0)
    best, med = best_and_median(lambda: ring.capture(scene, next(times), rng), repeats=30)
    cycles = 1.0 / med
    print(f"  capture (one firing cycle)                  {best * 1e3:7.1f} ms best {med * 1e3:7.1f} ms median")
    print(f"  -> {cycles:6.1f} cycles/s = {cycles * cfg.n_transducers:7.1f} firings/s; "
          f"real time x {cycles / cfg.frame_rate:5.2f}")
    n_echo = sum(len(d) for d, _ in ring.echoes(scene, 1.0))
    # Visibility rays of one cycle: two per candidate echo; at least one per firing.
    n_rays = max(2 * 4 * n_echo, 64)
    pose = ring.transducer_poses(scene, 1.0)[0]
    d = np.random.default_rng(1).normal(size=(n_rays, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    _, anchor = embree_anchor(scene, "ultrasonic", 1.0, pose.position, d, repeats=30)
    print_anchor(f"bare Embree cast of {n_rays} rays", anchor, med)
    print_load_at_end()


if __name__ == "__main__":
    main()
