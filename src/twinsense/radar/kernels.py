"""Compiled per-mover kernels of the fast IF synthesis (numba).

A moving scatterer's phase is expanded around every chirp's centre
(:mod:`twinsense.radar.nufft`): per receiver, chirp and scatterer, the
Taylor terms of both legs' lengths, then the phase coefficients phi0..phi3,
the NUFFT frequency and the reduced float32 phase. In NumPy that is some
forty passes over (chirps x scatterers) arrays with their temporaries;
:func:`moving_phases` makes one pass per scatterer without the GIL: 6
against 24 ms CPU for 6k movers of a walking person (the whole mover chunk,
NUFFTs included, 21 against 29 ms).

The operations are those of the NumPy reference
(``nufft.moving_phases_numpy``) in float64, in the same order, without
fastmath; the results are the same bits
(``tests/radar/test_synthesis_kernels.py``). The static scatterers' path
lengths and phases are one pass too (:func:`static_phases`); their cos and
sin stay NumPy's (vectorised float32 loops; ``tests/radar/test_static_phases.py``).

The 2-D mover path (``nufft.moving_chunk_2d``) has its per-block passes
here too: :func:`leg_offsets`, :func:`block_coefficients` (the delay
series, the phase coefficients per monomial and their extremes, any delay order;
:func:`leg_series` forms a transmit leg's series once for a block's receivers),
:func:`slow_rest` and :func:`rest_rows` (the per-scatterer rests),
:func:`series_majorants` (the majorant series that selects the kept monomials),
:func:`block_series` (the exp series of the rests) and :func:`block_rows_1d`
(a 1-D block's monomial sums and chunk-wide phase), each with the bits of
its NumPy form; and :func:`slow_rest_floor`, a lower bound on a block's
slow-time rest before its plan (``nufft._split_floor``) (``tests/radar/test_synthesis_block_kernels.py``,
``tests/radar/test_block_rows_kernel.py``). Before the chunks, which
scatterers move (:func:`faster_than`), the movers' range rates
(:func:`range_rates`), their stable sort (:func:`stable_argsort` on
:func:`rate_keys`: NumPy's stable order; :func:`stable_argsort_into` in the
caller's kept buffers; with two workers each sorts half the movers and
:func:`merge_orders` joins them) and each chunk's gather (:func:`gather_movers`;
``tests/radar/test_mover_sort.py``).
"""

from __future__ import annotations

import math

import numpy as np

from twinsense.compiled import jit

_TWO_PI = 2.0 * math.pi


@jit
def _reduce(phase):  # pragma: no cover
    """An angle into [-pi, pi]: the exact multiple of 2 pi removed in float64 (nufft._reduce)."""
    k = np.rint(phase * (1.0 / _TWO_PI))
    return phase - k * _TWO_PI


@jit
def _leg(p0, p1, p2, v0, v1, v2, speed2, e0, e1, e2):  # pragma: no cover
    """|d + v s| = r0 + r1 s + r2 s^2 + r3 s^3 + O(s^4), d = p - e (nufft._leg_taylor)."""
    d = p0 - e0
    dd = d * d
    dv = d * v0
    d = p1 - e1
    dd = dd + d * d
    dv = dv + d * v1
    d = p2 - e2
    dd = dd + d * d
    dv = dv + d * v2
    r0 = math.sqrt(dd)
    inv = 1.0 / r0
    r1 = dv * inv
    r2 = (speed2 - r1 * r1) * (0.5 * inv)
    r3 = -r1 * r2 * inv
    return r0, r1, r2, r3


