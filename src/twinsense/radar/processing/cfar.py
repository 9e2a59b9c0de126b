"""Constant-false-alarm-rate (CFAR) detectors, 1-D and 2-D.

All detectors work on *power* (square-law detected) maps. Under the usual
noise model (complex Gaussian noise, so exponentially distributed power) the
threshold factor ``alpha`` that gives the design false-alarm probability is
computed exactly from ``pfa``:

- CA (cell averaging, mean of N training cells ``Z``; threshold ``alpha Z``):
  ``pfa = (1 + alpha/N)^-N``  ->  ``alpha = N (pfa^(-1/N) - 1)``.
- OS (ordered statistic, k-th smallest of N cells ``X_(k)``; Rohling 1983,
  IEEE Trans. AES-19(4), eq. 12):
  ``pfa = prod_{i=0}^{k-1} (N - i) / (N - i + alpha)``, solved for alpha.
- GO / SO (greatest-of / smallest-of the means of the leading and lagging
  halves, n cells each; Hansen & Sawyers 1980, Gandhi & Kassam 1988), with
  ``T = alpha / n`` applied to the half's sum:
  ``pfa_SO = 2 sum_{i=0}^{n-1} C(n-1+i, i) (2+T)^-(n+i)``,
  ``pfa_GO = 2 (1+T)^-n - pfa_SO``.

Window geometry: per axis, ``guard`` cells on each side of the cell under test
(CUT) are skipped and the next ``train`` cells on each side are the training
cells. In 2-D the training cells are the rectangular ring between the guard box
``(2 g_d + 1) x (2 g_r + 1)`` and the outer box ``(2 (g_d + t_d) + 1) x
(2 (g_r + t_r) + 1)``; the GO/SO halves are the ring's columns before and after
the guard box along the range (last) axis, so that both halves hold the same
number of independent cells.

Edges: the map is padded per axis before filtering, ``"wrap"`` for a periodic
axis (Doppler) and ``"reflect"`` for range, so that every cell gets a full
training window (cells near a reflected edge see some training cells twice,
which raises their false-alarm rate slightly).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.ndimage import rank_filter
from scipy.optimize import brentq
from scipy.special import gammaln

from twinsense import validation as V
from twinsense.errors import ConfigError, UnknownNameError

PAD_MODES = ("wrap", "reflect")


# ---------------------------------------------------------------- exact Pfa


def ca_pfa(alpha: float, n: int) -> float:
    """False-alarm probability of CA-CFAR with ``n`` cells and factor ``alpha`` (on the mean)."""
    return float((1.0 + alpha / n) ** (-n))


def os_pfa(alpha: float, n: int, k: int) -> float:
    """Rohling's OS-CFAR false-alarm probability: k-th smallest of ``n`` cells, factor ``alpha``."""
    i = np.arange(k)
    return float(np.exp(np.sum(np.log(n - i) - np.log(n - i + alpha))))


def so_pfa(alpha: float, n_half: int) -> float:
    """SO-CFAR false-alarm probability, ``n_half`` cells per half, ``alpha`` on the half's mean."""
    t = alpha / n_half
    i = np.arange(n_half)
    # C(n-1+i, i) in log form so that large halves do not overflow.
    log_binom = gammaln(n_half + i) - gammaln(i + 1) - gammaln(n_half)
    return float(2.0 * np.sum(np.exp(log_binom - (n_half + i) * np.log(2.0 + t))))


def go_pfa(alpha: float, n_half: int) -> float:
    """GO-CFAR false-alarm probability (see :func:`so_pfa`); GO + SO = 2 x CA of one half."""
    return 2.0 * ca_pfa(alpha, n_half) - so_pfa(alpha, n_half)


def _solve(pfa_of_alpha: Callable[[float], float], pfa: float) -> float:
    # Every pfa(alpha) here falls monotonically from 1 (alpha = 0) to 0, so a
    # bracketing root finder on log(pfa) converges for any design pfa.
    target = np.log(pfa)
    hi = 1.0
    while np.log(pfa_of_alpha(hi)) > target:
        hi *= 2.0
    return float(brentq(lambda a: np.log(pfa_of_alpha(a)) - target, 0.0, hi,
                        xtol=1e-12, rtol=1e-12))


