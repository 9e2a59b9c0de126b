"""Device formats: Infineon config.json / recordings, TI mmWave .cfg."""

from __future__ import annotations

import json

import numpy as np
import pytest

from twinsense.data import real_recording
from twinsense.errors import ConfigError
from twinsense.radar import (
    FMCWRadar,
    InfineonConfig,
    Scatterers,
    load_infineon_config,
    preset_config,
    read_ti_cfg,
    save_infineon_config,
    write_infineon_recording,
)

IFX_DIR = real_recording("bgt60tr13c_napas") / "RadarIfxAvian_00"
TI_CFG = real_recording("iwr1843_dca1000") / "xwr18xx_profile_2023_01_01T00_00_00_000.cfg"


def test_real_infineon_config_loads_with_its_values():
    cfg = load_infineon_config(IFX_DIR / "config.json")
    assert cfg.start_frequency_Hz == 58e9 and cfg.end_frequency_Hz == 63.5e9
    assert (cfg.num_samples_per_chirp, cfg.num_chirps_per_frame) == (64, 8)
    assert cfg.rx_antennas == (1, 2, 3) and cfg.tx_antennas == (1,)
    assert (cfg.if_gain_dB, cfg.hp_cutoff_Hz, cfg.aaf_cutoff_Hz) == (23, 80000, 500000)
    radar = cfg.to_radar_config()
    assert radar.chirp.sampled_bandwidth == pytest.approx(5.5e9, rel=1e-12, abs=0)
    assert radar.chirp.sampling_time == pytest.approx(32e-6, rel=1e-12, abs=0)
    assert radar.cube_shape == (3, 8, 64)
    assert radar.if_chain.if_gain_db == 23 and radar.if_chain.hp_cutoff == 80e3
    # The folder form finds the same file.
    assert load_infineon_config(IFX_DIR.parent) == cfg


def test_infineon_config_round_trips_byte_for_byte(tmp_path):
    cfg = load_infineon_config(IFX_DIR / "config.json")
    out = save_infineon_config(cfg, tmp_path / "config.json")
    assert out.read_bytes() == (IFX_DIR / "config.json").read_bytes()
    assert load_infineon_config(out) == cfg


def test_radar_config_round_trips_through_config_json(tmp_path):
    radar = preset_config("infineon_bgt60tr13c", num_chirps=16, if_gain_db=33.0)
    path = save_infineon_config(radar, tmp_path / "config.json")
    back = load_infineon_config(path).to_radar_config()
    assert back.chirp.num_chirps == 16 and back.if_chain.if_gain_db == 33.0
    for f in ("start_frequency", "slope", "sample_rate", "chirp_repetition_time"):
        assert getattr(back.chirp, f) == pytest.approx(getattr(radar.chirp, f), rel=1e-12, abs=0)
    np.testing.assert_allclose(back.antennas.rx_positions, radar.antennas.rx_positions, atol=1e-12)
    assert back.tx_power_dbm == pytest.approx(radar.tx_power_dbm)


def test_bad_infineon_documents_name_the_field(tmp_path):
    p = tmp_path / "config.json"
    p.write_text(json.dumps({"device_config": {"fmcw_single_shape": {"bogus_field": 1}}}))
    with pytest.raises(ConfigError, match=r"fmcw_single_shape = \['bogus_field'\]"):
        load_infineon_config(p)
    doc = InfineonConfig(58e9, 63e9, 2e6, 64, 8, 6e-4, 0.1).to_dict()
    doc["device_config"]["fmcw_single_shape"]["rx_antennas"] = [1, 4]
    p.write_text(json.dumps(doc))
    with pytest.raises(ConfigError, match=r"rx_antennas\[1\] = 4 .*<= 3"):
        load_infineon_config(p)


def test_recording_is_written_in_the_sdk_layout(tmp_path):
    radar = FMCWRadar.preset("infineon_bgt60tr13c", process=False)
    target = Scatterers.point_targets([[0.05, 0.0, 0.4]], rcs=0.01)
    frames = np.stack([radar.capture_scatterers(target, t, np.random.default_rng(i)).adc
                       for i, t in enumerate((0.0, 0.08))])
    npy = write_infineon_recording(tmp_path / "rec", frames, radar.config)
    data = np.load(npy)
    # Same layout as the real recording: (frame, rx, chirp, sample) uint16 12-bit codes.
    real = np.load(IFX_DIR / "radar.npy", mmap_mode="r")
    assert data.dtype == real.dtype == np.uint16
    assert data.shape[1:] == real.shape[1:] and data.shape[0] == 2
    assert data.max() <= 4095
    np.testing.assert_array_equal(data, frames)
    cfg = load_infineon_config(tmp_path / "rec")
    assert cfg.to_radar_config().cube_shape == data.shape[1:]
    assert (tmp_path / "rec" / "RadarIfxAvian_00" / "format.version").read_text() == "1.0.0"
    with pytest.raises(ConfigError, match=r"adc_frames .*\(n_frames, 3, 8, 64\)"):
        write_infineon_recording(tmp_path / "bad", frames[:, :2], radar.config)


def test_ti_cfg_parses_to_the_device_numbers():
    cfg = read_ti_cfg(TI_CFG)
    prof = cfg.profiles[0]
    assert prof.start_frequency == pytest.approx(77e9)
    assert prof.slope == pytest.approx(70e12)  # 70 MHz/us
    assert prof.num_samples == 256
    assert prof.sample_rate == pytest.approx(5.209e6)
    assert prof.idle_time == pytest.approx(429e-6) and prof.ramp_end_time == pytest.approx(57.14e-6)
    assert cfg.tx_channels == (1, 3) and cfg.rx_channels == (1, 2, 3, 4)
    assert cfg.chirp_tx() == (1, 3)
    assert cfg.frame.num_loops == 16 and cfg.chirps_per_frame == 32
    assert cfg.frame.frame_period == pytest.approx(0.1)
    assert (cfg.adc_bits, cfg.adc_format) == (16, "complex1x")

    radar = cfg.to_radar_config()
    assert radar.cube_shape == (4, 32, 256)
    assert radar.if_chain.complex_if and radar.if_chain.adc_bits == 16
    assert radar.antennas.num_tx == 2 and radar.antennas.tx_sequence == (0, 1)
    # TX1 and TX3 are 2 lambda apart: the virtual array is a filled 8-element ULA.
    xs = np.sort(radar.antennas.virtual_positions()[:, 0])
    np.testing.assert_allclose(np.diff(xs), radar.chirp.wavelength / 2, rtol=1e-9)
    assert radar.chirp.chirp_repetition_time == pytest.approx(486.14e-6)
    # c fs / (2 S N): 4.36 cm range bins, as the recording's README derives.
    assert radar.chirp.range_resolution == pytest.approx(0.0436, abs=1e-4)


def test_ti_cfg_errors_name_the_command(tmp_path):
    p = tmp_path / "bad.cfg"
    p.write_text("channelCfg 15 5 0\nadcCfg 2 1\nprofileCfg 0 77 429\n")
    with pytest.raises(ConfigError, match=r"bad.cfg:3: profileCfg = '0 77 429' .*at least 14"):
        read_ti_cfg(p)
    p.write_text("channelCfg 15 5 0\nadcCfg 2 1\n")
    with pytest.raises(ConfigError, match=r"frameCfg = 'missing'"):
        read_ti_cfg(p)
