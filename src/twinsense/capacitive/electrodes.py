"""Electrode layouts, the data model: planar electrodes on a substrate, and solid conductors.

Everything is given in the layout frame (metres, z up, electrodes on the plane
z = 0 by default, the substrate below it from z = -thickness to 0); the layout
is placed in the world by the sensor's mount pose.

Planar electrodes are zero-thickness polygons (copper on a PCB is 35 um thick,
far below any mesh size that resolves the sensing volume). A driven shield or
a ground plane is an electrode with the role ``"shield"`` or ``"ground"``.
Closed bodies (a sphere, a gripper finger) are :class:`SolidElectrode`.
Factories of common shapes (stripes, pad grids, combs, rings) are in
:mod:`twinsense.capacitive.layouts`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from matplotlib.path import Path as _MplPath

from twinsense import validation as v
from twinsense.errors import ConfigError

__all__ = ["ROLES", "Electrode", "Layout", "SolidElectrode", "Substrate", "polygon_loops"]

ROLES = ("sense", "shield", "ground")
"""Electrode roles: a measured terminal, a driven shield, or ground (0 V)."""


@dataclass(frozen=True, eq=False)
class Electrode:
    """A planar electrode: a polygon on the plane z = ``z`` of the layout frame.

    Attributes
    ----------
    name : str
    polygon : (k, 2) float
        Outline vertices (x, y) [m], k >= 3, either orientation, not closed.
    z : float
        Height of the electrode plane in the layout frame [m].
    role : {"sense", "shield", "ground"}
    """

    name: str
    polygon: np.ndarray
    z: float = 0.0
    role: str = "sense"

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError("Electrode.name", self.name, "a non-empty string")
        poly = v.array(f"{self.name}.polygon", self.polygon, (None, 2), "m")
        if len(poly) < 3:
            raise ConfigError(f"{self.name}.polygon", self.polygon, "at least 3 vertices (k, 2) [m]")
        if abs(_area(poly)) <= 0:
            raise ConfigError(f"{self.name}.polygon", self.polygon, "a polygon with non-zero area")
        poly.setflags(write=False)
        object.__setattr__(self, "polygon", poly)
        object.__setattr__(self, "z", v.number(f"{self.name}.z", self.z, unit="m"))
        v.choice(f"{self.name}.role", self.role, ROLES)

    @property
    def rectilinear(self) -> bool:
        """True when every edge is parallel to x or y (embedded exactly by a tensor grid)."""
        d = np.diff(np.vstack([self.polygon, self.polygon[:1]]), axis=0)
        return bool(np.all((np.abs(d[:, 0]) < 1e-12) | (np.abs(d[:, 1]) < 1e-12)))

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) axis-aligned bounds [m] in the layout frame."""
        lo = np.append(self.polygon.min(axis=0), self.z)
        hi = np.append(self.polygon.max(axis=0), self.z)
        return np.vstack([lo, hi])

    @property
    def parts(self) -> tuple[tuple[np.ndarray, tuple[np.ndarray, ...]], ...]:
        """The outline as simple loops: ((outer (k, 2), (hole (k_i, 2), ...)), ...) [m].

        An outline that returns to an earlier vertex (the keyhole of
        :func:`ring`: out round the outer circle, across a zero-width slit,
        back round the inner one) is split there into loops; a loop inside
        a larger one is its hole, any other loop a separate part.
        """
        loops = polygon_loops(self.polygon)
        parts: list[tuple[np.ndarray, list[np.ndarray]]] = []
        for lp in loops:  # largest first
            owner = next((o for o in parts if _MplPath(o[0]).contains_point(tuple(lp.mean(axis=0)))), None)
            if owner is None:
                parts.append((lp, []))
            else:
                owner[1].append(lp)
        return tuple((outer, tuple(holes)) for outer, holes in parts)

    def contains_xy(self, xy: np.ndarray, tol: float) -> np.ndarray:
        """Points (n, 2) inside or within ``tol`` of the outline -> bool (n,)."""
        inside = np.zeros(len(xy), bool)
        for outer, holes in self.parts:
            part = _within(outer, xy, tol)
            for hole in holes:
                part &= ~_within(hole, xy, -tol)
            inside |= part
        return inside

    def nodes(self, points: np.ndarray, tol: float) -> np.ndarray:
        """Indices of mesh nodes (points (n, 3), layout frame) on this electrode."""
        on_plane = np.flatnonzero(np.abs(points[:, 2] - self.z) <= tol)
        inside = self.contains_xy(points[on_plane, :2], tol)
        return on_plane[inside]


