"""MuJoCo co-simulation with models a user brings: free, ball and slide joints, mocap bodies, every geom
type, odd time steps, files with relative mesh folders, and the errors a user can run into."""

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import twinsense as ts
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


@pytest.fixture
def in_tmp(tmp_path, monkeypatch):
    """MuJoCo appends its warnings to MUJOCO_LOG.TXT in the working folder: a temporary one here."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


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


def test_diverging_physics_raises_instead_of_hanging(in_tmp):
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


def test_nan_in_the_state_is_refused(in_tmp):
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


def test_nan_control_is_refused(in_tmp):
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


# --------------------------------------------------------------------------- closed forms
def _mujoco_reference(model, t):
    """MuJoCo's own state at the last step at or before ``t`` (stepped separately), after mj_forward."""
    data = mujoco.MjData(model)
    while data.time + model.opt.timestep * (1 - 1e-9) <= t:
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    return data


@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_free_fall_between_steps(integrator):
    dt, z0 = 0.003, 2.0
    model = drop_model(dt, integrator, z0)
    cosim = MujocoCosim(model)
    box, top = model.body("box").id, model.site("top").id
    for t in np.arange(12) / 30.0:  # a 30 Hz clock on 3 ms steps: 1/30 s is 11.1 steps
        st = cosim.body_state("box", t)
        ref = _mujoco_reference(model, t)
        k = round(ref.time / dt)
        # A frame time on a step (0.3 s = 100 steps) misses MuJoCo's summed step time by an ulp either way;
        # the co-simulation reads that step itself (tau = 0).
        assert -1e-12 < t - ref.time < dt
        tau = max(t - ref.time, 0.0)
        # MuJoCo's state at step k moved on by its velocity over tau (no rotation: the box falls flat).
        vel = np.zeros(6)
        mujoco.mj_objectVelocity(model, ref, mujoco.mjtObj.mjOBJ_XBODY, box, vel, 0)
        np.testing.assert_allclose(st.pose.position, ref.xpos[box] + vel[3:] * tau, rtol=0, atol=1e-12)
        np.testing.assert_allclose(st.pose.rotation, ref.xmat[box].reshape(3, 3), rtol=0, atol=1e-15)
        np.testing.assert_allclose(st.linear_velocity, vel[3:], rtol=0, atol=1e-15)
        # The closed form of each integrator. Semi-implicit Euler: v_k = -g k dt, z_k = z0 - g dt^2 k (k+1) / 2,
        # so z(t) = z_k + v_k tau = z0 - g t^2 / 2 - g (t_k dt - tau^2) / 2 exactly (its drift g t dt / 2,
        # 4.4 mm after 0.3 s, plus the propagation's g tau^2 / 2). RK4 is exact on the quadratic at the steps:
        # z(t) = z0 - g t^2 / 2 + g tau^2 / 2. 1e-12 m: float64 rounding of a few operations on 2 m.
        t_k = k * dt
        drift = g_drift = G * t_k * dt / 2 if integrator == "Euler" else 0.0
        assert st.pose.position[2] == pytest.approx(z0 - G * t * t / 2 - drift + G * tau**2 / 2, rel=0, abs=1e-12)
        assert st.linear_velocity[2] == pytest.approx(-G * t_k, rel=0, abs=1e-12)
        assert abs(st.pose.position[2] - (z0 - G * t * t / 2)) <= g_drift + G * dt**2 / 2 + 1e-12
        # A mount on the site follows MuJoCo's site_xpos / site_xmat (at the step; 1e-9 as asked, float64
        # composition of two poses gives ~1e-16).
        on_step = cosim.scene.mount_target("top").state_at(ref.time)
        np.testing.assert_allclose(on_step.pose.position, ref.site_xpos[top], rtol=0, atol=1e-9)
        np.testing.assert_allclose(on_step.pose.rotation, ref.site_xmat[top].reshape(3, 3), rtol=0, atol=1e-9)


