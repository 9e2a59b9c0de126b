"""Ray generation: pinhole intrinsics, FOV, distortion inversion, supersampling, orthographic."""

import numpy as np
import pytest

from twinsense import ConfigError, OrthographicCamera, PinholeCamera, Pose

PICO = PinholeCamera(224, 171, 213.08, 213.48, 106.31, 87.48, (0.0656, -2.146, 0.0005, -0.0033, 3.229))


@pytest.mark.parametrize("cam", [PinholeCamera(64, 48, 50.0, 52.0, 31.2, 24.1),
                                 PICO], ids=["ideal", "pico_flexx_distorted"])
@pytest.mark.parametrize("n", [1, 2, 3])
def test_directions_project_back_to_subpixel_centres(cam, n):
    # Projecting each ray (forward OpenCV model) must land on its sub-pixel
    # centre. Newton converges to 1e-13 in normalised coordinates, i.e.
    # ~2e-11 px: 1e-8 px leaves margin for rounding.
    d = cam.directions(n)
    uv = cam.project(d.reshape(-1, 3)).reshape(cam.height * n, cam.width * n, 2)
    u = (np.arange(cam.width * n) + 0.5) / n - 0.5
    v = (np.arange(cam.height * n) + 0.5) / n - 0.5
    np.testing.assert_allclose(uv[..., 0], np.broadcast_to(u, uv.shape[:2]), atol=1e-8)
    np.testing.assert_allclose(uv[..., 1], np.broadcast_to(v[:, None], uv.shape[:2]), atol=1e-8)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-12)


def test_supersample_groups_average_to_pixel_centre():
    cam = PinholeCamera(8, 6, 10.0, 10.0, 3.5, 2.5)
    x, _ = cam.pixel_normalised(2)
    # The 2 x 2 sub-pixels of each pixel are symmetric about its centre (no distortion).
    xm = x.reshape(6, 2, 8, 2).mean(axis=(1, 3))
    x1, _ = cam.pixel_normalised(1)
    np.testing.assert_allclose(xm, x1, atol=1e-15)


def test_fov_spans_the_image():
    cam = PinholeCamera.from_fov(200, 100, 90.0, 60.0)
    d = cam.directions(1)
    # Edge pixels' centres are half a pixel inside the FOV edge.
    half = np.degrees(np.arctan2(d[50, -1, 0], d[50, -1, 2]))
    assert 44.0 < half < 45.0
    assert np.isclose(np.degrees(np.arctan(0.5 * 100 / cam.fy)), 30.0)


def test_rays_follow_pose():
    cam = PinholeCamera.from_fov(5, 5, 40.0)
    pose = Pose.look_at((1, 2, 3), (1, 2, 10), up=(0, -1, 0))
    r = cam.rays(pose)
    np.testing.assert_allclose(r.origins, np.broadcast_to([1, 2, 3], (25, 3)))
    np.testing.assert_allclose(r.directions[12], [0, 0, 1], atol=1e-12)  # centre pixel on boresight


def test_orthographic_rays():
    cam = OrthographicCamera(4, 2, 2.0, 1.0)
    r = cam.rays(Pose.look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0)))
    np.testing.assert_allclose(r.directions, np.broadcast_to([0, 0, -1], (8, 3)), atol=1e-12)
    assert np.isclose(np.ptp(r.origins[:, 0]), 1.5) and np.allclose(r.origins[:, 2], 5)


@pytest.mark.parametrize("make, match", [
    (lambda: PinholeCamera(0, 10, 1.0, 1.0, 0.0, 0.0), "camera.width"),
    (lambda: PinholeCamera(10, 10, -1.0, 1.0, 0.0, 0.0), "camera.fx"),
    (lambda: PinholeCamera(10, 10, 1.0, 1.0, 0.0, 0.0, (0, 0, 0)), "camera.distortion"),
    (lambda: PinholeCamera.from_fov(10, 10, 190.0), "camera.hfov_deg"),
    (lambda: PinholeCamera.from_fov(10, 10, 60.0).directions(0), "supersample"),
])
def test_bad_cameras(make, match):
    with pytest.raises(ConfigError, match=match):
        make()
