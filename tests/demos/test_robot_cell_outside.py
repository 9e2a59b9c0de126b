"""The robot cell's safety figures and the walker's micro-Doppler against closed forms, on scenes of their own.

Not the demo's cell (but for one check of its separation trace): a swinging bar against a still sphere
(ISO/TS 15066's v_r in closed form), a walker of another height and speed crossing the radar's view at
an angle (the torso line against v cos(theta), the limbs' period against Boulic's cycle formula).
"""

import math

import numpy as np
import pytest
import trimesh

from twinsense.demos import robot_cell
from twinsense.demos.robot_cell import PERSON, ROBOT, build_arm_cell_scene, run_robot_cell_demo, separation_trace
from twinsense.errors import ConfigError
from twinsense.radar import make_radar
from twinsense.safety import SeparationMonitor, SeparationParameters, protective_separation_distance
from twinsense.scene import Box, Capsule, JointConstantVelocity, Mount, Pose, Scene, Sphere
from twinsense.scene.articulated import ArticulatedBody, Joint, KinematicTree, Link
from twinsense.scene.human import Walk, add_person


def _one_link(name, geometry, joint_motion=None, base=Pose(), kind="fixed", axis=(1.0, 0.0, 0.0), origin=Pose()):
    links = [Link("base"), Link("body", geometry, "aluminium", origin=origin)]
    joints = [Joint("j", kind, "base", "body", axis=axis)]
    return ArticulatedBody(name, KinematicTree(name, links, joints), joint_motion, base)


def test_protective_distance_takes_the_fastest_approaching_robot_point():
    # A bar of length L = 1 m (2 w = 4 mm square) swings about z through its end at omega = 1 rad/s, 1 m up;
    # a person's sphere (radius 0.1 m) stands still at c = (a, b) = (0.15, 0.3) at that height. At t = 0 the
    # bar lies along +x: its point x moves at omega x along +y, and the direction from it to the sphere
    # (towards the sphere's centre) is (a - x, b) / sqrt((a - x)^2 + b^2), so its speed towards the person is
    # f(x) = omega x b / sqrt((x - a)^2 + b^2). The closest point is x = a: f = omega a = 0.15 m/s. The
    # fastest approach is at x* = (a^2 + b^2) / a = 0.75 m (df/dx = 0): f(x*) = 0.3354 m/s. ISO/TS 15066's
    # v_r, the robot's speed in the direction of the person, is the latter: S_p for 0.15 m/s would let the
    # bar's middle close in 0.185 m/s faster than its stop allows for.
    omega, L, w, a, b = 1.0, 1.0, 0.002, 0.15, 0.3
    scene = Scene()
    scene.add_articulated(_one_link("robot", Box((L, 2 * w, 2 * w)), JointConstantVelocity([0.0], [omega]),
                                    Pose((0.0, 0.0, 1.0)), kind="revolute", axis=(0.0, 0.0, 1.0),
                                    origin=Pose((L / 2, 0.0, 0.0))))
    scene.add_articulated(_one_link("person", Sphere(0.1), base=Pose((a, b, 1.0))))
    spacing = 0.005
    s = SeparationMonitor(scene, "robot", "person", spacing=spacing).at(0.0)
    x_star = (a * a + b * b) / a
    v_max = omega * b * x_star / math.hypot(x_star - a, b)
    # Tolerance: the monitor takes the bar's surface vertices, not its axis. |grad f| <= omega (1 + |p| /
    # |c - p|) <= omega (1 + 1.0 / 0.298) = 4.4 omega on the bar; a surface point is within w sqrt(2) of
    # the axis (f can exceed the axis' maximum by 4.4 * 2.8 mm * omega = 12.4 mm/s), and a vertex lies within
    # w + spacing / sqrt(3) = 4.9 mm of the axis point x* (f falls short by at most 2.2 omega * 4.9 mm =
    # 10.8 mm/s, 2.2 = 1 + |p| / |c - p| near x*): 12.5 mm/s either way.
    tol = 0.0125
    assert s.approach_speed == pytest.approx(v_max, rel=0, abs=tol)
    # The closest point (the face at x = a, y = w) moves at omega (-w, a, 0), straight at the sphere's centre
    # along +y: omega a, to the vertex spacing along the bar (omega spacing / sqrt(3) = 2.9 mm/s).
    assert s.robot_speed == pytest.approx(omega * a, rel=0, abs=omega * spacing / math.sqrt(3))
    # The face at y = w is b - w - 0.1 from the sphere; the vertices overestimate by at most spacing / sqrt(3).
    assert b - w - 0.1 - 1e-12 <= s.distance <= b - w - 0.1 + spacing / math.sqrt(3)
    # S_p for that v_r: 1.6 (0.1 + 0.3) + v_r (0.1 + 0.3 / 2) + 0.26 = 0.9 + 0.25 v_r [m].
    assert protective_separation_distance(s.approach_speed) == pytest.approx(0.9 + 0.25 * v_max, rel=0,
                                                                               abs=0.25 * tol)