@jit
def moving_phases(p, v, pr, vr, tx_per_chirp, rx, centres, fc, slope, fs, half, inv_c,
                  x, ph, a2, a3):  # pragma: no cover
    """Per receiver a, chirp m and moving scatterer i: the NUFFT frequency x, the phase
    ph (float32) at the chirp's centre and the coefficients a2, a3 of u^2, u^3
    (u = s / half), all (R, M, m) (nufft._moving_receiver's phi0..phi3).

    p, v, pr, vr (m, 3): points and velocities closing the transmit and the
    receive leg; tx_per_chirp (M, 3), rx (R, 3); centres (M,) chirp-centre
    times [s] from the frame start.
    """
    two_pi_fc = _TWO_PI * fc
    pi_s = math.pi * slope
    two_pi_s = _TWO_PI * slope
    inv_fs = 1.0 / fs
    h2 = half ** 2
    h3 = half ** 3
    # Chirps outside, scatterers inside: every output row is written in order.
    for m in range(centres.shape[0]):
        tc = centres[m]
        for i in range(p.shape[0]):
            v0, v1, v2 = v[i, 0], v[i, 1], v[i, 2]
            sp = v0 * v0 + v1 * v1 + v2 * v2
            w0, w1, w2 = vr[i, 0], vr[i, 1], vr[i, 2]
            spr = w0 * w0 + w1 * w1 + w2 * w2
            p0, p1, p2 = p[i, 0] + v0 * tc, p[i, 1] + v1 * tc, p[i, 2] + v2 * tc
            e0, e1, e2, e3 = _leg(p0, p1, p2, v0, v1, v2, sp, tx_per_chirp[m, 0], tx_per_chirp[m, 1],
                                  tx_per_chirp[m, 2])
            q0, q1, q2 = pr[i, 0] + w0 * tc, pr[i, 1] + w1 * tc, pr[i, 2] + w2 * tc
            for a in range(rx.shape[0]):
                f0, f1, f2, f3 = _leg(q0, q1, q2, w0, w1, w2, spr, rx[a, 0], rx[a, 1], rx[a, 2])
                t0 = (e0 + f0) * inv_c
                t1 = (e1 + f1) * inv_c
                t2 = (e2 + f2) * inv_c
                t3 = (e3 + f3) * inv_c
                phi0 = t0 * (two_pi_fc - pi_s * t0)
                phi1 = _TWO_PI * (fc * t1 + slope * t0) - two_pi_s * t0 * t1
                phi2 = _TWO_PI * (fc * t2 + slope * t1) - pi_s * (t1 * t1 + 2 * t0 * t2)
                phi3 = _TWO_PI * (fc * t3 + slope * t2) - two_pi_s * (t0 * t3 + t1 * t2)
                x[a, m, i] = _reduce(phi1 * inv_fs)
                ph[a, m, i] = np.float32(_reduce(phi0))
                a2[a, m, i] = phi2 * h2
                a3[a, m, i] = phi3 * h3


@jit
def _offset(pos, vel, i, t, element):  # pragma: no cover
    """Scatterer i's offset d = pos[i] + vel[i] t - element (3 floats) [m]: one leg of a
    2-D block at its centre time ``t`` (nufft._Leg)."""
    return (pos[i, 0] + vel[i, 0] * t - element[0], pos[i, 1] + vel[i, 1] * t - element[1],
            pos[i, 2] + vel[i, 2] * t - element[2])


@jit
def _first_terms(d0, d1, d2, w0, w1, w2):  # pragma: no cover
    """A leg's first two Taylor terms of |d + w t| (nufft._leg_series): r0 = |d| [m], 0.5 / r0
    and r1 = (2 d.w) (0.5 / r0) [m/s] (its recursion's first step), in that order of
    operations. The one form :func:`block_coefficients` and :func:`slow_rest_floor` use."""
    r0 = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    h = 0.5 / r0
    return r0, h, (2.0 * (d0 * w0 + d1 * w1 + d2 * w2)) * h


@jit
def leg_offsets(pos, vel, t_mid, element, t_span, d, r0, y):  # pragma: no cover
    """One leg of the 2-D path's block (nufft._Leg): offsets d = pos + vel t_mid - element
    (m, 3) [m], their lengths r0 (m,) [m] and y = t_span |vel| / r0 (m,), in one pass.

    A point on an element gives y = inf or nan (NumPy's error model), which the
    caller's check rejects.
    """
    for i in range(pos.shape[0]):
        d0, d1, d2 = _offset(pos, vel, i, t_mid, element)
        d[i, 0], d[i, 1], d[i, 2] = d0, d1, d2
        r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        r0[i] = r
        s = math.sqrt(vel[i, 0] * vel[i, 0] + vel[i, 1] * vel[i, 1] + vel[i, 2] * vel[i, 2])
        y[i] = t_span * s / r


_CTILE = 128  # scatterers per tile of block_coefficients: its series rows stay in the L1 cache


@jit
def _leg_tile(d, vel, start, n, k1, ser, half, q2, work):  # pragma: no cover
    """One leg's Taylor series of |d + vel t| (nufft._leg_series) for the ``n`` scatterers from
    ``start``: ser (k1, >= n) rows 0..k1-1, from 2 r0 r_k = Q_k - sum_{i=1}^{k-1} r_i r_{k-i}
    (Q_1 = 2 d.vel, Q_2 = |vel|^2), scatterers innermost; ``half``, ``q2``, ``work`` (>= n)
    work rows. The one form of :func:`block_coefficients` and :func:`leg_series`."""
    for i in range(n):
        s = start + i
        w0, w1, w2 = vel[s, 0], vel[s, 1], vel[s, 2]
        ser[0, i], half[i], ser[1, i] = _first_terms(d[s, 0], d[s, 1], d[s, 2], w0, w1, w2)
        q2[i] = w0 * w0 + w1 * w1 + w2 * w2
    for k in range(2, k1):
        if k == 2:
            for i in range(n):
                work[i] = q2[i]
        else:
            for i in range(n):
                work[i] = 0.0
        for j in range(1, k):
            for i in range(n):
                work[i] -= ser[j, i] * ser[k - j, i]
        for i in range(n):
            ser[k, i] = work[i] * half[i]


