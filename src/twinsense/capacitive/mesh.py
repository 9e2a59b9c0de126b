"""Simplex meshes for the electrostatic FEM.

The default mesher is permissive and dependency-free: a graded tensor-product
grid whose grid lines pass through every electrode edge and layer interface,
triangulated in the x-y plane and extruded along z into triangular prisms, each
prism split into three tetrahedra. Because electrode edges and planes are grid
lines, planar rectilinear layouts (stripes, pads, combs) are embedded exactly;
circular features are embedded exactly by the polar grid (:func:`polar_grid_2d`)
and spheres by the spherical shell mesh (:func:`spherical_shell_mesh`).

Prisms are split with the minimum-global-index rule (Dompierre et al., "How to
subdivide pyramids, prisms and hexahedra into tetrahedra", IMR 1999): every
quadrilateral face is cut along the diagonal through its smallest node index,
which both neighbours agree on, so the tetrahedral mesh is conforming for any
2-D triangulation and any layering.
"""

from __future__ import annotations

import hashlib
import itertools
import os
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from twinsense.errors import ConfigError

__all__ = [
    "MESHERS",
    "MeshSettings",
    "SimplexMesh",
    "cache_dir",
    "cached_mesh",
    "check_disjoint",
    "extruded_mesh",
    "graded_axis",
    "polar_grid_2d",
    "prisms_to_tets",
    "rect_grid_2d",
    "spherical_shell_mesh",
    "tensor_tet_mesh",
]


@dataclass(frozen=True, eq=False)
class SimplexMesh:
    """A conforming simplex mesh (triangles in 2-D, tetrahedra in 3-D).

    Attributes
    ----------
    points : (n, d) float
        Node coordinates [m], d = 2 or 3.
    cells : (m, d + 1) int64
        Node indices of each simplex, positively oriented.
    """

    points: np.ndarray
    cells: np.ndarray

    def __post_init__(self) -> None:
        points = np.ascontiguousarray(self.points, dtype=float)
        cells = np.ascontiguousarray(self.cells, dtype=np.int64)
        if points.ndim != 2 or points.shape[1] not in (2, 3):
            raise ConfigError("SimplexMesh.points", f"array of shape {points.shape}", "(n, 2) or (n, 3)")
        d = points.shape[1]
        if cells.ndim != 2 or cells.shape[1] != d + 1 or len(cells) == 0:
            raise ConfigError("SimplexMesh.cells", f"array of shape {cells.shape}", f"(m, {d + 1}), m > 0")
        points.setflags(write=False)
        cells.setflags(write=False)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "cells", cells)

    @property
    def dim(self) -> int:
        """Spatial dimension (2 or 3)."""
        return self.points.shape[1]

    @property
    def n_nodes(self) -> int:
        return len(self.points)

    @property
    def n_cells(self) -> int:
        return len(self.cells)

    @cached_property
    def centroids(self) -> np.ndarray:
        """(m, d) cell centroids [m]."""
        return self.points[self.cells].mean(axis=1)

    @cached_property
    def volumes(self) -> np.ndarray:
        """(m,) cell volumes [m^3] (areas [m^2] in 2-D), all > 0."""
        return _signed_volumes(self.points, self.cells)

    @cached_property
    def boundary_facets(self) -> np.ndarray:
        """(k, d) node indices of the facets that belong to exactly one cell."""
        d = self.dim
        faces = np.concatenate([np.delete(self.cells, i, axis=1) for i in range(d + 1)], axis=0)
        key = np.sort(faces, axis=1)
        _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
        return faces[first[counts == 1]]

    @cached_property
    def cell_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-cell axis-aligned bounds ((m, d) min, (m, d) max) [m]."""
        p = self.points[self.cells]
        return p.min(axis=1), p.max(axis=1)

    @cached_property
    def bounds(self) -> np.ndarray:
        """(2, d) axis-aligned bounds of the whole mesh (min, max) [m]."""
        return np.vstack([self.points.min(axis=0), self.points.max(axis=0)])

    @cached_property
    def _bounds_columns(self) -> tuple[np.ndarray, ...]:
        # One contiguous array per axis and side: six 1-D comparisons are several
        # times faster than a reduction over the (m, d) rows.
        cmin, cmax = self.cell_bounds
        return tuple(np.ascontiguousarray(c[:, k]) for k in range(self.dim) for c in (cmin, cmax))

    def cells_meeting_box(self, box) -> np.ndarray:
        """(c,) int64 indices of the cells whose bounds meet ``box`` ((2, d) min/max corners [m]).

        Closed boxes: a cell touching the box counts.
        """
        b = np.asarray(box, float)
        cols = self._bounds_columns
        hit = cols[1] >= b[0, 0]
        hit &= cols[0] <= b[1, 0]
        for k in range(1, self.dim):
            hit &= cols[2 * k + 1] >= b[0, k]
            hit &= cols[2 * k] <= b[1, k]
        return np.flatnonzero(hit)

    def digest(self) -> str:
        """A hash of the node coordinates and connectivity (for caches)."""
        h = hashlib.sha256()
        h.update(self.points.tobytes())
        h.update(self.cells.tobytes())
        return h.hexdigest()[:24]


def _signed_volumes(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    d = points.shape[1]
    p = points[cells]
    edges = p[:, 1:, :] - p[:, :1, :]  # (m, d, d)
    fact = 2.0 if d == 2 else 6.0
    return np.linalg.det(edges) / fact


def _oriented(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Return ``cells`` with the last two nodes swapped where the volume is negative."""
    vol = _signed_volumes(points, cells)
    if np.any(vol == 0.0):
        raise ConfigError("mesh", "a degenerate cell (zero volume)", "cells of positive volume")
    cells = cells.copy()
    neg = vol < 0
    cells[neg, -2], cells[neg, -1] = cells[neg, -1], cells[neg, -2].copy()
    return cells