def test_tof_and_radar_see_the_falling_box():
    # The documented few lines: a MuJoCo model, MujocoCosim, sensors from presets, simulate. A 0.6 m wide
    # slab (0.2 m thick) falls from z0 = 2 m under a ToF camera and a radar 3 m up, looking down.
    xml = DROP.replace('size="0.1 0.1 0.1"', 'size="0.3 0.3 0.1"')
    model = mujoco.MjModel.from_xml_string(xml.format(dt=0.003, integrator="Euler", z0=2.0))
    cosim = MujocoCosim(model)
    down = ts.Mount(ts.Pose.look_at((0, 0, 3.0), (0, 0, 0), (1, 0, 0)))
    # Expected values only (no noise, no ADC rounding, no cross-talk), rendered at the frame time, a dimmer
    # light so that the slab 0.9 m away does not saturate the pixels; 40 x 30 px keep it fast.
    tof = ts.ToFCamera.preset("pmd_pico_flexx", mode="MODE_9_10FPS_1000", mount=down, name="tof", noise=False,
                              quantization=False, crosstalk_sigma_px=0.0, motion_artifacts=False,
                              width=40, height=30, intrinsics_px=None, fov_deg=(40.0, 30.0),
                              distortion=(0.0,) * 5, supersample=1, illumination_power=0.05)
    radar = ts.FMCWRadar.preset("paper_bgt60tr13c", mount=down, name="radar", render_width=64, render_height=48)
    result = ts.simulate(cosim.scene, [tof, radar], duration=0.4, seed=3)
    assert [round(f.t, 9) for f in result.frames["tof"]] == [0.0, 0.1, 0.2, 0.3]
    for f in result.frames["tof"]:
        top = cosim.body_state("box", f.t).pose.position[2] + 0.1
        h, w = f.depth.shape
        centre = f.depth[h // 2 - 1:h // 2 + 1, w // 2 - 1:w // 2 + 1]
        assert not f.invalid[h // 2 - 1:h // 2 + 1, w // 2 - 1:w // 2 + 1].any()
        # Noise-free, unquantised and without cross-talk, the depth of a fronto-parallel face is exact up to
        # the float32 phases (1e-7 rad: 3e-8 m at 80 MHz) and the float32 depth (ulp 1.2e-7 m at 1.3 m):
        # 1e-5 m leaves a margin (<= 1e-7 m seen).
        np.testing.assert_allclose(centre, 3.0 - top, rtol=0, atol=1e-5)
    cfg = radar.config
    for f in result.frames["radar"]:
        d = f.detections
        i = int(np.argmax(d.snr_db))
        mid = f.t + cfg.chirp.num_chirps * cfg.chirp.chirp_repetition_time / 2  # the chirps' middle
        v = -cosim.body_state("box", mid).linear_velocity[2]  # away from the radar above: positive
        r = 3.0 - (cosim.body_state("box", mid).pose.position[2] + 0.1)
        # One Doppler bin (0.52 m/s; <= 0.11 m/s seen). The range within two range bins (2 x 2.5 cm): one
        # for the bin and the face's spread over pixels, 7 mm for the range-Doppler coupling v f0 / S at
        # 3 m/s (<= 4.2 cm seen).
        assert abs(d.velocity[i] - v) <= cfg.velocity_resolution
        assert abs(d.range[i] - r) <= 2 * cfg.chirp.range_resolution


# --------------------------------------------------------------------------- geoms
HFIELD = """<mujoco>
  <asset><hfield name="hf" nrow="4" ncol="5" size="1.0 0.6 0.3 0.1"
    elevation="0 1 0 1 0  1 0 1 0 0.5  0 0 1 1 0.2  0.7 0.1 0 1 0.3"/></asset>
  <worldbody><geom name="terrain" type="hfield" hfield="hf" pos="0.2 -0.1 0.05" euler="0 0 25"/></worldbody>
</mujoco>"""


def test_height_field_is_drawn_where_mujoco_puts_it():
    import trimesh
    from trimesh.ray.ray_triangle import RayMeshIntersector

    model = mujoco.MjModel.from_xml_string(HFIELD)
    cosim = MujocoCosim(model)
    world = cosim.scene.object("world")
    st = world.state_at(0.0)
    mesh = trimesh.Trimesh(st.pose.apply(np.asarray(world.geometry.vertices, float)),
                           np.asarray(world.geometry.faces), process=False)
    assert mesh.is_watertight and mesh.volume > 0  # a closed prism down to the base, normals out
    # Heights under 400 random points against MuJoCo's own ray test of the height field (an independent
    # implementation: its grid, its cell diagonals). Both are float64 plane intersections: 1e-9 m.
    rng = np.random.default_rng(5)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    local = np.c_[rng.uniform(-0.99, 0.99, 400), rng.uniform(-0.59, 0.59, 400) * 1.0, np.full(400, 5.0)]
    origins = local @ data.geom_xmat[0].reshape(3, 3).T + data.geom_xpos[0] * [1, 1, 0]
    down = np.array([0.0, 0.0, -1.0])
    geomid = np.zeros(1, np.int32)
    theirs = np.array([mujoco.mj_ray(model, data, o, down, None, 1, -1, geomid) for o in origins])
    locs, index_ray, _ = RayMeshIntersector(mesh).intersects_location(origins, np.tile(down, (400, 1)),
                                                                      multiple_hits=False)
    ours = np.full(400, np.nan)
    ours[index_ray] = origins[index_ray, 2] - locs[:, 2]
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-9)


def test_sdf_and_flex_are_left_out_with_a_warning(in_tmp):
    flex = """<mujoco><worldbody><geom name="floor" type="plane" size="1 1 0.1"/>
      <flexcomp name="cloth" type="grid" count="3 3 1" spacing="0.1 0.1 0.1" pos="0 0 1" dim="2"/>
      </worldbody></mujoco>"""
    with pytest.warns(UserWarning, match=r"1 flex object.*not drawn"):
        cosim = MujocoCosim(mujoco.MjModel.from_xml_string(flex))
    assert [o.name for o in cosim.scene.objects] == ["world"]
    assert "cloth_0" in cosim.scene.frame_names  # the flex's vertex bodies stay mount points
    sdf = """<mujoco>
      <extension><plugin plugin="mujoco.sdf.torus"><instance name="torus">
        <config key="radius1" value="0.1"/><config key="radius2" value="0.03"/></instance></plugin></extension>
      <asset><mesh name="torus"><plugin instance="torus"/></mesh></asset>
      <worldbody><body name="ring"><freejoint/><geom name="donut" type="sdf" mesh="torus">
        <plugin instance="torus"/></geom><geom type="box" size="0.01 0.01 0.01" pos="0.2 0 0"/></body>
      </worldbody></mujoco>"""
    with pytest.warns(UserWarning, match=r"cosim.bodies\[ring\]: geom donut .*left out"):
        cosim = MujocoCosim(mujoco.MjModel.from_xml_string(sdf))
    assert len(cosim.scene.object("ring").geometry.vertices) == 8  # the box alone


# --------------------------------------------------------------------------- joints, sites, mocap, names
ARM = """<mujoco model="arm">
  <option timestep="0.002" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="pendulum" pos="0 0 1.5">
      <joint name="ball" type="ball" damping="0.01"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.03"/>
      <geom type="sphere" size="0.05" pos="0 0 -0.45"/>
      <site name="pendulum" pos="0 0.05 -0.45" euler="0 30 0"/>
      <body name="carriage" pos="0 0 -0.5" euler="0 0 30">
        <joint name="rail" type="slide" axis="1 0 0" pos="0.02 0 0"/>
        <geom type="box" size="0.05 0.02 0.02" pos="0.05 0 0"/>
        <geom type="cylinder" size="0.01 0.03" pos="0 0.03 0" euler="90 0 0"/>
        <site name="tool" pos="0.1 0 0" euler="0 90 0"/>
      </body>
    </body>
    <body pos="1 0 1"><freejoint/><geom type="sphere" size="0.05"/></body>
    <body name="body3" pos="1 1 1"><freejoint/><geom type="sphere" size="0.05"/></body>
    <body name="target" mocap="true" pos="0 -1 1"><geom type="box" size="0.05 0.05 0.05"/>
      <site name="aim" pos="0 0 0.1"/></body>
  </worldbody>
</mujoco>"""


def test_ball_slide_nested_sites_and_names():
    model = mujoco.MjModel.from_xml_string(ARM)
    data = mujoco.MjData(model)
    data.qvel[:] = np.random.default_rng(7).uniform(-1, 1, model.nv)  # swinging, sliding, thrown
    cosim = MujocoCosim(model, data)
    names = [o.name for o in cosim.scene.objects]
    # An unnamed body is "body<id>", unless a body is named that: body3 is taken, so "body3_".
    assert names == ["pendulum", "carriage", "body3_", "body3", "target"]
    # A site named like a body (MuJoCo keeps them apart) is the frame "<site>:site".
    assert set(cosim.scene.frame_names) == {"pendulum:site", "tool", "aim"}
    ref = mujoco.MjData(model)
    ref.qvel[:] = data.qvel
    for t in (0.0, 0.1, 0.2503):
        while ref.time + model.opt.timestep * (1 - 1e-9) <= t:
            mujoco.mj_step(model, ref)
        mujoco.mj_forward(model, ref)
        tau = max(t - ref.time, 0.0)
        for b in range(1, model.nbody):
            vel = np.zeros(6)
            mujoco.mj_objectVelocity(model, ref, mujoco.mjtObj.mjOBJ_XBODY, b, vel, 0)
            st = cosim.body_state(b, t)
            # MuJoCo's step state moved on as documented: p + v tau, exp([w tau]x) R. float64 both: 1e-9.
            np.testing.assert_allclose(st.pose.position, ref.xpos[b] + vel[3:] * tau, rtol=0, atol=1e-9)
            turn = Rotation.from_rotvec(vel[:3] * tau).as_matrix()
            np.testing.assert_allclose(st.pose.rotation, turn @ ref.xmat[b].reshape(3, 3), rtol=0, atol=1e-9)
            np.testing.assert_allclose(st.linear_velocity, vel[3:], rtol=0, atol=1e-9)
            np.testing.assert_allclose(st.angular_velocity, vel[:3], rtol=0, atol=1e-9)
        for site, frame in (("pendulum", "pendulum:site"), ("tool", "tool"), ("aim", "aim")):
            s = model.site(site).id
            on = ts.Mount(ts.Pose(), frame).state_at(cosim.scene, ref.time)  # on the step: MuJoCo's site
            np.testing.assert_allclose(on.pose.position, ref.site_xpos[s], rtol=0, atol=1e-9)
            np.testing.assert_allclose(on.pose.rotation, ref.site_xmat[s].reshape(3, 3), rtol=0, atol=1e-9)


def test_mocap_moved_by_the_user_between_steps():
    model = mujoco.MjModel.from_xml_string(ARM)
    cosim = MujocoCosim(model)
    cosim.step_to(0.1)
    t_k = cosim.time
    cosim.data.mocap_pos[0] = (0.3, -1.2, 0.8)  # moved by hand between steps
    cosim.data.mocap_quat[0] = (np.cos(0.2), 0.0, 0.0, np.sin(0.2))  # turned 0.4 rad about z
    aim = ts.Mount(ts.Pose(), "aim")
    # At the current step the sensors see the new pose (the kept state of that step is replaced), and
    # on from there; before it the old one.
    np.testing.assert_allclose(cosim.body_state("target", t_k).pose.position, (0.3, -1.2, 0.8), rtol=0, atol=0)
    np.testing.assert_allclose(aim.state_at(cosim.scene, 0.15).pose.position, (0.3, -1.2, 0.9), rtol=0,
                               atol=1e-15)
    np.testing.assert_allclose(cosim.body_state("target", 0.05).pose.position, (0, -1, 1), rtol=0, atol=0)
    rot = cosim.body_state("target", 0.2).pose.rotation
    np.testing.assert_allclose(rot, Rotation.from_rotvec([0, 0, 0.4]).as_matrix(), rtol=0, atol=1e-12)


# --------------------------------------------------------------------------- load_mjcf: ball and free joints
BALLS = """<mujoco model="balls">
  <worldbody>
    <body name="upper" pos="0.1 0.2 1.0" euler="10 0 20">
      <joint name="shoulder" type="ball" pos="0 0 0.05"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
      <body name="lower" pos="0.3 0 0">
        <joint name="elbow" type="hinge" axis="0 1 0" range="-120 120"/>
        <joint name="wrist" type="ball"/>
        <geom type="box" size="0.1 0.02 0.02" pos="0.1 0 0"/>
      </body>
    </body>
    <body name="puck" pos="1 0 0.2"><freejoint name="float"/><geom type="cylinder" size="0.05 0.01"/></body>
  </worldbody>
  <keyframe><key name="home" qpos="0.8 0.2 -0.3 0.1  0.5  0.9 0 0.3 0.1  1 0 0.2 1 0 0 0"/></keyframe>
</mujoco>"""


def _ball_qpos(model, tree, q, qd):
    """MuJoCo's qpos, qvel for the tree's joint values: a ball joint's quaternion from its three Euler
    angles, its qvel the angular velocity in the child frame (MuJoCo's ball-joint convention)."""
    qpos, qvel = model.qpos0.copy(), np.zeros(model.nv)
    names = list(tree.joint_names)
    for j in range(model.njnt):
        jn, qa, da = model.joint(j).name, int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
            qpos[qa], qvel[da] = q[names.index(jn)], qd[names.index(jn)]
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
            i = names.index(f"{jn}:x")
            a, r = q[i:i + 3], qd[i:i + 3]
            rot = Rotation.from_euler("XYZ", a)
            x, y, z, w = rot.as_quat()
            qpos[qa:qa + 4] = w, x, y, z
            rx, rxy = Rotation.from_euler("X", a[0]).as_matrix(), Rotation.from_euler("XY", a[:2]).as_matrix()
            omega = r[0] * np.array([1.0, 0, 0]) + r[1] * rx[:, 1] + r[2] * rxy[:, 2]  # joint frame
            qvel[da:da + 3] = rot.as_matrix().T @ omega
    return qpos, qvel


def test_load_mjcf_ball_joints_fixed_or_euler(in_tmp):
    from twinsense.robots import load_mjcf

    model = mujoco.MjModel.from_xml_string(BALLS)
    with pytest.warns(UserWarning, match=r"ball joint\(s\) shoulder, wrist held fixed"):
        fixed = load_mjcf(model)
    assert fixed.tree.joint_names == ("elbow",)
    with pytest.raises(ConfigError, match=r"mjcf.ball_joints = 'quat'.*fixed, euler"):
        load_mjcf(model, ball_joints="quat")
    tree = load_mjcf(model, ball_joints="euler").tree
    assert tree.joint_names == ("shoulder:x", "shoulder:y", "shoulder:z", "elbow", "wrist:x", "wrist:y", "wrist:z")
    data = mujoco.MjData(model)
    vel = np.zeros(6)
    rng = np.random.default_rng(2)
    # The home keyframe: its quaternions as Euler angles; the free puck stays at qpos0 (kinematic use).
    key = np.array(model.key_qpos[0])
    key[model.jnt_qposadr[model.joint("float").id]:][:7] = model.qpos0[-7:]
    states = [(tree.home, np.zeros(7), key)]
    for _ in range(3):
        q = rng.uniform(-1.5, 1.5, 7)  # within +-1.5 rad: away from the x-y-z Euler angles' gimbal lock at pi/2
        states.append((q, rng.uniform(-2, 2, 7), None))
    for q, qd, want in states:
        qpos, qvel = _ball_qpos(model, tree, q, qd)
        if want is not None:  # the tree at its home against MuJoCo at the keyframe itself
            qpos = want
        data.qpos[:], data.qvel[:] = qpos, qvel
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_comVel(model, data)
        st = tree.forward(q, qd)
        for b in range(1, model.nbody):
            i = st.index(model.body(b).name)
            # Forward kinematics in float64 on both sides: 1e-9 m, rad, m/s, rad/s as for the other MJCF trees.
            np.testing.assert_allclose(st.pose(i).position, data.xpos[b], rtol=0, atol=1e-9)
            np.testing.assert_allclose(st.pose(i).rotation, data.xmat[b].reshape(3, 3), rtol=0, atol=1e-9)
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_XBODY, b, vel, 0)
            np.testing.assert_allclose(st.linear_velocities[i], vel[3:], rtol=0, atol=1e-9)
            np.testing.assert_allclose(st.angular_velocities[i], vel[:3], rtol=0, atol=1e-9)


