"""Pulse-echo signal of a resonant ultrasonic transducer: burst, band-pass, ring-down, A-scan, detection.

The transducer is a resonator of quality factor Q at f0 (a piezo disk on a
membrane behaves as one near its series resonance), passed twice by an echo
(transmit and receive). A narrow-band signal through a resonator keeps its
carrier and low-pass filters its complex envelope with the time constant
tau = Q / (pi f0) (the resonator's -3 dB half-bandwidth f0 / (2Q)), so an
N-cycle burst of length T = N / f0 returns with the envelope of a rectangle
through two one-pole low-passes:

    e2(t) = g(t) - g(t - T),  g(t) = 1 - exp(-t/tau) (1 + t/tau)  (t > 0, else 0),

normalised to 1 for a long burst. The transmitter's own ringing (the
membrane keeps vibrating after the drive stops, and the receive amplifier
sees it) passes the resonator once: g1(t) = 1 - exp(-t/tau); it decays as
exp(-(t - T)/tau) after the burst and blinds the receiver until it falls
below the detection threshold: the minimum range.

The A-scan is the receiver's output in equivalent sound pressure [Pa]:
sum over echoes of p_e e2(t - t_e) cos(2 pi f0 (t - t_e)), plus the ring-down,
plus Gaussian noise filtered by the same resonator. Its envelope is the
magnitude of the analytic signal; the first echo is the first upward
crossing of a range-dependent threshold after the ring-down has fallen
below it (sensors such as the TI PGA460 store such a threshold map).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.signal import hilbert, iirpeak, lfilter


def time_constant(frequency: float, q_factor: float) -> float:
    """Envelope time constant tau = Q / (pi f0) [s] of a resonator at ``frequency`` [Hz]."""
    return q_factor / (math.pi * frequency)


def echo_envelope(t, burst_duration: float, tau: float) -> np.ndarray:
    """Envelope e2(t) of a rectangular burst through two resonators (peak 1 for a long burst), t [s]."""
    t = np.asarray(t, float)

    def g(x):
        xp = np.maximum(x, 0.0) / tau
        return np.where(x > 0, 1.0 - np.exp(-xp) * (1.0 + xp), 0.0)

    return g(t) - g(t - burst_duration)


def ring_envelope(t, burst_duration: float, tau: float) -> np.ndarray:
    """Envelope of the transmitter's ringing through one resonator, 1 at the end of the burst, t [s]."""
    t = np.asarray(t, float)

    def g(x):
        return np.where(x > 0, 1.0 - np.exp(-np.maximum(x, 0.0) / tau), 0.0)

    return (g(t) - g(t - burst_duration)) / (1.0 - math.exp(-burst_duration / tau))


def envelope_support(burst_duration: float, tau: float) -> float:
    """Length [s] after which e2 is below 1e-4 of its peak: T + 12 tau (exp(-12) (1 + 12) = 8e-5)."""
    return burst_duration + 12.0 * tau


def synthesize(n_samples: int, sample_rate: float, frequency: float, burst_duration: float, tau: float,
               delays, amplitudes) -> np.ndarray:
    """Noise-free echo signal (n_samples,) [Pa]: sum of a e2(t - d) cos(2 pi f0 (t - d)) over echoes.

    ``delays`` (e,) [s] from the start of the window (negative: an echo that
    began before the window), ``amplitudes`` (e,) [Pa]. Exact (no truncated
    tail), in O(n_samples + e) whatever the number of echoes.

    Why it is linear in both: with x = t - d, an echo is Re(A e^{j w t} (g(x) - g(x - T)))
    with A = a e^{-j w d}, and g(x) = 1 - e^{-x/tau} (1 + x/tau) for x > 0. Each of
    its two onsets (at d with A, at d + T with -A) adds A to a running sum S, A e^{-x/tau}
    to a decaying state E and A (x/tau) e^{-x/tau} to a second state F, at its first sample;
    from one sample to the next E' = rho E and F' = rho (F + delta E) with rho =
    e^{-delta}, delta = 1 / (f_s tau) (x grows by 1 / f_s). The envelope phasor is then
    S - E - F at every sample, for every echo at once (two first-order recursions).
    """
    d = np.asarray(delays, float).reshape(-1)
    a = np.asarray(amplitudes, float).reshape(-1)
    out = np.zeros(n_samples)
    if len(d) == 0 or n_samples == 0:
        return out
    w = 2 * math.pi * frequency
    onset = np.concatenate([d, d + burst_duration])
    amp = np.concatenate([a, -a]) * np.exp(-1j * w * np.concatenate([d, d]))
    # First sample at or after each onset (before the window: sample 0); g(0) = 0, so an
    # onset on a sample may take it or the next.
    k = np.maximum(np.ceil(onset * sample_rate), 0.0)
    live = k < n_samples
    k, onset, amp = k[live].astype(np.int64), onset[live], amp[live]
    x = (k / sample_rate - onset) / tau  # [1] >= 0
    ex = np.exp(-x)

    def per_sample(values):
        return (np.bincount(k, values.real, n_samples) + 1j * np.bincount(k, values.imag, n_samples))

    delta = 1.0 / (sample_rate * tau)
    rho = math.exp(-delta)
    s = np.cumsum(per_sample(amp))
    e = lfilter([1.0], [1.0, -rho], per_sample(amp * ex))
    f_in = per_sample(amp * x * ex)
    f_in[1:] += rho * delta * e[:-1]
    f = lfilter([1.0], [1.0, -rho], f_in)
    carrier = np.exp(1j * w * (np.arange(n_samples) / sample_rate))
    return (carrier * (s - e - f)).real


