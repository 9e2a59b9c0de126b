"""The movers' compiled sort by range rate and gather, against NumPy's stable argsort and take;
the compiled test of which scatterers move, against its NumPy form."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import twinsense.radar.synthesis as synthesis
from twinsense.radar.kernels import (
    faster_than,
    gather_movers,
    rate_keys,
    stable_argsort,
    stable_argsort_into,
)
from twinsense.radar.presets import paper_bgt60tr13c_config


def _argsort(rate):
    keys = np.empty(len(rate), np.uint64)
    rate_keys(np.ascontiguousarray(rate, dtype=float), keys)
    return stable_argsort(keys)


@pytest.mark.parametrize("case", ["spread", "ties", "zeros", "one_run"])
def test_stable_radix_argsort_is_numpys_order(case):
    rng = np.random.default_rng(3)
    n = 20_000
    if case == "spread":
        rate = rng.normal(0.0, 0.5, n) * 10.0 ** rng.uniform(-6, 1, n)
    elif case == "ties":
        rate = rng.integers(-5, 6, n).astype(float) * 0.25  # long runs of equal keys
    elif case == "zeros":
        rate = np.where(rng.random(n) < 0.5, 0.0, -0.0) * rng.integers(0, 2, n)  # +0 and -0 equal
        rate[::7] = rng.normal(size=len(rate[::7]))
    else:
        # Every key shares its top 32 bits (a rate band of ~1e-9 m/s): the insertion budget
        # runs out and the full radix sort takes over.
        rate = 1.0 + rng.uniform(0.0, 1e-9, n)
    np.testing.assert_array_equal(_argsort(rate), np.argsort(rate, kind="stable"))


@pytest.mark.parametrize("case", ["spread", "one_run"])
def test_sort_into_kept_buffers_is_numpys_order(case):
    # The synthesis keeps the sort's work arrays between frames: buffers full of an earlier
    # sort's entries (here: garbage) and views of longer ones give NumPy's order, on the
    # radix path and on the full radix fallback (one_run: every key's top 32 bits alike).
    rng = np.random.default_rng(6)
    n = 20_000
    rate = (rng.normal(0.0, 0.5, n) if case == "spread" else 1.0 + rng.uniform(0.0, 1e-9, n))
    keys = np.empty(n, np.uint64)
    rate_keys(rate, keys)
    big = rng.integers(0, 2**63, (3, n + 77)).astype(np.uint64)
    idx = big[2].view(np.int64)[5:5 + n]
    for _ in range(2):  # the second time on the first sort's leftovers
        stable_argsort_into(keys, big[0, :n], big[1, 3:3 + n], idx)
        np.testing.assert_array_equal(idx, np.argsort(rate, kind="stable"))


def test_faster_than_is_the_numpy_comparison():
    # |v|^2 > limit as synthesis._norm2 sums it: the same bits, so the same rows, also for
    # speeds a rounding away from the limit (v = sqrt(limit) along x, one ulp either side).
    rng = np.random.default_rng(5)
    limit2 = (0.5 * 3e-7) ** 2
    v = rng.normal(size=(5000, 3)) * 10.0 ** rng.uniform(-9, 0, (5000, 1))
    v[::11] = 0.0
    edge = np.sqrt(limit2)
    v[1:40:3] = [np.nextafter(edge, 0.0), 0.0, 0.0]
    v[2:40:3] = [edge, 0.0, 0.0]
    v[3:40:3] = [np.nextafter(edge, 1.0), 0.0, 0.0]
    moving = np.empty(len(v), bool)
    count = faster_than(v, limit2, moving)
    ref = synthesis._norm2(v) > limit2
    np.testing.assert_array_equal(moving, ref)
    assert count == int(np.count_nonzero(ref))
    assert 0 < count < len(v)


def test_gather_is_numpys_take():
    rng = np.random.default_rng(4)
    p, v = rng.normal(size=(500, 3)), rng.normal(size=(500, 3))
    w = rng.normal(size=500) + 1j * rng.normal(size=500)
    rows = rng.permutation(500)[:300]
    pm, vm, wm = np.empty((300, 3)), np.empty((300, 3)), np.empty(300, complex)
    gather_movers(rows, p, v, w, pm, vm, wm)
    assert pm.tobytes() == np.take(p, rows, axis=0).tobytes()
    assert vm.tobytes() == np.take(v, rows, axis=0).tobytes()
    assert wm.tobytes() == np.take(w, rows).tobytes()


def test_the_synthesis_bytes_do_not_depend_on_the_sort(monkeypatch):
    # More movers than a chunk (16,384), so they are sorted by range rate: the cube from the
    # compiled sort and gather is the one from NumPy's, byte for byte.
    rng = np.random.default_rng(5)
    n = 20_000
    p = rng.uniform([-1.0, -1.0, 0.5], [1.0, 1.0, 3.0], (n, 3))
    v = -(np.array([0.1, 0.0, 0.4]) + np.cross([0.0, 0.3, 0.1], p))
    w = rng.lognormal(0, 1, n) * 1e-6 * np.exp(1j * rng.uniform(0, 2 * np.pi, n))
    cfg = paper_bgt60tr13c_config()
    cfg = cfg.with_overrides(chirp=dataclasses.replace(cfg.chirp, num_samples=64, num_chirps=4))
    cube = synthesis.synthesize(p, v, w, cfg, eps=1e-4)
    # Chunks gathered and run on two worker threads, summed in chunk order: the same bytes.
    assert cube.tobytes() == synthesis.synthesize(p, v, w, cfg, eps=1e-4, workers=2).tobytes()
    monkeypatch.setattr(synthesis, "COMPILED_SORT", False)
    assert cube.tobytes() == synthesis.synthesize(p, v, w, cfg, eps=1e-4).tobytes()


def test_a_frame_of_movers_and_still_scatterers_the_same_bytes(monkeypatch):
    # Half the scatterers still (static chunks beside the sorted mover chunks), 2 workers
    # against NumPy's sort and gathers on one: the same bytes.
    rng = np.random.default_rng(8)
    n = 40_000
    p = rng.uniform([-1.0, -1.0, 0.5], [1.0, 1.0, 3.0], (n, 3))
    v = -(np.array([0.1, 0.0, 0.4]) + np.cross([0.0, 0.3, 0.1], p)) * (rng.random((n, 1)) < 0.5)
    w = rng.lognormal(0, 1, n) * 1e-6 * np.exp(1j * rng.uniform(0, 2 * np.pi, n))
    cfg = paper_bgt60tr13c_config()
    cfg = cfg.with_overrides(chirp=dataclasses.replace(cfg.chirp, num_samples=64, num_chirps=4))
    cube = synthesis.synthesize(p, v, w, cfg, eps=1e-4, workers=2)
    monkeypatch.setattr(synthesis, "COMPILED_SORT", False)
    assert cube.tobytes() == synthesis.synthesize(p, v, w, cfg, eps=1e-4).tobytes()


def test_nan_and_infinite_rates_sort_as_numpy_does():
    # NaNs of both signs (x86's 0/0 and inf/inf give one with the sign bit set, which the
    # bit trick alone sorted first) last in index order, infinities at the ends, +-0 equal.
    rng = np.random.default_rng(6)
    rate = rng.normal(size=3000)
    neg_nan = np.array([0xFFF8000000000000], np.uint64).view(np.float64)[0]
    rate[::11] = neg_nan
    rate[5::13] = np.nan
    rate[3::17] = np.inf
    rate[7::19] = -np.inf
    rate[2::23] = -0.0
    rate[4::29] = 0.0
    np.testing.assert_array_equal(_argsort(rate), np.argsort(rate, kind="stable"))
