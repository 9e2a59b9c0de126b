"""The single-origin bundle picker (render/bundle.py) against Embree's traversal.

For the robot cell (UR5e on its pick-and-place trajectory, the person walking;
every frame at a new time, so every moving object moves):

- the wrist ToF camera's rays (``pmd_pico_flexx``, 2 x 2 rays per pixel:
  153,216 rays from the moving flange) and the flange radar's
  (``paper_bgt60tr13c``, 1000 x 342 = 342,000 rays): the pick alone, the bundle
  picker (``BundlePicker.pick``) against Embree's traversal of the same
  instanced scene (``trace`` per chunk of 16,384 rays, on the same workers),
  alternating in one run, wall and process CPU, 1 and 2 workers; the bundle
  picker both ways: the world rays binned every pick, and the sensor's fixed
  local bundle (``Rays.local``: binned once, each pick moving only the
  triangles into the sensor's frame); with ``--before-picker SRC`` also the
  picker of another checkout's ``src`` (``git archive <commit> src | tar -x
  -C DIR``; its ``render/bundle.py`` and ``bundle_kernels.py`` loaded beside
  this package's), in the same turns; then the
  whole cast (every Hits field) with either picker;
- the whole wrist ToF frame (``tof.capture``) and the whole radar frame
  (``radar.capture``) with either picker, alternating;
- the picker's settings: rays per cell (16, 32, 64) and the early exit on/off;
  the UR5e's visual meshes (121,783 triangles) against its collision meshes;

and for the office scene of bench_render.py (1000 x 342 rays, >= 50k
triangles, a walking person): the pick and the whole cast with either picker.

Same-run anchor: a bare single-thread embreex cast of the same rays against
the scene posed at that time (one world-space BVH built beforehand), as in
the other benchmarks.

Run:  .venv/bin/python benchmarks/bench_bundle.py [--rounds N] [--before-picker SRC] [--picks-only]
"""

from __future__ import annotations

import argparse
import importlib.util
import shutil
import sys
import tempfile
import types
from concurrent.futures import wait
from pathlib import Path

import numpy as np
from _cell import flange_radar, radar_rays
from _timing import alternating, embree_anchor, in_turn, print_load_at_end, print_machine

from twinsense.demos.office import build_office_scene, sensor_pose
from twinsense.demos.robot_cell import ROBOT, build_arm_cell_scene, build_arm_cell_sensors
from twinsense.render import PinholeCamera, Rays, caster_for
from twinsense.render.embree4_kernels import trace
from twinsense.render.parallel import pool

T0 = 0.9  # [s] as bench_robot_cell.py: the arm between pick and lift, the person walking in
CHUNK = 16384  # rays per Embree task, as the caster's


def posed(caster, t):
    """(rots (m, 3, 3), poss (m, 3), the instanced scene's transforms) of the movers at t."""
    st = caster._states(t)
    rots = np.array([st[i].pose.rotation for i in caster._moving])
    poss = np.array([st[i].pose.position for i in caster._moving])
    ins = caster._instanced
    tr = np.zeros((len(ins._scenes), 3, 4))
    first = 1 if ins._has_static else 0
    if first:
        tr[0, :, :3] = np.eye(3)
    tr[first:, :, :3] = rots
    tr[first:, :, 3] = poss
    return rots, poss, tr


def embree_pick(caster, rays, t, workers):
    """Embree's picks of every ray (as InstancedScene.cast: chunks on the workers)."""
    ins = caster._instanced
    _, _, tr = posed(caster, t)
    top = ins._acquire(tr)
    o, d = rays.origins, rays.directions
    n = len(d)
    inst, prim = np.empty(n, np.int32), np.empty(n, np.int32)

    def run(lo):
        hi = min(lo + CHUNK, n)
        trace(ins._fn1, ins._fn8, ins.packet == 8, top.handle, o[lo:hi], d[lo:hi], prim[lo:hi], inst[lo:hi])

    try:
        if workers > 1:
            wait([pool(workers).submit(run, lo) for lo in range(0, n, CHUNK)])
        else:
            for lo in range(0, n, CHUNK):
                run(lo)
    finally:
        ins._release(top)
    return inst, prim


def bundle_pick(caster, rays, t, workers, picker=None, **kw):
    rots, poss, _ = posed(caster, t)
    picker = caster._instanced.bundle_picker() if picker is None else picker
    return picker.pick(rays.origins[0], rays.directions, rots, poss, workers, **kw)


