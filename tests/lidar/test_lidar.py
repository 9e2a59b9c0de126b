"""LiDAR: scan patterns, geometry against closed forms, the LiDAR equation, waveform echoes, rolling scan.

Noise is switched off (range_noise 0, no SNR term, a receiver noise far below
every echo) wherever a closed form is compared; ranges and powers are stored
as float32, so 2^-24 relative (6e-8) is the floor of every comparison.
"""

import math

import numpy as np
import pytest

from twinsense import Box, Material, Mount, Plane, Pose, Scene, Sphere
from twinsense.errors import ConfigError
from twinsense.lidar import Lidar, LidarConfig, RotatingScan, lidar_config
from twinsense.lidar import radiometry as rad
from twinsense.lidar.scan import subray_pattern
from twinsense.lidar.waveform import echoes
from twinsense.scene.motion import ConstantVelocity

F32 = 2.0 ** -24
MATTE = Material("lidar_test_matte", 0.5, 0.0)
QUIET = {"range_noise": 0.0, "snr_range_noise": False, "noise_power": 1e-18, "saturation_power": 1e3}


def single_beam(n_columns=1, subrays=1, **kw) -> LidarConfig:
    """One level beam; ``n_columns`` firings per revolution at 10 Hz (column 0 points straight ahead)."""
    kw = {"blind_range": 0.05, "full_overlap_range": 0.1, **QUIET, **kw}
    return LidarConfig(RotatingScan((0.0,), n_columns), 10.0, subrays=subrays, **kw)


FORWARD = Mount(Pose.look_at((0, 0, 1.0), (5.0, 0, 1.0)))  # optical z = world +x, level


# --- scan patterns ---------------------------------------------------------------

def test_vlp16_points_per_revolution_and_firing_order():
    cfg = lidar_config("velodyne_vlp16")
    # User manual: 16 lasers x 1800 firings per revolution at 600 rpm = 28,800 points.
    assert cfg.n_firings == 28_800 and cfg.scan.columns == 1800
    lidar = Lidar("v", cfg)
    f = lidar.capture(Scene(), 0.0, np.random.default_rng(0))
    assert f.range.shape == (28_800, 1) and f.xyz.shape == (28_800, 1, 3)
    # Rings ascend -15..+15 deg every 2 deg.
    np.testing.assert_allclose(np.rad2deg(f.elevation[:16]), np.arange(-15, 16, 2), atol=1e-5)
    # Firing times: laser with channel c (elevations -15, 1, -13, 3, ...) fires c x 2.304 us into its column.
    chan = [(-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15).index(e) for e in range(-15, 16, 2)]
    np.testing.assert_allclose(f.time[:16], np.array(chan) * 2.304e-6, rtol=0, atol=1e-12)
    # Columns 0.2 deg apart; each laser's azimuth carries its own firing delay (0.2 deg / 55.6 us).
    col = np.rad2deg(f.azimuth[16:32] - f.azimuth[:16])
    np.testing.assert_allclose(col, 0.2, rtol=0, atol=1e-4)  # float32 azimuths: 1e-7 rad
    np.testing.assert_allclose(np.rad2deg(f.azimuth[:16]), 360.0 * 10.0 * f.time[:16], rtol=0, atol=1e-5)
    # 20 Hz: 900 columns (manual: 0.4 deg, 14,400 points).
    assert lidar_config("velodyne_vlp16", frame_rate=20.0).n_firings == 14_400


def test_os1_and_rosette_patterns():
    os1 = lidar_config("ouster_os1_64")
    assert os1.n_firings == 64 * 1024
    el = np.asarray(os1.scan.elevations_deg)
    np.testing.assert_allclose(np.diff(el), 45.0 / 63.0, rtol=0, atol=1e-12)
    assert lidar_config("ouster_os1_64", columns=2048, frame_rate=20.0).n_firings == 64 * 2048
    mid = Lidar("m", lidar_config("livox_mid40"))
    a = mid.capture(Scene(), 0.0, np.random.default_rng(0))
    b = mid.capture(Scene(), 0.1, np.random.default_rng(0))
    assert a.time.shape == (10_000,)  # 100 kHz x 0.1 s
    np.testing.assert_allclose(np.diff(a.time), 1e-5, rtol=1e-9, atol=0)
    # Off-axis angle: cos(off) = cos(el) cos(az); it stays inside the 19.2 deg half-FOV and reaches it.
    off = np.rad2deg(np.arccos(np.cos(a.elevation.astype(float)) * np.cos(a.azimuth.astype(float))))
    assert off.max() <= 19.2 + 1e-4 and off.max() > 19.0
    # Non-repetitive: the next frame follows other paths.
    assert np.abs(a.azimuth - b.azimuth).max() > 0.05


