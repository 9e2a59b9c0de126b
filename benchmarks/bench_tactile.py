"""Tactile skin throughput: the mechanics of an 8 x 8 skin with two fingertips.

The skin: 20 mm x 20 mm, 2 mm Ecoflex 00-30 dielectric under a 0.5 mm TPU
cover, bonded to a rigid carrier; taxel pitch 2.5 mm. Two meshes:

- ``3 cells/taxel``: h_xy = 0.833 mm, 4 + 1 cells through the layers;
- ``4 cells/taxel``: h_xy = 0.625 mm, 5 + 2 cells (graded to 0.25 mm at the top).

Per frame two spherical fingertips (R = 8 mm and 6 mm) press 0.10-0.15 mm
and move 0.1 mm between frames (the warm start follows them). Timed:
``ElasticBody`` construction once (assembly, nested-dissection SuperLU
factorisation, Schur-complement compliance), and ``ElasticBody.solve``
(contact active set, displacement of every node, strain check), with the
default nodal volumetric average and with plain P1 (``volumetric="element"``,
sparser factor, locks at nu = 0.49), and with ``store_response=True``
(unit responses kept: a longer build, a sum over the contact nodes per frame).

Same-run anchor: one plain ``scipy.sparse.linalg.splu`` solve (default
COLAMD ordering) of the same constrained stiffness, factorised before
timing, with one right-hand side.

The electrical part of the tactile frame (electrostatics on the deformed
stack) is timed by ``electrical_section``: whole frames of ``skin_patch_8x8``
with the Maxwell solve in NumPy and in compiled loops, in the same run,
wall time and process CPU time (the machine is shared: CPU time is the
figure that load moves least).

Run:  .venv/bin/python benchmarks/bench_tactile.py [--electrical [--before REV] | --levers | --cycle-noise]
      (--electrical: whole frames only; --before REV: also the Maxwell solve of git revision REV's
      framesolver.py, same run, for revisions whose framesolver.py imports the shared kernels of
      capacitive/kernels.py (e1a994a and later); --levers: the Maxwell-solve variants of
      docs/tactile.md, Speed; --cycle-noise: the float32 cycle without the assembly's rounding
      noise against one keeping every entry, skin_patch_8x8 and 16x16)
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse.linalg as spla
from _timing import best_and_median, print_anchor, print_load_at_end, print_machine, skfem_pyamg_anchor

from twinsense.capacitive.mechanics import ElasticBody, Indenter, elastic_material, skin_mesh
from twinsense.capacitive.mechanics.elasticity import stiffness

SIZE = (20e-3, 20e-3)
LAYERS = (2.0e-3, 0.5e-3)
MATERIALS = ("ecoflex_0030", "tpu_cover")
MESHES = {
    "3 cells/taxel": {"h_xy": 2.5e-3 / 3, "h_top": 0.5e-3, "h_z": 0.5e-3},
    "4 cells/taxel": {"h_xy": 2.5e-3 / 4, "h_top": 0.25e-3, "h_z": 0.5e-3},
}


def fingertips(k: int) -> list[Indenter]:
    """Two spheres at frame ``k``: moving 0.1 mm per frame, pressing 0.10-0.15 mm."""
    top = sum(LAYERS)
    dx = 0.1e-3 * (k % 20)
    d1 = 0.10e-3 + 0.05e-3 * (k % 2)
    return [Indenter.sphere((-5e-3 + dx, -2e-3, top + 8e-3 - d1), 8e-3, "index"),
            Indenter.sphere((5e-3 - dx, 3e-3, top + 6e-3 - 0.12e-3), 6e-3, "thumb")]


def anchor_solve(lm) -> float:
    """Median seconds of one plain splu solve (COLAMD) of the same constrained stiffness."""
    p, t = lm.mesh.p.T, lm.mesh.t.T
    mats = [elastic_material(m) for m in MATERIALS]
    lam = np.array([m.lame[0] for m in mats])[lm.element_layer]
    mu = np.array([m.lame[1] for m in mats])[lm.element_layer]
    k = stiffness(p, t, lam, mu)
    free = np.flatnonzero(~np.repeat(lm.fixed, 3))
    lu = spla.splu(k[free][:, free].tocsc())
    b = np.random.default_rng(0).standard_normal(len(free))
    return best_and_median(lambda: lu.solve(b), repeats=15)[1]


def mechanics_section() -> None:
    print("mechanics: 20 x 20 mm skin, 2 mm ecoflex_0030 + 0.5 mm tpu_cover, 8 x 8 taxels at 2.5 mm, "
          "two moving fingertips")
    variants = (("nodal", False), ("nodal", True), ("element", False))
    for (label, kw), (volumetric, store) in [(m, var) for m in MESHES.items() for var in variants]:
        lm = skin_mesh(SIZE, LAYERS, **kw)
        t0 = time.perf_counter()
        body = ElasticBody.layered(lm, MATERIALS, volumetric=volumetric, store_response=store)
        build = time.perf_counter() - t0
        n_dof = 3 * int((~lm.fixed).sum())
        frames = iter(range(10**6))
        body.solve(fingertips(0))
        best, med = best_and_median(lambda b=body, f=frames: b.solve(fingertips(next(f))), repeats=40)
        sol = body.solve(fingertips(3))
        print(f"  {label}, volumetric={volumetric}, store_response={store}: {lm.mesh.p.shape[1]} nodes, "
              f"{lm.mesh.t.shape[1]} tets, {n_dof} dofs, {len(body.top_nodes)} contact nodes; build {build:.2f} s")
        print(f"    solve, 2 contacts          {best * 1e3:7.2f} ms best {med * 1e3:7.2f} ms median"
              f"  -> {1 / med:6.0f} frames/s  (forces {sol.force[0]:.3f} N, {sol.force[1]:.3f} N; "
              f"{int(sol.active.sum())} contact nodes; max strain {sol.max_strain:.3f})")
        print_anchor("one splu solve (COLAMD), same stiffness", anchor_solve(lm), med)


def electrical_section(before: str | None = None) -> None:
    """Whole tactile frames of the ``skin_patch_8x8`` preset: contact solve, deformed electrostatics, readout.

    Variants in the same run, alternating blocks of frames (the load drifts
    within a run): the compiled solve without and with the local correction
    of the warm start (``local_correction``), the latter with its column
    groups on 1 and 2 threads; with ``before`` (a git revision), first the
    compiled solve of that revision's ``framesolver.py`` on the same skin.
    (``compiled_solver=False`` runs the proximity sensor's ``MaxwellSolver``,
    timed by that sensor's benchmarks.)
    """
    from twinsense.capacitive.tactile import make_tactile

    variants = {"compiled, no local correction": {"local_correction": False, "solver_threads": 1},
                "compiled, local correction, 1 thread": {"solver_threads": 1},
                "compiled, local correction, 2 threads": {"solver_threads": 2}}
    skins = {label: make_tactile("skin_patch_8x8", **kw) for label, kw in variants.items()}
    if before is not None:
        label = f"compiled solve of {before}"
        skins = {label: _skin_with_old_solver(before), **skins}
    rows = _whole_frames(skins)
    stack = next(iter(skins.values())).stack
    m = stack.mesh
    print(f"electrical: skin_patch_8x8 (8 x 8 at 4 mm, 1.5 mm ecoflex_0030 + 0.5 mm pdms_sylgard184), "
          f"{m.n_nodes} nodes, {m.n_cells} tets, {len(stack.terminals)} electrodes")
    names = ("contact (objects -> heights -> active set -> node displacement)", "re-assembly of moved cells",
             "scene objects on the air cells", "Maxwell solve (warm AMG-PCG, 16 columns)")
    for label, r in rows.items():
        print(f"  {label}: first frame (assembly, AMG, baseline, elastic body, calibrations) {r['first']:.1f} s")
        print(f"    whole frame, 2 moving contacts {r['best'] * 1e3:7.1f} ms best {r['med'] * 1e3:7.1f} ms median"
              f"  -> {1 / r['med']:5.1f} frames/s; process CPU {r['cpu'] * 1e3:6.1f} ms median"
              f" -> {1 / r['cpu']:5.1f} frames/s of one core")
        print(f"    whole frame, contacts still    {r['s_best'] * 1e3:7.1f} ms best {r['s_med'] * 1e3:7.1f} ms median"
              f"  -> {1 / r['s_med']:5.1f} frames/s (contact and Maxwell matrix reused)")
        for name, wall, cpu in zip(names, r["stages"], r["stages_cpu"], strict=True):
            print(f"      {name:<66s} {wall * 1e3:7.1f} ms median wall {cpu * 1e3:7.1f} ms CPU")
        print(f"    PCG iterations per moving frame: {r['iters']:.2f} (most in one column), "
              f"{r['col_iters']:.1f} (all columns); local correction on {r['local']:.0f} nodes (mean)")
    labels = list(rows)
    base = labels[0]
    for b in labels[1:]:
        before_r, after = rows[base], rows[b]
        print(f"  {b} / {base}, same run: whole moving frame {after['med'] / before_r['med']:.2f} (wall median), "
              f"{after['cpu'] / before_r['cpu']:.2f} (CPU median); Maxwell solve "
              f"{after['stages'][3] / before_r['stages'][3]:.2f} (wall median), "
              f"{after['stages_cpu'][3] / before_r['stages_cpu'][3]:.2f} (CPU median)")
    anchor = skfem_pyamg_anchor(m.points, m.cells, stack.terminals, stack.ground, stack.permittivity)
    for label, r in rows.items():
        print_anchor(f"scikit-fem + pyamg cold solve, same mesh ({label})", anchor, r["med"])


def _skin_with_old_solver(rev: str):
    """A ``skin_patch_8x8`` whose Maxwell solve is ``framesolver.py`` as of git revision ``rev``."""
    import importlib.util
    import subprocess
    import sys
    from pathlib import Path

    from twinsense.capacitive.tactile import make_tactile

    path = "src/twinsense/capacitive/tactile/framesolver.py"
    root = Path(__file__).resolve().parent.parent
    source = subprocess.run(["git", "show", f"{rev}:{path}"], cwd=root, check=True, capture_output=True,
                            text=True).stdout
    spec = importlib.util.spec_from_loader(f"framesolver_{rev}", loader=None)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    exec(compile(source, f"{rev}:{path}", "exec"), module.__dict__)  # the project's own file at REV
    skin = make_tactile("skin_patch_8x8", solver_threads=1)
    es = skin.electrostatics
    es.solver = module.FrameSolver(es.system, skin.config.solver, 1)
    return skin


def _whole_frames(skins: dict, blocks: int = 6, per_block: int = 5, contexts: dict | None = None) -> dict:
    """Timings of whole frames of each skin, alternating blocks of ``per_block`` frames (seconds;
    ``cpu``: process CPU time per frame). ``contexts``: {label: a context manager factory} entered
    around each of that skin's frames (default: none)."""
    import contextlib

    contexts = contexts or {}
    from twinsense import Pose, Scene, Sphere

    lay = next(iter(skins.values())).config.layout
    top = lay.total_thickness

    # One geometry per finger, shared by every frame's scene as in a run (a
    # new Sphere per frame would re-tessellate it for its bounds, ~16 ms a
    # frame under load, which is the scene's cost, not the skin's).
    index_tip, thumb_tip = Sphere(9e-3), Sphere(9e-3)

    def scene(k: int) -> Scene:
        # Two grounded fingertips (R = 9 mm) pressing 0.10-0.15 mm, moving 0.1 mm per frame.
        sc = Scene()
        dx = 0.1e-3 * (k % 20)
        d1 = 0.10e-3 + 0.05e-3 * (k % 2)
        sc.add_object("index", index_tip, "human_skin", pose=Pose((-6e-3 + dx, -6e-3, top + 9e-3 - d1)))
        sc.add_object("thumb", thumb_tip, "human_skin", pose=Pose((6e-3 - dx, 6e-3, top + 9e-3 - 0.12e-3)))
        return sc

    scenes = [scene(k) for k in range(1, 61)]
    out = {}
    def ctx(label):
        return contexts.get(label, contextlib.nullcontext)()

    for label, skin in skins.items():
        t0 = time.perf_counter()
        with ctx(label):
            skin.capture(scene(0), 0.0)
        out[label] = {"first": time.perf_counter() - t0, "wall": [], "cpu": [], "stages": [], "iters": [], "local": []}
        for sc in scenes[:3]:  # the scenes' own geometry caches, not the skin's, are warmed here
            with ctx(label):
                skin.capture(sc, 0.0)
    k = 3
    for _ in range(blocks):
        for label, skin in skins.items():
            r = out[label]
            for q in range(per_block):
                sc = scenes[(k + q) % 60]
                with ctx(label):
                    w0, c0 = time.perf_counter(), time.process_time()
                    skin.capture(sc, 0.0)
                    r["wall"].append(time.perf_counter() - w0)
                    r["cpu"].append(time.process_time() - c0)
                r["iters"].append(skin._last_result.iterations)
                r["local"].append(getattr(skin.electrostatics.solver, "local_nodes", 0))
            for q in range(per_block):
                with ctx(label):
                    r["stages"].append(_frame_stages(skin, scenes[(k + per_block + q) % 60]))
        k += 2 * per_block
    for label, skin in skins.items():
        r = out[label]
        still = scenes[5]
        with ctx(label):
            skin.capture(still, 0.0)
            s_best, s_med = best_and_median(lambda s=skin, sc=still: s.capture(sc, 0.0), repeats=10)
        stages = np.array(r["stages"])
        r.update(best=float(np.min(r["wall"])), med=float(np.median(r["wall"])), cpu=float(np.median(r["cpu"])),
                 s_best=s_best, s_med=s_med, stages=np.median(stages[:, 0], axis=0),
                 stages_cpu=np.median(stages[:, 1], axis=0),
                 iters=float(np.mean([i.max() for i in r["iters"]])),
                 col_iters=float(np.mean([i.sum() for i in r["iters"]])), local=float(np.mean(r["local"])))
    return out


def _frame_stages(skin, scene) -> list[list[float]]:
    """[wall, CPU] seconds of the stages of one moving frame, in the order :meth:`TactileSensor.solve_at` runs them."""
    from twinsense.capacitive.coupling import inclusions_from_scene

    es = skin.electrostatics
    pose = skin.mount.pose_at(scene, 0.0)
    marks = [(time.perf_counter(), time.process_time())]
    u, _, _ = skin._contact(scene, 0.0, pose)
    marks.append((time.perf_counter(), time.process_time()))
    es.set_displacement(u)
    marks.append((time.perf_counter(), time.process_time()))
    es.set_objects(inclusions_from_scene(scene, 0.0, skin.kind), skin_to_world=pose)
    marks.append((time.perf_counter(), time.process_time()))
    skin._last_result = es.solve()
    marks.append((time.perf_counter(), time.process_time()))
    m = np.array(marks)
    return np.diff(m, axis=0).T.tolist()


def cycle_noise_section() -> None:
    """Whole frames of ``skin_patch_8x8`` and ``skin_patch_16x16`` with the float32 V-cycle as built
    (without the assembly's rounding noise, ``amg.CYCLE_NOISE``) against the same skin whose cycle keeps
    every entry (``CYCLE_NOISE = 0`` while its frames run), alternating blocks of frames in one process;
    the same CG steps are expected (docs/capacitive-accuracy.md, the cycle without the rounding noise)."""
    import contextlib

    from twinsense.capacitive import amg
    from twinsense.capacitive.tactile import make_tactile

    @contextlib.contextmanager
    def every_entry():
        kept = amg.CYCLE_NOISE
        amg.CYCLE_NOISE = 0.0
        try:
            yield
        finally:
            amg.CYCLE_NOISE = kept

    for preset in ("skin_patch_8x8", "skin_patch_16x16"):
        new, old = f"{preset}, cycle without the rounding noise", f"{preset}, cycle keeping every entry"
        skins = {old: make_tactile(preset, solver_threads=1), new: make_tactile(preset, solver_threads=1)}
        rows = _whole_frames(skins, contexts={old: every_entry})
        for label, r in rows.items():
            print(f"  {label}: whole moving frame {r['med'] * 1e3:7.1f} ms median wall, process CPU "
                  f"{r['cpu'] * 1e3:6.1f} ms median; Maxwell solve {r['stages'][3] * 1e3:6.1f} ms wall, "
                  f"{r['stages_cpu'][3] * 1e3:6.1f} ms CPU median; CG steps per frame {r['col_iters']:.1f} "
                  "(all columns)")
        print(f"  {preset}: without / keeping the noise, same run: whole frame CPU "
              f"{rows[new]['cpu'] / rows[old]['cpu']:.2f}, Maxwell solve CPU "
              f"{rows[new]['stages_cpu'][3] / rows[old]['stages_cpu'][3]:.2f}")


def levers_section(frames: int = 43) -> None:
    """The Maxwell-solve variants of docs/tactile.md (Speed), on the frames of ``_whole_frames``' sequence.

    Records the deformed systems of ``frames`` solves of a ``skin_patch_8x8``
    run (calibrations included; the first three are left out of the
    figures), solves each to a residual of 1e-13 as the reference, and
    replays the sequence with each variant: warm start, AMG hierarchy kept
    with its finest level swapped, block CG with an energy rule.
    Errors are the largest entry of the Maxwell matrix against the reference
    in AD7147 LSB; CG steps are per frame, slowest column and all columns.
    """
    from twinsense import Pose, Scene, Sphere
    from twinsense.capacitive.amg import BlockAMG
    from twinsense.capacitive.pcg import block_pcg
    from twinsense.capacitive.tactile import make_tactile
    from twinsense.capacitive.tactile.framesolver import system_blocks
    from twinsense.capacitive.tactile.readout import AD7147_READOUT
    from twinsense.capacitive.tactile.subdomain import correct_locally

    lsb = AD7147_READOUT.resolution
    skin = make_tactile("skin_patch_8x8")
    es = skin.electrostatics
    top = skin.config.layout.total_thickness
    tips = Sphere(9e-3), Sphere(9e-3)
    recorded = []
    solve = es.solve

    def recording():
        recorded.append(system_blocks(es.system))
        return solve()

    es.solve = recording
    k = 0
    while len(recorded) < frames:
        sc = Scene()
        dx, d1 = 0.1e-3 * (k % 20), 0.10e-3 + 0.05e-3 * (k % 2)
        sc.add_object("index", tips[0], "human_skin", pose=Pose((-6e-3 + dx, -6e-3, top + 9e-3 - d1)))
        sc.add_object("thumb", tips[1], "human_skin", pose=Pose((6e-3 - dx, 6e-3, top + 9e-3 - 0.12e-3)))
        skin.capture(sc, 0.0)
        k += 1
    recorded = recorded[:frames]
    exact = []
    for A, K, B, fixed, X_fixed in recorded:
        X, _ = block_pcg(A, B, X_fixed, BlockAMG(A), 1e-13, 2000, free=~fixed)
        exact.append(X.T @ (K @ X))

    def replay(rule, start="previous", coarse="kept", basis=0, local=False):
        ml, history, errors, steps = None, [], [], []
        for f, ((A, K, B, fixed, X_fixed), C_ref) in enumerate(zip(recorded, exact, strict=True)):
            if ml is None or coarse == "rebuilt":
                ml = BlockAMG(A)
            else:
                ml.set_fine(A)
                if coarse == "galerkin":
                    _galerkin_coarse(ml)
            X0 = X_fixed.copy()
            if history:
                X0 = history[-1].copy()
                if start == "extrapolated" and len(history) > 1:
                    X0 = 2.0 * history[-1] - history[-2]
                X0[fixed] = X_fixed[fixed]
                if basis:
                    X0 = _galerkin_start(A, B, X0, history, basis, fixed)
                if local:
                    R = np.ascontiguousarray(B - A @ X0)
                    correct_locally(A, B, X0, R, np.einsum("ij,ij->j", R, R), ~fixed)
            X, it = _pcg_with_rule(A, B, X0, ml, np.einsum("ij,ij->j", X0, K @ X0), rule, ~fixed)
            history = [*history, X][-4:]
            if f >= 3:
                errors.append(np.abs(X.T @ (K @ X) - C_ref).max() / lsb)
                steps.append(it)
        steps = np.array(steps)
        return max(errors), float(np.median(errors)), steps.max(axis=1).mean(), steps.sum(axis=1).mean()

    variants = [
        ("energy rule, 1e-5, start corrected locally (default)", {"rule": lambda e: 1e-5 * np.abs(e), "local": True}),
        ("energy rule, 1e-5 of each capacitance", {"rule": lambda e: 1e-5 * np.abs(e)}),
        ("energy rule, 1e-6", {"rule": lambda e: 1e-6 * np.abs(e)}),
        *[(f"absolute rule, {f} LSB per column", {"rule": lambda e, f=f: np.full_like(e, f * lsb)})
          for f in (0.5, 0.25, 0.1)],
        ("start extrapolated from two frames", {"rule": lambda e: 1e-5 * np.abs(e), "start": "extrapolated"}),
        *[(f"Galerkin start on the last {m} frame-to-frame changes", {"rule": lambda e: 1e-5 * np.abs(e),
                                                                      "basis": m}) for m in (1, 2, 3)],
        ("coarse levels recomputed (P^T A P) every frame", {"rule": lambda e: 1e-5 * np.abs(e), "coarse": "galerkin"}),
        ("AMG hierarchy rebuilt every frame", {"rule": lambda e: 1e-5 * np.abs(e), "coarse": "rebuilt"}),
    ]
    print(f"levers: {frames - 3} recorded frames of skin_patch_8x8, errors against a 1e-13 residual solve "
          f"(AD7147 LSB = {lsb * 1e15:.3f} fF)")
    for label, kw in variants:
        worst, median, slowest, total = replay(**kw)
        print(f"  {label:<58s} largest error {worst:5.2f} LSB (median {median:5.3f}); CG steps: "
              f"slowest column {slowest:4.2f}, all columns {total:5.1f}")


def _pcg_with_rule(A, B, X0, precond, energy, rule, free):
    """Block PCG whose energy rule stops a column when its estimated tail is below ``rule(energy)`` [F]."""
    from twinsense.capacitive.pcg import _EnergyTail

    X = X0.copy()
    R = B - A @ X
    t = B.shape[1]
    iters = np.zeros(t, int)
    active = np.arange(t)
    tail = _EnergyTail.start(energy)
    mask = free.astype(float)[:, None]
    Z = precond(R) * mask
    P = Z.copy()
    rz = np.einsum("ij,ij->j", R, Z)
    for _ in range(500):
        AP = A @ P
        alpha = rz / np.einsum("ij,ij->j", P, AP)
        X[:, active] += alpha * P
        Ra = R[:, active] - alpha * AP
        R[:, active] = Ra
        iters[active] += 1
        drop = alpha * rz
        # _EnergyTail.unconverged with a per-column absolute tolerance: tol = rule(E) / E.
        tol = rule(tail.energy[active] - drop) / np.abs(tail.energy[active] - drop)
        still = np.array([tail.unconverged(active[q:q + 1], drop[q:q + 1], tol[q])[0] for q in range(len(active))])
        if not np.any(still):
            return X, iters
        active, Ra, P, rz = active[still], Ra[:, still], P[:, still], rz[still]
        Z = precond(Ra) * mask
        rz_new = np.einsum("ij,ij->j", Ra, Z)
        P = Z + (rz_new / rz) * P
        rz = rz_new
    raise RuntimeError("no convergence in 500 steps")


def _galerkin_coarse(ml) -> None:
    """Recompute a BlockAMG's coarse operators from its current finest level (aggregates kept)."""
    import scipy.linalg as sla
    import scipy.sparse as sp

    for lvl in range(len(ml.P)):
        ml.A[lvl + 1] = sp.csr_matrix(ml.R[lvl] @ ml.A[lvl] @ ml.P[lvl])
    coarse = ml.A[-1].toarray()
    empty = np.diag(coarse) <= 0
    coarse[empty, empty] = 1.0
    coarse += 1e-14 * np.trace(coarse) / len(coarse) * np.eye(len(coarse))
    ml._chol = sla.cho_factor(coarse)


def _galerkin_start(A, B, X0, history, m, fixed):
    """X0 improved per column by the energy minimum over the span of the last ``m`` solution changes."""
    R0 = B - A @ X0
    W = [history[-1 - q] - history[-2 - q] for q in range(min(m, len(history) - 1))]
    if not W:
        return X0
    for w in W:
        w[fixed] = 0.0
    AW = [A @ w for w in W]
    X = X0.copy()
    for j in range(X0.shape[1]):
        G = np.array([[w[:, j] @ aw[:, j] for aw in AW] for w in W])
        g = np.array([w[:, j] @ R0[:, j] for w in W])
        c = np.linalg.lstsq(G, g, rcond=1e-12)[0]
        for w, cq in zip(W, c, strict=True):
            X[:, j] += cq * w[:, j]
    return X


def main() -> None:
    import sys

    print_machine()
    if "--levers" in sys.argv[1:]:
        levers_section()
    elif "--cycle-noise" in sys.argv[1:]:
        cycle_noise_section()
    else:
        if "--electrical" not in sys.argv[1:]:
            mechanics_section()
        args = sys.argv[1:]
        electrical_section(args[args.index("--before") + 1] if "--before" in args else None)
    print_load_at_end()


if __name__ == "__main__":
    main()
