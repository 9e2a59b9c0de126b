"""Every robot robosuite ships, through twinsense's MJCF tree and MuJoCo co-simulation, against MuJoCo itself.

For each ``<robot>/robot.xml``: (a) every body's world pose and velocities from
:func:`~twinsense.robots.mjcf_tree` at random joint states against MuJoCo's
``mj_kinematics`` and ``mj_objectVelocity``; (b) :class:`~twinsense.robots.MujocoCosim`
with every geom: each geom placed where MuJoCo puts it, and a wrist-mounted ToF
camera captured between two physics steps at the pose the adapter documents.
A small model with what robosuite's robots lack (capsule, ellipsoid, infinite
plane, height fields and an SDF, a ball joint, joints with ``ref``, a mocap
body) goes through the same checks.

Tolerance 1e-9 (m, rad, m/s, rad/s) throughout: both sides compute in float64
from the same compiled model; the longest chain here (GR1: 15 bodies, 11 joints
deep, on a free base; coordinates ~2 m, speeds ~10 m/s) accumulates a few 1e-15
of rounding (<= 5.2e-15 seen), so 1e-9 leaves five orders of margin while any
error of convention (a wrong frame, point, axis order, half-size or reference
position) shows as 1e-4 or more, and reading the step before a frame time on a
step as ~1e-6 m. The whole file runs in ~15 s on 2 cores (14-17 s measured),
6 s of it MuJoCo compiling the 12 robots.
"""

import functools
import zlib

import mujoco
import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from twinsense.robots import MujocoCosim, load_mjcf
from twinsense.robots.mjcf import geom_mesh, infinite_plane_size
from twinsense.robots.paths import robosuite_robots_dir
from twinsense.scene import Box, Capsule, Cylinder, Mount, Plane, Pose, Sphere
from twinsense.scene.motion import MotionState
from twinsense.tof.camera import ToFCamera

TOL = 1e-9
ROBOTS_DIR = robosuite_robots_dir()
ROBOTS = sorted(p.name for p in ROBOTS_DIR.iterdir() if (p / "robot.xml").is_file())
EXPECTED = ["baxter", "gr1", "iiwa", "jaco", "kinova3", "panda", "sawyer", "spot", "spot_arm", "tiago", "ur5e",
            "xarm7"]
FREE, SLIDE, HINGE = (int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_SLIDE),
                      int(mujoco.mjtJoint.mjJNT_HINGE))
G = mujoco.mjtGeom
PLANE, HFIELD, SPHERE, CAPSULE, ELLIPSOID, CYLINDER, BOX, MESH, SDF = (int(getattr(G, f"mjGEOM_{n}")) for n in (
    "PLANE", "HFIELD", "SPHERE", "CAPSULE", "ELLIPSOID", "CYLINDER", "BOX", "MESH", "SDF"))


def test_every_robosuite_robot_is_covered():
    # A robot added to (or dropped from) robosuite shows here rather than silently in the parameters.
    assert ROBOTS == EXPECTED


@functools.cache
def compiled(robot: str):
    return mujoco.MjModel.from_xml_path(str(ROBOTS_DIR / robot / "robot.xml"))


def _seed(robot: str) -> int:
    return zlib.crc32(robot.encode())  # one fixed seed per robot, the same on every run


def _random_quat(rng) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)  # MuJoCo order (w, x, y, z); a normalised Gaussian is uniform on SO(3)


def _free_base(model, data, j) -> MotionState:
    """The tree's base (root link "world") state that puts free joint j's body where MuJoCo's qpos, qvel do.

    twinsense keeps a free joint as a fixed joint at the body's MJCF offset O (MuJoCo's qpos0); the
    body's motion is the base's: base = X O^-1 with X the free joint's pose. MuJoCo's free-joint qvel
    is (linear velocity of the body origin in world axes, angular velocity in body axes).
    """
    b = int(model.jnt_bodyid[j])
    qa, da = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
    w, x, y, z = data.qpos[qa + 3:qa + 7]
    body_pose = Pose.from_quat(data.qpos[qa:qa + 3], (x, y, z, w))
    w0, x0, y0, z0 = model.body_quat[b]
    base = body_pose @ Pose.from_quat(model.body_pos[b], (x0, y0, z0, w0)).inverse()
    omega = body_pose.rotation @ data.qvel[da + 3:da + 6]
    v = data.qvel[da:da + 3] + np.cross(omega, base.position - body_pose.position)
    return MotionState(base, v, omega)


