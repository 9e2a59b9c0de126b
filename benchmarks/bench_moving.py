"""Sensors that move: a ToF camera and a radar rendered from scratch every frame.

A sensor on a robot moves every frame, so nothing it saw before can be kept:
every ray is traced again and every scatterer synthesised again. Cases:

- office (84k triangles, a walking person): ``pmd_pico_flexx`` (224 x 171 px,
  2 x 2 supersampling, dual frequency, every effect but multipath) turning a
  little every frame; ``paper_bgt60tr13c`` (1000 x 342 render, 16 chirps x
  2 Rx x 512 samples, processing included) with nothing kept
  (``reuse_static=False``), frames at t = 1 s + k / 30 s (the person walking);
- robot cell (``examples/ur5_cell.yaml``: a UR5 moving over a table, plus a
  person walking through the cell): the scenario's wrist ToF camera
  (``pmd_pico_flexx`` in MODE_9_25FPS_450) and a ``paper_bgt60tr13c`` radar
  beside it on the flange, both moving with the arm (so every scatterer the
  radar sees moves relative to it).

Each line gives the best and median wall time over the frames after one
warm-up frame, the frames per second of the median, and the same-run anchor:
a bare single-thread embreex cast (closest-hit ids only) of the sensor's
rays against the whole scene posed at one time, in one world-space BVH.
The numba kernels' first-call compile (or cache load) is timed separately.

Run:  .venv/bin/python benchmarks/bench_moving.py [--frames N]
"""

from __future__ import annotations

import argparse
import contextlib
import time
from pathlib import Path

import numpy as np
from _cell import flange_radar, radar_anchor, tof_anchor
from _timing import alternating, in_turn, print_anchor, print_load_at_end, print_machine, timed_frames

from twinsense.demos.office import SENSOR_EYE, SENSOR_TARGET, build_office_scene, sensor_pose
from twinsense.radar import FMCWRadar
from twinsense.scene import Mount, Pose
from twinsense.tof import ToFCamera

ROOT = Path(__file__).resolve().parents[1]


def report(label: str, best: float, median: float, cpu: float, anchor: float) -> None:
    # CPU time holds better than wall time when other jobs share the cores.
    print(f"  {label:<58s} {best * 1e3:7.1f} ms best {median * 1e3:7.1f} ms median "
          f"-> {1 / median:5.1f} frames/s; CPU {cpu * 1e3:7.1f} ms/frame (median)")
    print_anchor("bare embreex cast, same rays", anchor, median)


def office(frames: int) -> None:
    scene = build_office_scene(detail=6, person=True)
    print(f"\n== office, {sum(len(o.geometry.mesh.faces) for o in scene.objects)} triangles, walking person")
    rng = np.random.default_rng(0)
    cam = ToFCamera.preset("pmd_pico_flexx", mount=sensor_pose())
    anchor = tof_anchor(scene, cam, 1.5, 15)  # the camera's first pose

    def tof_frame(k):
        cam.mount = Mount(Pose.look_at(SENSOR_EYE, np.add(SENSOR_TARGET, (0.0, 1e-3 * k, 0.0))))
        cam.capture(scene, 1.0 + k / 45.0, rng)

    report("ToF pmd_pico_flexx, camera moving every frame", *timed_frames(tof_frame, frames), anchor)

    radar = FMCWRadar.preset("paper_bgt60tr13c", mount=Mount(sensor_pose()), reuse_static=False)
    anchor = radar_anchor(scene, radar, 1.5, 15)
    report("radar paper_bgt60tr13c, from scratch (nothing kept)",
           *timed_frames(lambda k: radar.capture(scene, 1.0 + k / 30.0, np.random.default_rng(k)), frames), anchor)


def robot_cell(frames: int, radar_only: bool = False) -> None:
    from twinsense.scenario import load_scenario
    from twinsense.scene.human import Walk, add_person

    sc = load_scenario(ROOT / "examples" / "ur5_cell.yaml")
    scene = sc.scene
    add_person(scene, "person", 1.75, position=(1.6, -1.5), walk=Walk(speed=1.0, heading_deg=90.0))
    n_tri = sum(len(o.geometry.mesh.faces) for o in scene.objects)
    moving = sum(not o.is_static for o in scene.objects)
    print(f"\n== robot cell (examples/ur5_cell.yaml), {n_tri} triangles, {moving} moving objects "
          f"(UR5 links, person)")
    rng = np.random.default_rng(0)
    tof = next(s for s in sc.sensors if s.name == "wrist_tof")
    t_of = [0.3 + k / tof.frame_rate for k in range(frames + 1)]
    anchor = tof_anchor(scene, tof, t_of[1], 15)
    if not radar_only:
        wrist_tof(scene, tof, t_of, frames, rng, anchor)
    wrist_radar(scene, t_of, frames)


