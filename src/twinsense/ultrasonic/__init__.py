"""Ultrasonic (airborne pulse-echo) sensors: single transducers and sequentially fired rings.

Piston transducers with the 2 J1(x) / x directivity, the speed of sound from
temperature, ISO 9613-1 air absorption, specular / curved / edge echoes from
the scene's surfaces (physical optics around each specular point, visibility
through the render stage), the burst through the transducer's resonance,
ring-down, noise, envelope, threshold detection of the first echo, and
cross-talk between the transducers of a ring. See docs/ultrasonic.md.
"""

from twinsense.ultrasonic.config import UltrasonicConfig, ring_poses
from twinsense.ultrasonic.sensor import SENSOR_PRESETS, UltrasonicFrame, UltrasonicSensor

__all__ = ["SENSOR_PRESETS", "UltrasonicConfig", "UltrasonicFrame", "UltrasonicSensor", "ring_poses"]
