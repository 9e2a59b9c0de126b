"""Receiver effects: filters, noise, SNR vs the radar equation, leakage, ADC."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.radar import (
    AntennaArray,
    ChirpConfig,
    ElementPattern,
    FMCWRadar,
    IFChain,
    NoiseConfig,
    RadarConfig,
    Scatterers,
    effects,
    ula_positions,
)

K_B = 1.380649e-23


def _config(complex_if=False, **ifc):
    chirp = ChirpConfig.from_frequencies(57e9, 63e9, 2e6, 512, 16, 300e-6, 1 / 30)
    ant = AntennaArray(np.array([[-3.5e-3, 0.0, 0.0]]), ula_positions(2, 2.5e-3),
                       ElementPattern(gain_dbi=6.0), ElementPattern(gain_dbi=4.0))
    kw = dict(complex_if=complex_if, rf_gain_db=20.0, if_gain_db=20.0, adc_bits=16,
              adc_full_scale=8.0)
    kw.update(ifc)
    return RadarConfig(chirp, ant, IFChain(**kw),
                       NoiseConfig("thermal", noise_figure_db=10.0, temperature=290.0),
                       tx_power_dbm=10.0)


def test_filters_are_butterworth_with_minus_3_db_corners():
    ifc = IFChain(hp_cutoff=80e3, hp_order=1, aaf_cutoff=500e3, aaf_order=4)
    hp_only = IFChain(hp_cutoff=80e3, hp_order=2)
    lp_only = IFChain(aaf_cutoff=500e3, aaf_order=4)
    # |H| at the corner is 1/sqrt(2) by the Butterworth definition.
    assert abs(effects.filter_response(80e3, hp_only)) == pytest.approx(2**-0.5, rel=1e-9, abs=0)
    assert abs(effects.filter_response(500e3, lp_only)) == pytest.approx(2**-0.5, rel=1e-9, abs=0)
    # n-th order low-pass: |H(f)|^2 = 1 / (1 + (f/fc)^(2n)).
    assert abs(effects.filter_response(2e6, lp_only)) ** 2 == pytest.approx(1 / (1 + 4**8),
                                                                             rel=1e-9, abs=0)
    # A complex receiver sees the conjugate response at negative frequency.
    h = effects.filter_response(np.array([2e5, -2e5]), ifc)
    assert h[1] == pytest.approx(np.conj(h[0]), rel=1e-12, abs=0)


def test_beat_frequency_is_range_term_plus_doppler():
    cfg = _config()
    s, lam = 6e9 / (512 / 2e6), SPEED_OF_LIGHT / 60e9  # slope 23.4 THz/s, lambda 5 mm
    # A point 3 m ahead receding at 2 m/s, plus a sideways velocity that changes no range:
    # f_b = 2 S R / c + 2 v_r / lambda = 468.4 kHz + 800 Hz.
    f = effects.beat_frequency(np.array([[0.0, 0.0, 3.0]]), np.array([[0.7, 0.0, 2.0]]), cfg)
    assert f[0] == pytest.approx(2 * s * 3.0 / SPEED_OF_LIGHT + 2 * 2.0 / lam, rel=1e-12, abs=0)
    # Bistatic: each leg adds its own range and range rate (2 m away at 2 m/s, 4 m approaching at 1 m/s).
    f = effects.beat_frequency(np.array([[0.0, 0.0, 2.0]]), np.array([[0.0, 0.0, 2.0]]), cfg,
                               np.array([[0.0, 4.0, 0.0]]), np.array([[0.0, -1.0, 0.0]]))
    assert f[0] == pytest.approx(s * 6.0 / SPEED_OF_LIGHT + (2.0 - 1.0) / lam, rel=1e-12, abs=0)


def test_tone_weight_is_the_steady_state_response_of_the_analog_filter():
    # Independent reference: simulate the analog filters in the time domain
    # (scipy lsim) on a long cosine and read amplitude and phase after the
    # transient has died out.
    ifc = IFChain(hp_cutoff=80e3, hp_order=1, aaf_cutoff=500e3, aaf_order=3)
    f = 150e3
    b1, a1 = signal.butter(1, 2 * np.pi * 80e3, "highpass", analog=True)
    b2, a2 = signal.butter(3, 2 * np.pi * 500e3, "lowpass", analog=True)
    sys = signal.lti(np.polymul(b1, b2), np.polymul(a1, a2))
    t = np.arange(0, 200e-6, 1e-8)
    _, y, _ = sys.output(np.cos(2 * np.pi * f * t), t)
    tail = t > 150e-6  # 150 us = 75 time constants of the 80 kHz high-pass
    h = effects.filter_response(f, ifc)
    expect = np.abs(h) * np.cos(2 * np.pi * f * t[tail] + np.angle(h))
    # lsim's linear interpolation at 10 ns steps (667 per period) is accurate to ~1e-4.
    np.testing.assert_allclose(y[tail], expect, atol=1e-3)


def test_thermal_noise_variance_is_k_t_b_nf():
    cfg = _config()
    noise = effects.thermal_noise(cfg, np.random.default_rng(0))
    g2 = 50.0 * 10 ** (40 / 10)  # impedance x (20 dB + 20 dB) voltage gain squared
    expect = K_B * 290.0 * 10.0 * 1e6 * g2  # k T NF (fs/2) per real sample
    # 16384 samples: the sample variance has a relative spread sqrt(2/N) = 1.1 %; 5 % is 4.5 sigma.
    assert noise.var() == pytest.approx(expect, rel=0.05, abs=0)
    c = effects.thermal_noise(_config(complex_if=True), np.random.default_rng(1))
    assert c.real.var() == pytest.approx(expect, rel=0.05, abs=0)
    assert c.imag.var() == pytest.approx(expect, rel=0.05, abs=0)


@pytest.mark.parametrize("complex_if", [False, True])
def test_target_snr_matches_the_radar_equation(complex_if):
    cfg = _config(complex_if)
    n = cfg.chirp.num_samples
    # A point target on boresight, exactly on range bin 60 (beat = 60 fs / N)
    # so that the un-windowed FFT puts all its energy in one bin.
    tau = 60 / n * cfg.chirp.sample_rate / cfg.chirp.slope
    r = tau * SPEED_OF_LIGHT / 2
    rcs = 0.5
    radar = FMCWRadar(cfg, process=False)
    frame = radar.capture_scatterers(Scatterers.point_targets([[0.0, 0.0, r]], rcs), 0.0,
                                     np.random.default_rng(5))
    sig = np.fft.fft(frame.signal, axis=-1)[..., 60]
    noise_bins = np.fft.fft(frame.noise, axis=-1)[..., 70:250]
    snr_db = 10 * np.log10(np.mean(np.abs(sig) ** 2) / np.mean(np.abs(noise_bins) ** 2))

    # Radar equation written out: P_r = P_t G_t G_r lambda^2 sigma / ((4 pi)^3 R^4).
    lam = SPEED_OF_LIGHT / 60e9
    p_r = 10e-3 * 10**0.6 * 10**0.4 * lam**2 * rcs / ((4 * math.pi) ** 3 * r**4)
    # Real IF: a cosine of power P_r, noise k T F fs/2 per sample ->
    # SNR = P_r N / (k T F fs). I/Q: the same tone on I and on Q, each with its
    # own noise -> 3 dB more (the real receiver's image band folds noise in).
    expect = p_r * n / (K_B * 290.0 * 10.0 * 2e6) * (2.0 if complex_if else 1.0)
    # The 1 dB bound: the noise estimate averages 2 x 16 x 180 bins (spread
    # 0.03 dB); the near-field / wavelength offsets of the model are < 0.1 dB.
    assert snr_db == pytest.approx(10 * np.log10(expect), abs=1.0)
    assert snr_db > 20.0


def test_leakage_tone_has_its_power_and_path():
    cfg = _config(complex_if=True, leakage_dbc=-40.0, leakage_path=0.03, hp_cutoff=50e3)
    tone = effects.leakage(cfg)
    f_beat = cfg.chirp.slope * 0.03 / SPEED_OF_LIGHT
    h_c = effects.filter_response(f_beat, cfg.if_chain)
    h = abs(h_c)
    # Amplitude sqrt(2 P_t 10^(-4)) times the high-pass gain at its beat frequency.
    expect = math.sqrt(2 * 10e-3 * 1e-4) * h
    np.testing.assert_allclose(np.abs(tone), expect, rtol=1e-12)
    # Its phase is the IF model of PHYSICS.md section 2 with tau = path / c:
    # 2 pi f_c tau + 2 pi S tau t - pi S tau^2 (the last term 7.4e-7 rad here), plus the
    # high-pass phase; float64 phases of ~2 pi * 6 rad agree to ~1e-14.
    tau = 0.03 / SPEED_OF_LIGHT
    t = np.arange(512) / 2e6
    s = 6e9 / (512 / 2e6)
    phase = 2 * np.pi * 57e9 * tau + 2 * np.pi * s * tau * t - np.pi * s * tau**2
    np.testing.assert_allclose(tone[0, 0], expect * np.exp(1j * (phase + np.angle(h_c))),
                               rtol=1e-12, atol=0)
    assert np.allclose(effects.leakage(_config()), 0.0)


def test_adc_quantises_clips_and_adds_mid_scale():
    ifc = IFChain(adc_bits=12, adc_full_scale=1.0)
    lsb = 1 / 4096
    v = np.array([0.0, 0.4 * lsb, 0.6 * lsb, -3.0 * lsb, 10.0, -10.0])
    codes = effects.adc(v, ifc)
    np.testing.assert_array_equal(codes, [2048, 2048, 2049, 2045, 4095, 0])
    assert codes.dtype == np.uint16
    back = effects.codes_to_voltage(codes, ifc)
    np.testing.assert_allclose(back[:4], [0, 0, lsb, -3 * lsb])
    c = effects.adc(np.array([0.3 + 0.7j]) * 10 / 2**16, IFChain(complex_if=True, adc_bits=16))
    assert c[0] == 3 + 7j


def test_quantisation_noise_is_lsb_squared_over_12():
    ifc = IFChain(adc_bits=12, adc_full_scale=1.0)
    x = np.random.default_rng(2).uniform(-0.3, 0.3, 200_000)
    err = effects.codes_to_voltage(effects.adc(x, ifc), ifc) - x
    # Uniform error on [-q/2, q/2]: variance q^2/12; 2e5 samples -> 0.3 % spread, 2 % bound.
    assert err.var() == pytest.approx((1 / 4096) ** 2 / 12, rel=0.02, abs=0)


def test_dc_offset_shifts_the_codes():
    cfg = _config(dc_offset=0.01, adc_bits=12, adc_full_scale=1.0)
    cfg = RadarConfig(cfg.chirp, cfg.antennas, cfg.if_chain, NoiseConfig("none"))
    frame = FMCWRadar(cfg, process=False).capture_scatterers(
        Scatterers.point_targets(np.zeros((0, 3)), np.zeros(0)))
    # 0.01 V = 40.96 LSB above mid-scale 2048, rounded.
    assert np.all(frame.adc == 2048 + 41)