def test_mocap_target_moves_with_its_velocity_and_radar_sees_it():
    # A mocap plate driven by the controller towards a radar at 1.5 m/s, turning at 0.5 rad/s about the
    # line of sight; a child body hangs from it on a hinge.
    xml = """<mujoco><option timestep="0.004" gravity="0 0 0"/><worldbody>
      <body name="plate" mocap="true" pos="0 3 1"><geom type="box" size="0.2 0.01 0.2"/>
        <site name="corner" pos="0.2 0 0.2"/>
        <body name="flap" pos="0 0 -0.25"><joint name="flap" type="hinge" axis="1 0 0"/>
          <geom type="box" size="0.1 0.01 0.05" pos="0 0 -0.05" mass="0.1"/></body></body>
      </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    v, rate, p0 = np.array([0.0, -1.5, 0.0]), 0.5, np.array([0.0, 3.0, 1.0])

    def control(m, d):
        d.mocap_pos[0] = p0 + v * d.time
        d.mocap_quat[0] = (np.cos(rate * d.time / 2), 0.0, np.sin(rate * d.time / 2), 0.0)

    cosim = MujocoCosim(model, control=control)
    dt = model.opt.timestep
    for t in (0.1, 0.2345):
        st = cosim.body_state("plate", t)
        # The controller sets the pose for the step it precedes, so the plate lags one step (MuJoCo's own
        # order); the finite difference of two steps is exact for constant rates: 1e-12 (float64 rounding).
        np.testing.assert_allclose(st.pose.position, p0 + v * (t - dt), rtol=0, atol=1e-12)
        np.testing.assert_allclose(st.linear_velocity, v, rtol=0, atol=1e-12)
        np.testing.assert_allclose(st.angular_velocity, [0, rate, 0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(st.pose.rotation, Rotation.from_rotvec([0, rate * (t - dt), 0]).as_matrix(),
                                   rtol=0, atol=1e-12)
        corner = ts.Mount(ts.Pose(), "corner").state_at(cosim.scene, t)  # rides on the plate: v + w x r
        r = corner.pose.position - st.pose.position
        np.testing.assert_allclose(corner.linear_velocity, v + np.cross([0, rate, 0], r), rtol=0, atol=1e-12)
    # The flap on its hinge at rest moves with the plate. At a step time (0.1 s = 25 steps): between steps
    # each body is moved on by its own step velocity, so their offset turns only to first order.
    st, flap = cosim.body_state("plate", 0.1), cosim.body_state("flap", 0.1)
    r = flap.pose.position - st.pose.position
    np.testing.assert_allclose(flap.linear_velocity, v + np.cross([0, rate, 0], r), rtol=0, atol=1e-12)
    np.testing.assert_allclose(flap.angular_velocity, [0, rate, 0], rtol=0, atol=1e-12)
    cosim = MujocoCosim(model, control=control)
    radar = ts.FMCWRadar.preset("paper_bgt60tr13c", mount=ts.Mount(ts.Pose.look_at((0, 0, 1), (0, 3, 1))),
                                name="radar", render_width=64, render_height=48)
    result = ts.simulate(cosim.scene, [radar], duration=0.1, seed=1)
    assert len(result.frames["radar"]) == 3
    for f in result.frames["radar"][1:]:  # at t = 0 the plate has not been moved yet: at rest
        i = int(np.argmax(f.detections.snr_db))
        # Approaching at 1.5 m/s: -1.5 m/s radial, within one Doppler bin (0.52 m/s). The plate's own turn
        # moves its edges by at most 0.2 m x 0.5 rad/s = 0.1 m/s.
        assert abs(f.detections.velocity[i] - (-1.5)) <= radar.config.velocity_resolution


# --------------------------------------------------------------------------- files, names, history, time steps
def test_model_from_a_path_with_mesh_folders(tmp_path, monkeypatch):
    import trimesh

    (tmp_path / "assets" / "meshes").mkdir(parents=True)
    trimesh.creation.box((0.2, 0.1, 0.3)).export(tmp_path / "assets" / "meshes" / "brick.stl")
    xml = """<mujoco model="cell"><compiler meshdir="assets/meshes"/>
      <asset><mesh name="brick" file="brick.stl"/><mesh name="wedge" vertex="0 0 0 0.1 0 0 0 0.1 0 0 0 0.1"/></asset>
      <worldbody><body name="part" pos="0 0 0.5"><freejoint/><geom type="mesh" mesh="brick"/>
        <geom type="mesh" mesh="wedge" pos="0.2 0 0"/></body></worldbody></mujoco>"""
    (tmp_path / "cell.xml").write_text(xml)
    (tmp_path / "gone.xml").write_text(xml.replace("brick.stl", "missing.stl"))
    monkeypatch.chdir(tmp_path.parent)  # the meshes are found from the file's folder, not the working one
    cosim = MujocoCosim(tmp_path / "cell.xml")
    part = cosim.scene.object("part")
    # The STL box (8 vertices) and the inline vertex list (MuJoCo's convex hull: 4) merged in the body frame,
    # where MuJoCo's compiled geoms put them (mesh re-centring included): float64 poses, 1e-12 m.
    model = cosim.model
    assert len(part.geometry.vertices) == 12
    mujoco.mj_forward(model, data := mujoco.MjData(model))
    world = part.state_at(0.0).pose.apply(np.asarray(part.geometry.vertices, float))
    for k, g in enumerate(range(model.body_geomadr[1], model.body_geomadr[1] + 2)):
        m = model.geom_dataid[g]
        v = model.mesh_vert[model.mesh_vertadr[m]:model.mesh_vertadr[m] + model.mesh_vertnum[m]]
        expect = v @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
        np.testing.assert_allclose(world[[0, 8][k]:[8, 12][k]], expect, rtol=0, atol=1e-12)
    with pytest.raises(ConfigError, match=r"mjcf.path.*gone.xml.*missing.stl"):
        MujocoCosim(tmp_path / "gone.xml")
    with pytest.raises(ConfigError, match=r"mjcf.path.*an existing MJCF"):
        MujocoCosim(tmp_path / "nowhere.xml")
    with pytest.raises(ConfigError, match=r"mjcf = 3.*a path to an MJCF file or a mujoco.MjModel"):
        MujocoCosim(3)


def test_unknown_names_and_short_history():
    from twinsense.errors import UnknownNameError

    cosim = MujocoCosim(drop_model(), history=0.05)
    with pytest.raises(UnknownNameError, match=r"mount.parent = 'lid'.*box, top, world"):
        ts.Mount(ts.Pose(), "lid").state_at(cosim.scene, 0.0)
    with pytest.raises(UnknownNameError, match=r"cosim.body = 'crate'"):
        cosim.body_state("crate", 0.0)
    with pytest.raises(ConfigError, match=r"cosim.body = 7.*0..1"):
        cosim.body_state(7, 0.0)
    with pytest.raises(ConfigError, match=r"cosim.history = 0"):
        MujocoCosim(drop_model(), history=0)
    with pytest.raises(ConfigError, match=r"cosim.geoms = 'visuals'.*visual, collision, all"):
        MujocoCosim(drop_model(), geoms="visuals")
    with pytest.raises(ConfigError, match=r"cosim.control"):
        MujocoCosim(drop_model(), control="pd")
    with pytest.raises(ConfigError, match=r"^t = nan"):
        cosim.body_state("box", float("nan"))
    cosim.step_to(2.0)  # 1000 steps: states older than the 0.05 s of history are dropped
    with pytest.raises(ConfigError, match=r"t = 0.5.*history.*MujocoCosim\(history=0.05\)"):
        cosim.body_state("box", 0.5)
    assert cosim.body_state("box", 1.97).pose.position[2] < 2.0  # within the history: fine


@pytest.mark.parametrize("dt", [1e-4, 0.25])
def test_tiny_and_huge_time_steps(dt):
    # A sensor clock of 30 Hz on steps of 0.1 ms (333.3 steps per frame) and of 0.25 s (a frame every
    # 0.13 steps): the body state at every frame time is the step before it moved on as documented.
    model = drop_model(dt, "RK4", 20.0)
    cosim = MujocoCosim(model)
    cam = ts.DepthCamera.preset("generic", name="cam", frame_rate=30, width=9, height=7,  # a pixel on the axis
                                mount=ts.Mount(ts.Pose.look_at((0, 0, 22.0), (0, 0, 0), (1, 0, 0))))
    result = ts.simulate(cosim.scene, [cam], 0.6)
    for f in result.frames["cam"]:
        z = cosim.body_state("box", f.t).pose.position[2]
        t_k = np.floor(f.t / dt * (1 + 1e-9)) * dt
        tau = f.t - t_k
        # RK4 is exact at the steps for free fall; between them the state moves on by the step's
        # velocity: z = z0 - g t_k^2 / 2 - g t_k tau. MuJoCo's summed time differs from k dt by rounding
        # (1e-12 after 6000 steps of 0.1 ms), the depth is float32 (ulp 4.8e-7 at 4 m): 1e-5 m.
        expect = 20.0 - G * t_k**2 / 2 - G * t_k * tau
        assert z == pytest.approx(expect, rel=0, abs=1e-9)
        h, w = f.depth.shape
        np.testing.assert_allclose(f.depth[h // 2, w // 2], 22.0 - (z + 0.1), rtol=0, atol=1e-5)
        # Against the closed form: the propagation's g tau^2 / 2, up to g dt^2 / 2 (0.31 m at 0.25 s).
        assert abs(z - (20.0 - G * f.t**2 / 2)) <= G * min(tau, dt) ** 2 / 2 + 1e-9


def test_a_child_forked_while_another_thread_holds_the_cosim_lock_steps_on():
    import sys
    from pathlib import Path

    from twinsense.forksafe import ForkSafeLock

    sys.path.insert(0, str(Path(__file__).parents[1] / "render"))
    from test_forksafe import held_by_another_thread, in_forked_child

    cosim = MujocoCosim(drop_model())
    assert isinstance(cosim._lock, ForkSafeLock)  # simulate(processes=N) forks while capture threads run
    with held_by_another_thread(cosim._lock):
        got = in_forked_child(lambda: cosim.body_state("box", 0.25).pose.matrix)  # steps: takes the lock
    np.testing.assert_array_equal(got, cosim.body_state("box", 0.25).pose.matrix)


def test_data_that_starts_late_and_visual_or_collision_geoms():
    model = drop_model()
    data = mujoco.MjData(model)
    data.time = 5.0  # a state the user ran on before: the co-simulation's clock starts there
    cosim = MujocoCosim(model, data)
    with pytest.raises(ConfigError, match=r"t = 0.*starts at data.time = 5 s"):
        cosim.body_state("box", 0.0)
    assert cosim.body_state("box", 5.1).pose.position[2] < 2.0
    # MuJoCo's convention: display geoms take no part in contacts (contype = conaffinity = 0).
    xml = """<mujoco><worldbody><body name="link"><joint/>
      <geom name="look" type="sphere" size="0.1" contype="0" conaffinity="0" group="2"/>
      <geom name="touch" type="box" size="0.05 0.05 0.05" pos="0 0 0.2" group="3"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    assert isinstance(MujocoCosim(model).scene.object("link").geometry, ts.Sphere)
    assert len(MujocoCosim(model, geoms="collision").scene.object("link").geometry.vertices) == 8
    assert len(MujocoCosim(model, geoms="all").scene.object("link").geometry.vertices) > 8


