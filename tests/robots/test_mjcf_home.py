"""An MJCF robot rests at its model's home: the keyframe named "home" (MuJoCo Menagerie's
convention) or else qpos0 (each joint's ``ref``), clipped into the joint ranges.

Reference: MuJoCo's own forward kinematics (``mj_resetDataKeyframe`` / ``mj_resetData`` then
``mj_kinematics``) of the same model; the tree and MuJoCo agree to 1e-12 m here (a 3-joint
chain under 1 m: a few ulps per joint, far below).
"""

import mujoco
import numpy as np
import pytest

from twinsense.errors import ConfigError
from twinsense.robots import load_mjcf
from twinsense.robots.mjcf import mjcf_tree
from twinsense.scene import ArticulatedBody, Joint, JointKeyframes, KinematicTree, Link, Pose

_ARM = """<mujoco model="arm">
  <compiler angle="radian"/>
  <worldbody>
    <body name="upper" pos="0 0 0.3">
      <joint name="shoulder" type="hinge" axis="0 1 0" range="-2 2" ref="{ref}"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03"/>
      <body name="fore" pos="0.4 0 0">
        <joint name="elbow" type="hinge" axis="0 0 1" range="0.2 2.5"/>
        <geom type="box" size="0.15 0.02 0.02" pos="0.15 0 0"/>
        <body name="tool" pos="0.3 0 0">
          <joint name="slide" type="slide" axis="1 0 0" range="0 0.05"/>
          <geom type="sphere" size="0.02"/>
        </body>
      </body>
    </body>
  </worldbody>
  {keyframe}
</mujoco>"""


def _model(tmp_path, ref=0.0, keyframe=""):
    path = tmp_path / "arm.xml"
    path.write_text(_ARM.format(ref=ref, keyframe=keyframe))
    return mujoco.MjModel.from_xml_path(str(path)), path


def _mujoco_poses(model, key=None):
    data = mujoco.MjData(model)
    if key is None:
        mujoco.mj_resetData(model, data)
    else:
        mujoco.mj_resetDataKeyframe(model, data, key)
    mujoco.mj_kinematics(model, data)
    return {model.body(b).name: (data.xpos[b].copy(), data.xmat[b].reshape(3, 3).copy()) for b in range(1, model.nbody)}


def _check(tree, model, key=None):
    st = tree.forward(tree.home)
    for name, (p, r) in _mujoco_poses(model, key).items():
        np.testing.assert_allclose(st.pose(name).position, p, rtol=0, atol=1e-12)
        np.testing.assert_allclose(st.pose(name).rotation, r, rtol=0, atol=1e-12)


def test_home_is_the_home_keyframe(tmp_path):
    key = '<keyframe><key name="other" qpos="0.1 0.3 0.01"/><key name="home" qpos="0.7 1.1 0.02"/></keyframe>'
    model, path = _model(tmp_path, ref=0.25, keyframe=key)
    tree = mjcf_tree(model)
    np.testing.assert_array_equal(tree.home, [0.7, 1.1, 0.02])
    _check(tree, model, key=1)
    body = load_mjcf(path)  # no joint motion: it rests at home
    np.testing.assert_allclose(body.state(0.3).pose("fore").position, _mujoco_poses(model, 1)["fore"][0],
                               rtol=0, atol=1e-12)
    # A motion of one joint: the others hold their home values.
    held = ArticulatedBody("arm2", tree, JointKeyframes([0, 1], [[0.0], [0.5]], joint_names=["shoulder"]))
    q = held.joint_state(1.0)[0]
    np.testing.assert_array_equal(q, [0.5, 1.1, 0.02])


def test_home_without_keyframe_is_qpos0_clipped(tmp_path):
    model, _ = _model(tmp_path, ref=0.25)
    tree = mjcf_tree(model)
    # shoulder: ref 0.25 (MuJoCo's qpos0); elbow: 0 outside [0.2, 2.5], clipped; slide: 0.
    np.testing.assert_array_equal(tree.home, [0.25, 0.2, 0.0])
    data = mujoco.MjData(model)
    np.testing.assert_array_equal(data.qpos[:1], [0.25])
    st = tree.forward(np.r_[0.25, 0.0 + 0.2, 0.0])
    # At q = qpos0 the tree is MuJoCo's model as written (the reference pose, MuJoCo's body frames).
    data.qpos[:] = [0.25, 0.2, 0.0]
    mujoco.mj_kinematics(model, data)
    for b in range(1, model.nbody):
        np.testing.assert_allclose(st.pose(model.body(b).name).position, data.xpos[b], rtol=0, atol=1e-12)


def test_tree_home_is_checked():
    links = [Link("a"), Link("b")]
    joints = [Joint("j", "revolute", "a", "b", Pose(), axis=(0, 0, 1), lower=-1, upper=1)]
    assert KinematicTree("t", links, joints, home=[0.5]).home.tolist() == [0.5]
    with pytest.raises(ConfigError, match=r"t\.home = 1\.5.*limits \[-1, 1\]"):
        KinematicTree("t", links, joints, home=[1.5])
    with pytest.raises(ConfigError, match=r"t\.home.*1 finite numbers"):
        KinematicTree("t", links, joints, home=[0.1, 0.2])
    tree = KinematicTree("t", links, joints, home=[0.5])
    h = tree.home
    h[0] = 0.9  # a copy: the tree's home does not change
    assert tree.home.tolist() == [0.5]
