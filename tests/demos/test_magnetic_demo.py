"""The magnetic demo runs end to end: encoder error against theory, end stop with hysteresis, recording."""

import numpy as np

from twinsense import open_recording
from twinsense.demos.magnetic import DISC, ECCENTRICITY, GAP, build_bench, run_magnetic_demo
from twinsense.magnetic.encoder import ambient_error, eccentricity_coefficients, eccentricity_error, reading_angle, wrap


def test_magnetic_demo_writes_pictures_and_recording(tmp_path):
    out = run_magnetic_demo(tmp_path, duration=0.02)
    assert out["encoder_png"].stat().st_size > 0 and out["end_stop_png"].stat().st_size > 0
    with open_recording(out["recording"]) as rec:
        assert rec["encoder"].kind == "magnetic" and len(rec["encoder"]) == 10  # 500 Hz over 20 ms
        assert np.asarray(rec["encoder"]["raw"]).shape == (10, 1, 3)
        assert np.asarray(rec["end_stop"]["raw"]).shape == (10, 1, 1)


def test_demo_encoder_matches_theory():
    # The demo's curve: exact field vs eccentricity (second order) + Earth field (first order). Remainders:
    # (e / l)^2 ~ 2 % of the eccentricity term (l ~ the 2 mm gap) and (B_E / B0)^2 ~ 1e-7 rad: 5 % of the
    # total amplitude as tolerance.
    scene, enc, _ = build_bench()
    r, ln, br = DISC
    theta = np.linspace(0, 2 * np.pi, 91)[:-1]
    b = enc.true_field(scene, theta / (2 * np.pi))[:, 0]
    err = wrap(reading_angle(b) - theta - np.pi)
    b0 = eccentricity_coefficients(r, ln, br, GAP)[0]
    pred = eccentricity_error(theta, ECCENTRICITY, r, ln, br, GAP) + ambient_error(theta, enc.config.ambient_field, b0)
    assert np.max(np.abs(err - pred)) < 0.05 * np.max(np.abs(pred))
