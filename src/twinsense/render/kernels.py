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
    shared = n > 0 and o.strides[0] == 0
    if shared:
        w0, w1, w2 = centre[0] - o[0, 0], centre[1] - o[0, 1], centre[2] - o[0, 2]
        ww = w0 * w0 + w1 * w1 + w2 * w2
        # Outside the sphere the rays that meet it form a cone around w:
        # tca >= sqrt(|w|^2 - r^2) (so tca > 0); inside, every ray does.
        cone = math.sqrt(ww - r2) if ww > r2 else -np.inf
        for i in range(n):
            tca = d[i, 0] * w0
            tca += d[i, 1] * w1
            tca += d[i, 2] * w2
            if tca >= cone and tca + radius > 0.0 and tca - radius < t_max[i]:
                cand[m] = i
                m += 1
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
    sel = np.empty(m, np.int64)
    ol = np.empty((m, 3))
    dl = np.empty((m, 3))
    k = 0
    for c in range(m):
        i = cand[c]
        x0, x1, x2 = o[i, 0] - pos[0], o[i, 1] - pos[1], o[i, 2] - pos[2]
        near = 0.0
        far = t_max[i]
        for a in range(3):
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
def rotate_rows(v, m):  # pragma: no cover
    """``v @ m`` for rows v (n, 3) float64 and m (3, 3): a new (n, 3) array, one pass.

    The products of :func:`twinsense.linalg.rotate_rows` summed in its order
    (x m[0, k] + y m[1, k] + z m[2, k]), so the same bits; that function
    makes nine passes over the rows, this one.
    """
    out = np.empty((v.shape[0], 3))
    for i in range(v.shape[0]):
        x, y, z = v[i, 0], v[i, 1], v[i, 2]
        for k in range(3):
            c = x * m[0, k]
            c += y * m[1, k]
            c += z * m[2, k]
            out[i, k] = c
    return out


@jit
def direction_cone(d):  # pragma: no cover
    """A cone around unit directions d (n, 3): its axis (3,) and the cosine of its half-angle.

    Every direction is within the half-angle of the axis (the minimum of d . axis,
    lowered by 1e-12 to cover rounding). An empty bundle gives a zero cone (cosine 2).
    """
    n = d.shape[0]
    s0 = s1 = s2 = 0.0
    for i in range(n):
        s0 += d[i, 0]
        s1 += d[i, 1]
        s2 += d[i, 2]
    norm = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
    axis = np.zeros(3)
    if n == 0:
        return axis, 2.0
    if norm == 0.0:  # directions that cancel: the whole sphere
        axis[2] = 1.0
        return axis, -1.0
    axis[0], axis[1], axis[2] = s0 / norm, s1 / norm, s2 / norm
    lowest = 1.0
    for i in range(n):
        c = d[i, 0] * axis[0] + d[i, 1] * axis[1] + d[i, 2] * axis[2]
        if c < lowest:
            lowest = c
    return axis, lowest - 1e-12
