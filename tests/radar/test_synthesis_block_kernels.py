"""The 2-D mover path's compiled per-block passes against their NumPy references.

The compiled passes (``twinsense.radar.kernels``: ``leg_offsets``,
``block_coefficients``, ``block_series``) make the
same floating-point operations in the same order as the NumPy forms
(``nufft._Leg(compiled=False)``, ``_leg_series`` + ``_monomial_coeffs``,
``_series_numpy``), without fastmath, so the results are compared bit for bit.
The whole planned block and its IF rows are then the same bits too, and the
end-to-end accuracy against the exact sum is held by test_synthesis_2d.py.
"""

from __future__ import annotations

import numpy as np
import pytest

import twinsense.radar.nufft as nufft
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.radar import AntennaArray, ChirpConfig, IFChain, RadarConfig, ula_positions
from twinsense.radar.kernels import block_coefficients
from twinsense.radar.nufft import (
    Geometry,
    _block_strengths,
    _coeffs_compiled,
    _Leg,
    _leg_series,
    _monomial_coeffs,
    _plan_block,
    _run_block,
)


def _config(num_chirps=16, num_samples=128):
    chirp = ChirpConfig.from_frequencies(58e9, 62e9, 2e6, num_samples, num_chirps, 150e-6, 0.05)
    return RadarConfig(chirp, AntennaArray(np.array([[-0.01, 0.0, 0.0]]), ula_positions(2, 2.5e-3)),
                       IFChain(complex_if=True))


def _movers(rng, n, speed):
    """Points 0.3-3 m in front of the radar with velocities up to ``speed`` [m/s] a side."""
    p = rng.uniform([-1.0, -0.8, 0.3], [1.0, 0.8, 3.0], (n, 3))
    v = rng.uniform(-speed, speed, (n, 3))
    return p, v, rng.lognormal(0, 1, n) * np.exp(1j * rng.uniform(0, 2 * np.pi, n))


