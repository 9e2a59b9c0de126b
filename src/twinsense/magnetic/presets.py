"""Named Hall sensor configurations, from the makers' data sheets.

- ``tle493d``: Infineon TLE493D-W2B6, 3-axis Hall, I2C, 12-bit per axis,
  +-160 mT full range at 7.7 LSB/mT (130 uT/LSB; the data sheet's
  "programmable resolution down to 65 uT" is the short-range mode,
  ``sensitivity=15.4e3, b_max=0.1``). Noise 0.1 mT rms per axis (the order of
  one full-range LSB; representative). Sensor axes: x, y in the package
  plane, z out of the top face.
- ``a1324``: Allegro A1324, 1-axis linear Hall, ratiometric analog output at
  5 V: 5.0 mV/G = 50 V/T, quiescent output 2.5 V (VCC / 2), 17 kHz bandwidth,
  output noise 7 mV peak-to-peak taken as 6 sigma (1.17 mV rms = 23 uT rms
  input-referred); output clamped at 0.25 / 4.75 V (representative clamps,
  i.e. +-45 mT); sensitivity drift +0.12 %/K (typical, compensating NdFeB
  magnets' -0.12 %/K).
- ``mlx90393``: Melexis MLX90393, 3-axis, 16-bit, at GAIN_SEL = 7 and
  RES = 0: 0.150 uT/LSB on x, y and 0.242 uT/LSB on z, so +-4.9 mT (x, y) and
  +-7.9 mT (z) before the code range clips. Noise 1 uT rms per axis
  (representative of its moderate oversampling settings).
- ``hall_switch``: a unipolar Hall switch (3144-class): operate 20 mT,
  release 15 mT (5 mT hysteresis), output on the package's z axis.
  Representative of that class, whose data sheets give wide min/max windows.
- ``hall_array8``: eight TLE493D in a row along x, 10 mm apart (one sensor
  object read in one vectorised call).
"""

from __future__ import annotations

from dataclasses import replace

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.magnetic.config import HallSwitch, MagneticConfig

_TLE = MagneticConfig(axes="xyz", output="digital", sensitivity=7.7e3, b_max=0.16, noise_rms=1e-4, adc_bits=12,
                      frame_rate=1000.0)

MAGNETIC_PRESETS: dict[str, tuple[MagneticConfig, str]] = {
    "tle493d": (_TLE, "Infineon TLE493D-W2B6 3-axis Hall, 12 bit, +-160 mT, 130 uT/LSB"),
    "a1324": (MagneticConfig(axes="z", output="analog", sensitivity=50.0, b_max=0.1, noise_rms=23.4e-6,
                             sensitivity_tc=0.0012, quiescent_voltage=2.5, output_min=0.25, output_max=4.75,
                             frame_rate=10_000.0),
              "Allegro A1324 1-axis linear Hall, 5 mV/G analog output, 2.5 V quiescent"),
    "mlx90393": (MagneticConfig(axes="xyz", output="digital", sensitivity=(1 / 0.150e-6, 1 / 0.150e-6, 1 / 0.242e-6),
                                b_max=0.05, noise_rms=1e-6, adc_bits=16, frame_rate=500.0),
                 "Melexis MLX90393 3-axis, 16 bit, 0.150 / 0.242 uT/LSB (gain 7)"),
    "hall_switch": (MagneticConfig(axes="z", output="switch", sensitivity=1.0, b_max=0.5,
                                   switch=HallSwitch(0.020, 0.015, "unipolar"), frame_rate=1000.0),
                    "unipolar Hall switch, operate 20 mT, release 15 mT"),
    "hall_array8": (replace(_TLE, positions=tuple((0.01 * k, 0.0, 0.0) for k in range(8))),
                    "eight TLE493D 10 mm apart along x, read together"),
}


def magnetic_config(name: str, **overrides) -> MagneticConfig:
    """The named configuration with config-field ``overrides``."""
    if name not in MAGNETIC_PRESETS:
        raise UnknownNameError("magnetic preset", name, list(MAGNETIC_PRESETS))
    cfg = MAGNETIC_PRESETS[name][0]
    bad = [k for k in overrides if k not in MagneticConfig.__dataclass_fields__]
    if bad:
        raise ConfigError("sensor.overrides", bad[0], "one of: " + ", ".join(MagneticConfig.__dataclass_fields__))
    return replace(cfg, **overrides) if overrides else cfg
