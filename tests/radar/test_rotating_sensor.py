"""A radar on a turntable: velocities of static targets from the sensor's rotation."""

from __future__ import annotations

import math

import numpy as np

from twinsense.radar import FMCWRadar, ScatterRenderer, preset_config
from twinsense.scene import Box, ConstantVelocity, Mount, Pose, Scene, SceneObject, Sphere

OMEGA = 3.0  # turntable spin about world +z [rad/s]
ARM = 1.0  # radar's distance from the spin axis [m]
HEIGHT = 0.5  # radar and targets above the turntable plane [m]
O = np.array([ARM, 0.0, HEIGHT])  # radar origin at t = 0 (the turntable starts at identity)
# Boresight 45 deg between radially out (+x) and the radar's own velocity (+y):
# targets to the left of boresight approach faster than those to the right.
MOUNT_POSE = Pose.look_at(tuple(O), tuple(O + np.array([1.0, 1.0, 0.0])))
TARGET_AZ_DEG = (-30.0, 0.0, 30.0)
TARGET_RANGE = (1.5, 2.0, 2.5)
RADIUS = 0.03


def _targets() -> np.ndarray:
    """(3, 3) world centres of the static targets at azimuth TARGET_AZ_DEG, range TARGET_RANGE."""
    out = []
    for az, r in zip(TARGET_AZ_DEG, TARGET_RANGE, strict=True):
        a = math.radians(az)
        d_sensor = np.array([math.sin(a), 0.0, math.cos(a)])  # x right, z boresight
        out.append(O + r * (MOUNT_POSE.rotation @ d_sensor))
    return np.array(out)


def _scene() -> Scene:
    # The turntable is hidden from the radar; only its motion matters.
    table = SceneObject("table", Box((0.2, 0.2, 0.05)), "plastic",
                        ConstantVelocity(Pose(), (0.0, 0.0, 0.0), (0.0, 0.0, OMEGA)),
                        layers={"capacitive"})
    balls = [SceneObject(f"ball{i}", Sphere(RADIUS), "corner_reflector", Pose(tuple(c)))
             for i, c in enumerate(_targets())]
    return Scene([table, *balls])


def test_static_points_seen_from_a_turning_radar_move_as_minus_omega_cross_r():
    cfg = preset_config("paper_bgt60tr13c", render_width=300, render_height=103)
    scene = _scene()
    state = Mount(MOUNT_POSE, parent="table").state_at(scene, 0.0)
    np.testing.assert_allclose(state.pose.position, O, atol=1e-15)
    scat = ScatterRenderer(cfg).render(scene, state, 0.0)
    assert len(scat) > 10
    # A static world point p seen from a frame that turns at omega about an axis
    # through the origin: in the rotating frame it moves at -omega x p (the
    # axis passes through the origin, so no lever-arm term is left), and in
    # sensor coordinates that is R^T (-omega x p).
    p_world = MOUNT_POSE.apply(scat.points)
    w = np.array([0.0, 0.0, OMEGA])
    expect = -np.cross(w, p_world) @ MOUNT_POSE.rotation
    # Float64 rounding of the pose products only (|v| ~ 10 m/s).
    np.testing.assert_allclose(scat.velocities, expect, rtol=0, atol=1e-12)
    # Radial velocity along the line of sight u from the radar origin O:
    # -(omega x p) . u = -(omega x O) . u, since (omega x (p - O)) . u = 0 -- only
    # the radar's own lever-arm motion changes the ranges.
    u = (p_world - O) / np.linalg.norm(p_world - O, axis=1, keepdims=True)
    radial = np.einsum("ij,ij->i", scat.velocities, scat.points) / np.linalg.norm(scat.points, axis=1)
    np.testing.assert_allclose(radial, -u @ np.cross(w, O), rtol=0, atol=1e-12)


def test_doppler_of_static_targets_seen_from_a_turning_radar():
    radar = FMCWRadar.preset("paper_bgt60tr13c", render_width=300, render_height=103,
                             mount=Mount(MOUNT_POSE, parent="table"))
    frame = radar.capture(_scene(), 0.0, np.random.default_rng(3))
    det = frame.detections
    cfg = radar.config
    w = np.array([0.0, 0.0, OMEGA])
    # Range rate of a static point p from the radar origin o(t) = Rz(omega t) O:
    # do/dt = omega x o, d|p - o|/dt = -(p - o) . (omega x o) / |p - o|.
    o_dot = np.cross(w, O)
    for c, r0 in zip(_targets(), TARGET_RANGE, strict=True):
        los = (c - O) / np.linalg.norm(c - O)
        v_expect = -los @ o_dot
        # The nearest detection in range to the sphere's front (one range bin, 2.5 cm).
        i = int(np.argmin(np.abs(det.range - (r0 - RADIUS))))
        assert abs(det.range[i] - (r0 - RADIUS)) <= cfg.chirp.range_resolution
        # One Doppler bin: lambda / (2 N_c T_rep) = 0.52 m/s; the three targets
        # move at -2.90, -2.12 and -0.78 m/s, more than a bin apart.
        assert abs(det.velocity[i] - v_expect) <= cfg.velocity_resolution, (r0, det.velocity[i],
                                                                              v_expect)
