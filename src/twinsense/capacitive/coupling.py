"""Scene objects -> per-cell material of the static FEM mesh.

Every cell takes the material of the object that contains its centroid,
decided by the object's exact inside test (primitives analytically, meshes by
ray parity), so hidden, hollow and concave objects are mapped right, unlike a
depth image that fills everything behind the visible surface. Dielectrics set
the cell's relative permittivity; conductors make all nodes of their cells
one conductor: grounded (0 V) or floating (one unknown potential, zero net
charge). Later objects override earlier dielectrics; a grounded node stays
grounded. Only cells whose bounds meet the object's bounding box are tested,
so a small object in a large mesh costs little, and an object whose box
misses the meshed domain (seen from either side: the object's box in the mesh
frame against the domain, the domain's box in the object frame against the
object's own box) costs no per-cell test at all. An :class:`InclusionCache`
keeps each object's inside cells with its pose relative to the mesh: a link
carried rigidly with the sensor (or any object at rest relative to it) is
mapped once.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from twinsense.capacitive.mesh import SimplexMesh
from twinsense.compiled import jit
from twinsense.errors import ConfigError
from twinsense.scene.geometry import Geometry, TriangleMesh
from twinsense.scene.materials import CONDUCTOR_KINDS

POSE_TOLERANCE = 1e-9
"""Largest change of a relative pose (translation [m], rotation matrix entries) that
reuses cached inside cells. A centroid at distance r from the object's origin moves
by at most about 1e-9 * (1 + 3 r) m (< 2 nm within 0.3 m), far below any cell; only a
centroid closer than that to the object's surface could be classified otherwise,
and there the exact test is itself decided by rounding."""

__all__ = [
    "CONDUCTOR_KINDS",
    "POSE_TOLERANCE",
    "Inclusion",
    "InclusionCache",
    "MaterialMap",
    "bounds_in_mesh_frame",
    "electrically_relevant",
    "held_weakly",
    "inclusions_from_scene",
    "map_inclusions",
    "meets_domain",
    "object_box_at_pose",
    "object_box_in_mesh_frame",
    "refers_to",
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
    pose : Pose or None
        Object -> world at this instant (None: unknown; then no culling in
        the object frame and no caching).
    local_bounds : (2, 3) float or None
        The object's own box in its frame [m] (with ``pose``).
    shape : object or None
        The geometry (its identity keys the cache: a new shape maps anew). A
        :class:`~twinsense.scene.Geometry` here must be the one ``contains``
        tests (in the world frame, through ``pose``): with ``pose`` the mapper
        runs its inside test in the object frame instead.
    """

    name: str
    contains: Callable[[np.ndarray], np.ndarray]
    bounds: np.ndarray
    permittivity: float = 1.0
    conductor: str = "none"
    pose: object = None
    local_bounds: np.ndarray | None = None
    shape: object = None

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
        if self.local_bounds is not None:
            object.__setattr__(self, "local_bounds", np.asarray(self.local_bounds, float))


def held_weakly(obj):
    """What an identity-keyed cache keeps of ``obj``: a weak reference (None for None).

    A sensor's caches compare scene objects, shapes and motions by identity
    (``is``); a strong reference would keep the last scene and its meshes
    alive for as long as the sensor lives. An object that takes no weak
    reference (``__slots__`` without ``__weakref__``) is kept as it is.
    Compare with :func:`refers_to`.
    """
    if obj is None:
        return None
    try:
        return weakref.ref(obj)
    except TypeError:
        return obj


def refers_to(held, obj) -> bool:
    """Whether ``held`` (from :func:`held_weakly`) is ``obj`` itself: never for a collected object
    (its dead reference gives None, and None is only ever held as None)."""
    if held is None or obj is None:
        return held is None and obj is None
    return held is obj or (type(held) is weakref.ref and held() is obj)


