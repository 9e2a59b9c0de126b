"""Compiled loops of the capacitive per-frame solves (numba): the proximity sensor's and the tactile skin's.

A frame's solve is a handful of passes over the stiffness and the AMG
levels: the Dirichlet split of the system, the coarse operators of the
frame's conductors (masked Galerkin products into fixed patterns), the
sparse products, updates and column inner products of block CG, and the
levels of the V-cycle. In NumPy each is a chain of (n, c) temporaries and
fancy-index copies; here each is one or two loops that touch every row
once. Blocks are C-ordered (n, c), a row's c columns side by side. The
variable-width loops serve any block (the tactile skin's frame solve runs
them, :mod:`~twinsense.capacitive.tactile.framesolver`); the ``...8`` and
``...6`` ones blocks of exactly 8 (:data:`WIDTH`) or 6 columns
(:data:`FIXED_WIDTH`), with the proximity sensor's Gauss-Seidel V-cycle.

Every loop computes a column in the same order whatever the other columns
are, so the result of a column does not depend on the block it is solved in.
"""

from __future__ import annotations

import numpy as np

from twinsense.compiled import jit

__all__ = ["FIXED_WIDTH", "WIDTH", "block_product", "block_residual", "cg_update", "cholesky_columns", "column_dots",
           "cycle_down", "cycle_operator", "cycle_up", "diagonal_split", "dirichlet_split", "dropped_rows_product",
           "first_coarse_update", "group_width", "gs_down6", "gs_down8", "gs_up6", "gs_up8", "lanczos_tridiagonal",
           "maxwell_from_residual", "new_direction", "product_into", "put_columns", "residual6", "residual8",
           "residual_row", "split_arrays", "split_row", "spmm6", "spmm8", "take_columns"]


@jit
def split_arrays(indptr, indices, t):  # pragma: no cover - compiled
    """The outputs :func:`split_row` fills for a CSR pattern of n rows: ``A``'s and ``K``'s
    (indptr (n + 1,) zeros, indices and data (nnz,) uninitialised) and ``B`` (n, t) zeros."""
    n = indptr.shape[0] - 1
    nnz = indptr[n]
    a_ptr = np.zeros(n + 1, indptr.dtype)
    a_ind = np.empty(nnz, indices.dtype)
    a_dat = np.empty(nnz)
    k_ptr = np.zeros(n + 1, indptr.dtype)
    k_ind = np.empty(nnz, indices.dtype)
    k_dat = np.empty(nnz)
    B = np.zeros((n, t))
    return a_ptr, a_ind, a_dat, k_ptr, k_ind, k_dat, B


@jit
def split_row(indptr, indices, k_data, fixed, column, i, a_ind, a_dat, na, k_ind, k_dat, nk, B
              ):  # pragma: no cover - compiled
    """Row ``i`` of :func:`dirichlet_split`: its entries appended to ``A`` at ``na`` and ``K`` at ``nk``,
    its ``B`` terms added; returns the new ``(na, nk)``. The one copy of the split's rule (the
    tactile skin's fused start, :func:`~twinsense.capacitive.tactile.kernels.start_system`, runs it too)."""
    for p in range(indptr[i], indptr[i + 1]):
        j = indices[p]
        v = k_data[p]
        if v == 0.0:
            continue
        k_ind[nk] = j
        k_dat[nk] = v
        nk += 1
        if fixed[i]:
            if j == i:
                a_ind[na] = j
                a_dat[na] = v
                na += 1
                if column[i] >= 0:
                    B[i, column[i]] = v
        elif fixed[j]:
            if column[j] >= 0:
                B[i, column[j]] -= v
        else:
            a_ind[na] = j
            a_dat[na] = v
            na += 1
    return na, nk


@jit
def dirichlet_split(indptr, indices, k_data, fixed, column, t):  # pragma: no cover - compiled
    """The Dirichlet system of a CSR stiffness ``K`` (n, n), exact zeros left out, in one pass.

    The same ``A`` and ``B`` as :meth:`~twinsense.capacitive.fem.ElectrostaticSystem.system`:
    ``A`` is ``K`` with the rows and columns of the prescribed nodes (``fixed``
    (n,) bool) replaced by their diagonal; ``B`` (n, t) is ``-K X_fixed`` on
    the free rows and ``K_ii`` on a node held at 1 V, where ``column`` (n,)
    int64 is the terminal (column of ``B``) of node ``i`` (-1: grounded or free).

    Returns
    -------
    (a_indptr, a_indices, a_data), (k_indptr, k_indices, k_data) without zeros, B (n, t) float.
    """
    n = indptr.shape[0] - 1
    a_ptr, a_ind, a_dat, k_ptr, k_ind, k_dat, B = split_arrays(indptr, indices, t)
    na = 0
    nk = 0
    for i in range(n):
        na, nk = split_row(indptr, indices, k_data, fixed, column, i, a_ind, a_dat, na, k_ind, k_dat, nk, B)
        a_ptr[i + 1] = na
        k_ptr[i + 1] = nk
    return (a_ptr, a_ind[:na].copy(), a_dat[:na].copy()), (k_ptr, k_ind[:nk].copy(), k_dat[:nk].copy()), B


