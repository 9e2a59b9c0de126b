"""Mesh files of robot descriptions, read through trimesh and merged into one mesh per link, whose inside
test is its parts' own (:class:`PartsMesh`).

COLLADA (.dae) files declare their length unit (``<unit meter="0.001"/>``);
trimesh reads the vertices as stored and only notes the unit, so the scale is
applied here. STL and OBJ carry no unit: robot descriptions store them in
metres, and a URDF ``scale`` attribute converts any other unit.
"""

from __future__ import annotations

import functools
import io
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, QhullError, cKDTree

from twinsense.errors import ConfigError, GeometryError
from twinsense.inputs import note_input
from twinsense.scene.geometry import WINDING_MAX_PAIRS, Geometry, TriangleMesh, ray_parity_contains, winding_inside
from twinsense.scene.pose import Pose


def dae_unit(path: Path) -> float:
    """Metres per length unit declared by a COLLADA file (1 when it declares none).

    The unit is the ``<unit meter=...>`` of the document's own ``<asset>`` (the root's first child), as
    pycollada's ``Collada.assetInfo.unitmeter`` reads it: either quote, after any length of comments, and
    not an ``<asset>`` of a node or geometry further down (those describe that element only).
    """
    depth = 0
    for event, el in ET.iterparse(str(path), events=("start", "end")):
        if event == "end":
            if depth == 2:  # the end of the root's first child: no unit in it
                return 1.0
            depth -= 1
            continue
        depth += 1
        tag = el.tag.rpartition("}")[2]
        if depth == 2 and tag != "asset":
            return 1.0
        if depth == 3 and tag == "unit":
            text = el.get("meter")
            if text is None:
                return 1.0
            try:
                meter = float(text)
            except ValueError:
                meter = math.nan
            if not (math.isfinite(meter) and meter > 0.0):
                raise ValueError(f"its <unit meter={text!r}> is not a positive number of metres")
            return meter
    return 1.0


_BIND_MATERIAL = re.compile(rb"<bind_material>.*?</bind_material>", re.S)


def _load(path: str) -> trimesh.Trimesh:
    loaded = trimesh.load(path, force="mesh", process=False)
    if path.lower().endswith(".dae") and len(loaded.faces) == 0:
        # pycollada drops a node's whole <instance_geometry> when one of its material
        # bindings names a missing effect or texture (Blender exports do), so the file
        # reads as empty. The link's material is twinsense's own: read the file again
        # without the bindings (the geometry and node transforms are untouched).
        with open(path, "rb") as fh:
            data = _BIND_MATERIAL.sub(b"", fh.read())
        loaded = trimesh.load(io.BytesIO(data), file_type="dae", force="mesh", process=False)
    return loaded


@functools.lru_cache(maxsize=128)
def _read(path: str, mtime: float) -> tuple[np.ndarray, np.ndarray]:
    loaded = _load(path)
    v = np.asarray(loaded.vertices, dtype=float)
    f = np.asarray(loaded.faces, dtype=np.int64)
    if path.lower().endswith(".dae"):
        v = v * dae_unit(Path(path))
    v.setflags(write=False)
    f.setflags(write=False)
    return v, f


