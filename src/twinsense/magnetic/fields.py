"""Exact fields of uniformly magnetised bodies, vectorised over points and bodies.

Every kernel takes points in the magnet's own frame (its centre at the origin,
its axis along z) as an (..., 3) array [m] and returns the flux density B
(..., 3) [T], inside and outside the body (inside, B = mu0 (H + M)). Sizes and
remanence broadcast against the points' leading shape, so one call evaluates
many magnets of one kind at once.

- Axially magnetised cylinder: Derby & Olbert, Am. J. Phys. 78, 229 (2010),
  with Bulirsch's generalised complete elliptic integral ``cel`` (vectorised).
- Block (cuboid): the magnetic surface charge +-M on the two faces normal to
  each magnetisation component; a uniformly charged rectangle has a closed
  form (arctan and log terms over its four corners, Furlani 2001, Camacho &
  Sosa 2013), summed over the 8 corners of the block. The logs are taken in a
  form without cancellation, so the far field keeps its relative accuracy.
- Diametrically magnetised cylinder: surface charge M cos(phi) on the curved
  surface; the z integral of each charged line is exact, the phi integral is
  the trapezoidal rule, which converges geometrically for a periodic analytic
  integrand: the error falls like exp(-alpha N) on N nodes, where alpha is
  the half-width of the strip in which the integrand is analytic. For a point
  at radius rho, beyond the end faces by dz (0 beside the magnet), the
  integrand's nearest singularity gives
  cosh(alpha) = (rho^2 + R^2 + dz^2) / (2 rho R). By default N = 40 / alpha
  (rounded up to a multiple of 4, 16 to 4096 nodes; the nearest point of the
  call decides), so the error is ~exp(-40) relative wherever the point is
  not on the curved surface itself: few nodes far away, more close by.
  tests/magnetic/test_fields.py checks it against an adaptive 2-D quadrature
  and against 4096 nodes.
- Ring: the outer cylinder minus the inner one (exact superposition).
"""

from __future__ import annotations

import numpy as np

from twinsense.constants import MU0

N_PHI = None  # trapezoidal nodes of the diametric cylinder's surface integral: None = adaptive (module notes)
N_PHI_MIN, N_PHI_MAX = 16, 4096
_ALPHA_DIGITS = 40.0  # N alpha: the trapezoid's error ~ exp(-40) ~ 4e-18 relative
_CEL_TOL = 1e-10  # Bulirsch's stop test; the iteration converges quadratically, so the result is at ~1e-16


def cel(kc, p, c, s) -> np.ndarray:
    """Bulirsch's generalised complete elliptic integral, vectorised.

    cel(kc, p, c, s) = int_0^{pi/2} (c cos^2 + s sin^2) / ((cos^2 + p sin^2) sqrt(cos^2 + kc^2 sin^2)) dphi,
    for kc != 0 (arrays broadcast). Special cases: K(m) = cel(sqrt(1 - m), 1, 1, 1),
    E(m) = cel(sqrt(1 - m), 1, 1, 1 - m). The algorithm (Bulirsch 1969, as printed
    by Derby & Olbert 2010) is an AGM-like iteration, quadratically convergent.
    """
    kc, p, c, s = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (kc, p, c, s)))
    k = np.abs(kc)
    pp, cc, ss = p.copy(), c.copy(), s.copy()
    em = np.ones_like(k)
    pos = p > 0
    pp[pos] = np.sqrt(p[pos])
    ss[pos] = s[pos] / pp[pos]
    neg = ~pos
    if neg.any():
        f = kc[neg] ** 2
        q = 1.0 - f
        g = 1.0 - p[neg]
        f = f - p[neg]
        q = q * (s[neg] - c[neg] * p[neg])
        pp[neg] = np.sqrt(f / g)
        cc[neg] = (c[neg] - s[neg]) / g
        ss[neg] = -q / (g * g * pp[neg]) + cc[neg] * pp[neg]
    f = cc
    cc = cc + ss / pp
    g = k / pp
    ss = 2.0 * (ss + f * g)
    pp = g + pp
    g = em
    em = k + em
    kk = k
    for _ in range(40):
        if not np.any(np.abs(g - k) > g * _CEL_TOL):
            break
        k = 2.0 * np.sqrt(kk)
        kk = k * em
        f = cc
        cc = cc + ss / pp
        g = kk / pp
        ss = 2.0 * (ss + f * g)
        pp = g + pp
        g = em
        em = k + em
    return 0.5 * np.pi * (ss + cc * em) / (em * (em + pp))


