"""Elastic materials: moduli identities, Gent's relation, the presets and the linear range."""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.capacitive.mechanics import LINEAR_STRAIN_LIMIT, MATERIALS, POISSON_MAX, ElasticMaterial
from twinsense.capacitive.mechanics.materials import gent_young_from_shore_a


def test_moduli_identities():
    # lambda = E nu / ((1+nu)(1-2nu)), mu = E / (2(1+nu)); M = lambda + 2 mu
    # = E (1-nu) / ((1+nu)(1-2nu)); E* = E / (1-nu^2). Exact algebra: 1e-14.
    m = ElasticMaterial("x", 2.0e6, 0.4)
    lam, mu = m.lame
    assert lam == pytest.approx(2e6 * 0.4 / (1.4 * 0.2), rel=1e-14, abs=0)
    assert mu == pytest.approx(2e6 / 2.8, rel=1e-14, abs=0)
    assert m.constrained_modulus == pytest.approx(2e6 * 0.6 / (1.4 * 0.2), rel=1e-14, abs=0)
    assert m.contact_modulus == pytest.approx(2e6 / (1 - 0.16), rel=1e-14, abs=0)
    # Back to E and nu: E = mu (3 lambda + 2 mu) / (lambda + mu), nu = lambda / (2 (lambda + mu)).
    assert mu * (3 * lam + 2 * mu) / (lam + mu) == pytest.approx(2e6, rel=1e-14, abs=0)
    assert lam / (2 * (lam + mu)) == pytest.approx(0.4, rel=1e-14, abs=0)


def test_gent_relation():
    # Gent (1958) evaluated by hand at Shore 85A: 0.0981 (56 + 647.9856) /
    # (0.137505 (254 - 215.9)) MPa = 13.18 MPa (4 digits).
    assert gent_young_from_shore_a(85.0) == pytest.approx(13.18e6, rel=5e-4, abs=0)
    assert MATERIALS["tpu_cover"].young == gent_young_from_shore_a(85.0)


def test_presets_in_their_stated_ranges():
    # The ranges the sources give: Ecoflex 00-30 60-70 kPa, Sylgard 184
    # 1-3 MPa, a silicone sponge 0.1-1 MPa, a Shore ~85A TPU 10-50 MPa.
    ranges = {"ecoflex_0030": (60e3, 70e3), "pdms_sylgard184": (1e6, 3e6), "silicone_foam": (0.1e6, 1e6),
              "tpu_cover": (10e6, 50e6)}
    assert set(ranges) == set(MATERIALS)
    for name, (lo, hi) in ranges.items():
        m = MATERIALS[name]
        assert m.name == name and lo <= m.young <= hi and 0 <= m.poisson <= POISSON_MAX


def test_linear_range_figures():
    # The module notes quote the neo-Hookean excess over the linear stress in
    # uniaxial compression, (l^-2 - l) / (3 e) - 1 with l = 1 - e.
    e = np.array([0.05, 0.10, 0.15])
    lam = 1 - e
    excess = (lam**-2 - lam) / (3 * e) - 1
    np.testing.assert_allclose(excess, [0.054, 0.115, 0.187], atol=5e-4, rtol=0)
    assert LINEAR_STRAIN_LIMIT == 0.15
