"""A 2-D block's phase coefficients at their extremes: a path leg of length 0, and the
shortest legs a block admits.

``kernels.block_coefficients`` divides by each leg's length r0 (its series' recursion
takes 0.5 / r0). Its one caller, ``nufft._plan_block`` (through ``_coeffs_array``), first
rejects a block in which any leg has y = t_span |v| / r0 above 0.5; a leg of length 0
gives y = inf (a moving leg) or NaN (a still one), and the check ``not y <= 0.5``
rejects both, so block_coefficients never sees r0 = 0: the chunk goes to the per-chirp
path. There a mover on an element has no expansion either (|v s| is not smooth at s = 0),
so ``synthesize`` raises a ConfigError naming the points instead of returning NaN. A
static scatterer on an element is well defined (its phase is linear in the path length:
nothing divides by it) and agrees with the exact sum.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_radar_blocks_compiled import coefficients_as_numpy

from twinsense.errors import ConfigError
from twinsense.radar import FMCWRadar, synthesize, synthesize_exact
from twinsense.radar.nufft import (
    Geometry,
    _Leg,
    _leg_series,
    _plan_block,
    moving_chunk_2d,
)


def _setup():
    """The wrist radar's config (receiver 0 at the sensor origin), its geometry, chirp
    centres [s] and the first transmit group's middle block (chirps, t_mid, a_step, t_span)."""
    cfg = FMCWRadar.preset("paper_bgt60tr13c").config
    c = cfg.chirp
    geo = Geometry(cfg, c.num_chirps)
    centres = c.chirp_times() + c.adc_start_time + (c.num_samples // 2) / c.sample_rate
    chirps = np.arange(c.num_chirps)
    t_mid = float(centres[chirps[len(chirps) // 2]])
    a_step = float(centres[1] - centres[0])
    t_span = a_step * (len(chirps) // 2) + (c.num_samples // 2) / geo.fs
    return cfg, geo, centres, chirps, t_mid, a_step, t_span


def _movers(rng, n):
    p = rng.uniform([-0.5, -0.5, 0.5], [0.5, 0.5, 1.5], (n, 3))
    v = rng.uniform(-0.3, 0.3, (n, 3))
    w = rng.normal(size=n) + 1j * rng.normal(size=n)
    return p, v, w


@pytest.mark.parametrize("still", [False, True])
def test_a_leg_of_length_zero_is_rejected_before_the_coefficients(still):
    # Mover 0 on receiver 0 (the sensor origin) at the block's centre time: its receive leg
    # has r0 = 0, so y = inf (moving) or NaN (a still receive leg, bistatic with vr = 0).
    _, geo, centres, chirps, t_mid, a_step, t_span = _setup()
    p, v, _ = _movers(np.random.default_rng(1), 300)
    pr, vr = p.copy(), v.copy()
    if still:
        vr[0] = 0.0
        pr[0] = geo.rx[0]
    else:
        pr[0] = geo.rx[0] - vr[0] * t_mid
    leg = _Leg(pr, vr, t_mid, geo.rx[0], t_span)
    assert leg.r0[0] == 0.0
    assert np.isnan(leg.y[0]) if still else np.isinf(leg.y[0])
    blk = _plan_block(p, v, pr, vr, geo.tx_per_chirp[0], geo.rx[0], chirps, t_mid, a_step, geo, 1e-5)
    assert blk is None
    # The other receiver's leg is fine, but the chunk's blocks need every receiver: no split.
    assert moving_chunk_2d(p, v, pr, vr, np.ones(len(p), complex), geo, centres, 1e-5,
                           force=True) is None


@pytest.mark.parametrize("order", [1, 2, 4])
def test_block_coefficients_at_the_shortest_admitted_legs(order):
    # The shortest legs the y check lets through: a moving leg at y = 0.499 (r0 = 2.004
    # t_span |v|, 1.5 mm here) and a still leg (v = 0: y = 0 for any r0 > 0) 1e-150 m from
    # its element (r0^2 = 1e-300, just above float64's normal range). Finite, and the bits
    # of the NumPy forms (_leg_series, _monomial_coeffs) as for ordinary legs.
    _, geo, _, _, t_mid, a_step, t_span = _setup()
    rng = np.random.default_rng(order)
    p, v, _ = _movers(rng, 200)
    speed = np.sqrt(np.sum(v * v, axis=1))
    direction = rng.normal(size=(len(p), 3))
    direction /= np.sqrt(np.sum(direction * direction, axis=1))[:, None]
    d = direction * (t_span * speed / 0.499)[:, None]
    pr, vr = p.copy(), v.copy()  # ordinary receive legs 0.5-1.5 m long ...
    p = geo.tx_per_chirp[0] + d - v * t_mid  # ... the transmit legs at y = 0.499
    vr[::2] = 0.0
    pr[::2] = geo.rx[0] + 1e-150 * direction[::2]  # still receive legs, 1e-150 m long
    leg_tx = _Leg(p, v, t_mid, geo.tx_per_chirp[0], t_span)
    leg_rx = _Leg(pr, vr, t_mid, geo.rx[0], t_span)
    assert np.all(leg_tx.y <= 0.5) and np.all(leg_rx.y <= 0.5)
    assert leg_rx.r0[::2].max() < 2e-150
    span = t_span ** np.arange(order + 1)
    coeffs, dmax, extremes, _, _ = coefficients_as_numpy(leg_tx, leg_rx, v, vr, order, geo, a_step, span)
    assert np.isfinite(dmax)
    assert all(np.all(np.isfinite(c)) for c in coeffs.values())
    assert all(np.isfinite(hi) and np.isfinite(lo) for hi, lo in extremes.values())
    # A still leg's series is its length alone (closed form: r_k = 0 for k >= 1).
    still = _leg_series(leg_rx.d[::2], vr[::2], order)[0]
    assert np.all(still[1:] == 0.0)


@pytest.mark.parametrize("n", [3, 2000])
def test_synthesize_rejects_a_mover_on_an_antenna_element(n):
    # 3 movers: the per-chirp path; 2,000: the 2-D blocks, which reject the chunk, then the
    # per-chirp path. Mover 0 sits on receiver 0 at chirp 8's centre.
    cfg, _, centres, _, _, _, _ = _setup()
    p, v, w = _movers(np.random.default_rng(n), n)
    p[0] = cfg.antennas.rx_positions[0] - v[0] * centres[8]
    with pytest.raises(ConfigError) as err:
        synthesize(p, v, w, cfg, eps=1e-5)
    assert err.value.field == "synthesize.points"
    assert "antenna element" in str(err.value)


def test_a_static_scatterer_on_an_antenna_element_is_the_exact_sum():
    # A static scatterer on receiver 0 (path leg 0 m) beside ordinary ones: the cube is
    # finite and within 2 eps (l2, relative) of the exact sum, the synthesis' documented
    # bound (synthesis.py: the transforms about eps, the series up to eps more).
    cfg, _, _, _, _, _, _ = _setup()
    rng = np.random.default_rng(5)
    p = rng.uniform([-0.5, -0.5, 0.5], [0.5, 0.5, 1.5], (40, 3))
    p[0] = cfg.antennas.rx_positions[0]
    w = rng.normal(size=40) + 1j * rng.normal(size=40)
    eps = 1e-6
    fast = synthesize(p, None, w, cfg, eps=eps)
    exact = synthesize_exact(p, None, w, cfg)
    assert np.all(np.isfinite(fast))
    assert np.linalg.norm(fast - exact) <= 2 * eps * np.linalg.norm(exact)
