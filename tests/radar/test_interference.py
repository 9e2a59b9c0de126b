"""Interference from a second radar: burst duration and timing, Friis level, equal slopes, simulate()."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError
from twinsense.radar import (
    AntennaArray,
    ChirpConfig,
    ElementPattern,
    FMCWRadar,
    IFChain,
    NoiseConfig,
    RadarConfig,
    Scatterers,
)
from twinsense.radar.interference import Interferer
from twinsense.scene import Mount, Pose, Scene
from twinsense.simulate import simulate

FS, N, M = 2e6, 256, 2
T_REP, T_FRAME = 150e-6, 1e-3
S_V = 2e13  # victim slope [Hz/s]
B_IF = 500e3  # anti-alias corner [Hz]
F0 = 60e9
DIST = 3.0  # the radars face each other 3 m apart
TAU = DIST / SPEED_OF_LIGHT
PATTERN = ElementPattern(gain_dbi=6.0, cos_exponent_azimuth=1.0, cos_exponent_elevation=1.0)


def _config(f0, slope, complex_if=True, tx_power_dbm=10.0):
    chirp = ChirpConfig(f0, slope, FS, N, M, T_REP, T_FRAME)
    ant = AntennaArray(np.zeros((1, 3)), np.zeros((1, 3)), PATTERN, PATTERN)
    # An 8th-order low-pass: its -3 dB corner sits at B_IF exactly (Butterworth).
    ifc = IFChain(complex_if=complex_if, aaf_cutoff=B_IF, aaf_order=8, adc_bits=24, adc_full_scale=1e3)
    return RadarConfig(chirp, ant, ifc, NoiseConfig("none"), tx_power_dbm=tx_power_dbm)


FACING = Mount(Pose(np.array([0.0, 0.0, DIST]), np.diag([-1.0, 1.0, -1.0])))  # looks back along -z


def _pair(f0_i, s_i, time_offset=0.0, complex_if=True):
    other = FMCWRadar(_config(f0_i, s_i, complex_if), name="other", mount=FACING, process=False)
    victim = FMCWRadar(_config(F0, S_V, complex_if), name="victim", process=False,
                       interferers=[(other, time_offset)])
    return victim, other


def _nothing():
    return Scatterers.point_targets(np.zeros((0, 3)), np.zeros(0))


def _friis(f):
    """Peak IF amplitude sqrt(2 P_r) [sqrt(W)], P_r = P_t G_t G_r (lambda / (4 pi R))^2, boresight."""
    g = 10 ** (6.0 / 10)
    return np.sqrt(2 * 1e-2 * g * g) * (SPEED_OF_LIGHT / f) / (4 * math.pi * DIST)


def _crossing(f0_i, s_i, time_offset):
    """Time after the victim's ramp start where f_v(t) = f_i(t - tau - time_offset) [s]."""
    return -((F0 - f0_i) + s_i * (TAU + time_offset)) / (S_V - s_i)


@pytest.mark.parametrize(("time_offset", "frame_t"), [(0.0, 0.0), (5e-9, 0.0), (0.0, 7 * T_FRAME)])
def test_burst_lasts_2B_over_the_slope_difference_and_sits_at_the_crossing(time_offset, frame_t):
    # Slopes 2e13 and 1.998e13 Hz/s: the IF frequency f_v(t) - f_i(t - tau) sweeps
    # at dS = 2e10 Hz/s and the filter passes |f_IF| < B_IF for 2 B_IF / dS = 50 us
    # (100 samples), around f_IF = 0. dS << B_IF^2 = 2.5e11 (the quasi-static regime).
    s_i = S_V - 2e10
    t_x0 = 64e-6  # put the crossing mid-chirp for time_offset 0
    f0_i = F0 + (S_V - s_i) * t_x0 + s_i * TAU
    victim, _ = _pair(f0_i, s_i, time_offset)
    frame = victim.capture_scatterers(_nothing(), frame_t, np.random.default_rng(0))
    sig = frame.signal[0] / victim.config.if_chain.voltage_gain  # (chirps, N) [sqrt(W)]
    t_n = victim.config.chirp.sample_times()
    t_x = _crossing(f0_i, s_i, time_offset)
    if time_offset == 0:
        assert t_x == pytest.approx(t_x0, rel=1e-9, abs=0)
    # Normalise by the Friis amplitude at the interferer's instantaneous frequency
    # (lambda changes ~1 % across the burst): what is left is |H(f_IF(t))|.
    f_i = f0_i + s_i * (t_n - TAU - time_offset)
    for m in range(M):
        env = np.abs(sig[m]) / _friis(f_i)
        # Peak: the sample nearest the crossing has |f_IF| <= dS / (2 fs) = 5 kHz,
        # |H| = (1 + (5e3/5e5)^16)^-1/2 = 1 - 5e-33.
        assert env.max() == pytest.approx(1.0, rel=1e-9, abs=0)
        above = np.flatnonzero(env >= 2**-0.5)
        lo, hi = above[0], above[-1]
        assert np.all(env[lo:hi + 1] >= 2**-0.5)  # one burst
        # Edges by linear interpolation of the monotonic flanks: each lies between
        # the same two samples as the true crossing, so it is off by < 1 / fs.
        rise = t_n[lo - 1] + (2**-0.5 - env[lo - 1]) / (env[lo] - env[lo - 1]) / FS
        fall = t_n[hi] + (env[hi] - 2**-0.5) / (env[hi] - env[hi + 1]) / FS
        assert fall - rise == pytest.approx(2 * B_IF / 2e10, rel=0, abs=2 / FS)
        assert (rise + fall) / 2 == pytest.approx(t_x, rel=0, abs=1 / FS)
    # Outside the burst the 8th-order filter leaves less than |H(2 B_IF)| = 2^-8.
    assert np.all(env[(np.abs(t_n - t_x) > 2 * B_IF / 2e10)] < 2.0**-8)


