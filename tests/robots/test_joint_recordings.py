"""Recorded joint trajectories: JointSamples and read_joint_states (MCAP of JointState, CSV), a UR5 replaying one.

The reference is a closed form, q_j(t) = a_j sin(w_j t + p_j) + c_j, sampled at 200 Hz and written as
real ``sensor_msgs/msg/JointState`` messages by rosbags (an independent writer: its own CDR serialiser and
the official ROS 2 Humble message definition) and as a CSV file by the standard library's csv module.

Error bounds between samples (h the sample spacing, M4 = max|q''''| = a w^4):

- cubic Hermite (positions and velocities recorded): |q - p| <= h^4 M4 / 384 and |q' - p'| <= sqrt(3)/216
  h^3 M4 (Birkhoff and Priver's optimal constants; both reached by q = t^4, whose Hermite error is
  t^2 (h - t)^2);
- not-a-knot spline (positions only): it differs from the complete spline (exact end slopes) by a spline
  that is 0 at every sample and decays by 2 - sqrt(3) = 0.27 per interval from the ends, so 10 intervals
  in, the complete spline's bounds hold (Hall and Meyer 1976): |e| <= 5/384 h^4 M4, |e'| <= (sqrt(3)/216
  + 1/24) h^3 M4; near the ends the error is O(h^4) (O(h^3) for velocities) with a larger constant,
  checked by its fitted order between h and h/2.
"""

import csv
import math

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from scipy.spatial.transform import Rotation

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.robots import load_robot, read_joint_states
from twinsense.scenario import ScenarioError, scenario_from_dict
from twinsense.scene import JointSamples, Mount, Pose, Scene
from twinsense.scene.articulated import SAMPLES_LIMIT_TOLERANCE

# UR5 joints in the order the UR ROS 2 driver publishes them (alphabetical), not the URDF's.
UR5_JOINTS = ("elbow_joint", "shoulder_lift_joint", "shoulder_pan_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint")
A = np.array([0.6, 0.5, 0.8, 0.7, 0.4, 0.9])  # [rad]; every joint stays inside the UR5's limits (elbow +-pi)
W = np.array([2.0, 3.0, 1.5, 2.5, 3.0, 1.0])  # [rad/s]
P = np.array([0.3, 1.1, -0.4, 2.0, 0.0, -1.3])  # [rad]
C = np.array([0.5, -1.2, 0.2, -1.0, 1.5, 0.0])  # [rad]
RATE = 200.0  # [Hz]
DURATION = 2.0  # [s]
STAMP0 = 1_732_470_000  # [s] an absolute ROS time: the reader's times start at 0 at the first message
STEP_NS = round(1e9 / RATE)


def q_true(t):
    t = np.asarray(t, dtype=float)[..., None]
    return A * np.sin(W * t + P) + C


def qd_true(t):
    t = np.asarray(t, dtype=float)[..., None]
    return A * W * np.cos(W * t + P)


M4 = A * W**4  # max|q''''| per joint [rad/s^4]

TS = get_typestore(Stores.ROS2_HUMBLE)
JS = TS.types["sensor_msgs/msg/JointState"]
HEADER = TS.types["std_msgs/msg/Header"]
TIME = TS.types["builtin_interfaces/msg/Time"]
STRING = TS.types["std_msgs/msg/String"]


def _js(stamp_ns: int, names, pos, vel=()):
    return JS(header=HEADER(stamp=TIME(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9), frame_id=""),
              name=list(names), position=np.asarray(pos, dtype=float), velocity=np.asarray(vel, dtype=float),
              effort=np.zeros(0))


def write_bag(path, messages, topic="/joint_states", extra_topics=()):
    """A ROS 2 bag (MCAP storage) written by rosbags: ``messages`` are (log_time_ns, JointState)."""
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection(topic, JS.__msgtype__, typestore=TS)
        for name in extra_topics:
            other = w.add_connection(name, STRING.__msgtype__, typestore=TS)
            w.write(other, 0, TS.serialize_cdr(STRING(data="x"), STRING.__msgtype__))
        for log_ns, msg in messages:
            w.write(conn, log_ns, TS.serialize_cdr(msg, JS.__msgtype__))
    return path


def sample_times_ns(n=int(DURATION * RATE) + 1):
    return STAMP0 * 10**9 + STEP_NS * np.arange(n, dtype=np.int64)