class InclusionCache:
    """Inside cells of each object, kept with the object's pose relative to the mesh.

    One cache belongs to one mesh (the sensor drops it with its mesh). An
    entry is reused when the same shape sits at the same relative pose within
    :data:`POSE_TOLERANCE`; otherwise the object is mapped anew and the entry
    replaced. ``hits`` and ``misses`` count the per-cell tests saved and done.
    """

    def __init__(self) -> None:
        self._entries: dict[str, tuple] = {}
        self.hits = 0
        self.misses = 0

    def lookup(self, name: str, shape, rel: np.ndarray) -> np.ndarray | None:
        e = self._entries.get(name)
        if e is None or not refers_to(e[0], shape) or np.max(np.abs(e[1] - rel)) > POSE_TOLERANCE:
            self.misses += 1
            return None
        self.hits += 1
        return e[2]

    def __getstate__(self) -> dict:
        # Weak references do not pickle, and a copy in another process never sees these shapes
        # (an unpickled scene's are new objects): the copy starts empty and maps anew, the same cells.
        return {**self.__dict__, "_entries": {}}

    def store(self, name: str, shape, rel: np.ndarray, inside: np.ndarray) -> None:
        # The shape held weakly: the cache outlives scenes, and must not keep their meshes alive.
        self._entries[name] = (held_weakly(shape), rel.copy(), inside)


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


_CORNER_ROWS = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
_CORNER_COLS = np.array([0, 1, 2])


def _box_corners(b: np.ndarray) -> np.ndarray:
    """(8, 3) corners of the box ``b`` (2, 3): min/max per axis, x slowest."""
    return np.asarray(b, float)[_CORNER_ROWS, _CORNER_COLS]


def _relative(inc: Inclusion, mesh_to_world) -> np.ndarray | None:
    """(3, 4) [R | p] of the object in the mesh frame (None without a pose)."""
    if inc.pose is None or inc.local_bounds is None:
        return None
    ro, po = np.asarray(inc.pose.rotation), np.asarray(inc.pose.position)
    if mesh_to_world is None:
        return np.column_stack([ro, po])
    rm, pm = np.asarray(mesh_to_world.rotation), np.asarray(mesh_to_world.position)
    return np.column_stack([rm.T @ ro, rm.T @ (po - pm)])


def _transformed_box(box: np.ndarray, rot: np.ndarray, pos: np.ndarray) -> np.ndarray:
    c = _box_corners(box) @ rot.T + pos
    return np.vstack([c.min(axis=0), c.max(axis=0)])


def _overlap(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.all(a[1] >= b[0]) and np.all(a[0] <= b[1]))


def bounds_in_mesh_frame(inc: Inclusion, mesh_to_world=None) -> np.ndarray:
    """(2, 3) axis-aligned bounds [m] of ``inc`` in the mesh frame (the box whose cells are tested).

    With the inclusion's pose, the box of its own local box (tighter than the
    box of its world box); every point inside the object lies in it either way.
    """
    rel = _relative(inc, mesh_to_world)
    if rel is not None:
        return _transformed_box(inc.local_bounds, rel[:, :3], rel[:, 3])
    if mesh_to_world is None:
        return inc.bounds
    c = mesh_to_world.inverse().apply(_box_corners(inc.bounds))
    return np.vstack([c.min(axis=0), c.max(axis=0)])


def meets_domain(inc: Inclusion, domain: np.ndarray, mesh_to_world=None) -> bool:
    """False when ``inc`` cannot hold a point of the mesh domain box ``domain`` (2, 3) [m].

    Both boxes are tested from both sides (a separating-axis test on the two
    frames' axes): the object's box in the mesh frame against the domain, and
    the domain's box in the object frame against the object's own box. A thin
    plane tilted against the mesh has a large mesh-frame box but is culled by
    the second test.
    """
    if not _overlap(bounds_in_mesh_frame(inc, mesh_to_world), domain):
        return False
    rel = _relative(inc, mesh_to_world)
    if rel is None:
        return True
    rt = rel[:, :3].T
    return _overlap(_transformed_box(domain, rt, -rt @ rel[:, 3]), inc.local_bounds)


