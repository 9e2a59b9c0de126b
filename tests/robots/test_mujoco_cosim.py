"""MuJoCo co-simulation: bodies moved by MuJoCo's physics, seen by sensors at their frame times."""

import math

import mujoco
import numpy as np
import pytest

from twinsense import ConfigError
from twinsense.depthcam import DepthCamera
from twinsense.errors import UnknownNameError
from twinsense.robots import MujocoCosim
from twinsense.scene import Box, Mount, Pose
from twinsense.simulate import simulate

G = 9.81
DT = 0.003  # physics step [s]: frame times at 10 Hz fall between steps (0.1 / 0.003 is not whole)
Z0 = 2.0  # box centre at t = 0 [m]
HALF = 0.1  # box half size [m]

DROP = f"""<mujoco model="drop">
  <option timestep="{DT}" integrator="RK4" gravity="0 0 -{G}"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1" pos="0 0 -5"/>
    <body name="box" pos="0 0 {Z0}"><freejoint/><geom type="box" size="{HALF} {HALF} {HALF}"/>
      <site name="top" pos="0 0 {HALF}"/></body>
  </worldbody>
</mujoco>"""

# RK4 integrates constant-gravity flight exactly at the steps (the trajectory is a quadratic), so what
# remains is the propagation between steps by the step's velocity: error g tau^2 / 2 <= g dt^2 / 2
# (4.4e-5 m) in position and g tau <= g dt (0.029 m/s) in velocity.
POS_TOL = G * DT**2 / 2 + 1e-12
VEL_TOL = G * DT + 1e-12


def test_falling_box_matches_free_fall():
    cosim = MujocoCosim(mujoco.MjModel.from_xml_string(DROP))
    assert [o.name for o in cosim.scene.objects] == ["world", "box"]
    assert cosim.scene.frame_names == ("top",)
    assert cosim.scene.object("world").is_static and not cosim.scene.object("box").is_static
    assert isinstance(cosim.scene.object("box").geometry, Box)  # one geom at the body origin stays a box
    for t in (0.0, 0.1, 0.2345, 0.5):
        st = cosim.body_state("box", t)
        np.testing.assert_allclose(st.pose.position, [0, 0, Z0 - G * t * t / 2], atol=POS_TOL)
        np.testing.assert_allclose(st.linear_velocity, [0, 0, -G * t], atol=VEL_TOL)
    # Looking back within the history works; the site frame rides on the body.
    st = cosim.body_state("box", 0.2)
    np.testing.assert_allclose(st.pose.position[2], Z0 - G * 0.02, atol=POS_TOL)
    top = Mount(Pose(), "top").state_at(cosim.scene, 0.3)
    np.testing.assert_allclose(top.pose.position[2], Z0 + HALF - G * 0.045, atol=POS_TOL)


