"""Field kernels against closed forms, multipole expansions, an independent quadrature and Maxwell's equations."""

import numpy as np
import pytest
from scipy import integrate
from scipy.special import ellipe, ellipk

from twinsense.constants import MU0
from twinsense.magnetic import fields as F

BR = 1.2  # [T] NdFeB remanence used throughout


def test_cel_against_scipy_complete_integrals():
    # K(m) = cel(kc, 1, 1, 1), E(m) = cel(kc, 1, 1, kc^2) with kc = sqrt(1 - m); scipy's Cephes K and E
    # are accurate to a few ulp, the iteration converges quadratically to ~1 ulp: 1e-14 relative.
    m = np.linspace(0.001, 0.999, 50)
    kc = np.sqrt(1 - m)
    np.testing.assert_allclose(F.cel(kc, 1.0, 1.0, 1.0), ellipk(m), rtol=1e-14, atol=0)
    np.testing.assert_allclose(F.cel(kc, 1.0, 1.0, kc ** 2), ellipe(m), rtol=1e-14, atol=0)


@pytest.mark.parametrize("kc, p, c, s", [(0.3, 0.5, 1.0, -1.0), (0.8, 2.0, 0.5, 0.7), (0.05, 0.09, 1.0, 0.3),
                                         (0.999, 0.001, 1.0, 0.5)])
def test_cel_general_against_quadrature(kc, p, c, s):
    # The defining integral by adaptive quadrature (epsrel 1e-13, so 1e-12 leaves a factor 10). The field
    # kernels call cel with p = 1 or p = gamma^2 > 0 (p = 0 only on the curved surface itself).
    ref = integrate.quad(lambda t: (c * np.cos(t) ** 2 + s * np.sin(t) ** 2)
                         / ((np.cos(t) ** 2 + p * np.sin(t) ** 2) * np.sqrt(np.cos(t) ** 2 + kc ** 2 * np.sin(t) ** 2)),
                         0, np.pi / 2, epsabs=0, epsrel=1e-13, limit=200)[0]
    assert F.cel(kc, p, c, s) == pytest.approx(ref, rel=1e-12, abs=0)


def axial_on_axis(z_face, radius, length, br):
    """Textbook on-axis field, z from the near face."""
    z = z_face
    return br / 2 * ((z + length) / np.hypot(z + length, radius) - z / np.hypot(z, radius))


def test_cylinder_on_axis_closed_form():
    # Derby-Olbert on the axis reduces to cel(1, 1, 1, 1) = pi / 2, so the two must agree to rounding:
    # each term is O(1) and the difference loses at most log10(B_r / B) ~ 4 digits at 10 lengths away,
    # so 1e-10 relative has a margin of ~100 over the 1e-16 * 1e4 rounding bound.
    r, ln = 0.003, 0.004
    z = np.array([1e-5, 1e-4, 1e-3, 0.004, 0.01, 0.04])
    for sign in (1, -1):  # above (+z) and below the magnet
        p = np.stack([0 * z, 0 * z, sign * (z + ln / 2)], axis=-1)
        b = F.cylinder_axial(p, r, ln, BR)
        np.testing.assert_allclose(b[:, 2], axial_on_axis(z, r, ln, BR), rtol=1e-10, atol=0)
        np.testing.assert_array_equal(b[:, :2], 0.0)
    # Inside, at the centre: B = B_r L / sqrt(L^2 + 4 R^2) (the solenoid formula).
    assert F.cylinder_axial(np.zeros(3), r, ln, BR)[2] == pytest.approx(BR * ln / np.hypot(ln, 2 * r), rel=1e-12,
                                                                        abs=0)


def test_ring_on_axis_closed_form():
    # Outer minus inner cylinder on the axis: the textbook ring formula, same rounding argument as above.
    ro, ri, ln = 0.005, 0.002, 0.003
    z = np.array([1e-4, 1e-3, 0.005, 0.02])
    p = np.stack([0 * z, 0 * z, z + ln / 2], axis=-1)
    b = F.ring(p, ro, ri, ln, (0, 0, BR))
    ref = axial_on_axis(z, ro, ln, BR) - axial_on_axis(z, ri, ln, BR)
    np.testing.assert_allclose(b[:, 2], ref, rtol=1e-10, atol=0)


