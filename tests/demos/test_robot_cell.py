"""The robot-cell demo: its cell equals examples/robot_cell.yaml, it writes its outputs, the radar sees the torso."""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.demos.robot_cell import (
    PERSON,
    ROBOT,
    build_arm_cell,
    build_arm_cell_scene,
    build_arm_cell_sensors,
    micro_doppler,
    run_robot_cell_demo,
    tof_separation,
    torso_line,
)
from twinsense.errors import ConfigError
from twinsense.io.recording import open_recording
from twinsense.safety import SeparationMonitor, point_box_distance, point_capsule_distance
from twinsense.scenario import ScenarioError, load_scenario
from twinsense.scene import Box

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "robot_cell.yaml"


def test_example_file_describes_the_demo_cell():
    # The demo builds its cell in Python (a pip install has no examples/); the example file must
    # describe the very same scene and sensors (at the file's rates).
    sc = load_scenario(EXAMPLE)
    scene, sensors = build_arm_cell()
    a, b = sc.scene.to_dict(), scene.to_dict()
    assert a == b
    # shapes: collision in the file, as in Python (to_dict does not show which meshes a link has).
    assert [len(o.geometry.mesh.faces) for o in sc.scene.objects] == [len(o.geometry.mesh.faces) for o in scene.objects]
    for t in (0.0, 1.1, 2.9, 3.4):
        for obj in scene.objects:
            np.testing.assert_array_equal(sc.scene.object(obj.name).pose_at(t).matrix, obj.pose_at(t).matrix)
    assert [(s.name, s.kind, s.frame_rate) for s in sc.sensors] == [(s.name, s.kind, s.frame_rate) for s in sensors]
    for mine, theirs in zip(sensors, sc.sensors):
        assert repr(mine.config) == repr(theirs.config)
        assert mine.mount.parent == theirs.mount.parent
        np.testing.assert_array_equal(mine.mount.pose.matrix, theirs.mount.pose.matrix)
    # The pick-and-place trajectory stays inside the UR5's joint limits at every keyframe and between.
    body = sc.scene.object(f"{ROBOT}/forearm_link").motion.body
    for t in np.linspace(0.0, 4.6, 47):
        body.joint_state(float(t))  # raises ConfigError outside the limits


def test_demo_writes_its_outputs(tmp_path):
    # Fast settings: 0.1 s, one frame of each camera and the skin, two radar frames.
    out = run_robot_cell_demo(tmp_path, duration=0.1, radar_rate=20.0, skin_rate=10.0, fast=True)
    for key in ("depth_wall_png", "depth_wrist_png", "micro_doppler_png", "separation_png", "recording"):
        assert out[key].is_file() and out[key].stat().st_size > 1000, key
    with open_recording(out["recording"]) as rec:
        assert {n: s.kind for n, s in rec.sensors.items()} == {"wall_tof": "tof", "radar": "radar",
                                                               "wrist_tof": "tof", "skin": "capacitive"}
        assert [len(rec[n]) for n in ("wall_tof", "radar", "wrist_tof", "skin")] == [1, 2, 1, 1]
    assert not list(tmp_path.glob(".*tmp*"))  # no half-written figure left behind


def test_spectrogram_torso_line_follows_the_true_radial_speed():
    # The demo's own cell and radar: 20 frames/s while the person walks away from the side wall at full
    # speed (0.6-1.1 s, after the 0.6 s start ramp; thorax at 0.87-1.19 m/s radial). Per frame, the
    # strongest moving Doppler bin over the person's range bins (the torso, the largest reflector) lies
    # within one Doppler bin (lambda / (2 N T_rep) = 0.41 m/s at 64 chirps of 100 us) of the thorax's
    # true radial velocity (see below).
    scene = build_arm_cell_scene()
    radar = build_arm_cell_sensors(radar_rate=20.0)[1]
    rng = np.random.default_rng(5)
    frames = [radar.capture(scene, t, rng) for t in np.arange(0.6, 1.11, 0.05)]
    _, vel, power, truth = micro_doppler(frames, scene)
    bin_width = float(np.diff(vel).mean())
    # The Doppler bin is lambda / (2 N T_rep) at the chirp's centre frequency (no zero padding): exact.
    wavelength = SPEED_OF_LIGHT / radar.config.chirp.centre_frequency
    assert bin_width == pytest.approx(wavelength / (2 * 64 * 1e-4), rel=1e-9, abs=0)
    line = torso_line(vel, power)
    assert truth.min() > 2 * bin_width  # walking away (0.87-1.19 m/s), clear of the zero bin
    # Measured: at most 0.78 bins off; the peak bin alone quantises by up to half
    # a bin, and the trunk's reflection centre sways about the thorax origin within a frame.
    np.testing.assert_array_less(np.abs(line - truth), bin_width)


