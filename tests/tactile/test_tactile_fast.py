"""The compiled re-assembly of moved cells against the NumPy forms and a fresh assembly."""

import numpy as np
import pytest

from twinsense.capacitive.fem import ElectrostaticSystem
from twinsense.capacitive.mesh import SimplexMesh, tensor_tet_mesh
from twinsense.capacitive.solver import SolverConfig
from twinsense.capacitive.tactile.deformed import MOVE_TOL, DeformedElectrostatics, tet_stiffness
from twinsense.capacitive.tactile.kernels import moved_cells, tet_stiffness_nb
from twinsense.capacitive.tactile.stack_mesh import DIELECTRIC, StackMesh


def _slab(d=1e-3, side=0.01):
    g = np.linspace(0.0, side, 5)
    mesh = tensor_tet_mesh(g, g, np.linspace(0.0, d, 4))
    z = mesh.points[:, 2]
    n = mesh.n_cells
    return StackMesh(mesh, np.full(n, DIELECTRIC), np.full(n, 2.8),
                     (np.flatnonzero(z < 1e-12), np.flatnonzero(z > d - 1e-12)), np.zeros(0, np.int64),
                     np.arange(n), np.arange(mesh.n_nodes), None, np.zeros(0, np.int64), d)


def test_compiled_element_matrices_equal_the_numpy_form():
    rng = np.random.default_rng(7)
    mesh = tensor_tet_mesh(np.linspace(0, 1e-2, 4), np.linspace(0, 1e-2, 4), np.linspace(0, 2e-3, 3))
    pts = mesh.points + rng.uniform(-3e-4, 3e-4, mesh.points.shape)
    sel = np.arange(0, mesh.n_cells, 3)
    k, vol = tet_stiffness_nb(pts, mesh.cells, sel)
    k_ref, vol_ref = tet_stiffness(pts, mesh.cells[sel])
    # The same products in another order: equal to rounding (1e-12 of the largest entry).
    np.testing.assert_allclose(k, k_ref, rtol=0, atol=1e-12 * np.abs(k_ref).max())
    np.testing.assert_allclose(vol, vol_ref, rtol=1e-12, atol=0)


def test_moved_cells_are_exactly_those_with_a_node_past_the_tolerance():
    mesh = tensor_tet_mesh(np.linspace(0, 1, 4), np.linspace(0, 1, 4), np.linspace(0, 1, 3))
    u = np.zeros_like(mesh.points)
    u[5, 1] = 2 * MOVE_TOL
    u[9, 2] = 0.5 * MOVE_TOL  # below the tolerance: not moved
    cells, moved = moved_cells(u, np.zeros_like(u), mesh.cells, MOVE_TOL)
    assert np.flatnonzero(moved).tolist() == [5]
    np.testing.assert_array_equal(cells, np.flatnonzero((mesh.cells == 5).any(axis=1)))


def test_sub_tolerance_creep_never_drifts_from_the_assembled_geometry():
    # 50 frames each moving every node by 0.6 MOVE_TOL: no single frame passes
    # the tolerance, but the drift does after two; the assembled stiffness must
    # then equal a fresh assembly on the applied geometry, and that geometry be
    # within MOVE_TOL of the target (the bound the tolerance's note derives).
    stack = _slab()
    es = DeformedElectrostatics(stack, SolverConfig(rtol=1e-12, energy_tol=0.0), outer_boundary="neumann")
    p = es.points0
    step = np.zeros_like(p)
    step[:, 2] = -0.6 * MOVE_TOL * p[:, 2] / 1e-3
    for k in range(1, 51):
        es.set_displacement(k * step)
    assert np.abs(es.displacement - 50 * step).max() <= MOVE_TOL
    fresh = ElectrostaticSystem(SimplexMesh(es.points, stack.mesh.cells), stack.terminals,
                                permittivity=stack.permittivity, outer_boundary="neumann")
    # Sums of a handful of rounded element entries: equal to ~1e-15 of the largest entry.
    scale = np.abs(fresh.k_data).max()
    np.testing.assert_allclose(es.system.k_data, fresh.k_data, rtol=0, atol=1e-12 * scale)


