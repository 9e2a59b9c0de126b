"""Radiometry and correlation kernels against closed forms and independent integrals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from twinsense.constants import PLANCK as H_PLANCK
from twinsense.constants import SPEED_OF_LIGHT as C_LIGHT
from twinsense.tof.effects import crosstalk
from twinsense.tof.signal import (
    PixelPhasors,
    beam_profile,
    block_sum,
    correlation_images,
    radiance_factor,
)


def _beam_integral_spherical(fwhm_x: float, fwhm_y: float) -> float:
    """Integral of the beam shape over the forward hemisphere in spherical coordinates (dblquad)."""
    k = 4 * math.log(2)
    fx, fy = math.radians(fwhm_x), math.radians(fwhm_y)

    def f(theta, phi):
        x, y, z = math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)
        tx, ty = math.atan2(x, z), math.atan2(y, z)
        return math.exp(-k * ((tx / fx) ** 2 + (ty / fy) ** 2)) * math.sin(theta)

    val, _ = integrate.dblquad(f, 0, 2 * math.pi, 0, math.pi / 2, epsabs=1e-10, epsrel=1e-9)
    return val


@pytest.mark.parametrize("fwhm", [(80.0, 60.0), (20.0, 10.0)])
def test_beam_profile_integrates_to_one(fwhm):
    # Reference: the same beam integrated in spherical coordinates by adaptive quadrature.
    # The module's midpoint rule on a 0.25 deg grid must agree to 1e-5 relative (its
    # discretisation error for Gaussians wider than 10 deg is ~1e-7).
    omega = _beam_integral_spherical(*fwhm)
    p0 = beam_profile(np.array([0.0, 0.0, 1.0]), fwhm)
    assert p0 * omega == pytest.approx(1.0, rel=1e-5, abs=0)
    # Half maximum at half the FWHM off axis, horizontally and vertically.
    half = math.radians(fwhm[0] / 2)
    d = np.array([math.sin(half), 0.0, math.cos(half)])
    assert beam_profile(d, fwhm) / p0 == pytest.approx(0.5, rel=1e-12, abs=0)
    assert beam_profile(np.array([0.0, 0.0, -1.0]), fwhm) == 0.0


def test_radiance_factor_lambertian_specular_retro():
    c = np.array([1.0, math.cos(math.radians(30)), math.cos(math.radians(60))])
    lam = radiance_factor(np.full(3, 0.5), np.zeros(3), np.zeros(3, bool), c, 30.0, 300.0)
    # Lambertian: pi x BRDF = albedo at every angle.
    np.testing.assert_allclose(lam, 0.5, rtol=1e-7)
    spec = radiance_factor(np.full(3, 0.5), np.ones(3), np.zeros(3, bool), c, 30.0, 300.0)
    # Normalised Phong lobe at the mirror direction: (n + 2) / 2 = 16 x albedo at normal incidence;
    # beyond 45 deg incidence the lobe points away from the source: 0.
    assert spec[0] == pytest.approx(0.5 * 16.0, rel=1e-6, abs=0)
    assert spec[1] == pytest.approx(0.5 * 16.0 * math.cos(math.radians(60)) ** 30, rel=1e-4, abs=0)
    assert spec[2] == 0.0
    retro = radiance_factor(np.full(3, 0.5), np.zeros(3), np.ones(3, bool), c, 30.0, 300.0)
    np.testing.assert_allclose(retro, 0.5 * 300.0 * c, rtol=1e-6)


def test_correlation_samples_are_cosines_of_the_phasor():
    # D_i = (c_d / 2) |Z| cos(phi + i pi / 2) for a single phasor Z = |Z| exp(j phi).
    phi = np.linspace(0, 2 * np.pi, 17, dtype=np.float32).reshape(1, 1, 17)
    mag = np.float32(1000.0)
    ph = PixelPhasors(mag * np.cos(phi), mag * np.sin(phi), np.zeros((1, 17), np.float32))
    d = correlation_images(ph, 0.75)
    assert d.shape == (1, 4, 1, 17)
    for i in range(4):
        expected = 0.5 * 0.75 * 1000.0 * np.cos(phi[0] + i * np.pi / 2)
        # float32 trigonometry: 1e-6 relative of the 375 e- amplitude.
        np.testing.assert_allclose(d[0, i], expected, atol=375 * 2e-6)


def test_block_sum_sums_subpixels():
    a = np.arange(4 * 6, dtype=np.float32).reshape(4, 6)
    s = block_sum(a, 2)
    assert s.shape == (2, 3)
    assert s[0, 0] == a[0, 0] + a[0, 1] + a[1, 0] + a[1, 1]
    assert block_sum(a, 1) is a


def test_crosstalk_is_a_normalised_gaussian():
    img = np.zeros((1, 1, 41, 41), np.float32)
    img[..., 20, 20] = 1.0
    out = crosstalk(img, 1.5)[0, 0]
    # A delta spreads into a Gaussian: total charge kept (the kernel is normalised; the
    # 3-sigma truncation is renormalised by scipy) and second moment sigma^2 per axis
    # (truncation at 3 sigma lowers it by ~3 %, hence rel=0.04).
    assert out.sum() == pytest.approx(1.0, rel=1e-6, abs=0)
    yy, xx = np.mgrid[-20:21, -20:21]
    assert (out * xx ** 2).sum() == pytest.approx(1.5 ** 2, rel=0.04, abs=0)
    assert (out * yy ** 2).sum() == pytest.approx(1.5 ** 2, rel=0.04, abs=0)
    # sigma 0 returns its input untouched; a uniform image stays uniform.
    assert crosstalk(img, 0.0) is img
    flat = np.full((2, 4, 9, 9), 3.0, np.float32)
    np.testing.assert_allclose(crosstalk(flat, 0.8), 3.0, rtol=1e-6)


def test_photon_constants():
    # 850 nm photon energy: h c / lambda = 2.337e-19 J (1.4586 eV).
    assert H_PLANCK * C_LIGHT / 850e-9 == pytest.approx(2.3370e-19, rel=1e-4, abs=0)


def test_power_by_squaring_matches_powf():
    from twinsense.tof.signal import _power

    x = np.linspace(0, 1, 101, dtype=np.float32)
    for e in (1.0, 2.0, 7.0, 30.0, 255.0, 12.5):
        # float32 rounding of up to 2 log2(e) products: a few 1e-6 relative.
        np.testing.assert_allclose(_power(x, e), x.astype(np.float64) ** e, rtol=2e-5, atol=1e-30)
