"""The LiDAR demo runs end to end on one revolution and writes its pictures and recording."""

from twinsense import open_recording
from twinsense.demos.lidar import run_lidar_demo


def test_lidar_demo_writes_pictures_and_recording(tmp_path):
    out = run_lidar_demo(tmp_path, duration=0.1)
    assert out["top_png"].stat().st_size > 0 and out["range_image_png"].stat().st_size > 0
    with open_recording(out["recording"]) as rec:
        r = rec["vlp16"]
        assert r.kind == "lidar" and len(r) == 1
        # One VLP-16 revolution at 10 Hz: 16 x 1800 firings, one echo slot (strongest return).
        assert r["range"].shape == (1, 28_800, 1)
