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
    "electrically_relevant",
    "inclusions_from_scene",
    "map_inclusions",
    "object_box_in_mesh_frame",
    "resolution_boxes",
    "resolving_cell_sizes",
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


def electrically_relevant(obj, kind: str = "capacitive") -> bool:
    """True for a scene object that can change a capacitance: visible to ``kind``, with
    volume, and a conductor or a dielectric other than vacuum."""
    if not obj.visible_to(kind):
        return False
    mat = obj.material
    if mat.conductor == "none" and float(mat.permittivity) == 1.0:
        return False
    b = np.asarray(obj.geometry.bounds, float)
    return bool(np.all(b[1] > b[0]))  # a plane holds no cell centroid


def object_box_in_mesh_frame(obj, t: float, mesh_to_world=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where ``obj`` is at time ``t`` [s], seen from the mesh frame.

    Returns
    -------
    bounds : (2, 3) float
        Axis-aligned bounds of the object's local box in the mesh frame [m].
    extent : (3,) float
        Edge lengths of the object's local box [m].
    rotation : (3, 3) float
        Object axes (columns) in the mesh frame.
    """
    pose = obj.pose_at(t)
    if mesh_to_world is not None:
        pose = mesh_to_world.inverse() @ pose
    local = np.asarray(obj.geometry.bounds, float)
    corners = pose.apply(_box_corners(local))
    return np.vstack([corners.min(axis=0), corners.max(axis=0)]), local[1] - local[0], np.asarray(pose.rotation)


def resolving_cell_sizes(extent: np.ndarray, rotation: np.ndarray, cells: float) -> np.ndarray:
    """(3,) cell sizes [m] along the mesh axes that put ``cells`` cells across a box.

    A box of edge lengths ``extent`` (3,) [m] whose axes are the columns of
    ``rotation`` (3, 3) in the mesh frame: along mesh axis k the size is
    min over the box axes j of extent_j / cells / abs(R_kj). An axis-aligned
    box gets extent_k / cells on axis k; a tilted face is crossed by every
    axis it leans on, and the cells along them step it in sum by at most
    ``sum_k abs(R_kj) h_k <= 3 extent_j / cells``.
    """
    with np.errstate(divide="ignore"):
        per_axis = np.asarray(extent, float)[None, :] / (cells * np.abs(np.asarray(rotation, float)))
    return per_axis.min(axis=1)


def resolution_boxes(
    scene,
    times,
    mesh_to_world_at: Callable[[float], object],
    region,
    cells: float,
    h_max: float,
    kind: str = "capacitive",
    exclude: Sequence[str] = (),
) -> tuple:
    """Refine boxes that resolve the scene's objects where they are at ``times``.

    Each electrically relevant object's mesh-frame box at each time, padded
    by one cell on every side (so the cells that meet the object lie inside
    the refined zone), clipped to ``region``, with the sizes of
    :func:`resolving_cell_sizes` capped at ``h_max``. The boxes of one object
    that overlap from one time to the next merge into their bounding box
    (the tensor grid refines whole slabs per axis, so this loses nothing there).

    Parameters
    ----------
    scene : Scene
    times : (f,) float, capture times [s].
    mesh_to_world_at : callable t -> Pose, mesh (sensor) frame -> world.
    region : (6,) float, the meshed box [m].
    cells : float, cells across each object (> 0).
    h_max : float, largest cell size of the mesh [m].
    kind : str, the sensor kind objects must be visible to.
    exclude : names of objects to leave out (the body the sensor rides on).

    Returns
    -------
    tuple of (9,) tuples (x_min, x_max, y_min, y_max, z_min, z_max, h_x, h_y, h_z) [m],
    the ``MeshSettings.refine`` entry form.
    """
    lo_r = np.asarray(region, float)[0::2]
    hi_r = np.asarray(region, float)[1::2]
    times = np.atleast_1d(np.asarray(times, float))
    poses = [mesh_to_world_at(t) for t in times]
    boxes: list[list[np.ndarray]] = []
    for obj in scene.objects:
        if obj.name in exclude or not electrically_relevant(obj, kind):
            continue
        current = None
        for t, pose in zip(times, poses):
            b, extent, rot = object_box_in_mesh_frame(obj, t, pose)
            h = np.minimum(resolving_cell_sizes(extent, rot, cells), h_max)
            if np.all(h >= h_max):
                continue  # the coarsest cells already resolve it
            lo = np.maximum(b[0] - h, lo_r)
            hi = np.minimum(b[1] + h, hi_r)
            if np.any(hi <= lo):
                continue  # outside the sensing volume
            if current is not None and np.all(lo <= current[1]) and np.all(hi >= current[0]):
                current = [np.minimum(current[0], lo), np.maximum(current[1], hi), np.minimum(current[2], h)]
                boxes[-1] = current
            else:
                current = [lo, hi, h]
                boxes.append(current)
    out = []
    for lo, hi, h in boxes:
        out.append(tuple(float(x) for x in (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], *h)))
    return tuple(out)
