"""Range and Doppler FFTs, DC / clutter removal and the physical axes.

Axis order everywhere is the Infineon Radar SDK's: a raw cube is
``(rx, chirp, sample)``; after the range FFT it is ``(rx, chirp, range_bin)``,
after the Doppler FFT ``(rx, doppler_bin, range_bin)``. Every function works on
any number of leading axes, so a recording ``(frame, rx, chirp, sample)`` can be
passed whole.

Real and complex IF
-------------------
A real-IF device (Infineon BGT60: one real ADC per receiver) samples
``A cos(phi(t))``; its spectrum is Hermitian, so only the positive half
(bins ``0 .. n_fft/2 - 1``) is kept and covers ranges up to
``fs/2 * c / (2 S)``. A complex-IF device (TI xWR, I/Q ADC) samples
``A exp(j phi(t))``; all ``n_fft`` bins are kept and cover ``0 .. fs * c/(2 S)``.
In both cases a target's range bin carries the phasor ``exp(+j phi)`` of the IF
model ``phi = 2 pi f_c tau + 2 pi S tau t - pi S tau^2`` (PHYSICS.md, section 2), so a
receding target (tau growing from chirp to chirp) appears at a positive
Doppler frequency and a positive radial velocity.

Scaling: spectra are divided by the window's coherent gain, so a complex tone
of amplitude A peaks at magnitude A and a real cosine of amplitude A at A/2.
"""

from __future__ import annotations

import numpy as np

from twinsense import validation as V
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError
from twinsense.radar.processing import windows

#: Speed of light in vacuum [m/s].

MTI_METHODS = ("none", "mean", "two_pulse")


def remove_dc(cube: np.ndarray, axis: int = -1) -> np.ndarray:
    """Subtract the mean along ``axis`` (default: fast time, per chirp and antenna).

    Removes the ADC mid-scale offset and the DC part of the Tx-Rx leakage
    before the range FFT. Returns a new float (or complex) array.
    """
    x = np.asarray(cube)
    if not np.iscomplexobj(x):
        x = x.astype(float)
    return x - x.mean(axis=axis, keepdims=True)


def mti(x: np.ndarray, method: str = "mean", axis: int = -2) -> np.ndarray:
    """Moving-target indication along the slow-time (chirp) ``axis``.

    Parameters
    ----------
    x : array, (..., chirp, range_bin) by default
        Range spectra (or raw samples) per chirp.
    method : {"none", "mean", "two_pulse"}
        ``"mean"`` subtracts the mean over chirps (static clutter removal;
        keeps the chirp count), ``"two_pulse"`` forms ``x[m] - x[m-1]``
        (a two-pulse canceller, one chirp fewer, gain ``2 sin(pi f_D T)``).
    """
    V.choice("mti", method, MTI_METHODS)
    if method == "none":
        return x
    if method == "mean":
        return x - x.mean(axis=axis, keepdims=True)
    return np.diff(x, axis=axis)