def _one_dof_ranges(model) -> tuple[list[int], np.ndarray]:
    """MuJoCo's hinge and slide joints and the ranges (n, 2) [rad or m] random states are drawn from."""
    one_dof = [j for j in range(model.njnt) if model.jnt_type[j] in (HINGE, SLIDE)]
    lim = np.array([model.jnt_range[j] if model.jnt_limited[j] else  # without limits: one turn, or +-0.5 m
                    ((-np.pi, np.pi) if model.jnt_type[j] == HINGE else (-0.5, 0.5)) for j in one_dof], float)
    return one_dof, lim.reshape(-1, 2)


@pytest.mark.parametrize("robot", ROBOTS)
def test_tree_poses_and_velocities_match_mujoco(robot):
    model = compiled(robot)
    floating = check_tree(model, np.random.default_rng(_seed(robot)))
    assert floating == [j for j in range(model.njnt) if model.jnt_type[j] == FREE]  # GR1's and Spot's bases moved


def check_tree(model, rng) -> list[int]:
    """Every body's pose and velocities from twinsense's tree at 2 random states against MuJoCo's; returns
    the free joints moved through the tree's base."""
    tree = load_mjcf(model).tree
    # The tree's joints are MuJoCo's hinge and slide joints, in MuJoCo's order; free and ball joints are
    # fixed joints of the tree (module docstring of twinsense.robots.mjcf).
    one_dof, lim = _one_dof_ranges(model)
    assert tree.joint_names == tuple(model.joint(j).name for j in one_dof)
    np.testing.assert_array_equal(tree.limits, np.where(model.jnt_limited[one_dof, None], lim, [-np.inf, np.inf]))
    qadr, dadr = model.jnt_qposadr[one_dof], model.jnt_dofadr[one_dof]
    free = [j for j in range(model.njnt) if model.jnt_type[j] == FREE]
    # A robot on a free joint (GR1, Spot: the only body hung from the world) moves as the tree's base;
    # a free body beside others keeps its fixed joint at qpos0, at rest, as the tree has it.
    floating = free if len(free) == 1 and np.count_nonzero(model.body_parentid[1:] == 0) == 1 else []
    data = mujoco.MjData(model)
    res = np.zeros(6)
    for _ in range(2):
        q = rng.uniform(lim[:, 0], lim[:, 1])
        qd = rng.uniform(-2.0, 2.0, len(q))
        data.qpos[:], data.qvel[:] = model.qpos0, 0.0  # ball joints at qpos0 (identity), as the tree has them
        data.qpos[qadr], data.qvel[dadr] = q, qd
        base = None
        for j in floating:
            qa, da = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
            data.qpos[qa:qa + 3], data.qpos[qa + 3:qa + 7] = rng.uniform(-1, 1, 3), _random_quat(rng)
            data.qvel[da:da + 6] = rng.uniform(-2.0, 2.0, 6)
            base = _free_base(model, data, j)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_comVel(model, data)  # mj_objectVelocity reads cvel and the subtree centres of mass
        st = tree.forward(q, qd, base)
        for b in range(1, model.nbody):
            name = model.body(b).name
            i = st.index(name)
            np.testing.assert_allclose(st.positions[i], data.xpos[b], rtol=0, atol=TOL, err_msg=name)
            np.testing.assert_allclose(st.rotations[i], data.xmat[b].reshape(3, 3), rtol=0, atol=TOL, err_msg=name)
            # flg_local = 0: the 6-vector is (angular, linear) in world axes; mjOBJ_XBODY gives the linear
            # part at the body frame's origin (xpos), mjOBJ_BODY at the inertial frame's (xipos, the centre
            # of mass): the tree's origin velocity and its point velocity there.
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_XBODY, b, res, 0)
            np.testing.assert_allclose(st.angular_velocities[i], res[:3], rtol=0, atol=TOL, err_msg=name)
            np.testing.assert_allclose(st.linear_velocities[i], res[3:], rtol=0, atol=TOL, err_msg=name)
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, b, res, 0)
            np.testing.assert_allclose(st.point_velocity(name, data.xipos[b][None])[0], res[3:], rtol=0, atol=TOL,
                                       err_msg=name)
    return floating


