"""External images -> hits: re-projection against closed forms, holes, parallax, bad input."""

import numpy as np
import pytest

from twinsense import ConfigError, PinholeCamera, Pose, Rays
from twinsense.render.external import ExternalImages, images_to_hits, read_image

W, H = 120, 90
CAM = PinholeCamera.from_fov(W, H, 90.0)
K = (CAM.fx, CAM.fy, CAM.cx, CAM.cy)
RENDER_POSE = Pose.look_at((0.0, 0.0, 1.0), (3.0, 0.0, 1.0))  # looks along world +x


def plane_images(normal_cam, offset, depth_kind="range", cam=CAM, pose=RENDER_POSE):
    """Images of the plane n . p = offset (render camera frame), computed in closed form."""
    n = np.asarray(normal_cam, float) / np.linalg.norm(normal_cam)
    d = cam.directions(1)  # (H, W, 3) unit rays
    r = offset / (d @ n)  # range along each ray
    depth = r if depth_kind == "range" else r * d[..., 2]
    return ExternalImages(depth, np.full(depth.shape, 0.4), (cam.fx, cam.fy, cam.cx, cam.cy, *cam.distortion),
                          pose, 0.0, depth_kind)


def ray_plane(o, d, n_world, p0):
    return ((p0 - o) @ n_world) / (d @ n_world)


@pytest.mark.parametrize("depth_kind", ["range", "z"])
def test_bilinear_inverse_depth_is_exact_on_a_tilted_plane_from_an_offset_sensor(depth_kind):
    # 1/z is affine in the image coordinates on a plane, so its bilinear
    # interpolation is exact, and the fixed point lands on the plane itself:
    # the only error is float64 rounding (1e-12 relative), 1e-9 m leaves room.
    n_cam = np.array([0.3, -0.2, -1.0])
    images = plane_images(n_cam, -2.5, depth_kind)
    rot = RENDER_POSE.rotation
    n_world = rot @ (n_cam / np.linalg.norm(n_cam))
    p0 = RENDER_POSE.apply(np.array([[0.0, 0.0, 2.5 / abs(n_cam[2] / np.linalg.norm(n_cam))]]))[0]
    p0 = RENDER_POSE.position + rot @ (n_cam / np.linalg.norm(n_cam) * -2.5)
    sensor = Pose.look_at((0.0, 0.06, 1.04), (3.0, 0.1, 1.1))  # 7 cm off the render centre, turned
    rays = PinholeCamera.from_fov(37, 23, 50.0).rays(sensor)
    ih = images_to_hits(images, rays)
    want = ray_plane(rays.origins, rays.directions, n_world, p0)
    assert ih.hits.hit.all()
    np.testing.assert_allclose(ih.hits.distance, want, rtol=0, atol=1e-9)
    # The normal derived from the depth image is the plane's (one-sided differences on one plane).
    cos = np.abs(rays.directions @ n_world)
    np.testing.assert_allclose(ih.hits.cos_incidence, cos, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ih.albedo, 0.4, rtol=0, atol=1e-12)


def test_nearest_sampling_stays_within_its_half_pixel_bound():
    # Nearest sampling reads 1/z at a pixel centre up to half a pixel away:
    # |dx|, |dy| <= 0.5 / f in normalised coordinates. On the plane
    # n . p = off, 1/z = (n_x x + n_y y + n_z) / off exactly, so the sampled
    # z' = z / (1 + e) with |e| <= z (|n_x| + |n_y|) / (2 f |off|), and the
    # range error is r |e| / (1 - |e|) at most (exact, no expansion).
    n_cam = np.array([0.5, 0.0, -1.0])
    n_cam = n_cam / np.linalg.norm(n_cam)
    off = -2.0
    images = plane_images(n_cam, off)
    rays = PinholeCamera.from_fov(31, 21, 60.0).rays(RENDER_POSE)
    ih = images_to_hits(images, rays, sampling="nearest")
    rot = RENDER_POSE.rotation
    n_world = rot @ n_cam
    p0 = RENDER_POSE.position + n_world * off
    want = ray_plane(rays.origins, rays.directions, n_world, p0)
    z = want * (rays.directions @ rot[:, 2])
    e = z * (abs(n_cam[0]) + abs(n_cam[1])) / (2 * CAM.fx * abs(off))
    bound = want * e / (1 - e) * (1 + 1e-9)
    err = np.abs(ih.hits.distance - want)
    assert (err <= bound).all()
    assert err.max() > 0.1 * bound.max()  # the bound is not loose by orders of magnitude


def test_holes_outside_and_behind_are_misses():
    images = plane_images([0, 0, -1.0], -2.0)
    depth = np.array(images.depth)
    depth[10:20, 10:20] = np.inf  # a hole (sky)
    images = ExternalImages(depth, images.intensity, K, RENDER_POSE)
    o = RENDER_POSE.position
    fwd, right = RENDER_POSE.rotation[:, 2], RENDER_POSE.rotation[:, 0]
    hole_dir = RENDER_POSE.rotation @ np.array([(15 - CAM.cx) / CAM.fx, (15 - CAM.cy) / CAM.fy, 1.0])
    dirs = np.array([fwd, -fwd, (right * 3 + fwd) / np.sqrt(10), hole_dir / np.linalg.norm(hole_dir)])
    hits = images_to_hits(images, Rays(o, dirs)).hits
    np.testing.assert_array_equal(hits.hit, [True, False, False, False])
    assert hits.distance[0] == pytest.approx(2.0, rel=0, abs=1e-12)
    assert np.isinf(hits.distance[1:]).all() and (hits.object_id[1:] == -1).all()


