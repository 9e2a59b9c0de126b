"""A ToF camera moving during its raw frames, against the closed form of the four-phase estimate.

Each raw frame (frequency f, phase step i) is rendered at the middle of its own exposure t_fi, from the
camera's pose then. A camera closing on a wall at v along its boresight sees, in a pixel whose ray
makes cos(theta) = u_z with the boresight, the distance d(t) = (D - v t) / u_z, so the tap difference
of raw frame (f, i) is A(t) cos(4 pi f d(t_fi) / c + i pi / 2) with A ~ 1 / d^2 (the camera's own
light on a Lambertian wall). The camera demodulates phi_f = atan2(D3 - D1, D0 - D2), unwraps the two
frequencies and averages them with weights f^2 / sum f^2 (docs/tof-chain.md). The closed form here
does the same on the ideal samples; the artefact is the estimate's shift from the still camera's
(the same closed form at v = 0), which takes out most of the pixel's sub-pixel spread. What is left:
float32 images at ~1.5 m (ulp 1.2e-7 m) after a float32 chain (arctan2 to a few ulp of 2 pi), 1e-6 m;
and the closed form's one ray per pixel where the camera sums 2 x 2 sub-pixel phasors whose 1 / u_z
spread by ~1 % off axis (a 1.4 deg pixel 30 deg out), which moves the shift by a second-order share,
2.4e-4 of it at most seen over the image: so within 2e-6 m + 5e-4 of the shift. The shift is 4.2 to
11.6 mm here (2.1 mm per m/s on axis, / u_z off it); one render at the mean raw-frame time instead
would be 25 % larger.
"""

import numpy as np
import pytest

from twinsense.scene import Box, ConstantVelocity, Frame, Mount, Pose, Scene
from twinsense.tof.camera import ToFCamera

C = 299_792_458.0
D = 1.5  # [m] the wall's face ahead of the camera at t = 0


def _camera_and_scene(v: float, motion: bool = True) -> tuple[ToFCamera, Scene]:
    scene = Scene()
    scene.add_object("wall", Box((6.0, 6.0, 0.02)), material="drywall", pose=Pose((0.0, 0.0, D + 0.01)))
    scene.add_frame(Frame("cart", ConstantVelocity(Pose(), velocity=(0.0, 0.0, v))))
    cam = ToFCamera.preset("pmd_pico_flexx", mount=Mount(Pose(), "cart"), width=45, height=34, noise=False,
                           quantization=False, crosstalk_sigma_px=0.0, flying_pixel_filter=False,
                           noise_filter=False, motion_artifacts=motion)
    return cam, scene


def _closed_form(cam: ToFCamera, v: float, u_z: float, near: float) -> float:
    cfg = cam.config
    times = cfg.raw_frame_times(0.0) + 0.5 * cfg.exposure_time
    freqs = np.asarray(cfg.modulation_frequencies)
    unwrapped = []
    for k, f in enumerate(freqs):
        d = (D - v * times[4 * k:4 * k + 4]) / u_z
        taps = np.cos(4 * np.pi * f * d / C + np.arange(4) * np.pi / 2) / d ** 2
        phi = np.arctan2(taps[3] - taps[1], taps[0] - taps[2]) % (2 * np.pi)
        wrapped, period = phi * C / (4 * np.pi * f), C / (2 * f)
        unwrapped.append(wrapped + period * np.round((near - wrapped) / period))
    return float(np.dot(freqs ** 2 / np.sum(freqs ** 2), unwrapped))


def test_a_still_camera_has_no_motion_artefact():
    cam, scene = _camera_and_scene(0.0)
    once, _ = _camera_and_scene(0.0, motion=False)
    a, b = cam.capture(scene, 0.0, np.random.default_rng(0)), once.capture(scene, 0.0, np.random.default_rng(0))
    assert np.all(a.invalid == 0)
    # Nine renders of one pose against one: the same sub-pixel phasors up to float32 rounding (2 ulp).
    np.testing.assert_allclose(a.distance, b.distance, rtol=0, atol=2.5e-7)


@pytest.mark.parametrize("v", [1.0, -2.0])
def test_a_camera_closing_on_a_wall_during_its_raw_frames(v):
    still_cam, still_scene = _camera_and_scene(0.0)
    still = still_cam.capture(still_scene, 0.0, np.random.default_rng(0))
    cam, scene = _camera_and_scene(v)
    frame = cam.capture(scene, 0.0, np.random.default_rng(0))
    for i, j in ((17, 22), (5, 8), (30, 40)):
        ray = still.points_sensor[i, j] / np.linalg.norm(still.points_sensor[i, j])
        near = float(still.distance[i, j])
        expect = _closed_form(cam, v, ray[2], near) - _closed_form(cam, 0.0, ray[2], near)
        got = float(frame.distance[i, j]) - near
        assert abs(expect) > 2e-3 * abs(v)  # the motion is there: 2.1 mm per m/s
        assert got == pytest.approx(expect, rel=0, abs=2e-6 + 5e-4 * abs(expect))
