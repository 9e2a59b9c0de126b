"""Fast path of IF synthesis (:func:`twinsense.radar.synthesis.synthesize`): NUFFT rows.

Static scatterers: one type-1 non-uniform FFT (finufft) per (tx, rx) pair
over the scatterers (:func:`static_chunk`). Moving scatterers: the path
length expanded around each chirp's centre, the quadratic and cubic phase
terms as a short Taylor series of extra NUFFT strength vectors
(:func:`moving_chunk`, its per-scatterer terms compiled in
:mod:`twinsense.radar.kernels`), or, where its estimated cost is lower, one
2-D NUFFT over (slow time, fast time) per receiver and chirp group with the
cross and curvature terms as Taylor strength vectors (:func:`moving_chunk_2d`;
its per-block passes over the movers compiled in :mod:`twinsense.radar.kernels`,
their NumPy forms kept as references with ``compiled=False``). Where a chunk's
slow-time frequencies lie in a narrow band (movers sorted by range rate), a
block's slow-time frequency becomes one more rest of the series and each
strength vector a 1-D NUFFT along the samples, about half the time of a 2-D
one on the (1.25 J) x (1.25 N) grid.
The model and the exact reference are in :mod:`twinsense.radar.synthesis`.
"""

from __future__ import annotations

import functools
import itertools
import math
import threading

import finufft
import numpy as np

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.radar.config import RadarConfig
from twinsense.radar.kernels import (
    OP_ACC,
    OP_SCALE,
    OP_SERIES_ACC,
    OP_SERIES_SET,
    OP_SET,
    abs_sum_max,
    block_coefficients,
    block_rows_1d,
    block_series,
    dense_majorants,
    leg_offsets,
    leg_series,
    moving_phases,
    rest_rows,
    series_majorants,
    slow_rest,
    slow_rest_floor,
    static_phases,
)
from twinsense.radar.spreader import kernel_for, spread_series_1d

_TWO_PI = 2.0 * math.pi


def _taylor_order(pmax: float, tol: float) -> int:
    """Smallest K with pmax^(K+1) / (K+1)! <= tol (remainder of the exp series)."""
    k, term = 0, pmax
    while term > tol and k < 60:
        k += 1
        term *= pmax / (k + 1)
    return k


def _exp_poly(a: np.ndarray, order: int) -> np.ndarray:
    """Coefficients of sum_{k<=order} (j P(u))^k / k! in powers of u.

    ``a`` is (n, D) with P(u) = sum_d a[:, d] u^d; returns (n, order * (D-1) + 1) complex.
    General form of :func:`_exp_quad_cubic` (used by the tests as its reference).
    """
    n, deg = a.shape
    total = np.zeros((n, order * (deg - 1) + 1), dtype=complex)
    total[:, 0] = 1.0
    term = np.zeros_like(total)
    term[:, 0] = 1.0
    term_deg = 0
    for k in range(1, order + 1):
        new = np.zeros_like(total)
        for d in range(1, deg):
            if not np.any(a[:, d]):
                continue
            new[:, d:d + term_deg + 1] += term[:, :term_deg + 1] * a[:, d:d + 1]
        term = new * (1j / k)
        term_deg += deg - 1
        total += term
    return total


def _exp_quad_cubic(a2: np.ndarray, a3: np.ndarray, order: int,
                    tol: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Taylor coefficients of exp(j (a2 u^2 + a3 u^3)) up to order ``order``.

    (j P)^k / k! = (j^k / k!) sum_i C(k, i) a2^(k-i) a3^i u^(2k+i). Terms whose
    bound max|a2|^(k-i) max|a3|^i C(k, i) / k! is small are skipped while the
    skipped bounds add up to at most ``tol`` (|u| <= 1, so that is the most any
    sample changes, relative to the scatterer's amplitude). Returns the
    degrees that occur, (n_deg,), and the coefficients, shape (n_deg, *a2.shape).
    """
    m2 = float(np.max(np.abs(a2))) if a2.size else 0.0
    m3 = float(np.max(np.abs(a3))) if a3.size else 0.0
    terms = [(k, i, math.comb(k, i) * m2 ** (k - i) * m3**i / math.factorial(k))
             for k in range(1, order + 1) for i in range(k + 1)]
    skipped = 0.0
    keep = []
    for k, i, bound in sorted(terms, key=lambda term: term[2]):
        if skipped + bound <= tol:
            skipped += bound
        else:
            keep.append((k, i))
    degrees = sorted({0} | {2 * k + i for k, i in keep})
    index = {d: j for j, d in enumerate(degrees)}
    out = np.zeros((len(degrees), *a2.shape), dtype=complex)
    out[0] = 1.0
    # Real arithmetic: j^k only picks the real or imaginary part and a sign.
    parts = out.view(float).reshape(*out.shape, 2)
    powers: dict[tuple[int, int], np.ndarray] = {}

    def power(a, tag, k):
        if k == 0:
            return None
        if (tag, k) not in powers:
            prev = power(a, tag, k - 1)
            powers[(tag, k)] = a if prev is None else prev * a
        return powers[(tag, k)]

    for k, i in keep:
        f2, f3 = power(a2, 2, k - i), power(a3, 3, i)
        term = f2 if f3 is None else (f3 if f2 is None else f2 * f3)
        scale = math.comb(k, i) / math.factorial(k) * (1.0 if k % 4 < 2 else -1.0)
        parts[index[2 * k + i], ..., k % 2] += scale * term
    return np.asarray(degrees), out


class _Plans:
    """finufft type-1 plans for rows of ``num_samples`` modes, one per batch size."""

    def __init__(self, num_samples: int, eps: float):
        self.num_samples = num_samples
        self.eps = eps
        self._plans: dict[int, finufft.Plan] = {}

    def rows(self, x: np.ndarray, strengths: np.ndarray) -> np.ndarray:
        """out[..., n] = sum_i strengths[..., i] exp(1j x_i (n - N/2)); strengths (n,) or (b, n)."""
        if len(x) == 0:
            return np.zeros((*strengths.shape[:-1], self.num_samples), dtype=complex)
        b = 1 if strengths.ndim == 1 else strengths.shape[0]
        plan = self._plans.get(b)
        if plan is None:
            # One thread per plan (the (tx, rx) pairs run in parallel instead);
            # the 1-D fine grid of 1.25 N points stays in cache, so sorting the
            # points first only costs time.
            plan = finufft.Plan(1, (self.num_samples,), n_trans=b, eps=self.eps, isign=1,
                                nthreads=1, modeord=0, spread_sort=0)
            self._plans[b] = plan
        plan.setpts(x)
        return plan.execute(np.ascontiguousarray(strengths))


CHUNK = 16384  # scatterers per task: a chunk's temporaries stay in a core's L2 cache


class Geometry:
    """Per-configuration constants of the fast synthesis (path length L [m] -> phases)."""

    def __init__(self, config: RadarConfig, n_chirps: int):
        c = config.chirp
        arr = config.antennas
        n_samp = c.num_samples
        self.n_samp = n_samp
        self.tx_of = arr.chirp_tx(n_chirps)
        self.txs = sorted(set(self.tx_of.tolist()))
        self.tx = [np.asarray(arr.tx_positions[k], float) for k in self.txs]
        self.rx = [np.asarray(r, float) for r in arr.rx_positions]
        # (tx, rx) pairs: the transmitter's index in self.txs and the receiver.
        self.pairs = [(i, a) for i in range(len(self.txs)) for a in range(len(self.rx))]
        fs, slope = c.sample_rate, c.slope
        # Expansion point: the sample with index N/2, which is mode 0 of the NUFFT.
        t_c = c.adc_start_time + (n_samp // 2) / fs
        fc = c.start_frequency + slope * t_c
        # With tau = L / c: x = 2 pi S tau / fs and
        # phi0 = 2 pi fc tau - pi S tau^2 = L (kf - ks L).
        self.kx = _TWO_PI * slope / (fs * SPEED_OF_LIGHT)
        self.kf = _TWO_PI * fc / SPEED_OF_LIGHT
        self.ks = math.pi * slope / SPEED_OF_LIGHT**2
        self.fc, self.slope, self.fs = fc, slope, fs
        self.tx_per_chirp = np.ascontiguousarray(arr.tx_positions[self.tx_of], dtype=float)  # (M, 3)
        self.rx_array = np.array(self.rx, dtype=float).reshape(-1, 3)  # for the compiled kernels
        self.tx_array = np.array(self.tx, dtype=float).reshape(-1, 3)
        self.pair_array = np.array(self.pairs, dtype=np.int64).reshape(-1, 2)


def _ranges(p: np.ndarray, elements: list[np.ndarray]) -> list[np.ndarray]:
    """Distances (m,) from the rows of ``p`` (m, 3) to each element (3,).

    |p - e|^2 = |p|^2 - 2 p.e + |e|^2, with |p|^2 computed once and only the
    non-zero components of e touched (array elements mostly lie in a plane).
    No cancellation: |e| (mm) is far below |p|, so the relative rounding
    error of the distance stays ~1e-16.
    """
    cols = [p[:, 0], p[:, 1], p[:, 2]]
    s2 = cols[0] * cols[0]
    s2 += cols[1] * cols[1]
    s2 += cols[2] * cols[2]
    out = []
    for e in elements:
        d = s2 + float(e @ e)
        for j in range(3):
            if e[j] != 0.0:
                d -= (2.0 * e[j]) * cols[j]
        out.append(np.sqrt(d, out=d))
    return out


def _reduce(phase: np.ndarray) -> np.ndarray:
    """Angles into [-pi, pi], in place (exact multiples of 2 pi removed in float64)."""
    k = np.multiply(phase, 1.0 / _TWO_PI)
    np.rint(k, out=k)
    k *= _TWO_PI
    phase -= k
    return phase


def static_chunk(p: np.ndarray, pr: np.ndarray, w: np.ndarray, geo: Geometry,
                  eps: float, compiled: bool = True, spread_tol: float | None = None) -> np.ndarray:
    """(n_pairs, N) rows of static scatterers ``p``/``pr`` (m, 3) with weights ``w`` (m,).

    ``spread_tol``: the spreader's tolerance (default eps / 2, as every 1-D transform of
    the synthesis; the noise-tolerance estimate asks for its 1e-3 itself).

    Per (tx, rx) pair and scatterer: the path length L in float64, the phase
    phi0 reduced to [-pi, pi] in float64, then cos and sin in float32 (error
    ~1e-7 rad, far inside the 1e-5 budget and ~30x faster than float64),
    and one type-1 NUFFT of the strengths w exp(j phi0) at frequencies x.
    The lengths, frequencies and phases come from one compiled pass per
    scatterer (:func:`twinsense.radar.kernels.static_phases`, the bits of the
    NumPy passes kept with ``compiled`` False: ~20 passes over the chunk with
    their temporaries); the cos and sin stay NumPy's (its float32 loops are
    vectorised, a compiled scalar loop ~3x slower).
    """
    m = len(p)
    rows = np.empty((len(geo.pairs), geo.n_samp), dtype=complex)
    if compiled:
        xs, phs = np.empty((len(geo.pairs), m)), np.empty((len(geo.pairs), m), np.float32)
        static_phases(p, pr, geo.tx_array, geo.rx_array, geo.pair_array, geo.kx, geo.kf, geo.ks,
                      xs, phs)
    else:
        r_tx = _ranges(p, geo.tx)
        r_rx = _ranges(pr, geo.rx)
    ph32 = np.empty(m, np.float32)
    trig = np.empty(m, np.float32)
    for j, (k, a) in enumerate(geo.pairs):
        if compiled:
            x, ph32 = xs[j], phs[j]
        else:
            length = r_tx[k] + r_rx[a]
            x = _reduce(length * geo.kx)
            phi = length * geo.ks
            np.subtract(geo.kf, phi, out=phi)
            phi *= length
            ph32[:] = _reduce(phi)
        strength = np.empty(m, dtype=complex)
        parts = strength.view(float).reshape(m, 2)
        parts[:, 0] = np.cos(ph32, out=trig)
        parts[:, 1] = np.sin(ph32, out=trig)
        strength *= w
        # The spreader at eps / 2, as every 1-D transform: 0.08-0.33 eps on chunks of wrist
        # scatterers from 1e-6 to 1e-3 (at eps itself up to 1.45 eps; finufft at eps, as
        # before: up to 3.6 eps, above the 2 eps the noise tolerance rests on).
        rows[j] = transform_1d(x, strength[None], geo.n_samp,
                               eps * _TOL_SPREAD if spread_tol is None else spread_tol, eps)[0]
    return rows


_LOCAL = threading.local()
_MAX_PLANS = 8  # sets of finufft plans kept per thread


def _thread_plans(num_samples: int, eps: float) -> _Plans:
    """This thread's NUFFT plans (finufft plans must not be shared between threads)."""
    cache = getattr(_LOCAL, "plans", None)
    if cache is None:
        cache = _LOCAL.plans = {}
    key = (num_samples, eps)
    if key not in cache:
        if len(cache) >= _MAX_PLANS:
            # A moving radar's tolerance comes from each frame's noise, so a new eps per
            # frame: keep the newest few sets of plans, not one per frame ever seen.
            del cache[next(iter(cache))]
        cache[key] = _Plans(num_samples, eps)
    return cache[key]


