"""Compiled per-mover kernel of the fast IF synthesis (numba).

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
(``tests/radar/test_synthesis_kernels.py``). The static scatterers stay
NumPy: their few long passes over contiguous arrays run faster vectorised.
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