def cylinder_axial(points, radius, length, remanence) -> np.ndarray:
    """B (..., 3) [T] of a cylinder magnetised along +z (Derby & Olbert 2010).

    points (..., 3) [m] in the cylinder frame (centre at the origin, axis z);
    radius, length [m] and remanence [T] broadcast against the leading shape.
    """
    p = np.asarray(points, dtype=float)
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    a = np.asarray(radius, dtype=float)
    h = 0.5 * np.asarray(length, dtype=float)
    rho = np.hypot(x, y)
    zp, zm = z + h, z - h
    s = rho + a
    dp, dm = np.sqrt(zp ** 2 + s ** 2), np.sqrt(zm ** 2 + s ** 2)
    kp = np.sqrt(zp ** 2 + (a - rho) ** 2) / dp
    km = np.sqrt(zm ** 2 + (a - rho) ** 2) / dm
    gam = (a - rho) / s
    one = np.ones_like(kp)
    # One cel call for the four integrals (k+, k-) x (radial, axial).
    kk = np.stack(np.broadcast_arrays(kp, km, kp, km))
    pg = np.stack(np.broadcast_arrays(one, one, gam ** 2 * one, gam ** 2 * one))
    ss = np.stack(np.broadcast_arrays(-one, -one, gam * one, gam * one))
    cv = cel(kk, pg, np.ones_like(kk), ss)
    b0 = np.asarray(remanence, dtype=float) / np.pi
    b_rho = b0 * (a / dp * cv[0] - a / dm * cv[1])
    b_z = b0 * a / s * (zp / dp * cv[2] - zm / dm * cv[3])
    safe = np.where(rho > 0, rho, 1.0)
    cx, cy = np.where(rho > 0, x / safe, 0.0), np.where(rho > 0, y / safe, 0.0)
    return np.stack([b_rho * cx, b_rho * cy, b_z], axis=-1)


def _segment(dx, dy, z, h):
    """Integral over z' in [-h, h] of (dx, dy, z - z') / (dx^2 + dy^2 + (z - z')^2)^(3/2), without cancellation."""
    d2 = dx * dx + dy * dy
    a, b = z + h, z - h
    sa, sb = np.sqrt(d2 + a * a), np.sqrt(d2 + b * b)
    # a/sa - b/sb = d2 (a^2 - b^2) / (sa sb (a sb + b sa)) when a and b share a sign (no cancellation);
    # the direct form otherwise (then it does not cancel either). Divided by d2 it stays finite on the axis.
    same = a * b > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        perp = np.where(same, 4.0 * h * z / (sa * sb * (a * sb + b * sa)), (a / sa - b / sb) / d2)
    pz = 4.0 * h * z / (sa * sb * (sa + sb))  # 1/sb - 1/sa
    return dx * perp, dy * perp, pz


def diametric_nodes(points, radius, length) -> int:
    """Trapezoidal nodes that resolve the diametric surface integral at every point to ~exp(-40) (module notes)."""
    p = np.asarray(points, dtype=float)
    rho = np.hypot(p[..., 0], p[..., 1])
    r = np.asarray(radius, dtype=float)
    dz = np.maximum(np.abs(p[..., 2]) - 0.5 * np.asarray(length, dtype=float), 0.0)
    with np.errstate(divide="ignore"):
        cosh_a = (rho ** 2 + r ** 2 + dz ** 2) / (2 * rho * r)
    alpha = float(np.min(np.arccosh(np.maximum(cosh_a, 1.0)))) if np.size(cosh_a) else np.inf
    if alpha <= 0:
        return N_PHI_MAX
    n = 4 * int(np.ceil(_ALPHA_DIGITS / alpha / 4))
    return int(min(max(n, N_PHI_MIN), N_PHI_MAX))


