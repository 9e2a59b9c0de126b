"""Echoes from the received waveform of each beam.

A beam is n x n sub-rays; sub-ray s returns the pulse with peak power P_s
delayed to its range R_s. The received waveform, as a function of range x, is

    w(x) = sum_s P_s exp(-(x - R_s)^2 / (2 sigma_R^2))

(the Gaussian pulse convolved with the footprint's range profile), with
sigma_R = c sigma_t / 2 the pulse's range spread. Echoes are the local maxima
of w. Two surfaces in one footprint give two echoes when they are further
apart than about 2 sigma_R (the pulse resolution), each with the power of its
share of the footprint, and one echo at a mixed range when they are closer.

Two exact-to-the-stated-bound paths:

- a beam whose sub-ray ranges span at most ``FAST_SPREAD`` sigma_R has one
  echo: its peak lies at the power-weighted mean range to within the third
  central moment of the ranges / (2 sigma_R^2) <= FAST_SPREAD^3 sigma_R / 2
  (2 microns for a 5 ns pulse), and the peak value is w evaluated there;
- every other beam is sampled on a grid of step sigma_R / 4 covering
  +- 4 sigma_R around each sub-ray range, local maxima are refined by a
  parabola through the log of three samples (exact for a single Gaussian).
"""

from __future__ import annotations

import numpy as np

FAST_SPREAD = 0.05  # sub-ray range spread (in sigma_R) under which a beam has one echo at the mean range
STEP = 0.25  # waveform sample step [sigma_R]
HALF_WIDTH = 4.0  # sampled half-width around each sub-ray range [sigma_R]; exp(-8) = 3e-4 of a peak beyond


class Echoes:
    """Candidate echoes of a set of beams, sorted by beam, then range.

    Attributes
    ----------
    beam : (m,) int64 — row of the beam.
    range : (m,) float64 — peak position [m].
    power : (m,) float64 — peak received power [W].
    source : (m,) int64 — sub-ray contributing most to the peak (index into the beam's S sub-rays).
    """

    def __init__(self, beam, range_, power, source):
        self.beam, self.range, self.power, self.source = beam, range_, power, source

    def __len__(self) -> int:
        return len(self.beam)


def echoes(r: np.ndarray, p: np.ndarray, sigma: float, fast_spread: float = FAST_SPREAD) -> Echoes:
    """Echoes of beams with sub-ray ranges ``r`` (n, S) [m] and peak powers ``p`` (n, S) [W].

    Sub-rays with p <= 0 (misses, range-gated) take no part. ``sigma``: the
    pulse's range standard deviation [m]. ``fast_spread`` (in sigma): beams
    whose sub-ray ranges span at most this use the single-echo closed form
    (0 sends every beam through the sampled waveform).
    """
    valid = p > 0
    big = 1e30
    rv = np.where(valid, r, big)
    any_valid = valid.any(axis=1)
    rmin = rv.min(axis=1)
    rmax = np.where(valid, r, -big).max(axis=1)
    spread = rmax - rmin
    fast = any_valid & (spread <= fast_spread * sigma)
    slow = any_valid & ~fast

    parts = []
    fb = np.flatnonzero(fast)
    if len(fb):
        pf, rf = p[fb], np.where(valid[fb], r[fb], 0.0)
        psum = pf.sum(axis=1)
        rbar = (pf * rf).sum(axis=1) / psum
        g = pf * np.exp(-0.5 * ((rf - rbar[:, None]) / sigma) ** 2)
        parts.append((fb, rbar, g.sum(axis=1), g.argmax(axis=1)))
    sb = np.flatnonzero(slow)
    if len(sb):
        parts.append(_sampled(rv[sb], p[sb], sigma, sb))
    if not parts:
        e = np.zeros(0, np.int64)
        return Echoes(e, np.zeros(0), np.zeros(0), e)
    beam, rng, pw, src = (np.concatenate(a) for a in zip(*parts))
    order = np.lexsort((rng, beam))
    return Echoes(beam[order], rng[order], pw[order], src[order])