CULL_PAD = 1e-9
"""[m] Both boxes of :func:`_meet_domain_all` are widened by this much: its vectorised products round
differently from :func:`meets_domain`'s, and the widening keeps it from dropping an object that test
keeps (a borderline object then passes and is mapped exactly, to no cells)."""


def _meet_domain_all(inclusions: Sequence[Inclusion], domain: np.ndarray, mesh_to_world=None) -> np.ndarray:
    """(k,) bool: :func:`meets_domain` of every inclusion, the posed ones in a few array operations.

    The same two box tests (the object's box in the mesh frame against the domain, the domain's
    box in the object's frame against the object's own box), each widened by :data:`CULL_PAD`, for
    all objects with a pose at once: a robot cell's 33 objects took 2.7 ms one by one (a dozen small
    NumPy calls each), about 0.2 ms here.
    """
    out = np.ones(len(inclusions), bool)
    posed = [i for i, inc in enumerate(inclusions) if inc.pose is not None and inc.local_bounds is not None]
    for i in set(range(len(inclusions))) - set(posed):
        out[i] = meets_domain(inclusions[i], domain, mesh_to_world)
    if not posed:
        return out
    ro = np.stack([np.asarray(inclusions[i].pose.rotation, float) for i in posed])  # (k, 3, 3)
    po = np.stack([np.asarray(inclusions[i].pose.position, float) for i in posed])  # (k, 3)
    lb = np.stack([np.asarray(inclusions[i].local_bounds, float) for i in posed])  # (k, 2, 3)
    if mesh_to_world is None:
        rot, pos = ro, po
    else:
        rm, pm = np.asarray(mesh_to_world.rotation, float), np.asarray(mesh_to_world.position, float)
        rot, pos = rm.T @ ro, (po - pm) @ rm  # the object in the mesh frame
    corners = lb[:, _CORNER_ROWS, _CORNER_COLS]  # (k, 8, 3), object frame
    c = corners @ rot.transpose(0, 2, 1) + pos[:, None, :]
    meets = np.all(c.max(axis=1) >= domain[0] - CULL_PAD, axis=1) & np.all(c.min(axis=1) <= domain[1] + CULL_PAD,
                                                                            axis=1)
    d = _box_corners(domain)[None] - pos[:, None, :]  # the domain's corners, taken into each object frame
    c = d @ rot
    meets &= np.all(c.max(axis=1) >= lb[:, 0] - CULL_PAD, axis=1) & np.all(c.min(axis=1) <= lb[:, 1] + CULL_PAD,
                                                                          axis=1)
    out[posed] = meets
    return out


def inclusions_from_scene(scene, t: float, kind: str = "capacitive") -> list[Inclusion]:
    """Inclusions of every scene object visible to ``kind`` at time ``t`` [s]."""
    out = []
    for obj in scene.objects:
        if not obj.visible_to(kind):
            continue
        pose = obj.pose_at(t)
        geom = obj.geometry
        local_bounds = np.asarray(geom.bounds, float)
        corners = _box_corners(local_bounds) @ pose.rotation.T + pose.position
        bounds = np.array([corners.min(axis=0), corners.max(axis=0)])

        # The inverse pose only when a point test runs: most objects of a cell are culled before
        # any (an inverse re-orthonormalises its rotation, ~30 us, 33 objects a frame).
        def contains(p, geom=geom, pose=pose):
            return np.asarray(geom.contains(pose.inverse().apply(p)), bool)

        mat = obj.material
        out.append(Inclusion(obj.name, contains, bounds, float(mat.permittivity), mat.conductor,
                             pose=pose, local_bounds=local_bounds, shape=geom))
    return out