@jit
def leg_series(d, vel, order, out):  # pragma: no cover
    """out (order + 1, m): one leg's Taylor series of |d + vel t| for the rows of d, vel (m, 3)
    (:func:`_leg_tile`, tile by tile as :func:`block_coefficients` forms them: the same bits),
    so that a block's receivers share their transmit leg's (``tx_series`` there)."""
    m = d.shape[0]
    k1 = order + 1
    ser = np.empty((k1, _CTILE))
    half = np.empty(_CTILE)
    q2 = np.empty(_CTILE)
    work = np.empty(_CTILE)
    for start in range(0, m, _CTILE):
        n = min(_CTILE, m - start)
        _leg_tile(d, vel, start, n, k1, ser, half, q2, work)
        for k in range(k1):
            for i in range(n):
                out[k, start + i] = ser[k, i]


@jit
def block_coefficients(d_tx, v_tx, d_rx, v_rx, order, inv_c, two_pi_fc, pi_s, two_pi_s, span,
                       c_row, c_src, c_first, factor, coeffs, acc, hi, lo,
                       tx_series):  # pragma: no cover
    """Per scatterer of a 2-D block, for any delay order K >= 1: both legs' Taylor series of
    |d + vel t| (nufft._leg_series), the delay tau = (tx + rx) / c, the bound
    acc = sum_{k>=1} |tau_k| span[k] (m,), the phase coefficients of nufft._monomial_coeffs,
    coeffs (n_monomials, m), and each monomial's largest and smallest value over the
    scatterers, hi and lo (n_monomials,), with g_k = 2 pi fc tau_k - pi S (tau * tau)_k and
    h_k = 2 pi S tau_k: the operations of the NumPy forms in their order (their bits).

    The contributions (nufft._coefficient_sources) in their order: ``c_row`` (C,) the
    monomial's row, ``c_src`` (C,) 2 k for g_k and 2 k + 1 for h_k, ``c_first`` (C,) 1 where
    the contribution is its monomial's first (set, else added), ``factor`` (C,).
    ``tx_series`` (K + 1, m): the transmit leg's series from :func:`leg_series` (the
    receivers of a block share it), or any array with another first dimension (e.g.
    (0, 0)): formed here. Tiles of scatterers with the scatterers innermost in every step (independent
    operations the compiler pipelines and vectorises; a sum over the orders per scatterer
    innermost waits on each addition), so one generic loop over the orders costs about
    what their arithmetic costs.
    """
    m = d_tx.shape[0]
    k1 = order + 1
    r_tx = np.empty((k1, _CTILE))
    r_rx = np.empty((k1, _CTILE))
    tau = np.empty((k1, _CTILE))
    gh = np.empty((2 * k1, _CTILE))
    half = np.empty(_CTILE)
    q2 = np.empty(_CTILE)
    work = np.empty(_CTILE)
    n_rows = coeffs.shape[0]
    for r in range(n_rows):
        hi[r] = -np.inf
        lo[r] = np.inf
    for start in range(0, m, _CTILE):
        n = min(_CTILE, m - start)
        if tx_series.shape[0] == k1:
            # The transmit leg's series, formed once for the receivers (leg_series).
            for k in range(k1):
                for i in range(n):
                    r_tx[k, i] = tx_series[k, start + i]
        else:
            _leg_tile(d_tx, v_tx, start, n, k1, r_tx, half, q2, work)
        _leg_tile(d_rx, v_rx, start, n, k1, r_rx, half, q2, work)
        for k in range(k1):
            for i in range(n):
                tau[k, i] = (r_tx[k, i] + r_rx[k, i]) * inv_c
        for k in range(k1):
            for i in range(n):
                work[i] = 0.0
            for j in range(k + 1):
                for i in range(n):
                    work[i] += tau[j, i] * tau[k - j, i]
            for i in range(n):
                gh[2 * k, i] = two_pi_fc * tau[k, i] - pi_s * work[i]
                gh[2 * k + 1, i] = two_pi_s * tau[k, i]
        for i in range(n):
            work[i] = abs(tau[1, i]) * span[1]
        for k in range(2, k1):
            for i in range(n):
                work[i] += abs(tau[k, i]) * span[k]
        for i in range(n):
            acc[start + i] = work[i]
        for c in range(c_row.shape[0]):
            row, src, f = c_row[c], c_src[c], factor[c]
            out = coeffs[row, start:start + n]
            g = gh[src]
            if c_first[c]:
                for i in range(n):
                    out[i] = g[i] * f
            else:
                for i in range(n):
                    out[i] += g[i] * f
        for r in range(n_rows):
            row_vals = coeffs[r, start:start + n]
            top, bottom = hi[r], lo[r]
            for i in range(n):
                top = max(top, row_vals[i])
                bottom = min(bottom, row_vals[i])
            hi[r], lo[r] = top, bottom


# Operations of block_series' program (one row: op, destination, source, residual).
OP_SET, OP_ACC, OP_SCALE, OP_SERIES_SET, OP_SERIES_ACC = 0, 1, 2, 3, 4
_TILE = 256  # scatterers per tile: a tile's terms stay in the L1 cache