def test_block_on_axis_closed_form():
    # Rectangular magnet on its axis (faces 2a x 2b, z from the near face): the classic arctan formula.
    a, b, ln = 0.004, 0.0025, 0.006
    z1 = np.array([1e-4, 1e-3, 0.005, 0.03])
    z2 = z1 + ln
    ref = BR / np.pi * (np.arctan(a * b / (z1 * np.sqrt(a * a + b * b + z1 ** 2)))
                        - np.arctan(a * b / (z2 * np.sqrt(a * a + b * b + z2 ** 2))))
    p = np.stack([0 * z1, 0 * z1, z1 + ln / 2], axis=-1)
    out = F.block(p, (2 * a, 2 * b, ln), (0, 0, BR))
    np.testing.assert_allclose(out[:, 2], ref, rtol=1e-10, atol=0)
    # The same block magnetised along x is the first one turned: x -> z, y -> x, z -> y (cyclic).
    q = p[:, [2, 0, 1]]
    out_x = F.block(q, (ln, 2 * a, 2 * b), (BR, 0, 0))
    np.testing.assert_allclose(out_x[:, 0], ref, rtol=1e-10, atol=0)


def test_cylinder_far_field_multipoles():
    # Far field of an axially magnetised cylinder (R, half length h): on the axis the exact field expands as
    # B / B_dip = 1 + k3 / z^2 + k5 / z^4 + O(z^-6), with k3 = 2 h^2 - 3 R^2 / 2 and
    # k5 = 3 h^4 - 15 R^2 h^2 / 2 + 15 R^4 / 8 (Taylor series of a / sqrt(a^2 + R^2) about a = z +- h).
    # Off the axis the l-pole terms go with P_l'(cos theta): in the equatorial plane the relative corrections
    # become -3/4 k3 / r^2 and +5/8 k5 / r^4. The remainder is O((a/r)^6), a = max(R, h); bound 2 (a/r)^6.
    r_, ln = 0.003, 0.004
    h = ln / 2
    m = BR * np.pi * r_ ** 2 * ln / MU0
    k3 = 2 * h ** 2 - 1.5 * r_ ** 2
    k5 = 3 * h ** 4 - 7.5 * r_ ** 2 * h ** 2 + 15 / 8 * r_ ** 4
    a = max(r_, h)
    for r in (0.02, 0.04, 0.08):
        axis = F.cylinder_axial(np.array([0, 0, r]), r_, ln, BR)[2] / F.dipole(np.array([0, 0, r]), (0, 0, m))[2]
        eq = F.cylinder_axial(np.array([r, 0, 0]), r_, ln, BR)[2] / F.dipole(np.array([r, 0, 0]), (0, 0, m))[2]
        tol = 2 * (a / r) ** 6
        assert axis - 1 == pytest.approx(k3 / r ** 2 + k5 / r ** 4, abs=tol)
        assert eq - 1 == pytest.approx(-0.75 * k3 / r ** 2 + 0.625 * k5 / r ** 4, abs=tol)
        # and the leading correction really is (a/r)^2: dropping it fails the bound
        assert abs(axis - 1) > 10 * tol