def ringdown(n_samples: int, sample_rate: float, frequency: float, burst_duration: float, tau: float,
             level: float) -> np.ndarray:
    """The transmitter's ringing as the receiver sees it (n_samples,) [Pa], ``level`` at the burst's end."""
    t = np.arange(n_samples) / sample_rate
    return level * ring_envelope(t, burst_duration, tau) * np.cos(2 * math.pi * frequency * t)


@functools.lru_cache(maxsize=32)
def _noise_filter(frequency: float, q_factor: float, sample_rate: float):
    b, a = iirpeak(frequency, q_factor, fs=sample_rate)
    # Output rms of unit white noise = sqrt(sum h^2) (Parseval); h decays as exp(-n / (tau fs)).
    n = int(40 * q_factor * sample_rate / (math.pi * frequency)) + 64
    imp = np.zeros(n)
    imp[0] = 1.0
    h = lfilter(b, a, imp)
    return b, a, float(np.sqrt(np.sum(h * h)))


def band_noise(shape: tuple[int, int], sample_rate: float, frequency: float, q_factor: float, rms: float,
               rng: np.random.Generator) -> np.ndarray:
    """Gaussian noise of ``rms`` [Pa] in the transducer's band (the receive resonator), shape (rows, samples)."""
    b, a, gain = _noise_filter(float(frequency), float(q_factor), float(sample_rate))
    # Start the filter in its stationary state: run it over a lead-in that is then dropped.
    lead = int(10 * q_factor * sample_rate / (math.pi * frequency)) + 1
    white = rng.standard_normal((shape[0], shape[1] + lead)) * (rms / gain)
    return lfilter(b, a, white, axis=-1)[:, lead:]


def envelope(signal: np.ndarray) -> np.ndarray:
    """Envelope |analytic signal| along the last axis (exact for a narrow-band signal)."""
    return np.abs(hilbert(signal, axis=-1))


def threshold_curve(n_samples: int, sample_rate: float, c: float, points) -> np.ndarray:
    """Detection threshold (n_samples,) [Pa] of a threshold map ``points`` ((range [m], level [Pa]), ...).

    Piecewise linear in range r = c t / 2, constant beyond the first and last points.
    """
    r = 0.5 * c * np.arange(n_samples) / sample_rate
    pts = np.asarray(points, float)
    return np.interp(r, pts[:, 0], pts[:, 1])


def first_crossing(env: np.ndarray, threshold: np.ndarray, sample_rate: float, start: int = 0) -> np.ndarray:
    """Time [s] of the first echo in each row of ``env`` (rows, samples); NaN where none.

    The first upward crossing of ``threshold`` (samples,) after the envelope
    has been below it at or after sample ``start`` (the end of the burst:
    the ring-down, above the threshold until then, is not an echo), linearly
    interpolated between the two samples around it.
    """
    env = np.atleast_2d(env)
    above = env >= threshold
    above[:, :start] = True
    out = np.full(len(env), np.nan)
    for i, row in enumerate(above):
        below = np.flatnonzero(~row)
        if len(below) == 0:
            continue
        rise = np.flatnonzero(row[below[0]:])
        if len(rise) == 0:
            continue
        j = below[0] + rise[0]  # first sample at or above, j - 1 below
        e0, e1 = env[i, j - 1] - threshold[j - 1], env[i, j] - threshold[j]
        frac = -e0 / (e1 - e0) if e1 != e0 else 0.0
        out[i] = (j - 1 + frac) / sample_rate
    return out


def blanking_time(burst_duration: float, tau: float, ring_level: float, threshold_at) -> float:
    """Time [s] after firing at which the ring-down falls below the threshold (no noise).

    After the burst the ring is ``ring_level`` exp(-(t - T)/tau): with a
    threshold ``threshold_at(t)`` it crosses at the root of
    ring_level exp(-(t - T)/tau) = threshold_at(t), found here by bisection
    (a constant threshold L gives t = T + tau ln(ring_level / L)).
    """
    def f(t):
        return ring_level * math.exp(-(t - burst_duration) / tau) - threshold_at(t)

    lo, hi = burst_duration, burst_duration + 200 * tau
    if f(lo) <= 0:
        return lo
    if f(hi) > 0:
        return hi
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)