@jit
def series_tile(resid, lo, n, program, scale, t_re, t_im, s_re, s_im):  # pragma: no cover
    """Run a series ``program`` (see :func:`block_series`) over the ``n`` scatterers from
    ``lo``: ``t_re``/``t_im`` (n_terms, >= n) the terms, ``s_re``/``s_im`` (n_series, >= n)
    the series, written in place. One home for block_series and the spreader's fused pass."""
    for i in range(n):
        t_re[0, i] = 1.0
        t_im[0, i] = 0.0
    for q in range(program.shape[0]):
        op, dst, src, r = program[q, 0], program[q, 1], program[q, 2], program[q, 3]
        if op == OP_SET:
            for i in range(n):
                c = resid[r, lo + i]
                a, b = t_re[src, i], t_im[src, i]
                t_re[dst, i] = -(b * c)
                t_im[dst, i] = a * c
        elif op == OP_ACC:
            for i in range(n):
                c = resid[r, lo + i]
                a, b = t_re[src, i], t_im[src, i]
                t_re[dst, i] -= b * c
                t_im[dst, i] += a * c
        elif op == OP_SCALE:
            f = scale[q]
            for i in range(n):
                t_re[dst, i] *= f
                t_im[dst, i] *= f
        elif op == OP_SERIES_SET:
            for i in range(n):
                s_re[dst, i] = t_re[src, i]
                s_im[dst, i] = t_im[src, i]
        else:
            for i in range(n):
                s_re[dst, i] += t_re[src, i]
                s_im[dst, i] += t_im[src, i]


@jit
def block_series(resid, program, scale, out_slots, n_terms, n_series, out):  # pragma: no cover
    """Series of a 2-D block (nufft._run_block): out[d, i] = the coefficient of the d-th
    kept monomial of exp(j R) for scatterer i, R = sum_r resid[r, i] U^a V^b.

    ``program`` (n_ops, 4) int64 lists the series' products as NumPy forms them
    (nufft._series_numpy), so the results are its bits: OP_SET / OP_ACC:
    term[dst] (+)= term[src] * (j resid[r]); OP_SCALE: term[dst] *= scale[op];
    OP_SERIES_SET / OP_SERIES_ACC: series[dst] (+)= term[src]. Term 0 is 1.
    ``out_slots`` (D,): the series slot of each output row; ``out`` (D, m) complex.
    Each operation runs over a tile of scatterers (a loop the compiler vectorises).
    """
    m = resid.shape[1]
    t_re = np.empty((n_terms, _TILE))
    t_im = np.empty((n_terms, _TILE))
    s_re = np.empty((n_series, _TILE))
    s_im = np.empty((n_series, _TILE))
    for lo in range(0, m, _TILE):
        n = min(_TILE, m - lo)
        series_tile(resid, lo, n, program, scale, t_re, t_im, s_re, s_im)
        for d in range(out_slots.shape[0]):
            k = out_slots[d]
            for i in range(n):
                out[d, lo + i] = complex(s_re[k, i], s_im[k, i])


@jit
def abs_sum_max(rows):  # pragma: no cover
    """max_i sum_r |rows[r, i]| of (R, m) rows, each sum from 0 in row order (the bits of
    NumPy's ``max(sum(abs(r) for r in rows, zeros))``); 0 for m = 0."""
    n_rows, m = rows.shape
    best = 0.0
    for i in range(m):
        acc = 0.0
        for r in range(n_rows):
            acc += abs(rows[r, i])
        if acc > best:
            best = acc
    return best


# The movers' sort by range rate (synthesis.synthesize): a stable radix argsort.
_DIGIT = 8
_BINS = 1 << _DIGIT
_LOW = np.uint64(0xFFFFFFFF)
_SIGN = np.uint64(0x8000000000000000)


@jit
def rate_keys(rate, keys):  # pragma: no cover
    """keys (n,) uint64 that sort as the float64 ``rate`` (n,) does: the sign bit
    flipped for positives, every bit for negatives; -0.0 taken as +0.0 (NumPy's sort has
    them equal, so a stable sort keeps their index order); every NaN, whatever its sign
    bit (x86's 0/0 and inf/inf set it), the largest key: NumPy sorts NaNs last, among
    themselves in index order."""
    bits = rate.view(np.uint64)
    for i in range(rate.shape[0]):
        r = rate[i]
        if r != r:
            keys[i] = ~np.uint64(0)
            continue
        b = bits[i]
        if r == 0.0:
            b = np.uint64(0)
        keys[i] = ~b if b & _SIGN else b | _SIGN


