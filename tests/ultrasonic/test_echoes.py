"""Echo model and detection against closed forms: time of flight, directivity, 1/(2R) and 1/R^2, cross-talk."""

import math

import numpy as np
import pytest

from twinsense import Mount, Plane, Pose, Scene, Sphere
from twinsense.ultrasonic import UltrasonicSensor, ring_poses
from twinsense.ultrasonic.acoustics import piston_directivity
from twinsense.ultrasonic.reflectors import fresnel_factor
from twinsense.ultrasonic.sensor import _STANDOFF
from twinsense.ultrasonic.signal import echo_envelope

EYE = np.array([0.0, 0.0, 1.0])


def wall_scene(distance, size=100.0):
    s = Scene()
    s.add_object("wall", Plane((size, size)), "drywall", pose=Pose.from_euler_deg((distance, 0, 1.0), (0, -90, 0)))
    return s


def sensor(preset="open_40khz", yaw_deg=0.0, **over):
    target = EYE + np.array([math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg)), 0.0])
    return UltrasonicSensor.preset(preset, mount=Mount(Pose.look_at(EYE, target)), **over)


def absorption(cfg, path):
    return 10.0 ** (-cfg.absorption_db_per_m * path / 20.0)


@pytest.mark.parametrize("distance", [0.8, 1.6, 3.2])
def test_plane_is_an_image_source(distance):
    # A plane at R returns p0 / (2R): the image source at 2R. The transducer
    # face sits _STANDOFF in front of the mount. The 100 m wall's edges add
    # Fresnel ripple of at most 1 / (pi u) per edge, u = 50 m sqrt(2 k / (pi R)).
    sen = sensor()
    cfg = sen.config
    delays, amps = sen.echoes(wall_scene(distance), 0.0)[0]
    r = distance - _STANDOFF
    assert len(amps) == 1
    u = 50.0 * math.sqrt(2 * cfg.wavenumber / (math.pi * r))
    want = cfg.source_pressure / (2 * r) * absorption(cfg, 2 * r)
    assert amps[0] == pytest.approx(want, rel=4 / (math.pi * u), abs=0)
    assert delays[0] == pytest.approx(2 * r / cfg.speed_of_sound, rel=1e-12, abs=0)


def test_small_sphere_follows_inverse_square():
    # A sphere of radius a returns p0 a / (2 r^2) for r >> a (sigma = pi a^2);
    # the physical-optics form is p0 a / ((a + r) 2 r), within a / r of it.
    a = 0.02
    sen = sensor()
    cfg = sen.config
    for r in (1.0, 2.0, 3.0):
        s = Scene()
        s.add_object("ball", Sphere(a, subdivisions=3), "metal", pose=Pose(EYE + np.array([r + a, 0.0, 0.0])))
        _, amps = sen.echoes(s, 0.0)[0]
        rr = r - _STANDOFF
        p = amps[0] / absorption(cfg, 2 * rr)
        assert p * 2 * rr**2 / (a * cfg.source_pressure) == pytest.approx(1.0, rel=a / rr + 1e-9, abs=0)


def test_directivity_of_the_echo():
    # A sphere off the boresight by theta: the echo falls as D(theta)^2 (transmit
    # and receive), D = 2 J1(k a sin theta) / (k a sin theta). The angle is taken
    # from the transducer face (2 mm ahead of the mount point, so it turns with
    # the sensor) to the ball; the face's range to the ball changes by
    # 2 mm (1 - cos theta) <= 0.8 mm, the amplitude by <= 2 x 0.8 mm / 1.5 m = 1.1e-3.
    ball = EYE + np.array([1.55, 0.0, 0.0])
    s = Scene()
    s.add_object("ball", Sphere(0.05, subdivisions=3), "metal", pose=Pose(ball))
    cfg = sensor().config

    def range_law(r):
        return 0.05 / ((0.05 + r) * 2 * r) * absorption(cfg, 2 * r)

    ref = sensor().echoes(s, 0.0)[0][1][0] / range_law(1.55 - 0.05 - _STANDOFF)
    for theta in (10.0, 20.0, 30.0, 40.0, 50.0):
        sen = sensor(yaw_deg=theta)
        pose = sen.transducer_poses(None, 0.0)[0]
        face = pose.position + _STANDOFF * pose.rotation[:, 2]
        r = np.linalg.norm(ball - face)
        local = pose.rotation.T @ (ball - face) / r
        d = float(piston_directivity(local[0], local[1], sen.config.ka[0]))
        got = sen.echoes(s, 0.0)[0][1][0] / range_law(r - 0.05)
        assert got / ref == pytest.approx(d * d, rel=1e-9, abs=0)


def crossing_time(amp, thr, tau, burst, t0):
    """Time where amp * e2(t - t0) first reaches thr (bisection on the rising edge)."""
    lo, hi = t0, t0 + burst
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if amp * echo_envelope(mid - t0, burst, tau) < thr else (lo, mid)
    return 0.5 * (lo + hi)