@jit
def product_into(a_ptr, a_ind, a_dat, keep, b_ptr, b_ind, b_dat, c_ptr, c_ind, c_dat):  # pragma: no cover
    """``C = M A M B`` into the fixed CSR pattern ``(c_ptr, c_ind)`` of ``C``; ``c_dat`` is overwritten.

    ``A`` (r, n) and ``B`` (n, m) CSR; ``M = diag(keep)`` with ``keep``
    (max(r, n),) bool (all True: the plain product). Row by row, each entry
    summed in the same order every time (Gustavson's row-wise product).

    Returns
    -------
    bool: False when a product entry falls outside the pattern (``c_dat`` is then invalid).
    """
    nr = c_ptr.shape[0] - 1
    m = 0
    for q in range(c_ind.shape[0]):
        m = max(m, c_ind[q] + 1)
    for q in range(b_ind.shape[0]):
        m = max(m, b_ind[q] + 1)
    slot = np.full(m, -1, np.int64)
    for row in range(nr):
        for q in range(c_ptr[row], c_ptr[row + 1]):
            slot[c_ind[q]] = q
            c_dat[q] = 0.0
        if keep[row]:
            for p in range(a_ptr[row], a_ptr[row + 1]):
                j = a_ind[p]
                w = a_dat[p]
                if w == 0.0 or not keep[j]:  # a stored zero adds nothing, wherever it sits
                    continue
                for u in range(b_ptr[j], b_ptr[j + 1]):
                    q = slot[b_ind[u]]
                    if q < 0:
                        return False
                    c_dat[q] += w * b_dat[u]
        for q in range(c_ptr[row], c_ptr[row + 1]):
            slot[c_ind[q]] = -1
    return True


@jit
def dropped_rows_product(dropped, in_dropped, a_ptr, a_ind, a_dat, p_ptr, p_ind, p_dat, c_ptr, c_ind, g, h
                         ):  # pragma: no cover - compiled
    """The Galerkin terms of the rows ``dropped`` (d,) int64 of ``A`` (n, n), into the pattern of ``P^T A P``.

    ``g = P_D^T A P`` and ``h = P_D^T A P_D``, ``P_D`` the rows ``dropped`` of
    ``P`` (n, nc) (``in_dropped`` (n,) bool marks them); ``g`` and ``h`` are
    overwritten. Then ``P^T M A M P = P^T A P - g - g^T + h`` with ``M`` the
    other rows: the coarse operator of ``A`` with the ``dropped`` unknowns
    prescribed, at a cost that grows with ``d``, not ``n``.
    """
    nc = c_ptr.shape[0] - 1
    slot = np.full(nc, -1, np.int64)
    g[:] = 0.0
    h[:] = 0.0
    for s in range(dropped.shape[0]):
        i = dropped[s]
        for t in range(p_ptr[i], p_ptr[i + 1]):
            row = p_ind[t]
            pi = p_dat[t]
            for q in range(c_ptr[row], c_ptr[row + 1]):
                slot[c_ind[q]] = q
            for p in range(a_ptr[i], a_ptr[i + 1]):
                j = a_ind[p]
                w = pi * a_dat[p]
                for u in range(p_ptr[j], p_ptr[j + 1]):
                    q = slot[p_ind[u]]
                    v = w * p_dat[u]
                    g[q] += v
                    if in_dropped[j]:
                        h[q] += v
            for q in range(c_ptr[row], c_ptr[row + 1]):
                slot[c_ind[q]] = -1


@jit
def block_product(indptr, indices, data, X, Y, w):  # pragma: no cover - compiled
    """``Y = A X`` for a CSR ``A`` (n, n) and a block ``X`` (n, c); ``w[k] = X[:, k] . Y[:, k]``."""
    n, c = X.shape
    w[:] = 0.0
    for i in range(n):
        for k in range(c):
            Y[i, k] = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            a = data[p]
            for k in range(c):
                Y[i, k] += a * X[j, k]
        for k in range(c):
            w[k] += X[i, k] * Y[i, k]


@jit
def cg_update(X, R, P, AP, alpha, rr):  # pragma: no cover - compiled
    """``X += alpha P`` and ``R -= alpha AP`` column by column (n, c); ``rr[k] = |R[:, k]|^2``."""
    n, c = X.shape
    rr[:] = 0.0
    for i in range(n):
        for k in range(c):
            X[i, k] += alpha[k] * P[i, k]
            r = R[i, k] - alpha[k] * AP[i, k]
            R[i, k] = r
            rr[k] += r * r


@jit
def new_direction(P, Z, beta):  # pragma: no cover - compiled
    """``P = Z + beta P`` column by column (n, c)."""
    n, c = P.shape
    for i in range(n):
        for k in range(c):
            P[i, k] = Z[i, k] + beta[k] * P[i, k]



@jit
def residual_row(indptr, indices, data, B, X, i, R, row):  # pragma: no cover - compiled
    """Row ``i`` of ``B - A X`` (blocks (n, c)) into ``R[row]``: the one residual loop of the
    variable-width kernels."""
    c = X.shape[1]
    for k in range(c):
        R[row, k] = B[i, k]
    for p in range(indptr[i], indptr[i + 1]):
        j = indices[p]
        a = data[p]
        for k in range(c):
            R[row, k] -= a * X[j, k]


