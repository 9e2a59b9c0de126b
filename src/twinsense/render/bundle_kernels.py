"""Compiled loops of the single-origin bundle picker (:mod:`twinsense.render.bundle`).

Rays from one origin o are binned by their normalised coordinates
(u, v) = (d . e1 / d . e3, d . e2 / d . e3) into a uniform grid; each triangle
(vertices made origin-relative and expressed along e1, e2, e3: W = (x, y, z))
is binned into the cells its projection can touch; then, per cell, every
triangle is tested against every ray of the cell. The ray is r = (u, v, 1)
(d / d . e3): each vertex is sheared along it onto its own depth,
Q_i = (x_i - z_i u, y_i - z_i v) (the ray becomes the point 0 of the plane,
as in Woop, Benthin and Wald, "Watertight ray/triangle intersection", JCGT
2013), and the edge functions are the 2-D cross products

    e_ij = Q_i x Q_j = r . (W_i x W_j),   inside: e01, e12, e20 all >= 0 or all <= 0,
    t = (W0 . (W1 x W2)) / (e01 + e12 + e20)   (depth along e3; the denominator is r . N)

Watertight in floating point: a vertex's Q is computed from the same
numbers, in the same operations, by every triangle that holds it, and
a x b = -(b x a) exactly, so a shared edge's function is exactly the negative
in its neighbour (no ray through an edge falls between the two triangles) and
every triangle around a vertex sees the ray at the same computed point (no ray
through a vertex falls through the fan: the 3-D form d . (w_i x w_j) rounds
each edge's cross product on its own and does lose rays aimed at a vertex).
Everything is float64.

All loops are compiled without the GIL (:func:`twinsense.compiled.jit`); the
caller runs ranges of triangles or cells on its worker threads, and every
output slot is written by one range only, so the result does not depend on
the number of threads.
"""

from __future__ import annotations

import numpy as np

from twinsense.compiled import jit

#: The data kept per kept triangle, in this order: its vertices along e1, e2, e3
#: (x0, y0, z0, x1, ..., z2: 9 numbers), W0 . (W1 x W2) and its edge tolerance.
TRI_WORDS = 11
#: Float64's unit roundoff.
_EPS = 2.0**-53


@jit
def ray_frame_sums(d):  # pragma: no cover
    """(sum of the unit directions (3,), number of valid rays) over the rays d (n, 3).

    A ray is valid when its three coordinates are finite float32 numbers (as
    :func:`~twinsense.render.embree4_kernels.trace` requires) and not all zero.
    """
    s0 = s1 = s2 = 0.0
    m = 0
    for i in range(d.shape[0]):
        x, y, z = d[i, 0], d[i, 1], d[i, 2]
        fx, fy, fz = np.float32(x), np.float32(y), np.float32(z)
        if (fx - fx) + (fy - fy) + (fz - fz) != 0:
            continue
        r = np.sqrt(x * x + y * y + z * z)
        if r == 0.0:
            continue
        s0 += x / r
        s1 += y / r
        s2 += z / r
        m += 1
    return np.array([s0, s1, s2]), m


@jit
def _uv(x, y, z, e):  # pragma: no cover
    """(u, v, c, |d|^2, valid) of the ray d = (x, y, z): u = d . e1 / c, v = d . e2 / c,
    c = d . e3 (e: the 9 numbers of e1, e2, e3 as a tuple: scalars only, so the call costs
    nothing; array arguments cost ~10x the arithmetic); valid: its coordinates are finite
    float32 numbers (as ``trace`` requires) and not all zero. The one place these are
    computed (binning and sorting must give the same bits)."""
    fx, fy, fz = np.float32(x), np.float32(y), np.float32(z)
    r2 = x * x + y * y + z * z
    ok = (fx - fx) + (fy - fy) + (fz - fz) == 0 and r2 != 0.0
    a = x * e[0] + y * e[1] + z * e[2]
    b = x * e[3] + y * e[4] + z * e[5]
    c = x * e[6] + y * e[7] + z * e[8]
    return a / c, b / c, c, r2, ok


@jit
def _axes(basis):  # pragma: no cover
    """The 9 numbers of basis (3, 3) rows e1, e2, e3, as a tuple (for :func:`_uv`)."""
    return (basis[0, 0], basis[0, 1], basis[0, 2], basis[1, 0], basis[1, 1], basis[1, 2],
            basis[2, 0], basis[2, 1], basis[2, 2])


