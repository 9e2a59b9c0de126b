"""ToF and radar frames from external images against the ray-cast path (images rendered by twinsense).

Same grid: a render from the sensor's own centre at the sensor's own (sub-)pixel
rays holds exactly the ray-cast hits, so the frames agree bit for bit (ToF)
or to the IF synthesis accuracy (radar). Transform cut: one wide render from
a point between the sensors feeds two ToF cameras and a radar with their own
extrinsics; away from the parallax band beside depth edges the hits are exact
(planes: bilinear 1/z interpolation is exact), so the frames agree there.
"""

import numpy as np
import pytest
from scipy import ndimage

from twinsense import Box, ConfigError, Mount, PinholeCamera, Plane, Pose, Scene
from twinsense.radar import FMCWRadar, ScatterRenderer, make_radar
from twinsense.radar.external import capture_from_images as radar_from_images
from twinsense.render.external import images_from_scene
from twinsense.scene.motion import ConstantVelocity
from twinsense.tof import ToFCamera
from twinsense.tof.external import capture_from_images as tof_from_images
from twinsense.tof.presets import tof_preset

CENTRE = Pose.look_at((0.0, 0.0, 1.0), (3.0, 0.0, 1.0))


def shifted(dy):
    """CENTRE moved by dy along world y (the sensors' -x)."""
    return Pose.look_at((0.0, dy, 1.0), (3.0, dy, 1.0))


@pytest.fixture(scope="module")
def scene():
    s = Scene()
    # A wall wide enough that every radar ray hits something (rows stay aligned).
    s.add_object("wall", Plane((60, 60)), "drywall", pose=Pose.from_euler_deg((4.0, 0, 1.0), (0, -90, 0)))
    s.add_object("box", Box((0.4, 0.4, 0.4)), "metal",
                 motion=ConstantVelocity(Pose((2.0, 0.2, 1.0)), (-1.0, 0.0, 0.0)))
    s.add_object("crate", Box((0.3, 0.5, 0.3)), "wood", pose=Pose((2.6, -0.5, 0.9)))
    return s


@pytest.fixture(scope="module")
def wide(scene):
    return images_from_scene(scene, PinholeCamera.from_fov(600, 400, 130.0, 90.0), CENTRE, 0.0, "tof")


def radar(name="radar", pose=CENTRE, **kw):
    """The IWR6843 preset with a 128 x 128 px field-of-view render (120 x 120 deg), at the fixed
    synthesis tolerance eps = 1e-6 the checks below rely on (the default follows each frame's noise)."""
    return make_radar("ti_iwr6843", name=name, mount=None if pose is None else Mount(pose), render_width=128,
                      render_height=128, **{"eps": 1e-6, **kw})


RADAR_RENDER = PinholeCamera.from_fov(360, 360, 130.0, 130.0)  # holds the radar's 120 x 120 deg view


def tof_config(**kw):
    return tof_preset("pmd_pico_flexx", width=80, height=60, **kw)


def test_tof_same_grid_is_the_ray_cast_frame_bit_for_bit(scene):
    # Noise, quantisation and filters on: the same generator gives the same
    # draws, and identical surface samples give identical frames.
    cam = ToFCamera(tof_config(), Mount(CENTRE))
    n = cam.config.supersample
    grid = cam.pinhole.resized(cam.config.width * n, cam.config.height * n)
    images = images_from_scene(scene, grid, CENTRE, 0.0, "tof")
    ray = cam.capture(scene, 0.0, np.random.default_rng(7))
    ext = tof_from_images(cam, images, 0.0, np.random.default_rng(7), materials=scene.materials)
    for f in ("raw", "distance", "depth", "amplitude", "invalid", "confidence"):
        np.testing.assert_array_equal(getattr(ext, f), getattr(ray, f), err_msg=f)