def recorded_t(stamps_ns):
    """The times the reader gives (stamp - first stamp, exact integers, then to seconds)."""
    return (stamps_ns - stamps_ns[0]) * 1e-9


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """The closed-form trajectory as JointState messages with velocities; message 7 lists its joints reversed."""
    stamps = sample_times_ns()
    t = recorded_t(stamps)
    q, qd = q_true(t), qd_true(t)
    msgs = []
    for k, s in enumerate(stamps):
        order = list(range(6))[::-1] if k == 7 else list(range(6))
        msgs.append((int(s) + 1000, _js(int(s), [UR5_JOINTS[j] for j in order], q[k, order], qd[k, order])))
    return write_bag(tmp_path_factory.mktemp("rec") / "ur5_bag", msgs, extra_topics=("/chatter",)), t, q, qd


def write_csv(path, t, q, qd=None, names=UR5_JOINTS):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time", *names, *([f"{n}_velocity" for n in names] if qd is not None else [])])
        for k in range(len(t)):
            # repr round-trips a float64 exactly.
            w.writerow([repr(float(t[k])), *(repr(float(x)) for x in q[k]),
                        *((repr(float(x)) for x in qd[k]) if qd is not None else ())])
    return path


def _between(t, n_per=7):
    """Points strictly inside every sample interval (not at the samples): the interpolant's worst places."""
    f = (np.arange(n_per) + 0.5) / n_per
    return (t[:-1, None] + np.diff(t)[:, None] * f).ravel()


# ---------------------------------------------------------------- accuracy against the closed form
def test_mcap_hermite_between_samples_within_the_error_bound_and_exact_at_samples(bag):
    path, t, q, qd = bag
    rec = read_joint_states(path)  # the bag directory: its one .mcap file
    assert rec.joint_names == UR5_JOINTS and rec.velocities is not None
    np.testing.assert_array_equal(rec.times, t)
    # Message 7 listed its joints reversed: reordered by name, so the columns hold the same joints throughout.
    np.testing.assert_array_equal(rec.positions, q)
    np.testing.assert_array_equal(rec.velocities, qd)
    for k in (0, 7, 150, len(t) - 1):  # at a sample: the recorded values themselves, bit for bit
        assert np.array_equal(rec.q(t[k]), q[k]) and np.array_equal(rec.qd(t[k]), qd[k])
    h = 1.0 / RATE
    x = _between(t)
    pos = np.array([rec.q(s) for s in x])
    vel = np.array([rec.qd(s) for s in x])
    # Hermite bounds (module docstring) plus 1e-14 for the float64 evaluation of O(1) values.
    err_q = np.abs(pos - q_true(x)).max(axis=0)
    err_qd = np.abs(vel - qd_true(x)).max(axis=0)
    assert np.all(err_q <= h**4 * M4 / 384 + 1e-14), (err_q, h**4 * M4 / 384)
    assert np.all(err_qd <= math.sqrt(3) / 216 * h**3 * M4 + 1e-12), (err_qd, math.sqrt(3) / 216 * h**3 * M4)
    # The bound is sharp to leading order: the worst error found is within 10 % of it for the fastest joint.
    j = int(np.argmax(M4))
    assert err_q[j] > 0.9 * h**4 * M4[j] / 384


def test_csv_not_a_knot_spline_within_its_bounds_and_fourth_order_at_the_ends(tmp_path):
    errs = []
    for rate in (100.0, 200.0):
        h = 1.0 / rate
        t = np.arange(int(DURATION * rate) + 1) * h
        q = q_true(t)
        rec = read_joint_states(write_csv(tmp_path / f"rec{rate:.0f}.csv", t, q))
        assert rec.velocities is None and rec.joint_names == UR5_JOINTS
        np.testing.assert_array_equal(rec.q(t[3]), q[3])
        x = _between(t)
        e_q = np.abs(np.array([rec.q(s) for s in x]) - q_true(x))
        e_qd = np.abs(np.array([rec.qd(s) for s in x]) - qd_true(x))
        inner = (x > t[10]) & (x < t[-11])
        # Ten intervals in: the complete spline's Hall-Meyer bounds (module docstring), + float64 rounding.
        assert np.all(e_q[inner].max(axis=0) <= 5 / 384 * h**4 * M4 + 1e-14)
        assert np.all(e_qd[inner].max(axis=0) <= (math.sqrt(3) / 216 + 1 / 24) * h**3 * M4 + 1e-12)
        errs.append((e_q.max(axis=0), e_qd.max(axis=0)))
    # Over the whole span (the ends included): halving h divides the error by 2^4 (velocity 2^3). The fitted
    # orders are within 0.25 of 4 and 3: the h^5 terms shift them by ~h w = 0.015 to 0.03.
    order_q = np.log2(errs[0][0] / errs[1][0])
    order_qd = np.log2(errs[0][1] / errs[1][1])
    assert np.all(np.abs(order_q - 4) < 0.25), order_q
    assert np.all(np.abs(order_qd - 3) < 0.25), order_qd


