"""Joint motions, link states and link-mounted sensors checked from outside: a hand-written URDF with a
prismatic, a revolute and a fixed joint (origins turned about all three axes, skew joint axes) against
MuJoCo's compiler of the same file, finite differences, closed forms and the same sensor mounted statically;
joint and scenario errors against the field a user writes."""

import math

import mujoco
import numpy as np
import pytest

from twinsense.depthcam import DepthCamera
from twinsense.errors import ConfigError
from twinsense.presets import make_sensor
from twinsense.radar import FMCWRadar
from twinsense.robots import load_robot
from twinsense.scenario import ScenarioError, scenario_from_dict
from twinsense.scene import (
    ArticulatedBody,
    Box,
    ConstantVelocity,
    Cylinder,
    Joint,
    JointConstantVelocity,
    JointKeyframes,
    JointSetpoints,
    KinematicTree,
    Link,
    Magnet,
    Mount,
    Pose,
    Scene,
    SceneObject,
)
from twinsense.tof import ToFCamera

# The centres of mass off the link origins: MuJoCo's inertial frames differ from the link frames.
INERTIAL = ('<inertial><origin xyz="0.05 0.02 -0.01"/><mass value="1"/>'
            '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>')
# fusestatic="false": MuJoCo keeps the fixed joint's child as a body of its own (its default merges it).
THREE_LINK_URDF = f"""<?xml version="1.0"?>
<robot name="three">
  <mujoco><compiler fusestatic="false" discardvisual="false"/></mujoco>
  <link name="base">{INERTIAL}</link>
  <link name="slider">{INERTIAL}
    <collision><origin xyz="0.1 0 0"/><geometry><box size="0.2 0.05 0.05"/></geometry></collision></link>
  <link name="arm">{INERTIAL}
    <collision><origin xyz="0.2 0 0"/><geometry><box size="0.4 0.04 0.04"/></geometry></collision></link>
  <link name="tool">{INERTIAL}</link>
  <joint name="slide" type="prismatic"><parent link="base"/><child link="slider"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.3 -0.2 0.5"/><axis xyz="1 0.5 0.2"/>
    <limit lower="-0.5" upper="0.5" effort="1" velocity="1"/></joint>
  <joint name="turn" type="revolute"><parent link="slider"/><child link="arm"/>
    <origin xyz="0.2 0.05 0.1" rpy="-0.4 0.7 0.1"/><axis xyz="0.2 -1 0.3"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="weld" type="fixed"><parent link="arm"/><child link="tool"/>
    <origin xyz="0.4 0.01 -0.02" rpy="0.1 0.2 0.3"/></joint>
</robot>
"""
LINKS = ("slider", "arm", "tool")


@pytest.fixture(scope="module")
def urdf(tmp_path_factory):
    p = tmp_path_factory.mktemp("three") / "three.urdf"
    p.write_text(THREE_LINK_URDF)
    return p


def test_link_poses_and_velocities_equal_mujoco(urdf):
    body = load_robot(urdf, name="three")
    m = mujoco.MjModel.from_xml_path(str(urdf))
    d = mujoco.MjData(m)
    assert [m.joint(i).name for i in range(m.njnt)] == list(body.tree.joint_names)
    rng = np.random.default_rng(7)
    for _ in range(8):
        q = rng.uniform(body.tree.limits[:, 0], body.tree.limits[:, 1])
        qd = rng.normal(0.0, 1.0, 2)
        d.qpos[:], d.qvel[:] = q, qd
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)  # mj_objectVelocity reads cdof and cvel
        mujoco.mj_comVel(m, d)
        st = body.tree.forward(q, qd)
        for link in LINKS:
            b = m.body(link).id
            v6 = np.zeros(6)
            # XBODY: the body frame (BODY is the inertial frame, here 0.05 m off). World frame: (w, v).
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_XBODY, b, v6, 0)
            i = st.index(link)
            # Both sides are a few products of unit rotations and lengths < 1 m: rounding is ~1e-15;
            # 1e-9 is the agreement asked of two implementations of the same convention.
            np.testing.assert_allclose(st.positions[i], d.xpos[b], rtol=0, atol=1e-9)
            np.testing.assert_allclose(st.rotations[i], d.xmat[b].reshape(3, 3), rtol=0, atol=1e-9)
            np.testing.assert_allclose(st.linear_velocities[i], v6[3:], rtol=0, atol=1e-9)
            np.testing.assert_allclose(st.angular_velocities[i], v6[:3], rtol=0, atol=1e-9)


