"""The robot-cell demo's figures against computations of their own (none of the demo's or the monitor's helpers).

- The separation plot's true distance, v_r and ISO/TS 15066 S_p: the UR5e posed by MuJoCo (its own
  ``mj_kinematics`` on the shipped MJCF) along the joint trajectory rebuilt with scipy's clamped cubic
  spline, point velocities by central differences, each robot point's nearest body point in closed form
  (segment and box clamps written here), S_p by the TS's formula by hand.
- The micro-Doppler figure's truth overlay: the thorax's range rate from the radar by central differences
  of its distance; the torso line within one Doppler bin of it over the whole walk, the bin from the waveform.
"""

import math
import re
from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest
from scipy.interpolate import CubicSpline

import twinsense
from body_distance import person_to_mesh
from twinsense.demos import robot_cell as rc
from twinsense.errors import ConfigError
from twinsense.safety import SeparationMonitor, SeparationParameters, protective_separation_distance
from twinsense.scene import Box, Sphere

C = 299_792_458.0


@pytest.fixture(scope="module")
def cell():
    scene = rc.build_arm_cell_scene()
    return scene, SeparationMonitor(scene, rc.ROBOT, rc.PERSON)


def _nearest_body_points(monitor, p, t):
    """(distance (n,) [m], nearest point (n, 3)) from robot points ``p`` to the person's capsules, spheres
    and boxes at t, in closed form: a capsule's axis point clamped to its segment plus the radius along the
    offset; a box's point clamped to its extent in the box frame (no robot point is inside a box here)."""
    st = monitor.person.state(t)
    best, near = np.full(len(p), np.inf), np.zeros_like(p)
    for i, lk in enumerate(monitor.person.tree.links):
        g = lk.geometry
        if g is None:
            continue
        pose = st.pose(i) @ lk.origin
        if isinstance(g, Box):
            local = (p - pose.position) @ pose.rotation
            half = 0.5 * np.asarray(g.size, dtype=float)
            assert not np.all(np.abs(local) < half, axis=1).any()
            c = np.clip(local, -half, half) @ pose.rotation.T + pose.position
            d = np.linalg.norm(p - c, axis=1)
        else:
            h = 0.0 if isinstance(g, Sphere) else 0.5 * g.height
            a, b = pose.position - h * pose.rotation[:, 2], pose.position + h * pose.rotation[:, 2]
            s = np.clip((p - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-300), 0.0, 1.0)
            axis = a + s[:, None] * (b - a)
            r = np.linalg.norm(p - axis, axis=1)
            d = r - g.radius
            c = axis + (p - axis) * (g.radius / r)[:, None]
        closer = d < best
        best[closer], near[closer] = d[closer], c[closer]
    return best, near


def test_separation_and_s_p_match_mujoco_kinematics_and_the_ts_formula(cell):
    _, monitor = cell
    model = mujoco.MjModel.from_xml_path(str(Path(twinsense.__file__).parent / "data/robots/ur5e/ur5e.xml"))
    data = mujoco.MjData(model)
    joints = CubicSpline(rc.TIMES, np.array(rc.KEYFRAMES), bc_type="clamped")  # zero velocity at both ends
    names = [lk.name for lk in monitor.robot.tree.links]
    base = np.array([0.0, 0.0, 0.8])  # the pedestal's top: the arm's base pose in the cell

    def points(t):
        # The monitor's own sampling of the link meshes (every vertex of each mesh subdivided to 10 mm, in
        # its link frame: what is checked here is where they are and how they move, not the sampling),
        # posed by MuJoCo.
        data.qpos[:] = joints(t)
        mujoco.mj_kinematics(model, data)
        out = []
        for i, local in monitor._robot_points:
            b = model.body(names[i]).id
            out.append(local @ data.xmat[b].reshape(3, 3).T + data.xpos[b] + base)
        return np.concatenate(out)

    times = np.array([0.5, 1.55, 2.4, 3.0, 3.6])  # walking in, crossing S_p, the swing to the place, the reach
    trace = rc.separation_trace(monitor, times)
    h = 1e-5
    for k, t in enumerate(times):
        p = points(t)
        v = (points(t + h) - points(t - h)) / (2 * h)
        d, c = _nearest_body_points(monitor, p, t)
        u = (c - p) / np.linalg.norm(c - p, axis=1)[:, None]
        v_r = float(np.maximum(np.einsum("ij,ij->i", v, u), 0.0).max())
        # The same points, two float64 kinematics chains (1e-15 m seen) and two closed forms: 1e-9 m.
        # Velocities: central differences of a C2 spline's poses over +-10 us, truncation h^2 / 6 x the
        # third derivative (<= 1e-10 m/s here) plus rounding 1e-16 m / h = 1e-11 m/s: 1e-7 m/s covers both.
        assert trace.true[k] == pytest.approx(d.min(), rel=0, abs=1e-9)
        assert trace.robot_speed[k] == pytest.approx(v_r, rel=0, abs=1e-7)
        # ISO/TS 15066 5.5.4.2.3, S_p = v_h (T_r + T_s) + v_r T_r + v_r T_s / 2 + C + Z_d + Z_r with the
        # figure's v_h 1.6 m/s, T_r 0.1 s, T_s 0.3 s, C 0.2 m, Z_d 0.05 m, Z_r 0.01 m.
        s_p = 1.6 * (0.1 + 0.3) + v_r * 0.1 + v_r * 0.3 / 2 + 0.2 + 0.05 + 0.01
        assert trace.protective[k] == pytest.approx(s_p, rel=0, abs=1e-7)
    # The figure's shading: the person crosses S_p between 1.5 and 1.55 s (docs/robots.md: 1.54 s, 0.90 m).
    assert trace.true[1] < trace.protective[1]
    # At 3.6 s the closest point recedes and a part of the forearm 10 cm from the hand approaches at
    # 0.37 m/s (docs/robots.md): S_p 0.99 m, 0.09 m above that of the closest point's speed.
    assert trace.robot_speed[4] == pytest.approx(0.37, rel=0, abs=0.01)


