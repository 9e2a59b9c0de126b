"""One rotation rule (scene.pose.is_rotation), two tolerances: a Pose's (1e-6, then
re-orthonormalised) and Rays.local's (1e-9, kept as given).

Reference: a rotation scaled by (1 + s) has R R^T - I = ((1 + s)^2 - 1) I = (2 s + s^2) I
exactly (up to one rounding of 1 + s, ~1e-16, far below both tolerances).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from twinsense import Pose, Rays
from twinsense.errors import ConfigError
from twinsense.render.rays import LOCAL_ROTATION_TOL
from twinsense.scene.pose import POSE_ROTATION_TOL, is_rotation

R = Rotation.from_rotvec([0.3, -0.8, 0.5]).as_matrix()


@pytest.mark.parametrize("tol", [POSE_ROTATION_TOL, LOCAL_ROTATION_TOL])
def test_a_scaled_rotation_passes_just_inside_the_tolerance_and_fails_just_outside(tol):
    # 2 s + s^2 = 0.8 tol inside, 1.2 tol outside (s ~ tol / 2: s^2 <= 3e-13 tol, negligible).
    assert is_rotation(R * (1 + 0.4 * tol), tol)
    assert not is_rotation(R * (1 + 0.6 * tol), tol)


def test_mirrors_nan_inf_and_huge_matrices_are_not_rotations():
    for bad in (-R, R @ np.diag([1.0, 1.0, -1.0]), np.full((3, 3), np.nan), np.where(np.eye(3) > 0, np.inf, 0.0),
                1e300 * R, np.zeros((3, 3))):
        assert not is_rotation(bad, POSE_ROTATION_TOL)  # 1e300: refused before R R^T overflows


def test_a_pose_takes_what_rays_local_refuses_naming_the_field():
    noisy = R * (1 + 1e-8)  # R R^T - I = 2e-8 I: float noise to a Pose, too far for Rays.local
    pose = Pose(rotation=noisy)
    # Re-orthonormalised: R R^T = I to a few ulp of 1 (3-term dot products, ~4e-16 each).
    np.testing.assert_allclose(pose.rotation @ pose.rotation.T, np.eye(3), rtol=0, atol=1e-15)
    dl = np.array([[0.0, 0.0, 1.0], [0.1, 0.0, 1.0]])
    dl.setflags(write=False)
    with pytest.raises(ConfigError, match=r"Rays\.local.*within 1e-09") as err:
        Rays(np.zeros(3), dl @ noisy.T, local=(dl, noisy))
    assert err.value.field == "Rays.local"
    with pytest.raises(ConfigError, match="within 1e-06") as err:
        Pose(rotation=R * (1 + 1e-6))  # 2e-6 off
    assert err.value.field == "Pose.rotation"
    assert Rays(np.zeros(3), dl @ R.T, local=(dl, R)).local[1].tolist() == R.tolist()  # kept as given
