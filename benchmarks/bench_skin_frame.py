"""The robot cell's forearm skin over the reach: this tree's frames against another source tree's, in turn.

The skin (``pad-grid`` on the moving forearm, 20 frames/s) with the person's
hand reaching for it (from 3.2 s, where every frame grounds another set of
nodes) is captured in two worker processes: one imports twinsense from this
tree, the other from ``--before`` (a ``src`` directory, e.g. made with
``git archive <commit> src | tar -x -C /tmp/before``). Each prepares the
skin for the same times and captures its first frame untimed; then they
capture frame k in turn, one process at a time, so both see the same
machine load. Printed per tree: wall time per frame (median, best), the
capturing process's CPU time (median and mean: a run's CPU is the mean's,
and the median frame hides a cut that only some frames get), the CG iterations of the largest
column, and the largest Maxwell difference between the two trees (against
the skin's ``capacitance_atol``). Without ``--before`` only this tree runs.

Same-run anchor: a plain scikit-fem + pyamg solve on the skin's mesh
(``_timing.skfem_pyamg_anchor``), timed in this tree's worker.

With ``--exact`` this tree's worker also solves every frame directly
(sparse LU of the free block, untimed) and the largest Maxwell error
against that exact discrete solution is printed.

With ``--start N`` each worker also starts a run again N times, in turn: a
prepare over the same times on the same scene (what ``simulate`` does at the
start of every run of a window: the bench_robot_cell.py runs), then frames 0,
1 and 2 of the reach. Printed per tree: the prepare's CPU and page faults
(minor faults, ``resource.getrusage``), the first frame's, and the second
(a reaching frame, warm); and whether both trees' three frames are the same
bytes.

With ``--classic`` a third worker runs this tree with the energy rule's early
stop off (``SolverConfig(early_stop=False)``), in turn with the others: the
early stop's share of a difference between the trees.

Run:  .venv/bin/python benchmarks/bench_skin_frame.py [--before /tmp/before/src] [--frames 12] [--rounds 2] [--exact]
      [--classic]
"""

from __future__ import annotations

import argparse
import os
import pickle
import subprocess
import sys
import time

import numpy as np
from _timing import print_anchor, print_load_at_end, print_machine

T_REACH = 3.2  # [s] the person's hand at the forearm: the skin's map changes every frame
HERE = os.path.dirname(os.path.abspath(__file__))


def exact_maxwell(system) -> np.ndarray:
    """The frame's Maxwell matrix from a sparse direct solve of its free block (the exact discrete solution)."""
    import scipy.sparse.linalg as spla

    from twinsense.capacitive.fem import reduce_floating
    from twinsense.capacitive.solver import split_system

    A, K, B, fixed, X = split_system(system)
    free = ~fixed
    X[free] = spla.splu(A[free][:, free].tocsc()).solve(B[free])
    full = X.T @ (K @ X)
    return reduce_floating(0.5 * (full + full.T), len(system.terminals))


