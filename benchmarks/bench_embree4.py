"""Embree 4 instancing against the per-object cast: old and new in one run, in turn.

Backend "embree" casts a moving sensor's rays through one instanced Embree 4
scene (the static objects' scene and one scene per moving object, posed per
frame), packets of 8 rays from a compiled loop; backend "embreex" is the
per-object path it replaced (static BVH, then per moving object a cull, a
cast in its frame and a merge). Cases:

- robot cell (``build_arm_cell``: UR5e and a walking person):
  the wrist ToF camera (``pmd_pico_flexx``, 2 x 2 sub-pixels, 153,216 rays)
  on the moving arm: whole frames and the cast alone; the wrist radar's render
  (``paper_bgt60tr13c``, 1000 x 342 rays) cast alone; the fixed wall ToF
  camera (its static hits kept, movers traced one by one) against the
  instanced cast of all its rays;
- office (84k triangles, a walking person): ``pmd_pico_flexx`` moving a little
  every frame (every ray new) and fixed (static hits kept).

Every line is old and new run in turn, ``--rounds`` times each (a change of
the machine's load reaches both alike): best and median wall time, median
process CPU time (every thread). Also ``rtcIntersect1`` against
``rtcIntersect8`` in the same compiled loop (thread CPU time, one thread),
and the same-run anchor: a bare single-thread embreex cast of the same rays
against the whole scene posed at one time, one world-space BVH.

``--packets`` runs only the wrist camera's traversal variants, one thread, thread
CPU time, in turn: packets of 4, 8 and 16 rays (``rtcIntersect4/8/16``) along
image rows or as 2 x 4, 4 x 2 and 4 x 4 tiles of neighbouring sub-pixels,
``RTCIntersectArguments`` with ``RTC_RAY_QUERY_FLAG_COHERENT`` or
``INCOHERENT`` against none, the compiled loop alone (a no-op in place of
Embree: filling and reading the packets), the static scene alone (no
instances) at low, medium and high build quality, and the cost of one
``rtcIntersect8`` call with 0, 1 and 8 active lanes on a far triangle.

Run:  .venv/bin/python benchmarks/bench_embree4.py [--rounds N] [--packets]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _timing import alternating, embree_anchor, print_anchor, print_load_at_end, print_machine
from _timing import in_turn as cycled

from twinsense.compiled import jit
from twinsense.demos.office import SENSOR_EYE, SENSOR_TARGET, build_office_scene, sensor_pose
from twinsense.demos.robot_cell import ROBOT, build_arm_cell
from twinsense.radar import FMCWRadar
from twinsense.render import caster_for, embree4
from twinsense.render.caster import _CACHE, SceneCaster
from twinsense.render.embree4 import F_GEOM, F_INST, F_MASK, F_PRIM, F_TFAR, RAY8_WORDS
from twinsense.render.embree4_kernels import _INVALID, _aligned, _load_ray, call4, trace
from twinsense.render.rays import PinholeCamera, Rays
from twinsense.scene import Mount, Pose
from twinsense.tof import ToFCamera
from twinsense.tof.rendering import DIRECT_FIELDS


def in_turn(variants: dict, rounds: int) -> dict:
    """{label: (best wall, median wall, median process CPU) [s]} of callables fn(k): one
    untimed call fn(0) each, then k = 1..rounds with the variants in turn
    (:func:`_timing.alternating`)."""
    return alternating({label: cycled(lambda k, fn=fn: fn(k - 1), rounds + 1) for label, fn in variants.items()},
                       rounds)


def report(title: str, results: dict, anchor: float) -> None:
    print(f"  {title}")
    for label, (best, med, cpu) in results.items():
        print(f"    {label:<44s} {best * 1e3:7.1f} ms best {med * 1e3:7.1f} ms median "
              f"-> {1 / med:6.1f} /s; CPU {cpu * 1e3:7.1f} ms (median)")
    print_anchor("bare embreex cast, same rays", anchor, results[next(reversed(results))][1])


def swap(scene, kind: str, caster: SceneCaster) -> None:
    """Make ``caster`` the one sensors of ``kind`` use on ``scene`` (backend "embree")."""
    _CACHE.setdefault(scene, {})[(kind, "embree")] = caster


def old_new(scene, kind: str):
    new = caster_for(scene, kind)
    old = SceneCaster(scene, kind, "embreex")
    assert new._instanced is not None
    return old, new


def packets(caster: SceneCaster, rays: Rays, t: float, reps: int) -> None:
    """rtcIntersect1 against rtcIntersect8 in the same compiled loop through the posed
    instanced scene: thread CPU time, medians over ``reps`` alternating calls."""
    inst = caster._instanced
    states = caster._states(t)
    st = [states[i] for i in caster._moving]
    m = len(st)
    tr = np.zeros((len(inst._scenes), 3, 4))
    tr[0, :, :3] = np.eye(3)
    tr[1:, :, :3] = np.array([s.pose.rotation for s in st]).reshape(m, 3, 3)
    tr[1:, :, 3] = np.array([s.pose.position for s in st]).reshape(m, 3)
    top = inst._acquire(tr)
    o, d = rays.origins, rays.directions
    n = len(d)
    prim, hit = np.empty(n, np.int32), np.empty(n, np.int32)
    spent: dict = {1: [], 8: []}
    for _ in range(reps):
        for p in (1, 8):
            c0 = time.thread_time()
            trace(inst._fn1, inst._fn8, p == 8, top.handle, o, d, prim, hit)
            spent[p].append(time.thread_time() - c0)
    inst._release(top)
    r1, r8 = np.median(spent[1]), np.median(spent[8])
    print(f"    Embree traversal alone, one thread: rtcIntersect1 {r1 * 1e3:.1f} ms, rtcIntersect8 "
          f"{r8 * 1e3:.1f} ms CPU ({n / r8 / 1e6:.1f} Mrays/s with packets; device packet8 = "
          f"{inst.device.packet8})")


@jit
def _trace_lanes(fn, lanes, scene, o, d, prim, inst, args, order):  # pragma: no cover
    """embree4_kernels.trace's packet loop for ``lanes`` = 4, 8 or 16 rays per call
    (``rtcIntersect4/8/16`` at ``fn``), rays taken in the order ``order`` (n,) (a
    permutation: tiles of sub-pixels), ``args``: the address of an RTCIntersectArguments
    or 0. For timing only: the rays are all finite here."""
    n = d.shape[0]
    b, bu, bi = _aligned(RAY8_WORDS + 16)  # 64-byte aligned: the valid mask at word RAY8_WORDS
    for j in range(lanes):
        bu[lanes * F_MASK + j] = _INVALID
    bp = b.ctypes.data
    vp = bp + 4 * RAY8_WORDS
    for s in range(0, n, lanes):
        for j in range(lanes):
            _load_ray(b, bu, j, lanes, o, d, order[min(s + j, n - 1)])
            bi[RAY8_WORDS + j] = -1 if s + j < n else 0
        call4(fn, vp, scene, bp, args)
        for j in range(min(lanes, n - s)):
            i = order[s + j]
            g = bu[lanes * F_GEOM + j]
            if g == _INVALID:
                prim[i] = -1
                inst[i] = -1
            else:
                prim[i] = bu[lanes * F_PRIM + j]
                k = bu[lanes * F_INST + j]
                inst[i] = g if k == _INVALID else k


@jit
def _calls(fn, scene, n, active, d):  # pragma: no cover
    """``n`` rtcIntersect8 calls on one packet of the ray (0, 0, 0) + t d (1, 3) in ``active`` lanes."""
    b, bu, bi = _aligned(RAY8_WORDS + 8)
    for j in range(8):
        bu[8 * F_MASK + j] = _INVALID
        _load_ray(b, bu, j, 8, np.zeros((1, 3)), d, 0)
        bi[RAY8_WORDS + j] = -1 if j < active else 0
    bp = b.ctypes.data
    for _ in range(n):
        for j in range(8):
            b[8 * F_TFAR + j] = np.inf
        call4(fn, bp + 4 * RAY8_WORDS, scene, bp, 0)


def tiles(height: int, width: int, th: int, tw: int) -> np.ndarray:
    """The ray order (n,) int64 of an image (height, width) of row-major rays in tiles of th x tw
    (partial tiles at the right and bottom edges), tile after tile along rows of tiles."""
    idx = np.arange(height * width).reshape(height, width)
    hp, wp = -(-height // th) * th, -(-width // tw) * tw
    pad = np.full((hp, wp), -1)
    pad[:height, :width] = idx
    order = pad.reshape(hp // th, th, wp // tw, tw).transpose(0, 2, 1, 3).reshape(-1)
    return order[order >= 0].astype(np.int64)


def packet_variants(rounds: int) -> None:
    """The wrist camera's rays through the posed instanced scene, one thread, the variants in turn."""
    import ctypes

    import numba
    from numba import types

    scene, sensors = build_arm_cell()
    cam = sensors[2]
    cfg = cam.config
    cam.capture(scene, 0.9, np.random.default_rng(0))
    caster = caster_for(scene, "tof")
    inst = caster._instanced
    t = 1.0
    pose = cam.mount.pose_at(scene, t)
    rays = cam._renderer.rays(pose.rotation, pose.position)
    o, d = rays.origins, rays.directions
    n = len(d)
    hn, wn = cfg.height * cfg.supersample, cfg.width * cfg.supersample
    states = caster._states(t)
    st = [states[i] for i in caster._moving]
    tr = np.zeros((len(inst._scenes), 3, 4))
    tr[0, :, :3] = np.eye(3)
    tr[1:, :, :3] = [s.pose.rotation for s in st]
    tr[1:, :, 3] = [s.pose.position for s in st]
    top = inst._acquire(tr)
    lib = ctypes.CDLL(embree4.library().path)
    fn = {k: ctypes.cast(getattr(lib, f"rtcIntersect{k}"), ctypes.c_void_p).value for k in (4, 8, 16)}

    @numba.cfunc(types.void(types.uint64, types.uint64, types.uint64, types.uint64))
    def noop(a, b, c, e):  # pragma: no cover
        pass

    def arguments(flags: int) -> np.ndarray:
        # RTCIntersectArguments (rtcore.h): flags, feature_mask (uint32 each), then the context,
        # filter and intersect pointers (NULL: Embree's defaults), 64 bytes with room to spare.
        a = np.zeros(8, np.uint64)
        a.view(np.uint32)[:2] = flags, 0xFFFFFFFF
        return a

    coherent, incoherent = arguments(1), arguments(0)
    rows = np.arange(n, dtype=np.int64)
    prim, hit = np.empty(n, np.int32), np.empty(n, np.int32)
    h = top.handle
    dev = embree4.device()
    static = {q: embree4.TriangleScene(dev, v, f, q) for q, (v, f) in
              [(q, _static_mesh(scene)) for q in (embree4.RTC_BUILD_QUALITY_LOW, embree4.RTC_BUILD_QUALITY_MEDIUM,
                                                 embree4.RTC_BUILD_QUALITY_HIGH)]}

    def run(f, lanes, handle, order, args=0):
        return lambda: _trace_lanes(f, lanes, handle, o, d, prim, hit, args, order)

    variants = {
        "kernels.trace as used (8 along rows, no arguments)":
            lambda: trace(inst._fn1, inst._fn8, True, h, o, d, prim, hit),
        "rtcIntersect4, along rows": run(fn[4], 4, h, rows),
        "rtcIntersect8, along rows": run(fn[8], 8, h, rows),
        "rtcIntersect16, along rows": run(fn[16], 16, h, rows),
        "rtcIntersect8, 2 x 4 tiles": run(fn[8], 8, h, tiles(hn, wn, 2, 4)),
        "rtcIntersect8, 4 x 2 tiles": run(fn[8], 8, h, tiles(hn, wn, 4, 2)),
        "rtcIntersect16, 4 x 4 tiles": run(fn[16], 16, h, tiles(hn, wn, 4, 4)),
        "rtcIntersect8, rows, COHERENT": run(fn[8], 8, h, rows, coherent.ctypes.data),
        "rtcIntersect8, rows, INCOHERENT": run(fn[8], 8, h, rows, incoherent.ctypes.data),
        "rtcIntersect8, 2 x 4 tiles, COHERENT": run(fn[8], 8, h, tiles(hn, wn, 2, 4), coherent.ctypes.data),
        "the loop alone (no-op in place of Embree)": run(noop.address, 8, h, rows),
        "static scene alone, build quality low": run(fn[8], 8, static[0].handle, rows),
        "static scene alone, build quality medium": run(fn[8], 8, static[1].handle, rows),
        "static scene alone, build quality high": run(fn[8], 8, static[2].handle, rows),
    }
    want = None
    for label, f in variants.items():
        f()
        if "Embree" in label.split("(")[0] or label.startswith(("kernels", "rtc")):
            got = (prim.copy(), hit.copy())
            if want is None:
                want = got
            elif not (np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])):
                print(f"    !! {label}: other hits than kernels.trace")
    spent: dict = {label: [] for label in variants}
    for _ in range(rounds):
        for label, f in variants.items():
            c0 = time.thread_time()
            f()
            spent[label].append(time.thread_time() - c0)
    inst._release(top)
    print(f"\n== wrist ToF rays ({n}) through the robot cell's instanced scene, one thread, {rounds} rounds in turn")
    for label, v in spent.items():
        print(f"  {label:<52s} CPU {np.median(v) * 1e3:6.2f} ms median ({min(v) * 1e3:6.2f} best), "
              f"{np.median(v) / n * 1e9:5.1f} ns per ray")
    far = embree4.TriangleScene(dev, np.array([[100.0, 100, 100], [101, 100, 100], [100, 101, 100]]),
                                np.array([[0, 1, 2]]))
    calls = 20000
    for active in (0, 1, 8):
        _calls(fn[8], far.handle, 10, active, np.array([[0.1, 0.2, 1.0]]))
        ts = []
        for _ in range(7):
            c0 = time.thread_time()
            _calls(fn[8], far.handle, calls, active, np.array([[0.1, 0.2, 1.0]]))
            ts.append(time.thread_time() - c0)
        print(f"  one rtcIntersect8 call missing a far triangle, {active} active lanes: "
              f"{np.median(ts) / calls * 1e9:5.0f} ns")