@jit
def bin_rays(lo, hi, d, basis, cos_min, grid, gu, gv, cell, counts):  # pragma: no cover
    """Rays lo..hi-1 into the grid: cell (n,) int64 (cu + gu cv, -1 for an invalid ray), and
    the number of rays per cell into counts (gu gv,) int64 (zeroed here).

    basis (3, 3): rows e1, e2, e3; grid (4,): umin, 1/du, vmin, 1/dv (a ray beyond the
    grid takes its border cell: triangles are mapped by the same clamped function).
    Returns (every valid ray within the cone d . e3 >= cos_min |d|, the number of valid
    rays, umin, umax, vmin, vmax over them: inf/-inf when none).

    With :func:`scatter_rays`: a counting sort of the rays by
    cell, in ranges of rays that threads can run at once (each range's rays land at
    its own offsets: the order is the same for any ranges).
    """
    e = _axes(basis)
    counts[:] = 0
    m = 0
    umin = vmin = np.inf
    umax = vmax = -np.inf
    inside = True
    for i in range(lo, hi):
        u, v, c, r2, ok = _uv(d[i, 0], d[i, 1], d[i, 2], e)
        cell[i] = -1
        if not ok:
            continue
        m += 1
        if not c >= cos_min * np.sqrt(r2):
            inside = False
            continue
        umin, umax = min(umin, u), max(umax, u)
        vmin, vmax = min(vmin, v), max(vmax, v)
        k = _cell_of(u, grid[0], grid[1], gu) + gu * _cell_of(v, grid[2], grid[3], gv)
        cell[i] = k
        counts[k] += 1
    return inside, m, umin, umax, vmin, vmax


@jit
def _cell_of(x, lo, inv, g):  # pragma: no cover
    """The grid index of coordinate x: floor((x - lo) * inv) clamped to [0, g - 1] (monotone in x)."""
    c = (x - lo) * inv
    if not c >= 0.0:  # also NaN
        return 0
    if c >= g:
        return g - 1
    return min(int(c), g - 1)


@jit
def scatter_rays(lo, hi, d, basis, cell, fill, order, us, vs):  # pragma: no cover
    """order[fill[c]++] = i for the rays i = lo..hi-1 in cell c >= 0 (ascending within a cell),
    and their u, v (:func:`_uv`: the bits of binning) into us, vs (m,) at the same slots.
    fill (gu gv,) int64: this range's first slot in every cell."""
    e = _axes(basis)
    for i in range(lo, hi):
        c = cell[i]
        if c >= 0:
            u, v, _, _, _ = _uv(d[i, 0], d[i, 1], d[i, 2], e)
            s = fill[c]
            order[s] = i
            us[s], vs[s] = u, v
            fill[c] = s + 1


@jit
def _clip(px, py, pz, k, a, b, c):  # pragma: no cover
    """Sutherland-Hodgman: the first k vertices of polygon (px, py, pz) clipped to
    a x + b y + c z >= 0, in place (arrays of 8); returns the new vertex count."""
    qx, qy, qz = np.empty(8), np.empty(8), np.empty(8)
    m = 0
    for i in range(k):
        j = (i + 1) % k
        si = a * px[i] + b * py[i] + c * pz[i]
        sj = a * px[j] + b * py[j] + c * pz[j]
        if si >= 0.0:
            qx[m], qy[m], qz[m] = px[i], py[i], pz[i]
            m += 1
        if (si >= 0.0) != (sj >= 0.0):
            s = si / (si - sj)
            qx[m] = px[i] + (px[j] - px[i]) * s
            qy[m] = py[i] + (py[j] - py[i]) * s
            qz[m] = pz[i] + (pz[j] - pz[i]) * s
            m += 1
    for i in range(m):
        px[i], py[i], pz[i] = qx[i], qy[i], qz[i]
    return m


