"""Receiver effects: IF filters, thermal noise, leakage, DC offset, gain, ADC.

Order of the chain (what a real receiver does): the scatterers' IF tones and
the Tx-Rx leakage tone pass the high-pass and anti-alias filters (applied as
the filters' steady-state response at each tone's beat frequency, exact for
a tone that lasts the whole chirp; the settling transient at the chirp start
is not modelled); receiver noise is added, shaped by the anti-alias filter
in the frequency domain (:func:`shape_noise`); everything is amplified
(:attr:`IFChain.voltage_gain`) to volts at the ADC input, the DC offset
is added and the ADC quantises and clips.

Units: the IF signal before the gain is in sqrt(W) (power at the receiver
input); after the gain in volts.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import signal

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.radar.config import IFChain, RadarConfig


def filter_response(frequency: np.ndarray | float, if_chain: IFChain) -> np.ndarray:
    """Complex response of the IF high-pass x anti-alias filters at ``frequency`` [Hz].

    Both are analog Butterworth filters with their -3 dB corner at the
    configured cut-off; a zero cut-off means no filter. For a complex
    (I/Q) receiver, a negative frequency sees the conjugate response, as
    identical real filters on I and Q give.

    Returns
    -------
    complex ndarray, shape of ``frequency``
    """
    f = np.asarray(frequency, dtype=float)
    h = np.ones(f.shape, dtype=complex)
    w = 2 * math.pi * np.abs(f)
    if if_chain.hp_cutoff > 0:
        b, a = signal.butter(if_chain.hp_order, 2 * math.pi * if_chain.hp_cutoff, "highpass",
                             analog=True)
        h = h * signal.freqs(b, a, worN=w.ravel())[1].reshape(f.shape)
    if if_chain.aaf_cutoff > 0:
        b, a = signal.butter(if_chain.aaf_order, 2 * math.pi * if_chain.aaf_cutoff, "lowpass",
                             analog=True)
        h = h * signal.freqs(b, a, worN=w.ravel())[1].reshape(f.shape)
    return np.where(f < 0, np.conj(h), h)


def beat_frequency(points: np.ndarray, velocities: np.ndarray | None, config: RadarConfig,
                   points_rx: np.ndarray | None = None,
                   velocities_rx: np.ndarray | None = None) -> np.ndarray:
    """(n,) beat frequency of each scatterer at the frame start [Hz].

    ``S (R_t + R_r) / c + (v_t + v_r) / lambda`` with R the leg lengths from
    the sensor origin and v the range rates (positive away) — the frequency
    at which the IF filters see the tone. Monostatic: R_t = R_r, v_t = v_r.
    """

    def leg(p, v):
        p = np.asarray(p, dtype=float)
        r = np.sqrt(np.einsum("ij,ij->i", p, p))
        if v is None:
            return r, np.zeros_like(r)
        with np.errstate(invalid="ignore", divide="ignore"):
            rate = np.einsum("ij,ij->i", p, np.asarray(v, float)) / r
        return r, np.nan_to_num(rate)

    r_t, v_t = leg(points, velocities)
    r_r, v_r = (r_t, v_t) if points_rx is None else leg(points_rx, velocities_rx)
    return (config.chirp.slope * (r_t + r_r) / SPEED_OF_LIGHT
            + (v_t + v_r) / config.chirp.wavelength)


def filtered_weights(amplitudes: np.ndarray, points: np.ndarray,
                     velocities: np.ndarray | None, config: RadarConfig,
                     points_rx: np.ndarray | None = None,
                     velocities_rx: np.ndarray | None = None) -> np.ndarray:
    """(n,) complex tone weights: peak amplitudes times the IF filter response at each beat."""
    ifc = config.if_chain
    if ifc.hp_cutoff <= 0 and ifc.aaf_cutoff <= 0:
        return np.asarray(amplitudes, dtype=complex)
    f = beat_frequency(points, velocities, config, points_rx, velocities_rx)
    return np.asarray(amplitudes, float) * filter_response(f, ifc)


def leakage(config: RadarConfig) -> np.ndarray:
    """Tx-Rx leakage tone at the receiver input, cube shape [sqrt(W)].

    Modelled as a static "scatterer" at path length ``IFChain.leakage_path``
    with received power ``P_tx * 10**(leakage_dbc / 10)``, filtered like any tone.
    Zeros if leakage is off.
    """
    ifc, c = config.if_chain, config.chirp
    shape = config.cube_shape
    if ifc.leakage_dbc is None:
        return np.zeros(shape, dtype=complex if ifc.complex_if else float)
    power = config.tx_power * 10 ** (ifc.leakage_dbc / 10)
    tau = ifc.leakage_path / SPEED_OF_LIGHT
    t = c.sample_times()
    phase = (2 * math.pi * c.start_frequency * tau + 2 * math.pi * c.slope * tau * t
             - math.pi * c.slope * tau**2)
    h = filter_response(c.slope * tau, ifc)
    tone = math.sqrt(2 * power) * h * np.exp(1j * phase)
    tone = tone if ifc.complex_if else tone.real
    return np.broadcast_to(tone, shape).copy()


def filter_cube(cube: np.ndarray, if_chain: IFChain, sample_rate: float) -> np.ndarray:
    """Apply the IF filters to a (.., sample) cube in the frequency domain (periodic per chirp).

    Used for the noise, whose spectrum is white: the filters shape its floor
    as they shape a real receiver's.
    """
    if if_chain.hp_cutoff <= 0 and if_chain.aaf_cutoff <= 0:
        return cube
    n = cube.shape[-1]
    if np.iscomplexobj(cube):
        h = filter_response(np.fft.fftfreq(n, 1 / sample_rate), if_chain)
        return np.fft.ifft(np.fft.fft(cube, axis=-1) * h, axis=-1)
    h = filter_response(np.fft.rfftfreq(n, 1 / sample_rate), if_chain)
    return np.fft.irfft(np.fft.rfft(cube, axis=-1) * h, n=n, axis=-1)


def shape_noise(noise: np.ndarray, config: RadarConfig) -> np.ndarray:
    """Shape white receiver noise by the anti-alias filter (not by the high-pass).

    The high-pass sits between mixer and IF amplifier; the noise that
    dominates after the gain is the amplifier's own, which only the
    anti-alias filter shapes. The BGT60TR13C recording shipped in twinsense.data
    shows exactly that: a flat floor down to the lowest bins, no dip below
    the 80 kHz high-pass corner, and a gentle roll-off towards fs/2.
    """
    ifc = config.if_chain
    if ifc.aaf_cutoff <= 0:
        return noise
    return filter_cube(noise, replace(ifc, hp_cutoff=0.0), config.chirp.sample_rate)


def noise_power(config: RadarConfig) -> float:
    """Receiver noise power per real IF sample (or of I and of Q) at the receiver input [W].

    The variance of :func:`thermal_noise` after :func:`shape_noise`, referred
    back through the voltage gain to the scale of the synthesised IF signal
    (sqrt(W)): ``noise_variance / gain^2`` times the mean of ``|H_aaf|^2``
    over the frequencies of a chirp's DFT bins (Parseval: the power of white
    noise filtered in the frequency domain, as :func:`shape_noise` does).
    """
    ifc = config.if_chain
    power = config.noise_variance() / ifc.voltage_gain**2
    if ifc.aaf_cutoff <= 0 or power == 0.0:
        return power
    n = config.chirp.num_samples
    h = filter_response(np.fft.fftfreq(n, 1.0 / config.chirp.sample_rate),
                        replace(ifc, hp_cutoff=0.0))
    return power * float(np.mean(np.abs(h) ** 2))


def thermal_noise(config: RadarConfig, rng: np.random.Generator) -> np.ndarray:
    """White receiver noise at the ADC input, cube shape [V] (before the IF filters).

    Each real sample (or I and Q each) has the variance
    :meth:`RadarConfig.noise_variance`: k T NF (fs/2) times the voltage gain
    squared, or the user's variance.
    """
    sigma = math.sqrt(config.noise_variance())
    shape = config.cube_shape
    if config.if_chain.complex_if:
        return sigma * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape))
    return sigma * rng.standard_normal(shape)


def adc(voltage: np.ndarray, if_chain: IFChain) -> np.ndarray:
    """Quantise and clip ADC-input voltages into codes.

    Real IF: unsigned codes 0 .. 2**bits - 1 around mid-scale 2**(bits-1)
    (the Infineon layout). Complex IF: signed two's-complement codes
    -2**(bits-1) .. 2**(bits-1) - 1 for I and Q (the TI layout).

    Returns
    -------
    uint16 (real IF, bits <= 16) / int32, or complex64 with integer parts (complex IF)
    """
    lsb = if_chain.lsb
    half = 2 ** (if_chain.adc_bits - 1)

    def q(x):
        return np.clip(np.round(x / lsb), -half, half - 1)

    if if_chain.complex_if:
        return (q(voltage.real) + 1j * q(voltage.imag)).astype(np.complex64)
    codes = q(voltage) + half
    return codes.astype(np.uint16 if if_chain.adc_bits <= 16 else np.uint32)


def codes_to_voltage(codes: np.ndarray, if_chain: IFChain) -> np.ndarray:
    """Inverse of :func:`adc` up to quantisation: volts at the ADC input (mid-scale removed)."""
    if if_chain.complex_if:
        return np.asarray(codes, dtype=complex) * if_chain.lsb
    return (np.asarray(codes, dtype=float) - 2 ** (if_chain.adc_bits - 1)) * if_chain.lsb