def test_parallax_misses_only_in_the_band_beside_a_depth_edge():
    # A near plate (z = 1 m) in front of a far wall (z = 3 m), both facing the
    # render. A sensor shifted b = 10 cm along x sees, beside the plate's edge,
    # the wall strip hidden from the render centre: angular width
    # b (1/z_near - 1/z_far) = 0.0667 rad. Only rays in that band miss, and
    # every other ray hits the closed-form surface (exact: planes).
    x, _ = CAM.pixel_normalised()
    z = np.where(np.abs(x) < 0.3, 1.0, 3.0)  # plate: |X| < 0.3 m at z = 1
    images = ExternalImages(z, np.full(z.shape, 0.5), K, Pose(), depth_kind="z")
    b = 0.10
    sensor = Pose((b, 0.0, 0.0))
    dirs = PinholeCamera.from_fov(200, 3, 70.0, 5.0).rays(sensor).directions
    hits = images_to_hits(images, Rays(sensor.position, dirs)).hits
    tx = dirs[:, 0] / dirs[:, 2]  # x/z of each ray from the sensor
    # Closed form: from the sensor the plate spans X in (-0.3, 0.3) at z=1, i.e. tx in (-0.3-b, 0.3-b).
    on_plate = np.abs(tx + b) < 0.3
    want = np.where(on_plate, 1.0, 3.0) * np.linalg.norm(dirs / dirs[:, 2:], axis=1)
    # The wall the sensor sees that the render centre does not: wall X = 3 tx + b
    # inside the plate's shadow |X| < 0.9 (= 0.3 * 3/1). For b > 0 it is the
    # strip beside the plate's right edge, tx in (0.3 - b, (0.9 - b)/3): in
    # slope units exactly b (1/z_near - 1/z_far) wide, as an angle less.
    shadow = ~on_plate & (np.abs(3 * tx + b) < 0.9)
    assert shadow.sum() > 3
    band = np.arctan(tx[shadow]) - np.arctan(0.3 - b)
    assert band.min() >= 0 and band.max() <= b * (1 / 1.0 - 1 / 3.0)
    assert not hits.hit[shadow].any()
    # Everything else: exact, except rays within one render pixel of the edge (nearest fallback).
    near_edge = np.min(np.abs(tx[:, None] - np.array([-0.3 - b, 0.3 - b, (-0.9 - b) / 3, (0.9 - b) / 3])),
                       axis=1) < 1.0 / CAM.fx
    ok = ~shadow & ~near_edge
    assert hits.hit[ok].all()
    np.testing.assert_allclose(hits.distance[ok], want[ok], rtol=1e-12, atol=0)