@jit
def block_residual(indptr, indices, data, B, X, R, rr):  # pragma: no cover - compiled
    """``R = B - A X`` for a CSR ``A`` (n, n) and blocks (n, c); ``rr[k] = |R[:, k]|^2``."""
    n, c = X.shape
    rr[:] = 0.0
    for i in range(n):
        residual_row(indptr, indices, data, B, X, i, R, i)
        for k in range(c):
            rr[k] += R[i, k] * R[i, k]


@jit
def take_columns(M, keep):  # pragma: no cover - compiled
    """(n, len(keep)) C-ordered copy of the columns ``keep`` of ``M`` (n, c)."""
    n = M.shape[0]
    m = keep.shape[0]
    out = np.empty((n, m))
    for i in range(n):
        for q in range(m):
            out[i, q] = M[i, keep[q]]
    return out


@jit
def put_columns(M, cols, S, which):  # pragma: no cover - compiled
    """``M[:, cols[q]] = S[:, which[q]]`` for each q: converged columns back into the whole block, in place.

    ``M`` (n, t), ``S`` (n, c) C-ordered; ``cols``, ``which`` (k,) int. One
    pass over the rows (NumPy's fancy-indexed assignment of strided columns
    takes several).
    """
    n = M.shape[0]
    for i in range(n):
        for q in range(cols.shape[0]):
            M[i, cols[q]] = S[i, which[q]]


@jit
def cholesky_columns(c, lower, B, X):  # pragma: no cover - compiled
    """``X = A^-1 B`` (m, k) from ``scipy.linalg.cho_factor``'s ``(c, lower)`` of ``A`` (m, m).

    Column by column, each in the same order whatever ``k``: unlike LAPACK's
    blocked solve, a column's bytes do not depend on the block it is in.
    """
    m, k = B.shape
    for col in range(k):
        # Forward: F y = b with F = c's lower triangle (lower) or U^T (upper).
        for i in range(m):
            s = B[i, col] * 1.0
            for j in range(i):
                f = c[i, j] if lower else c[j, i]
                s -= f * X[j, col]
            X[i, col] = s / c[i, i]
        # Back: F^T x = y.
        for i in range(m - 1, -1, -1):
            s = X[i, col]
            for j in range(i + 1, m):
                f = c[j, i] if lower else c[i, j]
                s -= f * X[j, col]
            X[i, col] = s / c[i, i]


@jit
def cycle_down(indptr, indices, data, d, B, X, p_indptr, p_indices, p_data, Rc):  # pragma: no cover - compiled
    """A V-cycle level going down, blocks (n, c): Jacobi ``X = d B`` and ``Rc = P^T (B - A X)``.

    ``d`` (n,) damped inverse diagonal; ``P`` (n, nc) the CSR prolongator; ``Rc`` (nc, c) output.
    """
    n, c = B.shape
    for i in range(n):
        for k in range(c):
            X[i, k] = d[i] * B[i, k]
    Rc[:] = 0.0
    r = np.empty((1, c))
    for i in range(n):
        residual_row(indptr, indices, data, B, X, i, r, 0)
        for q in range(p_indptr[i], p_indptr[i + 1]):
            col = p_indices[q]
            w = p_data[q]
            for k in range(c):
                Rc[col, k] += w * r[0, k]


@jit
def cycle_up(indptr, indices, data, d, B, X, p_indptr, p_indices, p_data, Xc, mask, T, rz):  # pragma: no cover
    """A V-cycle level going up, blocks (n, c): ``X += P Xc``, then Jacobi ``X += d (B - A X)``.

    The result is masked (``X *= mask``, zero on prescribed unknowns) and
    ``rz[k] = B[:, k] . X[:, k]``; ``T`` (n, c) is scratch.
    """
    n, c = B.shape
    for i in range(n):
        for q in range(p_indptr[i], p_indptr[i + 1]):
            col = p_indices[q]
            w = p_data[q]
            for k in range(c):
                X[i, k] += w * Xc[col, k]
    for i in range(n):
        residual_row(indptr, indices, data, B, X, i, T, i)
    rz[:] = 0.0
    for i in range(n):
        for k in range(c):
            X[i, k] = (X[i, k] + d[i] * T[i, k]) * mask[i]
            rz[k] += B[i, k] * X[i, k]  # the value as stored (rounded if X is float32)

# Blocks of exactly WIDTH (or 6) columns: the proximity sensor's groups, with a row's products in
# named accumulators (registers). With a loop over a run-time column count the compiler keeps them
# in memory, and the product with A took 1.4-1.8 ms for 6 columns against 0.7-1.1 ms for 8 here
# (docs/capacitive-accuracy.md), so both kinds stay: the tactile skin's blocks shrink as its
# columns converge and split over threads, which a fixed width would pad back. The register loop
# over a row stands in each kernel rather than in one helper returning the sums: a helper gave the
# same bits but took 4.9 against 3.6 ms (residual8) and 5.2 against 4.1 ms (a V-cycle level,
# float32) on a 60k-row test matrix, best of 25. The V-cycle's levels are symmetric Gauss-Seidel
# (gs_down8, gs_up8): the damped-Jacobi levels they replaced cost the same per cycle (a forward
# sweep from zero and the residual after it are one pass over A together, as were Jacobi's start
# and residual) and needed 4-5 CG iterations on the robot-cell skin's reach where these need 4.
WIDTH = 8


