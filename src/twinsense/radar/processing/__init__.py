"""FMCW radar signal processing: plain functions on numpy arrays.

Axis order follows the Infineon Radar SDK: raw cube ``(rx, chirp, sample)``,
range spectra ``(rx, chirp, range_bin)``, range-Doppler ``(rx, doppler_bin,
range_bin)``. Modules: :mod:`.windows`, :mod:`.fft` (range/Doppler FFTs, MTI,
axes), :mod:`.cfar`, :mod:`.peaks`, :mod:`.doa`, :mod:`.mimo`,
:mod:`.detections`, :mod:`.pipeline`.
"""

from twinsense.radar.processing.cfar import CFAR_METHODS, CfarResult, cfar_1d, cfar_2d
from twinsense.radar.processing.detections import Detections, RadarPointCloud
from twinsense.radar.processing.doa import DOA_METHODS, estimate_angle, estimate_direction_cosine
from twinsense.radar.processing.fft import (
    doppler_fft,
    max_range,
    max_velocity,
    mti,
    range_axis,
    range_fft,
    range_resolution,
    remove_dc,
    velocity_axis,
    velocity_resolution,
)
from twinsense.radar.processing.mimo import compensate_doppler_phase, demultiplex, virtual_array
from twinsense.radar.processing.peaks import group_peaks
from twinsense.radar.processing.pipeline import ProcessingResult, ProcessingSettings, process_cube
from twinsense.radar.processing.windows import WINDOWS

__all__ = [
    "CFAR_METHODS",
    "DOA_METHODS",
    "WINDOWS",
    "CfarResult",
    "Detections",
    "ProcessingResult",
    "ProcessingSettings",
    "RadarPointCloud",
    "cfar_1d",
    "cfar_2d",
    "compensate_doppler_phase",
    "demultiplex",
    "doppler_fft",
    "estimate_angle",
    "estimate_direction_cosine",
    "group_peaks",
    "max_range",
    "max_velocity",
    "mti",
    "process_cube",
    "range_axis",
    "range_fft",
    "range_resolution",
    "remove_dc",
    "velocity_axis",
    "velocity_resolution",
    "virtual_array",
]
