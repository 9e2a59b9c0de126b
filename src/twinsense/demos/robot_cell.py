"""The robot cells: the UR5e pick-and-place cell of ``examples/robot_cell.yaml`` and the simple cylinder cell.

``build_arm_cell`` builds the robot-cell demo's scene and sensors in Python
(a pip install has no ``examples/``); ``tests/demos/test_robot_cell.py``
checks that ``examples/robot_cell.yaml`` describes the same cell. A UR5e
(robosuite's MJCF with its collision meshes, 7,558 triangles, shipped with
twinsense as ``load_robot("ur5e")``; robosuite's visual meshes have 121,783)
picks a part from a table and places it; a person
walks up to the cell from the side and reaches towards the robot. A ToF
camera and a radar on the side wall, a ToF camera on the wrist flange and a
capacitive proximity skin on the forearm: the ``pad-grid`` preset, a flat
12 x 9 cm patch on the forearm (the tactile skin presets are flat patches
too; on the forearm's round tube it leaves up to 46 mm of air under its long
edges).

``build_cylinder_cell_scene`` is the simple cell of ``examples/cylinder_cell.yaml``
(a cylinder link, a capsule person), which the LiDAR and ultrasonic demos use.

``run_robot_cell_demo`` (``twinsense demo robot-cell``) writes the depth
frames of both ToF cameras, the radar's micro-Doppler spectrogram with the
torso's true radial speed, the separation plot (true human-robot minimum
distance against what the radar, the wall ToF camera and the skin see, with
ISO/TS 15066's protective separation distance for the robot's speed) and an
HDF5 recording of every sensor.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from os import PathLike
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.plotting import pyplot, save_figure
from twinsense.presets import make_sensor
from twinsense.robots import load_mjcf, load_robot
from twinsense.robots.paths import robosuite_robots_dir
from twinsense.safety import SeparationMonitor, SeparationParameters, point_box_distance, protective_separation_distance
from twinsense.scene import Box, Capsule, Cylinder, JointKeyframes, Mount, Oscillation, Plane, Pose, Scene, Waypoints
from twinsense.scene.human import Reach, Walk, add_person
from twinsense.simulate import check_processes, fork_available, simulate

#: Sensor kinds that see the cylinder cell's robot link: every kind but the capacitive skin riding on it.
LINK_LAYERS = ("tof", "radar", "camera", "lidar", "ultrasonic")

#: The pick-and-place cycle [s] and joint values [rad] (shoulder pan, shoulder lift, elbow, wrist 1-3); from
#: UR's home, the flange points straight down (lift + elbow + wrist 1 = -1.57, wrist 2 = -1.57, wrist 3 =
#: pan), 1.05 m above the floor over the part and the place, 0.885 m at them
#: (tests/demos/test_robot_cell.py). Far inside the UR5e's +-2 pi (elbow +-pi) limits.
TIMES = (0.0, 0.8, 1.3, 1.8, 2.8, 3.3, 3.8, 4.6)
HOME = (0.0, -1.57, 1.57, -1.57, -1.57, 0.0)
ABOVE_PICK = (0.159, -1.158, 1.706, -2.118, -1.57, 0.159)
PICK = (0.16, -0.865, 1.75, -2.455, -1.57, 0.16)
ABOVE_PLACE = (-0.841, -1.158, 1.706, -2.118, -1.57, -0.841)
PLACE = (-0.84, -0.865, 1.75, -2.455, -1.57, -0.84)
KEYFRAMES = (HOME, ABOVE_PICK, PICK, ABOVE_PICK, ABOVE_PLACE, PLACE, ABOVE_PLACE, HOME)
CYCLE = TIMES[-1]

ROBOT = "ur5e"
PERSON = "person"
WRIST_LINK = "tool0"
FOREARM_LINK = "forearm_link"
#: Wall sensor positions [m] (on the side wall, y = -3 m) and what they look at.
WALL_TOF_EYE, WALL_TOF_TARGET = (0.3, -2.95, 2.0), (0.5, 0.0, 0.9)
RADAR_EYE, RADAR_TARGET = (1.0, -2.95, 1.2), (1.1, 0.0, 1.0)
#: The radar's waveform for micro-Doppler: 64 chirps at 100 us (10 kHz slow time: +-13.1 m/s at the chirp's
#: 57.4 GHz centre, above the feet's ~5 m/s; 0.41 m/s Doppler bins), 64 samples; 96 x 48 rays.
RADAR_OVERRIDES = {"num_samples": 64, "num_chirps": 64, "chirp_repetition_time": 1.0e-4,
                   "ramp_end_time": 4.0e-5, "render_width": 96, "render_height": 48}
#: The skin: flat, 20 cm along the forearm, its normal along the link's -y (the elbow axis), its electrode face
#: 56 mm from the forearm's axis: the forearm's collision mesh comes to 53.6 mm under the 12 x 9 cm patch, so
#: 0.8 mm of air under the 1.6 mm board where it comes closest.
SKIN_POSE = Pose.from_euler_deg((0.0, -0.056, 0.2), (90, -90, 0))
#: The left hand's reach target [m]: the hand box's centre (what the arm's IK places; the 19 cm hand reaches
#: 9.5 cm beyond it), 9.5 cm out along the skin's normal from the patch at the place pose (3.3 s). The hand
#: holds there (3.3-3.8 s) while the arm lifts the skin past it: closest 16.0 mm from the patch at 3.58 s,
#: within 30 mm from 3.27 to 3.74 s, never inside the skin or a link (tests/demos/test_robot_cell.py).
REACH_TARGET = (0.161, -0.396, 1.132)


def build_cylinder_cell_scene() -> Scene:
    """The simple cylinder cell of ``examples/cylinder_cell.yaml`` (world frame, z up, sizes in metres)."""
    s = Scene(name="cylinder_cell")
    s.add_object("floor", Plane((6.0, 6.0)), "concrete")
    s.add_object("back_wall", Plane((6.0, 3.0)), "drywall",
                 pose=Pose.from_euler_deg((3.0, 0.0, 1.5), (0, -90, 0)))
    s.add_object("table", Box((0.8, 1.2, 0.75)), "wood", pose=Pose((1.8, 0.0, 0.375)))
    s.add_object("robot_link", Cylinder(0.06, 0.5), "aluminium",
                 motion=Oscillation(Pose.from_euler_deg((1.6, 0.3, 1.0), (0, 90, 0)),
                                    amplitude=(0.0, 0.25, 0.0), frequency=0.5),
                 layers=LINK_LAYERS)
    s.add_object("person", Capsule(0.2, 1.3), "human_skin",
                 motion=Waypoints([[1.2, -1.5, 0.9], [1.2, 1.5, 0.9]], speed=1.2, mode="back_and_forth"))
    s.add_object("corner_reflector", Box((0.08, 0.08, 0.08)), "corner_reflector", pose=Pose((2.5, -0.5, 0.79)))
    return s


#: The cell's static boxes (name, size, centre) [m]: what an SSM system knows of its cell.
STATIC_BOXES = (("pedestal", (0.3, 0.3, 0.8), (0.0, 0.0, 0.4)),
                ("table", (0.6, 1.0, 0.75), (0.6, 0.0, 0.375)),
                ("part", (0.12, 0.08, 0.05), (0.58, 0.23, 0.775)))


def arm(shapes: str = "collision"):
    """The cell's UR5e running the pick-and-place cycle on its pedestal (``shapes``: "collision", the
    shipped model's meshes; "visual", robosuite's display meshes on the same kinematics, its flange body
    ``right_hand`` named ``tool0`` as in the shipped model: robosuite must be installed)."""
    V.choice("shapes", shapes, ("collision", "visual"))
    kw = {"name": ROBOT, "joints": JointKeyframes(TIMES, KEYFRAMES), "base": Pose((0.0, 0.0, 0.8))}
    if shapes == "collision":
        return load_robot("ur5e", **kw)
    import mujoco  # the robots extra, which load_robot("ur5e") needs too

    spec = mujoco.MjSpec.from_file(str(robosuite_robots_dir() / "ur5e" / "robot.xml"))
    spec.body("right_hand").name = "tool0"
    return load_mjcf(spec.compile(), geoms="visual", **kw)


def build_arm_cell_scene(person: bool = True, shapes: str = "collision") -> Scene:
    """The UR5e cell of ``examples/robot_cell.yaml``: floor, walls, pedestal, table, part, UR5e, person
    (``person=False``: the cell without the person; ``shapes="visual"``: the UR5e's visual meshes, from
    robosuite's model, which must be installed: the same kinematics and link names)."""
    s = Scene(name="robot_cell")
    s.add_object("floor", Plane((6.0, 6.0)), "concrete")
    s.add_object("back_wall", Plane((6.0, 3.0)), "drywall", pose=Pose.from_euler_deg((2.5, 0.0, 1.5), (0, -90, 0)))
    s.add_object("side_wall", Plane((6.0, 3.0)), "drywall", pose=Pose.from_euler_deg((0.0, -3.0, 1.5), (-90, 0, 0)))
    materials = {"pedestal": "mild_steel", "table": "wood", "part": "plastic"}
    for name, size, centre in STATIC_BOXES:
        s.add_object(name, Box(size), materials[name], pose=Pose(centre))
    s.add_articulated(arm(shapes))
    if person:
        # Facing its path (atan2(1.6, -0.7) = 113.6 deg): a start that also turns the body slides the
        # standing foot (1.17 m/s peak for this 114 deg turn, docs/people.md).
        add_person(s, PERSON, 1.75, (1.3, -2.4), 113.6, walk=Walk(1.2, path=((0.6, -0.8),), body="smooth"),
                   reach=Reach(REACH_TARGET, 2.6, 0.7, 0.5, "left"))
    return s


def build_arm_cell_sensors(tof_rate: float = 10.0, radar_rate: float = 10.0, skin_rate: float = 20.0,
                           fast: bool = False) -> list:
    """The cell's sensors (``examples/robot_cell.yaml`` at the default rates [Hz]).

    ``fast``: one ray per ToF pixel (no 2 x 2 supersampling) and a coarse skin
    mesh (4 mm at the electrodes, 20 mm cells, no refinement around objects):
    for quick runs, not for figures."""
    tof_kw = {"supersample": 1} if fast else {}
    skin = make_sensor("capacitive", "pad-grid", name="skin", frame_rate=skin_rate,
                       mount=Mount(SKIN_POSE, parent=f"{ROBOT}/{FOREARM_LINK}"))
    if fast:
        skin = make_sensor("capacitive", "pad-grid", name="skin", frame_rate=skin_rate, mount=skin.mount,
                           mesh=replace(skin.config.mesh, h_min=4e-3, h_max=0.02, object_cells=0.0))
    return [
        make_sensor("tof", "pmd_pico_flexx", name="wall_tof", mode="MODE_9_25FPS_450", frame_rate=tof_rate,
                    mount=Mount(Pose.look_at(WALL_TOF_EYE, WALL_TOF_TARGET)), **tof_kw),
        make_sensor("radar", "paper_bgt60tr13c", name="radar", frame_rate=radar_rate,
                    mount=Mount(Pose.look_at(RADAR_EYE, RADAR_TARGET)), **RADAR_OVERRIDES),
        make_sensor("tof", "pmd_pico_flexx", name="wrist_tof", frame_rate=tof_rate,
                    mount=Mount(Pose((0.0, 0.0, 0.02)), parent=f"{ROBOT}/{WRIST_LINK}"), **tof_kw),
        skin,
    ]


def build_arm_cell(**rates) -> tuple[Scene, list]:
    """(scene, sensors) of the robot-cell demo; ``rates``: see :func:`build_arm_cell_sensors`."""
    return build_arm_cell_scene(), build_arm_cell_sensors(**rates)


def torso_radial_velocity(scene: Scene, radar_position, t: float) -> float:
    """The person's thorax radial velocity [m/s] seen from ``radar_position`` (3,) (> 0 moving away)."""
    st = scene.object(f"{PERSON}/thorax").state_at(t)
    los = st.pose.position - np.asarray(radar_position, dtype=float)
    return float(st.linear_velocity @ los / np.linalg.norm(los))


def micro_doppler(frames, scene: Scene, gate: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(times (n,) [s], velocity axis (m,) [m/s], power (n, m) over the person's range bins, truth (n,) [m/s]).

    Each processed frame's range-Doppler power summed over the range bins within
    ``gate`` [m] of the thorax's true range (the robot and the table move or sit
    at other ranges); the truth is the thorax's radial velocity.
    """
    times, rows, truth = [], [], []
    vel = None
    for f in frames:
        pr = f.processed
        if pr is None:
            raise ConfigError("radar.process", False, "a radar that processes its frames (range-Doppler maps)")
        radar_pos = f.pose.position
        r_torso = np.linalg.norm(scene.object(f"{PERSON}/thorax").pose_at(f.t).position - radar_pos)
        sel = np.abs(pr.range_axis - r_torso) <= gate
        rows.append(pr.power[:, sel].sum(axis=1))
        vel = pr.velocity_axis
        times.append(f.t)
        truth.append(torso_radial_velocity(scene, radar_pos, f.t))
    return np.array(times), np.asarray(vel), np.array(rows), np.array(truth)


def torso_line(velocity_axis, power) -> np.ndarray:
    """The strongest moving line per frame [m/s]: the peak Doppler bin, the zero bin left out (static clutter)."""
    p = np.array(power, dtype=float)
    p[:, np.argmin(np.abs(velocity_axis))] = 0.0
    return np.asarray(velocity_axis)[np.argmax(p, axis=1)]


@dataclass(frozen=True)
class SeparationTrace:
    """Per time ``times`` (n,) [s]: the true separation ``true`` (n,) [m], the robot's speed towards the
    person ``robot_speed`` (n,) [m/s] (its fastest approaching surface point: ISO/TS 15066's v_r) and the
    protective separation distance S_p for it, ``protective`` (n,) [m]."""

    times: np.ndarray
    true: np.ndarray
    robot_speed: np.ndarray
    protective: np.ndarray


def separation_trace(monitor: SeparationMonitor, times, params: SeparationParameters = SeparationParameters()
                     ) -> SeparationTrace:
    """The true separation and S_p at ``times`` (n,) [s].

    v_r is the fastest approach of any robot surface point towards the person
    (``SeparationSample.approach_speed``), not the closest point's: while the
    hand holds by the forearm (3.6 s) the closest point moves away and a part
    of the forearm 10 cm from the hand approaches at 0.37 m/s, which S_p must
    cover (+0.09 m)."""
    samples = [monitor.at(float(t)) for t in times]
    speed = np.array([s.approach_speed for s in samples])
    return SeparationTrace(np.asarray(times, dtype=float), np.array([s.distance for s in samples]), speed,
                           np.asarray(protective_separation_distance(speed, params)))


def _robot_distance(monitor: SeparationMonitor, points, t: float, exclude) -> float:
    """Smallest distance [m] from ``points`` (n, 3) to the robot surface at t, ignoring points within
    ``exclude`` [m] (scalar or (n,)) of it (the robot's own returns: the robot knows where it is)."""
    if len(points) == 0:
        return np.nan
    d, _ = cKDTree(monitor.robot_points(t)[0]).query(points)
    d = d[d > exclude]
    return float(d.min()) if len(d) else np.nan


def _static_mask(points, margin=0.04) -> np.ndarray:
    """Points on the cell's known static surfaces: floor, walls and the boxes (within ``margin`` [m],
    scalar or per point (n,))."""
    p = np.asarray(points)
    on = (p[:, 2] < margin) | (p[:, 0] > 2.5 - margin) | (p[:, 1] < -3.0 + margin)
    for _, size, centre in STATIC_BOXES:
        on |= point_box_distance(p - np.asarray(centre), size) < margin
    return on


#: A ToF point with fewer than this many other points within ISOLATED_RADIUS is a stray return.
ISOLATED_NEIGHBOURS = 2
ISOLATED_RADIUS = 0.05  # [m]


def tof_separation(monitor, frame, margin: float = 0.03) -> float:
    """The wall ToF's separation [m]: its valid points off the static cell and off the robot, nearest the robot.

    A point within ``margin`` + 3 x its own depth noise [m] of the robot is the robot's (at 3 m the
    pico flexx's depth noise reaches several centimetres). A point with fewer than ISOLATED_NEIGHBOURS
    others within ISOLATED_RADIUS is a stray return and left out: a surface 3 m away puts ~35 pixels in
    such a ball, while the noisy floor and wall pixels that pass the static margins and the mixed pixels
    of silhouettes are single (before the person is in view they read 0.7-1.2 m against a true 2.0-2.3 m)."""
    ok = frame.valid & np.isfinite(frame.points_world).all(axis=-1)
    pts, noise = frame.points_world[ok], frame.noise[ok]
    keep = ~_static_mask(pts, 0.04 + 3.0 * noise)
    pts, noise = pts[keep], noise[keep]
    if len(pts):
        others = cKDTree(pts).query_ball_point(pts, ISOLATED_RADIUS, return_length=True) - 1
        pts, noise = pts[others >= ISOLATED_NEIGHBOURS], noise[others >= ISOLATED_NEIGHBOURS]
    return _robot_distance(monitor, pts, frame.t, margin + 3.0 * noise)


def radar_separation(monitor, frame, min_speed: float, exclude: float = 0.15) -> float:
    """The radar's separation [m]: moving detections (|v| >= ``min_speed``) off the robot, nearest the robot."""
    det = frame.detections
    if det is None or det.points_world is None:
        return np.nan
    moving = np.abs(det.velocity) >= min_speed
    return _robot_distance(monitor, det.points_world[moving], frame.t, exclude)


def run_robot_cell_demo(out_dir, duration: float = CYCLE, progress: bool = False, *, tof_rate: float = 10.0,
                        radar_rate: float = 20.0, skin_rate: float = 5.0, seed: int = 1, fast: bool = False,
                        params: SeparationParameters = SeparationParameters(),
                        processes: int | None = None) -> dict[str, Path]:
    """Run the UR5e cell for ``duration`` [s] and write its pictures and recording into ``out_dir``.

    Writes ``depth_wall.png`` and ``depth_wrist.png`` (three depth frames
    each), ``micro_doppler.png`` (radar spectrogram, time vs radial velocity,
    with the thorax's true radial speed), ``separation.png`` and
    ``robot_cell.h5`` (every sensor's frames). ``fast``: see :func:`build_arm_cell_sensors`.
    ``processes``: capture processes of ``simulate`` (default 2 where processes can be forked, else 1;
    the same outputs either way).
    """
    # Every argument checked, and the cell built, before the output folder or any file is written.
    if not isinstance(out_dir, (str, PathLike)):
        raise ConfigError("out_dir", out_dir, "a folder path (str or os.PathLike)")
    if Path(out_dir).exists() and not Path(out_dir).is_dir():
        raise ConfigError("out_dir", str(out_dir), "a folder to write into (this path is a file)")
    for name, flag in (("fast", fast), ("progress", progress)):
        # Not truthiness: fast="no" would otherwise run the coarse settings.
        if not isinstance(flag, (bool, np.bool_)):
            raise ConfigError(name, flag, "True or False")
    V.positive("duration", duration, "s")
    for name, rate in (("tof_rate", tof_rate), ("radar_rate", radar_rate), ("skin_rate", skin_rate)):
        V.positive(name, rate, "Hz")
    V.integer("seed", seed, lo=0)
    if not isinstance(params, SeparationParameters):
        raise ConfigError("params", params, "a twinsense.safety.SeparationParameters")
    if processes is not None:
        check_processes(processes)
    scene, sensors = build_arm_cell(tof_rate=tof_rate, radar_rate=radar_rate, skin_rate=skin_rate, fast=fast)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if processes is None:
        # The cell's lanes in 2 processes: 0.86 s per scene second from 0.9 s on 2 idle cores, against 1.03-1.15
        # one after another (bench_robot_cell.py, docs/simulate.md).
        processes = 2 if fork_available() else 1
    res = simulate(scene, sensors, duration, out=out / "robot_cell.h5", seed=seed, progress=progress,
                   keep_frames=True, processes=processes)
    frames = res.frames
    written = {"recording": res.path}
    for cam in ("wall_tof", "wrist_tof"):
        written[f"depth_{cam.split('_')[0]}_png"] = _depth_figure(frames[cam], out / f"depth_{cam.split('_')[0]}.png",
                                                                  cam)
    t_md, vel, power, truth = micro_doppler(frames["radar"], scene)
    written["micro_doppler_png"] = _doppler_figure(t_md, vel, power, truth, out / "micro_doppler.png")

    monitor = SeparationMonitor(scene, ROBOT, PERSON)
    trace = separation_trace(monitor, np.arange(0.0, duration, 0.05), params)
    cell = np.diff(vel[:2])[0] if len(vel) > 1 else 0.1
    tof = [(f.t, tof_separation(monitor, f)) for f in frames["wall_tof"]]
    radar = [(f.t, radar_separation(monitor, f, min_speed=cell)) for f in frames["radar"]]
    skin = _skin_triggers(sensors[3], frames["skin"], seed)
    written["separation_png"] = _separation_figure(trace, tof, radar, skin, monitor, params,
                                                   out / "separation.png")
    return written


def _skin_triggers(skin, frames, seed: int) -> list[tuple[float, float, float]]:
    """(t, the person's share of the largest channel change [F], threshold [F]) per skin frame.

    The person's share is the measured reading minus the same skin's true
    channels in the cell without the person at that time (the robot's own
    arm and the table change the baseline as the arm moves); the threshold is
    five times the converter noise at the skin's frame rate.
    """
    twin = build_arm_cell_scene(person=False)
    ro = skin.config.readout
    thr = 5.0 * ro.noise_rms * np.sqrt(skin.frame_rate / ro.noise_rate)
    rng = np.random.default_rng(seed)
    out = []
    for f in frames:
        empty = skin.capture(twin, f.t, rng)
        out.append((f.t, float(np.max(np.abs(f.readout - empty.channels))), thr))
    return out


def _depth_figure(frames, path: Path, title: str) -> Path:
    plt = pyplot()
    pick = [frames[i] for i in sorted({0, len(frames) // 2, len(frames) - 1})]
    fig, axes = plt.subplots(1, len(pick), figsize=(4.2 * len(pick), 3.4), squeeze=False)
    depths = [np.where(f.valid, f.depth, np.nan) for f in pick]
    valid = np.concatenate([d[np.isfinite(d)] for d in depths])
    top = float(np.percentile(valid, 99)) if len(valid) else 1.0  # one colour scale for all frames
    for ax, f, d in zip(axes[0], pick, depths):
        im = ax.imshow(d, cmap="turbo", vmin=0.0, vmax=top)
        ax.set_title(f"{title}, t = {f.t:.2f} s", fontsize=9)
        ax.set_axis_off()
        fig.colorbar(im, ax=ax, label="depth [m]", fraction=0.04)
    return save_figure(fig, path)


def _doppler_figure(t, vel, power, truth, path: Path) -> Path:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8.0, 4.2))
    db = 10 * np.log10(np.maximum(power, power.max() * 1e-9) / power.max())
    dt = np.diff(t).mean() if len(t) > 1 else 0.05
    dv = np.diff(vel).mean() if len(vel) > 1 else 0.1
    # The image's edges are the bins' edges, half a bin beyond the first and last centres on both axes (from
    # centre to centre, each Doppler row was drawn 63/64 of a bin high: up to half a bin off at the ends).
    im = ax.imshow(db.T, origin="lower", aspect="auto", cmap="magma", vmin=-40, vmax=0,
                   extent=(t[0] - dt / 2, t[-1] + dt / 2, vel[0] - dv / 2, vel[-1] + dv / 2))
    fig.colorbar(im, ax=ax, label="power [dB re the strongest bin]", fraction=0.04)
    ax.plot(t, truth, "c-", lw=1.5, label="thorax radial speed (truth)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("radial velocity [m/s] (> 0 away)")
    ax.set_ylim(-6, 6)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("wall radar micro-Doppler: range-Doppler power over the person's range bins [dB]", fontsize=9)
    return save_figure(fig, path)


def _protective_label(params: SeparationParameters) -> str:
    """The S_p curve's legend: every term the curve adds up (Z_d and Z_r too: without them a reader's S_p
    from the legend came out 0.06 m under the curve), S_s and the acceleration when they are set."""
    terms = (f"v_h {params.human_speed:g} m/s, T_r {params.reaction_time:g} s, T_s {params.stopping_time:g} s,\n"
             f"C {params.intrusion_distance:g} m, Z_d {params.human_uncertainty:g} m, "
             f"Z_r {params.robot_uncertainty:g} m")
    if params.stopping_distance is not None:
        terms += f", S_s {params.stopping_distance:g} m"
    if params.robot_acceleration:
        terms += f", a {params.robot_acceleration:g} m/s^2"
    return f"ISO/TS 15066 S_p (v_r: fastest robot point towards the person; {terms})"


def _separation_figure(trace: SeparationTrace, tof, radar, skin, monitor, params, path: Path) -> Path:
    plt = pyplot()
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(8.0, 6.4), sharex=True, height_ratios=(3, 1))
    ax.plot(trace.times, trace.true, "k-", lw=2, label="true minimum distance (robot surface to body)")
    ax.plot(trace.times, trace.protective, "r--", lw=1.5, label=_protective_label(params))
    stop = trace.true < trace.protective
    ax.fill_between(trace.times, 0, 1, where=stop, color="r", alpha=0.1, transform=ax.get_xaxis_transform(),
                    label="protective stop required")
    if tof:
        ax.plot(*np.array(tof).T, "o", ms=4, color="tab:blue", label="wall ToF: nearest person point")
    if radar:
        ax.plot(*np.array(radar).T, "s", ms=3, color="tab:green", label="radar: nearest moving detection")
    ax.set_ylabel("separation [m]")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title(f"human-robot separation (true: link meshes within {monitor.spacing / np.sqrt(3) * 1e3:.0f} mm "
                 "vs exact body capsules and boxes)", fontsize=9)
    if skin:
        ts, dc, thr = np.array(skin).T
        ax2.semilogy(ts, np.maximum(dc, 1e-18) * 1e15, "o-", color="tab:purple", ms=3,
                     label="skin: person's largest channel change")
        ax2.axhline(thr[0] * 1e15, color="tab:purple", ls=":", label="proximity threshold (5 x noise)")
        ax2.legend(fontsize=7)
    ax2.set_ylabel("|dC| [fF]")
    ax2.set_xlabel("time [s]")
    return save_figure(fig, path)
