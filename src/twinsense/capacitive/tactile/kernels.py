"""Compiled per-frame loops of the deformed electrostatics (numba).

A moving contact moves ~15-20 k cells of an 8 x 8 skin by more than
:data:`~twinsense.capacitive.tactile.deformed.MOVE_TOL` each frame (the
displacement decays away from a contact but never reaches zero). In NumPy
their re-assembly is a chain of (m, 4, 4) temporaries, a boolean mask over
every cell and one ``bincount`` over the whole CSR data; here it is three
loops that touch each moved node and cell once. Then the frame solve's own
steps: the warm start's local correction and the fused start of the solve
(the block PCG's loops and the Maxwell matrix from CG's residual are
:mod:`twinsense.capacitive.kernels`').
"""

from __future__ import annotations

import numpy as np

from twinsense.capacitive.kernels import residual_row, split_arrays, split_row
from twinsense.compiled import jit

__all__ = ["grow_rows", "moved_cells", "residual_rows", "residual_seeds", "restamp",
           "start_system", "submatrix", "tet_stiffness_nb", "update_cell_boxes"]


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
        c = sel[q]
        i0, i1, i2, i3 = cells[c, 0], cells[c, 1], cells[c, 2], cells[c, 3]
        # Edges as scalars: a 3-vector expression (points[i] - p0) would be a
        # heap allocation per cell, ~5x the arithmetic (measured 2.9 against
        # 0.55 ms on 17k cells, the same bits).
        x0, y0, z0 = points[i0, 0], points[i0, 1], points[i0, 2]
        e10, e11, e12 = points[i1, 0] - x0, points[i1, 1] - y0, points[i1, 2] - z0
        e20, e21, e22 = points[i2, 0] - x0, points[i2, 1] - y0, points[i2, 2] - z0
        e30, e31, e32 = points[i3, 0] - x0, points[i3, 1] - y0, points[i3, 2] - z0
        g[1, 0] = e21 * e32 - e22 * e31
        g[1, 1] = e22 * e30 - e20 * e32
        g[1, 2] = e20 * e31 - e21 * e30
        g[2, 0] = e31 * e12 - e32 * e11
        g[2, 1] = e32 * e10 - e30 * e12
        g[2, 2] = e30 * e11 - e31 * e10
        g[3, 0] = e11 * e22 - e12 * e21
        g[3, 1] = e12 * e20 - e10 * e22
        g[3, 2] = e10 * e21 - e11 * e20
        for d in range(3):
            g[0, d] = -(g[1, d] + g[2, d] + g[3, d])
        det = e10 * g[1, 0] + e11 * g[1, 1] + e12 * g[1, 2]  # 6 V
        vol[q] = det / 6.0
        s = 1.0 / (6.0 * det)
        for a in range(4):
            for b in range(a, 4):
                v = (g[a, 0] * g[b, 0] + g[a, 1] * g[b, 1] + g[a, 2] * g[b, 2]) * s
                k[q, a, b] = v
                k[q, b, a] = v
    return k, vol


@jit
def update_cell_boxes(points, cells, sel, centroids, lo, hi):  # pragma: no cover - compiled
    """Centroids and bounding boxes (each (m, 3)) of ``cells[sel]`` from ``points`` (n, 3), in place."""
    for q in range(sel.shape[0]):
        c = sel[q]
        for d in range(3):
            v = points[cells[c, 0], d]
            s = v
            a = v
            b = v
            for k in range(1, cells.shape[1]):
                v = points[cells[c, k], d]
                s += v
                a = min(a, v)
                b = max(b, v)
            centroids[c, d] = s / cells.shape[1]
            lo[c, d] = a
            hi[c, d] = b


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


# -- the local correction of the warm start (capacitive/tactile/subdomain.py) -----------


@jit
def residual_seeds(indptr, indices, data, R, share):  # pragma: no cover - compiled
    """(n,) bool: rows whose residual energy ``sum_k R[i, k]^2 / A_ii`` exceeds ``share`` of the largest.

    ``R`` (n, c) the residual block of the CSR ``A`` (n, n); a row without a
    positive diagonal never qualifies. ``r_i^2 / A_ii`` is the energy a
    Jacobi step on row ``i`` alone would remove: it ranks rows by what
    relaxing them is worth, whatever their stiffness.
    """
    n, c = R.shape
    score = np.zeros(n)
    top = 0.0
    for i in range(n):
        d = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            if indices[p] == i:
                d = data[p]
        if d > 0.0:
            s = 0.0
            for k in range(c):
                s += R[i, k] * R[i, k]
            score[i] = s / d
            top = max(top, score[i])
    mark = np.zeros(n, np.bool_)
    if top > 0.0:
        for i in range(n):
            mark[i] = score[i] > share * top
    return mark


@jit
def grow_rows(indptr, indices, mark, layers, limit):  # pragma: no cover - compiled
    """(n,) bool: ``mark`` grown by up to ``layers`` rings of CSR neighbours, at most ``limit`` rows.

    A ring that would take the set past ``limit`` is not added (the set
    stays as the last ring left it); ``mark`` itself is never cut.
    """
    n = mark.shape[0]
    inside = mark.copy()
    front = np.empty(n, np.int64)
    nxt = np.empty(n, np.int64)
    nf = 0
    for i in range(n):
        if inside[i]:
            front[nf] = i
            nf += 1
    count = nf
    for _ in range(layers):
        nn = 0
        for q in range(nf):
            i = front[q]
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                if not inside[j]:
                    inside[j] = True
                    nxt[nn] = j
                    nn += 1
        if count + nn > limit:
            for q in range(nn):
                inside[nxt[q]] = False
            break
        count += nn
        front, nxt = nxt, front
        nf = nn
    return inside


