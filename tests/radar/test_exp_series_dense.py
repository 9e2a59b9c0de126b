"""The dense form of the 2-D exp series' monomial selection against the dictionaries'."""

from __future__ import annotations

import numpy as np
import pytest

import twinsense.radar.nufft as nufft


def test_dense_selection_is_the_dictionaries(monkeypatch):
    # Random rests, orders 1-12 and tolerances: the same kept monomials; majorants and the
    # skipped total equal to 1e-12 relative (sums of at most a few hundred positive terms in
    # another order: each rounding 1.1e-16, so ~1e-14 at most).
    monkeypatch.setattr(nufft, "_DENSE_ORDER", 10**6)  # the dictionaries for every order
    rng = np.random.default_rng(11)
    keys = [(1, 1), (2, 0), (0, 2), (0, 3), (1, 0), (1, 2), (2, 1), (0, 4), (3, 0)]
    for _ in range(400):
        chosen = [keys[i] for i in rng.choice(len(keys), rng.integers(1, 9), replace=False)]
        bounds = {k: float(10 ** rng.uniform(-8, 0.3)) for k in chosen}
        order, tol = int(rng.integers(1, 13)), float(10 ** rng.uniform(-9, -3))
        dense, skipped_dense = nufft._exp_series_2d_dense(bounds, order, tol)
        ref, skipped = nufft._exp_series_2d(bounds, order, tol)
        assert set(dense) == set(ref)
        for key, c in ref.items():
            assert dense[key] == pytest.approx(c, rel=1e-12, abs=0.0)
        assert skipped_dense == pytest.approx(skipped, rel=1e-12, abs=1e-300)
        assert skipped_dense <= tol


def test_long_series_take_the_dense_form():
    bounds = {(1, 0): 0.8, (1, 1): 0.05, (0, 2): 0.01}
    order = nufft._DENSE_ORDER + 2
    assert nufft._exp_series_2d(bounds, order, 1e-6) == nufft._exp_series_2d_dense(bounds, order, 1e-6)


def test_kept_at_least_is_a_lower_bound():
    rng = np.random.default_rng(12)
    keys = [(1, 1), (2, 0), (0, 2), (0, 3), (1, 0), (1, 2)]
    for _ in range(300):
        chosen = [keys[i] for i in rng.choice(len(keys), rng.integers(1, 7), replace=False)]
        bounds = {k: float(10 ** rng.uniform(-8, 0.3)) for k in chosen}
        order, tol = int(rng.integers(1, 10)), float(10 ** rng.uniform(-9, -3))
        assert nufft._kept_at_least(bounds, order, tol) <= len(nufft._exp_series_2d(bounds, order, tol)[0])


def test_the_budget_cut_changes_no_result(monkeypatch):
    # Fast movers close to a moving radar (long series; the 2-D path tries several splits and
    # loses to the per-chirp one): the plans cut short by the budget give the same outcome as
    # the full selections.
    from twinsense.radar.presets import paper_bgt60tr13c_config

    rng = np.random.default_rng(13)
    n = 1500
    p = rng.uniform([-0.3, -0.3, 0.1], [0.3, 0.3, 0.6], (n, 3))
    v = -(np.array([0.3, 0.1, 1.2]) + np.cross([0.5, -1.5, 0.3], p))
    w = rng.lognormal(0, 1, n) * np.exp(1j * rng.uniform(0, 2 * np.pi, n))
    cfg = paper_bgt60tr13c_config()
    geo = nufft.Geometry(cfg, cfg.chirp.num_chirps)
    c = cfg.chirp
    centres = c.chirp_times() + c.adc_start_time + (c.num_samples // 2) / c.sample_rate
    selections = []  # the series' selections made with the cut and without
    real = nufft._exp_series_2d
    monkeypatch.setattr(nufft, "_exp_series_2d", lambda *a: selections.append(1) or real(*a))
    for eps in (1e-6, 1e-4):
        fast = nufft.moving_chunk_2d(p, v, None, None, w, geo, centres, eps)
        with_cut = len(selections)
        with monkeypatch.context() as m:
            m.setattr(nufft, "_kept_at_least", lambda *a: -(10**9))  # no cut
            ref = nufft.moving_chunk_2d(p, v, None, None, w, geo, centres, eps)
        assert (fast is None) == (ref is None)
        if fast is not None:
            assert fast.tobytes() == ref.tobytes()
        assert with_cut < len(selections) - with_cut  # the cut saved selections
        selections.clear()
