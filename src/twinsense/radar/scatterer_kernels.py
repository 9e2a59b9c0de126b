"""Compiled per-scatterer passes of the radar render (numba).

A radar frame turns every hit pixel into a scatterer: its point in the
sensor frame, its velocity relative to the sensor, the RCS of the surface
patch the pixel sees and its radar-equation amplitude. In NumPy that is a
dozen passes over every pixel, each with its own temporaries (a moving radar
on the robot cell's flange: ~30 ms of CPU per frame for 342,000 pixels,
about as long as Embree's traversal of the same rays). Here it is one
compiled loop, run over blocks of pixels on the shared worker threads
(without the GIL), and the world rays of a new pose another.

Every loop does the IEEE float64 operations of the NumPy form it replaces in
the same order (``fastmath`` off: no reassociation, no fused multiply-adds),
so it gives the same bits: ``ScatterRenderer`` keeps the NumPy form as its
reference (``compiled=False``) and ``tests/radar/test_scatterer_kernels.py``
compares the two. The only calls into a maths library are ``acos`` and
``exp`` of the specular lobe, the same libm functions NumPy calls for
float64 on CPUs without AVX-512 (with it NumPy may take its own SIMD forms,
within an ulp or two of libm).
"""

from __future__ import annotations

import math

import numpy as np

from twinsense.compiled import jit


@jit
def world_directions(lo, hi, dirs_cols, rot, out):  # pragma: no cover
    """out[i] = R d_i for i in [lo, hi): dirs_cols (3, n) sensor-frame directions as
    three columns, rot (3, 3) sensor -> world, out (n, 3) (the NumPy form's column
    products: d_x R[k, 0] + R[k, 1] d_y + R[k, 2] d_z, in that order)."""
    r00, r01, r02 = rot[0, 0], rot[0, 1], rot[0, 2]
    r10, r11, r12 = rot[1, 0], rot[1, 1], rot[1, 2]
    r20, r21, r22 = rot[2, 0], rot[2, 1], rot[2, 2]
    for i in range(lo, hi):
        x, y, z = dirs_cols[0, i], dirs_cols[1, i], dirs_cols[2, i]
        c = x * r00
        c += r01 * y
        c += r02 * z
        out[i, 0] = c
        c = x * r10
        c += r11 * y
        c += r12 * z
        out[i, 1] = c
        c = x * r20
        c += r21 * y
        c += r22 * z
        out[i, 2] = c


@jit
def _times_row(v0, v1, v2, rot, k):  # pragma: no cover
    """(v @ rot)[k] summed as np.einsum("ij,jk->ik") sums it: from +0.0, j = 0, 1, 2."""
    acc = 0.0
    acc += v0 * rot[0, k]
    acc += v1 * rot[1, k]
    acc += v2 * rot[2, k]
    return acc


