"""The ToF frame's normals (SFC64 words -> float32 ziggurat normals) against NumPy and the normal law.

The words must be NumPy's own SFC64 words, bit for bit. The normals are this
package's own ziggurat, so they are tested as a distribution on 2,000,000
seeded draws: every statistic against its exact value with a tolerance of 5
standard errors of that statistic for N draws (or the Kolmogorov-Smirnov
critical value at alpha = 0.001); the seeds are fixed, so the tests are not flaky.
"""

import math

import numpy as np
import pytest
from scipy import special, stats

from twinsense.tof import normals

N = 2_000_000


@pytest.fixture(scope="module")
def draws() -> np.ndarray:
    return normals.standard_normals(20261124, np.empty(N, np.float32)).astype(np.float64)


@pytest.mark.parametrize("seed", [0, 1, 2 ** 62 + 12345])
def test_words_are_numpys_sfc64(seed):
    assert np.array_equal(normals.sfc64_words(seed, 10_000), np.random.SFC64(seed).random_raw(10_000))


def test_tables_give_every_layer_the_same_area():
    # Layer i >= 2 spans x in [0, x_i] and y in [f(x_i), f(x_{i-1})]: area x_i (f(x_{i-1}) - f(x_i)) = v,
    # v = r f(r) + int_r^inf f (the base: rectangle and tail), f(x) = exp(-x^2/2).
    r = normals.R
    v = r * math.exp(-0.5 * r * r) + math.sqrt(math.pi / 2) * special.erfc(r / math.sqrt(2))
    m = 2.0 ** 23
    x = normals._W.astype(np.float64) * m  # the float32 edges
    f = np.exp(-0.5 * x * x)
    area = x[2:] * (f[1:-1] - f[2:])
    # Tolerance: each edge is rounded to float32 (relative 2^-24); the area's relative error is then at most
    # 2^-24 (1 + (x_{i-1}^2 f(x_{i-1}) + x_i^2 f(x_i)) / (f(x_{i-1}) - f(x_i))), taken per layer (x f'(x) = -x^2 f).
    amp = 1 + (x[1:-1] ** 2 * f[1:-1] + x[2:] ** 2 * f[2:]) / (f[1:-1] - f[2:])
    assert np.all(np.abs(area / v - 1) <= 2.0 ** -24 * amp * 1.01)
    assert x[-1] == pytest.approx(r, rel=2.0 ** -24, abs=0.0)  # x_255 = r, rounded to float32
    # The top layer (no rectangle beneath) closes the recursion: its area x_1 (1 - f(x_1)) is v to the float32
    # rounding of x_1 (amplified as above with x_0 = 0).
    top = x[1] * (1 - f[1])
    assert top == pytest.approx(v, rel=2.0 ** -24 * (1 + x[1] ** 2 * f[1] / (1 - f[1])) * 1.01, abs=0.0)
    # The base layer's bound: the rectangle [0, r] of the base's width v / f(r), in 23-bit units.
    assert normals._K[0] == int(r / (v / math.exp(-0.5 * r * r)) * m)
    assert normals._K[1] == 0  # layer 1 always takes the wedge test


def test_same_seed_same_bytes_and_every_prefix_is_the_longer_runs(draws):
    short = normals.standard_normals(20261124, np.empty(100_003, np.float32))
    assert short.tobytes() == draws[:100_003].astype(np.float32).tobytes()
    again = normals.standard_normals(20261124, np.empty(100_003, np.float32))
    assert again.tobytes() == short.tobytes()
    other = normals.standard_normals(20261125, np.empty(100_003, np.float32))
    assert np.mean(other == short) < 1e-3  # another seed: another stream


def test_the_draws_are_standard_normal(draws):
    x = draws
    se = 1 / math.sqrt(N)
    assert abs(x.mean()) < 5 * se  # mean 0, standard error 1/sqrt(N)
    assert abs(x.var() - 1) < 5 * math.sqrt(2 / N)  # variance 1, standard error sqrt(2/N)
    assert abs(stats.skew(x)) < 5 * math.sqrt(6 / N)  # skewness 0, standard error sqrt(6/N)
    assert abs(stats.kurtosis(x)) < 5 * math.sqrt(24 / N)  # excess kurtosis 0, standard error sqrt(24/N)
    # Kolmogorov-Smirnov: the critical value at alpha = 0.001 is 1.95 / sqrt(N).
    assert stats.kstest(x, "norm").statistic < 1.95 / math.sqrt(N)
    # Draws one after another are independent: lag-1 correlation 0, standard error 1/sqrt(N).
    assert abs(np.corrcoef(x[:-1], x[1:])[0, 1]) < 5 * se
    # Signs: half positive (binomial, standard error 0.5/sqrt(N)).
    assert abs(np.mean(x > 0) - 0.5) < 5 * 0.5 * se


def test_the_tail_and_the_wedges_have_the_normal_shares(draws):
    x = draws
    # Beyond r (the tail method): a binomial share p = 2 Q(r), 5 standard errors.
    p = 2 * stats.norm.sf(normals.R)
    assert abs(np.mean(np.abs(x) > normals.R) - p) < 5 * math.sqrt(p * (1 - p) / N)
    assert np.abs(x).max() > normals.R + 0.5  # the tail reaches beyond r (P(|x| > 4.15) ~ 3e-5: ~65 draws)
    # 400 equal bins over [-4, 4] (the wedges' curved edges inside): Pearson's chi-square with 400 degrees of
    # freedom (399 bins and the rest) below its mean + 5 standard deviations, 400 + 5 sqrt(800).
    edges = np.linspace(-4.0, 4.0, 400)
    counts = np.histogram(x, np.concatenate(([-np.inf], edges, [np.inf])))[0]
    want = N * np.diff(stats.norm.cdf(np.concatenate(([-np.inf], edges, [np.inf]))))
    chi2 = np.sum((counts - want) ** 2 / want)
    assert chi2 < 400 + 5 * math.sqrt(800)
