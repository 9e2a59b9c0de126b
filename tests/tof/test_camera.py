"""System tests: scene -> rendered ToF frame -> depth, against geometry and closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twinsense.constants import PLANCK as H_PLANCK
from twinsense.constants import SPEED_OF_LIGHT as C_LIGHT
from twinsense.render import cast
from twinsense.render.rays import frozen
from twinsense.scene import Box, ConstantVelocity, Material, Pose, Scene
from twinsense.tof import InvalidReason, ToFCamera
from twinsense.tof.effects import crosstalk
from twinsense.tof.pipeline import expected_raw, finish_geometry, run_chain
from twinsense.tof.signal import beam_profile, pixel_phasors

#: The NumPy reference with libm's transcendental functions, as the compiled kernels call them.
pytestmark = pytest.mark.usefixtures("libm_reference")


def test_plane_depth_is_exact_without_noise_pico_flexx_with_distortion(wall_scene, look_x):
    """Plane at a known distance through the full device model (calibrated distortion, 2x2 SS)."""
    scene = wall_scene(1.2)
    cam = ToFCamera.preset("pmd_pico_flexx", mount=look_x, noise=False, quantization=False)
    frame = cam.capture(scene, 0.0)
    valid = frame.valid
    assert valid.mean() > 0.95
    # Every pixel of a fronto-parallel plane has z-depth 1.2 m. Noise-free, unquantised: the
    # remaining errors are float32 phases (~1e-6 rad -> um), the 2x2 sub-pixel spread
    # (second order in 1/4 px: < 1 um) and cross-talk mixing neighbours whose radial
    # distances differ by < 1 cm, i.e. well under 1 mm.
    err = frame.depth[valid] - 1.2
    assert abs(err.mean()) < 1e-3
    assert np.max(np.abs(err)) < 1e-3
    # Radial distance and points agree with the per-pixel ray direction.
    np.testing.assert_allclose(frame.points_sensor[valid][:, 2], frame.depth[valid], rtol=1e-6)
    world = frame.point_cloud("world")
    np.testing.assert_allclose(world[:, 0], 1.2, atol=1e-3)


def test_plane_mean_depth_with_adc_quantisation(wall_scene, look_x):
    scene = wall_scene(1.2)
    cam = ToFCamera.preset("pmd_pico_flexx", mount=look_x, noise=False)
    frame = cam.capture(scene, 0.0)
    # Rounding each raw value to 1 DN (amplitude ~100 DN) moves single pixels by up to a few
    # mm, but the rounding errors average out across the image: |mean| < 1 mm.
    assert abs(frame.depth[frame.valid].mean() - 1.2) < 1e-3


def test_radiometry_matches_camera_equation(wall_scene, make_camera, look_x):
    """Centre pixel amplitude vs the closed-form camera equation (independent of the module)."""
    d = 1.5
    cam = make_camera(supersample=1, ambient_irradiance=0.0)
    cfg = cam.config
    albedo = 0.80
    frame = cam.capture(wall_scene(d, Material("white_lambertian", albedo, 0.0)), 0.0)
    # Beam peak intensity p(0) = 1 / (beam solid angle), checked separately against quadrature.
    p0 = float(beam_profile(np.array([0.0, 0.0, 1.0]), cfg.illumination_fwhm_deg))
    irradiance = cfg.illumination_power * p0 / d ** 2  # W/m^2 on the wall, normal incidence
    image_irr = albedo * irradiance * cfg.lens_transmission / (4 * cfg.f_number ** 2)
    power = image_irr * cfg.pixel_pitch ** 2 * cfg.fill_factor
    electrons = power * cfg.exposure_time * cfg.wavelength / (H_PLANCK * C_LIGHT) * cfg.quantum_efficiency
    amp_dn = electrons * cfg.demodulation_contrast / 2 / cfg.electrons_per_dn
    cy, cx = cfg.height // 2, cfg.width // 2  # odd size: the centre pixel looks along the axis
    # float32 chain: 1e-5 relative.
    assert frame.amplitude[cy, cx] == pytest.approx(amp_dn, rel=1e-5, abs=0)


def test_amplitude_follows_inverse_square(wall_scene, make_camera):
    cam = make_camera()
    amps = []
    for d in (0.8, 1.2, 1.6, 2.4):
        f = cam.capture(wall_scene(d), 0.0)
        amps.append(f.amplitude[11, 15] * d ** 2)
    # Noise-free and unquantised, every factor but 1/d^2 is the same for the centre pixel of a
    # fronto-parallel wall: constant to float32 precision (1e-5).
    np.testing.assert_allclose(amps, amps[0], rtol=1e-5)


def test_step_edge_gives_flying_pixels_only_on_the_edge(look_x, small_config):
    """Near wall on the image's left half, far wall behind; the edge runs through a pixel column."""
    near, far = 1.0, 1.3
    scene = Scene()
    # Image right = world -y: the near wall covers world y > 0, i.e. the left half of the image.
    scene.add_object("near", Box((0.02, 4.0, 4.0)), "drywall", pose=Pose(position=(near + 0.01, 2.0, 0)))
    scene.add_object("far", Box((0.02, 10.0, 10.0)), "drywall", pose=Pose(position=(far + 0.01, 0, 0)))
    cfg = small_config(flying_pixel_filter=False)
    frame = ToFCamera(cfg, look_x).capture(scene, 0.0)
    edge_col = cfg.width // 2  # cx = 15.0 exactly: the edge splits this column's sub-pixels 2 + 2
    z = frame.depth
    # Off the edge the depths are exact (noise-free; 1 mm).
    np.testing.assert_allclose(z[:, :edge_col], near, atol=1e-3)
    np.testing.assert_allclose(z[:, edge_col + 1:], far, atol=1e-3)
    # On the edge: in-between depths from the phasor sum, never either surface.
    assert np.all((z[:, edge_col] > near + 0.02) & (z[:, edge_col] < far - 0.02))
    # The Royale flying-pixel filter removes exactly the edge column.
    filtered = ToFCamera(cfg.replaced(flying_pixel_filter=True), look_x).capture(scene, 0.0)
    flying = filtered.mask(InvalidReason.FLYING_PIXEL)
    assert np.all(flying[:, edge_col])
    assert not np.any(np.delete(flying, edge_col, axis=1))
    assert np.all(filtered.depth[:, edge_col] == 0.0)


