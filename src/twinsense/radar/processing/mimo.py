"""TDM-MIMO: virtual array and the Doppler-induced phase compensation.

With time-division multiplexing the transmitters fire in turn, chirp ``m``
from Tx ``m % n_tx``; one *loop* of ``n_tx`` chirps lasts ``T_loop = n_tx T_c``.
In the far field the phase at Rx ``r`` of the signal sent by Tx ``t`` depends
on ``(p_tx + p_rx) . u``, so the ``n_tx x n_rx`` channels act as a virtual
array at positions ``p_tx + p_rx``.

A moving target's phase also advances by ``2 pi f_D T_c`` between the chirps
of consecutive transmitters. Left alone, this adds a phase step every
``n_rx`` virtual elements that the angle estimator reads as a spatial phase:
the angle is biased. After the Doppler FFT each bin has a known ``f_D``, so
the step is removed by multiplying the channels of Tx ``t`` by
``exp(-j 2 pi f_D t T_c)`` (Li et al., IEEE Access 9, 2021; TI's
"MIMO radar" application note SWRA554). This is exact for targets inside the
TDM unambiguous velocity ``lambda / (4 T_loop)``.
"""

from __future__ import annotations

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError


def virtual_array(tx_positions: np.ndarray, rx_positions: np.ndarray) -> np.ndarray:
    """Virtual element positions ``p_tx + p_rx`` [m], (n_tx * n_rx, 3), Tx-major.

    Virtual index ``v = t * n_rx + r``, the order :func:`demultiplex` produces.
    """
    tx = V.array("tx_positions", tx_positions, (None, 3), "m")
    rx = V.array("rx_positions", rx_positions, (None, 3), "m")
    return (tx[:, None, :] + rx[None, :, :]).reshape(-1, 3)


def demultiplex(cube: np.ndarray, n_tx: int) -> np.ndarray:
    """Split a TDM cube into virtual channels.

    Parameters
    ----------
    cube : array, (rx, chirp, ...)
        Chirps in firing order: Tx 0, Tx 1, ..., Tx n_tx-1, Tx 0, ...
    n_tx : int
        Number of transmitters in the TDM cycle; ``chirp`` must be a multiple.

    Returns
    -------
    array, (n_tx * rx, chirp // n_tx, ...), virtual channel ``t * n_rx + r``.
    """
    x = np.asarray(cube)
    n_tx = V.integer("n_tx", n_tx, lo=1)
    n_rx, n_chirp = x.shape[:2]
    if n_chirp % n_tx:
        raise ConfigError("n_tx", n_tx, f"a divisor of the number of chirps ({n_chirp})")
    loops = n_chirp // n_tx
    # (rx, loop, tx, ...) -> (tx, rx, loop, ...)
    y = x.reshape((n_rx, loops, n_tx, *x.shape[2:]))
    y = np.moveaxis(y, 2, 0)
    return y.reshape((n_tx * n_rx, loops, *x.shape[2:]))


def doppler_phase_correction(n_doppler: int, n_tx: int, n_rx: int, *,
                             shifted: bool = True) -> np.ndarray:
    """Per-channel, per-Doppler-bin correction factors, (n_tx * n_rx, n_doppler) complex.

    Bin ``b`` of an ``n_doppler``-point Doppler FFT over loops has
    ``f_D T_loop = (b - n_doppler // 2) / n_doppler`` (fftshifted) or the
    wrapped ``b / n_doppler`` (not shifted); the Tx ``t`` channels get
    ``exp(-j 2 pi f_D t T_c) = exp(-j 2 pi t f_D T_loop / n_tx)``.
    """
    n = V.integer("n_doppler", n_doppler, lo=1)
    b = np.arange(n)
    frac = (b - n // 2) / n if shifted else np.where(b < (n + 1) // 2, b, b - n) / n
    t = np.repeat(np.arange(n_tx), n_rx)
    return np.exp(-2j * np.pi * t[:, None] * frac[None, :] / n_tx)


def compensate_doppler_phase(range_doppler: np.ndarray, n_tx: int, *,
                             shifted: bool = True) -> np.ndarray:
    """Remove the TDM Doppler phase from a virtual range-Doppler cube.

    Parameters
    ----------
    range_doppler : complex array, (n_tx * n_rx, doppler_bin, range_bin)
        Output of the Doppler FFT over loops of :func:`demultiplex`'s cube.
    n_tx : int
        Transmitters in the TDM cycle.
    shifted : bool
        Whether the Doppler axis is fftshifted (zero velocity in the middle).
    """
    x = np.asarray(range_doppler)
    n_v, n_d = x.shape[:2]
    n_tx = V.integer("n_tx", n_tx, lo=1)
    if n_v % n_tx:
        raise ConfigError("n_tx", n_tx, f"a divisor of the number of virtual channels ({n_v})")
    corr = doppler_phase_correction(n_d, n_tx, n_v // n_tx, shifted=shifted)
    return x * corr.reshape(corr.shape + (1,) * (x.ndim - 2))
