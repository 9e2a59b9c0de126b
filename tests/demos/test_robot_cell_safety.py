"""ISO/TS 15066 protective separation distance and the true human-robot separation against closed forms."""

import math

import numpy as np
import pytest
import trimesh

from twinsense.errors import ConfigError
from twinsense.safety import (
    SeparationMonitor,
    SeparationParameters,
    point_box_distance,
    point_capsule_distance,
    protective_separation_distance,
)
from twinsense.scene import Capsule, JointConstantVelocity, Pose, Scene
from twinsense.scene.articulated import ArticulatedBody, Joint, KinematicTree, Link
from twinsense.scene.geometry import TriangleMesh


def test_protective_separation_hand_worked():
    # v_r = 0.5 m/s with the defaults (v_h 1.6 m/s, T_r 0.1 s, T_s 0.3 s, C 0.2 m, Z_d 0.05 m, Z_r 0.01 m):
    # S_h = 1.6 * (0.1 + 0.3) = 0.64; S_r = 0.5 * 0.1 = 0.05; S_s = 0.5 * 0.3 / 2 = 0.075 (constant
    # deceleration); + C + Z_d + Z_r = 0.26 -> S_p = 1.025 m. Sums of a few decimals: 1e-12 absolute.
    assert protective_separation_distance(0.5) == pytest.approx(1.025, rel=0, abs=1e-12)
    # A measured stopping distance replaces v_r T_s / 2: 0.64 + 0.05 + 0.10 + 0.26 = 1.05 m.
    p = SeparationParameters(stopping_distance=0.10)
    assert protective_separation_distance(0.5, p) == pytest.approx(1.05, rel=0, abs=1e-12)
    # Standing robot: only the person's travel and the allowances, 0.64 + 0.26 = 0.90 m; arrays work too.
    np.testing.assert_allclose(protective_separation_distance(np.array([0.0, 0.5])), [0.9, 1.025], rtol=0,
                               atol=1e-12)


def test_protective_separation_rejects_bad_input():
    with pytest.raises(ConfigError, match="robot_speed"):
        protective_separation_distance(-0.1)
    with pytest.raises(ConfigError, match="robot_speed"):
        protective_separation_distance(float("nan"))
    with pytest.raises(ConfigError, match="human_speed"):
        SeparationParameters(human_speed=-1.6)
    with pytest.raises(ConfigError, match="stopping_time"):
        SeparationParameters(stopping_time=float("nan"))


def test_point_distances_match_trimesh():
    # Box: trimesh's signed distance (its own closest-point search, positive inside) is an independent
    # implementation; both are exact up to rounding: 1e-9 m.
    rng = np.random.default_rng(3)
    size = (0.3, 0.2, 0.5)
    pts = rng.uniform(-0.5, 0.5, (400, 3))
    ref = -trimesh.proximity.signed_distance(trimesh.creation.box(size), pts)
    np.testing.assert_allclose(point_box_distance(pts, size), ref, rtol=0, atol=1e-9)
    # Capsule: the segment's clamped projection; a point beside the middle, one beyond each end.
    d = point_capsule_distance([[0.5, 0, 0], [0, 0, 2.0], [0, 0, -1.3]], (0, 0, -1), (0, 0, 1), 0.2)
    np.testing.assert_allclose(d, [0.3, 0.8, 0.1], rtol=0, atol=1e-12)


def _one_link(name, geometry, joint_motion=None, base=Pose(), kind="fixed"):
    links = [Link("base"), Link("body", geometry, "aluminium")]
    joints = [Joint("slide", kind, "base", "body", axis=(1.0, 0.0, 0.0))]
    return ArticulatedBody(name, KinematicTree(name, links, joints), joint_motion, base)


def test_separation_sphere_mesh_vs_capsule_closed_form():
    # A "robot" link: an icosphere of radius R sliding along +x at 0.5 m/s from (0, 0, 1.2); a "person":
    # a vertical capsule (radius r, axis z = 0.5..1.5) at (2.0, 0.3). Closed form:
    # d(t) = |c(t) - (2.0, 0.3, 1.2)| - r - R, and the robot's speed towards the person is v . u.
    R, r, v = 0.1, 0.2, 0.5
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=R)
    scene = Scene()
    scene.add_articulated(_one_link("robot", TriangleMesh(sphere.vertices, sphere.faces),
                                    JointConstantVelocity([0.0], [v]), Pose((0.0, 0.0, 1.2)), kind="prismatic"))
    scene.add_articulated(_one_link("person", Capsule(r, 1.0), base=Pose((2.0, 0.3, 1.0))))
    mon = SeparationMonitor(scene, "robot", "person", spacing=0.01)
    # The mesh lies inside the sphere (vertices on it, faces sagging inward by at most `sag`), so the
    # result is never below the closed form; the nearest subdivided vertex is within spacing / sqrt(3) of
    # the facet point nearest the capsule, which is within `sag` of the sphere: d <= true + sag + s/sqrt(3).
    sag = R - np.min(np.abs(np.einsum("ij,ij->i", sphere.face_normals, sphere.triangles[:, 0])))
    tol = sag + mon.spacing / math.sqrt(3)
    for t in (0.0, 1.0, 2.5):
        c = np.array([v * t, 0.0, 1.2])
        gap = np.array([2.0, 0.3, 1.2]) - c
        true = np.linalg.norm(gap) - r - R
        s = mon.at(t)
        assert true - 1e-12 <= s.distance <= true + tol
        assert s.robot_link == "robot/body" and s.human_link == "person/body"
        # Every robot point moves at (v, 0, 0); the direction to the person from the sampled closest
        # point differs from u by at most (tol / |gap|) rad: speed error <= v * tol / |gap| (< 3 mm/s).
        u = gap / np.linalg.norm(gap)
        assert s.robot_speed == pytest.approx(v * u[0], rel=0, abs=v * tol / np.linalg.norm(gap))


def test_separation_monitor_rejects_unknown_bodies():
    scene = Scene()
    scene.add_articulated(_one_link("person", Capsule(0.2, 1.0)))
    with pytest.raises(ConfigError, match="robot = 'ur5'.*person"):
        SeparationMonitor(scene, "ur5", "person")
    with pytest.raises(ConfigError, match="spacing"):
        SeparationMonitor(scene, "person", "person", spacing=-1.0)
