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
