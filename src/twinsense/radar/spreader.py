"""A compiled 1-D type-1 NUFFT for many strength vectors on the same points.

    out[d, n] = sum_i strengths[d, i] exp(1j x_i (n - N//2)),   n = 0 .. N-1

(finufft's type 1 with ``isign=+1`` and ``modeord=0``, N even or odd) by the classic
spread - FFT - deconvolve scheme (Barnett, Magland, af Klinteberg, "A
parallel non-uniform fast Fourier transform library based on an
'exponential of semicircle' kernel", SIAM J. Sci. Comput. 41 (2019)): each
point is spread onto a fine grid of ``nf = 2 N`` points with the kernel

    phi(z) = exp(beta (sqrt(1 - (2 z / w)^2) - 1)),   |z| <= w / 2 (grid units),

the grid is Fourier transformed, and each mode divided by the kernel's
Fourier transform. Width and shape are finufft's own choice for the
upsampling factor 2 and a relative tolerance ``tol``: w = ceil(log10(10 /
tol)) points, beta = 2.30 w (2.20, 2.26, 2.38 for w = 2, 3, 4); the error
is then about ``tol`` relative in the l2 sense, as finufft's
(``tests/radar/test_nufft_spreader.py`` checks it against the exact sum
and against finufft: within 2 tol from 1e-3 to 1e-9; below ~1e-13 the
rounding of the sums, ~1e-14 relative, dominates: 1.1e-14 at 5e-15).
Points outside [-pi, pi) are taken modulo 2 pi.

Why not finufft itself: the fast synthesis transforms 5-15 strength
vectors per set of points (the Taylor series of a mover block), and
finufft spreads each vector separately, evaluating the kernel again for
every one. Here each point's kernel weights are evaluated once (a Horner
polynomial per grid offset, fitted at setup until it errs by at most 0.05 of
the tightest tolerance its width serves, 10^(1 - w), relative to the
kernel's peak, and never below 1e-14, the fit's rounding floor) and
all its vectors' strengths spread with them; the FFTs of the few 2 N-point
rows are a small share.
"""

from __future__ import annotations

import math

import numpy as np

from twinsense import validation as V
from twinsense.compiled import jit
from twinsense.errors import ConfigError
from twinsense.forksafe import ForkSafeLock
from twinsense.radar.kernels import series_tile

_TWO_PI = 2.0 * math.pi
UPSAMPLE = 2  # fine grid over modes: finufft's classic factor (its width rule below is for it)
_MAX_WIDTH = 16
# The Horner fit's target never below this (relative to the kernel's peak): the fit's own
# rounding floor, 3.6-6e-15 measured for widths 14-16.
_FIT_FLOOR = 1e-14


def kernel_shape(tol: float) -> tuple[int, float]:
    """(w, beta) of the ES kernel for relative tolerance ``tol`` at upsampling 2 (finufft's rule)."""
    w = math.ceil(-math.log10(tol / 10.0))
    w = max(2, min(w, _MAX_WIDTH))
    beta_over_w = {2: 2.20, 3: 2.26, 4: 2.38}.get(w, 2.30)
    return w, beta_over_w * w


def _phi(z: np.ndarray, w: int, beta: float) -> np.ndarray:
    """The ES kernel at offsets ``z`` [grid points] (0 outside |z| <= w / 2)."""
    arg = 1.0 - (2.0 * z / w) ** 2
    return np.where(arg >= 0.0, np.exp(beta * (np.sqrt(np.maximum(arg, 0.0)) - 1.0)), 0.0)