def test_block_and_isotropic_cylinder_far_field():
    # A cube and a cylinder with L = sqrt(3) R have no mass quadrupole, so their fields have no l = 3 term:
    # both equal the dipole of moment B_r V / mu0 up to O((a/r)^4). Measured coefficients: 0.25 (cube vs
    # dipole) and 0.12 (cube vs cylinder) over all directions; bound 0.5 (a/r)^4 plus 1e-8 for the rounding
    # of the corner sums at r = 40 a (a^3/r^3 cancellation of O(1) terms).
    a = 0.004
    rc = (a ** 3 / (np.pi * np.sqrt(3))) ** (1 / 3)
    lc = np.sqrt(3) * rc
    d = np.random.default_rng(1).normal(size=(60, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for r in (0.04, 0.08, 0.16):
        p = d * r
        dip = F.dipole(p, (0, 0, BR * a ** 3 / MU0))
        scale = np.linalg.norm(dip, axis=1)
        cube = F.block(p, (a, a, a), (0, 0, BR))
        cyl = F.cylinder(p, rc, lc, (0, 0, BR))
        bound = 0.5 * (a / r) ** 4 + 1e-8
        assert np.max(np.linalg.norm(cube - dip, axis=1) / scale) < bound
        assert np.max(np.linalg.norm(cube - cyl, axis=1) / scale) < bound
        assert np.max(np.linalg.norm(cyl - dip, axis=1) / scale) < bound


def _diametric_reference(p, r, ln, br):
    """B of a diametric (x) cylinder by adaptive 2-D quadrature of the surface charge M cos(phi)."""
    out = []
    for k in range(3):
        def f(z, phi, k=k):
            d = p - np.array([r * np.cos(phi), r * np.sin(phi), z])
            return np.cos(phi) * d[k] / np.linalg.norm(d) ** 3
        out.append(integrate.dblquad(f, 0, 2 * np.pi, -ln / 2, ln / 2, epsabs=0, epsrel=1e-11)[0])
    return br * r / (4 * np.pi) * np.array(out)


@pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")
@pytest.mark.parametrize("point", [(0.0, 0.0, -0.004), (0.0025, 0.001, -0.003), (0.005, -0.002, 0.0005),
                                   (0.01, 0.02, 0.01)])
def test_diametric_against_quadrature(point):
    # The adaptive trapezoidal rule in phi (error ~exp(-40)) against scipy's adaptive dblquad (epsrel 1e-11);
    # the tolerance 1e-9 is set by the quadrature's own accuracy on components that cancel.
    r, ln = 0.003, 0.0025
    p = np.array(point)
    got = F.cylinder_diametric(p, r, ln, BR)
    ref = _diametric_reference(p, r, ln, BR)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9 * np.linalg.norm(ref))


def test_diametric_equals_turned_axial_far_field_and_rotation():
    # Far away the diametric cylinder is the dipole of moment B_r V / mu0 along x: relative deviation O((a/r)^2)
    # with k3 as above but for the transverse axis; at r = 100 a it is below 1e-3.
    r, ln = 0.003, 0.0025
    m = BR * np.pi * r ** 2 * ln / MU0
    d = np.random.default_rng(2).normal(size=(20, 3))
    p = 0.3 * d / np.linalg.norm(d, axis=1, keepdims=True)
    b = F.cylinder_diametric(p, r, ln, BR)
    dip = F.dipole(p, (m, 0, 0))
    assert np.max(np.linalg.norm(b - dip, axis=1) / np.linalg.norm(dip, axis=1)) < 1e-3
    # Magnetisation along y equals the x one turned by 90 degrees about z (exact symmetry; the trapezoid
    # nodes map onto themselves: n_phi is a multiple of 4): equal to rounding.
    q = np.array([[0.002, 0.001, -0.003], [0.004, -0.002, 0.001]])
    rot = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    by = F.cylinder(q @ rot.T, r, ln, (0, BR, 0))
    bx = F.cylinder(q, r, ln, (BR, 0, 0))
    np.testing.assert_allclose(by, bx @ rot.T, rtol=0, atol=1e-14)


@pytest.mark.parametrize("kind", ["axial", "diametric", "block", "ring"])
def test_divergence_and_curl_vanish(kind):
    # Central differences with step h at points at least d = 2 mm from every surface: for a field varying on the
    # scale d the truncation error of a first derivative is |B''' | h^2 / 6 <= 10 |B| h^2 / d^3 (|d^3 r^-3 / dr^3|
    # = 60 r^-6), the rounding error delta |B| / h with delta ~ 1e-12 the kernels' relative accuracy. In units
    # of |B| / d: 10 (h/d)^2 + delta d / h = 2.5e-4 + 2e-10 for h = 1e-5 m; tolerance 1e-3.
    r, ln = 0.003, 0.004
    if kind == "axial":
        f = lambda q: F.cylinder(q, r, ln, (0, 0, BR))  # noqa: E731
    elif kind == "diametric":
        f = lambda q: F.cylinder(q, r, ln, (BR * 0.6, BR * 0.8, 0))  # noqa: E731
    elif kind == "block":
        f = lambda q: F.block(q, (0.006, 0.004, 0.003), (0.3, -0.5, 1.0))  # noqa: E731
    else:
        f = lambda q: F.ring(q, r, 0.0015, ln, (0, 0.5, BR))  # noqa: E731
    pts = np.array([[0.0, 0.0, 0.006], [0.005, 0.002, 0.0], [0.004, -0.004, -0.004], [0.0, 0.0, 0.0]
                    if kind == "ring" else [0.01, 0.0, 0.002]])  # the ring's hole centre is 1.5 mm from its wall
    h = 1e-5
    for p in pts:
        jac = np.empty((3, 3))  # jac[i, j] = dB_i / dx_j
        for j in range(3):
            e = np.zeros(3)
            e[j] = h
            jac[:, j] = (f(p + e) - f(p - e)) / (2 * h)
        b = np.linalg.norm(f(p))
        d = 0.0015 if kind == "ring" and not p.any() else 0.002
        scale = b / d
        assert abs(np.trace(jac)) < 1e-3 * scale
        curl = np.array([jac[2, 1] - jac[1, 2], jac[0, 2] - jac[2, 0], jac[1, 0] - jac[0, 1]])
        assert np.max(np.abs(curl)) < 1e-3 * scale


def test_inside_a_block_b_is_mu0_h_plus_m():
    # At the centre of a cube each charged face subtends a solid angle of 4 pi / 6, and a flat uniformly charged
    # face gives a normal field sigma Omega / (4 pi): H = -2 M / 6, so B = mu0 (H + M) = 2/3 B_r exactly.
    b = F.block(np.zeros(3), (0.01, 0.01, 0.01), (0, 0, BR))
    assert b[2] == pytest.approx(BR * 2 / 3, rel=1e-12, abs=0)


def test_diametric_adaptive_nodes_against_many_nodes():
    # The adaptive rule (N = 40 / alpha nodes, error ~exp(-40)) against 4096 nodes, whose own error is
    # exp(-4096 alpha) (negligible for alpha > 0.02, i.e. points more than ~2 % of R from the curved surface).
    # Points from 0.05 R to 20 R off the surface, beside and beyond the faces; agreement to 1e-12 of |B|
    # (kernel rounding; the trapezoid errors themselves are far below).
    r, ln = 0.003, 0.0025
    g = np.random.default_rng(4)
    rho = r + np.concatenate([g.uniform(0.05, 1, 30) * r, -g.uniform(0.05, 0.9, 10) * r, g.uniform(1, 20, 20) * r])
    z = g.uniform(-3 * ln, 3 * ln, len(rho))
    phi = g.uniform(0, 2 * np.pi, len(rho))
    pts = np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=-1)
    for p in pts:
        n = F.diametric_nodes(p, r, ln)
        assert F.N_PHI_MIN <= n <= F.N_PHI_MAX and n % 4 == 0
        got = F.cylinder_diametric(p, r, ln, BR)
        ref = F.cylinder_diametric(p, r, ln, BR, n_phi=4096)
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.linalg.norm(ref))
    # Far points need few nodes, near ones many.
    assert F.diametric_nodes(np.array([0.1, 0, 0]), r, ln) == F.N_PHI_MIN
    assert F.diametric_nodes(np.array([1.01 * r, 0, 0]), r, ln) > 1000