def test_capacitive_pad_under_a_falling_box():
    # A pad-grid proximity sensor on a site of a MuJoCo pad, a metal box falling onto it: the run (the
    # sensor resolves every frame time before it starts, stepping the physics ahead) must equal a capture
    # of a still scene with the box where MuJoCo has it at that time.
    xml = """<mujoco><option timestep="0.002"/><worldbody>
      <body name="box" pos="0 0 0.15"><freejoint/><geom type="box" size="0.05 0.05 0.05"/></body>
      <body name="pad" pos="0 0 0.02"><geom type="box" size="0.1 0.1 0.01"/><site name="pad_top" pos="0 0 0.011"/>
      </body></worldbody></mujoco>"""
    cosim = MujocoCosim(mujoco.MjModel.from_xml_string(xml))
    cap = ts.CapacitiveSensor.preset("pad-grid", name="cap", mount=ts.Mount(ts.Pose(), "pad_top"), frame_rate=10)
    frame = ts.simulate(cosim.scene, [cap], duration=0.2, seed=1).frames["cap"][-1]
    assert frame.t == pytest.approx(0.1, rel=0, abs=1e-12)
    box = cosim.body_state("box", frame.t).pose
    assert box.position[2] == pytest.approx(0.15 - G * 0.1**2 / 2, rel=0, abs=G * 0.1 * 0.002)  # Euler drift
    still = ts.Scene()
    still.add(ts.SceneObject("box", cosim.scene.object("box").geometry, "aluminium", ts.Static(box)))
    still.add(ts.SceneObject("pad", cosim.scene.object("pad").geometry, "silicone",
                             ts.Static(cosim.scene.object("pad").state_at(0.0).pose)))
    mount = ts.Mount(cosim.scene.mount_target("pad_top").state_at(0.0).pose)
    ref = ts.CapacitiveSensor.preset("pad-grid", name="cap", mount=mount, frame_rate=10).capture(
        still, frame.t, np.random.default_rng(0))
    # Each frame's capacitances lie within the solver's capacitance_atol of a direct solve (the sensor's
    # contract), so two solves of the same scene within twice that.
    atol = 2 * cap.frame_solver_config.capacitance_atol
    assert np.abs(frame.delta).max() > 100 * atol  # the box is seen
    np.testing.assert_allclose(frame.channels, ref.channels, rtol=0, atol=atol)


