"""Named radar configurations (the sensor and the preset registry build on them).

- ``infineon_bgt60tr13c``: the device as it recorded the real recording in twinsense.data
  (58-63.5 GHz, 64 samples at 2 MHz, 8 chirps, 1 Tx, 3 Rx in an L, real IF,
  12-bit ADC, IF gain 23 dB, HP 80 kHz, AAF 500 kHz). Receiver gain, ADC span,
  DC offset and leakage are set so that the simulated noise floor and ADC
  levels match that recording (noise ~1.1 codes rms, mean ~1870 codes).
- ``paper_bgt60tr13c``: the seed paper's Table 2 — 120 x 60 deg FOV, 57-63 GHz
  (B = 6 GHz, 60 GHz centre), fs = 2 MHz, N_s = 512, 16 chirps (1-16 allowed),
  2 Rx ULA at lambda/2, noise as a user variance.
- ``ti_iwr6843``: 3 Tx / 4 Rx TDM-MIMO (IWR6843ISK layout: TX1 and TX3 two
  wavelengths apart in azimuth, TX2 raised by lambda/2), complex IF, 16-bit
  ADC, 60 GHz start, 70 MHz/us, 256 samples at 5.209 MHz, 16 loops.

Element positions of the real boards are approximated from public antenna
layouts (lambda/2 receiver spacing); element gains are typical patch values.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import fields
from typing import Any

import numpy as np

from twinsense import validation
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError, UnknownNameError
from twinsense.radar.antennas import (
    AntennaArray,
    ElementPattern,
    l_shaped_positions,
    ula_positions,
)
from twinsense.radar.config import ChirpConfig, IFChain, NoiseConfig, RadarConfig


def bgt60tr13c_config() -> RadarConfig:
    """Infineon BGT60TR13C as configured in the shared real recording."""
    chirp = ChirpConfig.from_frequencies(58.0e9, 63.5e9, 2.0e6, 64, 8,
                                         5.911249900236726e-4, 7.726884633302689e-2)
    lam = SPEED_OF_LIGHT / 60.75e9
    # FOV 120 x 60 deg (half power at +-60 az, +-30 el): cos^1 in azimuth,
    # cos^4.8 in elevation (cos(30 deg)^4.8 = 0.5).
    pattern = ElementPattern(gain_dbi=5.0, cos_exponent_azimuth=1.0, cos_exponent_elevation=4.8)
    antennas = AntennaArray(np.array([[-3.5e-3, 0.0, 0.0]]), l_shaped_positions(lam / 2),
                            pattern, pattern)
    lsb = 1.0 / 4096
    if_chain = IFChain(complex_if=False, rf_gain_db=23.0, if_gain_db=23.0, hp_cutoff=80e3,
                       hp_order=1, aaf_cutoff=500e3, aaf_order=1, adc_bits=12,
                       adc_full_scale=1.0, dc_offset=-178 * lsb, leakage_dbc=-45.0,
                       leakage_path=0.02, max_sample_rate=4e6)
    return RadarConfig(chirp, antennas, if_chain, NoiseConfig("thermal", noise_figure_db=12.0),
                       tx_power_dbm=5.0, hfov_deg=120.0, vfov_deg=60.0, render_width=256,
                       render_height=128)


def paper_bgt60tr13c_config() -> RadarConfig:
    """The seed paper's simplified BGT60TR13C (Table 2), 16 chirps."""
    chirp = ChirpConfig.from_frequencies(57.0e9, 63.0e9, 2.0e6, 512, 16, 300e-6, 1.0 / 30)
    lam = SPEED_OF_LIGHT / 60e9
    pattern = ElementPattern(gain_dbi=5.0, cos_exponent_azimuth=1.0, cos_exponent_elevation=4.8)
    antennas = AntennaArray(np.array([[-3.5e-3, 0.0, 0.0]]), ula_positions(2, lam / 2),
                            pattern, pattern)
    if_chain = IFChain(complex_if=False, rf_gain_db=23.0, if_gain_db=23.0, adc_bits=12,
                       adc_full_scale=1.0, max_sample_rate=4e6)
    # The paper adds white Gaussian noise of a chosen variance; this one is
    # about one ADC code rms.
    noise = NoiseConfig("variance", variance=(1.0 / 4096) ** 2)
    return RadarConfig(chirp, antennas, if_chain, noise, tx_power_dbm=5.0, hfov_deg=120.0,
                       vfov_deg=60.0, render_width=1000, render_height=342)