def test_micro_doppler_truth_is_the_thorax_range_rate_and_the_torso_line_sits_on_it(cell):
    scene, _ = cell
    radar = rc.build_arm_cell_sensors(radar_rate=20.0)[1]
    thorax = scene.object(f"{rc.PERSON}/thorax")
    eye = np.array(rc.RADAR_EYE)  # the radar on the wall, where the demo mounts it

    def rng_(t):
        return float(np.linalg.norm(thorax.pose_at(t).position - eye))

    # Every frame while the person walks with the thorax faster than half a Doppler bin (0.25-1.9 s): below
    # that, the zero bin (left out as the static clutter's) would be the nearest.
    times = np.arange(5, 39) * 0.05
    rng = np.random.default_rng(7)
    frames = [radar.capture(scene, float(t), rng) for t in times]
    t_md, vel, power, truth = rc.micro_doppler(frames, scene)
    np.testing.assert_array_equal(t_md, times)  # the time axis: the frames' own times
    # The velocity axis: lambda / (2 N T_rep) bins (lambda at the sampled ramp's centre, 57.375 GHz), fftshifted
    # (the zero bin at N / 2), positive away from the radar.
    ch = radar.config.chirp
    f_centre = ch.start_frequency + ch.slope * (ch.adc_start_time + ch.num_samples / (2 * ch.sample_rate))
    dv = C / f_centre / (2 * 64 * 1e-4)
    np.testing.assert_allclose(vel, (np.arange(64) - 32) * dv, rtol=1e-12, atol=0)
    # The overlay: the thorax's range rate by central differences of its distance from the radar, positive
    # while it walks away from the wall. Over +-h = 10 us: where the walk's acceleration is smooth the error
    # is h^2 / 6 x the jerk (< 1e-9 m/s); at a join where only the velocity is continuous (0.6 s, the start
    # ramp's end) a jump da in the acceleration costs up to da h / 2 (measured 3e-7 m/s there, da ~ 0.06
    # m/s^2); rounding 1e-16 m / h = 1e-11 m/s. 1e-5 m/s allows a 2 m/s^2 jump, 1/40,000 of a Doppler bin.
    h = 1e-5
    rate = np.array([(rng_(t + h) - rng_(t - h)) / (2 * h) for t in times])
    np.testing.assert_allclose(truth, rate, rtol=0, atol=1e-5)
    assert rate.min() > dv / 2
    # The torso line within one Doppler bin of the overlay in every frame (measured: at most 0.78 bins off;
    # the peak bin quantises by up to half a bin, and the trunk's reflecting surface sways about the thorax).
    line = rc.torso_line(vel, power)
    np.testing.assert_array_less(np.abs(line - truth), dv)
    assert math.isclose(float(np.median(line - truth)), 0.0, abs_tol=dv / 2)


@pytest.mark.parametrize("kwargs, message", [
    ({"fast": "no"}, r"fast = 'no'.*True or False"),
    ({"progress": 1}, r"progress = 1.*True or False"),
    ({"out_dir": None}, r"out_dir = None.*folder path"),
    ({"out_dir": "FILE"}, r"out_dir = '.*afile'.*this path is a file"),
])
def test_demo_names_a_bad_flag_or_output_folder_before_building_anything(tmp_path, kwargs, message):
    # fast="no" ran the coarse settings (a non-empty string is true); out_dir=None gave TypeError from pathlib
    # and a file as out_dir FileExistsError from mkdir, both after the cell was built.
    (tmp_path / "afile").write_text("keep")
    kw = {"out_dir": tmp_path / "out", "duration": 0.05, **kwargs}
    if kw["out_dir"] == "FILE":
        kw["out_dir"] = str(tmp_path / "afile")
    with pytest.raises(ConfigError, match=message):
        rc.run_robot_cell_demo(**kw)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]
    assert (tmp_path / "afile").read_text() == "keep"