def _sampled(rv: np.ndarray, p: np.ndarray, sigma: float, rows: np.ndarray):
    """Local maxima of the sampled waveform of beams (k, S); rv holds 1e30 for sub-rays without power."""
    k, s = rv.shape
    step = STEP * sigma
    half = HALF_WIDTH * sigma
    # Merge the +-4 sigma windows of each beam's sub-rays (sorted by range)
    # into segments, then sample each segment on its own grid.
    order = np.argsort(rv, axis=1)
    rs = np.take_along_axis(rv, order, axis=1)
    ok = rs < 1e29
    beam_of = np.repeat(np.arange(k), s)[ok.ravel()]
    r_flat = rs.ravel()[ok.ravel()]
    new_seg = np.ones(len(r_flat), bool)
    new_seg[1:] = (beam_of[1:] != beam_of[:-1]) | (r_flat[1:] - r_flat[:-1] > 2 * half)
    seg_id = np.cumsum(new_seg) - 1
    starts = np.flatnonzero(new_seg)
    seg_lo = r_flat[starts] - half
    seg_hi = np.maximum.reduceat(r_flat, starts) + half
    seg_beam = beam_of[starts]
    n_samp = np.ceil((seg_hi - seg_lo) / step).astype(np.int64) + 1
    del seg_id
    total = int(n_samp.sum())
    seg_of = np.repeat(np.arange(len(starts)), n_samp)
    first = np.concatenate([[0], np.cumsum(n_samp)[:-1]])
    idx_in = np.arange(total) - np.repeat(first, n_samp)
    x = seg_lo[seg_of] + idx_in * step
    b = seg_beam[seg_of]
    # Waveform at every sample from all of its beam's sub-rays.
    d = (x[:, None] - rv[b]) / sigma
    contrib = p[b] * np.exp(-0.5 * d * d)
    w = contrib.sum(axis=1)
    # Interior local maxima of each segment.
    last = np.zeros(total, bool)
    last[np.cumsum(n_samp) - 1] = True
    firsts = np.zeros(total, bool)
    firsts[first] = True
    up = np.zeros(total, bool)
    up[1:] = w[1:] > w[:-1]
    down = np.zeros(total, bool)
    down[:-1] = w[:-1] >= w[1:]
    peak = np.flatnonzero(up & down & ~firsts & ~last & (w > 0))
    lm = np.log(np.maximum(w[peak - 1], 1e-300))
    l0 = np.log(w[peak])
    lp = np.log(np.maximum(w[peak + 1], 1e-300))
    curv = lm - 2.0 * l0 + lp
    off = np.where(curv < 0, 0.5 * (lm - lp) / np.where(curv < 0, curv, -1.0), 0.0)
    off = np.clip(off, -0.5, 0.5)
    r_peak = x[peak] + off * step
    p_peak = np.exp(l0 - 0.25 * (lm - lp) * off)
    # Contribution of each sub-ray at the refined peak: the strongest names the echo's surface.
    dd = (r_peak[:, None] - rv[b[peak]]) / sigma
    src = (p[b[peak]] * np.exp(-0.5 * dd * dd)).argmax(axis=1)
    return rows[b[peak]], r_peak, p_peak, src


def select(beam: np.ndarray, range_: np.ndarray, power: np.ndarray, mode: str, n: int) -> np.ndarray:
    """Indices of the echoes a device reports, per beam, for return ``mode`` (at most ``n`` per beam).

    ``beam``, ``range_``, ``power`` (m,): detected echoes sorted by beam then
    range. Modes: strongest, first, last, dual (strongest and last; when the
    last is the strongest, the second strongest), multi (the ``n`` strongest).
    Returned indices keep the input order (by beam, then range).
    """
    if len(beam) == 0:
        return np.zeros(0, np.int64)
    by_power = _rank(beam, -power)
    if mode == "strongest":
        keep = by_power == 0
    elif mode == "first":
        keep = _rank(beam, range_) == 0
    elif mode == "last":
        keep = _rank(beam, -range_) == 0
    elif mode == "dual":
        last = _rank(beam, -range_) == 0
        strongest = by_power == 0
        # Beams whose last echo is also their strongest report the second strongest instead.
        coincide = np.zeros(int(beam.max()) + 1, bool)
        coincide[beam[last & strongest]] = True
        keep = strongest | (last & ~strongest) | ((by_power == 1) & coincide[beam])
    else:  # multi
        keep = by_power < n
    return np.flatnonzero(keep)


def _rank(group: np.ndarray, key: np.ndarray) -> np.ndarray:
    """Rank (0 = smallest key) of every element within its group; ties in input order."""
    order = np.lexsort((np.arange(len(key)), key, group))
    g = group[order]
    start = np.ones(len(g), bool)
    start[1:] = g[1:] != g[:-1]
    first = np.maximum.accumulate(np.where(start, np.arange(len(g)), 0))
    rank = np.empty(len(g), np.int64)
    rank[order] = np.arange(len(g)) - first
    return rank


def slots(beam: np.ndarray) -> np.ndarray:
    """Echo slot of each element (0, 1, ... in input order within each beam); input sorted by beam."""
    if len(beam) == 0:
        return np.zeros(0, np.int64)
    start = np.ones(len(beam), bool)
    start[1:] = beam[1:] != beam[:-1]
    first = np.maximum.accumulate(np.where(start, np.arange(len(beam)), 0))
    return np.arange(len(beam)) - first
