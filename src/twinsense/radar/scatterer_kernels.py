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
                      sensor_moves, moving_obj, points, vel, rcs, amp):  # pragma: no cover
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
    """
    gather = rows.shape[0] > 0
    want_amp = amp.shape[0] > 0
    for m in range(lo, hi):
        i = rows[m] if gather else m
        r = dist[i]
        p0 = dirs_cols[0, i] * r
        p1 = dirs_cols[1, i] * r
        p2 = dirs_cols[2, i] * r
        points[m, 0] = p0
        points[m, 1] = p1
        points[m, 2] = p2
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
        rcs[m] = s
        if want_amp:
            a = gain[i] * s
            a *= amp_scale
            a = math.sqrt(a)
            den = r * r
            amp[m] = a / den if den > 0 else 0.0
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
            vel[m, 0] = e0
            vel[m, 1] = e1
            vel[m, 2] = e2
        elif moving_obj[obj[i]]:
            vel[m, 0] = _times_row(v0, v1, v2, rot, 0)
            vel[m, 1] = _times_row(v0, v1, v2, rot, 1)
            vel[m, 2] = _times_row(v0, v1, v2, rot, 2)
        else:
            vel[m, 0] = 0.0
            vel[m, 1] = 0.0
            vel[m, 2] = 0.0


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