def test_depth_camera_sees_the_box_where_physics_puts_it():
    cosim = MujocoCosim(mujoco.MjModel.from_xml_string(DROP))
    cam_z = 3.0
    cam = DepthCamera.preset("generic", name="cam", frame_rate=10, width=32, height=24,
                             mount=Mount(Pose.look_at((0, 0, cam_z), (0, 0, 0), (1, 0, 0))))
    result = simulate(cosim.scene, [cam], 0.5)
    frames = result.frames["cam"]
    assert [round(f.t, 9) for f in frames] == [0.0, 0.1, 0.2, 0.3, 0.4]
    for f in frames:
        # The optical axis hits the box top; the ideal camera stores float32 depth (ulp 1.2e-7 at 1.7 m),
        # so the bound is the propagation error g dt^2 / 2 plus 1e-6.
        expected = cam_z - (Z0 - G * f.t**2 / 2 + HALF)
        h, w = f.depth.shape
        pix = f.depth[h // 2 - 1:h // 2 + 1, w // 2 - 1:w // 2 + 1]  # the 4 pixels around the axis
        np.testing.assert_allclose(pix, expected, atol=POS_TOL + 1e-6)
    assert cosim.time == pytest.approx(0.4, abs=DT)


SPINNER = """<mujoco model="spin">
  <option timestep="0.002" integrator="RK4" gravity="0 0 0"/>
  <worldbody>
    <body name="arm" pos="0.5 0 1"><joint name="hinge" type="hinge" axis="0 0 1" damping="0"/>
      <geom type="box" size="0.3 0.02 0.02" pos="0.3 0 0" mass="1"/>
      <site name="tip" pos="0.6 0 0"/></body>
    <body name="slider" pos="0 2 0"><joint name="rail" type="slide" axis="1 0 0"/>
      <geom type="box" size="0.05 0.05 0.05" mass="2"/></body>
  </worldbody>
  <actuator><motor joint="rail" gear="1"/></actuator>
</mujoco>"""


def test_spinning_arm_and_controlled_slider():
    model = mujoco.MjModel.from_xml_string(SPINNER)
    data = mujoco.MjData(model)
    omega, force, mass = 2.0, 3.0, 2.0
    data.qvel[0] = omega  # no gravity, no damping: the hinge turns at a constant rate

    def control(m, d):
        d.ctrl[0] = force

    cosim = MujocoCosim(model, data, control=control)
    for t in (0.25, 0.5013):
        # Constant rate: RK4 and the propagation (rotation by w tau) are both exact; 1e-9 covers rounding.
        arm = cosim.body_state("arm", t)
        c, s = math.cos(omega * t), math.sin(omega * t)
        np.testing.assert_allclose(arm.pose.rotation, [[c, -s, 0], [s, c, 0], [0, 0, 1]], atol=1e-9)
        np.testing.assert_allclose(arm.angular_velocity, [0, 0, omega], atol=1e-9)
        tip = Mount(Pose(), "tip").state_at(cosim.scene, t)
        np.testing.assert_allclose(tip.pose.position, [0.5 + 0.6 * c, 0.6 * s, 1.0], atol=1e-9)
        np.testing.assert_allclose(tip.linear_velocity, [-0.6 * omega * s, 0.6 * omega * c, 0], atol=1e-9)
        # Constant force on the slider: x = F t^2 / (2 m); the propagation between 2 ms steps errs by
        # a tau^2 / 2 <= (F / m) dt^2 / 2 = 3e-6 m.
        x = cosim.body_state("slider", t).pose.position[0]
        assert x == pytest.approx(force * t * t / (2 * mass), abs=force / mass * 0.002**2 / 2 + 1e-12)


def test_cosim_errors(tmp_path):
    with pytest.raises(ConfigError, match="mjcf.path"):
        MujocoCosim(tmp_path / "missing.xml")
    bad = tmp_path / "bad.xml"
    bad.write_text('<mujoco><asset><mesh name="m" file="gone.stl"/></asset>'
                   '<worldbody><geom type="mesh" mesh="m"/></worldbody></mujoco>')
    with pytest.raises(ConfigError, match="gone.stl"):
        MujocoCosim(bad)
    cosim = MujocoCosim(mujoco.MjModel.from_xml_string(DROP), history=0.05)
    with pytest.raises(UnknownNameError, match="box"):
        cosim.body_state("crate", 0.0)
    cosim.step_to(3.0)  # 1000 steps: the states older than 0.05 s are dropped (in batches of >= 256)
    with pytest.raises(ConfigError, match="history"):
        cosim.body_state("box", 0.1)
    with pytest.raises(ConfigError, match="MjData"):
        MujocoCosim(mujoco.MjModel.from_xml_string(DROP), data=object())


def test_articulated_body_follows_mujoco_joints():
    from twinsense.scene import ArticulatedBody, Joint, KinematicTree, Link, Scene

    model = mujoco.MjModel.from_xml_string(SPINNER)
    data = mujoco.MjData(model)
    data.qvel[0] = 1.5
    cosim = MujocoCosim(model, data)
    # The same arm as a kinematic tree with its own shape: the hinge at (0.5, 0, 1) about z.
    tree = KinematicTree("copy", [Link("world"), Link("arm", Box((0.6, 0.04, 0.04)), origin=Pose((0.3, 0, 0)))],
                         [Joint("spin", "revolute", "world", "arm", Pose((0.5, 0, 1)))])
    copy = ArticulatedBody("copy", tree, cosim.joint_setpoints({"spin": "hinge"}))
    scene = Scene()
    scene.add_articulated(copy)
    for t in (0.1, 0.2571, 0.6):
        ours = scene.object("copy/arm").state_at(t)
        ref = cosim.body_state("arm", t)
        # Both move step k's state on by its velocity (q + qd tau about a fixed axis; R_k by w tau): the same
        # rotation, to rounding.
        np.testing.assert_allclose(ours.pose.matrix, ref.pose.matrix, atol=1e-9)
        np.testing.assert_allclose(ours.angular_velocity, ref.angular_velocity, atol=1e-9)
        np.testing.assert_allclose(ours.linear_velocity, ref.linear_velocity, atol=1e-9)
    with pytest.raises(UnknownNameError, match="hinge"):
        cosim.joint_setpoints({"spin": "nope"})
