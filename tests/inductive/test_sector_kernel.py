"""The compiled per-sector sum against the model's formula written in NumPy, on random hit patterns.

Also: at one distance per sector the ring sum telescopes to the disc of the outermost ring."""

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
    m = mat[outer, cols]

    def table(k, dd):  # dZ(m, dd, a_k) per sector, 0 for k < 0 (the zero radius)
        x = (np.clip(dd, model.distances[0], model.distances[-1]) - model.grid[0]) / (model.grid[1] - model.grid[0])
        i0 = np.minimum(x.astype(np.int64), len(model.grid) - 2)
        t = x - i0
        kk = np.maximum(k, 0)
        val = (1 - t) * model._dense[m, i0, kk] + t * model._dense[m, i0 + 1, kk]
        return np.where(k >= 0, val, 0.0)

    total = np.zeros(len(cols), complex)
    for k in range(K):
        dk = np.where(h[k], d[k, cols], dist)  # a ring without a hit: the sector's mean distance
        inc = table(np.full(len(cols), k), dk) - table(np.full(len(cols), k - 1), dk)
        total += np.where(k <= outer, inc, 0.0)
    return complex(np.sum(frac * total) / S)


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


def test_sector_at_one_distance_is_a_sector_of_the_outer_disc():
    # Every ray of the inner two rings at one distance: the disc of the middle table radius exactly
    # (the telescoping sum; same table values, so to rounding: rel 1e-12).
    sensor = InductiveSensor.preset("m18_flush")
    sensor.prepare()
    model = sensor.model
    S = model.sectors
    mat = np.array([0] * (2 * S) + [-1] * S)
    d = np.full(3 * S, 0.7 * sensor.config.rated_distance)
    want = model.disc(0, d[0], 1)[0]
    assert model.delta_z(mat, d) == pytest.approx(want, rel=1e-12, abs=1e-15)
