"""The internal trusted Pose constructor: the same bits as the public one, and the public one still checks.

``Pose._trusted`` skips the checks but keeps the re-orthonormalisation, so every pose it builds must
equal, bit for bit, the pose ``Pose(position, rotation)`` builds from the same arrays; motion states
(built with it) are compared with states rebuilt through the public constructor.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from twinsense import ConfigError, Pose
from twinsense.scene import ConstantVelocity, Keyframes, Oscillation, Waypoints
from twinsense.scene.pose import _as_rotation_matrix, rotvec_matrix

RNG = np.random.default_rng(11)


def bits_equal(a: Pose, b: Pose) -> bool:
    return a.position.tobytes() == b.position.tobytes() and a.rotation.tobytes() == b.rotation.tobytes()


def random_rotation() -> np.ndarray:
    return Rotation.random(random_state=int(RNG.integers(1 << 30))).as_matrix()


def test_trusted_gives_the_bits_of_the_public_constructor():
    for _ in range(200):
        p, r = RNG.normal(size=3), random_rotation()
        # A product of rotations (rounding noise of 1e-16) and a transposed (F-ordered) view, as
        # composition and inverse hand over.
        for rot in (r, r @ random_rotation(), r.T):
            a, b = Pose._trusted(p, rot), Pose(p, rot)
            assert bits_equal(a, b)
            assert not a.position.flags.writeable and not a.rotation.flags.writeable


def test_composition_and_inverse_equal_the_public_construction():
    for _ in range(50):
        a = Pose(RNG.normal(size=3), random_rotation())
        b = Pose(RNG.normal(size=3), random_rotation())
        assert bits_equal(a @ b, Pose(a.rotation @ b.position + a.position, a.rotation @ b.rotation))
        assert bits_equal(a.inverse(), Pose(-a.rotation.T @ a.position, a.rotation.T))


def test_trusted_does_not_alias_the_caller_position():
    p = np.array([1.0, 2.0, 3.0])
    pose = Pose._trusted(p, np.eye(3))
    p[0] = 9.0  # the caller's array stays writable and the pose keeps its own copy
    assert pose.position[0] == 1.0


@pytest.mark.parametrize("bad", [
    np.diag([1.0, 1.0, -1.0]),  # a mirror (det -1)
    2.0 * np.eye(3),  # scaled
    np.array([[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),  # sheared
    np.full((3, 3), np.nan),
    np.eye(2),
])
def test_public_constructor_still_rejects_bad_rotations(bad):
    with pytest.raises(ConfigError) as e:
        Pose((0.0, 0.0, 0.0), bad)
    assert e.value.field == "Pose.rotation"


def test_public_constructor_still_rejects_a_bad_position():
    with pytest.raises(ConfigError) as e:
        Pose((0.0, np.inf, 0.0), np.eye(3))
    assert e.value.field == "Pose.position"


def motions():
    p0 = Pose(RNG.normal(size=3), random_rotation())
    return [
        ConstantVelocity(p0, (0.3, -0.2, 0.1), (0.5, 1.0, -2.0)),
        ConstantVelocity(p0, (0.3, 0.0, 0.0)),  # no turn: one rotation built once
        Oscillation(p0, (0.02, 0.0, 0.01), 3.0, 20.0, (0.1, 0.0, 0.3)),
        Oscillation(p0, (0.02, 0.0, 0.01), 3.0, 20.0),
        Waypoints(np.array([[0.0, 0, 0], [1.0, 0, 0], [1.0, 1.0, 0]]), 0.7, "back_and_forth", random_rotation()),
        Keyframes(np.array([0.0, 1.0, 2.5]), (p0, Pose(RNG.normal(size=3), random_rotation()),
                                              Pose(RNG.normal(size=3), random_rotation()))),
    ]


def reference_pose(m, t: float, state) -> Pose:
    """The motion's pose at ``t`` by its formula, through the checked public constructor."""
    if isinstance(m, ConstantVelocity):
        return Pose(m.pose0.position + m.velocity * t, rotvec_matrix("w t", m.angular_velocity * t) @ m.pose0.rotation)
    if isinstance(m, Oscillation):
        s = np.sin(2 * np.pi * m.frequency * t + np.deg2rad(m.phase_deg))
        return Pose(m.pose0.position + m.amplitude * s,
                    rotvec_matrix("a s", m.angular_amplitude * s) @ m.pose0.rotation)
    if isinstance(m, Waypoints):  # the path position is not a rotation matter: taken from the state
        return Pose(state.pose.position, _as_rotation_matrix("rotation", m.rotation))
    ts = m.times
    if t <= ts[0] or t >= ts[-1]:
        return m.poses[0] if t <= ts[0] else m.poses[-1]
    rot = Slerp(ts, Rotation.from_matrix(np.array([p.rotation for p in m.poses])))([t])[0].as_matrix()
    return Pose(state.pose.position, rot)


@pytest.mark.parametrize("motion", motions(), ids=lambda m: type(m).__name__)
def test_motion_states_are_the_public_constructions_bit_for_bit(motion):
    for t in np.linspace(-0.5, 4.0, 37):
        st = motion.state(float(t))
        assert bits_equal(st.pose, reference_pose(motion, float(t), st)), t
