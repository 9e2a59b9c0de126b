"""The spreader's one-vector path (static rows, the noise estimate) against its many-vector
path (the same products in the same order: the same bits) and against the exact sum."""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.radar.spreader import kernel_for, nufft1d


@pytest.mark.parametrize("tol", [1e-3, 1e-6, 1e-9])
def test_one_vector_is_the_bits_of_the_many_vector_path(tol):
    # 1000 points (not a whole number of 64-point tiles), some beyond [-pi, pi] (wrapped).
    rng = np.random.default_rng(21)
    m = 1000
    x = rng.uniform(-np.pi, np.pi, m)
    x[::97] += 2 * np.pi
    s = rng.normal(size=(2, m)) + 1j * rng.normal(size=(2, m))
    kern = kernel_for(128, tol)
    one = kern.transform(x, s[:1])
    two = kern.transform(x, s)
    # Exact: the grid's entries of vector 0 get the same products in the same order.
    assert one[0].tobytes() == two[0].tobytes()


def test_one_vector_against_the_exact_sum():
    # The direct sum in float64: the l2 error within 2 tol (the spreader's documented bound,
    # tests/radar/test_nufft_spreader.py measures 0.7-1.3 tol).
    rng = np.random.default_rng(22)
    m, n = 3000, 64
    x = rng.uniform(-np.pi, np.pi, m)
    s = rng.normal(size=m) + 1j * rng.normal(size=m)
    k = np.arange(n) - n // 2
    exact = np.exp(1j * np.outer(k, x)) @ s
    for tol in (1e-3, 1e-6):
        err = np.linalg.norm(nufft1d(x, s, n, tol) - exact) / np.linalg.norm(exact)
        assert err <= 2 * tol
