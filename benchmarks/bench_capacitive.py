"""Capacitive sensor update rate: incremental warm-started updates vs full re-solves.

A 6-stripe printer-bed sensor (full 6x6 Maxwell matrix per update) and a
grounded cylinder moving along the zig-zag path T2, at several mesh sizes.
For each mesh it prints the incremental update time (scene mapping, changed
cells, warm-started AMG-PCG, capacitances), the time of a full re-solve
(fresh assembly, AMG set-up and cold solve, default tolerance) measured in the
same process, their ratio, and the largest deviation of the incremental result
from a tight full re-solve relative to the largest matrix entry.

Static condensation (``SolverConfig(condense=True)``): the same frames on a
sensor prepared with the cylinder's swept volume over the whole T2 run; it
prints the set-up (factorisation and interface block), the reduced system's
size, the incremental update time against the uncondensed one in the same
process and the accuracy against the tight full re-solve.

gmsh mesher (``MeshSettings(mesher="gmsh")``): meshing time and update time
on an unstructured mesh of the same layout of about the target size.

Frame solve against the NumPy solve (``--paths-only``): the default solver
(coarse operators refreshed for each frame's conductors, compiled PCG and
V-cycle) and the NumPy one with the hierarchy rebuilt by the changed-rows
rule, alternating frame by frame, both solved to the readout's noise.

The energy rule's early stop (``--early-stop-only``): the default rule and the
classic one (``SolverConfig(early_stop=False)``), alternating frame by frame,
each frame against a tight solve: CPU, CG steps and the largest Maxwell error
as a share of ``capacitance_atol``.

Run: .venv/bin/python benchmarks/bench_capacitive.py [--frames N] [--skip-condense] [--skip-gmsh] [--paths-only]
     [--early-stop-only]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np
from _timing import print_load_at_end, print_machine, skfem_pyamg_anchor

from twinsense.capacitive.mesh import MeshSettings
from twinsense.capacitive.sensor import make_capacitive
from twinsense.capacitive.solver import SolverConfig
from twinsense.demos.capacitive import PATHS, TOOL_CLEARANCE, TOOL_HEIGHT, demo_mesh_settings, printer_scene


def mesh_settings(h_min: float, h_refine: float, growth: float) -> MeshSettings:
    z_top = TOOL_CLEARANCE + TOOL_HEIGHT
    return MeshSettings(
        margin=0.02,
        height=0.06,
        depth=0.01,
        h_min=h_min,
        h_max=0.025,
        growth=growth,
        refine=((-0.1, 0.1, -0.1, 0.1, 0.0, z_top),),
        h_refine=h_refine,
        use_cache=False,
        # Update rate at these fixed mesh sizes: no object refinement (and no
        # warning that the tool is under-resolved; docs/capacitive-accuracy.md).
        object_cells=0,
    )


CASES = {
    "~30k tets (CapSense size)": mesh_settings(6.5e-3, 0.016, 1.8),
    "~55k tets (target)": mesh_settings(5e-3, 0.012, 1.8),
    "~200k tets": mesh_settings(3e-3, 0.006, 1.6),
}


def sensor_with(mesh: MeshSettings, solver: SolverConfig | None = None):
    s = make_capacitive("printer-bed")
    cfg = replace(s.config, mesh=mesh, solver=solver or SolverConfig())
    return type(s)(cfg, name="bed")


def run_case(label: str, mesh: MeshSettings, frames: int, full_every: int, condense: bool = True) -> None:
    scene = printer_scene(PATHS["T2"])
    rate = 30.0
    times = np.arange(frames) / rate
    sensor = sensor_with(mesh)
    t0 = time.perf_counter()
    sensor.solve_at(scene, times[0])  # mesh, assembly, AMG set-up, first solve
    setup = time.perf_counter() - t0
    n_cells = sensor.layout_mesh.mesh.n_cells
    n_nodes = sensor.layout_mesh.mesh.n_nodes
    inc_times, results, iters = [], [], []
    for t in times[1:]:
        t0 = time.perf_counter()
        res = sensor.solve_at(scene, t)
        inc_times.append(time.perf_counter() - t0)
        results.append(res.matrix)
        iters.append(res.iterations.mean())
    full_times, errors = [], []
    tight = SolverConfig(rtol=1e-11, energy_tol=0.0)
    for k in range(0, len(results), full_every):
        # Timing: a full re-solve at the default tolerance (assembly, AMG set-up,
        # cold start) on the same mesh. Accuracy: against a tight full re-solve.
        t0 = time.perf_counter()
        fresh = sensor_with(mesh)
        fresh._mesh = sensor.layout_mesh
        fresh.solve_at(scene, times[k + 1])
        full_times.append(time.perf_counter() - t0)
        ref_sensor = sensor_with(mesh, tight)
        ref_sensor._mesh = sensor.layout_mesh
        ref = ref_sensor.solve_at(scene, times[k + 1]).matrix
        errors.append(np.abs(results[k] - ref).max() / np.abs(ref).max())
    inc = np.median(inc_times)
    full = np.median(full_times)
    print(f"{label}: {n_cells} tets, {n_nodes} nodes, 6 electrodes, {frames} frames at 30 Hz")
    print(f"  set-up (mesh, assembly, AMG, first solve): {setup * 1e3:8.1f} ms")
    print(
        f"  incremental update, median:               {inc * 1e3:8.1f} ms  "
        f"({1 / inc:5.1f} updates/s; p90 {np.percentile(inc_times, 90) * 1e3:.1f} ms; "
        f"mean CG iterations per terminal {np.mean(iters):.1f})"
    )
    print(
        f"  full re-solve (assembly + AMG set-up + cold solve), median: "
        f"{full * 1e3:8.1f} ms  -> incremental is x{full / inc:.1f} faster"
    )
    print(f"  max |C_incremental - C_full(rtol 1e-11)| / max|C|: {max(errors):.2e}")
    lm = sensor.layout_mesh
    anchor = float(np.median([skfem_pyamg_anchor(lm.mesh.points, lm.mesh.cells, lm.terminal_nodes,
                                                 lm.ground_nodes, lm.permittivity) for _ in range(3)]))
    print(f"  anchor: plain scikit-fem assembly + pyamg set-up + 6 cold CG solves, same mesh: "
          f"{anchor * 1e3:8.1f} ms; incremental / anchor = {inc / anchor:.3f}")
    if condense:
        run_condensed(mesh, sensor, scene, times, inc_times, full_every)


def run_condensed(mesh: MeshSettings, plain, scene, times, plain_times, full_every: int) -> None:
    """The same frames with static condensation around the run's swept volume."""
    tool = scene.object("tool")
    run_times = np.arange(0.0, tool.motion.length / 0.04, 1 / 30.0)  # the whole T2 run at 30 Hz
    sensor = sensor_with(mesh, SolverConfig(condense=True))
    sensor._mesh = plain.layout_mesh
    t0 = time.perf_counter()
    active = sensor.prepare(scene, run_times)
    sensor.solve_at(scene, times[0])  # factorisation, interface block, AMG, first solve
    setup = time.perf_counter() - t0
    cond = sensor._solver.condensation
    n_nodes = plain.layout_mesh.mesh.n_nodes
    inc_times, errors, iters = [], [], []
    tight = SolverConfig(rtol=1e-11, energy_tol=0.0)
    for k, t in enumerate(times[1:]):
        t0 = time.perf_counter()
        res = sensor.solve_at(scene, t)
        inc_times.append(time.perf_counter() - t0)
        iters.append(res.iterations.mean())
        if k % full_every == 0:
            ref_sensor = sensor_with(mesh, tight)
            ref_sensor._mesh = plain.layout_mesh
            ref = ref_sensor.solve_at(scene, t).matrix
            errors.append(np.abs(res.matrix - ref).max() / np.abs(ref).max())
    inc = np.median(inc_times)
    ref = np.median(plain_times)
    print(
        f"  condensed: active cells {int(active.sum())} of {active.size}; reduced system {cond.n_reduced} "
        f"of {n_nodes} nodes, dense interface block {cond.n_interface}^2, eliminated {len(cond.f)}"
    )
    print(f"    set-up (swept volume, SuperLU factorisation, interface block, AMG, first solve): {setup:8.2f} s")
    print(
        f"    incremental update, median: {inc * 1e3:8.1f} ms (p90 {np.percentile(inc_times, 90) * 1e3:.1f} ms; "
        f"mean CG iterations {np.mean(iters):.1f}) vs {ref * 1e3:.1f} ms uncondensed -> x{ref / inc:.2f}; "
        f"rebuilds {sensor._solver.condensation_builds - 1}"
    )
    print(f"    max |C_condensed - C_full(rtol 1e-11)| / max|C|: {max(errors):.2e}")