def graded_axis(
    lo: float,
    hi: float,
    features=(),
    h_min: float = 1e-3,
    h_max: float = 1e-2,
    growth: float = 1.3,
    fine_intervals=(),
    zones=(),
) -> np.ndarray:
    """Grid coordinates on [lo, hi] that contain every feature and are graded away from them.

    The target spacing is ``min(h_max, h_min + (growth - 1) * distance)``, with
    ``distance`` to the nearest feature (0 inside a fine interval), which is a
    geometric growth at rate ``growth`` per cell. Each span between consecutive
    breakpoints gets ``ceil(integral dx / spacing)`` cells placed so that every
    cell holds the same integral.

    Parameters
    ----------
    lo, hi : float
        Axis range [m], ``lo < hi``.
    features : sequence of float
        Coordinates that must be grid lines (electrode edges, interfaces) [m].
    h_min, h_max : float
        Spacing at the features and far away [m].
    growth : float
        Ratio of neighbouring cell sizes away from features (> 1).
    fine_intervals : sequence of (a, b)
        Intervals meshed at ``h_min`` throughout (curved edges that are no
        grid lines, e.g. rings off the polar grid) [m].
    zones : sequence of (a, b, h)
        Intervals meshed at spacing ``h`` or finer, grading away at ``growth``.

    Returns
    -------
    (k,) float, strictly increasing, first ``lo`` and last ``hi`` [m].
    """
    if not hi > lo:
        raise ConfigError("graded_axis.hi", hi, f"a number > lo = {lo}")
    if not (0 < h_min <= h_max):
        raise ConfigError("graded_axis.h_min", h_min, f"0 < h_min <= h_max = {h_max}")
    if not growth > 1.0:
        raise ConfigError("graded_axis.growth", growth, "a number > 1")
    feats = np.asarray([f for f in features if lo <= f <= hi], dtype=float)
    intervals = [(max(a, lo), min(b, hi)) for a, b in fine_intervals if b > lo and a < hi]
    # Features closer than a tiny fraction of h_min are the same line.
    breaks = np.unique(np.concatenate([[lo, hi], feats]))
    tol = 1e-9 * (hi - lo)
    breaks = breaks[np.concatenate([[True], np.diff(breaks) > tol])]
    breaks[-1] = hi
    anchors = feats if len(feats) else np.array([])

    sources = [(a, b, h_min) for a, b in intervals]
    sources += [(max(a, lo), min(b, hi), h) for a, b, h in zones if b > lo and a < hi]

    def spacing(x: np.ndarray) -> np.ndarray:
        size = np.full(x.shape, float(h_max))
        if len(anchors):
            dist = np.min(np.abs(x[:, None] - anchors[None, :]), axis=1)
            size = np.minimum(size, h_min + (growth - 1.0) * dist)
        for a, b, h in sources:
            dist = np.maximum(np.maximum(a - x, x - b), 0.0)
            size = np.minimum(size, h + (growth - 1.0) * dist)
        return size

    out = [np.array([breaks[0]])]
    for a, b in itertools.pairwise(breaks):
        xs = np.linspace(a, b, 2001)
        inv = 1.0 / spacing(xs)
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (inv[1:] + inv[:-1]) * np.diff(xs))])
        n = max(1, int(np.ceil(cum[-1] - 1e-9)))
        targets = np.linspace(0.0, cum[-1], n + 1)[1:]
        seg = np.interp(targets, cum, xs)
        seg[-1] = b
        out.append(seg)
    return np.concatenate(out)


