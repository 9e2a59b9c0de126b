"""Radar equation and mirror losses against closed forms computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.radar import (
    ScatterRenderer,
    preset_config,
    radar_equation_amplitude,
    received_amplitude,
)
from twinsense.radar.radiometry import backscatter_rcs
from twinsense.scene import ConstantVelocity, Material, Mount, Plane, Pose, Scene, SceneObject


def test_radar_equation_in_decibels():
    # Skolnik's radar equation in its dB form, summed term by term:
    # P_r[dBm] = P_t[dBm] + G_t + G_r + 20 log(lambda) + 10 log(sigma) - 30 log(4 pi) - 40 log(R).
    # P_t = 10 dBm (10 mW), G_t = G_r = 10 dBi, lambda = 5 mm, sigma = 1 m^2, R = 10 m:
    # 10 + 10 + 10 - 46.0206 + 0 - 32.9763 - 40 = -88.9969 dBm.
    p_r_dbm = 10 + 10 + 10 + 20 * math.log10(5e-3) - 30 * math.log10(4 * math.pi) - 40
    assert p_r_dbm == pytest.approx(-88.9969, abs=1e-4)
    a = radar_equation_amplitude(10e-3, 5e-3, np.array([100.0]), np.array([1.0]), np.array([10.0]))
    # A = sqrt(2 P_r) [sqrt(W)]; the dB sum and the product agree to rounding (1e-12).
    assert a[0] == pytest.approx(math.sqrt(2 * 1e-3 * 10 ** (p_r_dbm / 10)), rel=1e-12, abs=0)
    # Bistatic: R^4 -> R_t^2 R_r^2, here 20 log(2) + 20 log(3) instead of 40 log(10).
    bi_dbm = p_r_dbm + 40 - 20 * math.log10(2.0) - 20 * math.log10(3.0)
    a = radar_equation_amplitude(10e-3, 5e-3, np.array([100.0]), np.array([1.0]), np.array([2.0]),
                                 np.array([3.0]))
    assert a[0] == pytest.approx(math.sqrt(2 * 1e-3 * 10 ** (bi_dbm / 10)), rel=1e-12, abs=0)
    # A point at an element's origin returns nothing (no division by zero).
    assert radar_equation_amplitude(1.0, 5e-3, np.ones(1), np.ones(1), np.zeros(1))[0] == 0.0


# ---------------------------------------------------------------- second bounce

H = 1.0  # radar height above the mirror floor z = 0 [m]
D = 3.0  # the plate's plane x = D [m]
PLATE_Y, PLATE_Z = (-0.6, 0.6), (0.2, 1.4)  # its extent [m]
GAMMA = 0.7  # the floor's specular share = mirror power reflectance
RHO = 0.3  # the plate's (Lambertian) reflectivity
POSE = Pose.look_at((0.0, 0.0, H), (D, 0.0, H - D * math.tan(math.radians(20.0))))
V_PLATE = np.array([0.4, -0.3, 0.5])  # the plate's velocity [m/s] (where it is at t = 0)


def _mirror_scene() -> Scene:
    floor = SceneObject("floor", Plane((20.0, 20.0)),
                        Material("test_mirror_floor", radar_reflectivity=0.05,
                                 radar_specular=GAMMA), Pose())
    # Local x -> world z, local y -> world y, normal (local z) -> world -x: facing the radar.
    rot = np.column_stack([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    plate = SceneObject("plate", Plane((PLATE_Z[1] - PLATE_Z[0], PLATE_Y[1] - PLATE_Y[0])),
                        Material("test_lambert_plate_2", radar_reflectivity=RHO, radar_specular=0.0),
                        ConstantVelocity(Pose((D, 0.0, 0.5 * sum(PLATE_Z)), rot), tuple(V_PLATE)))
    return Scene([floor, plate])


def _expected_second_bounce(cfg):
    """Per pixel whose ray meets the floor and then the plate: (pixel, unfolded range R,
    RCS of the plate patch) by hand, from the pinhole geometry and the image method."""
    w, h = cfg.render_width, cfg.render_height
    fx = 0.5 * w / math.tan(math.radians(cfg.hfov_deg) / 2)
    fy = 0.5 * h / math.tan(math.radians(cfg.vfov_deg) / 2)
    v, u = np.mgrid[0:h, 0:w]
    d = np.stack([(u - (w - 1) / 2) / fx, (v - (h - 1) / 2) / fy, np.ones(u.shape)], -1)
    d = d.reshape(-1, 3) / np.linalg.norm(d.reshape(-1, 3), axis=1, keepdims=True)
    # Pixel solid angle: focal-plane area 1/(fx fy) at distance 1/cos, tilted by cos: cos^3/(fx fy).
    omega = d[:, 2] ** 3 / (fx * fy)
    dw = d @ POSE.rotation.T
    down = dw[:, 2] < 0
    t1 = np.where(down, H / np.where(down, -dw[:, 2], 1.0), np.inf)  # to the floor
    p1 = POSE.position + t1[:, None] * dw
    refl = dw * [1.0, 1.0, -1.0]  # mirror direction off the floor
    with np.errstate(divide="ignore", invalid="ignore"):
        t2 = (D - p1[:, 0]) / refl[:, 0]
        p2 = p1 + t2[:, None] * refl  # NaN for rays that never meet the floor
    # Interior of the plate only (1 cm from its edges: pixels cut by an edge
    # are in or out by float32 hit tests, not by this geometry).
    m = 0.01
    inside = (down & (t2 > 0) & (p2[:, 1] > PLATE_Y[0] + m) & (p2[:, 1] < PLATE_Y[1] - m)
              & (p2[:, 2] > PLATE_Z[0] + m) & (p2[:, 2] < PLATE_Z[1] - m))
    pix = np.flatnonzero(inside)
    r = t1[pix] + t2[pix]
    # Lambert patch: sigma = rho cos(theta) Omega R^2, cos(theta) = |refl . (-x)| on the plate,
    # the footprint set by the unfolded range R (the image method's straight ray).
    sigma = RHO * refl[pix, 0] * omega[pix] * r**2
    return pix, d[pix], r, sigma, (fx, fy, w, h)


def test_second_bounce_rcs_and_amplitude_by_hand():
    cfg = preset_config("paper_bgt60tr13c", render_width=160, render_height=80, multipath=True)
    scene = _mirror_scene()
    scat = ScatterRenderer(cfg).render(scene, Mount(POSE).state_at(scene, 0.0), 0.0)
    pix, d, r, sigma, (fx, fy, w, h) = _expected_second_bounce(cfg)
    assert len(pix) > 200

    def pixel_of(points):
        return (np.rint(fy * points[:, 1] / points[:, 2] + (h - 1) / 2) * w
                + np.rint(fx * points[:, 0] / points[:, 2] + (w - 1) / 2)).astype(int)

    two = np.flatnonzero((scat.bounces == 2) & (scat.object_id == 1))
    same = np.all(scat.points[two] == scat.points_rx[two], axis=1)
    back, mixed = two[same], two[~same]
    # Out and back (tx -> floor -> plate -> floor -> rx): both legs end on the image
    # P2' = R d (the unfolded ray), and the mirror loss enters twice: Gamma^2 sigma.
    where = {p: i for i, p in enumerate(pixel_of(scat.points[back]))}
    rows = back[[where[p] for p in pix]]
    # Tolerance: the bounce ray starts 1e-6 m off the floor and the hit distances
    # are float64-refined planes (~1e-12 m): R is good to ~1e-6 m of 3-5 m, so
    # R^2 (and sigma) to ~7e-7; 1e-5 covers it, and Gamma instead of Gamma^2 is 43 % off.
    np.testing.assert_allclose(scat.points[rows], r[:, None] * d, rtol=0, atol=1e-5)
    np.testing.assert_allclose(scat.rcs[rows], GAMMA**2 * sigma, rtol=1e-5, atol=0)
    # The amplitude by hand: P_r = P_t G(P2')^2 lambda^2 Gamma^2 sigma / ((4 pi)^3 R^4), the
    # element gain 5 dBi cos(az) cos(el)^4.8 towards the image point.
    az = np.arctan2(d[:, 0], d[:, 2])
    el = np.arctan2(-d[:, 1], np.hypot(d[:, 0], d[:, 2]))
    g = 10**0.5 * np.cos(az) * np.cos(el) ** 4.8
    lam = SPEED_OF_LIGHT / 60e9
    p_r = 10**0.5 * 1e-3 * g * g * lam**2 * GAMMA**2 * sigma / ((4 * math.pi) ** 3 * r**4)
    amp = received_amplitude(scat.take(rows), cfg)
    # sigma to 1e-5 and R^-4 to ~1.3e-6: the amplitude (a square root) to < 1e-5.
    np.testing.assert_allclose(amp, np.sqrt(2 * p_r), rtol=1e-5, atol=0)

    # The image of a moving point moves as the point mirrored: (vx, vy, -vz) over the
    # floor z = 0, in sensor coordinates R^T v'.
    v_image = (V_PLATE * [1.0, 1.0, -1.0]) @ POSE.rotation
    np.testing.assert_allclose(scat.velocities[rows], np.tile(v_image, (len(rows), 1)),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(scat.velocities_rx[rows], scat.velocities[rows], rtol=0, atol=0)

    # The two mixed paths (tx -> plate -> floor -> rx and the reverse), plate seen
    # directly: one leg ends on P2, the other on P2'; one mirror hit, Gamma sigma.
    # The image leg is the longer one (P2' lies beyond the mirror).
    tx_on_image = (np.linalg.norm(scat.points[mixed], axis=1)
                   > np.linalg.norm(scat.points_rx[mixed], axis=1))[:, None]
    img = np.where(tx_on_image, scat.points[mixed], scat.points_rx[mixed])
    direct = np.where(tx_on_image, scat.points_rx[mixed], scat.points[mixed])
    # Either order once per pixel: tx on P2 and rx on P2', and the reverse.
    assert np.array_equal(np.bincount(pixel_of(img)[tx_on_image[:, 0]], minlength=w * h),
                          np.bincount(pixel_of(img)[~tx_on_image[:, 0]], minlength=w * h))
    count = np.bincount(pixel_of(img), minlength=w * h)
    assert np.all(count[pix] == 2)
    order = np.argsort(pixel_of(img), kind="stable")
    first = np.searchsorted(pixel_of(img)[order], pix)
    rows = np.stack([order[first], order[first + 1]], axis=1)  # (n, 2) indices into mixed
    np.testing.assert_allclose(scat.rcs[mixed][rows], GAMMA * sigma[:, None] * [1.0, 1.0],
                               rtol=1e-5, atol=0)
    # Their other leg ends on the plate itself, x = D in the world, and moves with it.
    np.testing.assert_allclose(POSE.apply(direct[rows[:, 0]])[:, 0], D, rtol=0, atol=1e-5)
    v_tx = np.where(tx_on_image, scat.velocities[mixed], scat.velocities_rx[mixed])
    v_rx = np.where(tx_on_image, scat.velocities_rx[mixed], scat.velocities[mixed])
    np.testing.assert_allclose(v_tx, np.tile(v_image, (len(mixed), 1)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(v_rx, np.tile(V_PLATE @ POSE.rotation, (len(mixed), 1)),
                               rtol=0, atol=1e-12)


def test_specular_lobe_scatters_as_much_as_the_diffuse_law():
    # sigma0(theta) = sigma / A with the footprint A = Omega R^2 / cos(theta); over the
    # hemisphere the diffuse law rho cos^2 integrates to rho 2 pi / 3, and the lobe
    # rho 2 / (3 theta_s^2) exp(-(theta / theta_s)^2) to the same, up to its small-angle
    # form: int exp(-theta^2/theta_s^2) sin(theta) dtheta = theta_s^2 / 2 (1 - theta_s^2 / 6 ...),
    # -0.51 % for theta_s = 10 deg. Tolerance 1 %.
    lobe = math.radians(10.0)
    theta = np.linspace(0.0, math.pi / 2, 20001)[:-1] + math.pi / 4 / 20000  # midpoints
    c = np.cos(theta)
    d_omega = 2 * math.pi * np.sin(theta) * (math.pi / 2 / 20000)
    ones = np.ones_like(theta)
    for spec in (0.0, 1.0):
        sigma = backscatter_rcs(2.0 * ones, c, 1e-4 * ones, 0.3 * ones, spec * ones, lobe)
        sigma0 = sigma * c / (1e-4 * 2.0**2)
        assert np.sum(sigma0 * d_omega) == pytest.approx(0.3 * 2 * math.pi / 3, rel=0.01, abs=0)