# --- geometry against closed forms ---------------------------------------------------

def test_plane_ranges_match_ray_plane_distance():
    # A wall 4 m ahead (normal towards the sensor); 360 columns: the beams facing it.
    scene = Scene()
    scene.add_object("wall", Plane((30.0, 30.0)), MATTE, pose=Pose.from_euler_deg((4.0, 0, 1.0), (0, -90, 0)))
    f = Lidar("l", single_beam(360), FORWARD).capture(scene, 0.0, np.random.default_rng(0))
    ok = f.valid[:, 0]
    az = f.azimuth[ok].astype(float)
    # Ray-plane: a level beam at azimuth phi meets x = 4 at 4 / cos(phi).
    expect = 4.0 / np.cos(az)
    assert ok.sum() > 100
    # float32 range and azimuth (the azimuth enters through 4 tan(phi) dphi, dphi <= 2^-24 pi).
    tol = expect * F32 + 4.0 * np.abs(np.tan(az)) / np.cos(az) * F32 * np.pi
    assert np.all(np.abs(f.range[ok, 0] - expect) <= tol)
    # World points lie on the wall.
    np.testing.assert_allclose(f.xyz_world[ok, 0, 0], 4.0, rtol=0, atol=4.0 * 8 * F32 * 10)


def test_sphere_ranges_within_facet_sag():
    radius, centre = 1.0, np.array([5.0, 0.3, 1.0])
    sph = Sphere(radius, subdivisions=4)
    scene = Scene()
    scene.add_object("ball", sph, MATTE, pose=Pose(centre))
    cfg = LidarConfig(RotatingScan(tuple(np.linspace(-10, 10, 21)), 3600), 10.0, subrays=1, blind_range=0.05,
                      full_overlap_range=0.1, **QUIET)
    f = Lidar("l", cfg, FORWARD).capture(scene, 0.0, np.random.default_rng(0))
    ok = f.valid[:, 0]
    d = f.xyz[ok, 0] / f.range[ok, 0:1]  # beam directions, sensor frame
    d_world = d @ FORWARD.pose.rotation.T
    o = FORWARD.pose.position
    # Ray-sphere: t = b - sqrt(b^2 - c), b = d.(C - o), c = |C - o|^2 - r^2.
    w = centre - o
    b = d_world @ w
    t = b - np.sqrt(b * b - (w @ w - radius**2))
    cos_inc = np.sqrt(np.maximum(b * b - (w @ w - radius**2), 0)) / radius
    # The icosphere's faces lie inside the sphere by at most the sag r - min_face(distance of its plane);
    # along a ray at incidence cosine c the hit moves by at most sag / c (the flat facet behind the sphere).
    m = sph.mesh
    v = m.vertices[m.faces]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    sag = radius - np.abs(np.einsum("ij,ij->i", n, v[:, 0])).min()
    sel = cos_inc > 0.5
    assert sel.sum() > 200 and 0 < sag < 5e-3
    err = f.range[ok, 0][sel] - t[sel]
    assert np.all(err >= -t[sel] * 8 * F32) and np.all(err <= sag / cos_inc[sel] + t[sel] * 8 * F32)


# --- the LiDAR equation -----------------------------------------------------------