def worker(frames: int, exact: bool, classic: bool = False) -> None:
    """The worker's side: read frame numbers on stdin, capture, answer on stdout (pickled).
    ``classic``: the skin's solver with the energy rule's early stop off."""
    from twinsense.demos.robot_cell import build_arm_cell

    scene, sensors = build_arm_cell()
    skin = sensors[3]
    if classic:
        from dataclasses import replace

        from twinsense.capacitive.sensor import CapacitiveSensor

        cfg = replace(skin.config, solver=replace(skin.config.solver, early_stop=False))
        skin = CapacitiveSensor(cfg, name=skin.name, mount=skin.mount)
    times = [T_REACH + k / 20.0 for k in range(frames + 1)]
    skin.prepare(scene, times)
    skin.capture(scene, times[0], None)  # untimed: mesh, baseline, hierarchy, compiled kernels
    out = sys.stdout.buffer
    for line in sys.stdin:
        cmd = line.split()
        if cmd[0] == "start":
            import resource

            def usage():
                r = resource.getrusage(resource.RUSAGE_SELF)
                return time.process_time(), r.ru_minflt

            def start():
                reply = {"bytes": []}
                c0, p0 = usage()
                skin.prepare(scene, times)
                c1, p1 = usage()
                reply["prepare"] = (c1 - c0, p1 - p0)
                for k in range(3):
                    c0, p0 = usage()
                    f = skin.capture(scene, times[k], None)
                    c1, p1 = usage()
                    reply[f"frame{k}"] = (c1 - c0, p1 - p0)
                    reply["bytes"].append(f.maxwell.tobytes())
                return reply

            if len(cmd) > 1 and cmd[1] == "fork":
                # As in a capture process of simulate(processes=N): a forked child that inherits the
                # sensor and starts the run (every page it writes is copied first).
                r_fd, w_fd = os.pipe()
                pid = os.fork()
                if pid == 0:
                    os.close(r_fd)
                    with os.fdopen(w_fd, "wb") as fh:
                        fh.write(pickle.dumps(start()))
                    os._exit(0)
                os.close(w_fd)
                with os.fdopen(r_fd, "rb") as fh:
                    reply = pickle.loads(fh.read())
                os.waitpid(pid, 0)
            else:
                reply = start()
        elif cmd[0] == "anchor":
            from _timing import skfem_pyamg_anchor

            lm = skin.layout_mesh
            got = min(skfem_pyamg_anchor(lm.mesh.points, lm.mesh.cells, lm.terminal_nodes, lm.ground_nodes,
                                         lm.permittivity) for _ in range(3))
            reply = {"anchor": got}
        else:
            k = int(cmd[1])
            c0, w0 = time.process_time(), time.perf_counter()
            f = skin.capture(scene, times[k], None)
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
            reply = {"wall": wall, "cpu": cpu, "iters": int(f.iterations.max()), "maxwell": f.maxwell,
                     "atol": skin.frame_solver_config.capacitance_atol}
            if exact:
                reply["exact"] = exact_maxwell(skin._solver.system)
        data = pickle.dumps(reply)
        out.write(len(data).to_bytes(8, "little") + data)
        out.flush()


