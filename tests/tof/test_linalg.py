"""twinsense.linalg.rotate_rows against NumPy's matrix product."""

from __future__ import annotations

import numpy as np

from twinsense.linalg import rotate_rows


def test_rotate_rows_is_a_matrix_product_in_the_rows_dtype():
    rng = np.random.default_rng(1)
    m = rng.normal(size=(3, 3))
    v64 = rng.normal(size=(500, 3))
    # Each entry is the same three products and two sums as a BLAS dot of length 3,
    # possibly in another order: equal to a few ulp (1e-12 relative is ~5000 ulp of slack).
    np.testing.assert_allclose(rotate_rows(v64, m), v64 @ m, rtol=1e-12, atol=1e-14)
    v32 = v64.astype(np.float32)
    out32 = rotate_rows(v32, m)
    assert out32.dtype == np.float32 and out32.flags.c_contiguous and out32.base is None
    # float32: the matrix is rounded to float32 first, as before (1e-5 ~ 100 ulp).
    np.testing.assert_allclose(out32, v32 @ m.astype(np.float32), rtol=1e-5, atol=1e-6)
    ints = rng.integers(-5, 5, size=(20, 3))
    assert rotate_rows(ints, m).dtype == np.float64
    np.testing.assert_allclose(rotate_rows(ints, m), ints @ m, rtol=1e-12, atol=1e-12)
    # Leading axes are kept: an image of vectors (H, W, 3), a single vector (3,).
    img = rng.normal(size=(4, 5, 3))
    np.testing.assert_allclose(rotate_rows(img, m), img @ m, rtol=1e-12, atol=1e-14)
    assert rotate_rows(img[0, 0], m).shape == (3,)
    # Strided input (a column slice of a wider array) works too.
    wide = rng.normal(size=(50, 6))
    np.testing.assert_allclose(rotate_rows(wide[:, 1:4], m), wide[:, 1:4] @ m, rtol=1e-12, atol=1e-14)