def _small_skin():
    from twinsense.capacitive.readout import ReadoutConfig
    from twinsense.capacitive.tactile import StackLayer, StackMeshSettings, TactileConfig, TactileLayout, TactileSensor

    lay = TactileLayout("t4", "crossing", 4, 4, 4e-3, 2e-3, 1e-3, dielectric=StackLayer(1.5e-3, 2.8, "ecoflex_0030"),
                        cover=StackLayer(0.5e-3, 2.72, "pdms_sylgard184"), edge=1e-3)
    mesh = StackMeshSettings(h_xy=1e-3, dielectric_cells=2, air_height=0.01, margin=4e-3, h_max=5e-3)
    quiet = ReadoutConfig(sample_rate=30.0)
    return TactileSensor(TactileConfig(lay, mesh, quiet, quiet), name="skin")


def _press(lay):
    from twinsense.capacitive.mechanics import Indenter

    x0, y0, r, d = lay.x_centers[2], lay.y_centers[2], 0.01, lay.dielectric.thickness / 15.0
    return Indenter.sphere((x0, y0, lay.total_thickness + r - d), r, "press"), (x0, y0), np.sqrt(2 * r * d)


def test_reference_press_on_a_few_contact_nodes_equals_the_whole_body():
    skin = _small_skin()
    ind, apex, overlap = _press(skin.config.layout)
    few = skin._reference_contact(ind, apex, 3.0 * overlap)
    assert skin._body is None  # solved on the candidates near the apex only
    full = skin.elastic_body.solve([ind])
    # The compliance of a subset of contact nodes is the submatrix of the full
    # one (Schur complement onto fewer dofs): the same LCP solution; only the
    # factorisation's rounding differs (condition ~1e3): 1e-9 relative.
    assert few.force[0] == pytest.approx(full.force[0], rel=1e-9, abs=0.0)
    scale = np.abs(full.displacement).max()
    np.testing.assert_allclose(few.displacement, full.displacement, rtol=0, atol=1e-9 * scale)


def test_reference_press_with_too_few_candidates_falls_back_to_the_whole_body():
    skin = _small_skin()
    ind, apex, overlap = _press(skin.config.layout)
    # Candidates within 0.6 of the overlap radius: the nodes between 0.6 and
    # 1.0 of it penetrate the sphere, so the check must reject the restricted solve.
    got = skin._reference_contact(ind, apex, 0.6 * overlap)
    assert skin._body is not None
    want = skin._body.solve([ind])
    assert got.force[0] == pytest.approx(want.force[0], rel=1e-12, abs=0.0)


def test_air_cell_boxes_follow_the_deformation():
    # The scene coupling picks its candidate cells by their boxes: after a
    # dent they must be the deformed cells' boxes, exactly (same coordinates,
    # min/max and a mean of 4).
    skin = _small_skin()
    es = skin.electrostatics
    am = es._air_mesh
    p0 = es.points0
    # A box ending 0.1 mm below the second layer of air cells: the 0.2 mm dent
    # brings that layer's cells into it.
    top = skin.config.layout.total_thickness
    floors = np.unique(p0[am.cells][:, :, 2].min(axis=1))
    second = floors[floors > top + 1e-9].min()
    box = np.array([[-3e-3, -3e-3, top], [3e-3, 3e-3, second - 1e-4]])
    before = am.cells_meeting_box(box)  # the per-axis box columns are cached here
    r2 = p0[:, 0] ** 2 + p0[:, 1] ** 2
    u = np.zeros_like(p0)
    u[:, 2] = -2e-4 * np.exp(-r2 / 4e-6) * np.clip(p0[:, 2] / 2e-3, 0.0, 1.0)
    es.set_displacement(u)
    p = es.points[am.cells]
    np.testing.assert_array_equal(am.cell_bounds[0], p.min(axis=1))
    np.testing.assert_array_equal(am.cell_bounds[1], p.max(axis=1))
    np.testing.assert_allclose(am.centroids, p.mean(axis=1), rtol=0, atol=1e-18)
    lo, hi = p.min(axis=1), p.max(axis=1)
    want = np.flatnonzero(np.all(hi >= box[0], axis=1) & np.all(lo <= box[1], axis=1))
    assert len(want) > len(before)
    np.testing.assert_array_equal(am.cells_meeting_box(box), want)
