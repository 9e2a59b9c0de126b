"""The robot cell (``twinsense demo robot-cell``, examples/robot_cell.yaml) at speed.

Measures, with the UR5e running its pick-and-place trajectory and the person
walking (every frame at a new time, so every moving object moves):

- the wrist ToF camera (``pmd_pico_flexx``, 224 x 171, 2 x 2 rays per pixel)
  on the moving flange; target >= 60 frames/s;
- a ``paper_bgt60tr13c`` radar (preset waveform: 512 samples, 16 chirps, 2 Rx)
  on the moving flange; target >= 30 frames/s;
- the whole cell (wall ToF, wrist ToF, wall radar, forearm skin at the file's
  rates: 10, 10, 10 and 20 frames/s) through ``simulate`` over 1 s of scene
  time from 0.9 s and over the reach (3.2 to 4.2 s, the skin at its most
  expensive), each after an untimed run of the same window: wall and CPU time
  per scene second (target <= 1, real time) with the sensors captured one after
  another, on simulate's capture threads and in two capture processes
  (``processes=2``), in turn, and each sensor's share; the cost of handing a
  ToF frame and a radar frame from a capture process to the parent (pickle
  protocol 5 over a pipe);
- the forearm skin (``pad-grid`` on the moving forearm, 20 frames/s) alone:
  each frame maps the scene onto its mesh and solves; anchored to a plain
  scikit-fem + pyamg solve on the same mesh; over the reach also the frame
  solve against the NumPy solve it replaced, alternating in one run;
- the true separation (``SeparationMonitor.at``) per time;
- the UR5e's link meshes used (collision, 7,558 triangles) against the visual
  ones (121,783): the wrist ToF frame with the visual meshes, and how far the
  visual surface lies from the collision surface (the geometric error of the
  lighter meshes).

Same-run anchor: a bare single-thread embreex cast of the same rays against the
scene posed at that time, one world-space BVH built beforehand.

``--cell-only --before COMMIT``: the whole cell's runs (both windows, the three ways) in fresh processes,
one with that commit's ``src`` (unpacked to a temporary folder; or a folder holding a ``twinsense``
package tree) and one with this tree's, in turn
``--rounds`` times, so that both codes see the same machine load.

``--radar-resolutions``: the flange radar at 1, 1/4 and 1/16 of its render rays: frame time and what
the cube loses (its power, its strongest range bin) against the full render.

Run:  .venv/bin/python benchmarks/bench_robot_cell.py [--frames N] [--cell-only | --skin-only] [--repeats N]
      .venv/bin/python benchmarks/bench_robot_cell.py --cell-only --before COMMIT [--rounds N]
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import trimesh
from _cell import flange_radar, radar_anchor, radar_before_after, tof_anchor
from _timing import (
    best_and_median,
    print_anchor,
    print_load_at_end,
    print_machine,
    skfem_pyamg_anchor,
    timed_frames,
)

from twinsense.demos.robot_cell import PERSON, ROBOT, arm, build_arm_cell, build_arm_cell_scene, build_arm_cell_sensors
from twinsense.render.parallel import default_workers
from twinsense.safety import SeparationMonitor
from twinsense.simulate import _receive, _send, lane_groups, simulate

T0 = 0.9  # [s] the arm between pick and lift, the person walking in
T_REACH = 3.2  # [s] the person's hand at the forearm (3.2 to 3.7 s): the skin's map changes every frame


def report(label: str, best: float, median: float, cpu: float, anchor: float, target: float) -> None:
    fps = 1 / median
    print(f"  {label:<52s} {best * 1e3:7.1f} ms best {median * 1e3:7.1f} ms median -> {fps:6.1f} frames/s "
          f"(target {target:.0f}: {'met' if fps >= target else 'NOT met'}); CPU {cpu * 1e3:.1f} ms/frame")
    print_anchor("bare embreex cast, same rays", anchor, median)


def wrist_tof(scene, tof, frames: int, label: str) -> None:
    times = [T0 + k / 30.0 for k in range(frames + 1)]
    anchor = tof_anchor(scene, tof, times[1], 9)
    rng = np.random.default_rng(0)
    report(label, *timed_frames(lambda k: tof.capture(scene, times[k], rng), frames), anchor, 60.0)


def wrist_radar(scene, frames: int) -> None:
    radar = flange_radar(ROBOT)
    cfg = radar.config
    times = [T0 + k / 30.0 for k in range(frames + 1)]
    anchor = radar_anchor(scene, radar, times[1], 9)
    # Before (the 2-D mover path with 2-D vectors only) and after (its 1-D variant where
    # cheaper) in turn.
    for label, measured in radar_before_after(radar, scene, times, frames).items():
        report(f"radar paper_bgt60tr13c on the moving flange ({cfg.render_width} x {cfg.render_height} "
               f"rays), {label}", *measured, anchor, 30.0)


def radar_resolutions(scene, frames: int) -> None:
    """The flange radar at 1, 1/4 and 1/16 of the preset's render rays (half and a quarter of each
    count): median wall and CPU per frame, and what the cube loses (its power against the full
    render's, frame by frame, and the strongest range bin) over ``frames`` frames from T0."""
    import dataclasses

    from twinsense.radar import FMCWRadar

    base = flange_radar(ROBOT)
    times = [T0 + k / 30.0 for k in range(frames + 2)]
    print(f"\n== the flange radar at fewer render rays ({frames} frames from {T0} s; power and strongest "
          "range bin of the noise-free cube against the full render's)")
    ref = None
    for div in (1, 2, 4):
        cfg = dataclasses.replace(base.config, render_width=base.config.render_width // div,
                                  render_height=base.config.render_height // div)
        radar = FMCWRadar(cfg, name="wrist_radar", mount=base.mount)
        for k in range(2):
            radar.capture(scene, times[k], np.random.default_rng(k))
        walls, cpus, profiles = [], [], []
        for k in range(2, frames + 2):
            c0, t0 = time.process_time(), time.perf_counter()
            frame = radar.capture(scene, times[k], np.random.default_rng(k))
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
            sig = frame.signal * np.hanning(frame.signal.shape[-1])
            profiles.append((np.abs(np.fft.rfft(sig, axis=-1)) ** 2).mean(axis=(0, 1)))
        profiles = np.array(profiles)
        ref = profiles if ref is None else ref
        db = 10 * np.log10(profiles.sum(axis=1) / ref.sum(axis=1))
        same_peak = int(np.sum(np.argmax(profiles, axis=1) == np.argmax(ref, axis=1)))
        med = float(np.median(walls))
        print(f"  {cfg.render_width:4d} x {cfg.render_height:3d} rays: {med * 1e3:7.1f} ms median wall "
              f"({1 / med:5.1f} frames/s), {np.median(cpus) * 1e3:6.1f} ms CPU; cube power "
              f"{db.min():+.1f} .. {db.max():+.1f} dB; strongest range bin the same in {same_peak} of {frames}")


def skin_frames(scene, skin, frames: int, t0: float = T0, label: str = "") -> None:
    """The forearm skin alone at its 20 frames/s from ``t0`` [s], prepared for those times as ``simulate`` does."""
    times = [t0 + k / 20.0 for k in range(frames + 1)]
    skin.prepare(scene, times)
    best, med, cpu = timed_frames(lambda k: skin.capture(scene, times[k], None), frames)
    lm = skin.layout_mesh
    print(f"  skin pad-grid on the moving forearm{label} ({lm.mesh.n_cells} cells): {best * 1e3:7.1f} ms best "
          f"{med * 1e3:7.1f} ms median -> {1 / med:6.1f} frames/s (its rate 20: "
          f"{'met' if med <= 0.05 else 'NOT met'}); CPU {cpu * 1e3:.1f} ms/frame")
    anchor = min(skfem_pyamg_anchor(lm.mesh.points, lm.mesh.cells, lm.terminal_nodes, lm.ground_nodes,
                                    lm.permittivity) for _ in range(3))
    print_anchor("scikit-fem + pyamg solve, same mesh", anchor, med)


class Timed:
    """A sensor whose captures are timed into ``spent`` (wall) and ``cpu`` (CPU of the capturing thread).

    ``prepare`` is passed through, as simulate calls it. The thread CPU leaves out work a capture hands to
    other threads (the render's cast workers, the ToF cameras' background noise draws and half of their
    chain): that is counted in the run's CPU outside the capture threads. The skin's frames run on the
    capturing thread alone, so its thread CPU is its whole cost.
    """

    def __init__(self, s, spent: dict, cpu: dict):
        self.s, self.name, self.kind, self.frame_rate = s, s.name, s.kind, s.frame_rate
        self.spent, self.cpu = spent, cpu
        if callable(getattr(s, "prepare", None)):
            self.prepare = s.prepare

    def capture(self, scene, t, rng):
        c0, w0 = time.thread_time(), time.perf_counter()
        f = self.s.capture(scene, t, rng)
        self.spent[self.name] += time.perf_counter() - w0
        self.cpu[self.name] += time.thread_time() - c0
        return f


def home_note(sensors, processes: int) -> str:
    """Which group of lanes simulate keeps in the calling process (none in a tree without home_group)."""
    try:
        from twinsense.simulate import home_group
    except ImportError:  # --before with a tree that forked every group
        return ", all forked"
    groups = lane_groups(sensors, processes)
    return f", {groups[home_group(sensors, groups)]} in this process"


def whole_cell(seconds: float, t0: float = T0, label: str = "", repeats: int = 1) -> None:
    """The cell's four sensors through ``simulate`` over ``seconds`` of scene time from ``t0`` [s].

    One untimed run of the same window first: compiled kernels, casters, and the skin's mesh, which
    ``prepare`` refines around where the objects are at the run's frame times (a run over other times
    builds another mesh in its first frame; that run's time is printed apart). Then the window again
    with the sensors captured one after another (``workers=1``), on simulate's default threads and
    in 2 capture processes, in turn ``repeats`` times, so that all ways see the same machine load. A
    capture's time is counted from its start to its end on the thread that runs it: with several
    threads the sensors' times overlap and add up to more than the wall time. In capture processes the
    per-sensor times stay in the children (not printed); the run's CPU adds the children's (os.times).
    """
    scene, sensors = build_arm_cell()
    spent = {s.name: 0.0 for s in sensors}
    tcpu = dict(spent)
    wrapped = [Timed(s, spent, tcpu) for s in sensors]
    w0 = time.perf_counter()
    simulate(scene, wrapped, seconds, t0=t0)
    print(f"  whole cell{label}, {seconds:.1f} s from {t0:g} s, first run (skin mesh built for these times): "
          f"{time.perf_counter() - w0:.2f} s wall")
    for _ in range(repeats):
        for workers, processes in ((1, None), (None, None), (None, 2)):
            spent.update({k: 0.0 for k in spent})
            tcpu.update({k: 0.0 for k in tcpu})
            k0 = os.times()
            c0, w0 = time.process_time(), time.perf_counter()
            simulate(scene, wrapped, seconds, t0=t0, workers=workers, processes=processes)
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
            k1 = os.times()
            cpu += (k1.children_user - k0.children_user) + (k1.children_system - k0.children_system)
            how = (f"{processes} capture processes (lanes {lane_groups(sensors, processes)}"
                   f"{home_note(sensors, processes)})" if processes
                   else f"{default_workers()} threads (default)" if workers is None else "one after another")
            print(f"  whole cell{label}, {seconds:.1f} s from {t0:g} s, {how}: {wall:.2f} s wall -> "
                  f"{wall / seconds:.2f} s per scene second "
                  f"({'real time met' if wall <= seconds else 'real time NOT met'}); "
                  f"CPU {cpu / seconds:.2f} s per scene second (floor on {default_workers()} cores: "
                  f"{cpu / default_workers() / seconds:.2f} s)")
            if processes:
                continue
            total = sum(spent.values())
            for s in sensors:
                n = round(seconds * s.frame_rate)
                print(f"    {s.name:<10s} {s.frame_rate:4.0f} frames/s: {spent[s.name]:6.2f} s "
                      f"({spent[s.name] / max(n, 1) * 1e3:7.1f} ms per frame, "
                      f"{spent[s.name] / total:5.1%} of capture time); thread CPU "
                      f"{tcpu[s.name] / max(n, 1) * 1e3:7.1f} ms per frame")
            # A sensor's frames run one after another on one thread: a lane's own thread CPU bounds the
            # run's wall time from below whatever the threads, as does all the CPU shared over the cores.
            lanes = sum(tcpu.values())
            longest = max(tcpu, key=tcpu.get)
            print(f"    CPU outside the capture threads (render workers, ToF background threads, kinematics, "
                  f"simulate): {(cpu - lanes) / seconds:.2f} s per scene second; lower bound on the wall time on "
                  f"{default_workers()} cores: longest lane ({longest}) {tcpu[longest] / seconds:.2f} s, all "
                  f"CPU / cores {cpu / default_workers() / seconds:.2f} s per scene second")


def transfer_cost(repeats: int = 9) -> None:
    """Handing a frame from a capture process to the parent: simulate's pickle protocol 5 with out-of-band
    buffers over a pipe, sent from a thread of this process (the same calls as the child's and the
    parent's reader), for the cell's wall ToF frame and radar frame at T0."""
    scene, sensors = build_arm_cell()
    for s in (sensors[0], sensors[1]):
        frame = s.capture(scene, T0, np.random.default_rng(0))
        nbytes = sum(np.asarray(v).nbytes for v in frame.streams().values())
        recv, send = multiprocessing.Pipe(duplex=False)

        def once(frame=frame, recv=recv, send=send):
            th = threading.Thread(target=_send, args=(send, ("frames", [frame])))
            th.start()
            _receive(recv)
            th.join()

        best, med = best_and_median(once, repeats)
        print(f"  frame {s.name} ({s.kind}, {nbytes / 1e6:.2f} MB of streams) from a capture process to the "
              f"parent: {med * 1e3:.2f} ms median ({best * 1e3:.2f} best)")


def cell_runs(seconds: float, repeats: int = 1) -> None:
    """The whole cell from T0 and over the reach (T_REACH, where the skin is at its most expensive)."""
    transfer_cost()
    whole_cell(seconds, T0, "", repeats)
    whole_cell(seconds, T_REACH, " (hand reaching for the skin)", repeats)


def separation(scene) -> None:
    """``SeparationMonitor.at`` per time, and its nearest-segment pass against the NumPy functions' pass
    (the anchor: ``_human_distances_numpy``, segment by segment) on the same points."""
    mon = SeparationMonitor(scene, ROBOT, PERSON)
    best, med = best_and_median(lambda: mon.at(T0), 9)
    pts, _, _ = mon.robot_points(T0)
    print(f"  true separation (SeparationMonitor.at, {len(pts)} robot surface points): {med * 1e3:.1f} ms median "
          f"({best * 1e3:.1f} best)")
    _, med_c = best_and_median(lambda: mon.human_distances(pts, T0, gradient=True), 9)
    _, med_n = best_and_median(lambda: mon._human_distances_numpy(pts, T0, gradient=True), 9)
    print(f"  nearest body segment of each point, compiled pass {med_c * 1e3:.1f} ms median; anchor: NumPy "
          f"functions segment by segment {med_n * 1e3:.1f} ms; measured / anchor = {med_c / med_n:.3f}")


def mesh_error() -> None:
    """How far the UR5e's visual surface lies from its collision surface, per link."""
    vis, col = arm("visual"), arm("collision")
    rng = np.random.default_rng(0)
    worst = []
    for lk in vis.tree.links:
        if lk.name not in col.tree.link_names:
            continue
        gv, gc = lk.link_frame_geometry(), col.tree.link(lk.name).link_frame_geometry()
        if gv is None or gc is None:
            continue
        pts, _ = trimesh.sample.sample_surface(gv.mesh, 3000, seed=int(rng.integers(1 << 31)))
        _, d, _ = trimesh.proximity.closest_point(gc.mesh, pts)
        worst.append((lk.name, float(np.median(d)), float(np.percentile(d, 99)), float(d.max())))
    print("  visual surface -> collision surface [mm] (median / 99th percentile / max of 3000 samples):")
    for name, med, p99, mx in worst:
        print(f"    {name:<16s} {med * 1e3:5.1f} / {p99 * 1e3:5.1f} / {mx * 1e3:5.1f}")


def skin_solver_paths(scene, skin, frames: int, t0: float = T_REACH) -> None:
    """The reaching frames with the frame solve (refreshed coarse operators, compiled PCG) and the
    NumPy one it replaced (hierarchy rebuilt by the changed-rows rule), alternating frame by frame
    in one process, each sensor warm-started from its own last frame."""
    import dataclasses

    from twinsense.capacitive.sensor import CapacitiveSensor

    old_cfg = dataclasses.replace(skin.config, solver=dataclasses.replace(skin.config.solver, coarse_refresh=False,
                                                                          compiled=False))
    paths = {"frame solve": skin, "NumPy, rebuilt": CapacitiveSensor(old_cfg, name="skin", mount=skin.mount)}
    times = [t0 + k / 20.0 for k in range(frames + 1)]
    for s in paths.values():
        s.prepare(scene, times)
        s.capture(scene, times[0], None)  # warm-up: mesh, baseline, first hierarchy
    spent = {name: ([], []) for name in paths}
    worst = 0.0
    for t in times[1:]:
        got = {}
        for name, s in paths.items():
            c0, w0 = time.process_time(), time.perf_counter()
            got[name] = s.capture(scene, t, None).maxwell
            spent[name][0].append(time.perf_counter() - w0)
            spent[name][1].append(time.process_time() - c0)
        worst = max(worst, float(np.abs(got["frame solve"] - got["NumPy, rebuilt"]).max()))
    atol = skin.frame_solver_config.capacitance_atol
    for name, (wall, cpu) in spent.items():
        print(f"  skin from {t0:g} s, {name:15s}: {np.median(wall) * 1e3:7.1f} ms median wall "
              f"({min(wall) * 1e3:.1f} best), {np.median(cpu) * 1e3:7.1f} ms median CPU")
    print(f"  largest Maxwell difference between the two: {worst * 1e15:.4f} fF ({worst / atol:.2f} x "
          f"capacitance_atol {atol * 1e15:.4f} fF; each within 3 x of the exact discrete solution)")


def before_after(commit: str, rounds: int, seconds: float) -> None:
    """The whole cell's runs with ``commit``'s code and this tree's, each in a fresh process, in turn."""
    root = Path(__file__).resolve().parents[1]
    with tempfile.TemporaryDirectory() as tmp:
        if Path(commit).is_dir():  # a package tree made by hand (e.g. this tree with some files as they were)
            before = str(Path(commit))
        else:
            archive = subprocess.run(["git", "-C", str(root), "archive", commit, "src"], capture_output=True,
                                     check=True).stdout
            subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
            before = str(Path(tmp) / "src")
        trees = {f"before ({commit[-24:]})": before, "after (this tree)": str(root / "src")}
        for r in range(rounds):
            for label, src in trees.items():
                out = subprocess.run([sys.executable, __file__, "--cell-only", "--seconds", str(seconds)],
                                     env={**os.environ, "PYTHONPATH": src}, capture_output=True, text=True,
                                     check=True, cwd=Path(__file__).parent).stdout
                print(f"== round {r + 1}, {label}")
                print("\n".join(line for line in out.splitlines() if line.startswith("  whole cell")
                                or line.startswith("load")))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--seconds", type=float, default=1.0)
    ap.add_argument("--cell-only", action="store_true", help="only the whole cell (both windows, both ways)")
    ap.add_argument("--repeats", type=int, default=1, help="whole-cell runs of each way per window")
    ap.add_argument("--skin-only", action="store_true", help="only the forearm skin's cases")
    ap.add_argument("--separation-only", action="store_true", help="only SeparationMonitor.at and its nearest-"
                    "segment pass")
    ap.add_argument("--wrist-tof-only", action="store_true", help="only the wrist ToF camera (collision meshes)")
    ap.add_argument("--radar-resolutions", action="store_true",
                    help="only the flange radar at 1, 1/4 and 1/16 of its render rays")
    ap.add_argument("--before", help="with --cell-only: a commit (or a src folder) whose code runs in turn with "
                    "this tree's")
    ap.add_argument("--rounds", type=int, default=2, help="with --before: runs of each code")
    args = ap.parse_args()
    print_machine()
    if args.cell_only and args.before:
        before_after(args.before, args.rounds, args.seconds)
        print_load_at_end()
        return
    if args.cell_only:
        cell_runs(args.seconds, args.repeats)
        print_load_at_end()
        return
    scene, sensors = build_arm_cell()
    if args.separation_only:
        separation(scene)
        print_load_at_end()
        return
    if args.skin_only:
        skin_frames(scene, sensors[3], args.frames)
        skin_frames(scene, sensors[3], args.frames, T_REACH, ", the person's hand reaching for it")
        skin_solver_paths(scene, sensors[3], args.frames)
        print_load_at_end()
        return
    if args.radar_resolutions:
        radar_resolutions(scene, args.frames)
        print_load_at_end()
        return
    n_tri = sum(len(o.geometry.mesh.faces) for o in scene.objects)
    print(f"\n== robot cell: {len(scene.objects)} objects, {n_tri} triangles (UR5e collision meshes), arm and person "
          "moving")
    wrist_tof(scene, sensors[2], args.frames, "wrist ToF pmd_pico_flexx, 2 x 2 rays per pixel")
    if args.wrist_tof_only:
        print_load_at_end()
        return
    wrist_radar(scene, args.frames)
    skin_frames(scene, sensors[3], args.frames)
    skin_frames(scene, sensors[3], args.frames, T_REACH, ", the person's hand reaching for it")
    skin_solver_paths(scene, sensors[3], args.frames)
    cell_runs(args.seconds, args.repeats)
    separation(scene)

    print("\n== the same cell with the UR5e's visual meshes")
    heavy = build_arm_cell_scene(shapes="visual")
    print(f"  {sum(len(o.geometry.mesh.faces) for o in heavy.objects)} triangles")
    wrist_tof(heavy, build_arm_cell_sensors()[2], max(3, args.frames // 2), "wrist ToF, visual meshes")
    mesh_error()
    print_load_at_end()


if __name__ == "__main__":
    main()