@jit
def spmm8(indptr, indices, data, X, Y):  # pragma: no cover - compiled
    """``Y = A X`` for a CSR ``A`` (n, n) and blocks (n, 8)."""
    n = X.shape[0]
    for i in range(n):
        a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            a = data[p]
            x = X[indices[p]]
            a0 += a * x[0]
            a1 += a * x[1]
            a2 += a * x[2]
            a3 += a * x[3]
            a4 += a * x[4]
            a5 += a * x[5]
            a6 += a * x[6]
            a7 += a * x[7]
        y = Y[i]
        y[0] = a0
        y[1] = a1
        y[2] = a2
        y[3] = a3
        y[4] = a4
        y[5] = a5
        y[6] = a6
        y[7] = a7


@jit
def residual8(indptr, indices, data, B, X, R):  # pragma: no cover - compiled
    """``R = B - A X`` for a CSR ``A`` (n, n) and blocks (n, 8) (``R`` may have another dtype)."""
    n = X.shape[0]
    for i in range(n):
        b = B[i]
        a0, a1, a2, a3, a4, a5, a6, a7 = b[0] * 1.0, b[1] * 1.0, b[2] * 1.0, b[3] * 1.0, b[4] * 1.0, \
            b[5] * 1.0, b[6] * 1.0, b[7] * 1.0
        for p in range(indptr[i], indptr[i + 1]):
            a = data[p]
            x = X[indices[p]]
            a0 -= a * x[0]
            a1 -= a * x[1]
            a2 -= a * x[2]
            a3 -= a * x[3]
            a4 -= a * x[4]
            a5 -= a * x[5]
            a6 -= a * x[6]
            a7 -= a * x[7]
        r = R[i]
        r[0] = a0
        r[1] = a1
        r[2] = a2
        r[3] = a3
        r[4] = a4
        r[5] = a5
        r[6] = a6
        r[7] = a7


@jit
def column_dots(X, Y, w):  # pragma: no cover - compiled
    """``w[k] = X[:, k] . Y[:, k]`` of two (n, c) blocks."""
    w[:] = 0.0
    for i in range(X.shape[0]):
        for k in range(X.shape[1]):
            w[k] += X[i, k] * Y[i, k]


@jit
def diagonal_split(indptr, indices, data):  # pragma: no cover - compiled
    """For a CSR ``A`` (n, n) with sorted rows: ``split`` (n,) int64, the first entry of each row at or
    right of the diagonal, and ``dinv`` (n,) its inverse diagonal (0 where the diagonal is missing or
    not positive: an empty coarse row is not smoothed)."""
    n = indptr.shape[0] - 1
    split = np.empty(n, np.int64)
    dinv = np.zeros(n)
    for i in range(n):
        p = indptr[i]
        while p < indptr[i + 1] and indices[p] < i:
            p += 1
        split[i] = p
        if p < indptr[i + 1] and indices[p] == i and data[p] > 0:
            dinv[i] = 1.0 / data[p]
    return split, dinv


@jit
def cycle_operator(indptr, indices, data, tol):  # pragma: no cover - compiled
    """A level's operator as the Gauss-Seidel cycle takes it: ``A`` (n, n) CSR with sorted rows, float64,
    without its rounding noise, in float32, with :func:`diagonal_split`'s ``split`` and ``dinv``.

    An off-diagonal entry with ``|a_ij| <= tol (sqrt|a_ii| sqrt|a_jj|)`` is left out (exact zeros too).
    The assembled stiffness holds such entries where the element terms of a coupling cancel (zero
    in exact arithmetic, ~1e-31 F against a diagonal of ~1e-13 F: 1e-24 to 1e-16 of it on the
    robot-cell skin, 48% of its entries; the smallest true coupling is 1e-6 of it). In float32
    their products with the sweep's potentials fall below the smallest normal number (1.2e-38),
    and every such subnormal product costs the CPU ~100 cycles: they made the down sweep 2.2x and
    the up sweep 2.3x slower than on the same matrix without them (docs/capacitive-accuracy.md).
    The rule is symmetric bit for bit (a symmetric ``A`` keeps a symmetric cycle) and keeps the diagonal.

    Returns
    -------
    (indptr (n + 1,), indices (m,), data (m,) float32), split (n,) int64, dinv (n,) float32.
    """
    n = indptr.shape[0] - 1
    root = np.zeros(n)  # sqrt(|a_ii|): the rule without a square root per entry
    dinv = np.zeros(n, np.float32)
    for i in range(n):
        for p in range(indptr[i], indptr[i + 1]):
            if indices[p] == i:
                a = data[p]
                root[i] = np.sqrt(abs(a))
                if a > 0:
                    dinv[i] = np.float32(1.0 / a)
    ptr = np.zeros(n + 1, indptr.dtype)
    ind = np.empty(indices.shape[0], indices.dtype)
    dat = np.empty(indices.shape[0], np.float32)
    split = np.empty(n, np.int64)
    m = 0
    for i in range(n):
        split[i] = m
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            a = data[p]
            if j != i and abs(a) <= tol * (root[i] * root[j]):  # the same product for a_ji: symmetric
                continue
            ind[m] = j
            dat[m] = np.float32(a)
            m += 1
            if j < i:  # sorted rows: the entries left of the diagonal come first
                split[i] = m
        ptr[i + 1] = m
    return (ptr, ind[:m], dat[:m]), split, dinv