def test_data_stepped_by_the_user_is_taken_in():
    model = drop_model(0.002, "RK4", 2.0)
    cosim = MujocoCosim(model)
    cosim.step_to(0.1)
    for _ in range(10):  # the user steps data alone, 20 ms
        mujoco.mj_step(model, cosim.data)
    t_user = cosim.time
    # RK4 free fall is exact at the steps: the state the user reached is kept and read there (1e-12 m).
    assert cosim.body_state("box", t_user).pose.position[2] == pytest.approx(2.0 - G * t_user**2 / 2, rel=0,
                                                                            abs=1e-12)
    # In the gap the step before it moves on (by 15 ms here: error g tau^2 / 2 = 1.1 mm, as documented for
    # steps that long), and after it the co-simulation steps on as before.
    z = cosim.body_state("box", 0.115).pose.position[2]
    t_k = 0.1
    assert z == pytest.approx(2.0 - G * t_k**2 / 2 - G * t_k * 0.015, rel=0, abs=1e-12)
    assert cosim.body_state("box", 0.2).pose.position[2] == pytest.approx(2.0 - G * 0.2**2 / 2, rel=0, abs=1e-12)


def test_mujoco_cameras_are_mounts_in_the_optical_frame():
    # A camera on a swinging arm and one in the world looking at a box; a tracking camera is left out.
    xml = """<mujoco><option timestep="0.002" gravity="0 0 0"/><worldbody>
      <camera name="overview" pos="0 -2 1" xyaxes="1 0 0 0 0.6 0.8"/>
      <camera name="chase" mode="trackcom" pos="0 -3 1"/>
      <body name="arm" pos="0 0 1"><joint name="swing" type="hinge" axis="0 0 1"/>
        <geom type="box" size="0.3 0.02 0.02" pos="0.3 0 0"/>
        <camera name="arm" pos="0.6 0 0" euler="0 -90 0"/></body>
      <body name="box" pos="2 0 1"><geom type="box" size="0.2 0.2 0.2"/></body>
      </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qvel[0] = 0.7
    cosim = MujocoCosim(model, data)
    assert set(cosim.scene.frame_names) == {"overview", "arm:camera"}  # named like a body: "<camera>:camera"
    ref = mujoco.MjData(model)
    ref.qvel[0] = 0.7
    for _ in range(50):
        mujoco.mj_step(model, ref)
    mujoco.mj_forward(model, ref)
    flip = np.diag([1.0, -1.0, -1.0])  # MuJoCo's camera looks along -z with y up; the optical frame z, y down
    for cam, frame in (("overview", "overview"), ("arm", "arm:camera")):
        c = model.camera(cam).id
        st = ts.Mount(ts.Pose(), frame).state_at(cosim.scene, ref.time)
        np.testing.assert_allclose(st.pose.position, ref.cam_xpos[c], rtol=0, atol=1e-9)
        np.testing.assert_allclose(st.pose.rotation, ref.cam_xmat[c].reshape(3, 3) @ flip, rtol=0, atol=1e-9)
    # The arm camera looks along the arm (+x turned by the swing) at the box face 2 - 0.2 m from the hinge
    # when the swing angle is 0: at t = 0 the ideal depth camera on it reads 1.8 - 0.6 = 1.2 m on its axis.
    cam = ts.DepthCamera.preset("generic", name="cam", width=9, height=7, mount=ts.Mount(ts.Pose(), "arm:camera"))
    frame = cam.capture(cosim.scene, 0.0)
    assert frame.depth[3, 4] == pytest.approx(1.2, rel=0, abs=1e-6)  # float32 depth: ulp 1.2e-7 at 1.2 m


def test_robosuite_arena_floor_is_seen():
    # robosuite's table arena: a collision floor plane (contype 1) and display-only walls in the world body.
    # A floor or terrain is its own display geom; it was dropped with the walls' "visual" choice, and a
    # camera looking down saw through the world.
    import importlib.util
    from pathlib import Path

    arena = Path(importlib.util.find_spec("robosuite").submodule_search_locations[0]) / "models" / "assets" / \
        "arenas" / "table_arena.xml"
    cosim = MujocoCosim(arena)
    cam = ts.DepthCamera.preset("generic", name="cam", width=9, height=7,
                                mount=ts.Mount(ts.Pose.look_at((-1.5, 1.0, 2.0), (-1.5, 1.0, 0.0), (1, 0, 0))))
    frame = cam.capture(cosim.scene, 0.0)
    assert frame.depth[3, 4] == pytest.approx(2.0, rel=0, abs=1e-6)  # the floor at z = 0; float32 depth


def test_nan_ctrl_names_the_controller(in_tmp):
    xml = """<mujoco><option timestep="0.002" gravity="0 0 0"/><worldbody>
      <body name="cart"><joint name="rail" type="slide" axis="1 0 0"/><geom type="box" size="0.1 0.1 0.1"/></body>
      </worldbody><actuator><motor joint="rail"/></actuator></mujoco>"""

    def control(m, d):
        d.ctrl[0] = np.nan if d.time > 0.05 else 1.0  # MuJoCo would warn and zero it, silently

    cosim = MujocoCosim(mujoco.MjModel.from_xml_string(xml), control=control)
    with pytest.raises(ConfigError, match=r"cosim.control = .*finite data.ctrl.*in ctrl"):
        cosim.body_state("cart", 0.1)
    assert cosim.time == pytest.approx(0.05, rel=0, abs=0.002)  # the last good step is kept