def test_velocity_and_material_are_taken_from_the_nearest_pixel():
    images = plane_images([0, 0, -1.0], -2.0)
    vel = np.zeros((H, W, 3))
    vel[:, W // 2:] = (0.0, 0.0, -1.5)
    mid = np.zeros((H, W), np.int32)
    mid[:, W // 2:] = 3
    images = ExternalImages(images.depth, images.intensity, K, RENDER_POSE, velocity=vel, material_id=mid)
    rays = CAM.rays(RENDER_POSE)
    h = images_to_hits(images, rays).hits
    np.testing.assert_array_equal(h.material_id.reshape(H, W), mid)
    np.testing.assert_array_equal(h.velocity.reshape(H, W, 3), vel)


# ---------------------------------------------------------------- bad input

GOOD = np.full((H, W), 2.0)


@pytest.mark.parametrize("kwargs, field", [
    ({"intensity": np.ones((H, W + 1))}, "images.intensity"),
    ({"depth": np.full((H, W), np.nan), "intensity": GOOD}, "images.depth"),
    ({"depth": -GOOD}, "images.depth"),
    ({"depth": 0 * GOOD}, "images.depth"),
    ({"depth": np.ones(5)}, "images.depth"),
    ({"depth": np.array([["a"]])}, "images.depth"),
    ({"intensity": -GOOD}, "images.intensity"),
    ({"intensity": GOOD * np.inf}, "images.intensity"),
    ({"depth_kind": "disparity"}, "images.depth_kind"),
    ({"intrinsics": (1.0, 2.0)}, "images.intrinsics"),
    ({"intrinsics": (-1.0, 2.0, 3.0, 4.0)}, "images.intrinsics"),
    ({"intrinsics": ("a", 2.0, 3.0, 4.0)}, "images.intrinsics"),
    ({"pose": np.eye(4)}, "images.pose"),
    ({"t": float("nan")}, "images.t"),
    ({"normals": np.ones((H, W, 3))}, "images.normals"),
    ({"normals": np.ones((H, W, 2))}, "images.normals"),
    ({"velocity": np.full((H, W, 3), np.nan)}, "images.velocity"),
    ({"material_id": np.zeros((H, W))}, "images.material_id"),
    ({"material_id": np.full((H, W), -2)}, "images.material_id"),
])
def test_bad_images_name_the_field(kwargs, field):
    args = {"depth": GOOD, "intensity": GOOD, "intrinsics": K, "pose": RENDER_POSE, **kwargs}
    with pytest.raises(ConfigError) as e:
        ExternalImages(**args)
    assert e.value.field == field


def test_bad_resampling_settings():
    images = plane_images([0, 0, -1.0], -2.0)
    rays = CAM.rays(RENDER_POSE)
    for kw, field in (({"sampling": "cubic"}, "sampling"), ({"edge_tolerance": 0}, "edge_tolerance"),
                      ({"miss_tolerance_px": float("nan")}, "miss_tolerance_px")):
        with pytest.raises(ConfigError) as e:
            images_to_hits(images, rays, **kw)
        assert e.value.field == field
    with pytest.raises(ConfigError, match="rays"):
        images_to_hits(images, np.zeros((3, 3)))


def test_files_round_trip_and_refuse_bad_paths(tmp_path):
    vel = np.zeros((H, W, 3))
    vel[..., 0] = 0.5
    a = plane_images([0.2, 0, -1.0], -2.0)
    a = ExternalImages(a.depth, a.intensity, a.intrinsics, RENDER_POSE, 0.25, "range", velocity=vel,
                       material_id=np.ones((H, W), np.int32))
    path = a.save(tmp_path / "render.npz")
    b = ExternalImages.load(path)
    for f in ("depth", "intensity", "velocity", "material_id"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert b.intrinsics == a.intrinsics and b.t == 0.25 and b.depth_kind == "range"
    np.testing.assert_allclose(b.pose.matrix, a.pose.matrix, rtol=0, atol=1e-15)
    assert [p.name for p in tmp_path.iterdir()] == ["render.npz"]  # no part file left
    np.save(tmp_path / "d.npy", a.depth.astype(np.float32))
    np.testing.assert_array_equal(read_image(tmp_path / "d.npy"), a.depth.astype(np.float32))
    from PIL import Image

    Image.fromarray(a.depth.astype(np.float32)).save(tmp_path / "d.tiff")
    np.testing.assert_array_equal(read_image(tmp_path / "d.tiff"), a.depth.astype(np.float32))
    for bad in (tmp_path / "missing.npz", tmp_path / "d.npy"):
        with pytest.raises(ConfigError) as e:
            ExternalImages.load(bad)
        assert e.value.field == "path"
    with pytest.raises(ConfigError, match="npz"):
        a.save(tmp_path / "x.npy")
    with pytest.raises(ConfigError):
        read_image(tmp_path / "missing.npy")


@pytest.mark.parametrize("sampling", ["bilinear", "nearest"])
def test_compiled_reprojection_matches_the_numpy_reference(sampling):
    # The same steps in the same float64 arithmetic; the compiled loop stops
    # each ray's polish on its own (NumPy when all rays have converged), so
    # distances agree to the polish's stopping rule (1e-12 relative) and the
    # hit sets are identical. A distorted render, a depth edge, a hole, rays
    # from the centre and from 8 cm aside.
    cam = PinholeCamera(160, 120, 90.0, 92.0, 80.3, 59.1, (0.05, -0.02, 0.001, -0.002, 0.0))
    x, y = cam.pixel_normalised()
    z = np.where(np.abs(x) < 0.25, 1.2, 2.5 + 0.3 * y)
    z[5:12, 5:12] = np.inf
    images = ExternalImages(z, 0.3 + 0.1 * (x > 0), (cam.fx, cam.fy, cam.cx, cam.cy, *cam.distortion), RENDER_POSE,
                            depth_kind="z")
    for sensor in (RENDER_POSE, Pose.look_at((0.0, -0.08, 1.02), (3.0, 0.1, 1.0))):
        rays = PinholeCamera.from_fov(90, 70, 70.0).rays(sensor)
        a = images_to_hits(images, rays, sampling=sampling)
        b = images_to_hits(images, rays, sampling=sampling, compiled=False)
        np.testing.assert_array_equal(a.hits.hit, b.hits.hit)
        hit = a.hits.hit
        assert hit.mean() > 0.5
        np.testing.assert_allclose(a.hits.distance[hit], b.hits.distance[hit], rtol=1e-11, atol=0)
        np.testing.assert_allclose(a.albedo, b.albedo, rtol=0, atol=1e-12)
        for f in ("point", "normal", "cos_incidence", "velocity"):
            np.testing.assert_allclose(getattr(a.hits, f)[hit], getattr(b.hits, f)[hit], rtol=0, atol=1e-9,
                                       err_msg=f)
        np.testing.assert_array_equal(a.hits.material_id, b.hits.material_id)
        np.testing.assert_array_equal(a.hits.object_id, b.hits.object_id)