def before_picker_class(src: str):
    """The BundlePicker class of another checkout's ``src`` (its bundle.py with its own kernels)."""
    # Copies in a directory of their own: numba's disk cache is kept per source file, and
    # the other checkout's own (its module names) must not meet these.
    root = Path(tempfile.mkdtemp(prefix="before_picker_"))
    for f in ("bundle.py", "bundle_kernels.py"):
        shutil.copy(Path(src) / "twinsense" / "render" / f, root / f)
    name = "twinsense.render._before_bundle_kernels"
    spec = importlib.util.spec_from_file_location(name, root / "bundle_kernels.py")
    kernels = importlib.util.module_from_spec(spec)
    sys.modules[name] = kernels
    spec.loader.exec_module(kernels)
    text = (root / "bundle.py").read_text()
    text = text.replace("from twinsense.render import bundle_kernels as bk", f"import {name} as bk")
    mod = types.ModuleType("twinsense.render._before_bundle")
    sys.modules[mod.__name__] = mod
    exec(compile(text, str(root / "bundle.py"), "exec"), mod.__dict__)
    return mod.BundlePicker


def picker_like(cls, instanced):
    """A ``cls`` picker over the instanced scene's triangles (as InstancedScene.bundle_picker builds it)."""
    static = None
    if instanced._static_meshes is not None:
        meshes = instanced._static_meshes
        base = np.cumsum([0] + [len(v) for v, _ in meshes[:-1]])
        static = (np.concatenate([v for v, _ in meshes]),
                  np.concatenate([f + b for (_, f), b in zip(meshes, base, strict=True)]))
    return cls(static, instanced._mover_meshes)


def line(label, res, anchor=None):
    best, med, cpu = res
    extra = f"; / anchor {med / anchor:5.2f}" if anchor else ""
    print(f"  {label:<58s} {best * 1e3:7.1f} ms best {med * 1e3:7.1f} ms median, CPU {cpu * 1e3:7.1f} ms{extra}")


def compare_picks(scene, kind, rays_at, times, rounds, anchor, before=None, picks_only=False):
    """The pick alone and the whole cast, both pickers, 1 and 2 workers, alternating."""
    caster = caster_for(scene, kind)
    bundles = [rays_at(t) for t in times]
    k = len(times) - 1
    old = None if before is None else picker_like(before, caster._instanced)
    for w in (1, 2):
        variants = {
            f"pick, Embree traversal, {w} worker(s)":
                in_turn(lambda i, w=w: embree_pick(caster, bundles[i], times[i], w), k),
            f"pick, bundle picker, world rays binned every pick, {w} worker(s)":
                in_turn(lambda i, w=w: bundle_pick(caster, bundles[i], times[i], w), k),
        }
        if bundles[0].local is not None:
            variants[f"pick, bundle picker, local bundle binned once, {w} worker(s)"] = in_turn(
                lambda i, w=w: bundle_pick(caster, bundles[i], times[i], w, local=bundles[i].local), k)
        if old is not None:
            variants[f"pick, bundle picker of --before-picker, {w} worker(s)"] = in_turn(
                lambda i, w=w: bundle_pick(caster, bundles[i], times[i], w, picker=old), k)
        for label, res in alternating(variants, rounds).items():
            line(label, res, anchor)
    if picks_only:
        return

    # Writable copies, one set per picker: a read-only bundle cast a second time would take the
    # fixed sensor's path (its static hits kept), not the moving sensor's.
    copies = {p: [Rays(b.origins, np.array(b.directions), local=b.local) for b in bundles]
              for p in ("embree", "bundle")}

    def whole(picker, w):
        def run(i):
            caster.picker = picker
            caster.cast(copies[picker][i], times[i], workers=w)
        return in_turn(run, k)

    for w in (1, 2):
        res = alternating({f"whole cast (every field), Embree, {w} worker(s)": whole("embree", w),
                           f"whole cast (every field), bundle, {w} worker(s)": whole("bundle", w)}, rounds)
        for label, r in res.items():
            line(label, r, anchor)
    caster.picker = "auto"


def settings(scene, kind, rays_at, times, rounds):
    caster = caster_for(scene, kind)
    bundles = [rays_at(t) for t in times]
    k = len(times) - 1
    variants = {}
    for rpc in (16, 32, 64):
        for early in (True, False):
            variants[f"bundle pick, {rpc} rays per cell, early exit {'on' if early else 'off'}, 1 worker"] = in_turn(
                lambda i, rpc=rpc, early=early: bundle_pick(caster, bundles[i], times[i], 1, rays_per_cell=rpc,
                                                            early=early), k)
    for label, res in alternating(variants, rounds).items():
        line(label, res)


