"""Tap noise at low signal: read noise of both taps and shot noise of the dark charge."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twinsense.scene import Scene
from twinsense.tof import ToFCamera


def test_tap_difference_variance_in_the_dark(small_config, look_x):
    """Nothing in view: each raw value is the difference of two taps holding dark charge only.

    A = S/2 + D/2 and B = S/2 - D/2 with D = 0: each tap is Poisson(S/2) plus its own read
    noise, so Var(A - B) = S + 2 sigma_read^2 [e-^2], with S = 2 dark_current t_exp. Here
    S = 1800 e- and 2 sigma_r^2 = 800 e-^2: one tap's read noise would give 2200, no shot
    noise 800.
    """
    cfg = small_config(noise=True, quantization=False, dark_current=2.0e6, exposure_time=450e-6,
                       ambient_irradiance=0.0, read_noise=20.0, electrons_per_dn=1.0)
    cam = ToFCamera(cfg, look_x)
    rng = np.random.default_rng(21)
    frames = [cam.capture(Scene(), 0.0, rng) for _ in range(20)]
    raw = np.stack([f.raw for f in frames]).astype(np.float64)
    d = (raw - cfg.adc_offset_dn) * cfg.electrons_per_dn  # [e-]
    n = d.size  # 20 frames x 4 phase steps x 23 x 31 = 57 040
    s = 2 * cfg.dark_current * cfg.exposure_time
    expected = s + 2 * cfg.read_noise ** 2  # 2600 e-^2
    # The sample variance of n Gaussian values has relative spread sqrt(2 / (n - 1)) = 0.59 %:
    # 5 sigma is 3 %, and the alternatives above are 15 % and 69 % away.
    assert d.var() == pytest.approx(expected, rel=5 * math.sqrt(2 / (n - 1)), abs=0)
    # No signal: the raw values sit at the ADC offset (float raw values too), the mean
    # difference is 0 within 5 standard errors.
    assert abs(d.mean()) < 5 * math.sqrt(expected / n)
    # The gray value is half the tap sum in DN, rounded: Var = (S + 2 sigma_r^2) / 4 + 1/12
    # [DN^2] (e = 1 e-/DN). 14 260 values: relative spread 1.2 %, 5 sigma = 6 %; without the
    # read noise it would be 31 % lower.
    gray = np.stack([f.gray for f in frames]).astype(np.float64)
    m = gray.size
    assert gray.var() == pytest.approx(expected / 4 + 1 / 12, rel=5 * math.sqrt(2 / (m - 1)), abs=0)
    assert gray.mean() == pytest.approx(s / 2, abs=5 * math.sqrt(expected / 4 / m) + 0.5)