@jit
def triangles(lo, hi, faces, verts, vert_owner, rots, poss, o, basis, grid, extent, gu, gv, reach,
              box, zmin, data):  # pragma: no cover
    """Triangles lo..hi-1 moved, binned and prepared in one pass.

    verts (nv, 3): static vertices in the world, a mover's in its frame; vert_owner
    (nv,) int: -1 static, else the mover j posed by rots[j] (3, 3), poss[j] (3,)
    (local -> world); o (3,) the origin; basis (3, 3) rows e1, e2, e3: each vertex
    v (in the world) becomes ((v - o) . e1, (v - o) . e2, (v - o) . e3). faces (t, 3).
    grid (4,): umin, 1/du, vmin, 1/dv; extent (4,): umin, umax, vmin, vmax of the
    rays, padded outwards; reach: the rays' largest |u| or |v|.

    Writes box (t, 4) int64 rows (cu0, cu1, cv0, cv1) of the cells the triangle can
    touch (cu0 = -1: dropped), zmin (t,) its least coordinate along e3, and, for a
    triangle kept, data (t, TRI_WORDS): its vertices along e1, e2, e3, W0 . (W1 x W2)
    (0 for a plane through the origin within rounding: never hit) and the edge
    tolerance 8 eps S^2.

    Dropped: a triangle of zero area within rounding (|N| <= 1e-10 |E0| |E1|: its
    edge functions and t would be rounding noise; Embree hits none either), one
    with no vertex in front of the plane through o normal to e3, one whose
    projection misses the rays' extent. A triangle reaching that plane is clipped
    to the rays' frustum (four planes through o) first; if a clipped vertex still
    has no positive depth, it gets the whole grid.

    The tolerance: S = max_k (|x_k| + |y_k| + |z_k|) (1 + reach) bounds every
    sheared coordinate |x - z u| for rays with |u|, |v| <= reach; a sheared
    coordinate is off by at most 2 eps S and a 2-D cross product of two by at most
    ~6 eps S^2: an edge function within 8 eps S^2 of zero is a ray on the edge
    within float64 rounding, and counts as inside (so a ray exactly through a
    silhouette edge hits, as in exact arithmetic; a shared edge was already exact).
    """
    px, py, pz = np.empty(8), np.empty(8), np.empty(8)
    w = np.empty(9)
    for f in range(lo, hi):
        for k in range(3):
            # The vertex moved to the world, origin-relative, along e1, e2, e3: the same operations
            # for every triangle that holds it (the same bits: what makes the picks watertight).
            # Written here, not as a call: a compiled call with array arguments costs ~10x this.
            i = faces[f, k]
            j = vert_owner[i]
            x, y, z = verts[i, 0], verts[i, 1], verts[i, 2]
            if j >= 0:
                wx = rots[j, 0, 0] * x + rots[j, 0, 1] * y + rots[j, 0, 2] * z + poss[j, 0]
                wy = rots[j, 1, 0] * x + rots[j, 1, 1] * y + rots[j, 1, 2] * z + poss[j, 1]
                wz = rots[j, 2, 0] * x + rots[j, 2, 1] * y + rots[j, 2, 2] * z + poss[j, 2]
                x, y, z = wx, wy, wz
            x -= o[0]
            y -= o[1]
            z -= o[2]
            w[3 * k] = x * basis[0, 0] + y * basis[0, 1] + z * basis[0, 2]
            w[3 * k + 1] = x * basis[1, 0] + y * basis[1, 1] + z * basis[1, 2]
            w[3 * k + 2] = x * basis[2, 0] + y * basis[2, 1] + z * basis[2, 2]
        ex0, ey0, ez0 = w[3] - w[0], w[4] - w[1], w[5] - w[2]
        ex1, ey1, ez1 = w[6] - w[0], w[7] - w[1], w[8] - w[2]
        nx = ey0 * ez1 - ez0 * ey1
        ny = ez0 * ex1 - ex0 * ez1
        nz = ex0 * ey1 - ey0 * ex1
        nn = nx * nx + ny * ny + nz * nz
        ee = (ex0 * ex0 + ey0 * ey0 + ez0 * ez0) * (ex1 * ex1 + ey1 * ey1 + ez1 * ez1)
        za, zb, zc = w[2], w[5], w[8]
        zmin[f] = min(za, zb, zc)
        box[f, 0] = -1
        if not nn > 1e-20 * ee or not max(za, zb, zc) > 0.0:
            continue
        for k in range(3):
            px[k], py[k], pz[k] = w[3 * k], w[3 * k + 1], w[3 * k + 2]
        k = 3
        if not min(za, zb, zc) > 0.0:
            # The frustum's four side planes (they keep only depth >= 0).
            k = _clip(px, py, pz, k, 1.0, 0.0, -extent[0])
            k = _clip(px, py, pz, k, -1.0, 0.0, extent[1])
            k = _clip(px, py, pz, k, 0.0, 1.0, -extent[2])
            k = _clip(px, py, pz, k, 0.0, -1.0, extent[3])
            if k == 0:
                continue
        u0 = v0 = np.inf
        u1 = v1 = -np.inf
        whole = False
        for i in range(k):
            if not pz[i] > 0.0:
                whole = True
                break
            uu, vv = px[i] / pz[i], py[i] / pz[i]
            u0, u1 = min(u0, uu), max(u1, uu)
            v0, v1 = min(v0, vv), max(v1, vv)
        if whole:
            box[f, 0], box[f, 1], box[f, 2], box[f, 3] = 0, gu - 1, 0, gv - 1
        else:
            # Padded by a relative 1e-9: the projection's rounding is ~1e-16 relative.
            pu = 1e-9 * (1.0 + abs(u0) + abs(u1))
            pv = 1e-9 * (1.0 + abs(v0) + abs(v1))
            u0, u1, v0, v1 = u0 - pu, u1 + pu, v0 - pv, v1 + pv
            if u1 < extent[0] or u0 > extent[1] or v1 < extent[2] or v0 > extent[3]:
                continue
            box[f, 0] = _cell_of(u0, grid[0], grid[1], gu)
            box[f, 1] = _cell_of(u1, grid[0], grid[1], gu)
            box[f, 2] = _cell_of(v0, grid[2], grid[3], gv)
            box[f, 3] = _cell_of(v1, grid[2], grid[3], gv)
        size = 0.0
        for k in range(9):
            data[f, k] = w[k]
        for k in range(3):
            size = max(size, abs(w[3 * k]) + abs(w[3 * k + 1]) + abs(w[3 * k + 2]))
        x0, y0, z0, x1, y1, z1, x2, y2, z2 = w[0], w[1], w[2], w[3], w[4], w[5], w[6], w[7], w[8]
        det = x0 * (y1 * z2 - z1 * y2) + y0 * (z1 * x2 - x1 * z2) + z0 * (x1 * y2 - y1 * x2)
        # A plane through the origin within rounding (|det| <= 8 eps S^3 bounds the rounding of
        # a triple product of coordinates up to S): t would be rounding noise around 0, a "hit"
        # at ~1e-16 m hiding everything, or a ray in the plane itself: never hit (det = 0: t = 0
        # or NaN). A ray can lie in a triangle's plane only if that plane holds the origin.
        data[f, 9] = 0.0 if abs(det) <= 8.0 * _EPS * size * size * size else det
        size *= 1.0 + reach
        data[f, 10] = 8.0 * _EPS * size * size


