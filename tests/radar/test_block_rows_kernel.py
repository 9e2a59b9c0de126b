"""The 1-D blocks' compiled monomial sums and chunk-wide phase against their NumPy form."""

from __future__ import annotations

import numpy as np
import pytest

import twinsense.radar.nufft as nufft
from twinsense.radar.presets import paper_bgt60tr13c_config


@pytest.mark.parametrize("eps", [1e-7, 1e-4])
def test_compiled_block_rows_are_the_numpy_rows_bit_for_bit(monkeypatch, eps):
    # Movers of a turning, translating radar (every block of the 1-D variant, forced): the
    # compiled pass repeats the NumPy passes' operations in their order, so the same bytes.
    rng = np.random.default_rng(21)
    n = 4000
    p = rng.uniform([-1.0, -1.0, 0.5], [1.0, 1.0, 3.0], (n, 3))
    v = -(np.array([0.05, 0.02, 0.3]) + np.cross([0.1, -0.2, 0.05], p))
    w = rng.lognormal(0, 1, n) * np.exp(1j * rng.uniform(0, 2 * np.pi, n))
    cfg = paper_bgt60tr13c_config()
    geo = nufft.Geometry(cfg, cfg.chirp.num_chirps)
    c = cfg.chirp
    centres = c.chirp_times() + c.adc_start_time + (c.num_samples // 2) / c.sample_rate
    order = np.argsort(np.einsum("ij,ij->i", p, v) / np.linalg.norm(p, axis=1), kind="stable")  # by range rate
    p, v, w = p[order], v[order], w[order]
    calls = []
    real = nufft._block_rows
    monkeypatch.setattr(nufft, "_block_rows", lambda *a, **k: calls.append(a) or real(*a, **k))
    cube = nufft.moving_chunk_2d(p, v, None, None, w, geo, centres, eps, force=True, slow=True)
    assert cube is not None and calls
    for args in calls:
        blk = args[0]
        assert blk.w is None and any(blk.common.values())
        assert real(*args).tobytes() == real(*args, compiled=False).tobytes()


def test_slow_rest_and_rest_rows_are_the_numpy_bits():
    # The block plan's two compiled passes (the 1-D variant's slow-time rest and the rests'
    # rows with their largest summed |rest|) against the NumPy operations they replace.
    from twinsense.radar.kernels import rest_rows, slow_rest

    rng = np.random.default_rng(22)
    m = 2001
    c10 = rng.uniform(-40.0, 40.0, m)
    delta = np.empty(m)
    hi, lo = slow_rest(c10, 1.25, 8.0, delta)
    ref = nufft._reduce(c10 - 1.25)
    ref *= 8.0
    assert delta.tobytes() == ref.tobytes() and (hi, lo) == (ref.max(), ref.min())
    src = rng.normal(0.0, 1e-3, (6, m))
    rows, scale, mid = np.array([4, -1, 0]), np.array([3.0, 1.0, 0.7]), np.array([1e-4, 0.0, -2e-5])
    stack = np.empty((3, m))
    best = rest_rows(src, rows, scale, mid, delta, stack)
    want = np.empty((3, m))
    for r, k in enumerate(rows):
        if k < 0:
            want[r] = delta
        else:
            np.multiply(src[k], scale[r], out=want[r])
            want[r] -= mid[r]
    assert stack.tobytes() == want.tobytes()
    assert best == float(np.max(sum((np.abs(r) for r in want), np.zeros(m))))