@jit
def _radix_top32(packed, spare):  # pragma: no cover
    """packed (n,) uint64 (a key's top 32 bits above a 32-bit index) sorted stably by the
    top 32 bits: four LSD passes of 8 bits, a pass whose digit every entry shares
    skipped; ``spare`` (n,) uint64 the other buffer of the passes. Returns True when the
    sorted entries end in ``spare`` (an odd number of passes), False: in ``packed``."""
    n = packed.shape[0]
    hist = np.zeros((4, _BINS), np.int64)
    mask = np.uint64(_BINS - 1)
    for i in range(n):
        k = packed[i]
        for d in range(4):
            hist[d, np.int64((k >> np.uint64(32 + _DIGIT * d)) & mask)] += 1
    out = spare
    offset = np.empty(_BINS, np.int64)
    passes = 0
    for d in range(4):
        h = hist[d]
        if h.max() == n:
            continue
        total = 0
        for b in range(_BINS):
            offset[b] = total
            total += h[b]
        shift = np.uint64(32 + _DIGIT * d)
        for i in range(n):
            k = packed[i]
            b = np.int64((k >> shift) & mask)
            at = offset[b]
            offset[b] = at + 1
            out[at] = k
        packed, out = out, packed
        passes += 1
    return passes % 2 == 1


@jit
def _full_radix(keys, packed, spare, idx):  # pragma: no cover
    """Stable argsort of keys (n,) uint64 into idx (n,) int64: by the low 32 bits, then
    stably by the top 32 (``packed`` and ``spare`` (n,) uint64: work buffers)."""
    n = keys.shape[0]
    for i in range(n):
        packed[i] = (keys[i] << np.uint64(32)) | np.uint64(i)
    if _radix_top32(packed, spare):
        packed, spare = spare, packed
    for m in range(n):
        i = np.int64(packed[m] & _LOW)
        packed[m] = (keys[i] & ~_LOW) | np.uint64(i)
    if _radix_top32(packed, spare):
        packed, spare = spare, packed
    for i in range(n):
        idx[i] = np.int64(packed[i] & _LOW)


@jit
def stable_argsort(keys):  # pragma: no cover
    """(n,) int64 indices that sort keys (n,) uint64 ascending, equal keys in index order
    (``np.argsort(kind="stable")``'s result; n < 2^32): :func:`stable_argsort_into` with
    new work arrays."""
    n = keys.shape[0]
    idx = np.empty(n, np.int64)
    stable_argsort_into(keys, np.empty(n, np.uint64), np.empty(n, np.uint64), idx)
    return idx


@jit
def stable_argsort_into(keys, packed, spare, idx):  # pragma: no cover
    """idx (n,) int64: the indices that sort keys (n,) uint64 ascending, equal keys in index
    order (``np.argsort(kind="stable")``'s result; n < 2^32). ``packed`` and ``spare`` (n,)
    uint64: work buffers (their contents are not read), so a caller can keep all three
    between frames (arrays of a frame's size allocated anew are page-faulted anew).

    Radix passes over the keys' top 32 bits (each packed with its index: 8 bytes an
    entry), then each run of entries sharing them sorted by the full keys by insertion
    (stable; range rates share their top 32 bits only in short runs). Past 16 moves per
    key in the insertions, a radix sort of the full keys instead.
    """
    n = keys.shape[0]
    for i in range(n):
        packed[i] = (keys[i] & ~_LOW) | np.uint64(i)
    if _radix_top32(packed, spare):
        packed, spare = spare, packed
    for i in range(n):
        idx[i] = np.int64(packed[i] & _LOW)
    budget = 16 * n
    moves = 0
    a = 0
    while a < n:
        top = packed[a] & ~_LOW
        b = a + 1
        while b < n and packed[b] & ~_LOW == top:
            b += 1
        for i in range(a + 1, b):
            j = idx[i]
            k = keys[j]
            at = i
            while at > a and keys[idx[at - 1]] > k:
                idx[at] = idx[at - 1]
                at -= 1
                moves += 1
            idx[at] = j
            if moves > budget:
                _full_radix(keys, packed, spare, idx)
                return
        a = b


@jit
def merge_orders(keys, left, right, out):  # pragma: no cover
    """out (a + b,) int64: the stable merge of ``left`` (a,) and ``right`` (b,), each a
    stable ascending order of ``keys`` (n,) uint64 over its own rows, every row of
    ``left`` below every row of ``right``. On equal keys ``left`` goes first, so the
    result is :func:`stable_argsort` of the rows together (the parallel sort's last step)."""
    i = 0
    j = 0
    m = 0
    a = left.shape[0]
    b = right.shape[0]
    while i < a and j < b:
        if keys[right[j]] < keys[left[i]]:
            out[m] = right[j]
            j += 1
        else:
            out[m] = left[i]
            i += 1
        m += 1
    while i < a:
        out[m] = left[i]
        i += 1
        m += 1
    while j < b:
        out[m] = right[j]
        j += 1
        m += 1


@jit
def gather_movers(rows, p, v, w, pm, vm, wm):  # pragma: no cover
    """Rows ``rows`` (k,) of p, v (n, 3) and w (n,) into pm, vm (k, 3) and wm (k,), in one
    pass (``np.take``'s values)."""
    for m in range(rows.shape[0]):
        i = rows[m]
        pm[m, 0] = p[i, 0]
        pm[m, 1] = p[i, 1]
        pm[m, 2] = p[i, 2]
        vm[m, 0] = v[i, 0]
        vm[m, 1] = v[i, 1]
        vm[m, 2] = v[i, 2]
        wm[m] = w[i]


