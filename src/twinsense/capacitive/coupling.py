"""Scene objects -> per-cell material of the static FEM mesh.

Every cell takes the material of the object that contains its centroid,
decided by the object's exact inside test (primitives analytically, meshes by
ray parity), so hidden, hollow and concave objects are mapped right, unlike a
depth image that fills everything behind the visible surface. Dielectrics set
the cell's relative permittivity; conductors make all nodes of their cells
one conductor: grounded (0 V) or floating (one unknown potential, zero net
charge). Later objects override earlier dielectrics; a grounded node stays
grounded. Only cells whose bounds meet the object's bounding box are tested,
so a small object in a large mesh costs little.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from twinsense.capacitive.mesh import SimplexMesh
from twinsense.errors import ConfigError
from twinsense.scene.materials import CONDUCTOR_KINDS

__all__ = [
    "CONDUCTOR_KINDS",
    "Inclusion",
    "MaterialMap",
    "bounds_in_mesh_frame",
    "inclusions_from_scene",
    "map_inclusions",
]



@dataclass(frozen=True, eq=False)
class Inclusion:
    """A body in the sensing volume at one instant.

    Attributes
    ----------
    name : str
    contains : callable ((n, 3) float world points [m]) -> (n,) bool
    bounds : (2, 3) float
        World axis-aligned bounds [m] (cells outside are not tested).
    permittivity : float
        Relative permittivity (> 0); unused for conductors.
    conductor : {"none", "grounded", "floating"}
    """

    name: str
    contains: Callable[[np.ndarray], np.ndarray]
    bounds: np.ndarray
    permittivity: float = 1.0
    conductor: str = "none"

    def __post_init__(self) -> None:
        if self.conductor not in CONDUCTOR_KINDS:
            raise ConfigError(f"{self.name}.conductor", self.conductor, "one of: " + ", ".join(CONDUCTOR_KINDS))
        eps = self.permittivity
        if not (isinstance(eps, (int, float, np.floating)) and np.isfinite(eps) and eps > 0):
            raise ConfigError(f"{self.name}.permittivity", eps, "a finite relative permittivity > 0")
        b = np.asarray(self.bounds, float)
        if b.shape != (2, 3) or not np.all(b[1] >= b[0]):
            raise ConfigError(f"{self.name}.bounds", self.bounds, "(2, 3) min/max corners [m]")
        object.__setattr__(self, "bounds", b)


@dataclass(frozen=True, eq=False)
class MaterialMap:
    """The mesh's material state for one frame.

    Attributes
    ----------
    permittivity : (m,) float, relative permittivity per cell.
    grounded : (n,) bool, nodes of grounded objects.
    floating : tuple of (k_i,) int64, node sets of floating objects (one per object).
    floating_names : tuple of str, the names of those objects.
    """

    permittivity: np.ndarray
    grounded: np.ndarray
    floating: tuple
    floating_names: tuple


def _box_corners(b: np.ndarray) -> np.ndarray:
    return np.array([[b[i, 0], b[j, 1], b[k, 2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])


def bounds_in_mesh_frame(inc: Inclusion, mesh_to_world=None) -> np.ndarray:
    """(2, 3) axis-aligned bounds [m] of ``inc`` in the mesh frame (the box whose cells are tested)."""
    if mesh_to_world is None:
        return inc.bounds
    c = mesh_to_world.inverse().apply(_box_corners(inc.bounds))
    return np.vstack([c.min(axis=0), c.max(axis=0)])


def inclusions_from_scene(scene, t: float, kind: str = "capacitive") -> list[Inclusion]:
    """Inclusions of every scene object visible to ``kind`` at time ``t`` [s]."""
    out = []
    for obj in scene.objects:
        if not obj.visible_to(kind):
            continue
        pose = obj.pose_at(t)
        inv = pose.inverse()
        geom = obj.geometry
        corners = pose.apply(_box_corners(np.asarray(geom.bounds, float)))
        bounds = np.vstack([corners.min(axis=0), corners.max(axis=0)])

        def contains(p, geom=geom, inv=inv):
            return np.asarray(geom.contains(inv.apply(p)), bool)

        mat = obj.material
        out.append(Inclusion(obj.name, contains, bounds, float(mat.permittivity), mat.conductor))
    return out


def map_inclusions(
    mesh: SimplexMesh,
    base_permittivity: np.ndarray,
    inclusions: Sequence[Inclusion],
    mesh_to_world=None,
) -> MaterialMap:
    """Map inclusions onto the cells of ``mesh``.

    Parameters
    ----------
    mesh : SimplexMesh, in its own (sensor) frame.
    base_permittivity : (m,) float, relative permittivity with no object.
    inclusions : sequence of Inclusion, world frame.
    mesh_to_world : Pose or None, mesh frame -> world (None: identity).

    Returns
    -------
    MaterialMap
    """
    eps = np.array(base_permittivity, float, copy=True)
    grounded = np.zeros(mesh.n_nodes, bool)
    floating, names = [], []
    cmin, cmax = mesh.cell_bounds
    for inc in inclusions:
        b = bounds_in_mesh_frame(inc, mesh_to_world)
        cand = np.flatnonzero(np.all(cmax >= b[0], axis=1) & np.all(cmin <= b[1], axis=1))
        if len(cand) == 0:
            continue
        cen = mesh.centroids[cand]
        if mesh_to_world is not None:
            cen = mesh_to_world.apply(cen)
        inside = cand[np.asarray(inc.contains(cen), bool)]
        if len(inside) == 0:
            continue
        if inc.conductor == "none":
            eps[inside] = inc.permittivity
        elif inc.conductor == "grounded":
            grounded[np.unique(mesh.cells[inside])] = True
        else:
            floating.append(np.unique(mesh.cells[inside]))
            names.append(inc.name)
    return MaterialMap(eps, grounded, tuple(floating), tuple(names))