@lru_cache(maxsize=256)
def threshold_factor(method: str, pfa: float, n_train: int, rank: int | None = None) -> float:
    """Exact threshold factor ``alpha`` for ``method`` at design ``pfa``.

    ``n_train`` is the total number of training cells (GO/SO: both halves);
    ``rank`` the OS order statistic k (1-based).
    """
    if method == "ca":
        return n_train * (pfa ** (-1.0 / n_train) - 1.0)
    if method == "os":
        return _solve(lambda a: os_pfa(a, n_train, rank), pfa)
    if method == "go":
        return _solve(lambda a: go_pfa(a, n_train // 2), pfa)
    if method == "so":
        return _solve(lambda a: so_pfa(a, n_train // 2), pfa)
    raise UnknownNameError("cfar method", method, list(CFAR_METHODS))


# ---------------------------------------------------------------- result


@dataclass(frozen=True)
class CfarResult:
    """Output of a CFAR detector; arrays have the input map's shape.

    Attributes
    ----------
    noise : float array
        Noise-power estimate per cell (same unit as the power map).
    threshold : float array
        Detection threshold ``alpha * noise``.
    mask : bool array
        ``power > threshold``.
    alpha : float
        Threshold factor used.
    method : str
        Registry name of the detector.
    n_train : int
        Training cells per window.
    """

    noise: np.ndarray
    threshold: np.ndarray
    mask: np.ndarray
    alpha: float
    method: str
    n_train: int


# ---------------------------------------------------------------- windows


def _box_sums_1d(xp: np.ndarray, starts: int, length: int, n_out: int) -> np.ndarray:
    """Sums of ``length`` consecutive cells starting at ``i + starts`` for i < n_out (last axis)."""
    c = np.concatenate([np.zeros((*xp.shape[:-1], 1)), np.cumsum(xp, axis=-1)], axis=-1)
    return c[..., starts + length: starts + length + n_out] - c[..., starts: starts + n_out]


def _sat(xp: np.ndarray) -> np.ndarray:
    """Summed-area table over the last two axes with a leading zero row and column."""
    s = np.zeros((*xp.shape[:-2], xp.shape[-2] + 1, xp.shape[-1] + 1))
    s[..., 1:, 1:] = xp.cumsum(axis=-2).cumsum(axis=-1)
    return s


def _box_sums_2d(sat: np.ndarray, r0: int, nr: int, c0: int, nc: int,
                 out: tuple[int, int]) -> np.ndarray:
    """Sums of the (nr, nc) box at offset (r0, c0) from each output cell."""
    d, r = out
    return (sat[..., r0 + nr: r0 + nr + d, c0 + nc: c0 + nc + r]
            - sat[..., r0: r0 + d, c0 + nc: c0 + nc + r]
            - sat[..., r0 + nr: r0 + nr + d, c0: c0 + r]
            + sat[..., r0: r0 + d, c0: c0 + r])


def _check_pfa(pfa: float) -> float:
    return V.number("pfa", pfa, lo=0.0, hi=1.0, lo_open=True, hi_open=True)


def _check_window(axis_name: str, guard: int, train: int, length: int) -> tuple[int, int]:
    g = V.integer(f"guard[{axis_name}]", guard, lo=0)
    t = V.integer(f"train[{axis_name}]", train, lo=1)
    if g >= t:
        raise ConfigError(f"guard[{axis_name}]", g,
                          f"fewer guard cells than training cells per side (train = {t}); "
                          "widen the training window or shrink the guard")
    if 2 * (g + t) + 1 > length:
        raise ConfigError(f"train[{axis_name}]", t,
                          f"a window 2*(guard + train) + 1 <= {length} cells (the map's "
                          f"{axis_name} length), got {2 * (g + t) + 1}")
    return g, t


def _os_rank(rank: int | None, n_train: int) -> int:
    if rank is None:
        # Rohling's recommendation k ~ 3N/4: robust to a few interfering
        # targets in the window at a small CA-like detection loss.
        return max(1, round(0.75 * n_train))
    return V.integer("rank", rank, lo=1, hi=n_train)


def _pad(x: np.ndarray, pads: list[tuple[int, int]], modes: tuple[str, ...]) -> np.ndarray:
    # One np.pad per axis: numpy applies a single mode to all axes.
    for ax, ((lo, hi), mode) in enumerate(zip(pads, modes)):
        if lo or hi:
            width = [(0, 0)] * x.ndim
            width[ax] = (lo, hi)
            x = np.pad(x, width, mode=mode)
    return x


# ---------------------------------------------------------------- detectors


def cfar_1d(power: np.ndarray, method: str = "ca", *, guard: int = 2, train: int = 8,
            pfa: float = 1e-3, rank: int | None = None, axis: int = -1,
            mode: str = "reflect") -> CfarResult:
    """CFAR along one ``axis`` of a power array (every other axis is independent).

    Parameters
    ----------
    power : float array, any shape, e.g. (rx, chirp, range_bin)
        Square-law detected map ``|X|^2`` (linear, not dB).
    method : {"ca", "os", "go", "so"}
        Key of :data:`CFAR_METHODS`.
    guard, train : int
        Guard and training cells on each side of the CUT (``guard < train``).
    pfa : float
        Design false-alarm probability in (0, 1).
    rank : int, optional
        OS only: order statistic k (1-based) among the ``2 train`` cells.
    axis : int
        Axis to slide along.
    mode : {"reflect", "wrap"}
        Edge handling along ``axis`` (``"wrap"`` for a Doppler axis).
    """
    spec = _method(method)
    p = np.asarray(power, dtype=float)
    p_last = np.moveaxis(p, axis, -1)
    length = p_last.shape[-1]
    g, t = _check_window("axis", guard, train, length)
    V.choice("mode", mode, PAD_MODES)
    pfa = _check_pfa(pfa)
    n = 2 * t
    k = _os_rank(rank, n) if method == "os" else None
    alpha = threshold_factor(method, pfa, n, k)
    pad = g + t
    if method == "os":
        footprint = np.ones(2 * pad + 1, dtype=bool)
        footprint[t: t + 2 * g + 1] = False
        fp = footprint.reshape((1,) * (p_last.ndim - 1) + (-1,))
        # As in cfar_2d: a wrapped axis uses the filter's own "wrap" mode unpadded.
        opad = 0 if mode == "wrap" else pad
        xp = _pad(p_last, [(0, 0)] * (p_last.ndim - 1) + [(opad, opad)],
                  ("reflect",) * (p_last.ndim - 1) + (mode,))
        noise = rank_filter(xp, k - 1, footprint=fp, mode="wrap")[..., opad: opad + length]
    else:
        xp = _pad(p_last, [(0, 0)] * (p_last.ndim - 1) + [(pad, pad)],
                  ("reflect",) * (p_last.ndim - 1) + (mode,))
        lead = _box_sums_1d(xp, 0, t, length) / t
        lag = _box_sums_1d(xp, t + 2 * g + 1, t, length) / t
        noise = spec.combine(lead, lag)
    noise = np.moveaxis(noise, -1, axis)
    threshold = alpha * noise
    return CfarResult(noise, threshold, p > threshold, alpha, method, n)


def cfar_2d(power: np.ndarray, method: str = "ca", *, guard: tuple[int, int] = (1, 2),
            train: tuple[int, int] = (2, 8), pfa: float = 1e-3, rank: int | None = None,
            modes: tuple[str, str] = ("wrap", "reflect")) -> CfarResult:
    """CFAR over the last two axes of a power map, e.g. (doppler_bin, range_bin).

    Parameters
    ----------
    power : float array, (..., doppler_bin, range_bin)
        Square-law detected map (linear). Leading axes are independent maps.
    method : {"ca", "os", "go", "so"}
        Key of :data:`CFAR_METHODS`.
    guard, train : (int, int)
        Guard and training cells on each side of the CUT per axis
        (doppler, range); ``guard < train`` on each axis.
    pfa : float
        Design false-alarm probability in (0, 1).
    rank : int, optional
        OS only: order statistic k (1-based) among the ring's cells.
    modes : (str, str)
        Edge handling per axis: ``"wrap"`` (periodic Doppler) or ``"reflect"``.
    """
    spec = _method(method)
    p = np.asarray(power, dtype=float)
    if p.ndim < 2:
        raise ConfigError("power", f"array of shape {p.shape}", "a map with at least 2 axes")
    d_len, r_len = p.shape[-2:]
    gd, td = _check_window("doppler", guard[0], train[0], d_len)
    gr, tr = _check_window("range", guard[1], train[1], r_len)
    for i, m in enumerate(modes):
        V.choice(f"modes[{i}]", m, PAD_MODES)
    pfa = _check_pfa(pfa)
    pd, pr = gd + td, gr + tr
    ring = (2 * pd + 1) * (2 * pr + 1) - (2 * gd + 1) * (2 * gr + 1)
    # GO/SO use the ring's columns beyond the guard box along range only.
    n = 2 * tr * (2 * pd + 1) if method in ("go", "so") else ring
    k = _os_rank(rank, n) if method == "os" else None
    alpha = threshold_factor(method, pfa, n, k)
    if method == "os":
        footprint = np.ones((2 * pd + 1, 2 * pr + 1), dtype=bool)
        footprint[td: td + 2 * gd + 1, tr: tr + 2 * gr + 1] = False
        fp = footprint.reshape((1,) * (p.ndim - 2) + footprint.shape)
        # The rank filter's cost grows with the cells it visits, so a wrapped
        # axis is not padded but left to the filter's own "wrap" mode; only
        # reflected axes are padded (and cropped again). A padded axis never
        # reaches the filter's edge handling for the cells that are kept.
        dpad = 0 if modes[0] == "wrap" else pd
        rpad = 0 if modes[1] == "wrap" else pr
        xp = _pad(p, [(0, 0)] * (p.ndim - 2) + [(dpad, dpad), (rpad, rpad)],
                  ("reflect",) * (p.ndim - 2) + tuple(modes))
        noise = rank_filter(xp, k - 1, footprint=fp, mode="wrap")
        noise = noise[..., dpad: dpad + d_len, rpad: rpad + r_len]
    else:
        xp = _pad(p, [(0, 0)] * (p.ndim - 2) + [(pd, pd), (pr, pr)],
                  ("reflect",) * (p.ndim - 2) + tuple(modes))
        sat = _sat(xp)
        out = (d_len, r_len)
        if method == "ca":
            outer = _box_sums_2d(sat, 0, 2 * pd + 1, 0, 2 * pr + 1, out)
            inner = _box_sums_2d(sat, td, 2 * gd + 1, tr, 2 * gr + 1, out)
            noise = (outer - inner) / ring
        else:
            half = n // 2
            lead = _box_sums_2d(sat, 0, 2 * pd + 1, 0, tr, out) / half
            lag = _box_sums_2d(sat, 0, 2 * pd + 1, tr + 2 * gr + 1, tr, out) / half
            noise = spec.combine(lead, lag)
    threshold = alpha * noise
    return CfarResult(noise, threshold, p > threshold, alpha, method, n)


# ---------------------------------------------------------------- registry


@dataclass(frozen=True)
class CfarMethod:
    """A CFAR variant: how the two half-window means combine into the noise estimate.

    ``combine`` is None for OS, whose estimate is an order statistic of the
    whole window rather than a function of the two half means.
    """

    name: str
    description: str
    combine: Callable[[np.ndarray, np.ndarray], np.ndarray] | None


#: name -> CFAR variant, for :func:`cfar_1d` and :func:`cfar_2d`.
CFAR_METHODS: dict[str, CfarMethod] = {
    "ca": CfarMethod("ca", "cell averaging", lambda a, b: 0.5 * (a + b)),
    "os": CfarMethod("os", "ordered statistic (Rohling 1983)", None),
    "go": CfarMethod("go", "greatest-of the two half means", np.maximum),
    "so": CfarMethod("so", "smallest-of the two half means", np.minimum),
}


def _method(name: str) -> CfarMethod:
    if name not in CFAR_METHODS:
        raise UnknownNameError("cfar method", name, list(CFAR_METHODS))
    return CFAR_METHODS[name]