def _block_setup(cfg):
    c = cfg.chirp
    geo = Geometry(cfg, c.num_chirps)
    centres = c.chirp_times() + c.adc_start_time + (c.num_samples // 2) / c.sample_rate
    chirps = np.arange(c.num_chirps)
    t_mid = float(centres[len(chirps) // 2])
    a_step = float(centres[1] - centres[0])
    t_span = a_step * (len(chirps) // 2) + (geo.n_samp // 2) / geo.fs
    return geo, chirps, t_mid, a_step, t_span


def _plans(p, v, geo, chirps, t_mid, a_step, **kw):
    """The compiled and the NumPy plan of one block of movers (eps 1e-6), checked the same bits
    in everything both variants have: order, kept terms, rests, phases and positions."""
    args = (p, v, p, v, geo.tx_per_chirp[0], geo.rx[0], chirps, t_mid, a_step, geo, 1e-6)
    fast, ref = _plan_block(*args, **kw), _plan_block(*args, compiled=False, **kw)
    assert fast is not None and ref is not None
    assert (fast.order, fast.keep, fast.common) == (ref.order, ref.keep, ref.common)
    assert list(fast.resid) == list(ref.resid)
    for key in ref.resid:
        np.testing.assert_array_equal(fast.resid[key], ref.resid[key])
    np.testing.assert_array_equal(fast.phi0, ref.phi0)
    np.testing.assert_array_equal(fast.x, ref.x)
    return fast, ref


def _assert_same_rows(fast, ref, w, geo):
    """The two plans' IF rows for strengths ``w``, compiled and NumPy: the same bits (2-D
    vectors). 1-D vectors: the compiled pass multiplies the series by the strengths and
    spreads at once (radar.spreader.spread_series_1d), NumPy's complex product rounds
    in another order: equal to rounding, each of the ~6,000 products per grid point off by
    an ulp at most, so 1e-12 of the largest sample (measured: 2e-16 of it)."""
    a = _run_block(fast, w, geo, 1e-6)
    b = _run_block(ref, w, geo, 1e-6, compiled=False)
    if fast.w is None:
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * np.abs(b).max())
    else:
        np.testing.assert_array_equal(a, b)


def test_leg_offsets_are_the_numpy_bits():
    rng = np.random.default_rng(1)
    p, v, _ = _movers(rng, 500, 3.0)
    element = np.array([0.004, -0.002, 0.0])
    fast, ref = _Leg(p, v, 0.013, element, 2e-3), _Leg(p, v, 0.013, element, 2e-3, compiled=False)
    for a, b in ((fast.d, ref.d), (fast.r0, ref.r0), (fast.y, ref.y)):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("order", [1, 2, 3])
def test_block_coefficients_are_the_numpy_bits(order):
    cfg = _config()
    geo, _, t_mid, a_step, t_span = _block_setup(cfg)
    rng = np.random.default_rng(order)
    p, v, _ = _movers(rng, 400, 4.0)
    leg_tx = _Leg(p, v, t_mid, geo.tx[0], t_span)
    leg_rx = _Leg(p, v, t_mid, geo.rx[1], t_span)
    span = t_span ** np.arange(order + 1)
    coeffs, dmax, extremes = _coeffs_compiled(leg_tx, leg_rx, order, geo, a_step, span)
    tau = (_leg_series(leg_tx.d, v, order)[0] + _leg_series(leg_rx.d, v, order)[0]) * (
        1.0 / SPEED_OF_LIGHT)
    ref = _monomial_coeffs(tau, geo, a_step)
    assert list(coeffs) == list(ref)  # the same monomials in the same order
    for key in ref:
        np.testing.assert_array_equal(coeffs[key], ref[key])
        assert extremes[key] == (ref[key].max(), ref[key].min())
    acc = np.abs(tau[1]) * span[1]
    for k in range(2, order + 1):
        acc += np.abs(tau[k]) * span[k]
    assert dmax == float(acc.max())


@pytest.mark.parametrize("order", [1, 3, 5])
def test_shared_transmit_series_are_the_numpy_bits(order):
    # The receivers of a block share their transmit leg's series (kernels.leg_series, kept
    # per order by the leg): _leg_series' bits, and block_coefficients given them or
    # forming them itself (any other first dimension, here (0, 0)) the same bits. 300
    # movers: two full tiles of 128 and a short one.
    cfg = _config()
    geo, _, t_mid, a_step, t_span = _block_setup(cfg)
    rng = np.random.default_rng(10 + order)
    p, v, _ = _movers(rng, 300, 3.0)
    leg_tx = _Leg(p, v, t_mid, geo.tx[0], t_span)
    leg_rx = _Leg(p, v, t_mid, geo.rx[0], t_span)
    series = leg_tx.compiled_series(order)
    np.testing.assert_array_equal(series, _leg_series(leg_tx.d, v, order)[0])
    assert leg_tx.compiled_series(order) is series  # kept for the other receiver
    outs = []
    for tx_series in (series, np.zeros((0, 0))):
        keys, (row, src, first, factor) = nufft._coefficient_sources(order, a_step, 1.0 / geo.fs)
        coeffs, acc = np.empty((len(keys), len(p))), np.empty(len(p))
        hi, lo = np.empty(len(keys)), np.empty(len(keys))
        block_coefficients(leg_tx.d, v, leg_rx.d, v, order, 1.0 / SPEED_OF_LIGHT, 2 * np.pi * geo.fc,
                           np.pi * geo.slope, 2 * np.pi * geo.slope, t_span ** np.arange(order + 1),
                           row, src, first, factor, coeffs, acc, hi, lo, tx_series)
        outs.append((coeffs, acc, hi, lo))
    for a, b in zip(*outs):
        assert a.tobytes() == b.tobytes()


@pytest.mark.parametrize("speed", [0.5, 1.5])
def test_planned_blocks_and_their_rows_are_the_numpy_bits(speed):
    # Slow movers: exp-series order 1; fast ones (1.5 m/s a side over 0.3-3 m): order >= 2
    # with products of the rests, the series' cross terms.
    cfg = _config()
    geo, chirps, t_mid, a_step, _ = _block_setup(cfg)
    rng = np.random.default_rng(7)
    p, v, w = _movers(rng, 600, speed)
    fast, ref = _plans(p, v, geo, chirps, t_mid, a_step)
    np.testing.assert_array_equal(fast.w, ref.w)
    if speed > 1.0:
        assert fast.order >= 2
    strength = w.astype(complex)
    s_fast, s_ref = _block_strengths(fast, strength), _block_strengths(fast, strength, compiled=False)
    assert list(s_fast) == list(s_ref)
    for key in s_ref:
        np.testing.assert_array_equal(s_fast[key], s_ref[key])
    _assert_same_rows(fast, ref, w, geo)


@pytest.mark.parametrize("speed", [0.5, 1.5])
def test_1d_variant_blocks_and_their_rows_are_the_numpy_bits(speed):
    # The slow-time frequency as a rest (1-D vectors): 600 of 3000 movers sorted by
    # range rate, a narrow band of it as in a chunk of the synthesis.
    cfg = _config()
    geo, chirps, t_mid, a_step, _ = _block_setup(cfg)
    rng = np.random.default_rng(8)
    p, v, w = _movers(rng, 3000, speed)
    order = np.argsort(np.einsum("ij,ij->i", p, v) / np.linalg.norm(p, axis=1), kind="stable")
    p, v, w = p[order[1200:1800]], v[order[1200:1800]], w[order[1200:1800]]
    fast, ref = _plans(p, v, geo, chirps, t_mid, a_step, slow=True)
    assert fast.w is None and ref.w is None and (1, 0) in fast.resid
    _assert_same_rows(fast, ref, w, geo)


def test_abs_sum_max_is_the_numpy_bits():
    # The block plan's largest summed |rest| (the exp series' order comes from it): the
    # compiled pass against NumPy's sum of |rows| from 0, row by row, and its max.
    from twinsense.radar.kernels import abs_sum_max

    rng = np.random.default_rng(12)
    for n_rows in (1, 3, 7):
        rows = rng.normal(0.0, 1e-3, (n_rows, 1001))
        ref = float(np.max(sum((np.abs(r) for r in rows), np.zeros(rows.shape[1]))))
        assert abs_sum_max(rows) == ref
