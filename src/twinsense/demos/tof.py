"""The seed paper's office experiment (Fig. 2-3) with the simulated pico flexx.

Desks, a chair, walls, a monitor, a walking person and a strong infrared
retro-reflector on the back wall. In the output the reflector saturates
(depth 0), cross-talk spreads a cloud of wrong depths around it, and flying
pixels appear at object edges (they are kept here, as in the paper's figure;
the Royale filter would remove them).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from twinsense.plotting import pyplot, save_figure
from twinsense.tof.camera import ToFCamera
from twinsense.tof.frame import InvalidReason, ToFFrame


def office_camera(preset: str = "paper_pico_flexx", **overrides) -> ToFCamera:
    """The demo camera at the office sensor pose; flying and noisy pixels kept, as in the paper."""
    from twinsense.demos.office import sensor_pose

    overrides.setdefault("flying_pixel_filter", False)
    overrides.setdefault("noise_filter", False)
    return ToFCamera.preset(preset, mount=sensor_pose(), name="tof", **overrides)


def run_tof_office_demo(out_dir, duration: float = 0.5, preset: str = "paper_pico_flexx",
                        progress: bool = False, recording: bool = True, **overrides) -> dict[str, Path]:
    """Simulate the office for ``duration`` [s]; write PNGs of the last frame and the recording.

    Parameters
    ----------
    out_dir : path-like
        Created if needed.
    duration : float
        Simulated time [s] at the camera's frame rate.
    preset : str
        ToF preset (``paper_pico_flexx`` as in the paper, or ``pmd_pico_flexx``).
    recording : bool
        Also write ``tof_office.h5`` (every frame's streams).
    overrides
        Config fields of the camera (e.g. ``width``/``height`` for a quick run).

    Returns
    -------
    dict of written files: depth_png, amplitude_png, confidence_png, pointcloud_png
    (and recording).
    """
    from twinsense.demos.office import build_office_scene
    from twinsense.simulate import simulate

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene = build_office_scene()
    cam = office_camera(preset, **overrides)
    path = out / "tof_office.h5" if recording else None
    res = simulate(scene, [cam], duration, out=path, progress=progress, keep_frames=True, seed=0)
    frame: ToFFrame = res.frames[cam.name][-1]
    files = write_tof_figures(frame, out, label="ToF office")
    if path is not None:
        files["recording"] = Path(res.path)
    return files


def write_tof_figures(frame: ToFFrame, out_dir, label: str = "ToF", prefix: str = "tof") -> dict[str, Path]:
    """Depth, amplitude and confidence images and a 3-D point-cloud picture of one frame.

    Returns {depth_png, amplitude_png, confidence_png, pointcloud_png}; files are
    ``<prefix>_depth.png`` etc. under ``out_dir``.
    """
    out = Path(out_dir)
    return {
        "depth_png": _image(frame, np.where(frame.valid, frame.depth, np.nan), "z-depth [m]", "viridis",
                            out / f"{prefix}_depth.png", f"{label}, depth (invalid pixels blank)"),
        "amplitude_png": _image(frame, frame.amplitude, "amplitude [DN]", "gray", out / f"{prefix}_amplitude.png",
                                f"{label}, amplitude", log=True),
        "confidence_png": _image(frame, frame.confidence.astype(float), "confidence 0..255", "magma",
                                 out / f"{prefix}_confidence.png", f"{label}, depth confidence"),
        "pointcloud_png": _point_cloud(frame, out / f"{prefix}_pointcloud.png", f"{label}, point cloud (world frame)"),
    }


def _image(frame: ToFFrame, img: np.ndarray, label: str, cmap: str, path: Path, title: str,
           log: bool = False) -> Path:
    from matplotlib.colors import LogNorm

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 5.0))
    norm = LogNorm(vmin=max(np.nanmin(img[img > 0]), 1e-3), vmax=np.nanmax(img)) if log else None
    im = ax.imshow(img, cmap=cmap, norm=norm)
    fig.colorbar(im, ax=ax, label=label)
    sat = frame.mask(InvalidReason.SATURATED)
    if sat.any():
        ys, xs = np.nonzero(sat)
        ax.scatter(xs, ys, s=2, c="red", marker="s", label="saturated (depth 0)")
        ax.legend(loc="lower right", fontsize=8)
    ax.set_title(f"{title}, t = {frame.t:.2f} s")
    ax.set_xlabel("column [px]")
    ax.set_ylabel("row [px]")
    return save_figure(fig, path)


def _point_cloud(frame: ToFFrame, path: Path, title: str) -> Path:
    plt = pyplot()
    pts = frame.point_cloud("world")
    step = max(1, len(pts) // 20_000)
    pts = pts[::step]
    fig = plt.figure(figsize=(7.0, 5.6))
    ax = fig.add_subplot(projection="3d")
    ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], c=pts[:, 0], s=0.5, cmap="viridis")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.view_init(elev=20, azim=-150)
    ax.set_title(title)
    return save_figure(fig, path)
