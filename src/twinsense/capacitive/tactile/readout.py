"""How touch controllers read a taxel array: self and mutual capacitance, images, ghosts.

Self-capacitance mode: the controller measures each electrode (every Tx row
and every Rx column) against ground in turn, the others held at ground: the
diagonal of the Maxwell matrix. A crossing array gives one profile per axis,
so a touch is located as the outer product of a row profile and a column
profile, and two touches on a diagonal light up four crossings: the two
touches and two ghosts (:func:`self_image`).

Mutual-capacitance mode: the controller drives one Tx row and reads every
Rx column at virtual ground: ``C_m = -C_tx,rx`` per crossing, one value per
taxel, so any number of touches are resolved.

Noise and quantisation follow :mod:`twinsense.capacitive.readout`. The
controller preset of the skins is the Analog Devices AD7147 CapTouch
controller (13 inputs, a 16-bit capacitance-to-digital converter with an
excitation source, used in the iCub skin): we take its conversion range as
+-8 pF (16 pF / 2**16 = 0.24 fF LSB) and its stated femtofarad resolution as
1 fF rms of noise at one full 12-stage sequence, whose conversion time is
9 ms in the datasheet (about 111 Hz). Those two figures are our reading of
the datasheet, not a measurement.
"""

from __future__ import annotations

import numpy as np

from twinsense.capacitive.presets import AD7746_READOUT, FDC1004_READOUT
from twinsense.capacitive.readout import ReadoutConfig
from twinsense.errors import UnknownNameError

__all__ = ["AD7147_READOUT", "CONTROLLERS", "controller", "mutual_image", "self_image"]

AD7147_READOUT = ReadoutConfig(noise_rms=1e-15, resolution=16e-12 / 2**16, noise_rate=1.0 / 9e-3)
"""Analog Devices AD7147: 1 fF rms at ~111 Hz, 0.24 fF LSB (see the module notes)."""

CONTROLLERS = {
    "ad7147": AD7147_READOUT,
    "fdc1004": FDC1004_READOUT,
    "ad7746": AD7746_READOUT,
}
"""Converter models by name (FDC1004 and AD7745/6: :mod:`twinsense.capacitive.presets`)."""


def controller(name: str) -> ReadoutConfig:
    """The converter model ``name`` (see :data:`CONTROLLERS`)."""
    if name not in CONTROLLERS:
        raise UnknownNameError("tactile controller", name, list(CONTROLLERS))
    return CONTROLLERS[name]


def mutual_image(maxwell: np.ndarray, tx: np.ndarray, rx: np.ndarray) -> np.ndarray:
    """(rows, cols) mutual capacitance ``-C[tx, rx]`` of every taxel [F].

    Parameters
    ----------
    maxwell : (k, k) float, Maxwell matrix [F].
    tx, rx : (rows, cols) int, the taxels' Tx and Rx terminals.
    """
    return -np.asarray(maxwell)[tx, rx]


def self_image(row_delta: np.ndarray, col_delta: np.ndarray, threshold: float) -> np.ndarray:
    """(rows, cols) bool: crossings a self-capacitance controller reports as touched.

    A crossing is touched when both its row and its column rose by more than
    ``threshold`` [F]: with two touches at (r1, c1) and (r2, c2) this also
    reports (r1, c2) and (r2, c1), the ghosts of a self-capacitance scan.
    """
    return (np.asarray(row_delta)[:, None] > threshold) & (np.asarray(col_delta)[None, :] > threshold)