@pytest.mark.parametrize("person, centre, radius", [("sphere", (0.7, 0.4, 1.0), 0.15),
                                                    ("touching capsule", (0.3, 0.2, 1.0), 0.15),
                                                    ("overlapping capsule", (0.3, 0.15, 1.0), 0.2)])
def test_separation_of_a_rotating_box_link_matches_trimesh(person, centre, radius):
    # A 0.6 x 0.1 x 0.1 m box link turning about z at 1 rad/s from its end; a person's sphere, or a vertical
    # capsule that touches (then overlaps by 0.1 m) the box's +y face at t = 0. Reference: trimesh's exact
    # closest point on the box mesh to the sphere's centre (or to the capsule's axis point at the box's
    # height, its nearest), minus the radius. The monitor's subdivided vertices overestimate by at most
    # spacing / sqrt(3) and never underestimate; on a box the vertices lie on the faces, so closer still.
    scene = Scene()
    scene.add_articulated(_one_link("robot", Box((0.6, 0.1, 0.1)), JointConstantVelocity([0.0], [1.0]),
                                    Pose((0.0, 0.0, 1.0)), kind="revolute", axis=(0.0, 0.0, 1.0),
                                    origin=Pose((0.3, 0.0, 0.0))))
    geometry = Sphere(radius) if person == "sphere" else Capsule(radius, 0.6)
    scene.add_articulated(_one_link("person", geometry, base=Pose(centre)))
    monitor = SeparationMonitor(scene, "robot", "person", spacing=0.01)
    for t in (0.0, 0.3, 0.6) if person == "sphere" else (0.0,):
        box = trimesh.creation.box((0.6, 0.1, 0.1))
        box.apply_transform(trimesh.transformations.rotation_matrix(t, (0, 0, 1)) @
                            trimesh.transformations.translation_matrix((0.3, 0.0, 0.0)))
        box.apply_translation((0.0, 0.0, 1.0))
        _, gap, _ = trimesh.proximity.closest_point(box, [centre])
        inside = box.contains([centre])[0]
        true = (-gap[0] if inside else gap[0]) - radius
        d = monitor.at(t).distance
        assert true - 1e-9 <= d <= true + monitor.spacing / math.sqrt(3), (t, d, true)


def test_robot_cell_trace_draws_s_p_for_the_fastest_approach():
    # The demo's cell at 3.6 s: the hand holds beside the forearm (28 mm) while the arm lifts away; the closest
    # point recedes (0.01 m/s towards the person), a part of the forearm 10 cm from the hand approaches at
    # 0.37 m/s. The figure's S_p must be the one for that approach: 0.9 + 0.25 * 0.37 = 0.99 m, not 0.90.
    scene = build_arm_cell_scene()
    monitor = SeparationMonitor(scene, ROBOT, PERSON)
    times = np.array([2.4, 3.6])
    trace = separation_trace(monitor, times)
    samples = [monitor.at(float(t)) for t in times]
    np.testing.assert_array_equal(trace.robot_speed, [s.approach_speed for s in samples])
    np.testing.assert_allclose(trace.protective, 0.9 + 0.25 * trace.robot_speed, rtol=0, atol=1e-12)
    assert samples[1].robot_speed < 0.01 and samples[1].approach_speed > 0.25  # measured 0.009 and 0.374 m/s
    assert all(s.approach_speed >= s.robot_speed for s in samples)


def test_protective_distance_rejects_bad_input_by_name():
    with pytest.raises(ConfigError, match=r"robot_speed = 'fast'.*finite speeds >= 0 m/s"):
        protective_separation_distance("fast")
    with pytest.raises(ConfigError, match=r"robot_speed = \[0.1, -0.2\]"):
        protective_separation_distance([0.1, -0.2])
    with pytest.raises(ConfigError, match=r"params = \{'human_speed': 2.0\}.*SeparationParameters"):
        protective_separation_distance(0.5, {"human_speed": 2.0})
    with pytest.raises(ConfigError, match="intrusion_distance"):
        SeparationParameters(intrusion_distance=float("inf"))


