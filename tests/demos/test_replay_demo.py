"""Hybrid twin demo: the real recording and the simulation side by side, with fast settings."""

from __future__ import annotations

import json

import numpy as np

from twinsense import open_recording
from twinsense.data import bgt60_radar_npy
from twinsense.demos.registry import DEMOS
from twinsense.demos.replay import CHEST_RANGE, run_replay_demo


def test_replay_demo_writes_figures_summary_and_recording(tmp_path):
    assert DEMOS["replay"][:2] == ("twinsense.demos.replay", "run_replay_demo")
    files = run_replay_demo(tmp_path, frames=4)
    for key in ("replay_range_profiles", "replay_range_doppler", "replay_noise_floor"):
        assert files[key].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with open_recording(files["recording"]) as rec:
        assert len(rec["real"]) == len(rec["sim"]) == 4
        np.testing.assert_array_equal(rec["real"].timestamps, rec["sim"].timestamps)  # one clock
        np.testing.assert_array_equal(rec["real"]["adc"][:], np.load(bgt60_radar_npy())[:4])
    summary = json.loads(files["replay_summary"].read_text())
    # Both see the chest where the README puts it (0.327 m): within one range
    # cell c / (2 B) = 2.73 cm of the simulated chest range.
    cell = 299_792_458.0 / (2 * 5.5e9)
    for name in ("real BGT60TR13C", "simulated"):
        assert abs(summary[f"{name} peak range [m]"] - CHEST_RANGE) <= cell
    # The noise floors: the receiver noise of the preset is set from this
    # recording's floor, so they agree; 3 dB covers the spread of 4 frames
    # x 3 rx x 8 chirps periodogram averages (~96 looks: +-0.4 dB at 1 sigma)
    # and the real floor's slope with range.
    real = summary["real BGT60TR13C noise floor beyond 0.5 m [dB V^2]"]
    sim = summary["simulated noise floor beyond 0.5 m [dB V^2]"]
    assert abs(real - sim) <= 3.0
