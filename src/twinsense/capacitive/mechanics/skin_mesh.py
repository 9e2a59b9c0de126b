"""Layered box meshes of a soft skin for the elastic solve.

The skin frame: x, y in the skin plane, z the outward normal, the bottom of
the stack (bonded to a rigid carrier) at z = 0 and the contact surface at
z = total thickness. The mesh is the capacitive package's tensor grid
(:func:`~twinsense.capacitive.mesh.tensor_tet_mesh`, prisms split into
tetrahedra by the minimum-index rule), graded in z towards the contact
surface, where the strain under an indenter is largest, with every layer
interface a grid plane so each cell lies in one layer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import skfem

from twinsense import validation as v
from twinsense.capacitive.mesh import graded_axis, tensor_tet_mesh
from twinsense.errors import ConfigError

__all__ = ["LayeredMesh", "box_mesh", "skin_mesh"]


@dataclass(frozen=True, eq=False)
class LayeredMesh:
    """A tetrahedral skin mesh with its layers and boundary sets.

    Attributes
    ----------
    mesh : skfem.MeshTet
    element_layer : (n_elements,) int
        Layer of each cell, 0 at the bottom.
    fixed : (n_nodes,) bool
        Nodes on z = 0 (bonded to the rigid carrier).
    top : (n_nodes,) bool
        Nodes on the contact surface z = z_top.
    interfaces : (n_layers + 1,) float
        Layer boundaries [m], 0 first, z_top last.
    """

    mesh: skfem.MeshTet
    element_layer: np.ndarray
    fixed: np.ndarray
    top: np.ndarray
    interfaces: np.ndarray


def box_mesh(x, y, z, interfaces=None) -> LayeredMesh:
    """The tensor-grid box ``x`` by ``y`` by ``z`` as a :class:`LayeredMesh`.

    Parameters
    ----------
    x, y, z : (k,) float
        Strictly increasing grid coordinates [m]; z[0] is the bonded bottom,
        z[-1] the contact surface.
    interfaces : (n_layers + 1,) float, optional
        Layer boundaries [m] (grid planes of ``z``); default one layer.
    """
    x, y, z = (v.array(f"box_mesh.{n}", a, (None,), "m") for n, a in (("x", x), ("y", y), ("z", z)))
    for name, a in (("x", x), ("y", y), ("z", z)):
        if len(a) < 2 or np.any(np.diff(a) <= 0):
            raise ConfigError(f"box_mesh.{name}", a, "at least 2 strictly increasing coordinates [m]")
    iface = np.array([z[0], z[-1]]) if interfaces is None else v.array("box_mesh.interfaces", interfaces, (None,), "m")
    tol = 1e-9 * (z[-1] - z[0])
    if (len(iface) < 2 or np.any(np.diff(iface) <= 0) or abs(iface[0] - z[0]) > tol or abs(iface[-1] - z[-1]) > tol
            or not np.all(np.min(np.abs(iface[:, None] - z[None, :]), axis=1) <= tol)):
        raise ConfigError("box_mesh.interfaces", iface, "increasing grid planes of z from z[0] to z[-1] [m]")
    sm = tensor_tet_mesh(x, y, z)
    mesh = skfem.MeshTet(np.ascontiguousarray(sm.points.T), np.ascontiguousarray(sm.cells.T))
    zc = sm.centroids[:, 2]
    layer = np.clip(np.searchsorted(iface, zc) - 1, 0, len(iface) - 2)
    pz = sm.points[:, 2]
    return LayeredMesh(mesh, layer.astype(np.int64), np.abs(pz - z[0]) <= tol, np.abs(pz - z[-1]) <= tol,
                       iface)


def skin_mesh(size, thicknesses, *, h_xy: float, h_top: float, h_z: float | None = None,
              growth: float = 1.3) -> LayeredMesh:
    """A layered skin ``size[0]`` x ``size[1]`` centred on the origin, graded towards its top.

    Parameters
    ----------
    size : (2,) float
        Skin extent in x and y [m].
    thicknesses : sequence of float
        Layer thicknesses from the bottom up [m] (e.g. dielectric, cover).
    h_xy : float
        In-plane cell size [m] (uniform: taxels sit everywhere on the skin).
    h_top : float
        Cell height at the contact surface [m].
    h_z : float, optional
        Largest cell height, reached towards the bottom [m] (default 2 h_top).
    growth : float
        Ratio of neighbouring cell heights away from the top (> 1).
    """
    sx, sy = v.vector("skin_mesh.size", size, 2, "m")
    if sx <= 0 or sy <= 0:
        raise ConfigError("skin_mesh.size", size, "two sizes > 0 [m]")
    t = v.array("skin_mesh.thicknesses", thicknesses, (None,), "m")
    if len(t) == 0 or np.any(t <= 0):
        raise ConfigError("skin_mesh.thicknesses", thicknesses, "one or more layer thicknesses > 0 [m]")
    h_xy = v.positive("skin_mesh.h_xy", h_xy, "m")
    h_top = v.positive("skin_mesh.h_top", h_top, "m")
    h_z = 2 * h_top if h_z is None else v.number("skin_mesh.h_z", h_z, lo=h_top, unit="m (>= h_top)")
    growth = v.number("skin_mesh.growth", growth, lo=1.0, lo_open=True)
    iface = np.concatenate([[0.0], np.cumsum(t)])
    top = iface[-1]
    z = graded_axis(0.0, top, features=iface[1:-1], h_min=h_z, h_max=h_z, growth=growth,
                    zones=[(top - 1e-12 * top, top, h_top)])
    x = np.linspace(-sx / 2, sx / 2, max(2, int(np.ceil(sx / h_xy - 1e-9)) + 1))
    y = np.linspace(-sy / 2, sy / 2, max(2, int(np.ceil(sy / h_xy - 1e-9)) + 1))
    return box_mesh(x, y, z, iface)