# ---------------------------------------------------------------- geoms and the co-simulation clock
def _on_surface(t: int, size: np.ndarray, v: np.ndarray, plane_side: float) -> tuple[np.ndarray, np.ndarray]:
    """(distance of each geom-frame vertex (n, 3) from the geom's exact surface [m], the surface's
    extent along x, y, z [m]), from MuJoCo's own meaning of ``geom_size`` (half sizes, radii);
    ``plane_side``: the side an infinite plane is drawn [m]."""
    x, y, z = v.T
    if t == SPHERE:
        return np.abs(np.linalg.norm(v, axis=1) - size[0]), np.full(3, size[0])
    if t == ELLIPSOID:  # the unit sphere scaled by the radii: sum (x_i / a_i)^2 = 1
        return np.abs(np.sum((v / size) ** 2, axis=1) - 1.0) * size.min(), size.copy()
    if t == BOX:  # on a face: inside every slab, on at least one of them
        d = np.abs(v) - size
        return np.where(np.all(d <= TOL, axis=1), np.abs(d.max(axis=1)), np.inf), size.copy()
    r, h = size[0], size[1]
    if t == CAPSULE:  # radius r about the segment z in [-h, h]
        return np.abs(np.linalg.norm(v - np.c_[0 * x, 0 * y, np.clip(z, -h, h)], axis=1) - r), np.array([r, r, h + r])
    if t == CYLINDER:  # on the side or on a cap
        rho = np.hypot(x, y)
        side, cap = np.abs(rho - r), np.abs(np.abs(z) - h)
        inside = (rho <= r + TOL) & (np.abs(z) <= h + TOL)
        return np.where(inside, np.minimum(side, cap), np.inf), np.array([r, r, h])
    assert t == PLANE
    # size 0 is MuJoCo's infinite plane, drawn as a finite square (documented in docs/robots.md)
    half = np.array([s if s > 0 else plane_side / 2 for s in size[:2]])
    inside = np.all(np.abs(v[:, :2]) <= half + TOL, axis=1)
    return np.where(inside, np.abs(z), np.inf), np.array([*half, 0.0])


def _geom_points(model, g: int) -> np.ndarray | None:
    """Geom-frame points (n, 3) [m] twinsense must draw for geom g, None for a type it leaves out."""
    t = int(model.geom_type[g])
    if t == MESH:  # MuJoCo's compiled vertices (scaled, re-centred), not twinsense's reading
        m = int(model.geom_dataid[g])
        return np.asarray(model.mesh_vert[model.mesh_vertadr[m]:model.mesh_vertadr[m] + model.mesh_vertnum[m]], float)
    mesh = geom_mesh(model, g, "test")
    if t == SDF:
        assert mesh is None  # SDFs are left out, with a warning (docs/robots.md, "Limits of the model")
        return None
    if t == HFIELD:  # a closed prism; its top against MuJoCo's ray test in test_cosim_review.py
        return mesh[0]
    v = mesh[0]
    # The tessellation lies on the exact surface of MuJoCo's size and spans it: along each axis the
    # vertex nearest it is within half an edge (<= 4 deg for the 32-gons and the 3-times subdivided
    # icosahedron), so the extent is at least cos(4 deg) = 0.9976 of the exact one; 0.99 is the bound.
    dist, extent = _on_surface(t, np.asarray(model.geom_size[g], float), v, infinite_plane_size(model))
    assert dist.max() <= TOL, (model.geom(g).name, t, dist.max())
    seen = np.abs(v).max(axis=0)
    assert np.all(seen <= extent + TOL) and np.all(seen >= 0.99 * extent), (t, seen, extent)
    return v


