"""The compiled 1-D type-1 NUFFT (twinsense.radar.spreader) against the exact sum and finufft."""

from __future__ import annotations

import finufft
import numpy as np
import pytest

from twinsense.errors import ConfigError
from twinsense.radar.spreader import Kernel, kernel_for, kernel_shape, nufft1d


def _exact(x, s, n):
    k = np.arange(n) - n // 2
    return s @ np.exp(1j * np.outer(x, k))


def _rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.mark.parametrize("tol", [1e-3, 1e-4, 3e-5, 1e-6, 1e-9])
def test_against_exact_sum_and_finufft(tol):
    rng = np.random.default_rng(7)
    n, m, d = 128, 800, 5
    x = rng.uniform(-np.pi, np.pi, m)
    s = rng.normal(size=(d, m)) + 1j * rng.normal(size=(d, m))
    exact = _exact(x, s, n)
    mine = nufft1d(x, s, n, tol)
    ref = finufft.nufft1d1(x, s, n, eps=tol, isign=1, modeord=0)
    # finufft's width rule aims at a relative l2 error ~tol; it meets it only to within
    # ~2x (the width moves in whole points, one per decade of tol): measured 0.7-1.3 tol
    # here and on the radar's blocks. Limit 2 tol; finufft itself is held to the same.
    assert _rel(mine, exact) <= 2.0 * tol
    assert _rel(ref, exact) <= 2.0 * tol
    # Each within 2 tol of the exact sum, so within 4 tol of each other.
    assert _rel(mine, ref) <= 4.0 * tol


def test_single_vector_and_batch_agree():
    rng = np.random.default_rng(3)
    x = rng.uniform(-np.pi, np.pi, 300)
    s = rng.normal(size=(3, 300)) + 1j * rng.normal(size=(3, 300))
    batch = nufft1d(x, s, 64, 1e-6)
    for d in range(3):
        # The same spread and FFT per vector: equal to rounding (the grid's sums run in the
        # same order; only the FFT's batch layout may differ) -> 1e-13 relative.
        one = nufft1d(x, s[d], 64, 1e-6)
        assert one.shape == (64,)
        np.testing.assert_allclose(one, batch[d], rtol=0, atol=1e-13 * np.abs(batch[d]).max())