def test_intensity_law_on_tilted_plane():
    # A matte plane tilted 40 deg about the vertical, 3 m ahead: incidence and range vary along the scan.
    scene = Scene()
    scene.add_object("wall", Plane((30.0, 30.0)), MATTE, pose=Pose.from_euler_deg((3.0, 0, 1.0), (0, -90, 40)))
    cfg = single_beam(720)
    f = Lidar("l", cfg, FORWARD).capture(scene, 0.0, np.random.default_rng(0))
    ok = f.valid[:, 0]
    p, r = f.power[ok, 0].astype(float), f.range[ok, 0].astype(float)
    d = f.xyz_world[ok, 0] - FORWARD.pose.position
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    normal = Pose.from_euler_deg((0, 0, 0), (0, -90, 40)).rotation[:, 2]
    cos_t = np.abs(d @ normal)
    assert ok.sum() > 100 and cos_t.min() < 0.5 < cos_t.max()
    # P = P_t rho cos(theta) / R^2 (A_r / pi) eta (full overlap, clear air, one sub-ray of weight 1).
    expect = rad.system_constant(cfg) * 0.5 * cos_t / r**2
    # float32 power and range, and the direction taken from float32 points (cos via ~4 ulp).
    np.testing.assert_allclose(p, expect, rtol=16 * F32 / cos_t.min(), atol=0)
    # Reported intensity: 100 x rho cos(theta), rounded.
    assert np.all(np.abs(f.intensity[ok, 0].astype(float) - 100 * 0.5 * cos_t) <= 0.5 + 1e-3)


def test_overlap_blind_range_and_fog():
    cfg = single_beam(1, blind_range=0.5, full_overlap_range=1.5)
    # Smoothstep overlap: 0 below the blind range, 1/2 half-way, 1 from full overlap.
    np.testing.assert_allclose(rad.overlap(np.array([0.3, 0.5, 1.0, 1.5, 9.0]), 0.5, 1.5),
                               [0, 0, 0.5, 1, 1], rtol=0, atol=1e-15)
    near = Scene()
    near.add_object("wall", Plane((5.0, 5.0)), MATTE, pose=Pose.from_euler_deg((0.4, 0, 1.0), (0, -90, 0)))
    assert Lidar("l", cfg, FORWARD).capture(near, 0.0, np.random.default_rng(0)).n_points == 0
    # Kim model at V = 1 km, 905 nm: q = V - 0.5 = 0.5, alpha = 3.912 / 1000 (905 / 550)^-0.5.
    alpha = 3.912e-3 * (905.0 / 550.0) ** -0.5
    assert rad.fog_extinction(1000.0, 905e-9) == pytest.approx(alpha, rel=1e-12, abs=0)
    far = Scene()
    far.add_object("wall", Plane((20.0, 20.0)), MATTE, pose=Pose.from_euler_deg((30.0, 0, 1.0), (0, -90, 0)))
    clear = Lidar("l", cfg, FORWARD).capture(far, 0.0, np.random.default_rng(0))
    foggy = Lidar("l", single_beam(1, fog_visibility=1000.0), FORWARD).capture(far, 0.0, np.random.default_rng(0))
    # Two-way extinction exp(-2 alpha R), R = 30 m (float32 powers).
    assert foggy.power[0, 0] / clear.power[0, 0] == pytest.approx(math.exp(-2 * alpha * 30.0), rel=4 * F32, abs=0)


def test_retroreflector_saturates_with_range_walk():
    scene = Scene()
    scene.add_object("tape", Plane((3.0, 3.0)), "ir_reflector", pose=Pose.from_euler_deg((5.0, 0, 1.0), (0, -90, 0)))
    base = single_beam(1)
    p_sat = 1e-6
    f = Lidar("l", single_beam(1, saturation_power=p_sat), FORWARD).capture(scene, 0.0, np.random.default_rng(0))
    # Unclipped power: K rho G cos / R^2 with rho = 0.95, G = 300 (ir_reflector), cos = 1, R = 5 m.
    p = rad.system_constant(base) * 0.95 * 300.0 / 25.0
    assert f.power[0, 0] == pytest.approx(p_sat, rel=F32, abs=0) and f.intensity[0, 0] == 255
    walk = base.pulse_sigma_range * math.sqrt(2 * math.log(p / p_sat))
    assert f.range[0, 0] == pytest.approx(5.0 - walk, rel=0, abs=8 * F32 * 5.0)