def _exact_primitive_matches(model, g: int, geom) -> None:
    t, s = int(model.geom_type[g]), model.geom_size[g]
    expect = {SPHERE: (Sphere, {"radius": s[0]}), BOX: (Box, {"size": tuple(2 * s)}),
              CAPSULE: (Capsule, {"radius": s[0], "height": 2 * s[1]}),
              CYLINDER: (Cylinder, {"radius": s[0], "height": 2 * s[1]})}
    if t == PLANE:
        expect[t] = (Plane, {"size": tuple(2 * x if x > 0 else infinite_plane_size(model) for x in s[:2])})
    cls, fields = expect[t]
    assert type(geom) is cls
    for k, val in fields.items():
        np.testing.assert_allclose(getattr(geom, k), val, rtol=0, atol=1e-15)


def check_geoms(cosim: MujocoCosim, data, t: float) -> None:
    """Every geom of ``cosim.model`` (co-simulated with geoms="all") is drawn at MuJoCo's geom pose in ``data``
    (the physics state at time t), or left out by type; nothing else is drawn."""
    model, scene = cosim.model, cosim.scene
    for b in range(model.nbody):
        name = cosim.names[b]
        gids = range(int(model.body_geomadr[b]), int(model.body_geomadr[b] + model.body_geomnum[b]))
        parts = [(g, _geom_points(model, g)) for g in gids]
        parts = [(g, v) for g, v in parts if v is not None]
        if not parts:  # no geom, or only left-out types: a mount frame (none for the world body)
            assert name not in {o.name for o in scene.objects}
            assert b == 0 or name in scene.frame_names
            continue
        obj = scene.object(name)
        st = obj.state_at(t)
        if type(obj.geometry) in (Sphere, Box, Capsule, Cylinder, Plane):
            assert len(parts) == 1, name
            # a single primitive at the body origin stays an exact primitive: the object frame is the geom's
            g = parts[0][0]
            _exact_primitive_matches(model, g, obj.geometry)
            np.testing.assert_allclose(st.pose.position, data.geom_xpos[g], rtol=0, atol=TOL)
            np.testing.assert_allclose(st.pose.rotation, data.geom_xmat[g].reshape(3, 3), rtol=0, atol=TOL)
            continue
        # the merged mesh's vertices as built (trimesh's processed view merges those within 1e-8)
        drawn = st.pose.apply(np.asarray(obj.geometry.vertices, float))
        assert len(drawn) == sum(len(v) for _, v in parts), name  # nothing but these geoms
        world = [v @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g] for g, v in parts]
        if np.abs(np.vstack(world) - drawn).max() <= TOL:
            continue  # the parts in geom order (the fast way to pass); else each part anywhere in the mesh
        near = cKDTree(drawn)
        for (g, _), w in zip(parts, world, strict=True):
            d, _ = near.query(w)
            assert d.max() <= TOL, (name, model.geom(g).name, d.max())


def _wrist(model) -> int:
    """The body with the most joints above it (the end of the longest chain: a hand, a gripper, a foot)."""
    depth = np.zeros(model.nbody, int)
    for b in range(1, model.nbody):  # parents come before children
        depth[b] = depth[model.body_parentid[b]] + int(model.body_jntnum[b])
    return int(np.argmax(depth))


def _propagated(model, data, b: int, tau: float) -> MotionState:
    """Body b's state tau after the step held in ``data``, as MujocoCosim documents it: p_k + v_k tau,
    exp([w_k tau]x) R_k, velocities held (the body origin's, world axes)."""
    res = np.zeros(6)
    mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_XBODY, b, res, 0)
    w, v = res[:3].copy(), res[3:].copy()
    rot = Rotation.from_rotvec(w * tau).as_matrix() @ data.xmat[b].reshape(3, 3)
    return MotionState(Pose(data.xpos[b] + v * tau, rot), v, w)


