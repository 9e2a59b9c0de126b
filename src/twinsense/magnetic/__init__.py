"""Magnetic sensing: permanent magnets in the scene, Hall and magnetoresistive sensors.

Exact fields of cylinders (axial and diametric), blocks and rings, superposed
with the ambient (Earth) field; sensors with sensitivity, offset, noise,
saturation, temperature drift, quantisation and Hall switches with
hysteresis. See docs/magnetic.md.
"""

from functools import partial

from twinsense.magnetic.config import EARTH_FIELD, HallSwitch, MagneticConfig
from twinsense.magnetic.presets import MAGNETIC_PRESETS, magnetic_config
from twinsense.magnetic.scene_field import magnet_field, scene_field
from twinsense.magnetic.sensor import MagneticFrame, MagneticSensor

#: Presets of kind "magnetic" for the registry: name -> (factory(name=, mount=, **overrides), description).
SENSOR_PRESETS = {name: (partial(MagneticSensor.preset, name), desc) for name, (_, desc) in MAGNETIC_PRESETS.items()}

__all__ = ["EARTH_FIELD", "MAGNETIC_PRESETS", "SENSOR_PRESETS", "HallSwitch", "MagneticConfig", "MagneticFrame",
           "MagneticSensor", "magnet_field", "magnetic_config", "scene_field"]
