"""IF filters and ADC against closed forms written out here.

Butterworth responses by hand: first order H_lp = 1/(1 + j x), H_hp = j x/(1 + j x)
with x = f/f_c; the fourth-order low-pass from its pole pair product
H = 1/((s^2 + 2 sin(pi/8) s + 1)(s^2 + 2 sin(3 pi/8) s + 1)), s = j f/f_c.
A negative frequency of a complex (I/Q) receiver sees the conjugate response.
Tolerances: float64 round-off of a few operations, 1e-12 relative.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from twinsense.radar import FMCWRadar
from twinsense.radar.effects import adc, beat_frequency, codes_to_voltage, filter_cube, filtered_weights

TOL = 1e-12


def lp1(f, fc):
    return 1.0 / (1.0 + 1j * f / fc)


def hp1(f, fc):
    x = 1j * f / fc
    return x / (1.0 + x)


def lp4(f, fc):
    s = 1j * f / fc
    return 1.0 / ((s * s + 2 * math.sin(math.pi / 8) * s + 1) * (s * s + 2 * math.sin(3 * math.pi / 8) * s + 1))


def test_tone_weights_are_amplitudes_times_the_filters_at_their_beat():
    cfg = FMCWRadar.preset("infineon_bgt60tr13c").config  # real IF, 1st-order HP 80 kHz and AAF 500 kHz
    ifc = cfg.if_chain
    r = np.array([0.05, 0.3, 0.9, 2.0])
    pts = np.stack([np.zeros_like(r), np.zeros_like(r), r], axis=1)
    amps = np.array([1.0, 0.5, 2.0, 0.25])
    f = beat_frequency(pts, None, cfg)
    want = amps * hp1(f, ifc.hp_cutoff) * lp1(f, ifc.aaf_cutoff)
    np.testing.assert_allclose(filtered_weights(amps, pts, None, cfg), want, rtol=TOL, atol=0)
    # The anti-alias filter alone (no high-pass) still shapes every tone.
    only_aaf = replace(cfg, if_chain=replace(ifc, hp_cutoff=0.0))
    np.testing.assert_allclose(filtered_weights(amps, pts, None, only_aaf), amps * lp1(f, ifc.aaf_cutoff),
                               rtol=TOL, atol=0)
    # No filter at all: the amplitudes unchanged.
    none = replace(cfg, if_chain=replace(ifc, hp_cutoff=0.0, aaf_cutoff=0.0))
    np.testing.assert_array_equal(filtered_weights(amps, pts, None, none), amps.astype(complex))


def test_complex_noise_filter_multiplies_each_bin_by_its_response():
    # A periodic complex tone on FFT bin k comes out multiplied by H(k fs/N);
    # on a negative bin by conj(H(|f|)). Exact for the frequency-domain filter.
    cfg = FMCWRadar.preset("ti_iwr6843").config  # complex IF, 1st-order HP, 4th-order AAF
    ifc, fs = cfg.if_chain, cfg.chirp.sample_rate
    n = 256
    t = np.arange(n)
    for k in (3, 40, 100, -3, -40, -100):
        tone = np.exp(2j * np.pi * k * t / n)[None, None, :] * np.ones((2, 3, 1))
        f = abs(k) * fs / n
        h = hp1(f, ifc.hp_cutoff) * lp4(f, ifc.aaf_cutoff)
        h = h if k > 0 else np.conj(h)
        np.testing.assert_allclose(filter_cube(tone, ifc, fs), h * tone, rtol=0, atol=TOL * 10)


def test_real_noise_filter_multiplies_each_bin_by_its_response():
    cfg = FMCWRadar.preset("infineon_bgt60tr13c").config
    ifc, fs = cfg.if_chain, cfg.chirp.sample_rate
    n = 64
    k = 5
    x = np.cos(2 * np.pi * k * np.arange(n) / n)
    h = hp1(k * fs / n, ifc.hp_cutoff) * lp1(k * fs / n, ifc.aaf_cutoff)
    want = np.abs(h) * np.cos(2 * np.pi * k * np.arange(n) / n + np.angle(h))
    np.testing.assert_allclose(filter_cube(x, ifc, fs), want, rtol=0, atol=TOL * 10)


@pytest.mark.parametrize("preset", ["infineon_bgt60tr13c", "ti_iwr6843"])
def test_adc_codes_round_trip_within_half_an_lsb(preset):
    ifc = FMCWRadar.preset(preset).config.if_chain
    rng = np.random.default_rng(3)
    span = 0.9 * ifc.lsb * 2 ** (ifc.adc_bits - 1)
    v = rng.uniform(-span, span, 500)
    if ifc.complex_if:
        v = v + 1j * rng.uniform(-span, span, 500)
    back = codes_to_voltage(adc(v, ifc), ifc)
    assert np.max(np.abs(back.real - v.real)) <= 0.5 * ifc.lsb * (1 + 1e-9)
    assert np.max(np.abs(np.imag(back) - np.imag(v))) <= 0.5 * ifc.lsb * (1 + 1e-9)


def test_adc_code_type_follows_the_bit_count():
    ifc = FMCWRadar.preset("infineon_bgt60tr13c").config.if_chain
    assert adc(np.zeros(4), replace(ifc, adc_bits=16)).dtype == np.uint16
    assert adc(np.zeros(4), replace(ifc, adc_bits=17)).dtype == np.uint32
