"""The inductive gripper demo runs end to end and its switching points sit where the physics puts them."""

import json

from twinsense.demos.inductive import run_inductive_demo


def test_inductive_demo_writes_figures_recording_and_switching_points(tmp_path):
    # 200 updates/s instead of the preset's 1 kHz keeps the test short: the jaws close 10 mm/s, so one
    # update is 0.05 mm of travel.
    out = run_inductive_demo(tmp_path, duration=1.1, frame_rate=200.0)
    assert out["switching_png"].stat().st_size > 0 and out["impedance_png"].stat().st_size > 0
    assert out["recording"].stat().st_size > 0
    res = json.loads(out["switching_json"].read_text())
    sn, sw = res["rated_distance_m"], res["switching_distance_m"]
    # Steel is the calibration target: it switches at s_n to one update of travel (0.05 mm) plus the
    # noise, whose sigma is the datasheet repeatability / 3 = 1.7 % of s_n = 0.08 mm (4 sigma: 0.33 mm).
    assert abs(sw["steel"] - sn) < 0.05e-3 + 0.33e-3
    # Aluminium inside the datasheet band of reduction factors (0.2-0.45, see test_device.py), same margin.
    assert 0.2 * sn - 0.4e-3 < sw["aluminium"] < 0.45 * sn + 0.4e-3
