"""Radar configuration: validation at the boundary, derived figures, presets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError, UnknownNameError
from twinsense.presets import list_presets, make_sensor
from twinsense.radar import (
    AntennaArray,
    ChirpConfig,
    ElementPattern,
    FMCWRadar,
    IFChain,
    NoiseConfig,
    RadarConfig,
    l_shaped_positions,
    planar_positions,
    preset_config,
    ula,
    ula_positions,
)


def _chirp(**kw):
    base = dict(start_frequency=60e9, slope=20e12, sample_rate=2e6, num_samples=128,
                num_chirps=8, chirp_repetition_time=100e-6, frame_repetition_time=0.05)
    base.update(kw)
    return ChirpConfig(**base)


def _array():
    return AntennaArray(np.zeros((1, 3)), ula_positions(2, 2.5e-3))


def test_chirp_longer_than_repetition_time_is_rejected():
    # 128 samples at 2 MHz last 64 us; a 50 us repetition time cannot hold them.
    with pytest.raises(ConfigError, match=r"chirp_repetition_time = 5e-05 .*chirp duration"):
        _chirp(chirp_repetition_time=50e-6)


def test_samples_beyond_the_ramp_are_rejected():
    with pytest.raises(ConfigError, match=r"ramp_end_time .*ADC samples must lie on the ramp"):
        _chirp(adc_start_time=10e-6, ramp_end_time=60e-6)


def test_frame_shorter_than_its_chirps_is_rejected():
    with pytest.raises(ConfigError, match=r"frame_repetition_time .*num_chirps"):
        _chirp(frame_repetition_time=500e-6)


def test_sample_rate_above_device_limit_is_rejected():
    with pytest.raises(ConfigError, match=r"sample_rate = 2000000.0 .*maximum sample rate 1e\+06"):
        RadarConfig(_chirp(), _array(), IFChain(max_sample_rate=1e6))


def test_sample_rate_too_low_for_the_anti_alias_filter_is_rejected():
    # Real IF at 2 MHz: Nyquist 1 MHz, so a 1.5 MHz anti-alias corner lets aliases through.
    with pytest.raises(ConfigError, match=r"sample_rate .*>= 2 x IFChain.aaf_cutoff = 3e\+06"):
        RadarConfig(_chirp(), _array(), IFChain(aaf_cutoff=1.5e6))
    # A complex (I/Q) ADC has a band of fs: the same filter is fine there.
    RadarConfig(_chirp(), _array(), IFChain(complex_if=True, aaf_cutoff=1.5e6))


def test_antennas_in_the_wrong_shape_are_rejected():
    with pytest.raises(ConfigError, match=r"rx_positions = 'array of shape \(3, 2\)'.*\(N, 3\)"):
        AntennaArray(np.zeros((1, 3)), np.zeros((3, 2)))
    with pytest.raises(ConfigError, match=r"tx_positions .*\(N, 3\)"):
        AntennaArray(np.zeros(3), np.zeros((2, 3)))
    with pytest.raises(ConfigError, match=r"tx_sequence .*indices into tx_positions, each in 0..1"):
        AntennaArray(np.zeros((2, 3)), np.zeros((2, 3)), tx_sequence=(0, 2))


def test_nan_values_are_rejected():
    with pytest.raises(ConfigError, match=r"ChirpConfig.slope = nan"):
        _chirp(slope=float("nan"))
    with pytest.raises(ConfigError, match=r"rx_positions = 'array with NaN or inf'"):
        AntennaArray(np.zeros((1, 3)), np.array([[0.0, np.nan, 0.0]]))
    with pytest.raises(ConfigError, match=r"RadarConfig.tx_power_dbm = nan"):
        RadarConfig(_chirp(), _array(), tx_power_dbm=float("nan"))


def test_tdm_sequence_must_divide_the_chirps():
    arr = AntennaArray(np.zeros((3, 3)), ula_positions(4, 2.5e-3))
    with pytest.raises(ConfigError,
                       match=r"num_chirps = 8 .*multiple of the TDM sequence length 3"):
        RadarConfig(_chirp(), arr)


def test_other_field_errors():
    with pytest.raises(ConfigError,
                       match=r"NoiseConfig.mode = 'loud'.*one of: none, thermal, variance"):
        NoiseConfig(mode="loud")
    with pytest.raises(ConfigError, match=r"NoiseConfig.variance = 0.0 .*mode = 'variance'"):
        NoiseConfig(mode="variance")
    with pytest.raises(ConfigError, match=r"hp_cutoff = 600000.0 .*< aaf_cutoff"):
        IFChain(hp_cutoff=600e3, aaf_cutoff=500e3)
    with pytest.raises(ConfigError, match=r"adc_bits = 0"):
        IFChain(adc_bits=0)


def test_unknown_preset_lists_the_valid_names():
    with pytest.raises(UnknownNameError,
                       match=r"infineon_bgt60tr13c, paper_bgt60tr13c, ti_iwr6843"):
        FMCWRadar.preset("bgt60")
    with pytest.raises(ConfigError, match=r"override 'num_chirpz'.*num_chirps"):
        preset_config("paper_bgt60tr13c", num_chirpz=4)


def test_derived_figures_match_closed_forms():
    c = ChirpConfig.from_frequencies(57e9, 63e9, 2e6, 512, 16, 300e-6, 1 / 30)
    assert c.sampled_bandwidth == pytest.approx(6e9, rel=1e-12, abs=0)
    assert c.range_resolution == pytest.approx(SPEED_OF_LIGHT / 12e9, rel=1e-12, abs=0)
    assert c.centre_frequency == pytest.approx(60e9, rel=1e-12, abs=0)
    cfg = RadarConfig(c, _array())
    # Real IF: beat frequencies up to fs/2 -> R_max = c fs / (4 S); S = 6 GHz / 256 us.
    assert cfg.max_range == pytest.approx(SPEED_OF_LIGHT * 2e6 / (4 * 6e9 / 256e-6), rel=1e-12, abs=0)
    lam = SPEED_OF_LIGHT / 60e9
    assert cfg.max_velocity == pytest.approx(lam / (4 * 300e-6), rel=1e-12, abs=0)
    assert cfg.velocity_resolution == pytest.approx(lam / (2 * 16 * 300e-6), rel=1e-12, abs=0)
    assert cfg.cube_shape == (2, 16, 512)


def test_presets_hold_the_documented_numbers():
    paper = preset_config("paper_bgt60tr13c")
    assert paper.chirp.sampled_bandwidth == pytest.approx(6e9)
    assert paper.chirp.centre_frequency == pytest.approx(60e9)
    assert (paper.chirp.sample_rate, paper.chirp.num_samples, paper.chirp.num_chirps) == (
        2e6, 512, 16)
    assert (paper.hfov_deg, paper.vfov_deg, paper.num_rx) == (120, 60, 2)
    assert not paper.if_chain.complex_if
    assert paper.noise.mode == "variance"
    one = preset_config("paper_bgt60tr13c", num_chirps=1)
    assert one.chirp.num_chirps == 1

    ifx = preset_config("infineon_bgt60tr13c")
    assert (ifx.antennas.num_tx, ifx.antennas.num_rx, ifx.if_chain.adc_bits) == (1, 3, 12)
    # The L: RX1 and RX2 each lambda/2 from the corner RX3, at right angles.
    d = ifx.antennas.rx_positions - ifx.antennas.rx_positions[2]
    assert np.dot(d[0], d[1]) == pytest.approx(0.0, abs=1e-15)
    assert np.linalg.norm(d[0]) == pytest.approx(SPEED_OF_LIGHT / 60.75e9 / 2)

    ti = preset_config("ti_iwr6843")
    assert ti.if_chain.complex_if and ti.antennas.is_mimo
    assert (ti.antennas.num_tx, ti.antennas.num_rx, len(ti.antennas.virtual_positions())) == (
        3, 4, 12)
    assert set(list_presets("radar")["radar"]) == {"infineon_bgt60tr13c", "paper_bgt60tr13c",
                                                   "ti_iwr6843"}
    radar = make_sensor("radar", "ti_iwr6843", name="front")
    assert radar.name == "front" and radar.frame_rate == pytest.approx(10.0)


def test_element_pattern_is_cos_power():
    p = ElementPattern(gain_dbi=6.0, cos_exponent_azimuth=2.0, cos_exponent_elevation=1.0)
    az, el = math.radians(30), math.radians(20)
    d = np.array([[math.cos(el) * math.sin(az), -math.sin(el), math.cos(el) * math.cos(az)],
                  [0.0, 0.0, -1.0]])
    g = p.gain(d)
    assert g[0] == pytest.approx(10**0.6 * math.cos(az) ** 2 * math.cos(el), rel=1e-12, abs=0)
    assert g[1] == 0.0  # behind the array


def test_array_builders():
    lam = 5e-3
    arr = ula(4, lam, num_tx=2)
    v = arr.virtual_positions()
    # TDM with Tx spaced N_rx lambda/2 fills a ULA of 8 elements at lambda/2.
    xs = np.sort(v[:, 0])
    np.testing.assert_allclose(np.diff(xs), lam / 2, rtol=1e-12)
    np.testing.assert_array_equal(arr.chirp_tx(5), [0, 1, 0, 1, 0])
    assert l_shaped_positions(lam / 2).shape == (3, 3)
    grid = planar_positions(3, 2, lam / 2)
    assert grid.shape == (6, 3) and grid[:, 1].min() == pytest.approx(-lam / 2)
