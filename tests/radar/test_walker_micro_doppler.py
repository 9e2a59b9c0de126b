"""A walking person seen by an FMCW radar: the torso's Doppler line and the limbs' gait periodicity."""

import numpy as np
import pytest

from twinsense.radar import make_radar
from twinsense.radar.processing.fft import doppler_fft, range_fft, velocity_axis, velocity_resolution
from twinsense.scene import Mount, Pose, Scene
from twinsense.scene.human import Walk, add_person

SPEED = 1.4
FPS = 20.0
N_FRAMES = 40  # 2 s
N_CHIRPS = 64
T_CHIRP = 100e-6  # 10 kHz slow-time rate: +-12.5 m/s unambiguous at 60 GHz, above the feet's ~5 m/s


@pytest.fixture(scope="module")
def spectrogram():
    """(frames, doppler bins) power of the range-summed range-Doppler maps, its velocity axis, the walker."""
    scene = Scene()
    # Walking along +x since t = -2 s (the start blend is over), towards a radar 6 m ahead at 1 m height.
    body = add_person(scene, "walker", 1.75, (0.0, 0.0), 0.0, walk=Walk(SPEED, heading_deg=0.0, start_time=-2.0))
    radar = make_radar("paper_bgt60tr13c", num_samples=64, num_chirps=N_CHIRPS, chirp_repetition_time=T_CHIRP,
                       ramp_end_time=40e-6, frame_rate=FPS, render_width=96, render_height=48, process=False,
                       mount=Mount(Pose.look_at((6.0, 0.0, 1.0), (0.0, 0.0, 1.0))))
    rng = np.random.default_rng(7)
    rows = []
    for k in range(N_FRAMES):
        frame = radar.capture(scene, k / FPS, rng)
        cube = frame.adc.astype(float)
        r = range_fft(cube - cube.mean(axis=-1, keepdims=True))
        rd = doppler_fft(r, n_fft=4 * N_CHIRPS, axis=-2)
        rows.append((np.abs(rd) ** 2).sum(axis=(0, 2)))
    fc = radar.config.chirp.centre_frequency
    vel = velocity_axis(4 * N_CHIRPS, chirp_repetition_time=T_CHIRP, carrier_frequency=fc)
    res = velocity_resolution(N_CHIRPS, chirp_repetition_time=T_CHIRP, carrier_frequency=fc)
    return np.array(rows), vel, res, body


def test_torso_line_is_the_walking_speed(spectrogram):
    power, vel, res, _ = spectrogram
    # The trunk is the largest reflector: the strongest line of the frame-averaged spectrum is the
    # walker's radial velocity, -v (approaching; the radar at 4-6 m and 0.2 m below the torso sees
    # it within 1 deg of the walking direction, cos = 0.9998). Within one Doppler resolution cell
    # lambda / (2 N T) = 0.41 m/s: the torso itself sways by +-0.2 m/s about v within a step.
    v_peak = vel[np.argmax(power.mean(axis=0))]
    assert v_peak == pytest.approx(-SPEED, rel=0, abs=res)  # measured -1.43 m/s


def test_limb_envelope_repeats_every_step(spectrogram):
    power, vel, _, body = spectrogram
    rel_db = 10 * np.log10(power / power.max(axis=1, keepdims=True))
    # Doppler extent of each frame: the fastest velocity within 20 dB of the frame's peak (the
    # swinging foot and shank, up to ~4 v): the feet are in the picture.
    extent = np.array([np.max(np.abs(vel[row > -20])) for row in rel_db])
    assert np.median(extent) > 1.4 * SPEED
    assert extent.max() > 2.5 * SPEED
    # The micro-Doppler signature repeats once per step, D_c / 2 (each leg swings once per cycle and
    # the legs are mirror images in radial velocity; D_c = 1.346 / sqrt(RV) = 1.096 s at 1.4 m/s):
    # 0.548 s = 11.0 frames at 20 fps. The autocorrelation over frames of the whole spectrum (dB,
    # clipped 30 dB below each frame's peak, each Doppler bin's mean removed) peaks there.
    s = np.maximum(rel_db, -30.0)
    s = s - s.mean(axis=0)
    n = len(s)
    ac = np.array([np.sum(s[: n - lag] * s[lag:]) / (n - lag) for lag in range(n // 2)])
    step = body.joint_motion.person.cycle.timing.cycle_duration / 2
    lags = np.arange(len(ac))
    search = (lags >= 5) & (lags <= 16)  # between half a step and 1.5 steps
    best = lags[search][np.argmax(ac[search])]
    # Sub-frame peak: the vertex of the parabola through the peak and its neighbours.
    y0, y1, y2 = ac[best - 1], ac[best], ac[best + 1]
    peak = best + 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)
    # Within one frame (0.05 s) of the step period (measured 10.7 frames = 0.534 s).
    assert abs(peak / FPS - step) <= 1.0 / FPS