@jit
def gs_down8(indptr, indices, data, split, dinv, B, X, T, r_ptr, r_ind, r_dat, Bc):  # pragma: no cover - compiled
    """A V-cycle level going down, blocks (n, 8): a forward Gauss-Seidel sweep from zero, ``X = (D + L)^-1 B``,
    then ``Bc = P^T (B - A X)``.

    ``A`` (n, n) CSR with sorted rows, ``split`` (n,) the first entry of each row at or right of the
    diagonal and ``dinv`` (n,) the inverse diagonal (0 on an empty row)
    (:func:`diagonal_split`); ``T`` (n, 8) scratch; ``R = P^T`` (nc, n) CSR; ``Bc`` (nc, 8) the next
    level's right-hand side. The sweep touches the entries left of the diagonal only and the residual
    the others (``T`` holds the sweep's sums in between): one pass over ``A`` in all. The restriction
    gathers rows of ``T`` (a scatter into ``Bc`` would chain its read-modify-writes row to row).
    """
    n = B.shape[0]
    for i in range(n):
        b = B[i]
        r0, r1, r2, r3, r4, r5, r6, r7 = b[0] * 1.0, b[1] * 1.0, b[2] * 1.0, b[3] * 1.0, b[4] * 1.0, b[5] * 1.0, \
            b[6] * 1.0, b[7] * 1.0
        for p in range(indptr[i], split[i]):
            a = data[p]
            x = X[indices[p]]
            r0 -= a * x[0]
            r1 -= a * x[1]
            r2 -= a * x[2]
            r3 -= a * x[3]
            r4 -= a * x[4]
            r5 -= a * x[5]
            r6 -= a * x[6]
            r7 -= a * x[7]
        t = T[i]
        x = X[i]
        di = dinv[i]
        t[0] = r0
        x[0] = di * r0
        t[1] = r1
        x[1] = di * r1
        t[2] = r2
        x[2] = di * r2
        t[3] = r3
        x[3] = di * r3
        t[4] = r4
        x[4] = di * r4
        t[5] = r5
        x[5] = di * r5
        t[6] = r6
        x[6] = di * r6
        t[7] = r7
        x[7] = di * r7
    for i in range(n):
        t = T[i]
        r0, r1, r2, r3, r4, r5, r6, r7 = t[0] * 1.0, t[1] * 1.0, t[2] * 1.0, t[3] * 1.0, t[4] * 1.0, t[5] * 1.0, \
            t[6] * 1.0, t[7] * 1.0
        for p in range(split[i], indptr[i + 1]):
            a = data[p]
            x = X[indices[p]]
            r0 -= a * x[0]
            r1 -= a * x[1]
            r2 -= a * x[2]
            r3 -= a * x[3]
            r4 -= a * x[4]
            r5 -= a * x[5]
            r6 -= a * x[6]
            r7 -= a * x[7]
        t[0] = r0
        t[1] = r1
        t[2] = r2
        t[3] = r3
        t[4] = r4
        t[5] = r5
        t[6] = r6
        t[7] = r7
    for i in range(Bc.shape[0]):
        a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
        for q in range(r_ptr[i], r_ptr[i + 1]):
            w = r_dat[q]
            c = T[r_ind[q]]
            a0 += w * c[0]
            a1 += w * c[1]
            a2 += w * c[2]
            a3 += w * c[3]
            a4 += w * c[4]
            a5 += w * c[5]
            a6 += w * c[6]
            a7 += w * c[7]
        c = Bc[i]
        c[0] = a0
        c[1] = a1
        c[2] = a2
        c[3] = a3
        c[4] = a4
        c[5] = a5
        c[6] = a6
        c[7] = a7


