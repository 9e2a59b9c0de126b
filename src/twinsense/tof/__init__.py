"""AMCW time-of-flight camera: configuration, presets, signal model, effects, demodulation."""

from twinsense.tof.camera import ToFCamera, capture_sequence
from twinsense.tof.config import ToFConfig
from twinsense.tof.frame import InvalidReason, ToFFrame
from twinsense.tof.presets import PICO_FLEXX_MODES, TOF_PRESETS, tof_preset

__all__ = ["PICO_FLEXX_MODES", "TOF_PRESETS", "InvalidReason", "ToFCamera", "ToFConfig", "ToFFrame",
           "capture_sequence", "tof_preset"]
