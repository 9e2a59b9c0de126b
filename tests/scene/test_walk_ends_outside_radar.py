"""A walker that stops, seen by an FMCW radar ahead of it: the torso's Doppler line falls to 0 m/s.

docs/people.md ("Paths, starts and stops"): the gait comes to rest at ``arrival_time`` and two closing
steps bring the person into the standing pose by ``stop_time``; the pelvis moves by centimetres in
them. Reference written out here: the trunk is the largest reflector, so the strongest line of the
range-summed Doppler spectrum is the torso's radial velocity (tests/radar/test_walker_micro_doppler.py);
while walking that is the thorax link's velocity towards the radar, and from the arrival on 0 m/s.
"""

import numpy as np
import pytest

from twinsense.radar import make_radar
from twinsense.radar.processing.fft import doppler_fft, range_fft, velocity_axis, velocity_resolution
from twinsense.scene import Mount, Pose, Scene
from twinsense.scene.human import Walk, add_person

N_CHIRPS = 64
T_CHIRP = 100e-6  # +-12.5 m/s unambiguous at 60 GHz, above the feet's speeds
N_FFT = 4 * N_CHIRPS  # bins of lambda / (2 N_FFT T) = 0.098 m/s


@pytest.fixture(scope="module")
def walker_and_radar():
    scene = Scene()
    # Towards a radar 6 m ahead at 1 m height along +x, 2.5 m from t = 0: arrival 2.40 s, standing from 3.20 s.
    body = add_person(scene, "walker", 1.75, (0.0, 0.0), 0.0, walk=Walk(1.4, path=((2.5, 0.0),), start_time=0.0))
    radar = make_radar("paper_bgt60tr13c", num_samples=64, num_chirps=N_CHIRPS, chirp_repetition_time=T_CHIRP,
                       ramp_end_time=40e-6, frame_rate=10.0, render_width=96, render_height=48, process=False,
                       mount=Mount(Pose.look_at((6.0, 0.0, 1.0), (0.0, 0.0, 1.0))))
    return scene, body, radar


def _peak(scene, radar, t):
    frame = radar.capture(scene, t, np.random.default_rng(7))
    cube = frame.adc.astype(float)
    r = range_fft(cube - cube.mean(axis=-1, keepdims=True))
    power = (np.abs(doppler_fft(r, n_fft=N_FFT, axis=-2)) ** 2).sum(axis=(0, 2))
    vel = velocity_axis(N_FFT, chirp_repetition_time=T_CHIRP, carrier_frequency=radar.config.chirp.centre_frequency)
    return float(vel[np.argmax(power)])


def test_the_torso_line_falls_to_zero_when_the_walker_stops(walker_and_radar):
    scene, body, radar = walker_and_radar
    person = body.joint_motion.person
    fc = radar.config.chirp.centre_frequency
    res = velocity_resolution(N_CHIRPS, chirp_repetition_time=T_CHIRP, carrier_frequency=fc)  # 0.39 m/s
    assert person.arrival_time == pytest.approx(2.40, abs=0.01)
    # Walking and slowing: the line is the thorax's velocity towards the radar (radar within 1 deg of
    # the walking direction), to one resolution cell (the trunk's links sway about it; measured within
    # 0.16 m/s at 1.2-2.2 s).
    for t in (1.2, 1.6, 2.0, 2.2):
        toward = -float(body.state(t).state("thorax").linear_velocity[0])
        assert _peak(scene, radar, t) == pytest.approx(toward, abs=res)
    # In the closing steps and standing: the pelvis moves by centimetres (under 0.1 m/s) and the stepping
    # foot is a small reflector, so the line stays in the bins about 0 (bins 0.098 m/s apart; bound one
    # and a half bins; measured 0 or one bin). Before the stop it was at -1.2 to -1.8 m/s.
    for t in (2.5, 2.7, 2.9, 3.1, 3.4):
        assert abs(_peak(scene, radar, t)) <= 0.15
