"""Mesh files of robot descriptions, read through trimesh and merged into one mesh per link.

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
from scipy.spatial import ConvexHull

from twinsense.errors import ConfigError
from twinsense.inputs import note_input
from twinsense.scene.geometry import Geometry, TriangleMesh
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


@dataclass(frozen=True, eq=False)
class LinkMesh(TriangleMesh):
    """A robot link's display mesh, with an inside test that also works when the mesh is open.

    Vendor display meshes are often not closed (seams, open caps, parts that
    only touch), and an inside test of an open mesh is undefined. A closed
    mesh is tested exactly; an open one by its convex hull, which for arm
    links (tubes between joint housings) adds the concave gaps between
    housings and is the volume a capacitive or inductive sensor sees first.
    """

    def contains(self, points):
        m = self.mesh
        if m.is_watertight:
            return super().contains(points)
        eq = self.hull_equations
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        # Inside the hull: on the inner side of every facet plane (n . p + d <= 0), to rounding.
        return np.all(p @ eq[:, :3].T + eq[:, 3] <= 1e-12, axis=1)

    @functools.cached_property
    def hull_equations(self) -> np.ndarray:
        """(n_facets, 4) outward unit normals and offsets of the convex hull's facets (n . p + d = 0)."""
        return np.asarray(ConvexHull(np.asarray(self.mesh.vertices)).equations, dtype=float)


def stack_parts(parts: list[tuple[np.ndarray, np.ndarray, Pose]]) -> tuple[np.ndarray, np.ndarray]:
    """Parts (vertices (n, 3), faces (m, 3), part -> link pose), at least one, as one vertex array [m] in the
    link frame and one face array indexing it."""
    verts, faces, off = [], [], 0
    for v, f, pose in parts:
        verts.append(pose.apply(v))
        faces.append(np.asarray(f) + off)
        off += len(v)
    return np.vstack(verts), np.vstack(faces)


def merge(parts: list[tuple[np.ndarray, np.ndarray, Pose]], name: str) -> Geometry | None:
    """One LinkMesh from parts (vertices (n, 3), faces (m, 3), part -> link pose); None if no parts."""
    return LinkMesh(*stack_parts(parts), name=name) if parts else None


def primitive_mesh(geometry: Geometry) -> tuple[np.ndarray, np.ndarray]:
    m = geometry.mesh
    return np.asarray(m.vertices, dtype=float), np.asarray(m.faces, dtype=np.int64)
