"""Response tables: FEM impedance changes over (material, distance, target radius), stored on disk.

A table holds ``delta Z[m, i, k]`` [ohm] of the sensor head for a disc
target of material ``m`` (conductivity, permeability), thickness ``c``, at
distance ``distances[i]`` and radius ``radii[k]``. All radii and materials
of one distance share one grid (its lines contain every disc edge, its cells
resolve the smallest skin depth of the materials) and one assembly
(:func:`~twinsense.inductive.fem.target_sweep`), so a table of M materials,
D distances and K radii costs D (M K + 1) sparse factorisations.

Tables are cached on disk keyed by a hash of everything that enters them
(head, frequency, grids, materials, thickness, mesh resolution and the
format version): first the package's shipped tables
(``twinsense/inductive/tables/``, written by ``python -m
twinsense.inductive.table``), then ``$TWINSENSE_CACHE_DIR/inductive`` (or
``~/.cache/twinsense/inductive``), else computed and stored there.
"""

from __future__ import annotations

import hashlib
import json
import os
import threading
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from twinsense.inductive.fem import MeshSpec, Region, build_grid, skin_depth, target_sweep
from twinsense.inductive.head import HeadGeometry, target_disc

FORMAT_VERSION = 1
SHIPPED_DIR = Path(__file__).parent / "tables"


@dataclass(frozen=True)
class TableSpec:
    """What a table is computed for (every field enters the cache key)."""

    head: HeadGeometry
    frequency: float
    distances: tuple[float, ...]
    radii: tuple[float, ...]
    materials: tuple[tuple[str, float, float], ...]  # (name, sigma [S/m], mu_r)
    thickness: float
    mesh: MeshSpec

    def key(self) -> str:
        d = asdict(self)
        d["format"] = FORMAT_VERSION
        text = json.dumps(d, sort_keys=True, default=float)
        return hashlib.sha256(text.encode()).hexdigest()[:24]


def cache_dir() -> Path:
    root = os.environ.get("TWINSENSE_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "twinsense")
    return Path(root) / "inductive"


def compute_table(spec: TableSpec, progress=None) -> np.ndarray:
    """``delta Z`` [ohm], complex (materials, distances, radii), by FEM."""
    head = spec.head
    coil, fixed = head.coil(), head.regions()
    out = np.zeros((len(spec.materials), len(spec.distances), len(spec.radii)), dtype=complex)
    # Grid resolution: the smallest skin depth among the materials.
    finest = min(spec.materials, key=lambda m: skin_depth(spec.frequency, m[1], m[2]))
    edges = (0.0, *spec.radii)
    mats = tuple((sigma, mu_r) for _, sigma, mu_r in spec.materials)
    for i, d in enumerate(spec.distances):
        ghosts = tuple(target_disc(d, a, spec.thickness, finest[1], finest[2]) for a in spec.radii)
        r_nodes, z_nodes = build_grid(coil, fixed + ghosts, spec.frequency, spec.mesh)
        # The disc of radius radii[k] is the union of the rings edges[0..k+1].
        rings = tuple(Region(edges[k], edges[k + 1], -d - spec.thickness, -d) for k in range(len(spec.radii)))
        out[:, i, :] = target_sweep(coil, fixed, rings, mats, spec.frequency, r_nodes, z_nodes)
        if progress is not None:
            progress(i + 1, len(spec.distances))
    return out


def head_impedance(head: HeadGeometry, frequency: float, mesh: MeshSpec) -> complex:
    """Impedance [ohm] of the coil in its core and housing, no target (winding resistance excluded)."""
    from twinsense.inductive.fem import coil_impedance

    return coil_impedance(head.coil(), head.regions(), frequency, mesh).impedance


def load_or_compute(spec: TableSpec, *, use_cache: bool = True, progress=None) -> tuple[np.ndarray, complex]:
    """(table, head impedance Z0) from the shipped tables, the disk cache, or the FEM."""
    name = f"{spec.key()}.npz"
    if use_cache:
        for path in (SHIPPED_DIR / name, cache_dir() / name):
            if path.exists():
                try:
                    with np.load(path) as data:
                        return data["delta_z"], complex(data["z0"])
                except (OSError, ValueError, KeyError):
                    pass  # a broken entry is recomputed below
    table = compute_table(spec, progress)
    z0 = head_impedance(spec.head, spec.frequency, spec.mesh)
    if use_cache:
        save(spec, table, z0, cache_dir())
    return table, z0


def save(spec: TableSpec, table: np.ndarray, z0: complex, directory: Path) -> Path:
    path = Path(directory) / f"{spec.key()}.npz"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        # Named per process and thread: sensors prepare on capture threads at once, and two
        # writers of the same table must not share (and truncate) one temporary file.
        tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp.npz")
        np.savez(tmp, delta_z=table, z0=np.complex128(z0))
        os.replace(tmp, path)
    except OSError:
        pass  # a read-only location only costs the recomputation next time
    return path


__all__ = ["FORMAT_VERSION", "Region", "TableSpec", "cache_dir", "compute_table", "head_impedance",
           "load_or_compute", "save"]