@jit
def cell_lists(kept, box, gu, gv):  # pragma: no cover
    """Counting sort of the kept triangles (indices, in the order given) into cells.

    Returns tri_start (gu gv + 1,) int64 and tris (p,) int64: cell c's triangles
    are tris[tri_start[c]:tri_start[c + 1]] (triangle indices), in kept's order.
    """
    nc = gu * gv
    start = np.zeros(nc + 1, np.int64)
    for q in range(kept.shape[0]):
        f = kept[q]
        for cv in range(box[f, 2], box[f, 3] + 1):
            for cu in range(box[f, 0], box[f, 1] + 1):
                start[cu + gu * cv + 1] += 1
    for c in range(nc):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    tris = np.empty(start[nc], np.int64)
    for q in range(kept.shape[0]):
        f = kept[q]
        for cv in range(box[f, 2], box[f, 3] + 1):
            for cu in range(box[f, 0], box[f, 1] + 1):
                c = cu + gu * cv
                tris[fill[c]] = f
                fill[c] += 1
    return start, tris


@jit
def _test(us, vs, best_t, best_k, tri, k):  # pragma: no cover
    """One triangle (tri: its TRI_WORDS numbers, k its key) against the rays (us, vs) (r,):
    best_t, best_k (r,) updated where it is hit nearer (or as near with a lower key).

    Branch-free over whole arrays from index 0 (views): the compiler vectorises it.
    """
    x0, y0, z0 = tri[0], tri[1], tri[2]
    x1, y1, z1 = tri[3], tri[4], tri[5]
    x2, y2, z2 = tri[6], tri[7], tri[8]
    det = tri[9]
    tol = tri[10]
    for r in range(us.shape[0]):
        u, v = us[r], vs[r]
        # The vertices sheared along the ray (the same operations for every triangle).
        ax, ay = x0 - z0 * u, y0 - z0 * v
        bx, by = x1 - z1 * u, y1 - z1 * v
        cx, cy = x2 - z2 * u, y2 - z2 * v
        e0 = ax * by - ay * bx
        e1 = bx * cy - by * cx
        e2 = cx * ay - cy * ax
        t = det / (e0 + e1 + e2)
        lo = min(e0, min(e1, e2))
        hi = max(e0, max(e1, e2))
        bt, bk = best_t[r], best_k[r]
        # Inside (all three >= 0 or all <= 0 within rounding: either side), in front,
        # finite (a ray in the triangle's plane has t = +-inf or NaN), nearer or a tie
        # with a lower key.
        ok = ((lo >= -tol) | (hi <= tol)) & (t > 0.0) & (t < np.inf) & ((t < bt) | ((t == bt) & (k < bk)))
        best_t[r] = t if ok else bt
        best_k[r] = k if ok else bk


