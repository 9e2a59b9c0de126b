"""Contact conditions, several indenters, warm starts and bad inputs of the skin mechanics."""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.capacitive.mechanics import (
    ElasticBody,
    ElasticMaterial,
    Indenter,
    box_mesh,
    elastic_material,
    skin_mesh,
)
from twinsense.capacitive.mechanics.contact import ContactLcp
from twinsense.capacitive.mechanics.elasticity import (
    deviatoric_stiffness,
    element_dofs,
    gradients,
    nodal_volumetric_stiffness,
    scatter,
    strain_matrices,
)
from twinsense.errors import ConfigError, UnknownNameError

SIZE = (20e-3, 7e-3)
LAYERS = (2.0e-3, 0.5e-3)
Z_TOP = sum(LAYERS)
R = 5e-3
D = 0.15e-3  # indentation [m]
SEP = 6e-3  # indenters at x = +-SEP: 12 mm apart, 4.8 skin thicknesses


@pytest.fixture(scope="module")
def skin():
    lm = skin_mesh(SIZE, LAYERS, h_xy=0.6e-3, h_top=0.25e-3, h_z=0.5e-3)
    # Contact surface: the band |y| <= 2 mm the indenters (patch radius
    # < 1.2 mm) can reach; fewer contact nodes, a smaller dense compliance.
    top = lm.top & (np.abs(lm.mesh.p[1]) <= 2.0e-3)
    return lm, ElasticBody(lm.mesh, lm.element_layer, ("ecoflex_0030", "tpu_cover"), lm.fixed, top)


def sphere(x, name, d=D):
    return Indenter.sphere((x, 0.0, Z_TOP + R - d), R, name)


def test_signorini_conditions_hold(skin):
    _, body = skin
    sol = body.solve([sphere(-SEP, "left"), sphere(SEP, "right")])
    assert sol.active.any()
    # Only compressive pressure; no force where there is no contact.
    assert np.all(sol.nodal_force >= 0) and np.all(sol.pressure >= 0)
    assert np.all(sol.nodal_force[~sol.active] == 0)
    # The gap recomputed from the displacement field and the indenters'
    # surfaces: zero at the contact nodes (rounding: 1e-9 of the depth), never
    # negative (no penetration), positive where there is no contact.
    top = body.top_points
    h = np.minimum(sphere(-SEP, "l").height(top[:, 0], top[:, 1]), sphere(SEP, "r").height(top[:, 0], top[:, 1]))
    gap = h - (top[:, 2] + sol.displacement[body.top_nodes, 2])
    tol = 1e-9 * D
    assert np.abs(gap[sol.active]).max() <= tol
    assert np.all(gap[np.isfinite(gap)] >= -tol)
    assert np.all(gap[~sol.active] > -tol)
    np.testing.assert_allclose(sol.gap[sol.active], 0.0, atol=tol)


def test_displacement_solves_the_assembled_system(skin):
    # Independent check of the condensation and the back substitution: the
    # full stiffness times the displacement gives the contact forces on the
    # top nodes, zero at every other free dof, and reactions at the bonded
    # base that balance the load (rounding: 1e-8 of the total force, from a
    # stiffness with condition ~1e7).
    lm, body = skin
    sol = body.solve([sphere(-SEP, "left"), sphere(SEP, "right")])
    p, t = lm.mesh.p.T, lm.mesh.t.T
    mats = (elastic_material("ecoflex_0030"), elastic_material("tpu_cover"))
    lam = np.array([m.lame[0] for m in mats])[lm.element_layer]
    mu = np.array([m.lame[1] for m in mats])[lm.element_layer]
    # The default formulation (nodal volumetric average), assembled globally
    # in node order, without the elimination order or the condensation.
    grad, vol = gradients(p, t)
    b = strain_matrices(grad)
    k = (scatter(deviatoric_stiffness(b, vol, mu), element_dofs(t), 3 * len(p))
         + nodal_volumetric_stiffness(b, vol, t, lam + 2 * mu / 3, lm.element_layer, len(p)))
    r = (k @ sol.displacement.ravel()).reshape(-1, 3)
    total = sol.force.sum()
    load = np.zeros_like(r)
    load[body.top_nodes, 2] = -sol.nodal_force
    free = ~lm.fixed
    assert np.abs(r[free] - load[free]).max() <= 1e-8 * total
    assert r[lm.fixed, 2].sum() == pytest.approx(total, rel=1e-8, abs=0)


def test_two_distant_indenters_superpose(skin):
    # Each indenter alone, then both. The coupling is the displacement one
    # patch causes under the other: w_cross, taken from the single solutions
    # at the other's contact nodes. F grows at most like d^(3/2) (Hertz; a
    # thin bonded layer is closer to linear), so the relative force change
    # is at most 1.5 |w_cross| / d; the bound is checked to be small (< 1 %)
    # so the test means "well separated".
    _, body = skin
    left, right = sphere(-SEP, "left"), sphere(SEP, "right")
    a = body.solve([left])
    b = body.solve([right])
    both = body.solve([left, right])
    w_on_left = np.abs(b.displacement[body.top_nodes[a.active], 2]).max()
    w_on_right = np.abs(a.displacement[body.top_nodes[b.active], 2]).max()
    tol = 1.5 * max(w_on_left, w_on_right) / D
    assert tol < 0.01
    assert both.force[0] == pytest.approx(a.force[0], rel=tol, abs=0)
    assert both.force[1] == pytest.approx(b.force[0], rel=tol, abs=0)
    assert both.area[0] == pytest.approx(a.area[0], rel=tol, abs=0)
    # Mirror images: the tetrahedral split is not mirror-symmetric, so the
    # two patches differ by the local discretisation only (h / a ~ 0.6 mm /
    # 0.87 mm: a few per cent of the force).
    assert both.force[0] == pytest.approx(both.force[1], rel=0.05, abs=0)