class Kernel:
    """Setup of one transform size and kernel width: the kernel's Horner table and the
    deconvolution factors. ``tol`` matters only through the width it asks for, so one
    setup serves every tolerance of that width (:func:`kernel_for` keeps one per (N, w):
    the noise-derived tolerance differs in every frame, and a setup takes ~10 ms)."""

    def __init__(self, n_modes: int, tol: float):
        if n_modes < 1:
            raise ValueError(f"n_modes must be >= 1, got {n_modes}")
        self.n_modes = n_modes
        w, beta = kernel_shape(tol)
        self.width, self.beta = w, beta
        # The tightest tolerance this width serves (w = ceil(log10(10 / tol))).
        self.tol = 10.0 ** (1 - w)
        self.nf = max(UPSAMPLE * n_modes, 2 * w)
        # Piecewise polynomials: grid point j of the support (offset z = s + j - w/2, s in
        # [0, 1) the point's fraction) as a polynomial in u = 2 s - 1, fitted at Chebyshev
        # nodes; the degree grows until the fit errs by at most 0.05 of the width's tightest
        # tolerance (max, relative to phi(0) = 1): the weights' own error stays a small
        # share of the transform's. Not below _FIT_FLOOR: the least-squares fit in
        # monomials stalls at ~4e-15 whatever its degree (widths 14-16), and chasing
        # 0.05 of 1e-14 or 1e-15 ran the degree to its cap (52-55 terms for no gain).
        target = max(0.05 * self.tol, _FIT_FLOOR)
        dense = np.linspace(-1.0, 1.0, 401)
        for deg in range(w + 2, 3 * w + 8):
            nodes = np.cos(np.pi * (np.arange(2 * deg + 2) + 0.5) / (2 * deg + 2))
            vals = np.array([_phi(0.5 * (nodes + 1.0) + j - 0.5 * w, w, beta) for j in range(w)]).T
            coef = np.linalg.lstsq(np.vander(nodes, deg + 1, increasing=True), vals, rcond=None)[0]
            # coef (deg + 1, w), lowest power first
            fit = np.polynomial.polynomial.polyval(dense, coef)  # (w, 401)
            exact = np.array([_phi(0.5 * (dense + 1.0) + j - 0.5 * w, w, beta) for j in range(w)])
            if np.max(np.abs(fit - exact)) <= target:
                break
        self.coef = np.ascontiguousarray(coef[::-1])  # highest power first (Horner)
        # Deconvolution: sum_l phi(l - t) e^{i k h l} = e^{i k h t} phihat(k) up to aliasing,
        # phihat(k) = int phi(z) cos(k h z) dz (phi even), by Gauss-Legendre quadrature
        # (the integrand is smooth inside |z| < w/2; 4 w + 40 nodes resolve it to rounding).
        # The grid is stored shifted by nf / 2 (index l holds l - nf/2), a factor (-1)^k.
        gx, gw = np.polynomial.legendre.leggauss(4 * w + 40)
        z = 0.5 * w * gx
        k = np.arange(n_modes) - n_modes // 2
        h = _TWO_PI / self.nf
        phihat = (0.5 * w * gw * _phi(z, w, beta)) @ np.cos(np.outer(z, k * h))
        self.factor = np.where(k % 2 == 0, 1.0, -1.0) / phihat  # (N,)

    def transform(self, x: np.ndarray, strengths: np.ndarray) -> np.ndarray:
        """(D, N) complex: out[d, n] = sum_i strengths[d, i] exp(1j x_i (n - N//2)).

        ``x`` (m,) float in [-pi, pi]; ``strengths`` (D, m) complex."""
        grid = self.grid(strengths.shape[0])
        spread_1d(np.ascontiguousarray(x, dtype=float), np.ascontiguousarray(strengths), self.coef,
                  self.nf, grid.view(np.float64))
        return self.finish(grid)

    def transform_rows(self, x: np.ndarray, strengths: np.ndarray) -> np.ndarray:
        """(M, D, N) complex: :meth:`transform` of each row's points, out[r] =
        transform(x[r], strengths[:, r]), by one compiled spreading pass over all rows and
        one batched FFT (the per-chirp path's rows: one call where there were M).

        ``x`` (M, m) float in [-pi, pi]; ``strengths`` (D, M, m) complex. Each row is spread
        with the operations of :meth:`transform` in its order, so its grid is the same bits."""
        n_rows = x.shape[0]
        grid = np.zeros((n_rows, self.nf + 2 * self.width, strengths.shape[0]), dtype=complex)
        spread_rows_1d(np.ascontiguousarray(x, dtype=float), strengths, self.coef, self.nf,
                       grid.view(np.float64))
        return self.finish(grid)

    def grid(self, n_vectors: int) -> np.ndarray:
        """A zeroed padded grid (nf + 2 w, D) complex; the kernels spread into its float view."""
        return np.zeros((self.nf + 2 * self.width, n_vectors), dtype=complex)

    def finish(self, grid: np.ndarray) -> np.ndarray:
        """(D, N) modes of a spread grid (nf + 2 w, D): wrapped, Fourier transformed and
        deconvolved; (M, D, N) of M grids (M, nf + 2 w, D)."""
        w = self.width
        fine = grid[..., w:w + self.nf, :]
        fine[..., :w, :] += grid[..., w + self.nf:, :]   # wrap the padding onto the periodic grid
        fine[..., -w:, :] += grid[..., :w, :]
        # sum_l g[l] e^{+2 pi i k l / nf}: the unscaled inverse transform, each vector a
        # contiguous row; then the modes -(N//2)..N-1-N//2 (negative k at nf + k) deconvolved.
        spectrum = np.fft.ifft(np.swapaxes(fine, -1, -2), axis=-1, norm="forward")  # (..., D, nf)
        half = self.n_modes // 2
        out = np.empty((*spectrum.shape[:-1], self.n_modes), dtype=complex)
        np.multiply(spectrum[..., self.nf - half:], self.factor[:half], out=out[..., :half])
        np.multiply(spectrum[..., :self.n_modes - half], self.factor[half:], out=out[..., half:])
        return out