@jit
def faster_than(v, limit2, moving):  # pragma: no cover
    """moving (n,) bool: |v_i|^2 > ``limit2`` [m^2/s^2] for the rows of v (n, 3) [m/s], the
    square summed as synthesis._norm2 sums it ((v0 v0 + v1 v1) + v2 v2: its bits); returns
    how many rows move. One pass, without _norm2's three (n,) temporaries."""
    count = 0
    for i in range(v.shape[0]):
        s = v[i, 0] * v[i, 0]
        s = s + v[i, 1] * v[i, 1]
        s = s + v[i, 2] * v[i, 2]
        m = s > limit2
        moving[i] = m
        count += m
    return count


@jit
def range_rates(p, v, rows, rate):  # pragma: no cover
    """rate (k,) [m/s]: p.v / max(|p|, 1e-12) of the rows ``rows`` (k,) of p, v (n, 3), the
    operations of synthesis._range_rate in its order (its bits)."""
    for m in range(rows.shape[0]):
        i = rows[m]
        dot = p[i, 0] * v[i, 0]
        dot = dot + p[i, 1] * v[i, 1]
        dot = dot + p[i, 2] * v[i, 2]
        s = p[i, 0] * p[i, 0]
        s = s + p[i, 1] * p[i, 1]
        s = s + p[i, 2] * p[i, 2]
        rate[m] = dot / max(math.sqrt(s), 1e-12)


@jit
def static_phases(p, pr, tx, rx, pairs, kx, kf, ks, x, ph):  # pragma: no cover
    """Per (tx, rx) pair j and static scatterer i: the NUFFT frequency x[j, i] (float64)
    and the reduced phase ph[j, i] (float32) of nufft.static_chunk, the operations of its
    NumPy form in its order (nufft._ranges: |p|^2 + |e|^2 - 2 e_k p_k over the non-zero
    components of e; then L = r_tx + r_rx, x = L kx and phi = (kf - L ks) L, both reduced),
    so the same bits.

    p, pr (m, 3) [m]: the points closing the transmit and the receive leg; tx (T, 3),
    rx (R, 3) [m]; pairs (P, 2) int64: (transmitter, receiver) rows; x, ph (P, m).
    """
    n_tx, n_rx = tx.shape[0], rx.shape[0]
    ee_tx = np.empty(n_tx)
    ee_rx = np.empty(n_rx)
    for k in range(n_tx):
        ee_tx[k] = tx[k, 0] * tx[k, 0] + tx[k, 1] * tx[k, 1] + tx[k, 2] * tx[k, 2]
    for k in range(n_rx):
        ee_rx[k] = rx[k, 0] * rx[k, 0] + rx[k, 1] * rx[k, 1] + rx[k, 2] * rx[k, 2]
    r_tx = np.empty(n_tx)
    r_rx = np.empty(n_rx)
    for i in range(p.shape[0]):
        for leg in range(2):
            q = p if leg == 0 else pr
            el = tx if leg == 0 else rx
            ee = ee_tx if leg == 0 else ee_rx
            out = r_tx if leg == 0 else r_rx
            c0, c1, c2 = q[i, 0], q[i, 1], q[i, 2]
            s2 = c0 * c0
            s2 = s2 + c1 * c1
            s2 = s2 + c2 * c2
            for k in range(el.shape[0]):
                d = s2 + ee[k]
                if el[k, 0] != 0.0:
                    d = d - (2.0 * el[k, 0]) * c0
                if el[k, 1] != 0.0:
                    d = d - (2.0 * el[k, 1]) * c1
                if el[k, 2] != 0.0:
                    d = d - (2.0 * el[k, 2]) * c2
                out[k] = math.sqrt(d)
        for j in range(pairs.shape[0]):
            length = r_tx[pairs[j, 0]] + r_rx[pairs[j, 1]]
            x[j, i] = _reduce(length * kx)
            phi = (kf - length * ks) * length
            ph[j, i] = np.float32(_reduce(phi))



