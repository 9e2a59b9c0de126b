"""People: building a walker, one body state (gait + forward kinematics), a radar frame of a walker.

Anchors (same run): the bare forward kinematics of the same tree with the
same joint values (what a person adds on top is the gait evaluation), and a
radar frame of the same person standing still (what walking adds to a frame).

Run: .venv/bin/python benchmarks/bench_people.py
"""

from __future__ import annotations

import numpy as np
from _timing import best_and_median, print_anchor, print_load_at_end, print_machine

from twinsense.radar import make_radar
from twinsense.scene import Mount, Pose, Scene
from twinsense.scene.gait import GaitTiming, WalkCycle
from twinsense.scene.human import Walk, add_person, leg_geometry


def main() -> None:
    print_machine()
    leg = leg_geometry(1.75)
    for body in ("planted", "smooth"):
        best, med = best_and_median(lambda b=body: WalkCycle(GaitTiming(1.4, leg.leg_length), leg, b), repeats=3)
        print(f"walk cycle set-up ({body}, 1.4 m/s): {best * 1e3:7.1f} ms best, {med * 1e3:7.1f} ms median")

    scene = Scene()
    person = add_person(scene, "w", 1.75, (0.0, 0.0), 0.0, walk=Walk(1.4, heading_deg=0.0, start_time=-2.0))
    times = iter(np.arange(1e6) * 1e-3 + 0.1234)  # a new time per call: no cache hit

    def state():
        person.state(next(times))

    best, med = best_and_median(state, repeats=200)
    print(f"person state (gait + FK of {len(person.tree.links)} links): {best * 1e3:6.2f} ms best, "
          f"{med * 1e3:6.2f} ms median")
    q, qd = person.joint_state(0.5)
    base = person.base.state(0.5)
    _, a_med = best_and_median(lambda: person.tree.forward(q, qd, base), repeats=200)
    print_anchor("bare forward kinematics, same tree and q", a_med, med)
    steady = med

    # A walk along a 3 m path: its set-up (gait, the start's swinging-leg spline, the closing steps), and the
    # state at new times in its start ramp and in its closing steps, against the steady walk's above.
    def path_walker():
        return add_person(Scene(), "p", 1.75, (0.0, 0.0), 0.0, walk=Walk(1.4, path=((3.0, 0.0),), start_time=0.5))

    best, med = best_and_median(path_walker, repeats=5)
    print(f"walker along a 3 m path, set-up: {best * 1e3:7.1f} ms best, {med * 1e3:7.1f} ms median")
    walker = path_walker()
    motion = walker.joint_motion.person
    for what, t0, span in (("start ramp", 0.5, 0.6), ("closing steps", motion.arrival_time, 0.8)):
        ts = iter(t0 + (np.arange(1e6) * 1e-3 + 0.1234) % span)
        best, med = best_and_median(lambda ts=ts: walker.state(next(ts)), repeats=200)
        print(f"person state in the {what}: {best * 1e3:6.2f} ms best, {med * 1e3:6.2f} ms median")
        print_anchor("the steady walk's state", steady, med)

    radar = make_radar("paper_bgt60tr13c", num_samples=64, num_chirps=64, chirp_repetition_time=100e-6,
                       ramp_end_time=40e-6, frame_rate=20.0, render_width=96, render_height=48, process=False,
                       mount=Mount(Pose.look_at((6.0, 0.0, 1.0), (0.0, 0.0, 1.0))))
    rng = np.random.default_rng(0)
    frame_times = iter(np.arange(1000) / 20.0)
    best, med = best_and_median(lambda: radar.capture(scene, next(frame_times), rng), repeats=10)
    print(f"radar frame of a walker (64 chirps x 64 samples x 2 Rx, 96 x 48 rays): {best * 1e3:6.1f} ms best, "
          f"{med * 1e3:6.1f} ms median")
    still = Scene()
    add_person(still, "s", 1.75, (3.0, 0.0), 0.0)
    radar2 = make_radar("paper_bgt60tr13c", num_samples=64, num_chirps=64, chirp_repetition_time=100e-6,
                        ramp_end_time=40e-6, frame_rate=20.0, render_width=96, render_height=48, process=False,
                        mount=Mount(Pose.look_at((6.0, 0.0, 1.0), (0.0, 0.0, 1.0))))
    _, a_med = best_and_median(lambda: radar2.capture(still, 0.0, rng), repeats=10)
    print_anchor("radar frame of the same person standing", a_med, med)
    print_load_at_end()


if __name__ == "__main__":
    main()
