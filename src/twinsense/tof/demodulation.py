"""Demodulation: phase, amplitude and distance from the correlation samples, and unwrapping.

With four samples D_i at phase offsets tau_i = i pi / 2 of a tap-cosine
amplitude a, ``D_0 - D_2 = 2 a cos(phi)`` and ``D_3 - D_1 = 2 a sin(phi)``,
so (Lange 2000; pmd Royale):

    phi = atan2(D_3 - D_1, D_0 - D_2) mod 2 pi,   d = c phi / (4 pi f),
    a = sqrt((D_0 - D_2)^2 + (D_3 - D_1)^2) / 2.

A single frequency measures distances modulo c / (2 f). Two frequencies
f_1 = k_1 g and f_2 = k_2 g (g = gcd) are unwrapped jointly to the range
c / (2 g) by testing the k_1 wrap counts of the first frequency against the
second (the pmd "phase unwrapping" of dual-frequency modes).
"""

from __future__ import annotations

import math

import numpy as np

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.tof.config import ToFConfig, _gcd_hz

TWO_PI = 2.0 * math.pi


def phase_amplitude(difference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Phase and amplitude from four-phase correlation samples.

    Parameters
    ----------
    difference : (F, 4, H, W) float
        Tap differences D_i (any unit: e- or DN), axis 1 = phase step i.

    Returns
    -------
    phase : (F, H, W) float32 in [0, 2 pi) [rad]
    amplitude : (F, H, W) float32, tap-cosine amplitude in the unit of ``difference``
    """
    i = (difference[:, 0] - difference[:, 2]).astype(np.float32, copy=False)
    q = (difference[:, 3] - difference[:, 1]).astype(np.float32, copy=False)
    phase = np.arctan2(q, i)
    phase[phase < 0] += np.float32(TWO_PI)
    # float32 rounding can turn -tiny + 2 pi into exactly 2 pi; keep [0, 2 pi).
    phase[phase >= np.float32(TWO_PI)] = 0.0
    amplitude = np.float32(0.5) * np.hypot(i, q)
    return phase, amplitude


def phase_to_distance(phase: np.ndarray, frequency: float) -> np.ndarray:
    """Wrapped radial distance c phi / (4 pi f) [m] for phase ``phase`` [rad] at ``frequency`` [Hz]."""
    return phase * np.float32(SPEED_OF_LIGHT / (2.0 * TWO_PI * frequency))


def unwrap_weights(frequencies: tuple[float, ...]) -> np.ndarray:
    """Weights (F,) of each frequency's distance in the combined estimate.

    The phase noise of every frequency is the same (same exposure, same
    amplitude), so the distance variance scales with 1/f^2 and the
    inverse-variance weights are proportional to f^2.
    """
    f = np.asarray(frequencies, dtype=float)
    return f ** 2 / np.sum(f ** 2)


def unwrap_two_frequencies(d1: np.ndarray, d2: np.ndarray, f1: float, f2: float) -> np.ndarray:
    """Joint unwrapping of two wrapped distances [m] to the range c / (2 gcd(f1, f2)).

    With f_i = k_i g and R = c / (2 g), the true distance is d = d1 + n1 R/k1
    = d2 + n2 R/k2, so m = k2 n1 - k1 n2 = round(k1 k2 (d2 - d1) / R) is an
    integer, and n1 follows from m by the Chinese remainder theorem
    (n1 = m k2^-1 mod k1). The two unwrapped distances are then averaged with
    :func:`unwrap_weights`. Rounding picks the right m while the distance
    errors stay below R / (2 k1 k2) (0.31 m for 80.32 + 60.24 MHz); the
    result equals testing all k1 wrap counts and keeping the most consistent.

    Parameters
    ----------
    d1, d2 : (...,) float
        Wrapped distances in [0, c/(2 f1)) and [0, c/(2 f2)) [m].

    Returns
    -------
    (...,) float32 in [0, c / (2 g)) [m].
    """
    g = _gcd_hz(f1, f2)
    k1, k2 = round(f1) // g, round(f2) // g
    rng = SPEED_OF_LIGHT / (2.0 * g)
    r1, r2 = np.float32(rng / k1), np.float32(rng / k2)
    w2 = np.float32(unwrap_weights((f1, f2))[1])
    d1 = np.asarray(d1, dtype=np.float32)
    d2 = np.asarray(d2, dtype=np.float32)
    m = np.rint((d2 - d1) * np.float32(k1 * k2 / rng))
    inv = pow(k2, -1, k1) if k1 > 1 else 0
    table = np.array([(r * inv) % k1 for r in range(k1)], dtype=np.float32)
    n1 = table[np.mod(m, k1).astype(np.intp)]
    n2 = (k2 * n1 - m) / np.float32(k1)
    x1 = d1 + n1 * r1
    x2 = d2 + n2 * r2
    # Weighted mean w1 x1 + w2 x2 = x1 + w2 (x2 - x1).
    d = x1 + w2 * (x2 - x1)
    return np.mod(d, np.float32(rng)).astype(np.float32)


def radial_distance(phase: np.ndarray, config: ToFConfig) -> np.ndarray:
    """Unwrapped radial distance (H, W) [m] from the per-frequency phases (F, H, W)."""
    f = config.modulation_frequencies
    if len(f) == 1:
        return phase_to_distance(phase[0], f[0])
    return unwrap_two_frequencies(phase_to_distance(phase[0], f[0]),
                                  phase_to_distance(phase[1], f[1]), f[0], f[1])


def depth_noise(amplitude_dn: np.ndarray, tap_sum_e: np.ndarray, config: ToFConfig) -> np.ndarray:
    """Per-pixel distance noise estimate [m] by error propagation (Lange 2000).

    sigma_D^2 = (S + 2 sigma_read^2) / e^2 + 1/12 (quantisation)  [DN^2],
    sigma_phi = sigma_D / (sqrt(2) a),   sigma_d,f = c sigma_phi / (4 pi f),
    combined over frequencies with :func:`unwrap_weights`.

    Parameters
    ----------
    amplitude_dn : (F, H, W) float
        Measured tap-cosine amplitudes [DN].
    tap_sum_e : (H, W) float
        Electrons of both taps (from the gray value) [e-].

    Returns
    -------
    (H, W) float32 [m]; inf where the amplitude is 0.
    """
    cfg = config
    e = cfg.electrons_per_dn
    var_d = (np.maximum(tap_sum_e, 0.0) + 2.0 * cfg.read_noise ** 2) / e ** 2
    if cfg.quantization:
        var_d = var_d + 1.0 / 12.0
    sigma_d = np.sqrt(var_d).astype(np.float32)
    f = cfg.modulation_frequencies
    w = unwrap_weights(f) if len(f) == 2 else np.ones(1)
    total = np.zeros(amplitude_dn.shape[1:], dtype=np.float32)
    with np.errstate(divide="ignore"):
        for k, fk in enumerate(f):
            sigma_phi = sigma_d / (np.float32(math.sqrt(2.0)) * amplitude_dn[k])
            sd = sigma_phi * np.float32(SPEED_OF_LIGHT / (2.0 * TWO_PI * fk))
            total += np.float32(w[k] ** 2) * sd * sd
    return np.sqrt(total)