def test_equal_slopes_give_a_tone_inside_the_band_and_nothing_outside():
    # Same slope: f_IF = (f0_v - f0_i) + S tau is constant, a tone of that
    # frequency with amplitude Friis x |H(f_IF)| while the interferer transmits.
    for offset, in_band in ((300e3, True), (2e6, False)):
        f0_i = F0 - offset + S_V * TAU
        victim, _ = _pair(f0_i, S_V)
        sig = victim.capture_scatterers(_nothing(), 0.0).signal[0] / victim.config.if_chain.voltage_gain
        t_n = victim.config.chirp.sample_times()
        h = 1 / math.sqrt(1 + (offset / B_IF) ** 16)
        f_i = f0_i + S_V * (t_n - TAU)
        # Both chirps start together, so the interferer is on over the whole window
        # except the first tau = 10 ns (before its ramp reaches the victim).
        np.testing.assert_allclose(np.abs(sig[:, 1:]), np.broadcast_to(_friis(f_i[1:]) * h, (M, N - 1)),
                                   rtol=1e-9, atol=0)
        if in_band:
            # The tone's frequency from its phase steps: 2 pi offset / fs per sample.
            # The ramp phases reach 2 pi f0 t ~ 5e7 rad, where doubles are 7.5e-9 rad
            # apart: the steps are good to ~1e-8 rad.
            step = np.angle(sig[:, 2:] * np.conj(sig[:, 1:-1]))
            np.testing.assert_allclose(step, 2 * math.pi * offset / FS, rtol=0, atol=1e-7)
        else:
            assert h < 2e-5  # 4 x the corner, 8th order: -96 dB


def test_real_if_sees_the_real_part_and_the_interferer_only_while_it_transmits():
    s_i = S_V - 2e10
    f0_i = F0 + 2e10 * 64e-6 + s_i * TAU
    real, _ = _pair(f0_i, s_i, complex_if=False)
    cplx, _ = _pair(f0_i, s_i)
    a = real.capture_scatterers(_nothing(), 0.0, np.random.default_rng(4)).signal
    b = cplx.capture_scatterers(_nothing(), 0.0, np.random.default_rng(4)).signal
    assert a.shape == b.shape and not np.iscomplexobj(a)
    # The interferer's random start phases follow the noise draws, which differ
    # in size, so the phases differ; the magnitude |Re z| <= |z| does not.
    assert np.all(np.abs(a) <= np.abs(b) * (1 + 1e-12))
    # An interferer that starts its frames half a frame later is silent during this frame.
    late, _ = _pair(f0_i, s_i, time_offset=T_FRAME / 2)
    assert not np.any(late.capture_scatterers(_nothing(), 0.0).signal)


def test_a_simulation_with_two_radars_uses_the_scene_poses():
    s_i = S_V - 2e10
    f0_i = F0 + 2e10 * 64e-6 + s_i * TAU
    victim, other = _pair(f0_i, s_i)
    victim.config = victim.config.with_overrides(render_width=8, render_height=4)
    other.config = other.config.with_overrides(render_width=8, render_height=4)
    res = simulate(Scene([]), [victim, other], 2.5e-3, seed=1)  # frames at 0 and 1 ms
    frames = res.frames["victim"]
    assert len(frames) == 2
    for fr in frames:
        env = np.abs(fr.signal[0]) / victim.config.if_chain.voltage_gain
        # At the crossing (sample 128, 64 us into each chirp) the filter passes
        # all (|H| = 1 - 5e-33 within 5 kHz of f_IF = 0): the Friis level at the
        # interferer's frequency there.
        t_c = 128 / FS
        assert np.all(env[:, 128] == pytest.approx(_friis(f0_i + s_i * (t_c - TAU)), rel=1e-9, abs=0))
    # The interferer's own frames see no interference.
    assert not np.any(res.frames["other"][0].signal)


def test_interferers_are_checked():
    radar = FMCWRadar(_config(F0, S_V), name="a")
    with pytest.raises(ConfigError, match=r"interferers\[0\]"):
        FMCWRadar(_config(F0, S_V), interferers=["b"])
    with pytest.raises(ConfigError, match="Interferer.time_offset"):
        FMCWRadar(_config(F0, S_V), interferers=[(radar, math.nan)])
    with pytest.raises(ConfigError, match="FMCWRadar.interferers"):
        FMCWRadar(_config(F0, S_V), interferers=5)
    with pytest.raises(ConfigError, match="Interferer.radar"):
        Interferer("radar")
    radar.interferers = radar._check_interferers([])
    with pytest.raises(ConfigError, match="itself"):
        radar._check_interferers([radar])