@jit
def gs_up8(indptr, indices, data, dinv, B, X, p_ptr, p_ind, p_dat, Xc, mask, rz):  # pragma: no cover - compiled
    """A V-cycle level going up, blocks (n, 8): ``X += P Xc``, then a backward Gauss-Seidel sweep
    ``X += (D + U)^-1 (B - A X)``, masked (``X *= mask``, zero on prescribed unknowns), with
    ``rz[k] = B[:, k] . X[:, k]`` (the value as stored). The adjoint of :func:`gs_down8`'s sweep, so
    the cycle is symmetric. A row is final once swept (later rows lie above it), so its mask and its
    share of ``rz`` are applied in the same pass.
    """
    n = B.shape[0]
    for i in range(n):
        x = X[i]
        a0, a1, a2, a3, a4, a5, a6, a7 = x[0] * 1.0, x[1] * 1.0, x[2] * 1.0, x[3] * 1.0, x[4] * 1.0, x[5] * 1.0, \
            x[6] * 1.0, x[7] * 1.0
        for q in range(p_ptr[i], p_ptr[i + 1]):
            w = p_dat[q]
            c = Xc[p_ind[q]]
            a0 += w * c[0]
            a1 += w * c[1]
            a2 += w * c[2]
            a3 += w * c[3]
            a4 += w * c[4]
            a5 += w * c[5]
            a6 += w * c[6]
            a7 += w * c[7]
        x[0] = a0
        x[1] = a1
        x[2] = a2
        x[3] = a3
        x[4] = a4
        x[5] = a5
        x[6] = a6
        x[7] = a7
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = 0.0
    for i in range(n - 1, -1, -1):
        b = B[i]
        r0, r1, r2, r3, r4, r5, r6, r7 = b[0] * 1.0, b[1] * 1.0, b[2] * 1.0, b[3] * 1.0, b[4] * 1.0, b[5] * 1.0, \
            b[6] * 1.0, b[7] * 1.0
        for p in range(indptr[i], indptr[i + 1]):
            a = data[p]
            x = X[indices[p]]
            r0 -= a * x[0]
            r1 -= a * x[1]
            r2 -= a * x[2]
            r3 -= a * x[3]
            r4 -= a * x[4]
            r5 -= a * x[5]
            r6 -= a * x[6]
            r7 -= a * x[7]
        x = X[i]
        di = dinv[i]
        m = mask[i]
        x[0] = (x[0] + di * r0) * m
        s0 += b[0] * x[0]
        x[1] = (x[1] + di * r1) * m
        s1 += b[1] * x[1]
        x[2] = (x[2] + di * r2) * m
        s2 += b[2] * x[2]
        x[3] = (x[3] + di * r3) * m
        s3 += b[3] * x[3]
        x[4] = (x[4] + di * r4) * m
        s4 += b[4] * x[4]
        x[5] = (x[5] + di * r5) * m
        s5 += b[5] * x[5]
        x[6] = (x[6] + di * r6) * m
        s6 += b[6] * x[6]
        x[7] = (x[7] + di * r7) * m
        s7 += b[7] * x[7]
    rz[0] = s0
    rz[1] = s1
    rz[2] = s2
    rz[3] = s3
    rz[4] = s4
    rz[5] = s5
    rz[6] = s6
    rz[7] = s7



@jit
def lanczos_tridiagonal(indptr, indices, data, v, alphas, betas):  # pragma: no cover - compiled
    """Lanczos on ``D^-1/2 A D^-1/2`` (``A`` (n, n) CSR, ``D`` its diagonal, rows without one counted 0)
    from the unit vector ``v`` (n,) (overwritten): the tridiagonal's ``alphas`` (s,) and ``betas``
    (s,), ``s`` the steps at most; returns the steps taken. The loop of
    :func:`~twinsense.capacitive.amg.spectral_radius` with its sums in this order, in one pass
    per step (that one's NumPy steps cost ~0.1 ms each on a 2,846-row coarse level, 2 ms a refresh).
    """
    n = v.shape[0]
    s = np.zeros(n)
    for i in range(n):
        for p in range(indptr[i], indptr[i + 1]):
            if indices[p] == i and data[p] > 0:
                s[i] = 1.0 / np.sqrt(data[p])
    sv = np.empty(n)
    w = np.empty(n)
    v_prev = np.zeros(n)
    beta = 0.0
    k = 0
    for _ in range(min(alphas.shape[0], n)):
        for i in range(n):
            sv[i] = s[i] * v[i]
        alpha = 0.0
        for i in range(n):
            acc = 0.0
            for p in range(indptr[i], indptr[i + 1]):
                acc += data[p] * sv[indices[p]]
            w[i] = s[i] * acc - beta * v_prev[i]
            alpha += w[i] * v[i]
        nrm = 0.0
        for i in range(n):
            w[i] -= alpha * v[i]
            nrm += w[i] * w[i]
        alphas[k] = alpha
        k += 1
        beta = np.sqrt(nrm)
        if beta <= 1e-12 * abs(alpha):
            break
        betas[k - 1] = beta
        for i in range(n):
            v_prev[i] = v[i]
            v[i] = w[i] / beta
    return k


@jit
def first_coarse_update(c0, g, h, tslot, rows, c_ind, diag, p_ptr, p_ind, support, prune, c
                        ):  # pragma: no cover - compiled
    """The first coarse operator of a refresh from the build's, in one pass (see
    :meth:`~twinsense.capacitive.amg.BlockAMG.refresh`): ``c = c0 - g - g^T + h`` on the slots of
    coarse unknowns that keep free support, exactly zero elsewhere, then the near-empty unknowns
    pruned (``diag <= prune * max diag``: rows and columns zero).

    ``c0``, ``g``, ``h`` (nnz,) on the coarse pattern; ``tslot`` (nnz,) the transposed entry's slot;
    ``rows``, ``c_ind`` (nnz,) each slot's row and column; ``diag`` (nc,) the diagonal slots;
    ``P`` (n, nc) CSR pattern; ``support`` (n,) bool, the fine unknowns free now and at the build.

    Returns
    -------
    bool: False when a kept unknown's diagonal fell below 1e-9 of its build value (the update's
    rounding would then be ~1e-7 of it or worse: the caller forms the product directly).
    """
    nc = diag.shape[0]
    alive = np.zeros(nc, np.bool_)
    for i in range(support.shape[0]):
        if support[i]:
            for q in range(p_ptr[i], p_ptr[i + 1]):
                alive[p_ind[q]] = True
    for q in range(c.shape[0]):
        if alive[rows[q]] and alive[c_ind[q]]:
            c[q] = c0[q] - g[q] - g[tslot[q]] + h[q]
        else:
            c[q] = 0.0
    top = 0.0
    for r in range(nc):
        d = c[diag[r]]
        if alive[r] and d <= 1e-9 * c0[diag[r]]:
            return False
        top = max(top, d)
    gone = np.empty(nc, np.bool_)
    for r in range(nc):
        gone[r] = c[diag[r]] <= prune * top
    for q in range(c.shape[0]):
        if gone[rows[q]] or gone[c_ind[q]]:
            c[q] = 0.0
    return True