def _saturation_scene(reflector_distance=1.5, wall_distance=2.5):
    s = Scene()
    s.add_object("wall", Box((0.02, 10, 10)), "drywall", pose=Pose(position=(wall_distance + 0.01, 0, 0)))
    s.add_object("reflector", Box((0.01, 0.2, 0.2)), "ir_reflector",
                 pose=Pose(position=(reflector_distance + 0.005, 0, 0)))
    return s


def test_saturation_sets_depth_zero_exactly_where_taps_clip(look_x, small_config):
    cfg = small_config(crosstalk_sigma_px=0.8)
    cam = ToFCamera(cfg, look_x)
    scene = _saturation_scene()
    frame = cam.capture(scene, 0.0)
    # Independent clip test on the expected taps: A, B = (S +- D) / 2 after cross-talk.
    samples = cam.render(scene, 0.0)
    corr, taps, _ = expected_raw(pixel_phasors(samples, cam.radiometry), cfg)
    corr, taps = crosstalk(corr, cfg.crosstalk_sigma_px), crosstalk(taps, cfg.crosstalk_sigma_px)
    tap_max = (taps + np.abs(corr)) / 2
    raw = cfg.adc_offset_dn + corr / cfg.electrons_per_dn
    clip = np.any((tap_max > cfg.full_well) | (raw < cfg.raw_valid_range_dn[0])
                  | (raw > cfg.raw_valid_range_dn[1]), axis=(0, 1))
    assert clip.sum() >= 4  # the retro-reflector saturates
    np.testing.assert_array_equal(frame.mask(InvalidReason.SATURATED), clip)
    assert np.all(frame.depth[clip] == 0.0)
    assert np.all(frame.confidence[clip] == 0)
    # Cross-talk spreads the reflector's huge signal: wrong depths around it (the paper's cloud).
    ring = ~clip & frame.valid & (np.abs(frame.depth - 2.5) > 0.02)
    assert ring.sum() > 0
    no_xt = ToFCamera(cfg.replaced(crosstalk_sigma_px=0.0), look_x).capture(scene, 0.0)
    wall_px = no_xt.valid & (np.abs(no_xt.depth - 2.5) < 0.05)
    # Without cross-talk every valid wall pixel off the reflector's edge is exact.
    assert np.all(np.abs(no_xt.depth[wall_px] - 2.5) < 1e-3)


