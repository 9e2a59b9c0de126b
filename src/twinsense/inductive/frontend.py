"""The oscillator front end: LC tank, damping, switching with hysteresis.

The coil (``L0``, loss resistance ``R0``) and a capacitor ``C = 1 / (omega0^2 L0)``
form the tank of the oscillator. Near resonance the tank is a parallel
resistance ``Rp = L / (R C)`` (series-to-parallel conversion, valid for
Q >> 1), and the oscillator amplitude of a current-driven tank is
proportional to it. A target changes the coil to ``L0 + dL``,
``R0 + dR`` (``dZ = dR + j omega dL`` from the FEM), so the amplitude
relative to the undamped sensor is

    a = Rp / Rp0 = ((L0 + dL) / L0) (R0 / (R0 + dR)),

and the oscillation frequency becomes ``1 / (2 pi sqrt((L0 + dL) C))``.
``dZ`` is taken at the nominal frequency; the shift, a few 1e-3 for the
targets here, changes it by less than that.

``R0`` holds the winding and core losses, set by the coil quality factor
``Q0`` (``R_w = omega0 L0 / Q0``), plus the eddy-current loss in the housing
(the real part of the head's FEM impedance).

The switching output turns on when the amplitude falls below ``a_on`` and
off when it rises above ``a_off > a_on`` (hysteresis), both calibrated on the
standard target: ``a_on`` is its amplitude at the switching distance
``s_n (1 + k_T (T - T_ref))`` and ``a_off`` at that distance times
``(1 + H)``.
"""

from __future__ import annotations

import numpy as np


def tank_amplitude(l0: float, r0: float, delta_r, delta_l):
    """Relative oscillator amplitude ``a = (L / L0) (R0 / R)`` (1 = undamped)."""
    return (l0 + np.asarray(delta_l)) / l0 * (r0 / (r0 + np.asarray(delta_r)))


def tank_frequency(l0: float, frequency: float, delta_l):
    """Oscillation frequency [Hz] of the tank tuned to ``frequency`` with the coil at ``L0 + dL``."""
    return frequency * np.sqrt(l0 / (l0 + np.asarray(delta_l)))


def switch(previous: bool, amplitude: float, a_on: float, a_off: float) -> bool:
    """Output with hysteresis: on below ``a_on``, off above ``a_off``, else unchanged."""
    if amplitude < a_on:
        return True
    if amplitude > a_off:
        return False
    return previous
