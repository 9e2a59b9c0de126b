"""Interference from other FMCW radars in the scene (direct, one-way path).

An interfering radar's chirps reach each victim receiver directly after the
one-way delay ``tau = |rx_victim - tx_interferer| / c``. Mixed with the
victim's LO, its IF phase is the victim's ramp phase minus the interferer's
(the same convention as the echoes, PHYSICS.md section 2):

    phi_IF(t) = Phi_v(t) - Phi_i(t - tau) - psi,
    f_IF(t)   = f_v(t) - f_i(t - tau),

with ``Phi(u) = 2 pi (f0 u + S u^2 / 2)`` from each radar's ramp start and a
random start phase ``psi`` per interfering chirp (the two oscillators are not
locked). For slopes S_v != S_i the IF frequency sweeps at ``S_v - S_i``: the
victim's IF filters pass it only while ``|f_IF| < B_IF``, a burst of

    2 B_IF / |S_v - S_i|

centred where the two ramps cross (``f_IF = 0``). Equal slopes give a
constant offset: a tone if it lies in the IF band, nothing otherwise.

Amplitude: Friis, one way, ``P_r = P_t G_t G_r (lambda / (4 pi R))^2`` with
the interferer's transmit pattern towards the victim's receiver and the
victim's receive pattern towards the interferer (both in their own sensor
frames), lambda at the interferer's instantaneous frequency, and the peak
IF amplitude ``sqrt(2 P_r)`` [sqrt(W)] as for the echoes.

IF filters: the quasi-static (instantaneous-frequency) response
``H(f_IF(t))`` of the victim's high-pass and anti-alias filters
(:func:`twinsense.radar.effects.filter_response`); a receiver without an
anti-alias filter passes its Nyquist band ``|f_IF| < fs / 2`` and nothing
else. The quasi-static response is exact for a tone and holds for a sweep
while the burst lasts many filter time constants, ``|S_v - S_i| << B_IF^2``;
for faster sweeps the burst energy ``int |H|^2 df / |S_v - S_i|`` is still
right, but a real filter stretches the burst to about its impulse response
(~1 / B_IF).

Timing: the interferer sends frames of its own chirp config starting at
``time_offset + k T_frame`` for every integer k (all time, not only the
frames a simulation records), each chirp transmitting during its ramp
(``0 <= u <= ramp_end_time``) and silent between ramps. Poses are those at
the victim's frame start (motion within a frame is not modelled: the
interference is incoherent from chirp to chirp anyway).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from twinsense import validation as V
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError
from twinsense.radar.config import RadarConfig
from twinsense.radar.effects import filter_response
from twinsense.scene import Pose

__all__ = ["Interferer", "interference"]

_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, eq=False)
class Interferer:
    """Another radar whose chirps reach this one.

    Attributes
    ----------
    radar : FMCWRadar
        The interfering radar (its config gives chirps, power and antennas; its
        mount gives its pose, so it can sit on a moving object of the scene).
        Usually another sensor of the same simulation.
    time_offset : float
        Start of the interferer's frame 0 on the simulation clock [s]; its frames
        start at ``time_offset + k * frame_repetition_time``.
    """

    radar: Any
    time_offset: float = 0.0

    def __post_init__(self) -> None:
        cfg = getattr(self.radar, "config", None)
        if not isinstance(cfg, RadarConfig) or not hasattr(self.radar, "mount"):
            raise ConfigError("Interferer.radar", self.radar, "an FMCWRadar")
        object.__setattr__(self, "time_offset",
                           V.number("Interferer.time_offset", self.time_offset, lo=-1e9, hi=1e9,
                                    unit="s"))


def interference(config: RadarConfig, pose: Pose, t: float, source: RadarConfig, source_pose: Pose,
                 time_offset: float, rng: np.random.Generator) -> np.ndarray:
    """IF signal one interfering radar causes in a victim's frame, (rx, chirp, sample) complex.

    Parameters
    ----------
    config, pose : RadarConfig, Pose
        The victim and its sensor -> world pose.
    t : float
        Start of the victim's frame [s].
    source, source_pose : RadarConfig, Pose
        The interferer and its pose.
    time_offset : float
        Start of the interferer's frame 0 [s].
    rng : numpy.random.Generator
        Draws the start phase of each interfering chirp.

    Returns
    -------
    (n_rx, n_chirps, n_samples) complex128
        Analytic IF signal at the victim's receiver input after its IF filters
        [sqrt(W)]; the real-IF signal is its real part.
    """
    cv, ci = config.chirp, source.chirp
    ant_v, ant_i = config.antennas, source.antennas
    rx_w = ant_v.rx_positions @ pose.rotation.T + pose.position  # (n_rx, 3)
    tx_w = ant_i.tx_positions @ source_pose.rotation.T + source_pose.position  # (n_tx_i, 3)
    link = rx_w[:, None, :] - tx_w[None, :, :]  # (n_rx, n_tx_i, 3), interferer -> victim
    dist = np.linalg.norm(link, axis=-1)
    if np.any(dist <= 0):
        raise ConfigError("Interferer.radar", "a radar at the victim's antennas",
                          "an interferer whose transmitters are apart from the victim's receivers")
    delay = dist / SPEED_OF_LIGHT
    flat = link.reshape(-1, 3)
    # Each radar's pattern in its own sensor frame.
    g_t = ant_i.tx_pattern.gain(flat @ source_pose.rotation).reshape(dist.shape)
    g_r = ant_v.rx_pattern.gain(-flat @ pose.rotation).reshape(dist.shape)
    power_gain = source.tx_power * g_t * g_r / (4 * math.pi * dist) ** 2  # times lambda^2 below

    t_n = cv.sample_times()  # (N,) from the victim's ramp start
    slow = cv.chirp_times()  # (M,)
    # Time since the start of the interferer's frame that holds the victim's frame start,
    # reduced once in Python floats (t may be large; the rest stays small and exact).
    base = math.fmod(t - time_offset, ci.frame_repetition_time)
    if base < 0:
        base += ci.frame_repetition_time
    n_rx = ant_v.num_rx
    local0 = base + slow[:, None] + t_n[None, :]  # (M, N) before the path delay
    # The transmitter of an interfering chirp depends on the chirp index; the
    # delays of its transmitters differ by picoseconds, so the index is found
    # with the mean delay of each receiver.
    tau_mean = delay.mean(axis=1)
    out = np.zeros(config.cube_shape, dtype=complex)
    seq = np.asarray(ant_i.tx_sequence)
    idx_rows = []
    for a in range(n_rx):
        local = local0 - tau_mean[a]
        frame = np.floor(local / ci.frame_repetition_time)
        local = local - frame * ci.frame_repetition_time
        chirp = np.floor(local / ci.chirp_repetition_time)
        idx_rows.append((frame, chirp))
    # One random start phase per interfering chirp, shared by every receiver.
    keys = np.stack([f * ci.num_chirps + m for f, m in idx_rows])
    uniq, inverse = np.unique(keys, return_inverse=True)
    psi = rng.uniform(0.0, _TWO_PI, len(uniq))[inverse].reshape(keys.shape)
    phi_v = _TWO_PI * (cv.start_frequency * t_n + 0.5 * cv.slope * t_n**2)  # (N,)
    f_v = cv.start_frequency + cv.slope * t_n
    for a in range(n_rx):
        frame, chirp = idx_rows[a]
        k = seq[(chirp.astype(np.int64) % len(seq))]  # (M, N) transmitter index
        tau = delay[a][k]
        u = local0 - tau - frame * ci.frame_repetition_time - chirp * ci.chirp_repetition_time
        on = (chirp >= 0) & (chirp < ci.num_chirps) & (u >= 0) & (u <= ci.ramp_end_time)
        f_i = ci.start_frequency + ci.slope * u
        phi_i = _TWO_PI * (ci.start_frequency * u + 0.5 * ci.slope * u * u) + psi[a]
        f_if = f_v[None, :] - f_i
        lam = SPEED_OF_LIGHT / f_i
        amp = np.sqrt(2.0 * power_gain[a][k]) * lam
        h = _if_response(f_if, config)
        out[a] = np.where(on, amp * h * np.exp(1j * (phi_v[None, :] - phi_i)), 0.0)
    return out


def _if_response(f: np.ndarray, config: RadarConfig) -> np.ndarray:
    """Quasi-static IF filter response at instantaneous frequencies ``f`` [Hz]."""
    ifc = config.if_chain
    h = filter_response(f, ifc)
    if ifc.aaf_cutoff <= 0:
        h = np.where(np.abs(f) < config.chirp.sample_rate / 2, h, 0.0)
    return h
