"""The compiled per-mover phase kernel against its NumPy reference, and the synthesis it feeds.

``kernels.moving_phases`` evaluates the NumPy expressions of
``nufft.moving_phases_numpy`` scatterer by scatterer, in the same float64
operations and order (fastmath off), so every output must be the same bits.
The whole fast synthesis is then checked against the exact sample-by-sample
reference within its 1e-5 budget (tests/radar/test_synthesis.py derives it).
"""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.radar import (
    AntennaArray,
    ChirpConfig,
    IFChain,
    RadarConfig,
    synthesize,
    synthesize_exact,
    ula_positions,
)
from twinsense.radar.kernels import moving_phases
from twinsense.radar.nufft import Geometry, moving_phases_numpy


def _config(seq=None, tx=None):
    chirp = ChirpConfig.from_frequencies(58e9, 62e9, 2e6, 128, 8, 150e-6, 0.05)
    tx = np.array([[-0.01, 0.0, 0.0]]) if tx is None else tx
    return RadarConfig(chirp, AntennaArray(tx, ula_positions(3, 2.5e-3), tx_sequence=seq), IFChain())


def _movers(n, seed=1):
    rng = np.random.default_rng(seed)
    p = rng.uniform([-2.0, -1.0, 0.3], [2.0, 1.0, 6.0], (n, 3))
    v = rng.uniform(-3.0, 3.0, (n, 3))
    return p, v


@pytest.mark.parametrize("bistatic", [False, True])
def test_moving_phases_are_the_numpy_bits(bistatic):
    tx = np.array([[-0.01, 0.0, 0.0], [0.0, 0.005, 0.0]])
    cfg = _config(seq=(0, 1), tx=tx)  # two transmitters taking turns: per-chirp tx rows
    geo = Geometry(cfg, cfg.chirp.num_chirps)
    p, v = _movers(500)
    pr, vr = (_movers(500, seed=2) if bistatic else (None, None))
    c = cfg.chirp
    centres = c.chirp_times() + c.adc_start_time + (c.num_samples // 2) / c.sample_rate
    want = moving_phases_numpy(p, v, pr, vr, geo, centres)
    shape = (3, c.num_chirps, len(p))
    got = (np.empty(shape), np.empty(shape, np.float32), np.empty(shape), np.empty(shape))
    moving_phases(p, v, p if pr is None else pr, v if vr is None else vr, geo.tx_per_chirp,
                  geo.rx_array, centres, geo.fc, geo.slope, geo.fs, c.num_samples / 2 / c.sample_rate,
                  1.0 / SPEED_OF_LIGHT, *got)
    for a, b in zip(got, want):
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(a, b)


def test_synthesis_with_the_kernel_matches_exact():
    # Movers and static scatterers together; the fast cube agrees with the
    # exact reference to its eps-sized budget (1e-5 relative, as in test_synthesis).
    cfg = _config()
    p, v = _movers(60, seed=3)
    v[:20] = 0.0
    w = np.exp(1j * np.linspace(0.0, 5.0, len(p))) * np.linspace(0.5, 2.0, len(p))
    fast = synthesize(p, v, w, cfg, workers=2)
    ref = synthesize_exact(p, v, w, cfg)
    assert np.linalg.norm(fast - ref) / np.linalg.norm(ref) < 1e-5


def test_scatterers_slower_than_the_still_speed_are_synthesised_as_static():
    # Below still_speed the motion changes no sample by more than eps / 4 of
    # the scatterer's weight (bound derived in its docstring), so the static
    # path is used and the cube still matches the exact moving model to the
    # 1e-5 budget. Twice that speed stays on the moving path.
    from twinsense.radar.synthesis import still_speed

    cfg = _config()
    eps = 1e-6
    v_still = still_speed(cfg, eps)
    # Monostatic: both legs move, so |v| <= v_still / 2 is still.
    assert 1e-9 < v_still < 1e-6  # ~4e-8 m/s for 62 GHz and a 1.2 ms frame
    p, v = _movers(40, seed=5)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    w = np.linspace(1.0, 2.0, len(p)) * np.exp(1j * np.linspace(0.0, 3.0, len(p)))
    slow = synthesize(p, 0.49 * v_still * v, w, cfg, eps=eps)
    np.testing.assert_array_equal(slow, synthesize(p, None, w, cfg, eps=eps))
    ref = synthesize_exact(p, 0.49 * v_still * v, w, cfg)
    assert np.linalg.norm(slow - ref) / np.linalg.norm(ref) < 1e-5
    fast = synthesize(p, 0.51 * v_still * v, w, cfg, eps=eps)
    assert not np.array_equal(fast, synthesize(p, None, w, cfg, eps=eps))


def test_a_whole_scene_moving_past_a_turning_radar_matches_exact():
    # More movers than one chunk (16384): they are ordered by range rate
    # before chunking. Every point of a rigid scene moves relative to a radar
    # that drives and turns: v = -v_s - w x p. The fast cube stays within the
    # 1e-5 budget of the exact sum and does not depend on the threads.
    chirp = ChirpConfig.from_frequencies(58e9, 62e9, 2e6, 32, 4, 150e-6, 0.05)
    cfg = RadarConfig(chirp, AntennaArray(np.array([[-0.01, 0.0, 0.0]]), ula_positions(2, 2.5e-3)),
                      IFChain())
    rng = np.random.default_rng(9)
    p = rng.uniform([-2.0, -1.0, 0.3], [2.0, 1.0, 5.0], (17000, 3))
    v = -np.array([0.3, 0.0, 0.8]) - np.cross([0.0, 0.7, 0.1], p)
    w = rng.lognormal(0, 0.5, len(p)) * np.exp(1j * rng.uniform(0, 2 * np.pi, len(p)))
    fast = synthesize(p, v, w, cfg, workers=1)
    np.testing.assert_array_equal(fast, synthesize(p, v, w, cfg, workers=2))
    ref = synthesize_exact(p, v, w, cfg, chunk=4096)  # large chunks: the same sum, faster
    assert np.linalg.norm(fast - ref) / np.linalg.norm(ref) < 1e-5