def map_inclusions(
    mesh: SimplexMesh,
    base_permittivity: np.ndarray,
    inclusions: Sequence[Inclusion],
    mesh_to_world=None,
    cache: InclusionCache | None = None,
) -> MaterialMap:
    """Map inclusions onto the cells of ``mesh``.

    Parameters
    ----------
    mesh : SimplexMesh, in its own (sensor) frame.
    base_permittivity : (m,) float, relative permittivity with no object.
    inclusions : sequence of Inclusion, world frame.
    mesh_to_world : Pose or None, mesh frame -> world (None: identity).
    cache : InclusionCache or None
        Inside cells of earlier frames on this mesh, reused for an object at
        the same relative pose (within :data:`POSE_TOLERANCE`).

    Returns
    -------
    MaterialMap
    """
    eps = np.array(base_permittivity, float, copy=True)
    grounded = np.zeros(mesh.n_nodes, bool)
    floating, names = [], []
    domain = mesh.bounds
    # Culling first: most objects of a cell are far from a small skin.
    may_meet = _meet_domain_all(inclusions, domain, mesh_to_world)
    for inc, meets in zip(inclusions, may_meet, strict=True):
        if not meets:
            continue
        rel = _relative(inc, mesh_to_world) if cache is not None else None
        inside = None if rel is None else cache.lookup(inc.name, inc.shape, rel)
        if inside is None:
            local = _relative(inc, mesh_to_world) if rel is None else rel
            if local is not None and mesh.dim == 3:
                inside = _inside_cells_local(mesh, inc, local, mesh_to_world)
            else:
                inside = _inside_cells_world(mesh, inc, mesh_to_world)
            if rel is not None:
                cache.store(inc.name, inc.shape, rel, inside)
        if len(inside) == 0:
            continue
        if inc.conductor == "none":
            eps[inside] = inc.permittivity
        elif inc.conductor == "grounded":
            grounded[mesh.cells[inside].ravel()] = True
        else:
            floating.append(_node_set(mesh, inside))
            names.append(inc.name)
    return MaterialMap(eps, grounded, tuple(floating), tuple(names))


def _node_set(mesh: SimplexMesh, cells: np.ndarray) -> np.ndarray:
    """(k,) int64 sorted nodes of ``cells`` (``np.unique`` of their nodes, by a mask: no sort)."""
    mark = np.zeros(mesh.n_nodes, bool)
    mark[mesh.cells[cells].ravel()] = True
    return np.flatnonzero(mark)


def _inside_cells_world(mesh: SimplexMesh, inc: Inclusion, mesh_to_world) -> np.ndarray:
    """Cells whose centroid ``inc.contains`` holds, among those meeting its box (no object pose known)."""
    cand = mesh.cells_meeting_box(bounds_in_mesh_frame(inc, mesh_to_world))
    if len(cand) == 0:
        return cand
    cen = mesh.centroids[cand]
    if mesh_to_world is not None:
        cen = mesh_to_world.apply(cen)
    return cand[np.asarray(inc.contains(cen), bool)]


def _inside_cells_local(mesh: SimplexMesh, inc: Inclusion, local: np.ndarray, mesh_to_world) -> np.ndarray:
    """Cells whose centroid lies inside ``inc`` at ``local`` (3, 4) [R | p] (object -> mesh frame).

    One compiled pass takes every centroid into the object frame and keeps those
    within the object's own box (padded by 1 nm against rounding: the inside test
    sees the coordinates computed another way), so the costly inside test sees no
    others. That test runs in the object frame on those coordinates when the
    inclusion carries its geometry (``shape``; a convex mesh by its face planes,
    compiled), else through ``inc.contains`` in the world frame. The two frames
    round a centroid's coordinates differently by ~1e-16 m: only a centroid that
    close to the surface could be classified otherwise, where the exact test is
    itself decided by rounding.
    """
    lb = inc.local_bounds
    idx, q = _local_box_kernel(mesh.centroids, np.ascontiguousarray(local[:, :3]),
                               np.ascontiguousarray(local[:, 3]), lb[0] - 1e-9, lb[1] + 1e-9)
    if len(idx) == 0:
        return idx
    shape = inc.shape
    if isinstance(shape, Geometry):
        planes = _convex_planes(shape)
        if planes is not None:
            return idx[_inside_planes_kernel(q, planes[0], planes[1])]
        return idx[np.asarray(shape.contains(q), bool)]
    cen = mesh.centroids[idx]
    if mesh_to_world is not None:
        cen = mesh_to_world.apply(cen)
    return idx[np.asarray(inc.contains(cen), bool)]