class Worker:
    def __init__(self, src: str, frames: int, exact: bool = False, classic: bool = False):
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([src, HERE]), OMP_NUM_THREADS="1",
                   OPENBLAS_NUM_THREADS="1")
        cmd = [sys.executable, os.path.abspath(__file__), "--worker", "--frames", str(frames)]
        cmd += (["--exact"] if exact else []) + (["--classic"] if classic else [])
        self.p = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)

    def ask(self, cmd: str) -> dict:
        self.p.stdin.write((cmd + "\n").encode())
        self.p.stdin.flush()
        n = int.from_bytes(self.p.stdout.read(8), "little")
        return pickle.loads(self.p.stdout.read(n))

    def close(self) -> None:
        self.p.stdin.close()
        self.p.wait()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", help="a src directory of another tree, run in turn with this one")
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--rounds", type=int, default=2, help="passes over the frames (a frame again is a warm "
                    "start from the last frame of the pass)")
    ap.add_argument("--exact", action="store_true", help="also solve each frame of this tree directly (untimed) "
                    "and print its largest Maxwell error")
    ap.add_argument("--classic", action="store_true", help="also run this tree with the energy rule's early stop "
                    "off (SolverConfig(early_stop=False)), in turn with the others")
    ap.add_argument("--start", type=int, default=0, help="also start a run again this many times per tree, in "
                    "turn: the prepare's and the first frames' CPU and page faults")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.frames < 1 or args.rounds < 1:
        ap.error("--frames and --rounds must be at least 1")
    if args.worker:
        worker(args.frames, args.exact, args.classic)
        return
    print_machine()
    trees = {"this tree": os.path.join(os.path.dirname(HERE), "src")}
    if args.before:
        if not os.path.isdir(os.path.join(args.before, "twinsense")):
            ap.error(f"--before {args.before!r}: no twinsense package there (give a src directory)")
        trees = {"before": args.before, **trees}
    if args.classic:
        trees["classic rule"] = trees["this tree"]
    workers = {name: Worker(src, args.frames, args.exact and name == "this tree", name == "classic rule")
               for name, src in trees.items()}
    got = {name: {"wall": [], "cpu": [], "iters": []} for name in trees}
    worst = 0.0
    errors = []
    atol = None
    try:
        for _ in range(args.rounds):
            for k in range(1, args.frames + 1):
                mats = {}
                for name, w in workers.items():
                    r = w.ask(f"frame {k}")
                    for key in ("wall", "cpu", "iters"):
                        got[name][key].append(r[key])
                    mats[name] = r["maxwell"]
                    atol = r["atol"]
                    if "exact" in r:
                        errors.append(float(np.abs(r["maxwell"] - r["exact"]).max()))
                if "before" in mats:
                    worst = max(worst, float(np.abs(mats["before"] - mats["this tree"]).max()))
        starts = {name: [] for name in trees}
        same = True
        forks = {name: [] for name in trees}
        for _ in range(args.start):
            for how, into in (("start", starts), ("start fork", forks)):
                got_bytes = {}
                for name, w in workers.items():
                    r = w.ask(how)
                    into[name].append(r)
                    got_bytes[name] = r["bytes"]
                same &= len({tuple(b) for b in got_bytes.values()}) == 1
        anchor = workers["this tree"].ask("anchor")["anchor"]
    finally:
        for w in workers.values():
            w.close()
    n = args.frames * args.rounds
    print(f"skin pad-grid on the moving forearm, hand reaching (from {T_REACH:g} s, {args.frames} frames x "
          f"{args.rounds} rounds, trees in turn frame by frame):")
    for name, g in got.items():
        wall, cpu = np.array(g["wall"]), np.array(g["cpu"])
        print(f"  {name:12s}: {np.median(wall) * 1e3:6.1f} ms median wall ({wall.min() * 1e3:.1f} best, "
              f"{np.percentile(wall, 90) * 1e3:.1f} 90th percentile), {np.median(cpu) * 1e3:6.1f} ms median CPU "
              f"({np.mean(cpu) * 1e3:.1f} mean: CPU per scene second / 20); "
              f"CG iterations {min(g['iters'])}-{max(g['iters'])} (mean {np.mean(g['iters']):.2f}) over {n} frames; "
              f"{'under' if np.median(wall) < 0.05 else 'NOT under'} 50 ms")
    if "before" in got:
        print(f"  largest Maxwell difference between the trees: {worst * 1e15:.4f} fF ({worst / atol:.2f} x "
              f"capacitance_atol {atol * 1e15:.4f} fF)")
    if errors:
        print(f"  this tree against a direct solve of each frame: largest Maxwell error {max(errors) * 1e15:.4f} fF "
              f"({max(errors) / atol:.2f} x capacitance_atol; median over frames {np.median(errors) / atol:.2f} x)")
    if args.start:
        print(f"a run started again {args.start} times per tree (a prepare over the same times, frames 0-2), "
              "CPU median (best) and page faults median:")
        for name, rs in [(n, r) for n, r in starts.items()] + [(n + ", forked", r) for n, r in forks.items()]:
            parts = []
            for key, label in (("prepare", "prepare"), ("frame0", "first frame"), ("frame1", "second frame"),
                               ("frame2", "third frame")):
                cpu = np.array([r[key][0] for r in rs]) * 1e3
                faults = np.array([r[key][1] for r in rs])
                parts.append(f"{label} {np.median(cpu):.1f} ({cpu.min():.1f}) ms, {np.median(faults):.0f} faults")
            print(f"  {name:20s}: " + "; ".join(parts))
        if len(starts) > 1:
            print(f"  frames 0-2 the same bytes in every tree: {same}")
    print_anchor("scikit-fem + pyamg solve, same mesh", anchor, float(np.median(got["this tree"]["wall"])))
    print_load_at_end()


if __name__ == "__main__":
    main()
