"""The moving radars' synthesis, one commit's code against the working tree's, in turn.

The robot cell's (``demos.robot_cell.build_arm_cell``, as ``bench_robot_cell.py``) flange
radar (``paper_bgt60tr13c``: 342,000 scatterers, every one moving relative to the radar,
512 samples x 16 chirps x 2 Rx) is rendered at T0 = 0.9 s (the arm between pick and
lift, the person walking in) and 3.4 s (over the reach) with the working tree's code and
its scatterers saved; so are the wall radar's movers (64 chirps x 64 samples: the
walking person and the arm, synthesised per frame beside the kept static cube) at
times from 0.9 to 4.0 s, timed as one sum over those frames. Then, round after round, a fresh process
of each tree (``--before``: a commit, its ``src`` unpacked to a temporary folder; "after":
this tree) takes the same saved frames and measures, on one thread (thread CPU, median
of its repeats): the noise-tolerance estimate, the synthesis by stage (the stage timers of
``bench_moving.py``) and in all; on 2 workers: process CPU and wall time of the synthesis.
Same-run anchor: the same scatterers synthesised as a static scene (velocities dropped),
one thread, in each process. Each tree's cube is checked against the after tree's
synthesis at eps = 1e-8 (relative l2 error; the bound is 2 eps) and its bytes compared
with the other tree's.

Run:  .venv/bin/python benchmarks/bench_radar_trees.py --before COMMIT [--rounds 3]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _timing import print_load_at_end, print_machine

ROOT = Path(__file__).resolve().parents[1]
TIMES = (0.9, 3.4)  # the flange radar's frame times [s]
# The wall radar's frame times [s]: the person walking in (0.9-1.4 s, a few hundred
# movers, 2-D blocks) and then only the arm and the reaching hand (a few movers: the
# per-chirp path, after the 2-D plans were tried).
WALL_TIMES = (0.9, 1.2, 1.6, 2.0, 2.4, 2.8, 3.2, 3.4, 3.6, 4.0)


def save_frames(folder: Path) -> None:
    """The wrist radar's scatterers, weights and noise tolerance at ``TIMES`` (this tree's
    render), its config, and each frame's reference cube at eps = 1e-8."""
    from _cell import flange_radar

    from twinsense.demos.robot_cell import ROBOT, build_arm_cell
    from twinsense.radar.scatterers import ScatterRenderer
    from twinsense.radar.synthesis import synthesize

    scene, sensors = build_arm_cell()
    radar = flange_radar(ROBOT)
    radar.capture(scene, 0.3, np.random.default_rng(0))  # the renderer and its kernels
    for t in TIMES:
        scat = radar._renderer.render(scene, radar.mount.state_at(scene, t), t)
        w = radar._weights(scat)
        eps = radar._tolerance(scat.points, w, scat.points_rx)
        ref = synthesize(scat.points, scat.velocities, w, radar.config, eps=1e-8, workers=radar.workers)
        np.savez(folder / f"frame_{t}.npz", p=scat.points, v=scat.velocities, w=w, eps=eps, ref=ref)
    (folder / "config.pkl").write_bytes(pickle.dumps(radar.config))
    wall = next(s for s in sensors if s.name == "radar")
    renderer = ScatterRenderer(wall.config, wall.backend, 2, reuse_static_hits=False)
    for t in WALL_TIMES:
        scat = renderer.render(scene, wall.mount.state_at(scene, t), t)
        w = wall._weights(scat)
        rows = np.flatnonzero(np.any(scat.velocities != 0.0, axis=1))
        np.savez(folder / f"wall_{t}.npz", p=scat.points[rows], v=scat.velocities[rows], w=w[rows])
    (folder / "wall_config.pkl").write_bytes(pickle.dumps(wall.config))


