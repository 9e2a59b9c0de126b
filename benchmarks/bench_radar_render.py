"""The render stage of a moving radar, stage by stage: NumPy passes (before) and compiled
passes (after) in turn.

The robot cell (``examples/ur5_cell.yaml`` with a person walking through it) and
``paper_bgt60tr13c`` on the UR5's flange (1000 x 342 render rays, every one a
scatterer that moves relative to the radar). Per frame, process CPU (every
thread) and wall time of each stage of ``ScatterRenderer.render`` on the
radar's worker threads (the cores, 2 here):

- the radar's pose (its mount on the flange: the arm's forward kinematics),
- the world rays of the new pose,
- the moving objects' poses at the frame's time (the arm's links, the
  person's segments: ``state_at`` of each, which the cast asks for),
- the cast (one Embree 4 traversal per ray through the instanced scene, then
  float64 distances, ids, incidence and point velocities),
- the scatterers: points, velocities relative to the radar, RCS and amplitudes;

then whole renders and whole frames (``FMCWRadar.capture``: render, IF
synthesis, noise, ADC, processing), before and after in turn. Each variant
runs at its own times (a frame's time is never repeated, so no pose is taken
from a cache the other variant filled). The same-run anchor is the bare
single-thread embreex cast of the same rays against the scene posed at one
time, in one world-space BVH (``_timing.embree_anchor``).

Run:  .venv/bin/python benchmarks/bench_radar_render.py [--frames N] [--rounds R]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from _cell import flange_radar, radar_anchor
from _timing import alternating, in_turn, print_load_at_end, print_machine

from twinsense.radar.scatterers import _DIRECT_FIELDS, ScatterRenderer
from twinsense.render import caster_for

ROOT = Path(__file__).resolve().parents[1]
T0 = 0.31  # [s] frames at T0 + k / 30 s: none at a keyframe, where the arm (and radar) rests
FORMS = {"before (NumPy passes)": False, "after (compiled passes)": True}


def cell_scene():
    from twinsense.scenario import load_scenario
    from twinsense.scene.human import Walk, add_person

    scene = load_scenario(ROOT / "examples" / "ur5_cell.yaml").scene
    add_person(scene, "person", 1.75, position=(1.6, -1.5), walk=Walk(speed=1.0, heading_deg=90.0))
    return scene


def stages(scene, radar, frames: int, anchor: float) -> None:
    """Process CPU and wall of every stage of one render, medians over ``frames``, the two forms
    frame by frame in turn (each at its own times)."""
    caster = caster_for(scene, "radar")
    renderers = {label: ScatterRenderer(radar.config, workers=radar.workers, compiled=c)
                 for label, c in FORMS.items()}
    spent: dict = {label: {} for label in FORMS}

    def one(label, r, t):
        rec = spent[label]
        c0, w0 = time.process_time(), time.perf_counter()

        def done(name):
            nonlocal c0, w0
            c1, w1 = time.process_time(), time.perf_counter()
            rec.setdefault(name, []).append((c1 - c0, w1 - w0))
            c0, w0 = c1, w1

        state = radar.mount.state_at(scene, t)
        done("radar pose (mount on the flange)")
        rays = r._world_rays(state.pose)
        done("world rays of the new pose")
        caster._states(t)
        done("moving objects' poses (state_at of 26 objects)")
        # As render casts: into the arrays it keeps (after), into new ones (before).
        kept = r._hit_buffers(len(rays.directions), _DIRECT_FIELDS) if r.compiled else None
        hits = caster.cast(rays, t, _DIRECT_FIELDS, r.workers, buffers=kept)
        done("cast: picks (as the caster chooses) + float64 hits")
        (r._direct_compiled if r.compiled else r._direct_numpy)(scene, state, hits, True)
        done("scatterers: points, velocities, RCS, amplitudes")

    for k in range(frames + 1):  # frame 0: warm-up (compiled kernels loaded), not counted
        for j, (label, r) in enumerate(renderers.items()):
            one(label, r, T0 + k / 30.0 + j * 1e-3)
    print(f"\n  stages of one render, process CPU / wall per frame (median of {frames} frames, "
          f"workers={radar.workers}; anchor {anchor * 1e3:.1f} ms):")
    labels = list(FORMS)
    print(f"    {'stage':<52s} " + "  ".join(f"{lab:>28s}" for lab in labels))
    totals = {lab: np.zeros(2) for lab in labels}
    for name in spent[labels[0]]:
        cells = []
        for lab in labels:
            a = np.median(np.array(spent[lab][name][1:]), axis=0)
            totals[lab] += a
            cells.append(f"{a[0] * 1e3:8.1f} / {a[1] * 1e3:8.1f} ms")
        print(f"    {name:<52s} " + "  ".join(f"{c:>28s}" for c in cells))
    print(f"    {'sum of the stages':<52s} " + "  ".join(
        f"{f'{totals[lab][0] * 1e3:8.1f} / {totals[lab][1] * 1e3:8.1f} ms':>28s}" for lab in labels))
    for lab in labels:
        cast = np.median(np.array(spent[lab]["cast: picks (as the caster chooses) + float64 hits"][1:]),
                         axis=0)[0]
        print(f"    {lab}: CPU outside the cast {(totals[lab][0] - cast) * 1e3:.1f} ms, "
              f"{(totals[lab][0] - cast) / anchor:.2f} x anchor; whole stage {totals[lab][0] / anchor:.2f} x anchor")


def whole(scene, radar, rounds: int, anchor: float) -> None:
    """Whole renders and whole frames, the two forms in turn (each at its own times)."""
    renderers = {label: ScatterRenderer(radar.config, workers=radar.workers, compiled=c)
                 for label, c in FORMS.items()}

    def render(r, offset):
        def run(k):
            t = T0 + k / 30.0 + offset
            r.render(scene, radar.mount.state_at(scene, t), t)
        return run

    results = alternating({lab: in_turn(render(r, 2e-3 + j * 1e-3), rounds)
                           for j, (lab, r) in enumerate(renderers.items())}, rounds)
    print(f"\n  whole render (ScatterRenderer.render), in turn, {rounds} rounds:")
    for lab, (best, med, cpu) in results.items():
        print(f"    {lab:<28s} CPU {cpu * 1e3:7.1f} ms, wall {med * 1e3:7.1f} ms median "
              f"({best * 1e3:6.1f} best); CPU / anchor {cpu / anchor:5.2f}")

    radars = {}
    for lab, c in FORMS.items():
        rad = flange_radar("ur5")
        rad._renderer = ScatterRenderer(rad.config, rad.backend, rad.workers,
                                        reuse_static_hits=rad.reuse_static, compiled=c)
        radars[lab] = rad

    def frame(rad, offset):
        def run(k):
            rad.capture(scene, T0 + k / 30.0 + offset, np.random.default_rng(k))
        return run

    n = max(2, rounds // 2)
    results = alternating({lab: in_turn(frame(rad, 4e-3 + j * 1e-3), n)
                           for j, (lab, rad) in enumerate(radars.items())}, n)
    print(f"\n  whole frame (FMCWRadar.capture: render, IF synthesis, noise, ADC, processing), in turn, "
          f"{n} rounds:")
    for lab, (best, med, cpu) in results.items():
        print(f"    {lab:<28s} CPU {cpu * 1e3:7.1f} ms, wall {med * 1e3:7.1f} ms median "
              f"({best * 1e3:6.1f} best); CPU / anchor {cpu / anchor:5.2f}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--rounds", type=int, default=10)
    args = ap.parse_args()
    if args.frames < 1 or args.rounds < 1:
        ap.error("--frames and --rounds must be at least 1")
    print_machine()
    scene = cell_scene()
    radar = flange_radar("ur5")
    cfg = radar.config
    anchor = radar_anchor(scene, radar, T0 + 1 / 30.0, 9)
    print(f"robot cell, {cfg.render_width} x {cfg.render_height} radar rays on the moving flange; "
          f"anchor: bare single-thread embreex cast of the same rays {anchor * 1e3:.1f} ms (median of 9)")
    stages(scene, radar, args.frames, anchor)
    whole(scene, radar, args.rounds, anchor)
    print_load_at_end()


if __name__ == "__main__":
    main()