@jit
def maxwell_from_residual(k_indptr, k_indices, k_data, X, R, fixed):  # pragma: no cover - compiled
    """(t, t) ``X^T K X`` of solved potentials ``X`` (n, t) from their residual ``R = B - A X`` (n, t) [F].

    ``K`` (n, n) CSR, ``A`` its Dirichlet system, ``fixed`` (n,) bool the
    prescribed rows. On a free row ``(K X)_i = (A X - B)_i = -R_i`` (``B``
    carries the prescribed nodes' couplings), so only the prescribed rows
    with a nonzero potential (the terminals' nodes, a few thousand of the
    robot-cell skin's 32k; grounded rows add nothing) take their ``K`` row
    products: the terminal charges. The free rows' term ``-X^T R`` keeps the
    result the energy form (error quadratic in the potentials' error), not
    the charge form alone (linear). The proximity sensor's and the tactile
    skin's frame solves both take their Maxwell matrix here.
    """
    n, t = X.shape
    G = np.zeros((t, t))
    s = np.empty(t)
    for i in range(n):
        if fixed[i]:
            live = False
            for a in range(t):
                if X[i, a] != 0.0:
                    live = True
            if not live:
                continue
            for b in range(t):
                acc = 0.0
                for p in range(k_indptr[i], k_indptr[i + 1]):
                    acc += k_data[p] * X[k_indices[p], b]
                s[b] = acc
            for a in range(t):
                x = X[i, a]
                if x != 0.0:
                    for b in range(t):
                        G[a, b] += x * s[b]
        else:
            for a in range(t):
                x = X[i, a]
                for b in range(t):
                    G[a, b] -= x * R[i, b]
    return G


# The same loops for blocks of exactly 6 columns: a skin of 6 terminals (the robot cell's pad-grid)
# solves one group of 6 instead of 8 with two zero columns. A product's cost is mostly per stored
# entry (index, value, the gathered row), so 6 columns take ~0.8 of 8 (0.54 against 0.67 ms for the
# 252k-entry skin matrix), not 0.75.


@jit
def spmm6(indptr, indices, data, X, Y):  # pragma: no cover - compiled
    """``Y = A X`` for a CSR ``A`` (n, n) and blocks (n, 6)."""
    n = X.shape[0]
    for i in range(n):
        a0 = a1 = a2 = a3 = a4 = a5 = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            a = data[p]
            x = X[indices[p]]
            a0 += a * x[0]
            a1 += a * x[1]
            a2 += a * x[2]
            a3 += a * x[3]
            a4 += a * x[4]
            a5 += a * x[5]
        y = Y[i]
        y[0] = a0
        y[1] = a1
        y[2] = a2
        y[3] = a3
        y[4] = a4
        y[5] = a5


@jit
def residual6(indptr, indices, data, B, X, R):  # pragma: no cover - compiled
    """``R = B - A X`` for a CSR ``A`` (n, n) and blocks (n, 6) (``R`` may have another dtype)."""
    n = X.shape[0]
    for i in range(n):
        b = B[i]
        a0, a1, a2, a3, a4, a5 = b[0] * 1.0, b[1] * 1.0, b[2] * 1.0, b[3] * 1.0, b[4] * 1.0, b[5] * 1.0
        for p in range(indptr[i], indptr[i + 1]):
            a = data[p]
            x = X[indices[p]]
            a0 -= a * x[0]
            a1 -= a * x[1]
            a2 -= a * x[2]
            a3 -= a * x[3]
            a4 -= a * x[4]
            a5 -= a * x[5]
        r = R[i]
        r[0] = a0
        r[1] = a1
        r[2] = a2
        r[3] = a3
        r[4] = a4
        r[5] = a5


