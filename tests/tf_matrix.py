"""A decoded ROS 2 TransformStamped as a 4 x 4 homogeneous matrix (the tests that read /tf back)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def tf_matrix(tf) -> np.ndarray:
    """(4, 4) child -> parent transform of a decoded ``geometry_msgs/TransformStamped`` [m]."""
    r, p = tf.transform.rotation, tf.transform.translation
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix()
    m[:3, 3] = [p.x, p.y, p.z]
    return m