def test_link_velocities_are_the_central_differences_of_the_poses(urdf):
    """Keyframed joints on a base that moves and turns: v = dp/dt, [w]x = dR/dt R^T (world frame)."""
    body = load_robot(urdf, name="three")
    body.joint_motion = JointKeyframes([0.0, 0.7, 1.5, 2.0], [[0, 0], [0.3, 1.0], [-0.2, -0.5], [0.1, 0.2]])
    body.base = ConstantVelocity(Pose((1, 2, 0.5), Pose.from_euler_deg((0, 0, 0), (6, 11, 17)).rotation),
                                 (0.3, -0.1, 0.2), (0.2, 0.5, -0.4))
    h = 1e-5
    # Central differences err by h^2 / 6 |x'''| + eps |x| / h. Here |q'''| <= 6 max|c3| ~ 60 rad/s^3 (the
    # spline's cubic coefficients), the links lie within 3 m of the origin and turn at < 4 rad/s: |x'''| is
    # below ~1e3, so truncation <= 1.7e-8 and rounding <= 3e-11 (m/s, rad/s). Tolerance 1e-7.
    tol = 1e-7
    for t in (0.3, 0.7, 1.1, 1.5, 1.9):  # inside pieces and at the inner keyframes
        s1, s0, s = body.state(t + h), body.state(t - h), body.state(t)
        for link in LINKS:
            i = s.index(link)
            v = (s1.positions[i] - s0.positions[i]) / (2 * h)
            wx = (s1.rotations[i] - s0.rotations[i]) / (2 * h) @ s.rotations[i].T
            w = 0.5 * np.array([wx[2, 1] - wx[1, 2], wx[0, 2] - wx[2, 0], wx[1, 0] - wx[0, 1]])
            np.testing.assert_allclose(s.linear_velocities[i], v, rtol=0, atol=tol)
            np.testing.assert_allclose(s.angular_velocities[i], w, rtol=0, atol=tol)
            # A point fixed to the link: its velocity is v + w x r, and the difference of its positions.
            r_local = np.array([0.05, -0.02, 0.03])
            p1 = s1.pose(link).apply(r_local[None])[0]
            p0 = s0.pose(link).apply(r_local[None])[0]
            pw = s.pose(link).apply(r_local[None])
            np.testing.assert_allclose(s.point_velocity(link, pw)[0], (p1 - p0) / (2 * h), rtol=0, atol=tol)


def test_keyframe_velocity_is_continuous_and_the_derivative_of_the_position():
    kf = JointKeyframes([0.0, 0.7, 1.5, 2.0], [[0, 0], [0.3, 1.0], [-0.2, -0.5], [0.1, 0.2]])
    for tk in (0.7, 1.5):
        # A C1 curve: the velocity either side of a keyframe differs by |q''| dt (|q''| < 100 rad/s^2 here).
        np.testing.assert_allclose(kf.qd(tk - 1e-9), kf.qd(tk + 1e-9), rtol=0, atol=1e-6)
    h = 1e-5
    for t in (0.2, 0.7, 1.2, 1.5, 1.8):
        # Central difference of a cubic: h^2 / 6 |q'''| <= 1e-9 with |q'''| < 60; rounding 1e-16 / h = 1e-11.
        np.testing.assert_allclose(kf.qd(t), (kf.q(t + h) - kf.q(t - h)) / (2 * h), rtol=0, atol=1e-8)


def _still_arm(urdf):
    body = load_robot(urdf, name="arm")
    body.joint_motion = JointConstantVelocity([0.2, 0.4], [0.0, 0.0])
    scene = Scene()
    scene.add_articulated(body)
    return body, scene


PRESETS = {"tof": "pmd_pico_flexx", "radar": "paper_bgt60tr13c", "lidar": "livox_mid40", "ultrasonic": "open_40khz",
           "inductive": "m12_flush", "magnetic": "tle493d", "capacitive": "pad-grid"}


