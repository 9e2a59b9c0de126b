"""Detections beyond a complex IF's anti-alias cutoff: the negative beat frequencies next to DC.

A complex-IF range FFT of N samples covers beat frequencies 0..fs, and its last bins are also the
negative frequencies -fs/N, -2 fs/N, ... next to DC, where the Tx-Rx leakage's (and any near-DC
energy's) window skirts land. A still TI IWR6843 in front of a plate reported, besides the plate, a
point at its last range bin (11.11 m, 12 dB over the noise). Beyond the IF's anti-alias cutoff
(0.9 fs: 10.04 m) no target is in the filter's passband and the bins are ambiguous with those negative
frequencies; the radar now keeps its detections below it unless ``ProcessingSettings.max_range`` says
otherwise (TI's demo configurations keep their CFAR field of view below it too).
"""

import numpy as np
import pytest

from twinsense import ConfigError
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.radar import ProcessingSettings, make_radar
from twinsense.scene import Box, Mount, Pose, Scene


def _scene():
    s = Scene()
    s.add_object("plate", Box((0.02, 1.0, 1.0)), "aluminium", pose=Pose((4.0, 0.0, 1.0)))
    return s


def _radar(**kw):
    return make_radar("ti_iwr6843", mount=Mount(Pose.look_at((0, 0, 1), (1, 0, 1))), render_width=64,
                      render_height=64, **kw)


def test_a_still_iwr6843_reports_the_plate_and_nothing_at_its_last_bins():
    radar = _radar()
    ifc, ch = radar.config.if_chain, radar.config.chirp
    # 0.9 fs: c 0.9 x 5.209 MHz / (2 x 70 MHz/us) = 10.04 m of the unambiguous 11.16 m.
    cutoff_range = SPEED_OF_LIGHT * ifc.aaf_cutoff / (2 * ch.slope)
    assert cutoff_range == pytest.approx(SPEED_OF_LIGHT * 0.9 * 5.209e6 / (2 * 70e12), rel=1e-12, abs=0)
    f = radar.capture(_scene(), 0.5, np.random.default_rng(0))
    det = f.detections
    # The plate's face at 3.99 m (within a range bin, 0.044 m), and nothing beyond the cutoff's range.
    assert np.min(np.abs(det.range - 3.99)) < 0.044
    assert np.all(det.range <= cutoff_range)
    # The cube still holds the wrapped near-DC energy there (the processing keeps the bins, not the points):
    # the last bin's power stands over the median of the far bins.
    far = f.processed.power.max(axis=0)[f.processed.range_axis > 6.0]
    assert far[-1] > 3 * np.median(far)
    # Asked explicitly, the whole unambiguous range comes back, the last bin's point with it.
    wide = _radar(processing=ProcessingSettings(min_range=0.05, max_range=1e3))
    g = wide.capture(_scene(), 0.5, np.random.default_rng(0))
    assert np.any(g.detections.range > cutoff_range)


def test_a_real_if_radar_keeps_every_bin_and_max_range_is_checked():
    # A real IF has no negative frequencies in its bins: the BGT60's settings are left as given.
    radar = make_radar("paper_bgt60tr13c", render_width=32, render_height=16)
    assert radar._settings() is radar.processing
    # An explicit max_range on any radar drops what lies beyond it.
    near = _radar(processing=ProcessingSettings(min_range=0.05, max_range=3.0))
    f = near.capture(_scene(), 0.5, np.random.default_rng(0))
    assert np.all(f.detections.range <= 3.0) and not np.any(np.abs(f.detections.range - 3.99) < 0.1)
    for bad in (0.0, -1.0, float("nan"), "far"):
        with pytest.raises(ConfigError, match="max_range"):
            ProcessingSettings(max_range=bad)