def test_bad_duration_names_the_field_and_writes_nothing(tmp_path):
    with pytest.raises(ConfigError, match="duration = -1.0"):
        run_robot_cell_demo(tmp_path / "out", duration=-1.0)
    assert not (tmp_path / "out").exists()


def test_unknown_robot_shapes_name_the_field(tmp_path):
    p = tmp_path / "cell.yaml"
    p.write_text(EXAMPLE.read_text().replace("shapes: collision", "shapes: hulls"))
    with pytest.raises(ScenarioError, match=r"robots\[0\]\.shapes.*hulls.*'visual' or 'collision'"):
        load_scenario(p)


def _surface_points(geometry, spacing: float) -> np.ndarray:
    """Vertices (n, 3) of a link mesh subdivided to edges <= ``spacing`` [m] (its own frame)."""
    v, _ = trimesh.remesh.subdivide_to_size(np.asarray(geometry.mesh.vertices), np.asarray(geometry.mesh.faces),
                                            max_edge=spacing, max_iter=30)
    return np.unique(v, axis=0)


def test_reaching_hand_comes_close_to_the_skin_but_never_into_it_or_a_link():
    # The person reaches towards the forearm's skin and holds while the arm lifts the skin past the hand.
    # Clearance of the whole body (exact capsules and boxes, as safety.SeparationMonitor measures it) to
    # (a) the skin patch: its FR-4 slab (the preset's substrate extent, z from -1.6 mm to 0 in the mount
    # frame, the ground plane at its bottom) as a 2 mm grid on both faces: a body surface can come closer
    # than the grid's points by at most half the grid's diagonal, 1.4 mm; (b) the UR5e's collision meshes
    # subdivided to 10 mm edges: exact to 10 / sqrt(3) = 5.8 mm from above (SeparationMonitor's bound).
    scene, sensors = build_arm_cell()
    skin = sensors[3]
    robot = scene.object(f"{ROBOT}/forearm_link").motion.body
    person = scene.object("person/left_hand").motion.body
    x0, x1, y0, y1 = skin.config.layout.substrate.extent
    step = 2e-3
    gx, gy = np.meshgrid(np.arange(x0, x1 + 1e-9, step), np.arange(y0, y1 + 1e-9, step))
    face = np.c_[gx.ravel(), gy.ravel(), np.zeros(gx.size)]
    patch = np.vstack([face, face - [0.0, 0.0, skin.config.layout.substrate.thickness]])
    grid_err, mesh_err = step / np.sqrt(2.0), 1e-2 / np.sqrt(3.0)
    links = [(i, pts, np.linalg.norm(pts - pts.mean(0), axis=1).max(), pts.mean(0))
             for i, lk in enumerate(robot.tree.links) if (g := lk.link_frame_geometry()) is not None
             for pts in [_surface_points(g, 1e-2)]]
    prims = [(i, lk.geometry, lk.origin) for i, lk in enumerate(person.tree.links) if lk.geometry is not None]
    reach = 0.1  # [m] clearances beyond this are not resolved (bounding spheres farther apart are left out)

    def body_distance(points, segments, centre, radius):
        """Smallest distance [m] from ``points`` (n, 3), within ``radius`` of ``centre``, to the body
        ``segments`` [(pose, geometry, bounding radius)] whose bounding spheres come within ``reach`` of that
        sphere (``reach`` if none)."""
        best = reach
        for pose, g, bound in segments:
            if np.linalg.norm(pose.position - centre) - bound - radius < reach:
                best = min(best, float(segment_distance(points, pose, g).min()))
        return best

    def segment_distance(points, pose, g):
        if isinstance(g, Box):
            return point_box_distance((points - pose.position) @ pose.rotation, g.size)
        a, b = pose.apply(np.array([[0.0, 0.0, -g.height / 2], [0.0, 0.0, g.height / 2]]))
        return point_capsule_distance(points, a, b, g.radius)

    patch_radius = np.linalg.norm([x1 - x0, y1 - y0]) / 2

    def clearances(t):
        """(body to skin, body to robot) [m] at t, each at most ``reach``."""
        sp, rs, ps = skin.mount.pose_at(scene, t), robot.state(t), person.state(t)
        segments = [(ps.pose(i) @ origin, g, np.linalg.norm(g.size) / 2 if isinstance(g, Box)
                     else g.height / 2 + g.radius) for i, g, origin in prims]
        d_skin = body_distance(sp.apply(patch), segments, sp.position, patch_radius)
        d_robot = min(body_distance(rs.pose(i).apply(pts), segments, rs.pose(i).apply(c[None])[0], r)
                      for i, pts, r, c in links)
        return d_skin, d_robot

    # Time steps from the clearance itself: no point of the body moves faster than V_BODY (the reaching
    # hand is its fastest part once the person stands; its corners checked below: 1.70 m/s) and no point of
    # the robot or its skin faster than V_ROBOT (the links' vertices checked below: 1.01 m/s), so a
    # clearance D at t stays above D - (V_BODY + V_ROBOT) |dt|; stepping by (D - floor) / (V_BODY +
    # V_ROBOT), at least 1 ms, leaves no moment in between below the floor (5 mm plus the sampling error).
    V_BODY, V_ROBOT = 2.0, 1.2
    floor_skin, floor_robot = 5e-3 + grid_err, 5e-3 + mesh_err
    hand = [lk.name for lk in person.tree.links].index("left_hand")
    hand_link = person.tree.links[hand]
    corners = np.array(np.meshgrid(*[[-0.5, 0.5]] * 3)).reshape(3, -1).T * hand_link.geometry.size
    # A rigid body's fastest point is a vertex of its convex hull (the velocity is affine in the position):
    # the hand box's corners, the links' own mesh vertices.
    vertices = [(i, np.asarray(g.mesh.vertices)) for i, lk in enumerate(robot.tree.links)
                if (g := lk.link_frame_geometry()) is not None]
    t, end, trace = 2.6, 2.6 + 2 * 0.7 + 0.5, []  # the reach: out over 0.7 s, 0.5 s hold, back over 0.7 s
    while t <= end:
        d_skin, d_robot = clearances(t)
        trace.append((t, d_skin, d_robot))
        t += max(1e-3, min(d_skin - floor_skin, d_robot - floor_robot) / (V_BODY + V_ROBOT))
    ts, d_skin, d_robot = np.array(trace).T
    # The hand's corners (finite differences over 1 ms: its motion is smooth on that scale) and the robot's
    # vertices stay under their bounds (10 % spare) throughout the reach, so the steps above were safe.
    for tt in np.linspace(2.6, end, 40):
        a, b = (person.state(float(x)).pose(hand) @ hand_link.origin for x in (tt, tt + 1e-3))
        assert np.linalg.norm(b.apply(corners) - a.apply(corners), axis=1).max() / 1e-3 < V_BODY / 1.1
        rs = robot.state(float(tt))
        v = np.concatenate([rs.point_velocity(i, rs.pose(i).apply(p)) for i, p in vertices])
        assert np.linalg.norm(v, axis=1).max() < V_ROBOT / 1.1
    # Never inside: 5 mm of margin beyond the sampling errors; the robot's links farther still.
    assert d_skin.min() > floor_skin and d_robot.min() > floor_robot
    # Close enough for a strong skin response: at the closest, within 30 mm of the patch (measured:
    # 16.0 mm at 3.58 s; within 30 mm from 3.27 to 3.74 s).
    assert d_skin.min() < 0.03
    close = ts[d_skin < 0.03]
    assert 3.2 < close.min() < close.max() < 3.75


