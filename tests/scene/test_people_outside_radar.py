"""A walker seen by the TI IWR6843 radar preset at other speeds than the radar tests use.

References: the torso's radial speed, v cos(theta) (the radar 7.5 m ahead on the walking line at
1 m height, the torso 0.2-0.3 m above it at 4.5-7.5 m: theta < 4 deg, cos > 0.997) and Boulic's
cycle duration in closed form, D_c = 1.346 / sqrt(v / H_t), H_t = 0.530 H (Winter's hip
height), written out here, not taken from twinsense.scene.gait. The micro-Doppler signature
repeats every step, D_c / 2 (the legs are mirror images in radial velocity).
"""

import math

import numpy as np
import pytest

from twinsense.radar import make_radar
from twinsense.radar.processing.fft import doppler_fft, range_fft, velocity_axis, velocity_resolution
from twinsense.scene import Mount, Pose, Scene
from twinsense.scene.human import Walk, add_person

FPS = 20.0
N_FRAMES = 60  # 3 s: 4.6-5.9 steps at 1.0-1.6 m/s
T_CHIRP = 40e-6  # per chirp; TDM over 3 TX, so one TX every 120 us: +-10.2 m/s unambiguous at 61 GHz
N_TX = 3


def _spectrogram(speed, height=1.75):
    scene = Scene()
    # Walking along +x since t = -2 s (the start ramp is over) towards the radar 7.5 m ahead.
    add_person(scene, "walker", height, (0.0, 0.0), 0.0, walk=Walk(speed, heading_deg=0.0, start_time=-2.0))
    radar = make_radar("ti_iwr6843", num_samples=64, num_chirps=192, chirp_repetition_time=T_CHIRP,
                       ramp_end_time=30e-6, frame_rate=FPS, render_width=96, render_height=48, process=False,
                       mount=Mount(Pose.look_at((7.5, 0.0, 1.0), (0.0, 0.0, 1.0))))
    rng = np.random.default_rng(7)
    rows = []
    for k in range(N_FRAMES):
        cube = np.asarray(radar.capture(scene, k / FPS, rng).adc)[..., 0::N_TX, :]  # TX0's chirps
        r = range_fft(cube - cube.mean(axis=-1, keepdims=True), real_if=not np.iscomplexobj(cube))
        rd = doppler_fft(r, n_fft=256, axis=-2)
        rows.append((np.abs(rd) ** 2).sum(axis=(0, 2)))
    fc = radar.config.chirp.centre_frequency
    vel = velocity_axis(256, chirp_repetition_time=N_TX * T_CHIRP, carrier_frequency=fc)
    res = velocity_resolution(192 // N_TX, chirp_repetition_time=N_TX * T_CHIRP, carrier_frequency=fc)
    return np.array(rows), vel, res


@pytest.mark.parametrize("speed", [1.0, 1.6])
def test_torso_line_and_step_period(speed):
    power, vel, res = _spectrogram(speed)
    # The trunk is the largest reflector: the frame-averaged spectrum's strongest line is -v (approaching)
    # within one Doppler resolution cell lambda / (2 N T) = 0.32 m/s (measured -1.04 and -1.68 m/s).
    assert vel[np.argmax(power.mean(axis=0))] == pytest.approx(-speed, rel=0, abs=res)
    # The legs' band (2-5 m/s: the swinging shanks and feet, 2-4.8 v; the torso stays within +-22 % of v)
    # in dB, its slow trend (13-frame mean) removed: its autocorrelation over frames peaks at the step.
    band = (np.abs(vel) >= 2.0) & (np.abs(vel) <= 5.0)
    lp = 10 * np.log10(power[:, band].sum(axis=1))
    lp = (lp - np.convolve(lp, np.ones(13) / 13, mode="same"))[6:-6]
    s = lp - lp.mean()
    n = len(s)
    ac = np.array([np.sum(s[: n - lag] * s[lag:]) / (n - lag) for lag in range(n // 2)])
    step = 0.5 * 1.346 / math.sqrt(speed / (0.530 * 1.75))  # Boulic: 0.648 s at 1.0 m/s, 0.512 s at 1.6
    lags = np.arange(len(ac))
    search = (lags >= 0.5 * step * FPS) & (lags <= 1.5 * step * FPS)
    best = lags[search][np.argmax(ac[search])]
    # Within one frame (0.05 s) of the step (measured 0.650 s and 0.500 s).
    assert abs(best / FPS - step) <= 1.0 / FPS
