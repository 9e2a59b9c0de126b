"""Meshes: conformity, exact embedding of layouts, grading, the disk cache."""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.capacitive import layouts as L
from twinsense.capacitive.fem import element_stiffness
from twinsense.capacitive.layout_mesh import mesh_layout
from twinsense.capacitive.mesh import (
    MeshSettings,
    cached_mesh,
    graded_axis,
    polar_grid_2d,
    spherical_shell_mesh,
    tensor_tet_mesh,
)


def _interior_facets_shared_twice(mesh) -> bool:
    d = mesh.dim
    faces = np.concatenate([np.delete(mesh.cells, i, axis=1) for i in range(d + 1)])
    _, counts = np.unique(np.sort(faces, axis=1), axis=0, return_counts=True)
    return bool(np.all(counts <= 2))


def test_tensor_mesh_is_conforming_and_fills_the_box():
    rng = np.random.default_rng(3)
    x, y, z = (np.sort(np.concatenate([[0.0, 1.0], rng.uniform(0, 1, 4)])) for _ in range(3))
    mesh = tensor_tet_mesh(x, y, z)
    assert np.all(mesh.volumes > 0)
    assert mesh.volumes.sum() == pytest.approx(1.0, rel=1e-12, abs=0)
    assert _interior_facets_shared_twice(mesh)
    # A conforming box mesh has exactly 2 boundary triangles per boundary quad.
    nx, ny, nz = len(x) - 1, len(y) - 1, len(z) - 1
    assert len(mesh.boundary_facets) == 4 * (nx * ny + ny * nz + nx * nz)


def test_p1_patch_test_linear_potential_is_exact():
    # A linear potential has zero discrete Laplacian at interior nodes of any
    # conforming P1 mesh: the stiffness rows sum against it to round-off.
    for mesh in (
        spherical_shell_mesh([1.0, 1.5, 2.0], 1),
        tensor_tet_mesh(np.linspace(0, 1, 4), np.linspace(0, 2, 3), [0, 0.3, 1.0]),
    ):
        local = element_stiffness(mesh)
        phi = mesh.points @ np.array([0.3, -1.2, 0.7])
        r = np.zeros(mesh.n_nodes)
        np.add.at(r, mesh.cells, np.einsum("mij,mj->mi", local, phi[mesh.cells]))
        interior = np.setdiff1d(np.arange(mesh.n_nodes), np.unique(mesh.boundary_facets))
        assert np.abs(r[interior]).max() < 1e-12 * np.abs(local).max()


def test_polar_grid_puts_every_radius_on_a_circle():
    radii = np.array([0.0, 0.3, 0.5, 1.0, 2.0])
    p, t = polar_grid_2d(radii)
    r = np.hypot(p[:, 0], p[:, 1])
    assert np.all(np.min(np.abs(r[:, None] - radii[None, :]), axis=1) < 1e-12)
    from twinsense.capacitive.mesh import SimplexMesh

    mesh = SimplexMesh(p, t)
    assert np.all(mesh.volumes > 0)
    assert _interior_facets_shared_twice(mesh)


def test_graded_axis_keeps_features_and_grades():
    feats = [-0.013, -0.003, 0.003, 0.013]
    ax = graded_axis(-0.05, 0.05, feats, h_min=1e-3, h_max=8e-3, growth=1.3)
    for f in feats:
        assert np.min(np.abs(ax - f)) < 1e-15
    h = np.diff(ax)
    assert h.min() > 0 and h.max() <= 8e-3 * (1 + 1e-9)
    # Cells next to a feature are at most ~h_min (the span is divided evenly).
    i = np.searchsorted(ax, 0.003)
    assert h[i] <= 1.3e-3 and h[i - 1] <= 1.3e-3
    # Neighbouring cells differ by the growth factor or less (1.3 + rounding).
    assert np.max(np.maximum(h[1:] / h[:-1], h[:-1] / h[1:])) < 1.6


def test_layout_electrodes_are_embedded_exactly():
    tx, rx = L.interdigital(3, 2e-3, 10e-3, 1e-3)
    lay = L.Layout((tx, rx, L.ring("ring", 3e-3, 5e-3, center=(0.0, 0.02))))
    lm = mesh_layout(lay, MeshSettings(margin=5e-3, height=0.01, h_min=1e-3, h_max=4e-3, use_cache=False))
    pts = lm.mesh.points
    for nodes, e in zip(lm.terminal_nodes, lay.electrodes):
        assert np.all(np.abs(pts[nodes, 2] - e.z) < 1e-12)
    # Rectilinear combs: every outline vertex is a mesh node of its electrode.
    for nodes, e in zip(lm.terminal_nodes[:2], lay.electrodes[:2]):
        got = {tuple(np.round(p, 9)) for p in pts[nodes, :2]}
        assert all(tuple(np.round(v, 9)) in got for v in e.polygon)
    # The ring's nodes lie in the annulus (to a tolerance of one cell size).
    r = np.hypot(pts[lm.terminal_nodes[2], 0], pts[lm.terminal_nodes[2], 1] - 0.02)
    assert np.all((r >= 3e-3 - 1e-9) & (r <= 5e-3 + 1e-9))
    # FR-4 under the electrodes.
    c = lm.mesh.centroids
    assert np.all(lm.permittivity[(c[:, 2] < 0) & (c[:, 2] > -1.6e-3)] == 4.4)


def test_mesh_cache_round_trip(tmp_path, monkeypatch):
    monkeypatch.setenv("TWINSENSE_CACHE_DIR", str(tmp_path))
    calls = []

    def build():
        calls.append(1)
        return tensor_tet_mesh([0, 1], [0, 1], [0, 0.5, 1])

    a = cached_mesh("key-1", build)
    b = cached_mesh("key-1", build)
    assert len(calls) == 1
    assert np.array_equal(a.points, b.points) and np.array_equal(a.cells, b.cells)
    cached_mesh("key-2", build)
    assert len(calls) == 2
    assert len(list((tmp_path / "capacitive-mesh").glob("*.npz"))) == 2
