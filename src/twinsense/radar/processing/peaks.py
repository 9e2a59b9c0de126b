"""Peak grouping: one detection per target instead of every cell above threshold.

A point target spreads over a few range and Doppler bins (window main lobe,
zero padding), and CFAR marks all of them. Grouping keeps one cell per target:

- ``"local_max"``: a detected cell survives if no cell in its 3 x 3
  neighbourhood is stronger (TI's range/Doppler "peak grouping"). Two targets
  one resolution cell apart stay separate as long as a dip lies between them.
- ``"cluster"``: connected groups of detected cells (8-connectivity) give one
  detection each, at the group's strongest cell.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from twinsense import validation as V

GROUPING_METHODS = ("local_max", "cluster", "none")


def group_peaks(power: np.ndarray, mask: np.ndarray, method: str = "local_max", *,
                wrap_doppler: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the grouped detections in a (doppler_bin, range_bin) map.

    Parameters
    ----------
    power : float array, (doppler_bin, range_bin)
        Power map the detections were found in.
    mask : bool array, (doppler_bin, range_bin)
        CFAR detection mask.
    method : {"local_max", "cluster", "none"}
        Grouping rule (module docstring); ``"none"`` returns every detected cell.
    wrap_doppler : bool
        Treat the Doppler axis as periodic when comparing neighbours
        (``"local_max"`` only).

    Returns
    -------
    (doppler_idx, range_idx) : two int arrays, (n,), sorted by decreasing power.
    """
    V.choice("grouping", method, GROUPING_METHODS)
    p = np.asarray(power, dtype=float)
    m = np.asarray(mask, dtype=bool)
    if method == "none":
        d, r = np.nonzero(m)
    elif method == "local_max":
        # -inf outside the range edges so edge cells compete only with real cells.
        padded = np.pad(p, ((1, 1), (0, 0)), mode="wrap" if wrap_doppler else "edge")
        padded = np.pad(padded, ((0, 0), (1, 1)), mode="constant", constant_values=-np.inf)
        neigh = ndimage.maximum_filter(padded, size=3, mode="nearest")[1:-1, 1:-1]
        d, r = np.nonzero(m & (p >= neigh))
    else:
        labels, n = ndimage.label(m, structure=np.ones((3, 3), dtype=bool))
        if n == 0:
            return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
        flat = ndimage.maximum_position(p, labels, index=np.arange(1, n + 1))
        d, r = (np.array(a, dtype=int) for a in zip(*flat))
    order = np.argsort(-p[d, r], kind="stable")
    return d[order].astype(int), r[order].astype(int)


def parabolic_offset(left: np.ndarray, centre: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Sub-bin offset in [-0.5, 0.5] of a peak from three samples (e.g. log power).

    Vertex of the parabola through (-1, left), (0, centre), (1, right).
    """
    den = left - 2.0 * centre + right
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.where(den < 0, 0.5 * (left - right) / den, 0.0)
    return np.clip(off, -0.5, 0.5)