def _edge_distance(distance):
    """Pixels (H, W) from the nearest depth edge (a step > 5 cm between neighbours)."""
    edge = np.zeros(distance.shape, bool)
    gy = np.abs(np.diff(distance, axis=0)) > 0.05
    gx = np.abs(np.diff(distance, axis=1)) > 0.05
    edge[:-1] |= gy
    edge[1:] |= gy
    edge[:, :-1] |= gx
    edge[:, 1:] |= gx
    return ndimage.distance_transform_edt(~edge)


@pytest.mark.parametrize("dy", [0.05, -0.05])
def test_transform_cut_tof_cameras_match_away_from_the_parallax_band(scene, wide, dy):
    # Noise and quantisation off: depth is then a deterministic function of
    # the surface samples. The parallax band is f b (1/z_near - 1/z_far)
    # = 66 px/rad * 0.05 m * (1/1.8 - 1/4) m^-1 = 1.0 ToF pixel; a mixed pixel
    # adds one and the flying-pixel filter's 3 x 3 window one more: pixels
    # more than 3 px from a depth edge must agree. There the sub-pixel hits
    # are exact (planes), so the depths agree to float32 phase rounding of
    # the 1.87 m unambiguous range (~1e-7 m per operation): 1e-4 m.
    cam = ToFCamera(tof_config(noise=False, quantization=False), Mount(shifted(dy)))
    ray = cam.capture(scene, 0.0, np.random.default_rng(0))
    ext = tof_from_images(cam, wide, 0.0, np.random.default_rng(0), materials=scene.materials)
    far = _edge_distance(ray.distance) > 3
    valid = (ray.invalid == 0) & far
    assert valid.sum() > 0.8 * far.sum()
    np.testing.assert_array_equal(ext.invalid[far] == 0, ray.invalid[far] == 0)
    np.testing.assert_allclose(ext.distance[valid], ray.distance[valid], rtol=0, atol=1e-4)


def test_radar_same_grid_gives_the_ray_cast_scatterers_and_peak(scene):
    r = radar("r")
    cam = ScatterRenderer(r.config).camera
    images = images_from_scene(scene, cam, CENTRE, 0.0, "radar")
    ray = r.capture(scene, 0.0, np.random.default_rng(3))
    ext = radar("e")
    fe = radar_from_images(ext, images, 0.0, np.random.default_rng(3), materials=scene.materials)
    a, b = ray.scatterers, fe.scatterers
    # The same rays meet the same surfaces: points, velocities and RCS to float64 rounding.
    np.testing.assert_allclose(b.points, a.points, rtol=0, atol=1e-9)
    np.testing.assert_allclose(b.velocities, a.velocities, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.rcs, a.rcs, rtol=1e-9, atol=1e-15)
    _same_peak(ray, fe, 0.01)  # synthesis eps 1e-6 -> 1e-5 dB; 0.01 dB covers the ADC rounding


def _peak(frame, r_min=0.5):
    p = frame.processed.power.copy()
    p[:, frame.processed.range_axis < r_min] = 0.0  # Tx-Rx leakage and DC
    k = np.unravel_index(np.argmax(p), p.shape)
    return k, 10 * np.log10(p[k])


def _same_peak(f1, f2, tol_db):
    (k1, p1), (k2, p2) = _peak(f1), _peak(f2)
    assert k1 == k2
    assert abs(p1 - p2) <= tol_db
    return k1