@jit
def block_rows_1d(out, key_i, key_j, ivals, upow, vpow, c_i, c_j, c_val, pvals, rows,
                  phase):  # pragma: no cover
    """A 1-D block's rows and its chunk-wide phase (nufft._block_rows for 1-D vectors), the
    operations of its NumPy form in its order, so its bits:

    rows[m, n] = sum over i in ``ivals`` of U_m^i acc_i[n], acc_i = sum over the vectors d
    with key_i[d] = i (in order) of out[d] V^key_j[d]; phase[m, n] = sum over i in
    ``pvals`` of U_m^i poly_i[n], poly_i = sum over the non-zero coefficients c (in order)
    of monomials (i, j) of c V^j, reduced to [-pi, pi].

    out (D, N) complex: the vectors' transforms; key_i, key_j (D,): their monomials;
    ivals (I,), pvals (P,): the powers of U that occur, ascending; upow (>= max i + 1, M):
    U^i per chirp row; vpow (>= max j + 1, N): V^j per sample (NumPy's powers, passed in);
    c_i, c_j, c_val (C,): the chunk-wide coefficients; rows (M, N) complex, zeroed;
    phase (M, N) float64 (untouched when P = 0).
    """
    n_samp = out.shape[1]
    n_rows = rows.shape[0]
    acc_re = np.empty(n_samp)
    acc_im = np.empty(n_samp)
    for q in range(ivals.shape[0]):
        i = ivals[q]
        first = True
        for d in range(out.shape[0]):
            if key_i[d] != i:
                continue
            j = key_j[d]
            for n in range(n_samp):
                re, im = out[d, n].real, out[d, n].imag
                if j:
                    re = re * vpow[j, n]
                    im = im * vpow[j, n]
                if first:
                    acc_re[n], acc_im[n] = re, im
                else:
                    acc_re[n] += re
                    acc_im[n] += im
            first = False
        for m in range(n_rows):
            u = upow[i, m]
            for n in range(n_samp):
                rows[m, n] = complex(rows[m, n].real + u * acc_re[n], rows[m, n].imag + u * acc_im[n])
    if pvals.shape[0] == 0:
        return
    poly = np.empty(n_samp)
    for m in range(n_rows):
        for n in range(n_samp):
            phase[m, n] = 0.0
    for q in range(pvals.shape[0]):
        i = pvals[q]
        first = True
        for c in range(c_val.shape[0]):
            if c_i[c] != i or c_val[c] == 0.0:
                continue
            j = c_j[c]
            for n in range(n_samp):
                t = c_val[c] * vpow[j, n]
                if first:
                    poly[n] = t
                else:
                    poly[n] += t
            first = False
        for m in range(n_rows):
            u = upow[i, m]
            for n in range(n_samp):
                phase[m, n] += u * poly[n]
    for m in range(n_rows):
        for n in range(n_samp):
            phase[m, n] = _reduce(phase[m, n])


@jit
def slow_rest(c10, w_c, mu_scale, delta):  # pragma: no cover
    """The 1-D variant's slow-time rest (nufft._plan_block): delta = reduce(c10 - w_c)
    mu_scale (m,), NumPy's operations in its order; returns its (max, min)."""
    hi = -np.inf
    lo = np.inf
    for i in range(c10.shape[0]):
        t = _reduce(c10[i] - w_c) * mu_scale
        delta[i] = t
        if t > hi:
            hi = t
        if t < lo:
            lo = t
    return hi, lo


@jit
def rest_rows(src, rows, scale, mid, delta, stack):  # pragma: no cover
    """The block's rests (nufft._plan_block) as rows of stack (R, m): src[rows[r]] scale[r]
    - mid[r], or ``delta`` where rows[r] < 0; returns max_i sum_r |stack[r, i]| (summed
    from 0 in row order, :func:`abs_sum_max`'s bits)."""
    n_rows, m = stack.shape
    best = 0.0
    for i in range(m):
        acc = 0.0
        for r in range(n_rows):
            k = rows[r]
            t = delta[i] if k < 0 else src[k, i] * scale[r] - mid[r]
            stack[r, i] = t
            acc += abs(t)
        if acc > best:
            best = acc
    return best


@jit
def slow_rest_floor(p, v, pr, vr, sample, t_mid, tx, rx, inv_c, two_pi_fc, pi_s,
                    a_step):  # pragma: no cover
    """A lower bound [rad] on the 1-D variant's slow-time rest of a block before its plan
    (nufft._split_floor): half the largest circular distance |reduce(c_a - c_b)| between
    the slow-time frequencies c10 (rad per chirp step) of the movers ``sample`` (k,) int64.

    c10 = A g_1 (A = ``a_step``) with g_1 = 2 pi fc tau_1 - pi S (tau_0 tau_1 + tau_1 tau_0),
    the delay's terms at the block's centre time ``t_mid`` from both legs' offsets to
    ``tx`` and ``rx`` (3,) (nufft._plan_block's operations). Whatever the centre w_c the plan
    takes, one of two movers lies at least half their circular distance from it (the
    triangle inequality on the circle), so any subset of movers bounds the plan's
    max_i |reduce(c10_i - w_c)| from below.
    """
    k = sample.shape[0]
    c10 = np.empty(k)
    r0 = np.empty(2)
    r1 = np.empty(2)
    for q in range(k):
        i = sample[q]
        for leg in range(2):
            pos = p if leg == 0 else pr
            vel = v if leg == 0 else vr
            d0, d1, d2 = _offset(pos, vel, i, t_mid, tx if leg == 0 else rx)
            r0[leg], _, r1[leg] = _first_terms(d0, d1, d2, vel[i, 0], vel[i, 1], vel[i, 2])
        t0 = (r0[0] + r0[1]) * inv_c
        t1 = (r1[0] + r1[1]) * inv_c
        c10[q] = (two_pi_fc * t1 - pi_s * (t0 * t1 + t1 * t0)) * a_step
    best = 0.0
    for a in range(k):
        for b in range(a + 1, k):
            dist = abs(_reduce(c10[a] - c10[b]))
            if dist > best:
                best = dist
    return 0.5 * best


