"""Burst envelope against an independent real-signal resonator, noise level, config errors."""

import math

import numpy as np
import pytest
from scipy.signal import hilbert, iirpeak, lfilter

from twinsense.errors import ConfigError
from twinsense.ultrasonic import UltrasonicConfig, UltrasonicSensor
from twinsense.ultrasonic.signal import band_noise, echo_envelope, time_constant


def test_envelope_matches_two_real_resonators():
    # An 8-cycle 40 kHz burst through two digital resonators (Q 34.6, unit gain at
    # f0, 4 MHz sampling), envelope by the analytic signal. The closed form is
    # the narrow-band (complex-envelope) limit; its error is of order
    # 1 / (2 Q) = 1.4 % of the peak, the tolerance.
    f0, q, fs, n_cyc = 40e3, 34.6, 4e6, 8
    t = np.arange(int(0.004 * fs)) / fs
    burst = np.where(t < n_cyc / f0, np.sin(2 * np.pi * f0 * t), 0.0)
    b, a = iirpeak(f0, q, fs=fs)
    y = lfilter(b, a, lfilter(b, a, burst))
    env = np.abs(hilbert(y))
    want = echo_envelope(t, n_cyc / f0, time_constant(f0, q))
    sl = slice(int(0.0002 * fs), None)  # after the first few cycles (the analytic signal's edge)
    assert np.max(np.abs(env[sl] - want[sl])) <= 1 / (2 * q) * want.max()


def test_band_noise_rms():
    # The rms of 8 rows x 40k samples estimates sigma to ~ 1 / sqrt(2 N_indep),
    # N_indep = duration x bandwidth = 0.1 s x 2.3 kHz x 8 rows: 1.7 %; 5 % is 3 sigma.
    x = band_noise((8, 40_000), 400e3, 40e3, 34.6, 1e-3, np.random.default_rng(3))
    assert np.sqrt(np.mean(x * x)) == pytest.approx(1e-3, rel=0.05, abs=0)


@pytest.mark.parametrize("field, value, match", [
    ("max_range", 50.0, "max_range"),
    ("threshold", ((1.0, 0.1), (0.5, 0.1)), "threshold"),
    ("sample_rate", 50e3, "sample_rate"),
    ("transducers", (), "transducers"),
    ("n_cycles", 0, "n_cycles"),
])
def test_bad_config_names_the_field(field, value, match):
    with pytest.raises(ConfigError, match=match):
        UltrasonicConfig(**{field: value})


def test_unknown_override_lists_fields():
    with pytest.raises(ConfigError, match="one of: "):
        UltrasonicSensor.preset("open_40khz", beam_width=3)


def test_ring_window_must_end_before_next_firing():
    # 8 transducers at 15 Hz fire every 8.33 ms: 1.43 m of listening at most.
    with pytest.raises(ConfigError, match=r"max_range.*<= 1\.43"):
        UltrasonicSensor.preset("ring8_40khz", max_range=2.0)
    assert math.isclose(UltrasonicSensor.preset("ring8_40khz").config.firing_interval, 1 / 120, rel_tol=1e-12)
