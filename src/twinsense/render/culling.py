"""Ray culling against bounding volumes: which rays can reach a moving object.

A moving object is traced only for the rays that meet its bounding sphere
(world frame) and then its bounding box (object frame). Both tests are
conservative: a ray that can hit the object before ``t_max`` is never dropped.
"""

from __future__ import annotations

import numpy as np


def rays_hit_box(o: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray, t_max: np.ndarray) -> np.ndarray:
    """(n,) bool: rays (origins o, shared (stride 0) or (n, 3); directions d (n, 3)) that
    enter the axis-aligned box [lo, hi] before ``t_max`` (slab test, one axis at a time)."""
    near = np.zeros(len(d))
    far = np.array(t_max, dtype=float, copy=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        for a in range(3):
            oa = o[0, a] if o.strides[0] == 0 else o[:, a]
            inv = 1.0 / d[:, a]
            t1 = (lo[a] - oa) * inv
            t2 = (hi[a] - oa) * inv
            # fmin/fmax ignore the NaN of 0 * inf (a ray lying in a slab's plane).
            near = np.fmax(near, np.fmin(t1, t2))
            far = np.fmin(far, np.fmax(t1, t2))
    return near <= far


def rays_near_sphere(o: np.ndarray, d: np.ndarray, centre: np.ndarray, radius: float,
                      t_max: np.ndarray) -> np.ndarray:
    """Indices of rays (unit d) that enter the sphere before distance ``t_max``."""
    if o.strides[0] == 0:  # one shared origin (a camera): scalar offsets
        w = centre - o[0]
        tca = d[:, 0] * w[0]
        tca += d[:, 1] * w[1]
        tca += d[:, 2] * w[2]
        # Outside the sphere, the rays that meet it form a cone around w:
        # tca >= sqrt(|w|^2 - r^2) (this also gives tca > 0); inside, all rays do.
        w2 = float(w @ w)
        cand = (np.flatnonzero(tca >= np.sqrt(w2 - radius * radius)) if w2 > radius * radius
                else np.arange(len(d)))
        tc = np.take(tca, cand)
        return cand[(tc + radius > 0) & (tc - radius < np.take(t_max, cand))]
    w = centre - o
    tca = d[:, 0] * w[:, 0] + d[:, 1] * w[:, 1] + d[:, 2] * w[:, 2]
    d2 = w[:, 0] ** 2 + w[:, 1] ** 2 + w[:, 2] ** 2 - tca * tca
    return np.nonzero((d2 <= radius * radius) & (tca + radius > 0) & (tca - radius < t_max))[0]