def test_detection_probability_at_threshold():
    # Inside a sphere every beam meets the wall head-on at ~R: with the noise tied to that echo
    # (SNR = threshold), P_detect = Phi(0) = 1/2.
    radius = 10.0
    scene = Scene()
    scene.add_object("shell", Sphere(radius, subdivisions=5), MATTE, pose=Pose((0, 0, 1.0)))
    base = LidarConfig(RotatingScan((-2.0, 0.0, 2.0), 1000), 10.0, subrays=1, blind_range=0.05,
                       full_overlap_range=0.1, **QUIET)
    noise = rad.noise_power_for(radius, 0.5, base.detection_snr, base.peak_power, base.aperture_area,
                                base.optics_efficiency)
    f = Lidar("l", base.with_overrides(noise_power=noise), Mount(Pose((0, 0, 1.0)))).capture(
        scene, 0.0, np.random.default_rng(3))
    n = f.range.shape[0]
    # Binomial: 3000 firings, p = 1/2 +- the facets (range within the sag, 1e-3 R: SNR within 2e-3 x 5,
    # dP = phi(0) 0.01 = 0.004); 5 sigma of the count is 5 sqrt(n / 4) = 137.
    assert abs(f.n_points - n / 2) <= 5 * math.sqrt(n / 4) + 0.004 * n


# --- waveform echoes ----------------------------------------------------------------

def _edge_scene(d_front, d_back, edge_y):
    """Back wall at d_back; a front plate at d_front covering world y > edge_y (the sensor looks along +x)."""
    s = Scene()
    s.add_object("back", Plane((20.0, 20.0)), MATTE, pose=Pose.from_euler_deg((d_back, 0, 1.0), (0, -90, 0)))
    s.add_object("front", Box((0.01, 4.0, 4.0)), MATTE, pose=Pose((d_front + 0.005, edge_y + 2.0, 1.0)))
    return s