def read_mesh(path: Path, field_name: str, link: str, written: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) [m, before any URDF scale] and faces (m, 3) of a mesh file; ConfigError naming the link.

    ``written``: the reference as the description writes it (shown in full: a long path may be shortened).
    """
    if not path.is_file():
        ref = f" ({written!r} in the description, resolved to {str(path)!r})" if written else f" ({str(path)!r})"
        if written and written.startswith("package://"):
            pkg = written[len("package://"):].lstrip("/").partition("/")[0]
            ref += (f"; package {pkg!r} is looked up in packages={{{pkg!r}: folder}}, then example-robot-data, "
                    f"then a folder named {pkg!r} beside or above the description")
        raise ConfigError(field_name, str(path), f"an existing mesh file for link {link!r}{ref}")
    note_input(path)
    try:
        v, f = _read(str(path), path.stat().st_mtime)
    except Exception as exc:  # trimesh raises many types for damaged or unsupported files
        raise ConfigError(field_name, str(path), f"a readable mesh file for link {link!r} ({type(exc).__name__}: "
                          f"{exc})") from None
    if len(f) == 0 or not np.all(np.isfinite(v)):
        raise ConfigError(field_name, str(path), f"a mesh file with triangles and finite vertices for link {link!r}")
    return v, f


#: Open meshes of one link whose bounding boxes come this close [m] are hulled together (see PartsMesh).
OPEN_MESH_GAP = 1e-3
#: Vertices of touching open meshes this close [m] are one when checking whether they close together: far
#: above the rounding of float32 mesh data (MuJoCo compiles meshes to float32 and re-centres each: a shared
#: seam then differs by ~1e-8 m at 0.2 m), far below any feature of a robot's shell.
WELD_TOLERANCE = 1e-6


@dataclass(frozen=True, eq=False)
class MeshVolume:
    """A mesh part, vertices (n, 3) [m] and faces (m, 3) in the part frame; its inside test is the mesh's
    own (winding number) when it is closed (:attr:`closed`); an open one is hulled by :class:`PartsMesh`,
    together with the open parts it touches."""

    vertices: np.ndarray
    faces: np.ndarray

    @functools.cached_property
    def closed(self) -> TriangleMesh | None:
        """The mesh when it is closed (watertight), else None."""
        try:
            mesh = TriangleMesh(self.vertices, self.faces, name="mesh part")
            return mesh if mesh.mesh.is_watertight else None
        except GeometryError:  # degenerate triangles only: an open mesh
            return None

    @functools.cached_property
    def _triangles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The closed mesh's corners (m, 3, 3) [m] and its box's lower and upper corners (3,) [m]."""
        m = self.closed.mesh
        return (np.ascontiguousarray(m.triangles, dtype=float), np.asarray(m.bounds[0], float).copy(),
                np.asarray(m.bounds[1], float).copy())

    def contains(self, points) -> np.ndarray:
        p = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 3))
        tri, lo, hi = self._triangles
        if len(p) * len(tri) > WINDING_MAX_PAIRS:  # linear in the points: ray parity
            return ray_parity_contains(self.closed.mesh, p)
        return winding_inside(p, tri, lo, hi)


@dataclass(frozen=True, eq=False)
class PartsMesh(TriangleMesh):
    """Parts (a link's visuals, a body's geoms) merged into one triangle mesh in the link frame (what rays
    see), whose inside test is the parts' own: a point is inside when it lies inside one of them.

    ``solids``: ((inside test in the part frame, part -> link pose), ...) of the parts with a volume:
    primitives exactly, closed meshes (:class:`MeshVolume`) by their winding number; open meshes (vendor
    display meshes often are: shells that close only together) by the convex hull of each group of them
    that touch (bounding boxes within OPEN_MESH_GAP), or, when a group closes together (its merged mesh,
    vertices within WELD_TOLERANCE made one, is watertight), by that mesh's winding number. Separate parts
    keep the air between them outside, and a closed concave part its concavity. ``()``: no part has a
    volume (nothing is inside); None: the whole mesh is one part.
    """

    solids: tuple | None = None

    @functools.cached_property
    def _tests(self) -> tuple[tuple, tuple]:
        """((inside test, part -> link pose), ...) of the exact solids and ((facets (k, 4), lower (3,), upper
        (3,)), ...) of the open meshes' hulls in the link frame: outward unit normals and offsets, and the
        hull's box. Arrays and geometries only, no closures: a scene is copied by pickle."""
        if self.solids is None:  # one part, the whole mesh (contains tests a closed one itself)
            return (), _hull_facets([self.vertices])
        exact, parts = [], []
        for solid, pose in self.solids:
            if isinstance(solid, MeshVolume) and solid.closed is None:
                parts.append((pose.apply(solid.vertices), solid.faces))
            else:
                exact.append((solid, pose))
        hulls = []
        for group in _touching([(v.min(axis=0), v.max(axis=0)) for v, _ in parts], OPEN_MESH_GAP):
            if len(group) > 1:
                together = MeshVolume(*_weld(*stack_parts([(*parts[i], Pose()) for i in group]), WELD_TOLERANCE))
                if together.closed is not None:
                    exact.append((together, Pose()))
                    continue
            hulls += _hull_facets([parts[i][0] for i in group])
        return tuple(exact), tuple(hulls)

    def contains(self, points):
        if self.solids is None and self.mesh.is_watertight:
            return super().contains(points)
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        exact, hulls = self._tests
        # Inside a hull: on the inner side of every facet plane (n . p + d <= 0), to rounding.
        out = np.zeros(len(p), dtype=bool)
        for eq, lo, hi in hulls:
            # Only points in the hull's box (padded far beyond the 1e-12 m above) meet its facets' test.
            cand = np.flatnonzero(np.all((p >= lo) & (p <= hi), axis=1))
            out[cand] |= np.all(p[cand] @ eq[:, :3].T + eq[:, 3] <= 1e-12, axis=1)
        for solid, pose in exact:
            rest = np.flatnonzero(~out)
            if len(rest) == 0:
                break
            # Link -> part frame: R^T (p - t), written as a row product.
            out[rest] = solid.contains((p[rest] - pose.position) @ pose.rotation)
        return out


