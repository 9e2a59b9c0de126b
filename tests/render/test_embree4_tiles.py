"""The packet-tile ray order that ``bench_embree4.py --packets`` times: a permutation of the image's
rays, tile after tile, with partial tiles at the right and bottom edges of odd-sized images."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

_DIR = Path(__file__).resolve().parents[2] / "benchmarks"


@pytest.fixture
def bench(monkeypatch):
    monkeypatch.syspath_prepend(str(_DIR))  # the script imports its sibling _timing
    spec = importlib.util.spec_from_file_location("twinsense_bench_embree4_tiles", _DIR / "bench_embree4.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("height, width, th, tw", [(342, 448, 2, 4), (342, 448, 4, 2), (7, 9, 2, 4),
                                                    (5, 3, 4, 4), (1, 1, 2, 4), (6, 8, 1, 8)])
def test_tiles_are_a_permutation_that_round_trips(bench, height, width, th, tw):
    order = bench.tiles(height, width, th, tw)
    n = height * width
    assert order.dtype == np.int64 and order.shape == (n,)
    np.testing.assert_array_equal(np.sort(order), np.arange(n))  # every ray once
    inverse = np.empty(n, np.int64)
    inverse[order] = np.arange(n)
    values = np.random.default_rng(1).normal(size=n)
    np.testing.assert_array_equal(values[order][inverse], values)  # back to image order
    # Rays of one tile are consecutive: tile (i, j) covers rows i th.., columns j tw.., cut at the edges.
    r, c = np.divmod(order, width)
    tile = (r // th) * (-(-width // tw)) + c // tw
    assert np.all(np.diff(tile) >= 0)
    sizes = np.bincount(tile)
    want = [min(th, height - i * th) * min(tw, width - j * tw)
            for i in range(-(-height // th)) for j in range(-(-width // tw))]
    np.testing.assert_array_equal(sizes, want)