def transform_1d(x: np.ndarray, strengths: np.ndarray, n_samp: int, tol: float,
                 finufft_tol: float) -> np.ndarray:
    """(D, N) rows out[d, n] = sum_i strengths[d, i] exp(1j x_i (n - N/2)) of strengths (D, m):
    the compiled spreader at ``tol`` (:mod:`twinsense.radar.spreader`), or finufft at
    ``finufft_tol`` when :data:`SPREAD_1D` is off (the code before the spreader, kept for
    same-run comparisons)."""
    if SPREAD_1D:
        return kernel_for(n_samp, tol).transform(x, strengths)
    return _thread_plans(n_samp, finufft_tol).rows(x, strengths).reshape(len(strengths), n_samp)


def _leg_taylor(pos: list[np.ndarray], vel: list[np.ndarray], speed2: np.ndarray,
                element: np.ndarray) -> tuple[np.ndarray, ...]:
    """Distance |d + v s| = r0 + r1 s + r2 s^2 + r3 s^3 + O(s^4) from one antenna element.

    ``pos``: the 3 coordinates (M, m) of the scatterers at each chirp centre,
    ``vel``: their velocity components (m,), ``element``: (M, 3) or (3,)
    element position per chirp. From r(s)^2 = r0^2 + 2 (d.v) s + |v|^2 s^2:
    r1 = d.v / r0, r2 = (|v|^2 - r1^2) / (2 r0), r3 = -r1 r2 / r0.
    """
    e = np.asarray(element, float).reshape(-1, 3)
    dd = dv = None
    for j in range(3):
        d = pos[j] - e[:, j:j + 1]
        dd = d * d if dd is None else dd + d * d
        d *= vel[j]
        dv = d if dv is None else dv + d
    r0 = np.sqrt(dd)
    inv = 1.0 / r0
    r1 = dv * inv
    r2 = (speed2 - r1 * r1) * (0.5 * inv)
    r3 = -r1 * r2 * inv
    return r0, r1, r2, r3


def moving_phases_numpy(p, v, pr, vr, geo: Geometry, chirp_centre: np.ndarray):
    """NumPy reference of :func:`twinsense.radar.kernels.moving_phases`: (x, ph, a2, a3), each
    (n_rx, M, m) (ph float32). ``pr``/``vr`` None: monostatic."""
    tc = chirp_centre[:, None]

    def legs(p_, v_):
        vel = [v_[:, j] for j in range(3)]
        pos = [p_[:, j] + vel[j] * tc for j in range(3)]  # (M, m) at each chirp centre
        return pos, vel, vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]

    pos, vel, speed2 = legs(p, v)
    tx = _leg_taylor(pos, vel, speed2, geo.tx_per_chirp)
    if pr is not None:
        pos, vel, speed2 = legs(pr, vr)
    fc, slope, fs = geo.fc, geo.slope, geo.fs
    half = geo.n_samp / 2 / fs
    out = []
    for r in geo.rx:
        rx = _leg_taylor(pos, vel, speed2, r)
        t0, t1, t2, t3 = ((et + er) * (1.0 / SPEED_OF_LIGHT) for et, er in zip(tx, rx))
        # phi(s) = 2 pi f0 tau + 2 pi S tau (t_c + s) - pi S tau^2, tau = t0 + t1 s + ...
        phi0 = t0 * (_TWO_PI * fc - math.pi * slope * t0)
        phi1 = _TWO_PI * (fc * t1 + slope * t0) - _TWO_PI * slope * t0 * t1
        phi2 = (_TWO_PI * (fc * t2 + slope * t1)
                - math.pi * slope * (t1 * t1 + 2 * t0 * t2))
        phi3 = _TWO_PI * (fc * t3 + slope * t2) - _TWO_PI * slope * (t0 * t3 + t1 * t2)
        out.append((_reduce(phi1 * (1.0 / fs)), _reduce(phi0).astype(np.float32),
                    phi2 * half**2, phi3 * half**3))
    return tuple(np.stack(a) for a in zip(*out))


def moving_chunk(p, v, pr, vr, w, geo: Geometry, chirp_centre: np.ndarray,
                  eps: float) -> np.ndarray:
    """(n_rx, M, N) cube of moving scatterers (one NUFFT per receiver and chirp).

    ``pr``/``vr`` None: monostatic (the receive legs end at ``p``). The
    per-scatterer phase terms come from one compiled pass
    (:func:`twinsense.radar.kernels.moving_phases`).
    """
    shape = (len(geo.rx), len(chirp_centre), len(p))
    x, a2, a3 = np.empty(shape), np.empty(shape), np.empty(shape)
    ph = np.empty(shape, np.float32)
    moving_phases(p, v, p if pr is None else pr, v if vr is None else vr, geo.tx_per_chirp,
                  geo.rx_array, np.ascontiguousarray(chirp_centre, dtype=float), geo.fc, geo.slope,
                  geo.fs, geo.n_samp / 2 / geo.fs, 1.0 / SPEED_OF_LIGHT, x, ph, a2, a3)
    return np.stack([_moving_rows(x[a], ph[a], a2[a], a3[a], w, geo, eps) for a in range(shape[0])])


