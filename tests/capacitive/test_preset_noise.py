"""The presets' readout noise: the datasheet figure, scaled to the frame rate, drawn from the run's seed."""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.capacitive import MeshSettings, ReadoutConfig, make_capacitive
from twinsense.capacitive.presets import AD7746_READOUT, FDC1004_READOUT
from twinsense.scene import Scene

# The preset's electrodes and readout on a coarse mesh: the noise does not
# depend on the mesh, and an empty-scene frame then costs ~10 ms.
COARSE = MeshSettings(margin=0.01, height=0.02, depth=0.005, h_min=5e-3, h_max=0.015, growth=1.5)
FRAMES = 150


def _noise(sensor, seed: int) -> np.ndarray:
    """(FRAMES, c) readout minus true channel value [F] of an empty scene."""
    rng = np.random.default_rng(seed)
    frames = [sensor.capture(Scene([]), k / sensor.config.readout.sample_rate, rng) for k in range(FRAMES)]
    return np.array([f.readout - f.channels for f in frames])


def test_datasheet_figures_and_their_rate_scaling():
    # FDC1004: 16 effective bits over 30 pF at 100 S/s; AD7746: 21 over 8 pF at 10 Hz.
    assert FDC1004_READOUT.noise_rms == pytest.approx(0.4578e-15, rel=1e-4, abs=0)
    assert AD7746_READOUT.noise_rms == pytest.approx(3.815e-18, rel=1e-3, abs=0)
    at_rate = make_capacitive("pad-grid", frame_rate=100.0).config.readout
    assert at_rate.sample_noise_rms == FDC1004_READOUT.noise_rms
    # White noise: four times the rate (a quarter of the averaging time), twice the rms.
    fast = make_capacitive("interdigital", frame_rate=40.0).config.readout
    assert fast.sample_noise_rms == pytest.approx(2 * AD7746_READOUT.noise_rms, rel=1e-15, abs=0)
    assert ReadoutConfig(noise_rms=1e-15).sample_noise_rms == 1e-15  # no rate given: as stated


@pytest.mark.parametrize("frame_rate", [100.0, 25.0])
def test_preset_frames_carry_the_stated_noise(frame_rate):
    sensor = make_capacitive("pad-grid", frame_rate=frame_rate, mesh=COARSE)
    sigma = FDC1004_READOUT.noise_rms * np.sqrt(frame_rate / 100.0)
    noise = _noise(sensor, seed=4)
    n = noise.size  # 150 frames x 6 pads
    # Gaussian samples: the sample standard deviation has a relative standard
    # error 1 / sqrt(2 (n - 1)) = 2.4 %, the mean sigma / sqrt(n); 4 standard
    # errors (a false failure once in ~16 000 runs; the seed is fixed anyway).
    assert np.std(noise, ddof=1) == pytest.approx(sigma, rel=4 / np.sqrt(2 * (n - 1)), abs=0)
    assert abs(noise.mean()) < 4 * sigma / np.sqrt(n)
    # Independent pads and frames: the lag-1 correlation in time and the
    # correlation between two pads are O(1/sqrt(FRAMES)) = 0.08; 4 of those.
    assert abs(np.corrcoef(noise[1:, 0], noise[:-1, 0])[0, 1]) < 4 / np.sqrt(FRAMES)
    assert abs(np.corrcoef(noise[:, 0], noise[:, 1])[0, 1]) < 4 / np.sqrt(FRAMES)


def test_same_seed_same_frames_other_seed_other_frames_and_noise_off():
    sensor = make_capacitive("pad-grid", frame_rate=100.0, mesh=COARSE)
    a, b, c = (_noise(sensor, seed) for seed in (7, 7, 8))
    assert a.tobytes() == b.tobytes()
    assert np.all(a != c)
    quiet = make_capacitive("pad-grid", mesh=COARSE, readout=ReadoutConfig(noise_rms=0.0))
    frame = quiet.capture(Scene([]), 0.0, np.random.default_rng(7))
    assert np.array_equal(frame.readout, frame.channels)
    assert np.all(frame.delta == 0.0)
