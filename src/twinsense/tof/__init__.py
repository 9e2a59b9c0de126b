"""AMCW time-of-flight camera: configuration, presets, signal model, effects, demodulation."""

from twinsense.tof.camera import ToFCamera, capture_sequence
from twinsense.tof.config import ToFConfig
from twinsense.tof.frame import InvalidReason, ToFFrame
from twinsense.tof.presets import PICO_FLEXX_MODES, TOF_PRESETS, tof_preset

__all__ = ["PICO_FLEXX_MODES", "SENSOR_PRESETS", "TOF_PRESETS", "InvalidReason", "ToFCamera", "ToFConfig", "ToFFrame",
           "capture_sequence", "tof_preset"]

_DESCRIPTIONS = {
    "pmd_pico_flexx": "pmd CamBoard pico flexx: 224 x 171, calibrated lens, Royale modes (mode=...)",
    "paper_pico_flexx": "seed paper's pico flexx: 224 x 171, 72 x 45 deg, 20 MHz, 7.5 m",
    "generic": "plain AMCW ToF camera, 62 x 45 deg, 80.32 + 60.24 MHz",
}


#: Presets for the registry (:mod:`twinsense.presets`): name -> (factory(**overrides), description).
SENSOR_PRESETS = {name: (lambda _p=name, **kw: ToFCamera.preset(_p, **kw), _DESCRIPTIONS[name])
                  for name in TOF_PRESETS}