@pytest.mark.parametrize("kind", list(PRESETS))
def test_a_sensor_on_a_still_link_gives_the_frame_of_the_same_sensor_fixed_there(urdf, kind):
    body, scene = _still_arm(urdf)
    link = body.state(0.0).pose("tool")
    eye, target = link.position + np.array([0.01, 0.02, 0.0]), link.position + np.array([1.0, 0.3, -0.2])
    world = Pose.look_at(eye, target)
    offset = link.inverse() @ world  # the sensor pose on the flange
    pose = link @ offset             # where a mount on the link puts it (the same product, the same bits)
    ahead = pose.rotation[:, 2]
    scene.add(SceneObject("wall", Box((3, 3, 0.05)), "concrete",
                          Pose.look_at(pose.position + 1.2 * ahead, pose.position + 2 * ahead)))
    if kind in ("inductive", "magnetic", "capacitive"):  # a target in front of the short-range sensors
        gap = 0.004 if kind == "inductive" else 0.02
        near = Pose.look_at(pose.position + gap * ahead, pose.position + ahead)
        geom = Box((0.05, 0.05, 0.05)) if kind == "capacitive" else Cylinder(0.02, 0.002)
        scene.add(SceneObject("target", geom, "mild_steel", near, magnet=Magnet() if kind == "magnetic" else None))
    on_link = make_sensor(kind, PRESETS[kind], name="s", mount=Mount(offset, parent="arm/tool"))
    fixed = make_sensor(kind, PRESETS[kind], name="s", mount=Mount(pose))
    a = on_link.capture(scene, 0.0, np.random.default_rng(5)).streams()
    b = fixed.capture(scene, 0.0, np.random.default_rng(5)).streams()
    assert a.keys() == b.keys()
    for k in a:
        assert np.asarray(a[k]).tobytes() == np.asarray(b[k]).tobytes(), k  # the same bytes (NaN included)
    seen = {"tof": "depth", "radar": "adc", "lidar": "range", "ultrasonic": "envelope", "inductive": "delta_r",
            "magnetic": "field_true", "capacitive": "maxwell"}[kind]
    assert np.nanmax(np.abs(np.asarray(a[seen], dtype=float))) > 0  # the sensor sees something


def _rail(v: float, w: float):
    """A carriage on a rail along world x at 1 m height moving at v [m/s], a head on it turning about z at
    w [rad/s] 0.1 m ahead, a sensor 0.2 m ahead of the head's origin looking along its x."""
    links = [Link("base"), Link("carriage"), Link("head", Box((0.05, 0.05, 0.05)))]
    joints = [Joint("slide", "prismatic", "base", "carriage", Pose((0, 0, 1.0)), axis=(1, 0, 0), lower=-1, upper=2),
              Joint("pan", "revolute", "carriage", "head", Pose((0.1, 0, 0)), axis=(0, 0, 1), lower=-3, upper=3)]
    body = ArticulatedBody("rail", KinematicTree("rail", links, joints), JointConstantVelocity([0.0, 0.0], [v, w]))
    scene = Scene()
    scene.add_articulated(body)
    return body, scene, Mount(Pose((0.2, 0, 0)) @ Pose.look_at((0, 0, 0), (1, 0, 0)), parent="rail/head")


def test_radar_on_a_link_moving_at_v_toward_a_wall_sees_range_rate_minus_v():
    probe = FMCWRadar.preset("paper_bgt60tr13c", name="r")
    dv = float(np.diff(probe.capture(Scene(), 0.0, np.random.default_rng(0)).processed.velocity_axis)[0])
    v = 2 * dv  # on a Doppler bin's centre: the peak falls on that bin, not between two
    _, scene, mount = _rail(v, 0.0)
    scene.add(SceneObject("plate", Box((0.05, 0.3, 0.3)), "mild_steel", Pose((4.0, 0, 1.0))))
    radar = FMCWRadar.preset("paper_bgt60tr13c", mount=mount, name="r")
    for t in (0.1, 0.5):
        f = radar.capture(scene, t, np.random.default_rng(1))
        s = f.scatterers
        plate = s.object_id == [o.name for o in scene.objects].index("plate")
        p, vel = s.points[plate], s.velocities[plate]
        # The plate is still and the radar translates at v along its boresight: a scatterer in direction u
        # (sensor frame) closes at range rate -v u_z (-v on boresight), to rounding.
        rate = np.sum(p * vel, axis=1) / np.linalg.norm(p, axis=1)
        np.testing.assert_allclose(rate, -v * p[:, 2] / np.linalg.norm(p, axis=1), rtol=0, atol=1e-12)
        pr = f.processed
        i, j = np.unravel_index(np.argmax(pr.power), pr.power.shape)
        assert pr.velocity_axis[i] == pytest.approx(-v, abs=1e-9 + 1e-12 * v)
        # The plate's face at 3.975 m; the radar at 0.1 + 0.2 + v t: the range peak within one bin.
        dr = float(np.diff(pr.range_axis)[0])
        assert pr.range_axis[j] == pytest.approx(3.975 - 0.3 - v * t, abs=dr)