@jit
def direct_scatterers(lo, hi, rows, dirs_cols, solid_angle, gain, dist, cos_inc, mat, obj,
                      v_world, refl, spec, inv_lobe, lobe_scale, amp_scale, rot, v_o, w_s,
                      sensor_moves, moving_obj, points, vel, rcs, amp, rates, work):  # pragma: no cover
    """Scatterers m in [lo, hi) of the direct hits: points, velocities, RCS, amplitudes.

    Inputs per pixel (n pixels): dirs_cols (3, n) sensor-frame unit directions,
    solid_angle (n,) [sr], gain (n,) G_t G_r; per ray of the cast: dist (n,) [m],
    cos_inc (n,), mat, obj (n,) int32, v_world (n, 3) world velocity of the hit
    point [m/s]. rows (k,) int64: the hit pixel of each scatterer (empty: every
    pixel hit, scatterer m is pixel m). refl, spec (materials,): radar
    reflectivity and specular share per scene material; inv_lobe = 1 / lobe [1/rad],
    lobe_scale = 2 / (3 lobe^2); amp_scale = 2 P_t lambda^2 / (4 pi)^3 [W m^2].
    rot (3, 3) sensor -> world; v_o, w_s (3,) the sensor's linear and angular
    velocity in its own frame (v @ R), used when sensor_moves; else moving_obj
    (objects,) bool: which objects move (their points get R^T v, others zero).

    Writes points (k, 3) [m] and vel (k, 3) [m/s] (sensor frame), rcs (k,) [m^2]
    and, if amp has k rows (zero rows: not wanted), amp (k,) [sqrt(W)]:
    the operations of ``radiometry.backscatter_rcs``,
    ``radiometry.radar_equation_amplitude`` and ``ScatterRenderer._hit_velocities``.
    If rates has k rows: rates (k,) each scatterer's range rate p . v / |p| [m/s] (as
    the synthesis forms it to sort its movers; a moving sensor only). If work has k rows: work (k, 8) gets each
    scatterer's point, velocity, rcs and amplitude instead of points, vel, rcs, amp.
    """
    gather = rows.shape[0] > 0
    to_work = work.shape[0] > 0
    want_amp = amp.shape[0] > 0 or to_work
    want_rates = rates.shape[0] > 0
    for m in range(lo, hi):
        i = rows[m] if gather else m
        r = dist[i]
        p0 = dirs_cols[0, i] * r
        p1 = dirs_cols[1, i] * r
        p2 = dirs_cols[2, i] * r
        # RCS of the pixel's patch: rho [(1 - k) c + k L(theta) / c] Omega R^2.
        c = cos_inc[i]
        if c < 1e-6:  # np.clip(c, 1e-6, 1.0) (a NaN stays NaN)
            c = 1e-6
        elif c > 1.0:
            c = 1.0
        mid = mat[i]
        sp = spec[mid]
        s = (1.0 - sp) * c
        # Where the share is zero the NumPy form adds a lobe of +0.0: no change.
        if sp != 0.0:
            th = math.acos(c) * inv_lobe
            th = th * th
            lobe = math.exp(-th)
            lobe *= lobe_scale
            lobe *= sp
            lobe /= c
            s += lobe
        s *= refl[mid]
        s *= solid_angle[i]
        s *= r
        s *= r
        a = 0.0
        if want_amp:
            a = gain[i] * s
            a *= amp_scale
            a = math.sqrt(a)
            den = r * r
            a = a / den if den > 0 else 0.0
        # Velocity relative to the sensor, sensor frame.
        v0, v1, v2 = v_world[i, 0], v_world[i, 1], v_world[i, 2]
        if sensor_moves:
            # R^T v_p - R^T v_o - (R^T w) x p_s, column by column as the NumPy form.
            e0 = _times_row(v0, v1, v2, rot, 0) - v_o[0]
            e1 = _times_row(v0, v1, v2, rot, 1) - v_o[1]
            e2 = _times_row(v0, v1, v2, rot, 2) - v_o[2]
            if w_s[1] != 0.0:
                e0 -= w_s[1] * p2
            if w_s[2] != 0.0:
                e0 += w_s[2] * p1
            if w_s[2] != 0.0:
                e1 -= w_s[2] * p0
            if w_s[0] != 0.0:
                e1 += w_s[0] * p2
            if w_s[0] != 0.0:
                e2 -= w_s[0] * p1
            if w_s[1] != 0.0:
                e2 += w_s[1] * p0
            if want_rates:
                rates[m] = range_rate(p0, p1, p2, e0, e1, e2)
        elif moving_obj[obj[i]]:
            e0 = _times_row(v0, v1, v2, rot, 0)
            e1 = _times_row(v0, v1, v2, rot, 1)
            e2 = _times_row(v0, v1, v2, rot, 2)
        else:
            e0 = e1 = e2 = 0.0
        if to_work:  # one 64-byte row per scatterer, for the gather in sorted order
            work[m, 0] = p0
            work[m, 1] = p1
            work[m, 2] = p2
            work[m, 3] = e0
            work[m, 4] = e1
            work[m, 5] = e2
            work[m, 6] = s
            work[m, 7] = a
        else:
            points[m, 0] = p0
            points[m, 1] = p1
            points[m, 2] = p2
            vel[m, 0] = e0
            vel[m, 1] = e1
            vel[m, 2] = e2
            rcs[m] = s
            if want_amp:
                amp[m] = a


@jit
def range_rate(p0, p1, p2, v0, v1, v2):  # pragma: no cover
    """p . v / max(|p|, 1e-12) [m/s]: the range rate from the sensor origin, summed as
    ``synthesis._range_rate`` sums it (column by column, then one division)."""
    dot = p0 * v0
    dot += p1 * v1
    dot += p2 * v2
    n2 = p0 * p0
    n2 += p1 * p1
    n2 += p2 * p2
    r = math.sqrt(n2)
    if r < 1e-12:  # np.maximum(r, 1e-12); a NaN stays NaN
        r = 1e-12
    return dot / r


_SIGN = np.uint64(1 << 63)
_ALL = np.uint64(0xFFFFFFFFFFFFFFFF)


@jit
def rate_key(x, bits):  # pragma: no cover
    """A uint64 whose unsigned order is NumPy's sort order of the float64 x (``bits``: its
    bit pattern): -0.0 and 0.0 are one key (NumPy sorts them as equal), every NaN the
    largest key (NumPy sorts NaNs last)."""
    if x != x:
        return _ALL
    if x == 0.0:
        return _SIGN
    return bits ^ _ALL if bits & _SIGN else bits | _SIGN


_DIGIT = 8
_BINS = 1 << _DIGIT
_LOW = np.uint64(0xFFFFFFFF)


@jit
def _radix_top32(packed):  # pragma: no cover
    """packed (n,) uint64 (a key's top 32 bits above a 32-bit index) sorted stably by
    the top 32 bits: four LSD radix passes of 8 bits, a pass whose digit every entry
    shares skipped. Returns the sorted array (``packed`` or a new one)."""
    n = packed.shape[0]
    hist = np.zeros((4, _BINS), np.int64)
    mask = np.uint64(_BINS - 1)
    for i in range(n):
        k = packed[i]
        for d in range(4):
            hist[d, np.int64((k >> np.uint64(32 + _DIGIT * d)) & mask)] += 1
    out = np.empty(n, np.uint64)
    offset = np.empty(_BINS, np.int64)
    for d in range(4):
        h = hist[d]
        if h.max() == n:
            continue
        total = 0
        for b in range(_BINS):
            offset[b] = total
            total += h[b]
        shift = np.uint64(32 + _DIGIT * d)
        for i in range(n):
            k = packed[i]
            b = np.int64((k >> shift) & mask)
            at = offset[b]
            offset[b] = at + 1
            out[at] = k
        packed, out = out, packed
    return packed


