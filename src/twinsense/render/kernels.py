"""Compiled per-ray kernels of the caster (numba).

A cast turns Embree's triangle ids into hit distances, normals and ids, and
moves the rays near each moving object into that object's frame. In NumPy
each of those steps is a pass over every ray with its own temporaries; here
each is one loop over the rays, compiled once (cached on disk) and run
without the GIL, so the caster's worker threads run them side by side.

Every kernel does the same IEEE float64 operations in the same order as the
NumPy expressions it replaces (``fastmath`` off, so no reassociation or
fused multiply-adds), and gives the same bits; ``tests/render`` checks that
against the NumPy forms.
"""

from __future__ import annotations

import math

import numpy as np

from twinsense.compiled import jit


@jit
def finish_hits(face, planes, face_geom, face_prim, o, d, t, geom, prim, normal, den):  # pragma: no cover
    """Hit distance, ids and normal of each ray from its global triangle id (-1: a miss).

    face (n,) int; planes (m + 1, 4) (unit normal, n . v0; last row zeros);
    face_geom, face_prim (m + 1,) int32 (last entry -1); o, d (n, 3) float64
    (o may be a stride-0 broadcast of one origin). Writes t (n,) [inf on a
    miss], geom, prim (n,) int32, normal (n, 3) and den = normal . d (n,).
    The distance is (n . v0 - n . o) / (n . d): float64, exact for the hit
    triangle's plane whatever precision found the triangle.
    """
    last = planes.shape[0] - 1
    for i in range(face.shape[0]):
        f = face[i]
        row = last if f < 0 else f
        n0, n1, n2, off = planes[row, 0], planes[row, 1], planes[row, 2], planes[row, 3]
        dn = d[i, 0] * n0
        dn += d[i, 1] * n1
        dn += d[i, 2] * n2
        normal[i, 0], normal[i, 1], normal[i, 2] = n0, n1, n2
        den[i] = dn
        geom[i] = face_geom[row]
        prim[i] = face_prim[row]
        if f >= 0 and dn != 0.0:
            on = o[i, 0] * n0
            on += o[i, 1] * n1
            on += o[i, 2] * n2
            t[i] = (off - on) / dn
        else:
            t[i] = np.inf


@jit
def _fmin(a, b):  # pragma: no cover
    """np.fmin: the smaller, ignoring a NaN operand."""
    if a != a:
        return b
    if b != b:
        return a
    return a if a < b else b


@jit
def _fmax(a, b):  # pragma: no cover
    if a != a:
        return b
    if b != b:
        return a
    return a if a > b else b


@jit
def _sphere_rays_shared(d, w0, w1, w2, cone, radius, t_max, i0, i1, cand, m):  # pragma: no cover
    """Append to ``cand`` (from ``m`` on) the rays i in [i0, i1) from one origin that enter
    the sphere (centre at origin + w, ``radius``) before ``t_max``; returns the new count.
    ``cone``: sqrt(|w|^2 - r^2) outside the sphere (-inf inside)."""
    for i in range(i0, i1):
        tca = d[i, 0] * w0
        tca += d[i, 1] * w1
        tca += d[i, 2] * w2
        if tca >= cone and tca + radius > 0.0 and tca - radius < t_max[i]:
            cand[m] = i
            m += 1
    return m


@jit
def _box_into_frame(o, d, cand, m, rot, pos, lo, hi, t_max):  # pragma: no cover
    """The candidate rays ``cand[:m]`` that enter the object-frame box [lo, hi] before
    ``t_max``, moved into the object's frame: (sel, o_local, d_local) as cull_into_frame."""
    sel = np.empty(m, np.int64)
    ol = np.empty((m, 3))
    dl = np.empty((m, 3))
    shared = o.shape[0] > 0 and o.strides[0] == 0
    # One origin: its local coordinates are the same for every ray (computed once).
    s0 = s1 = s2 = 0.0
    if shared:
        s0, s1, s2 = o[0, 0] - pos[0], o[0, 1] - pos[1], o[0, 2] - pos[2]
    so = np.empty(3)
    for a in range(3):
        oa = s0 * rot[0, a]
        oa += s1 * rot[1, a]
        oa += s2 * rot[2, a]
        so[a] = oa
    k = 0
    for c in range(m):
        i = cand[c]
        if not shared:
            x0, x1, x2 = o[i, 0] - pos[0], o[i, 1] - pos[1], o[i, 2] - pos[2]
        near = 0.0
        far = t_max[i]
        for a in range(3):
            if shared:
                oa = so[a]
            else:
                oa = x0 * rot[0, a]
                oa += x1 * rot[1, a]
                oa += x2 * rot[2, a]
            da = d[i, 0] * rot[0, a]
            da += d[i, 1] * rot[1, a]
            da += d[i, 2] * rot[2, a]
            ol[k, a] = oa
            dl[k, a] = da
            inv = 1.0 / da
            t1 = (lo[a] - oa) * inv
            t2 = (hi[a] - oa) * inv
            near = _fmax(near, _fmin(t1, t2))
            far = _fmin(far, _fmax(t1, t2))
        if near <= far:
            sel[k] = i
            k += 1
    return sel[:k], ol[:k], dl[:k]