def range_fft(cube: np.ndarray, *, n_fft: int | None = None, window: str = "hann",
              real_if: bool = True) -> np.ndarray:
    """Windowed, zero-padded FFT along the last (fast-time) axis.

    Parameters
    ----------
    cube : array, (..., sample)
        IF samples, e.g. ``(rx, chirp, sample)``; real for ``real_if``.
    n_fft : int, optional
        FFT length >= number of samples (zero padding interpolates the
        spectrum; it does not improve resolution). Default: number of samples.
    window : str
        A name in :data:`twinsense.radar.processing.windows.WINDOWS`.
    real_if : bool
        Keep the positive half of a real signal's spectrum (``n_fft // 2``
        bins); otherwise keep all ``n_fft`` bins of a complex signal.

    Returns
    -------
    complex array, (..., range_bin)
    """
    x = np.asarray(cube)
    n = x.shape[-1]
    n_fft = n if n_fft is None else V.integer("range n_fft", n_fft, lo=n)
    if real_if and np.iscomplexobj(x):
        raise ConfigError("real_if", True, "False for a complex IF cube (or pass the real samples)")
    if real_if and n_fft % 2:
        raise ConfigError("range n_fft", n_fft, "an even length for a real-IF cube")
    w = windows.get(window, n)
    w = w / windows.coherent_gain(w)
    if real_if:
        spec = np.fft.rfft(x * w, n=n_fft)
        # The positive half without the Nyquist bin. No factor 2: a cosine then
        # peaks at A/2, and white noise of variance sigma^2 gives the same
        # per-bin noise power for real and complex devices (sigma^2 sum(w^2)/sum(w)^2).
        return spec[..., : n_fft // 2]
    return np.fft.fft(x * w, n=n_fft)


def doppler_fft(x: np.ndarray, *, n_fft: int | None = None, window: str = "hann",
                axis: int = -2, shift: bool = True) -> np.ndarray:
    """Windowed, zero-padded FFT along the slow-time (chirp) ``axis``.

    With ``shift`` (default) the zero-velocity bin is moved to index
    ``n_fft // 2`` (``numpy.fft.fftshift``), matching :func:`velocity_axis`.

    Returns
    -------
    complex array, the chirp axis replaced by ``n_fft`` Doppler bins, e.g.
    ``(rx, doppler_bin, range_bin)``.
    """
    x = np.asarray(x)
    ax = axis % x.ndim
    n = x.shape[ax]
    n_fft = n if n_fft is None else V.integer("doppler n_fft", n_fft, lo=n)
    w = windows.get(window, n)
    w = w / windows.coherent_gain(w)
    shape = [1] * x.ndim
    shape[ax] = n
    spec = np.fft.fft(x * w.reshape(shape), n=n_fft, axis=ax)
    return np.fft.fftshift(spec, axes=ax) if shift else spec


# ---------------------------------------------------------------- axes


def range_bin_spacing(sample_rate: float, slope: float, n_fft: int) -> float:
    """Range step between FFT bins [m]: ``c fs / (2 S n_fft)``.

    ``sample_rate`` [Hz], ``slope`` S [Hz/s] of the chirp ramp.
    """
    fs = V.positive("sample_rate", sample_rate, "Hz")
    s = V.positive("slope", slope, "Hz/s")
    return SPEED_OF_LIGHT * fs / (2.0 * s * V.integer("n_fft", n_fft, lo=1))


def range_axis(n_bins: int, *, sample_rate: float, slope: float, n_fft: int) -> np.ndarray:
    """Range [m] of the first ``n_bins`` bins of an ``n_fft``-point range FFT, (n_bins,)."""
    return np.arange(n_bins) * range_bin_spacing(sample_rate, slope, n_fft)


def range_resolution(*, sample_rate: float, slope: float, n_samples: int) -> float:
    """Rayleigh range resolution ``c / (2 B_s)`` [m], B_s = S n / fs the sampled bandwidth."""
    return range_bin_spacing(sample_rate, slope, n_samples)


def max_range(*, sample_rate: float, slope: float, real_if: bool) -> float:
    """Largest unambiguous range [m]: beat frequency ``fs/2`` (real IF) or ``fs`` (complex IF)."""
    fs = V.positive("sample_rate", sample_rate, "Hz")
    s = V.positive("slope", slope, "Hz/s")
    f_max = fs / 2 if real_if else fs
    return SPEED_OF_LIGHT * f_max / (2.0 * s)


def wavelength(carrier_frequency: float) -> float:
    """Carrier wavelength [m] for ``carrier_frequency`` [Hz]."""
    return SPEED_OF_LIGHT / V.positive("carrier_frequency", carrier_frequency, "Hz")


def velocity_axis(n_fft: int, *, chirp_repetition_time: float,
                  carrier_frequency: float) -> np.ndarray:
    """Radial velocity [m/s] of each fftshifted Doppler bin, (n_fft,); positive = receding.

    ``chirp_repetition_time`` [s] is the time between chirps that share an
    antenna (for TDM-MIMO, the loop period ``n_tx * T_c``);
    ``carrier_frequency`` [Hz] the frequency at the middle of the sampled ramp.
    """
    n = V.integer("doppler n_fft", n_fft, lo=1)
    t = V.positive("chirp_repetition_time", chirp_repetition_time, "s")
    f_d = (np.arange(n) - n // 2) / (n * t)
    return f_d * wavelength(carrier_frequency) / 2.0


def max_velocity(*, chirp_repetition_time: float, carrier_frequency: float) -> float:
    """Unambiguous radial velocity ``lambda / (4 T)`` [m/s]; the axis spans [-v_max, v_max)."""
    t = V.positive("chirp_repetition_time", chirp_repetition_time, "s")
    return wavelength(carrier_frequency) / (4.0 * t)


def velocity_resolution(n_chirps: int, *, chirp_repetition_time: float,
                        carrier_frequency: float) -> float:
    """Doppler resolution ``lambda / (2 N T)`` [m/s] for ``n_chirps`` chirps."""
    n = V.integer("n_chirps", n_chirps, lo=1)
    t = V.positive("chirp_repetition_time", chirp_repetition_time, "s")
    return wavelength(carrier_frequency) / (2.0 * n * t)
