"""The BGT60TR13C preset's empty-scene noise floor against k T0 B NF worked out by hand.

Independent of the real recording the preset's receiver gain was tuned on
(that comparison is ``test_sensor_system``): here the floor follows from the
receiver values alone.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from twinsense.radar import FMCWRadar
from twinsense.scene import Scene

# Receiver values of the preset: Infineon SDK config of the recording (fs, N,
# IF gain, AAF and HP corners), BGT60TR13C datasheet (12-bit ADC, 1 V span),
# and the preset's front end (12 dB noise figure, 23 dB LNA + mixer gain, 50 ohm).
K_B = 1.380649e-23  # J/K (exact, SI 2019)
T0 = 290.0  # K, the noise-figure reference
NF_DB = 12.0
FS = 2.0e6  # Hz
N = 64  # samples per chirp
GAIN_DB = 23.0 + 23.0  # rf_gain_db + if_gain_db (SDK if_gain_dB = 23)
Z = 50.0  # ohm
LSB = 1.0 / 2**12  # V: 1 V peak-to-peak over 12 bits
F_AAF = 500e3  # Hz, first-order anti-alias low-pass (SDK aaf_cutoff_Hz)
FRAMES = 16


@pytest.fixture(scope="module")
def empty_scene_codes() -> np.ndarray:
    """(frame, rx, chirp, sample) ADC codes of the preset looking at nothing."""
    radar = FMCWRadar.preset("infineon_bgt60tr13c", process=False)
    cfg = radar.config
    # The derivation below holds for exactly these receiver values.
    assert (cfg.noise.mode, cfg.noise.noise_figure_db, cfg.noise.temperature) == ("thermal", NF_DB, T0)
    ifc = cfg.if_chain
    assert (ifc.rf_gain_db + ifc.if_gain_db, ifc.impedance, ifc.lsb, ifc.complex_if) == (
        GAIN_DB, Z, LSB, False)
    assert (ifc.aaf_cutoff, ifc.aaf_order, cfg.chirp.sample_rate, cfg.chirp.num_samples) == (
        F_AAF, 1, FS, N)
    codes = np.stack([radar.capture(Scene([]), k / radar.frame_rate,
                                    np.random.default_rng(100 + k)).adc for k in range(FRAMES)])
    return codes.astype(float)  # (frame, rx, chirp, sample)


def _noise_only(codes: np.ndarray) -> tuple[np.ndarray, int]:
    """Codes minus their mean over frames and chirps per (rx, sample): the DC offset and
    the leakage tone repeat in every chirp, the noise does not. Returns the residual
    (realisation, rx, sample) and the number M of realisations per (rx, sample)."""
    x = codes.transpose(0, 2, 1, 3).reshape(-1, codes.shape[1], codes.shape[3])
    return x - x.mean(axis=0), len(x)


def _by_hand():
    # Thermal noise per real sample at the receiver input, over the Nyquist band fs/2:
    # k T0 = 4.0039e-21 W/Hz (-173.98 dBm/Hz), + 12 dB NF, + 60 dB (1 MHz) = -101.98 dBm.
    p_in = K_B * T0 * 10 ** (NF_DB / 10) * (FS / 2)
    assert 10 * math.log10(p_in / 1e-3) == pytest.approx(-101.98, abs=0.01)
    # At the ADC: P Z times the 46 dB voltage gain squared, 1.2632e-7 V^2 = 2.1192 codes^2.
    white = p_in * Z * 10 ** (GAIN_DB / 10) / LSB**2
    assert white == pytest.approx(2.1192, abs=1e-4)
    # The AAF shapes the noise per chirp (periodic over the N samples): at the
    # DFT frequencies f_k its power response is 1 / (1 + (f_k / f_c)^2).
    f = np.fft.fftfreq(N, 1 / FS)
    h2 = 1.0 / (1.0 + (f / F_AAF) ** 2)
    return white, h2


def test_empty_scene_noise_per_adc_sample_is_k_t_b_nf_times_the_gain(empty_scene_codes):
    white, h2 = _by_hand()
    # Parseval for a circular filter: the variance per sample is the mean of |H|^2 over
    # the N bins (0.553 here; the continuous band average (f_c / (fs/2)) atan(2) = 0.554),
    # and rounding to codes adds LSB^2 / 12 (uniform error; the noise spans > 1 LSB).
    expect = white * h2.mean() + 1.0 / 12.0
    assert expect == pytest.approx(1.256, abs=1e-3)  # 1.12 codes rms
    resid, m = _noise_only(empty_scene_codes)
    var = np.sum(resid**2) / (resid[0].size * (m - 1))  # m - 1: one mean taken per (rx, sample)
    # Spread of the estimate: a chirp's 64 samples are correlated by the AAF; the
    # sum of squares of one chirp has variance 2 sum(lambda_k^2) with the circulant's
    # eigenvalues lambda_k ~ |H_k|^2, so K chirps act as n_eff = K (sum |H|^2)^2 / sum |H|^4
    # independent samples (~17 600 here), relative spread sqrt(2 / n_eff) ~ 1.1 %.
    k = (m - 1) * resid.shape[1]
    n_eff = k * h2.sum() ** 2 / np.sum(h2**2)
    tol = 5 * math.sqrt(2 / n_eff)  # 5 sigma
    assert var == pytest.approx(expect, rel=tol, abs=0)


def test_empty_scene_noise_per_range_bin_follows_the_anti_alias_filter(empty_scene_codes):
    white, h2 = _by_hand()
    resid, m = _noise_only(empty_scene_codes)
    spec = np.abs(np.fft.rfft(resid, axis=-1)) ** 2 * m / (m - 1)
    k = np.arange(1, N // 2)  # without DC and Nyquist (real bins: other statistics)
    measured = spec[..., k].mean(axis=(0, 1))
    # E|X_k|^2 = N (sigma_white^2 |H(f_k)|^2 + LSB^2/12) codes^2 for an unwindowed N-point
    # DFT of noise (the high-pass does not shape the floor: the amplifier's own noise
    # dominates after it, see effects.shape_noise).
    expect = N * (white * h2[k] + 1.0 / 12.0)
    # Each bin averages (m - 1) x 3 exponential powers (|X_k|^2 of complex Gaussian
    # noise): relative spread 1 / sqrt(3 (m - 1)) = 5.1 %; 5 sigma per bin.
    tol = 5 / math.sqrt(3 * (m - 1))
    np.testing.assert_allclose(measured, expect, rtol=tol, atol=0)