_PLANES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _convex_planes(shape: Geometry) -> tuple[np.ndarray, np.ndarray] | None:
    """Face planes (normals (f, 3), offsets (f,) [m]) of a convex closed mesh geometry, else None.

    A box link with an offset origin (a person's hand, a robot's block) arrives as a
    12-triangle :class:`TriangleMesh`, whose general inside test (winding numbers) costs
    points x triangles arctangents; inside a convex closed mesh is below every face
    plane. Computed once per shape (kept as long as the shape lives).
    """
    if not isinstance(shape, TriangleMesh):
        return None
    if shape in _PLANES:
        return _PLANES[shape]
    m = shape.mesh
    planes = None
    if m.is_watertight and m.is_convex:
        normals = np.ascontiguousarray(m.face_normals, float)
        offsets = np.einsum("ij,ij->i", normals, m.triangles[:, 0, :])
        planes = (normals, offsets)
    _PLANES[shape] = planes
    return planes


@jit
def _local_box_kernel(centroids, rot, pos, lo, hi):
    """Centroids (m, 3) in the object frame ``(c - pos) @ rot``, kept within ``[lo, hi]`` (3,) [m].

    Returns (k,) int64 indices and their (k, 3) object-frame coordinates.
    """
    m = centroids.shape[0]
    idx = np.empty(m, np.int64)
    q = np.empty((m, 3))
    k = 0
    for i in range(m):
        x = centroids[i, 0] - pos[0]
        y = centroids[i, 1] - pos[1]
        z = centroids[i, 2] - pos[2]
        a = x * rot[0, 0] + y * rot[1, 0] + z * rot[2, 0]
        if a < lo[0] or a > hi[0]:
            continue
        b = x * rot[0, 1] + y * rot[1, 1] + z * rot[2, 1]
        if b < lo[1] or b > hi[1]:
            continue
        c = x * rot[0, 2] + y * rot[1, 2] + z * rot[2, 2]
        if c < lo[2] or c > hi[2]:
            continue
        idx[k] = i
        q[k, 0] = a
        q[k, 1] = b
        q[k, 2] = c
        k += 1
    return idx[:k], q[:k]


@jit
def _inside_planes_kernel(q, normals, offsets):
    """(k,) bool: points ``q`` (k, 3) strictly below every plane ``normals . x = offsets``."""
    out = np.empty(q.shape[0], np.bool_)
    for i in range(q.shape[0]):
        inside = True
        for f in range(normals.shape[0]):
            if q[i, 0] * normals[f, 0] + q[i, 1] * normals[f, 1] + q[i, 2] * normals[f, 2] >= offsets[f]:
                inside = False
                break
        out[i] = inside
    return out


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
    return object_box_at_pose(obj.pose_at(t), obj.geometry.bounds, mesh_to_world)


def object_box_at_pose(pose, local_bounds, mesh_to_world=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`object_box_in_mesh_frame` of an object at ``pose`` (object -> world) whose own box
    is ``local_bounds`` (2, 3) [m]: (bounds (2, 3) [m], extent (3,) [m], rotation (3, 3))."""
    local = np.asarray(local_bounds, float)
    rot, pos = np.asarray(pose.rotation), np.asarray(pose.position)
    if mesh_to_world is not None:
        rm = np.asarray(mesh_to_world.rotation)
        rot, pos = rm.T @ rot, rm.T @ (pos - np.asarray(mesh_to_world.position))
    return _transformed_box(local, rot, pos), local[1] - local[0], rot


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