@jit
def cull_into_frame(o, d, centre, radius, rot, pos, lo, hi, t_max):  # pragma: no cover
    """The rays that can hit a moving object before ``t_max``, moved into its frame.

    o, d (n, 3) float64 world rays (o may be a stride-0 broadcast of one
    origin); centre (3,) the object's bounding-sphere centre in the world,
    radius its radius; rot (3, 3), pos (3,) the object's pose (local -> world);
    lo, hi (3,) its bounding box in its frame; t_max (n,) the rays' current
    closest hits. A ray is kept if it enters the sphere and then the box
    before ``t_max`` (the tests of ``culling.rays_near_sphere`` and
    ``culling.rays_hit_box``, in the same float operations).

    Returns sel (k,) int64 ascending ray indices, o_local and d_local (k, 3)
    float64: x_local = (x - pos) @ rot, d_local = d @ rot.
    """
    n = d.shape[0]
    r2 = radius * radius
    # Sphere test first, alone: a tight loop over every ray (with one shared
    # origin, a camera, its threshold is one number and the loop vectorises).
    cand = np.empty(n, np.int64)
    m = 0
    if n > 0 and o.strides[0] == 0:
        w0, w1, w2 = centre[0] - o[0, 0], centre[1] - o[0, 1], centre[2] - o[0, 2]
        ww = w0 * w0 + w1 * w1 + w2 * w2
        # Outside the sphere the rays that meet it form a cone around w:
        # tca >= sqrt(|w|^2 - r^2) (so tca > 0); inside, every ray does.
        cone = math.sqrt(ww - r2) if ww > r2 else -np.inf
        m = _sphere_rays_shared(d, w0, w1, w2, cone, radius, t_max, 0, n, cand, 0)
    else:
        for i in range(n):
            w0 = centre[0] - o[i, 0]
            w1 = centre[1] - o[i, 1]
            w2 = centre[2] - o[i, 2]
            tca = d[i, 0] * w0
            tca += d[i, 1] * w1
            tca += d[i, 2] * w2
            ww = w0 * w0 + w1 * w1 + w2 * w2
            if ww > r2 and not tca >= math.sqrt(ww - r2):
                continue
            if tca + radius > 0.0 and tca - radius < t_max[i]:
                cand[m] = i
                m += 1
    return _box_into_frame(o, d, cand, m, rot, pos, lo, hi, t_max)


#: Rays per block of :func:`block_cones` (a chunk of the caster is a whole number of blocks).
CONE_BLOCK = 64
#: Added to every cone's half-angle [rad]: acos and asin of a float64 near 1 are off by up to
#: sqrt(2 * 2.2e-16) ~ 2.1e-8 rad (and a unit direction's length by ~1e-16), so 1e-7 rad keeps
#: the cones conservative (0.1 um at 1 m: no measurable loss of culling).
_ANGLE_MARGIN = 1e-7