@dataclass(frozen=True, eq=False)
class SolidElectrode:
    """A closed body used as an electrode or conductor (sphere, box, finger).

    Attributes
    ----------
    name : str
    geometry : object with ``contains(points (n, 3)) -> bool (n,)`` and
        ``bounds`` (2, 3) [m] in its local frame (any twinsense geometry).
    pose : Pose or None
        Body-to-layout transform (None: identity).
    role : {"sense", "shield", "ground"}
    """

    name: str
    geometry: Any
    pose: Any = None
    role: str = "sense"

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError("SolidElectrode.name", self.name, "a non-empty string")
        if not callable(getattr(self.geometry, "contains", None)):
            raise ConfigError(
                f"{self.name}.geometry",
                self.geometry,
                "a geometry with contains(points) (Box, Sphere, TriangleMesh, ...)",
            )
        v.choice(f"{self.name}.role", self.role, ROLES)

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Inside test of layout-frame points (n, 3) -> bool (n,)."""
        local = points if self.pose is None else self.pose.inverse().apply(points)
        return np.asarray(self.geometry.contains(local), bool)

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) axis-aligned bounds [m] in the layout frame."""
        b = np.asarray(self.geometry.bounds, float)
        if self.pose is None:
            return b
        corners = np.array([[b[i, 0], b[j, 1], b[k, 2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        c = self.pose.apply(corners)
        return np.vstack([c.min(axis=0), c.max(axis=0)])

    def nodes(self, points: np.ndarray, cells: np.ndarray, centroids: np.ndarray) -> np.ndarray:
        """Mesh nodes inside the body or on a cell whose centroid is inside."""
        inside = self.contains(points)
        cell_in = self.contains(centroids)
        nodes = np.union1d(np.flatnonzero(inside), np.unique(cells[cell_in]))
        return nodes.astype(np.int64)


@dataclass(frozen=True)
class Substrate:
    """A dielectric slab under the electrodes.

    Attributes
    ----------
    thickness : float
        Slab from z = -thickness to z = 0 [m] (FR-4 boards: 1.6e-3).
    permittivity : float
        Relative permittivity (FR-4: 4.4).
    extent : (4,) float or None
        (x_min, x_max, y_min, y_max) [m]; None covers the whole mesh.
    """

    thickness: float = 1.6e-3
    permittivity: float = 4.4
    extent: tuple[float, float, float, float] | None = None

    def __post_init__(self) -> None:
        v.positive("Substrate.thickness", self.thickness, "m")
        v.number(
            "Substrate.permittivity",
            self.permittivity,
            lo=0.0,
            lo_open=True,
            unit="relative, vacuum = 1",
        )
        if self.extent is not None:
            e = v.vector("Substrate.extent", self.extent, 4, "m")
            if not (e[1] > e[0] and e[3] > e[2]):
                raise ConfigError("Substrate.extent", self.extent, "x_min < x_max and y_min < y_max")
            object.__setattr__(self, "extent", tuple(float(x) for x in e))


@dataclass(frozen=True, eq=False)
class Layout:
    """Electrodes, substrate and the layout's name.

    Attributes
    ----------
    electrodes : tuple of Electrode or SolidElectrode
        In terminal order; names must be unique. Ground electrodes are held
        at 0 V and are not terminals.
    substrate : Substrate or None
    name : str
    """

    electrodes: tuple = ()
    substrate: Substrate | None = field(default_factory=Substrate)
    name: str = "layout"

    def __post_init__(self) -> None:
        els = tuple(self.electrodes)
        if len(els) == 0:
            raise ConfigError("Layout.electrodes", (), "at least one electrode")
        names = set()
        for i, e in enumerate(els):
            if not isinstance(e, (Electrode, SolidElectrode)):
                raise ConfigError(f"Layout.electrodes[{i}]", e, "an Electrode or SolidElectrode")
            if e.name in names:
                raise ConfigError(f"Layout.electrodes[{i}].name", e.name, "a name not used twice")
            names.add(e.name)
        if not any(e.role == "sense" for e in els):
            raise ConfigError(
                "Layout.electrodes",
                [e.name for e in els],
                "at least one electrode with role 'sense'",
            )
        if self.substrate is not None and not isinstance(self.substrate, Substrate):
            raise ConfigError("Layout.substrate", self.substrate, "a Substrate or None")
        object.__setattr__(self, "electrodes", els)

    @property
    def terminals(self) -> tuple:
        """Electrodes that are terminals (sense and shield), in order."""
        return tuple(e for e in self.electrodes if e.role != "ground")

    @property
    def terminal_names(self) -> tuple[str, ...]:
        return tuple(e.name for e in self.terminals)

    @property
    def sense_names(self) -> tuple[str, ...]:
        return tuple(e.name for e in self.electrodes if e.role == "sense")

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) bounds of all electrodes and the substrate [m], layout frame."""
        b = np.array([e.bounds for e in self.electrodes])
        lo, hi = b[:, 0].min(axis=0), b[:, 1].max(axis=0)
        if self.substrate is not None:
            lo[2] = min(lo[2], -self.substrate.thickness)
            hi[2] = max(hi[2], 0.0)
            if self.substrate.extent is not None:
                x0, x1, y0, y1 = self.substrate.extent
                lo[:2] = np.minimum(lo[:2], [x0, y0])
                hi[:2] = np.maximum(hi[:2], [x1, y1])
        return np.vstack([lo, hi])

    def digest_key(self) -> str:
        """A text describing every input that shapes the mesh (for the mesh cache)."""
        parts = [f"layout:{self.name}"]
        for e in self.electrodes:
            if isinstance(e, Electrode):
                parts.append(f"E:{e.name}:{e.role}:{e.z!r}:{np.round(e.polygon, 12).tolist()}")
            else:
                parts.append(f"S:{e.name}:{e.role}:{np.round(e.bounds, 12).tolist()}")
        s = self.substrate
        if s is not None:
            parts.append(f"sub:{s.thickness!r}:{s.permittivity!r}:{s.extent!r}")
        return "|".join(parts)


def _within(loop: np.ndarray, xy: np.ndarray, tol: float) -> np.ndarray:
    """Points inside the simple ``loop`` grown by ``tol`` (shrunk for tol < 0) -> bool (n,)."""
    path = _MplPath(np.vstack([loop, loop[:1]]), closed=True)
    # matplotlib's radius sign depends on the loop's orientation: test both
    # signs; their union grows the loop, their intersection shrinks it.
    a = path.contains_points(xy, radius=abs(tol))
    b = path.contains_points(xy, radius=-abs(tol))
    return (a | b) if tol >= 0 else (a & b)


def polygon_loops(polygon: np.ndarray, tol: float = 1e-12) -> list[np.ndarray]:
    """Split an outline at repeated vertices into simple loops, largest area first.

    Parameters
    ----------
    polygon : (k, 2) float [m]
    tol : float, distance under which two vertices are the same [m].

    Returns
    -------
    list of (k_i, 2) float loops, each without a repeated end vertex.
    """
    loops: list[np.ndarray] = []
    chain: list[np.ndarray] = []
    for p in np.asarray(polygon, float):
        hit = next((j for j, q in enumerate(chain) if np.max(np.abs(p - q)) <= tol), None)
        if hit is None:
            chain.append(p)
            continue
        loop = chain[hit:]
        if len(loop) >= 3:
            loops.append(np.array(loop))
        chain = chain[: hit + 1]
    if len(chain) >= 3:
        loops.append(np.array(chain))
    loops.sort(key=lambda lp: -abs(_area(lp)))
    return loops


def _area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