def test_saturation_threshold_from_closed_form(wall_scene, make_camera):
    """A wall saturates the centre pixel exactly below the distance the camera equation predicts."""
    cam = make_camera(supersample=1, ambient_irradiance=0.0, dark_current=0.0,
                      illumination_power=4.0, electrons_per_dn=100.0)
    lambertian = Material("white_lambertian", 0.8, 0.0)
    cfg = cam.config
    p0 = float(beam_profile(np.array([0.0, 0.0, 1.0]), cfg.illumination_fwhm_deg))
    k = (0.8 * cfg.illumination_power * p0 * cfg.lens_transmission / (4 * cfg.f_number ** 2)
         * cfg.pixel_pitch ** 2 * cfg.fill_factor * cfg.exposure_time * cfg.wavelength
         / (H_PLANCK * C_LIGHT) * cfg.quantum_efficiency)  # signal e- = k / d^2
    # max tap = N/2 (1 + c_d/2 |cos|) with |cos| -> 1 on some phase step when phi is a
    # multiple of pi/2; in general max over the 4 steps of |cos(phi + i pi/2)| >= 1/sqrt(2).
    def max_tap(d):
        phi = 4 * math.pi * 20e6 * d / C_LIGHT
        c = max(abs(math.cos(phi + i * math.pi / 2)) for i in range(4))
        return k / d ** 2 / 2 * (1 + cfg.demodulation_contrast / 2 * c)
    ds = np.linspace(0.2, 1.0, 400)
    d_star = ds[np.argmin(np.abs(np.array([max_tap(d) for d in ds]) - cfg.full_well))]
    cy, cx = cfg.height // 2, cfg.width // 2
    # 2 % either side of the threshold changes the tap level by ~4 %: unambiguous.
    assert cam.capture(wall_scene(d_star * 0.98, lambertian), 0.0).mask(InvalidReason.SATURATED)[cy, cx]
    assert cam.capture(wall_scene(d_star * 1.02, lambertian), 0.0).valid[cy, cx]


def test_crosstalk_zero_changes_nothing_and_flat_regions_stay_exact(wall_scene, make_camera):
    scene = wall_scene(1.4)
    a = make_camera(crosstalk_sigma_px=0.0).capture(scene, 0.0)
    b = make_camera(crosstalk_sigma_px=0.0).capture(scene, 0.0)
    np.testing.assert_array_equal(a.raw, b.raw)
    c = make_camera(crosstalk_sigma_px=1.0).capture(scene, 0.0)
    # A flat wall away from the image border: the blur mixes neighbours symmetrically, so only
    # the curvature of the radial distance across the image remains, sigma^2 d''/2 < 0.4 mm
    # (1.3 deg per pixel). At the border the replicated edge makes it one-sided (mm).
    inner = (slice(3, -3), slice(3, -3))
    np.testing.assert_allclose(c.depth[inner], a.depth[inner], atol=1e-3)


