"""A LiDAR on a turning mount: every firing at its own exact pose, against the ray-plane closed form.

The head rides a carrier that moves and turns at constant rates (a ``ConstantVelocity`` frame, and a
link driven by a revolute joint at a constant speed), 0.2-0.4 m off the turning axis, in front of a
static wall. The reference pose of each firing is written here from the motion's closed form with
scipy's rotation vectors: R(t) = exp([w] t) R0, p(t) = p0 + v t + R(t) r; the beam leaves the pose
along the frame's own azimuth and elevation (docs/lidar.md: x = cos el sin az, y = -sin el,
z = cos el cos az, optical frame), and meets the wall x = X at (X - o_x) / d_x.

Ranges and points are stored as float32, so 2^-24 of the range (6e-8 relative) is the floor. The
rotation is carried between the exact 1 ms states by the state's own angular velocity (exact for a
constant one) and the position on a cubic Hermite curve (off by r w^4 dt^4 / 384 < 1e-10 m here), so
the tolerance is 8 x 2^-24 of the range (rounding of the range, the point and the float32 angles
read back) plus 1e-9 m; the largest errors are 9.4e-7 and 4.8e-7 m. The first-order carry before,
(I + [w] dt) R and p + v dt, missed by 7.9e-4 and 2.9e-4 m (beams tilted and lengthened by
w^2 dt^2 / 2, the offset's centripetal w^2 r dt^2 / 2).
"""

import numpy as np
from scipy.spatial.transform import Rotation

from twinsense import Box, Material, Mount, Pose, Scene
from twinsense.lidar import Lidar
from twinsense.lidar.scan import firings
from twinsense.scene import ArticulatedBody, Frame, Joint, JointConstantVelocity, KinematicTree, Link
from twinsense.scene.motion import ConstantVelocity

F32 = 2.0 ** -24
MATTE = Material("lidar_turning_matte", 0.5, 0.0)
QUIET = {"range_noise": 0.0, "snr_range_noise": False, "noise_power": 1e-18, "saturation_power": 1e3,
         "subrays": 1}
WALL_X = 5.0
#: The head 0.3 m ahead, 0.2 m left of and 0.1 m above the carrier's origin, level, azimuth 0 along +x.
HEAD = Pose.look_at((0.3, 0.2, 0.1), (1.3, 0.2, 0.1))


def _wall_scene() -> Scene:
    scene = Scene()
    # Front face at x = WALL_X, 80 m wide: every firing towards +x hits it.
    scene.add_object("wall", Box((0.02, 80.0, 80.0)), MATTE, pose=Pose((WALL_X + 0.01, 0.0, 0.0)))
    return scene


def _check(lidar: Lidar, scene: Scene, carrier_pose) -> int:
    """Compare every wall return of one revolution with the closed form; the number compared."""
    f = lidar.capture(scene, 0.0, np.random.default_rng(0))
    fir = firings(lidar.config, 0.0)
    assert fir.origin is None  # the VLP-16's beams leave the sensor origin
    np.testing.assert_array_equal(f.time, fir.time)
    az, el = fir.azimuth, fir.elevation
    u = np.stack([np.cos(el) * np.sin(az), -np.sin(el), np.cos(el) * np.cos(az)], axis=-1)
    rot_c, pos_c = carrier_pose(fir.time)  # (n, 3, 3), (n, 3): carrier -> world at each firing
    rot = rot_c @ HEAD.rotation
    o = pos_c + np.einsum("nij,j->ni", rot_c, HEAD.position)
    d = np.einsum("nij,nj->ni", rot, u)
    hit = (f.object_id[:, 0] == 0) & (d[:, 0] > 0.3)  # incidence within 73 deg: no grazing ill-conditioning
    r_exp = (WALL_X - o[hit, 0]) / d[hit, 0]
    p_exp = o[hit] + r_exp[:, None] * d[hit]
    tol = 8 * F32 * r_exp + 1e-9
    err_r = np.abs(f.range[hit, 0] - r_exp)
    assert np.all(err_r <= tol), float(np.max(err_r / tol))
    err_p = np.abs(f.xyz_world[hit, 0] - p_exp).max(axis=1)
    assert np.all(err_p <= tol), float(np.max(err_p / tol))
    return int(hit.sum())


def test_head_on_a_turning_carrier_sees_the_wall_where_it_is():
    v, w = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 10.0])
    p0 = np.array([0.0, 0.0, 1.0])
    scene = _wall_scene()
    scene.add_frame(Frame("cart", ConstantVelocity(Pose(p0), tuple(v), tuple(w))))
    lidar = Lidar.preset("velodyne_vlp16", name="l", mount=Mount(HEAD, "cart"), **QUIET)

    def carrier(t):
        return Rotation.from_rotvec(np.outer(t, w)).as_matrix(), p0 + np.outer(t, v)

    assert _check(lidar, scene, carrier) > 2000


def test_head_on_a_link_turning_at_a_constant_rate():
    # A base link at (0, 0, 1) and an arm turning about z at 6 rad/s from q0 = 0.2 rad; the head sits on
    # the arm's tip link, 0.4 m out along the arm (and HEAD's offset in the tip frame).
    q0, qd, reach = 0.2, 6.0, 0.4
    links = [Link("base"), Link("arm"), Link("tip")]
    joints = [Joint("turn", "revolute", "base", "arm", axis=(0.0, 0.0, 1.0)),
              Joint("tip", "fixed", "arm", "tip", origin=Pose((reach, 0.0, 0.0)))]
    body = ArticulatedBody("rob", KinematicTree("rob", links, joints), JointConstantVelocity([q0], [qd]),
                           base=Pose((0.0, 0.0, 1.0)))
    scene = _wall_scene()
    scene.add_articulated(body)
    lidar = Lidar.preset("velodyne_vlp16", name="l", mount=Mount(HEAD, "rob/tip"), **QUIET)

    def carrier(t):
        rz = Rotation.from_rotvec(np.outer(q0 + qd * t, [0.0, 0.0, 1.0])).as_matrix()
        return rz, np.array([0.0, 0.0, 1.0]) + rz @ np.array([reach, 0.0, 0.0])

    assert _check(lidar, scene, carrier) > 1000