def frames(scene, kind, sensor, times, rounds, anchor):
    caster = caster_for(scene, kind)
    k = len(times) - 1

    def capture(picker):
        # Each picker at its own times (the bundle's half a frame later): a camera's rays are
        # kept per pose, read-only, and a bundle cast a second time takes the fixed sensor's path.
        shift = 0.0 if picker == "embree" else 1 / 60

        def run(i):
            caster.picker = picker
            sensor.capture(scene, times[i] + shift, np.random.default_rng(i))
        return in_turn(run, k)

    res = alternating({f"whole frame ({kind}), Embree picks": capture("embree"),
                       f"whole frame ({kind}), bundle picks": capture("bundle")}, rounds)
    for label, r in res.items():
        line(f"{label} -> {1 / r[1]:5.1f} frames/s", r, anchor)
    caster.picker = "auto"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--before-picker", default=None, help="another checkout's src: its picker in the same turns")
    ap.add_argument("--picks-only", action="store_true", help="the robot cell's picks only (no casts, frames, "
                    "settings, visual meshes or office)")
    args = ap.parse_args()
    before = None if args.before_picker is None else before_picker_class(args.before_picker)
    print_machine()
    times = [T0 + i / 30.0 for i in range(args.rounds + 1)]

    scene = build_arm_cell_scene()
    sensors = build_arm_cell_sensors()
    tof = sensors[2]
    radar = flange_radar(ROBOT)

    def tof_rays(t):
        pose = tof.mount.pose_at(scene, t)
        return tof._renderer.rays(pose.rotation, pose.position)

    cfg = radar.config
    radar_local = PinholeCamera.from_fov(cfg.render_width, cfg.render_height, cfg.hfov_deg,
                                         cfg.vfov_deg).directions().reshape(-1, 3).copy()
    radar_local.setflags(write=False)

    def radar_rays_at(t):
        pose = radar.mount.pose_at(scene, t)
        r = radar_rays(radar, pose)
        return Rays(r.origins, r.directions, local=(radar_local, pose.rotation))  # as the radar casts them

    n_tri = sum(len(o.geometry.mesh.faces) for o in scene.objects)
    for label, kind, rays_at, sensor in (
            ("wrist ToF pmd_pico_flexx, 2 x 2 rays per pixel", "tof", tof_rays, tof),
            ("radar paper_bgt60tr13c on the flange", "radar", radar_rays_at, radar)):
        r = rays_at(times[1])
        anchor = embree_anchor(scene, kind, times[1], r.origins, r.directions, 7)[1]
        print(f"\n== robot cell ({n_tri} triangles, UR5e collision meshes), {label}: {len(r)} rays")
        print(f"  anchor: bare embreex cast, 1 thread, same rays       {anchor * 1e3:7.1f} ms median")
        compare_picks(scene, kind, rays_at, times, args.rounds, anchor, before, args.picks_only)
        if args.picks_only:
            continue
        frames(scene, kind, sensor, times, args.rounds, anchor)
        settings(scene, kind, rays_at, times, max(3, args.rounds // 2))

    if args.picks_only:
        print_load_at_end()
        return
    print("\n== the robot cell with the UR5e's visual meshes, wrist ToF rays")
    heavy = build_arm_cell_scene(shapes="visual")
    print(f"  {sum(len(o.geometry.mesh.faces) for o in heavy.objects)} triangles")
    r = tof_rays(times[1])
    anchor = embree_anchor(heavy, "tof", times[1], r.origins, r.directions, 7)[1]
    print(f"  anchor: bare embreex cast, 1 thread, same rays       {anchor * 1e3:7.1f} ms median")

    def heavy_rays(t):
        pose = tof.mount.pose_at(heavy, t)
        return tof._renderer.rays(pose.rotation, pose.position)

    compare_picks(heavy, "tof", heavy_rays, times, max(3, args.rounds // 2), anchor)

    print("\n== office scene (bench_render.py: detail 6, a walking person), 1000 x 342 rays")
    office = build_office_scene(detail=6, person=True)
    cam = PinholeCamera.from_fov(1000, 342, 90.0, 40.0)
    base = cam.rays(sensor_pose())
    otimes = [0.3 + i / 30.0 for i in range(args.rounds + 1)]

    def office_rays(t):
        return Rays(base.origins, np.array(base.directions))  # fresh, writable: a sensor that may move

    print(f"  {sum(len(o.geometry.mesh.faces) for o in office.objects)} triangles")
    anchor = embree_anchor(office, "tof", otimes[1], base.origins, base.directions, 7)[1]
    print(f"  anchor: bare embreex cast, 1 thread, same rays       {anchor * 1e3:7.1f} ms median")
    compare_picks(office, "tof", office_rays, otimes, max(3, args.rounds // 2), anchor)
    print_load_at_end()


if __name__ == "__main__":
    main()