@jit
def block_cones(d, block):  # pragma: no cover
    """Cones around each block of ``block`` consecutive unit directions d (n, 3) (unit to
    rounding, ~1e-16: the margin below covers what that does to an angle).

    Returns axis (b, 3), half-angle (b,) [rad] and its cosine and sine (b,),
    b = ceil(n / block): every direction of block k lies within half[k] of
    axis[k] (the largest angle found, widened by _ANGLE_MARGIN for rounding).
    A block whose directions cancel out gets the whole sphere (half-angle pi).
    """
    n = d.shape[0]
    nb = (n + block - 1) // block
    axis = np.zeros((nb, 3))
    half = np.empty(nb)
    cos_h = np.empty(nb)
    sin_h = np.empty(nb)
    for b in range(nb):
        i0 = b * block
        i1 = min(n, i0 + block)
        s0 = s1 = s2 = 0.0
        for i in range(i0, i1):
            s0 += d[i, 0]
            s1 += d[i, 1]
            s2 += d[i, 2]
        norm = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        if norm == 0.0:
            axis[b, 2] = 1.0
            h = math.pi
        else:
            a0, a1, a2 = s0 / norm, s1 / norm, s2 / norm
            axis[b, 0], axis[b, 1], axis[b, 2] = a0, a1, a2
            lowest = 1.0
            for i in range(i0, i1):
                # d is unit to ~1e-16: the angle from that is off by far less than the margin.
                c = d[i, 0] * a0 + d[i, 1] * a1 + d[i, 2] * a2
                if c < lowest:
                    lowest = c
            h = min(math.pi, math.acos(max(-1.0, min(1.0, lowest))) + _ANGLE_MARGIN)
        half[b] = h
        cos_h[b] = math.cos(h)
        sin_h[b] = math.sin(h)
    return axis, half, cos_h, sin_h


@jit
def _box_cone(o, rot, pos, lo, hi):  # pragma: no cover
    """A cone from the origin o[0] that holds the box [lo, hi] (object frame; pose rot, pos):
    its unit axis (three floats) and half-angle [rad] (pi if none narrower than a half-space).

    The axis points at the box's centre; the half-angle is the largest angle to a
    corner, widened by _ANGLE_MARGIN. A cone of half-angle below pi / 2 is convex,
    so it holds the convex hull of the corners, the box; from an origin inside
    the box, or one that sees the corners over pi / 2 or more, no cone is given.
    """
    c0 = c1 = c2 = 0.0
    for a in range(3):
        m = 0.5 * (lo[a] + hi[a])
        c0 += rot[0, a] * m
        c1 += rot[1, a] * m
        c2 += rot[2, a] * m
    a0, a1, a2 = pos[0] + c0 - o[0, 0], pos[1] + c1 - o[0, 1], pos[2] + c2 - o[0, 2]
    norm = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    if norm == 0.0:
        return 0.0, 0.0, 1.0, math.pi
    a0, a1, a2 = a0 / norm, a1 / norm, a2 / norm
    lowest = 1.0
    for corner in range(8):
        x = hi[0] if corner & 1 else lo[0]
        y = hi[1] if corner & 2 else lo[1]
        z = hi[2] if corner & 4 else lo[2]
        p0 = pos[0] + rot[0, 0] * x + rot[0, 1] * y + rot[0, 2] * z - o[0, 0]
        p1 = pos[1] + rot[1, 0] * x + rot[1, 1] * y + rot[1, 2] * z - o[0, 1]
        p2 = pos[2] + rot[2, 0] * x + rot[2, 1] * y + rot[2, 2] * z - o[0, 2]
        pn = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
        if pn == 0.0:
            return a0, a1, a2, math.pi
        c = (p0 * a0 + p1 * a1 + p2 * a2) / pn
        if c < lowest:
            lowest = c
    half = math.acos(max(-1.0, min(1.0, lowest))) + _ANGLE_MARGIN
    if half >= 0.5 * math.pi - 1e-6:
        return a0, a1, a2, math.pi
    return a0, a1, a2, half


