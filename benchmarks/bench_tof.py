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

``--wrist-chain`` runs only the signal chain's case: the robot cell's wrist
camera (``pmd_pico_flexx`` on the moving UR5e, a walking person), whole
captures with the NumPy reference chain and with the compiled chain in turn,
frame by frame, then the chain's stages on one frame's hits.

``--wrist-stages`` times where the wall time of one wrist frame goes on the
worker threads: every stage's calls (camera pose and world rays, the links'
poses, the top level's posing, Embree's traversal and the float64 hit pass
per chunk or the bundle picker's pick of all rays, the phasor pass's two loops per band,
the noise draw, the chain's two passes per band) are wrapped to record their thread, start, end and
thread CPU; per frame the span of each stage (first start to last end, from
the capture's start), its summed wall and CPU, each thread's busy time, and
the cores' idle time (2 x wall - process CPU), medians over the frames.

``--before SRC`` times the wrist camera's whole captures with the package at
SRC (another checkout's ``src``, e.g. ``git archive <commit> src | tar -x -C
DIR``) and with this one, in child processes taking turns (``--rounds``
rounds of ``--frames`` frames each, the first child of each untimed: numba
compiles or loads its cache), every child at the same frame times and seeds:
median and best wall per frame, median process CPU per frame, the same-run
anchor (a bare embreex cast of the same rays, in each child) and the load.

``--wrist-ways`` takes whole wrist captures with the chain after the whole cast or per chunk of the
cast, and NumPy's normals or the compiled ziggurat (same SFC64 stream), frame by frame in turn.

``--wrist-noise`` takes whole wrist captures with the noise drawn per block of
8 rows (a generator each, as before) or as one stream, frame by frame in turn;
``--wrist-phasors`` with the phasors made after the whole cast (as before) or
per chunk of the cast (``SceneCaster.cast(then=)``), frame by frame in turn.

Run:  .venv/bin/python benchmarks/bench_tof.py [--wrist-chain | --wrist-stages | --wrist-noise |
      --wrist-phasors | --wrist-ways | --before SRC]
      [--frames N]
"""

from __future__ import annotations

import argparse
import itertools
import time

import numpy as np
from _timing import best_and_median, embree_anchor, print_anchor, print_load_at_end, print_machine, timed_frames

from twinsense.demos.office import SENSOR_EYE, SENSOR_TARGET, build_office_scene, sensor_pose, triangle_count
from twinsense.linalg import rotate_rows
from twinsense.render import Rays, caster_for
from twinsense.scene.pose import Pose
from twinsense.scene.scene import Mount
from twinsense.tof import ToFCamera
from twinsense.tof.pipeline import finish_geometry, run_chain
from twinsense.tof.rendering import DIRECT_FIELDS
from twinsense.tof.signal import PixelPhasors, pixel_phasors

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


def _pcg64_noise(cfg, seeds):
    """The noise draws before the slabs: a PCG64 stream per block of rows, raw and gray
    images drawn apart, the blocks concatenated."""
    from twinsense.tof.pipeline import NOISE_BLOCK_ROWS

    k = NOISE_BLOCK_ROWS
    raws, grays = [], []
    for b, seed in enumerate(seeds):
        g = np.random.Generator(np.random.PCG64(int(seed)))
        rows = min(k, cfg.height - b * k)
        raws.append(g.standard_normal((cfg.n_frequencies, 4, rows, cfg.width), dtype=np.float32))
        grays.append(g.standard_normal((rows, cfg.width), dtype=np.float32))
    return np.concatenate(raws, axis=2), np.concatenate(grays, axis=0)


def wrist_chain(frames: int) -> None:
    """The robot cell's wrist camera: whole captures with the NumPy chain and the compiled
    chain in turn, frame by frame, then the stages after the cast on one frame's hits."""
    from twinsense.demos.robot_cell import build_arm_cell
    from twinsense.render.parallel import default_workers
    from twinsense.tof.camera import _background
    from twinsense.tof.chain_kernels import chain_frame
    from twinsense.tof.kernels import hits_to_phasors
    from twinsense.tof.pipeline import (
        NOISE_BLOCK_ROWS,
        blurred_raw,
        chain_in_halves,
        draw_noise_slabs,
        noise_seeds,
        slab_noise,
    )
    from twinsense.tof.rendering import material_table

    scene, sensors = build_arm_cell()
    new = sensors[2]
    cfg = new.config
    old = ToFCamera(cfg, new.mount, "wrist_tof_numpy")
    old.compiled_chain = False
    t0 = 0.9  # the arm between pick and lift, the person walking in (as bench_robot_cell.py)
    times = [t0 + k / 30.0 for k in range(frames + 1)]
    pose = new.mount.pose_at(scene, times[1])
    rays = new._renderer.rays(pose.rotation, pose.position)
    n_rays = len(rays.directions)
    print(f"\n== robot cell, wrist ToF pmd_pico_flexx on the moving UR5e ({cfg.width} x {cfg.height} px, "
          f"{n_rays} rays), walking person; {default_workers()} worker threads")
    _, anchor = embree_anchor(scene, "tof", times[1], rays.origins, rays.directions, repeats=9)
    print(f"  anchor: bare embreex cast of the same {n_rays} rays, 1 thread: {anchor * 1e3:.1f} ms median")
    rng = np.random.default_rng(0)
    # Every frame time captured by both cameras, in turn (the order alternating), so that both
    # see the same load and the same scene; CPU of every thread and wall per capture.
    ways = {"NumPy chain": old, "compiled chain": new}
    cpu: dict[str, list] = {label: [] for label in ways}
    wall: dict[str, list] = {label: [] for label in ways}
    for cam in ways.values():
        cam.capture(scene, times[0], rng)
    for k in range(1, frames + 1):
        order = list(ways.items()) if k % 2 else list(ways.items())[::-1]
        for label, cam in order:
            c0, w0 = time.process_time(), time.perf_counter()
            cam.capture(scene, times[k], rng)
            cpu[label].append(time.process_time() - c0)
            wall[label].append(time.perf_counter() - w0)
    for label in ways:
        med = float(np.median(wall[label]))
        print(f"  {label:<15s} capture, {frames} frames: wall {med * 1e3:6.1f} ms median (best "
              f"{min(wall[label]) * 1e3:5.1f}) -> {1 / med:5.1f} frames/s, CPU {np.median(cpu[label]) * 1e3:5.1f} "
              f"ms/frame (median)")
        print_anchor("bare embreex cast, same rays", anchor, med)
    diff = np.subtract(cpu["NumPy chain"], cpu["compiled chain"])
    print(f"  CPU saved per frame (paired, same frame time): {np.median(diff) * 1e3:.1f} ms median "
          f"(quartiles {np.percentile(diff, 25) * 1e3:.1f} to {np.percentile(diff, 75) * 1e3:.1f})")

    # The stages after the cast, on the hits of one frame (CPU of every thread, median).
    hits = new._renderer.hits(scene, pose.rotation, pose.position, times[1])
    tables = material_table(scene)
    r_ = new._renderer
    workers = default_workers()

    def stage(label, fn, n=30):
        _, med, cpu = timed_frames(fn, n)  # fn(k), k = 0..n
        print(f"  stage: {label:<58s} CPU {cpu * 1e3:6.2f} ms, wall {med * 1e3:6.2f} ms (median)")

    def cast_new_pose(k):
        tk = times[1] + (k + 1) / 300.0  # a new pose and new object poses every call: nothing kept
        p = new.mount.pose_at(scene, tk)
        return r_.hits(scene, p.rotation, p.position, tk)

    stage("cast of the wrist rays, new pose each time (for scale)", cast_new_pose, 15)
    ph = PixelPhasors(*hits_to_phasors(hits.distance, hits.cos_incidence, hits.object_id, tables, cfg,
                                       r_.radiometry, workers, r_._scratch))
    stage(f"hits -> pixel phasors (compiled, {workers} bands)",
          lambda k: hits_to_phasors(hits.distance, hits.cos_incidence, hits.object_id, tables, cfg,
                                    r_.radiometry, workers, r_._scratch))
    seeds = noise_seeds(rng)
    slabs = draw_noise_slabs(cfg, seeds)
    # The two ways of drawing the noise taken in turn, call by call (one thread each, no threads to share).
    before, now = [], []
    for _ in range(100):
        c0 = time.thread_time()
        _pcg64_noise(cfg, seeds)
        c1 = time.thread_time()
        draw_noise_slabs(cfg, seeds, slabs)
        before.append(c1 - c0)
        now.append(time.thread_time() - c1)
    print(f"  stage: noise draws, in turn 100 times: PCG64 per block, concatenated (before) CPU "
          f"{np.median(before) * 1e3:6.2f} ms; SFC64 per block into kept slabs (now) {np.median(now) * 1e3:6.2f} ms")

    def numpy_chain(k):
        corr, taps, gray_taps = blurred_raw(ph, cfg)
        out = chain_in_halves(corr, taps, gray_taps, cfg, slab_noise(cfg, slabs), _background())
        distance, _, invalid, _, _ = finish_geometry(out, new._pixel_dirs, cfg)
        world = distance[..., None] * r_.pixel_world_directions(pose.rotation)
        world += pose.position.astype(np.float32)
        world[invalid != 0] = np.nan
        out.amplitude.mean(axis=0)

    scratch: dict = {}
    ways = {"NumPy (half the rows on the background thread)": numpy_chain}
    for w in sorted({1, workers}):
        ways[f"compiled, {w} band(s)"] = (
            lambda k, w=w: chain_frame(ph.real, ph.imag, ph.tap_sum, slabs, cfg, new._pixel_dirs, pose.rotation,
                                       pose.position, NOISE_BLOCK_ROWS, w, scratch))
    # The ways taken in turn, call by call, so that they see the same load.
    cpu: dict[str, list] = {label: [] for label in ways}
    wall: dict[str, list] = {label: [] for label in ways}
    for fn in ways.values():
        fn(0)
    for k in range(40):
        for label, fn in ways.items():
            c0, w0 = time.process_time(), time.perf_counter()
            fn(k)
            cpu[label].append(time.process_time() - c0)
            wall[label].append(time.perf_counter() - w0)
    for label in ways:
        print(f"  stage: chain after the phasors, {label:<47s} CPU {np.median(cpu[label]) * 1e3:6.2f} ms, "
              f"wall {np.median(wall[label]) * 1e3:6.2f} ms (median, in turn 40 times)")


class _Recorder:
    """Wraps functions to record (thread name, stage, start, end, thread CPU) of every call."""

    def __init__(self):
        self.events: list = []
        self._undo: list = []

    def wrap(self, owner, name: str, stage: str) -> None:
        import functools
        import threading

        fn = getattr(owner, name)

        @functools.wraps(fn)
        def timed(*a, **k):
            t0, c0 = time.perf_counter(), time.thread_time()
            try:
                return fn(*a, **k)
            finally:
                self.events.append((threading.current_thread().name, stage, t0, time.perf_counter(),
                                    time.thread_time() - c0))

        self._undo.append((owner, name, owner.__dict__.get(name) if isinstance(owner, type) else fn))
        setattr(owner, name, timed)

    def restore(self) -> None:
        for owner, name, fn in reversed(self._undo):
            setattr(owner, name, fn)


def wrist_stages(frames: int) -> None:
    """Where the wall time of a wrist frame goes (see the module docstring)."""
    from collections import defaultdict

    import twinsense.render.embree4 as embree4
    import twinsense.render.instanced as instanced
    import twinsense.tof.camera as camera
    import twinsense.tof.chain_kernels as chain_kernels
    import twinsense.tof.kernels as tof_kernels
    from twinsense.demos.robot_cell import build_arm_cell
    from twinsense.render.bundle import BundlePicker
    from twinsense.render.caster import SceneCaster
    from twinsense.render.parallel import default_workers
    from twinsense.scene.scene import Mount
    from twinsense.tof.rendering import ToFRenderer

    scene, sensors = build_arm_cell()
    cam = sensors[2]
    cfg = cam.config
    times = [0.9 + k / 30.0 for k in range(frames + 4)]
    rng = np.random.default_rng(0)
    for k in range(3):
        cam.capture(scene, times[k], rng)
    rec = _Recorder()
    for owner, name, stage in (
            (Mount, "pose_at", "camera pose"), (ToFRenderer, "rays", "world rays"),
            (SceneCaster, "_states", "moving links' poses (state_at)"),
            (embree4.InstanceScene, "pose", "top level posed and committed"),
            (instanced, "trace", "Embree traversal (per chunk)"),
            (BundlePicker, "pick", "bundle picker (all rays at once)"),
            (instanced, "instanced_hits", "float64 hit pass (per chunk)"),
            (camera, "draw_noise_slabs", "noise draw (background thread)"),
            (tof_kernels, "_sample_rows", "phasors: samples (per band)"),
            (tof_kernels, "_block_rows", "phasors: block sums (per band)"),
            (chain_kernels, "_pixel_rows", "chain pass 1 (per band)"),
            (chain_kernels, "_geometry_rows", "chain pass 2 (per band)")):
        rec.wrap(owner, name, stage)
    spans: dict = defaultdict(list)
    summed: dict = defaultdict(lambda: np.zeros((frames, 2)))
    busy: dict = defaultdict(lambda: np.zeros(frames))
    wall, cpu = np.zeros(frames), np.zeros(frames)
    try:
        for k in range(frames):
            rec.events.clear()
            c0, t0 = time.process_time(), time.perf_counter()
            cam.capture(scene, times[k + 3], rng)
            wall[k], cpu[k] = time.perf_counter() - t0, time.process_time() - c0
            first: dict = {}
            for thread, stage, a, b, c in rec.events:
                lo, hi = first.get(stage, (np.inf, -np.inf))
                first[stage] = (min(lo, a - t0), max(hi, b - t0))
                summed[stage][k] += (b - a, c)
                busy[thread][k] += b - a
            for stage, span in first.items():
                spans[stage].append(span)
    finally:
        rec.restore()
    n_rays = cfg.width * cfg.height * cfg.supersample ** 2
    print(f"\n== robot cell, wrist ToF pmd_pico_flexx ({n_rays} rays): where one frame's wall time goes, "
          f"{default_workers()} worker threads, {frames} frames (medians)")
    print(f"  frame: wall {np.median(wall) * 1e3:.2f} ms (best {wall.min() * 1e3:.2f}), process CPU "
          f"{np.median(cpu) * 1e3:.2f} ms; the 2 cores idle {np.median(2 * wall - cpu) * 1e3:.2f} ms of "
          f"2 x wall")
    print(f"  {'stage':<40s} {'span from capture start':>24s} {'wall (sum of calls)':>20s} {'thread CPU':>11s}")
    for stage, v in sorted(spans.items(), key=lambda x: np.median([a for a, _ in x[1]])):
        v = np.array(v)
        w, c = np.median(summed[stage], axis=0)
        print(f"  {stage:<40s} {np.median(v[:, 0]) * 1e3:9.2f} .. {np.median(v[:, 1]) * 1e3:7.2f} ms "
              f"{w * 1e3:14.2f} ms {c * 1e3:8.2f} ms")
    for thread, b in sorted(busy.items()):
        print(f"  thread {thread:<33s} busy in the stages above {np.median(b) * 1e3:6.2f} ms per frame")


def _per_block_slabs(cfg, seeds, out=None):
    """The noise draw as it was before one stream per frame: a generator per block of rows (seeded
    from the frame's seed through SeedSequence.spawn: 22 for a pico flexx frame), one fill each.
    Other bytes than draw_noise_slabs; for timing."""
    from twinsense.tof.pipeline import NOISE_BLOCK_ROWS, noise_size, slab_size

    k, size = NOISE_BLOCK_ROWS, slab_size(cfg)
    out = np.empty(noise_size(cfg), np.float32) if out is None else out
    blocks = np.random.SeedSequence(int(seeds[0])).spawn(-(-cfg.height // k))
    for b, seq in enumerate(blocks):
        rows = min(k, cfg.height - b * k)
        np.random.Generator(np.random.SFC64(seq)).standard_normal(
            dtype=np.float32, out=out[b * size:b * size + rows * (size // k)])
    return out


def wrist_noise_ways(frames: int) -> None:
    """Whole wrist captures with the noise drawn per block or as one stream, frame by frame in turn (the
    order alternating), one process."""
    import twinsense.tof.camera as camera
    from twinsense.demos.robot_cell import build_arm_cell

    scene, sensors = build_arm_cell()
    cam = sensors[2]
    times = [0.9 + k / 30.0 for k in range(frames + 3)]
    one_stream = camera.draw_noise_slabs
    ways = {"per block of 8 rows (before)": _per_block_slabs, "one stream (now)": one_stream}
    wall: dict = {w: [] for w in ways}
    cpu: dict = {w: [] for w in ways}
    try:
        for k in range(frames + 3):
            for way in (list(ways) if k % 2 else list(ways)[::-1]):
                camera.draw_noise_slabs = ways[way]
                c0, t0 = time.process_time(), time.perf_counter()
                # Each way at its own time (10 us apart): a pose seen before would reuse its rays
                # and keep their static hits (a fixed camera's path).
                cam.capture(scene, times[k] + 1e-5 * list(ways).index(way), np.random.default_rng(k))
                if k >= 3:  # the first three untimed
                    wall[way].append(time.perf_counter() - t0)
                    cpu[way].append(time.process_time() - c0)
    finally:
        camera.draw_noise_slabs = one_stream
    print(f"\n== robot cell, wrist ToF: the noise draw's ways, {frames} frames each in turn")
    for way in ways:
        print(f"  {way:<30s} wall {np.median(wall[way]) * 1e3:6.2f} ms median (best {min(wall[way]) * 1e3:6.2f}), "
              f"process CPU {np.median(cpu[way]) * 1e3:6.2f} ms")


def _numpy_normals_slabs(cfg, seeds, out=None):
    """The noise draw before the compiled ziggurat: NumPy's standard_normal on the same SFC64 stream, one
    fill. Other bytes than draw_noise_slabs; for timing."""
    from twinsense.tof.pipeline import noise_size

    out = np.empty(noise_size(cfg), np.float32) if out is None else out
    used = 9 * cfg.height * cfg.width
    np.random.Generator(np.random.SFC64(int(seeds[0]))).standard_normal(dtype=np.float32, out=out[:used])
    return out


def wrist_ways(frames: int) -> None:
    """Whole wrist captures in four ways, frame by frame in turn (the order rotating), one process: the
    chain after the whole cast or per chunk of the cast, NumPy's normals or the compiled ziggurat. Per
    way the median wall and process CPU, and each way's CPU less the current way's, paired by frame."""
    import twinsense.tof.camera as camera
    from twinsense.demos.robot_cell import build_arm_cell

    scene, sensors = build_arm_cell()
    cam = sensors[2]
    times = [0.9 + k / 30.0 for k in range(frames + 3)]
    fed, draw = camera._FedChain, camera.draw_noise_slabs
    ways = {"chain after the cast, NumPy normals (before)": (lambda *a: None, _numpy_normals_slabs),
            "chain after the cast, compiled normals": (lambda *a: None, draw),
            "chain per chunk, NumPy normals": (fed, _numpy_normals_slabs),
            "chain per chunk, compiled normals (now)": (fed, draw)}
    names = list(ways)
    wall: dict = {w: [] for w in ways}
    cpu: dict = {w: [] for w in ways}
    try:
        for k in range(frames + 3):
            order = names[k % 4:] + names[:k % 4]
            for way in order:
                camera._FedChain, camera.draw_noise_slabs = ways[way]
                c0, t0 = time.process_time(), time.perf_counter()
                # Each way at its own time (10 us apart): a pose seen before would reuse its rays.
                cam.capture(scene, times[k] + 1e-5 * names.index(way), np.random.default_rng(k))
                if k >= 3:  # the first three untimed
                    wall[way].append(time.perf_counter() - t0)
                    cpu[way].append(time.process_time() - c0)
    finally:
        camera._FedChain, camera.draw_noise_slabs = fed, draw
    now = names[-1]
    print(f"\n== robot cell, wrist ToF: the chain per chunk and the compiled normals, {frames} frames each in turn")
    for way in ways:
        d = np.subtract(cpu[way], cpu[now])
        print(f"  {way:<46s} wall {np.median(wall[way]) * 1e3:6.2f} ms median (best {min(wall[way]) * 1e3:6.2f}), "
              f"process CPU {np.median(cpu[way]) * 1e3:6.2f} ms; CPU - now's, paired: {np.median(d) * 1e3:5.2f} ms "
              f"(quartiles {np.percentile(d, 25) * 1e3:.2f} to {np.percentile(d, 75) * 1e3:.2f})")


def wrist_phasor_ways(frames: int) -> None:
    """Whole wrist captures with the phasors made per chunk of the cast (now) or after the whole cast
    (before: the cast, then hits_to_phasors in bands), frame by frame in turn, one process."""
    from twinsense.demos.robot_cell import build_arm_cell
    from twinsense.render.parallel import default_workers
    from twinsense.tof.kernels import hits_to_phasors
    from twinsense.tof.rendering import material_table

    scene, sensors = build_arm_cell()
    now = sensors[2]
    before = ToFCamera(now.config, now.mount, "wrist_tof_before")
    r = before._renderer

    def after_the_cast(scene, rotation, position, t):
        hits = r.hits(scene, rotation, position, t)
        return PixelPhasors(*hits_to_phasors(hits.distance, hits.cos_incidence, hits.object_id,
                                             material_table(scene), r.config, r.radiometry, default_workers(),
                                             r._scratch))

    r.phasors = after_the_cast
    ways = {"after the whole cast (before)": before, "per chunk of the cast (now)": now}
    times = [0.9 + k / 30.0 for k in range(frames + 3)]
    wall: dict = {w: [] for w in ways}
    cpu: dict = {w: [] for w in ways}
    for k in range(frames + 3):
        for j, way in enumerate(list(ways) if k % 2 else list(ways)[::-1]):
            c0, t0 = time.process_time(), time.perf_counter()
            ways[way].capture(scene, times[k] + 1e-5 * j, np.random.default_rng(k))
            if k >= 3:
                wall[way].append(time.perf_counter() - t0)
                cpu[way].append(time.process_time() - c0)
    print(f"\n== robot cell, wrist ToF: the phasors after the cast or per chunk, {frames} frames each in turn")
    for way in ways:
        print(f"  {way:<32s} wall {np.median(wall[way]) * 1e3:6.2f} ms median (best {min(wall[way]) * 1e3:6.2f}), "
              f"process CPU {np.median(cpu[way]) * 1e3:6.2f} ms")


def wrist_child(frames: int) -> None:
    """One child of ``--before``: ``frames`` wrist captures after 3 untimed ones; prints one JSON line."""
    import json
    import os

    import twinsense
    from twinsense.demos.robot_cell import build_arm_cell

    scene, sensors = build_arm_cell()
    cam = sensors[2]
    times = [0.9 + k / 30.0 for k in range(frames + 3)]
    rng = np.random.default_rng(0)
    for k in range(3):
        cam.capture(scene, times[k], rng)
    wall, cpu = [], []
    for k in range(frames):
        c0, t0 = time.process_time(), time.perf_counter()
        cam.capture(scene, times[k + 3], rng)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    pose = cam.mount.pose_at(scene, times[3])
    rays = cam._renderer.rays(pose.rotation, pose.position)
    _, anchor = embree_anchor(scene, "tof", times[3], rays.origins, rays.directions, repeats=9)
    print(json.dumps({"package": os.path.dirname(twinsense.__file__), "wall": wall, "cpu": cpu,
                      "anchor": anchor, "load": os.getloadavg()[0]}))


def before_after(before_src: str, frames: int, rounds: int) -> None:
    """The wrist camera with the package at ``before_src`` and with this one, in child processes in turn."""
    import json
    import os
    import subprocess
    import sys

    here = os.path.abspath(__file__)
    env_of = {"before": {**os.environ, "PYTHONPATH": os.path.abspath(before_src)},
              "after": {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}}

    def child(way: str, n: int) -> dict:
        out = subprocess.run([sys.executable, here, "--wrist-child", "--frames", str(n)], env=env_of[way],
                             check=True, capture_output=True, text=True).stdout
        return json.loads(out.strip().splitlines()[-1])

    for way in env_of:  # untimed: compiled kernels built or loaded, files cached
        print(f"  {way}: {child(way, 2)['package']}")
    got: dict = {way: {"wall": [], "cpu": [], "anchor": [], "load": []} for way in env_of}
    for r in range(rounds):
        for way in (list(env_of) if r % 2 == 0 else list(env_of)[::-1]):
            res = child(way, frames)
            for key in ("wall", "cpu"):
                got[way][key] += res[key]
            got[way]["anchor"].append(res["anchor"])
            got[way]["load"].append(res["load"])
    print(f"\n== robot cell, wrist ToF pmd_pico_flexx on the moving UR5e (153,216 rays): {rounds} rounds of "
          f"{frames} frames per way, in child processes taking turns")
    for way, g in got.items():
        med = float(np.median(g["wall"]))
        anchor = float(np.median(g["anchor"]))
        print(f"  {way:<7s} wall {med * 1e3:6.1f} ms median (best {min(g['wall']) * 1e3:5.1f}) -> {1 / med:5.1f} "
              f"frames/s; process CPU {np.median(g['cpu']) * 1e3:5.1f} ms/frame; anchor {anchor * 1e3:5.1f} ms, "
              f"wall / anchor {med / anchor:4.2f}; load {min(g['load']):.1f}-{max(g['load']):.1f}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--wrist-chain", action="store_true", help="only the robot cell's wrist camera chain case")
    ap.add_argument("--wrist-stages", action="store_true", help="only where a wrist frame's wall time goes")
    ap.add_argument("--wrist-noise", action="store_true", help="only the wrist frame with the noise draw's ways")
    ap.add_argument("--wrist-phasors", action="store_true", help="only the wrist frame, phasors per chunk or after")
    ap.add_argument("--wrist-ways", action="store_true",
                    help="only the wrist frame: chain per chunk or after the cast, compiled or NumPy normals")
    ap.add_argument("--before", metavar="SRC", help="the wrist camera with the package at SRC and with this one")
    ap.add_argument("--rounds", type=int, default=6, help="child processes per way with --before")
    ap.add_argument("--wrist-child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--frames", type=int, default=40)
    args = ap.parse_args()
    if args.wrist_child:
        wrist_child(args.frames)
    elif args.before:
        print_machine()
        before_after(args.before, args.frames, args.rounds)
        print_load_at_end()
    elif args.wrist_chain or args.wrist_stages or args.wrist_noise or args.wrist_phasors or args.wrist_ways:
        print_machine()
        if args.wrist_ways:
            wrist_ways(args.frames)
        if args.wrist_phasors:
            wrist_phasor_ways(args.frames)
        if args.wrist_noise:
            wrist_noise_ways(args.frames)
        if args.wrist_chain:
            wrist_chain(args.frames)
        if args.wrist_stages:
            wrist_stages(args.frames)
        print_load_at_end()
    else:
        main()
