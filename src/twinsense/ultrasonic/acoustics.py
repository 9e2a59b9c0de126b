"""Airborne ultrasound: speed of sound, ISO 9613-1 air absorption, piston directivity.

Plain functions of SI quantities; every one is checked against its closed form
or the standard's tabulated values in ``tests/ultrasonic/test_acoustics.py``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq
from scipy.special import j1

from twinsense import validation as V
from twinsense.errors import ConfigError

ZERO_CELSIUS = 273.15  # [K]
ISO_T0 = 293.15  # ISO 9613-1 reference temperature [K]
ISO_T01 = 273.16  # triple-point isotherm of water [K] (ISO 9613-1, saturation pressure)
ISO_PR = 101.325e3  # reference pressure [Pa]
#: 2 J1(x) / x = 1/2 (the -6 dB point of a piston's one-way pattern) at x = 2.2152.
X_MINUS_6DB = float(brentq(lambda x: 2 * j1(x) / x - 0.5, 1.0, 3.8))


def speed_of_sound(temperature_c: float) -> float:
    """Speed of sound in dry air [m/s] at ``temperature_c`` [deg C]: c = 331.3 sqrt(1 + T/273.15).

    The ideal-gas law with c = 331.3 m/s at 0 deg C. Humidity raises c by
    0.1-0.3 % at room temperature (Cramer 1993); left out, as sensors that
    compensate temperature do (a 2 m target then reads ~4 mm short at 50 % RH).
    """
    t = V.number("temperature_c", temperature_c, lo=-ZERO_CELSIUS, lo_open=True, unit="deg C")
    return 331.3 * math.sqrt(1.0 + t / ZERO_CELSIUS)


def air_absorption_db_per_m(frequency, temperature_c: float = 20.0, relative_humidity: float = 50.0,
                            pressure: float = ISO_PR) -> np.ndarray:
    """Pure-tone attenuation coefficient alpha [dB/m] of air, ISO 9613-1:1993 eq. (3)-(5), Annex B.

    The full formula: classical and rotational absorption plus the vibrational
    relaxation of oxygen and nitrogen, with their relaxation frequencies

    - f_rO = (p/p_r) (24 + 4.04e4 h (0.02 + h) / (0.391 + h)),
    - f_rN = (p/p_r) (T/T0)^-1/2 (9 + 280 h exp(-4.170 ((T/T0)^-1/3 - 1))),

    h the molar concentration of water vapour [%] from the relative humidity
    through the saturation pressure p_sat/p_r = 10^(-6.8346 (T01/T)^1.261 + 4.6151).
    The standard tabulates 50 Hz - 10 kHz; the formula holds beyond (it is
    given for ultrasonic scale modelling), with an estimated accuracy of
    +-10 % up to 1 MHz at the humidities of indoor air.

    frequency [Hz] (scalar or array), temperature [deg C], relative humidity [%], pressure [Pa].
    A pressure amplitude after a path of length s is multiplied by 10^(-alpha s / 20).
    """
    f = np.asarray(frequency, dtype=float)
    if not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise ConfigError("frequency", frequency, "finite frequencies > 0 [Hz]")
    tc = V.number("temperature_c", temperature_c, lo=-100.0, hi=100.0, unit="deg C")
    hr = V.number("relative_humidity", relative_humidity, lo=0.0, hi=100.0, unit="%")
    pa = V.number("pressure", pressure, lo=1e3, hi=2e5, unit="Pa")
    t = tc + ZERO_CELSIUS
    p_rel = pa / ISO_PR
    psat_rel = 10.0 ** (-6.8346 * (ISO_T01 / t) ** 1.261 + 4.6151)
    h = hr * psat_rel / p_rel
    fr_o = p_rel * (24.0 + 4.04e4 * h * (0.02 + h) / (0.391 + h))
    fr_n = p_rel * (t / ISO_T0) ** -0.5 * (9.0 + 280.0 * h * math.exp(-4.170 * ((t / ISO_T0) ** (-1.0 / 3.0) - 1.0)))
    classical = 1.84e-11 / p_rel * (t / ISO_T0) ** 0.5
    relax = (t / ISO_T0) ** -2.5 * (0.01275 * math.exp(-2239.1 / t) / (fr_o + f * f / fr_o)
                                     + 0.1068 * math.exp(-3352.0 / t) / (fr_n + f * f / fr_n))
    return 8.686 * f * f * (classical + relax)


def piston_directivity(sin_x, sin_y, ka_x: float, ka_y: float | None = None) -> np.ndarray:
    """Far-field pressure directivity of a baffled piston, D = 2 J1(u) / u, D(0) = 1.

    ``sin_x``, ``sin_y``: direction cosines of the direction along the
    transducer's x and y axes (the boresight is z); ``ka_x``, ``ka_y``: wave
    number times the aperture semi-axes (a circular piston: ka_y = ka_x).
    u = sqrt((ka_x sin_x)^2 + (ka_y sin_y)^2): for a circular piston of
    radius a, u = k a sin(theta). An elliptical aperture is the affine image
    of a circle, so its pattern is the same function of this u (Kinsler et al.,
    Fundamentals of Acoustics, 4th ed., sec. 7.4 for the circular piston).
    The sign is kept: side lobes alternate in phase.
    """
    ka_y = ka_x if ka_y is None else ka_y
    u = np.hypot(ka_x * np.asarray(sin_x, float), ka_y * np.asarray(sin_y, float))
    small = u < 1e-6
    safe = np.where(small, 1.0, u)
    return np.where(small, 1.0 - u * u / 8.0, 2.0 * j1(safe) / safe)


def radius_for_beam_angle(full_angle_deg: float, frequency: float, c: float) -> float:
    """Piston radius [m] whose one-way pattern is 6 dB down at half of ``full_angle_deg``.

    Datasheets quote the total beam angle between the -6 dB points of the
    sound pressure: 2 J1(k a sin(theta/2)) / (k a sin(theta/2)) = 1/2, so
    a = 2.2152 / (k sin(theta/2)) with k = 2 pi f / c.
    """
    ang = V.number("beam_angle_deg", full_angle_deg, lo=0.0, hi=180.0, lo_open=True, hi_open=True, unit="deg")
    k = 2 * math.pi * V.positive("frequency", frequency, "Hz") / V.positive("c", c, "m/s")
    return X_MINUS_6DB / (k * math.sin(math.radians(ang) / 2))


def beam_angle_deg(radius: float, frequency: float, c: float) -> float:
    """Total -6 dB beam angle [deg] of a piston of ``radius`` [m] (inverse of :func:`radius_for_beam_angle`).

    180 when the pattern never falls by 6 dB (k a < 2.2152).
    """
    ka = 2 * math.pi * frequency / c * radius
    if ka <= X_MINUS_6DB:
        return 180.0
    return 2 * math.degrees(math.asin(X_MINUS_6DB / ka))