@jit
def object_wins(sel, t_m, prim, n_local, dist, d, rot, update):  # pragma: no cover
    """The traced rays on which a moving object is nearer than their current hit.

    sel (k,) ray indices traced against the object; t_m (k,) their hit
    distances (inf: a miss), prim (k,) int32 triangle ids, n_local (k, 3)
    normals in the object's frame; dist (n,) the current closest hits (set to
    the object's distance where it wins, if ``update``); d (n, 3) world
    directions; rot (3, 3) the object's rotation (local -> world).

    Returns rows (w,) int64, distances (w,), triangle ids (w,) int32, world
    normals (w, 3) (n_local @ rot.T, as ``caster._rotate``) and normal . d (w,),
    with the float operations of the NumPy forms in their order (same bits).
    """
    k = sel.shape[0]
    won = np.empty(k, np.int64)
    w = 0
    for j in range(k):
        if t_m[j] < dist[sel[j]]:  # inf < inf is False: misses never win
            won[w] = j
            w += 1
    rows = np.empty(w, np.int64)
    t_won = np.empty(w)
    tri = np.empty(w, np.int32)
    normal = np.empty((w, 3))
    dn = np.empty(w)
    for q in range(w):
        j = won[q]
        i = sel[j]
        rows[q] = i
        t_won[q] = t_m[j]
        tri[q] = prim[j]
        x, y, z = n_local[j, 0], n_local[j, 1], n_local[j, 2]
        for a in range(3):
            c = x * rot[a, 0]
            c += y * rot[a, 1]
            c += z * rot[a, 2]
            normal[q, a] = c
        s = normal[q, 0] * d[i, 0]
        s += normal[q, 1] * d[i, 1]
        s += normal[q, 2] * d[i, 2]
        dn[q] = s
    if update:
        for q in range(w):
            dist[rows[q]] = t_won[q]
    return rows, t_won, tri, normal, dn


@jit
def rotate_rows(v, m):  # pragma: no cover
    """``v @ m`` for rows v (n, 3) float64 and m (3, 3): a new (n, 3) array, one pass.

    The products of :func:`twinsense.linalg.rotate_rows` summed in its order
    (x m[0, k] + y m[1, k] + z m[2, k]), so the same bits; that function
    makes nine passes over the rows, this one.
    """
    out = np.empty((v.shape[0], 3))
    for i in range(v.shape[0]):
        _rotate_row(v, m, out, i)
    return out


@jit
def _rotate_row(v, m, out, i):  # pragma: no cover
    """out[i] = v[i] @ m, each column x m[0, k] + y m[1, k] + z m[2, k] in that order."""
    x, y, z = v[i, 0], v[i, 1], v[i, 2]
    for k in range(3):
        c = x * m[0, k]
        c += y * m[1, k]
        c += z * m[2, k]
        out[i, k] = c


@jit
def rotate_rows_summed(v, m, w):  # pragma: no cover
    """:func:`rotate_rows` of v (n, 3) by m (3, 3), and in the same pass over v the sums of
    :func:`twinsense.render.bundle_kernels.row_sums` (sum_i w_i v_i (3,), sum_i |v_i|^2) with
    weights w (n,): each in its own order, so the bits of both (a moving sensor's bundle is
    rotated and its checksum taken in one read of the rows instead of three)."""
    out = np.empty((v.shape[0], 3))
    s0 = s1 = s2 = ff = 0.0
    for i in range(v.shape[0]):
        _rotate_row(v, m, out, i)
        x, y, z = v[i, 0], v[i, 1], v[i, 2]
        s0 += w[i] * x
        s1 += w[i] * y
        s2 += w[i] * z
        ff += x * x + y * y + z * z
    return out, np.array([s0, s1, s2]), ff


@jit
def _grown(sel, ol, dl, k, cap):  # pragma: no cover
    """Copies of the first k rows of sel (n,) and ol, dl (n, 3) in buffers of ``cap`` rows."""
    sel2 = np.empty(cap, np.int64)
    ol2 = np.empty((cap, 3))
    dl2 = np.empty((cap, 3))
    for q in range(k):
        sel2[q] = sel[q]
        for a in range(3):
            ol2[q, a] = ol[q, a]
            dl2[q, a] = dl[q, a]
    return sel2, ol2, dl2


