"""A body that follows MuJoCo's joints through ``MujocoCosim.joint_setpoints`` at a joint limit.

MuJoCo's joint limits are soft constraints (solref/solimp): a hinge pressed against its range by
gravity sits a little past it (here 0.0267 rad past 0.5 rad). The following body used to refuse that
value and stop the run at the first frame after the contact with the limit. It now holds the joint at
its limit (MuJoCo's value elsewhere, exactly), and says once per joint that MuJoCo went past it.
"""

import warnings

import mujoco
import numpy as np
import pytest

from twinsense.robots import MujocoCosim
from twinsense.scene import ArticulatedBody, Box, Joint, KinematicTree, Link, Pose

# A 0.6 m arm on a hinge about y, limited to [-0.5, 0.5] rad, starting level at 0.3 rad: gravity
# swings it down onto its +0.5 rad limit within 0.2 s and holds it there.
PENDULUM = """
<mujoco>
  <compiler angle="radian"/>
  <option timestep="0.002" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="arm" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0" limited="true" range="-0.5 0.5"/>
      <geom type="box" size="0.3 0.02 0.02" pos="0.3 0 0" mass="2"/>
    </body>
  </worldbody>
  <keyframe><key qpos="0.3"/></keyframe>
</mujoco>
"""


def _follower():
    model = mujoco.MjModel.from_xml_string(PENDULUM)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    cosim = MujocoCosim(model, data)
    tree = KinematicTree("copy", [Link("world"), Link("arm", Box((0.6, 0.04, 0.04)), origin=Pose((0.3, 0, 0)))],
                         [Joint("hinge", "revolute", "world", "arm", Pose((0, 0, 1)), (0, 1, 0), -0.5, 0.5)])
    return cosim, ArticulatedBody("copy", tree, cosim.joint_setpoints({"hinge": "hinge"}))


def test_a_joint_pressed_past_its_soft_limit_is_held_at_the_limit():
    cosim, body = _follower()
    with pytest.warns(UserWarning, match=r"hinge.*0\.5.*soft") as caught:
        past = []
        for t in np.arange(0.0, 1.0, 0.01):
            q, qd = body.joint_state(float(t))
            cosim.step_to(float(t))
            mj, v, tau = float(cosim.data.qpos[0]), float(cosim.data.qvel[0]), t - cosim.data.time
            if mj > 0.5:
                past.append(mj)
            # MuJoCo's last step held within the limit, moved on by its velocity to t, stopped at the limit
            # (at rest there: a joint at its limit does not move further into it).
            ref = min(mj, 0.5) + v * tau
            if ref >= 0.5 - 1e-12 and v >= 0:  # (t and the step time agree to rounding)
                assert q[0] == 0.5 and qd[0] == 0.0
            else:
                assert q[0] == pytest.approx(ref, rel=0, abs=1e-12) and qd[0] == v
    # MuJoCo did go past the limit (its soft constraint), and the warning came once.
    assert max(past) - 0.5 > 0.005
    assert len([w for w in caught if "hinge" in str(w.message)]) == 1


def test_the_link_follows_mujoco_within_the_limits():
    # Before the arm reaches the limit (0.1 s), the copy's link is MuJoCo's body, to rounding.
    cosim, body = _follower()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning while within the limits
        for t in (0.0, 0.05, 0.1):
            st = body.state(t)
            ref = cosim.body_state("arm", t)
            np.testing.assert_allclose(st.pose("arm").rotation, ref.pose.rotation, rtol=0, atol=1e-12)