def test_radar_on_a_turning_link_sees_the_range_rate_of_v_plus_w_cross_r():
    v, w = 0.4, 0.3
    _, scene, mount = _rail(v, w)
    scene.add(SceneObject("wall", Box((0.05, 6, 3)), "concrete", Pose((4.0, 0, 1.0))))
    radar = FMCWRadar.preset("paper_bgt60tr13c", mount=mount, name="r", process=False)
    t = 0.5
    s = radar.capture(scene, t, np.random.default_rng(1)).scatterers
    # Closed form: the head turned by w t, the sensor 0.2 m along the head's x: v_s = v x + w z x r.
    th = w * t
    r = 0.2 * np.array([math.cos(th), math.sin(th), 0.0])
    v_s = np.array([v, 0, 0]) + np.cross([0, 0, w], r)
    rot = Pose.from_euler_deg((0, 0, 0), (0, 0, math.degrees(th))).rotation @ mount.pose.rotation
    u = s.points / np.linalg.norm(s.points, axis=1)[:, None]
    rate = np.sum(s.points * s.velocities, axis=1) / np.linalg.norm(s.points, axis=1)
    np.testing.assert_allclose(rate, -(u @ rot.T) @ v_s, rtol=0, atol=1e-12)


def test_cameras_on_a_moving_link_see_the_wall_at_its_distance_at_each_frame_time():
    body, scene, mount = _rail(0.0, 0.0)
    body.joint_motion = JointKeyframes([0, 1, 2], [[0, 0], [0.6, 0.0], [1.0, 0.0]])
    scene.add(SceneObject("wall", Box((0.05, 6, 4)), "concrete", Pose((4.0, 0, 1.0))))
    depth = DepthCamera.preset("vga", mount=mount, name="d")
    tof = ToFCamera.preset("pmd_pico_flexx", mount=mount, name="c")
    for t in (0.0, 0.35, 1.0, 1.6, 2.5):
        q = body.joint_motion.q(t)[0]
        d = depth.capture(scene, t, np.random.default_rng(0)).depth
        # The wall's face is at x = 3.975 m, the camera at 0.3 m + q(t) looking along x: every pixel's
        # z-depth is 3.675 - q(t); the depth image is float32 (half an ulp at 4 m is 2.4e-7 m).
        np.testing.assert_allclose(d, 3.675 - q, rtol=0, atol=5e-7)
        # The ToF camera on the link at t is the one fixed at the link's pose at t, to the byte.
        a = tof.capture(scene, t, np.random.default_rng(3)).streams()
        fixed = ToFCamera.preset("pmd_pico_flexx", mount=Mount(mount.pose_at(scene, t)), name="c")
        b = fixed.capture(scene, t, np.random.default_rng(3)).streams()
        for k in a:
            assert np.asarray(a[k]).tobytes() == np.asarray(b[k]).tobytes(), (t, k)


# ----------------------------------------------------------------- errors
def test_setpoints_outside_the_limits_are_refused_when_the_body_is_built(urdf):
    body = load_robot(urdf, name="three")
    with pytest.raises(ConfigError) as e:
        body.joint_motion = JointSetpoints([0.9, 0.0])
    assert e.value.field == "three.joints.setpoints.q0[0]" and e.value.value == 0.9
    assert "[-0.5, 0.5] m of joint 'slide'" in str(e.value)
    sp = JointSetpoints([0.0, 0.0], joint_names=["turn", "slide"])
    sp.set(0.0, [2.5, 0.1])
    with pytest.raises(ConfigError) as e:
        body.joint_motion = sp  # a kept pushed value outside: named with its time
    assert e.value.field == "three.joints.setpoints.q[0]" and "at t = 0 s" in str(e.value.value)
    assert "[-2, 2] rad of joint 'turn'" in str(e.value)