def test_held_outside_the_span_with_zero_velocity(bag):
    path, _, q, _ = bag
    rec = read_joint_states(path / "ur5_bag.mcap", time_offset=5.0)  # the file itself; times shifted by 5 s
    assert rec.times[0] == 5.0
    np.testing.assert_array_equal(rec.q(4.0), q[0])
    np.testing.assert_array_equal(rec.q(100.0), q[-1])
    assert not rec.qd(4.0).any() and not rec.qd(100.0).any()


def test_log_clock_and_selected_joints(bag):
    path, t, q, _ = bag
    rec = read_joint_states(path, joint_names=["wrist_3_joint", "elbow_joint"], clock="log")
    assert rec.joint_names == ("wrist_3_joint", "elbow_joint")
    # Log times were the stamps + 1 us: the same times relative to the first.
    np.testing.assert_allclose(rec.times, t, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(rec.positions, q[:, [5, 0]])


# ---------------------------------------------------------------- a UR5 replaying the recording
def test_ur5_tool_mount_velocity_matches_finite_difference_of_its_pose(bag):
    path, t, q, qd = bag
    ur5 = load_robot("ur5", name="ur5", joints=read_joint_states(path), shapes="collision")
    scene = Scene()
    scene.add_articulated(ur5)
    mount = Mount(Pose((0.0, 0.02, 0.05)), parent="ur5/tool0")
    # The body's joint state is the recording's, in the URDF's order (shoulder_pan first).
    qb, qdb = ur5.joint_state(t[40])
    np.testing.assert_array_equal(qb, q[40, [2, 1, 0, 3, 4, 5]])
    np.testing.assert_array_equal(qdb, qd[40, [2, 1, 0, 3, 4, 5]])
    d = 1e-5  # [s]; t +- d stays inside one sample interval (a cubic: smooth there)
    for tt in (t[40] + 0.0021, t[211] + 0.0033):
        st = mount.state_at(scene, tt)
        p0, p1 = mount.state_at(scene, tt - d).pose, mount.state_at(scene, tt + d).pose
        # Central differences: error d^2/6 max|x'''|. With sum|qd| <= 9 rad/s, sum|qdd| <= 18 rad/s^2,
        # sum|qddd| <= 50 rad/s^3 and a reach <= 1.2 m, |x'''| <= 1.2 (9^3 + 3*9*18 + 50) = 1.5e3 m/s^3: 2.5e-8
        # m/s; rounding: 1e-16 m / 1e-5 s = 1e-11. |w''| <= 9*18 + 50 + ... < 1e3 rad/s^3: 1.7e-8 rad/s.
        v_fd = (p1.position - p0.position) / (2 * d)
        w_fd = Rotation.from_matrix(p1.rotation @ p0.rotation.T).as_rotvec() / (2 * d)
        np.testing.assert_allclose(st.linear_velocity, v_fd, rtol=0, atol=5e-8)
        np.testing.assert_allclose(st.angular_velocity, w_fd, rtol=0, atol=5e-8)
        assert np.linalg.norm(st.linear_velocity) > 0.1  # the tool really moves


# ---------------------------------------------------------------- the scenario route
def test_scenario_recording_relative_to_the_file(tmp_path, bag):
    path, t, q, _ = bag
    write_csv(tmp_path / "rec.csv", t, q)
    data = {"name": "replay", "duration": 0.1, "outputs": {"recording": None},
            "robots": [{"name": "ur5", "description": "ur5", "shapes": "collision",
                        "joints": {"recording": {"file": "rec.csv"}}}]}
    sc = scenario_from_dict(data, base_dir=tmp_path)
    assert "ur5/tool0" in sc.scene.frame_names
    body = next(o.motion.body for o in sc.scene.objects if o.name == "ur5/wrist_3_link")
    assert isinstance(body.joint_motion, JointSamples)
    np.testing.assert_array_equal(body.joint_state(t[9])[0], q[9, [2, 1, 0, 3, 4, 5]])
    # The MCAP route with topic and joint_names; the other joints hold their home value (0).
    data["robots"][0]["joints"] = {"recording": {"file": str(path), "topic": "/joint_states", "time_offset": 1.0},
                                   "joint_names": ["elbow_joint"]}
    body = next(o.motion.body for o in scenario_from_dict(data, base_dir=tmp_path).scene.objects
                if o.name == "ur5/wrist_3_link")
    np.testing.assert_array_equal(body.joint_state(1.0 + t[9])[0], [0, 0, q[9, 0], 0, 0, 0])


@pytest.mark.parametrize(("recording", "field", "text"), [
    ({"file": "gone.mcap"}, "robots[0].joints.recording.file", "existing file"),
    ({"file": "BAG", "topic": "/nope"}, "robots[0].joints.recording.topic", "/chatter"),
    ({"file": "BAG", "topic": "/chatter"}, "robots[0].joints.recording.topic", "std_msgs/msg/String"),
    ({"file": "BAG", "speed": 2}, "robots[0].joints.recording", "file required"),
    ({"topic": "/joint_states"}, "robots[0].joints.recording", "file required"),
    ({"file": "BAG", "clock": "wall"}, "robots[0].joints.recording.clock", "header"),
])
def test_scenario_recording_errors_name_the_field(tmp_path, bag, recording, field, text):
    rec = {k: (str(bag[0]) if v == "BAG" else v) for k, v in recording.items()}
    data = {"name": "replay", "duration": 0.1, "outputs": {"recording": None},
            "robots": [{"name": "ur5", "description": "ur5", "shapes": "collision", "joints": {"recording": rec}}]}
    with pytest.raises(ScenarioError) as exc:
        scenario_from_dict(data, base_dir=tmp_path)
    assert [p[0] for p in exc.value.problems] == [field]
    assert text in str(exc.value)


# ---------------------------------------------------------------- errors of the reader
def test_reader_errors_name_file_topic_and_what_is_allowed(tmp_path, bag):
    path = bag[0]
    with pytest.raises(ConfigError, match="existing file") as e:
        read_joint_states(tmp_path / "gone.mcap")
    assert e.value.field == "path"
    with pytest.raises(ConfigError) as e:
        read_joint_states(path, topic="/joint_state")
    assert e.value.field == "topic" and e.value.source.endswith("ur5_bag.mcap")
    assert "/chatter (std_msgs/msg/String)" in e.value.allowed and "/joint_states (sensor_msgs/msg/JointState)" \
        in e.value.allowed
    with pytest.raises(ConfigError, match="carries std_msgs/msg/String") as e:
        read_joint_states(path, topic="/chatter")
    assert "['/joint_states']" in e.value.allowed
    with pytest.raises(ConfigError, match="wrist_3_joint") as e:
        read_joint_states(path, joint_names=["wrist_3_joint", "gripper_joint"])
    assert e.value.field == "/joint_states[0].name"
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(ConfigError, match="CSV file"):
        read_joint_states(tmp_path / "notes.txt")
    (tmp_path / "junk.mcap").write_bytes(b"not an mcap file at all")
    with pytest.raises(ConfigError, match="readable MCAP file"):
        read_joint_states(tmp_path / "junk.mcap")
    with pytest.raises(ConfigError, match="for a CSV file"):
        read_joint_states(write_csv(tmp_path / "a.csv", [0, 1], [[0] * 6, [0] * 6]), topic="/other")


def test_unknown_recorded_joint_is_refused_when_the_body_is_built_listing_the_joints(tmp_path):
    rec = read_joint_states(write_csv(tmp_path / "a.csv", [0, 1], [[0.0], [0.1]], names=["finger_joint"]))
    with pytest.raises(UnknownNameError, match="shoulder_pan_joint") as e:
        load_robot("ur5", name="ur5", joints=rec, shapes="collision")
    assert e.value.field == "ur5.joints.joint_names" and e.value.value == "finger_joint"


def test_mcap_messages_missing_a_joint_too_few_or_bad_stamps(tmp_path):
    s = sample_times_ns(4)
    names = ["a", "b"]
    # The second message lacks joint b (a gripper published on its own, say).
    path = write_bag(tmp_path / "missing", [(int(s[0]), _js(int(s[0]), names, [0, 0])),
                                            (int(s[1]), _js(int(s[1]), ["a"], [0]))])
    with pytest.raises(ConfigError, match="'b' is missing") as e:
        read_joint_states(path)
    assert e.value.field == "/joint_states[1].name"
    # Reading only a works: b was never asked for.
    assert read_joint_states(path, joint_names=["a"]).joint_names == ("a",)
    path = write_bag(tmp_path / "empty", [])
    with pytest.raises(ConfigError, match="at least 2 messages .it holds 0"):
        read_joint_states(path)
    # A stamp going back, and a repeated stamp with other values: named by message index.
    back = [(int(x), _js(int(y), names, [0, 0])) for x, y in zip(s, (s[0], s[2], s[1], s[3]), strict=True)]
    with pytest.raises(ConfigError) as e:
        read_joint_states(write_bag(tmp_path / "back", back))
    assert e.value.field == "/joint_states[2].header.stamp"
    rep = [(int(x), _js(int(y), names, [0, k])) for k, (x, y) in enumerate(zip(s, (s[0], s[1], s[1], s[3]),
                                                                                  strict=True))]
    with pytest.raises(ConfigError, match="whole row repeats") as e:
        read_joint_states(write_bag(tmp_path / "rep", rep))
    assert e.value.field == "/joint_states[2].header.stamp"
    # A driver republishing the same state under the same stamp: the repeat is dropped.
    same = [(int(x), _js(int(y), names, [0, 1 if k >= 2 else 0])) for k, (x, y) in
            enumerate(zip(s, (s[0], s[1], s[1], s[3]), strict=True))]
    same[2] = (int(s[2]), _js(int(s[1]), names, [0, 0]))
    rec = read_joint_states(write_bag(tmp_path / "same", same))
    np.testing.assert_array_equal(rec.times, recorded_t(s[[0, 1, 3]]))
    # Velocities of only some messages: positions only (a not-a-knot spline).
    part = [(int(x), _js(int(x), names, [0, 0.1 * k], [0, 0.1] if k else [])) for k, x in enumerate(s)]
    assert read_joint_states(write_bag(tmp_path / "part", part)).velocities is None
    nan = [(int(x), _js(int(x), names, [0, math.nan if k == 2 else 0])) for k, x in enumerate(s)]
    with pytest.raises(ConfigError) as e:
        read_joint_states(write_bag(tmp_path / "nan", nan))
    assert e.value.field == "/joint_states[2].position[b]"


@pytest.mark.parametrize(("text", "field", "match"), [
    ("", "header", "empty file"),
    ("time,a\n", "rows", "at least 2 rows"),
    ("a,b\n0,1\n", "header", "time"),
    ("time,a,b,a_velocity\n0,0,0,0\n1,0,0,0\n", "header", r"missing for \['b'\]"),
    ("time,a\n0,0\n1,x\n", "row 2.a", "finite number"),
    ("time,a\n0,0\n1,nan\n", "row 2.a", "finite number"),
    ("time,a\n0,0\n1\n", "row 2", "one cell per column"),
    ("time,a\n0,0\n0,1\n", "row 2.time", "whole row repeats"),
    ("time,a\n0,0\n-1,1\n", "row 2.time", "previous sample"),
])
def test_csv_errors_name_the_row_and_column(tmp_path, text, field, match):
    p = tmp_path / "r.csv"
    p.write_text(text)
    with pytest.raises(ConfigError, match=match) as e:
        read_joint_states(p)
    assert e.value.field == field and e.value.source == str(p)


def test_csv_with_velocity_columns_is_hermite(tmp_path):
    t = np.arange(5) * 0.01
    rec = read_joint_states(write_csv(tmp_path / "v.csv", t, q_true(t)[:, :2], qd_true(t)[:, :2], names=("a", "b")))
    np.testing.assert_array_equal(rec.qd(t[2]), qd_true(t)[2, :2])
    with pytest.raises(ConfigError, match="joint column of the file"):
        read_joint_states(tmp_path / "v.csv", joint_names=["c"])


# ---------------------------------------------------------------- JointSamples itself
def _arm():
    from twinsense.scene import ArticulatedBody, Joint, KinematicTree, Link

    tree = KinematicTree("arm", [Link("base"), Link("upper")],
                         [Joint("j", "revolute", "base", "upper", Pose(), lower=-1.0, upper=1.0)])
    return lambda motion: ArticulatedBody("arm", tree, motion)


def test_limits_sample_overshoot_and_noise_at_a_limit():
    build = _arm()
    with pytest.raises(ConfigError, match="joint 'j'") as e:
        build(JointSamples([0, 0.1, 0.2], [[0.0], [1.01], [0.0]]))
    assert e.value.field == "arm.joints.samples.positions[1][0]" and "t = 0.1 s" in e.value.value
    # Samples inside the limits, but the not-a-knot cubic through them peaks at 1.0125 between samples.
    with pytest.raises(ConfigError, match="overshoots") as e:
        build(JointSamples([0, 0.1, 0.2, 0.3], [[0.9], [1.0], [1.0], [0.9]]))
    assert e.value.field == "arm.joints.samples" and "at t = 0.15 s" in e.value.value
    # Measurement noise half the tolerance past the limit: accepted, and q(t) clipped onto the limit.
    tol = SAMPLES_LIMIT_TOLERANCE
    body = build(JointSamples([0, 0.1, 0.2], [[0.5], [1.0 + tol / 2], [0.5]], [[0.0], [0.0], [0.0]]))
    assert body.joint_state(0.1)[0][0] == 1.0
    assert body.joint_state(0.05)[0][0] <= 1.0


def test_samples_input_errors():
    with pytest.raises(ConfigError) as e:
        JointSamples([0, 1], [[0.0], [math.inf]])
    assert e.value.field == "joints.samples.positions[1][0]"
    with pytest.raises(ConfigError, match="one velocity per position"):
        JointSamples([0, 1], [[0.0, 1.0], [0.0, 1.0]], [[0.0], [0.0]])
    with pytest.raises(ConfigError, match="at least 2 samples"):
        JointSamples([0, 0], [[0.0], [0.0]])
    with pytest.raises(ConfigError, match="one name per column"):
        JointSamples([0, 1], [[0.0], [0.0]], joint_names=["a", "b"])
    with pytest.raises(ConfigError):
        JointSamples([0, "x"], [[0.0], [0.0]])
    s = JointSamples([0, 1, 2], [0.0, 1.0, 0.0])  # one joint as a vector
    assert s.n_columns == 1 and s.to_dict()["type"] == "samples"


def _raw_mcap(path, msgdef: str, messages, **writer_options):
    """An MCAP file written record by record with mcap's low-level Writer (CDR bytes from rosbags)."""
    from mcap.writer import Writer as McapWriter

    with open(path, "wb") as f:
        w = McapWriter(f, **writer_options)
        w.start("ros2", "test")
        sid = w.register_schema(JS.__msgtype__, "ros2msg", msgdef.encode())
        cid = w.register_channel("/joint_states", "cdr", sid)
        for log_ns, msg in messages:
            w.add_message(cid, log_ns, TS.serialize_cdr(msg, JS.__msgtype__), log_ns)
        w.finish()
    return path


def test_mcap_without_summary_or_chunks_and_unreadable_files(tmp_path):
    from mcap.writer import IndexType

    s = sample_times_ns(3)
    msgs = [(int(x), _js(int(x), ["a"], [0.1 * k])) for k, x in enumerate(s)]
    bare = dict(repeat_channels=False, repeat_schemas=False, index_types=IndexType.NONE, use_chunking=False,
                use_statistics=False, use_summary_offsets=False)
    # No summary section (the channels are found by reading the file through).
    path = _raw_mcap(tmp_path / "bare.mcap", TS.generate_msgdef(JS.__msgtype__, ros_version=2)[0], msgs, **bare)
    np.testing.assert_array_equal(read_joint_states(path).positions.ravel(), [0.0, 0.1, 0.2])
    # A ROS 1 style definition ("time stamp") the ROS 2 decoder cannot read: the message is named.
    path = _raw_mcap(tmp_path / "ros1def.mcap", TS.generate_msgdef(JS.__msgtype__, ros_version=1)[0], msgs)
    with pytest.raises(ConfigError, match="definition decodes") as e:
        read_joint_states(path)
    assert e.value.field == "/joint_states[0]"
    # A recording cut short (no footer).
    data = (tmp_path / "bare.mcap").read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: len(data) // 2])
    with pytest.raises(ConfigError, match="readable MCAP file"):
        read_joint_states(tmp_path / "cut.mcap")
    # A bag directory must hold exactly one .mcap file.
    (tmp_path / "two").mkdir()
    for n in ("a", "b"):
        (tmp_path / "two" / f"{n}.mcap").write_bytes(data)
    with pytest.raises(ConfigError, match="holds 2 .mcap files"):
        read_joint_states(tmp_path / "two")


def test_malformed_messages_and_bad_arguments(tmp_path):
    s = sample_times_ns(2)
    dup = write_bag(tmp_path / "dup", [(int(x), _js(int(x), ["a", "a"], [0, 0])) for x in s])
    with pytest.raises(ConfigError, match="without repeats") as e:
        read_joint_states(dup)
    assert e.value.field == "/joint_states[0].name"
    short = write_bag(tmp_path / "short", [(int(x), _js(int(x), ["a", "b"], [0])) for x in s])
    with pytest.raises(ConfigError, match="one position per name") as e:
        read_joint_states(short)
    assert e.value.field == "/joint_states[0].position"
    for kw, field in (({"joint_names": "a"}, "joint_names"), ({"joint_names": ["a", "a"]}, "joint_names"),
                      ({"time_offset": math.nan}, "time_offset"), ({"clock": "wall"}, "clock"),
                      ({"topic": 3}, "topic")):
        with pytest.raises(ConfigError) as e:
            read_joint_states(short, **kw)
        assert e.value.field == field
    with pytest.raises(ConfigError):
        read_joint_states(None)


def test_a_recording_pickles_with_its_body(bag):
    import pickle

    ur5 = load_robot("ur5", name="ur5", joints=read_joint_states(bag[0]), shapes="collision")
    copy = pickle.loads(pickle.dumps(ur5))
    for tt in (0.0123, 1.5):
        for a, b in zip(copy.joint_state(tt), ur5.joint_state(tt), strict=True):
            np.testing.assert_array_equal(a, b)


def test_unset_header_stamps_point_to_the_log_clock(tmp_path):
    # A driver that leaves JointState's header unset: every stamp 0. Header times would all repeat;
    # the error names clock and its way out, and the log clock reads the file.
    names = ["a", "b"]
    msgs = [(10**9 + k * 10**7, _js(0, names, [0.01 * k, -0.01 * k])) for k in range(5)]
    path = write_bag(tmp_path / "unset", msgs)
    with pytest.raises(ConfigError, match=r"clock = 'header'.*'log' for messages whose header stamps are all 0"):
        read_joint_states(path)
    rec = read_joint_states(path, clock="log")
    np.testing.assert_allclose(rec.times, 0.01 * np.arange(5), rtol=0, atol=1e-15)


def test_a_real_panda_log_with_both_fingers_drives_the_first(tmp_path):
    # franka_ros publishes both finger joints; the URDF's second finger mimics the first. As ROS, the
    # body warns and the second follows the first; its recorded column is not used.
    names = [f"panda_joint{i}" for i in range(1, 8)] + ["panda_finger_joint1", "panda_finger_joint2"]
    arm = [0.0, -0.5, 0.0, -2.0, 0.0, 1.6, 0.8]
    msgs = [(k * 10**7, _js(10**9 + k * 10**7, names, [*arm, 0.01 + 0.005 * k, 0.03])) for k in range(5)]
    rec = read_joint_states(write_bag(tmp_path / "panda", msgs))
    with pytest.warns(UserWarning, match=r"\['panda_finger_joint2'\] are mimic joints"):
        panda = load_robot("panda", joints=rec, shapes="collision")
    q, _ = panda.joint_state(0.02)
    assert panda.tree.joint_names[-1] == "panda_finger_joint1" and q[-1] == rec.q(0.02)[7]
    st = panda.state(0.02)
    left, right = st.pose("panda_leftfinger").position, st.pose("panda_rightfinger").position
    # Both fingers at q1 = 0.02 m from the hand's axis (the recorded 0.03 of finger 2 not used):
    # 0.04 m apart, to the rounding of the chain (~1e-15 m).
    assert abs(np.linalg.norm(left - right) - 2 * 0.02) < 1e-12
