"""What the scene keeps between frames: link poses per time, geometry bounds.

Link poses and states of a forward-kinematics state are built once per link and time, the poses with
the bits of the public constructor.

A ``TreeState`` is cached per time and every sensor asks for every moving link at each capture, so
``TreeState.pose`` keeps each link's pose. It must equal, bit for bit, ``Pose(position, rotation)`` of
the kernel's rows (the checked constructor), for a real robot (example-robot-data's UR5) and a person.
A geometry's bounds are kept (its mesh's vertices are read-only): the mesh's own bounds, read-only.
"""

import numpy as np
import pytest

from twinsense import Pose
from twinsense.robots import load_robot
from twinsense.scene import Box, Cylinder, JointKeyframes, Scene, Sphere
from twinsense.scene.human import Walk, add_person


def bits_equal(a: Pose, b: Pose) -> bool:
    return a.position.tobytes() == b.position.tobytes() and a.rotation.tobytes() == b.rotation.tobytes()


def test_link_poses_are_the_checked_poses_and_built_once():
    ur5 = load_robot("ur5", joints=JointKeyframes((0.0, 2.0), ((0.0,) * 6, (0.5, -1.2, 1.4, -0.7, 1.1, 0.3))))
    s = Scene()
    add_person(s, "p", 1.75, (1.0, -2.0), walk=Walk(1.2, path=((0.5, 0.0),)))
    person = s.object("p/thorax").motion.body
    for body in (ur5, person):
        for t in (0.0, 0.37, 1.3):
            st = body.state(t)
            for i in range(len(st.link_names)):
                pose = st.pose(i)
                assert bits_equal(pose, Pose(st.positions[i], st.rotations[i]))
                assert st.pose(st.link_names[i]) is pose  # by name or index: the same pose
                ms = st.state(i)
                assert ms.pose is pose
                assert np.array_equal(ms.linear_velocity, st.linear_velocities[i])
                assert np.array_equal(ms.angular_velocity, st.angular_velocities[i])
                # One state per link and time, shared by every sensor that asks (by index or name); its
                # velocities read-only, as a static object's: no caller can change another's state.
                assert st.state(i) is ms and st.state(st.link_names[i]) is ms
                for v in (ms.linear_velocity, ms.angular_velocity):
                    assert not v.flags.writeable
                    with pytest.raises(ValueError):
                        v[:] = 7.0
                assert not np.any(st.linear_velocities[i] == 7.0)


def test_geometry_bounds_are_the_mesh_bounds_kept_read_only():
    for g in (Box((0.1, 0.2, 0.3)), Sphere(0.25), Cylinder(0.06, 0.5)):
        b = g.bounds
        assert b.tobytes() == np.asarray(g.mesh.bounds, dtype=float).tobytes()
        assert g.bounds is b and not b.flags.writeable


def test_person_base_pose_is_the_checked_pose_of_its_plan():
    # The person's base pose skips Pose(...)'s checks (a product of two proper rotations and a finite
    # floor point); it must be that constructor's pose bit for bit, walking, turning and reaching.
    from twinsense.demos.robot_cell import PERSON, build_arm_cell_scene
    from twinsense.scene.human import _rot_x, _rot_z

    motion = build_arm_cell_scene().object(f"{PERSON}/thorax").motion.body.joint_motion.person
    for t in np.linspace(0.0, 6.0, 61):
        base = motion._at(float(t))[2]
        plan = motion._plan(float(t), True)
        want = Pose(plan.p, _rot_z(plan.yaw) @ _rot_x(plan.roll))
        assert bits_equal(base.pose, want)
        assert not base.pose.rotation.flags.writeable and not base.pose.position.flags.writeable
        # The base state is kept for its time and shared by every caller (the body's forward kinematics,
        # PersonBase.state): its velocities are read-only, so a caller's write cannot reach the next one.
        assert motion._at(float(t))[2] is base
        for v in (base.linear_velocity, base.angular_velocity):
            assert not v.flags.writeable
            with pytest.raises(ValueError):
                v[:] = 7.0
        assert base.linear_velocity.tobytes() == plan.v.tobytes()