def test_a_bad_pushed_velocity_names_setpoints_qd():
    sp = JointSetpoints([0.0, 0.0])
    with pytest.raises(ConfigError) as e:
        sp.set(0.0, [0.1, 0.2], [1.0, 2.0, 3.0])
    assert e.value.field == "setpoints.qd" and e.value.value == [1.0, 2.0, 3.0]
    with pytest.raises(ConfigError) as e:
        sp.set(0.0, [0.1, 0.2], [float("nan"), 0.0])
    assert e.value.field == "setpoints.qd"
    with pytest.raises(ConfigError) as e:
        sp.set(0.0, [0.1])
    assert e.value.field == "setpoints.q" and e.value.value == [0.1]


def test_a_constant_velocity_asked_before_zero_gives_the_time_it_entered_the_limits(urdf):
    body = load_robot(urdf, name="three")
    body.joint_motion = JointConstantVelocity([0.4, 0.0], [0.2, 0.0])
    # q = 0.4 + 0.2 t is within [-0.5, 0.5] for t in [-4.5, 0.5] s.
    with pytest.raises(ConfigError, match=r"within them only from t = -4\.5 s on; asked at t = -5 s"):
        body.state(-5.0)
    with pytest.raises(ConfigError, match=r"leaves them at t = 0\.5 s; asked at t = 0\.6 s"):
        body.state(0.6)


def _scenario(urdf, joints):
    return {"name": "s", "duration": 0.1, "seed": 1,
            "robots": [{"name": "arm", "description": str(urdf), "base": {"position": [0, 0, 0.5]},
                        "joints": joints}],
            "outputs": {}}


@pytest.mark.parametrize(("joints", "field"), [
    ({"setpoints": [0.9, 0.0]}, "robots[0].joints.setpoints[0]"),
    ({"setpoints": [0.1, 0.0, 0.0]}, "robots[0].joints"),
    ({"keyframes": {"times": [0, 1], "values": [[0, 0], [0, 0]]}, "joint_names": ["slide"]},
     "robots[0].joints.joint_names"),
    ({"constant_velocity": {"q0": [0, 0], "qd": [0, 0]}, "joint_names": ["turn", "turn"]},
     "robots[0].joints.joint_names"),
    ({"setpoints": [0.1], "joint_names": ["slide", "turn"]}, "robots[0].joints.joint_names"),
    ({"fixed": [0.1, 0.2], "joint_names": ["slide"]}, "robots[0].joints.joint_names"),
    ({"keyframes": {"times": [0, 1], "values": [[0, 0], [0, 2.5]]}}, "robots[0].joints.keyframes.values[1][1]"),
    ({"keyframes": {"times": [0, 1], "values": [[0], [0]]}, "joint_names": ["twist"]},
     "robots[0].joints.joint_names"),
])
def test_scenario_joint_errors_name_the_field_as_written(urdf, joints, field):
    with pytest.raises(ScenarioError) as e:
        scenario_from_dict(_scenario(urdf, joints))
    assert [p[0] for p in e.value.problems] == [field]



def test_keyframes_too_fast_for_a_joint_name_the_value_instead_of_overflowing():
    # 1e308 rad one second after 0: a cubic through it overflows (its coefficients were NaN and the
    # message spoke of 'nan at t = 0 s' overshooting [-inf, inf]); refused like a constant joint
    # velocity above 1e6 rad/s, naming the keyframe.
    with pytest.raises(ConfigError) as e:
        JointKeyframes([0, 1, 2], [[0, 0], [0, 1e308], [0, 0]])
    assert e.value.field == "joints.keyframes.values[1][1]" and e.value.value == 1e308
    assert "joint speeds <= 1e+06" in str(e.value)
    JointKeyframes([0, 1], [[0], [1e6]])  # exactly the bound: accepted
    with pytest.raises(ConfigError) as e:
        JointConstantVelocity([[0.0]], [[0.0]])
    assert e.value.field == "joints.constant_velocity.q0"  # it named qd


