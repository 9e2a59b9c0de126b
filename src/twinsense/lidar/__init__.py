"""Pulsed time-of-flight LiDAR: rotating multi-beam heads and rosette scanners.

Scan patterns with per-point timestamps and rolling-scan skew, beams cast as
sub-ray bundles over their divergence, echoes from the received waveform
(multi-echo, first / last / strongest / dual), the LiDAR equation with
near-range overlap, fog and rain extinction, detection from SNR, range noise,
saturation and range walk. See docs/lidar.md.
"""

from functools import partial

from twinsense.lidar.config import RETURN_MODES, LidarConfig, RosetteScan, RotatingScan
from twinsense.lidar.frame import LidarFrame
from twinsense.lidar.presets import LIDAR_PRESETS, lidar_config
from twinsense.lidar.sensor import Lidar

#: Presets of kind "lidar" for the registry: name -> (factory(name=, mount=, **overrides), description).
SENSOR_PRESETS = {name: (partial(Lidar.preset, name), desc) for name, (_, desc) in LIDAR_PRESETS.items()}

__all__ = ["LIDAR_PRESETS", "RETURN_MODES", "SENSOR_PRESETS", "Lidar", "LidarConfig", "LidarFrame", "RosetteScan",
           "RotatingScan", "lidar_config"]
