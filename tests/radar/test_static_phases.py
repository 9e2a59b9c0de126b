"""The static rows' compiled phase pass against its NumPy form (the same bits)."""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.radar import AntennaArray, ChirpConfig, IFChain, NoiseConfig, RadarConfig, ula_positions
from twinsense.radar.nufft import Geometry, static_chunk


def _config(n_tx):
    chirp = ChirpConfig.from_frequencies(57e9, 63e9, 2e6, 128, 4, 300e-6, 1 / 30)
    tx = np.array([[-3.5e-3, 0.0, 0.0], [0.0, 2.0e-3, 1.0e-3]])[:n_tx]
    return RadarConfig(chirp, AntennaArray(tx, ula_positions(3, 2.5e-3)), IFChain(), NoiseConfig())


@pytest.mark.parametrize(("n_tx", "bistatic"), [(1, False), (2, True)])
def test_compiled_static_rows_are_the_numpy_rows_bit_for_bit(n_tx, bistatic):
    # The compiled pass repeats NumPy's operations in its order (no fastmath), so the rows
    # must be the same bytes, for every (tx, rx) pair, an element with a zero component or not.
    rng = np.random.default_rng(7)
    m = 3000
    p = rng.uniform([-2.0, -2.0, 0.1], [2.0, 2.0, 6.0], (m, 3))
    pr = p + rng.normal(0.0, 0.3, (m, 3)) if bistatic else p
    w = rng.lognormal(0, 1, m) * np.exp(1j * rng.uniform(0, 2 * np.pi, m))
    cfg = _config(n_tx)
    geo = Geometry(cfg, cfg.chirp.num_chirps)
    for eps in (1e-6, 1e-3):
        fast = static_chunk(p, pr, w, geo, eps)
        ref = static_chunk(p, pr, w, geo, eps, compiled=False)
        assert fast.tobytes() == ref.tobytes()