def run_paths(label: str, mesh: MeshSettings, frames: int) -> None:
    """The frame solve (refreshed coarse operators, compiled PCG; the default) against the NumPy
    solve it replaced (hierarchy built on each frame's matrix, rebuilt by the changed-rows rule),
    alternating frame by frame in one process, both solved to the readout's noise."""
    scene = printer_scene(PATHS["T2"])
    times = np.arange(frames) / 30.0
    legacy = replace(SolverConfig(), coarse_refresh=False, compiled=False)
    paths = {"frame solve": sensor_with(mesh), "NumPy, rebuilt": sensor_with(mesh, legacy)}
    paths["NumPy, rebuilt"]._mesh = paths["frame solve"].layout_mesh
    for s in paths.values():
        s.capture(scene, times[0])
    spent = {name: ([], [], []) for name in paths}
    worst = 0.0
    for t in times[1:]:
        got = {}
        for name, s in paths.items():
            c0, w0 = time.process_time(), time.perf_counter()
            frame = s.capture(scene, t)
            spent[name][0].append(time.perf_counter() - w0)
            spent[name][1].append(time.process_time() - c0)
            spent[name][2].append(frame.iterations.max())
            got[name] = frame.maxwell
        worst = max(worst, float(np.abs(got["frame solve"] - got["NumPy, rebuilt"]).max()))
    atol = paths["frame solve"].frame_solver_config.capacitance_atol
    print(f"{label}, the two solves alternating ({frames - 1} frames):")
    for name, (wall, cpu, its) in spent.items():
        print(f"  {name:15s}: {np.median(wall) * 1e3:7.1f} ms median wall, {np.median(cpu) * 1e3:7.1f} ms median CPU, "
              f"CG iterations {np.mean(its):.1f} (largest column)")
    scale = f"{worst / atol:.2f} x capacitance_atol" if atol > 0 else \
        f"{worst / np.abs(got['frame solve']).max():.1e} of the largest entry; relative energy_tol"
    print(f"  largest Maxwell difference: {worst * 1e15:.4f} fF ({scale})")