@jit
def pick_cells(c_lo, c_hi, ray_start, order, us, vs, tri_start, tris, data, zmin, early,
               tri_inst, tri_prim, inst, prim):  # pragma: no cover
    """Closest triangle of every ray in cells c_lo..c_hi-1: its instance and primitive into
    inst, prim (n,) int32 at the ray's index (-1 on a miss; every binned ray is written, so
    arrays whose rays are all binned need no filling first).

    ray_start, order, us, vs: the rays counting-sorted by cell with their u, v
    (:func:`bin_rays`, :func:`scatter_rays`: structure of arrays, so the loop over a
    cell's rays vectorises); tri_start, tris: :func:`cell_lists`; data (t,
    TRI_WORDS), zmin (t,): :func:`triangles`, by triangle index, which is also the
    key of a tie (in (instance, primitive) order: the lowest wins) and indexes
    tri_inst, tri_prim; every cell's list ascends in zmin.

    ``early``: a cell stops once every ray's hit lies nearer than the next
    triangle's nearest depth (t < zmin (1 - 1e-9): a margin far above the
    rounding of t, so that no triangle that could win or tie is skipped).
    """
    size = 0
    for c in range(c_lo, c_hi):
        size = max(size, ray_start[c + 1] - ray_start[c])
    best_t, best_k = np.empty(size), np.empty(size, np.int64)
    for c in range(c_lo, c_hi):
        r0, r1 = ray_start[c], ray_start[c + 1]
        k = r1 - r0
        if k == 0:
            continue
        for j in range(k):
            best_t[j] = np.inf
            best_k[j] = -1
        reach = np.inf  # the farthest depth of a current hit in this cell
        for p in range(tri_start[c], tri_start[c + 1]):
            f = tris[p]
            if early and reach < zmin[f] * (1.0 - 1e-9):
                break
            _test(us[r0:r1], vs[r0:r1], best_t[:k], best_k[:k], data[f], f)
            if early:
                reach = 0.0
                for j in range(k):
                    reach = max(reach, best_t[j])
        for j in range(k):
            f = best_k[j]
            if f >= 0:
                inst[order[r0 + j]] = tri_inst[f]
                prim[order[r0 + j]] = tri_prim[f]
            else:
                inst[order[r0 + j]] = -1
                prim[order[r0 + j]] = -1



@jit
def row_sums(a, w):  # pragma: no cover
    """(sum_i w_i a_i (3,), sum_i |a_i|^2) over the rows of a (n, 3), weights w (n,).

    One pass in a fixed order on the calling thread (no BLAS threads: a threaded gemv
    took 7-8 ms instead of 0.1 ms for 342,000 rows when the other core was busy), so the
    same arrays always give the same bits. NaN and inf propagate.
    """
    s0 = s1 = s2 = ff = 0.0
    for i in range(a.shape[0]):
        x, y, z = a[i, 0], a[i, 1], a[i, 2]
        s0 += w[i] * x
        s1 += w[i] * y
        s2 += w[i] * z
        ff += x * x + y * y + z * z
    return np.array([s0, s1, s2]), ff
