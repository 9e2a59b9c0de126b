"""Echo paths of airborne ultrasound in a scene: specular points, curvature, edges.

Ultrasound in air has a wavelength of 6-9 mm (40-58 kHz), small against walls,
furniture and people but not against edges and thin parts, so a ray-optics
picture with the diffraction of finite surfaces is the right level: every
surface that can send sound back does so from its *specular point*, where the
path transmitter -> surface -> receiver is stationary (the surface normal
bisects the two directions), and the strength follows from the Kirchhoff
(physical optics) integral around that point.

Model (one echo per surface element and transmitter/receiver pair)
-----------------------------------------------------------------
Around the specular point P, with r1 = |P - Tx|, r2 = |P - Rx| and unit
directions d1, d2 from P to Tx and Rx, the two-way path grows quadratically
with a displacement x along a surface tangent t:

    L(x) = r1 + r2 + q(t) x^2 / k,
    q(t) = k [(1 - (t.d1)^2) / (2 r1) + (1 - (t.d2)^2) / (2 r2)] + k (n.d1 + n.d2) / (2 a_t)

(the last term is the sag x^2 / (2 a_t) of a convex surface with radius of
curvature a_t along t; a flat direction has 1/a_t = 0). The physical-optics
pressure, normalised so that an infinite plane gives exactly its image
source, is

    p / p0 = R D_tx D_rx F_1 F_2 / (r1 + r2) * 10^(-alpha (r1 + r2) / 20),
    F_i = int_{lo_i}^{hi_i} exp(j q_i x^2) dx / int_{-inf}^{inf} exp(j q_flat,i x^2) dx,

p0 the source's on-axis pressure at 1 m, R the surface's pressure
reflection coefficient, D the piston directivities towards P, and lo/hi the
extent of the surface around P along each principal direction (Fresnel
integrals). Limits this reproduces exactly:

- infinite plane at any angle: F = 1, p = p0 / (r1 + r2), the image source
  (1 / (2R) monostatic);
- sphere of radius a, monostatic, both directions curved and unbounded:
  F = sqrt(a / (a + r)) each, p -> p0 a / (2 r^2) for r >> a, i.e. the
  geometric cross-section sigma = pi a^2 (1 / R^2 law);
- cylinder broadside: one curved direction (sqrt(a / (a + r))) and one flat
  direction of length l (Fresnel over the length: 1 for l >> sqrt(lambda r),
  l sqrt(2 / (lambda r)) for a short one);
- small flat plate of area S at normal incidence: |F_1 F_2| = 2 S / (lambda r),
  p = p0 S / (lambda r^2), the plate's physical-optics cross-section 4 pi S^2 / lambda^2.

When the specular point falls outside a finite face, F is the tail of the
Fresnel integral (the physical-optics edge wave, decaying like the distance
to the edge in Fresnel-zone units): the echo is placed at the nearest point
of the face (its delay and directivity are those of the edge path). This
gives the weak edge and corner echoes of boxes, tables and plates.

Surfaces come from the geometry: boxes and planes are flat rectangles,
cylinder and capsule sides are curved in one direction, spheres and capsule
caps in both, cylinder end caps are flat squares of the same area, and
triangle meshes are flat facets (each an equal-area square at its centroid;
a curved mesh surface then echoes from the facets that face the sensor,
like the tessellated body it is). Whether the transmitter and the receiver
see the echo point is decided by the render stage: one ray from each to the
point (:func:`visible`).

Not modelled: multiple reflections (a wall-floor corner returns a doubled
echo in reality), Rayleigh scattering of parts much smaller than the
wavelength (k a < 1, sigma ~ k^4 a^6), the Doppler shift (0.35 % at 1.2 m/s,
inside the transducer's band) and motion during the flight time (the scene
is posed at the firing time).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import fresnel

from twinsense.render import Rays, cast
from twinsense.scene.geometry import Box, Capsule, Cylinder, Plane, Sphere, TriangleMesh
from twinsense.scene.scene import Scene

KIND = "ultrasonic"

#: Pressure reflection coefficient of airborne ultrasound per material name.
#: Solids: R = (Z2 - Z1) / (Z2 + Z1) with Z_air = 413 Pa s/m against Z >= 1e6
#: Pa s/m (wood, plaster, concrete, metal, plastic, glass, skin): R > 0.999,
#: taken as 1. Textiles absorb: open fabric about 75 % of the energy at
#: 40 kHz (R = 0.5); people in a robot cell are clothed, so the human
#: materials take the fabric value. A material not listed reflects fully.
REFLECTION: dict[str, float] = {"fabric": 0.5, "human": 0.5, "human_skin": 0.5, "air": 0.0}


def reflection_coefficient(material_name: str) -> float:
    return REFLECTION.get(material_name, 1.0)


@dataclass(frozen=True, eq=False)
class Elements:
    """Reflecting surface elements of a scene posed at one time, world frame.

    rect_* (nr,): flat rectangles: centre (nr, 3), unit axes u, v (nr, 3),
    half sizes hu, hv (nr,) [m], two_sided (nr,) bool (a Plane reflects on
    both sides, a closed body's face only outwards), object index, reflection.
    sph_* (ns,): spheres or caps: centre, radius, cap axis (zeros: full
    sphere), object, reflection.
    cyl_* (nc,): cylinder sides: centre, unit axis, half length, radius,
    edge (True: a finite cylinder with rims that diffract; False: a
    capsule side, whose ends blend into the caps), object, reflection.
    """

    rect_c: np.ndarray
    rect_u: np.ndarray
    rect_v: np.ndarray
    rect_hu: np.ndarray
    rect_hv: np.ndarray
    rect_two: np.ndarray
    rect_obj: np.ndarray
    rect_r: np.ndarray
    sph_c: np.ndarray
    sph_a: np.ndarray
    sph_axis: np.ndarray
    sph_obj: np.ndarray
    sph_r: np.ndarray
    cyl_c: np.ndarray
    cyl_w: np.ndarray
    cyl_h: np.ndarray
    cyl_a: np.ndarray
    cyl_edge: np.ndarray
    cyl_obj: np.ndarray
    cyl_r: np.ndarray

    @property
    def counts(self) -> tuple[int, int, int]:
        """Numbers of rectangles, spheres and cylinders."""
        return len(self.rect_c), len(self.sph_c), len(self.cyl_c)

    @staticmethod
    def concat(parts: list[Elements]) -> Elements:
        """The elements of several sets, in order (rectangles of all parts first, then spheres, cylinders)."""
        return Elements(*(np.concatenate([getattr(p, f) for p in parts]) for f in Elements.__dataclass_fields__))


def scene_elements(scene: Scene, t: float, objects=None) -> Elements:
    """Reflecting elements of the objects visible to ultrasonic sensors (or of ``objects``, indices), posed at ``t``."""
    rect: list[tuple] = []  # rows of the primitives since the last mesh
    rect_parts: list[list[np.ndarray]] = []  # the rectangles' columns, block by block in object order
    sph: list[tuple] = []
    cyl: list[tuple] = []
    for i in (scene.visible(KIND) if objects is None else objects):
        obj = scene.objects[i]
        refl = reflection_coefficient(obj.material.name)
        if refl <= 0.0:
            continue
        pose = obj.pose_at(t)
        rot, pos = pose.rotation, pose.position
        ex, ey, ez = rot[:, 0], rot[:, 1], rot[:, 2]
        g = obj.geometry
        if isinstance(g, Box):
            sx, sy, sz = (0.5 * s for s in g.size)
            for axis, half, a1, h1, a2, h2 in ((ex, sx, ey, sy, ez, sz), (ey, sy, ez, sz, ex, sx),
                                               (ez, sz, ex, sx, ey, sy)):
                for sign in (1.0, -1.0):
                    # u x v must be the outward normal sign * axis
                    u, v = (a1, a2) if sign > 0 else (a2, a1)
                    hu, hv = (h1, h2) if sign > 0 else (h2, h1)
                    rect.append((pos + sign * half * axis, u, v, hu, hv, False, i, refl))
        elif isinstance(g, Plane):
            rect.append((pos, ex, ey, 0.5 * g.size[0], 0.5 * g.size[1], True, i, refl))
        elif isinstance(g, Sphere):
            sph.append((pos, g.radius, np.zeros(3), i, refl))
        elif isinstance(g, Cylinder):
            h = 0.5 * g.height
            cyl.append((pos, ez, h, g.radius, True, i, refl))
            side = 0.5 * np.sqrt(np.pi) * g.radius  # half side of the square of the disk's area
            rect.append((pos + h * ez, ex, ey, side, side, False, i, refl))
            rect.append((pos - h * ez, ey, ex, side, side, False, i, refl))
        elif isinstance(g, Capsule):
            h = 0.5 * g.height
            if h > 0:
                cyl.append((pos, ez, h, g.radius, False, i, refl))
                sph.append((pos + h * ez, g.radius, ez, i, refl))
                sph.append((pos - h * ez, g.radius, -ez, i, refl))
            else:
                sph.append((pos, g.radius, np.zeros(3), i, refl))
        elif isinstance(g, TriangleMesh):
            m = g.mesh
            tri = pose.apply(np.asarray(m.vertices, float))[np.asarray(m.faces)]
            e1 = tri[:, 1] - tri[:, 0]
            nrm = np.cross(e1, tri[:, 2] - tri[:, 0])
            area2 = np.linalg.norm(nrm, axis=1)
            ok = area2 > 0
            u = e1[ok] / np.linalg.norm(e1[ok], axis=1)[:, None]
            n = nrm[ok] / area2[ok, None]
            v = np.cross(n, u)
            half = 0.5 * np.sqrt(0.5 * area2[ok])
            k = len(half)
            # A mesh's facets as one block of rows (a Python tuple per facet cost ~4 us each:
            # 0.6 s for a robot's 135k visual facets).
            rect_parts.append(_stack(rect, 8, _RECT_WIDTHS, _RECT_TYPES))
            rect.clear()
            rect_parts.append([tri[ok].mean(axis=1), u, v, half, half.copy(), np.zeros(k, bool),
                               np.full(k, i, np.int32), np.full(k, refl)])
    rect_parts.append(_stack(rect, 8, _RECT_WIDTHS, _RECT_TYPES))
    return Elements(*(np.concatenate(cols) for cols in zip(*rect_parts)),
                    *_stack(sph, 5, (3, 0, 3, 0, 0), (float, float, float, np.int32, float)),
                    *_stack(cyl, 7, (3, 3, 0, 0, 0, 0, 0), (float, float, float, float, bool, np.int32, float)))


_RECT_WIDTHS = (3, 3, 3, 0, 0, 0, 0, 0)
_RECT_TYPES = (float, float, float, float, float, bool, np.int32, float)


def _stack(rows, n, widths, dtypes):
    if not rows:
        return [np.zeros((0, w) if w else 0, d) for w, d in zip(widths, dtypes)]
    cols = list(zip(*rows))
    return [np.array(c, dtype=d).reshape(-1, w) if w else np.array(c, dtype=d) for c, w, d in zip(cols, widths, dtypes)]


@dataclass(frozen=True, eq=False)
class EchoPaths:
    """Candidate echoes (e in all) of the elements' transmitters towards their receivers.

    element : (e,) int — element row (rectangles, then spheres, then cylinders, as in
    :attr:`Elements.counts`); rx : (e,) int — receiver index; point : (e, 3) — echo point [m];
    path : (e,) — two-way path length via the echo point [m];
    gain : (e,) — |F_1 F_2| / (r1 + r2) [1/m] (spreading, curvature, finite size);
    reflection : (e,) — pressure reflection coefficient; obj : (e,) int — object index.
    """

    element: np.ndarray
    rx: np.ndarray
    point: np.ndarray
    path: np.ndarray
    gain: np.ndarray
    reflection: np.ndarray
    obj: np.ndarray


def fresnel_factor(q, lo, hi) -> np.ndarray:
    """|int_lo^hi exp(j q x^2) dx| / |int_-inf^inf exp(j q x^2) dx| for q > 0 (arrays broadcast).

    With u = x sqrt(2 q / pi): (E(u_hi) - E(u_lo)) / (1 + j), E = C + j S the
    Fresnel integrals; 1 for an unbounded interval.
    """
    s = np.sqrt(2.0 * np.asarray(q, float) / np.pi)
    s_hi, c_hi = fresnel(np.clip(hi * s, -1e8, 1e8))
    s_lo, c_lo = fresnel(np.clip(lo * s, -1e8, 1e8))
    return np.hypot(c_hi - c_lo, s_hi - s_lo) / np.sqrt(2.0)


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _q(k, t, d1, d2, r1, r2):
    """k [(1 - (t.d1)^2) / (2 r1) + (1 - (t.d2)^2) / (2 r2)]: the flat-surface quadratic phase along t."""
    return k * ((1 - _dot(t, d1) ** 2) / (2 * r1) + (1 - _dot(t, d2) ** 2) / (2 * r2))


def echo_paths(el: Elements, tx: np.ndarray, rx: np.ndarray, k: float) -> EchoPaths:
    """Specular (or edge) echo of every element from a transmitter to each of m receivers.

    ``tx``: transmitter position (3,), or one per element (K, 3) in element
    order; ``rx``: receiver positions (m, 3), or (K, m, 3) per element (so
    firings at different times are handled in one call); ``k``: wave number
    [1/m]. No visibility test (see :func:`visible`) and no directivity or
    absorption here: geometry only.
    """
    n_el = sum(el.counts)
    tx = np.broadcast_to(np.asarray(tx, float), (n_el, 3))
    rx = np.asarray(rx, float)
    rx = np.broadcast_to(rx, (n_el, *rx.shape[-2:])) if rx.ndim == 2 else rx
    nr, ns, _ = el.counts
    parts = [_rect_echoes(el, tx[:nr, None], rx[:nr], k), _sphere_echoes(el, tx[nr:nr + ns, None], rx[nr:nr + ns], k),
             _cyl_echoes(el, tx[nr + ns:, None], rx[nr + ns:], k)]
    offsets = (0, nr, nr + ns)
    elem = np.concatenate([p[0] + o for p, o in zip(parts, offsets)])
    rx_i, pts, path, gain, refl, obj = (np.concatenate(a) for a in list(zip(*parts))[1:])
    return EchoPaths(elem.astype(np.int64), rx_i.astype(np.int64), pts.reshape(-1, 3), path, gain, refl,
                     obj.astype(np.int32))


def _empty():
    return (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0),
            np.zeros(0, np.int32))


def _finish(ok, rxi, pts, path, gain, refl, obj):
    shape = ok.shape
    elem = np.broadcast_to(np.arange(shape[0])[:, None], shape).ravel()
    ok = ok.ravel()
    return elem[ok], rxi[ok], pts[ok], path[ok], gain[ok], refl[ok], obj[ok]


def _rect_echoes(el: Elements, tx, rx, k):
    if len(el.rect_c) == 0:
        return _empty()
    c = el.rect_c[:, None]  # (K, 1, 3)
    u, v = el.rect_u[:, None], el.rect_v[:, None]
    n = np.cross(el.rect_u, el.rect_v)[:, None]
    ht = _dot(tx - c, n)  # (K, 1) height of Tx over the plane
    hr = _dot(rx - c, n)  # (K, m)
    side = np.sign(ht)
    ok = (side != 0) & (ht * hr > 0) & (el.rect_two[:, None] | (side > 0))
    at, ar = np.abs(ht), np.abs(hr)
    # Image method: the specular point divides the projected Tx -> Rx segment in the ratio of heights.
    pt = tx - ht[..., None] * n
    pr = rx - hr[..., None] * n
    w = at / np.where(at + ar > 0, at + ar, 1.0)
    p = pt + (pr - pt) * w[..., None]  # (K, m, 3)
    us, vs = _dot(p - c, u), _dot(p - c, v)
    hu, hv = el.rect_hu[:, None], el.rect_hv[:, None]
    r1 = np.linalg.norm(tx - p, axis=-1)
    r2 = np.linalg.norm(rx - p, axis=-1)
    r1s, r2s = np.maximum(r1, 1e-9), np.maximum(r2, 1e-9)
    d1, d2 = (tx - p) / r1s[..., None], (rx - p) / r2s[..., None]
    # The Fresnel integrals only where the face can echo (the other half of a mesh's facets
    # face away: their gains are never read).
    gain = np.zeros(ok.shape)
    sel = np.nonzero(ok)
    hu_, hv_, us_, vs_ = np.broadcast_to(hu, ok.shape)[sel], np.broadcast_to(hv, ok.shape)[sel], us[sel], vs[sel]
    u_, v_ = np.broadcast_to(u, (*ok.shape, 3))[sel], np.broadcast_to(v, (*ok.shape, 3))[sel]
    d1_, d2_, r1_, r2_ = d1[sel], d2[sel], r1s[sel], r2s[sel]
    fu = fresnel_factor(_q(k, u_, d1_, d2_, r1_, r2_), -hu_ - us_, hu_ - us_)
    fv = fresnel_factor(_q(k, v_, d1_, d2_, r1_, r2_), -hv_ - vs_, hv_ - vs_)
    gain[sel] = fu * fv / (r1_ + r2_)
    # Outside the face: the echo comes from its nearest point (edge / corner wave).
    e = c + np.clip(us, -hu, hu)[..., None] * u + np.clip(vs, -hv, hv)[..., None] * v
    path = np.linalg.norm(tx - e, axis=-1) + np.linalg.norm(rx - e, axis=-1)
    shape = ok.shape
    rxi = np.broadcast_to(np.arange(shape[1]), shape)
    refl = np.broadcast_to(el.rect_r[:, None], shape)
    obj = np.broadcast_to(el.rect_obj[:, None], shape)
    return _finish(ok, rxi.ravel(), e.reshape(-1, 3), path.ravel(), gain.ravel(), refl.ravel(), obj.ravel())


def _sphere_echoes(el: Elements, tx, rx, k):
    if len(el.sph_c) == 0:
        return _empty()
    c = el.sph_c[:, None]
    a = el.sph_a[:, None]
    et, er = _unit(tx - c), _unit(rx - c)
    # Specular point of a sphere: the normal bisects the directions to Tx and Rx
    # (exact monostatic; for r >> a bistatic the error in the normal is O(a / r)).
    b = _unit(et + er)
    p = c + a[..., None] * b
    r1 = np.linalg.norm(tx - p, axis=-1)
    r2 = np.linalg.norm(rx - p, axis=-1)
    outside = (np.linalg.norm(tx - c, axis=-1) > a) & (np.linalg.norm(rx - c, axis=-1) > a)
    cap = el.sph_axis[:, None]
    ok = outside & (_dot(b, cap) >= 0) & (np.linalg.norm(et + er, axis=-1) > 1e-9)
    r1s, r2s = np.maximum(r1, 1e-9), np.maximum(r2, 1e-9)
    d1, d2 = (tx - p) / r1s[..., None], (rx - p) / r2s[..., None]
    t2 = np.cross(d1, d2)
    fallback = np.cross(b, np.where(np.abs(b[..., :1]) < 0.9, [1.0, 0, 0], [0, 1.0, 0]))
    t2 = _unit(np.where(np.linalg.norm(t2, axis=-1, keepdims=True) > 1e-9, t2, fallback))
    t1 = np.cross(t2, b)
    sag = k * (_dot(b, d1) + _dot(b, d2)) / (2 * a)
    gain = np.ones(ok.shape)
    for t in (t1, t2):
        qf = _q(k, t, d1, d2, r1s, r2s)
        gain = gain * _spreading(qf, sag, ok)
    gain = gain / (r1s + r2s)
    shape = ok.shape
    rxi = np.broadcast_to(np.arange(shape[1]), shape)
    refl = np.broadcast_to(el.sph_r[:, None], shape)
    obj = np.broadcast_to(el.sph_obj[:, None], shape)
    return _finish(ok, rxi.ravel(), p.reshape(-1, 3), (r1 + r2).ravel(), gain.ravel(), refl.ravel(),
                   obj.ravel())


def _spreading(qf: np.ndarray, sag: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """sqrt(qf / (qf + sag)): the curved surface's spreading factor along one
    principal direction, where the specular point exists (``ok``), else 0.

    Outside ``ok`` (a transducer inside the body's radius, no stationary point)
    the ratio is meaningless and may be negative or 0/0; those rows are dropped
    by the caller, and must not produce NaN on the way.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(ok, qf / (qf + sag), 0.0)
    return np.sqrt(np.clip(ratio, 0.0, None))


def _cyl_echoes(el: Elements, tx, rx, k):
    if len(el.cyl_c) == 0:
        return _empty()
    c, w = el.cyl_c[:, None], el.cyl_w[:, None]
    a, h = el.cyl_a[:, None], el.cyl_h[:, None]
    zt, zr = _dot(tx - c, w), _dot(rx - c, w)
    vt = tx - c - zt[..., None] * w
    vr = rx - c - zr[..., None] * w
    rho_t, rho_r = np.linalg.norm(vt, axis=-1), np.linalg.norm(vr, axis=-1)
    b = _unit(_unit(vt) + _unit(vr))
    ok = (rho_t > a) & (rho_r > a) & (np.linalg.norm(b, axis=-1) > 0.5)
    q0 = a[..., None] * b
    lt = np.linalg.norm(vt - q0, axis=-1)
    lr = np.linalg.norm(vr - q0, axis=-1)
    # Along the axis the side is a straight line: the mirror law puts the
    # stationary point where the axial offsets are in the ratio of the distances.
    zs = (zt * lr + zr * lt) / np.maximum(lt + lr, 1e-12)
    p = c + q0 + zs[..., None] * w
    r1 = np.linalg.norm(tx - p, axis=-1)
    r2 = np.linalg.norm(rx - p, axis=-1)
    r1s, r2s = np.maximum(r1, 1e-9), np.maximum(r2, 1e-9)
    d1, d2 = (tx - p) / r1s[..., None], (rx - p) / r2s[..., None]
    tc = np.cross(np.broadcast_to(w, b.shape), b)
    qf = _q(k, tc, d1, d2, r1s, r2s)
    sag = k * (_dot(b, d1) + _dot(b, d2)) / (2 * a)
    f_axis = fresnel_factor(_q(k, np.broadcast_to(w, b.shape), d1, d2, r1s, r2s), -h - zs, h - zs)
    inside = np.abs(zs) <= h
    ok &= inside | el.cyl_edge[:, None]
    gain = _spreading(qf, sag, ok) * f_axis / (r1s + r2s)
    e = c + q0 + np.clip(zs, -h, h)[..., None] * w
    path = np.linalg.norm(tx - e, axis=-1) + np.linalg.norm(rx - e, axis=-1)
    shape = ok.shape
    rxi = np.broadcast_to(np.arange(shape[1]), shape)
    refl = np.broadcast_to(el.cyl_r[:, None], shape)
    obj = np.broadcast_to(el.cyl_obj[:, None], shape)
    return _finish(ok, rxi.ravel(), e.reshape(-1, 3), path.ravel(), gain.ravel(), refl.ravel(), obj.ravel())


def visible(scene: Scene, t: float, origins: np.ndarray, points: np.ndarray, tol: float = 5e-3) -> np.ndarray:
    """(n,) bool: nothing else lies on the straight path from ``origins`` (n, 3) to ``points`` (n, 3).

    One ray per path through the render stage (objects hidden from
    ultrasonic sensors are transparent). A point is visible when the ray's
    first hit is no nearer than the point less ``tol`` [m] (the tessellated
    mesh lies up to a chord's sag inside a curved surface; an edge point is
    grazed).
    """
    if len(points) == 0:
        return np.zeros(0, bool)
    d = points - origins
    dist = np.linalg.norm(d, axis=1)
    dirs = d / np.maximum(dist, 1e-12)[:, None]
    hits = cast(scene, Rays(origins, dirs), t, kind=KIND, fields=("distance", "object_id"))
    return hits.distance >= dist - tol