def test_transform_cut_radar_peak_and_the_difference_is_the_band_rows(scene):
    # The radar sits 4 cm off the render centre. Every ray hits (the wall
    # fills the view), so rows are pixels in both paths. Rows that differ
    # are those of the parallax band; by linearity of the IF synthesis the
    # noise-free IF difference between the two frames is the synthesis of
    # those rows alone (to the synthesis' relative accuracy eps = 1e-6 of
    # the cube's amplitude: 1e-5 relative). The peak power may then differ by
    # at most 20 log10(1 + sqrt(P_d / P)) dB, P_d the band rows' power at the
    # peak (triangle inequality on the channel vector, whose mean square is
    # the map).
    pose = shifted(0.04)
    images = images_from_scene(scene, RADAR_RENDER, CENTRE, 0.0, "radar")
    ray = radar("r", pose).capture(scene, 0.0, np.random.default_rng(5))
    ext = radar_from_images(radar("e", pose), images, 0.0,
                            np.random.default_rng(5), materials=scene.materials)
    a, b = ray.scatterers, ext.scatterers
    assert len(a) == len(b)
    diff = np.flatnonzero((np.abs(a.points - b.points).max(axis=1) > 1e-9) | (np.abs(a.rcs - b.rcs) > 1e-12 * a.rcs))
    assert 0 < len(diff) < 0.02 * len(a)  # the band: a few hundred of 16384 pixels at most
    plain = FMCWRadar(radar().config, reuse_static=False, process=False, eps=1e-6)
    part_a = plain.capture_scatterers(a.take(diff), 0.0, np.random.default_rng(0)).signal
    part_b = plain.capture_scatterers(b.take(diff), 0.0, np.random.default_rng(0)).signal
    d_frames = ray.signal - ext.signal
    np.testing.assert_allclose(d_frames, part_a - part_b, rtol=0, atol=1e-5 * np.abs(ray.signal).max())
    k, _ = _peak(ray)
    p_d = plain.process_cube(part_a - part_b).power[k]
    p_sig = plain.process_cube(ray.signal).power[k]
    bound = 20 * np.log10(1 + np.sqrt(p_d / p_sig))
    _same_peak(ray, ext, bound + 0.01)


def test_transform_cut_serves_two_cameras_and_a_radar_from_one_render(scene, wide):
    # One render, three sensors: each cut keeps its own extrinsics (the
    # cameras' distance images differ by the 10 cm baseline's disparity).
    left = tof_from_images(ToFCamera(tof_config(noise=False), Mount(shifted(0.05)), name="l"), wide,
                           materials=scene.materials)
    right = tof_from_images(ToFCamera(tof_config(noise=False), Mount(shifted(-0.05)), name="r"), wide,
                            materials=scene.materials)
    assert not np.array_equal(left.distance, right.distance)
    assert left.pose.position[1] == pytest.approx(0.05, rel=0, abs=1e-12)
    radar_images = images_from_scene(scene, RADAR_RENDER, CENTRE, 0.0, "radar")
    frame = radar_from_images(radar("r", shifted(0.02)), radar_images,
                              materials=scene.materials)
    # The moving box (closing at 1 m/s along the boresight) is the strongest return.
    k, _ = _peak(frame)
    v = frame.processed.velocity_axis[k[0]]
    assert v == pytest.approx(-1.0, rel=0, abs=frame.processed.velocity_axis[1] - frame.processed.velocity_axis[0])


def test_bad_sensor_calls_name_the_field(scene, wide):
    cam = ToFCamera(tof_config(motion_artifacts=True), Mount(CENTRE))
    with pytest.raises(ConfigError, match="motion_artifacts"):
        tof_from_images(cam, wide)
    rides = ToFCamera(tof_config(), Mount(Pose(), parent="box"))
    with pytest.raises(ConfigError) as e:
        tof_from_images(rides, wide)
    assert e.value.field == "pose"
    with pytest.raises(ConfigError) as e:
        tof_from_images(ToFCamera(tof_config(), Mount(CENTRE)), wide, materials=[])
    assert e.value.field == "materials"
    with pytest.raises(ConfigError) as e:
        tof_from_images(ToFCamera(tof_config()), np.zeros((4, 4)))
    assert e.value.field == "images"
    with pytest.raises(ConfigError, match="multipath"):
        radar_from_images(radar(multipath=True), wide)
    with pytest.raises(ConfigError) as e:
        radar_from_images(radar(), wide, t=float("inf"))
    assert e.value.field == "t"
    with pytest.raises(ConfigError) as e:
        radar_from_images(radar(), wide, reflectivity=-1.0)
    assert e.value.field == "reflectivity"