def _subray_geometry(cfg, distances_by_side, edge_y):
    """Independent sub-ray ranges and powers: plane distance / cos of the sub-ray's angle to +x."""
    dh, dv, w = subray_pattern(cfg.subrays, *cfg.divergence_deg)
    # Sub-ray direction in the world: forward +x, tilted by dh about z (right = -y) and dv about y.
    d = np.stack([np.ones_like(dh), -np.tan(dh), np.tan(dv)], axis=1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d_front, d_back = distances_by_side
    # Lateral (world y) position of each sub-ray where it crosses the front plate's plane.
    front = d[:, 1] * d_front / d[:, 0] > edge_y
    r = np.where(front, d_front, d_back) / d[:, 0]
    p = rad.system_constant(cfg) * w * 0.5 * d[:, 0] / r**2
    return r, p, front, w


def test_edge_straddling_beam_gives_two_echoes_in_footprint_proportion():
    cfg = single_beam(1, subrays=3, divergence_deg=(0.2, 0.2), return_mode="multi", max_echoes=2)
    d_front, d_back = 5.0, 7.0
    # Gauss-Hermite sub-rays at 0, +-sqrt(3) sigma: the edge half-way to the +y column leaves that
    # column (weight 1/6 of the beam) on the front plate.
    sigma = np.deg2rad(0.2) / (2 * math.sqrt(2 * math.log(2)))
    edge_y = 0.5 * d_front * math.tan(math.sqrt(3) * sigma)
    f = Lidar("l", cfg, FORWARD).capture(_edge_scene(d_front, d_back, edge_y), 0.0, np.random.default_rng(0))
    r, p, front, w = _subray_geometry(cfg, (d_front, d_back), edge_y)
    assert w[front].sum() == pytest.approx(1 / 6, rel=1e-12, abs=0)
    assert f.valid[0].all()
    # The echoes are 2 m apart (6 sigma_R): each peak is its plate's power, the other's tail adds
    # exp(-(2 / 0.318)^2 / 2) = 2e-9 of it; the sub-ray ranges on one plate differ by ~1e-5 m (<< sigma_R).
    np.testing.assert_allclose(f.range[0], [np.average(r[front], weights=p[front]),
                                            np.average(r[~front], weights=p[~front])], rtol=4 * F32, atol=0)
    np.testing.assert_allclose(f.power[0], [p[front].sum(), p[~front].sum()], rtol=1e-6, atol=0)
    # Energies in proportion to the footprint fractions (1/6 : 5/6) after the 1/R^2 law.
    ratio = f.power[0, 0] / f.power[0, 1]
    assert ratio == pytest.approx((1 / 6) / d_front**2 / ((5 / 6) / d_back**2), rel=1e-5, abs=0)


def test_surfaces_within_pulse_resolution_give_one_mixed_echo():
    cfg = single_beam(1, subrays=3, divergence_deg=(0.2, 0.2), return_mode="multi", max_echoes=2)
    d_front, d_back = 5.0, 5.1  # 0.1 m apart, below the pulse resolution 2 sigma_R = 0.64 m (5 ns)
    assert d_back - d_front < cfg.pulse_resolution
    sigma = np.deg2rad(0.2) / (2 * math.sqrt(2 * math.log(2)))
    edge_y = 0.5 * d_front * math.tan(math.sqrt(3) * sigma)
    f = Lidar("l", cfg, FORWARD).capture(_edge_scene(d_front, d_back, edge_y), 0.0, np.random.default_rng(0))
    r, p, _, _ = _subray_geometry(cfg, (d_front, d_back), edge_y)
    assert f.valid[0].tolist() == [True, False]
    # Independent peak of the waveform sum_s P_s exp(-(x - R_s)^2 / 2 sigma_R^2): a 1 um grid search.
    s_r = cfg.pulse_sigma_range
    x = np.arange(4.9, 5.2, 1e-6)
    wave = (p[None, :] * np.exp(-0.5 * ((x[:, None] - r[None, :]) / s_r) ** 2)).sum(axis=1)
    x_peak = x[wave.argmax()]
    # The model refines its sigma_R / 4 grid with a parabola through ln w: exact for one Gaussian; for
    # two merged ones the cubic term of ln w moves the vertex by well under 1e-4 sigma_R (3e-5 m) here.
    assert f.range[0, 0] == pytest.approx(x_peak, rel=0, abs=3e-5 + 1e-6 + 8 * F32 * 5)
    assert f.power[0, 0] == pytest.approx(wave.max(), rel=1e-6, abs=0)
    # A mixed range: between the plates, the power-weighted mean within the third-moment bound.
    assert d_front < f.range[0, 0] < d_back


def test_fast_single_echo_path_agrees_with_sampled_waveform():
    rng = np.random.default_rng(1)
    r = 10.0 + rng.normal(0, 0.002, (200, 9))  # spread << sigma_R: one surface per beam
    p = rng.uniform(1e-6, 2e-6, (200, 9))
    sigma = lidar_config("velodyne_vlp16").pulse_sigma_range
    a, b = echoes(r, p, sigma), echoes(r, p, sigma, fast_spread=0.0)
    assert len(a) == len(b) == 200
    # Closed form (mean range) vs sampled waveform: third-moment bound spread^3 / (2 sigma^2) ~ 1e-7 m.
    np.testing.assert_allclose(a.range, b.range, rtol=0, atol=1e-6)
    np.testing.assert_allclose(a.power, b.power, rtol=1e-6, atol=0)


def test_return_modes():
    cfg = single_beam(1, subrays=3, divergence_deg=(0.2, 0.2))
    sigma = np.deg2rad(0.2) / (2 * math.sqrt(2 * math.log(2)))
    edge_y = 0.5 * 5.0 * math.tan(math.sqrt(3) * sigma)
    scene = _edge_scene(5.0, 7.0, edge_y)  # weak near echo (1/6), strong far one (5/6)
    got = {}
    for mode, n in (("strongest", 1), ("first", 1), ("last", 1), ("dual", 2)):
        c = cfg.with_overrides(return_mode=mode, max_echoes=n)
        got[mode] = Lidar("l", c, FORWARD).capture(scene, 0.0, np.random.default_rng(0)).range[0]
    assert got["strongest"][0] == pytest.approx(7.0, abs=1e-3) and got["last"][0] == pytest.approx(7.0, abs=1e-3)
    assert got["first"][0] == pytest.approx(5.0, abs=1e-3)
    # Dual: strongest = last, so the second strongest joins; slots in range order.
    np.testing.assert_allclose(got["dual"], [5.0, 7.0], rtol=0, atol=1e-3)


# --- rolling scan -------------------------------------------------------------------

def test_moving_sensor_scan_skew():
    # The sensor rides a carrier moving at v along +x towards a wall at x = 6: a firing at time t is
    # v t closer. The pose is exact per firing (constant velocity: the first-order carry is exact).
    v = 5.0
    scene = Scene()
    scene.add_object("wall", Plane((40.0, 40.0)), MATTE, pose=Pose.from_euler_deg((6.0, 0, 1.0), (0, -90, 0)))
    scene.add_object("cart", Box((0.1, 0.1, 0.1)), MATTE, motion=ConstantVelocity(Pose((0, 0, 1.0)), (v, 0, 0)),
                     layers=["tof"])
    mount = Mount(Pose.look_at((0, 0, 0), (1.0, 0, 0)), parent="cart")
    f = Lidar("l", single_beam(360), mount).capture(scene, 0.0, np.random.default_rng(0))
    ok = f.valid[:, 0]
    t, az = f.time[ok], f.azimuth[ok].astype(float)
    expect = (6.0 - v * t) / np.cos(az)
    assert ok.sum() > 100 and (v * t).max() > 0.04  # the skew spans > 4 cm over the wall's half turn
    tol = expect * 8 * F32 + 6.0 * np.abs(np.tan(az)) / np.cos(az) * F32 * np.pi
    assert np.all(np.abs(f.range[ok, 0] - expect) <= tol)
    # In the world every point lies on the wall: the skew is all in the sensor frame.
    np.testing.assert_allclose(f.xyz_world[ok, 0, 0], 6.0, rtol=0, atol=1e-5)


def test_moving_object_posed_per_time_slice():
    # A wall approaching a fixed sensor at v: each firing sees it at its own slice's middle time, so the
    # range is off from 6 - v t by at most v motion_slice / 2.
    v, dt = 3.0, 1e-3
    scene = Scene()
    scene.add_object("wall", Plane((40.0, 40.0)), MATTE,
                     motion=ConstantVelocity(Pose.from_euler_deg((6.0, 0, 1.0), (0, -90, 0)), (-v, 0, 0)))
    f = Lidar("l", single_beam(360, motion_slice=dt), FORWARD).capture(scene, 0.0, np.random.default_rng(0))
    ok = f.valid[:, 0]
    t, az = f.time[ok], f.azimuth[ok].astype(float)
    expect = (6.0 - v * t) / np.cos(az)
    assert ok.sum() > 100
    err = np.abs(f.range[ok, 0] - expect)
    assert np.all(err <= v * dt / 2 / np.cos(az) + expect * 8 * F32 + 6.0 * np.abs(np.tan(az)) / np.cos(az) * 4e-7)
    assert err.max() > 0.1 * v * dt / 2  # the slicing is visible: not posed per firing


# --- configuration --------------------------------------------------------------------

def test_bad_config_names_field_and_allowed():
    with pytest.raises(ConfigError, match="return_mode"):
        lidar_config("velodyne_vlp16", return_mode="loudest")
    with pytest.raises(ConfigError, match=r"max_echoes.*2 for return_mode 'dual'"):
        lidar_config("velodyne_vlp16", return_mode="dual")
    with pytest.raises(ConfigError, match="sensor.overrides"):
        lidar_config("ouster_os1_64", colums=2048)
    with pytest.raises(ConfigError, match="frame_rate"):
        lidar_config("velodyne_vlp16", frame_rate=50.0)
    with pytest.raises(ConfigError, match="firing_offsets"):
        RotatingScan((0.0, 1.0), 10, firing_offsets=(0.0,))
