"""Object geometry in its local frame, in metres.

Primitives carry exact inside tests (the capacitive coupling needs them) and a
triangle mesh for ray casting. Mesh files are read through trimesh with an
explicit length unit, so a model in millimetres never silently becomes metres.

Every size (box edges, radii, heights, plane sides, the largest extent of a
mesh) lies in [1 um, 10 km] (``validation.LENGTH_MIN`` .. ``LENGTH_MAX``);
outside it trimesh's builders return NaN vertices or lose every triangle.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from twinsense import validation as V
from twinsense.compiled import jit
from twinsense.errors import ConfigError, GeometryError
from twinsense.inputs import note_input

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
MAX_SECTIONS = 4096  # cylinder facets: beyond this the mesh only costs memory
MESH_SUFFIXES = (".obj", ".stl", ".ply", ".gltf", ".glb", ".off")


class Geometry:
    """Base class: ``mesh`` (trimesh, local frame, metres) and ``contains``."""

    kind: str = "geometry"

    @functools.cached_property
    def mesh(self) -> trimesh.Trimesh:
        m = self._build_mesh()
        m.vertices.flags.writeable = False
        return m

    def _build_mesh(self) -> trimesh.Trimesh:  # pragma: no cover - abstract
        raise NotImplementedError

    def contains(self, points) -> np.ndarray:
        """Inside test for points (n, 3) in the local frame -> bool (n,)."""
        raise NotImplementedError

    @functools.cached_property
    def bounds(self) -> np.ndarray:
        """Axis-aligned bounds (2, 3) in the local frame [m] (read-only).

        Kept: the mesh's vertices are read-only, and trimesh checks its own cache by hashing the
        arrays at every call (sensors ask for every object's bounds at every frame).
        """
        b = np.array(self.mesh.bounds, dtype=float)
        b.setflags(write=False)
        return b

    def to_dict(self) -> dict:
        raise NotImplementedError


def _scaled(unit_mesh: trimesh.Trimesh, scale: float) -> trimesh.Trimesh:
    """A primitive built at radius 1 and scaled to ``scale`` [m].

    trimesh merges vertices closer than 1e-8 and drops triangles of area under
    ~1e-12 while it builds, in absolute units: a cylinder of radius 1 um would
    lose every face. Built at unit size the mesh keeps them all.
    """
    return trimesh.Trimesh(unit_mesh.vertices * scale, unit_mesh.faces, process=False)


def _sizes(field_name: str, value, n: int) -> np.ndarray:
    """``n`` edge lengths, each within [LENGTH_MIN, LENGTH_MAX] [m]."""
    allowed = f"{n} edge lengths, each in [{V.LENGTH_MIN:g}, {V.LENGTH_MAX:g}] [m]"
    s = V.vector(field_name, value, n, "m")
    if np.any(s < V.LENGTH_MIN) or np.any(s > V.LENGTH_MAX):
        raise ConfigError(field_name, s.tolist(), allowed)
    return s


def _check_extent(field_name: str, vertices: np.ndarray, unit_note: str = "") -> None:
    """Refuse a mesh whose largest bounding-box edge lies outside [LENGTH_MIN, LENGTH_MAX]."""
    with np.errstate(over="ignore", invalid="ignore"):
        extent = float(np.max(np.ptp(vertices, axis=0))) if len(vertices) else 0.0
    if not (V.LENGTH_MIN <= extent <= V.LENGTH_MAX):
        raise GeometryError(f"{field_name}: largest extent {extent:.6g} m{unit_note} is outside the allowed "
                            f"[{V.LENGTH_MIN:g}, {V.LENGTH_MAX:g}] m (check the unit)")


def _faces(field_name: str, value) -> np.ndarray:
    """Face indices as int64; integral floats pass, fractions, NaN, text and huge ints do not."""
    allowed = "an integer array (m, 3) of vertex indices"
    try:
        raw = np.asarray(value)
        if raw.dtype.kind == "f":
            if not np.all(np.isfinite(raw)) or np.any(raw != np.round(raw)) or np.any(np.abs(raw) > 2**53):
                raise ValueError
        elif raw.dtype.kind not in "iu":
            raise TypeError
        return raw.astype(np.int64)
    except (TypeError, ValueError, OverflowError):
        raise ConfigError(field_name, value, allowed) from None


def _pts(points) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    return p.reshape(-1, 3)


@dataclass(frozen=True, eq=False)
class Box(Geometry):
    """Axis-aligned box centred on the origin; ``size`` = full edge lengths (3,) [m]."""

    size: tuple[float, float, float] = (1.0, 1.0, 1.0)
    kind = "box"

    def __post_init__(self) -> None:
        s = _sizes("box.size", self.size, 3)
        object.__setattr__(self, "size", tuple(float(x) for x in s))

    def _build_mesh(self):
        return trimesh.creation.box(extents=self.size)

    def contains(self, points):
        p = _pts(points)
        return np.all(np.abs(p) <= 0.5 * np.asarray(self.size), axis=1)

    def to_dict(self):
        return {"type": "box", "size": list(self.size)}


@dataclass(frozen=True, eq=False)
class Sphere(Geometry):
    """Sphere centred on the origin. ``subdivisions`` sets the icosphere mesh."""

    radius: float = 0.5
    subdivisions: int = 4
    kind = "sphere"

    def __post_init__(self) -> None:
        V.length("sphere.radius", self.radius)
        V.integer("sphere.subdivisions", self.subdivisions, lo=0, hi=7)

    def _build_mesh(self):
        return _scaled(trimesh.creation.icosphere(subdivisions=self.subdivisions, radius=1.0), self.radius)

    def contains(self, points):
        p = _pts(points)
        return np.einsum("ij,ij->i", p, p) <= self.radius**2

    def to_dict(self):
        return {"type": "sphere", "radius": self.radius}


@dataclass(frozen=True, eq=False)
class Cylinder(Geometry):
    """Cylinder along local z, centred on the origin; ``height`` is the full length."""

    radius: float = 0.5
    height: float = 1.0
    sections: int = 64
    kind = "cylinder"

    def __post_init__(self) -> None:
        V.length("cylinder.radius", self.radius)
        V.length("cylinder.height", self.height)
        V.integer("cylinder.sections", self.sections, lo=3, hi=MAX_SECTIONS)

    def _build_mesh(self):
        return _scaled(trimesh.creation.cylinder(radius=1.0, height=self.height / self.radius,
                                                 sections=self.sections), self.radius)

    def contains(self, points):
        p = _pts(points)
        return (p[:, 0] ** 2 + p[:, 1] ** 2 <= self.radius**2) & (np.abs(p[:, 2]) <= 0.5 * self.height)

    def to_dict(self):
        return {"type": "cylinder", "radius": self.radius, "height": self.height}


@dataclass(frozen=True, eq=False)
class Capsule(Geometry):
    """Capsule along local z: a cylinder of length ``height`` capped by hemispheres."""

    radius: float = 0.25
    height: float = 1.0
    kind = "capsule"

    def __post_init__(self) -> None:
        V.length("capsule.radius", self.radius)
        # height 0 is a sphere; otherwise the cylinder part is a size like any other.
        if V.non_negative("capsule.height", self.height, "m") != 0.0:
            V.number("capsule.height", self.height, lo=V.LENGTH_MIN, hi=V.LENGTH_MAX,
                     unit="m; or 0 for a sphere")

    def _build_mesh(self):
        return _scaled(trimesh.creation.capsule(height=self.height / self.radius, radius=1.0, count=[32, 32]),
                       self.radius)

    def contains(self, points):
        p = _pts(points)
        z = np.clip(p[:, 2], -0.5 * self.height, 0.5 * self.height)
        return p[:, 0] ** 2 + p[:, 1] ** 2 + (p[:, 2] - z) ** 2 <= self.radius**2

    def to_dict(self):
        return {"type": "capsule", "radius": self.radius, "height": self.height}


@dataclass(frozen=True, eq=False)
class Plane(Geometry):
    """Finite plane (rectangle) in local z = 0, normal +z, ``size`` = (sx, sy) [m].

    It has no volume, so nothing is inside it.
    """

    size: tuple[float, float] = (10.0, 10.0)
    kind = "plane"

    def __post_init__(self) -> None:
        s = _sizes("plane.size", self.size, 2)
        object.__setattr__(self, "size", tuple(float(x) for x in s))

    def _build_mesh(self):
        hx, hy = 0.5 * self.size[0], 0.5 * self.size[1]
        v = np.array([[-hx, -hy, 0], [hx, -hy, 0], [hx, hy, 0], [-hx, hy, 0]], dtype=float)
        f = np.array([[0, 1, 2], [0, 2, 3]])
        return trimesh.Trimesh(v, f, process=False)

    def contains(self, points):
        return np.zeros(len(_pts(points)), dtype=bool)

    def to_dict(self):
        return {"type": "plane", "size": list(self.size)}


@dataclass(frozen=True, eq=False)
class TriangleMesh(Geometry):
    """A mesh given as arrays: vertices (n, 3) [m] and faces (m, 3) int."""

    vertices: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    faces: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=int))
    name: str = "mesh"
    kind = "mesh"

    def __post_init__(self) -> None:
        v = V.array(f"{self.name}.vertices", self.vertices, (None, 3), "m")
        f = _faces(f"{self.name}.faces", self.faces)
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise GeometryError(f"{self.name}: faces must be a non-empty (m, 3) integer array, got shape {f.shape}")
        if f.min() < 0 or f.max() >= len(v):
            raise GeometryError(f"{self.name}: face indices must lie in 0..{len(v) - 1}, "
                                f"got {f.min()}..{f.max()}")
        _check_extent(f"{self.name}.vertices", v[np.unique(f)])
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)

    def _build_mesh(self):
        m = trimesh.Trimesh(self.vertices, self.faces, process=True)
        m.remove_unreferenced_vertices()
        if len(m.faces) == 0 or not np.all(np.isfinite(m.vertices)):
            raise GeometryError(f"{self.name}: the mesh has no valid triangles")
        return m

    def contains(self, points):
        m = self.mesh
        if not m.is_watertight:
            raise GeometryError(
                f"{self.name}: inside tests need a closed (watertight) mesh; this one has open edges")
        p = _pts(points)
        return _mesh_contains(m, p)

    def to_dict(self):
        return {"type": "mesh", "name": self.name, "n_faces": len(self.faces)}


#: Ray directions of :func:`ray_parity_contains`: the first for every point, the second for the points whose
#: forward and backward parities disagree (a ray through an edge or a vertex counted a hit twice or none).
PARITY_DIRECTIONS = (np.array([0.4395064455, 0.617598629942, 0.652231566745]),
                     np.array([-0.5812381937, 0.2365148372, 0.7786407556]))


def ray_parity_contains(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """(n,) points (n, 3) inside the closed ``mesh`` by ray parity (Embree through trimesh's intersector).

    Each point casts a ray forward and backward along PARITY_DIRECTIONS[0] and counts every surface it
    crosses; an odd count is inside. Where the two counts disagree and both rays hit something (a ray
    through an edge or a vertex), the point is cast again along the second direction. trimesh's own
    ``contains`` retries those along a direction drawn from an unseeded generator, so the same points
    gave different answers from run to run (0.6772-0.6796 of a UR5's collision points inside); these
    directions are fixed: the same points, the same answer.
    """
    points = np.asarray(points, dtype=float)
    out = np.zeros(len(points), dtype=bool)
    lo, hi = mesh.bounds
    idx = np.nonzero(np.all((points >= lo) & (points <= hi), axis=1))[0]
    for k, d in enumerate(PARITY_DIRECTIONS):
        if len(idx) == 0:
            break
        p = points[idx]
        dirs = np.broadcast_to(d, p.shape)
        _, ray, _ = mesh.ray.intersects_location(np.vstack((p, p)), np.vstack((dirs, -dirs)), multiple_hits=True)
        hits = np.bincount(ray, minlength=2 * len(p)).reshape(2, -1)
        odd = hits % 2 == 1
        agree = odd[0] == odd[1]
        free = (hits == 0).any(axis=0)  # one way out hits nothing: outside, whatever the other counted
        settled = agree | free | (k == len(PARITY_DIRECTIONS) - 1)
        # Agreeing parities decide; a disagreement with a free way out (or left after both directions)
        # is outside.
        out[idx[settled]] = (odd[0] & agree)[settled]
        idx = idx[~settled]
    return out


#: Above this many point-triangle pairs a closed mesh is tested by ray parity (linear in the points), below
#: by the compiled winding number (exact, robust to grazing rays).
WINDING_MAX_PAIRS = 2e7


@jit
def winding_inside(points, tri, lo, hi):
    """Points (n, 3) [m] inside the closed mesh of corners ``tri`` (m, 3, 3) [m] in the box [lo, hi] (3,):
    |generalised winding number| > 1/2, the solid angle of each triangle by Van Oosterom and Strackee's
    formula, one point at a time (no (points x triangles) temporaries)."""
    n = points.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        if px < lo[0] or px > hi[0] or py < lo[1] or py > hi[1] or pz < lo[2] or pz > hi[2]:
            continue
        w = 0.0
        for k in range(tri.shape[0]):
            ax, ay, az = tri[k, 0, 0] - px, tri[k, 0, 1] - py, tri[k, 0, 2] - pz
            bx, by, bz = tri[k, 1, 0] - px, tri[k, 1, 1] - py, tri[k, 1, 2] - pz
            cx, cy, cz = tri[k, 2, 0] - px, tri[k, 2, 1] - py, tri[k, 2, 2] - pz
            la = np.sqrt(ax * ax + ay * ay + az * az)
            lb = np.sqrt(bx * bx + by * by + bz * bz)
            lc = np.sqrt(cx * cx + cy * cy + cz * cz)
            det = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
            den = la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (bx * cx + by * cy + bz * cz) * la \
                + (cx * ax + cy * ay + cz * az) * lb
            w += np.arctan2(det, den)
        out[i] = abs(w / (2.0 * np.pi)) > 0.5
    return out


def _mesh_contains(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Inside test for a closed mesh: the compiled generalised winding number (exact, robust to grazing
    rays) up to WINDING_MAX_PAIRS point-triangle pairs, ray parity (Embree, linear in the points) above."""
    if len(points) * len(mesh.faces) > WINDING_MAX_PAIRS:
        return ray_parity_contains(mesh, points)
    lo, hi = mesh.bounds
    return winding_inside(np.ascontiguousarray(points, dtype=float), np.ascontiguousarray(mesh.triangles, dtype=float),
                          np.asarray(lo, float).copy(), np.asarray(hi, float).copy())


@dataclass(frozen=True, eq=False)
class MeshFile(TriangleMesh):
    """A mesh read from OBJ, STL, PLY, OFF, glTF or GLB, scaled from ``unit`` to metres."""

    path: str = ""
    unit: str = "m"
    kind = "mesh_file"

    def __init__(self, path, unit: str = "m"):
        if unit not in UNITS:
            raise ConfigError("mesh.unit", unit, "one of: " + ", ".join(UNITS))
        p = Path(path)
        if p.suffix.lower() not in MESH_SUFFIXES:
            raise ConfigError("mesh.path", str(path), "a mesh file ending in " + ", ".join(MESH_SUFFIXES))
        if not p.is_file():
            raise GeometryError(f"mesh.path: file not found: {str(path)!r}")
        note_input(p)
        kind = p.suffix.lower().lstrip(".").upper()
        try:
            # Unprocessed first: merging vertices (1e-8 in file units) would hide the true extent.
            loaded = trimesh.load(p, force="mesh", process=False)
        except ImportError as exc:
            # trimesh imports some readers lazily (ASCII STL needs charset_normalizer).
            raise GeometryError(f"mesh.path: cannot read {str(path)!r}: the {kind} reader needs the missing "
                                f"package {exc.name or exc}; reinstall twinsense with its dependencies") from None
        except Exception:  # trimesh raises many types (IndexError, KeyError, ...) for damaged files
            raise GeometryError(f"mesh.path: cannot read {str(path)!r} as a mesh: it is damaged or not "
                                f"a valid {kind} file") from None
        if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
            raise GeometryError(f"mesh.path: {str(path)!r} holds no triangles")
        verts = np.asarray(loaded.vertices, dtype=float)
        faces = np.asarray(loaded.faces, dtype=np.int64)
        if not np.all(np.isfinite(verts)):
            raise GeometryError(f"mesh.path: {str(path)!r} has NaN or infinite vertex coordinates")
        if faces.min() < 0 or faces.max() >= len(verts):
            raise GeometryError(f"mesh.path: {str(path)!r} has face indices outside its {len(verts)} vertices")
        with np.errstate(over="ignore", under="ignore"):
            scaled = verts * UNITS[unit]
        _check_extent(f"mesh.path: {str(path)!r}", scaled[np.unique(faces)], f" (read in {unit})")
        loaded.process()  # merge duplicate vertices, drop degenerate faces
        if len(loaded.faces) == 0:
            raise GeometryError(f"mesh.path: {str(path)!r} holds no triangles of non-zero area")
        verts = np.asarray(loaded.vertices, dtype=float) * UNITS[unit]
        faces = np.asarray(loaded.faces, dtype=np.int64)
        object.__setattr__(self, "path", str(path))
        object.__setattr__(self, "unit", unit)
        object.__setattr__(self, "name", p.name)
        object.__setattr__(self, "vertices", verts)
        object.__setattr__(self, "faces", faces)

    def to_dict(self):
        return {"type": "mesh", "path": self.path, "unit": self.unit}


GEOMETRY_TYPES = {"box": Box, "sphere": Sphere, "cylinder": Cylinder, "capsule": Capsule,
                  "plane": Plane, "mesh": MeshFile}