def _assert_state(ours: MotionState, ref_pose: Pose, ref_v, ref_w, what: str) -> None:
    np.testing.assert_allclose(ours.pose.position, ref_pose.position, rtol=0, atol=TOL, err_msg=what)
    np.testing.assert_allclose(ours.pose.rotation, ref_pose.rotation, rtol=0, atol=TOL, err_msg=what)
    np.testing.assert_allclose(ours.linear_velocity, ref_v, rtol=0, atol=TOL, err_msg=what)
    np.testing.assert_allclose(ours.angular_velocity, ref_w, rtol=0, atol=TOL, err_msg=what)


STEPS = 25  # physics steps before the capture (the arms sag under gravity: bodies move and turn)
FRACTION = 0.4  # the capture at t = (STEPS + FRACTION) dt, between steps STEPS and STEPS + 1
MOUNT = Pose.from_euler_deg((0.02, -0.01, 0.05), (10.0, 0.0, 30.0))  # sensor -> wrist body


def check_cosim(model, rng) -> None:
    # A random start (joints within their ranges, every joint moving), the same for the co-simulation and
    # the reference, MuJoCo alone with the same calls (mj_forward, then mj_step).
    one_dof, lim = _one_dof_ranges(model)
    q0, qd0 = rng.uniform(lim[:, 0], lim[:, 1]), rng.uniform(-1.0, 1.0, model.nv)
    data, ref = mujoco.MjData(model), mujoco.MjData(model)
    for d in (data, ref):
        d.qpos[model.jnt_qposadr[one_dof]], d.qvel[:] = q0, qd0
    cosim = MujocoCosim(model, data, geoms="all")
    follower = cosim.joint_setpoints({model.joint(j).name: model.joint(j).name for j in one_dof})
    qadr, dadr = model.jnt_qposadr[one_dof], model.jnt_dofadr[one_dof]
    mujoco.mj_forward(model, ref)
    for _ in range(STEPS):
        mujoco.mj_step(model, ref)
    mujoco.mj_forward(model, ref)  # after mj_step xpos, xmat lag one step: recompute them from qpos, qvel
    t = (STEPS + FRACTION) * model.opt.timestep
    tau = t - ref.time
    assert 0 < tau < model.opt.timestep

    wrist = _wrist(model)
    name = cosim.names[wrist]
    tof = ToFCamera.preset("generic", name="wrist_tof", width=32, height=24, mount=Mount(MOUNT, name))
    frame = tof.capture(cosim.scene, t, np.random.default_rng(0))
    assert frame.t == t and frame.depth.shape == (24, 32)
    body = _propagated(model, ref, wrist, tau)
    assert np.linalg.norm(body.angular_velocity) > 1e-3  # the wrist really turns: the propagation is exercised
    mount = body.pose @ MOUNT
    np.testing.assert_allclose(frame.pose.matrix, mount.matrix, rtol=0, atol=TOL)
    _assert_state(tof.mount.state_at(cosim.scene, t), mount, body.point_velocity(mount.position[None])[0],
                  body.angular_velocity, "wrist mount")

    # Every moving body and every named site at that time: its step's state moved on by tau.
    for b in range(1, model.nbody):
        st = _propagated(model, ref, b, tau)
        _assert_state(cosim.scene.mount_target(cosim.names[b]).state_at(t), st.pose, st.linear_velocity,
                      st.angular_velocity, cosim.names[b])
    for s in range(model.nsite):
        b = int(model.site_bodyid[s])
        st = _propagated(model, ref, b, tau)
        # The site's offset in its body, from MuJoCo's world site pose at the step.
        rb = ref.xmat[b].reshape(3, 3)
        offset = Pose(rb.T @ (ref.site_xpos[s] - ref.xpos[b]), rb.T @ ref.site_xmat[s].reshape(3, 3))
        pose = st.pose @ offset
        _assert_state(cosim.scene.mount_target(model.site(s).name).state_at(t), pose,
                      st.point_velocity(pose.position[None])[0], st.angular_velocity, model.site(s).name)
    # On a step every geom is where MuJoCo puts it; the step's own time is the clock's k dt (a frame time
    # k / frame_rate), which MuJoCo's accumulated time (k additions of dt) misses by a few ulps either way:
    # that time is on the step and sees its state, not the previous step's moved on by ~dt.
    on_step = STEPS * model.opt.timestep
    assert 0 < ref.time - on_step < 1e-9 * model.opt.timestep  # the case that read the step before
    check_geoms(cosim, ref, on_step)
    res = np.zeros(6)
    for b in range(1, model.nbody):
        mujoco.mj_objectVelocity(model, ref, mujoco.mjtObj.mjOBJ_XBODY, b, res, 0)
        _assert_state(cosim.body_state(b, on_step), Pose(ref.xpos[b], ref.xmat[b].reshape(3, 3)), res[3:], res[:3],
                      cosim.names[b])
    # A joint motion following MuJoCo's joints: the step's qpos, qvel on the step, moved on linearly between.
    np.testing.assert_allclose(follower.q(on_step), ref.qpos[qadr], rtol=0, atol=TOL)
    np.testing.assert_allclose(follower.qd(on_step), ref.qvel[dadr], rtol=0, atol=TOL)
    np.testing.assert_allclose(follower.q(t), ref.qpos[qadr] + ref.qvel[dadr] * tau, rtol=0, atol=TOL)
    np.testing.assert_allclose(follower.qd(t), ref.qvel[dadr], rtol=0, atol=TOL)


