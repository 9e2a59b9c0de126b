"""The command line, run as a user would (console script in a subprocess)."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
EXE = Path(sys.executable).with_name("twinsense")


def run(*args, cwd=None):
    return subprocess.run([str(EXE), *args], capture_output=True, text=True, cwd=cwd, timeout=300)


def test_python_dash_m_runs_the_same_command_line():
    r = subprocess.run([sys.executable, "-m", "twinsense", "info"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "ray casting: embree" in r.stdout


def test_info_lists_backend_and_extras():
    r = run("info")
    assert r.returncode == 0, r.stderr
    assert "twinsense" in r.stdout and "ray casting: embree" in r.stdout and "gmsh" in r.stdout


def test_validate_ok_and_errors(tmp_path):
    r = run("validate", str(ROOT / "examples" / "office_depth.yaml"))
    assert r.returncode == 0 and ": ok (4 objects, 1 sensors" in r.stdout
    bad = tmp_path / "bad.yaml"
    bad.write_text("objects:\n  - name: a\n    geometry: {type: sphere, radius: -1}\n")
    r = run("validate", str(bad))
    assert r.returncode == 2
    assert "objects[0].geometry.radius = -1" in r.stderr and "Traceback" not in r.stderr


def test_run_writes_recording(tmp_path):
    r = run("run", str(ROOT / "examples" / "office_depth.yaml"), "-o", str(tmp_path), "--no-progress")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "recording.h5").exists() and "depth: 5" in r.stdout


def test_presets_and_demo_list():
    r = run("presets")
    assert r.returncode == 0 and "camera:" in r.stdout and "generic" in r.stdout
    r = run("demo", "list")
    assert r.returncode == 0 and "depth" in r.stdout


def test_unknown_demo_is_a_clear_error(tmp_path):
    r = run("demo", "nope", "-o", str(tmp_path))
    assert r.returncode == 2 and "demo = 'nope'" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("demo", ["depth"])
def test_depth_demo(tmp_path, demo):
    r = run("demo", demo, "-o", str(tmp_path), "--no-progress")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "depth.png").stat().st_size > 10_000


def test_office_demo_writes_every_output(tmp_path):
    # The `make demo` entry point: ToF + radar + depth camera on one clock.
    r = run("demo", "office", "-o", str(tmp_path), "--no-progress")
    assert r.returncode == 0, r.stderr
    for name in ("office_recording.h5", "tof_depth.png", "tof_amplitude.png", "tof_confidence.png",
                 "tof_pointcloud.png", "radar_range_spectrum.png", "radar_range_angle.png",
                 "radar_doppler_tracking.png", "ground_truth_depth.png"):
        assert (tmp_path / name).stat().st_size > 1000, name
    from twinsense import open_recording

    with open_recording(tmp_path / "office_recording.h5") as rec:
        assert set(rec.sensors) == {"tof", "radar", "depth"}
        # One clock: every sensor's timestamps are multiples of its own period from t = 0.
        for s in rec.sensors.values():
            np.testing.assert_allclose(s.timestamps, np.arange(len(s)) / s.frame_rate, atol=1e-12)
        tof = rec["tof"]
        # The IR reflector saturates: flagged pixels with depth exactly 0.
        inv, depth = tof["invalid"][-1], tof["depth"][-1]
        assert np.any(inv & 1) and np.all(depth[(inv & 1) > 0] == 0)


@pytest.mark.parametrize("example", sorted((ROOT / "examples").glob("*.yaml")), ids=lambda p: p.name)
def test_every_example_validates(example):
    r = run("validate", str(example))
    assert r.returncode == 0, r.stderr


def test_robot_cell_runs_all_sensor_kinds(tmp_path):
    r = run("run", str(ROOT / "examples" / "robot_cell.yaml"), "-o", str(tmp_path), "--no-progress")
    assert r.returncode == 0, r.stderr
    from twinsense import open_recording

    with open_recording(tmp_path / "recording.h5") as rec:
        assert {s.kind for s in rec.sensors.values()} == {"tof", "radar", "capacitive"}
        assert len(rec["radar"]) == 2 and len(rec["skin"]) == 4  # 10 Hz and 20 Hz over 0.2 s


def test_overrides_and_limits_are_validated_like_the_file(tmp_path):
    ex = str(ROOT / "examples" / "office_depth.yaml")
    r = run("validate", ex, "--duration", "1e9")
    assert r.returncode == 2 and "duration = 1000000000.0" in r.stderr and "estimated 1e+10 frames" in r.stderr
    assert "Traceback" not in r.stderr
    r = run("run", ex, "-o", str(tmp_path), "--duration", "-1", "--seed", "-3")
    assert r.returncode == 2 and "duration = -1.0" in r.stderr and "seed = -3" in r.stderr
    assert not list(tmp_path.iterdir())


def test_run_duration_and_seed_overrides(tmp_path):
    # office_depth.yaml: 0.5 s at 10 Hz, seed 7; the overrides give 3 frames with seed 3.
    r = run("run", str(ROOT / "examples" / "office_depth.yaml"), "-o", str(tmp_path), "--no-progress",
            "--duration", "0.3", "--seed", "3")
    assert r.returncode == 0, r.stderr
    assert "depth: 3 frames" in r.stdout
    from twinsense import open_recording

    with open_recording(tmp_path / "recording.h5") as rec:
        assert rec.scenario["duration"] == 0.3 and rec.scenario["seed"] == 3
        np.testing.assert_array_equal(rec["depth"].timestamps, np.arange(3) / 10)


def test_bad_names_and_recording_paths_fail_validation(tmp_path):
    text = (ROOT / "examples" / "office_depth.yaml").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("  - name: depth\n", "  - name: cam/depth\n")
                   .replace("outputs: {recording: recording.h5}", "outputs: {recording: /tmp/x/rec.txt}"))
    r = run("validate", str(bad))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "sensors[0].name = 'cam/depth'" in r.stderr and "a letter, then up to 63" in r.stderr
    assert "outputs.recording = '/tmp/x/rec.txt'" in r.stderr and "ending in .h5" in r.stderr
    null = tmp_path / "null.yaml"
    null.write_text(text.replace("outputs: {recording: recording.h5}", "outputs: {recording: null}"))
    out = tmp_path / "out"
    r = run("run", str(null), "-o", str(out), "--no-progress", "--duration", "0.1")
    assert r.returncode == 0, r.stderr
    assert "no recording written (outputs.recording is null)" in r.stdout and not out.exists()