def _weld(vertices: np.ndarray, faces: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The mesh with vertices within ``tol`` [m] of each other (chains of them) made one, at their first
    one's place, and the faces that become degenerate left out: (vertices (k, 3) [m], faces (j, 3))."""
    pairs = cKDTree(vertices).query_pairs(tol, output_type="ndarray")
    n = len(vertices)
    _, label = connected_components(coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)),
                                    directed=False)
    first = np.full(label.max() + 1, n)
    np.minimum.at(first, label, np.arange(n))
    f = first[label][faces]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    return vertices, f[keep]


def _hull_facets(vertices: list[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """[((n_facets, 4) outward unit normals and offsets of the convex hull of the stacked vertices [m], its
    box's lower and upper corners (3,) [m] padded by 1 nm)], or [] when they span no volume (all in one
    plane, or fewer than four)."""
    v = np.vstack(vertices)
    try:
        eq = np.asarray(ConvexHull(v).equations, dtype=float)
    except QhullError:
        return []
    return [(eq, v.min(axis=0) - 1e-9, v.max(axis=0) + 1e-9)]


def _touching(boxes: list[tuple[np.ndarray, np.ndarray]], gap: float) -> list[list[int]]:
    """Groups of the boxes (lower (3,), upper (3,) corners [m]) linked by boxes within ``gap`` of each other."""
    group = list(range(len(boxes)))

    def root(i: int) -> int:
        while group[i] != i:
            i = group[i]
        return i

    for i, (lo_i, hi_i) in enumerate(boxes):
        for j in range(i):
            lo_j, hi_j = boxes[j]
            if np.all(lo_i <= hi_j + gap) and np.all(lo_j <= hi_i + gap):
                group[root(i)] = root(j)
    out: dict[int, list[int]] = {}
    for i in range(len(boxes)):
        out.setdefault(root(i), []).append(i)
    return list(out.values())


@dataclass(frozen=True, eq=False)
class LinkMesh(PartsMesh):
    """A URDF link's visuals (or collisions) merged into one mesh, with the parts' own inside test
    (:class:`PartsMesh`): boxes, cylinders and spheres exactly, closed mesh files by their winding number,
    open ones (vendor display meshes: seams, open caps) by the hull of the open meshes they touch, which
    for an arm link's shell (tubes between joint housings) adds the concave gaps between housings and is
    the volume a capacitive or inductive sensor sees first. Without ``solids`` the mesh is one part.
    """


def stack_parts(parts: list[tuple[np.ndarray, np.ndarray, Pose]]) -> tuple[np.ndarray, np.ndarray]:
    """Parts (vertices (n, 3), faces (m, 3), part -> link pose), at least one, as one vertex array [m] in the
    link frame and one face array indexing it."""
    verts, faces, off = [], [], 0
    for v, f, pose in parts:
        verts.append(pose.apply(v))
        faces.append(np.asarray(f) + off)
        off += len(v)
    return np.vstack(verts), np.vstack(faces)


def merge(parts: list[tuple[np.ndarray, np.ndarray, Pose, Geometry | None]], name: str) -> Geometry | None:
    """One LinkMesh from parts (vertices (n, 3), faces (m, 3), part -> link pose, the part's exact geometry:
    a primitive, or None for a mesh part, whose volume its vertices and faces are); None if no parts.

    A single mesh part is the link's whole mesh (its own inside test, no second copy of it); otherwise each
    part keeps its own (see :class:`PartsMesh`).
    """
    if not parts:
        return None
    v, f = stack_parts([part[:3] for part in parts])
    if len(parts) == 1 and parts[0][3] is None:
        return LinkMesh(v, f, name=name)
    solids = tuple((MeshVolume(pv, pf) if solid is None else solid, pose) for pv, pf, pose, solid in parts)
    return LinkMesh(v, f, name=name, solids=solids)


def primitive_mesh(geometry: Geometry) -> tuple[np.ndarray, np.ndarray]:
    m = geometry.mesh
    return np.asarray(m.vertices, dtype=float), np.asarray(m.faces, dtype=np.int64)
