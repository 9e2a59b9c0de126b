"""Compiled re-projection of sensor rays into an external render (numba).

:func:`twinsense.render.external.images_to_hits` describes the method: a ray
from the render centre samples the render once; an offset ray is marched
through the render in steps of at most one pixel, the first step behind the
surface is bisected, and the fixed point polishes the crossing. In NumPy
every step is a pass over all rays with its own temporaries; here each ray
runs its own loop (its own number of marching steps) without the GIL.
The arithmetic is the NumPy reference's (``_reproject_numpy`` in
``external.py``), so both give the same hits to rounding; the tests run both.
"""

from __future__ import annotations

import math

import numpy as np

from twinsense.compiled import jit


@jit
def _surface(px, py, pz, iz, w, h, fx, fy, cx, cy, k1, k2, p1, p2, k3, distorted, nearest,
             edge_tol):  # pragma: no cover - compiled
    """(ok, z, xn, yn, u, v): the render's surface along the pixel ray through point p."""
    if not pz > 0.0:
        return False, math.nan, 0.0, 0.0, math.nan, math.nan
    inv = 1.0 / pz
    xn = px * inv
    yn = py * inv
    xd, yd = xn, yn
    if distorted:
        r2 = xn * xn + yn * yn
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = xn * radial + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn)
        yd = yn * radial + p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn
    u = fx * xd + cx
    v = fy * yd + cy
    if not (u >= -0.5 and u <= w - 0.5 and v >= -0.5 and v <= h - 0.5):
        return False, math.nan, xn, yn, u, v
    uu = min(max(u, 0.0), w - 1.0)
    vv = min(max(v, 0.0), h - 1.0)
    near = iz[int(np.rint(vv)), int(np.rint(uu))]
    val = near
    if not nearest:
        u0 = min(int(uu), max(w - 2, 0))
        v0 = min(int(vv), max(h - 2, 0))
        u1 = u0 + 1 if w > 1 else u0
        v1 = v0 + 1 if h > 1 else v0
        a = iz[v0, u0]
        b = iz[v0, u1]
        c = iz[v1, u0]
        d = iz[v1, u1]
        gmax = max(max(a, b), max(c, d))
        gmin = min(min(a, b), min(c, d))
        if gmin > 0 and gmax - gmin <= edge_tol * gmin:
            fu = uu - u0
            fv = vv - v0
            top = a + fu * (b - a)
            bottom = c + fu * (d - c)
            val = top + fv * (bottom - top)
    if not val > 0:
        return False, math.nan, xn, yn, u, v
    return True, 1.0 / val, xn, yn, u, v


@jit
def reproject(o, d, iz, intr, distorted, nearest, edge_tol, s_near, s_far, f_max, max_steps,
              bisections, iterations, s_out, q_out, u_out, v_out, ok_out):  # pragma: no cover - compiled
    """For rays o (n, 3), d (n, 3) in the render camera frame: ray parameter s [m], the last
    surface point Q (n, 3), its render pixel (u, v) and validity (written into the ``*_out`` arrays).

    ``intr``: (fx, fy, cx, cy, k1, k2, p1, p2, k3); ``s_near``, ``s_far`` (n,): marching span.
    """
    h, w = iz.shape
    fx, fy, cx, cy, k1, k2, p1, p2, k3 = (intr[0], intr[1], intr[2], intr[3], intr[4], intr[5], intr[6],
                                         intr[7], intr[8])
    for i in range(o.shape[0]):
        ox, oy, oz = o[i, 0], o[i, 1], o[i, 2]
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        od = ox * dx + oy * dy + oz * dz
        ax, ay, az = ox - od * dx, oy - od * dy, oz - od * dz
        across = math.sqrt(ax * ax + ay * ay + az * az)
        s = math.nan
        if across <= 1e-12 * (1.0 + math.sqrt(ox * ox + oy * oy + oz * oz)):
            ok, z, xn, yn, u, v = _surface(dx, dy, dz, iz, w, h, fx, fy, cx, cy, k1, k2, p1, p2, k3,
                                           distorted, nearest, edge_tol)
            if ok:
                s = (xn * z - ox) * dx + (yn * z - oy) * dy + (z - oz) * dz
        else:
            inv_near, inv_far = 1.0 / s_near[i], 1.0 / s_far[i]
            steps = min(math.ceil(f_max * across * (inv_near - inv_far)) + 2, max_steps)
            lo = s_near[i]
            hi = math.nan
            for k in range(1, steps):
                sk = 1.0 / (inv_near + (inv_far - inv_near) * (k / (steps - 1)))
                pz = oz + sk * dz
                ok, z, xn, yn, u, v = _surface(ox + sk * dx, oy + sk * dy, pz, iz, w, h, fx, fy, cx, cy,
                                               k1, k2, p1, p2, k3, distorted, nearest, edge_tol)
                if ok and pz > z * (1 + 1e-12):
                    hi = sk
                    break
                lo = sk
            if hi == hi:  # found a bracket
                a, c = lo, hi
                for _ in range(bisections):
                    mid = 0.5 * (a + c)
                    pz = oz + mid * dz
                    ok, z, xn, yn, u, v = _surface(ox + mid * dx, oy + mid * dy, pz, iz, w, h, fx, fy, cx, cy,
                                                   k1, k2, p1, p2, k3, distorted, nearest, edge_tol)
                    if ok and pz > z * (1 + 1e-12):
                        c = mid
                    else:
                        a = mid
                s = c
        ok_final = False
        u_f = math.nan
        v_f = math.nan
        qx = qy = qz = math.nan
        if s == s:
            for _ in range(iterations):
                ok, z, xn, yn, u, v = _surface(ox + s * dx, oy + s * dy, oz + s * dz, iz, w, h, fx, fy, cx, cy,
                                               k1, k2, p1, p2, k3, distorted, nearest, edge_tol)
                ok_final, u_f, v_f = ok, u, v
                if not ok:
                    break
                qx, qy, qz = xn * z, yn * z, z
                s_new = (xn * z - ox) * dx + (yn * z - oy) * dy + (z - oz) * dz
                step = abs(s_new - s)
                s = s_new
                if step <= 1e-12 * abs(s):
                    break
        s_out[i] = s
        q_out[i, 0] = qx
        q_out[i, 1] = qy
        q_out[i, 2] = qz
        u_out[i] = u_f
        v_out[i] = v_f
        ok_out[i] = ok_final


