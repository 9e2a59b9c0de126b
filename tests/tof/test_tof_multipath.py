"""One-bounce indirect light against an independent quadrature over the lit wall."""

from __future__ import annotations

import math

import numpy as np

from twinsense.constants import SPEED_OF_LIGHT as C_LIGHT
from twinsense.scene import Box, Pose, Scene
from twinsense.tof import ToFCamera
from twinsense.tof.multipath import indirect_phasors
from twinsense.tof.signal import beam_profile

R2 = math.sqrt(0.5)
CORNER = np.array([2.0, 0.0, 0.0])


def _corner():
    s = Scene()
    s.add_object("left", Box((0.02, 3.0, 3.0)), "drywall",
                 pose=Pose.from_euler_deg(CORNER + 1.5 * np.array([-R2, R2, 0]) + 0.01 * np.array([R2, R2, 0]),
                                          (0, 0, 45.0)))
    s.add_object("right", Box((0.02, 3.0, 3.0)), "drywall",
                 pose=Pose.from_euler_deg(CORNER + 1.5 * np.array([-R2, -R2, 0]) + 0.01 * np.array([R2, -R2, 0]),
                                          (0, 0, -45.0)))
    return s


def test_indirect_light_matches_quadrature(look_x, small_config):
    cfg = small_config(width=21, height=15, fov_deg=(50.0, 36.0), supersample=1, multipath=True,
                       multipath_vpl_grid=(21, 15), multipath_stride=1)
    cam = ToFCamera(cfg, look_x)
    scene = _corner()
    pose = look_x
    samples, normals = cam._renderer.samples(scene, pose.rotation, pose.position, 0.0, normals=True)
    ind = indirect_phasors(samples.distance, normals, samples.albedo, cam.radiometry, None)

    # Reference: receiver = the surface point seen by pixel (7, 3) on the left wall; sources =
    # every point of the right wall inside the camera's view, lit by the beam, Lambertian.
    row, col = 7, 3
    d_pix = cam.pinhole.directions(1)[row, col]
    x_s = d_pix * samples.distance[row, col]  # sensor frame
    x = pose.apply(x_s[None])[0]
    n_x = np.array([-R2, -R2, 0.0])  # left wall faces the camera
    n_y = np.array([-R2, R2, 0.0])  # right wall faces the camera
    albedo = 0.8
    # Midpoint rule, 2 mm cells over the right wall (3 m along, +-1.5 m high).
    a = (np.arange(1500) + 0.5) * 2e-3
    z = (np.arange(1500) + 0.5) * 2e-3 - 1.5
    aa, zz = np.meshgrid(a, z, indexing="ij")
    y = CORNER + aa[..., None] * np.array([-R2, -R2, 0]) + zz[..., None] * np.array([0, 0, 1.0])
    y_s = pose.inverse().apply(y.reshape(-1, 3))
    uv = cam.pinhole.project(y_s)
    seen = ((uv[:, 0] >= -0.5) & (uv[:, 0] <= cfg.width - 0.5) & (uv[:, 1] >= -0.5)
            & (uv[:, 1] <= cfg.height - 0.5) & (y_s[:, 2] > 0))
    y, y_s = y.reshape(-1, 3)[seen], y_s[seen]
    d_y = np.linalg.norm(y_s, axis=1)
    u_y = y_s / d_y[:, None]
    cos_src = np.abs(u_y @ pose.inverse().apply_vectors(n_y[None])[0])
    e_y = cfg.illumination_power * beam_profile(u_y, cfg.illumination_fwhm_deg) * cos_src / d_y ** 2
    v = x - y
    r = np.linalg.norm(v, axis=1)
    cos_y = (v @ n_y) / r
    cos_x = -(v @ n_x) / r
    e_x = albedo * e_y / math.pi * cos_y * cos_x / r ** 2 * 4e-6  # irradiance at x [W/m^2]
    k = 2 * math.pi * cfg.modulation_frequencies[0] / C_LIGHT
    path = d_y + r + np.linalg.norm(x_s)
    gain = cam.radiometry.camera_gain[row, col] * albedo
    ref = gain * np.sum(e_x * np.exp(1j * k * path))
    got = ind.real[0, row, col] + 1j * ind.imag[0, row, col]
    # The VPL sum is a midpoint rule with one light per pixel (~8 cm cells 1.5-2.5 m away
    # from x): its error is O((cell/distance)^2) ~ 1e-3; 2 % covers the pinhole solid-angle
    # approximation at the image border and float32 sums.
    assert abs(got - ref) < 0.02 * abs(ref)
    np.testing.assert_allclose(ind.tap_sum[row, col], gain * np.sum(e_x), rtol=0.02)