@pytest.mark.parametrize("robot", ROBOTS)
def test_cosim_geoms_and_wrist_tof_between_steps(robot):
    check_cosim(compiled(robot), np.random.default_rng(_seed(robot)))


EVERY_GEOM = """<mujoco model="every_geom">
  <option timestep="0.004" gravity="0 0 -9.81"/>
  <extension><plugin plugin="mujoco.sdf.torus"><instance name="torus">
    <config key="radius1" value="0.1"/><config key="radius2" value="0.03"/></instance></plugin></extension>
  <asset>
    <mesh name="torus"><plugin instance="torus"/></mesh>
    <hfield name="terrain" nrow="3" ncol="3" size="0.5 0.5 0.1 0.05" elevation="0 1 0 1 0 1 0 1 0"/>
    <mesh name="tet" vertex="0 0 0  0.1 0 0  0 0.1 0  0 0 0.1" scale="1 2 1"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 0.05" pos="0 0 -1"/>
    <body name="ground" pos="2 0 -0.9"><geom type="hfield" hfield="terrain"/></body>
    <body name="ring" pos="-1 0 0.2"><joint name="spin" type="hinge" axis="1 0 0"/>
      <geom type="sdf" mesh="torus"><plugin instance="torus"/></geom>
      <geom name="tag" type="box" size="0.01 0.01 0.01" pos="0.2 0 0"/></body>
    <body name="arm" pos="0 0 0.5" euler="10 20 30">
      <joint name="shoulder" type="hinge" axis="0 1 1" ref="20"/>
      <geom name="cap" type="capsule" size="0.03 0.1" pos="0.1 0 0" euler="0 90 0"/>
      <geom name="ell" type="ellipsoid" size="0.05 0.03 0.02" pos="0.25 0.01 0" euler="5 10 15"/>
      <geom name="can" type="cylinder" size="0.02 0.04" pos="0.3 -0.05 0"/>
      <geom name="bump" type="hfield" hfield="terrain" pos="0.3 0 0.2"/>
      <body name="hand" pos="0.4 0 0" euler="0 0 40">
        <joint name="wrist" type="slide" axis="1 0 0" pos="0.02 0 0" ref="0.05"/>
        <joint name="roll" type="hinge" axis="1 0 0" pos="0 0.03 0"/>
        <geom name="ball" type="sphere" size="0.03"/>
        <body name="tip" pos="0.05 0 0"><joint name="swivel" type="ball"/>
          <geom name="pad" type="box" size="0.01 0.02 0.03" pos="0.01 0 0" euler="0 0 20"/>
          <geom name="tet" type="mesh" mesh="tet" pos="0.02 0 0"/>
          <site name="tool" pos="0.04 0.01 0" euler="0 90 0"/>
        </body>
      </body>
    </body>
    <body name="crate" pos="0 1 0.3"><freejoint/><geom type="box" size="0.1 0.05 0.02"/></body>
    <body name="target" mocap="true" pos="0 -1 0.5"><geom type="box" size="0.02 0.02 0.02" pos="0 0 0.05"/>
      <site name="aim" pos="0 0 0.1"/></body>
  </worldbody>
</mujoco>"""