@jit
def gs_down6(indptr, indices, data, split, dinv, B, X, T, r_ptr, r_ind, r_dat, Bc):  # pragma: no cover - compiled
    """A V-cycle level going down, blocks (n, 6): a forward Gauss-Seidel sweep from zero, ``X = (D + L)^-1 B``,
    then ``Bc = P^T (B - A X)``.

    ``A`` (n, n) CSR with sorted rows, ``split`` (n,) the first entry of each row at or right of the
    diagonal and ``dinv`` (n,) the inverse diagonal (0 on an empty row)
    (:func:`diagonal_split`); ``T`` (n, 6) scratch; ``R = P^T`` (nc, n) CSR; ``Bc`` (nc, 6) the next
    level's right-hand side. The sweep touches the entries left of the diagonal only and the residual
    the others (``T`` holds the sweep's sums in between): one pass over ``A`` in all. The restriction
    gathers rows of ``T`` (a scatter into ``Bc`` would chain its read-modify-writes row to row).
    """
    n = B.shape[0]
    for i in range(n):
        b = B[i]
        r0, r1, r2, r3, r4, r5 = b[0] * 1.0, b[1] * 1.0, b[2] * 1.0, b[3] * 1.0, b[4] * 1.0, b[5] * 1.0
        for p in range(indptr[i], split[i]):
            a = data[p]
            x = X[indices[p]]
            r0 -= a * x[0]
            r1 -= a * x[1]
            r2 -= a * x[2]
            r3 -= a * x[3]
            r4 -= a * x[4]
            r5 -= a * x[5]
        t = T[i]
        x = X[i]
        di = dinv[i]
        t[0] = r0
        x[0] = di * r0
        t[1] = r1
        x[1] = di * r1
        t[2] = r2
        x[2] = di * r2
        t[3] = r3
        x[3] = di * r3
        t[4] = r4
        x[4] = di * r4
        t[5] = r5
        x[5] = di * r5
    for i in range(n):
        t = T[i]
        r0, r1, r2, r3, r4, r5 = t[0] * 1.0, t[1] * 1.0, t[2] * 1.0, t[3] * 1.0, t[4] * 1.0, t[5] * 1.0
        for p in range(split[i], indptr[i + 1]):
            a = data[p]
            x = X[indices[p]]
            r0 -= a * x[0]
            r1 -= a * x[1]
            r2 -= a * x[2]
            r3 -= a * x[3]
            r4 -= a * x[4]
            r5 -= a * x[5]
        t[0] = r0
        t[1] = r1
        t[2] = r2
        t[3] = r3
        t[4] = r4
        t[5] = r5
    for i in range(Bc.shape[0]):
        a0 = a1 = a2 = a3 = a4 = a5 = 0.0
        for q in range(r_ptr[i], r_ptr[i + 1]):
            w = r_dat[q]
            c = T[r_ind[q]]
            a0 += w * c[0]
            a1 += w * c[1]
            a2 += w * c[2]
            a3 += w * c[3]
            a4 += w * c[4]
            a5 += w * c[5]
        c = Bc[i]
        c[0] = a0
        c[1] = a1
        c[2] = a2
        c[3] = a3
        c[4] = a4
        c[5] = a5


@jit
def gs_up6(indptr, indices, data, dinv, B, X, p_ptr, p_ind, p_dat, Xc, mask, rz):  # pragma: no cover - compiled
    """A V-cycle level going up, blocks (n, 6): ``X += P Xc``, then a backward Gauss-Seidel sweep
    ``X += (D + U)^-1 (B - A X)``, masked (``X *= mask``, zero on prescribed unknowns), with
    ``rz[k] = B[:, k] . X[:, k]`` (the value as stored). The adjoint of :func:`gs_down6`'s sweep, so
    the cycle is symmetric. A row is final once swept (later rows lie above it), so its mask and its
    share of ``rz`` are applied in the same pass.
    """
    n = B.shape[0]
    for i in range(n):
        x = X[i]
        a0, a1, a2, a3, a4, a5 = x[0] * 1.0, x[1] * 1.0, x[2] * 1.0, x[3] * 1.0, x[4] * 1.0, x[5] * 1.0
        for q in range(p_ptr[i], p_ptr[i + 1]):
            w = p_dat[q]
            c = Xc[p_ind[q]]
            a0 += w * c[0]
            a1 += w * c[1]
            a2 += w * c[2]
            a3 += w * c[3]
            a4 += w * c[4]
            a5 += w * c[5]
        x[0] = a0
        x[1] = a1
        x[2] = a2
        x[3] = a3
        x[4] = a4
        x[5] = a5
    s0 = s1 = s2 = s3 = s4 = s5 = 0.0
    for i in range(n - 1, -1, -1):
        b = B[i]
        r0, r1, r2, r3, r4, r5 = b[0] * 1.0, b[1] * 1.0, b[2] * 1.0, b[3] * 1.0, b[4] * 1.0, b[5] * 1.0
        for p in range(indptr[i], indptr[i + 1]):
            a = data[p]
            x = X[indices[p]]
            r0 -= a * x[0]
            r1 -= a * x[1]
            r2 -= a * x[2]
            r3 -= a * x[3]
            r4 -= a * x[4]
            r5 -= a * x[5]
        x = X[i]
        di = dinv[i]
        m = mask[i]
        x[0] = (x[0] + di * r0) * m
        s0 += b[0] * x[0]
        x[1] = (x[1] + di * r1) * m
        s1 += b[1] * x[1]
        x[2] = (x[2] + di * r2) * m
        s2 += b[2] * x[2]
        x[3] = (x[3] + di * r3) * m
        s3 += b[3] * x[3]
        x[4] = (x[4] + di * r4) * m
        s4 += b[4] * x[4]
        x[5] = (x[5] + di * r5) * m
        s5 += b[5] * x[5]
    rz[0] = s0
    rz[1] = s1
    rz[2] = s2
    rz[3] = s3
    rz[4] = s4
    rz[5] = s5


FIXED_WIDTH = {8: (spmm8, residual8, gs_down8, gs_up8), 6: (spmm6, residual6, gs_down6, gs_up6)}
"""The fixed-width loops by block width: ``(spmm, residual, cycle_down, cycle_up)``."""


def group_width(m: int) -> int:
    """The fixed block width for a group of ``m`` <= :data:`WIDTH` columns: 6 when they fit, else 8."""
    return 6 if m <= 6 else WIDTH