def cylinder_diametric(points, radius, length, remanence, n_phi: int | None = N_PHI) -> np.ndarray:
    """B (..., 3) [T] of a cylinder magnetised along +x (diametrically), axis z, centre at the origin.

    Surface charge sigma = M cos(phi') on the curved surface; exact in z, the
    trapezoidal rule on ``n_phi`` nodes in phi' (None: as many as the nearest
    point needs, see the module notes).
    """
    p = np.asarray(points, dtype=float)
    if n_phi is None:
        n_phi = diametric_nodes(p, radius, length)
    x, y, z = (p[..., i][..., None] for i in range(3))
    a = np.asarray(radius, dtype=float)[..., None]
    h = 0.5 * np.asarray(length, dtype=float)[..., None]
    phi = 2.0 * np.pi * np.arange(n_phi) / n_phi
    cp, sp = np.cos(phi), np.sin(phi)
    hx, hy, hz = _segment(x - a * cp, y - a * sp, z, h)
    w = cp * (2.0 * np.pi / n_phi)  # sigma / M times d phi'
    br = np.asarray(remanence, dtype=float)
    scale = br * np.asarray(radius, dtype=float) / (4.0 * np.pi)
    out = np.stack([(hx * w).sum(-1), (hy * w).sum(-1), (hz * w).sum(-1)], axis=-1) * scale[..., None]
    inside = (np.hypot(p[..., 0], p[..., 1]) < radius) & (np.abs(p[..., 2]) < 0.5 * np.asarray(length))
    out[..., 0] += np.where(inside, br, 0.0)
    return out


def _logdiff(v1, v2, rho2):
    """ln(v1 + R1) - ln(v2 + R2) with R = sqrt(rho2 + v^2) and v1 - v2 > 0, without cancellation."""
    r1, r2 = np.sqrt(rho2 + v1 * v1), np.sqrt(rho2 + v2 * v2)
    dv = v1 - v2
    with np.errstate(divide="ignore", invalid="ignore"):
        # both >= 0: the ratio (v1 + R1)/(v2 + R2) = 1 + dv (R1 + R2 + v1 + v2) / ((R1 + R2)(v2 + R2));
        # both <= 0: (v + R) = rho2 / (R - v) turns it into (R2 - v2)/(R1 - v1), same treatment.
        up = np.log1p(dv * (r1 + r2 + v1 + v2) / ((r1 + r2) * (v2 + r2)))
        down = np.log1p(dv * (r1 + r2 - v1 - v2) / ((r1 + r2) * (r1 - v1)))
        mixed = np.log((v1 + r1) * (r2 - v2) / rho2)
    return np.where(v2 >= 0, up, np.where(v1 <= 0, down, mixed))


def _rectangle(x, y, zr, a, b):
    """Field (H per unit surface charge, times 4 pi) of the rectangle |x'| <= a, |y'| <= b at height zr below."""
    u1, u2 = x + a, x - a
    v1, v2 = y + b, y - b
    sgn = np.where(zr >= 0, 1.0, -1.0)
    az = np.abs(zr)

    def at(u, v):
        # arctan(u v / (z R)) written with arctan2 so that z = 0 (the face's own plane) is finite.
        return np.arctan2(u * v * sgn, az * np.sqrt(u * u + v * v + zr * zr))

    hz = at(u1, v1) - at(u2, v1) - at(u1, v2) + at(u2, v2)
    hx = -(_logdiff(v1, v2, u1 * u1 + zr * zr) - _logdiff(v1, v2, u2 * u2 + zr * zr))
    hy = -(_logdiff(u1, u2, v1 * v1 + zr * zr) - _logdiff(u1, u2, v2 * v2 + zr * zr))
    return hx, hy, hz


