"""Tactile skin throughput: the mechanics of an 8 x 8 skin with two fingertips.

The skin: 20 mm x 20 mm, 2 mm Ecoflex 00-30 dielectric under a 0.5 mm TPU
cover, bonded to a rigid carrier; taxel pitch 2.5 mm. Two meshes:

- ``3 cells/taxel``: h_xy = 0.833 mm, 4 + 1 cells through the layers;
- ``4 cells/taxel``: h_xy = 0.625 mm, 5 + 2 cells (graded to 0.25 mm at the top).

Per frame two spherical fingertips (R = 8 mm and 6 mm) press 0.10-0.15 mm
and move 0.1 mm between frames (the warm start follows them). Timed:
``ElasticBody`` construction once (assembly, nested-dissection SuperLU
factorisation, Schur-complement compliance), and ``ElasticBody.solve``
(contact active set, displacement of every node, strain check).

Same-run anchor: one plain ``scipy.sparse.linalg.splu`` solve (default
COLAMD ordering) of the same constrained stiffness, factorised before
timing, with one right-hand side.

The electrical part of the tactile frame (electrostatics on the deformed
stack) is timed by ``electrical_section`` when present.

Run:  .venv/bin/python benchmarks/bench_tactile.py
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse.linalg as spla
from _timing import best_and_median, print_anchor, print_load_at_end, print_machine

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
    for label, kw in MESHES.items():
        lm = skin_mesh(SIZE, LAYERS, **kw)
        t0 = time.perf_counter()
        body = ElasticBody.layered(lm, MATERIALS)
        build = time.perf_counter() - t0
        n_dof = 3 * int((~lm.fixed).sum())
        frames = iter(range(10**6))
        body.solve(fingertips(0))
        best, med = best_and_median(lambda b=body, f=frames: b.solve(fingertips(next(f))), repeats=40)
        sol = body.solve(fingertips(3))
        print(f"  {label}: {lm.mesh.p.shape[1]} nodes, {lm.mesh.t.shape[1]} tets, {n_dof} dofs, "
              f"{len(body.top_nodes)} contact nodes; build {build:.2f} s")
        print(f"    solve, 2 contacts          {best * 1e3:7.2f} ms best {med * 1e3:7.2f} ms median"
              f"  -> {1 / med:6.0f} frames/s  (forces {sol.force[0]:.3f} N, {sol.force[1]:.3f} N; "
              f"{int(sol.active.sum())} contact nodes; max strain {sol.max_strain:.3f})")
        print_anchor("one splu solve (COLAMD), same stiffness", anchor_solve(lm), med)


def main() -> None:
    print_machine()
    mechanics_section()
    print_load_at_end()


if __name__ == "__main__":
    main()
