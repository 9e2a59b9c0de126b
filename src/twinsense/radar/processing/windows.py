"""Tapering windows for the range and Doppler FFTs.

A window trades main-lobe width (resolution) for side-lobe level (dynamic
range). The registry holds the ones radar processing chains commonly use; the
Infineon Radar SDK examples use Blackman-Harris for range and Chebyshev for
Doppler, TI's demos Hann/Blackman.

Windows are periodic ("DFT-even", ``scipy.signal.get_window(..., fftbins=True)``),
the right choice for spectral analysis with an FFT of the same length.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.signal import get_window

from twinsense import validation as V
from twinsense.errors import UnknownNameError


def _scipy(name: str | tuple) -> Callable[[int], np.ndarray]:
    return lambda n: get_window(name, n, fftbins=True)


#: name -> function ``n -> (n,) float`` window.
WINDOWS: dict[str, Callable[[int], np.ndarray]] = {
    "rect": lambda n: np.ones(n),
    "hann": _scipy("hann"),
    "hamming": _scipy("hamming"),
    "blackman": _scipy("blackman"),
    "blackmanharris": _scipy("blackmanharris"),
    # 60 dB Chebyshev: flat side lobes just under a 12-bit ADC's dynamic range.
    "chebyshev60": _scipy(("chebwin", 60)),
}


def get(name: str, n: int) -> np.ndarray:
    """Window ``name`` of length ``n`` as a (n,) float64 array (peak 1).

    Raises
    ------
    UnknownNameError
        If ``name`` is not a key of :data:`WINDOWS` (the message lists them).
    """
    if name not in WINDOWS:
        raise UnknownNameError("window", name, list(WINDOWS))
    n = V.integer("window length", n, lo=1)
    return np.asarray(WINDOWS[name](n), dtype=float)


def coherent_gain(w: np.ndarray) -> float:
    """Coherent (amplitude) gain ``sum(w)``: a unit tone's FFT peak magnitude."""
    return float(np.sum(w))


def noise_gain(w: np.ndarray) -> float:
    """Noise power gain ``sum(w**2)``: white noise of unit variance gives this mean FFT power."""
    return float(np.sum(w * w))
