"""Range/Doppler FFT kernels: default axes, DC and clutter removal, peak levels,
and the argument bounds — each against values derived by hand.

Every expected value here is exact in exact arithmetic; the tolerances are a
few hundred float64 ulps of the quantities compared (FFT round-off grows as
log2(n) eps), hence 1e-12 relative.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError
from twinsense.radar.processing import doppler_fft, mti, range_fft, remove_dc
from twinsense.radar.processing.fft import range_bin_spacing, velocity_axis, velocity_resolution

TOL = 1e-12


def _cube(rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rx=2, chirp=3, sample=8) = per-chirp offsets + zero-mean tones (whole cycles)."""
    n = np.arange(8)
    tone = np.cos(2 * np.pi * 2 * n / 8)[None, None, :] * rng.uniform(1, 2, (2, 3, 1))
    offset = rng.uniform(100, 200, (2, 3, 1))  # differs per chirp and antenna
    return offset + tone, offset, tone


def test_remove_dc_takes_the_fast_time_mean_of_each_chirp():
    cube, _, tone = _cube(np.random.default_rng(0))
    out = remove_dc(cube)
    # The tone has whole cycles, so its mean is exactly zero: only the offsets go.
    np.testing.assert_allclose(out, tone, rtol=0, atol=TOL * 200)
    assert out.shape == cube.shape


def test_mti_mean_removes_the_static_part_along_chirps_by_default():
    rng = np.random.default_rng(1)
    static = rng.normal(size=(2, 1, 5))
    moving = rng.normal(size=(2, 4, 5))
    x = static + moving
    out = mti(x)  # default: method "mean", chirp axis -2
    np.testing.assert_allclose(out, moving - moving.mean(axis=1, keepdims=True), rtol=0, atol=TOL)
    np.testing.assert_allclose(out.mean(axis=1), 0.0, rtol=0, atol=TOL)
    two = mti(x, "two_pulse")
    np.testing.assert_allclose(two, np.diff(moving, axis=1), rtol=0, atol=TOL)


def test_doppler_fft_peak_is_the_tone_amplitude_on_the_chirp_axis():
    # A tone exp(j 2 pi k m / N) of amplitude A along the chirps: the
    # window-normalised FFT (divided by sum(w)) peaks at exactly A, at the
    # fftshifted bin N/2 + k, for any window.
    n_chirps, k, amp = 16, 3, 2.5
    m = np.arange(n_chirps)
    x = amp * np.exp(2j * np.pi * k * m / n_chirps)[None, :, None] * np.ones((2, 1, 4))
    for window in ("hann", "rect"):
        spec = doppler_fft(x, window=window)
        assert spec.shape == (2, n_chirps, 4)
        mag = np.abs(spec[0, :, 0])
        assert int(np.argmax(mag)) == n_chirps // 2 + k
        assert mag.max() == pytest.approx(amp, rel=TOL, abs=0)


def test_range_fft_peak_of_a_cosine_is_half_its_amplitude():
    n, k, amp = 64, 5, 3.0
    x = amp * np.cos(2 * np.pi * k * np.arange(n) / n)
    for window in ("hann", "rect"):
        spec = range_fft(x, window=window)
        assert spec.shape == (n // 2,)
        assert np.abs(spec[k]) == pytest.approx(amp / 2, rel=TOL, abs=0)
    with pytest.raises(ConfigError, match="even"):
        range_fft(x, n_fft=65)  # a real IF spectrum needs an even length
    assert range_fft(x[:63] * 1j, n_fft=65, real_if=False).shape == (65,)  # any length for complex


def test_axis_helpers_accept_one_bin_and_refuse_zero():
    fs, slope = 2e6, 1e14
    assert range_bin_spacing(fs, slope, 1) == pytest.approx(SPEED_OF_LIGHT * fs / (2 * slope), rel=TOL, abs=0)
    with pytest.raises(ConfigError):
        range_bin_spacing(fs, slope, 0)
    np.testing.assert_array_equal(velocity_axis(1, chirp_repetition_time=1e-4, carrier_frequency=60e9), [0.0])
    with pytest.raises(ConfigError):
        velocity_axis(0, chirp_repetition_time=1e-4, carrier_frequency=60e9)
    lam = SPEED_OF_LIGHT / 60e9
    assert velocity_resolution(1, chirp_repetition_time=1e-4, carrier_frequency=60e9) == pytest.approx(
        lam / (2 * 1e-4), rel=TOL, abs=0)
    with pytest.raises(ConfigError):
        velocity_resolution(0, chirp_repetition_time=1e-4, carrier_frequency=60e9)
    assert math.isfinite(range_bin_spacing(fs, slope, 2))
