"""Every path of the fast synthesis within the 2 eps bound the noise tolerance rests on.

The static rows, the per-chirp movers and the 2-D blocks (both variants), each at
tolerances from 1e-6 to 1e-3, against the exact sum. The bound
(twinsense.radar.synthesis, "What is exact and what is bounded"): the transforms'
relative l2 error about eps (the compiled spreader runs at eps / 2, erring 0.7-1.3
of its tolerance; finufft's 2-D transforms at eps / 2 too) plus the per-scatterer
series budget of at most eps of each amplitude: 2 eps at most.
"""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.radar import (
    AntennaArray,
    ChirpConfig,
    IFChain,
    RadarConfig,
    synthesize,
    synthesize_exact,
    ula_positions,
)
from twinsense.radar.nufft import Geometry, moving_chunk, moving_chunk_2d, static_chunk

EPS = [1e-6, 1e-5, 1e-4, 1e-3]


def _config():
    chirp = ChirpConfig.from_frequencies(58e9, 62e9, 2e6, 128, 16, 150e-6, 0.05)
    return RadarConfig(chirp, AntennaArray(np.array([[-0.01, 0.0, 0.0]]), ula_positions(2, 2.5e-3)),
                       IFChain(complex_if=True))


def _scene(n=500, seed=5):
    """Scatterers 0.3-3 m ahead, strengths over two decades, moving at up to 1.5 m/s (a
    radar on an arm), sorted by range rate as the synthesis sorts a chunk."""
    rng = np.random.default_rng(seed)
    p = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(0.3, 3.0, n)])
    v = rng.normal(0.0, 0.5, (n, 3))
    w = rng.lognormal(0, 1, n) * np.exp(1j * rng.uniform(0, 2 * np.pi, n))
    order = np.argsort(np.einsum("ij,ij->i", p, v) / np.linalg.norm(p, axis=1), kind="stable")
    return p[order], v[order], w[order]


def _rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.fixture(scope="module")
def setup():
    cfg = _config()
    p, v, w = _scene()
    c = cfg.chirp
    centres = c.chirp_times() + c.adc_start_time + (c.num_samples // 2) / c.sample_rate
    return cfg, p, v, w, Geometry(cfg, c.num_chirps), centres, synthesize_exact(p, v, w, cfg), \
        synthesize_exact(p, None, w, cfg)


@pytest.mark.parametrize("eps", EPS)
def test_static_rows_within_2_eps(setup, eps):
    _, p, _, w, geo, _, _, exact = setup
    rows = static_chunk(p, p, w, geo, eps)  # (pairs, N): one transmitter, every chirp alike
    assert _rel(rows, exact[:, 0, :]) <= 2.0 * eps


@pytest.mark.parametrize("eps", EPS)
def test_per_chirp_movers_within_2_eps(setup, eps):
    _, p, v, w, geo, centres, exact, _ = setup
    assert _rel(moving_chunk(p, v, None, None, w, geo, centres, eps), exact) <= 2.0 * eps


@pytest.mark.parametrize("eps", EPS)
@pytest.mark.parametrize("slow", [True, False])
def test_block_movers_within_2_eps(setup, eps, slow):
    _, p, v, w, geo, centres, exact, _ = setup
    cube = moving_chunk_2d(p, v, None, None, w, geo, centres, eps, force=True, slow=slow)
    assert cube is not None
    assert _rel(cube, exact) <= 2.0 * eps


def test_odd_sample_count_within_2_eps():
    # An ADC window of 127 samples (odd): the 1-D transforms' modes -63..63. Static and
    # moving scatterers through the public entry, against the exact sum, 2 eps as above.
    chirp = ChirpConfig.from_frequencies(58e9, 62e9, 2e6, 127, 16, 150e-6, 0.05)
    cfg = RadarConfig(chirp, AntennaArray(np.array([[-0.01, 0.0, 0.0]]), ula_positions(2, 2.5e-3)),
                      IFChain(complex_if=True))
    p, v, w = _scene(300, seed=6)
    v[::2] = 0.0
    eps = 1e-5
    assert _rel(synthesize(p, v, w, cfg, eps=eps), synthesize_exact(p, v, w, cfg)) <= 2.0 * eps


def test_finufft_plans_kept_per_thread_are_bounded():
    # The finufft path (kept for comparisons) makes plans per tolerance; a moving radar's
    # tolerance changes every frame, so only the newest few sets stay.
    import twinsense.radar.nufft as nufft

    for k in range(3 * nufft._MAX_PLANS):
        nufft._thread_plans(64, 1e-6 * (1.0 + k))
    assert len(nufft._LOCAL.plans) == nufft._MAX_PLANS
    assert (64, 1e-6 * (3 * nufft._MAX_PLANS)) in nufft._LOCAL.plans