def child(folder: Path, repeats: int) -> None:
    """One tree's figures on the saved frames, as JSON on stdout."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_moving import _stage_timers

    from twinsense.radar.synthesis import noise_tolerance, synthesize

    cfg = pickle.loads((folder / "config.pkl").read_bytes())
    out = {}
    for t in TIMES:
        f = np.load(folder / f"frame_{t}.npz")
        p, v, w, eps = f["p"], f["v"], f["w"], float(f["eps"])
        synthesize(p, v, w, cfg, eps=eps, workers=1)  # warm-up (kernels, plans)
        runs = []
        for _ in range(repeats):
            stages: dict = {}
            c0 = time.thread_time()
            nt = noise_tolerance(p, w, cfg, workers=1)
            stages["noise tolerance (first-chirp power estimate)"] = time.thread_time() - c0
            undo = _stage_timers(stages)
            try:
                c0 = time.thread_time()
                cube = synthesize(p, v, w, cfg, eps=eps, workers=1)
                stages["synthesis, all (one thread)"] = time.thread_time() - c0
            finally:
                undo()
            work = sum(stages.get(k, 0.0) for k in ("movers' 2-D blocks (plan and run)",
                                                     "movers per chirp (the tails)", "static rows"))
            stages["- movers found, range rates, sort, gathers, sums"] = \
                stages["synthesis, all (one thread)"] - work
            c0 = time.thread_time()
            synthesize(p, None, w, cfg, eps=eps, workers=1)
            stages["anchor: the same scatterers static (one thread)"] = time.thread_time() - c0
            c0, t0 = time.process_time(), time.perf_counter()
            two = synthesize(p, v, w, cfg, eps=eps, workers=2)
            stages["synthesis on 2 workers: process CPU"] = time.process_time() - c0
            stages["synthesis on 2 workers: wall"] = time.perf_counter() - t0
            runs.append(stages)
        ref = f["ref"]
        out[str(t)] = {
            "ms": {k: float(np.median([r.get(k, 0.0) for r in runs])) * 1e3 for k in runs[0]},
            "eps": eps, "noise_eps": nt, "err": float(np.linalg.norm(cube - ref) / np.linalg.norm(ref)),
            "sha": hashlib.sha256(cube.tobytes()).hexdigest()[:16],
            "same_with_2_workers": cube.tobytes() == two.tobytes(),
        }
    wall_cfg = pickle.loads((folder / "wall_config.pkl").read_bytes())
    frames = [np.load(folder / f"wall_{t}.npz") for t in WALL_TIMES]
    for f in frames:  # warm-up
        synthesize(f["p"], f["v"], f["w"], wall_cfg, workers=1)
    runs = []
    for _ in range(repeats):
        c0 = time.thread_time()
        cubes = [synthesize(f["p"], f["v"], f["w"], wall_cfg, workers=1) for f in frames]
        runs.append(time.thread_time() - c0)
    out["wall"] = {"ms_per_frame": float(np.median(runs)) * 1e3 / len(frames),
                   "movers": [len(f["p"]) for f in frames],
                   "sha": hashlib.sha256(b"".join(c.tobytes() for c in cubes)).hexdigest()[:16]}
    print(json.dumps(out))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", required=True, help="a commit whose src is the before code")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per frame in each process")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(Path(args.child), args.repeats)
        return
    print_machine()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        before_src = folder / "before"
        before_src.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.before, "src"],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(before_src)], input=archive, check=True)
        save_frames(folder)
        trees = {f"before ({args.before[:8]})": str(before_src / "src"), "after (this tree)": str(ROOT / "src")}
        results: dict = {label: [] for label in trees}
        for _ in range(args.rounds):
            for label, src in trees.items():
                env = {**os.environ, "PYTHONPATH": src}
                text = subprocess.run([sys.executable, __file__, "--before", args.before, "--child", tmp,
                                       "--repeats", str(args.repeats)],
                                      env=env, capture_output=True, text=True, check=True).stdout
                results[label].append(json.loads(text.strip().splitlines()[-1]))
    labels = list(trees)
    for t in TIMES:
        key = str(t)
        first = {label: results[label][0][key] for label in labels}
        print(f"\n== wrist frame at t = {t} s, eps {first[labels[1]]['eps']:.2g} "
              f"(noise tolerance: {', '.join(format(first[lb]['noise_eps'], '.4g') for lb in labels)}); "
              f"ms, medians of {args.rounds} rounds x {args.repeats} (min-max of the rounds' medians)")
        stage_names = list(dict.fromkeys(k for lb in labels for k in first[lb]["ms"]))
        print(f"  {'stage':<58s}" + "".join(f"{lb:>30s}" for lb in labels))
        for name in stage_names:
            if not any(r[key]["ms"].get(name, 0.0) for lb in labels for r in results[lb]):
                continue  # a stage neither tree ran on this frame
            cells = []
            for lb in labels:
                vals = [r[key]["ms"].get(name, 0.0) for r in results[lb]]
                cells.append(f"{np.median(vals):8.1f} ({min(vals):6.1f}-{max(vals):6.1f})")
            print(f"  {name:<58s}" + "".join(f"{c:>30s}" for c in cells))
        for lb in labels:
            r = first[lb]
            print(f"  {lb}: relative l2 error against eps=1e-8 {r['err']:.2e} ({r['err'] / r['eps']:.2f} eps, "
                  f"bound 2 eps); cube sha256 {r['sha']}; 1 and 2 workers the same bytes: "
                  f"{r['same_with_2_workers']}")
    walls = {lb: [r["wall"] for r in results[lb]] for lb in labels}
    print(f"\n== wall radar movers at t = {', '.join(map(str, WALL_TIMES))} s "
          f"({walls[labels[1]][0]['movers']} movers), default eps: synthesis thread CPU per frame "
          f"on one thread, median of {args.rounds} rounds x {args.repeats} (min-max)")
    for lb in labels:
        vals = [r["ms_per_frame"] for r in walls[lb]]
        print(f"  {lb:<30s} {np.median(vals):7.2f} ms ({min(vals):.2f}-{max(vals):.2f}); cubes sha256 "
              f"{walls[lb][0]['sha']}")
    print_load_at_end()


if __name__ == "__main__":
    main()