def _moving_rows(x, ph32, a2, a3, w, geo: Geometry, eps: float) -> np.ndarray:
    """(M, N) rows of one receiver from the NUFFT frequencies x, the float32 phases at the
    chirp centres and the u^2, u^3 phase coefficients a2, a3 (each (M, m); a2, a3 are changed)."""
    n_chirps, n_samp = x.shape[0], geo.n_samp
    u = (np.arange(n_samp) - n_samp // 2) / (n_samp / 2)
    # w exp(j phi0): phase reduced in float64, cos/sin in float32 (as for static ones).
    strength = np.empty(ph32.shape, dtype=complex)
    strength.real = np.cos(ph32)
    strength.imag = np.sin(ph32)
    strength *= w
    # exp(j (a2 u^2 + a3 u^3)) = exp(j (c2 u^2 + c3 u^3)) exp(j (r2 u^2 + r3 u^3)) with
    # c the mid-range of each chirp's coefficients: the first factor is exact on
    # the output grid, only the small residuals r need the Taylor series (a2 is
    # mostly S times the range rate, nearly the same for the points of a body).
    c2 = _mid_range(a2)
    c3 = _mid_range(a3)
    a2 -= c2
    a3 -= c3
    rows = np.empty((n_chirps, n_samp), dtype=complex)
    # Series truncation and skipped terms each within eps / 2 of a scatterer's
    # amplitude at any sample: the same form and size as the NUFFT's own error
    # bound (eps times the sum of |strengths|), so the two together stay ~eps.
    tol = 0.5 * eps
    order = _taylor_order(float(np.max(np.abs(a2) + np.abs(a3))), tol)
    # The transforms by the compiled spreader at half the tolerance, as the blocks': its
    # l2 error 0.7-1.3 of its tolerance, so at most ~eps / 2 + eps / 2 (the series) in all
    # (finufft at eps itself erred by up to 1.94 eps here, 2.9 eps with the series).
    if order == 0:
        if SPREAD_1D:
            # Every chirp's transform in one call (the same bits as one call per chirp).
            rows[:] = kernel_for(n_samp, eps * _TOL_SPREAD).transform_rows(x, strength[None])[:, 0]
        else:
            for m in range(n_chirps):
                rows[m] = transform_1d(x[m], strength[m:m + 1], n_samp, eps * _TOL_SPREAD, eps)[0]
    else:
        degrees, coeffs = _exp_quad_cubic(a2, a3, order, tol)  # (D, M, m)
        coeffs[0] = strength
        coeffs[1:] *= strength
        upow = u[None, :] ** degrees[:, None]  # (D, N)
        if SPREAD_1D:
            # Every chirp at once: the transforms in one call, the sums over the degrees in
            # one einsum (its loop over d per output element in order: the per-chirp bits).
            outs = kernel_for(n_samp, eps * _TOL_SPREAD).transform_rows(x, coeffs)  # (M, D, N)
            np.einsum("mdn,dn->mn", outs, upow, out=rows)
        else:
            for m in range(n_chirps):
                out = transform_1d(x[m], coeffs[:, m, :], n_samp, eps * _TOL_SPREAD, eps)
                rows[m] = np.einsum("dn,dn->n", out, upow)
    if np.any(c2) or np.any(c3):
        rows *= np.exp(1j * (c2 * u**2 + c3 * u**3))
    return rows


def _mid_range(a: np.ndarray) -> np.ndarray:
    """(M, 1) centre of each row's range of values."""
    return 0.5 * (a.max(axis=1, keepdims=True) + a.min(axis=1, keepdims=True))


def moving_bounds(n: int) -> list[tuple[int, int]]:
    """Chunks of moving scatterers: at least two, so that two threads share even a
    few thousand movers, but none tiny (each costs n_rx x M NUFFT calls)."""
    parts = max(1, min(max(2, -(-n // CHUNK)), n // 1024))
    return [(int(a), int(b)) for a, b in itertools.pairwise(np.linspace(0, n, parts + 1))]


_MIN_PIECE = 1024  # movers: no chunk cut from a wide one is smaller


def rate_bounds(rate: np.ndarray, floor: float = 0.0) -> list[tuple[int, int]]:
    """Chunks of movers sorted by range rate ``rate`` (n,) [m/s]: :func:`moving_bounds`'s
    equal counts, with any chunk whose rates spread over more than twice the median
    chunk's, and over ``floor`` [m/s], cut into pieces of at most that spread (and at
    least 1,024 movers).

    ``floor``: a spread too small to matter (the synthesis passes the one whose
    slow-time phase over the frame is 0.1 rad, :func:`rate_floor`). Without it, a
    scene whose movers mostly share one range rate (a radar moving straight at a
    wall: a median spread near 0) would have every chunk with any spread cut into
    pieces of 1,024 movers, each with its own plans and transforms.

    The tails of the distribution (the few fastest and slowest movers) would otherwise
    share a chunk with many movers of a narrow band: its rests grow with the spread,
    and the whole chunk pays for the long series or the per-chirp path. Depends only
    on ``rate``, so the cube does not depend on the number of workers.
    """
    base = moving_bounds(len(rate))
    spans = [float(rate[hi - 1] - rate[lo]) for lo, hi in base]
    limit = max(2.0 * float(np.median(spans)), float(floor))
    out = []
    for lo, hi in base:
        start = lo
        while start < hi:
            end = int(np.searchsorted(rate, rate[start] + limit, side="right"))
            end = min(max(end, start + _MIN_PIECE), hi)
            if hi - end < _MIN_PIECE:
                end = hi
            out.append((start, end))
            start = end
    return out


def rate_floor(config: RadarConfig) -> float:
    """Range-rate spread [m/s] whose slow-time phase over the frame is 0.1 rad.

    Two movers whose range rates differ by dr drift apart in phase by 4 pi dr T / lambda
    over the frame (T: the last ramp's end, lambda at the ramp's start frequency): at 0.1
    rad the chunk's slow-time rest (the 1-D variant's largest, up to 1 rad allowed)
    stays small, so cutting such a chunk saves nothing."""
    c = config.chirp
    t_end = float(c.chirp_times()[-1]) + c.ramp_end_time
    wavelength = SPEED_OF_LIGHT / c.start_frequency
    return 0.1 * wavelength / (4.0 * math.pi * t_end)


# ---------------------------------------------------------------------------
# Movers on a 2-D grid: one NUFFT over (slow time, fast time) per block of chirps.
#
# The chirps sent by one position of the transmit sequence (m = q + L j) are
# evenly spaced in time, so per receiver and such a group the phase of every
# sample (chirp j, sample n) is a smooth function of the time offset
# Delta = A mu + B nu from the group's centre sample (mu = j - j_c and
# nu = n - N/2 integers, A = L T_rep, B = 1 / fs). Expanded around that centre,
#
#     Phi(mu, nu) = phi0 + w mu + x nu + sum_{i+j>=2} c_ij mu^i nu^j ,
#
# the linear part is a 2-D type-1 NUFFT over the scatterers (points (w, x));
# the rest (range migration mu nu, slow-time curvature mu^2, the in-chirp
# terms nu^2, nu^3, ...) is a chunk-wide part taken exactly on the grid and a
# small per-scatterer rest whose exp is a short Taylor series, one more
# strength vector per monomial (the in-chirp trick of :func:`_moving_rows`
# in two dimensions). The per-scatterer work is then per group, not per chirp.
#
# The 1-D variant of a block: w = w_c + delta with w_c the chunk's mid-range
# (taken exactly on the grid) and delta mu one more rest, so every strength
# vector's transform runs along nu only (the mu dependence is in the monomials
# U^i V^j it is summed with). Range migration (mu nu, ~kappa w mu nu with
# kappa = S / (fs fc)) and the in-chirp Doppler term (nu^2) scale with w too and
# stay rests. Its series is longer (delta mu is the largest rest), but a 1-D
# vector costs ~0.4x a 2-D one, whose spreading covers 8 x 8 fine-grid points
# and whose FFT covers the (1.25 J) x (1.25 N) grid whatever the band of w (finufft 2.5
# picks the upsampling factor 1.25 from these points' density; widths at 4.2e-5).


def _dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a . b of (m, 3) arrays, summed left to right (the compiled kernels' order;
    einsum's order differs by an ulp now and then)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def _leg_series(d: np.ndarray, vel: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Taylor coefficients (order + 1, m) of |d + vel t| in t, and |vel| / |d| (m,) [1/s].

    From r^2 = r0^2 + q1 t + q2 t^2 (q1 = 2 d.vel, q2 = |vel|^2):
    2 r0 r_k = Q_k - sum_{i=1}^{k-1} r_i r_{k-i}. The series converges for
    |t| < |d| / |vel| (the complex roots of r^2): see :func:`_leg_tail`.
    """
    r0 = np.sqrt(_dot3(d, d))
    q1 = 2.0 * _dot3(d, vel)
    q2 = _dot3(vel, vel)
    r = np.zeros((order + 1, len(d)))
    r[0] = r0
    half_inv = 0.5 / r0
    for k in range(1, order + 1):
        acc = q1.copy() if k == 1 else (q2.copy() if k == 2 else np.zeros(len(d)))
        for i in range(1, k):
            acc -= r[i] * r[k - i]
        r[k] = acc * half_inv
    return r, np.sqrt(q2) / r0


def _leg_tail(r0: np.ndarray, y: np.ndarray, order: int) -> np.ndarray:
    """Bound (m,) on |sum_{k>order} r_k t^k| for |t| <= T, with y = T |vel| / r0 < 1.

    r(t) = r0 sqrt(1 - t/z) sqrt(1 - t/z*) with |z| = r0 / |vel|; each square
    root's coefficients are at most |z|^-k (|binom(1/2, k)| <= 1/2), so
    |r_k| <= (k + 1) r0 |z|^-k and the tail is r0 sum_{k>K} (k + 1) y^k =
    r0 y^(K+1) ((K + 2) - (K + 1) y) / (1 - y)^2.
    """
    k = order
    return r0 * y ** (k + 1) * ((k + 2) - (k + 1) * y) / (1.0 - y) ** 2


_SERIES_TOL = 13.0 / 32.0  # share of eps for the series order, and again for skipped terms
_Y_MAX = 0.5  # the 2-D expansion is used only well inside the series' radius
# The 1-D variant only while the rests add up to at most 1 rad: the series' terms R^k / k!
# then stay below 1, so rounding in their sums stays ~1e-16 (a larger R makes terms of
# R^R / R! that cancel, and needs high orders).
_SLOW_REST_MAX = 1.0
# finufft's tolerance is a relative l2 target met only roughly: it sets the kernel width in
# whole points (about one per decade, one more in 2-D than in 1-D at some tolerances: 8
# against 7 at 4.2e-5), so the achieved error swings with where the tolerance lies in its
# decade (random points and strengths too: 2.0x in 2-D at 1e-3, 1.7x at 1e-6). Measured
# on chunks of wrist movers, the l2 error over the tolerance: 2-D transforms 0.6-2.0x
# (2.0x at 1e-3, 1.85x at 1e-6), 1-D ones up to 2.5x (1.0e-4 at 4.2e-5 on the wrist
# frame); a single point's worst sample errs by 5-20x in both (the tolerance bounds no
# sample). The vectors therefore run at a fraction of the block's tolerance so that the
# NUFFTs' l2 error stays within ~eps: 2-D ones at a half, 1-D ones at a quarter (each
# widens the kernel by at most one point). With these, the cube's l2 error on that chunk
# over 19 tolerances from 1e-6 to 1e-3: 0.13-0.43 eps (1-D), 0.2-1.25 eps (2-D).
_TOL_1D = 0.25  # finufft's 1-D vectors (with SPREAD_1D off, the code before the spreader)
_TOL_2D = 0.5
# Every 1-D transform by the compiled spreader (twinsense.radar.spreader; False: finufft,
# as before it, for same-run comparisons), at half the tolerance: its l2 error is 0.7-1.3
# of its own tolerance (finufft's width rule at upsampling 2; no decade swing beyond
# that), 0.06-1.06 eps measured on chunks of wrist scatterers, static and moving.
SPREAD_1D = True
_TOL_SPREAD = 0.5
_MAX_ORDER = 16


def _monomial_coeffs(tau: np.ndarray, geo: Geometry, a_step: float) -> dict[tuple[int, int], np.ndarray]:
    """Phase coefficients c_ij (m,) of mu^i nu^j (integer chirp and sample offsets).

    ``tau`` (K + 1, m): the delay's Taylor coefficients in Delta = A mu + B nu
    (A = ``a_step``, B = 1 / fs). Phi = 2 pi (fc + S s) tau - pi S tau^2 with
    s = B nu: g_k = 2 pi fc tau_k - pi S (tau * tau)_k for k <= K (the
    dropped degrees of tau^2 are bounded by the caller) and h_k = 2 pi S tau_k
    multiplies s Delta^k.
    """
    order = tau.shape[0] - 1
    b = 1.0 / geo.fs
    out: dict[tuple[int, int], np.ndarray] = {}

    def add(i, j, arr):
        if (i, j) in out:
            out[(i, j)] = out[(i, j)] + arr
        else:
            out[(i, j)] = arr

    for k in range(order + 1):
        sq = sum((tau[i] * tau[k - i] for i in range(k + 1)), np.zeros(tau.shape[1]))
        g = (_TWO_PI * geo.fc) * tau[k] - (math.pi * geo.slope) * sq
        h = (_TWO_PI * geo.slope) * tau[k]
        for i in range(k + 1):
            f = math.comb(k, i) * a_step**i * b ** (k - i)
            add(i, k - i, g * f)
            add(i, k - i + 1, h * (f * b))
    return out


def _poly_mul(p: dict, q: dict, keep: set | None = None) -> dict:
    """Product of two 2-D polynomials {(i, j): coefficient array}; only monomials in ``keep``."""
    out: dict = {}
    for (i1, j1), c1 in p.items():
        for (i2, j2), c2 in q.items():
            key = (i1 + i2, j1 + j2)
            if keep is not None and key not in keep:
                continue
            prod = c1 * c2
            if key in out:
                out[key] += prod
            else:
                out[key] = prod
    return out


# Series longer than this take the dense form (measured: dictionaries 0.02-0.19 ms at
# orders 2-4, as fast as it at 6, 1.3 against 0.76 ms at 8, 4.7 against 0.85 ms at 12).
_DENSE_ORDER = 6


def _exp_series_2d_dense(bounds: dict[tuple[int, int], float], order: int,
                         tol: float) -> tuple[dict[tuple[int, int], float], float]:
    """:func:`_exp_series_2d` on dense arrays, for long series: the majorants of every
    monomial up to degree (order max i, order max j) in a (I, J) array, each order's term
    the previous one times R's bounds by shifted slices, the skipped monomials the longest
    prefix of the ascending majorants whose running sum stays within ``tol`` (the
    dictionaries' rule: their sum grows, so once one is kept every larger one is). A few
    array operations per rest and order where the dictionaries take a Python step per pair
    of monomials (a chunk of fast tail movers tried 54 plans of orders up to ~12: ~20 ms
    of dictionary work). The kept monomials are the dictionaries' (tested); their
    majorants may differ in the last bit (another order of addition), so a tie at the cut
    may go the other way, both within ``tol``. The majorants come from one compiled call
    (:func:`twinsense.radar.kernels.dense_majorants`, the slices' sums element by element:
    the same bits; the NumPy form with :data:`COMPILED_SERIES` off)."""
    rests = list(bounds.items())
    bi = max(i for (i, _), _ in rests)
    bj = max(j for (_, j), _ in rests)
    if COMPILED_SERIES:
        # The same sums in one compiled call (kernels.dense_majorants: the same bits).
        maj = np.empty((order * bi + 1, order * bj + 1))
        reach = np.empty(maj.shape, np.bool_)
        dense_majorants(np.array([i for (i, _), _ in rests], np.int64),
                        np.array([j for (_, j), _ in rests], np.int64),
                        np.array([c for _, c in rests], float), order, maj, reach)
    else:
        term = np.zeros((order * bi + 1, order * bj + 1))
        term[0, 0] = 1.0
        maj = term.copy()
        reach = term > 0.0  # the monomials the series forms (the dictionaries' keys)
        prev = reach.copy()
        for k in range(1, order + 1):
            new = np.zeros_like(term)
            new_reach = np.zeros_like(reach)
            hi, hj = (k - 1) * bi + 1, (k - 1) * bj + 1  # the previous term's extent
            for (i, j), c in rests:
                new[i:i + hi, j:j + hj] += term[:hi, :hj] * (c / k)
                new_reach[i:i + hi, j:j + hj] |= prev[:hi, :hj]
            term, prev = new, new_reach
            maj += term
            reach |= new_reach
    reach[0, 0] = False
    ii, jj = np.nonzero(reach)
    vals = maj[ii, jj]
    order_ = np.argsort(vals, kind="stable")
    running = np.cumsum(vals[order_])
    n_skip = int(np.searchsorted(running, tol, side="right"))
    skipped = float(running[n_skip - 1]) if n_skip else 0.0
    keep = {(0, 0): 1.0}
    for q in order_[n_skip:]:
        keep[(int(ii[q]), int(jj[q]))] = float(vals[q])
    return keep, skipped


# The dictionaries' majorant series compiled (False: the dictionaries themselves, the
# reference; the same monomials and bits).
COMPILED_SERIES = True


def _exp_series_2d_compiled(bounds: dict[tuple[int, int], float], order: int,
                            tol: float) -> tuple[dict[tuple[int, int], float], float]:
    """:func:`_exp_series_2d`'s dictionary form with its majorants from one compiled call
    (:func:`twinsense.radar.kernels.series_majorants`: the same sums in the same order,
    so the same bits) and its skipping rule on them (a stable sort: ties in order of
    first appearance, as Python's sort of the dictionary's items)."""
    keys = list(bounds)
    b_i = np.array([k[0] for k in keys], np.int64)
    b_j = np.array([k[1] for k in keys], np.int64)
    b_val = np.array([bounds[k] for k in keys], float)
    cap = (order * int(b_i.max()) + 1) * (order * int(b_j.max()) + 1)
    maj_i, maj_j, maj_val = np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap)
    n = series_majorants(b_i, b_j, b_val, order, maj_i, maj_j, maj_val)
    vals = maj_val[:n].tolist()
    ii, jj = maj_i[:n].tolist(), maj_j[:n].tolist()
    skipped = 0.0
    keep = {(0, 0): 1.0}
    for q in sorted(range(n), key=vals.__getitem__):
        c = vals[q]
        if (ii[q], jj[q]) != (0, 0) and skipped + c <= tol:
            skipped += c
        else:
            keep[(ii[q], jj[q])] = c
    return keep, skipped


def _exp_series_2d(bounds: dict[tuple[int, int], float], order: int,
                   tol: float) -> tuple[dict[tuple[int, int], float], float]:
    """Monomials to keep of sum_{k<=order} (j R)^k / k!, R = sum r_ij U^i V^j with |r_ij| <= bounds.

    The majorant series (the same sums with |r_ij| replaced by their bounds)
    bounds every coefficient; monomials are skipped, smallest first, while
    their majorants add up to at most ``tol`` (|U|, |V| <= 1, so that is the
    most any sample changes relative to a scatterer's amplitude). Returns the
    kept monomials (with (0, 0)) with their majorants, and the skipped total.
    """
    if order > _DENSE_ORDER and bounds:
        return _exp_series_2d_dense(bounds, order, tol)
    if COMPILED_SERIES and bounds:
        return _exp_series_2d_compiled(bounds, order, tol)
    maj: dict = {(0, 0): 1.0}
    term: dict = {(0, 0): 1.0}
    for k in range(1, order + 1):
        new: dict = {}
        for (i1, j1), c1 in term.items():
            for (i2, j2), c2 in bounds.items():
                key = (i1 + i2, j1 + j2)
                new[key] = new.get(key, 0.0) + c1 * c2 / k
        term = new
        for key, c in term.items():
            maj[key] = maj.get(key, 0.0) + c
    skipped = 0.0
    keep = {(0, 0): 1.0}
    for key, c in sorted(maj.items(), key=lambda kv: kv[1]):
        if key != (0, 0) and skipped + c <= tol:
            skipped += c
        else:
            keep[key] = c
    return keep, skipped


class _Block2D:
    """The 2-D expansion of one chunk of movers over one block of chirps and one receiver."""

    def __init__(self, chirps, mu_scale, nu_scale, phi0, w, x, common, resid, keep, order):
        self.chirps = chirps      # (J,) chirp indices of the block, evenly spaced
        self.mu_scale = mu_scale  # U = mu / mu_scale
        self.nu_scale = nu_scale  # V = nu / nu_scale
        # (m,) reduced phases and NUFFT frequencies; w None: the slow-time frequency is a
        # rest (``resid[(1, 0)]``), and each vector is a 1-D NUFFT along the samples.
        self.phi0, self.w, self.x = phi0, w, x
        self.cost = 0.0           # the cost model's estimate of its run [ns]
        self.resid_rows = None    # (R, m) the rests' rows in ``resid``'s order, when stacked
        self.common = common      # {(i, j): float} chunk-wide coefficients (normalised)
        self.resid = resid        # {(i, j): (m,)} per-scatterer rests (normalised)
        self.keep = keep          # monomials of the series kept
        self.order = order        # order of the exp series


class _Leg:
    """One leg's offsets d (m, 3) from an element at the block's centre time, their
    lengths r0 (m,), y = T |vel| / r0 (m,) and its Taylor series per order (kept).

    ``compiled``: d, r0 and y from one compiled pass
    (:func:`twinsense.radar.kernels.leg_offsets`), else NumPy (the reference).
    """

    def __init__(self, pos, vel, t_mid, element, t_span, compiled: bool = True):
        self.vel = vel
        if compiled:
            m = len(pos)
            self.d, self.r0, self.y = np.empty((m, 3)), np.empty(m), np.empty(m)
            leg_offsets(pos, vel, float(t_mid), np.asarray(element, float), float(t_span),
                        self.d, self.r0, self.y)
        else:
            self.d = pos + vel * t_mid - element
            self.r0 = np.sqrt(_dot3(self.d, self.d))
            with np.errstate(divide="ignore", invalid="ignore"):  # a point on an element: not 2-D
                self.y = t_span * np.sqrt(_dot3(vel, vel)) / self.r0
        self._series: dict[int, np.ndarray] = {}
        self._compiled_series: dict[int, np.ndarray] = {}

    def series(self, order: int) -> np.ndarray:
        if order not in self._series:
            self._series[order] = _leg_series(self.d, self.vel, order)[0]
        return self._series[order]

    def compiled_series(self, order: int) -> np.ndarray:
        """(order + 1, m) the series from :func:`twinsense.radar.kernels.leg_series` (the bits
        of the compiled block pass), kept per order: a block's receivers share their
        transmit leg (its series was formed once per receiver)."""
        if order not in self._compiled_series:
            out = np.empty((order + 1, len(self.r0)))
            leg_series(self.d, self.vel, order, out)
            self._compiled_series[order] = out
        return self._compiled_series[order]


@functools.lru_cache(maxsize=64)
def _coefficient_sources(order: int, a_step: float, b: float) -> tuple[tuple, tuple]:
    """The contributions of :func:`_monomial_coeffs` in its order, for the compiled pass:
    the monomials (tuple of (i, j), in order of first contribution) and the arrays of
    :func:`twinsense.radar.kernels.block_coefficients`: each contribution's monomial row,
    its source (2 k: g_k, 2 k + 1: h_k), whether it is its monomial's first, and its factor
    (C(k, i) A^i B^(k-i) for g_k, times B for h_k). Cached: a frame's blocks share their
    order, chirp spacing and sample period (the callers only read the results)."""
    index: dict[tuple[int, int], int] = {}
    row, src, first, factor = [], [], [], []
    for k in range(order + 1):
        for i in range(k + 1):
            f = math.comb(k, i) * a_step**i * b ** (k - i)
            for key, fac, s in (((i, k - i), f, 2 * k), ((i, k - i + 1), f * b, 2 * k + 1)):
                first.append(key not in index)
                index.setdefault(key, len(index))
                row.append(index[key])
                src.append(s)
                factor.append(fac)
    arrays = (np.array(row, np.int64), np.array(src, np.int64), np.array(first, np.bool_),
              np.array(factor, float))
    for a in arrays:
        a.setflags(write=False)
    return tuple(index), arrays


def _coeffs_compiled(leg_tx: _Leg, leg_rx: _Leg, order: int, geo: Geometry, a_step: float,
                     span: np.ndarray) -> tuple[dict, float, dict]:
    """:func:`_coeffs_array`'s monomials, bound and extremes."""
    return _coeffs_array(leg_tx, leg_rx, order, geo, a_step, span)[:3]


# The transmit leg's series formed once for a block's receivers from this many movers on
# (the wrist radar's chunks of ~16,000: the phase coefficients 47 -> 40 ms per frame); below,
# each block forms it (a few movers of the wall radar's many small plans: the extra call and
# array cost more than the series, ~1.3 ms per frame measured). The same bits either way.
_SHARED_SERIES_MIN = 2048
_NO_SERIES = np.zeros((0, 0))


def _coeffs_array(leg_tx: _Leg, leg_rx: _Leg, order: int, geo: Geometry, a_step: float,
                  span: np.ndarray) -> tuple[dict, float, dict, tuple]:
    """:func:`_monomial_coeffs` of the two legs' delay series, the bound dmax and each
    monomial's (max, min) over the scatterers, from one compiled pass
    (:func:`twinsense.radar.kernels.block_coefficients`, any delay order): the same bits
    (the extremes the same values as NumPy's max and min). Also the (K, m) array the
    monomials' rows are views of, and each one's row."""
    keys, (row, src, first, factor) = _coefficient_sources(order, a_step, 1.0 / geo.fs)
    m = len(leg_tx.r0)
    coeffs = np.empty((len(keys), m))
    acc = np.empty(m)
    hi, lo = np.empty(len(keys)), np.empty(len(keys))
    block_coefficients(leg_tx.d, leg_tx.vel, leg_rx.d, leg_rx.vel, order, 1.0 / SPEED_OF_LIGHT,
                       _TWO_PI * geo.fc, math.pi * geo.slope, _TWO_PI * geo.slope, span, row, src,
                       first, factor, coeffs, acc, hi, lo,
                       leg_tx.compiled_series(order) if m >= _SHARED_SERIES_MIN else _NO_SERIES)
    extremes = {key: (float(a), float(b)) for key, a, b in zip(keys, hi, lo)}
    return dict(zip(keys, coeffs)), float(np.max(acc)), extremes, (coeffs, dict(zip(keys, range(len(keys)))))


def _plan_block(p, v, pr, vr, tx, rx, chirps, t_mid, a_step, geo: Geometry,
                eps: float, tx_leg: _Leg | None = None, compiled: bool = True,
                slow: bool | None = None, budget: float = math.inf) -> _Block2D | None:
    """Expansion of movers (p, v; pr, vr) for one receiver ``rx`` and the chirps ``chirps``
    (sent by ``tx``, evenly ``a_step`` seconds apart; ``t_mid`` [s]: the time of the
    block's centre sample from the frame start). None when the delay's Taylor
    series converges too slowly over the block (then the per-chirp path is used).

    Error budget per scatterer, relative to its amplitude at any sample (a
    phase error delta moves a sample by at most |delta|): delay truncation
    and dropped degrees of tau^2 eps / 16 each, dropped monomials eps / 16,
    exp-series order and skipped series terms 13/32 eps each: together eps,
    the per-chirp path's budget (its series order and skipped terms, eps / 2
    each). ``tx_leg``: the transmit leg of the same movers, block and
    transmitter, shared by the receivers' blocks (computed here when None).
    ``compiled``: the per-scatterer passes compiled (:mod:`twinsense.radar.kernels`),
    else NumPy (the reference; the same bits). ``budget`` [ns]: None also when the block's
    estimated cost surely exceeds it (the caller's split then loses to the per-chirp path).
    """
    n_samp = geo.n_samp
    jb = len(chirps)
    mu_half = jb // 2
    t_span = a_step * mu_half + (n_samp // 2) / geo.fs  # max |Delta| [s]
    leg_tx = _Leg(p, v, t_mid, tx, t_span, compiled) if tx_leg is None else tx_leg
    leg_rx = _Leg(pr, vr, t_mid, rx, t_span, compiled)
    r0_tx, r0_rx, y_tx, y_rx = leg_tx.r0, leg_rx.r0, leg_tx.y, leg_rx.y
    # Each leg on its own: a leg of length 0 has y inf (moving) or NaN (still), and Python's
    # max(a, nan) is a, so a NaN of the receive leg would pass a max of the two.
    y_big = np.array([y_tx.max(), y_rx.max()])  # each leg's largest y (NaN if any is)
    if not (y_big[0] <= _Y_MAX and y_big[1] <= _Y_MAX):
        return None
    # |d Phi / d tau| <= 2 pi (|fc| + |S| (N/2 / fs + tau)): the tail of the delay moves
    # the phase by at most that times the tail.
    tau_max = float((r0_tx + r0_rx).max()) * 2.0 / SPEED_OF_LIGHT
    f_top = abs(geo.fc) + abs(geo.slope) * ((n_samp // 2) / geo.fs + tau_max)
    phase_per_m = _TWO_PI * f_top / SPEED_OF_LIGHT
    # The tail grows with y (< 1) and r0, so the largest of each bounds every
    # scatterer's: a scalar search for the order.
    r_big = np.array([r0_tx.max(), r0_rx.max()])
    order = 1
    while True:
        tail = float(np.sum(_leg_tail(r_big, y_big, order)))
        if phase_per_m * tail <= eps / 16 or order >= _MAX_ORDER:
            break
        order += 1
    if phase_per_m * tail > eps / 16:
        return None
    # Degrees of tau^2 above the order are dropped: at most pi S (sum_{k>=1} |tau_k| T^k)^2.
    span = t_span ** np.arange(order + 1)
    if compiled:
        coeffs, dmax, extremes, (coeff_array, row_of) = _coeffs_array(leg_tx, leg_rx, order, geo,
                                                                       a_step, span)
    else:
        tau = (leg_tx.series(order) + leg_rx.series(order)) * (1.0 / SPEED_OF_LIGHT)
        # (A loop, not a (m, K) @ (K,) product: BLAS threads on tall, thin products
        # cost far more than the arithmetic on shared cores.)
        acc = np.abs(tau[1]) * span[1]
        for k in range(2, order + 1):
            acc += np.abs(tau[k]) * span[k]
        dmax = float(np.max(acc))
    if math.pi * abs(geo.slope) * dmax**2 > eps / 16:
        return None
    if not compiled:
        coeffs = _monomial_coeffs(tau, geo, a_step)
    mu_s, nu_s = max(mu_half, 1), n_samp // 2
    phi0 = _reduce(coeffs.pop((0, 0)))
    c10 = coeffs.pop((1, 0))
    x = _reduce(coeffs.pop((0, 1)))
    common: dict = {}
    scales: dict = {}
    bounds: dict = {}
    for (i, j), c in coeffs.items():
        if i > 0 and mu_half == 0:
            continue  # a single chirp: mu = 0
        scale = float(mu_s) ** i * float(nu_s) ** j
        # max(c scale) = max(c) scale exactly (rounding is monotone, scale > 0), so the
        # compiled pass's extremes of the unscaled c give the same bits.
        raw_hi, raw_lo = extremes[(i, j)] if compiled else (float(c.max()), float(c.min()))
        hi, lo = raw_hi * scale, raw_lo * scale
        common[(i, j)] = 0.5 * (hi + lo)
        scales[(i, j)] = scale
        # max |c - mid| = (hi - lo) / 2; the factor covers the rounding of mid and of c - mid.
        bounds[(i, j)] = 0.5 * (hi - lo) * (1.0 + 1e-12)
    # The slow-time frequency w mu as one more rest (the 1-D variant): w = w_c + delta with
    # w_c the chunk's mid-range, exact on the grid, and delta reduced to [-pi, pi] (mu is an
    # integer, so whole turns drop exactly). Movers sorted by range rate have a narrow
    # spread of w, so delta mu is small and each strength vector needs only a 1-D NUFFT
    # along the samples (about half a 2-D one's time on the wrist radar's blocks).
    variants = [(False, bounds)] if slow is not True or mu_half == 0 else []
    if slow is not False and mu_half > 0:
        raw_hi, raw_lo = extremes[(1, 0)] if compiled else (float(c10.max()), float(c10.min()))
        w_c = 0.5 * (raw_hi + raw_lo)
        if compiled:
            delta = np.empty(len(c10))
            d_hi, d_lo = slow_rest(c10, w_c, float(mu_s), delta)
        else:
            delta = _reduce(c10 - w_c)
            delta *= float(mu_s)
            d_hi, d_lo = float(delta.max()), float(delta.min())
        b10 = max(d_hi, -d_lo) * (1.0 + 1e-12)
        if b10 + sum(bounds.values()) <= _SLOW_REST_MAX:
            variants.append((True, {**bounds, (1, 0): b10}))
    if not variants:
        return None
    best = None
    # The 1-D variant's estimate first: the 2-D one's is skipped when it cannot be cheaper
    # (its cost with a single vector, its least, above the 1-D one's); on a tie the 2-D
    # variant is taken, as when it was estimated first.
    prepared = []
    for is_slow, var_bounds in sorted(variants, key=lambda var: not var[0]):
        # Drop the per-scatterer rest of the smallest monomials within eps / 16.
        kept = dict(var_bounds)
        dropped = 0.0
        for key, b in sorted(kept.items(), key=lambda kv: kv[1]):
            if dropped + b <= eps / 16:
                dropped += b
                del kept[key]
        # The order from the summed bounds (at least the largest rest of any scatterer):
        # an estimate for the choice only; the chosen variant's order comes from its rests.
        kept = {key: kept[key] for key in (*common, (1, 0)) if key in kept}  # the rests' order
        est_order = _taylor_order(sum(kept.values()), _SERIES_TOL * eps)
        prepared.append((is_slow, kept, est_order))
    # Over the caller's budget whatever the variant (a cost from a lower bound on the kept
    # monomials): the split is rejected as it would be after the series' selection, which
    # is skipped (tail movers' long series: most of the failed attempts' time).
    if all(_block_cost(len(p), _kept_at_least(kept, est_order, _SERIES_TOL * eps), jb, n_samp,
                       is_slow) > budget for is_slow, kept, est_order in prepared):
        return None
    for is_slow, kept, est_order in prepared:
        if (not is_slow and best is not None
                and best[0] < _block_cost(len(p), 1, jb, n_samp, slow=False)):
            continue
        est_keep, _ = _exp_series_2d(kept, est_order, _SERIES_TOL * eps)
        cost = _block_cost(len(p), len(est_keep), jb, n_samp, is_slow)
        if best is None or cost < best[0] or (cost == best[0] and not is_slow):
            best = (cost, is_slow, kept, est_order, est_keep)
    _, is_slow, bounds, est_order, est_keep = best
    if is_slow:
        common[(1, 0)] = w_c * float(mu_s)
        coeffs[(1, 0)] = delta
        scales[(1, 0)] = 1.0  # delta is scaled and centred already
        w = None
    else:
        w = _reduce(c10)
    # The rests as rows of one (R, m) array (the compiled series reads them so), each
    # c scale - mid as before; the largest summed |rest| in one compiled pass (the same
    # sum, left to right from 0, as sum(|r|) over the rows).
    res_keys = [key for key in common if key in bounds]
    stack = np.empty((len(res_keys), len(p)))
    if compiled and res_keys:
        # One compiled pass: the rows as below and their largest summed |rest| (the bits).
        pmax = rest_rows(coeff_array, np.array([-1 if k == (1, 0) else row_of[k] for k in res_keys],
                                               np.int64),
                         np.array([scales[k] for k in res_keys]), np.array([common[k] for k in res_keys]),
                         coeffs[(1, 0)] if (1, 0) in res_keys else phi0, stack)
    else:
        for r, key in enumerate(res_keys):
            c = coeffs[key]
            if key != (1, 0):
                np.multiply(c, scales[key], out=stack[r])
                stack[r] -= common[key]
            else:
                stack[r] = c
        pmax = abs_sum_max(stack) if res_keys else 0.0
    resid = {key: stack[r] for r, key in enumerate(res_keys)}
    bounds = {k: bounds[k] for k in resid}
    exp_order = _taylor_order(pmax, _SERIES_TOL * eps)
    # The estimate's selection when its order holds (the same bounds, in the same order).
    keep = (est_keep if exp_order == est_order
            else _exp_series_2d(bounds, exp_order, _SERIES_TOL * eps)[0])
    blk = _Block2D(chirps, mu_s, nu_s, phi0, w, x, common, resid, keep, exp_order)
    blk.resid_rows = stack
    blk.cost = _block_cost(len(p), len(keep), jb, n_samp, is_slow)
    return blk


def _kept_at_least(bounds: dict, order: int, tol: float) -> int:
    """A lower bound on len(:func:`_exp_series_2d` (bounds, order, tol)[0]): (0, 0) and every
    power (k i, k j), k <= order, of a rest (i, j) whose own share b^k / k! of its majorant
    exceeds ``tol`` (majorants are sums of non-negative terms, and one above ``tol`` is
    never skipped)."""
    found = {(0, 0)}
    for (i, j), b in bounds.items():
        term = 1.0
        for k in range(1, order + 1):
            term *= b / k
            if term <= tol:
                break
            found.add((k * i, k * j))
    return len(found)


def _needed(keep) -> set:
    """Monomials a kept one can grow from: R's monomials have non-negative degrees, so a
    term only feeds monomials at least as large in both (the others are never formed)."""
    return {(i, j) for i in range(max(k[0] for k in keep) + 1)
            for j in range(max(k[1] for k in keep) + 1)
            if any(i <= ki and j <= kj for ki, kj in keep)}


def _series_numpy(blk: _Block2D, n: int) -> dict:
    """{monomial: (n,) complex} coefficients of exp(j R) kept by the block (the reference of
    the compiled :func:`twinsense.radar.kernels.block_series`)."""
    series = {(0, 0): np.ones(n, dtype=complex)}
    term = dict(series)
    r_poly = {k: 1j * r for k, r in blk.resid.items()}
    needed = _needed(blk.keep)
    for k in range(1, blk.order + 1):
        term = _poly_mul(term, r_poly, needed)
        for key in term:
            term[key] *= 1.0 / k
        for key, c in term.items():
            if key in blk.keep:
                series[key] = series[key] + c if key in series else c.copy()
    return series


def _series_program(res_keys: list, keep, order: int):
    """:func:`_series_program_of` (cached: blocks of a frame share a few structures)."""
    return _series_program_of(tuple(res_keys), tuple(sorted(keep)), order)


@functools.lru_cache(maxsize=256)
def _series_program_of(res_keys: tuple, keep: tuple, order: int):
    """The compiled series' program (:func:`twinsense.radar.kernels.block_series`): the
    products, scalings and sums of :func:`_series_numpy` in its order (dictionary
    order of :func:`_poly_mul`). Returns (program (n_ops, 4), scale (n_ops,),
    out_slots (D,) for the sorted kept monomials, n_terms, n_series)."""
    needed = _needed(keep)
    program, scale = [(OP_SERIES_SET, 0, 0, 0)], [1.0]
    series_slot = {(0, 0): 0}
    term = {(0, 0): 0}  # monomial -> term slot; slot 0 holds 1
    n_terms = 1
    for k in range(1, order + 1):
        new: dict = {}
        for (i1, j1), src in term.items():
            for r, (i2, j2) in enumerate(res_keys):
                key = (i1 + i2, j1 + j2)
                if key not in needed:
                    continue
                if key in new:
                    program.append((OP_ACC, new[key], src, r))
                else:
                    new[key] = n_terms
                    n_terms += 1
                    program.append((OP_SET, new[key], src, r))
                scale.append(1.0)
        for slot in new.values():
            program.append((OP_SCALE, slot, 0, 0))
            scale.append(1.0 / k)
        term = new
        for key, slot in term.items():
            if key in keep:
                if key in series_slot:
                    program.append((OP_SERIES_ACC, series_slot[key], slot, 0))
                else:
                    series_slot[key] = len(series_slot)
                    program.append((OP_SERIES_SET, series_slot[key], slot, 0))
                scale.append(1.0)
    out_slots = [series_slot[key] for key in sorted(keep)]
    return (np.array(program, np.int64).reshape(-1, 4), np.array(scale), np.array(out_slots, np.int64),
            n_terms, len(series_slot))


def _block_strengths(blk: _Block2D, strength: np.ndarray, compiled: bool = True) -> dict:
    """{monomial: (m,) complex} strength vectors of the kept monomials (sorted): strength
    times their coefficient in exp(j R), from one compiled pass over the scatterers
    (:func:`twinsense.radar.kernels.block_series`, the same bits) or NumPy
    (``compiled`` False, the reference)."""
    keys = sorted(blk.keep)
    if not compiled:
        series = _series_numpy(blk, len(strength))
        return {key: series[key] * strength for key in keys}
    res_keys = list(blk.resid)
    resid = (np.array([blk.resid[k] for k in res_keys]) if res_keys
             else np.zeros((0, len(strength))))  # (R, m)
    program, scale, out_slots, n_terms, n_series = _series_program(res_keys, blk.keep, blk.order)
    out = np.empty((len(keys), len(strength)), dtype=complex)
    block_series(resid, program, scale, out_slots, n_terms, n_series, out)
    # NumPy's complex product (its vector loop rounds as the reference does).
    out *= strength
    return dict(zip(keys, out))


def _run_block(blk: _Block2D, wt: np.ndarray, geo: Geometry, eps: float,
               compiled: bool = True) -> np.ndarray:
    """(J, N) IF rows of one planned block (weights ``wt`` (m,)); ``compiled``: the strength
    vectors from the compiled pass (else NumPy, the reference)."""
    n_samp = geo.n_samp
    jb = len(blk.chirps)
    strength = np.empty(len(wt), dtype=complex)
    ph32 = blk.phi0.astype(np.float32)
    strength.real = np.cos(ph32)
    strength.imag = np.sin(ph32)
    strength *= wt
    if blk.w is None and SPREAD_1D:
        # The 1-D variant: every vector on the same points (the compiled spreader, all at
        # one tolerance; NumPy's series and the unfused spreader as the reference).
        tol = eps * _TOL_SPREAD
        if compiled:
            keys, out = _spread_block_1d(blk, strength, n_samp, tol)
        else:
            series = _block_strengths(blk, strength, compiled=False)
            keys = sorted(series)
            out = kernel_for(n_samp, tol).transform(blk.x, np.array([series[k] for k in keys]))
        return _block_rows(blk, keys, out, jb, n_samp)
    # exp(j R) as a polynomial in (U, V), only the kept monomials, times the strengths.
    series = _block_strengths(blk, strength, compiled)
    # Each vector's NUFFT at its own tolerance: vector d has strengths of at
    # most beta_d |w| (its majorant), so at tolerance eps_d its error is about
    # eps_d beta_d sum |w| (in finufft's l2 sense). The constant term (beta = 1) gets
    # e = eps / 2 (2-D vectors) or eps / 4 (1-D ones), the margins for finufft's excess
    # over its tolerance (_TOL_2D, _TOL_1D), the others eps_d <= e / (n_others beta_d)
    # in decades up to 1e-2: together at most e sum |w| more. Looser tolerances need
    # narrower kernels (finufft spreads ~(digits + 1)^2 grid points per point).
    others = max(len(series) - 1, 1)
    levels: dict[float, list] = {}
    first = eps * (_TOL_2D if blk.w is not None else _TOL_1D)
    for key in series:
        tol = first
        while key != (0, 0) and tol * 10.0 <= 1e-2 and tol * 10.0 * blk.keep[key] * others <= first:
            tol *= 10.0
        levels.setdefault(tol, []).append(key)
    keys, outs = [], []
    for tol, group in sorted(levels.items()):
        strengths = np.empty((len(group), len(wt)), dtype=complex)
        for d, key in enumerate(group):
            strengths[d] = series[key]
        if blk.w is None:  # 1-D along the samples (finufft: the spreader's blocks ran above)
            outs.append(_thread_plans(n_samp, tol).rows(blk.x, strengths).reshape(len(group), n_samp))
            keys += group
            continue
        plan = finufft.Plan(1, (jb, n_samp), n_trans=len(group), eps=tol, isign=1, nthreads=1,
                            modeord=0)
        plan.setpts(blk.w, blk.x)
        outs.append(plan.execute(strengths).reshape(len(group), jb, n_samp))
        keys += group
    return _block_rows(blk, keys, np.concatenate(outs), jb, n_samp)


def _spread_block_1d(blk: _Block2D, strength: np.ndarray, n_samp: int, tol: float):
    """The 1-D variant's strength vectors and their transforms in one compiled pass
    (:func:`twinsense.radar.spreader.spread_series_1d`: the series of
    :func:`_block_strengths`, times ``strength``, spread with each mover's kernel
    weights evaluated once). Returns the sorted kept monomials and their (D, N) modes."""
    keys = sorted(blk.keep)
    res_keys = list(blk.resid)
    if blk.resid_rows is not None:
        resid = blk.resid_rows
    else:
        resid = (np.array([blk.resid[k] for k in res_keys]) if res_keys
                 else np.zeros((0, len(strength))))  # (R, m)
    program, scale, out_slots, n_terms, n_series = _series_program(res_keys, blk.keep, blk.order)
    kern = kernel_for(n_samp, tol)
    grid = kern.grid(len(keys))
    spread_series_1d(resid, program, scale, out_slots, n_terms, n_series, strength,
                     np.ascontiguousarray(blk.x, dtype=float), kern.coef, kern.nf, grid.view(np.float64))
    return keys, kern.finish(grid)


def _block_rows(blk: _Block2D, keys: list, out: np.ndarray, jb: int, n_samp: int,
                compiled: bool = True) -> np.ndarray:
    """(J, N) rows of a block from its vectors' transforms ``out`` (D, J, N), or (D, N)
    for 1-D ones, of the monomials ``keys``: their sum times the chunk-wide factor.
    ``compiled``: a 1-D block's sums and phase in one compiled call
    (:func:`twinsense.radar.kernels.block_rows_1d`, the bits of the NumPy passes below,
    kept as the reference with ``compiled`` False: ~20 passes over the (J, N) rows)."""
    uu = (np.arange(jb) - jb // 2) / blk.mu_scale
    vv = (np.arange(n_samp) - n_samp // 2) / blk.nu_scale
    if compiled and blk.w is None:
        return _block_rows_compiled(blk, keys, out, uu, vv)
    rows = np.zeros((jb, n_samp), dtype=complex)
    if blk.w is None:
        # sum_d out_d(nu) U^i V^j = sum_i U^i (sum_{d: i_d = i} out_d V^j): 1-D sums first.
        by_i: dict = {}
        for d, (i, j) in enumerate(keys):
            term = out[d] * vv**j if j else out[d]
            by_i[i] = by_i[i] + term if i in by_i else term
        for i, acc in sorted(by_i.items()):
            # Broadcast, not np.outer: 3x faster for a real column times a complex row.
            rows += (uu**i)[:, None] * acc[None, :]
    else:
        for d, (i, j) in enumerate(keys):
            rows += out[d] * np.outer(uu**i, vv**j)
    # The chunk-wide phase sum_ij c_ij U^i V^j, grouped by i as above (one (J, N) pass per
    # power of U), reduced to [-pi, pi] in float64 and its cos and sin in float32 as for
    # the strengths (error ~1e-7 rad; 8x faster than a complex exp).
    poly: dict = {}
    for (i, j), c in blk.common.items():
        if c != 0.0:
            term = c * vv**j
            poly[i] = poly[i] + term if i in poly else term
    if poly:
        common = np.zeros((jb, n_samp))
        for i, acc in sorted(poly.items()):
            common += (uu**i)[:, None] * acc[None, :]
        ph32 = _reduce(common).astype(np.float32)
        phasor = np.empty((jb, n_samp), dtype=complex)
        phasor.real = np.cos(ph32)
        phasor.imag = np.sin(ph32)
        rows *= phasor
    return rows


def _block_rows_compiled(blk: _Block2D, keys: list, out: np.ndarray, uu: np.ndarray,
                         vv: np.ndarray) -> np.ndarray:
    """:func:`_block_rows` of a 1-D block by :func:`twinsense.radar.kernels.block_rows_1d`
    (the powers of U and V from NumPy, as there), then the phasor's cos and sin in float32
    and the product by NumPy, as there."""
    common = [(i, j, c) for (i, j), c in blk.common.items()]
    ivals = sorted({i for i, _ in keys})
    pvals = sorted({i for i, _, c in common if c != 0.0})
    n_u = max([*ivals, *pvals, 0]) + 1
    n_v = max([j for _, j in keys] + [j for _, j, _ in common] + [0]) + 1
    upow = np.array([uu**i for i in range(n_u)])
    vpow = np.array([vv**j for j in range(n_v)])
    rows = np.zeros((len(uu), len(vv)), dtype=complex)
    phase = np.empty((len(uu), len(vv)))
    block_rows_1d(np.ascontiguousarray(out), np.array([i for i, _ in keys], np.int64),
                  np.array([j for _, j in keys], np.int64), np.array(ivals, np.int64), upow, vpow,
                  np.array([i for i, _, _ in common], np.int64),
                  np.array([j for _, j, _ in common], np.int64),
                  np.array([c for _, _, c in common], float), np.array(pvals, np.int64), rows, phase)
    if pvals:
        ph32 = phase.astype(np.float32)
        phasor = np.empty(rows.shape, dtype=complex)
        phasor.real = np.cos(ph32)
        phasor.imag = np.sin(ph32)
        rows *= phasor
    return rows


def _tx_period(tx_of: np.ndarray) -> int:
    """Smallest L with tx_of[m] == tx_of[m % L] for every chirp (1 for a single transmitter)."""
    n = len(tx_of)
    for period in range(1, n + 1):
        if np.array_equal(tx_of[period:], tx_of[:n - period]):
            return period
    return n


# Cost model of the two mover paths [ns], measured on one core (16k movers,
# 512 samples, eps = 1e-6): the per-chirp path spends ~90 ns per (receiver,
# chirp, mover) on its phase terms and strengths plus ~70 ns per strength
# vector in its 1-D NUFFT (counted here with one vector, its least); the 2-D
# path ~400 ns per (block, receiver, mover) on its expansion, ~130 ns per
# strength vector and mover in the 2-D NUFFT (kernel width ~8 x 8) and ~5 ns
# per fine-grid point and vector in the FFT and the monomial sums.
_NS_1D_TERMS, _NS_1D_VECTOR = 90.0, 70.0
_NS_2D_PLAN, _NS_2D_VECTOR, _NS_2D_GRID = 400.0, 130.0, 5.0
# The 1-D variant (the slow-time frequency a rest): ~10 ns per strength vector and mover
# (the compiled series and spreading at width 6, each mover's kernel weights once:
# 9-11 ns measured on the wrist radar's 42 blocks of 16,286 movers with 10.4 vectors;
# finufft took ~50 ns per vector) and ~5 ns per sample of its sums.
_NS_SLOW_VECTOR, _NS_SLOW_GRID = 10.0, 5.0


def _block_cost(m: int, n_vectors: int, n_chirps: int, n_samp: int, slow: bool) -> float:
    """Estimated run time [ns] of one block's NUFFTs and sums (not its plan) with
    ``n_vectors`` strength vectors over ``m`` movers: 2-D vectors or 1-D ones (``slow``)."""
    if slow:
        return n_vectors * (m * _NS_SLOW_VECTOR + _NS_SLOW_GRID * (n_chirps + 4) * n_samp)
    return n_vectors * (m * _NS_2D_VECTOR + _NS_2D_GRID * 5 * n_chirps * n_samp)


# The floor of a split's cost before its plans (True; False: every split planned, as
# before it, for same-run comparisons; the same blocks either way).
SPLIT_FLOOR = True
_FLOOR_SAMPLE = 64  # movers whose slow-time frequencies bound a block's slow-time rest


def _floor_sample(m: int) -> np.ndarray:
    """(k,) int64: up to 64 movers spread evenly over the chunk, its first and last among
    them (a sorted chunk's extreme range rates)."""
    return np.unique(np.linspace(0, m - 1, min(m, _FLOOR_SAMPLE)).astype(np.int64))


def _powers_kept(b: float, tol: float) -> int:
    """A lower bound on the vectors of a 1-D variant whose slow-time rest is at least ``b``
    (<= 1): (0, 0) and every power (k, 0) with b^k / k! > tol (with a margin of 1e-9 for
    rounding). Such a power's majorant is at least b^k / k! (a sum of non-negative terms),
    so the series' selection never skips it, and the exp series' order (from the largest
    summed rest, at least b) reaches it: b^k / k! falls with k for b <= 1."""
    n, term = 1, 1.0
    for k in range(1, _MAX_ORDER * 4):
        term *= b / k
        if term <= tol * (1.0 + 1e-9):
            break
        n += 1
    return n


def _block_floor(m: int, b_slow: float, jb: int, n_samp: int, eps: float,
                 slow: bool | None) -> float:
    """A lower bound [ns] on ``_plan_block(...).cost`` of a block of ``jb`` chirps whose 1-D
    variant's slow-time rest is at least ``b_slow`` [rad] (inf: no variant applies).

    The 2-D variant has at least one vector; the 1-D variant at least
    :func:`_powers_kept` (b_slow) and exists only for b_slow <= 1 (its rests' sum)."""
    mu_half = jb // 2
    best = math.inf
    if slow is not True or mu_half == 0:
        best = _block_cost(m, 1, jb, n_samp, slow=False)
    if slow is not False and mu_half > 0 and b_slow <= _SLOW_REST_MAX:
        best = min(best, _block_cost(m, _powers_kept(b_slow, _SERIES_TOL * eps), jb, n_samp,
                                     slow=True))
    return best


def _split_blocks(groups: list, splits: int, geo: Geometry, chirp_centre: np.ndarray):
    """The blocks of a split, in order: each group of chirps (one position of the transmit
    sequence, evenly spaced) cut into ``min(splits, len(group))`` runs of consecutive chirps.
    Yields per block its chirps (J,) int, ``t_mid`` [s] (the centre chirp's centre time),
    ``a_step`` [s] (the spacing of its chirps; 0 for a single chirp) and ``tx`` (3,) [m]
    (its transmitter's position)."""
    for g in groups:
        for part in np.array_split(g, min(splits, len(g))):
            jb = len(part)
            t_mid = float(chirp_centre[part[jb // 2]])
            a_step = float(chirp_centre[part[1]] - chirp_centre[part[0]]) if jb > 1 else 0.0
            yield part, t_mid, a_step, geo.tx_per_chirp[part[0]]


def _split_ceiling(m: int, groups: list, splits: int, geo: Geometry, chirp_centre: np.ndarray,
                   slow: bool | None) -> float:
    """The largest value :func:`_split_floor` can return for the split, whatever the movers
    [ns]: per block the plan's share and one 2-D vector (the floor of a block is at most
    that when the 2-D variant may be taken; inf when only the 1-D variant may, ``slow``
    True)."""
    if slow is True:
        return math.inf
    total = 0.0
    for part, _, _, _ in _split_blocks(groups, splits, geo, chirp_centre):
        total += len(geo.rx) * (m * _NS_2D_PLAN + _block_cost(m, 1, len(part), geo.n_samp,
                                                              slow=False))
    return total


def _split_floor(p, v, pr, vr, groups: list, splits: int, geo: Geometry,
                 chirp_centre: np.ndarray, eps: float, slow: bool | None,
                 sample: np.ndarray) -> float:
    """A lower bound [ns] on the cost :func:`moving_chunk_2d` counts for a split (its blocks'
    plans and runs), from a compiled pass over ``sample``'s movers per block
    (:func:`twinsense.radar.kernels.slow_rest_floor`) instead of the plans: a split
    it puts above the per-chirp path's cost is one the cost rule would turn down.

    The slow-time rest's bound is lowered by 1e-9 of itself and 1e-12 rad for the
    rounding of its own sums against the plan's."""
    m, n_samp = len(p), geo.n_samp
    inv_c, two_pi_fc, pi_s = 1.0 / SPEED_OF_LIGHT, _TWO_PI * geo.fc, math.pi * geo.slope
    total = 0.0
    for part, t_mid, a_step, tx in _split_blocks(groups, splits, geo, chirp_centre):
        jb = len(part)
        for a in range(len(geo.rx)):
            b = 0.0
            if jb > 1:
                half = slow_rest_floor(p, v, pr, vr, sample, t_mid, tx, geo.rx_array[a], inv_c,
                                       two_pi_fc, pi_s, a_step)
                b = max(0.0, half * (jb // 2) * (1.0 - 1e-9) - 1e-12)
            total += m * _NS_2D_PLAN + _block_floor(m, b, jb, n_samp, eps, slow)
    return total


def moving_chunk_2d(p, v, pr, vr, w, geo: Geometry, chirp_centre: np.ndarray,
                    eps: float, force: bool = False, slow: bool | None = None) -> np.ndarray | None:
    """(n_rx, M, N) cube of moving scatterers by 2-D NUFFTs, or None if the per-chirp path
    (:func:`moving_chunk`) is estimated cheaper or the expansion does not apply.

    Chirps are grouped by their position in the transmit sequence (evenly spaced
    in time, one transmitter each) and each group is cut into 1, 2, 4, ... blocks
    of consecutive chirps: fewer blocks mean less per-scatterer work and fewer
    transforms, more blocks a smaller slow-time span and so shorter series. The
    first split whose operation count beats the per-chirp path's (counted with a
    single strength vector per chirp, its least) is used; ``force``: the first
    split that applies, whatever its cost (for tests). Each block takes the variant with
    the lower estimated cost: 2-D NUFFTs, or the slow-time frequency as one more rest
    with 1-D NUFFTs along the samples (``slow``: True or False forces one, for tests).
    A split whose cost floor (:func:`_split_floor`, from a few movers, without plans)
    already exceeds the per-chirp path's is skipped unplanned: the rule would turn it
    down, so the blocks chosen and the cube are those without the floor.
    """
    pr = p if pr is None else pr
    vr = v if vr is None else vr
    n_rx, n_chirps, n_samp = len(geo.rx), len(chirp_centre), geo.n_samp
    m = len(p)
    one_d = math.inf if force else n_rx * n_chirps * m * (_NS_1D_TERMS + _NS_1D_VECTOR)
    period = _tx_period(geo.tx_of)
    groups = [np.arange(q, n_chirps, period) for q in range(min(period, n_chirps))]
    longest = max(len(g) for g in groups)
    sample = _floor_sample(m) if SPLIT_FLOOR and not force else None
    splits = 1
    while True:
        blocks = []
        cost = 0.0
        # A split whose cost surely exceeds the per-chirp path's is skipped before any plan.
        # (Its passes only where the floor can reach that cost: not for the wrist radar's
        # thousands of movers, whose first split always can afford its blocks' grids.)
        if (sample is not None
                and _split_ceiling(m, groups, splits, geo, chirp_centre, slow) > one_d
                and _split_floor(p, v, pr, vr, groups, splits, geo, chirp_centre, eps, slow,
                                 sample) > one_d):
            cost = math.inf
            groups_to_plan = []
        else:
            groups_to_plan = groups
        for part, t_mid, a_step, tx in _split_blocks(groups_to_plan, splits, geo, chirp_centre):
            t_span = a_step * (len(part) // 2) + (n_samp // 2) / geo.fs
            tx_leg = _Leg(p, v, t_mid, tx, t_span)  # shared by the receivers
            for a in range(n_rx):
                blk = _plan_block(p, v, pr, vr, tx, geo.rx[a], part, t_mid, a_step, geo, eps,
                                  tx_leg, slow=slow, budget=one_d - cost - m * _NS_2D_PLAN)
                if blk is None:
                    cost = math.inf
                    break
                cost += m * _NS_2D_PLAN + blk.cost
                blocks.append((a, blk))
            # Past the per-chirp path's cost the split is lost: no further block is planned
            # (the blocks of a split that is taken, and so the cube, are the same).
            if cost == math.inf or cost > one_d:
                break
        if cost < math.inf and cost <= one_d:
            break
        splits *= 2
        if longest // splits < 2:
            return None
    cube = np.zeros((n_rx, n_chirps, n_samp), dtype=complex)
    for a, blk in blocks:
        cube[a, blk.chirps] += _run_block(blk, w, geo, eps)
    return cube