def test_wall_tof_separation_leaves_out_isolated_returns_but_not_a_surface():
    # A 10 x 10 cm patch of points 1 cm apart (a surface 3 m away puts ~1.4 cm between pixels) 0.5 m in
    # front of the robot's base, and three lone points (one 20 cm from the robot, in mid-air, as a noisy
    # floor pixel that passed the static margins reads): the reading is the patch's distance to the robot
    # (the same cKDTree query over the same robot points: exact), not the strays'.
    scene = build_arm_cell_scene()
    monitor = SeparationMonitor(scene, ROBOT, PERSON)
    t = 1.0
    robot = monitor.robot_points(t)[0]
    base = robot[np.argmin(robot[:, 2])]
    u, v = np.meshgrid(np.arange(10) * 0.01, np.arange(10) * 0.01)
    patch = np.stack([base[0] + 0.5 + 0 * u, base[1] - 0.6 + u, 1.2 + v], axis=-1).reshape(-1, 3)
    strays = np.array([[base[0] + 0.15, base[1] - 0.3, 1.0], [0.9, -1.0, 1.6], [0.2, -1.8, 0.7]])
    pts = np.vstack([patch, strays])
    d_strays = cKDTree(robot).query(strays)[0]
    assert d_strays.min() < cKDTree(robot).query(patch)[0].min()  # a stray is nearer: it would win
    frame = SimpleNamespace(t=t, valid=np.ones(len(pts), bool), points_world=pts, noise=np.full(len(pts), 1e-3))
    assert tof_separation(monitor, frame) == cKDTree(robot).query(patch)[0].min()
    # Strays alone: nothing to report.
    alone = SimpleNamespace(t=t, valid=np.ones(3, bool), points_world=strays, noise=np.full(3, 1e-3))
    assert np.isnan(tof_separation(monitor, alone))