def test_a_missing_urdf_mesh_in_a_scenario_is_named_where_docs_robots_md_says(tmp_path):
    (tmp_path / "arm.urdf").write_text(
        '<robot name="arm"><link name="base"/><link name="upper"><visual><geometry>'
        '<mesh filename="meshes/upper.stl"/></geometry></visual></link>'
        '<joint name="j" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>')
    with pytest.raises(ScenarioError) as e:
        scenario_from_dict({"name": "s", "duration": 0.1, "robots": [{"name": "a", "description": "arm.urdf"}],
                            "outputs": {}}, base_dir=tmp_path)
    [(field, value, allowed)] = e.value.problems
    assert field == "robots[0].urdf[arm.urdf].links[upper].visual[0].mesh"
    assert value == str(tmp_path / "meshes" / "upper.stl") and "link 'upper'" in allowed


def test_a_keyframe_on_a_limit_does_not_fail_at_times_next_to_it():
    # Keyframes that touch the upper limit 1 rad and turn there (a gripper opening fully, twice): the
    # check at load allows the spline's rounding past the limit (1e-12 of the limit's size), but q(t) one
    # ulp of time before the keyframe was 1.0000000000000002 and the body refused it part-way through a run
    # (found by a random search over such keyframes). Now q(t) is put back on the limit there.
    a, dt, start = 0.4600451393090961, 1.913204247394201, 0.7577288453082914
    times = np.arange(5) * dt + start
    tree = KinematicTree("g", [Link("b"), Link("c")], [Joint("j", "revolute", "b", "c", lower=0.0, upper=1.0)])
    body = ArticulatedBody("g", tree, JointKeyframes(times, [[a], [1.0], [a], [1.0], [a]]))
    for tk in (times[1], times[3]):
        t = float(tk)
        for _ in range(64):  # the 64 representable times before the keyframe, then the 64 after
            t = float(np.nextafter(t, -np.inf))
            q, qd = body.joint_state(t)
            assert 0.0 <= q[0] <= 1.0 and abs(qd[0]) < 1e-12  # the spline turns there: qd ~ |q''| * 1e-14 s
        t = float(tk)
        for _ in range(64):
            t = float(np.nextafter(t, np.inf))
            assert 0.0 <= body.joint_state(t)[0][0] <= 1.0


def test_a_setpoint_moved_on_by_its_velocity_stops_at_the_limit(urdf):
    body = load_robot(urdf, name="three")
    sp = JointSetpoints([0.0, 0.0])
    body.joint_motion = sp
    # A driver's push 1 cm before the prismatic joint's upper limit 0.5 m at 0.1 m/s, the revolute joint
    # 0.01 rad inside its lower limit -2 rad at -1 rad/s: the guess q + qd (t - t_k) left the limits
    # 0.1 s and 0.01 s later and the body refused the run there. Closed form: min(0.49 + 0.1 t, 0.5) and
    # max(-1.99 - t, -2); the velocity is the pushed one until the stop, 0 after.
    sp.set(0.0, [0.49, -1.99], [0.1, -1.0])
    for t in (0.005, 0.05, 0.2, 3.0):
        q, qd = body.joint_state(t)
        np.testing.assert_allclose(q, [min(0.49 + 0.1 * t, 0.5), max(-1.99 - t, -2.0)], rtol=0, atol=1e-15)
        np.testing.assert_array_equal(qd, [0.1 if 0.49 + 0.1 * t < 0.5 else 0.0, -1.0 if t < 0.01 else 0.0])
    # A pushed value outside the limits is still refused, naming the joint and the value.
    sp.set(3.0, [0.7, 0.0])
    with pytest.raises(ConfigError, match=r"three.joints\[slide\] = 0.7 .*\[-0.5, 0.5\] m of joint 'slide'"):
        body.state(3.1)


