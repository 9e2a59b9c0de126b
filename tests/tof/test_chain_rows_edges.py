"""ChainRows at its edges: one row per chunk, images of a few rows, a frame abandoned halfway whose kept
work arrays the next frame reuses, a feed whose noise cannot be had. Every comparison is exact (the same
compiled code computes every pixel whatever the rows of the call)."""

import numpy as np
import pytest
from test_chain_rows import LOOK_X, assert_same, config, phasors_and_noise

from twinsense.errors import ConfigError
from twinsense.tof.chain_kernels import ChainRows, chain_frame
from twinsense.tof.pipeline import NOISE_BLOCK_ROWS


def parts(cfg):
    cam, ph, slabs = phasors_and_noise(cfg)
    args = (cfg, cam._pixel_dirs, LOOK_X.rotation, LOOK_X.position, NOISE_BLOCK_ROWS)
    return ph, slabs, args


@pytest.mark.parametrize("height, supersample, sigma", [(1, 1, 0.6), (2, 3, 1.3), (5, 1, 2.0), (17, 2, 0.6)])
def test_one_row_per_chunk_bottom_up_on_small_images(height, supersample, sigma):
    # The cross-talk radius (up to 5 rows at sigma 2) reaches past images of 1-5 rows: the clipped
    # neighbourhoods must still let every row through both passes once every row is final.
    cfg = config(height=height, supersample=supersample, crosstalk_sigma_px=sigma)
    ph, slabs, args = parts(cfg)
    want = chain_frame(ph.real, ph.imag, ph.tap_sum, slabs, *args)
    chain = ChainRows(ph.real, ph.imag, ph.tap_sum, lambda: slabs, *args)
    for r in reversed(range(height)):
        chain.feed(r, r + 1)
    assert all(chain._taken2)
    assert_same(chain.finish(1), want)


def test_a_frame_abandoned_halfway_leaves_nothing_to_the_next_one_on_the_same_work_arrays():
    # Frame 1 is fed a third of its rows and dropped (its cast raised); frame 2, other phasors, reuses the
    # kept work arrays (distance and validity before the flying pixels): its bits are those of a chain
    # with fresh arrays. Frame 2's rows are fed so that pass 2 runs before every row's pass 1 would have
    # overwritten frame 1's values, if the book-keeping let stale rows through.
    cfg = config()
    scratch: dict = {}
    ph1, slabs1, args = parts(cfg)
    first = ChainRows(ph1.real, ph1.imag, ph1.tap_sum, lambda: slabs1, *args, scratch)
    first.feed(0, 50)
    rng = np.random.default_rng(9)
    real, imag = ph1.real * 0.5, ph1.imag * 0.25  # another frame's phasors
    tap = ph1.tap_sum * 0.75
    slabs2 = rng.standard_normal(slabs1.shape).astype(np.float32)
    want = chain_frame(real, imag, tap, slabs2, *args)
    second = ChainRows(real, imag, tap, lambda: slabs2, *args, scratch)
    for a in (40, 60, 20, 100, 0, 80, 120, 140):
        second.feed(a, min(a + 20, cfg.height))
    assert_same(second.finish(2), want)


def test_a_feed_without_the_noise_raises_naming_it():
    cfg = config()
    ph, _, args = parts(cfg)
    chain = ChainRows(ph.real, ph.imag, ph.tap_sum, lambda: None, *args)
    with pytest.raises(ConfigError, match="chain_frame.noise"):
        chain.feed(0, 30)