_KERNELS: dict[tuple[int, int], Kernel] = {}
_KERNELS_LOCK = ForkSafeLock()


def kernel_for(n_modes: int, tol: float) -> Kernel:
    """The :class:`Kernel` of ``n_modes`` modes for tolerance ``tol``: one per (N, width),
    kept for the process (a few widths and sizes in all)."""
    key = (int(n_modes), kernel_shape(float(tol))[0])
    kern = _KERNELS.get(key)
    if kern is None:
        kern = Kernel(int(n_modes), float(tol))
        with _KERNELS_LOCK:  # two threads may build it at once: both get the first one kept
            kern = _KERNELS.setdefault(key, kern)
    return kern


def nufft1d(x: np.ndarray, strengths: np.ndarray, n_modes: int, tol: float) -> np.ndarray:
    """Type-1 NUFFT of one or many strength vectors on the points ``x`` (m,) in [-pi, pi].

    ``strengths`` (m,) or (D, m) complex; returns (N,) or (D, N) complex with
    out[..., n] = sum_i strengths[..., i] exp(1j x_i (n - N//2)), to about ``tol``
    relative (l2). Points outside [-pi, pi] are taken modulo 2 pi."""
    tol = V.number("nufft1d.tol", tol, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    n_modes = V.integer("nufft1d.n_modes", n_modes, lo=1)
    x = np.asarray(x, dtype=float)
    s = np.asarray(strengths, dtype=complex)
    if x.ndim != 1 or s.ndim not in (1, 2) or s.shape[-1] != len(x):
        raise ConfigError("nufft1d.strengths", f"shapes x {x.shape}, strengths {s.shape}",
                          "x (m,) and strengths (m,) or (D, m)")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(s))):
        raise ConfigError("nufft1d.x", "NaN or inf in x or strengths", "finite values")
    out = kernel_for(n_modes, tol).transform(x, s[None] if s.ndim == 1 else s)
    return out[0] if s.ndim == 1 else out


_TILE = 64  # points per tile: their kernel weights are evaluated together (vectorised)


@jit
def _tile_weights(x, lo, n, coef, nf, ker, u, first):  # pragma: no cover
    """Kernel weights ker[j, i] (w, tile) and first grid rows first[i] of points lo..lo+n."""
    n_deg, w = coef.shape
    scale = nf / _TWO_PI
    off = 0.5 * nf - 0.5 * w
    half = 0.5 * nf
    for i in range(n):
        t = x[lo + i] * scale
        if not (t >= -half and t <= half):
            # Outside [-pi, pi] (the padding holds only ~w / 2 points beyond either end):
            # whole periods off, which leaves every exp(1j x k) as it was; NaN or inf to 0,
            # so no point ever writes outside the grid.
            t -= nf * math.floor(t / nf + 0.5)
            if not (t >= -half and t <= half):
                t = 0.0
        t += off  # the support's left end [grid points]
        c = math.ceil(t)
        first[i] = int(c) + w
        u[i] = 2.0 * (c - t) - 1.0  # the fraction s = c - t in [0, 1) as u in [-1, 1)
    for j in range(w):
        c0 = coef[0, j]
        for i in range(n):
            ker[j, i] = c0
        for q in range(1, n_deg):
            cq = coef[q, j]
            for i in range(n):
                ker[j, i] = ker[j, i] * u[i] + cq


@jit
def _spread_tile(a, n, ker, first, grid):  # pragma: no cover
    """grid[first[i] + j, :] += a[i, :] ker[j, i] for the tile's n points; ``a`` (tile, 2 D)
    and ``grid`` (rows, 2 D): real and imaginary parts interleaved, contiguous rows (the
    inner loop runs over them, vectorised)."""
    w = ker.shape[0]
    n2 = a.shape[1]
    for i in range(n):
        b = first[i]
        ai = a[i]
        for j in range(w):
            kj = ker[j, i]
            row = grid[b + j]
            for e in range(n2):
                row[e] += ai[e] * kj