def _static_mesh(scene) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3), faces (m, 3)) of the scene's static objects in the world, one mesh."""
    verts, faces, off = [], [], 0
    for obj in scene.objects:
        if obj.is_static:
            m = obj.geometry.mesh
            verts.append(obj.pose_at(0.0).apply(np.asarray(m.vertices, float)))
            faces.append(np.asarray(m.faces) + off)
            off += len(m.vertices)
    return np.concatenate(verts), np.concatenate(faces)


def robot_cell(rounds: int) -> None:
    scene, sensors = build_arm_cell()
    n_tri = sum(len(o.geometry.mesh.faces) for o in scene.objects)
    moving = sum(not o.is_static for o in scene.objects)
    print(f"\n== robot cell: {n_tri} triangles, {moving} moving objects (UR5e links, person)")
    wall_tof, wrist = sensors[0], sensors[2]
    times = [0.9 + k / 30.0 for k in range(rounds + 2)]
    pose = wrist.mount.pose_at(scene, times[1])
    rays = wrist._renderer.rays(pose.rotation, pose.position)
    _, anchor = embree_anchor(scene, "tof", times[1], rays.origins, rays.directions, repeats=9)
    old, new = old_new(scene, "tof")
    rng = np.random.default_rng(0)

    def frame(caster, shift):
        # Each variant at its own times (half a frame apart): a pose the camera has seen
        # before would take its fixed-pose path (static hits kept) instead.
        def run(k):
            swap(scene, "tof", caster)
            wrist.capture(scene, times[k] + shift, rng)
        return run

    report(f"wrist ToF frame ({len(rays.directions)} rays, moving with the arm)",
           in_turn({"old (embreex, per object)": frame(old, 0.0),
                    "new (Embree 4, instanced)": frame(new, 1 / 60)}, rounds), anchor)
    swap(scene, "tof", new)

    def cast_only(caster):
        def run(k):
            p = wrist.mount.pose_at(scene, times[k])
            r = wrist._renderer.rays(p.rotation, p.position)
            caster.cast(Rays(r.origins, np.array(r.directions)), times[k], DIRECT_FIELDS)
        return run

    report("wrist ToF cast alone (distance, cos_incidence, object_id)",
           in_turn({"old (embreex, per object)": cast_only(old), "new (Embree 4, instanced)": cast_only(new)},
                   rounds), anchor)
    packets(new, rays, times[1], max(5, rounds))

    # The fixed wall camera: static hits kept (memo) and movers traced one by one,
    # against tracing all its rays through the instanced scene (writable rays: no memo).
    wpose = wall_tof.mount.pose_at(scene, 0.0)
    wrays = wall_tof._renderer.rays(wpose.rotation, wpose.position)
    _, wanchor = embree_anchor(scene, "tof", times[1], wrays.origins, wrays.directions, repeats=9)
    fresh = Rays(wrays.origins, np.array(wrays.directions))
    report("wall ToF cast (fixed camera)",
           in_turn({"old (embreex): static kept, movers": lambda k: old.cast(wrays, times[k], DIRECT_FIELDS),
                    "Embree 4: static kept, movers": lambda k: new.cast(wrays, times[k], DIRECT_FIELDS),
                    "Embree 4 instanced, every ray": lambda k: new.cast(fresh, times[k], DIRECT_FIELDS)},
                   rounds), wanchor)

    radar = FMCWRadar.preset("paper_bgt60tr13c", name="wrist_radar",
                             mount=Mount(Pose((0.06, 0.0, 0.02)), parent=f"{ROBOT}/tool0"))
    cfg = radar.config
    cam = PinholeCamera.from_fov(cfg.render_width, cfg.render_height, cfg.hfov_deg, cfg.vfov_deg)
    rpose = radar.mount.pose_at(scene, times[1])
    r = cam.rays(rpose)
    _, ranchor = embree_anchor(scene, "radar", times[1], r.origins, r.directions, repeats=9)
    rold, rnew = old_new(scene, "radar")
    fields = ("distance", "cos_incidence", "material_id", "object_id", "velocity")

    def radar_cast(caster):
        def run(k):
            rr = cam.rays(radar.mount.pose_at(scene, times[k]))
            caster.cast(rr, times[k], fields)
        return run

    report(f"wrist radar render cast ({cfg.render_width} x {cfg.render_height} rays, moving)",
           in_turn({"old (embreex, per object)": radar_cast(rold), "new (Embree 4, instanced)": radar_cast(rnew)},
                   rounds), ranchor)