@jit
def submatrix(indptr, indices, data, rows):  # pragma: no cover - compiled
    """``A[rows][:, rows]`` of a CSR ``A`` as CSR arrays (indptr, indices int32, data); ``rows`` (m,) sorted."""
    n = indptr.shape[0] - 1
    m = rows.shape[0]
    local = np.full(n, -1, np.int64)
    for q in range(m):
        local[rows[q]] = q
    ptr = np.zeros(m + 1, np.int32)
    nnz = 0
    for q in range(m):
        i = rows[q]
        for p in range(indptr[i], indptr[i + 1]):
            if local[indices[p]] >= 0:
                nnz += 1
        ptr[q + 1] = nnz
    ind = np.empty(nnz, np.int32)
    dat = np.empty(nnz)
    k = 0
    for q in range(m):
        i = rows[q]
        for p in range(indptr[i], indptr[i + 1]):
            j = local[indices[p]]
            if j >= 0:
                ind[k] = j
                dat[k] = data[p]
                k += 1
    return ptr, ind, dat


@jit
def residual_rows(indptr, indices, data, B, X, R, rows, rr):  # pragma: no cover - compiled
    """Rows ``rows`` of ``R = B - A X`` recomputed in place; ``rr[k] = |R[:, k]|^2`` over all rows.

    The norms are summed afresh in row order (not corrected by the change),
    so they carry no cancellation and equal :func:`~twinsense.capacitive.kernels.block_residual`'s for
    the same ``R``.
    """
    n, c = X.shape
    for q in range(rows.shape[0]):
        residual_row(indptr, indices, data, B, X, rows[q], R, rows[q])
    rr[:] = 0.0
    for i in range(n):
        for k in range(c):
            rr[k] += R[i, k] * R[i, k]


# -- the frame's start and its Maxwell matrix ------------------------------------------
# The block PCG's own loops (sparse products, updates, V-cycle levels, column copies) are the
# capacitive package's, twinsense.capacitive.kernels: the skin's are those with a run-time width.


@jit
def start_system(indptr, indices, k_data, fixed, column, t, previous):  # pragma: no cover - compiled
    """A frame's Dirichlet system, warm start, start residual and start energies in one pass over the CSR data.

    :func:`~twinsense.capacitive.kernels.dirichlet_split` (the same ``A``, ``K`` and ``B``, zeros left out),
    fused with what the solve computes next from them:

    - ``X0`` (n, t): ``previous`` (n, p) on the free nodes (its first
      ``min(p, t)`` columns, zero beyond), 1 V at column ``column[i]`` on a
      terminal node, 0 on the others (as :func:`~twinsense.capacitive.solver.warm_start`);
    - ``R0 = B - A X0`` (n, t), each row as :func:`~twinsense.capacitive.kernels.block_residual` computes it,
      and ``rr0[k] = |R0[:, k]|^2``;
    - ``energy[k] = X0[:, k]^T K X0[:, k]`` [F]: on a free row ``(K X0)_i =
      (A X0 - B)_i = -R0_i`` (``B`` carries the prescribed nodes' couplings),
      so only a terminal's own rows need their ``K`` row product.

    Returns
    -------
    A : (indptr, indices, data); K : (indptr, indices, data); B, X0, R0 : (n, t) float;
    rr0, energy : (t,) float.
    """
    n = indptr.shape[0] - 1
    p_cols = min(previous.shape[1], t)
    X0 = np.zeros((n, t))
    for i in range(n):
        if fixed[i]:
            if column[i] >= 0:
                X0[i, column[i]] = 1.0
        else:
            for k in range(p_cols):
                X0[i, k] = previous[i, k]
    a_ptr, a_ind, a_dat, k_ptr, k_ind, k_dat, B = split_arrays(indptr, indices, t)
    R0 = np.empty((n, t))
    rr0 = np.zeros(t)
    energy = np.zeros(t)
    na = 0
    nk = 0
    for i in range(n):
        row_k = nk
        na, nk = split_row(indptr, indices, k_data, fixed, column, i, a_ind, a_dat, na, k_ind, k_dat, nk, B)
        a_ptr[i + 1] = na
        k_ptr[i + 1] = nk
        # The row's residual from the row of A just written (a_ptr[i] .. na).
        residual_row(a_ptr, a_ind, a_dat, B, X0, i, R0, i)
        for k in range(t):
            rr0[k] += R0[i, k] * R0[i, k]
        if fixed[i]:
            c = column[i]
            if c >= 0:  # X0[i, c] = 1: the row's charge on its own terminal
                s = 0.0
                for p in range(row_k, nk):
                    s += k_dat[p] * X0[k_ind[p], c]
                energy[c] += s
        else:
            for k in range(t):
                energy[k] -= X0[i, k] * R0[i, k]
    A = (a_ptr, a_ind[:na].copy(), a_dat[:na].copy())
    K = (k_ptr, k_ind[:nk].copy(), k_dat[:nk].copy())
    return A, K, B, X0, R0, rr0, energy


