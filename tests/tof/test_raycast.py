"""Culling helpers of the ToF caster against brute-force sampling."""

from __future__ import annotations

import numpy as np

from twinsense.tof.raycast import _rays_hit_box, _rays_near_sphere, rotate_rows


def _sampled_hits(o, d, inside_fn, t_max=6.0, steps=3001):
    ts = np.linspace(0, t_max, steps, dtype=np.float32)
    p = o + d[:, None, :] * ts[None, :, None]
    return inside_fn(p).any(axis=1)


def test_box_and_sphere_culling_keep_every_ray_that_enters():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(3000, 3)).astype(np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:5] = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, 0, -1]]  # axis-parallel rays
    o = np.array([-2.0, 0.1, 0.2], np.float32)
    lo, hi = np.array([-0.2, -0.3, -0.9], np.float32), np.array([0.2, 0.3, 0.9], np.float32)
    dist = np.full(len(d), np.inf, np.float32)
    box = _rays_hit_box(o, d, np.eye(3, dtype=np.float32), lo, hi, dist)
    # Sampling every 2 mm along each ray finds every ray that crosses the box by more than
    # 2 mm; the slab test may only add rays that graze it.
    sampled = _sampled_hits(o, d, lambda p: np.all((p >= lo) & (p <= hi), axis=2))
    assert np.all(box[sampled])
    assert box.sum() - sampled.sum() <= 2
    assert box[0] and not box[3]  # straight through, and straight away from it
    radius = float(np.linalg.norm(hi))
    near = np.zeros(len(d), bool)
    near[_rays_near_sphere(np.tile(o, (len(d), 1)), d, np.zeros(3), radius, dist)] = True
    # The bounding sphere contains the box: every box ray passes the sphere test too.
    assert np.all(near[box])
    # A closer hit already found hides the box.
    assert not np.any(_rays_hit_box(o, d, np.eye(3, dtype=np.float32), lo, hi, np.full(len(d), 1.0, np.float32)))
    # A rotated box: directions are turned into its frame column by column.
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], np.float32)  # 90 deg about z
    turned = _rays_hit_box(o @ rot, d, rot, lo, hi, dist)
    sampled_rot = _sampled_hits(o @ rot, d @ rot, lambda p: np.all((p >= lo) & (p <= hi), axis=2))
    assert np.all(turned[sampled_rot]) and turned.sum() - sampled_rot.sum() <= 2


def test_rotate_rows_is_a_matrix_product():
    rng = np.random.default_rng(1)
    v = rng.normal(size=(50, 3)).astype(np.float32)
    m = rng.normal(size=(3, 3))
    np.testing.assert_allclose(rotate_rows(v, m), v @ m.astype(np.float32), rtol=1e-5, atol=1e-6)