def test_separation_monitor_refuses_a_spacing_beyond_the_memory():
    # A spacing that would subdivide the bar (0.016 m^2) into ~1e11 points: refused up front with the
    # smallest spacing allowed (the subdivision would exhaust the memory otherwise).
    bar = _one_link("robot", Box((1.0, 0.004, 0.004)))
    scene = Scene()
    scene.add_articulated(bar)
    scene.add_articulated(_one_link("person", Sphere(0.1), base=Pose((0.0, 1.0, 0.0))))
    with pytest.raises(ConfigError, match=r"spacing = 1e-06.*a spacing >= .* m for this robot"):
        SeparationMonitor(scene, "robot", "person", spacing=1e-6)


@pytest.mark.parametrize("kwargs, message", [
    ({"radar_rate": -1.0}, r"radar_rate = -1.0.*> 0 \[Hz\]"),
    ({"skin_rate": 0.0}, r"skin_rate = 0.0.*> 0 \[Hz\]"),
    ({"seed": "x"}, r"seed = 'x'"),
    ({"params": {"human_speed": 2.0}}, r"params = .*SeparationParameters"),
])
def test_demo_names_a_bad_argument_and_writes_nothing(tmp_path, kwargs, message):
    # Each argument is named as given (not as the preset override or readout field it becomes), before the
    # output folder is made: no empty folder, no recording without its figures.
    with pytest.raises(ConfigError, match=message):
        run_robot_cell_demo(tmp_path / "out", duration=0.05, fast=True, **kwargs)
    assert not (tmp_path / "out").exists()


def test_spectrogram_rows_sit_on_their_doppler_bins(tmp_path, monkeypatch):
    # 64 Doppler bins of 0.408 m/s centred on -13.06 ... +12.65 m/s: the image must span the bins' edges,
    # centre -/+ half a bin, so that row k is drawn centred on velocity k (and frame j on time j).
    vel = (np.arange(64) - 32) * 0.408
    t = np.arange(5) * 0.05
    shown, save = {}, robot_cell.save_figure

    def keep(fig, path):
        shown["extent"] = fig.axes[0].images[0].get_extent()
        shown["labels"] = [ax.get_ylabel() for ax in fig.axes]
        return save(fig, path)

    monkeypatch.setattr(robot_cell, "save_figure", keep)
    robot_cell._doppler_figure(t, vel, np.ones((5, 64)), np.zeros(5), tmp_path / "md.png")
    np.testing.assert_allclose(shown["extent"], [-0.025, 0.225, vel[0] - 0.204, vel[-1] + 0.204], rtol=0,
                               atol=1e-12)
    # The colours are labelled too: power in dB relative to the strongest bin.
    assert shown["labels"] == ["radial velocity [m/s] (> 0 away)", "power [dB re the strongest bin]"]


# A walker the radar tests do not use: 1.60 m tall, 1.0 m/s, walking away at 40 deg to the radar's boresight,
# 3.7-6.5 m out, the radar 0.9 m up (below the thorax).
HEIGHT, SPEED, HEADING, FPS, N_FRAMES = 1.6, 1.0, 40.0, 20.0, 60
START = np.array([2.0, -0.3])
T_START = -2.0  # walking since -2 s: the start ramp (0.6 s) is over


