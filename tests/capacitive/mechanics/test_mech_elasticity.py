"""P1 elasticity of the skin: assembly, factorisation kernels, and the confined layer in closed form."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import skfem
from skfem.models.elasticity import linear_elasticity

from twinsense.capacitive.mechanics import ElasticBody, ElasticMaterial, Indenter, box_mesh, skin_mesh
from twinsense.capacitive.mechanics.elasticity import (
    deviatoric_stiffness,
    element_dofs,
    gradients,
    nodal_volumetric_stiffness,
    principal_min,
    scatter,
    stiffness,
    strain_matrices,
)
from twinsense.capacitive.mechanics.kernels import split_diagonal, upper_solve
from twinsense.capacitive.mechanics.ordering import nested_dissection, node_graph

SOFT = ElasticMaterial("soft", 60e3, 0.49)
COVER = ElasticMaterial("cover", 2e6, 0.45)


def _graded_box():
    x = np.array([0.0, 1e-3, 1.5e-3, 3e-3])
    z = np.array([0.0, 0.4e-3, 1.0e-3, 1.2e-3])
    return box_mesh(x, x[:3], z, interfaces=[0.0, 1.0e-3, 1.2e-3])


def test_stiffness_matches_scikit_fem():
    # Independent implementation: scikit-fem's linear_elasticity form on the
    # same mesh. Both integrate constants exactly, so they agree to rounding
    # (1e-12 of the largest entry: sums of ~24 terms of 1e-16 relative error).
    lm = _graded_box()
    lam, mu = SOFT.lame
    basis = skfem.Basis(lm.mesh, skfem.ElementVector(skfem.ElementTetP1()))
    ref = skfem.asm(linear_elasticity(lam, mu), basis).tocsr()
    pts, cells = lm.mesh.p.T, lm.mesh.t.T
    ours = stiffness(pts, cells, np.full(len(cells), lam), np.full(len(cells), mu))
    assert abs(ours - ref).max() <= 1e-12 * abs(ref).max()


def test_rigid_motions_are_free_of_energy():
    # K annihilates the six rigid-body modes exactly (constant and skew-linear fields).
    lm = _graded_box()
    pts, cells = lm.mesh.p.T, lm.mesh.t.T
    k = stiffness(pts, cells, np.full(len(cells), 1e5), np.full(len(cells), 4e4))
    for w in (np.array([0.0, 0, 1]), np.array([1.0, 0, 0])):
        u = np.cross(w, pts) + np.array([1e-3, -2e-3, 3e-3])
        assert np.abs(k @ u.ravel()).max() <= 1e-9 * abs(k).max() * np.abs(u).max()


def test_upper_solve_matches_scipy():
    # Same triangular system through scipy's solver: agreement to rounding.
    rng = np.random.default_rng(3)
    a = sp.random(60, 60, density=0.1, random_state=rng, format="csr")
    up = (sp.triu(a) + sp.eye(60) * 4.0).tocsc()
    b = rng.standard_normal((60, 3))
    ref = spla.spsolve_triangular(up.tocsr(), b, lower=False)
    parts = split_diagonal(up)
    np.testing.assert_allclose(parts[1], up.diagonal(), rtol=0, atol=0)
    np.testing.assert_allclose(upper_solve(*parts, b), ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(upper_solve(*parts, b[:, 1]), ref[:, 1], rtol=1e-12, atol=1e-12)


def test_nested_dissection_is_a_permutation():
    lm = _graded_box()
    pts, cells = lm.mesh.p.T, lm.mesh.t.T
    nodes = np.flatnonzero(~lm.fixed)
    order = nested_dissection(pts, node_graph(cells, len(pts)), nodes)
    assert sorted(order.tolist()) == nodes.tolist()


def test_principal_min_matches_eigvalsh():
    rng = np.random.default_rng(0)
    a = rng.standard_normal((5, 3, 3))
    t = a + np.transpose(a, (0, 2, 1))
    voigt = np.column_stack([t[:, 0, 0], t[:, 1, 1], t[:, 2, 2], 2 * t[:, 1, 2], 2 * t[:, 0, 2], 2 * t[:, 0, 1]])
    np.testing.assert_allclose(principal_min(voigt), np.linalg.eigvalsh(t)[:, 0], rtol=1e-12, atol=1e-14)


def test_affine_fields_store_the_exact_energy():
    # For u = G x every formulation is exact: the strain is sym(G) in every
    # cell and at every node, so u^T K_dev u = 2 mu |dev sym G|^2 V and
    # u^T K_vol u = kappa tr(G)^2 V (V the mesh volume). Rounding: 1e-12.
    lm = _graded_box()
    pts, cells = lm.mesh.p.T, lm.mesh.t.T
    grad, vol = gradients(pts, cells)
    b = strain_matrices(grad)
    mu, kappa = 4e4, 3e5
    g = np.array([[1.0, 0.3, -0.2], [0.1, -0.5, 0.4], [0.2, 0.0, 0.7]]) * 1e-3
    u = (pts @ g.T).ravel()
    eps = 0.5 * (g + g.T)
    dev = eps - np.trace(eps) / 3 * np.eye(3)
    total = vol.sum()
    kdev = scatter(deviatoric_stiffness(b, vol, np.full(len(cells), mu)), element_dofs(cells), 3 * len(pts))
    kvol = nodal_volumetric_stiffness(b, vol, cells, np.full(len(cells), kappa), lm.element_layer, len(pts))
    assert u @ (kdev @ u) == pytest.approx(2 * mu * np.sum(dev * dev) * total, rel=1e-12, abs=0)
    assert u @ (kvol @ u) == pytest.approx(kappa * np.trace(g) ** 2 * total, rel=1e-12, abs=0)
    # Rigid motions carry no volumetric energy either.
    omega = np.array([0.3, -1.0, 0.5]) * 1e-3
    w = np.cross(omega, pts).ravel()
    assert abs(w @ (kvol @ w)) <= 1e-12 * kappa * total * omega @ omega


def _confined(store, volumetric="nodal"):
    """Two-layer skin with rollers on its four sides under a punch wider than the skin."""
    lm = skin_mesh((4e-3, 3e-3), (1.0e-3, 0.25e-3), h_xy=1e-3, h_top=0.125e-3, h_z=0.3e-3)
    p = lm.mesh.p.T
    rollers = np.zeros((len(p), 3), bool)
    rollers[np.isclose(np.abs(p[:, 0]), 2e-3), 0] = True
    rollers[np.isclose(np.abs(p[:, 1]), 1.5e-3), 1] = True
    body = ElasticBody.layered(lm, (SOFT, COVER), rollers=rollers, store_response=store, volumetric=volumetric)
    return lm, body


@pytest.mark.parametrize(("store", "volumetric"), [(True, "nodal"), (False, "nodal"), (False, "element")])
def test_confined_layers_follow_the_constrained_modulus(store, volumetric):
    # A laterally confined stack under uniform pressure p is in uniaxial
    # strain: eps_i = p / M_i with M = E (1 - nu) / ((1 + nu)(1 - 2 nu)), so a
    # rigid plate pushed by d needs p = d / sum(t_i / M_i). The field is linear
    # in each layer, which P1 represents exactly: the only error is rounding
    # in the factorisation (condition ~1e7 here: 1e-8 relative).
    lm, body = _confined(store, volumetric)
    d = 20e-6
    t = np.diff(lm.interfaces)
    m = np.array([SOFT.constrained_modulus, COVER.constrained_modulus])
    p = d / np.sum(t / m)
    sol = body.solve(Indenter.flat_punch((0, 0, lm.interfaces[-1] - d), 1.0))
    assert sol.active.all()
    np.testing.assert_allclose(sol.pressure, p, rtol=1e-8, atol=0)
    assert sol.force[0] == pytest.approx(p * 4e-3 * 3e-3, rel=1e-8, abs=0)
    assert sol.area[0] == pytest.approx(4e-3 * 3e-3, rel=1e-12, abs=0)
    strain = body.strains(sol.displacement)
    layer = lm.element_layer
    np.testing.assert_allclose(strain[:, 2], -p / m[layer], rtol=1e-8, atol=0)
    assert np.abs(strain[:, [0, 1, 3, 4, 5]]).max() <= 1e-8 * p / m[0]
    assert sol.max_strain == pytest.approx(p / m[0], rel=1e-8, abs=0)
    np.testing.assert_allclose(sol.displacement[lm.top, 2], -d, rtol=1e-9, atol=0)
    # The gap closes exactly at every contact node.
    assert np.abs(sol.gap).max() <= 1e-9 * d