@jit
def finish(s, q, u, v, ok, o, d, origins, directions, rot, normals, velocity, material, intensity, iz,
           nearest, edge_tol, miss_tol, min_f, dist_out, point_out, normal_out, cos_out, object_out,
           material_out, velocity_out, albedo_out):  # pragma: no cover - compiled
    """Per-ray hit fields from the re-projection (see ``images_to_hits``'s NumPy reference).

    ``o``, ``d``: rays in the render camera frame; ``origins``, ``directions``:
    the same in the world; ``rot``: render camera -> world rotation;
    ``normals`` (H, W, 3) render camera frame; ``velocity`` (H, W, 3) or
    (0, 0, 3), ``material`` (H, W) or (0, 0): absent when empty.
    """
    h, w = iz.shape
    has_vel = velocity.shape[0] > 0
    has_mat = material.shape[0] > 0
    for i in range(s.shape[0]):
        si = s[i]
        px, py, pz = o[i, 0] + si * d[i, 0], o[i, 1] + si * d[i, 1], o[i, 2] + si * d[i, 2]
        ex, ey, ez = q[i, 0] - px, q[i, 1] - py, q[i, 2] - pz
        off_ray = math.sqrt(ex * ex + ey * ey + ez * ez)
        hit = ok[i] and si > 0 and off_ray <= miss_tol * (q[i, 2] / min_f)
        if not hit:
            dist_out[i] = math.inf
            for k in range(3):
                point_out[i, k] = math.nan
                normal_out[i, k] = 0.0
                velocity_out[i, k] = 0.0
            cos_out[i] = 0.0
            object_out[i] = -1
            material_out[i] = -1
            albedo_out[i] = 0.0
            continue
        uu = min(max(u[i], 0.0), w - 1.0)
        vv = min(max(v[i], 0.0), h - 1.0)
        ui = int(np.rint(uu))
        vi = int(np.rint(vv))
        dist_out[i] = si
        for k in range(3):
            point_out[i, k] = origins[i, k] + si * directions[i, k]
        nx, ny, nz = normals[vi, ui, 0], normals[vi, ui, 1], normals[vi, ui, 2]
        c = nx * d[i, 0] + ny * d[i, 1] + nz * d[i, 2]
        if c > 0:  # facing the ray
            nx, ny, nz = -nx, -ny, -nz
        for k in range(3):
            normal_out[i, k] = nx * rot[k, 0] + ny * rot[k, 1] + nz * rot[k, 2]
        cos_out[i] = min(max(abs(c), 0.0), 1.0)
        object_out[i] = 0
        material_out[i] = material[vi, ui] if has_mat else -1
        for k in range(3):
            velocity_out[i, k] = velocity[vi, ui, k] if has_vel else 0.0
        val = intensity[vi, ui]
        if not nearest:
            u0 = min(int(uu), max(w - 2, 0))
            v0 = min(int(vv), max(h - 2, 0))
            u1 = u0 + 1 if w > 1 else u0
            v1 = v0 + 1 if h > 1 else v0
            ga, gb, gc, gd = iz[v0, u0], iz[v0, u1], iz[v1, u0], iz[v1, u1]
            gmax = max(max(ga, gb), max(gc, gd))
            gmin = min(min(ga, gb), min(gc, gd))
            if gmin > 0 and gmax - gmin <= edge_tol * gmin:
                fu = uu - u0
                fv = vv - v0
                a, b = intensity[v0, u0], intensity[v0, u1]
                cc, dd = intensity[v1, u0], intensity[v1, u1]
                top = a + fu * (b - a)
                bottom = cc + fu * (dd - cc)
                val = top + fv * (bottom - top)
        albedo_out[i] = val
