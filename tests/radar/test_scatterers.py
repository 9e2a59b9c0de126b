"""Scene -> scatterers: radar equation, surface RCS, layers, relative motion."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.radar import (
    FMCWRadar,
    Scatterers,
    ScatterRenderer,
    preset_config,
    received_amplitude,
)
from twinsense.scene import (
    Box,
    ConstantVelocity,
    Material,
    Mount,
    Plane,
    Pose,
    Scene,
    SceneObject,
    Sphere,
)

# Sensor at the world origin looking along world +y, "up" world +z.
LOOK_Y = Pose.look_at((0.0, 0.0, 0.0), (0.0, 1.0, 0.0))


def test_amplitude_is_the_radar_equation():
    cfg = preset_config("paper_bgt60tr13c")
    az, el, r, rcs = math.radians(20), math.radians(10), 2.5, 0.3
    p = [[r * math.cos(el) * math.sin(az), -r * math.sin(el), r * math.cos(el) * math.cos(az)]]
    a = received_amplitude(Scatterers.point_targets(p, rcs), cfg)
    # Written out: element gain G0 cos(az)^1 cos(el)^4.8 (5 dBi) on Tx and on Rx.
    g = 10**0.5 * math.cos(az) * math.cos(el) ** 4.8
    lam = SPEED_OF_LIGHT / 60e9
    p_r = 10**0.5 * 1e-3 * g * g * lam**2 * rcs / ((4 * math.pi) ** 3 * r**4)
    assert a[0] == pytest.approx(math.sqrt(2 * p_r), rel=1e-12, abs=0)


def test_diffuse_plate_rcs_sums_to_the_surface_integral():
    rho, depth, sx, sz = 0.2, 1.5, 1.0, 0.6
    mat = Material("test_lambert_plate", radar_reflectivity=rho, radar_specular=0.0)
    # Plane normal +z rotated to face the sensor (-y), centred on boresight.
    plate = SceneObject("plate", Plane((sx, sz)), mat,
                        Pose.from_euler_deg((0.0, depth, 0.0), (90.0, 0.0, 0.0)))
    cfg = preset_config("paper_bgt60tr13c", render_width=600, render_height=300)
    st = Mount(LOOK_Y).state_at(None, 0.0)
    scat = ScatterRenderer(cfg).render(Scene([plate]), st, 0.0)
    # Lambert: sigma0 = rho cos^2(theta), so the plate's RCS is rho * integral
    # of cos^2 over its area, cos = D / sqrt(x^2 + z^2 + D^2).
    exact, _ = integrate.dblquad(lambda z, x: depth**2 / (x * x + z * z + depth**2),
                                 -sx / 2, sx / 2, -sz / 2, sz / 2)
    exact *= rho
    # One scatterer per pixel (0.2 deg ~ 5 mm at 1.5 m): edge pixels are in
    # or out by their centre, which over the 3.2 m perimeter is ~0.2 % of the
    # 0.6 m^2 area; 1 % covers it.
    assert scat.rcs.sum() == pytest.approx(exact, rel=0.01, abs=0)
    assert np.all(scat.object_id == 0)
    np.testing.assert_allclose(np.abs(scat.points[:, 2]), depth, atol=1e-9)


def _wall_scene(extra=()):
    wall = SceneObject("wall", Box((4.0, 0.1, 3.0)), "drywall", Pose(position=(0.0, 3.0, 0.0)))
    return Scene([wall, *extra])


def test_an_object_hidden_from_the_radar_leaves_the_cube_unchanged():
    radar = FMCWRadar.preset("paper_bgt60tr13c", render_width=200, render_height=68,
                             num_chirps=4, mount=Mount(LOOK_Y), process=False)
    ghost = SceneObject("ghost", Box((0.5, 0.5, 0.5)), "metal", Pose(position=(0.0, 1.5, 0.0)),
                        layers={"tof"})
    seen = SceneObject("seen", Box((0.5, 0.5, 0.5)), "metal", Pose(position=(0.0, 1.5, 0.0)))
    rng = np.random.default_rng
    base = radar.capture(_wall_scene(), 0.0, rng(1))
    hidden = radar.capture(_wall_scene([ghost]), 0.0, rng(1))
    shown = radar.capture(_wall_scene([seen]), 0.0, rng(1))
    np.testing.assert_array_equal(hidden.signal, base.signal)
    np.testing.assert_array_equal(hidden.adc, base.adc)
    assert not np.allclose(shown.signal, base.signal)


def test_velocities_are_relative_to_the_sensor_in_its_frame():
    v_obj = np.array([0.3, -0.8, 0.1])
    ball = SceneObject("ball", Sphere(0.2), "metal",
                       ConstantVelocity(Pose(position=(0.5, 2.0, 0.0)), v_obj))
    cfg = preset_config("paper_bgt60tr13c", render_width=120, render_height=40)
    rend = ScatterRenderer(cfg)
    scene = _wall_scene([ball])
    scat = rend.render(scene, Mount(LOOK_Y).state_at(scene, 0.0), 0.0)
    on_ball = scat.object_id == 1
    # World -> sensor frame: the rows of R^T.
    np.testing.assert_allclose(scat.velocities[on_ball], np.tile(v_obj @ LOOK_Y.rotation,
                                                                 (on_ball.sum(), 1)), atol=1e-12)
    np.testing.assert_allclose(scat.velocities[~on_ball], 0.0, atol=1e-12)

    # A radar riding on a cart (hidden from the radar) moving at v_cart sees
    # the static wall coming at -v_cart.
    v_cart = np.array([0.0, 1.2, 0.0])
    cart = SceneObject("cart", Box((0.2, 0.2, 0.2)), "plastic",
                       ConstantVelocity(Pose(position=(0.0, -0.5, 0.0)), v_cart),
                       layers={"capacitive"})
    scene2 = _wall_scene([cart])
    mount = Mount(Pose.look_at((0.0, 0.5, 0.0), (0.0, 1.5, 0.0)), parent="cart")
    scat2 = rend.render(scene2, mount.state_at(scene2, 0.0), 0.0)
    np.testing.assert_allclose(scat2.velocities, np.tile(-v_cart @ LOOK_Y.rotation,
                                                         (len(scat2), 1)), atol=1e-12)