def test_points_at_the_ends_and_the_deconvolution():
    # A point at x = 0 with unit strength: every mode is 1 exactly; at x = +-pi the modes
    # alternate (-1)^k: the grid's wrap-around at both ends. l2 limit 2 tol (as above).
    tol = 1e-7
    n = 32
    for x0 in (0.0, np.pi, -np.pi, np.pi - 1e-12):
        out = nufft1d(np.array([x0]), np.array([1.0 + 0j]), n, tol)
        exact = np.exp(1j * x0 * (np.arange(n) - n // 2))
        assert _rel(out, exact) <= 2.0 * tol


def test_kernel_shape_is_finuffts_rule():
    # finufft (upsampling 2): w = ceil(log10(10 / tol)), beta = 2.30 w (2.20, 2.26, 2.38
    # for w = 2, 3, 4).
    assert kernel_shape(1e-6) == (7, pytest.approx(16.1, rel=1e-12, abs=1e-12))
    assert kernel_shape(1e-3)[0] == 4 and kernel_shape(1e-3)[1] == pytest.approx(4 * 2.38, rel=1e-12, abs=1e-12)
    assert kernel_shape(0.05)[0] == 3
    # One setup per size and width: every tolerance of one width shares it (1e-6 and
    # 5.5e-6 both ask for w = 7), another width has its own.
    assert kernel_for(64, 1e-6) is kernel_for(64, 5.5e-6)
    assert kernel_for(64, 1e-6) is not kernel_for(64, 1e-7)
    assert kernel_for(64, 5.5e-6).tol == pytest.approx(1e-6, rel=1e-12, abs=0.0)


def test_horner_table_fits_the_kernel():
    # The kernel weights come from the fitted polynomials: within 0.05 tol of exp(beta
    # (sqrt(1 - (2z/w)^2) - 1)) at every offset (the fit's own stopping rule).
    k = Kernel(64, 1e-5)
    w, beta = k.width, k.beta
    s = np.linspace(0.0, 1.0, 997, endpoint=False)
    u = 2.0 * s - 1.0
    for j in range(w):
        z = s + j - 0.5 * w
        exact = np.exp(beta * (np.sqrt(np.maximum(1.0 - (2.0 * z / w) ** 2, 0.0)) - 1.0))
        fit = np.polynomial.polynomial.polyval(u, k.coef[::-1, j])
        assert np.max(np.abs(fit - exact)) <= 0.05 * 1e-5


@pytest.mark.parametrize("n", [63, 1, 3])
def test_odd_mode_counts_are_finuffts_modes(n):
    # N odd: modes -(N//2)..N//2 (finufft's modeord=0), as an ADC window of odd length
    # needs (the synthesis centres its samples at N//2). Before, odd N was refused deep in
    # the synthesis. Limits as in the first test: 2 tol against the exact sum, 4 tol
    # against finufft.
    rng = np.random.default_rng(8)
    tol = 1e-6
    x = rng.uniform(-np.pi, np.pi, 300)
    s = rng.normal(size=(2, 300)) + 1j * rng.normal(size=(2, 300))
    mine = nufft1d(x, s, n, tol)
    assert mine.shape == (2, n)
    assert _rel(mine, _exact(x, s, n)) <= 2.0 * tol
    assert _rel(mine, finufft.nufft1d1(x, s, n, eps=tol, isign=1, modeord=0)) <= 4.0 * tol


def test_points_outside_the_period_wrap():
    # exp(1j x k) has period 2 pi in x for integer k: points a few periods (or a fraction of
    # one) outside [-pi, pi] give the exact sum's modes as well. Before the wrap such points
    # were spread past the grid's padding (~w / 2 points): wrong modes and writes outside
    # the array. Same l2 limit 2 tol as the in-range test.
    rng = np.random.default_rng(11)
    tol, n = 1e-6, 64
    x = np.concatenate([rng.uniform(-np.pi, np.pi, 50), [np.pi + 0.3, -np.pi - 0.3, 7.0 * np.pi + 0.1,
                                                          -9.5 * np.pi, 1e3]])
    s = rng.normal(size=(2, len(x))) + 1j * rng.normal(size=(2, len(x)))
    assert _rel(nufft1d(x, s, n, tol), _exact(x, s, n)) <= 2.0 * tol


@pytest.mark.parametrize("kwargs, field", [
    ({"tol": float("nan")}, "nufft1d.tol"),
    ({"tol": 0.0}, "nufft1d.tol"),
    ({"tol": 1.5}, "nufft1d.tol"),
    ({"n_modes": 0}, "nufft1d.n_modes"),
    ({"x": np.array([0.1, np.nan])}, "nufft1d.x"),
    ({"x": np.zeros(3)}, "nufft1d.strengths"),
])
def test_bad_input_names_the_field(kwargs, field):
    args = {"x": np.array([0.1, -0.2]), "strengths": np.ones(2, complex), "n_modes": 16, "tol": 1e-6}
    args.update(kwargs)
    with pytest.raises(ConfigError) as err:
        nufft1d(**args)
    assert err.value.field == field


def test_empty_point_set_gives_zero_modes():
    out = nufft1d(np.empty(0), np.empty((3, 0), complex), 16, 1e-6)
    assert out.shape == (3, 16) and not np.any(out)


@pytest.mark.parametrize("tol", [5e-14, 5e-15])
def test_tightest_widths_fit_without_runaway_degree(tol):
    # Widths 15 and 16 (the synthesis' eps >= 1e-14 runs the spreader at eps / 2 >= 5e-15):
    # the monomial fit stalls at ~4e-15 (rounding), so 0.05 of 1e-14 or 1e-15 cannot be met;
    # the fit stops at its 1e-14 floor with a degree near the width's (it ran to 52-55
    # before). The transform stays at its rounding-level accuracy: the l2 limit is 2 tol
    # plus 1e-14 for the rounding of the spread sums and of the exact sum itself
    # (measured 1.06e-14 at 5e-15, 2.5e-14 at 5e-14).
    k = kernel_for(64, tol)
    assert k.coef.shape[0] - 1 <= k.width + 4
    s = np.linspace(0.0, 1.0, 997, endpoint=False)
    for j in range(k.width):
        z = s + j - 0.5 * k.width
        exact = np.exp(k.beta * (np.sqrt(np.maximum(1.0 - (2.0 * z / k.width) ** 2, 0.0)) - 1.0))
        assert np.max(np.abs(np.polynomial.polynomial.polyval(2.0 * s - 1.0, k.coef[::-1, j]) - exact)) <= 1e-14
    rng = np.random.default_rng(9)
    x = rng.uniform(-np.pi, np.pi, 400)
    st = rng.normal(size=(2, 400)) + 1j * rng.normal(size=(2, 400))
    assert _rel(nufft1d(x, st, 64, tol), _exact(x, st, 64)) <= 2.0 * tol + 1e-14