@jit
def stable_argsort(x, bits):  # pragma: no cover
    """(n,) int64 indices that sort x (n,) float64 ascending, equal values in index order:
    ``np.argsort(x, kind="stable")`` (n < 2^32); ``bits``: ``x.view(np.uint64)``.

    Radix passes over the keys' top 32 bits (each packed with its index, 8 bytes an
    entry), then each run of entries that share them sorted by the full keys by
    insertion (stable; range rates share 32 bits only in runs of a few). If the
    insertions take more than 16 moves per key, a stable radix sort of the full keys
    (low 32 bits first, then the top 32) instead.
    """
    n = x.shape[0]
    keys = np.empty(n, np.uint64)
    packed = np.empty(n, np.uint64)
    for i in range(n):
        k = rate_key(x[i], bits[i])
        keys[i] = k
        packed[i] = (k & ~_LOW) | np.uint64(i)
    packed = _radix_top32(packed)
    idx = np.empty(n, np.int64)
    for i in range(n):
        idx[i] = np.int64(packed[i] & _LOW)
    budget = 16 * n
    moves = 0
    a = 0
    while a < n:
        top = packed[a] & ~_LOW
        b = a + 1
        while b < n and packed[b] & ~_LOW == top:
            b += 1
        for i in range(a + 1, b):  # insertion sort of idx[a:b] by the full keys
            j = idx[i]
            k = keys[j]
            at = i
            while at > a and keys[idx[at - 1]] > k:
                idx[at] = idx[at - 1]
                at -= 1
                moves += 1
            idx[at] = j
            if moves > budget:
                return _full_radix(keys)
        a = b
    return idx


@jit
def _full_radix(keys):  # pragma: no cover
    """Stable argsort of keys (n,) uint64 by two sorts of 32 bits: by the low half,
    then (stably) by the high half."""
    n = keys.shape[0]
    packed = np.empty(n, np.uint64)
    for i in range(n):
        packed[i] = (keys[i] << np.uint64(32)) | np.uint64(i)
    packed = _radix_top32(packed)
    for m in range(n):
        i = np.int64(packed[m] & _LOW)
        packed[m] = (keys[i] & ~_LOW) | np.uint64(i)
    packed = _radix_top32(packed)
    idx = np.empty(n, np.int64)
    for i in range(n):
        idx[i] = np.int64(packed[i] & _LOW)
    return idx


@jit
def gather_rows(lo, hi, order, work, rows, obj, points, vel, rcs, amp, obj_out):  # pragma: no cover
    """Scatterers m in [lo, hi) in sorted order: row order[m] of work (k, 8) [points (3),
    velocity (3), rcs, amplitude] into points, vel (k, 3), rcs, amp (k,), and its
    object id from obj (n,) int32 (through rows (k,) if not empty, as in
    :func:`direct_scatterers`) into obj_out (k,)."""
    gather = rows.shape[0] > 0
    for m in range(lo, hi):
        i = order[m]
        points[m, 0] = work[i, 0]
        points[m, 1] = work[i, 1]
        points[m, 2] = work[i, 2]
        vel[m, 0] = work[i, 3]
        vel[m, 1] = work[i, 4]
        vel[m, 2] = work[i, 5]
        rcs[m] = work[i, 6]
        amp[m] = work[i, 7]
        obj_out[m] = obj[rows[i] if gather else i]


@jit
def hit_rows(obj):  # pragma: no cover
    """The rays that hit (obj >= 0): (rows, k), rows (k,) int64 their indices, ascending,
    k their count; rows is empty if every ray hits (a scatterer is then its ray:
    nothing to gather)."""
    n = obj.shape[0]
    k = 0
    for i in range(n):
        if obj[i] >= 0:
            k += 1
    if k == n:
        return np.zeros(0, np.int64), k
    rows = np.empty(k, np.int64)
    k = 0
    for i in range(n):
        if obj[i] >= 0:
            rows[k] = i
            k += 1
    return rows, k



@jit
def moving_mask(v, moving):  # pragma: no cover
    """moving (n,) bool: row i of v (n, 3) [m/s] has a component that is not zero (NaN
    counts as moving, as ``v != 0`` does); returns how many rows move."""
    count = 0
    for i in range(v.shape[0]):
        m = v[i, 0] != 0.0 or v[i, 1] != 0.0 or v[i, 2] != 0.0
        moving[i] = m
        count += m
    return count


@jit
def count_weighted(moving, w):  # pragma: no cover
    """How many rows are moving (n,) bool and carry a weight w (n,) complex that is not zero."""
    count = 0
    for i in range(w.shape[0]):
        if moving[i] and w[i] != 0:
            count += 1
    return count