def test_a_urdf_robot_driven_by_mujoco_through_joint_setpoints_follows_mujocos_bodies(urdf):
    from twinsense.robots.mujoco_cosim import MujocoCosim

    m = mujoco.MjModel.from_xml_path(str(urdf))  # MuJoCo compiles the same URDF
    m.opt.timestep = 0.002
    m.opt.gravity[:] = 0.0  # a constant generalised force alone: the joints stay within their limits to 0.3 s

    def push(model, data):
        data.qfrc_applied[:] = (0.5, -0.3)

    cosim = MujocoCosim(m, control=push, geoms="all")
    body = load_robot(urdf, name="three")
    body.joint_motion = cosim.joint_setpoints({"slide": "slide", "turn": "turn"})
    for k in (0, 25, 50, 100, 150):  # step times: the same qpos and qvel on both sides
        t = k * 0.002
        st = body.state(t)
        for link in LINKS:
            ref = cosim.body_state(link, t)
            i = st.index(link)
            # Two forward kinematics of one state: rounding (~1e-15), 1e-12 allowed.
            np.testing.assert_allclose(st.positions[i], ref.pose.position, rtol=0, atol=1e-12)
            np.testing.assert_allclose(st.rotations[i], ref.pose.rotation, rtol=0, atol=1e-12)
            np.testing.assert_allclose(st.linear_velocities[i], ref.linear_velocity, rtol=0, atol=1e-12)
            np.testing.assert_allclose(st.angular_velocities[i], ref.angular_velocity, rtol=0, atol=1e-12)
    # Between two steps the joints are the last step's moved on by its velocities: q_k + qd_k tau.
    t = 0.3013
    cosim.step_to(t)
    step = cosim.data
    q, qd = body.joint_state(t)
    np.testing.assert_allclose(q, step.qpos + step.qvel * (t - step.time), rtol=0, atol=1e-15)
    np.testing.assert_array_equal(qd, step.qvel)


@pytest.mark.parametrize("name", ["kinova", "xarm7", "ur10", "panda-mjcf"])
def test_installed_robots_link_velocities_are_the_differences_of_their_poses(name):
    body = load_robot(name, shapes="collision")
    lo, hi = np.maximum(body.tree.limits[:, 0], -2.0), np.minimum(body.tree.limits[:, 1], 2.0)
    rng = np.random.default_rng(3)
    # Four keyframes 1 s apart in the middle 40 % of each joint's range (<= 2 rad from 0).
    body.joint_motion = JointKeyframes([0, 1, 2, 3], rng.uniform(lo + 0.3 * (hi - lo), hi - 0.3 * (hi - lo),
                                                                  (4, body.tree.n_joints)))
    h = 1e-5
    # As above: |q'''| <= 6 max|c3| < 30 rad/s^3 for steps < 2.4 rad, links within 1.5 m of the base and
    # turning at < 10 rad/s give |x'''| < 1e3 and central differences within h^2 / 6 * 1e3 = 1.7e-8 plus
    # rounding 2 eps * 2 m / h = 4e-11; tolerance 1e-7.
    for t in (0.4, 1.0, 2.6):
        s1, s0, s = body.state(t + h), body.state(t - h), body.state(t)
        v = (s1.positions - s0.positions) / (2 * h)
        wx = np.einsum("nij,nkj->nik", (s1.rotations - s0.rotations) / (2 * h), s.rotations)
        w = 0.5 * np.stack([wx[:, 2, 1] - wx[:, 1, 2], wx[:, 0, 2] - wx[:, 2, 0], wx[:, 1, 0] - wx[:, 0, 1]], 1)
        np.testing.assert_allclose(s.linear_velocities, v, rtol=0, atol=1e-7)
        np.testing.assert_allclose(s.angular_velocities, w, rtol=0, atol=1e-7)


def test_an_object_keyframe_that_is_no_pose_is_named_by_its_index():
    from twinsense.scene import Keyframes

    with pytest.raises(ConfigError) as e:
        Keyframes(np.array([0.0, 1.0]), (Pose(), "x"))
    # It said motion.poses = '2 poses': expected one Pose per keyframe time (2), true of the count.
    assert e.value.field == "motion.poses[1]" and e.value.value == "x"
    with pytest.raises(ConfigError) as e:
        Keyframes(np.array([0.0, 1.0]), (Pose(),))
    assert e.value.field == "motion.poses" and e.value.value == "1 poses"
