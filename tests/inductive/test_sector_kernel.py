"""The compiled per-sector sum against the model's formula written in NumPy, on random hit patterns."""

import numpy as np
import pytest

from twinsense.inductive import InductiveSensor


def numpy_delta_z(model, material, distance) -> complex:
    """``(1 / S) sum_s f_s dZ(m_s, d_s, a_{o_s})`` with array operations (see model.py's notes)."""
    K, S = len(model.edges) - 1, model.sectors
    mat = np.asarray(material).reshape(K, S)
    d = np.asarray(distance, dtype=float).reshape(K, S)
    hit = (mat >= 0) & (d <= model.distances[-1])
    if not hit.any():
        return 0j
    cols = np.flatnonzero(hit.any(axis=0))
    h = hit[:, cols]
    outer = K - 1 - np.argmax(h[::-1], axis=0)
    area = np.pi * np.diff(model.edges ** 2)
    w = np.where(h, area[:, None], 0.0)
    frac = w.sum(axis=0) / np.cumsum(area)[outer]
    dist = (w * np.where(h, d[:, cols], 0.0)).sum(axis=0) / w.sum(axis=0)
    x = (np.clip(dist, model.distances[0], model.distances[-1]) - model.grid[0]) / (model.grid[1] - model.grid[0])
    i0 = np.minimum(x.astype(np.int64), len(model.grid) - 2)
    t = x - i0
    m = mat[outer, cols]
    val = (1 - t) * model._dense[m, i0, outer] + t * model._dense[m, i0 + 1, outer]
    return complex(np.sum(frac * val) / S)


def test_compiled_sector_sum_matches_numpy():
    sensor = InductiveSensor.preset("m18_flush")
    sensor.prepare()
    model = sensor.model
    rng = np.random.default_rng(0)
    n = len(model.face_points())
    for _ in range(200):
        mat = np.where(rng.random(n) < 0.6, rng.integers(0, 5, n), -1)
        d = rng.uniform(0.0, 1.2 * model.distances[-1], n)  # below, inside and beyond the table
        d[rng.random(n) < 0.1] = np.inf
        # Same arithmetic in another order: agreement to a few ulps of the largest term (rel 1e-12).
        want = numpy_delta_z(model, mat, d)
        got = model.delta_z(mat, d)
        assert got == pytest.approx(want, rel=1e-12, abs=1e-15 * abs(model._dense).max())
    assert model.delta_z(np.full(n, -1), np.full(n, np.inf)) == 0j