def run_early_stop(label: str, mesh: MeshSettings, frames: int) -> None:
    """The energy rule with and without its early stop at the third CG step (``SolverConfig.early_stop``):
    every frame of both against a tight solve of the same frame (rtol 1e-11, energy rule off), errors
    as a share of the readout-derived ``capacitance_atol``; CPU per frame alternating in one process."""
    scene = printer_scene(PATHS["T2"])
    times = np.arange(frames) / 30.0
    rules = {"classic": sensor_with(mesh, SolverConfig(early_stop=False)), "early": sensor_with(mesh)}
    rules["early"]._mesh = rules["classic"].layout_mesh
    ref_sensor = sensor_with(mesh, SolverConfig(rtol=1e-11, energy_tol=0.0))
    ref_sensor._mesh = rules["classic"].layout_mesh
    for s in rules.values():
        s.capture(scene, times[0])
    got = {name: {"cpu": [], "steps": [], "err": []} for name in rules}
    for t in times[1:]:
        ref = ref_sensor.solve_at(scene, t).matrix
        for name, s in rules.items():
            c0 = time.process_time()
            frame = s.capture(scene, t)
            got[name]["cpu"].append(time.process_time() - c0)
            got[name]["steps"].append(int(frame.iterations.max()))
            got[name]["err"].append(float(np.abs(frame.maxwell - ref).max()))
    atol = rules["early"].frame_solver_config.capacitance_atol
    print(f"{label}, energy rule with and without the early stop ({frames - 1} frames, alternating):")
    for name, g in got.items():
        err = np.array(g["err"]) / atol
        print(f"  {name:8s}: {np.median(g['cpu']) * 1e3:7.1f} ms median CPU, CG steps (largest column) "
              f"{min(g['steps'])}-{max(g['steps'])} (mean {np.mean(g['steps']):.2f}); largest Maxwell error against "
              f"the tight solve {err.max():.3f} x capacitance_atol ({atol * 1e15:.4f} fF; median {np.median(err):.3f})")


def run_gmsh(frames: int) -> None:
    """Printer bed on a gmsh mesh of about the target size: meshing and update times."""
    from twinsense.capacitive.gmsh_mesher import gmsh_version

    # The demo's mesh, finer at the stripe edges, meshed by gmsh.
    mesh = replace(demo_mesh_settings(), h_min=2.5e-3, growth=1.5, h_refine=0.01, use_cache=False, mesher="gmsh")
    sensor = sensor_with(mesh)
    t0 = time.perf_counter()
    lm = sensor.layout_mesh
    t_mesh = time.perf_counter() - t0
    scene = printer_scene(PATHS["T2"])
    times = np.arange(frames) / 30.0
    sensor.solve_at(scene, times[0])
    inc_times = []
    for t in times[1:]:
        t0 = time.perf_counter()
        sensor.solve_at(scene, t)
        inc_times.append(time.perf_counter() - t0)
    inc = np.median(inc_times)
    print(f"gmsh {gmsh_version()} mesher: {lm.mesh.n_cells} tets, {lm.mesh.n_nodes} nodes, meshing {t_mesh:.2f} s")
    print(f"  incremental update, median: {inc * 1e3:8.1f} ms ({1 / inc:5.1f} updates/s)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=91)
    ap.add_argument("--full-every", type=int, default=15)
    ap.add_argument("--skip-condense", action="store_true")
    ap.add_argument("--skip-gmsh", action="store_true")
    ap.add_argument("--paths-only", action="store_true", help="only the frame solve against the NumPy one")
    ap.add_argument("--early-stop-only", action="store_true", help="only the energy rule with and without its "
                    "early stop, every frame against a tight solve")
    args = ap.parse_args()
    print_machine()
    if args.early_stop_only:
        for label, mesh in CASES.items():
            run_early_stop(label, mesh, args.frames)
        print_load_at_end()
        return
    if args.paths_only:
        for label, mesh in CASES.items():
            run_paths(label, mesh, args.frames)
        print_load_at_end()
        return
    for label, mesh in CASES.items():
        run_case(label, mesh, args.frames, args.full_every, condense=not args.skip_condense)
    if not args.skip_gmsh:
        run_gmsh(args.frames)
    print_load_at_end()


if __name__ == "__main__":
    main()
