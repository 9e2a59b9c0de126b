"""A Velodyne VLP-16 over the cylinder cell: point cloud pictures with the walking person's true position."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from twinsense.demos.robot_cell import build_cylinder_cell_scene
from twinsense.errors import ConfigError
from twinsense.lidar import Lidar
from twinsense.plotting import pyplot, save_figure
from twinsense.scenario import load_scenario
from twinsense.scene import Mount, Pose
from twinsense.simulate import simulate

#: The LiDAR sits behind the cell's near edge, 1.6 m up, tilted 12 deg down towards the back wall.
EYE = (-0.8, 0.0, 1.6)
TARGET = (2.0, 0.0, 1.6 - 2.8 * np.tan(np.deg2rad(12.0)))


def run_lidar_demo(out_dir, duration: float = 0.3, progress: bool = False, scenario=None) -> dict[str, Path]:
    """Simulate the VLP-16 for ``duration`` [s] (10 revolutions per second) in the cylinder cell.

    Writes ``lidar_top.png`` (top view of the last revolution's points, world
    frame, coloured by intensity, with the person's true position),
    ``lidar_range_image.png`` (ring x azimuth image of intensity and range)
    and ``lidar_recording.h5``. ``scenario``: another scenario file with a
    ``person`` object (default: the cylinder cell of examples/cylinder_cell.yaml,
    built by :func:`twinsense.demos.robot_cell.build_cylinder_cell_scene`).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if scenario is None:
        scene = build_cylinder_cell_scene()
    else:
        path = Path(scenario)
        if not path.is_file():
            raise ConfigError("scenario", str(path), "an existing scenario file with a 'person' object")
        scene = load_scenario(path).scene
    lidar = Lidar.preset("velodyne_vlp16", name="vlp16", mount=Mount(Pose.look_at(EYE, TARGET)))
    res = simulate(scene, [lidar], duration, out=out / "lidar_recording.h5", progress=progress, keep_frames=True)
    frame = res.frames["vlp16"][-1]
    person = scene.object("person")
    t_mid = 0.5 * (frame.time[0] + frame.time[-1])
    p_true = person.pose_at(float(t_mid)).position
    top = _top_view(frame, p_true, scene.index("person"), out / "lidar_top.png")
    image = _range_image(frame, lidar, out / "lidar_range_image.png")
    return {"top_png": top, "range_image_png": image, "recording": res.path}


def _top_view(frame, p_true, person_id: int, path: Path) -> Path:
    plt = pyplot()
    pc = frame.point_cloud(world=True)
    fig, ax = plt.subplots(figsize=(6.4, 6.0))
    sc = ax.scatter(pc["x"], pc["y"], c=pc["intensity"], s=1.5, cmap="viridis", vmin=0, vmax=100)
    fig.colorbar(sc, ax=ax, label="intensity (calibrated reflectivity, 0-100 diffuse)")
    on_person = pc["object_id"] == person_id
    ax.scatter(pc["x"][on_person], pc["y"][on_person], s=3, c="tab:red", label="echoes on the person")
    ax.add_patch(plt.Circle((p_true[0], p_true[1]), 0.2, fill=False, color="k", lw=1.5,
                            label="person, true position"))
    ax.plot(*EYE[:2], marker="^", color="k", ls="none", label="VLP-16")
    ax.set_aspect("equal")
    ax.set_xlim(-3.2, 3.2)
    ax.set_ylim(-3.2, 3.2)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title(f"cylinder cell, VLP-16 revolution at t = {frame.t:.2f} s: {frame.n_points} points")
    return save_figure(fig, path)


def _range_image(frame, lidar: Lidar, path: Path) -> Path:
    plt = pyplot()
    scan = lidar.config.scan
    shape = (scan.columns, scan.beams)
    inten = np.where(frame.valid[:, 0], frame.intensity[:, 0].astype(float), np.nan).reshape(shape).T[::-1]
    rng = frame.range[:, 0].reshape(shape).T[::-1]
    fig, axes = plt.subplots(2, 1, figsize=(9.0, 4.8), sharex=True)
    extent = (0.0, 360.0, scan.elevations_deg[0] - 1, scan.elevations_deg[-1] + 1)
    im0 = axes[0].imshow(inten, aspect="auto", cmap="viridis", vmin=0, vmax=100, extent=extent, interpolation="nearest")
    fig.colorbar(im0, ax=axes[0], label="intensity")
    im1 = axes[1].imshow(rng, aspect="auto", cmap="magma", extent=extent, interpolation="nearest")
    fig.colorbar(im1, ax=axes[1], label="range [m]")
    for ax in axes:
        ax.set_ylabel("elevation [deg]")
    axes[1].set_xlabel("column azimuth [deg] (0 = forward, positive right)")
    axes[0].set_title("VLP-16 range image (ring x column), last revolution")
    return save_figure(fig, path)