@jit
def series_majorants(b_i, b_j, b_val, order, maj_i, maj_j, maj_val):  # pragma: no cover
    """The majorant series of a 2-D block's exp series (nufft._exp_series_2d, dictionary
    form): for k = 1..order the term T_k = T_{k-1} * B / k (B = sum_r b_val[r] U^b_i[r]
    V^b_j[r], the rests' bounds in their dictionary order) and the majorants
    M = sum_k T_k, each sum formed in the dictionaries' order (a term's monomials in the
    order they first appear, each product (c1 c2) / k added to what is there), so the
    same bits. Writes M's monomials in their order of first appearance, (0, 0) first,
    into maj_i, maj_j, maj_val (capacity (order max b_i + 1) (order max b_j + 1)) and
    returns their count."""
    n_r = b_i.shape[0]
    top_i, top_j = 0, 0
    for r in range(n_r):
        top_i = max(top_i, b_i[r])
        top_j = max(top_j, b_j[r])
    n_i, n_j = order * top_i + 1, order * top_j + 1
    cap = n_i * n_j
    maj_slot = np.full((n_i, n_j), -1, np.int64)
    new_slot = np.full((n_i, n_j), -1, np.int64)
    t_i = np.empty(cap, np.int64)
    t_j = np.empty(cap, np.int64)
    t_v = np.empty(cap)
    w_i = np.empty(cap, np.int64)
    w_j = np.empty(cap, np.int64)
    w_v = np.empty(cap)
    t_i[0], t_j[0], t_v[0] = 0, 0, 1.0
    n_t = 1
    maj_i[0], maj_j[0], maj_val[0] = 0, 0, 1.0
    maj_slot[0, 0] = 0
    n_maj = 1
    for k in range(1, order + 1):
        n_w = 0
        for a in range(n_t):
            c1 = t_v[a]
            for r in range(n_r):
                ki, kj = t_i[a] + b_i[r], t_j[a] + b_j[r]
                x = c1 * b_val[r] / k
                s = new_slot[ki, kj]
                if s < 0:
                    new_slot[ki, kj] = n_w
                    w_i[n_w], w_j[n_w], w_v[n_w] = ki, kj, 0.0 + x
                    n_w += 1
                else:
                    w_v[s] = w_v[s] + x
        for a in range(n_w):
            new_slot[w_i[a], w_j[a]] = -1
            t_i[a], t_j[a], t_v[a] = w_i[a], w_j[a], w_v[a]
            s = maj_slot[w_i[a], w_j[a]]
            if s < 0:
                maj_slot[w_i[a], w_j[a]] = n_maj
                maj_i[n_maj], maj_j[n_maj], maj_val[n_maj] = w_i[a], w_j[a], 0.0 + w_v[a]
                n_maj += 1
            else:
                maj_val[s] = maj_val[s] + w_v[a]
        n_t = n_w
    return n_maj


@jit
def dense_majorants(b_i, b_j, b_val, order, maj, reach):  # pragma: no cover
    """The majorant series on dense arrays (nufft._exp_series_2d_dense): maj (I, J) the sum
    of the terms T_k = T_{k-1} * B / k over k = 0..order (T_0 = 1 at (0, 0)), each term's
    element formed by adding, rest by rest in order, the previous term's element times
    (b_val[r] / k) (NumPy's shifted-slice sums: the same bits), and reach (I, J) the
    monomials the series forms; both written in place (zeroed here)."""
    n_i, n_j = maj.shape
    top_i, top_j = 0, 0
    for r in range(b_i.shape[0]):
        top_i = max(top_i, b_i[r])
        top_j = max(top_j, b_j[r])
    term = np.zeros((n_i, n_j))
    new = np.empty((n_i, n_j))
    prev = np.zeros((n_i, n_j), np.bool_)
    new_reach = np.empty((n_i, n_j), np.bool_)
    for a in range(n_i):
        for b in range(n_j):
            maj[a, b] = 0.0
            reach[a, b] = False
    term[0, 0] = 1.0
    maj[0, 0] = 1.0
    reach[0, 0] = True
    prev[0, 0] = True
    for k in range(1, order + 1):
        for a in range(n_i):
            for b in range(n_j):
                new[a, b] = 0.0
                new_reach[a, b] = False
        hi, hj = (k - 1) * top_i + 1, (k - 1) * top_j + 1
        for r in range(b_i.shape[0]):
            i, j = b_i[r], b_j[r]
            f = b_val[r] / k
            for a in range(hi):
                for b in range(hj):
                    new[i + a, j + b] = new[i + a, j + b] + term[a, b] * f
                    if prev[a, b]:
                        new_reach[i + a, j + b] = True
        for a in range(n_i):
            for b in range(n_j):
                term[a, b] = new[a, b]
                prev[a, b] = new_reach[a, b]
                maj[a, b] = maj[a, b] + new[a, b]
                if new_reach[a, b]:
                    reach[a, b] = True
