"""Forward kinematics and link velocities of MJCF robots against MuJoCo's own."""

import mujoco
import numpy as np
import pytest

from twinsense.robots import mjcf_tree

# Both sides compute in float64 from the same compiled model (MuJoCo's normalised body quaternions);
# chains of ~10 rotations accumulate a few 1e-16. 1e-9 m, 1e-9 rad and 1e-9 m/s leave a wide margin.
TOL = 1e-9


@pytest.fixture(scope="module", params=["ur5e-mjcf", "panda-mjcf"])
def compiled(request, mj_model):
    model = mj_model(request.param)
    return model, mjcf_tree(model)


def test_forward_kinematics_and_velocities_match_mujoco(compiled):
    model, tree = compiled
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    assert model.nq == tree.n_joints  # fixed-base arms: qpos is q in joint order
    assert tree.joint_names == tuple(model.joint(j).name for j in range(model.njnt))
    res = np.zeros(6)
    for _ in range(10):
        q = rng.uniform(tree.limits[:, 0], tree.limits[:, 1])
        qd = rng.uniform(-2.0, 2.0, tree.n_joints)
        data.qpos[:] = q
        data.qvel[:] = qd
        mujoco.mj_forward(model, data)
        st = tree.forward(q, qd)
        for b in range(1, model.nbody):
            name = model.body(b).name
            np.testing.assert_allclose(st.pose(name).position, data.xpos[b], atol=TOL)
            np.testing.assert_allclose(st.pose(name).rotation, data.xmat[b].reshape(3, 3), atol=TOL)
            # flg_local = 0: (angular, linear) world-aligned; mjOBJ_XBODY is the body frame (mjOBJ_BODY
            # would be the inertial frame at the centre of mass).
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_XBODY, b, res, 0)
            np.testing.assert_allclose(st.angular_velocities[st.index(name)], res[:3], atol=TOL)
            np.testing.assert_allclose(st.linear_velocities[st.index(name)], res[3:], atol=TOL)


def test_mjcf_meshes_match_the_compiled_model(compiled):
    model, tree = compiled
    # Every drawn face of the visual geoms ends up in exactly one link mesh.
    visual = (model.geom_contype == 0) & (model.geom_conaffinity == 0) & (model.geom_type == 7)
    faces = int(sum(model.mesh_facenum[model.geom_dataid[g]] for g in np.nonzero(visual)[0]))
    ours = sum(len(lk.geometry.faces) for lk in tree.links if lk.geometry is not None)
    # TriangleMesh drops no face here (merge keeps all; degenerate ones are dropped only when ray-cast).
    assert ours == faces


OFFSET_JOINTS = """<mujoco model="offsets">
  <worldbody>
    <body name="a" pos="0.1 0.2 0.3" quat="0.9 0.1 0.3 0.2">
      <joint name="hinge_off" type="hinge" pos="0.05 -0.1 0.2" axis="1 1 0" range="-120 120" limited="true"/>
      <geom type="capsule" size="0.03 0.1"/>
      <body name="b" pos="0.3 0 0" euler="30 -20 60">
        <joint name="slide_b" type="slide" pos="0.1 0 0" axis="0 0 1"/>
        <joint name="hinge_b" type="hinge" pos="0 0.1 -0.05" axis="0 1 0.5"/>
        <geom type="box" size="0.05 0.02 0.04" pos="0.1 0 0"/>
        <body name="c" pos="0 0.2 0"><joint name="ball" type="ball"/><geom type="sphere" size="0.02"/></body>
      </body>
    </body>
  </worldbody>
</mujoco>"""


def test_offset_and_stacked_joints_match_mujoco():
    # A hinge away from its body's origin, a slide and a hinge stacked in one body, a ball joint (fixed here).
    model = mujoco.MjModel.from_xml_string(OFFSET_JOINTS)
    tree = mjcf_tree(model)
    assert tree.joint_names == ("hinge_off", "slide_b", "hinge_b")
    assert "b:slide_b" in tree.link_names and "a:hinge_off" in tree.link_names
    data = mujoco.MjData(model)
    rng = np.random.default_rng(2)
    res = np.zeros(6)
    for _ in range(10):
        q = rng.uniform(-1.5, 1.5, 3)
        qd = rng.uniform(-2.0, 2.0, 3)
        data.qpos[:3] = q  # the ball joint's quaternion stays the identity
        data.qvel[:3] = qd
        mujoco.mj_forward(model, data)
        st = tree.forward(q, qd)
        for b in range(1, model.nbody):
            name = model.body(b).name
            np.testing.assert_allclose(st.pose(name).matrix[:3], np.c_[data.xmat[b].reshape(3, 3), data.xpos[b]],
                                       atol=TOL)
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_XBODY, b, res, 0)
            np.testing.assert_allclose(st.angular_velocities[st.index(name)], res[:3], atol=TOL)
            np.testing.assert_allclose(st.linear_velocities[st.index(name)], res[3:], atol=TOL)
