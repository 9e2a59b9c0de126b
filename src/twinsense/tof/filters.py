"""Royale-style post-filters: flying pixels and noisy pixels.

Thresholds start from the pmd Royale defaults collected in PHYSICS.md: a
pixel is flying when its z-depth differs from both horizontal neighbours, or
from both vertical neighbours, by more than a threshold that rises linearly
from 0.018 m at z <= 1 m to 0.14 m at z >= 4.5 m; a pixel is too noisy when
its estimated distance noise exceeds a cut-off (Royale: 0.07 m for the pico
flexx's modes; :attr:`ToFConfig.noise_cutoff` carries it over to other
modulation frequencies).

Royale's ramp is tuned to the noise of its own modes. A camera whose pixels
are noisier (a lower modulation frequency, less light) would lose most of a
flat, edge-free wall to it, so the threshold of each neighbour pair is raised
to ``k sqrt(sigma_c^2 + sigma_n^2)`` (the spread of the difference of two
independent noisy depths) where that is larger; ``k`` follows from the
share of pixels the filter may remove for noise alone
(:func:`noise_factor`).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import integrate, optimize

from twinsense.tof.config import ToFConfig


def _both_beyond(k: float, rho: float) -> float:
    """P(U1 > k, U2 > k) for standard normals U1, U2 of correlation ``rho``.

    Conditioning on U1 = x leaves U2 normal with mean rho x and variance
    1 - rho^2, so the probability is the integral over x > k of
    phi(x) Q((k - rho x) / sqrt(1 - rho^2)).
    """
    s = math.sqrt(2.0 * (1.0 - rho * rho))

    def integrand(x: float) -> float:
        return math.exp(-0.5 * x * x) / math.sqrt(2.0 * math.pi) * 0.5 * math.erfc((k - rho * x) / s)

    val, _ = integrate.quad(integrand, k, np.inf, epsabs=1e-14, epsrel=1e-10)
    return val


def noise_false_rate(k: float) -> float:
    """Share of the pixels of a flat, noisy surface flagged at the threshold ``k sqrt(2) sigma``.

    Along a row the two differences X1 = z_c - z_l and X2 = z_c - z_r have
    variance 2 sigma^2 each and covariance sigma^2 (they share z_c):
    correlation 1/2. Standardised, the pixel is flagged along the row when
    |U1| > k and |U2| > k: 2 P(U1 > k, U2 > k) (same sign; correlation 1/2)
    + 2 P(U1 > k, -U2 > k) (opposite signs; correlation -1/2). A row or a
    column flags the pixel: the union bound doubles that (the two events share
    only z_c, and their joint probability is of the order of the square of
    either).
    """
    row = 2.0 * (_both_beyond(k, 0.5) + _both_beyond(k, -0.5))
    return 2.0 * row


@functools.lru_cache(maxsize=16)
def noise_factor(false_rate: float) -> float:
    """k with :func:`noise_false_rate` (k) = ``false_rate`` (2.74 for 1e-3)."""
    return float(optimize.brentq(lambda k: noise_false_rate(k) - false_rate, 0.1, 12.0, xtol=1e-10))


def flying_pixel_mask(z: np.ndarray, valid: np.ndarray, config: ToFConfig,
                      sigma_z: np.ndarray | None = None) -> np.ndarray:
    """Pixels whose depth jumps away from both neighbours along a row or a column.

    An invalid or missing neighbour (image border) never counts as a jump,
    so a pixel next to a saturated region is not removed for that reason.

    Parameters
    ----------
    z : (H, W) float
        z-depth [m].
    valid : (H, W) bool
        Pixels with a measurement.
    config : ToFConfig
        Supplies the threshold ramp and the allowed false-positive rate.
    sigma_z : (H, W) float or None
        Estimated noise (1 sigma) of ``z`` [m]. A pair's threshold is then
        max(Royale ramp at z_c, k sqrt(sigma_c^2 + sigma_n^2)) with
        k = :func:`noise_factor` (``config.flying_pixel_false_rate``); None:
        the Royale ramp alone.

    Returns
    -------
    (H, W) bool: valid pixels that are flying pixels.
    """
    thr = config.flying_pixel_threshold(z).astype(np.float32)
    zz = np.where(valid, z, np.nan).astype(np.float32)
    pad = np.pad(zz, 1, constant_values=np.nan)
    centre = pad[1:-1, 1:-1]
    if sigma_z is not None:
        k2 = np.float32(noise_factor(config.flying_pixel_false_rate) ** 2)
        var = np.pad(np.where(valid, sigma_z, 0.0).astype(np.float32) ** 2, 1)
        var_c = var[1:-1, 1:-1]

    def jump(rows, cols):
        nb = pad[rows, cols]
        t = thr if sigma_z is None else np.maximum(thr, np.sqrt(k2 * (var_c + var[rows, cols])))
        # NaN comparisons are False: invalid neighbours never count as jumps.
        with np.errstate(invalid="ignore"):
            return np.abs(centre - nb) > t

    inner, before, after = slice(1, -1), slice(None, -2), slice(2, None)
    horizontal = jump(inner, before) & jump(inner, after)
    vertical = jump(before, inner) & jump(after, inner)
    return valid & (horizontal | vertical)


def noise_mask(sigma: np.ndarray, valid: np.ndarray, max_noise: float) -> np.ndarray:
    """Valid pixels whose estimated distance noise ``sigma`` [m] exceeds ``max_noise`` [m]."""
    return valid & ~(sigma <= max_noise)