def office(rounds: int) -> None:
    scene = build_office_scene(detail=6, person=True)
    print(f"\n== office, {sum(len(o.geometry.mesh.faces) for o in scene.objects)} triangles, walking person")
    cam = ToFCamera.preset("pmd_pico_flexx", mount=sensor_pose())
    pose0 = sensor_pose()
    rays = cam._renderer.rays(pose0.rotation, pose0.position)
    _, anchor = embree_anchor(scene, "tof", 1.5, rays.origins, rays.directions, repeats=9)
    old, new = old_new(scene, "tof")
    rng = np.random.default_rng(0)

    def moving(caster, shift):
        def run(k):  # each variant at its own poses (see robot_cell)
            swap(scene, "tof", caster)
            cam.mount = Mount(Pose.look_at(SENSOR_EYE, np.add(SENSOR_TARGET, (0.0, 1e-3 * (k + shift), 0.0))))
            cam.capture(scene, 1.0 + (k + shift) / 45.0, rng)
        return run

    report("ToF pmd_pico_flexx frame, camera moving every frame",
           in_turn({"old (embreex, per object)": moving(old, 0.0), "new (Embree 4, instanced)": moving(new, 0.5)},
                   rounds), anchor)

    def fixed(caster):
        def run(k):
            swap(scene, "tof", caster)
            cam.mount = Mount(sensor_pose())
            cam.capture(scene, 1.0 + k / 45.0, rng)
        return run

    report("ToF pmd_pico_flexx frame, fixed camera (static hits kept)",
           in_turn({"old (embreex)": fixed(old), "new (Embree 4 scenes)": fixed(new)}, rounds), anchor)
    swap(scene, "tof", new)
    fresh = Rays(rays.origins, np.array(rays.directions))
    report("ToF pmd_pico_flexx cast, fixed camera",
           in_turn({"old (embreex): static kept, movers": lambda k: old.cast(rays, 1.0 + k / 45.0, DIRECT_FIELDS),
                    "Embree 4: static kept, movers": lambda k: new.cast(rays, 1.0 + k / 45.0, DIRECT_FIELDS),
                    "Embree 4 instanced, every ray": lambda k: new.cast(fresh, 1.0 + k / 45.0, DIRECT_FIELDS)},
                   rounds), anchor)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line; ``--rounds`` below 1 exits with status 2 before any scene is built."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=12, help="frames of each variant, in turn (>= 1)")
    ap.add_argument("--packets", action="store_true", help="only the wrist camera's traversal variants")
    args = ap.parse_args(argv)
    if args.rounds < 1:
        # Zero rounds leaves nothing to take a median of: refuse it here, not after the build.
        ap.error(f"--rounds = {args.rounds} is invalid: expected an integer >= 1")
    return args


def main() -> None:
    args = parse_args()
    print_machine()
    if args.packets:
        packet_variants(args.rounds)
        print_load_at_end()
        return
    robot_cell(args.rounds)
    office(args.rounds)
    print_load_at_end()


if __name__ == "__main__":
    main()
