"""The tactile demo runs end to end (fast settings) and writes its pictures, ISO check and recording."""

import numpy as np

from twinsense import open_recording
from twinsense.demos.registry import DEMOS
from twinsense.demos.tactile import run_tactile_demo


def test_tactile_demo_writes_its_outputs(tmp_path):
    assert "tactile" in DEMOS
    out = run_tactile_demo(tmp_path, duration=2.6, frame_rate=2.5)
    for key in ("maps_png", "channels_png", "force_png"):
        assert out[key].stat().st_size > 0
    text = out["iso_txt"].read_text()
    assert "300 N/cm^2" in text and "frames over the limit: 0" in text
    with open_recording(out["recording"]) as rec:
        skin = rec["skin"]
        assert skin.kind == "tactile" and len(skin) == 6  # 2.5 Hz over 2.6 s: t = 0, 0.4, ... 2.0 s
        true = np.asarray(skin["force_true"])
        # Finger 1 presses from 1.1 s, finger 2 from 2.0 s; nothing before 0.8 s.
        assert np.all(np.isnan(true[:2])) and true[3, 0] > 0 and true[5, 1] > 0
        prox = np.asarray(skin["proximity"])
        assert prox[1].sum() > prox[0].sum() > 0  # the fingers come nearer: the hover signal grows
