"""The tetrahedral mesh of a tactile layer stack and the air above it.

One tensor grid serves both physics: the elastic solve runs on the cells of
the soft layers (dielectric and cover), the electrostatic solve on all cells
(carrier, soft layers, air). The mechanics' nodes are a subset of the
electrostatic nodes, so the displacement moves the electrostatic nodes
exactly, with no interpolation. The grid contains every electrode edge and
layer interface; in-plane it is uniform at ``h_xy`` over the skin and grades
out to the open boundary; above the skin it grades from ``first_air`` up to
``air_height``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from twinsense import validation as v
from twinsense.capacitive.mesh import SimplexMesh, graded_axis, tensor_tet_mesh
from twinsense.capacitive.tactile.layouts import TactileLayout
from twinsense.errors import ConfigError

__all__ = ["BASE", "COVER", "DIELECTRIC", "OUTSIDE", "SoftGrid", "StackMesh", "StackMeshSettings", "mesh_stack"]

BASE, DIELECTRIC, COVER, OUTSIDE = 0, 1, 2, 3
"""Cell regions: the rigid carrier, the soft dielectric, the soft cover, air (and what lies below)."""


@dataclass(frozen=True)
class StackMeshSettings:
    """Mesh resolution of a tactile stack.

    Attributes
    ----------
    h_xy : float, in-plane cell size over the skin [m].
    dielectric_cells, cover_cells : int, cells across the soft layers.
    first_air : float, height of the first air cell above the skin [m]; it
        must exceed the deepest indentation (the cell is squeezed by it).
    air_height : float, height of the meshed air above the skin [m].
    margin : float, air beyond the skin edge on every side [m].
    depth : float, air below the stack when there is no shield [m].
    mechanics_refine : int, the elastic grid splits every electrostatic cell of
        the soft layers into this many along each axis (the contact patch needs
        finer cells than the capacitances; the electrostatic nodes stay nodes of
        the elastic grid, so the displacement carries over exactly).
    h_max : float, largest cell [m]; growth : float, cell growth away from the skin.
    """

    h_xy: float = 1e-3
    dielectric_cells: int = 3
    cover_cells: int = 1
    first_air: float = 1e-3
    air_height: float = 0.03
    margin: float = 0.01
    depth: float = 0.01
    mechanics_refine: int = 1
    h_max: float = 8e-3
    growth: float = 1.5

    def __post_init__(self) -> None:
        for f in ("h_xy", "first_air", "air_height", "margin", "depth", "h_max"):
            v.positive(f"StackMeshSettings.{f}", getattr(self, f), "m")
        v.integer("StackMeshSettings.dielectric_cells", self.dielectric_cells, lo=1, hi=32)
        v.integer("StackMeshSettings.cover_cells", self.cover_cells, lo=1, hi=32)
        v.integer("StackMeshSettings.mechanics_refine", self.mechanics_refine, lo=1, hi=4)
        v.number("StackMeshSettings.growth", self.growth, lo=1.0, lo_open=True, hi=3.0)
        if self.h_xy > self.h_max or self.first_air > self.h_max:
            raise ConfigError("StackMeshSettings.h_max", self.h_max, "a size >= h_xy and >= first_air")


@dataclass(frozen=True, eq=False)
class StackMesh:
    """A tactile stack on its mesh.

    Attributes
    ----------
    mesh : SimplexMesh, undeformed, skin frame [m].
    region : (m,) int, cell region (BASE, DIELECTRIC, COVER, OUTSIDE).
    permittivity : (m,) float, relative permittivity of the empty stack.
    terminals : tuple of (k_i,) int, electrode nodes (:attr:`TactileLayout.electrode_names` order).
    ground : (g,) int, shield nodes (empty without a shield).
    soft_cells : (s,) int, cells of the dielectric and the cover (the elastic body).
    soft_nodes : (q,) int, their nodes.
    soft : SoftGrid, the elastic grid of the soft layers.
    soft_index : (q,) int, node of the elastic grid at each of ``soft_nodes``.
    z_top : float, top surface height [m].
    """

    mesh: SimplexMesh
    region: np.ndarray
    permittivity: np.ndarray
    terminals: tuple
    ground: np.ndarray
    soft_cells: np.ndarray
    soft_nodes: np.ndarray
    soft: SoftGrid
    soft_index: np.ndarray
    z_top: float

    @property
    def air_cells(self) -> np.ndarray:
        """(a,) int, cells that scene objects may occupy (above or beside the skin)."""
        return np.flatnonzero(self.region == OUTSIDE)

    def node_displacement(self, soft_displacement: np.ndarray) -> np.ndarray:
        """(n, 3) displacement of every mesh node [m] from the elastic grid's (q_soft, 3) field.

        Nodes outside the soft layers (carrier, air) stay where they are.
        """
        u = np.zeros((self.mesh.n_nodes, 3))
        u[self.soft_nodes] = np.asarray(soft_displacement, float)[self.soft_index]
        return u


@dataclass(frozen=True, eq=False)
class SoftGrid:
    """The elastic grid of the soft layers (dielectric and cover).

    Attributes
    ----------
    mesh : SimplexMesh, tetrahedra of the soft layers [m], skin frame.
    material : (m,) int, 0 for the dielectric, 1 for the cover.
    fixed : (q,) bool, nodes bonded to the carrier (z = z_tx).
    top : (q,) bool, nodes of the top surface (z = z_top).
    """

    mesh: SimplexMesh
    material: np.ndarray
    fixed: np.ndarray
    top: np.ndarray

    @property
    def top_points(self) -> np.ndarray:
        """(n_top, 3) top-surface nodes [m] (the order of the contact pressures)."""
        return self.mesh.points[self.top]


def _split(lines: np.ndarray, k: int) -> np.ndarray:
    if k == 1:
        return lines
    parts = [np.linspace(a, b, k + 1)[:-1] for a, b in itertools.pairwise(lines)]
    return np.concatenate([*parts, lines[-1:]])


def _soft_grid(x, y, z, hx, hy, z_tx, z_rx, k) -> tuple:
    xs = _split(x[(x >= -hx - 1e-12) & (x <= hx + 1e-12)], k)
    ys = _split(y[(y >= -hy - 1e-12) & (y <= hy + 1e-12)], k)
    zs = _split(z[(z >= z_tx - 1e-12)], k)
    zs = zs[zs <= z[-1]]
    mesh = tensor_tet_mesh(xs, ys, zs)
    cz = mesh.centroids[:, 2]
    material = (cz > z_rx).astype(np.int64)
    pz = mesh.points[:, 2]
    return SoftGrid(mesh, material, np.abs(pz - z_tx) < 1e-12, np.abs(pz - zs[-1]) < 1e-12), xs, ys, zs


def _axis_with_fine(half: float, margin: float, features, s: StackMeshSettings) -> np.ndarray:
    return graded_axis(-half - margin, half + margin, features, h_min=s.h_xy, h_max=s.h_max, growth=s.growth,
                       fine_intervals=[(-half, half)])


def mesh_stack(layout: TactileLayout, settings: StackMeshSettings | None = None) -> StackMesh:
    """Mesh ``layout``'s stack and the air around it."""
    if not isinstance(layout, TactileLayout):
        raise ConfigError("mesh_stack.layout", layout, "a TactileLayout")
    s = settings or StackMeshSettings()
    if not isinstance(s, StackMeshSettings):
        raise ConfigError("mesh_stack.settings", s, "a StackMeshSettings")
    hx, hy = layout.half_extent
    x = _axis_with_fine(hx, s.margin, layout.x_features(), s)
    y = _axis_with_fine(hy, s.margin, layout.y_features(), s)
    z_tx, z_rx, z_top = layout.z_tx, layout.z_rx, layout.total_thickness
    zs = [np.array([0.0, z_tx]), np.linspace(z_tx, z_rx, s.dielectric_cells + 1)[1:]]
    if layout.cover is not None:
        zs.append(np.linspace(z_rx, z_top, s.cover_cells + 1)[1:])
    air = graded_axis(z_top, z_top + s.air_height, (z_top,), h_min=s.first_air, h_max=s.h_max, growth=s.growth)
    zs.append(air[1:])
    if not layout.shield:
        below = graded_axis(-s.depth, 0.0, (0.0,), h_min=max(z_tx, s.h_xy), h_max=s.h_max, growth=s.growth)
        zs.insert(0, below[:-1])
    z = np.concatenate(zs)
    mesh = tensor_tet_mesh(x, y, z)
    p = mesh.points
    tol = 1e-12
    c = mesh.centroids
    inside = (np.abs(c[:, 0]) < hx) & (np.abs(c[:, 1]) < hy)
    region = np.full(mesh.n_cells, OUTSIDE, np.int64)
    region[inside & (c[:, 2] > 0) & (c[:, 2] < z_tx)] = BASE
    region[inside & (c[:, 2] > z_tx) & (c[:, 2] < z_rx)] = DIELECTRIC
    region[inside & (c[:, 2] > z_rx) & (c[:, 2] < z_top)] = COVER
    eps = np.ones(mesh.n_cells)
    eps[region == BASE] = layout.base.permittivity
    eps[region == DIELECTRIC] = layout.dielectric.permittivity
    if layout.cover is not None:
        eps[region == COVER] = layout.cover.permittivity
    if layout.shield:
        # The robot link (or the shield layer) is a grounded plane under the whole mesh.
        eps[(c[:, 2] < z_tx) & ~inside] = layout.base.permittivity
        region[(c[:, 2] < z_tx) & ~inside] = BASE
    tx_m, rx_m = layout.electrode_masks(p[:, :2])
    on_tx = np.abs(p[:, 2] - z_tx) < tol
    on_rx = np.abs(p[:, 2] - z_rx) < tol
    terminals = tuple(np.flatnonzero(m & on_tx) for m in tx_m) + tuple(np.flatnonzero(m & on_rx) for m in rx_m)
    for name, t in zip(layout.electrode_names, terminals):
        if len(t) == 0:
            raise ConfigError("mesh_stack.settings.h_xy", s.h_xy, f"a grid that puts nodes on electrode {name!r}")
    ground = np.flatnonzero(np.abs(p[:, 2]) < tol) if layout.shield else np.zeros(0, np.int64)
    soft_cells = np.flatnonzero((region == DIELECTRIC) | (region == COVER))
    soft_nodes = np.unique(mesh.cells[soft_cells])
    zsoft = z[(z >= z_tx - tol) & (z <= z_top + tol)]
    soft, xs, ys, zs = _soft_grid(x, y, zsoft, hx, hy, z_tx, z_rx, s.mechanics_refine)
    ps = p[soft_nodes]
    i = np.searchsorted(xs, ps[:, 0] - tol)
    j = np.searchsorted(ys, ps[:, 1] - tol)
    k = np.searchsorted(zs, ps[:, 2] - tol)
    soft_index = k * (len(xs) * len(ys)) + i * len(ys) + j
    if not np.allclose(soft.mesh.points[soft_index], ps, rtol=0, atol=1e-12):
        raise AssertionError("the elastic grid lost an electrostatic node")  # a bug, not an input error
    return StackMesh(mesh, region, eps, terminals, ground, soft_cells, soft_nodes, soft, soft_index, z_top)
