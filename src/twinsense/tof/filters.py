"""Royale-style post-filters: flying pixels and noisy pixels.

Thresholds follow the pmd Royale defaults collected in PHYSICS.md: a pixel
is flying when its z-depth differs from both horizontal neighbours, or from
both vertical neighbours, by more than a threshold that rises linearly from
0.018 m at z <= 1 m to 0.14 m at z >= 4.5 m; a pixel is too noisy when its
estimated distance noise exceeds 0.07 m.
"""

from __future__ import annotations

import numpy as np

from twinsense.tof.config import ToFConfig


def flying_pixel_mask(z: np.ndarray, valid: np.ndarray, config: ToFConfig) -> np.ndarray:
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
        Supplies the threshold ramp.

    Returns
    -------
    (H, W) bool: valid pixels that are flying pixels.
    """
    thr = config.flying_pixel_threshold(z).astype(np.float32)
    zz = np.where(valid, z, np.nan).astype(np.float32)
    pad = np.pad(zz, 1, constant_values=np.nan)
    centre = pad[1:-1, 1:-1]

    def jump(nb):
        # NaN comparisons are False: invalid neighbours never count as jumps.
        with np.errstate(invalid="ignore"):
            return np.abs(centre - nb) > thr

    horizontal = jump(pad[1:-1, :-2]) & jump(pad[1:-1, 2:])
    vertical = jump(pad[:-2, 1:-1]) & jump(pad[2:, 1:-1])
    return valid & (horizontal | vertical)


def noise_mask(sigma: np.ndarray, valid: np.ndarray, max_noise: float) -> np.ndarray:
    """Valid pixels whose estimated distance noise ``sigma`` [m] exceeds ``max_noise`` [m]."""
    return valid & ~(sigma <= max_noise)
