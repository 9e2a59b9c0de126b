"""``make demo``: the seed paper's office seen by a ToF camera, a radar and a
ground-truth depth camera at once, on one clock, into one recording.

Writes under ``out_dir``:

- ``office_recording.h5``: every frame of the three sensors (see docs/recording-format.md);
- ``tof_depth.png``, ``tof_amplitude.png``, ``tof_confidence.png``, ``tof_pointcloud.png``:
  the pico flexx's last frame (Royale mode MODE_9_5FPS_2000) (the IR reflector saturates: depth 0);
- ``radar_range_spectrum.png`` and ``radar_range_angle.png`` (paper Fig. 4-5),
  ``radar_doppler_tracking.png`` (Fig. 6) and, when the real BGT60TR13C
  recording is available, ``radar_noise_floor.png``;
- ``ground_truth_depth.png``: the ideal depth camera.
"""

from __future__ import annotations

from pathlib import Path

from twinsense.demos.depth import depth_figure
from twinsense.demos.office import build_office_scene, sensor_pose
from twinsense.depthcam import DepthCamera, DepthCameraConfig
from twinsense.render import PinholeCamera
from twinsense.scene import Mount
from twinsense.simulate import simulate


def run_office_demo(out_dir, duration: float = 1.0, progress: bool = False) -> dict[str, Path]:
    """Simulate the office for ``duration`` [s] with all sensors and write plots and the recording."""
    from twinsense.demos import radar as radar_demos
    from twinsense.demos.tof import write_tof_figures
    from twinsense.radar import FMCWRadar
    from twinsense.tof import ToFCamera

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene = build_office_scene()
    mount = Mount(sensor_pose())
    tof = ToFCamera.preset("pmd_pico_flexx", mode="MODE_9_5FPS_2000", mount=mount, name="tof")
    radar = FMCWRadar.preset("paper_bgt60tr13c", mount=mount, name="radar")
    depth = DepthCamera("depth", DepthCameraConfig(PinholeCamera.from_fov(224, 171, 72.0, 45.0), frame_rate=10.0),
                        mount)
    res = simulate(scene, [tof, radar, depth], duration, out=out / "office_recording.h5", seed=0,
                   progress=progress, keep_frames=True)
    files: dict[str, Path] = {"recording": res.path}
    files.update(write_tof_figures(res.frames["tof"][-1], out, label="pico flexx, office"))
    t_last = res.frames["radar"][-1].t
    files.update(radar_demos.office_spectrum_figures(out, t=t_last))
    files.update(radar_demos.doppler_tracking_figure(out))
    files.update(radar_demos.noise_floor_figure(out))
    files["ground_truth_depth_png"] = depth_figure(res.frames["depth"][-1], out / "ground_truth_depth.png",
                                                   "office, ideal depth camera (ground truth)")
    return files
