"""MuJoCo co-simulation with models a user brings: free, ball and slide joints, mocap bodies, every geom
type, odd time steps, files with relative mesh folders, and the errors a user can run into."""

import mujoco
import numpy as np
import pytest

from twinsense import ConfigError
from twinsense.robots import MujocoCosim

G = 9.81

# A box on a free joint with a site on its top face; nothing below it for 10 m.
DROP = """<mujoco model="drop">
  <option timestep="{dt}" integrator="{integrator}" gravity="0 0 -9.81"/>
  <worldbody>
    <geom name="floor" type="plane" size="3 3 0.1" pos="0 0 -10"/>
    <body name="box" pos="0 0 {z0}"><freejoint/><geom type="box" size="0.1 0.1 0.1"/>
      <site name="top" pos="0 0 0.1" euler="10 20 30"/></body>
  </worldbody>
</mujoco>"""


def drop_model(dt=0.002, integrator="Euler", z0=2.0):
    return mujoco.MjModel.from_xml_string(DROP.format(dt=dt, integrator=integrator, z0=z0))


# --------------------------------------------------------------------------- errors a user can run into
def test_control_that_raises_is_named():
    def control(m, d):
        if d.time > 0.01:
            raise RuntimeError("controller lost its gains")

    cosim = MujocoCosim(drop_model(), control=control)
    with pytest.raises(ConfigError, match=r"cosim.control.*RuntimeError: controller lost its gains"):
        cosim.body_state("box", 0.1)


def test_diverging_physics_raises_instead_of_hanging():
    # A 1 kg slider on a 1e6 N/m spring, 10 ms steps: omega dt = 10, far beyond the explicit spring's
    # stability limit of 2. MuJoCo warns and resets the state to t = 0 (its auto-reset); the time running
    # back made step_to loop for ever on models like this.
    xml = """<mujoco><option timestep="0.01" gravity="0 0 0"/><worldbody>
      <body name="b"><joint name="s" type="slide" axis="1 0 0" stiffness="1e6"/>
      <geom type="box" size="0.1 0.1 0.1" mass="1"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qpos[0] = 0.01
    cosim = MujocoCosim(model, data)
    with pytest.raises(ConfigError, match=r"cosim.model.opt.timestep = 0.01.*unstable"):
        cosim.body_state("b", 5.0)
    failed_at = cosim.time  # data holds the last good state again, and the kept states stay readable
    assert 0 < failed_at < 1.0 and cosim.data.qpos[0] != 0.0
    assert cosim.body_state("b", failed_at).pose.position[0] == cosim.data.qpos[0]
    with pytest.raises(ConfigError, match=r"unstable"):  # and stepping on stays refused
        cosim.step_to(6.0)


def test_nan_in_the_state_is_refused():
    model = drop_model()
    data = mujoco.MjData(model)
    data.qpos[2] = np.nan
    with pytest.raises(ConfigError, match=r"cosim.data.qpos"):
        MujocoCosim(model, data)
    cosim = MujocoCosim(model)
    cosim.step_to(0.05)
    cosim.data.qvel[0] = np.inf  # set by the user between steps: MuJoCo would reset the state silently
    with pytest.raises(ConfigError, match=r"cosim.data.qvel"):
        cosim.body_state("box", 0.1)


def test_nan_control_is_refused():
    def control(m, d):
        d.qfrc_applied[2] = np.nan  # MuJoCo would warn and reset the state to t = 0

    cosim = MujocoCosim(drop_model(), control=control)
    with pytest.raises(ConfigError, match=r"unstable|finite"):
        cosim.body_state("box", 0.1)


def test_time_moved_back_under_the_cosim_is_refused():
    cosim = MujocoCosim(drop_model())
    cosim.step_to(0.5)
    mujoco.mj_resetData(cosim.model, cosim.data)  # a reset behind the co-simulation's back
    with pytest.raises(ConfigError, match=r"cosim.data.time.*new MujocoCosim"):
        cosim.body_state("box", 0.6)
