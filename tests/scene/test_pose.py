"""Pose algebra: composition, inverse, constructors, look_at."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from twinsense import ConfigError, Pose

RNG = np.random.default_rng(1)


def random_pose():
    return Pose(RNG.normal(size=3), Rotation.random(random_state=RNG.integers(1 << 30)).as_matrix())


def test_compose_matches_sequential_application():
    a, b = random_pose(), random_pose()
    p = RNG.normal(size=(10, 3))
    # Composition is exact up to float rounding (1e-12 on O(1) coordinates).
    np.testing.assert_allclose((a @ b).apply(p), a.apply(b.apply(p)), atol=1e-12)


def test_inverse_round_trip_and_identity():
    a = random_pose()
    assert (a @ a.inverse()).isclose(Pose(), atol=1e-12)
    assert (a.inverse() @ a).isclose(Pose(), atol=1e-12)
    p = RNG.normal(size=(5, 3))
    np.testing.assert_allclose(a.inverse().apply(a.apply(p)), p, atol=1e-12)


def test_associativity():
    a, b, c = random_pose(), random_pose(), random_pose()
    assert ((a @ b) @ c).isclose(a @ (b @ c), atol=1e-12)


def test_constructors_agree():
    pos = (1.0, -2.0, 0.5)
    e = Pose.from_euler_deg(pos, (10, 20, 30))
    q = Pose.from_quat(pos, Rotation.from_euler("xyz", (10, 20, 30), degrees=True).as_quat())
    m = Pose.from_matrix(e.matrix)
    assert e.isclose(q, atol=1e-12) and e.isclose(m, atol=1e-12)
    np.testing.assert_allclose(e.euler_deg(), (10, 20, 30), atol=1e-9)
    # 90 deg yaw turns +x into +y.
    np.testing.assert_allclose(Pose.from_euler_deg(rpy_deg=(0, 0, 90)).apply_vectors([1, 0, 0]), [0, 1, 0],
                               atol=1e-12)


def test_look_at_optical_convention():
    p = Pose.look_at((0, 0, 1), (5, 0, 1))
    np.testing.assert_allclose(p.rotation[:, 2], [1, 0, 0], atol=1e-12)  # boresight +z -> target
    np.testing.assert_allclose(p.rotation[:, 1], [0, 0, -1], atol=1e-12)  # image down = world down
    np.testing.assert_allclose(p.rotation[:, 0], [0, -1, 0], atol=1e-12)  # image right = world -y
    assert np.isclose(np.linalg.det(p.rotation), 1.0)


@pytest.mark.parametrize("kwargs, match", [
    ({"position": [0, 0, float("nan")]}, r"Pose.position .* expected 3 finite numbers"),
    ({"position": [0, 0]}, r"Pose.position"),
    ({"rotation": np.diag([1.0, 1.0, -1.0])}, r"proper rotation"),
    ({"rotation": 2 * np.eye(3)}, r"proper rotation"),
])
def test_bad_pose_errors(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        Pose(**kwargs)


def test_look_at_degenerate():
    with pytest.raises(ConfigError, match="look_at.up"):
        Pose.look_at((0, 0, 0), (0, 0, 5))
    with pytest.raises(ConfigError, match="look_at.target"):
        Pose.look_at((1, 1, 1), (1, 1, 1))


def test_quaternion_near_the_float_limits_is_normalised_without_overflow():
    # (1e200, 1e200, 0, 0) is the half-turn about (x + y)/sqrt(2): R = 2 n n^T - I.
    # Its squared norm overflows; scaled by the largest entry first, the result
    # matches the closed form to a few ulp of 1 (4e-16).
    n = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    expect = 2 * np.outer(n, n) - np.eye(3)
    for scale in (1e200, 1e-3, 1.0):
        r = Pose.from_quat((0, 0, 0), (scale, scale, 0, 0)).rotation
        np.testing.assert_allclose(r, expect, rtol=0, atol=4e-16)


def test_rotation_vector_angle_is_reduced_modulo_two_pi():
    # A turn of 2 pi k + 0.3 rad about z is the 0.3 rad turn. The input angle
    # itself carries one ulp of 2 pi k + 0.3 (~9.3e-10 at 6.3e6 rad), which is
    # the error bound of the reduced angle: atol 2e-9 on the matrix.
    k = 1_000_000
    r = Pose.from_rotvec((0, 0, 0), (0, 0, 2 * np.pi * k + 0.3)).rotation
    np.testing.assert_allclose(r, Rotation.from_rotvec([0, 0, 0.3]).as_matrix(), rtol=0, atol=2e-9)
    # 1e300 rad: scipy's Rodrigues formula alone gives NaN; reduced, a proper rotation.
    r = Pose.from_rotvec((0, 0, 0), (1e300, 0, 0)).rotation
    np.testing.assert_allclose(r @ r.T, np.eye(3), rtol=0, atol=1e-15)
    assert r[0, 0] == pytest.approx(1.0, rel=0, abs=1e-15)  # still a turn about x


def test_look_at_with_huge_or_tiny_up_vector():
    # Only the direction of up matters: 1e300 * z and 1e-300 * z give the same frame as z.
    ref = Pose.look_at((0, 0, 1), (3, 0, 1))
    for up in ((0, 0, 1e300), (0, 0, 1e-300)):
        assert Pose.look_at((0, 0, 1), (3, 0, 1), up).isclose(ref, atol=0)
    with pytest.raises(ConfigError, match=r"look_at.target .* offset from eye is finite"):
        Pose.look_at((-1e308, 0, 0), (1e308, 0, 0))