@pytest.fixture(scope="module")
def walker_spectrogram():
    scene = Scene()
    add_person(scene, "w", HEIGHT, tuple(START), HEADING, walk=Walk(SPEED, heading_deg=HEADING, start_time=T_START))
    radar = make_radar("paper_bgt60tr13c", num_samples=64, num_chirps=64, chirp_repetition_time=1e-4,
                       ramp_end_time=40e-6, frame_rate=FPS, render_width=96, render_height=48,
                       mount=Mount(Pose.look_at((0.0, 0.0, 0.9), (1.0, 0.0, 0.9))))
    rng = np.random.default_rng(11)
    heading = np.array([math.cos(math.radians(HEADING)), math.sin(math.radians(HEADING)), 0.0])
    rows, radial, limbs = [], [], []
    body = scene.object("w/left_foot").motion.body
    names = list(body.tree.link_names)
    for k in range(N_FRAMES):
        t = k / FPS
        f = radar.capture(scene, t, rng)
        pr = f.processed
        # The walking path in closed form (not the model's thorax): start + v (t - t0 - 0.3 s) along the
        # heading (the walk's rate ramps from 0 to 1 over its first 0.6 s, covering half of what full speed
        # would: it runs 0.3 s behind start + v (t - t0) after that), at the thorax's height (0.72 H);
        # radial speed v cos(theta) with theta the angle to the line of sight.
        centre = np.r_[START + SPEED * (t - T_START - 0.3) * heading[:2], 0.72 * HEIGHT] - f.pose.position
        radial.append(SPEED * heading @ centre / np.linalg.norm(centre))
        rows.append(pr.power[:, np.abs(pr.range_axis - np.linalg.norm(centre)) <= 1.0].sum(axis=1))
        # The limbs' true fastest radial speed (every vertex of the feet, shanks and hands).
        st = body.state(t)
        v = 0.0
        for part in ("left_foot", "right_foot", "left_shank", "right_shank", "left_hand", "right_hand"):
            i = names.index(part)
            p = st.pose(i).apply(np.asarray(body.tree.links[i].link_frame_geometry().mesh.vertices))
            los = p - f.pose.position
            v = max(v, float(np.abs(np.einsum("ij,ij->i", st.point_velocity(i, p), los)
                                    / np.linalg.norm(los, axis=1)).max()))
        limbs.append(v)
    return np.array(rows), pr.velocity_axis, np.array(radial), np.array(limbs)


def test_walker_torso_line_is_v_cos_theta(walker_spectrogram):
    power, vel, radial, _ = walker_spectrogram
    bin_width = float(np.diff(vel).mean())  # lambda / (2 N T_rep) = 0.408 m/s at 57.4 GHz
    p = power.copy()
    p[:, np.argmin(np.abs(vel))] = 0.0  # the static clutter's zero bin
    # The frame-averaged spectrum's strongest moving line is the torso: within one Doppler bin of the mean
    # v cos(theta) (0.94 m/s; the torso's own +-20 % sway within a step averages out over 3 s = 4.8 steps).
    assert vel[np.argmax(p.mean(axis=0))] == pytest.approx(radial.mean(), rel=0, abs=bin_width)  # measured 0.82
    # Frame by frame the swinging legs sometimes outshine the trunk; most frames' peak is the torso.
    line = vel[np.argmax(p, axis=1)]
    assert np.mean(np.abs(line - radial) < bin_width) > 0.8  # measured 0.85


def test_walker_limbs_repeat_at_the_step_period_and_reach_the_feet_speed(walker_spectrogram):
    power, vel, _, limbs = walker_spectrogram
    bin_width = float(np.diff(vel).mean())
    noise = np.median(power[:, np.abs(vel) > 8.0], axis=1)  # no scatterer moves faster than 8 m/s here
    # Boulic's cycle in closed form: D_c = 1.346 / sqrt(v / (0.53 H)) = 1.2395 s; the legs are mirror images
    # in radial velocity, so the signature repeats every step, D_c / 2 = 0.620 s.
    step = 1.346 / math.sqrt(SPEED / (0.53 * HEIGHT)) / 2
    # The power above the torso's band (2-5 m/s: the swinging leg) rises once per step: the peak of its
    # spectrum (Hann window, zero-padded to 4096) lies within one frame (0.05 s) of the step period.
    band = power[:, (vel > 2.0) & (vel < 5.0)].sum(axis=1) / noise
    x = band - band.mean()
    spec = np.abs(np.fft.rfft(x * np.hanning(len(x)), 4096))
    freqs = np.fft.rfftfreq(4096, 1.0 / FPS)
    period = 1.0 / freqs[1:][np.argmax(spec[1:])]
    assert period == pytest.approx(step, rel=0, abs=1.0 / FPS)  # measured 0.583 s
    # The limb envelope (the fastest bin 10 dB above the noise) reaches beyond 2.5 v, and no bin stands out
    # faster than the limbs' true fastest radial speed (4.2 v here) plus one bin.
    extent = np.array([np.abs(vel[r > 10 * n]).max(initial=0.0) for r, n in zip(power, noise)])
    assert 2.5 * SPEED < extent.max() <= limbs.max() + bin_width  # measured 3.67 against 4.25 m/s