def iwr6843_config() -> RadarConfig:
    """TI IWR6843 (ISK antenna layout), 3 Tx TDM-MIMO x 4 Rx, complex IF."""
    chirp = ChirpConfig(start_frequency=60.0e9, slope=70e12, sample_rate=5.209e6,
                        num_samples=256, num_chirps=48, chirp_repetition_time=87.14e-6,
                        frame_repetition_time=0.1, adc_start_time=7e-6, ramp_end_time=57.14e-6)
    lam = chirp.wavelength
    tx = np.array([[0.0, 0.0, 0.0], [lam, -lam / 2, 0.0], [2 * lam, 0.0, 0.0]])
    tx = tx - np.array([4 * lam, 0.0, 0.0])  # transmitters left of the receivers
    pattern = ElementPattern(gain_dbi=7.0, cos_exponent_azimuth=1.0, cos_exponent_elevation=1.0)
    antennas = AntennaArray(tx, ula_positions(4, lam / 2), pattern, pattern, tx_sequence=(0, 1, 2))
    if_chain = IFChain(complex_if=True, rf_gain_db=20.0, if_gain_db=30.0, hp_cutoff=175e3,
                       hp_order=1, aaf_cutoff=0.9 * 5.209e6, aaf_order=4, adc_bits=16,
                       adc_full_scale=2.0, max_sample_rate=12.5e6)
    return RadarConfig(chirp, antennas, if_chain, NoiseConfig("thermal", noise_figure_db=12.0),
                       tx_power_dbm=12.0, hfov_deg=120.0, vfov_deg=120.0, render_width=320,
                       render_height=320)


PRESET_CONFIGS: dict[str, tuple[Callable[[], RadarConfig], str]] = {
    "infineon_bgt60tr13c": (bgt60tr13c_config,
                            "Infineon BGT60TR13C: 1 Tx, 3 Rx (L), real IF, as its SDK records"),
    "paper_bgt60tr13c": (paper_bgt60tr13c_config,
                         "Seed paper Table 2: 60 GHz, B = 6 GHz, 512 samples, 16 chirps, 2 Rx ULA"),
    "ti_iwr6843": (iwr6843_config, "TI IWR6843: 3 Tx x 4 Rx TDM-MIMO, complex IF"),
}

def preset_config(preset: str, /, **overrides: Any) -> RadarConfig:
    """The :class:`RadarConfig` of ``preset`` with ``overrides``.

    An override names a RadarConfig field (``tx_power_dbm=10``), a field of a
    sub-config (``num_chirps=4``, ``if_gain_db=30``, ``noise_figure_db=10``)
    or a nested path (``chirp__num_chirps=4``); ``frame_rate`` [Hz] sets
    ``frame_repetition_time``.
    """
    if preset not in PRESET_CONFIGS:
        raise UnknownNameError("radar preset", preset, list(PRESET_CONFIGS))
    cfg = PRESET_CONFIGS[preset][0]()
    top = {f.name for f in fields(RadarConfig)}
    subs = {part: {f.name for f in fields(type(getattr(cfg, part)))}
            for part in ("chirp", "if_chain", "noise")}
    resolved: dict[str, Any] = {}
    if "frame_rate" in overrides:
        # Frames per second [Hz] set the frame repetition time.
        rate = validation.positive(f"{preset} override 'frame_rate'", overrides.pop("frame_rate"), "Hz")
        overrides["frame_repetition_time"] = 1.0 / rate
    for key, value in overrides.items():
        if key in top or "__" in key:
            resolved[key] = value
            continue
        owners = [part for part, names in subs.items() if key in names]
        if len(owners) != 1:
            valid = sorted(top | set().union(*subs.values()))
            raise ConfigError(f"{preset} override {key!r}", value,
                              "a field of RadarConfig or of its chirp / if_chain / noise: "
                              + ", ".join(valid))
        resolved[f"{owners[0]}__{key}"] = value
    return cfg.with_overrides(**resolved) if resolved else cfg