@pytest.mark.parametrize("temp", [0.0, 30.0])
def test_first_echo_time_of_flight(temp):
    # The first echo crosses a flat threshold L at t = 2R/c(T) + t_rise, with
    # amp * e2(t_rise) = L from the closed-form envelope. Linear interpolation
    # between samples of the smooth rising edge is within one sample: the
    # distance c t / 2 is within c / (2 fs) = 0.43 mm of the prediction.
    sen = sensor(temperature_c=temp, noise_pa=0.0, threshold=((0.0, 0.05),))
    cfg = sen.config
    R = 1.5
    frame = sen.capture(wall_scene(R), 0.0, np.random.default_rng(0))
    _, amps = sen.echoes(wall_scene(R), 0.0)[0]
    r = R - _STANDOFF
    t_pred = crossing_time(amps[0], 0.05, cfg.tau, cfg.burst_duration, 2 * r / cfg.speed_of_sound)
    c = cfg.speed_of_sound
    assert frame.first_echo_distance[0] == pytest.approx(0.5 * c * t_pred, abs=c / (2 * cfg.sample_rate))
    # And the time of flight itself is 2 R / c(T): the rise time does not depend on T.
    t_rise = t_pred - 2 * r / c
    assert 2 * frame.first_echo_distance[0] / c - t_rise == pytest.approx(2 * r / c, abs=1 / cfg.sample_rate)


def test_ring_down_sets_the_minimum_range():
    # A wall inside the blanked range is masked by the ringing; one beyond it is
    # reported. Constant threshold L: blanking at T + tau ln(ring / L).
    sen = sensor(noise_pa=0.0, threshold=((0.0, 0.02),))
    cfg = sen.config
    t_b = cfg.burst_duration + cfg.tau * math.log(cfg.ringdown_pa / 0.02)
    assert cfg.min_range == pytest.approx(0.5 * cfg.speed_of_sound * t_b, rel=1e-9, abs=0)
    near = sen.capture(wall_scene(0.6 * cfg.min_range, size=0.02), 0.0, np.random.default_rng(0))
    assert np.isnan(near.first_echo_distance[0]) or near.first_echo_distance[0] > cfg.min_range
    far = sen.capture(wall_scene(2.0 * cfg.min_range), 0.0, np.random.default_rng(0))
    assert far.first_echo_distance[0] == pytest.approx(2.0 * cfg.min_range, abs=0.02)


def test_cross_talk_arrives_on_the_bistatic_path():
    # Two transducers 0.2 m apart, both facing a wall 3 m away, fired 10 ms
    # apart. Transducer 1 hears transducer 0's echo over the bistatic path
    # whose length is |T1 - image(T0)| (mirror in the wall), 10 ms later than
    # transducer 0 fired: delay = L / c - dt, exact.
    poses = (Pose((-0.1, 0.0, 0.0)), Pose((0.1, 0.0, 0.0)))
    sen = sensor(transducers=poses, frame_rate=50.0, max_range=1.7, noise_pa=0.0)
    cfg = sen.config
    dt = cfg.firing_interval
    assert dt == pytest.approx(0.01, rel=1e-12, abs=0)
    wall_x = 3.0
    world = [sen.transducer_poses(None, 0.0)[i] for i in range(2)]
    t0, t1 = (p.position + _STANDOFF * p.rotation[:, 2] for p in world)
    image = t0.copy()
    image[0] = 2 * wall_x - t0[0]
    want = np.linalg.norm(t1 - image) / cfg.speed_of_sound - dt
    delays, _ = sen.echoes(wall_scene(wall_x), 0.0)[1]
    assert np.any(np.abs(delays - want) < 1e-12), (delays, want)
    # And its own echo comes later than its window closes (3 m > max range): the
    # only thing it hears in its window is the cross-talk.
    assert len(delays) == 1


def test_ring_geometry_and_fresnel_limits():
    poses = ring_poses(8, 0.15)
    z = np.array([p.rotation[:, 2] for p in poses])
    np.testing.assert_allclose(np.linalg.norm([p.position for p in poses], axis=1), 0.15, rtol=1e-12, atol=0)
    np.testing.assert_allclose(z[2], [1.0, 0.0, 0.0], atol=1e-12)  # 90 deg: sensor +x
    # Fresnel factor: 1 unbounded, 1/2 for a half-plane, w sqrt(q / pi) for a short strip.
    assert float(fresnel_factor(10.0, -1e6, 1e6)) == pytest.approx(1.0, rel=1e-5, abs=0)
    assert float(fresnel_factor(10.0, 0.0, 1e6)) == pytest.approx(0.5, rel=1e-5, abs=0)
    w = 1e-3
    assert float(fresnel_factor(10.0, -w / 2, w / 2)) == pytest.approx(w * math.sqrt(10.0 / math.pi), rel=1e-5,
                                                                       abs=0)


def test_ring_in_the_robot_cell_has_no_invalid_spreading_factor():
    # At t = 1.4 s the walking person (a capsule) stands where some transducer
    # pairs have no specular point on its cylinder; those rows are dropped and
    # must not pass a negative ratio through sqrt on the way (RuntimeWarning,
    # an error in this suite) nor leave NaN in the frame.
    import warnings

    from twinsense.demos.ultrasonic import build_cell

    scene, ring = build_cell()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        for t in (1.267, 1.4, 3.333):
            f = ring.capture(scene, t, np.random.default_rng(0))
            assert np.isfinite(f.envelope).all() and np.isfinite(f.ascan).all()
