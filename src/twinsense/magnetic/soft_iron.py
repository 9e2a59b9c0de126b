"""Soft-iron distortion, approximate: one induced dipole per permeable object.

An object visible to kind "magnetic" with relative permeability mu_r > 1 in
its material (and no magnet of its own) takes the magnetisation of a
permeable sphere of its volume V in the field B_ext at its volume centre
(magnets plus ambient):

    m = V chi_eff B_ext / mu0,   chi_eff = chi / (1 + N chi),   chi = mu_r - 1,   N = 1/3,

and adds the field of that dipole. This is exact for a sphere in a uniform
field (the textbook result m = 4 pi a^3 (mu_r - 1)/(mu_r + 2) H0). For other
shapes it ignores the shape's demagnetisation factors (a long rod along the
field is magnetised more, a plate across it less: up to a factor ~3 for
chi_eff -> 1/N), the variation of B_ext over the object, the object's
higher multipoles and the interaction between permeable objects, so it is
a first-order estimate, good when the object is small compared with its
distances to the magnets and the sensor. Enabled per sensor with
``MagneticConfig.soft_iron``.
"""

from __future__ import annotations

import numpy as np

from twinsense.constants import MU0
from twinsense.magnetic import fields as F
from twinsense.magnetic.scene_field import KIND, object_transforms, scene_field
from twinsense.scene.geometry import Sphere
from twinsense.scene.scene import Scene

N_DEMAG = 1.0 / 3.0  # demagnetisation factor of the equivalent sphere


def permeable_bodies(scene: Scene) -> list[tuple]:
    """(object, volume [m^3], volume centre (3,) in the object frame, chi_eff) of each permeable object."""
    out = []
    for o in scene.objects:
        mu_r = float(getattr(o.material, "mu_r", 1.0))
        if mu_r <= 1.0 or o.magnet is not None or not o.visible_to(KIND):
            continue
        g = o.geometry
        if isinstance(g, Sphere):
            vol, centre = 4.0 / 3.0 * np.pi * g.radius ** 3, np.zeros(3)
        else:
            mesh = g.mesh
            vol = abs(float(mesh.volume)) if mesh.is_volume else 0.0
            centre = np.asarray(mesh.center_mass if mesh.is_volume else mesh.bounds.mean(axis=0), dtype=float)
        if vol <= 0:
            continue  # a surface (plane) carries no volume
        chi = mu_r - 1.0
        out.append((o, vol, centre, chi / (1.0 + N_DEMAG * chi)))
    return out


def soft_iron_field(scene: Scene, points, times, ambient, bodies=None, n_phi=F.N_PHI) -> np.ndarray:
    """Field (T, P, 3) [T] of the induced dipoles at world ``points`` (T, P, 3) or (P, 3), ``times`` (T,)."""
    t = np.atleast_1d(np.asarray(times, dtype=float))
    pts = np.asarray(points, dtype=float)
    pts = np.broadcast_to(pts, (len(t), *pts.shape[-2:]))
    bodies = permeable_bodies(scene) if bodies is None else bodies
    out = np.zeros(pts.shape)
    if not bodies:
        return out
    centres = []
    for o, _, c, _ in bodies:
        rot, pos = object_transforms(o, t)
        centres.append(pos + rot @ c)
    centres = np.stack(centres, axis=1)  # (T, K, 3)
    b_ext = scene_field(scene, centres, t, n_phi) + np.asarray(ambient, dtype=float)
    scale = np.array([vol * chi_eff / MU0 for _, vol, _, chi_eff in bodies])
    moments = b_ext * scale[None, :, None]  # (T, K, 3) [A m^2]
    for k in range(len(bodies)):
        out += F.dipole(pts - centres[:, k:k + 1, :], moments[:, k:k + 1, :])
    return out