def test_same_seed_same_frames(wall_scene, make_camera):
    scene = wall_scene(1.4)
    cam = make_camera(noise=True, quantization=True)
    f1 = cam.capture(scene, 0.0, np.random.default_rng(99))
    f2 = cam.capture(scene, 0.0, np.random.default_rng(99))
    f3 = cam.capture(scene, 0.0, np.random.default_rng(100))
    for name, arr in f1.streams().items():
        np.testing.assert_array_equal(arr, f2.streams()[name], err_msg=name)
    assert not np.array_equal(f1.raw, f3.raw)


def test_noise_over_many_frames_matches_error_propagation(wall_scene, make_camera):
    """Per-pixel depth spread over 400 frames vs the error-propagation prediction."""
    scene = wall_scene(1.5)
    cam = make_camera(width=9, height=7, noise=True, quantization=True, noise_filter=False,
                      flying_pixel_filter=False)
    rng = np.random.default_rng(5)
    depths = np.stack([cam.capture(scene, 0.0, rng).distance for _ in range(400)])
    clean = make_camera(width=9, height=7, quantization=False).capture(scene, 0.0)
    cfg = cam.config
    # sigma_D^2 = (S + 2 sigma_r^2) / e^2 + 1/12 [DN^2], S from the noise-free gray value.
    s = clean.gray.astype(float) * 2 * cfg.electrons_per_dn
    sigma_dn = np.sqrt((s + 2 * cfg.read_noise ** 2) / cfg.electrons_per_dn ** 2 + 1 / 12)
    predicted = C_LIGHT / (4 * math.pi * 20e6) * sigma_dn / (math.sqrt(2) * clean.amplitude)
    ratio = depths.std(axis=0) / predicted
    # Each pixel's std over 400 frames is known to 3.5 % (1 sigma); the mean over 63 pixels to
    # 0.5 %. The 10 % bound holds for the mean with a wide margin and for every pixel
    # at ~3 sigma.
    assert ratio.mean() == pytest.approx(1.0, abs=0.03)
    assert np.all(np.abs(ratio - 1) < 0.12)


def test_sunlight_lowers_snr(wall_scene, make_camera):
    scene = wall_scene(1.5)
    dark = make_camera(ambient_irradiance=0.0).capture(scene, 0.0)
    sun = make_camera(ambient_irradiance=20.0).capture(scene, 0.0)
    # Unmodulated light adds no amplitude but fills the taps: more shot noise, same depth.
    np.testing.assert_allclose(sun.amplitude, dark.amplitude, rtol=1e-5)
    assert np.all(sun.gray > dark.gray)
    assert np.all(sun.noise > 1.5 * dark.noise)


def _corner_scene(corner=2.0):
    """Two perpendicular walls meeting in a vertical line at x = corner, opening towards the camera."""
    s = Scene()
    r2 = math.sqrt(0.5)
    c = np.array([corner, 0.0, 0.0])
    for name, yaw, along in (("left", 45.0, np.array([-r2, r2, 0])), ("right", -45.0, np.array([-r2, -r2, 0]))):
        normal_back = np.array([r2, r2, 0]) if yaw > 0 else np.array([r2, -r2, 0])
        centre = c + 1.5 * along + 0.01 * normal_back
        s.add_object(name, Box((0.02, 3.0, 3.0)), "drywall", pose=Pose.from_euler_deg(centre, (0, 0, yaw)))
    return s


def _corner_truth(cam, corner=2.0):
    """Exact z-depth on the two corner planes (x + |y| = corner) seen by each pixel.

    Radial distances of the sub-pixel rays, averaged per pixel (the pixel straddling the
    corner line sees the two walls left and right of the apex), times the pixel-centre
    ray's z component.
    """
    n = cam.config.supersample
    d = cam.pinhole.directions(n)  # sensor frame; world x = z_s, world y = -x_s
    t = corner / (d[..., 2] + np.abs(d[..., 0]))
    h, w = t.shape[0] // n, t.shape[1] // n
    radial = t.reshape(h, n, w, n).mean(axis=(1, 3))
    return radial * cam.pinhole.directions(1)[..., 2]


