"""The office demo writes its pictures and recording; the reflector saturates."""

from __future__ import annotations

import h5py
import numpy as np

from twinsense.demos.tof import office_camera, run_tof_office_demo
from twinsense.tof.frame import InvalidReason


def test_office_demo_writes_pngs_and_recording(tmp_path):
    files = run_tof_office_demo(tmp_path, duration=0.05, width=56, height=43, fov_deg=(72.0, 45.0))
    for key in ("depth_png", "amplitude_png", "confidence_png", "pointcloud_png", "recording"):
        assert files[key].exists() and files[key].stat().st_size > 1000, key
    with h5py.File(files["recording"], "r") as f:
        assert f["tof/raw"].shape[1:] == (1, 4, 43, 56)  # (frames, frequency, phase step, row, col)
        assert f["tof/depth"].shape[1:] == (43, 56)


def test_office_reflector_saturates_and_edges_fly():
    from twinsense.demos.office import build_office_scene

    scene = build_office_scene(person=False)
    cam = office_camera()
    frame = cam.capture(scene, 0.0, np.random.default_rng(0))
    sat = frame.mask(InvalidReason.SATURATED)
    # The retro-reflector (0.3 x 0.3 m at 5 m: ~12 x 12 px) saturates; depth 0 there.
    assert 50 < sat.sum() < 400
    assert np.all(frame.depth[sat] == 0)
    # With the Royale filter on, flying pixels are found at the object edges.
    filtered = office_camera(flying_pixel_filter=True).capture(scene, 0.0, np.random.default_rng(0))
    assert filtered.mask(InvalidReason.FLYING_PIXEL).sum() > 20
