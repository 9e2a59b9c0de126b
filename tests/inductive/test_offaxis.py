"""Targets off axis: the thin-sheet reference against the axisymmetric FEM, then the scene model against it.

The reference (inductive/thin_sheet.py) integrates the head's own field over a
thin plate in any pose; on a centred disc it must give the FEM's impedance
change of the same thin disc. Then the per-sector scene model (on a table of
the reference's own centred discs, so only its geometric rule differs) is held
to the accuracy docs/inductive.md states for plates moved sideways and tilted.
A coarse grid (cells Rc / 9, growth 1.4, box 10 coil radii) keeps the test short;
the figures it checks differ from the preset grid's by < 1 % (docs table).
"""

import pytest

from twinsense.inductive import inductive_config
from twinsense.inductive.fem import MeshSpec, delta_impedance
from twinsense.inductive.head import target_disc
from twinsense.inductive.offaxis import study
from twinsense.inductive.thin_sheet import disc_delta_z, head_field_for

CFG = inductive_config("m18_flush")
COARSE = MeshSpec(h_coil=CFG.head.core_radius / 9, skin_fraction=1.0, growth=1.4, domain=10.0)


@pytest.fixture(scope="module")
def field():
    return head_field_for(CFG.head, CFG.frequency, COARSE, r_max=1.5 * CFG.standard_target_side,
                          z_max=2.5 * CFG.rated_distance)


@pytest.fixture(scope="module")
def preset_field():
    return head_field_for(CFG.head, CFG.frequency, CFG.mesh, r_max=1.5 * CFG.standard_target_side,
                          z_max=2.5 * CFG.rated_distance)


@pytest.mark.parametrize(("sigma", "mu_r", "tol"), [(0.0, 10.0, 0.035), (2.5e4, 1.0, 0.035)])
def test_thin_sheet_reference_matches_the_axisymmetric_fem_on_axis(preset_field, sigma, mu_r, tol):
    # A 20 um disc of the standard radius at s_n. The first-order formula leaves out the sheet's
    # reaction: for the magnetic sheet ~ (mu_r - 1) t / (mu_r a) ~ 2e-3, for the conducting one
    # omega mu0 sigma t a ~ 1e-5. What remains is discretisation: the FEM of the 20 um disc and the
    # spline of the head's field (its derivatives for H) come from different grids. Measured: preset
    # grid 0.55 % (magnetic) and 2.2 % (conducting) at the preset's 700 kHz; at 300 kHz 0.3 % and 2.0 %,
    # that grid refined x2 3.0 % and 0.7 %, while either side alone moved by 1-4 % between the two grids.
    # Tolerance 3.5 %: the largest of these plus margin.
    d, a, t = CFG.rated_distance, CFG.standard_radius, 20e-6
    ref = disc_delta_z(preset_field, d, a, t, sigma, mu_r)
    fem = delta_impedance(CFG.head.coil(), CFG.head.regions(), (target_disc(d, a, t, sigma, mu_r),), CFG.frequency,
                          CFG.mesh)
    assert abs(ref - fem) / abs(fem) < tol, (ref, fem)


def test_scene_model_against_the_reference_off_axis_and_tilted(field):
    cases = {(c.sheet, round(c.offset / CFG.head.face_radius, 2), c.tilt_deg): c
             for c in study(CFG, field=field, cells=16, offsets=(0.25, 1.0), tilts_deg=(10.0, 20.0))}
    err = {k: c.error for k, c in cases.items()}
    # Bounds: the figures of docs/inductive.md (preset grid) plus 2 points for this coarse grid and
    # 16-cell plate mesh (their difference measured < 1 point).
    assert err[("steel-like", 0.25, 0.0)] < 0.10, err  # doc: 7.9 %
    assert err[("steel-like", 1.0, 0.0)] < 0.05, err  # doc: 0.9 %
    assert err[("steel-like", 0.0, 10.0)] < 0.06, err  # doc: 3.3 %
    assert err[("steel-like", 0.0, 20.0)] < 0.13, err  # doc: 10.6 %
    assert err[("aluminium-like", 0.25, 0.0)] < 0.10, err  # doc: 7.5 %
    assert err[("aluminium-like", 0.0, 10.0)] < 0.11, err  # doc: 8.6 %
    # The stated limit: a conducting sheet whose edge reaches the axis carries far less current than
    # the model's half disc (the currents must close inside the plate): the model overstates it x4-5.
    over = abs(cases[("aluminium-like", 1.0, 0.0)].model) / abs(cases[("aluminium-like", 1.0, 0.0)].reference)
    assert 3.5 < over < 6.0, over


def test_a_plate_reaching_behind_the_face_is_refused(field):
    from twinsense.errors import ConfigError
    from twinsense.inductive.thin_sheet import plate_delta_z

    with pytest.raises(ConfigError, match="plate"):
        plate_delta_z(field, (0.0, 0.0, 1e-3), 0.5, 0.018, 1e-6, 0.0, 100.0, cells=4)