def test_active_set_matches_lawson_hanson(skin):
    # The same problem through scipy's NNLS (Lawson-Hanson) on the Cholesky
    # form: same forces to the rounding of the triangular solves.
    _, body = skin
    inds = [sphere(-SEP, "left"), sphere(SEP, "right", d=0.1e-3)]
    sol = body.solve(inds)
    g0, _ = body.initial_gaps(inds)
    reach = np.isfinite(g0)
    ref = ContactLcp(body.compliance)._lawson_hanson(np.where(reach, g0, 0.0), reach)
    assert np.abs(sol.nodal_force - ref).max() <= 1e-6 * ref.max()
    np.testing.assert_array_equal(sol.active, ref > 1e-6 * ref.max())


def test_warm_start_reuses_the_contact_set(skin):
    _, body = skin
    inds = [sphere(-SEP, "left"), sphere(SEP, "right")]
    body.solve(inds)
    again = body.solve(inds)
    assert again.iterations == 1
    moved = body.solve([sphere(-SEP + 0.05e-3, "left"), sphere(SEP, "right")])
    assert moved.iterations <= 3


def test_heightfield_reproduces_the_sphere(skin):
    # A sphere sampled every 0.05 mm and interpolated bilinearly: height
    # error <= s^2 / (8 R) = 6e-8 m, 4e-4 of the depth; the force follows it
    # with the factor 1.5 (d^(3/2)): 1e-3.
    _, body = skin
    xs = np.arange(-SEP - 4e-3, -SEP + 4e-3, 0.05e-3)
    ys = np.arange(-4e-3, 4e-3, 0.05e-3)
    ref = sphere(-SEP, "s")
    z = ref.height(*np.meshgrid(xs, ys, indexing="ij"))
    hf = Indenter.from_heightfield(xs, ys, z, name="hf")
    assert body.solve([hf]).force[0] == pytest.approx(body.solve([ref]).force[0], rel=1e-3, abs=0)


def test_no_contact_gives_zero(skin):
    _, body = skin
    sol = body.solve([Indenter.sphere((0, 0, Z_TOP + R + 1e-3), R, "above")])
    assert not sol.active.any() and sol.force[0] == 0 and sol.max_strain == 0
    assert np.all(sol.displacement == 0)


def test_load_beyond_the_linear_range_is_refused(skin):
    _, body = skin
    with pytest.raises(ConfigError, match=r"indenters\[1\] \(deep\)\.max_strain.*<= 0\.15"):
        body.solve([sphere(-SEP, "shallow", d=0.05e-3), sphere(SEP, "deep", d=0.8e-3)])


def test_bad_inputs_name_the_field(skin):
    lm, body = skin
    with pytest.raises(ConfigError, match="indenters"):
        body.solve("sphere")
    with pytest.raises(ConfigError, match=r"indenters\[0\]"):
        body.solve([3.0])
    with pytest.raises(ConfigError, match=r"indenters\[0\] \(nan\)\.height"):
        body.solve([Indenter(lambda x, y: np.full(np.shape(x), np.nan), "nan")])
    with pytest.raises(ConfigError, match="radius"):
        Indenter.sphere((0, 0, 0), -1.0)
    with pytest.raises(ConfigError, match="center"):
        Indenter.flat_punch((0, np.nan, 0), 1e-3)
    with pytest.raises(ConfigError, match="z"):
        Indenter.from_heightfield([0, 1], [0, 1], np.zeros((3, 2)))
    with pytest.raises(UnknownNameError, match="ecoflex_0030"):
        elastic_material("rubber")
    with pytest.raises(ConfigError, match="poisson"):
        ElasticMaterial("incompressible", 1e5, 0.5)
    with pytest.raises(ConfigError, match="young"):
        ElasticMaterial("x", float("nan"), 0.3)
    with pytest.raises(ConfigError, match="thicknesses"):
        skin_mesh((4e-3, 4e-3), (1e-3, -1e-3), h_xy=1e-3, h_top=0.5e-3)
    with pytest.raises(ConfigError, match="interfaces"):
        box_mesh([0, 1e-3], [0, 1e-3], [0, 1e-3, 2e-3], interfaces=[0, 1.5e-3, 2e-3])
    with pytest.raises(ConfigError, match="volumetric"):
        ElasticBody.layered(skin_mesh((4e-3, 4e-3), LAYERS, h_xy=1e-3, h_top=0.5e-3), ("ecoflex_0030",) * 2,
                            volumetric="mixed")
    lm = skin_mesh((4e-3, 4e-3), LAYERS, h_xy=1e-3, h_top=0.5e-3)
    n = lm.mesh.p.shape[1]
    with pytest.raises(ConfigError, match="ElasticBody.fixed"):
        ElasticBody(lm.mesh, lm.element_layer, ("ecoflex_0030", "tpu_cover"), np.zeros(n, bool), lm.top)
    with pytest.raises(ConfigError, match="ElasticBody.top"):
        ElasticBody(lm.mesh, lm.element_layer, ("ecoflex_0030", "tpu_cover"), lm.fixed, lm.top[:-1])
    with pytest.raises(ConfigError, match="element_material"):
        ElasticBody(lm.mesh, lm.element_layer + 1, ("ecoflex_0030", "tpu_cover"), lm.fixed, lm.top)
    with pytest.raises(ConfigError, match="strain_limit"):
        ElasticBody.layered(lm, ("ecoflex_0030", "tpu_cover"), strain_limit=0.5)