@jit
def _spread_points(x, strengths, coef, nf, grid, ker, u, first, a):  # pragma: no cover
    """The tile loop of :func:`spread_1d` and :func:`spread_rows_1d`: ``strengths`` (D, m)
    complex (any strides) at points ``x`` (m,) onto ``grid`` (nf + 2 w, 2 D) float; ``ker``
    (w, tile), ``u`` (tile,), ``first`` (tile,) and ``a`` (tile, 2 D) are the caller's work
    arrays. A tile of points' weights first (vectorised over the tile), then each point's
    strengths times its w weights."""
    w = coef.shape[1]
    n_vec, m = strengths.shape
    for lo in range(0, m, _TILE):
        n = min(_TILE, m - lo)
        _tile_weights(x, lo, n, coef, nf, ker, u, first)
        if n_vec == 1:
            # One vector (static rows, the noise estimate, the per-chirp rows without a
            # series): its real and imaginary parts straight into the grid, without the copy
            # and the inner loop of two (the same products added in the same order: the
            # same bits; 0.36 against 0.58 ms for a chunk of 16,285 points at width 4).
            s0 = strengths[0]
            for i in range(n):
                b = first[i]
                v = s0[lo + i]
                re = v.real
                im = v.imag
                for j in range(w):
                    kj = ker[j, i]
                    grid[b + j, 0] += re * kj
                    grid[b + j, 1] += im * kj
            continue
        for i in range(n):
            for d in range(n_vec):
                v = strengths[d, lo + i]
                a[i, 2 * d] = v.real
                a[i, 2 * d + 1] = v.imag
        _spread_tile(a, n, ker, first, grid)


@jit
def spread_1d(x, strengths, coef, nf, grid):  # pragma: no cover
    """Spread ``strengths`` (D, m) complex at points ``x`` (m,) onto the padded, shifted fine
    grid of :class:`Kernel`: ``grid`` (nf + 2 w, 2 D) float, row l + w holding fine point
    l, real and imaginary parts interleaved (a complex (nf + 2 w, D) array's view).
    ``coef`` (deg + 1, w): the kernel's Horner table, highest power first
    (:func:`_spread_points`)."""
    w = coef.shape[1]
    n_vec = strengths.shape[0]
    _spread_points(x, strengths, coef, nf, grid, np.empty((w, _TILE)), np.empty(_TILE),
                   np.empty(_TILE, np.int64), np.empty((_TILE, 2 * n_vec)))


@jit
def spread_rows_1d(x, strengths, coef, nf, grid):  # pragma: no cover
    """:func:`spread_1d` of each row r: ``x[r]`` (M, m), ``strengths[:, r]`` (D, M, m) complex
    onto ``grid[r]`` (M, nf + 2 w, 2 D) float, by the same tile loop
    (:func:`_spread_points`), so the same operations in the same order."""
    w = coef.shape[1]
    n_vec, n_rows, _ = strengths.shape
    ker = np.empty((w, _TILE))
    u = np.empty(_TILE)
    first = np.empty(_TILE, np.int64)
    a = np.empty((_TILE, 2 * n_vec))
    for r in range(n_rows):
        _spread_points(x[r], strengths[:, r], coef, nf, grid[r], ker, u, first, a)


@jit
def spread_series_1d(resid, program, scale, out_slots, n_terms, n_series, strength, x, coef, nf,
                     grid):  # pragma: no cover
    """:func:`twinsense.radar.kernels.block_series` and :func:`spread_1d` in one pass: per
    tile of points the kept monomials' coefficients of exp(j R) (the same program and
    operations), times ``strength`` (m,) complex, spread at once with the tile's kernel
    weights; the (D, m) strength vectors are never stored. Arguments as there."""
    w = coef.shape[1]
    m = resid.shape[1]
    n_vec = out_slots.shape[0]
    t_re = np.empty((n_terms, _TILE))
    t_im = np.empty((n_terms, _TILE))
    s_re = np.empty((n_series, _TILE))
    s_im = np.empty((n_series, _TILE))
    ker = np.empty((w, _TILE))
    u = np.empty(_TILE)
    first = np.empty(_TILE, np.int64)
    a = np.empty((_TILE, 2 * n_vec))
    for lo in range(0, m, _TILE):
        n = min(_TILE, m - lo)
        series_tile(resid, lo, n, program, scale, t_re, t_im, s_re, s_im)
        _tile_weights(x, lo, n, coef, nf, ker, u, first)
        for d in range(n_vec):
            k = out_slots[d]
            for i in range(n):
                st = strength[lo + i]
                e_re, e_im = s_re[k, i], s_im[k, i]
                a[i, 2 * d] = e_re * st.real - e_im * st.imag
                a[i, 2 * d + 1] = e_re * st.imag + e_im * st.real
        _spread_tile(a, n, ker, first, grid)
