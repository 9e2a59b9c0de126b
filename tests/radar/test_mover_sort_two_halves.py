"""The movers' sort on two workers (two halves sorted apart, one stable merge) against
NumPy's stable argsort, and the cube's bytes with one and two workers."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import twinsense.radar.synthesis as synthesis
from twinsense.radar.kernels import merge_orders, rate_keys, stable_argsort
from twinsense.radar.presets import paper_bgt60tr13c_config


def _rates(case: str, n: int, rng) -> np.ndarray:
    if case == "spread":
        return rng.normal(0.0, 0.5, n) * 10.0 ** rng.uniform(-6, 1, n)
    if case == "ties":
        return rng.integers(-5, 6, n).astype(float) * 0.25  # equal keys across both halves
    rate = rng.normal(size=n)
    rate[::11] = np.nan
    rate[3::17] = np.inf
    rate[7::19] = -np.inf
    rate[2::23] = -0.0
    rate[4::29] = 0.0
    return rate


@pytest.mark.parametrize("case", ["spread", "ties", "special"])
@pytest.mark.parametrize("cut", [0, 1, 4999, 10_000])
def test_merged_halves_are_numpys_stable_order(case, cut):
    # Exact: an order is a permutation, equal or not. Ties across the cut must keep the left
    # half first; a cut at 0 leaves one half empty.
    rng = np.random.default_rng(11)
    rate = _rates(case, 10_000, rng)
    keys = np.empty(len(rate), np.uint64)
    rate_keys(rate, keys)
    left = stable_argsort(keys[:cut])
    right = stable_argsort(keys[cut:]) + cut
    out = np.empty(len(rate), np.int64)
    merge_orders(keys, left, right, out)
    np.testing.assert_array_equal(out, np.argsort(rate, kind="stable"))


def _moving_scene(n: int, seed: int):
    # A sensor on a moving arm: every scatterer moves with one rigid motion.
    rng = np.random.default_rng(seed)
    p = rng.uniform([-1.0, -1.0, 0.5], [1.0, 1.0, 3.0], (n, 3))
    v = -(np.array([0.1, 0.0, 0.4]) + np.cross([0.0, 0.3, 0.1], p))
    w = rng.lognormal(0, 1, n) * 1e-6 * np.exp(1j * rng.uniform(0, 2 * np.pi, n))
    return p, v, w


def test_sorted_rates_do_not_depend_on_the_workers():
    # More than two chunks of movers: two halves on two workers. Rates and order exact.
    p, v, _ = _moving_scene(40_000, 12)
    rows = np.random.default_rng(13).permutation(40_000)[:35_000]
    # The results are the thread's work arrays: copied before the next call.
    rate1, order1 = (a.copy() for a in synthesis._sorted_rates(p, v, rows, 1))
    rate2, order2 = synthesis._sorted_rates(p, v, rows, 2)
    assert rate1.tobytes() == rate2.tobytes() == synthesis._range_rate(p, v, rows).tobytes()
    np.testing.assert_array_equal(order1, order2)
    np.testing.assert_array_equal(order2, np.argsort(rate1, kind="stable"))


def test_cube_bytes_equal_with_one_and_two_workers(monkeypatch):
    # 34,000 movers (> 2 chunks): the two-half sort runs with 2 workers. The cube is the
    # same bytes as with one worker and as with NumPy's sort and gathers.
    p, v, w = _moving_scene(34_000, 14)
    cfg = paper_bgt60tr13c_config()
    cfg = cfg.with_overrides(chirp=dataclasses.replace(cfg.chirp, num_samples=64, num_chirps=4))
    cube2 = synthesis.synthesize(p, v, w, cfg, eps=1e-4, workers=2)
    assert cube2.tobytes() == synthesis.synthesize(p, v, w, cfg, eps=1e-4, workers=1).tobytes()
    monkeypatch.setattr(synthesis, "COMPILED_SORT", False)
    assert cube2.tobytes() == synthesis.synthesize(p, v, w, cfg, eps=1e-4).tobytes()


def test_tasks_run_dearest_first_and_sum_in_task_order(monkeypatch):
    # Half the scatterers move (2 mover chunks of 10,000, 3 static chunks): the workers get
    # the movers first, larger chunks before smaller ones and, at equal size, the larger
    # |range rate| first; the cube is the bytes of one worker. The velocities reversed so
    # the rates run from -0.07 to +0.41 m/s: the second chunk (the fastest) runs first.
    p, v, w = _moving_scene(40_000, 15)
    v = -v
    v[::2] = 0.0
    cfg = paper_bgt60tr13c_config()
    cfg = cfg.with_overrides(chirp=dataclasses.replace(cfg.chirp, num_samples=64, num_chirps=4))
    seen = []
    real = synthesis.map_ordered

    def recording(fn, items, workers=1):
        items = list(items)
        if items and isinstance(items[0][0], str):
            seen.append(items)
        return real(fn, items, workers)

    monkeypatch.setattr(synthesis, "map_ordered", recording)
    cube2 = synthesis.synthesize(p, v, w, cfg, eps=1e-4, workers=2)
    (order,) = seen
    kinds = [k for k, _, _ in order]
    assert kinds == sorted(kinds)  # "moving" before "static"
    assert order[:2] == [("moving", 10_000, 20_000), ("moving", 0, 10_000)]
    for kind in ("moving", "static"):
        sizes = [hi - lo for k, lo, hi in order if k == kind]
        assert sizes == sorted(sizes, reverse=True)
    monkeypatch.setattr(synthesis, "map_ordered", real)
    assert cube2.tobytes() == synthesis.synthesize(p, v, w, cfg, eps=1e-4, workers=1).tobytes()
