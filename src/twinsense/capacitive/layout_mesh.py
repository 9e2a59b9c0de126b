"""Meshing an electrode layout: the sensing box, its graded grid (or gmsh), and the layout on the mesh.

:func:`mesh_layout` turns a :class:`~twinsense.capacitive.layouts.Layout` and
:class:`~twinsense.capacitive.mesh.MeshSettings` into a :class:`LayoutMesh`:
the simplex mesh (built by :mod:`twinsense.capacitive.mesh` or by the optional
:mod:`twinsense.capacitive.gmsh_mesher`), the node sets of the electrodes and
the substrate permittivity per cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from twinsense.capacitive.gmsh_mesher import gmsh_layout_mesh
from twinsense.capacitive.layouts import Electrode
from twinsense.capacitive.mesh import (
    MeshSettings,
    SimplexMesh,
    cached_mesh,
    graded_axis,
    tensor_tet_mesh,
)
from twinsense.errors import ConfigError

__all__ = ["LayoutMesh", "layout_axes", "layout_region", "mesh_layout"]


@dataclass(frozen=True, eq=False)
class LayoutMesh:
    """A mesh of a layout's sensing volume with the layout mapped onto it.

    Attributes
    ----------
    mesh : SimplexMesh
        Tetrahedra in the layout frame [m].
    terminal_nodes : tuple of (k_i,) int64
        Nodes of each terminal electrode (``layout.terminals`` order).
    ground_nodes : (g,) int64
        Nodes of ground electrodes.
    permittivity : (m,) float
        Relative permittivity of every cell with no scene object (substrate or 1).
    region : (6,) float
        The meshed box [m].
    """

    mesh: SimplexMesh
    terminal_nodes: tuple
    ground_nodes: np.ndarray
    permittivity: np.ndarray
    region: tuple


def layout_region(layout, settings: MeshSettings) -> tuple:
    """The meshed box (x_min, x_max, y_min, y_max, z_min, z_max) [m] of ``layout``."""
    s = settings
    if s.region is not None:
        return tuple(float(x) for x in s.region)
    lb = layout.bounds
    region = (
        lb[0, 0] - s.margin,
        lb[1, 0] + s.margin,
        lb[0, 1] - s.margin,
        lb[1, 1] + s.margin,
        lb[0, 2] - s.depth,
        lb[1, 2] + s.height,
    )
    return tuple(float(x) for x in region)


def layout_axes(layout, settings: MeshSettings) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple]:
    """The graded grid lines (x, y, z) [m] and the region that mesh ``layout``."""
    s = settings
    region = layout_region(layout, s)
    feats: list[list[float]] = [[], [], []]
    fine: list[list[tuple[float, float]]] = [[], [], []]
    for e in layout.electrodes:
        if isinstance(e, Electrode):
            feats[2].append(e.z)
            if e.rectilinear:
                feats[0].extend(e.polygon[:, 0].tolist())
                feats[1].extend(e.polygon[:, 1].tolist())
            else:
                b = e.bounds
                fine[0].append((b[0, 0], b[1, 0]))
                fine[1].append((b[0, 1], b[1, 1]))
        else:
            b = e.bounds
            for k in range(3):
                fine[k].append((b[0, k], b[1, k]))
    if layout.substrate is not None:
        feats[2].extend([-layout.substrate.thickness, 0.0])
        if layout.substrate.extent is not None:
            x0, x1, y0, y1 = layout.substrate.extent
            feats[0].extend([x0, x1])
            feats[1].extend([y0, y1])
    axes = []
    for k in range(3):
        lo, hi = region[2 * k], region[2 * k + 1]
        zones = [(b[2 * k], b[2 * k + 1], h[k]) for b, h in s.refine_zones()]
        axes.append(graded_axis(lo, hi, feats[k], s.h_min, s.h_max, s.growth, fine_intervals=fine[k], zones=zones))
    return axes[0], axes[1], axes[2], tuple(float(x) for x in region)


def mesh_layout(layout, settings: MeshSettings | None = None) -> LayoutMesh:
    """Mesh the sensing volume of ``layout`` with ``settings.mesher`` (cached on disk).

    Raises ConfigError for an electrode outside the meshed region or one that
    covers no mesh node, and for overlapping or touching electrodes;
    ImportError for ``mesher="gmsh"`` without gmsh installed.
    """
    from twinsense.capacitive.fem import check_disjoint
    s = settings or MeshSettings()
    region = layout_region(layout, s)
    lo = np.array(region[0::2])
    hi = np.array(region[1::2])
    for i, e in enumerate(layout.electrodes):
        b = e.bounds
        if np.any(b[0] < lo - 1e-12) or np.any(b[1] > hi + 1e-12):
            raise ConfigError(
                f"Layout.electrodes[{i}]",
                e.name,
                f"an electrode inside the mesh region {tuple(np.round(region, 6))} [m]",
            )
    if s.mesher == "gmsh":
        mesh = gmsh_layout_mesh(layout, s, region)
        # Nodes on an electrode lie on its plane and outline to round-off.
        tol = 1e-9 * max(hi - lo)
    else:
        x, y, z, _ = layout_axes(layout, s)
        key = "tensor-v1|" + "|".join(np.asarray(a).tobytes().hex() for a in (x, y, z))
        mesh = cached_mesh(key, lambda: tensor_tet_mesh(x, y, z), use_cache=s.use_cache)
        tol = 1e-6 * min(np.diff(x).min(), np.diff(y).min(), np.diff(z).min())
    node_sets = []
    for e in layout.electrodes:
        if isinstance(e, Electrode):
            nodes = e.nodes(mesh.points, tol)
        else:
            nodes = e.nodes(mesh.points, mesh.cells, mesh.centroids)
        if len(nodes) == 0:
            raise ConfigError(
                f"electrode {e.name!r}",
                e.name,
                "an electrode that covers at least one mesh node (refine h_min)",
            )
        node_sets.append(nodes)
    check_disjoint(node_sets, [e.name for e in layout.electrodes], "Layout.electrodes")
    terminal = tuple(n for n, e in zip(node_sets, layout.electrodes) if e.role != "ground")
    ground = [n for n, e in zip(node_sets, layout.electrodes) if e.role == "ground"]
    ground_nodes = np.concatenate(ground) if ground else np.zeros(0, np.int64)
    eps = np.ones(mesh.n_cells)
    sub = layout.substrate
    if sub is not None:
        c = mesh.centroids
        in_sub = (c[:, 2] < 0.0) & (c[:, 2] > -sub.thickness)
        if sub.extent is not None:
            x0, x1, y0, y1 = sub.extent
            in_sub &= (c[:, 0] > x0) & (c[:, 0] < x1) & (c[:, 1] > y0) & (c[:, 1] < y1)
        eps[in_sub] = sub.permittivity
    eps.setflags(write=False)
    return LayoutMesh(mesh, terminal, ground_nodes, eps, region)
