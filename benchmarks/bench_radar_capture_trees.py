"""The flange radar's whole moving frames, one commit's code against the working tree's, in turn.

The robot cell's UR5e (``demos.robot_cell.build_arm_cell_scene``) carries the
``paper_bgt60tr13c`` radar on its flange (``_cell.flange_radar``: 1000 x 342 render rays,
512 samples x 16 chirps x 2 Rx): every scatterer moves relative to the radar, so every frame
is a full moving synthesis. Round after round, a fresh process of each tree (``--before``: a
commit, its ``src`` unpacked to a temporary folder; "after": this tree) builds the cell,
captures two warm-up frames and then ``--frames`` frames at T0 = 0.9 + k / 30 s with seed k,
and reports per frame the median process CPU (every thread), the median wall time and the
median count of minor page faults, on the sensor's own workers (2 on these machines) and on
one. Same-run anchor: the bare single-thread Embree cast of the radar's rays at T0
(``_cell.radar_anchor``) in each process. The cubes of both trees are compared byte for byte.

Run:  .venv/bin/python benchmarks/bench_radar_capture_trees.py --before COMMIT [--rounds 4]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _timing import print_load_at_end, print_machine

ROOT = Path(__file__).resolve().parents[1]
T0 = 0.9


def _faults() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def child(frames: int) -> None:
    """One tree's figures, as JSON on stdout."""
    from _cell import flange_radar, radar_anchor

    from twinsense.demos.robot_cell import ROBOT, build_arm_cell_scene

    scene = build_arm_cell_scene()
    radar = flange_radar(ROBOT)
    out = {}
    digest = hashlib.sha256()
    for label, workers in (("sensor's workers", radar.workers), ("one worker", 1)):
        radar.workers = workers
        for k in range(2):  # warm-up: the renderer's buffers, the kernels, the plans
            radar.capture(scene, T0 + k / 30, np.random.default_rng(k))
        cpu, wall, faults = [], [], []
        for k in range(2, 2 + frames):
            f0, c0, t0 = _faults(), time.process_time(), time.perf_counter()
            frame = radar.capture(scene, T0 + k / 30, np.random.default_rng(k))
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            faults.append(_faults() - f0)
            digest.update(np.ascontiguousarray(frame.cube).tobytes())
            digest.update(np.ascontiguousarray(frame.signal).tobytes())
        out[label] = {"workers": workers, "cpu_ms": float(np.median(cpu)) * 1e3,
                      "wall_ms": float(np.median(wall)) * 1e3, "faults": float(np.median(faults))}
    out["anchor_ms"] = radar_anchor(scene, radar, T0, repeats=5) * 1e3
    out["sha"] = digest.hexdigest()[:16]
    print(json.dumps(out))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", required=True, help="a commit whose src is the before code")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--frames", type=int, default=8, help="timed frames per process and worker count")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.frames)
        return
    print_machine()
    with tempfile.TemporaryDirectory() as tmp:
        before_src = Path(tmp) / "before"
        before_src.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.before, "src"],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(before_src)], input=archive, check=True)
        trees = {f"before ({args.before[:8]})": str(before_src / "src"), "after (this tree)": str(ROOT / "src")}
        results: dict = {label: [] for label in trees}
        for _ in range(args.rounds):
            for label, src in trees.items():
                env = {**os.environ, "PYTHONPATH": src}
                text = subprocess.run([sys.executable, __file__, "--before", args.before, "--child",
                                       "--frames", str(args.frames)],
                                      env=env, capture_output=True, text=True, check=True).stdout
                results[label].append(json.loads(text.strip().splitlines()[-1]))
    labels = list(trees)
    print(f"\n== flange radar frames at T0 = {T0} + k / 30 s, k = 2..{args.frames + 1}: medians over "
          f"{args.rounds} processes per tree of each process's median frame (min-max of the processes)")
    for mode in ("sensor's workers", "one worker"):
        workers = results[labels[0]][0][mode]["workers"]
        print(f"  {mode} ({workers}):")
        for lb in labels:
            cells = []
            for key, unit in (("cpu_ms", "ms CPU"), ("wall_ms", "ms wall"), ("faults", "faults")):
                vals = [r[mode][key] for r in results[lb]]
                cells.append(f"{np.median(vals):8.1f} {unit} ({min(vals):.1f}-{max(vals):.1f})")
            anchor = float(np.median([r["anchor_ms"] for r in results[lb]]))
            cpu = float(np.median([r[mode]["cpu_ms"] for r in results[lb]]))
            print(f"    {lb:<22s}" + "  ".join(cells) + f"  = {cpu / anchor:.2f} x anchor")
    for lb in labels:
        print(f"  anchor (bare Embree cast of the radar's rays, one thread) in {lb}: "
              f"{np.median([r['anchor_ms'] for r in results[lb]]):.1f} ms; cubes sha256 {results[lb][0]['sha']}")
    same = len({r["sha"] for lb in labels for r in results[lb]}) == 1
    print(f"  every process's cubes and IF signals the same bytes: {same}")
    print_load_at_end()


if __name__ == "__main__":
    main()
