"""Scene objects pressing on the skin -> indenter height fields in the skin frame.

An object touches the skin where its lower surface dips below the undeformed
top surface ``z = z_top``. The elastic contact solve needs that lower surface
as a height field ``h(x, y)`` [m] in the skin frame (``inf`` where the
object is absent). Spheres, capsules and boxes have exact closed forms (the
lower envelope of a sphere; of a capsule, the lower of its two end spheres
and its cylinder; of a box, the entry point of an upward vertical ray, slab
method). Any other geometry (cylinders, triangle meshes, mesh files) is
sampled by upward vertical rays cast through :func:`twinsense.render.cast`
on the mesh points' grid and is exact at those points (the mechanics asks
for the height at its top nodes only).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from twinsense.render.caster import cast
from twinsense.render.rays import Rays
from twinsense.scene.geometry import Box, Capsule, Sphere
from twinsense.scene.scene import Scene

__all__ = ["ContactShape", "height_field", "sphere_height", "touching_objects"]


@dataclass(frozen=True, eq=False)
class ContactShape:
    """A scene object's lower surface over the skin at one instant.

    Attributes
    ----------
    name : str, the scene object.
    height : callable ((n,) x, (n,) y) -> (n,) z [m], skin frame, inf where absent.
    position : (3,) float, a reference point of the object in the skin frame [m]
        (the centre of its bounds), to match estimated and true contacts.
    """

    name: str
    height: Callable[[np.ndarray, np.ndarray], np.ndarray]
    position: np.ndarray


def sphere_height(center, radius: float) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """Lower surface ``z = c_z - sqrt(r^2 - rho^2)`` of a sphere [m] (inf outside its shadow)."""
    c = np.asarray(center, float)

    def h(x, y):
        rho2 = (np.asarray(x, float) - c[0]) ** 2 + (np.asarray(y, float) - c[1]) ** 2
        with np.errstate(invalid="ignore"):
            z = c[2] - np.sqrt(radius**2 - rho2)
        return np.where(rho2 <= radius**2, z, np.inf)

    return h


def _capsule_height(a: np.ndarray, b: np.ndarray, radius: float):
    """Lower envelope of a capsule (segment a-b, radius) [m]: end spheres and the cylinder part."""
    ha, hb = sphere_height(a, radius), sphere_height(b, radius)
    d = b - a
    length = float(np.linalg.norm(d))

    def h(x, y):
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        out = np.minimum(ha(x, y), hb(x, y))
        if length == 0.0:
            return out
        e = d / length
        # Points p = (x, y, z): w = p - a = w0 + z ez; distance^2 to the axis
        # |w|^2 - (w.e)^2 = r^2 is quadratic in z: A z^2 + B z + C = 0.
        w0x, w0y, w0z = x - a[0], y - a[1], -a[2]
        s0 = w0x * e[0] + w0y * e[1] + w0z * e[2]
        qa = 1.0 - e[2] ** 2
        qb = 2.0 * (w0z - s0 * e[2])
        qc = w0x**2 + w0y**2 + w0z**2 - s0**2 - radius**2
        if qa < 1e-12:  # vertical axis: the cylinder adds nothing below the lower end sphere
            return out
        disc = qb**2 - 4 * qa * qc
        with np.errstate(invalid="ignore"):
            z = (-qb - np.sqrt(disc)) / (2 * qa)
        s = s0 + z * e[2]
        ok = (disc >= 0) & (s >= 0) & (s <= length)
        return np.where(ok, np.minimum(out, z), out)

    return h


def _box_height(rotation: np.ndarray, center: np.ndarray, half: np.ndarray):
    """Entry height of an upward vertical ray into an oriented box (slab method) [m]."""
    def h(x, y):
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        o = np.stack([x - center[0], y - center[1], np.full_like(x, -center[2])], axis=1) @ rotation  # box frame
        dz = rotation[2]  # the skin's +z in the box frame
        t_in = np.full(len(x), -np.inf)
        t_out = np.full(len(x), np.inf)
        for k in range(3):
            if abs(dz[k]) < 1e-15:
                outside = np.abs(o[:, k]) > half[k]
                t_in[outside] = np.inf
                continue
            t1 = (-half[k] - o[:, k]) / dz[k]
            t2 = (half[k] - o[:, k]) / dz[k]
            t_in = np.maximum(t_in, np.minimum(t1, t2))
            t_out = np.minimum(t_out, np.maximum(t1, t2))
        return np.where(t_in <= t_out, t_in, np.inf)

    return h


def _ray_height(obj, t: float, skin_to_world, z_below: float):
    """Lower surface by upward vertical rays through the render stage."""
    scene = Scene([obj])

    def h(x, y):
        x = np.asarray(x, float)
        o = np.column_stack([x, np.asarray(y, float), np.full(len(x), z_below)])
        origins = skin_to_world.apply(o)
        up = np.broadcast_to(np.asarray(skin_to_world.rotation)[:, 2], origins.shape)
        hits = cast(scene, Rays(origins, np.ascontiguousarray(up)), t, kind="tactile")
        return z_below + hits.distance

    return h


def height_field(obj, t: float, skin_to_world, z_below: float = -1.0):
    """The lower surface of scene object ``obj`` at time ``t`` over the skin (skin frame).

    Parameters
    ----------
    obj : SceneObject
    t : float [s]
    skin_to_world : Pose, skin frame -> world at ``t``.
    z_below : float, start height of the rays of the generic path [m] (skin frame).

    Returns
    -------
    callable ((n,) x, (n,) y) -> (n,) z [m], inf where the object is absent.
    """
    pose = skin_to_world.inverse() @ obj.pose_at(t)  # object -> skin
    g = obj.geometry
    R = np.asarray(pose.rotation, float)
    c = np.asarray(pose.position, float)
    if isinstance(g, Sphere):
        return sphere_height(c, g.radius)
    if isinstance(g, Capsule):
        axis = R[:, 2] * 0.5 * g.height
        return _capsule_height(c - axis, c + axis, g.radius)
    if isinstance(g, Box):
        return _box_height(R, c, 0.5 * np.asarray(g.size, float))
    return _ray_height(obj, t, skin_to_world, z_below)


def touching_objects(scene, t: float, skin_to_world, x: np.ndarray, y: np.ndarray, z_top: float,
                     kind: str = "tactile", exclude=()) -> list[ContactShape]:
    """Objects whose lower surface dips below ``z_top`` somewhere on the points (x, y).

    Parameters
    ----------
    x, y : (n,) float, top-surface points of the skin [m], skin frame.
    z_top : float, the undeformed top surface [m].
    """
    out = []
    inv = skin_to_world.inverse()
    for obj in scene.objects:
        if obj.name in exclude or not obj.visible_to(kind):
            continue
        b = np.asarray(obj.geometry.bounds, float)
        if not np.all(b[1] > b[0]):
            continue  # planes have no volume to press with
        pose = inv @ obj.pose_at(t)
        corners = pose.apply(np.array([[b[i, 0], b[j, 1], b[k, 2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)]))
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        if lo[2] >= z_top or hi[0] < x.min() or lo[0] > x.max() or hi[1] < y.min() or lo[1] > y.max():
            continue  # cheap rejection: the object's box is above the skin or beside it
        h = height_field(obj, t, skin_to_world)
        if np.any(h(x, y) < z_top):
            out.append(ContactShape(obj.name, h, 0.5 * (lo + hi)))
    return out
