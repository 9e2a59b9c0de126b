"""Device effects on the correlation images: cross-talk, noise, ADC and saturation.

Each raw frame of a two-tap pixel holds tap A and tap B electrons,

    A = S/2 + D/2,   B = S/2 - D/2,

with ``S`` the electrons of both taps (modulated signal, ambient light and
dark current) and ``D`` the correlation sample (tap difference). The device
reads out ``D`` through the ADC as ``raw = offset + D / electrons_per_dn``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from twinsense.tof.config import ToFConfig

#: The cross-talk kernel is cut at this many standard deviations.
CROSSTALK_TRUNCATE = 3.0


def crosstalk(images: np.ndarray, sigma_px: float) -> np.ndarray:
    """Isotropic Gaussian cross-talk over the last two (row, column) axes.

    Optical and electrical cross-talk spread a pixel's charge into its
    neighbours. No public model of the pico flexx exists, so this is the
    seed paper's assumption: a Gaussian of ``sigma_px`` pixels (0: off, the
    input is returned unchanged). Edges replicate the border pixel so that a
    uniform image stays uniform.

    Parameters
    ----------
    images : (..., H, W) float32
    sigma_px : float
        Standard deviation [px].
    """
    if sigma_px <= 0:
        return images
    sigma = (0.0,) * (images.ndim - 2) + (sigma_px, sigma_px)
    return ndimage.gaussian_filter(images, sigma, mode="nearest", truncate=CROSSTALK_TRUNCATE)


@dataclass(frozen=True, eq=False)
class Digitized:
    """Read-out of one depth frame's modulated raw frames.

    Attributes
    ----------
    raw : (F, 4, H, W) uint16 or float32
        Raw values [DN] (``adc_offset_dn`` + tap difference); uint16 with
        quantization, float32 without.
    difference_dn : (F, 4, H, W) float32
        Tap differences ``raw - adc_offset_dn`` [DN].
    saturated : (H, W) bool
        A tap passed full well or a raw value left ``raw_valid_range_dn`` in
        any raw frame.
    """

    raw: np.ndarray
    difference_dn: np.ndarray
    saturated: np.ndarray


def digitize(correlation: np.ndarray, tap_sum: np.ndarray, config: ToFConfig,
             normals: np.ndarray | None) -> Digitized:
    """Noise, ADC quantisation and saturation of the correlation samples.

    Noise (``config.noise``): the tap electrons are Poisson (signal, ambient
    and dark electrons all count) plus Gaussian read noise per tap, so the
    difference has variance ``S + 2 sigma_read^2``. The Poisson counts are
    drawn in their Gaussian limit: the mean counts here are thousands of
    electrons, where the two distributions differ by less than 1 % in spread,
    and at low counts the read noise dominates.

    Saturation: tap A or B above ``full_well`` or a raw value outside the
    valid window (the device reports such pixels as invalid, depth 0). The tap
    sum ``S`` enters the clipping test without its own noise: that noise is
    ``sqrt(S)``, under 0.4 % of a 100 ke- full well.

    Parameters
    ----------
    correlation : (F, 4, H, W) float32
        Expected tap differences D [e-].
    tap_sum : (F or 1, 4 or 1, H, W) float32
        Expected electrons of both taps S [e-] (broadcast against ``correlation``).
    config : ToFConfig
    normals : (F, 4, H, W) float32 or None
        Standard normal draws for the noise (required when ``config.noise`` is
        on; see :func:`twinsense.tof.pipeline.draw_noise`). Overwritten.

    Returns
    -------
    Digitized
    """
    cfg = config
    d = correlation
    s = tap_sum
    if cfg.noise:
        if normals is None or normals.shape != d.shape:
            raise ValueError("standard normal draws of the raw frames' shape are needed when "
                             "ToFConfig.noise is on")
        # sigma depends on S only, so it is computed on S's (possibly broadcast) shape.
        sigma = np.sqrt(np.maximum(s, 0.0) + np.float32(2.0 * cfg.read_noise ** 2))
        normals *= sigma
        normals += d
        d = normals
    e = np.float32(cfg.electrons_per_dn)
    off = np.float32(cfg.adc_offset_dn)
    lo, hi = cfg.raw_valid_range_dn
    # max(A, B) = (S + |D|) / 2 > full well  <=>  |D| > 2 FW - S; the raw window bounds D too.
    well = np.float32(2.0 * cfg.full_well) - s
    upper = np.minimum(well, np.float32((hi - cfg.adc_offset_dn) * cfg.electrons_per_dn))
    lower = np.maximum(-well, np.float32((lo - cfg.adc_offset_dn) * cfg.electrons_per_dn))
    bad = (d > upper) | (d < lower)
    f, k = bad.shape[:2]
    saturated = np.logical_or.reduce(bad.reshape(f * k, -1), axis=0).reshape(bad.shape[2:])
    code = d * (np.float32(1.0) / e)
    code += off
    if cfg.quantization:
        np.rint(code, out=code)
        # Quantisation can carry a value just inside the window onto its edge value: the
        # device compares the digital value.
        saturated |= np.logical_or.reduce(((code < lo) | (code > hi)).reshape(f * k, -1), axis=0
                                          ).reshape(bad.shape[2:])
    np.clip(code, 0.0, float(2 ** cfg.adc_bits - 1), out=code)
    # Without quantisation the raw values are floats: copied, since ``code`` becomes the difference.
    raw = code.astype(np.uint16) if cfg.quantization else code.copy()
    code -= off
    return Digitized(raw, code, saturated)


def gray_value(tap_sum: np.ndarray, config: ToFConfig, normals: np.ndarray | None) -> np.ndarray:
    """Gray-value image: mean tap electrons of the intensity frame in DN, (H, W) uint16.

    Parameters
    ----------
    tap_sum : (H, W) float32
        Expected electrons of both taps [e-].
    normals : (H, W) float32 or None
        Standard normal draws (required when ``config.noise`` is on).
    """
    cfg = config
    s = tap_sum
    if cfg.noise:
        if normals is None or normals.shape != s.shape:
            raise ValueError("standard normal draws of the image's shape are needed when "
                             "ToFConfig.noise is on")
        sigma = np.sqrt(np.maximum(s, 0.0) + np.float32(2.0 * cfg.read_noise ** 2))
        s = s + sigma * normals
    code = np.clip(np.rint(s * np.float32(0.5 / cfg.electrons_per_dn)), 0, 2 ** cfg.adc_bits - 1)
    return code.astype(np.uint16)