def test_true_distance_against_trimesh_on_mujocos_own_meshes(cell):
    # Brute force at two times the other checks do not use (the arm swinging to the place, 2.4 s; the hand
    # coming in, 3.0 s): MuJoCo's own copy of the link meshes (mesh_vert, float32: 1e-7 m) posed by its
    # geom_xpos / geom_xmat, trimesh's exact point-to-triangle distance from points on the body segments
    # (2 mm apart). The monitor's distance is never below the truth and at most spacing / sqrt(3) = 5.8 mm
    # above it; the reference at most the sampling bound (1 mm on an axis, 1.4 mm on a box face) above it.
    import trimesh
    from scipy.spatial import cKDTree

    _, monitor = cell
    model = mujoco.MjModel.from_xml_path(str(Path(twinsense.__file__).parent / "data/robots/ur5e/ur5e.xml"))
    data = mujoco.MjData(model)
    joints = CubicSpline(rc.TIMES, np.array(rc.KEYFRAMES), bc_type="clamped")
    bound = monitor.spacing / math.sqrt(3.0)
    for t in (2.4, 3.0):
        got = monitor.at(t).distance
        data.qpos[:] = joints(t)
        mujoco.mj_kinematics(model, data)
        parts = []
        for g in range(model.ngeom):
            m = model.geom_dataid[g]
            if m < 0:
                continue
            v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
            f0, nf = model.mesh_faceadr[m], model.mesh_facenum[m]
            v = model.mesh_vert[v0:v0 + nv].astype(float) @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
            parts.append(trimesh.Trimesh(v + np.array([0.0, 0.0, 0.8]), model.mesh_face[f0:f0 + nf], process=False))
        robot = trimesh.util.concatenate(parts)
        # Only as a filter: every point of the mesh subdivided to 10 mm edges is within 5.8 mm of a vertex.
        fine = trimesh.remesh.subdivide_to_size(robot.vertices, robot.faces, max_edge=0.01, max_iter=30)[0]
        near = cKDTree(fine)
        # A body point whose mesh distance could reach the monitor's value lies within that plus 5.8 mm
        # of a vertex of the subdivided mesh.
        ref, err = person_to_mesh(monitor.person, t, robot, near, got + 1.01 * bound)
        assert -err - 1e-6 <= got - ref <= bound + 1e-6, (t, got, ref)  # measured 0 and -2.6 um


@pytest.mark.parametrize("params", [SeparationParameters(),
                                    SeparationParameters(stopping_distance=0.12, robot_acceleration=2.0,
                                                         human_uncertainty=0.08)])
def test_separation_figure_legend_gives_every_term_of_its_s_p_curve(tmp_path, monkeypatch, params):
    # A reader of separation.png recomputes the red curve from its legend by ISO/TS 15066 5.5.4.2.3:
    # S_p = v_h (T_r + T_s) + v_r T_r + a T_r^2 / 2 + S_s + C + Z_d + Z_r, S_s = (v_r + a T_r) T_s / 2 unless
    # given. The legend named v_h, T_r, T_s and C only: the reader's S_p came out Z_d + Z_r = 0.06 m under
    # the curve at every speed.
    speed = np.array([0.0, 0.25, 0.5, 1.2])
    trace = rc.SeparationTrace(np.arange(4) * 0.5, np.full(4, 1.0), speed,
                               np.asarray(protective_separation_distance(speed, params)))
    shown = {}
    save = rc.save_figure

    def keep(fig, path):
        (line,) = [ln for ln in fig.axes[0].get_lines() if ln.get_linestyle() == "--"]
        shown["label"], shown["y"] = line.get_label(), np.asarray(line.get_ydata())
        return save(fig, path)

    monkeypatch.setattr(rc, "save_figure", keep)
    rc._separation_figure(trace, [], [], [], SimpleNamespace(spacing=0.01), params, tmp_path / "s.png")
    terms = {k: float(v) for k, v in re.findall(r"\b(v_h|T_r|T_s|C|Z_d|Z_r|S_s|a) ([0-9.]+)", shown["label"])}
    assert {"v_h", "T_r", "T_s", "C", "Z_d", "Z_r"} <= set(terms)
    a = terms.get("a", 0.0)
    s_s = terms["S_s"] if "S_s" in terms else (speed + a * terms["T_r"]) * terms["T_s"] / 2
    by_hand = (terms["v_h"] * (terms["T_r"] + terms["T_s"]) + speed * terms["T_r"] + a * terms["T_r"] ** 2 / 2
               + s_s + terms["C"] + terms["Z_d"] + terms["Z_r"])
    # The legend prints the parameters as given (%g: these have at most 3 digits): float rounding only.
    np.testing.assert_allclose(shown["y"], by_hand, rtol=0, atol=1e-12)