def test_multipath_overestimates_depth_in_a_corner(make_camera):
    scene = _corner_scene()
    cfg_kw = dict(width=21, height=15, fov_deg=(50.0, 36.0), multipath_vpl_grid=(16, 12),
                  multipath_stride=1, flying_pixel_filter=False, noise_filter=False,
                  modulation_frequencies=(80.32e6, 60.24e6))
    direct = make_camera(**cfg_kw).capture(scene, 0.0)
    mp = make_camera(multipath=True, **cfg_kw).capture(scene, 0.0)
    truth = _corner_truth(make_camera(**cfg_kw))
    inner = np.zeros_like(direct.valid)
    inner[2:-2, 2:-2] = True
    # Direct light only: exact (1 mm).
    assert np.max(np.abs(direct.depth[inner] - truth[inner])) < 1e-3
    err = mp.depth[inner] - truth[inner]
    # Indirect light travels longer paths: every pixel reads too far, by millimetres to cm.
    assert np.all(err > 1e-3)
    assert 5e-3 < err.mean() < 0.2
    # Symmetric scene, symmetric error, up to the VPL grid (16 lights over 42 sub-pixel
    # columns cannot sit symmetrically): 2 mm of a ~3 cm error.
    e = mp.depth - truth
    np.testing.assert_allclose(e[2:-2, 2:-2], e[2:-2, 2:-2][:, ::-1], atol=2e-3)


def test_multipath_visibility_blocks_light(make_camera):
    """Shadow rays: nothing blocks two planar walls, so visibility changes nothing there."""
    scene = _corner_scene()
    cfg_kw = dict(width=21, height=15, fov_deg=(50.0, 36.0), multipath=True,
                  multipath_vpl_grid=(16, 12), multipath_stride=1, noise_filter=False)
    open_ = make_camera(multipath_visibility=False, **cfg_kw).capture(scene, 0.0)
    shadowed = make_camera(**cfg_kw).capture(scene, 0.0)
    # Nothing blocks the view between two planar walls: the shadow rays change nothing.
    np.testing.assert_allclose(shadowed.depth, open_.depth, atol=1e-5)


def test_motion_artifacts_render_each_raw_frame_at_its_time(wall_scene, make_camera):
    scene = Scene()
    v = 2.0  # m/s away from the camera
    scene.add_object("wall", Box((0.02, 30, 30)), "drywall",
                     motion=ConstantVelocity(Pose(position=(1.51, 0, 0)), (v, 0, 0)))
    cam = make_camera(motion_artifacts=True, exposure_time=1e-3, readout_time=1e-3)
    cfg = cam.config
    frame = cam.capture(scene, 0.0)
    times = cfg.raw_frame_times(0.0)[:4] + cfg.exposure_time / 2
    # Four phase steps of a linearly receding wall: the estimate lies between the first and
    # last raw frame's distance (it is not a plain average: the phasor picks up the motion).
    d_first, d_last = 1.5 + v * times[0], 1.5 + v * times[-1]
    c = frame.depth[11, 15]
    assert d_first - 5e-3 < c < d_last + 5e-3
    still = make_camera().capture(scene, 0.0)
    assert still.depth[11, 15] == pytest.approx(1.5, abs=1e-3)
    assert abs(c - 1.5) > 1e-3
    # A static scene gives the same frame with and without per-raw-frame rendering.
    static = wall_scene(1.5)
    same_timing = make_camera(exposure_time=1e-3, readout_time=1e-3)
    np.testing.assert_allclose(cam.capture(static, 0.0).depth, same_timing.capture(static, 0.0).depth,
                               atol=1e-6)


