"""From capacitance changes to pressures and contact forces, with a calibration we derive.

A taxel is a capacitor across the dielectric of thickness ``d``. Under a
uniform pressure ``p`` on a laterally confined layer (uniaxial strain: the
layer bonded to a rigid carrier and wide compared with its thickness) the
dielectric shortens by ``delta = p d / M`` with ``M = lambda + 2 mu`` the
constrained (P-wave) modulus, and an ideal plate capacitor rises by

    C / C0 = d / (d - delta),   r = C / C0 - 1 = e / (1 - e),   e = delta / d = p / M.

A real taxel has fringe fields through the cover and the air that the
compression does not scale, so its relative change is a fraction ``g`` of the
ideal one. :func:`calibrate` measures ``g`` per taxel on the FEM by
imposing the exact confined-compression displacement at a strain ``e0``
(``u_z = -e0 (z - z_tx)`` in the dielectric, the cover carried along rigidly),
the same displacement a uniform pressure ``M e0`` gives. The estimate then
inverts the closed form with that gain:

    e = (r / g) / (1 + r / g),   p = M e.

The pressure map holds for the confined state; under a finger the layer
also bulges sideways, which makes it read several times high there (the
confined modulus of a rubber at nu = 0.49 is 17 E). A contact's force is
therefore estimated the way a skin is calibrated on the bench: the summed
mutual-capacitance rise over the contact's taxels (taxels above a pressure
threshold, grouped into connected patches) times a gain measured on one
reference press (:attr:`TactileSensor.force_gain`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

__all__ = ["Calibration", "ContactEstimate", "confined_compression", "estimate_contacts"]


def confined_compression(points: np.ndarray, z_tx: float, z_rx: float, z_top: float, strain: float) -> np.ndarray:
    """(n, 3) displacement of uniform confined compression of the dielectric by ``strain`` [m].

    Nodes in the dielectric move by ``-strain (z - z_tx)``, the cover above it
    moves down rigidly by ``strain (z_rx - z_tx)``; nothing else moves.
    """
    z = points[:, 2]
    uz = np.zeros(len(z))
    soft = (z >= z_tx) & (z <= z_top + 1e-12)
    uz[soft] = -strain * (np.minimum(z[soft], z_rx) - z_tx)
    u = np.zeros_like(points)
    u[:, 2] = uz
    return u


@dataclass(frozen=True, eq=False)
class Calibration:
    """Per-taxel calibration of the pressure estimate.

    Attributes
    ----------
    baseline : (rows, cols) float, mutual capacitance of the unloaded taxels [F].
    gain : (rows, cols) float, relative change per ideal relative change (``g``).
    modulus : float, constrained modulus ``M`` of the dielectric [Pa].
    """

    baseline: np.ndarray
    gain: np.ndarray
    modulus: float

    @classmethod
    def from_compression(cls, baseline: np.ndarray, compressed: np.ndarray, strain: float,
                         modulus: float) -> Calibration:
        """Gains from the mutual capacitances at rest and at a confined ``strain``."""
        ideal = strain / (1.0 - strain)
        return cls(np.asarray(baseline, float), (np.asarray(compressed) / baseline - 1.0) / ideal, float(modulus))

    def pressure(self, delta: np.ndarray) -> np.ndarray:
        """(rows, cols) estimated pressure [Pa] from the mutual changes ``delta`` [F] (>= 0)."""
        r = np.asarray(delta, float) / self.baseline / self.gain
        e = np.clip(r / (1.0 + np.maximum(r, -0.5)), 0.0, None)
        return self.modulus * e


@dataclass(frozen=True)
class ContactEstimate:
    """Contacts found in a pressure map.

    Attributes
    ----------
    force : (k,) float, estimated normal force per contact [N], largest first.
    position : (k, 2) float, pressure-weighted centre (x, y) per contact [m], skin frame.
    """

    force: np.ndarray
    position: np.ndarray


def estimate_contacts(pressure: np.ndarray, x: np.ndarray, y: np.ndarray, threshold: float,
                      taxel_force: np.ndarray) -> ContactEstimate:
    """Group taxels above ``threshold`` [Pa] into connected patches (4-neighbours) and sum their forces.

    Parameters
    ----------
    pressure : (rows, cols) float, estimated pressure [Pa] (decides the patches).
    x : (cols,) float, y : (rows,) float, taxel centres [m].
    threshold : float [Pa].
    taxel_force : (rows, cols) float, force attributed to each taxel [N].
    """
    labels, n = ndimage.label(pressure > threshold)
    forces, pos = [], []
    Y, X = np.meshgrid(y, x, indexing="ij")
    for k in range(1, n + 1):
        m = labels == k
        w = pressure[m]
        forces.append(float(taxel_force[m].sum()))
        pos.append((float((X[m] * w).sum() / w.sum()), float((Y[m] * w).sum() / w.sum())))
    order = np.argsort(forces)[::-1]
    return ContactEstimate(np.asarray(forces)[order] if n else np.zeros(0),
                           np.asarray(pos).reshape(-1, 2)[order] if n else np.zeros((0, 2)))
