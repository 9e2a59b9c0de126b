"""FMCW radar: configuration, antennas, scene scatterers, IF synthesis, device
effects, device configuration files (:mod:`~twinsense.radar.formats`) and raw
captures (:mod:`~twinsense.radar.captures`), presets, the :class:`FMCWRadar` sensor and the
processing chain (:mod:`twinsense.radar.processing`).

Raw cube axis order follows the Infineon Radar SDK: ``(rx, chirp, sample)``.
"""

from functools import partial

from twinsense.radar.antennas import (
    AntennaArray,
    ElementPattern,
    l_shaped_positions,
    planar_positions,
    ula,
    ula_positions,
)
from twinsense.radar.captures import (
    InfineonRecording,
    load_dca1000,
    load_infineon_recording,
    load_ti_capture,
    write_infineon_recording,
)
from twinsense.radar.config import ChirpConfig, IFChain, NoiseConfig, RadarConfig
from twinsense.radar.formats import (
    InfineonConfig,
    TICfg,
    load_infineon_config,
    read_ti_cfg,
    save_infineon_config,
)
from twinsense.radar.impairments import ChirpNonlinearity, Impairments, PhaseNoiseMask
from twinsense.radar.interference import Interferer
from twinsense.radar.presets import PRESET_CONFIGS, preset_config
from twinsense.radar.processing import *  # noqa: F403
from twinsense.radar.processing import __all__ as _processing_all
from twinsense.radar.radiometry import radar_equation_amplitude
from twinsense.radar.scatterers import Scatterers, ScatterRenderer, received_amplitude
from twinsense.radar.sensor import FMCWRadar, RadarFrame, make_radar
from twinsense.radar.synthesis import synthesize, synthesize_exact

__all__ = [
    "PRESET_CONFIGS",
    "AntennaArray",
    "ChirpConfig",
    "ChirpNonlinearity",
    "ElementPattern",
    "FMCWRadar",
    "IFChain",
    "Impairments",
    "InfineonConfig",
    "InfineonRecording",
    "Interferer",
    "NoiseConfig",
    "PhaseNoiseMask",
    "RadarConfig",
    "RadarFrame",
    "SENSOR_PRESETS",
    "ScatterRenderer",
    "Scatterers",
    "TICfg",
    "l_shaped_positions",
    "load_dca1000",
    "load_infineon_config",
    "load_infineon_recording",
    "load_ti_capture",
    "make_radar",
    "planar_positions",
    "preset_config",
    "radar_equation_amplitude",
    "read_ti_cfg",
    "received_amplitude",
    "save_infineon_config",
    "synthesize",
    "synthesize_exact",
    "ula",
    "ula_positions",
    "write_infineon_recording",
    *_processing_all,
]

#: Presets for the registry (:mod:`twinsense.presets`): name -> (factory(**overrides), description).
SENSOR_PRESETS = {name: (partial(make_radar, name), description)
                  for name, (_, description) in PRESET_CONFIGS.items()}