def _moving_scene():
    scene = _saturation_scene()
    scene.add_object("mover", Box((0.3, 0.3, 0.3)), "wood",
                     motion=ConstantVelocity(Pose(position=(1.2, 0.4, 0.1)), (0, -1.0, 0)))
    # A spinning, elongated object: the rays go into its rotating frame and are culled
    # against its bounding sphere there.
    scene.add_object("spinner", Box((0.1, 0.6, 0.05)), "plastic",
                     motion=ConstantVelocity(Pose(position=(1.0, -0.3, -0.1)), (0, 0, 0), (0.3, 2.0, 5.0)))
    return scene


def test_tof_hits_are_the_shared_casters_hits(look_x):
    """The camera renders through twinsense.render.cast: same rays, same hits, moving objects too."""
    scene = _moving_scene()
    cam = ToFCamera.preset("generic", mount=look_x, width=40, height=30)
    rays = cam.pinhole.rays(look_x, 2)
    for t in (0.0, 0.1, 0.37):
        ref = cast(scene, rays, t, kind="tof")
        hits = cam._renderer.hits(scene, look_x.rotation, look_x.position, t, normals=True)
        assert np.any(np.isin(ref.object_id, [2, 3]))  # the movers are in view
        # Same rays (the camera's are the pinhole's, rotated without BLAS): the hit
        # objects agree exactly; distances, cosines and normals to float64 rounding
        # of the ray directions (~1e-16 relative), far below 1e-12.
        np.testing.assert_array_equal(hits.object_id, ref.object_id)
        hit = ref.hit
        np.testing.assert_allclose(hits.distance[hit], ref.distance[hit], rtol=1e-12)
        np.testing.assert_allclose(hits.cos_incidence, ref.cos_incidence, atol=1e-12)
        np.testing.assert_allclose(hits.normal, ref.normal, atol=1e-12)
        assert np.all(np.isinf(hits.distance[~hit]))
        # The surface samples are these hits in float32, 0 on a miss.
        samples = cam.render(scene, t)
        d_ref = np.where(hit, ref.distance, 0.0).astype(np.float32).reshape(samples.distance.shape)
        np.testing.assert_allclose(samples.distance, d_ref, rtol=1e-6)


@pytest.mark.parametrize("supersample", [1, 2, 3])
def test_kept_static_phasors_equal_a_full_rendering(look_x, supersample):
    """A fixed camera keeps its static-scene phasors and recomputes only pixels that see
    movers: bit for bit what a full rendering at each time gives."""
    scene = _moving_scene()
    cam = ToFCamera.preset("generic", mount=look_x, width=40, height=30, supersample=supersample)
    for t in (0.0, 0.1, 0.37, 0.1, 5.0):  # 5 s: the mover has left the view
        fast = cam._renderer.phasors(scene, look_x.rotation, look_x.position, t)
        full = pixel_phasors(cam.render(scene, t), cam.radiometry)
        for name in ("real", "imag", "tap_sum"):
            np.testing.assert_array_equal(getattr(fast, name), getattr(full, name), err_msg=f"{name} t={t}")
    # Nothing moving in view: the kept phasors themselves (read-only, so nothing downstream
    # can change them in place).
    quiet = _saturation_scene()
    quiet.add_object("mover", Box((0.3, 0.3, 0.3)), "wood",
                     motion=ConstantVelocity(Pose(position=(1.2, 40.0, 0.1)), (0, 1.0, 0)))
    cam.capture(quiet, 0.0, np.random.default_rng(0))
    kept = cam._renderer.phasors(quiet, look_x.rotation, look_x.position, 1.0)
    assert not kept.real.flags.writeable
    np.testing.assert_array_equal(kept.real, pixel_phasors(cam.render(quiet, 1.0), cam.radiometry).real)
    frame = cam.capture(quiet, 2.0, np.random.default_rng(0))
    np.testing.assert_array_equal(frame.raw, cam.capture(quiet, 3.0, np.random.default_rng(0)).raw)
    # Frames with motion artefacts render every raw frame this way, too.
    motion = ToFCamera.preset("generic", mount=look_x, width=40, height=30, motion_artifacts=True,
                              noise=False, supersample=supersample)
    frame = motion.capture(scene, 0.1)
    times = motion.config.raw_frame_times(0.1) + 0.5 * motion.config.exposure_time
    ref = expected_raw([pixel_phasors(motion.render(scene, float(ti)), motion.radiometry) for ti in times],
                       motion.config)
    fast = expected_raw([motion._renderer.phasors(scene, look_x.rotation, look_x.position, float(ti))
                         for ti in times], motion.config)
    for a, b in zip(fast, ref):
        np.testing.assert_array_equal(a, b)
    assert np.isfinite(frame.distance).any()