def wrist_tof(scene, tof, t_of, frames: int, rng, anchor: float) -> None:
    """The wrist ToF camera's frames, their stages and the world-BVH alternative."""
    report(f"wrist ToF ({tof.config.width} x {tof.config.height}, {tof.config.supersample} x "
           f"{tof.config.supersample} sub-pixels), on the moving arm",
           *timed_frames(lambda k: tof.capture(scene, t_of[k], rng), frames), anchor)
    tof_stages(scene, tof, t_of[1:], anchor)
    movers_world_bvh(scene, tof, t_of[1:])


def wrist_radar(scene, t_of, frames: int) -> None:
    """The flange radar's whole frames before and after in turn, then its synthesis alone."""
    # Beside the ToF camera on the flange, looking the same way (down at the table).
    radar = flange_radar("ur5")
    anchor = radar_anchor(scene, radar, t_of[1], 15)
    n = max(2, frames // 4)  # every scatterer moves with the arm: seconds per frame
    # Whole frames, before (finufft for the 1-D transforms) and after (the compiled spreader) in turn.
    for label, times in radar_frames_before_after(radar, scene, t_of, n).items():
        report(f"radar paper_bgt60tr13c on the moving wrist, {label} ({n} frames)", *times, anchor)
    wrist_synthesis(radar, scene, t_of[1], anchor)


def tof_stages(scene, tof, times, anchor: float) -> None:
    """CPU time of each stage of a moving ToF camera's frame on this thread (one worker,
    thread CPU time: it holds better than wall time on a busy machine), medians over ``times``."""
    from twinsense.render import caster_for
    from twinsense.tof.kernels import hits_to_phasors
    from twinsense.tof.pipeline import (
        ChainNoise,
        blurred_raw,
        chain_from_raw,
        finish_geometry,
        noise_rows,
        noise_seeds,
    )
    from twinsense.tof.rendering import DIRECT_FIELDS, material_table
    from twinsense.tof.signal import PixelPhasors

    caster = caster_for(scene, "tof")
    cfg, renderer = tof.config, tof._renderer
    rng = np.random.default_rng(0)
    stages: dict[str, list[float]] = {}
    clock = [0.0]

    def done(name):
        now = time.thread_time()
        stages.setdefault(name, []).append(now - clock[0])
        clock[0] = time.thread_time()

    for t in times:
        clock[0] = time.thread_time()
        pose = tof.mount.pose_at(scene, t)
        done("camera pose (mount on the flange)")
        rays = renderer.rays(pose.rotation, pose.position)
        done("world rays of the new pose")
        caster._states(t)
        done("moving objects' poses (state_at of every link)")
        caster.cast(rays, 0.0, DIRECT_FIELDS, workers=1, moving=False)
        done("cast, static objects only (Embree + distances)")
        o32 = np.broadcast_to(rays.origins[0].astype(np.float32), rays.directions.shape)
        d32 = rays.directions.astype(np.float32)
        clock[0] = time.thread_time()
        caster._static_bvh._run(o32, d32)
        done("- of which Embree's own traversal")
        hits = caster.cast(rays, t, DIRECT_FIELDS, workers=1)
        done("cast, everything (poses as above)")
        ph = PixelPhasors(*hits_to_phasors(hits.distance, hits.cos_incidence, hits.object_id,
                                           material_table(scene), cfg, tof.radiometry, 1))
        done("hits -> pixel phasors")
        noise = noise_rows(cfg, noise_seeds(rng), 0, cfg.height)
        done("noise draws (a background thread in a capture)")
        raw = blurred_raw(ph, cfg)
        done("cross-talk blur")
        out = chain_from_raw(*raw, cfg, ChainNoise(noise.raw, noise.gray))
        done("noise, ADC, demodulation, unwrapping, validity")
        finish_geometry(out, tof._pixel_dirs, cfg)
        done("flying pixels, confidence, points")
    print(f"  stages of the wrist ToF frame, CPU on one thread (median of {len(times)} frames; anchor "
          f"{anchor * 1e3:.1f} ms):")
    for name, v in stages.items():
        print(f"    {name:<52s} {np.median(v) * 1e3:6.1f} ms ({np.median(v) / anchor:4.2f} x anchor)")


def movers_world_bvh(scene, tof, times) -> None:
    """The alternative to tracing each moving object in its own frame: one world-space
    Embree BVH per frame over every moving object's posed triangles. Its posing and
    build time against the moving objects' share of the per-object cast (process CPU)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    from twinsense.render import caster_for
    from twinsense.tof.rendering import DIRECT_FIELDS

    caster = caster_for(scene, "tof")
    objs = scene.objects
    meshes = [(np.asarray(objs[i].geometry.mesh.vertices, float), np.asarray(objs[i].geometry.mesh.faces))
              for i in caster._moving]
    pose_cpu, build_cpu, movers_cpu = [], [], []
    for t in times:
        c0 = time.process_time()
        tri = np.ascontiguousarray(np.concatenate([objs[i].pose_at(t).apply(v)[f]
                                                   for (v, f), i in zip(meshes, caster._moving)]), np.float32)
        c1 = time.process_time()
        bvh = rtcore_scene.EmbreeScene()
        TriangleMesh(bvh, tri)
        bvh.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32))  # commit: the build
        c2 = time.process_time()
        pose_cpu.append(c1 - c0)
        build_cpu.append(c2 - c1)
        pose = tof.mount.pose_at(scene, t)
        rays = tof._renderer.rays(pose.rotation, pose.position)
        caster._states(t)
        c3 = time.process_time()
        caster.cast(rays, t, DIRECT_FIELDS, workers=1, moving=False)
        c4 = time.process_time()
        caster.cast(rays, t, DIRECT_FIELDS, workers=1)
        movers_cpu.append((time.process_time() - c4) - (c4 - c3))
    print(f"  one world BVH of the {len(tri)} moving triangles per frame: posing {np.median(pose_cpu) * 1e3:.1f} ms "
          f"+ Embree build {np.median(build_cpu) * 1e3:.1f} ms CPU, before any ray; the per-object path's "
          f"moving objects (cull, trace, merge): {np.median(movers_cpu) * 1e3:.1f} ms CPU")


def _stage_timers(stages: dict):
    """Wrap the synthesis' stage functions to add their thread CPU time to ``stages``
    (label -> seconds; a call inside another is counted in both). Returns the undo."""
    import finufft

    import twinsense.radar.nufft as nufft_module
    import twinsense.radar.spreader as spreader_module
    import twinsense.radar.synthesis as synthesis_module

    targets = [
        (synthesis_module, "moving_chunk_2d", "movers' 2-D blocks (plan and run)"),
        (synthesis_module, "moving_chunk", "movers per chirp (the tails)"),
        (synthesis_module, "static_chunk", "static rows"),
        (nufft_module, "_split_floor", "- split floors (splits skipped before their plans)"),
        (nufft_module, "_plan_block", "- block plans (legs, phase coefficients, series choice)"),
        (nufft_module, "block_coefficients", "  - of which the phase coefficients (compiled)"),
        (nufft_module, "spread_series_1d", "- 1-D blocks: series + spreading (compiled)"),
        (spreader_module.Kernel, "transform_rows", "- per-chirp rows' transforms (one call per receiver)"),
        (spreader_module.Kernel, "finish", "- spreader FFTs and deconvolution"),
        (nufft_module, "_block_rows", "- monomial sums and chunk-wide phasor"),
        (finufft.Plan, "execute", "- finufft executes (2-D vectors)"),
    ]
    saved = []
    for owner, name, label in targets:
        fn = getattr(owner, name, None)
        if fn is None:  # a stage an older tree (bench_radar_trees.py --before) does not have
            continue
        stages.setdefault(label, 0.0)  # printed in this order, nested stages under their parent
        saved.append((owner, name, fn))

        def timed(*a, _fn=fn, _label=label, **k):
            c0 = time.thread_time()
            try:
                return _fn(*a, **k)
            finally:
                stages[_label] = stages.get(_label, 0.0) + time.thread_time() - c0
        setattr(owner, name, timed)

    def undo():
        for owner, name, fn in saved:
            setattr(owner, name, fn)
    return undo


def synthesis_stages(p, v, w, cfg, eps: float, rounds: int = 3) -> None:
    """Thread CPU time of each stage of one wrist frame's synthesis on one thread (median of
    ``rounds``), and of the noise-tolerance estimate before it."""
    from twinsense.radar.synthesis import noise_tolerance, synthesize

    runs: list[dict] = []
    for _ in range(rounds + 1):
        stages: dict = {}
        c0 = time.thread_time()
        noise_tolerance(p, w, cfg, workers=1)
        stages["noise tolerance (first-chirp power estimate)"] = time.thread_time() - c0
        undo = _stage_timers(stages)
        try:
            c0 = time.thread_time()
            synthesize(p, v, w, cfg, eps=eps, workers=1)
            stages["synthesis, all"] = time.thread_time() - c0
        finally:
            undo()
        work = sum(stages.get(k, 0.0) for k in ("movers' 2-D blocks (plan and run)",
                                                 "movers per chirp (the tails)", "static rows"))
        stages["- movers found, range rates, sort, gathers, sums"] = stages["synthesis, all"] - work
        runs.append(stages)
    runs = runs[1:]  # the first: warm-up
    print(f"  stages of the wrist synthesis, thread CPU on one thread (median of {rounds}; eps={eps:.2g}):")
    for label in runs[0]:
        if any(r.get(label, 0.0) for r in runs):  # stages the frame never ran left out
            print(f"    {label:<58s} {np.median([r.get(label, 0.0) for r in runs]) * 1e3:7.1f} ms")


def wrist_synthesis(radar: FMCWRadar, scene, t: float, anchor: float) -> None:
    """The wrist radar's IF synthesis alone (every scatterer moves), the variants in
    turn: the per-chirp path only, the code before the compiled spreader (finufft for
    every 1-D transform: ``nufft.SPREAD_1D`` off) and after, anchored to the
    static-scene synthesis of the same scatterers (velocities dropped) and to the bare
    embreex cast; the preset's 16 chirps and the same frame with 64 chirps. Then the
    stages of the 16-chirp synthesis on one thread."""
    import dataclasses

    import twinsense.radar.nufft as nufft_module
    import twinsense.radar.synthesis as synthesis_module

    scat = radar._renderer.render(scene, radar.mount.state_at(scene, t), t)
    w = radar._weights(scat)
    p, v = scat.points, scat.velocities
    workers = radar.workers
    # The tolerance the radar's own frame uses (its eps, or the receiver noise's share).
    eps = radar._tolerance(p, w, scat.points_rx)
    for num_chirps in (radar.config.chirp.num_chirps, 64):
        cfg = dataclasses.replace(radar.config,
                                  chirp=dataclasses.replace(radar.config.chirp, num_chirps=num_chirps))
        rounds = 5 if num_chirps <= 16 else 2

        def run(cfg=cfg):
            return synthesis_module.synthesize(p, v, w, cfg, eps=eps, workers=workers)

        def per_chirp():
            two_d = synthesis_module.moving_chunk_2d
            synthesis_module.moving_chunk_2d = lambda *a, **k: None  # the per-chirp path everywhere
            try:
                return run()
            finally:
                synthesis_module.moving_chunk_2d = two_d

        def before():
            with finufft_1d():
                return run()

        def static(cfg=cfg):
            return synthesis_module.synthesize(p, None, w, cfg, eps=eps, workers=workers)

        # Accuracy against the same frame at eps = 1e-8 (the bound: 2 eps).
        ref = synthesis_module.synthesize(p, v, w, cfg, eps=1e-8, workers=workers)
        errs = [np.linalg.norm(fn() - ref) / np.linalg.norm(ref) for fn in (before, run)]
        times = alternating({"per-chirp path only": per_chirp, "finufft 1-D (before)": before,
                             "compiled spreader (after)": run,
                             "anchor: same scatterers static": static}, rounds)
        print(f"  wrist radar synthesis alone, {len(p)} scatterers, all moving, {num_chirps} chirps "
              f"(workers={workers}, eps={eps:.2g}, {rounds} rounds in turn); relative l2 error against "
              f"eps=1e-8: {errs[0]:.1e} ({errs[0] / eps:.2f} eps) before, {errs[1]:.1e} "
              f"({errs[1] / eps:.2f} eps) after")
        static_cpu = times["anchor: same scatterers static"][2]
        for label, (best, median, cpu) in times.items():
            print(f"    {label:<36s} {best * 1e3:8.1f} ms best {median * 1e3:8.1f} ms median; "
                  f"CPU {cpu * 1e3:8.1f} ms/frame; {cpu / static_cpu:5.1f} x static CPU")
        print_anchor("bare embreex cast, same rays", anchor, times["compiled spreader (after)"][1])
    assert nufft_module.SPREAD_1D
    # The render before it (scatterers and amplitudes), at times 10 ms apart (new poses).
    render = timed_frames(lambda k: radar._weights(radar._renderer.render(
        scene, radar.mount.state_at(scene, t + 0.01 * k), t + 0.01 * k)), 3)
    print(f"  the frame's render and amplitudes (workers={workers}): {render[1] * 1e3:.1f} ms median "
          f"wall, CPU {render[2] * 1e3:.1f} ms")
    synthesis_stages(p, v, w, radar.config, eps)


@contextlib.contextmanager
def finufft_1d():
    """The synthesis before the compiled spreader: finufft for every 1-D transform (at the
    tolerances it had: eps for static and per-chirp rows, eps / 4 and looser for the
    blocks' 1-D vectors); restored on exit."""
    import twinsense.radar.nufft as nufft_module

    nufft_module.SPREAD_1D = False
    try:
        yield
    finally:
        nufft_module.SPREAD_1D = True


def radar_frames_before_after(radar: FMCWRadar, scene, times, n: int) -> dict:
    """{"before": ..., "after": ...}: (best wall, median wall, median CPU) [s] of whole frames
    at ``times[k]``, k = 1..n, finufft 1-D (before) and the compiled spreader (after) in
    turn, each round at the next time (frame k's noise from seed k)."""
    def before(k):
        with finufft_1d():
            radar.capture(scene, times[k], np.random.default_rng(k))

    return alternating({"before (finufft 1-D)": in_turn(before, n),
                        "after (compiled spreader)": in_turn(
                            lambda k: radar.capture(scene, times[k], np.random.default_rng(k)), n)}, n)


def compile_times() -> None:
    """The compiled kernels' first call in this process (from the on-disk cache if present)."""
    import subprocess
    import sys

    code = ("import time, numpy as np;"
            "from twinsense.scene import Box, ConstantVelocity, Pose, Scene;"
            "from twinsense.tof import ToFCamera; from twinsense.radar import FMCWRadar;"
            "from twinsense.scene import Mount;"
            "s = Scene(); s.add_object('w', Box((0.02, 4, 4)), 'drywall', pose=Pose((3, 0, 0)));"
            "s.add_object('c', Box((0.3, 0.3, 0.3)), 'metal',"
            "             motion=ConstantVelocity(Pose((1.5, 0.3, 0)), (0, -0.5, 0)));"
            "cam = ToFCamera.preset('pmd_pico_flexx', mount=Pose.look_at((0, 0, 0), (1, 0, 0)));"
            "r = FMCWRadar.preset('paper_bgt60tr13c', mount=Mount(Pose.look_at((0, 0, 0), (1, 0, 0))),"
            "                     reuse_static=False);"
            "t0 = time.perf_counter(); cam.capture(s, 0.0, np.random.default_rng(0)); t1 = time.perf_counter();"
            "r.capture(s, 0.0, np.random.default_rng(0)); t2 = time.perf_counter();"
            "cam.mount = Mount(Pose.look_at((0, 0.01, 0), (1, 0, 0))); cam.capture(s, 0.1, np.random.default_rng(0));"
            "t3 = time.perf_counter(); r.capture(s, 0.1, np.random.default_rng(0)); t4 = time.perf_counter();"
            "print(f'{t1 - t0:.2f} {t2 - t1:.2f} {t3 - t2:.3f} {t4 - t3:.3f}')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    print(f"\nfirst ToF frame {out[0]} s and first radar frame {out[1]} s in a new process "
          f"(kernels loaded from the cache); second frames {float(out[2]) * 1e3:.0f} / {float(out[3]) * 1e3:.0f} ms")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--skip-robot", action="store_true")
    ap.add_argument("--wrist-radar-only", action="store_true",
                    help="only the robot cell's wrist radar (frames, synthesis, its stages)")
    args = ap.parse_args()
    print_machine()
    if args.wrist_radar_only:
        robot_cell(args.frames, radar_only=True)
        print_load_at_end()
        return
    office(args.frames)
    if not args.skip_robot:
        robot_cell(args.frames)
    compile_times()
    print_load_at_end()


if __name__ == "__main__":
    main()
