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