@jit
def cull_objects_into_frames(o, d, cones, block, centres, radius, rots, poss, lo, hi, t_max):  # pragma: no cover
    """:func:`cull_into_frame` for every moving object in one call, for rays from one
    origin (o a stride-0 broadcast), skipping the blocks of rays whose cone misses an object.

    cones: :func:`block_cones` of ``d`` with ``block`` rays per block; centres
    (m, 3) the objects' bounding-sphere centres in the world, radius (m,), rots
    (m, 3, 3) and poss (m, 3) their poses (local -> world), lo, hi (m, 3) their
    boxes in their frames; t_max (n,) as for :func:`cull_into_frame` (every
    object is culled against the same ``t_max``).

    A ray that meets an object lies within a cone from the origin that holds
    it (half-angle beta: the bounding sphere's angular radius, or the box's,
    see :func:`_box_cone`, whichever is narrower) and within its block's
    half-angle of the block's axis, so the angle between the two axes is at
    most half + beta (triangle inequality on the unit sphere); blocks beyond
    that (with margins of _ANGLE_MARGIN on each angle) hold no ray that the
    sphere and box tests keep. The rays of the other blocks take the sphere
    and box tests of :func:`cull_into_frame`: the same rays, the same bits.

    Returns sel (k,), o_local, d_local (k, 3): the objects' kept rays one after
    the other, and offsets (m + 1,): object j's rows are offsets[j]:offsets[j + 1].
    """
    axis, half, cos_h, sin_h = cones
    n = d.shape[0]
    m = radius.shape[0]
    offsets = np.zeros(m + 1, np.int64)
    cand = np.empty(n, np.int64)
    # One growing buffer (no list of arrays: those make the compile much longer).
    cap = 1024
    sel_all = np.empty(cap, np.int64)
    ol_all = np.empty((cap, 3))
    dl_all = np.empty((cap, 3))
    k = 0
    for j in range(m):
        if n == 0:
            break
        r = radius[j]
        r2 = r * r
        w0, w1, w2 = centres[j, 0] - o[0, 0], centres[j, 1] - o[0, 1], centres[j, 2] - o[0, 2]
        ww = w0 * w0 + w1 * w1 + w2 * w2
        inside = not ww > r2
        cone = -np.inf if inside else math.sqrt(ww - r2)
        # The cone from the origin that holds the object: around the sphere's centre
        # with its angular radius, or (tighter for an origin inside the sphere but
        # outside the box, a camera beside its own carrier's link) around the box.
        u0, u1, u2, beta = _box_cone(o, rots[j], poss[j], lo[j], hi[j])
        if not inside:
            dist = math.sqrt(ww)
            b_sphere = math.asin(min(1.0, r / dist)) + _ANGLE_MARGIN
            if b_sphere < beta:
                u0, u1, u2, beta = w0 / dist, w1 / dist, w2 / dist, b_sphere
        cb, sb = math.cos(beta), math.sin(beta)
        c_count = 0
        for b in range(half.shape[0]):
            i0 = b * block
            i1 = min(n, i0 + block)
            if half[b] + beta < math.pi:
                # cos(angle from the block's axis to the object's cone axis) against cos(half + beta).
                c = axis[b, 0] * u0 + axis[b, 1] * u1 + axis[b, 2] * u2
                if c < cos_h[b] * cb - sin_h[b] * sb - 1e-12:
                    continue
            c_count = _sphere_rays_shared(d, w0, w1, w2, cone, r, t_max, i0, i1, cand, c_count)
        sel, ol, dl = _box_into_frame(o, d, cand, c_count, rots[j], poss[j], lo[j], hi[j], t_max)
        need = k + sel.shape[0]
        if need > cap:
            cap = max(need, 2 * cap)
            sel_all, ol_all, dl_all = _grown(sel_all, ol_all, dl_all, k, cap)
        # Element by element: numba compiles these loops much faster than slice copies.
        for q in range(sel.shape[0]):
            sel_all[k + q] = sel[q]
            for a in range(3):
                ol_all[k + q, a] = ol[q, a]
                dl_all[k + q, a] = dl[q, a]
        k = need
        offsets[j + 1] = k
    return sel_all[:k], ol_all[:k], dl_all[:k], offsets


def cull_blocks_into_frame(o, d, cones, block, centre, radius, rot, pos, lo, hi, t_max):
    """:func:`cull_objects_into_frames` for one object (centre (3,), radius, rot (3, 3),
    pos, lo, hi (3,)): its (sel, o_local, d_local)."""
    one = np.ascontiguousarray
    sel, o_local, d_local, _ = cull_objects_into_frames(
        o, d, cones, block, one(np.reshape(centre, (1, 3)), dtype=float), one([float(radius)]),
        one(np.reshape(rot, (1, 3, 3)), dtype=float), one(np.reshape(pos, (1, 3)), dtype=float),
        one(np.reshape(lo, (1, 3)), dtype=float), one(np.reshape(hi, (1, 3)), dtype=float), t_max)
    return sel, o_local, d_local
