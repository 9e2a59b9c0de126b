"""Ground-truth depth of the office scene from an ideal pinhole camera."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from twinsense.demos.office import build_office_scene, sensor_pose
from twinsense.depthcam import DepthCamera, DepthCameraConfig
from twinsense.plotting import pyplot, save_figure
from twinsense.render import PinholeCamera
from twinsense.scene import Mount
from twinsense.simulate import simulate


def run_depth_demo(out_dir, duration: float = 1.0, progress: bool = False) -> dict[str, Path]:
    """Render the office's depth over ``duration`` [s] at 10 fps; write a PNG and a recording."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene = build_office_scene()
    cam = DepthCamera("depth_camera", DepthCameraConfig(PinholeCamera.from_fov(320, 240, 72.0), frame_rate=10.0),
                      Mount(sensor_pose()))
    res = simulate(scene, [cam], duration, out=out / "depth_recording.h5", progress=progress, keep_frames=True)
    frame = res.frames["depth_camera"][-1]
    png = depth_figure(frame, out / "depth.png", "office, ideal depth camera")
    return {"depth_png": png, "recording": res.path}


def depth_figure(frame, path: Path, title: str) -> Path:
    """PNG of a DepthFrame's z-depth (blank where nothing was hit)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 5.0))
    im = ax.imshow(np.where(frame.depth > 0, frame.depth, np.nan), cmap="viridis")
    fig.colorbar(im, ax=ax, label="z-depth [m]")
    ax.set_title(f"{title}, t = {frame.t:.2f} s")
    ax.set_xlabel("column [px]")
    ax.set_ylabel("row [px]")
    return save_figure(fig, path)