def _block_along_z(x, y, z, a, b, c):
    """4 pi H / M of the block |x| <= a, |y| <= b, |z| <= c magnetised along +z (faces +-c charged +-M)."""
    tx, ty, tz = _rectangle(x, y, z - c, a, b)
    bx, by, bz = _rectangle(x, y, z + c, a, b)
    return tx - bx, ty - by, tz - bz


def block(points, size, magnetisation) -> np.ndarray:
    """B (..., 3) [T] of a block of edge lengths ``size`` (..., 3) [m] centred at the origin.

    ``magnetisation`` (..., 3) is mu0 M [T] (remanence times direction) in the block frame.
    """
    p = np.asarray(points, dtype=float)
    half = 0.5 * np.asarray(size, dtype=float)
    m = np.asarray(magnetisation, dtype=float)
    out = np.zeros(np.broadcast_shapes(p.shape, half.shape, m.shape))
    for k in range(3):
        if not np.any(m[..., k]):
            continue  # no charge on this pair of faces
        i, j = (k + 1) % 3, (k + 2) % 3
        hi, hj, hk = _block_along_z(p[..., i], p[..., j], p[..., k], half[..., i], half[..., j], half[..., k])
        mk = m[..., k] / (4.0 * np.pi)
        out[..., i] += mk * hi
        out[..., j] += mk * hj
        out[..., k] += mk * hk
    inside = np.all(np.abs(p) < half, axis=-1)
    return out + np.where(inside[..., None], m, 0.0)


def cylinder(points, radius, length, magnetisation, n_phi: int | None = N_PHI) -> np.ndarray:
    """B (..., 3) [T] of a cylinder (axis z) with mu0 M = ``magnetisation`` (..., 3) [T] in any direction.

    Superposition: the axial part by Derby & Olbert, the transverse part as a
    diametric cylinder turned to the transverse direction.
    """
    p = np.asarray(points, dtype=float)
    m = np.broadcast_to(np.asarray(magnetisation, dtype=float), np.broadcast_shapes(p.shape, np.shape(magnetisation)))
    out = cylinder_axial(p, radius, length, m[..., 2])
    mt = np.hypot(m[..., 0], m[..., 1])
    has = mt > 0
    if np.any(has):
        # Only the points of magnets with a transverse part: rotate them so that it lies along +x,
        # evaluate, rotate back.
        shape = out.shape[:-1]
        sel = np.broadcast_to(has, shape).reshape(-1)

        def pick(v):
            return np.broadcast_to(np.asarray(v, dtype=float), shape).reshape(-1)[sel]

        q = np.broadcast_to(p, out.shape).reshape(-1, 3)[sel]
        mts = pick(mt)
        c, s = pick(m[..., 0]) / mts, pick(m[..., 1]) / mts
        xr = c * q[:, 0] + s * q[:, 1]
        yr = -s * q[:, 0] + c * q[:, 1]
        bd = cylinder_diametric(np.stack([xr, yr, q[:, 2]], axis=-1), pick(radius), pick(length), mts, n_phi)
        out = out.reshape(-1, 3).copy()
        out[sel] += np.stack([c * bd[:, 0] - s * bd[:, 1], s * bd[:, 0] + c * bd[:, 1], bd[:, 2]], axis=-1)
        out = out.reshape(*shape, 3)
    return out


def ring(points, outer_radius, inner_radius, length, magnetisation, n_phi: int | None = N_PHI) -> np.ndarray:
    """B (..., 3) [T] of a ring (tube) magnet: the outer cylinder minus the inner one."""
    return (cylinder(points, outer_radius, length, magnetisation, n_phi)
            - cylinder(points, inner_radius, length, magnetisation, n_phi))


def dipole(points, moment) -> np.ndarray:
    """B (..., 3) [T] of a point dipole of moment ``moment`` (..., 3) [A m^2] at the origin."""
    p = np.asarray(points, dtype=float)
    m = np.asarray(moment, dtype=float)
    r = np.linalg.norm(p, axis=-1, keepdims=True)
    n = p / r
    return MU0 / (4.0 * np.pi) * (3.0 * np.sum(m * n, axis=-1, keepdims=True) * n - m) / r ** 3
