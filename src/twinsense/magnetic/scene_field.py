"""The field of every magnet in a scene at world points, at one or many times.

Magnets are the ``magnet`` of scene objects visible to kind ``"magnetic"``;
each moves with its object (pose from the object's motion at t). Magnets of
one shape are evaluated in one vectorised kernel call over (times x magnets x
points); a ring is its outer cylinder minus its inner one.
"""

from __future__ import annotations

import numpy as np

from twinsense.magnetic import fields as F
from twinsense.scene.motion import ConstantVelocity, Oscillation, Static
from twinsense.scene.scene import Scene

KIND = "magnetic"


def magnet_objects(scene: Scene) -> list:
    """Scene objects that carry a magnet and are visible to magnetic sensors."""
    return [o for o in scene.objects if o.magnet is not None and o.visible_to(KIND)]


def _rodrigues(rv: np.ndarray) -> np.ndarray:
    """Rotation matrices (T, 3, 3) of rotation vectors (T, 3)."""
    th = np.linalg.norm(rv, axis=-1)
    safe = np.where(th > 0, th, 1.0)
    k = rv / safe[:, None]
    kx = np.zeros((len(rv), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx[:, 1, 0], kx[:, 2, 0], kx[:, 2, 1] = k[:, 2], -k[:, 1], k[:, 0]
    s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    return np.eye(3) + s * kx + (1 - c) * (kx @ kx)


def object_transforms(obj, times) -> tuple[np.ndarray, np.ndarray]:
    """Object -> world rotations (T, 3, 3) and positions (T, 3) at ``times`` (T,).

    Static, constant-velocity and oscillating objects are evaluated for all
    times at once from the motion's closed form (the same formulas as the
    motion's ``state``; tests/magnetic/test_scene_field.py checks they agree);
    any other motion through ``state(t)`` one time after another.
    """
    t = np.asarray(times, dtype=float)
    m = obj.motion
    if isinstance(m, Static):
        return np.broadcast_to(m.pose0.rotation, (len(t), 3, 3)), np.broadcast_to(m.pose0.position, (len(t), 3))
    if isinstance(m, ConstantVelocity):
        rot = _rodrigues(m.angular_velocity[None] * t[:, None]) @ m.pose0.rotation
        return rot, m.pose0.position + m.velocity * t[:, None]
    if isinstance(m, Oscillation):
        s = np.sin(2 * np.pi * m.frequency * t + np.deg2rad(m.phase_deg))[:, None]
        rot = _rodrigues(m.angular_amplitude[None] * s) @ m.pose0.rotation
        return rot, m.pose0.position + m.amplitude * s
    states = [obj.state_at(float(tk)) for tk in t]
    return (np.array([st.pose.rotation for st in states]).reshape(len(t), 3, 3),
            np.array([st.pose.position for st in states]).reshape(len(t), 3))


def _magnet_transforms(obj, times):
    """Magnet -> world rotations (T, 3, 3) and positions (T, 3)."""
    r_o, p_o = object_transforms(obj, times)
    mp = obj.magnet.pose
    return r_o @ mp.rotation, p_o + r_o @ mp.position


def magnet_field(magnet, points_local, n_phi: int | None = F.N_PHI) -> np.ndarray:
    """B (..., 3) [T] of one ``Magnet`` at points in its own frame."""
    m = magnet.remanence * np.asarray(magnet.direction)
    s = magnet.size
    if magnet.shape == "cylinder":
        return F.cylinder(points_local, 0.5 * s[0], s[1], m, n_phi)
    if magnet.shape == "block":
        return F.block(points_local, s, m)
    return F.ring(points_local, 0.5 * s[0], 0.5 * s[1], s[2], m, n_phi)


def scene_field(scene: Scene, points, times, n_phi: int | None = F.N_PHI) -> np.ndarray:
    """B (T, P, 3) [T] of every magnet of ``scene`` at world ``points`` (P, 3) or (T, P, 3), ``times`` (T,).

    The ambient (Earth) field is not included: it belongs to the sensor's site
    (``MagneticConfig.ambient_field``).
    """
    t = np.atleast_1d(np.asarray(times, dtype=float))
    pts = np.asarray(points, dtype=float)
    pts = np.broadcast_to(pts, (len(t), *pts.shape[-2:]))
    out = np.zeros(pts.shape)
    objs = magnet_objects(scene)
    if not objs:
        return out
    # Cylinders (rings split in two, the inner one with negative magnetisation) and blocks.
    groups: dict[str, list] = {"cylinder": [], "block": []}
    for o in objs:
        mg = o.magnet
        rot, pos = _magnet_transforms(o, t)
        mvec = mg.remanence * np.asarray(mg.direction)
        if mg.shape == "cylinder":
            groups["cylinder"].append((rot, pos, (0.5 * mg.size[0], mg.size[1]), mvec))
        elif mg.shape == "ring":
            groups["cylinder"].append((rot, pos, (0.5 * mg.size[0], mg.size[2]), mvec))
            groups["cylinder"].append((rot, pos, (0.5 * mg.size[1], mg.size[2]), -mvec))
        else:
            groups["block"].append((rot, pos, mg.size, mvec))
    for shape, items in groups.items():
        if not items:
            continue
        rot = np.stack([it[0] for it in items], axis=1)  # (T, M, 3, 3)
        pos = np.stack([it[1] for it in items], axis=1)  # (T, M, 3)
        # Points in each magnet's frame: R^T (p - c), shape (T, M, P, 3).
        local = np.einsum("tmji,tmpj->tmpi", rot, pts[:, None, :, :] - pos[:, :, None, :])
        dims = np.array([it[2] for it in items], dtype=float)  # (M, 2) or (M, 3)
        mv = np.array([it[3] for it in items], dtype=float)[None, :, None, :]  # (1, M, 1, 3)
        if shape == "cylinder":
            b = F.cylinder(local, dims[None, :, None, 0], dims[None, :, None, 1], mv, n_phi)
        else:
            b = F.block(local, dims[None, :, None, :], mv)
        out += np.einsum("tmij,tmpj->tpi", rot, b)
    return out