def test_every_geom_type_and_free_and_ball_joints():
    # Capsule, ellipsoid, an infinite plane, height fields, an SDF, a ball joint and joints with a reference
    # position (ref: MuJoCo turns a hinge by qpos - qpos0): what robosuite's robots do not use, through
    # the same checks (with a free body beside the arm and a mocap body moved by the controller).
    model = mujoco.MjModel.from_xml_string(EVERY_GEOM)
    assert np.all(model.qpos0[model.jnt_qposadr[[model.joint("shoulder").id, model.joint("wrist").id]]] != 0)
    check_tree(model, np.random.default_rng(11))
    data = mujoco.MjData(model)
    data.qvel[:] = np.random.default_rng(3).uniform(-2, 2, model.nv)  # turning from the start

    def control(m, d):  # the mocap body glides along x and turns about z
        d.mocap_pos[0] = (0.3 * d.time, -1.0, 0.5)
        d.mocap_quat[0] = (np.cos(d.time), 0.0, 0.0, np.sin(d.time))

    cosim = MujocoCosim(model, data, geoms="all", control=control)
    assert "ground" in {o.name for o in cosim.scene.objects}  # a body with only a height field is drawn
    assert len(cosim.scene.object("ring").geometry.vertices) == 8  # the SDF left out, the box kept
    assert isinstance(cosim.scene.object("hand").geometry, Sphere)  # one primitive at the body origin
    ref = mujoco.MjData(model)
    ref.qvel[:] = data.qvel
    mujoco.mj_forward(model, ref)
    check_geoms(cosim, ref, 0.0)
    t = 7.5 * model.opt.timestep
    for _ in range(7):
        control(model, ref)
        mujoco.mj_step(model, ref)
    mujoco.mj_forward(model, ref)
    assert ref.mocap_pos[0, 0] > 0  # the mocap body has moved
    # MuJoCo gives the mocap body no velocity; MujocoCosim the finite difference of its last two steps,
    # exact for the controller's constant glide (0.3 m/s along x) and turn (2 rad/s about z).
    v_m, w_m, tau = np.array([0.3, 0.0, 0.0]), np.array([0.0, 0.0, 2.0]), t - ref.time
    turn = Rotation.from_rotvec(w_m * tau).as_matrix()
    for b in range(1, model.nbody):
        st = _propagated(model, ref, b, tau)
        if model.body_mocapid[b] >= 0:
            st = MotionState(Pose(ref.xpos[b] + v_m * tau, turn @ ref.xmat[b].reshape(3, 3)), v_m, w_m)
        _assert_state(cosim.scene.mount_target(cosim.names[b]).state_at(t), st.pose, st.linear_velocity,
                      st.angular_velocity, cosim.names[b])
    aim, target = model.site("aim").id, model.body("target").id
    np.testing.assert_allclose(cosim.scene.mount_target("aim").state_at(t).pose.position,
                               ref.xpos[target] + v_m * tau + turn @ (ref.site_xpos[aim] - ref.xpos[target]),
                               rtol=0, atol=TOL)
    check_geoms(cosim, ref, ref.time)
