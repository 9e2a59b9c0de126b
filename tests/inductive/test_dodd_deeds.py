"""The eddy-current FEM against the Dodd-Deeds closed form (1968), with a mesh-refinement study.

Coil: r1 = 2 mm, r2 = 4 mm, lift-off 1..3 mm, 100 turns, 100 kHz, over
aluminium (sigma 3.5e7 S/m, skin depth 0.27 mm) and mild steel (7e6 S/m,
mu_r 100, skin depth 60 um), as a 1 mm plate and (aluminium) as a
half-space. The closed form is integrated independently (scipy quad over
alpha, the Bessel moment by its Struve-function form, itself checked against
quadrature).
"""

import numpy as np
import pytest

from twinsense.errors import ConfigError
from twinsense.inductive import dodd_deeds as dd
from twinsense.inductive.fem import (
    Coil,
    MeshSpec,
    Region,
    build_grid,
    delta_impedance,
    skin_depth,
    solve_on_grid,
    target_sweep,
)

R1, R2, L1, L2, N, F = 2e-3, 4e-3, 1e-3, 3e-3, 100, 100e3
COIL = Coil(R1, R2, L1, L2, N)
BASE = MeshSpec(h_coil=0.5e-3, skin_fraction=1.0, growth=1.4, domain=12.0)


def test_bessel_moment_closed_form_matches_quadrature():
    # Struve form vs adaptive quadrature of x J1(x): both to ~1e-12 on these arguments.
    for x1, x2 in [(0.0, 1.0), (0.5, 3.0), (2.0, 20.0), (10.0, 60.0)]:
        assert dd.bessel_moment(x1, x2) == pytest.approx(dd.bessel_moment_quad(x1, x2), rel=1e-9, abs=1e-12)


def test_skin_depth_textbook_value():
    # Copper at 50 Hz: 1 / sqrt(pi 50 mu0 5.8e7) = 9.35 mm (the usual textbook figure).
    assert skin_depth(50.0, 5.8e7) == pytest.approx(9.346e-3, rel=1e-3, abs=0)
    assert skin_depth(1e5, 0.0) == np.inf


def test_plate_reflection_limits():
    a = np.array([10.0, 300.0, 3000.0])
    thick = dd.reflection(a, F, 3.5e7, 1.0, thickness=0.05)  # 0.05 m = 185 skin depths
    np.testing.assert_allclose(thick, dd.reflection(a, F, 3.5e7, 1.0), rtol=1e-12)
    # A sheet much thinner than the skin depth: the thin-sheet reflection
    # -j w mu0 sigma c / (2 a + j w mu0 sigma c) (sheet conductance sigma c);
    # the next term is relatively O(a c) = 3e-6 at a = 3000 / m, hence rtol 1e-5.
    c = 1e-9
    from twinsense.constants import MU0
    k = 1j * 2 * np.pi * F * MU0 * 3.5e7 * c
    np.testing.assert_allclose(dd.reflection(a, F, 3.5e7, 1.0, thickness=c), -k / (2 * a + k), rtol=1e-5)


CASES = {
    # name: (sigma, mu_r, thickness, plate radius, error cap at the finer mesh)
    "aluminium-plate": (3.5e7, 1.0, 1e-3, 40e-3, 0.006),
    "steel-plate": (7.0e6, 100.0, 1e-3, 40e-3, 0.03),
    "aluminium-half-space": (3.5e7, 1.0, 15e-3, 40e-3, 0.006),
}


@pytest.mark.parametrize("case", list(CASES))
def test_fem_converges_to_dodd_deeds(case):
    sigma, mu_r, c, radius, cap = CASES[case]
    exact = dd.delta_z(R1, R2, L1, L2, N, F, sigma, mu_r, thickness=c if c < 10e-3 else np.inf)
    plate = (Region(0.0, radius, -c, 0.0, mu_r, sigma),)
    z1 = delta_impedance(COIL, (), plate, F, BASE)
    z2 = delta_impedance(COIL, (), plate, F, BASE.refined(2))
    e1, e2 = abs(z1 - exact) / abs(exact), abs(z2 - exact) / abs(exact)
    # P1 elements: the impedance (an energy) converges as h^2, so halving every
    # cell cuts the error ~4x (measured 3.5x for steel, 4.4x for aluminium);
    # asking for > 2.5x proves convergence towards the closed form, not to an offset.
    assert e2 < e1 / 2.5, (e1, e2)
    # Tolerance from the refinement itself: the Richardson estimate of the
    # finer mesh's error is |z2 - z1| / (4 - 1); allow 1.5x that (the coarse
    # mesh is not fully asymptotic) and never more than the stated cap
    # (0.6 % aluminium, 3 % steel: its 60 um skin is the hardest to resolve).
    richardson = abs(z2 - z1) / 3 / abs(exact)
    assert e2 <= 1.5 * richardson, (e2, richardson)
    assert e2 < cap
    # Physics signs: aluminium lowers L and adds loss; steel (mu_r 100) raises L.
    assert exact.real > 0
    assert (exact.imag < 0) == (mu_r == 1.0)


def test_sweep_equals_direct_solves():
    # target_sweep adds scaled unit matrices instead of re-assembling: same grid, same answer to rounding.
    d, c = 1e-3, 1e-3
    pieces = (Region(0.0, 3e-3, -d - c, -d), Region(3e-3, 6e-3, -d - c, -d))
    ghosts = tuple(Region(p.r0, p.r1, p.z0, p.z1, 100.0, 7e6) for p in pieces)
    r, z = build_grid(COIL, ghosts, F, BASE)
    got = target_sweep(COIL, (), pieces, ((7e6, 100.0), (3.5e7, 1.0)), F, r, z)
    ref = solve_on_grid(COIL, (), F, r, z)
    for i, (s, m) in enumerate(((7e6, 100.0), (3.5e7, 1.0))):
        one = solve_on_grid(COIL, (Region(0.0, 3e-3, -d - c, -d, m, s),), F, r, z) - ref
        two = solve_on_grid(COIL, (Region(0.0, 6e-3, -d - c, -d, m, s),), F, r, z) - ref
        np.testing.assert_allclose(got[i], [one, two], rtol=1e-8)


def test_bad_geometry_names_the_field():
    with pytest.raises(ConfigError, match="Region"):
        Region(2e-3, 1e-3, 0.0, 1.0)
    with pytest.raises(ConfigError, match="Coil.turns"):
        Coil(1e-3, 2e-3, 0.0, 1e-3, 0)
    with pytest.raises(ConfigError, match="regions"):
        delta_impedance(COIL, (), (Region(0.0, 5e-3, 0.0, 5e-3, 1.0, 1e6),), F, BASE)
