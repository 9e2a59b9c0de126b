"""Named ToF camera configurations.

- ``pmd_pico_flexx``: the pmd CamBoard pico flexx as the Royale SDK drives
  it: calibrated intrinsics and OpenCV distortion, the 9-raw-frame
  dual-frequency modes (80.32 + 60.24 MHz, 5-25 fps) and the 5-raw-frame
  60.24 MHz modes (35 and 45 fps), chosen by ``mode``.
- ``paper_pico_flexx``: the seed paper's simplified camera (Table 1):
  224 x 171 px, 72 x 45 deg, 20 MHz single frequency (7.5 m unambiguous),
  no lens distortion.
- ``generic``: a plain 62 x 45 deg camera with the defaults of
  :class:`~twinsense.tof.config.ToFConfig`.

Overriding ``width`` / ``height`` gives the same optics on a smaller or larger
image (the sensor binned or resampled): the field of view and the optical
axis stay. ``fov_deg`` presets recompute their focal lengths from the size;
the calibrated pico flexx intrinsics are scaled with
:func:`~twinsense.render.rays.scaled_intrinsics`. To set other optics give
``intrinsics_px=(fx, fy, cx, cy)`` (with ``fov_deg=None`` on a ``fov_deg``
preset): explicit intrinsics are used as given.

Radiometric figures that pmd does not publish (illumination power, f-number,
full well, read noise) are representative of PMD/Infineon REAL3 sensors and
are chosen so that a white wall saturates closer than ~0.2 m in the
shortest-exposure mode and a retro-reflector saturates at room distances, as
the device does.

Working ranges for a matte white wall (drywall) facing the camera, from
:func:`~twinsense.tof.working_range.working_range`: the wall distances at
which at least 95 % of the pixels are expected valid (not saturated, above
the amplitude threshold, under the noise cut-off) and no pixel wraps.

==========================  =============
preset / mode               range [m]
==========================  =============
pmd MODE_9_5FPS_2000        0.87 - 5.36
pmd MODE_9_10FPS_1000       0.62 - 4.27
pmd MODE_9_15FPS_700        0.52 - 3.76
pmd MODE_9_25FPS_450        0.41 - 3.18
pmd MODE_5_35FPS_600        0.48 - 1.72
pmd MODE_5_45FPS_500        0.44 - 1.72
paper_pico_flexx            0.42 - 2.81
generic                     0.41 - 3.31
==========================  =============

The 60.24 MHz modes end where the image corners reach the 2.49 m
unambiguous range; the others where the dimmest pixels (image corners: beam
fall-off and cos^7 of the off-axis angle) reach the noise cut-off. Darker
surfaces end sooner, the centre of the image reaches further.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from twinsense import validation as V
from twinsense.errors import UnknownNameError
from twinsense.render.rays import scaled_intrinsics
from twinsense.tof.config import ToFConfig


@dataclass(frozen=True)
class PicoFlexxMode:
    """A Royale operation mode of the pico flexx."""

    frequencies: tuple[float, ...]
    frame_rate: float
    exposure_time: float


#: Royale use cases of the pico flexx: name -> (frequencies [Hz], fps, exposure [s]).
PICO_FLEXX_MODES: dict[str, PicoFlexxMode] = {
    "MODE_9_5FPS_2000": PicoFlexxMode((80.32e6, 60.24e6), 5.0, 2000e-6),
    "MODE_9_10FPS_1000": PicoFlexxMode((80.32e6, 60.24e6), 10.0, 1000e-6),
    "MODE_9_15FPS_700": PicoFlexxMode((80.32e6, 60.24e6), 15.0, 700e-6),
    "MODE_9_25FPS_450": PicoFlexxMode((80.32e6, 60.24e6), 25.0, 450e-6),
    "MODE_5_35FPS_600": PicoFlexxMode((60.24e6,), 35.0, 600e-6),
    "MODE_5_45FPS_500": PicoFlexxMode((60.24e6,), 45.0, 500e-6),
}

#: Public calibration of a pico flexx (PHYSICS.md): fx, fy, cx, cy [px] and OpenCV k.
PICO_FLEXX_INTRINSICS = (213.08, 213.48, 106.31, 87.48)
PICO_FLEXX_DISTORTION = (0.0656, -2.146, 0.0005, -0.0033, 3.229)
_PICO_SIZE = (224, 171)  # image size of the calibration

_PICO_COMMON = {
    "width": 224, "height": 171, "wavelength": 850e-9, "pixel_pitch": 17.5e-6,
    "gray_frame": True, "adc_bits": 12, "raw_valid_range_dn": (400.0, 3750.0),
    "adc_offset_dn": 2048.0, "readout_time": 1.0e-3, "illumination_power": 0.8,
    "illumination_fwhm_deg": (80.0, 60.0),
}


def pmd_pico_flexx(mode: str = "MODE_9_25FPS_450", **overrides) -> ToFConfig:
    """The pmd CamBoard pico flexx in one of its Royale modes (see ``PICO_FLEXX_MODES``)."""
    if mode not in PICO_FLEXX_MODES:
        raise UnknownNameError("pmd_pico_flexx.mode", mode, list(PICO_FLEXX_MODES))
    m = PICO_FLEXX_MODES[mode]
    fields = dict(_PICO_COMMON, fov_deg=None, intrinsics_px=PICO_FLEXX_INTRINSICS,
                  distortion=PICO_FLEXX_DISTORTION, modulation_frequencies=m.frequencies,
                  frame_rate=m.frame_rate, exposure_time=m.exposure_time)
    fields.update(overrides)
    size = (V.integer("ToFConfig.width", fields["width"], lo=1, hi=10_000),
            V.integer("ToFConfig.height", fields["height"], lo=1, hi=10_000))
    if "intrinsics_px" not in overrides and fields["intrinsics_px"] is not None and size != _PICO_SIZE:
        # A resized image is the same sensor binned or resampled: same field of view and axis.
        fields["intrinsics_px"] = scaled_intrinsics(PICO_FLEXX_INTRINSICS, _PICO_SIZE, size)
    return ToFConfig(**fields)


def paper_pico_flexx(**overrides) -> ToFConfig:
    """The seed paper's camera: 224 x 171, 72 x 45 deg, 20 MHz, 2 x 2 supersampling."""
    fields = dict(_PICO_COMMON, fov_deg=(72.0, 45.0), intrinsics_px=None,
                  distortion=(0.0, 0.0, 0.0, 0.0, 0.0), modulation_frequencies=(20e6,),
                  frame_rate=45.0, exposure_time=500e-6, supersample=2)
    fields.update(overrides)
    return ToFConfig(**fields)


def generic(**overrides) -> ToFConfig:
    """A plain camera with the ToFConfig defaults."""
    return ToFConfig(**overrides)


#: Preset registry: name -> factory(**overrides) -> ToFConfig.
TOF_PRESETS: dict[str, Callable[..., ToFConfig]] = {
    "pmd_pico_flexx": pmd_pico_flexx,
    "paper_pico_flexx": paper_pico_flexx,
    "generic": generic,
}


def tof_preset(name: str, **overrides) -> ToFConfig:
    """The named preset's config with ``overrides`` applied (``mode=`` for pmd_pico_flexx)."""
    if name not in TOF_PRESETS:
        raise UnknownNameError("ToF preset", name, list(TOF_PRESETS))
    unknown = sorted(set(overrides) - set(ToFConfig.__dataclass_fields__) - {"mode"})
    if unknown:
        raise UnknownNameError("ToFConfig field", unknown[0], list(ToFConfig.__dataclass_fields__))
    if "mode" in overrides and name != "pmd_pico_flexx":
        raise UnknownNameError(f"{name} option", "mode", list(ToFConfig.__dataclass_fields__))
    return TOF_PRESETS[name](**overrides)
