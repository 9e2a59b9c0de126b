"""Compiled per-frame loops of the deformed electrostatics (numba).

A moving contact moves ~15-20 k cells of an 8 x 8 skin by more than
:data:`~twinsense.capacitive.tactile.deformed.MOVE_TOL` each frame (the
displacement decays away from a contact but never reaches zero). In NumPy
their re-assembly is a chain of (m, 4, 4) temporaries, a boolean mask over
every cell and one ``bincount`` over the whole CSR data; here it is three
loops that touch each moved node and cell once.
"""

from __future__ import annotations

import numpy as np

from twinsense.compiled import jit

__all__ = ["moved_cells", "restamp", "tet_stiffness_nb"]


@jit
def moved_cells(u, applied, cells, tol):  # pragma: no cover - compiled
    """Cells with a node whose target displacement ``u`` (n, 3) differs from the applied one by > ``tol`` [m].

    Returns (c,) int64 cell indices and the (n,) bool mask of the moved nodes.
    """
    n = u.shape[0]
    moved = np.zeros(n, np.bool_)
    for i in range(n):
        for d in range(3):
            if abs(u[i, d] - applied[i, d]) > tol:
                moved[i] = True
                break
    out = np.empty(cells.shape[0], np.int64)
    k = 0
    for c in range(cells.shape[0]):
        if moved[cells[c, 0]] or moved[cells[c, 1]] or moved[cells[c, 2]] or moved[cells[c, 3]]:
            out[k] = c
            k += 1
    return out[:k], moved


@jit
def tet_stiffness_nb(points, cells, sel):  # pragma: no cover - compiled
    """Unit-permittivity P1 element matrices (c, 4, 4) [m] and signed volumes (c,) [m^3] of ``cells[sel]``.

    The same algebra as :func:`~twinsense.capacitive.tactile.deformed.tet_stiffness`:
    barycentric gradients from edge cross products, ``K = g g^T / (36 V)``.
    """
    m = sel.shape[0]
    k = np.empty((m, 4, 4))
    vol = np.empty(m)
    g = np.empty((4, 3))
    for q in range(m):
        c = cells[sel[q]]
        p0 = points[c[0]]
        e1 = points[c[1]] - p0
        e2 = points[c[2]] - p0
        e3 = points[c[3]] - p0
        g[1, 0] = e2[1] * e3[2] - e2[2] * e3[1]
        g[1, 1] = e2[2] * e3[0] - e2[0] * e3[2]
        g[1, 2] = e2[0] * e3[1] - e2[1] * e3[0]
        g[2, 0] = e3[1] * e1[2] - e3[2] * e1[1]
        g[2, 1] = e3[2] * e1[0] - e3[0] * e1[2]
        g[2, 2] = e3[0] * e1[1] - e3[1] * e1[0]
        g[3, 0] = e1[1] * e2[2] - e1[2] * e2[1]
        g[3, 1] = e1[2] * e2[0] - e1[0] * e2[2]
        g[3, 2] = e1[0] * e2[1] - e1[1] * e2[0]
        for d in range(3):
            g[0, d] = -(g[1, d] + g[2, d] + g[3, d])
        det = e1[0] * g[1, 0] + e1[1] * g[1, 1] + e1[2] * g[1, 2]  # 6 V
        vol[q] = det / 6.0
        s = 1.0 / (6.0 * det)
        for a in range(4):
            for b in range(a, 4):
                v = (g[a, 0] * g[b, 0] + g[a, 1] * g[b, 1] + g[a, 2] * g[b, 2]) * s
                k[q, a, b] = v
                k[q, b, a] = v
    return k, vol


@jit
def restamp(k_data, slots, local, sel, k_new, eps_new, eps_old, eps0):  # pragma: no cover - compiled
    """Swap the moved cells' stiffness in the CSR data: ``+= eps0 (eps_new K_new - eps_old K_old)``.

    ``slots`` (m, 4, 4) CSR data index of each element entry; ``local`` (m, 4, 4)
    stored unit element matrices, updated to ``k_new`` (c, 4, 4) for ``sel`` (c,).
    """
    for q in range(sel.shape[0]):
        c = sel[q]
        for a in range(4):
            for b in range(4):
                k_data[slots[c, a, b]] += eps0 * (eps_new[q] * k_new[q, a, b] - eps_old[q] * local[c, a, b])
                local[c, a, b] = k_new[q, a, b]