@pytest.mark.parametrize("extra", [{}, {"crosstalk_sigma_px": 2.5, "quantization": False},
                                   {"noise": False, "modulation_frequencies": (20e6,)}])
def test_capture_equals_the_whole_image_chain(look_x, extra):
    """Noise drawn on another thread and the chain run in two halves of rows change nothing:
    the frame is the whole-image chain's, bit for bit (odd height: unequal halves)."""
    scene = _moving_scene()
    cam = ToFCamera.preset("generic", mount=look_x, width=40, height=31, **extra)
    for t in (0.0, 0.1, 0.2):
        frame = cam.capture(scene, t, np.random.default_rng(5))
        phasors = pixel_phasors(cam.render(scene, t), cam.radiometry)
        out = run_chain(phasors, cam.config, np.random.default_rng(5))
        distance, depth, invalid, confidence, _ = finish_geometry(out, cam._pixel_dirs, cam.config)
        np.testing.assert_array_equal(frame.raw, out.raw)
        np.testing.assert_array_equal(frame.gray, out.gray)
        np.testing.assert_array_equal(frame.distance, distance)
        np.testing.assert_array_equal(frame.depth, depth)
        np.testing.assert_array_equal(frame.invalid, invalid)
        np.testing.assert_array_equal(frame.confidence, confidence)


def test_camera_rays_are_read_only_and_kept_per_pose(look_x):
    """Read-only rays let the shared caster keep the static hits of a fixed camera."""
    cam = ToFCamera.preset("generic", mount=look_x, width=8, height=6)
    rays = cam._renderer.rays(look_x.rotation, look_x.position)
    assert frozen(rays.directions) and frozen(rays.origins)
    assert cam._renderer.rays(look_x.rotation, look_x.position.copy()) is rays
    ref = cam.pinhole.rays(look_x, cam.config.supersample)
    np.testing.assert_array_equal(rays.directions, ref.directions)
    np.testing.assert_array_equal(rays.origins, ref.origins)


def test_vignetting_and_beam_fall_off_across_a_wall(wall_scene, look_x):
    """Amplitude over a fronto-parallel wall vs p(u) cos^7(a) (pico flexx lens, distortion included).

    A pixel whose ray makes the angle a with the axis sees the wall at d = D / cos a with
    incidence cosine cos a and vignetting cos^4 a: signal = P p(u) cos a cos^4 a cos^2 a / D^2.
    """
    cam = ToFCamera.preset("pmd_pico_flexx", mount=look_x, supersample=1, noise=False,
                           quantization=False, crosstalk_sigma_px=0.0)
    frame = cam.capture(wall_scene(1.0, Material("white_lambertian", 0.8, 0.0)), 0.0)
    d = cam.pinhole.directions(1)
    expected = beam_profile(d, cam.config.illumination_fwhm_deg) * d[..., 2] ** 7
    ratio = frame.amplitude / expected
    valid = frame.valid
    assert valid.mean() > 0.95
    # Exact up to float32: 1e-5 relative over the whole image.
    np.testing.assert_allclose(ratio[valid], np.median(ratio[valid]), rtol=1e-5)
    # The corners get far less light than the centre: cos^7 and the beam's fall-off.
    assert frame.amplitude[0, 0] < 0.4 * frame.amplitude[85, 106]