def rect_grid_2d(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate the tensor grid ``x`` by ``y``.

    Returns
    -------
    points : (len(x) * len(y), 2) float, node (i, j) at index ``i * len(y) + j``.
    triangles : (2 * (len(x) - 1) * (len(y) - 1), 3) int64.
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    nx, ny = len(x), len(y)
    X, Y = np.meshgrid(x, y, indexing="ij")
    points = np.column_stack([X.ravel(), Y.ravel()])
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    n00 = (i * ny + j).ravel()
    n10, n01, n11 = n00 + ny, n00 + 1, n00 + ny + 1
    tris = np.concatenate([np.column_stack([n00, n10, n11]), np.column_stack([n00, n11, n01])])
    return points, tris


def polar_grid_2d(radii) -> tuple[np.ndarray, np.ndarray]:
    """A triangulated disk whose grid rings are exact circles of the given radii.

    A tensor grid with coordinates ``±radii`` is mapped ring by ring: the square
    of max-norm ``r`` goes onto the circle of radius ``r``. Every radius is then
    a polygonal circle of the mesh (disk electrodes, rings, round domains), and
    the lines x = 0 and y = 0 stay straight grid lines. Each quad is cut along
    its radial diagonal so no triangle has three nodes on one circle.

    Parameters
    ----------
    radii : (k,) float
        Strictly increasing radii starting at 0 [m].

    Returns
    -------
    points : (n, 2) float [m]; triangles : (m, 3) int64.
    """
    r = np.asarray(radii, float)
    if r.ndim != 1 or len(r) < 2 or r[0] != 0.0 or np.any(np.diff(r) <= 0):
        raise ConfigError("polar_grid_2d.radii", r, "strictly increasing radii starting at 0")
    c = np.concatenate([-r[:0:-1], r])
    n = len(c)
    U, V = np.meshgrid(c, c, indexing="ij")
    u, v = U.ravel(), V.ravel()
    rho = np.maximum(np.abs(u), np.abs(v))
    norm = np.hypot(u, v)
    scale = np.divide(rho, norm, out=np.zeros_like(rho), where=norm > 0)
    points = np.column_stack([u * scale, v * scale])
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    n00 = (i * n + j).ravel()
    n10, n01, n11 = n00 + n, n00 + 1, n00 + n + 1
    # Radial diagonal: from the corner nearest the centre to the farthest one.
    uc = 0.5 * (c[i] + c[i + 1]).ravel()
    vc = 0.5 * (c[j] + c[j + 1]).ravel()
    same = (uc * vc) > 0  # quadrants I and III: diagonal n00-n11, else n10-n01
    t1 = np.where(same[:, None], np.column_stack([n00, n10, n11]), np.column_stack([n00, n10, n01]))
    t2 = np.where(same[:, None], np.column_stack([n00, n11, n01]), np.column_stack([n10, n11, n01]))
    tris = np.concatenate([t1, t2])
    return points, _oriented(points, tris)


def prisms_to_tets(bottom: np.ndarray, top: np.ndarray) -> np.ndarray:
    """Split triangular prisms into tetrahedra with the minimum-index rule.

    Parameters
    ----------
    bottom, top : (m, 3) int
        Node indices of the bottom triangle and of the nodes above them.

    Returns
    -------
    (3 m, 4) int64 tetrahedra (orientation not yet fixed).
    """
    pr = np.concatenate([np.asarray(bottom), np.asarray(top)], axis=1).astype(np.int64)
    m = len(pr)
    amin = np.argmin(pr, axis=1)
    # Put the minimum node at the bottom: flip top/bottom where it is on top.
    flip = amin >= 3
    pr[flip] = pr[flip][:, [3, 4, 5, 0, 1, 2]]
    amin = np.where(flip, amin - 3, amin)
    # Rotate the triangles so the minimum node is first (a).
    rows = np.arange(m)[:, None]
    rot = (amin[:, None] + np.arange(3)[None, :]) % 3
    pr = np.concatenate([pr[rows, rot], pr[rows, rot + 3]], axis=1)
    a, b, c, d, e, f = pr.T
    bf = np.minimum(b, f) < np.minimum(c, e)
    t1 = np.where(bf[:, None], np.column_stack([a, b, c, f]), np.column_stack([a, b, c, e]))
    t2 = np.where(bf[:, None], np.column_stack([a, b, f, e]), np.column_stack([a, e, c, f]))
    t3 = np.column_stack([a, e, f, d])
    return np.concatenate([t1, t2, t3])


def extruded_mesh(points2d: np.ndarray, triangles: np.ndarray, z) -> SimplexMesh:
    """Extrude a 2-D triangulation along z into a tetrahedral mesh.

    Parameters
    ----------
    points2d : (n, 2) float [m]
    triangles : (m, 3) int
    z : (k,) float, strictly increasing layer heights [m].

    Returns
    -------
    SimplexMesh with ``n * k`` nodes (node ``p`` of layer ``l`` at ``l * n + p``)
    and ``3 m (k - 1)`` tetrahedra.
    """
    z = np.asarray(z, float)
    if z.ndim != 1 or len(z) < 2 or np.any(np.diff(z) <= 0):
        raise ConfigError("extruded_mesh.z", z, "at least 2 strictly increasing heights")
    n = len(points2d)
    pts = np.column_stack([np.tile(points2d, (len(z), 1)), np.repeat(z, n)])
    tri = np.asarray(triangles, np.int64)
    layers = np.arange(len(z) - 1)[:, None, None] * n
    bottom = (tri[None, :, :] + layers).reshape(-1, 3)
    tets = prisms_to_tets(bottom, bottom + n)
    return SimplexMesh(pts, _oriented(pts, tets))


def tensor_tet_mesh(x, y, z) -> SimplexMesh:
    """Tetrahedral mesh of the box grid ``x`` by ``y`` by ``z`` (6 tets per cell)."""
    p2, tri = rect_grid_2d(x, y)
    return extruded_mesh(p2, tri, z)


def spherical_shell_mesh(radii, subdivisions: int = 2) -> SimplexMesh:
    """Tetrahedral mesh of the shell between concentric spheres at the origin.

    The surfaces are icospheres (all nodes on the exact spheres), layered at
    the given radii, each layer of prisms split into tetrahedra.

    Parameters
    ----------
    radii : (k,) float
        Strictly increasing shell radii [m], k >= 2.
    subdivisions : int
        Icosphere subdivisions (20 * 4**s triangles per sphere).
    """
    import trimesh

    r = np.asarray(radii, float)
    if r.ndim != 1 or len(r) < 2 or r[0] <= 0 or np.any(np.diff(r) <= 0):
        raise ConfigError("spherical_shell_mesh.radii", r, "at least 2 strictly increasing radii > 0")
    ico = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    v = np.asarray(ico.vertices, float)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    f = np.asarray(ico.faces, np.int64)
    n = len(v)
    pts = (r[:, None, None] * v[None, :, :]).reshape(-1, 3)
    layers = np.arange(len(r) - 1)[:, None, None] * n
    bottom = (f[None, :, :] + layers).reshape(-1, 3)
    tets = prisms_to_tets(bottom, bottom + n)
    return SimplexMesh(pts, _oriented(pts, tets))


def cache_dir() -> Path:
    """Directory of the on-disk mesh cache (``$TWINSENSE_CACHE_DIR`` or ``~/.cache/twinsense``)."""
    root = os.environ.get("TWINSENSE_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "twinsense")
    return Path(root) / "capacitive-mesh"


def cached_mesh(key: str, build, *, use_cache: bool = True) -> SimplexMesh:
    """Return the mesh stored under ``key`` or build, store and return it.

    Parameters
    ----------
    key : str
        A description of every input of ``build`` (hashed into the file name).
    build : callable () -> SimplexMesh
    use_cache : bool
        False builds without reading or writing the cache.
    """
    if not use_cache:
        return build()
    digest = hashlib.sha256(key.encode()).hexdigest()[:32]
    path = cache_dir() / f"{digest}.npz"
    if path.exists():
        try:
            with np.load(path) as data:
                return SimplexMesh(data["points"], data["cells"])
        except (OSError, ValueError, KeyError):
            pass  # a broken cache entry is rebuilt below
    mesh = build()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, points=mesh.points, cells=mesh.cells)
        os.replace(tmp, path)
    except OSError:
        pass  # a read-only home only costs the rebuild next time
    return mesh


MESHERS = ("grid", "gmsh")
"""Layout meshers: the graded tensor grid (default, permissive) or gmsh (optional, GPL)."""


@dataclass(frozen=True)
class MeshSettings:
    """Mesher choice and size settings of the layout mesh.

    Both meshers read the same sizes: ``h_min`` at electrode edges, growing
    at ``growth`` away from them up to ``h_max``, at most ``h_refine`` in the
    refine boxes.

    Attributes
    ----------
    margin : float
        Air beyond the layout's extent in x and y [m].
    height : float
        Air above the highest electrode [m].
    depth : float
        Air below the lowest electrode or substrate bottom [m].
    h_min : float
        Cell size at electrode edges and the electrode plane [m].
    h_max : float
        Largest cell size [m].
    growth : float
        Size ratio of neighbouring cells away from features (> 1).
    refine : tuple of (6,), (7,) or (9,) tuples
        Boxes (x_min, x_max, y_min, y_max, z_min, z_max) [m] meshed at
        ``h_refine``, or at their own cell size given as a 7th value (h) or
        as 7th to 9th values (h_x, h_y, h_z, per mesh axis) [m].
        :meth:`CapacitiveSensor.prepare` adds the boxes that resolve the
        scene's objects (see ``object_cells``).
    h_refine : float
        Cell size inside the refine boxes that give none of their own [m].
    object_cells : float
        Cells across each scene object where a prepared run places it: the
        cell size along mesh axis k is min over the object's own axes j of
        extent_j / object_cells / abs(cos(angle(k, j))), at most ``h_max``.
        0 turns the automatic refinement off. The error of a grounded
        object's effect is first order in the cell size (staircased
        conductors): at 6 a neighbour sphere's +7.2 % rise comes out at
        +9.5..9.9 %, and doubling ``object_cells`` with ``h_min`` halves the
        excess (docs/capacitive-accuracy.md).
    region : (6,) tuple or None
        Explicit mesh box (x_min, x_max, y_min, y_max, z_min, z_max) [m];
        overrides margin, height and depth.
    use_cache : bool
        Read and write the on-disk cache.
    mesher : {"grid", "gmsh"}
        ``"grid"``: graded tensor grid split into tetrahedra (rectilinear
        outlines exact, curved ones staircased). ``"gmsh"``: unstructured
        tetrahedra with every electrode polygon embedded exactly (needs the
        optional gmsh package, see :mod:`twinsense.capacitive.gmsh_mesher`).
    """

    margin: float = 0.02
    height: float = 0.04
    depth: float = 0.01
    h_min: float = 1e-3
    h_max: float = 8e-3
    growth: float = 1.3
    refine: tuple = ()
    h_refine: float = 4e-3
    region: tuple | None = None
    use_cache: bool = True
    mesher: str = "grid"
    object_cells: float = 6.0

    def __post_init__(self) -> None:
        from twinsense import validation as v

        v.choice("MeshSettings.mesher", self.mesher, MESHERS)

        v.non_negative("MeshSettings.margin", self.margin, "m")
        v.positive("MeshSettings.height", self.height, "m")
        v.non_negative("MeshSettings.depth", self.depth, "m")
        v.positive("MeshSettings.h_min", self.h_min, "m")
        v.number("MeshSettings.h_max", self.h_max, lo=self.h_min, unit="m (>= h_min)")
        v.number("MeshSettings.growth", self.growth, lo=1.0, lo_open=True)
        v.positive("MeshSettings.h_refine", self.h_refine, "m")
        v.non_negative("MeshSettings.object_cells", self.object_cells, "cells across an object (0: off)")
        boxes = []
        for i, b in enumerate(self.refine):
            field_name = f"MeshSettings.refine[{i}]"
            n = len(b) if isinstance(b, (tuple, list, np.ndarray)) else 0
            if n not in (6, 7, 9):
                raise ConfigError(field_name, b, "6 box bounds [m], optionally followed by h or (h_x, h_y, h_z) [m]")
            arr = v.vector(field_name, b, n, "m")
            if not (arr[1] > arr[0] and arr[3] > arr[2] and arr[5] > arr[4]):
                raise ConfigError(field_name, b, "a box with min < max on every axis")
            if np.any(arr[6:] <= 0):
                raise ConfigError(field_name, b, "cell sizes > 0 [m] after the 6 box bounds")
            boxes.append(tuple(float(x) for x in arr))
        object.__setattr__(self, "refine", tuple(boxes))
        if self.region is not None:
            r = v.vector("MeshSettings.region", self.region, 6, "m")
            if not (r[1] > r[0] and r[3] > r[2] and r[5] > r[4]):
                raise ConfigError("MeshSettings.region", self.region, "a box with min < max on every axis")
            object.__setattr__(self, "region", tuple(float(x) for x in r))

    def refine_zones(self) -> tuple:
        """The refine boxes with their cell sizes: ((box (6,), (h_x, h_y, h_z)), ...) [m]."""
        out = []
        for b in self.refine:
            sizes = b[6:] if len(b) == 9 else (b[6],) * 3 if len(b) == 7 else (self.h_refine,) * 3
            out.append((b[:6], tuple(sizes)))
        return tuple(out)


def check_disjoint(sets: Sequence[np.ndarray], names: Sequence[str], field: str) -> None:
    """Raise ConfigError if two terminal node sets share a node (overlapping or touching)."""
    owner = {}
    for i, nodes in enumerate(sets):
        for node in np.asarray(nodes).tolist():
            k = owner.setdefault(node, i)
            if k != i:
                raise ConfigError(
                    f"{field}[{i}]",
                    names[i],
                    f"an electrode that neither overlaps nor touches {names[k]!r}",
                )
